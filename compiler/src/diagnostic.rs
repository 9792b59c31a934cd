//! User-facing diagnostics: errors and warnings with spans, labels and notes.
//!
//! Every phase (preprocessor, lexer, parser, checker) reports problems as [`Diagnostic`]s and keeps
//! going, so one run reports every error it can find. A diagnostic has a stable [`Code`]; the list of
//! codes, with one line each, is [`Code::ALL`] and is printed in `docs/diagnostics.md`.
//!
//! Rendering follows rustc: `error[E0100]: message`, then ` --> file:line:col`, the source line with
//! a caret under the span, secondary labels, and notes. [`render`] uses codespan-reporting.

use crate::source::{Location, SourceMap, Span};
use codespan_reporting::diagnostic as cs;
use codespan_reporting::term;
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    Note,
    Warning,
    Error,
}

macro_rules! codes {
    ($($name:ident = $code:literal, $sev:ident, $doc:literal;)*) => {
        /// Every kind of diagnostic the compiler emits. The code string is stable across releases.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Code { $($name,)* }

        impl Code {
            pub const ALL: &'static [Code] = &[$(Code::$name,)*];

            pub fn as_str(self) -> &'static str {
                match self { $(Code::$name => $code,)* }
            }

            /// Whether the code is an error or a warning by default.
            pub fn severity(self) -> Severity {
                match self { $(Code::$name => Severity::$sev,)* }
            }

            /// One line describing the code, for documentation.
            pub fn description(self) -> &'static str {
                match self { $(Code::$name => $doc,)* }
            }
        }
    };
}

codes! {
    // Preprocessor.
    IncludeNotFound = "E0001", Error, "an `#include`d file was not found on the include path";
    IncludeDepth = "E0002", Error, "`#include` nested too deeply (usually a file that includes itself)";
    StrayConditional = "E0004", Error, "`#else`, `#elif` or `#endif` without a matching `#if`";
    MalformedDirective = "E0005", Error, "a preprocessor directive that cannot be read";
    BadIfExpression = "E0006", Error, "an `#if` expression that is not a valid integer expression";
    MacroArgCount = "E0007", Error, "a function-like macro called with the wrong number of arguments";
    UnterminatedMacroCall = "E0008", Error, "a function-like macro call whose `)` is missing";
    ErrorDirective = "E0009", Error, "an `#error` directive was reached";
    MacroRecursionLimit = "E0010", Error, "macro expansion produced too many tokens (runaway expansion)";
    // Lexer.
    InvalidCharacter = "E0020", Error, "a character that cannot start any token";
    UnterminatedString = "E0021", Error, "a string literal without its closing quote";
    UnterminatedComment = "E0022", Error, "a `/*` comment without its `*/`";
    // Parser.
    Syntax = "E0030", Error, "a syntax error: an unexpected token";
    UnexpectedEof = "E0031", Error, "the file ended in the middle of a construct";
    // Checker.
    UndefinedVariable = "E0100", Error, "a name that is not a variable in scope";
    UndefinedFunction = "E0101", Error, "a call to a function that is neither built in nor defined";
    Redefinition = "E0102", Error, "a name declared twice in the same scope";
    AssignTypeMismatch = "E0103", Error, "a value of one type assigned or initialised into a variable of another";
    NoMatchingOverload = "E0104", Error, "a built-in called with arguments that match none of its signatures";
    ArgumentCount = "E0105", Error, "a user function called with the wrong number of arguments";
    BinaryOperandTypes = "E0106", Error, "a binary operator applied to types it does not accept";
    UnaryOperandType = "E0107", Error, "a unary operator applied to a type it does not accept";
    BadCondition = "E0108", Error, "a condition that is not a relation or a float";
    NotAssignable = "E0109", Error, "an assignment to something that cannot be written (a read-only global, a constant, an expression)";
    VaryingToUniform = "E0110", Error, "a varying value flowing into a uniform variable";
    IlluminanceContext = "E0111", Error, "`illuminance` or `gather` in a shader type without lights";
    IlluminateContext = "E0112", Error, "`illuminate` or `solar` outside a light shader";
    BreakLevel = "E0113", Error, "`break n`/`continue n` with more levels than enclosing loops";
    Recursion = "E0114", Error, "a function that calls itself, directly or through others";
    OutputArgument = "E0115", Error, "an `output` parameter given a value that cannot be written";
    ReturnMismatch = "E0116", Error, "a `return` outside a function, or returning the wrong type";
    BadIndex = "E0117", Error, "indexing something that is not an array or triple, or with a non-float index";
    UnknownColorSpace = "E0118", Error, "a colour typecast naming a colour space that does not exist";
    MissingReturn = "E0119", Error, "a function with a result that can end without `return`";
    MissingDefault = "E0120", Error, "a shader parameter without a default value";
    MultipleShaders = "E0121", Error, "more than one shader defined in one file";
    ExternNotFound = "E0123", Error, "an `extern` declaration naming no variable of an enclosing scope";
    ArrayMismatch = "E0124", Error, "an array initialiser or assignment whose length or element type does not fit";
    BadConstructor = "E0125", Error, "a triple or matrix written with the wrong number or type of components";
    VoidValue = "E0126", Error, "a `void` function's result used as a value";
    BadTypecast = "E0127", Error, "a typecast between types that cannot be converted";
    LightGlobalOutsideLoop = "E0128", Error, "`L` or `Cl` written outside `illuminance`, `illuminate` or `solar`";
    VaryingString = "E0129", Error, "a `varying` string: strings are always uniform";
    ArraySize = "E0130", Error, "an array size that is not a positive integer constant";
    DuplicateParameter = "E0131", Error, "two parameters with the same name";
    FunctionRedefinition = "E0132", Error, "a function defined twice with the same parameter types";
    NotAFunction = "E0133", Error, "a call of something that is a variable, not a function";
    ShaderGlobalRedeclared = "E0134", Error, "a shader parameter or function named like a shader global it would hide";
    MessagePassing = "E0135", Error, "a message-passing call whose name is not a constant string";
    DefaultNotUniform = "E0136", Error, "a default value that depends on varying data";
    InlineBudget = "E0137", Error, "a shader too large once its user function calls are inlined (calls that nest multiply its size; arrays count by their floats)";
    StorageBudget = "E0138", Error, "a shader whose variables hold too many floats (large arrays), every inlined call's included";
    InternalError = "E0999", Error, "an internal compiler error: the compiler produced invalid IR (please report it)";
    // Warnings.
    UnusedVariable = "W0001", Warning, "a local variable that is never read";
    UnusedParameter = "W0002", Warning, "a parameter that is never read";
    ImplicitNarrowing = "W0003", Warning, "a triple used where a float is expected (keeps only its first component)";
    UnreachableCode = "W0004", Warning, "statements after `return`, `break` or `continue`";
    UnknownDirective = "W0005", Warning, "an unknown preprocessor directive or `#pragma`, ignored";
    MacroRedefined = "W0006", Warning, "a macro defined again with a different body";
    Unsupported = "W0007", Warning, "a built-in this renderer accepts but cannot honour (it returns a documented value)";
    WarningDirective = "W0008", Warning, "a `#warning` directive was reached";
    ImplicitColorConversion = "W0009", Warning, "a colour used as a point, vector or normal, or the reverse, without a typecast";
    ShadowedVariable = "W0010", Warning, "a local variable that hides a shader parameter or global of the same name";
    VendorExtension = "W0012", Warning, "another renderer's extension: a built-in under its own name (read as rtsl's equivalent), or a global a shader type has only there";
    UnterminatedConditional = "W0011", Warning, "a file that ends inside an `#if`/`#ifdef`/`#ifndef`: the conditional ends with the file, as C preprocessors take it";
}

/// One message to the user.
#[derive(Clone, Debug)]
pub struct Diagnostic {
    pub severity: Severity,
    pub code: Code,
    pub message: String,
    /// Where the problem is. Every diagnostic has one.
    pub span: Span,
    /// The text shown under the primary caret, if any.
    pub label: Option<String>,
    /// Other places worth showing ("declared here").
    pub secondary: Vec<(Span, String)>,
    /// Free-form notes and help ("did you mean `normalize`?").
    pub notes: Vec<String>,
}

impl Diagnostic {
    pub fn new(code: Code, span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity: code.severity(),
            code,
            message: message.into(),
            span,
            label: None,
            secondary: Vec::new(),
            notes: Vec::new(),
        }
    }

    pub fn with_label(mut self, label: impl Into<String>) -> Diagnostic {
        self.label = Some(label.into());
        self
    }

    pub fn with_secondary(mut self, span: Span, label: impl Into<String>) -> Diagnostic {
        self.secondary.push((span, label.into()));
        self
    }

    pub fn with_note(mut self, note: impl Into<String>) -> Diagnostic {
        self.notes.push(note.into());
        self
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    /// The one-line form: `file:line:col: error[E0100]: message`.
    pub fn one_line(&self, sources: &SourceMap) -> String {
        format!(
            "{}: {}[{}]: {}",
            sources.location(self.span),
            severity_word(self.severity),
            self.code.as_str(),
            self.message
        )
    }

    fn to_codespan(&self) -> cs::Diagnostic<crate::source::FileId> {
        let sev = match self.severity {
            Severity::Error => cs::Severity::Error,
            Severity::Warning => cs::Severity::Warning,
            Severity::Note => cs::Severity::Note,
        };
        let mut primary = cs::Label::primary(self.span.file, self.span.range());
        if let Some(l) = &self.label {
            primary = primary.with_message(l.clone());
        }
        let mut labels = vec![primary];
        for (span, msg) in &self.secondary {
            labels.push(cs::Label::secondary(span.file, span.range()).with_message(msg.clone()));
        }
        cs::Diagnostic::new(sev)
            .with_code(self.code.as_str())
            .with_message(self.message.clone())
            .with_labels(labels)
            .with_notes(self.notes.clone())
    }

    /// A machine-readable record of the diagnostic, for `--json`.
    pub fn to_json(&self, sources: &SourceMap) -> JsonDiagnostic {
        let to_loc = |span: Span| {
            let Location { file, line, column } = sources.location(span);
            let end = sources.location(Span::new(span.file, span.end, span.end));
            JsonSpan {
                file: file.to_string(),
                line,
                column,
                end_line: end.line,
                end_column: end.column,
                byte_start: span.start,
                byte_end: span.end,
            }
        };
        JsonDiagnostic {
            severity: self.severity,
            code: self.code.as_str(),
            message: self.message.clone(),
            span: to_loc(self.span),
            label: self.label.clone(),
            secondary: self.secondary.iter().map(|(s, l)| JsonLabel { span: to_loc(*s), label: l.clone() }).collect(),
            notes: self.notes.clone(),
        }
    }
}

fn severity_word(s: Severity) -> &'static str {
    match s {
        Severity::Error => "error",
        Severity::Warning => "warning",
        Severity::Note => "note",
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct JsonSpan {
    pub file: String,
    pub line: usize,
    pub column: usize,
    pub end_line: usize,
    pub end_column: usize,
    pub byte_start: u32,
    pub byte_end: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct JsonLabel {
    pub span: JsonSpan,
    pub label: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct JsonDiagnostic {
    pub severity: Severity,
    pub code: &'static str,
    pub message: String,
    pub span: JsonSpan,
    pub label: Option<String>,
    pub secondary: Vec<JsonLabel>,
    pub notes: Vec<String>,
}

/// Renders diagnostics the way rustc does, into a string (no colour).
pub fn render(sources: &SourceMap, diagnostics: &[Diagnostic]) -> String {
    let mut buf = term::termcolor::NoColor::new(Vec::new());
    render_to(sources, diagnostics, &mut buf);
    String::from_utf8_lossy(&buf.into_inner()).into_owned()
}

/// Renders diagnostics to any codespan writer (coloured terminals included).
pub fn render_to(sources: &SourceMap, diagnostics: &[Diagnostic], out: &mut dyn term::WriteStyle) {
    let config = term::Config::default();
    for d in diagnostics {
        // Rendering can only fail on an I/O error of `out` or a span outside its file; neither is the
        // user's fault, and the one-line form below still reaches them.
        let emitted = match Clipped::new(sources, d) {
            Some(clipped) => term::emit_to_write_style(out, &config, &clipped, &clipped.diagnostic),
            None => term::emit_to_write_style(out, &config, sources, &d.to_codespan()),
        };
        if emitted.is_err() {
            let _ = writeln!(out, "{}", d.one_line(sources));
        }
    }
}

/// The most diagnostics one compilation reports; the rest are counted, not shown (as rustc stops
/// after too many errors), so a file of garbage costs a bounded amount of output.
pub const MAX_REPORTED: usize = 100;

/// Source lines longer than this are shown clipped around the diagnostic's labels.
const MAX_SHOWN_LINE: usize = 200;
/// How much of the line to show on each side of the labels when clipping.
const CLIP_CONTEXT: usize = 40;
/// The most of one label's span shown when clipping.
const CLIP_SPAN: usize = 120;

/// A diagnostic whose labels all sit on one long line, rendered over a file of that one line cut
/// down to a window around them: the output of each diagnostic stays proportional to its window,
/// not to the line, while line and column numbers stay those of the real file.
struct Clipped<'a> {
    name: &'a str,
    /// The window's text, between `...` where the line goes on, with a final newline.
    text: String,
    line_number: usize,
    /// Columns of the real line before the window (in characters).
    columns_before: usize,
    /// The length of the `...` before the window.
    prefix: usize,
    diagnostic: cs::Diagnostic<()>,
}

impl<'a> Clipped<'a> {
    fn new(sources: &'a SourceMap, d: &Diagnostic) -> Option<Clipped<'a>> {
        let file = sources.get(d.span.file);
        let text: &str = &file.text;
        let line = file.line_index(d.span.start);
        let line_start = file.line_start(line)? as usize;
        let line_end = file.line_start(line + 1).map_or(text.len(), |s| s as usize);
        let line_end = line_start + text.get(line_start..line_end)?.trim_end_matches(['\n', '\r']).len();
        if line_end - line_start <= MAX_SHOWN_LINE {
            return None;
        }
        let spans: Vec<Span> = std::iter::once(d.span).chain(d.secondary.iter().map(|(s, _)| *s)).collect();
        let on_line = |s: &Span| {
            s.file == d.span.file && (line_start..=line_end).contains(&(s.start as usize)) && s.end >= s.start
        };
        if !spans.iter().all(on_line) {
            return None;
        }
        let shown_end = |s: &Span| (s.end as usize).min(line_end).min(s.start as usize + CLIP_SPAN);
        let lo = spans.iter().map(|s| s.start as usize).min()?;
        let hi = spans.iter().map(shown_end).max()?;
        let floor = |mut i: usize| {
            while !text.is_char_boundary(i) {
                i -= 1;
            }
            i
        };
        let start = floor(lo.saturating_sub(CLIP_CONTEXT).max(line_start));
        let end = floor((hi + CLIP_CONTEXT).min(line_end));
        let (prefix, suffix) = (if start > line_start { "..." } else { "" }, if end < line_end { "..." } else { "" });
        let window = format!("{prefix}{}{suffix}\n", text.get(start..end)?);
        let columns_before = text.get(line_start..start)?.chars().count();
        let to_window = |s: &Span| {
            let a = floor((s.start as usize).clamp(start, end)) - start + prefix.len();
            let b = floor(shown_end(s).clamp(start, end)) - start + prefix.len();
            a..b.max(a)
        };
        let cd = d.to_codespan();
        let labels = cd
            .labels
            .into_iter()
            .zip(&spans)
            .map(|(label, span)| cs::Label::new(label.style, (), to_window(span)).with_message(label.message))
            .collect();
        let mut diagnostic =
            cs::Diagnostic::new(cd.severity).with_message(cd.message).with_labels(labels).with_notes(cd.notes);
        if let Some(code) = cd.code {
            diagnostic = diagnostic.with_code(code);
        }
        Some(Clipped {
            name: &file.name,
            text: window,
            line_number: line + 1,
            columns_before,
            prefix: prefix.len(),
            diagnostic,
        })
    }
}

impl<'a> codespan_reporting::files::Files<'a> for Clipped<'_> {
    type FileId = ();
    type Name = &'a str;
    type Source = &'a str;

    fn name(&'a self, _: ()) -> Result<&'a str, codespan_reporting::files::Error> {
        Ok(self.name)
    }

    fn source(&'a self, _: ()) -> Result<&'a str, codespan_reporting::files::Error> {
        Ok(&self.text)
    }

    fn line_index(&'a self, _: (), _: usize) -> Result<usize, codespan_reporting::files::Error> {
        Ok(0)
    }

    fn line_number(&'a self, _: (), _: usize) -> Result<usize, codespan_reporting::files::Error> {
        Ok(self.line_number)
    }

    fn column_number(&'a self, _: (), _: usize, byte: usize) -> Result<usize, codespan_reporting::files::Error> {
        // A position inside the window counts the real line's characters before the window.
        let inside = self.text.get(self.prefix..byte.max(self.prefix)).map_or(0, |s| s.chars().count());
        Ok(self.columns_before + inside + 1)
    }

    fn line_range(&'a self, _: (), _: usize) -> Result<std::ops::Range<usize>, codespan_reporting::files::Error> {
        Ok(0..self.text.len())
    }
}

/// A list of diagnostics with helpers for the phases that fill it.
#[derive(Clone, Debug, Default)]
pub struct Diagnostics {
    pub list: Vec<Diagnostic>,
}

impl Diagnostics {
    pub fn push(&mut self, d: Diagnostic) {
        self.list.push(d);
    }

    pub fn error(&mut self, code: Code, span: Span, message: impl Into<String>) {
        self.push(Diagnostic::new(code, span, message));
    }

    pub fn has_errors(&self) -> bool {
        self.list.iter().any(Diagnostic::is_error)
    }

    pub fn error_count(&self) -> usize {
        self.list.iter().filter(|d| d.is_error()).count()
    }

    pub fn warning_count(&self) -> usize {
        self.list.iter().filter(|d| d.severity == Severity::Warning).count()
    }

    /// Sorts by file and position, keeping the order of diagnostics at the same place, and drops exact
    /// duplicates (a header included twice reports its problems once).
    pub fn finish(&mut self) {
        self.list.sort_by_key(|d| (d.span.file, d.span.start, d.severity == Severity::Warning));
        self.list.dedup_by(|a, b| a.code == b.code && a.span == b.span && a.message == b.message);
    }

    /// Keeps the first [`MAX_REPORTED`] diagnostics (in the order of `finish`); returns how many
    /// errors and warnings were dropped.
    pub fn cap(&mut self) -> (usize, usize) {
        if self.list.len() <= MAX_REPORTED {
            return (0, 0);
        }
        let dropped = self.list.split_off(MAX_REPORTED);
        let errors = dropped.iter().filter(|d| d.is_error()).count();
        (errors, dropped.len() - errors)
    }
}

//! The compiler driver: one `.sl` file through every phase.

use crate::diagnostic::{Diagnostic, Diagnostics, Severity};
use crate::front::lex::Token;
use crate::front::parse::ast;
use crate::front::{check, parse, preprocess};
use crate::interface::ShaderInterface;
use crate::ir::Module;
use crate::ir::ShaderKind;
use crate::source::{FileId, SourceMap};
use crate::symbol::Interner;
use std::path::Path;

/// Settings for a compilation.
#[derive(Clone, Debug, Default)]
pub struct Options {
    pub preprocessor: preprocess::Options,
}

/// Everything one compilation produced. Always returned, whatever the input.
#[derive(Debug)]
pub struct Compilation {
    pub sources: SourceMap,
    /// Errors and warnings, sorted by position.
    pub diagnostics: Vec<Diagnostic>,
    /// The checked IR, when there was no error.
    pub module: Option<Module>,
    /// The shader's interface, when there was no error and the file defines a shader.
    pub interface: Option<ShaderInterface>,
    /// The type and name of the shader the file defines, known as soon as it parsed.
    pub shader: Option<(ShaderKind, String)>,
    /// The main file and every file it included, main file first.
    pub files: Vec<FileId>,
    /// Lines of source read (main file and includes, counting each include once).
    pub lines: usize,
    /// Errors and warnings found beyond the first [`crate::diagnostic::MAX_REPORTED`], counted but
    /// left out of `diagnostics`.
    pub suppressed: (usize, usize),
}

impl Compilation {
    pub fn ok(&self) -> bool {
        self.errors() == 0
    }

    /// Errors found, the suppressed ones included.
    pub fn errors(&self) -> usize {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Error).count() + self.suppressed.0
    }

    /// Warnings found, the suppressed ones included.
    pub fn warnings(&self) -> usize {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Warning).count() + self.suppressed.1
    }

    /// The diagnostics rendered as rustc does (no colour), with a final note counting those left
    /// out.
    pub fn render(&self) -> String {
        let mut out = crate::diagnostic::render(&self.sources, &self.diagnostics);
        if let Some(note) = self.suppressed_note() {
            out.push_str(&note);
            out.push('\n');
        }
        out
    }

    /// "note: ... not shown" when diagnostics were suppressed.
    pub fn suppressed_note(&self) -> Option<String> {
        let (errors, warnings) = self.suppressed;
        let count = |n: usize, what: &str| format!("{n} more {what}{}", if n == 1 { "" } else { "s" });
        let what = match (errors, warnings) {
            (0, 0) => return None,
            (e, 0) => count(e, "error"),
            (0, w) => count(w, "warning"),
            (e, w) => format!("{} and {}", count(e, "error"), count(w, "warning")),
        };
        Some(format!(
            "note: {what} not shown (only the first {} diagnostics of a file are reported)",
            crate::diagnostic::MAX_REPORTED
        ))
    }
}

/// State shared by the compilations of one command or one thread: the interner, the headers
/// already read and lexed, and buffers reused from one file to the next. Headers are assumed not to
/// change while a session lives.
#[derive(Debug, Default)]
pub struct Session {
    interner: Interner,
    headers: preprocess::HeaderCache,
    /// The token stream of the previous file, kept for its capacity.
    tokens: Vec<Token>,
    /// Where the syntax tree of the file being compiled lives; emptied (keeping its memory) before
    /// each file.
    syntax_arena: bumpalo::Bump,
}

impl Session {
    pub fn new() -> Session {
        Session::default()
    }

    /// Compiles a file from disk. A file that cannot be read is an `Err` with the I/O problem.
    pub fn compile_file(&mut self, path: &Path, options: &Options) -> std::io::Result<Compilation> {
        let mut sources = SourceMap::new();
        let file = sources.load(path)?;
        Ok(self.compile_loaded(sources, file, options))
    }

    /// Compiles source text held in memory; `name` is used in diagnostics and `#include "x"` is
    /// looked up in the include path only.
    pub fn compile_source(&mut self, name: &str, text: &str, options: &Options) -> Compilation {
        let mut sources = SourceMap::new();
        let file = sources.add_virtual(name, std::sync::Arc::<str>::from(text));
        self.compile_loaded(sources, file, options)
    }

    /// Compiles text held in memory as if it were the file at `path` (so `#include "x"` searches that
    /// file's directory first).
    pub fn compile_source_at(&mut self, path: &Path, text: &str, options: &Options) -> Compilation {
        let mut sources = SourceMap::new();
        let file = sources.add(path.display().to_string(), Some(path.to_path_buf()), std::sync::Arc::<str>::from(text));
        self.compile_loaded(sources, file, options)
    }

    /// Forgets cached headers (after files changed on disk).
    pub fn forget_headers(&mut self) {
        self.headers.clear();
    }

    fn compile_loaded(&mut self, sources: SourceMap, file: FileId, options: &Options) -> Compilation {
        compile_loaded(sources, file, options, self)
    }
}

/// Compiles a file from disk in a fresh session. A file that cannot be read is an `Err` with the I/O
/// problem.
pub fn compile_file(path: &Path, options: &Options) -> std::io::Result<Compilation> {
    Session::new().compile_file(path, options)
}

/// Compiles source text held in memory, in a fresh session.
pub fn compile_source(name: &str, text: &str, options: &Options) -> Compilation {
    Session::new().compile_source(name, text, options)
}

/// Compiles text held in memory as if it were the file at `path`, in a fresh session.
pub fn compile_source_at(path: &Path, text: &str, options: &Options) -> Compilation {
    Session::new().compile_source_at(path, text, options)
}

fn compile_loaded(mut sources: SourceMap, file: FileId, options: &Options, session: &mut Session) -> Compilation {
    let mut diags = Diagnostics::default();
    let buffer = std::mem::take(&mut session.tokens);
    session.syntax_arena.reset();
    let arena = &session.syntax_arena;
    let interner = &mut session.interner;
    let mut pre = preprocess::preprocess(
        buffer,
        file,
        &mut sources,
        interner,
        &mut session.headers,
        &options.preprocessor,
        &mut diags,
    );
    let unit = if pre.aborted {
        ast::TranslationUnit { items: &[] }
    } else {
        parse::parse(arena, &pre.tokens, interner, &mut diags)
    };
    let shader = unit.items.iter().find_map(|i| match i {
        ast::Item::Shader(s) => Some((s.kind, interner.resolve(s.name.sym).to_string())),
        _ => None,
    });
    session.tokens = std::mem::take(&mut pre.tokens);
    let mut checked = check::check(&unit, interner, &mut diags);
    // Only validated IR leaves the compiler: a violation is a compiler bug, reported as such.
    if let Some(module) = &checked.module {
        if let Err(problems) = crate::valid::validate(module) {
            let span = module.shader.as_ref().map(|s| s.span).unwrap_or(crate::source::Span::new(file, 0, 0));
            let mut d =
                Diagnostic::new(crate::diagnostic::Code::InternalError, span, "internal compiler error: invalid IR")
                    .with_label("while compiling this");
            for p in problems.iter().take(10) {
                d = d.with_note(p.clone());
            }
            diags.push(d);
            checked.module = None;
        }
    }
    drop_syntax_cascades(&mut diags, &sources);
    drop_quieted_warnings(&mut diags, &sources, file, &pre.nolint);
    diags.finish();
    let suppressed = diags.cap();
    // After the cap: only the diagnostics shown are looked up among the expansions.
    note_macro_expansions(&mut diags, &pre.expansions, interner);
    let interface = checked.module.as_ref().and_then(|m| ShaderInterface::from_module(m, &sources));
    let lines = pre.files.iter().map(|f| sources.get(*f).line_count()).sum();
    Compilation {
        diagnostics: diags.list,
        module: checked.module,
        interface,
        shader,
        files: pre.files,
        lines,
        sources,
        suppressed,
    }
}

/// Warnings nobody asked for: those on the line after a `#pragma nolint`, and unused variables and
/// parameters in included headers (library code the shader's author does not edit, which every
/// shader including it would repeat; the compiled file's own are still reported).
fn drop_quieted_warnings(diags: &mut Diagnostics, sources: &SourceMap, main: FileId, nolint: &[(FileId, usize)]) {
    use crate::diagnostic::{Code, Severity};
    diags.list.retain(|d| {
        if d.severity != Severity::Warning {
            return true;
        }
        if matches!(d.code, Code::UnusedVariable | Code::UnusedParameter) && d.span.file != main {
            return false;
        }
        let line = sources.get(d.span.file).line_index(d.span.start);
        !line.checked_sub(1).is_some_and(|above| nolint.contains(&(d.span.file, above)))
    });
}

/// A bad character or unterminated string is dropped by the preprocessor, so the parser usually
/// trips over the gap it leaves. That second error says nothing new: drop syntax errors on a line
/// that already has a lexical error.
fn drop_syntax_cascades(diags: &mut Diagnostics, sources: &SourceMap) {
    use crate::diagnostic::Code;
    let lexical: std::collections::HashSet<(FileId, usize)> = diags
        .list
        .iter()
        .filter(|d| matches!(d.code, Code::InvalidCharacter | Code::UnterminatedString | Code::UnterminatedComment))
        .map(|d| (d.span.file, sources.get(d.span.file).line_index(d.span.start)))
        .collect();
    if lexical.is_empty() {
        return;
    }
    diags.list.retain(|d| {
        if !matches!(d.code, Code::Syntax | Code::UnexpectedEof) {
            return true;
        }
        let line = sources.get(d.span.file).line_index(d.span.start);
        let after_lexical = line.checked_sub(1).is_some_and(|above| lexical.contains(&(d.span.file, above)));
        !lexical.contains(&(d.span.file, line)) && !after_lexical
    });
}

/// A diagnostic inside a macro call points at the call (tokens from a macro body carry the call's
/// span); say which macro it was and where it is defined, as rustc does.
fn note_macro_expansions(diags: &mut Diagnostics, expansions: &[preprocess::Expansion], interner: &Interner) {
    if expansions.is_empty() {
        return;
    }
    for d in &mut diags.list {
        use crate::diagnostic::Code;
        // Preprocessor and lexer diagnostics already speak of macros.
        let early = matches!(
            d.code,
            Code::MacroArgCount
                | Code::UnterminatedMacroCall
                | Code::MacroRecursionLimit
                | Code::MalformedDirective
                | Code::MacroRedefined
                | Code::InvalidCharacter
                | Code::UnterminatedString
                | Code::UnterminatedComment
        );
        if early {
            continue;
        }
        let inside = expansions.iter().find(|e| {
            e.call.file == d.span.file && e.call.start <= d.span.start && d.span.end <= e.call.end && e.call != d.span
                || e.call == d.span
        });
        if let Some(e) = inside {
            let name = interner.resolve(e.name);
            d.notes.push(format!("this is inside the expansion of macro `{name}`"));
            if e.definition.file != d.span.file || e.definition.start != d.span.start {
                d.secondary.push((e.definition, format!("`{name}` is defined here")));
            }
        }
    }
}

//! The C preprocessor, working on tokens.
//!
//! It reads the main file's tokens, executes directives (`#include`, `#define`, `#undef`, the
//! conditionals, `#error`, `#warning`, `#pragma`, `#line`), expands macros with C's rules (arguments
//! are expanded before substitution except next to `#` and `##`; a macro is not expanded again inside
//! its own expansion), and produces one token stream for the parser.
//!
//! Invariants kept here:
//! - every output token has the span of text the user wrote: its own text if it came from a file or a
//!   macro argument, or the whole macro call if it came from a macro body (see [`Token::span`]);
//! - excluded code (`#if 0`) is never reported on, except for its conditional directives;
//! - the preprocessor never fails: problems become diagnostics and it goes on.

mod expr;
pub mod standard_headers;

use crate::diagnostic::{Code, Diagnostic, Diagnostics};
use crate::front::lex::{self, Token, TokenKind, LINE_START, NO_EXPAND, SPACE_BEFORE};
use crate::source::{FileId, SourceMap, Span};
use crate::symbol::{Interner, Symbol};
use rustc_hash::{FxHashMap, FxHashSet};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// How deep `#include` may nest before we assume a file includes itself.
const MAX_INCLUDE_DEPTH: usize = 64;
/// How many tokens macro expansion may produce for one file before we call it runaway.
const MAX_EXPANDED_TOKENS: usize = 2_000_000;
/// How deeply macro calls may nest inside each other's arguments (each level recurses).
const MAX_ARGUMENT_NESTING: usize = 200;
/// How deeply macro expansions may nest.
const MAX_EXPANSION_DEPTH: usize = 4096;

/// Preprocessor settings: the include path and the command line's definitions.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Directories searched for `#include` (after the including file's own directory for `"x"`).
    pub include_paths: Vec<PathBuf>,
    /// `-D NAME[=VALUE]`: the value defaults to `1`.
    pub defines: Vec<(String, Option<String>)>,
    /// `-U NAME`: removes a predefined macro.
    pub undefines: Vec<String>,
}

/// Headers already read and lexed, shared by the compilations of one [`crate::Session`] (with the
/// session's interner, so symbols in cached tokens stay valid). It assumes files do not change while
/// it lives: a session is made per command, or cleared when a watcher sees an edit.
#[derive(Debug, Default)]
pub struct HeaderCache {
    headers: FxHashMap<PathBuf, CachedHeader>,
    /// `#include` names resolved from a directory: (including file's directory, name, angled).
    resolved: FxHashMap<(Option<PathBuf>, String, bool), Option<PathBuf>>,
}

#[derive(Debug)]
struct CachedHeader {
    text: std::sync::Arc<str>,
    lines: std::sync::Arc<[u32]>,
    /// Tokens with spans in file 0; rewritten to the file id of each compilation that uses them.
    tokens: Vec<Token>,
}

impl HeaderCache {
    pub fn clear(&mut self) {
        self.headers.clear();
        self.resolved.clear();
    }
}

/// The crate's version as one integer: major * 10000 + minor * 100 + patch.
pub fn version_number() -> u32 {
    let parse = |s: &str| s.parse::<u32>().unwrap_or(0);
    parse(env!("CARGO_PKG_VERSION_MAJOR")) * 10000
        + parse(env!("CARGO_PKG_VERSION_MINOR")) * 100
        + parse(env!("CARGO_PKG_VERSION_PATCH"))
}

#[derive(Clone, Debug)]
struct Macro {
    /// Where the macro was defined (its name in the `#define` line).
    def_span: Span,
    function_like: bool,
    params: Vec<Symbol>,
    variadic: bool,
    body: Rc<[Token]>,
}

impl Macro {
    fn same_definition(&self, other: &Macro) -> bool {
        self.function_like == other.function_like
            && self.params == other.params
            && self.variadic == other.variadic
            && self.body.len() == other.body.len()
            && self.body.iter().zip(other.body.iter()).all(|(a, b)| a.kind == b.kind && a.sym == b.sym)
    }
}

/// One file being read: its tokens and where we are in them.
struct FileFrame {
    file: FileId,
    tokens: Rc<[Token]>,
    pos: usize,
    /// The conditional stack's depth when this file was entered; deeper at its end means an
    /// unterminated `#if`.
    cond_base: usize,
}

/// One macro expansion being read.
struct Context {
    tokens: Vec<Token>,
    pos: usize,
    /// The macro being expanded, if any: it is not expanded again while this context is on the stack,
    /// which covers the rescan of everything its expansion produced.
    disabled: Option<Symbol>,
    /// A barrier ends a sub-expansion (of a macro argument or an `#if` line): reading past it yields
    /// `Eof` instead of continuing into the enclosing streams.
    barrier: bool,
}

#[derive(Clone, Copy, Debug)]
struct Conditional {
    span: Span,
    /// The branch we are in is being compiled.
    active: bool,
    /// Some branch of this conditional has already been taken.
    taken: bool,
    /// The code around the conditional is being compiled.
    parent_active: bool,
    else_seen: bool,
}

/// What the preprocessor produces.
#[derive(Debug, Default)]
pub struct Output {
    pub tokens: Vec<Token>,
    /// Every file that was read, main file first (for dependency tracking and content hashes).
    pub files: Vec<FileId>,
    /// Expansion ran away and was stopped: the tokens are incomplete and not worth parsing.
    pub aborted: bool,
    /// Every macro call written in a file, in order: diagnostics inside one say which macro.
    pub expansions: Vec<Expansion>,
    /// The lines (file, 0-based line) of each `#pragma nolint`: warnings on the line after one are
    /// dropped.
    pub nolint: Vec<(FileId, usize)>,
}

/// A macro call written in a source file.
#[derive(Clone, Copy, Debug)]
pub struct Expansion {
    /// The call, from the macro's name to its closing `)`.
    pub call: Span,
    pub name: Symbol,
    /// The macro's name in its `#define`.
    pub definition: Span,
}

/// Preprocesses `main` into one token stream ending in `Eof`.
pub fn preprocess(
    buffer: Vec<Token>,
    main: FileId,
    sources: &mut SourceMap,
    interner: &mut Interner,
    headers: &mut HeaderCache,
    options: &Options,
    diags: &mut Diagnostics,
) -> Output {
    let mut pp = Preprocessor {
        sources,
        interner,
        headers,
        diags,
        options,
        macros: FxHashMap::default(),
        file_cache: FxHashMap::default(),
        pragma_once: FxHashSet::default(),
        files: Vec::new(),
        contexts: Vec::new(),
        pending: Vec::new(),
        conds: Vec::new(),
        produced: 0,
        aborted: false,
        expansions: Vec::new(),
        nolint: Vec::new(),
        end_span: Span::default(),
        isolated_depth: 0,
        read_files: Vec::new(),
        sym_defined: Symbol::default(),
        sym_va_args: Symbol::default(),
        sym_file: Symbol::default(),
        sym_line: Symbol::default(),
    };
    pp.sym_defined = pp.interner.intern("defined");
    pp.sym_va_args = pp.interner.intern("__VA_ARGS__");
    pp.sym_file = pp.interner.intern("__FILE__");
    pp.sym_line = pp.interner.intern("__LINE__");
    pp.predefine();
    let main_len = pp.sources.get(main).text.len() as u32;
    pp.end_span = Span::new(main, main_len, main_len);
    let tokens = pp.tokens_of(main);
    pp.read_files.push(main);
    // Room for the main file and about as much again from headers, so the stream rarely regrows;
    // a buffer reused from an earlier file usually has room already.
    let mut out = buffer;
    out.clear();
    out.reserve(tokens.len() * 2 + 64);
    pp.files.push(FileFrame { file: main, tokens, pos: 0, cond_base: 0 });
    loop {
        let t = pp.next_expanded();
        if t.kind == TokenKind::Eof {
            out.push(t);
            break;
        }
        match t.kind {
            TokenKind::ErrorChar => {
                pp.error(Code::InvalidCharacter, t.span, "this character cannot start a token", "unexpected character")
            }
            TokenKind::ErrorString => pp.error(
                Code::UnterminatedString,
                t.span,
                "this string literal has no closing `\"`",
                "string starts here",
            ),
            TokenKind::ErrorComment => {
                pp.error(Code::UnterminatedComment, t.span, "this comment has no closing `*/`", "comment starts here")
            }
            _ => out.push(t),
        }
    }
    Output { tokens: out, files: pp.read_files, aborted: pp.aborted, expansions: pp.expansions, nolint: pp.nolint }
}

struct Preprocessor<'a> {
    sources: &'a mut SourceMap,
    interner: &'a mut Interner,
    headers: &'a mut HeaderCache,
    diags: &'a mut Diagnostics,
    options: &'a Options,
    macros: FxHashMap<Symbol, Rc<Macro>>,
    file_cache: FxHashMap<PathBuf, (FileId, Rc<[Token]>)>,
    pragma_once: FxHashSet<FileId>,
    files: Vec<FileFrame>,
    contexts: Vec<Context>,
    /// Tokens pushed back after looking ahead for a macro call's `(`.
    pending: Vec<Token>,
    conds: Vec<Conditional>,
    produced: usize,
    aborted: bool,
    expansions: Vec<Expansion>,
    nolint: Vec<(FileId, usize)>,
    /// The end of the main file, where a premature end of input is reported.
    end_span: Span,
    isolated_depth: usize,
    read_files: Vec<FileId>,
    sym_defined: Symbol,
    sym_va_args: Symbol,
    sym_file: Symbol,
    sym_line: Symbol,
}

impl Preprocessor<'_> {
    fn error(&mut self, code: Code, span: Span, message: impl Into<String>, label: &str) {
        self.diags.push(Diagnostic::new(code, span, message).with_label(label));
    }

    fn predefine(&mut self) {
        let mut text = String::new();
        text.push_str("#define RTSL 1\n");
        text.push_str(&format!("#define RTSL_VERSION {}\n", version_number()));
        for (name, value) in &self.options.defines {
            let value = value.as_deref().unwrap_or("1");
            text.push_str(&format!("#define {name} {value}\n"));
        }
        for name in &self.options.undefines {
            text.push_str(&format!("#undef {name}\n"));
        }
        let file = self.sources.add_virtual("<command line>", text);
        let tokens: Rc<[Token]> = lex::lex(file, &self.sources.get(file).text.clone(), self.interner).into();
        self.files.push(FileFrame { file, tokens, pos: 0, cond_base: 0 });
        while self.next_file_token().kind != TokenKind::Eof {}
        self.files.clear();
    }

    fn tokens_of(&mut self, file: FileId) -> Rc<[Token]> {
        let text = self.sources.get(file).text.clone();
        lex::lex(file, &text, self.interner).into()
    }

    fn active(&self) -> bool {
        self.conds.last().is_none_or(|c| c.active)
    }

    // ---- Reading tokens -------------------------------------------------------------------------

    /// The next token with macros expanded.
    fn next_expanded(&mut self) -> Token {
        loop {
            let t = self.next_unexpanded();
            if t.kind != TokenKind::Ident || t.flags & NO_EXPAND != 0 || self.aborted {
                return t;
            }
            if t.sym == self.sym_file || t.sym == self.sym_line {
                return self.builtin_macro(t);
            }
            let Some(m) = self.macros.get(&t.sym) else {
                return t;
            };
            if self.is_disabled(t.sym) {
                let mut t = t;
                t.flags |= NO_EXPAND;
                return t;
            }
            let m = m.clone();
            // Only expansions written in a file (not produced by another expansion) are recorded.
            let outermost = self.contexts.is_empty();
            if !m.function_like {
                if outermost {
                    self.expansions.push(Expansion { call: t.span, name: t.sym, definition: m.def_span });
                }
                let body = self.substitute(&m, &[], t.span, t.flags);
                self.push_context(body, Some(t.sym));
                continue;
            }
            let next = self.next_unexpanded();
            if next.kind != TokenKind::LParen {
                self.pending.push(next);
                return t;
            }
            match self.collect_args(&m, t) {
                Some((args, close)) => {
                    let call = t.span.to(close);
                    if outermost {
                        self.expansions.push(Expansion { call, name: t.sym, definition: m.def_span });
                    }
                    let body = self.substitute(&m, &args, call, t.flags);
                    self.push_context(body, Some(t.sym));
                }
                None => return self.eof_token(),
            }
        }
    }

    fn builtin_macro(&mut self, t: Token) -> Token {
        let loc = self.sources.location(t.span);
        let (kind, text) = if t.sym == self.sym_file {
            (TokenKind::String, loc.file.to_string())
        } else {
            (TokenKind::Number, loc.line.to_string())
        };
        Token { kind, sym: self.interner.intern(&text), ..t }
    }

    fn is_disabled(&self, sym: Symbol) -> bool {
        self.contexts.iter().any(|c| c.disabled == Some(sym))
    }

    fn push_context(&mut self, tokens: Vec<Token>, disabled: Option<Symbol>) {
        self.produced += tokens.len();
        if self.produced > MAX_EXPANDED_TOKENS || self.contexts.len() > MAX_EXPANSION_DEPTH {
            if !self.aborted {
                let span = tokens.first().map(|t| t.span).unwrap_or_default();
                self.error(
                    Code::MacroRecursionLimit,
                    span,
                    "macro expansion does not terminate (too many tokens produced)",
                    "expanding this",
                );
            }
            self.aborted = true;
            return;
        }
        self.contexts.push(Context { tokens, pos: 0, disabled, barrier: false });
    }

    fn eof_token(&self) -> Token {
        Token { kind: TokenKind::Eof, sym: Symbol::default(), span: self.end_span, flags: LINE_START }
    }

    /// The next token before macro expansion: pushed-back tokens, then macro contexts, then files.
    fn next_unexpanded(&mut self) -> Token {
        if let Some(t) = self.pending.pop() {
            return t;
        }
        while let Some(ctx) = self.contexts.last_mut() {
            if ctx.pos < ctx.tokens.len() {
                let t = ctx.tokens[ctx.pos];
                ctx.pos += 1;
                return t;
            }
            if ctx.barrier {
                return self.eof_token();
            }
            self.contexts.pop();
        }
        if self.aborted {
            return self.eof_token();
        }
        self.next_file_token()
    }

    /// The next token of the current file that is in compiled code, running directives as they come
    /// and leaving finished included files.
    fn next_file_token(&mut self) -> Token {
        loop {
            let Some(frame) = self.files.last_mut() else {
                return self.eof_token();
            };
            let t = frame.tokens[frame.pos];
            if t.kind == TokenKind::Eof {
                let cond_base = frame.cond_base;
                while self.conds.len() > cond_base {
                    if let Some(c) = self.conds.pop() {
                        self.error(
                            Code::UnterminatedConditional,
                            c.span,
                            "this conditional has no `#endif` before the end of its file; it ends there",
                            "opened here",
                        );
                    }
                }
                if self.files.len() == 1 {
                    return t;
                }
                self.files.pop();
                continue;
            }
            frame.pos += 1;
            if t.kind == TokenKind::Hash && t.line_start() {
                let (tokens, line) = self.directive_line();
                self.directive(t, &tokens[line]);
                continue;
            }
            if self.active() {
                return t;
            }
        }
    }

    /// The rest of the current directive's line (the tokens after `#`): the file's tokens (shared,
    /// not copied) and the line's range in them.
    fn directive_line(&mut self) -> (Rc<[Token]>, std::ops::Range<usize>) {
        let Some(frame) = self.files.last_mut() else {
            return (Rc::from([]), 0..0);
        };
        let start = frame.pos;
        while !frame.tokens[frame.pos].line_start() {
            frame.pos += 1;
        }
        (frame.tokens.clone(), start..frame.pos)
    }

    // ---- Directives -----------------------------------------------------------------------------

    fn directive(&mut self, hash: Token, line: &[Token]) {
        let Some(first) = line.first() else {
            return; // The null directive.
        };
        // The directive's name as a static string ("" when unknown), without allocating.
        const DIRECTIVES: &[&str] = &[
            "if",
            "ifdef",
            "ifndef",
            "elif",
            "else",
            "endif",
            "define",
            "undef",
            "include",
            "include_next",
            "import",
            "error",
            "warning",
            "pragma",
            "line",
            "ident",
            "sccs",
        ];
        let name: &'static str = match first.kind {
            TokenKind::Ident => {
                let text = self.interner.resolve(first.sym);
                DIRECTIVES.iter().find(|d| **d == text).copied().unwrap_or("")
            }
            TokenKind::Number => "line",
            _ => "",
        };
        let rest = &line[1..];
        let span = hash.span.to(first.span);
        match name {
            "if" => {
                let value = if self.active() { self.eval_if(span, rest) } else { false };
                self.push_cond(span, value);
            }
            "ifdef" | "ifndef" => {
                let value = if self.active() {
                    match rest.first() {
                        Some(t) if t.kind == TokenKind::Ident => {
                            if rest.len() > 1 {
                                self.extra_tokens(name, rest[1].span);
                            }
                            self.macros.contains_key(&t.sym) == (name == "ifdef")
                        }
                        _ => {
                            self.error(
                                Code::MalformedDirective,
                                span,
                                format!("`#{name}` needs a macro name"),
                                "no name after this",
                            );
                            false
                        }
                    }
                } else {
                    false
                };
                self.push_cond(span, value);
            }
            "elif" => {
                let Some(c) = self.conds.last().copied() else {
                    self.error(
                        Code::StrayConditional,
                        span,
                        "`#elif` without a matching `#if`",
                        "no `#if` is open here",
                    );
                    return;
                };
                if c.else_seen {
                    self.error(Code::StrayConditional, span, "`#elif` after `#else`", "this `#elif`");
                }
                let value = if c.parent_active && !c.taken { self.eval_if(span, rest) } else { false };
                if let Some(c) = self.conds.last_mut() {
                    c.active = c.parent_active && !c.taken && value;
                    c.taken |= c.active;
                }
            }
            "else" => {
                let Some(c) = self.conds.last_mut() else {
                    self.error(
                        Code::StrayConditional,
                        span,
                        "`#else` without a matching `#if`",
                        "no `#if` is open here",
                    );
                    return;
                };
                let repeated = c.else_seen;
                c.active = c.parent_active && !c.taken;
                c.taken = true;
                c.else_seen = true;
                if repeated {
                    self.error(Code::StrayConditional, span, "a second `#else` for the same `#if`", "this `#else`");
                }
            }
            "endif" => {
                let base = self.files.last().map(|f| f.cond_base).unwrap_or(0);
                if self.conds.len() <= base {
                    self.error(
                        Code::StrayConditional,
                        span,
                        "`#endif` without a matching `#if`",
                        "no `#if` is open here",
                    );
                } else {
                    self.conds.pop();
                }
            }
            _ if !self.active() => {}
            "define" => self.define(span, rest),
            "undef" => match rest.first() {
                Some(t) if t.kind == TokenKind::Ident => {
                    self.macros.remove(&t.sym);
                }
                _ => self.error(Code::MalformedDirective, span, "`#undef` needs a macro name", "no name after this"),
            },
            "include" | "include_next" | "import" => self.include(span, rest),
            "error" => {
                let text = self.line_text(rest);
                self.error(Code::ErrorDirective, span, format!("#error {text}"), "reached here");
            }
            "warning" => {
                let text = self.line_text(rest);
                self.diags.push(
                    Diagnostic::new(Code::WarningDirective, span, format!("#warning {text}"))
                        .with_label("reached here"),
                );
            }
            "pragma" => {
                let pragma = rest.first().map(|t| self.interner.resolve(t.sym).to_string()).unwrap_or_default();
                if pragma == "once" {
                    if let Some(f) = self.files.last() {
                        self.pragma_once.insert(f.file);
                    }
                } else if pragma == "nolint" {
                    // The lint pragma of RenderMan shader compilers (Advanced RenderMan's shaders
                    // put it before a line a lint would question): quiet the next line.
                    let line = self.sources.get(span.file).line_index(span.start);
                    self.nolint.push((span.file, line));
                } else {
                    self.diags.push(
                        Diagnostic::new(Code::UnknownDirective, span, format!("unknown pragma `{pragma}` is ignored"))
                            .with_label("ignored"),
                    );
                }
            }
            "line" | "ident" | "sccs" => {}
            _ => {
                let shown = if name.is_empty() { self.describe(first) } else { name.to_string() };
                self.diags.push(
                    Diagnostic::new(
                        Code::UnknownDirective,
                        span,
                        format!("unknown preprocessor directive `#{shown}` is ignored"),
                    )
                    .with_label("not a directive"),
                );
            }
        }
    }

    fn extra_tokens(&mut self, directive: &str, span: Span) {
        self.diags.push(
            Diagnostic::new(Code::UnknownDirective, span, format!("extra tokens after `#{directive}` are ignored"))
                .with_label("ignored"),
        );
    }

    fn push_cond(&mut self, span: Span, value: bool) {
        let parent_active = self.active();
        self.conds.push(Conditional {
            span,
            active: parent_active && value,
            taken: parent_active && value,
            parent_active,
            else_seen: false,
        });
    }

    fn describe(&self, t: &Token) -> String {
        match t.kind {
            TokenKind::Ident | TokenKind::Number => self.interner.resolve(t.sym).to_string(),
            TokenKind::String => format!("\"{}\"", lex::escape(self.interner.resolve(t.sym))),
            k => k.spelling().to_string(),
        }
    }

    /// The source text of a directive's remaining tokens, as written.
    fn line_text(&self, rest: &[Token]) -> String {
        match (rest.first(), rest.last()) {
            (Some(a), Some(b)) if a.span.file == b.span.file => {
                self.sources.text(Span::new(a.span.file, a.span.start, b.span.end)).to_string()
            }
            _ => String::new(),
        }
    }

    fn define(&mut self, span: Span, rest: &[Token]) {
        let Some(name) = rest.first().filter(|t| t.kind == TokenKind::Ident) else {
            self.error(Code::MalformedDirective, span, "`#define` needs a macro name", "no name after this");
            return;
        };
        if name.sym == self.sym_defined {
            self.error(Code::MalformedDirective, name.span, "`defined` cannot be a macro name", "reserved");
            return;
        }
        let mut params = Vec::new();
        let mut variadic = false;
        let mut i = 1;
        let function_like = rest.get(1).is_some_and(|t| t.kind == TokenKind::LParen && !t.space_before());
        if function_like {
            i = 2;
            loop {
                let Some(t) = rest.get(i) else {
                    self.error(
                        Code::MalformedDirective,
                        name.span,
                        "unterminated parameter list in `#define`",
                        "macro defined here",
                    );
                    return;
                };
                match t.kind {
                    TokenKind::RParen if params.is_empty() && !variadic => {
                        i += 1;
                        break;
                    }
                    TokenKind::Ident => {
                        if params.contains(&t.sym) {
                            self.error(Code::MalformedDirective, t.span, "duplicate macro parameter", "repeated here");
                            return;
                        }
                        params.push(t.sym);
                        i += 1;
                    }
                    TokenKind::Dot
                        if rest.get(i + 1).is_some_and(|t| t.kind == TokenKind::Dot)
                            && rest.get(i + 2).is_some_and(|t| t.kind == TokenKind::Dot) =>
                    {
                        variadic = true;
                        params.push(self.sym_va_args);
                        i += 3;
                    }
                    _ => {
                        self.error(
                            Code::MalformedDirective,
                            t.span,
                            "expected a parameter name in `#define`",
                            "not a parameter name",
                        );
                        return;
                    }
                }
                match rest.get(i).map(|t| t.kind) {
                    Some(TokenKind::Comma) if !variadic => i += 1,
                    Some(TokenKind::RParen) => {
                        i += 1;
                        break;
                    }
                    _ => {
                        let at = rest.get(i).map(|t| t.span).unwrap_or(name.span);
                        self.error(
                            Code::MalformedDirective,
                            at,
                            "expected `,` or `)` in the macro's parameter list",
                            "here",
                        );
                        return;
                    }
                }
            }
        }
        let body: Rc<[Token]> = rest[i..].to_vec().into();
        if let Some(first) = body.first() {
            if first.kind == TokenKind::HashHash {
                self.error(
                    Code::MalformedDirective,
                    first.span,
                    "`##` cannot start a macro body",
                    "nothing to paste onto",
                );
                return;
            }
        }
        if let Some(last) = body.last() {
            if last.kind == TokenKind::HashHash {
                self.error(Code::MalformedDirective, last.span, "`##` cannot end a macro body", "nothing to paste");
                return;
            }
        }
        let m = Macro { def_span: name.span, function_like, params, variadic, body };
        if let Some(old) = self.macros.get(&name.sym) {
            if !old.same_definition(&m) {
                let old_span = old.def_span;
                let text = self.interner.resolve(name.sym).to_string();
                self.diags.push(
                    Diagnostic::new(
                        Code::MacroRedefined,
                        name.span,
                        format!("macro `{text}` redefined with a different body"),
                    )
                    .with_label("redefined here")
                    .with_secondary(old_span, "previous definition"),
                );
            }
        }
        self.macros.insert(name.sym, Rc::new(m));
    }

    fn include(&mut self, span: Span, rest: &[Token]) {
        // `#include MACRO` expands the line first.
        let expanded;
        let rest = if rest.first().is_some_and(|t| t.kind == TokenKind::Ident) {
            expanded = self.expand_isolated(rest.to_vec());
            &expanded[..]
        } else {
            rest
        };
        let (name, angled) = match rest.first().map(|t| t.kind) {
            Some(TokenKind::String) => (self.interner.resolve(rest[0].sym).to_string(), false),
            Some(TokenKind::Lt) => match rest.iter().position(|t| t.kind == TokenKind::Gt) {
                Some(close) if close > 1 && rest[0].span.file == rest[close].span.file => {
                    let s = Span::new(rest[0].span.file, rest[0].span.end, rest[close].span.start);
                    (self.sources.text(s).trim().to_string(), true)
                }
                _ => {
                    self.error(
                        Code::MalformedDirective,
                        span,
                        "`#include <` needs a file name and a closing `>`",
                        "incomplete",
                    );
                    return;
                }
            },
            _ => {
                self.error(
                    Code::MalformedDirective,
                    span,
                    "`#include` needs a file name in quotes or angle brackets",
                    "no file name",
                );
                return;
            }
        };
        if self.files.len() >= MAX_INCLUDE_DEPTH {
            self.error(
                Code::IncludeDepth,
                span,
                format!("`#include \"{name}\"` nests more than {MAX_INCLUDE_DEPTH} files deep"),
                "included here",
            );
            return;
        }
        let resolved = self.resolve_include(&name, angled);
        if resolved.is_none() {
            if let Some(text) = standard_headers::standard_header(&name) {
                self.include_standard(&name, text);
                return;
            }
        }
        let Some(path) = resolved else {
            let mut d = Diagnostic::new(Code::IncludeNotFound, span, format!("cannot find include file `{name}`"))
                .with_label("included here");
            let searched = self.search_dirs(angled);
            if searched.is_empty() {
                d = d.with_note("no include directories were given; add one with `-I DIR`");
            } else {
                let list: Vec<String> = searched.iter().map(|p| p.display().to_string()).collect();
                d = d.with_note(format!("searched: {}", list.join(", ")));
            }
            self.diags.push(d);
            return;
        };
        // Keyed by the path as resolved (not canonicalised: that costs several system calls, and a
        // header reached by two spellings is merely lexed twice).
        self.enter_header(path.clone(), |pp| pp.load_header(&path, span));
    }

    /// Enters a standard header (see [`standard_headers`]).
    fn include_standard(&mut self, name: &str, text: &'static str) {
        let label = standard_headers::label(name);
        self.enter_header(PathBuf::from(&label), |pp| {
            let file = pp.sources.add_virtual(label, text);
            Some((file, pp.tokens_of(file)))
        });
    }

    /// Enters the header cached under `key`, or the one `load` registers (lexed once per
    /// compilation), unless `#pragma once` has already seen it.
    fn enter_header(&mut self, key: PathBuf, load: impl FnOnce(&mut Self) -> Option<(FileId, Rc<[Token]>)>) {
        let (file, tokens) = match self.file_cache.get(&key) {
            Some((file, tokens)) => (*file, tokens.clone()),
            None => {
                let Some((file, tokens)) = load(self) else { return };
                self.read_files.push(file);
                self.file_cache.insert(key, (file, tokens.clone()));
                (file, tokens)
            }
        };
        if self.pragma_once.contains(&file) {
            return;
        }
        self.files.push(FileFrame { file, tokens, pos: 0, cond_base: self.conds.len() });
    }

    /// Registers a header in this compilation's source map, from the session's cache or from disk.
    fn load_header(&mut self, path: &Path, span: Span) -> Option<(FileId, Rc<[Token]>)> {
        if let Some(h) = self.headers.headers.get(path) {
            let file = self.sources.add_shared(
                path.display().to_string(),
                Some(path.to_path_buf()),
                h.text.clone(),
                h.lines.clone(),
            );
            let tokens: Rc<[Token]> = h.tokens.iter().map(|t| Token { span: Span { file, ..t.span }, ..*t }).collect();
            return Some((file, tokens));
        }
        let file = match self.sources.load(path) {
            Ok(f) => f,
            Err(e) => {
                self.error(
                    Code::IncludeNotFound,
                    span,
                    format!("cannot read include file `{}`: {e}", path.display()),
                    "included here",
                );
                return None;
            }
        };
        let tokens = self.tokens_of(file);
        let src = self.sources.get(file);
        self.headers.headers.insert(
            path.to_path_buf(),
            CachedHeader { text: src.text.clone(), lines: src.line_starts().clone(), tokens: tokens.to_vec() },
        );
        Some((file, tokens))
    }

    fn search_dirs(&self, angled: bool) -> Vec<PathBuf> {
        let mut dirs = Vec::new();
        let current = self
            .files
            .last()
            .and_then(|f| self.sources.get(f.file).path.as_ref())
            .and_then(|p| p.parent())
            .map(Path::to_path_buf);
        if !angled {
            dirs.extend(current.clone());
        }
        dirs.extend(self.options.include_paths.iter().cloned());
        if angled {
            // Lenient: many shader collections include their own headers with `<...>`.
            dirs.extend(current);
        }
        dirs
    }

    fn resolve_include(&mut self, name: &str, angled: bool) -> Option<PathBuf> {
        let direct = Path::new(name);
        if direct.is_absolute() {
            return direct.is_file().then(|| direct.to_path_buf());
        }
        let dir = self
            .files
            .last()
            .and_then(|f| self.sources.get(f.file).path.as_ref())
            .and_then(|p| p.parent())
            .map(Path::to_path_buf);
        let key = (dir, name.to_string(), angled);
        if let Some(found) = self.headers.resolved.get(&key) {
            return found.clone();
        }
        let found = self.search_dirs(angled).into_iter().map(|d| d.join(name)).find(|p| p.is_file());
        self.headers.resolved.insert(key, found.clone());
        found
    }

    // ---- #if ------------------------------------------------------------------------------------

    fn eval_if(&mut self, span: Span, rest: &[Token]) -> bool {
        if rest.is_empty() {
            self.error(Code::BadIfExpression, span, "`#if` needs an expression", "nothing to evaluate");
            return false;
        }
        // `defined X` and `defined(X)` are replaced before macro expansion.
        let mut replaced = Vec::with_capacity(rest.len());
        let mut i = 0;
        while i < rest.len() {
            let t = rest[i];
            if t.kind == TokenKind::Ident && t.sym == self.sym_defined {
                let (name, next) = match (rest.get(i + 1), rest.get(i + 2), rest.get(i + 3)) {
                    (Some(n), _, _) if n.kind == TokenKind::Ident => (Some(*n), i + 2),
                    (Some(l), Some(n), Some(r))
                        if l.kind == TokenKind::LParen && n.kind == TokenKind::Ident && r.kind == TokenKind::RParen =>
                    {
                        (Some(*n), i + 4)
                    }
                    _ => (None, i + 1),
                };
                let Some(name) = name else {
                    self.error(Code::BadIfExpression, t.span, "`defined` needs a macro name", "here");
                    return false;
                };
                let value = if self.macros.contains_key(&name.sym) { "1" } else { "0" };
                replaced.push(Token { kind: TokenKind::Number, sym: self.interner.intern(value), ..t });
                i = next;
            } else {
                replaced.push(t);
                i += 1;
            }
        }
        let expanded = self.expand_isolated(replaced);
        match expr::evaluate(&expanded, self.interner) {
            Ok(v) => v != 0,
            Err((at, msg)) => {
                let at = at.unwrap_or(span);
                self.error(Code::BadIfExpression, at, format!("invalid `#if` expression: {msg}"), "here");
                false
            }
        }
    }

    // ---- Macro expansion ------------------------------------------------------------------------

    /// Fully expands a token list on its own, without reading past it.
    fn expand_isolated(&mut self, tokens: Vec<Token>) -> Vec<Token> {
        if self.isolated_depth >= MAX_ARGUMENT_NESTING {
            if !self.aborted {
                let span = tokens.first().map(|t| t.span).unwrap_or_default();
                self.error(Code::MacroRecursionLimit, span, "macro calls nest too deeply in arguments", "nested here");
            }
            self.aborted = true;
            return Vec::new();
        }
        self.isolated_depth += 1;
        let out = self.expand_isolated_inner(tokens);
        self.isolated_depth -= 1;
        out
    }

    fn expand_isolated_inner(&mut self, tokens: Vec<Token>) -> Vec<Token> {
        let saved_pending = std::mem::take(&mut self.pending);
        self.contexts.push(Context { tokens, pos: 0, disabled: None, barrier: true });
        let depth = self.contexts.len();
        let mut out = Vec::new();
        loop {
            let t = self.next_expanded();
            if t.kind == TokenKind::Eof {
                break;
            }
            out.push(t);
        }
        // The barrier context is the one at `depth`; contexts above it are exhausted expansions.
        self.contexts.truncate(depth.saturating_sub(1));
        self.pending = saved_pending;
        out
    }

    /// Reads a macro call's arguments after its `(`. Returns the raw argument token lists and the
    /// span of the closing `)`, or `None` (with a diagnostic) when the input ends first.
    fn collect_args(&mut self, m: &Macro, name: Token) -> Option<(Vec<Vec<Token>>, Span)> {
        let mut args: Vec<Vec<Token>> = vec![Vec::new()];
        let mut depth = 0usize;
        let close = loop {
            let t = self.next_unexpanded();
            match t.kind {
                TokenKind::Eof => {
                    let text = self.interner.resolve(name.sym).to_string();
                    self.error(
                        Code::UnterminatedMacroCall,
                        name.span,
                        format!("the call of macro `{text}` has no closing `)`"),
                        "macro call starts here",
                    );
                    if self.contexts.last().is_some_and(|c| c.barrier) {
                        return None;
                    }
                    self.pending.push(t);
                    return None;
                }
                TokenKind::LParen => depth += 1,
                TokenKind::RParen if depth == 0 => break t.span,
                TokenKind::RParen => depth -= 1,
                TokenKind::Comma if depth == 0 && !(m.variadic && args.len() == m.params.len()) => {
                    args.push(Vec::new());
                    continue;
                }
                _ => {}
            }
            if let Some(last) = args.last_mut() {
                last.push(t);
            }
        };
        // `F()` passes one empty argument, which is right for a one-parameter macro and means no
        // arguments for a macro without parameters.
        if m.params.is_empty() && args.len() == 1 && args[0].is_empty() {
            args.clear();
        }
        if m.variadic && args.len() == m.params.len() - 1 {
            args.push(Vec::new());
        }
        if args.len() != m.params.len() {
            let text = self.interner.resolve(name.sym).to_string();
            let d = Diagnostic::new(
                Code::MacroArgCount,
                name.span.to(close),
                format!(
                    "macro `{text}` takes {} argument{} but {} were given",
                    m.params.len(),
                    plural(m.params.len()),
                    args.len()
                ),
            )
            .with_label("in this macro call")
            .with_secondary(m.def_span, "macro defined here");
            self.diags.push(d);
            // Go on with missing arguments empty and extra ones dropped.
            args.resize(m.params.len(), Vec::new());
        }
        Some((args, close))
    }

    /// The macro's body with arguments substituted, `#` and `##` applied, and spans set to the call.
    fn substitute(&mut self, m: &Macro, args: &[Vec<Token>], call: Span, call_flags: u8) -> Vec<Token> {
        let body = m.body.clone();
        let param_index = |sym: Symbol| m.params.iter().position(|&p| p == sym);
        let mut expanded_args: Vec<Option<Vec<Token>>> = vec![None; args.len()];
        let mut out: Vec<Token> = Vec::with_capacity(body.len());
        // Positions in `out` where a `##` must join the token before with the one after.
        let mut pastes: Vec<usize> = Vec::new();
        let mut i = 0;
        while i < body.len() {
            let t = body[i];
            let mut from_body = t;
            from_body.span = call;
            from_body.flags &= SPACE_BEFORE;
            match t.kind {
                TokenKind::Hash if m.function_like => {
                    if let Some(idx) =
                        body.get(i + 1).filter(|n| n.kind == TokenKind::Ident).and_then(|n| param_index(n.sym))
                    {
                        let text = self.stringify(&args[idx]);
                        out.push(Token { kind: TokenKind::String, sym: self.interner.intern(&text), ..from_body });
                        i += 2;
                        continue;
                    }
                    out.push(from_body);
                }
                TokenKind::HashHash => {
                    pastes.push(out.len());
                }
                TokenKind::Ident if m.function_like && param_index(t.sym).is_some() => {
                    let idx = param_index(t.sym).unwrap_or(0);
                    let next_is_paste = body.get(i + 1).is_some_and(|n| n.kind == TokenKind::HashHash);
                    let prev_is_paste = i > 0 && body[i - 1].kind == TokenKind::HashHash;
                    let start = out.len();
                    if next_is_paste || prev_is_paste {
                        out.extend_from_slice(&args[idx]);
                    } else {
                        if expanded_args[idx].is_none() {
                            expanded_args[idx] = Some(self.expand_isolated(args[idx].clone()));
                        }
                        out.extend_from_slice(expanded_args[idx].as_deref().unwrap_or(&[]));
                    }
                    if let Some(first) = out.get_mut(start) {
                        first.flags = (first.flags & !SPACE_BEFORE) | (t.flags & SPACE_BEFORE);
                    }
                    if out.len() == start && (next_is_paste || prev_is_paste) {
                        // An empty argument next to `##` is a placemarker: pasting with it is a no-op.
                        pastes.retain(|&p| p != start);
                    }
                }
                _ => out.push(from_body),
            }
            i += 1;
        }
        if !pastes.is_empty() {
            out = self.paste_all(out, &pastes, call);
        }
        if let Some(first) = out.first_mut() {
            first.flags = (first.flags & !SPACE_BEFORE) | (call_flags & SPACE_BEFORE);
        }
        out
    }

    fn paste_all(&mut self, tokens: Vec<Token>, pastes: &[usize], call: Span) -> Vec<Token> {
        let mut out: Vec<Token> = Vec::with_capacity(tokens.len());
        for (idx, t) in tokens.into_iter().enumerate() {
            if idx > 0 && pastes.contains(&idx) {
                if let Some(prev) = out.pop() {
                    let joined = format!("{}{}", self.spell(&prev), self.spell(&t));
                    match self.relex_one(&joined, call) {
                        Some(mut tok) => {
                            tok.flags = prev.flags & SPACE_BEFORE;
                            out.push(tok);
                        }
                        None => {
                            self.diags.push(
                                Diagnostic::new(
                                    Code::MalformedDirective,
                                    call,
                                    format!(
                                        "pasting `{}` and `{}` does not give a valid token",
                                        self.spell(&prev),
                                        self.spell(&t)
                                    ),
                                )
                                .with_label("in this macro expansion"),
                            );
                            out.push(prev);
                            out.push(t);
                        }
                    }
                    continue;
                }
            }
            out.push(t);
        }
        out
    }

    fn spell(&self, t: &Token) -> String {
        match t.kind {
            TokenKind::Ident | TokenKind::Number => self.interner.resolve(t.sym).to_string(),
            TokenKind::String => format!("\"{}\"", lex::escape(self.interner.resolve(t.sym))),
            k => k.spelling().to_string(),
        }
    }

    /// Lexes `text`, which must be exactly one token, giving it `span`.
    fn relex_one(&mut self, text: &str, span: Span) -> Option<Token> {
        let toks = lex::lex(span.file, text, self.interner);
        if toks.len() != 2
            || matches!(toks[0].kind, TokenKind::ErrorChar | TokenKind::ErrorString | TokenKind::ErrorComment)
        {
            return None;
        }
        Some(Token { span, flags: 0, ..toks[0] })
    }

    fn stringify(&self, tokens: &[Token]) -> String {
        let mut s = String::new();
        for (i, t) in tokens.iter().enumerate() {
            if i > 0 && t.space_before() {
                s.push(' ');
            }
            s.push_str(&self.spell(t));
        }
        s
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

#[cfg(test)]
mod tests;

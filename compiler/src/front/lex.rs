//! The lexer (logos): source text to tokens with spans.
//!
//! Words are all lexed as [`TokenKind::Ident`] (keywords are told apart after preprocessing, see
//! [`crate::symbol`]). Comments and whitespace are dropped, but each token records whether it starts a
//! line (for preprocessor directives) and whether space preceded it (for `#` stringification). A
//! backslash before a newline joins lines. The lexer never fails: bad input becomes an error token that
//! the preprocessor reports only if it lies in code that is not excluded by `#if`.

use crate::source::{FileId, Span};
use crate::symbol::{Interner, Symbol};
use logos::Logos;

fn block_comment(lex: &mut logos::Lexer<RawToken>) -> bool {
    match lex.remainder().find("*/") {
        Some(end) => {
            lex.bump(end + 2);
            true
        }
        None => {
            lex.bump(lex.remainder().len());
            false
        }
    }
}

/// The raw token kinds logos recognises.
#[derive(Logos, Clone, Copy, Debug, PartialEq, Eq)]
#[logos(skip r"[ \t\r\n\x0c\x0b]+")]
#[logos(skip r"\\\r?\n")]
#[logos(skip(r"//[^\n]*", allow_greedy = true))]
enum RawToken {
    #[token("/*", block_comment)]
    BlockComment(bool),
    #[regex(r"[A-Za-z_][A-Za-z0-9_]*")]
    Ident,
    #[regex(r"[0-9]+(\.[0-9]*)?([eE][+-]?[0-9]+)?[fF]?")]
    #[regex(r"\.[0-9]+([eE][+-]?[0-9]+)?[fF]?")]
    #[regex(r"0[xX][0-9a-fA-F]+")]
    Number,
    #[regex(r#""([^"\\\n]|\\(.|\n))*""#)]
    String,
    #[regex(r#""([^"\\\n]|\\(.|\n))*"#)]
    UnterminatedString,
    #[token("'")]
    #[regex(r"'([^'\\\n]|\\.)*'")]
    CharLiteral,
    #[token("(")]
    LParen,
    #[token(")")]
    RParen,
    #[token("{")]
    LBrace,
    #[token("}")]
    RBrace,
    #[token("[")]
    LBracket,
    #[token("]")]
    RBracket,
    #[token(";")]
    Semi,
    #[token(",")]
    Comma,
    #[token(".")]
    Dot,
    #[token("?")]
    Question,
    #[token(":")]
    Colon,
    #[token("+")]
    Plus,
    #[token("-")]
    Minus,
    #[token("*")]
    Star,
    #[token("/")]
    Slash,
    #[token("%")]
    Percent,
    #[token("^")]
    Caret,
    #[token("!")]
    Bang,
    #[token("~")]
    Tilde,
    #[token("&")]
    Amp,
    #[token("|")]
    Pipe,
    #[token("<")]
    Lt,
    #[token(">")]
    Gt,
    #[token("<=")]
    Le,
    #[token(">=")]
    Ge,
    #[token("==")]
    EqEq,
    #[token("!=")]
    Ne,
    #[token("&&")]
    AndAnd,
    #[token("||")]
    OrOr,
    #[token("<<")]
    Shl,
    #[token(">>")]
    Shr,
    #[token("=")]
    Assign,
    #[token("+=")]
    PlusAssign,
    #[token("-=")]
    MinusAssign,
    #[token("*=")]
    StarAssign,
    #[token("/=")]
    SlashAssign,
    #[token("++")]
    PlusPlus,
    #[token("--")]
    MinusMinus,
    #[token("#")]
    Hash,
    #[token("##")]
    HashHash,
}

/// Token kinds after lexing. Keywords are still `Ident` here.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TokenKind {
    Ident,
    Number,
    String,
    LParen,
    RParen,
    LBrace,
    RBrace,
    LBracket,
    RBracket,
    Semi,
    Comma,
    Dot,
    Question,
    Colon,
    Plus,
    Minus,
    Star,
    Slash,
    Percent,
    Caret,
    Bang,
    Tilde,
    Amp,
    Pipe,
    Lt,
    Gt,
    Le,
    Ge,
    EqEq,
    Ne,
    AndAnd,
    OrOr,
    Shl,
    Shr,
    Assign,
    PlusAssign,
    MinusAssign,
    StarAssign,
    SlashAssign,
    PlusPlus,
    MinusMinus,
    Hash,
    HashHash,
    /// A character that starts no token.
    ErrorChar,
    /// A string literal missing its closing quote.
    ErrorString,
    /// A `/*` comment missing its `*/`.
    ErrorComment,
    /// The end of the token stream.
    Eof,
}

impl TokenKind {
    /// How the token is spelled in source, for stringification and messages.
    pub fn spelling(self) -> &'static str {
        use TokenKind::*;
        match self {
            Ident => "identifier",
            Number => "number",
            String => "string",
            LParen => "(",
            RParen => ")",
            LBrace => "{",
            RBrace => "}",
            LBracket => "[",
            RBracket => "]",
            Semi => ";",
            Comma => ",",
            Dot => ".",
            Question => "?",
            Colon => ":",
            Plus => "+",
            Minus => "-",
            Star => "*",
            Slash => "/",
            Percent => "%",
            Caret => "^",
            Bang => "!",
            Tilde => "~",
            Amp => "&",
            Pipe => "|",
            Lt => "<",
            Gt => ">",
            Le => "<=",
            Ge => ">=",
            EqEq => "==",
            Ne => "!=",
            AndAnd => "&&",
            OrOr => "||",
            Shl => "<<",
            Shr => ">>",
            Assign => "=",
            PlusAssign => "+=",
            MinusAssign => "-=",
            StarAssign => "*=",
            SlashAssign => "/=",
            PlusPlus => "++",
            MinusMinus => "--",
            Hash => "#",
            HashHash => "##",
            ErrorChar => "invalid character",
            ErrorString => "unterminated string",
            ErrorComment => "unterminated comment",
            Eof => "end of file",
        }
    }
}

/// The token is the first on its (logical) line.
pub const LINE_START: u8 = 1;
/// Whitespace or a comment preceded the token.
pub const SPACE_BEFORE: u8 = 2;
/// The token is an identifier that must not be macro-expanded again (C's "painted blue" tokens).
pub const NO_EXPAND: u8 = 4;

/// A token with its text and origin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Token {
    pub kind: TokenKind,
    /// The identifier, the number's spelling, or the string's value (escapes resolved).
    pub sym: Symbol,
    /// Where the token's text is. For tokens produced by a macro body, where the outermost macro
    /// call is, so that spans of a construct stay inside one file and in order.
    pub span: Span,
    pub flags: u8,
}

impl Token {
    pub fn line_start(&self) -> bool {
        self.flags & LINE_START != 0
    }

    pub fn space_before(&self) -> bool {
        self.flags & SPACE_BEFORE != 0
    }
}

/// Resolves the escapes of a string literal's body (without its quotes).
pub fn unescape(body: &str) -> String {
    let mut out = String::with_capacity(body.len());
    let mut chars = body.chars();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match chars.next() {
            Some('n') => out.push('\n'),
            Some('t') => out.push('\t'),
            Some('r') => out.push('\r'),
            Some('a') => out.push('\x07'),
            Some('b') => out.push('\x08'),
            Some('f') => out.push('\x0c'),
            Some('v') => out.push('\x0b'),
            Some('\n') => {}
            Some(other) => out.push(other),
            None => out.push('\\'),
        }
    }
    out
}

/// Escapes a string value so that it reads back as the same literal (for `#` stringification and
/// printed IR).
pub fn escape(value: &str) -> String {
    let mut out = String::with_capacity(value.len() + 2);
    for c in value.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c => out.push(c),
        }
    }
    out
}

/// Lexes a whole file. The result ends with an `Eof` token whose span is the end of the file.
pub fn lex(file: FileId, text: &str, interner: &mut Interner) -> Vec<Token> {
    let mut tokens = Vec::with_capacity(text.len() / 4);
    let mut lexer = RawToken::lexer(text);
    let mut prev_end = 0usize;
    let mut at_line_start = true;
    let mut comment_between = false;
    while let Some(result) = lexer.next() {
        let range = lexer.span();
        let gap = &text[prev_end..range.start];
        let (newline, space) = scan_gap(gap);
        at_line_start |= newline;
        let space = space || comment_between;
        prev_end = range.end;
        let span = Span::new(file, range.start as u32, range.end as u32);
        let slice = lexer.slice();
        let mut flags = 0u8;
        if at_line_start {
            flags |= LINE_START;
        }
        if space {
            flags |= SPACE_BEFORE;
        }
        let (kind, sym) = match result {
            Ok(RawToken::BlockComment(true)) => {
                comment_between = true;
                continue;
            }
            Ok(raw) => raw_kind(raw, slice, interner),
            Err(()) => (TokenKind::ErrorChar, Symbol::default()),
        };
        comment_between = false;
        at_line_start = false;
        tokens.push(Token { kind, sym, span, flags });
    }
    let end = text.len() as u32;
    tokens.push(Token {
        kind: TokenKind::Eof,
        sym: Symbol::default(),
        span: Span::new(file, end, end),
        flags: LINE_START,
    });
    tokens
}

fn raw_kind(raw: RawToken, slice: &str, interner: &mut Interner) -> (TokenKind, Symbol) {
    use TokenKind as K;
    let none = Symbol::default();
    match raw {
        RawToken::BlockComment(_) => (K::ErrorComment, none),
        RawToken::Ident => (K::Ident, interner.intern(slice)),
        RawToken::Number => (K::Number, interner.intern(slice)),
        RawToken::String => {
            let body = &slice[1..slice.len() - 1];
            let sym = if body.contains('\\') { interner.intern(&unescape(body)) } else { interner.intern(body) };
            (K::String, sym)
        }
        RawToken::UnterminatedString => (K::ErrorString, none),
        RawToken::CharLiteral => (K::ErrorChar, none),
        RawToken::LParen => (K::LParen, none),
        RawToken::RParen => (K::RParen, none),
        RawToken::LBrace => (K::LBrace, none),
        RawToken::RBrace => (K::RBrace, none),
        RawToken::LBracket => (K::LBracket, none),
        RawToken::RBracket => (K::RBracket, none),
        RawToken::Semi => (K::Semi, none),
        RawToken::Comma => (K::Comma, none),
        RawToken::Dot => (K::Dot, none),
        RawToken::Question => (K::Question, none),
        RawToken::Colon => (K::Colon, none),
        RawToken::Plus => (K::Plus, none),
        RawToken::Minus => (K::Minus, none),
        RawToken::Star => (K::Star, none),
        RawToken::Slash => (K::Slash, none),
        RawToken::Percent => (K::Percent, none),
        RawToken::Caret => (K::Caret, none),
        RawToken::Bang => (K::Bang, none),
        RawToken::Tilde => (K::Tilde, none),
        RawToken::Amp => (K::Amp, none),
        RawToken::Pipe => (K::Pipe, none),
        RawToken::Lt => (K::Lt, none),
        RawToken::Gt => (K::Gt, none),
        RawToken::Le => (K::Le, none),
        RawToken::Ge => (K::Ge, none),
        RawToken::EqEq => (K::EqEq, none),
        RawToken::Ne => (K::Ne, none),
        RawToken::AndAnd => (K::AndAnd, none),
        RawToken::OrOr => (K::OrOr, none),
        RawToken::Shl => (K::Shl, none),
        RawToken::Shr => (K::Shr, none),
        RawToken::Assign => (K::Assign, none),
        RawToken::PlusAssign => (K::PlusAssign, none),
        RawToken::MinusAssign => (K::MinusAssign, none),
        RawToken::StarAssign => (K::StarAssign, none),
        RawToken::SlashAssign => (K::SlashAssign, none),
        RawToken::PlusPlus => (K::PlusPlus, none),
        RawToken::MinusMinus => (K::MinusMinus, none),
        RawToken::Hash => (K::Hash, none),
        RawToken::HashHash => (K::HashHash, none),
    }
}

/// Looks at the skipped text between two tokens: did it contain a line break (not one escaped by a
/// backslash), and any space at all?
fn scan_gap(gap: &str) -> (bool, bool) {
    if gap.is_empty() {
        return (false, false);
    }
    let bytes = gap.as_bytes();
    let mut newline = false;
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\\' => {
                // A line continuation: skip the (optional CR and) LF.
                i += 1;
                if i < bytes.len() && bytes[i] == b'\r' {
                    i += 1;
                }
            }
            b'\n' => newline = true,
            b'/' if i + 1 < bytes.len() && bytes[i + 1] == b'/' => {
                // A line comment runs to the newline, which the next iteration sees.
                i = memchr::memchr(b'\n', &bytes[i..]).map_or(bytes.len(), |k| i + k);
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    (newline, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(src: &str) -> Vec<TokenKind> {
        let mut i = Interner::new();
        lex(FileId(0), src, &mut i).iter().map(|t| t.kind).collect()
    }

    #[test]
    fn numbers_and_dot_operator() {
        use TokenKind::*;
        assert_eq!(kinds("a.b .5 1. 2e3 P.N"), vec![Ident, Dot, Ident, Number, Number, Number, Ident, Dot, Ident, Eof]);
    }

    #[test]
    fn line_starts_ignore_escaped_newlines_and_comments() {
        let mut i = Interner::new();
        let toks = lex(FileId(0), "#define A \\\n 1 /* x\n y */ 2\nb // c\n c", &mut i);
        let starts: Vec<bool> = toks.iter().map(|t| t.line_start()).collect();
        // # define A 1 2 b c eof
        assert_eq!(starts, vec![true, false, false, false, false, true, true, true]);
    }

    #[test]
    fn strings_unescape_and_errors_are_tokens() {
        let mut i = Interner::new();
        let toks = lex(FileId(0), "\"a\\\"b\" \"open\n@", &mut i);
        assert_eq!(toks[0].kind, TokenKind::String);
        assert_eq!(i.resolve(toks[0].sym), "a\"b");
        assert_eq!(toks[1].kind, TokenKind::ErrorString);
        assert_eq!(toks[2].kind, TokenKind::ErrorChar);
    }

    #[test]
    fn unterminated_comment_is_an_error_token() {
        assert_eq!(kinds("a /* b"), vec![TokenKind::Ident, TokenKind::ErrorComment, TokenKind::Eof]);
    }
}

//! The VRML 97 lexer (ISO/IEC 14772-1, clause 5 and annex A): identifiers, numbers, strings and
//! the four brackets and the period, with `#` comments and commas read as white space.
//!
//! Identifiers follow the grammar's `IdFirstChar`/`IdRestChars`: any character but the control
//! characters, space, `"`, `#`, `'`, `,`, `.`, `[`, `\`, `]`, `{`, `}` and DEL, where the first may
//! not be a digit, `+` or `-`. Keywords (`DEF`, `USE`, `PROTO`, `TRUE`, ...) are identifiers; the
//! parser tells them apart. Numbers are decimal floats or integers, or hexadecimal integers
//! (`0xFF`, which `SFImage` pixels use).

use super::Loc;

/// What a token is.
#[derive(Clone, Debug, PartialEq)]
pub enum Tok {
    Ident(String),
    /// A number, and whether it was written as an integer (decimal or hexadecimal).
    Number(f64, bool),
    Str(String),
    LBracket,
    RBracket,
    LBrace,
    RBrace,
    Period,
}

/// A token and where it starts.
#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    pub tok: Tok,
    pub loc: Loc,
}

/// A lexical error: a character that starts no token, an unterminated string, a malformed number.
#[derive(Clone, Debug, PartialEq)]
pub struct LexError {
    pub loc: Loc,
    pub message: String,
}

/// Splits `text` into tokens (the `#VRML` header line is a comment like any other). Stops at the
/// first error.
pub fn tokenize(text: &str) -> Result<Vec<Token>, LexError> {
    let mut lexer = Lexer::new(text);
    let mut tokens = Vec::new();
    while let Some(token) = lexer.next_token()? {
        tokens.push(token);
    }
    Ok(tokens)
}

/// Tokens read one at a time (the parser pulls them, so a large file is never held as tokens).
pub struct Lexer<'a> {
    chars: std::iter::Peekable<std::str::CharIndices<'a>>,
    text: &'a str,
    line: u32,
    column: u32,
}

/// Whether `c` may appear in an identifier after its first character.
pub fn is_id_rest(c: char) -> bool {
    !(c <= ' ' || c == '\u{7f}' || matches!(c, '"' | '#' | '\'' | ',' | '.' | '[' | '\\' | ']' | '{' | '}'))
}

/// Whether `c` may start an identifier.
pub fn is_id_first(c: char) -> bool {
    is_id_rest(c) && !c.is_ascii_digit() && c != '+' && c != '-'
}

impl<'a> Lexer<'a> {
    pub fn new(text: &'a str) -> Lexer<'a> {
        Lexer { chars: text.char_indices().peekable(), text, line: 1, column: 1 }
    }

    /// Where the next token would start (after white space not yet skipped).
    pub fn loc(&self) -> Loc {
        Loc { line: self.line, column: self.column }
    }

    fn peek(&mut self) -> Option<char> {
        self.chars.peek().map(|&(_, c)| c)
    }

    fn bump(&mut self) -> Option<char> {
        let (_, c) = self.chars.next()?;
        if c == '\n' {
            self.line = self.line.saturating_add(1);
            self.column = 1;
        } else {
            self.column = self.column.saturating_add(1);
        }
        Some(c)
    }

    /// The byte offset of the next character (the text's length at its end).
    fn offset(&mut self) -> usize {
        let len = self.text.len();
        self.chars.peek().map_or(len, |&(i, _)| i)
    }

    /// The next token; `None` at the end of the text.
    pub fn next_token(&mut self) -> Result<Option<Token>, LexError> {
        // White space, commas and comments.
        loop {
            match self.peek() {
                Some(c) if c.is_whitespace() || c == ',' || c == '\u{feff}' => {
                    self.bump();
                }
                Some('#') => {
                    while self.peek().is_some_and(|c| c != '\n' && c != '\r') {
                        self.bump();
                    }
                }
                _ => break,
            }
        }
        let loc = self.loc();
        let Some(c) = self.peek() else { return Ok(None) };
        let simple = match c {
            '[' => Some(Tok::LBracket),
            ']' => Some(Tok::RBracket),
            '{' => Some(Tok::LBrace),
            '}' => Some(Tok::RBrace),
            _ => None,
        };
        if let Some(tok) = simple {
            self.bump();
            return Ok(Some(Token { tok, loc }));
        }
        let tok = if c == '"' {
            self.string(loc)?
        } else if c.is_ascii_digit() || c == '+' || c == '-' || c == '.' {
            self.number(loc)?
        } else if is_id_first(c) {
            let start = self.offset();
            while self.peek().is_some_and(is_id_rest) {
                self.bump();
            }
            let end = self.offset();
            Tok::Ident(self.text[start..end].to_string())
        } else {
            return Err(LexError { loc, message: format!("unexpected character {c:?}") });
        };
        Ok(Some(Token { tok, loc }))
    }

    fn string(&mut self, loc: Loc) -> Result<Tok, LexError> {
        self.bump();
        let mut s = String::new();
        loop {
            match self.bump() {
                None => return Err(LexError { loc, message: "string without its closing `\"`".into() }),
                Some('"') => return Ok(Tok::Str(s)),
                Some('\\') => match self.bump() {
                    Some(c) => s.push(c),
                    None => return Err(LexError { loc, message: "string without its closing `\"`".into() }),
                },
                Some(c) => s.push(c),
            }
        }
    }

    fn number(&mut self, loc: Loc) -> Result<Tok, LexError> {
        let start = self.offset();
        // A lone period (a ROUTE's `node.field`) is punctuation, not a number.
        if self.peek() == Some('.') {
            let mut ahead = self.chars.clone();
            ahead.next();
            if !ahead.peek().is_some_and(|&(_, c)| c.is_ascii_digit()) {
                self.bump();
                return Ok(Tok::Period);
            }
        }
        if matches!(self.peek(), Some('+' | '-')) {
            self.bump();
        }
        // Hexadecimal: 0x or 0X and hex digits.
        let rest = &self.text[self.offset()..];
        if rest.len() > 2 && (rest.starts_with("0x") || rest.starts_with("0X")) {
            self.bump();
            self.bump();
            let digits_start = self.offset();
            while self.peek().is_some_and(|c| c.is_ascii_hexdigit()) {
                self.bump();
            }
            let digits = &self.text[digits_start..self.offset()];
            let value = u64::from_str_radix(digits, 16)
                .map_err(|_| LexError { loc, message: format!("malformed hexadecimal number 0x{digits}") })?;
            let negative = self.text[start..].starts_with('-');
            let value = value as f64;
            return Ok(Tok::Number(if negative { -value } else { value }, true));
        }
        let mut integer = true;
        let mut digits = 0;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.bump();
            digits += 1;
        }
        if self.peek() == Some('.') {
            integer = false;
            self.bump();
            while self.peek().is_some_and(|c| c.is_ascii_digit()) {
                self.bump();
                digits += 1;
            }
        }
        if digits > 0 && matches!(self.peek(), Some('e' | 'E')) {
            let mut ahead = self.chars.clone();
            ahead.next();
            if ahead.peek().is_some_and(|&(_, c)| c == '+' || c == '-') {
                ahead.next();
            }
            if ahead.peek().is_some_and(|&(_, c)| c.is_ascii_digit()) {
                integer = false;
                self.bump();
                if matches!(self.peek(), Some('+' | '-')) {
                    self.bump();
                }
                while self.peek().is_some_and(|c| c.is_ascii_digit()) {
                    self.bump();
                }
            }
        }
        let text = &self.text[start..self.offset()];
        if digits == 0 {
            return Err(LexError { loc, message: format!("malformed number {text:?}") });
        }
        // A number runs into no identifier (`1abc`).
        if self.peek().is_some_and(|c| is_id_first(c) && !matches!(c, 'e' | 'E')) || self.peek() == Some('.') {
            let c = self.peek().unwrap_or(' ');
            return Err(LexError { loc, message: format!("malformed number: {text:?} followed by {c:?}") });
        }
        let value: f64 = text.parse().map_err(|_| LexError { loc, message: format!("malformed number {text:?}") })?;
        Ok(Tok::Number(value, integer))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn toks(text: &str) -> Vec<Tok> {
        tokenize(text).expect("lexes").into_iter().map(|t| t.tok).collect()
    }

    #[test]
    fn tokens_of_every_kind() {
        assert_eq!(
            toks("#VRML V2.0 utf8\nDEF a_1 Transform { translation 1, -2.5 +3e2 } # c\n[ \"s\\\"t\" 0xFF .5 ]"),
            vec![
                Tok::Ident("DEF".into()),
                Tok::Ident("a_1".into()),
                Tok::Ident("Transform".into()),
                Tok::LBrace,
                Tok::Ident("translation".into()),
                Tok::Number(1.0, true),
                Tok::Number(-2.5, false),
                Tok::Number(300.0, false),
                Tok::RBrace,
                Tok::LBracket,
                Tok::Str("s\"t".into()),
                Tok::Number(255.0, true),
                Tok::Number(0.5, false),
                Tok::RBracket,
            ]
        );
        // A ROUTE's node.field, identifiers with + and - inside.
        assert_eq!(
            toks("ROUTE T-1.fraction_changed TO I+2.set_fraction"),
            vec![
                Tok::Ident("ROUTE".into()),
                Tok::Ident("T-1".into()),
                Tok::Period,
                Tok::Ident("fraction_changed".into()),
                Tok::Ident("TO".into()),
                Tok::Ident("I+2".into()),
                Tok::Period,
                Tok::Ident("set_fraction".into()),
            ]
        );
    }

    #[test]
    fn locations_count_lines_and_characters() {
        let t = tokenize("a\n  é b\n\"x\ny\" c").expect("lexes");
        let locs: Vec<(u32, u32)> = t.iter().map(|t| (t.loc.line, t.loc.column)).collect();
        assert_eq!(locs, vec![(1, 1), (2, 3), (2, 5), (3, 1), (4, 4)]);
    }

    #[test]
    fn errors_name_where() {
        let e = tokenize("a\n  \"open").unwrap_err();
        assert_eq!((e.loc.line, e.loc.column), (2, 3));
        assert!(e.message.contains("closing"), "{}", e.message);
        let e = tokenize("1.2.3").unwrap_err();
        assert!(e.message.contains("malformed number"), "{}", e.message);
        let e = tokenize("x \\ y").unwrap_err();
        assert_eq!((e.loc.line, e.loc.column), (1, 3));
        assert!(tokenize("- x").is_err());
    }
}

//! The ASCII RIB tokenizer: request names, numbers, strings, `[` and `]`, with `#` comments
//! skipped.
//!
//! Invariants: tokenizing never fails and never panics, whatever the bytes. Text that is not a
//! token becomes one [`TokenKind::Error`] token (a run of bad bytes is one token, so binary RIB
//! or a stray byte does not flood the diagnostics). Every token carries the 1-based line and
//! column (in characters) of its first byte. Numbers are finite as `f32`.
//!
//! Hand-written rather than logos: string escapes, the error tokens and line/column tracking are
//! simpler to state directly than as a generated automaton with callbacks.

/// What a token is.
#[derive(Clone, Debug, PartialEq)]
pub enum TokenKind {
    /// A bare word: a request name such as `WorldBegin`.
    Name(String),
    /// A number (RIB does not distinguish integer and float literals syntactically).
    Number(f64),
    /// A string literal, escapes resolved.
    Str(String),
    /// `[`
    OpenBracket,
    /// `]`
    CloseBracket,
    /// Text that is not a token; the message says why.
    Error(String),
}

/// A token and where it starts.
#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    /// What it is.
    pub kind: TokenKind,
    /// 1-based line.
    pub line: u32,
    /// 1-based column, counted in characters.
    pub column: u32,
}

/// Splits RIB text into tokens.
pub fn tokenize(text: &[u8]) -> Vec<Token> {
    let mut lexer = Lexer { text, pos: 0, line: 1, column: 1 };
    let mut tokens = Vec::new();
    while let Some(token) = lexer.next_token() {
        tokens.push(token);
    }
    tokens
}

struct Lexer<'a> {
    text: &'a [u8],
    pos: usize,
    line: u32,
    column: u32,
}

fn is_name_start(b: u8) -> bool {
    b.is_ascii_alphabetic() || b == b'_'
}

fn is_name_continue(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

/// Bytes that can never start a token: anything other than whitespace, `#`, `"`, brackets,
/// names and numbers.
fn is_junk(b: u8) -> bool {
    !(b.is_ascii_whitespace()
        || matches!(b, b'#' | b'"' | b'[' | b']' | b'-' | b'+' | b'.')
        || b.is_ascii_digit()
        || is_name_start(b))
}

impl Lexer<'_> {
    fn peek(&self) -> Option<u8> {
        self.text.get(self.pos).copied()
    }

    fn peek_at(&self, offset: usize) -> Option<u8> {
        self.text.get(self.pos + offset).copied()
    }

    /// Advances one byte, keeping line and column (columns count characters: UTF-8
    /// continuation bytes do not advance the column).
    fn bump(&mut self) -> Option<u8> {
        let b = self.peek()?;
        self.pos += 1;
        if b == b'\n' {
            self.line = self.line.saturating_add(1);
            self.column = 1;
        } else if b & 0xC0 != 0x80 {
            self.column = self.column.saturating_add(1);
        }
        Some(b)
    }

    fn skip_trivia(&mut self) {
        while let Some(b) = self.peek() {
            if b.is_ascii_whitespace() {
                self.bump();
            } else if b == b'#' {
                // `#` and `##` (structural) comments both run to the end of the line.
                while let Some(b) = self.peek() {
                    if b == b'\n' {
                        break;
                    }
                    self.bump();
                }
            } else {
                break;
            }
        }
    }

    fn next_token(&mut self) -> Option<Token> {
        self.skip_trivia();
        let (line, column) = (self.line, self.column);
        let b = self.peek()?;
        let kind = match b {
            b'[' => {
                self.bump();
                TokenKind::OpenBracket
            }
            b']' => {
                self.bump();
                TokenKind::CloseBracket
            }
            b'"' => self.string(),
            b'-' | b'+' | b'.' | b'0'..=b'9' => self.number(),
            b if is_name_start(b) => {
                let start = self.pos;
                while self.peek().is_some_and(is_name_continue) {
                    self.bump();
                }
                TokenKind::Name(String::from_utf8_lossy(&self.text[start..self.pos]).into_owned())
            }
            _ => {
                while self.peek().is_some_and(is_junk) {
                    self.bump();
                }
                let message = if b.is_ascii_graphic() {
                    format!("unexpected character `{}`", b as char)
                } else {
                    // Bytes outside printable ASCII: binary RIB or a corrupt file.
                    format!("unexpected byte 0x{b:02x} (only ASCII RIB is read)")
                };
                TokenKind::Error(message)
            }
        };
        Some(Token { kind, line, column })
    }

    /// A string literal; the opening quote is next. A raw newline or the end of the file ends an
    /// unterminated string (as an error), so one missing quote does not swallow the file.
    fn string(&mut self) -> TokenKind {
        self.bump();
        let mut bytes = Vec::new();
        loop {
            match self.peek() {
                None | Some(b'\n') => return TokenKind::Error("unterminated string".into()),
                Some(b'"') => {
                    self.bump();
                    break;
                }
                Some(b'\\') => {
                    self.bump();
                    match self.peek() {
                        None => return TokenKind::Error("unterminated string".into()),
                        Some(d @ b'0'..=b'7') => {
                            let mut value = u32::from(d - b'0');
                            self.bump();
                            for _ in 0..2 {
                                match self.peek() {
                                    Some(d @ b'0'..=b'7') => {
                                        value = value * 8 + u32::from(d - b'0');
                                        self.bump();
                                    }
                                    _ => break,
                                }
                            }
                            bytes.push((value & 0xFF) as u8);
                        }
                        Some(b'\n') => {
                            // A backslash before a newline continues the string on the next line.
                            self.bump();
                        }
                        Some(c) => {
                            self.bump();
                            bytes.push(match c {
                                b'n' => b'\n',
                                b't' => b'\t',
                                b'r' => b'\r',
                                b'b' => 0x08,
                                b'f' => 0x0C,
                                // `\\`, `\"` and any other escaped character stand for themselves.
                                other => other,
                            });
                        }
                    }
                }
                Some(b) => {
                    self.bump();
                    bytes.push(b);
                }
            }
        }
        TokenKind::Str(String::from_utf8_lossy(&bytes).into_owned())
    }

    /// A number: `[+-]? digits* (. digits*)? ([eE] [+-]? digits+)?` with at least one digit.
    /// Letters or dots glued to it make the whole run one error (`12abc`, `1.2.3`).
    fn number(&mut self) -> TokenKind {
        let start = self.pos;
        if matches!(self.peek(), Some(b'-' | b'+')) {
            self.bump();
        }
        let mut digits = 0;
        while self.peek().is_some_and(|b| b.is_ascii_digit()) {
            self.bump();
            digits += 1;
        }
        if self.peek() == Some(b'.') {
            self.bump();
            while self.peek().is_some_and(|b| b.is_ascii_digit()) {
                self.bump();
                digits += 1;
            }
        }
        if digits > 0 && matches!(self.peek(), Some(b'e' | b'E')) {
            let sign = usize::from(matches!(self.peek_at(1), Some(b'-' | b'+')));
            if self.peek_at(1 + sign).is_some_and(|b| b.is_ascii_digit()) {
                for _ in 0..=sign {
                    self.bump();
                }
                while self.peek().is_some_and(|b| b.is_ascii_digit()) {
                    self.bump();
                }
            }
        }
        let glued = self.peek().is_some_and(|b| is_name_continue(b) || b == b'.');
        while self.peek().is_some_and(|b| is_name_continue(b) || b == b'.') {
            self.bump();
        }
        let text = String::from_utf8_lossy(&self.text[start..self.pos]);
        if digits == 0 || glued {
            return TokenKind::Error(format!("malformed number `{text}`"));
        }
        match text.parse::<f64>() {
            Ok(value) if (value as f32).is_finite() => TokenKind::Number(value),
            _ => TokenKind::Error(format!("number `{text}` is out of range")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(text: &str) -> Vec<TokenKind> {
        tokenize(text.as_bytes()).into_iter().map(|t| t.kind).collect()
    }

    #[test]
    fn names_numbers_strings_and_brackets() {
        use TokenKind::*;
        assert_eq!(
            kinds(r#"Sphere 1 -1 .5 360 [ 1e3 -2.5E-1 +3. ] "plastic""#),
            vec![
                Name("Sphere".into()),
                Number(1.0),
                Number(-1.0),
                Number(0.5),
                Number(360.0),
                OpenBracket,
                Number(1000.0),
                Number(-0.25),
                Number(3.0),
                CloseBracket,
                Str("plastic".into()),
            ]
        );
    }

    #[test]
    fn string_escapes() {
        assert_eq!(kinds(r#""a\nb\t\\\"\101\7z""#), vec![TokenKind::Str("a\nb\t\\\"A\u{7}z".into())]);
        assert_eq!(kinds("\"con\\\ntinued\""), vec![TokenKind::Str("continued".into())]);
    }

    #[test]
    fn comments_are_skipped_and_positions_tracked() {
        let tokens = tokenize(b"##RenderMan RIB\n# a comment\n  WorldBegin # trailing\n\tSphere");
        assert_eq!(tokens.len(), 2);
        assert_eq!((tokens[0].line, tokens[0].column), (3, 3));
        assert_eq!((tokens[1].line, tokens[1].column), (4, 2));
    }

    #[test]
    fn bad_input_becomes_error_tokens() {
        let k = kinds("12abc \"open\nNext @@@ - 1e999");
        assert!(matches!(&k[0], TokenKind::Error(m) if m.contains("malformed number `12abc`")));
        assert!(matches!(&k[1], TokenKind::Error(m) if m.contains("unterminated string")));
        assert_eq!(k[2], TokenKind::Name("Next".into()));
        assert!(matches!(&k[3], TokenKind::Error(m) if m.contains("`@`")));
        assert!(matches!(&k[4], TokenKind::Error(m) if m.contains("malformed number `-`")));
        assert!(matches!(&k[5], TokenKind::Error(m) if m.contains("out of range")));
        assert_eq!(k.len(), 6);
    }

    #[test]
    fn columns_count_characters() {
        let tokens = tokenize("\"é\" X".as_bytes());
        assert_eq!(tokens[1].column, 5);
    }
}

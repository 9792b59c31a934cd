//! The RIB tokenizer: request names, numbers, strings, `[` and `]`, with `#` comments skipped,
//! in ASCII and in the binary encoding of RISpec 3.2 appendix C.2, which may be mixed in one
//! stream (every byte from 0x80 up starts a binary token).
//!
//! Invariants: tokenizing never fails and never panics, whatever the bytes. Text that is not a
//! token becomes one [`TokenKind::Error`] token (a run of bad bytes is one token, so a stray byte
//! does not flood the diagnostics). Every token carries the 1-based line and column (in
//! characters) of its first byte; the bytes of a binary token's payload advance the column only,
//! never the line. Numbers are finite as `f32`. Binary tokens expand to no more than their input
//! allows: a float array's length is checked against the bytes left, and the text that encoded
//! string and request references expand to is bounded by [`MAX_ENCODED_EXPANSION`].
//!
//! Binary integers follow the writers that produce them (Aqsis's RIB writer, for one): 1 to 3
//! bytes are unsigned, 4 bytes are a two's-complement `int32`; fixed-point numbers are unsigned.
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

/// The most bytes of text that references to encoded strings and requests (binary RIB) may
/// expand to in one stream, beyond the stream's own length: a three-byte reference can name a
/// long string, and a file of references would otherwise ask for far more memory than it holds.
pub const MAX_ENCODED_EXPANSION: usize = 1 << 26;

/// The longest request name a binary stream may define (the longest RISpec name is 24 bytes).
const MAX_ENCODED_REQUEST_NAME: usize = 64;

/// Splits RIB text into tokens.
pub fn tokenize(text: &[u8]) -> Vec<Token> {
    tokens(text).collect()
}

/// The tokens of RIB text, read as they are asked for: a stream's tokens take several times its
/// bytes (40 bytes a token, a number often 5 to 10 bytes of text), so a reader that holds one
/// request's tokens at a time reads any stream in memory proportional to its largest request.
pub fn tokens(text: &[u8]) -> Tokens<'_> {
    Tokens(Lexer {
        text,
        pos: 0,
        line: 1,
        column: 1,
        requests: vec![None; 256],
        strings: std::collections::HashMap::new(),
        expansion_left: MAX_ENCODED_EXPANSION,
        floats_left: 0,
        array_open: false,
    })
}

/// The tokens of RIB text, in order ([`tokens`]).
pub struct Tokens<'a>(Lexer<'a>);

impl Iterator for Tokens<'_> {
    type Item = Token;

    fn next(&mut self) -> Option<Token> {
        self.0.next_token()
    }
}

struct Lexer<'a> {
    text: &'a [u8],
    pos: usize,
    line: u32,
    column: u32,
    /// Binary RIB: request names defined by `0314 code name`.
    requests: Vec<Option<String>>,
    /// Binary RIB: strings defined by `0315+w code string`.
    strings: std::collections::HashMap<u32, String>,
    /// Bytes that references to defined strings and requests may still expand to.
    expansion_left: usize,
    /// Elements of a binary float array (`0310+l`) still to read.
    floats_left: usize,
    /// Whether a binary float array's `]` is still to come (after `floats_left` elements).
    array_open: bool,
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
    b < 0x80
        && !(b.is_ascii_whitespace()
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
        if self.floats_left > 0 {
            self.floats_left -= 1;
            let (line, column) = (self.line, self.column);
            let kind = match self.binary_bytes(4) {
                Some(v) => finite(f64::from(f32::from_bits(v as u32))),
                None => TokenKind::Error("binary float array ends early".into()),
            };
            return Some(Token { kind, line, column });
        }
        if self.array_open {
            // A binary float array's `]` comes after its last element.
            self.array_open = false;
            return Some(Token { kind: TokenKind::CloseBracket, line: self.line, column: self.column });
        }
        self.skip_trivia();
        let (line, column) = (self.line, self.column);
        let b = self.peek()?;
        let kind = match b {
            0x80..=0xFF => match self.binary_token() {
                Some(kind) => kind,
                // A definition: it makes no token of its own.
                None => return self.next_token_after_definition(),
            },
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
                    format!("unexpected byte 0x{b:02x}")
                };
                TokenKind::Error(message)
            }
        };
        Some(Token { kind, line, column })
    }

    /// The token after a binary definition (`0314`, `0315`, `0316`), iteratively: a file of
    /// definitions must not recurse once per definition.
    fn next_token_after_definition(&mut self) -> Option<Token> {
        loop {
            self.skip_trivia();
            let (line, column) = (self.line, self.column);
            let b = self.peek()?;
            if b < 0x80 {
                return self.next_token();
            }
            if let Some(kind) = self.binary_token() {
                return Some(Token { kind, line, column });
            }
        }
    }

    /// `n` (1 to 8) payload bytes of a binary token, most significant first; `None` (and the rest of
    /// the input consumed) when fewer are left.
    fn binary_bytes(&mut self, n: usize) -> Option<u64> {
        let Some(bytes) = self.text.get(self.pos..self.pos + n) else {
            self.column = self.column.saturating_add((self.text.len() - self.pos) as u32);
            self.pos = self.text.len();
            return None;
        };
        self.pos += n;
        self.column = self.column.saturating_add(n as u32);
        Some(bytes.iter().fold(0u64, |v, &b| (v << 8) | u64::from(b)))
    }

    /// `n` payload bytes as text (binary strings carry no escapes).
    fn binary_text(&mut self, n: usize) -> Option<String> {
        let bytes = self.text.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        self.column = self.column.saturating_add(n as u32);
        Some(String::from_utf8_lossy(bytes).into_owned())
    }

    /// Expands a reference to defined text, within the stream's expansion budget.
    fn expand(&mut self, text: Option<String>, what: &str) -> TokenKind {
        match text {
            None => TokenKind::Error(format!("binary RIB refers to an undefined {what}")),
            Some(text) if text.len() > self.expansion_left => TokenKind::Error(format!(
                "binary RIB references expand to more than {MAX_ENCODED_EXPANSION} bytes of text"
            )),
            Some(text) => {
                self.expansion_left -= text.len();
                if what == "request" {
                    TokenKind::Name(text)
                } else {
                    TokenKind::Str(text)
                }
            }
        }
    }

    /// One binary token (RISpec 3.2 appendix C.2); its first byte, 0x80 or above, is next.
    /// `None` for a definition, which makes no token.
    fn binary_token(&mut self) -> Option<TokenKind> {
        let ends_early = || Some(TokenKind::Error("binary RIB ends inside a token".into()));
        let code = self.peek()?;
        self.pos += 1;
        self.column = self.column.saturating_add(1);
        let kind = match code {
            // Integers: 0200 + w, then w + 1 bytes.
            0x80..=0x83 => {
                let width = usize::from(code - 0x80) + 1;
                let Some(v) = self.binary_bytes(width) else { return ends_early() };
                let v = if width == 4 { f64::from(v as u32 as i32) } else { v as f64 };
                TokenKind::Number(v)
            }
            // Fixed point: 0200 + 4d + w, then w + 1 bytes with the radix point d bytes from the
            // right.
            0x84..=0x8F => {
                let width = usize::from(code & 3) + 1;
                let radix = u32::from((code >> 2) & 3);
                let Some(v) = self.binary_bytes(width) else { return ends_early() };
                TokenKind::Number(v as f64 / f64::from(1u32 << (8 * radix)))
            }
            // Short strings: 0220 + w, then w bytes.
            0x90..=0x9F => match self.binary_text(usize::from(code - 0x90)) {
                Some(text) => TokenKind::Str(text),
                None => return self.binary_end(),
            },
            // Strings: 0240 + l, an l + 1 byte length, the bytes.
            0xA0..=0xA3 => {
                let Some(len) = self.binary_bytes(usize::from(code - 0xA0) + 1) else { return ends_early() };
                match self.binary_text(len as usize) {
                    Some(text) => TokenKind::Str(text),
                    None => return self.binary_end(),
                }
            }
            0xA4 => match self.binary_bytes(4) {
                Some(v) => finite(f64::from(f32::from_bits(v as u32))),
                None => return ends_early(),
            },
            0xA5 => match self.binary_bytes(8) {
                Some(v) => finite(f64::from_bits(v)),
                None => return ends_early(),
            },
            // A request by its defined code: 0246, the code byte.
            0xA6 => {
                let Some(index) = self.binary_bytes(1) else { return ends_early() };
                let name = self.requests.get(index as usize).cloned().flatten();
                self.expand(name, "request")
            }
            // Float arrays: 0310 + l, an l + 1 byte count, that many IEEE floats.
            0xC8..=0xCB => {
                let Some(count) = self.binary_bytes(usize::from(code - 0xC8) + 1) else { return ends_early() };
                let count = count as usize;
                if count.saturating_mul(4) > self.text.len() - self.pos {
                    self.pos = self.text.len();
                    return Some(TokenKind::Error(format!(
                        "binary float array of {count} elements is longer than the rest of the file"
                    )));
                }
                self.floats_left = count;
                self.array_open = true;
                TokenKind::OpenBracket
            }
            // Request definition: 0314, the code byte, a string.
            0xCC => {
                let Some(index) = self.binary_bytes(1) else { return ends_early() };
                match self.definition_text() {
                    Ok(name) if !name.is_empty() && name.len() <= MAX_ENCODED_REQUEST_NAME => {
                        self.requests[index as usize] = Some(name);
                        return None;
                    }
                    Ok(_) => TokenKind::Error("binary RIB defines a request with an empty or overlong name".into()),
                    Err(kind) => kind,
                }
            }
            // String definition: 0315 + w, a w + 1 byte code, a string.
            0xCD | 0xCE => {
                let Some(index) = self.binary_bytes(usize::from(code - 0xCD) + 1) else { return ends_early() };
                match self.definition_text() {
                    Ok(text) => {
                        self.strings.insert(index as u32, text);
                        return None;
                    }
                    Err(kind) => kind,
                }
            }
            // A defined string: 0317 + w, a w + 1 byte code.
            0xCF | 0xD0 => {
                let Some(index) = self.binary_bytes(usize::from(code - 0xCF) + 1) else { return ends_early() };
                let text = self.strings.get(&(index as u32)).cloned();
                self.expand(text, "string")
            }
            // 0377 ends a RunProgram's output; in a file it is the end.
            0xFF => {
                self.pos = self.text.len();
                return None;
            }
            reserved => TokenKind::Error(format!("reserved binary RIB byte 0x{reserved:02x}")),
        };
        Some(kind)
    }

    /// The string operand of a binary definition: a binary or ASCII string token.
    fn definition_text(&mut self) -> Result<String, TokenKind> {
        self.skip_trivia();
        let token = match self.peek() {
            Some(b'"') => self.string(),
            Some(0x90..=0xA3) => self.binary_token().unwrap_or(TokenKind::Error(String::new())),
            _ => TokenKind::Error(String::new()),
        };
        match token {
            TokenKind::Str(text) => Ok(text),
            TokenKind::Error(m) if !m.is_empty() => Err(TokenKind::Error(m)),
            _ => Err(TokenKind::Error("a binary RIB definition is missing its string".into())),
        }
    }

    /// The error for a binary token whose payload runs past the end of the input.
    fn binary_end(&mut self) -> Option<TokenKind> {
        self.pos = self.text.len();
        Some(TokenKind::Error("binary RIB ends inside a token".into()))
    }

    /// A string literal; the opening quote is next. A string may span lines, as Aqsis's and
    /// PRMan's readers take it (a procedural's argument text, say). One that the file ends inside
    /// is an error, and reading goes on after the line it began on, so that one missing quote
    /// does not swallow the file.
    fn string(&mut self) -> TokenKind {
        self.bump();
        let mut bytes = Vec::new();
        let mut first_line_end = None;
        loop {
            match self.peek() {
                None => {
                    if let Some((pos, line, column)) = first_line_end {
                        (self.pos, self.line, self.column) = (pos, line, column);
                    }
                    return TokenKind::Error("unterminated string".into());
                }
                Some(b'\n') if first_line_end.is_none() => {
                    first_line_end = Some((self.pos, self.line, self.column));
                    self.bump();
                    bytes.push(b'\n');
                }
                Some(b'"') => {
                    self.bump();
                    break;
                }
                Some(b'\\') => {
                    self.bump();
                    match self.peek() {
                        None => continue,
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

/// A decoded binary float, refused when it is not finite as `f32`.
fn finite(value: f64) -> TokenKind {
    if (value as f32).is_finite() {
        TokenKind::Number(value)
    } else {
        TokenKind::Error(format!("binary number {value} is out of range"))
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

    /// Strings may span lines, as Aqsis reads them; one the file ends inside is an error, and
    /// reading goes on after the line it began on.
    #[test]
    fn strings_span_lines_and_an_unclosed_one_ends_at_its_line() {
        let k = kinds("Procedural \"DynamicLoad\" [\"menger\" \"4 -1 1\n\n  Other patterns to try:\n\"] [0 1]");
        assert_eq!(k[4], TokenKind::Str("4 -1 1\n\n  Other patterns to try:\n".into()));
        assert_eq!((&k[5], &k[6], k.len()), (&TokenKind::CloseBracket, &TokenKind::OpenBracket, 10), "{k:?}");
        let k = kinds("Surface \"open\nSphere 1 -1 1 360\nWorldEnd\n");
        assert!(matches!(&k[1], TokenKind::Error(m) if m.contains("unterminated string")), "{k:?}");
        assert_eq!(k[2], TokenKind::Name("Sphere".into()));
        assert_eq!(k.last(), Some(&TokenKind::Name("WorldEnd".into())));
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

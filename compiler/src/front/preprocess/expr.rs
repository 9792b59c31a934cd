//! Integer expressions of `#if` and `#elif`, evaluated as C does (64-bit signed arithmetic).
//!
//! The tokens arrive with macros expanded and `defined` already replaced. Identifiers left over are
//! undefined macros and count as `0`.

use crate::front::lex::{Token, TokenKind};
use crate::source::Span;
use crate::symbol::Interner;

type Error = (Option<Span>, String);

/// How deeply parentheses, unary operators and `?:` may nest. The evaluator recurses once per
/// level, so without a bound a long enough line overflows the stack; the bound is the checker's
/// for shader expressions, far beyond what a real header writes.
pub const MAX_DEPTH: u32 = 400;

pub fn evaluate(tokens: &[Token], interner: &Interner) -> Result<i64, Error> {
    let mut p = Parser { tokens, pos: 0, interner, depth: 0 };
    let v = p.ternary()?;
    match p.peek() {
        None => Ok(v),
        Some(t) => Err((Some(t.span), format!("unexpected `{}`", spell(t, interner)))),
    }
}

fn spell(t: &Token, interner: &Interner) -> String {
    match t.kind {
        TokenKind::Ident | TokenKind::Number => interner.resolve(t.sym).to_string(),
        TokenKind::String => format!("\"{}\"", interner.resolve(t.sym)),
        k => k.spelling().to_string(),
    }
}

struct Parser<'a> {
    tokens: &'a [Token],
    pos: usize,
    interner: &'a Interner,
    depth: u32,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.pos)
    }

    fn eat(&mut self, kind: TokenKind) -> bool {
        if self.peek().is_some_and(|t| t.kind == kind) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    fn end_error(&self) -> Error {
        (self.tokens.last().map(|t| t.span), "the expression ends too early".to_string())
    }

    /// Runs `f` one nesting level deeper, refusing at `MAX_DEPTH` with the span of the token that
    /// would have gone too deep.
    fn nested(&mut self, f: impl FnOnce(&mut Self) -> Result<i64, Error>) -> Result<i64, Error> {
        if self.depth >= MAX_DEPTH {
            let at = self.peek().or(self.tokens.last()).map(|t| t.span);
            return Err((at, format!("the expression nests more than {MAX_DEPTH} levels deep")));
        }
        self.depth += 1;
        let v = f(self);
        self.depth -= 1;
        v
    }

    fn ternary(&mut self) -> Result<i64, Error> {
        let cond = self.binary(0)?;
        if self.eat(TokenKind::Question) {
            let a = self.nested(Self::ternary)?;
            if !self.eat(TokenKind::Colon) {
                return Err(match self.peek() {
                    Some(t) => (Some(t.span), "expected `:`".to_string()),
                    None => self.end_error(),
                });
            }
            let b = self.nested(Self::ternary)?;
            return Ok(if cond != 0 { a } else { b });
        }
        Ok(cond)
    }

    fn binary(&mut self, min_prec: u8) -> Result<i64, Error> {
        let mut lhs = self.unary()?;
        while let Some(t) = self.peek() {
            let Some(prec) = precedence(t.kind) else { break };
            if prec < min_prec {
                break;
            }
            let op = *t;
            self.pos += 1;
            let rhs = self.binary(prec + 1)?;
            lhs = apply(op, lhs, rhs)?;
        }
        Ok(lhs)
    }

    fn unary(&mut self) -> Result<i64, Error> {
        self.nested(Self::unary_inner)
    }

    fn unary_inner(&mut self) -> Result<i64, Error> {
        let Some(t) = self.peek().copied() else {
            return Err(self.end_error());
        };
        self.pos += 1;
        match t.kind {
            TokenKind::Minus => Ok(self.unary()?.wrapping_neg()),
            TokenKind::Plus => self.unary(),
            TokenKind::Bang => Ok((self.unary()? == 0) as i64),
            TokenKind::Tilde => Ok(!self.unary()?),
            TokenKind::LParen => {
                let v = self.ternary()?;
                if !self.eat(TokenKind::RParen) {
                    return Err(match self.peek() {
                        Some(t) => (Some(t.span), "expected `)`".to_string()),
                        None => self.end_error(),
                    });
                }
                Ok(v)
            }
            TokenKind::Number => parse_int(self.interner.resolve(t.sym))
                .ok_or_else(|| (Some(t.span), format!("`{}` is not an integer", self.interner.resolve(t.sym)))),
            TokenKind::Ident => Ok(0),
            _ => Err((Some(t.span), format!("unexpected `{}`", spell(&t, self.interner)))),
        }
    }
}

fn precedence(kind: TokenKind) -> Option<u8> {
    use TokenKind::*;
    Some(match kind {
        OrOr => 1,
        AndAnd => 2,
        Pipe => 3,
        Caret => 4,
        Amp => 5,
        EqEq | Ne => 6,
        Lt | Gt | Le | Ge => 7,
        Shl | Shr => 8,
        Plus | Minus => 9,
        Star | Slash | Percent => 10,
        _ => return None,
    })
}

fn apply(op: Token, a: i64, b: i64) -> Result<i64, Error> {
    use TokenKind::*;
    Ok(match op.kind {
        OrOr => ((a != 0) || (b != 0)) as i64,
        AndAnd => ((a != 0) && (b != 0)) as i64,
        Pipe => a | b,
        Caret => a ^ b,
        Amp => a & b,
        EqEq => (a == b) as i64,
        Ne => (a != b) as i64,
        Lt => (a < b) as i64,
        Gt => (a > b) as i64,
        Le => (a <= b) as i64,
        Ge => (a >= b) as i64,
        Shl => a.wrapping_shl((b & 63) as u32),
        Shr => a.wrapping_shr((b & 63) as u32),
        Plus => a.wrapping_add(b),
        Minus => a.wrapping_sub(b),
        Star => a.wrapping_mul(b),
        Slash | Percent if b == 0 => return Err((Some(op.span), "division by zero".to_string())),
        Slash => a.wrapping_div(b),
        Percent => a.wrapping_rem(b),
        _ => return Err((Some(op.span), "not an operator".to_string())),
    })
}

fn parse_int(s: &str) -> Option<i64> {
    let s = s.trim_end_matches(['u', 'U', 'l', 'L']);
    if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        return i64::from_str_radix(hex, 16).ok();
    }
    if s.len() > 1 && s.starts_with('0') && s.bytes().all(|b| b.is_ascii_digit()) {
        return i64::from_str_radix(&s[1..], 8).ok();
    }
    s.parse().ok()
}

//! The parser: preprocessed tokens to an [`ast::TranslationUnit`].
//!
//! The grammar (`grammar.lalrpop`) is LR(1) and generated at build time by lalrpop. Tokens are fed by
//! index, so grammar locations are token indices; [`span_of`] turns a range of them into a source span.
//! Adjacent string literals are joined here, before parsing, as C does.
//!
//! Syntax errors are recovered at statement and definition boundaries, so the result is always a
//! tree (with `Error` nodes where parsing failed) plus every syntax error found.

pub mod ast;

use crate::diagnostic::{Code, Diagnostic, Diagnostics};
use crate::front::lex::{Token, TokenKind};
use crate::source::Span;
use crate::symbol::{Interner, Symbol, KEYWORDS};
use lalrpop_util::{lalrpop_mod, ParseError};

lalrpop_mod!(
    #[allow(clippy::all, clippy::pedantic, unused_parens, unused_imports, dead_code)]
    grammar,
    "/front/parse/grammar.rs"
);

/// The parser's terminals.
///
/// Deliberately not `Copy`, and with an (empty) `Drop`: lalrpop pops a terminal off its symbol stack
/// with `match stack.pop() { Some((l, Variant(tok), r)) => ..., _ => mismatch }`. For a payload
/// without drop glue, rustc does not count the binding as a move, so it drops the whole stack symbol
/// afterwards through the symbol type's out-of-line drop glue: a call for every terminal parsed. A payload that needs dropping is moved out, and
/// nothing is left to drop. For the same reason the grammar takes identifiers, numbers and strings
/// as whole tokens (`"ident" => Tok::Ident(_)`) rather than their `Copy` payloads.
#[derive(Clone, Debug, PartialEq)]
pub enum Tok {
    Ident(Symbol),
    Number(f64),
    Str(Symbol),
    Float,
    Color,
    Point,
    Vector,
    Normal,
    Matrix,
    StringKw,
    Void,
    Uniform,
    Varying,
    Output,
    Extern,
    If,
    Else,
    While,
    For,
    Break,
    Continue,
    Return,
    Illuminance,
    Illuminate,
    Solar,
    Gather,
    Surface,
    Light,
    Displacement,
    Volume,
    Imager,
    Pixel,
    Camera,
    Lightfield,
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
    Caret,
    Bang,
    Lt,
    Gt,
    Le,
    Ge,
    EqEq,
    Ne,
    AndAnd,
    OrOr,
    Assign,
    PlusAssign,
    MinusAssign,
    StarAssign,
    SlashAssign,
    PlusPlus,
    MinusMinus,
    /// A token that the preprocessor accepts but the language does not (`%`, `&`, `#`, ...).
    Other,
}

impl Tok {
    /// The symbol of an identifier or string literal; the grammar asks only those tokens.
    pub fn symbol(&self) -> Symbol {
        match self {
            Tok::Ident(s) | Tok::Str(s) => *s,
            _ => Symbol::default(),
        }
    }

    /// The value of a number; the grammar asks only number tokens.
    pub fn number(&self) -> f64 {
        match self {
            Tok::Number(n) => *n,
            _ => 0.0,
        }
    }
}

impl Drop for Tok {
    // See the type's documentation: having drop glue is the point.
    fn drop(&mut self) {}
}

/// Keyword tokens in the order of [`KEYWORDS`].
const KEYWORD_TOKENS: [Tok; 31] = [
    Tok::Float,
    Tok::Color,
    Tok::Point,
    Tok::Vector,
    Tok::Normal,
    Tok::Matrix,
    Tok::StringKw,
    Tok::Void,
    Tok::Uniform,
    Tok::Varying,
    Tok::Output,
    Tok::Extern,
    Tok::If,
    Tok::Else,
    Tok::While,
    Tok::For,
    Tok::Break,
    Tok::Continue,
    Tok::Return,
    Tok::Illuminance,
    Tok::Illuminate,
    Tok::Solar,
    Tok::Gather,
    Tok::Surface,
    Tok::Light,
    Tok::Displacement,
    Tok::Volume,
    Tok::Imager,
    Tok::Pixel,
    Tok::Camera,
    Tok::Lightfield,
];

/// The symbol of a keyword (keywords are interned first, in order).
pub fn keyword_symbol(word: &str) -> Symbol {
    Symbol(KEYWORDS.iter().position(|k| *k == word).unwrap_or(0) as u32)
}

/// The span covering tokens `l..r` (an empty range points at token `l`).
pub fn span_of(spans: &[Span], l: u32, r: u32) -> Span {
    let (l, r) = (l as usize, r as usize);
    let last = spans.len().saturating_sub(1);
    let first = spans[l.min(last)];
    if r > l {
        first.to(spans[(r - 1).min(last)])
    } else {
        Span::new(first.file, first.start, first.start)
    }
}

/// How tightly a binary operator binds: `||` loosest, then `&&`, equality, relations, `+ -`, `^`
/// (cross), `* /`, and `.` (dot) tightest. All are left-associative.
pub fn precedence(op: ast::BinaryOp) -> u8 {
    use ast::BinaryOp::*;
    match op {
        Or => 1,
        And => 2,
        Eq | Ne => 3,
        Lt | Gt | Le | Ge => 4,
        Add | Sub => 5,
        Cross => 6,
        Mul | Div => 7,
        Dot => 8,
    }
}

/// Groups a chain `first op1 e1 op2 e2 ...` by precedence (operator-precedence parsing).
///
/// The operator stack holds strictly rising precedences, so it never holds more than one operator
/// per level: both stacks fit in fixed arrays and a chain allocates nothing but its nodes.
pub fn climb<'a>(
    arena: &'a bumpalo::Bump,
    first: ast::Expr<'a>,
    rest: ArenaVec<'a, (ast::BinaryOp, ast::Expr<'a>)>,
) -> ast::Expr<'a> {
    const LEVELS: usize = 8;
    struct Stacks<'a> {
        operands: [Option<ast::Expr<'a>>; LEVELS + 1],
        ops: [ast::BinaryOp; LEVELS],
        len: usize,
    }
    impl<'a> Stacks<'a> {
        /// Replaces the top two operands by the top operator applied to them.
        fn reduce(&mut self, arena: &'a bumpalo::Bump) {
            let rhs = self.operands[self.len].take();
            let lhs = self.operands[self.len - 1].take();
            let op = self.ops[self.len - 1];
            self.len -= 1;
            if let (Some(lhs), Some(rhs)) = (lhs, rhs) {
                let span = lhs.span.to(rhs.span);
                self.operands[self.len] =
                    Some(ast::Expr::new(ast::ExprKind::Binary(op, arena.alloc(lhs), arena.alloc(rhs)), span));
            }
        }
    }
    let mut stacks = Stacks { operands: Default::default(), ops: [ast::BinaryOp::Add; LEVELS], len: 0 };
    stacks.operands[0] = Some(first);
    for (op, e) in rest {
        while stacks.len > 0 && precedence(stacks.ops[stacks.len - 1]) >= precedence(op) {
            stacks.reduce(arena);
        }
        stacks.ops[stacks.len] = op;
        stacks.len += 1;
        stacks.operands[stacks.len] = Some(e);
    }
    while stacks.len > 0 {
        stacks.reduce(arena);
    }
    stacks.operands[0].take().unwrap_or_else(|| ast::Expr::new(ast::ExprKind::Error, crate::source::Span::default()))
}

/// The value of a `break n` level (clamped to `u32`).
pub fn number_value(v: f64) -> u32 {
    if v.is_finite() && v >= 0.0 {
        v.min(u32::MAX as f64) as u32
    } else {
        0
    }
}

/// Parses a number's spelling (`1`, `1.5`, `.5e3`, `2.f`, `0x1F`).
pub fn parse_number(text: &str) -> f64 {
    let t = text.trim_end_matches(['f', 'F']);
    if let Some(v) = plain_decimal(t) {
        return v;
    }
    if let Some(hex) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        return u64::from_str_radix(hex, 16).map(|v| v as f64).unwrap_or(0.0);
    }
    t.parse::<f64>().unwrap_or(0.0)
}

/// The value of `digits[.digits]` with at most 15 digits in all, computed exactly: the digits as an
/// integer (below 2^53, so exact) divided by a power of ten (exact up to 10^22) is one correctly
/// rounded operation, the same value a full decimal parser gives. Anything else is `None`.
fn plain_decimal(t: &str) -> Option<f64> {
    const POWERS: [f64; 16] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15];
    let mut mantissa = 0u64;
    let mut digits = 0usize;
    let mut fraction: Option<usize> = None;
    for &b in t.as_bytes() {
        match b {
            b'0'..=b'9' => {
                mantissa = mantissa * 10 + u64::from(b - b'0');
                digits += 1;
                if let Some(f) = &mut fraction {
                    *f += 1;
                }
            }
            b'.' if fraction.is_none() => fraction = Some(0),
            _ => return None,
        }
        if digits > 15 {
            return None;
        }
    }
    if digits == 0 {
        return None;
    }
    Some(mantissa as f64 / POWERS[fraction.unwrap_or(0)])
}

fn convert(t: &Token, interner: &Interner) -> Tok {
    match t.kind {
        TokenKind::Ident => match Interner::keyword(t.sym) {
            Some(k) => KEYWORD_TOKENS[k].clone(),
            None => Tok::Ident(t.sym),
        },
        TokenKind::Number => Tok::Number(parse_number(interner.resolve(t.sym))),
        TokenKind::String => Tok::Str(t.sym),
        TokenKind::LParen => Tok::LParen,
        TokenKind::RParen => Tok::RParen,
        TokenKind::LBrace => Tok::LBrace,
        TokenKind::RBrace => Tok::RBrace,
        TokenKind::LBracket => Tok::LBracket,
        TokenKind::RBracket => Tok::RBracket,
        TokenKind::Semi => Tok::Semi,
        TokenKind::Comma => Tok::Comma,
        TokenKind::Dot => Tok::Dot,
        TokenKind::Question => Tok::Question,
        TokenKind::Colon => Tok::Colon,
        TokenKind::Plus => Tok::Plus,
        TokenKind::Minus => Tok::Minus,
        TokenKind::Star => Tok::Star,
        TokenKind::Slash => Tok::Slash,
        TokenKind::Caret => Tok::Caret,
        TokenKind::Bang => Tok::Bang,
        TokenKind::Lt => Tok::Lt,
        TokenKind::Gt => Tok::Gt,
        TokenKind::Le => Tok::Le,
        TokenKind::Ge => Tok::Ge,
        TokenKind::EqEq => Tok::EqEq,
        TokenKind::Ne => Tok::Ne,
        TokenKind::AndAnd => Tok::AndAnd,
        TokenKind::OrOr => Tok::OrOr,
        TokenKind::Assign => Tok::Assign,
        TokenKind::PlusAssign => Tok::PlusAssign,
        TokenKind::MinusAssign => Tok::MinusAssign,
        TokenKind::StarAssign => Tok::StarAssign,
        TokenKind::SlashAssign => Tok::SlashAssign,
        TokenKind::PlusPlus => Tok::PlusPlus,
        TokenKind::MinusMinus => Tok::MinusMinus,
        TokenKind::Percent
        | TokenKind::Tilde
        | TokenKind::Amp
        | TokenKind::Pipe
        | TokenKind::Shl
        | TokenKind::Shr
        | TokenKind::Hash
        | TokenKind::HashHash
        | TokenKind::ErrorChar
        | TokenKind::ErrorString
        | TokenKind::ErrorComment
        | TokenKind::Eof => Tok::Other,
    }
}

/// How a terminal is shown in "expected ..." messages.
fn describe_terminal(name: &str) -> String {
    match name {
        "\"ident\"" => "an identifier".into(),
        "\"number\"" => "a number".into(),
        "\"string\"" => "a string".into(),
        "\"string_kw\"" => "`string`".into(),
        "\"other\"" => "a token".into(),
        other => format!("`{}`", other.trim_matches('"')),
    }
}

fn describe_tok(t: &Tok, interner: &Interner) -> String {
    match t {
        Tok::Ident(s) => format!("identifier `{}`", interner.resolve(*s)),
        Tok::Number(v) => format!("number `{v}`"),
        Tok::Str(s) => format!("string \"{}\"", crate::front::lex::escape(interner.resolve(*s))),
        Tok::Other => "this token".into(),
        other => {
            let k = KEYWORD_TOKENS.iter().position(|k| k == other);
            match k {
                Some(k) => format!("keyword `{}`", KEYWORDS[k]),
                None => format!("`{}`", punct_spelling(other)),
            }
        }
    }
}

fn punct_spelling(t: &Tok) -> &'static str {
    match t {
        Tok::LParen => "(",
        Tok::RParen => ")",
        Tok::LBrace => "{",
        Tok::RBrace => "}",
        Tok::LBracket => "[",
        Tok::RBracket => "]",
        Tok::Semi => ";",
        Tok::Comma => ",",
        Tok::Dot => ".",
        Tok::Question => "?",
        Tok::Colon => ":",
        Tok::Plus => "+",
        Tok::Minus => "-",
        Tok::Star => "*",
        Tok::Slash => "/",
        Tok::Caret => "^",
        Tok::Bang => "!",
        Tok::Lt => "<",
        Tok::Gt => ">",
        Tok::Le => "<=",
        Tok::Ge => ">=",
        Tok::EqEq => "==",
        Tok::Ne => "!=",
        Tok::AndAnd => "&&",
        Tok::OrOr => "||",
        Tok::Assign => "=",
        Tok::PlusAssign => "+=",
        Tok::MinusAssign => "-=",
        Tok::StarAssign => "*=",
        Tok::SlashAssign => "/=",
        Tok::PlusPlus => "++",
        Tok::MinusMinus => "--",
        _ => "token",
    }
}

/// The shader-type words, which the grammar also takes wherever it takes an identifier.
const SHADER_WORDS: [&str; 8] =
    ["\"surface\"", "\"light\"", "\"displacement\"", "\"volume\"", "\"imager\"", "\"pixel\"", "\"camera\"", "\"lightfield\""];

fn expected_list(expected: &[String]) -> String {
    // Where a name is expected, "an identifier" says it: the shader-type words are names there too.
    let any_name = expected.iter().any(|e| e == "\"ident\"");
    let mut names: Vec<String> = expected
        .iter()
        .filter(|e| !(any_name && SHADER_WORDS.contains(&e.as_str())))
        .map(|e| describe_terminal(e))
        .collect();
    names.sort();
    names.dedup();
    const MAX: usize = 6;
    if names.len() > MAX {
        // Long lists say little; show the most useful few.
        names.retain(|n| matches!(n.as_str(), "`;`" | "`)`" | "`}`" | "`]`" | "`,`" | "an identifier" | "`(`" | "`{`"));
    }
    match names.len() {
        0 => String::new(),
        1 => names[0].clone(),
        _ => {
            let last = names.pop().unwrap_or_default();
            format!("{} or {}", names.join(", "), last)
        }
    }
}

/// A list under construction in the parse arena.
pub type ArenaVec<'a, T> = bumpalo::collections::Vec<'a, T>;

/// Parses preprocessed tokens (ending in `Eof`) into a tree allocated in `arena`. Never fails:
/// syntax errors become diagnostics.
pub fn parse<'a>(
    arena: &'a bumpalo::Bump,
    tokens: &[Token],
    interner: &mut Interner,
    diags: &mut Diagnostics,
) -> ast::TranslationUnit<'a> {
    // Join adjacent string literals, as C does.
    let mut toks: Vec<Tok> = Vec::with_capacity(tokens.len());
    let mut spans: Vec<Span> = Vec::with_capacity(tokens.len());
    let mut i = 0;
    let mut eof_span = Span::default();
    while i < tokens.len() {
        let t = &tokens[i];
        if t.kind == TokenKind::Eof {
            eof_span = t.span;
            break;
        }
        if t.kind == TokenKind::String && tokens.get(i + 1).is_some_and(|n| n.kind == TokenKind::String) {
            let mut text = String::from(interner.resolve(t.sym));
            let mut span = t.span;
            let mut j = i + 1;
            while let Some(n) = tokens.get(j).filter(|n| n.kind == TokenKind::String) {
                text.push_str(interner.resolve(n.sym));
                span = span.to(n.span);
                j += 1;
            }
            toks.push(Tok::Str(interner.intern(&text)));
            spans.push(span);
            i = j;
            continue;
        }
        toks.push(convert(t, interner));
        spans.push(t.span);
        i += 1;
    }
    spans.push(eof_span);

    let mut recovered = Vec::new();
    let input = toks.into_iter().enumerate().map(|(i, t)| Ok::<_, ()>((i as u32, t, i as u32 + 1)));
    let result = grammar::TranslationUnitParser::new().parse(arena, &spans, &mut recovered, input);
    for r in recovered {
        report(r.error, &spans, interner, diags);
    }
    match result {
        Ok(unit) => unit,
        Err(e) => {
            report(e, &spans, interner, diags);
            ast::TranslationUnit { items: &[] }
        }
    }
}

fn report(e: ParseError<u32, Tok, ()>, spans: &[Span], interner: &Interner, diags: &mut Diagnostics) {
    let d = match e {
        ParseError::UnrecognizedToken { token: (l, tok, _), expected } => {
            let l = l as usize;
            let what = describe_tok(&tok, interner);
            let list = expected_list(&expected);
            let mut d = Diagnostic::new(Code::Syntax, spans[l], format!("unexpected {what}"));
            d = if list.is_empty() {
                d.with_label("not expected here")
            } else {
                d.with_label(format!("expected {list}"))
            };
            // Suggest a missing `;` only where the previous token ends before this one starts (not
            // inside one macro expansion, whose tokens share the call's span).
            if l > 0 && list.contains("`;`") && spans[l - 1].file == spans[l].file && spans[l - 1].end < spans[l].start
            {
                let prev = spans[l - 1];
                d = d
                    .with_note("a `;` may be missing at the end of the previous statement")
                    .with_secondary(Span::new(prev.file, prev.end, prev.end), "perhaps `;` here");
            }
            d
        }
        ParseError::UnrecognizedEof { location, expected } => {
            let span = spans[(location as usize).min(spans.len() - 1)];
            let list = expected_list(&expected);
            let mut d = Diagnostic::new(Code::UnexpectedEof, span, "the file ends in the middle of a construct");
            if !list.is_empty() {
                d = d.with_label(format!("expected {list}"));
            }
            d
        }
        ParseError::InvalidToken { location } => {
            Diagnostic::new(Code::Syntax, spans[(location as usize).min(spans.len() - 1)], "invalid token")
        }
        ParseError::ExtraToken { token: (l, tok, _) } => Diagnostic::new(
            Code::Syntax,
            spans[(l as usize).min(spans.len() - 1)],
            format!("unexpected {}", describe_tok(&tok, interner)),
        ),
        ParseError::User { .. } => return,
    };
    diags.push(d);
}

#[cfg(test)]
mod tests {
    #[test]
    fn plain_decimals_parse_as_the_full_parser_does() {
        for text in [
            "0",
            "1",
            "10",
            "0.5",
            ".5",
            "5.",
            "1.5f",
            "3.14159",
            "0.1",
            "0.3",
            "123456789012345",
            "0.000000000000001",
            "99999.9999999999",
            "1e3",
            "2.5e-2",
            "0x1F",
            "1.0F",
            ".",
        ] {
            let full = text.trim_end_matches(['f', 'F']);
            let expected = if let Some(hex) = full.strip_prefix("0x") {
                u64::from_str_radix(hex, 16).map(|v| v as f64).unwrap_or(0.0)
            } else {
                full.parse::<f64>().unwrap_or(0.0)
            };
            assert_eq!(super::parse_number(text).to_bits(), expected.to_bits(), "{text}");
        }
        // Random decimals of up to 15 digits, the point anywhere.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let len = 1 + (state % 15) as usize;
            let digits: String = (0..len).map(|k| char::from(b'0' + ((state >> (4 + 3 * k)) % 10) as u8)).collect();
            let point = (state >> 60) as usize % (len + 1);
            let text = format!("{}.{}", &digits[..point], &digits[point..]);
            assert_eq!(super::parse_number(&text).to_bits(), text.parse::<f64>().unwrap().to_bits(), "{text}");
        }
        // Past 15 digits the fast path steps aside for the full parser.
        assert_eq!(super::plain_decimal("1234567890123456"), None);
        assert_eq!(super::plain_decimal("0.1"), Some(0.1));
    }

    use super::ast::{ExprKind, Item, StmtKind, TranslationUnit};
    use crate::diagnostic::Diagnostics;
    use crate::source::FileId;
    use crate::symbol::Interner;

    /// `text` lexed and parsed as one file, with the parser's diagnostics.
    fn parse_text<'a>(
        arena: &'a bumpalo::Bump,
        text: &str,
        interner: &mut Interner,
    ) -> (TranslationUnit<'a>, Diagnostics) {
        let mut diags = Diagnostics::default();
        let tokens = crate::front::lex::lex(FileId(0), text, interner);
        let unit = super::parse(arena, &tokens, interner, &mut diags);
        (unit, diags)
    }

    /// The expression of `surface s() { x = EXPR; }`, fully parenthesised.
    fn grouped(expr: &str) -> String {
        fn show(e: &super::ast::Expr, interner: &Interner) -> String {
            match &e.kind {
                ExprKind::Ident(s) => interner.resolve(*s).to_string(),
                ExprKind::Binary(op, a, b) => {
                    format!("({} {} {})", show(a, interner), op.spelling(), show(b, interner))
                }
                ExprKind::Assign(_, _, v) => show(v, interner),
                other => format!("{other:?}"),
            }
        }
        let mut interner = Interner::new();
        let mut diags = Diagnostics::default();
        let text = format!("surface s() {{ x = {expr}; }}");
        let tokens = crate::front::lex::lex(FileId(0), &text, &mut interner);
        let arena = bumpalo::Bump::new();
        let unit = super::parse(&arena, &tokens, &mut interner, &mut diags);
        assert!(diags.list.is_empty(), "{expr}: {:?}", diags.list);
        let Some(Item::Shader(shader)) = unit.items.first() else { panic!("no shader in {text}") };
        let StmtKind::Expr(e) = &shader.body.stmts[0].kind else { panic!("not an expression statement") };
        show(e, &interner)
    }

    #[test]
    fn binary_operators_group_by_precedence_and_to_the_left() {
        // Every level, loosest first: the deepest operator stack the grouping can build.
        assert_eq!(
            grouped("a || b && c == d < e + f ^ g * h . i"),
            "(a || (b && (c == (d < (e + (f ^ (g * (h . i))))))))"
        );
        // Tightest first: each operator closes the group before it.
        assert_eq!(
            grouped("a . b * c ^ d + e < f == g && h || i"),
            "((((((((a . b) * c) ^ d) + e) < f) == g) && h) || i)"
        );
        assert_eq!(grouped("a - b - c"), "((a - b) - c)");
        assert_eq!(grouped("a + b * c - d / e"), "((a + (b * c)) - (d / e))");
        assert_eq!(grouped("a * b + c . d ^ e"), "((a * b) + ((c . d) ^ e))");
    }

    #[test]
    fn shader_type_words_are_names_below_the_top_level() {
        let text = "float imager(float light) { return light; }\n\
                    light l(float volume = 1; output float surface[2] = {0, 0};) {\n\
                      color dark = 0, light = color(1, .3, .2), camera[2];\n\
                      light += mix(dark, light, volume);\n\
                      surface(\"Kd\", dark);\n\
                    }\n";
        let mut interner = Interner::new();
        let arena = bumpalo::Bump::new();
        let (unit, diags) = parse_text(&arena, text, &mut interner);
        assert!(diags.list.is_empty(), "{:?}", diags.list);
        let name = |i: &super::ast::Ident| interner.resolve(i.sym).to_string();
        let [Item::Function(f), Item::Shader(shader)] = unit.items else { panic!("{:?}", unit.items) };
        assert_eq!((name(&f.name), name(&f.params[0].name)), ("imager".into(), "light".into()));
        assert_eq!(shader.kind, crate::ir::ShaderKind::Light);
        let params: Vec<String> = shader.params.iter().map(|p| name(&p.name)).collect();
        assert_eq!(params, ["volume", "surface"]);
        let stmts = shader.body.stmts;
        let StmtKind::Decl(d) = &stmts[0].kind else { panic!("{:?}", stmts[0]) };
        let vars: Vec<String> = d.vars.iter().map(|v| name(&v.name)).collect();
        assert_eq!(vars, ["dark", "light", "camera"]);
        // The variable is an ordinary name: an identifier expression with the keyword's symbol.
        let StmtKind::Expr(e) = &stmts[1].kind else { panic!("{:?}", stmts[1]) };
        let ExprKind::Assign(_, target, value) = &e.kind else { panic!("{e:?}") };
        assert!(matches!(target.kind, ExprKind::Ident(s) if s == super::keyword_symbol("light")));
        let ExprKind::Call { args, .. } = &value.kind else { panic!("{value:?}") };
        assert!(matches!(args[1].kind, ExprKind::Ident(s) if interner.resolve(s) == "light"));
        // Followed by `(` the same word is still a call (message passing).
        let StmtKind::Expr(e) = &stmts[2].kind else { panic!("{:?}", stmts[2]) };
        assert!(matches!(&e.kind, ExprKind::Call { name: n, .. } if name(n) == "surface"), "{e:?}");
    }

    #[test]
    fn parameter_groups_may_end_in_several_semicolons() {
        // A macro of parameter declarations that ends in `;`, used as `AOVS;` (Aqsis's grammar takes
        // `formals ';'` after any group). An empty list and a lone `;` between groups still parse
        // as before; a list may not start with `;`.
        let text = "surface s(float a = 1;; color b = 0; output varying color o1 = 0;;) { Ci = a; }\n\
                    surface t() { }\n\
                    surface u(float k = 1) { }\n";
        let mut interner = Interner::new();
        let arena = bumpalo::Bump::new();
        let (unit, diags) = parse_text(&arena, text, &mut interner);
        assert!(diags.list.is_empty(), "{:?}", diags.list);
        let counts: Vec<usize> = unit
            .items
            .iter()
            .map(|item| match item {
                Item::Shader(s) => s.params.len(),
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(counts, [3, 0, 1]);

        let (_, diags) = parse_text(&arena, "surface v(; float a = 1) { }", &mut interner);
        assert_eq!(diags.list.len(), 1, "{:?}", diags.list);
    }
}

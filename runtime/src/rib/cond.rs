//! Conditional RIB: the expressions of `IfBegin` and `ElseIf` (PRMan's conditional RIB, as Pixie
//! implements it too), and the state they read.
//!
//! An expression is parsed and evaluated in one pass, so nothing but nesting (parentheses, `!`,
//! unary minus, function arguments) recurses, and that is bounded by [`MAX_EXPR_DEPTH`]:
//!
//! - `$name` reads a variable: `$Frame` (the number of the frame being read), `$Option:cat:name`
//!   and `$Attribute:cat:name` (an `Option` or `Attribute` parameter), `$cat:name` (the option, or
//!   the attribute when there is no such option: `$user:pass`). An array reads as its first value.
//! - `'text'` (or `"text"`) is a string, `12.5` a number.
//! - `+ - * /` on numbers; `== != < > <= >=` compare strings when either side is a string, numbers
//!   otherwise; `=~` matches the left string against the right as a glob pattern (`*`, `?`,
//!   `[a-z]`, `[!a-z]`).
//! - `!`, `&&`, `||` (short-circuit), parentheses; `defined(cat:name)` (whether the variable
//!   exists, with or without its `$`), `concat(a, b)` (strings joined).
//!
//! The condition holds when the value is a non-zero number or a string (Pixie's rule).
//! Precedence, loosest first: `||`, `&&`, equality and `=~`, ordering, `+ -`, `* /`, unary.

/// How deeply an expression may nest (parentheses, `!`, unary minus, function arguments).
pub const MAX_EXPR_DEPTH: usize = 64;

/// How deeply `IfBegin` blocks may nest.
pub const MAX_IF_DEPTH: usize = 256;

/// The work the conditions of one RIB stream may do, counted in characters: of the expressions,
/// of the values they compare, match or join, and the steps of glob matching. An inline archive
/// read many times evaluates its conditions each time, and a glob match costs up to the product
/// of its strings' lengths.
pub const CONDITION_BUDGET: usize = 1 << 26;

/// A value in an expression.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// A number (integers and floats alike).
    Num(f64),
    /// A string.
    Str(String),
}

impl Value {
    fn text(&self) -> String {
        match self {
            Value::Str(s) => s.clone(),
            Value::Num(n) if n.fract() == 0.0 && n.abs() < 1e15 => format!("{}", *n as i64),
            Value::Num(n) => format!("{n}"),
        }
    }

    fn truth(&self) -> bool {
        match self {
            Value::Num(n) => *n != 0.0,
            Value::Str(_) => true,
        }
    }
}

/// Why an expression could not be evaluated.
#[derive(Clone, Debug, PartialEq)]
pub enum CondError {
    /// The expression is malformed.
    Syntax(String),
    /// It reads a variable that is not set.
    Undefined(String),
    /// The stream's conditions have done [`CONDITION_BUDGET`]'s work.
    OverBudget,
}

impl std::fmt::Display for CondError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CondError::Syntax(m) => write!(f, "{m}"),
            CondError::Undefined(name) => write!(f, "no option or attribute `{name}` is set"),
            CondError::OverBudget => {
                write!(f, "the conditions of this stream have done their work (budget {CONDITION_BUDGET})")
            }
        }
    }
}

/// Evaluates `expr`, reading variables through `lookup` (given the name after `$`), its work taken
/// from `budget` (see [`CONDITION_BUDGET`]).
pub fn evaluate(expr: &str, lookup: &dyn Fn(&str) -> Option<Value>, budget: &mut usize) -> Result<bool, CondError> {
    *budget = budget.checked_sub(expr.len()).ok_or(CondError::OverBudget)?;
    let tokens = tokenize(expr)?;
    let mut p = Eval { tokens, pos: 0, depth: 0, lookup, budget };
    let v = p.or(true)?;
    match p.tokens.get(p.pos) {
        None => Ok(v.truth()),
        Some(t) => Err(CondError::Syntax(format!("unexpected {} after the expression", t.describe()))),
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Num(f64),
    Str(String),
    Var(String),
    Ident(String),
    Op(&'static str),
}

impl Tok {
    fn describe(&self) -> String {
        match self {
            Tok::Num(n) => format!("number {n}"),
            Tok::Str(s) => format!("string '{s}'"),
            Tok::Var(v) => format!("`${v}`"),
            Tok::Ident(i) => format!("`{i}`"),
            Tok::Op(o) => format!("`{o}`"),
        }
    }
}

const OPERATORS: &[&str] =
    &["==", "!=", "<=", ">=", "&&", "||", "=~", "<", ">", "!", "+", "-", "*", "/", "(", ")", ","];

fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == ':'
}

fn tokenize(text: &str) -> Result<Vec<Tok>, CondError> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if c.is_whitespace() {
            rest = &rest[c.len_utf8()..];
        } else if c == '\'' || c == '"' {
            let body = &rest[1..];
            let end = body.find(c).ok_or_else(|| CondError::Syntax(format!("string not closed with {c}")))?;
            out.push(Tok::Str(body[..end].to_string()));
            rest = &body[end + 1..];
        } else if c == '$' {
            let body = &rest[1..];
            let (body, braced) = match body.strip_prefix('{') {
                Some(b) => (b, true),
                None => (body, false),
            };
            let len = body.find(|c: char| !is_name_char(c)).unwrap_or(body.len());
            if len == 0 {
                return Err(CondError::Syntax("`$` is not followed by a variable name".into()));
            }
            out.push(Tok::Var(body[..len].to_string()));
            rest = &body[len..];
            if braced {
                rest = rest.strip_prefix('}').ok_or_else(|| CondError::Syntax("`${` is not closed with `}`".into()))?;
            }
        } else if c.is_ascii_digit() || (c == '.' && rest[1..].starts_with(|d: char| d.is_ascii_digit())) {
            let mut len = rest.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(rest.len());
            // An exponent.
            let after = &rest[len..];
            if after.starts_with(['e', 'E']) {
                let digits_from = if after[1..].starts_with(['+', '-']) { 2 } else { 1 };
                let digits =
                    after[digits_from..].find(|c: char| !c.is_ascii_digit()).unwrap_or(after.len() - digits_from);
                if digits > 0 {
                    len += digits_from + digits;
                }
            }
            let n =
                rest[..len].parse::<f64>().map_err(|_| CondError::Syntax(format!("bad number `{}`", &rest[..len])))?;
            out.push(Tok::Num(n));
            rest = &rest[len..];
        } else if c.is_ascii_alphabetic() || c == '_' {
            let len = rest.find(|c: char| !is_name_char(c)).unwrap_or(rest.len());
            out.push(Tok::Ident(rest[..len].to_string()));
            rest = &rest[len..];
        } else if let Some(op) = OPERATORS.iter().find(|op| rest.starts_with(**op)) {
            out.push(Tok::Op(op));
            rest = &rest[op.len()..];
        } else {
            return Err(CondError::Syntax(format!("unexpected character `{c}`")));
        }
    }
    Ok(out)
}

struct Eval<'a> {
    tokens: Vec<Tok>,
    pos: usize,
    depth: usize,
    lookup: &'a dyn Fn(&str) -> Option<Value>,
    budget: &'a mut usize,
}

type R = Result<Value, CondError>;

fn number(v: &Value, op: &str) -> Result<f64, CondError> {
    match v {
        Value::Num(n) => Ok(*n),
        Value::Str(s) => Err(CondError::Syntax(format!("`{op}` needs numbers, not the string '{s}'"))),
    }
}

fn bool_value(b: bool) -> Value {
    Value::Num(if b { 1.0 } else { 0.0 })
}

impl Eval<'_> {
    /// The text of two values, their lengths taken from the budget.
    fn texts(&mut self, a: &Value, b: &Value) -> Result<(String, String), CondError> {
        let (a, b) = (a.text(), b.text());
        *self.budget = self.budget.checked_sub(a.len() + b.len()).ok_or(CondError::OverBudget)?;
        Ok((a, b))
    }

    fn peek_op(&self, ops: &[&str]) -> Option<&'static str> {
        match self.tokens.get(self.pos) {
            Some(Tok::Op(o)) if ops.contains(o) => Some(o),
            _ => None,
        }
    }

    fn expect(&mut self, op: &str) -> Result<(), CondError> {
        match self.tokens.get(self.pos) {
            Some(Tok::Op(o)) if *o == op => {
                self.pos += 1;
                Ok(())
            }
            Some(t) => Err(CondError::Syntax(format!("expected `{op}`, found {}", t.describe()))),
            None => Err(CondError::Syntax(format!("expected `{op}`, found the end of the expression"))),
        }
    }

    /// `live` false: parsed for its syntax only (the untaken side of `&&` or `||`), reading no
    /// variable.
    fn or(&mut self, live: bool) -> R {
        let mut v = self.and(live)?;
        while self.peek_op(&["||"]).is_some() {
            self.pos += 1;
            let taken = live && !v.truth();
            let right = self.and(taken)?;
            v = bool_value(v.truth() || (taken && right.truth()));
        }
        Ok(v)
    }

    fn and(&mut self, live: bool) -> R {
        let mut v = self.equality(live)?;
        while self.peek_op(&["&&"]).is_some() {
            self.pos += 1;
            let taken = live && v.truth();
            let right = self.equality(taken)?;
            v = bool_value(v.truth() && taken && right.truth());
        }
        Ok(v)
    }

    fn equality(&mut self, live: bool) -> R {
        let mut v = self.ordering(live)?;
        while let Some(op) = self.peek_op(&["==", "!=", "=~"]) {
            self.pos += 1;
            let right = self.ordering(live)?;
            v = bool_value(match (op, &v, &right) {
                ("=~", _, _) => {
                    let (text, pattern) = self.texts(&v, &right)?;
                    glob(&pattern, &text, self.budget).ok_or(CondError::OverBudget)?
                }
                (_, Value::Num(a), Value::Num(b)) => (a == b) == (op == "=="),
                _ => {
                    let (a, b) = self.texts(&v, &right)?;
                    (a == b) == (op == "==")
                }
            });
        }
        Ok(v)
    }

    fn ordering(&mut self, live: bool) -> R {
        let mut v = self.sum(live)?;
        while let Some(op) = self.peek_op(&["<", ">", "<=", ">="]) {
            self.pos += 1;
            let right = self.sum(live)?;
            let order = match (&v, &right) {
                (Value::Num(a), Value::Num(b)) => a.partial_cmp(b),
                _ => {
                    let (a, b) = self.texts(&v, &right)?;
                    Some(a.cmp(&b))
                }
            };
            use std::cmp::Ordering::*;
            v = bool_value(matches!(
                (op, order),
                ("<", Some(Less)) | (">", Some(Greater)) | ("<=", Some(Less | Equal)) | (">=", Some(Greater | Equal))
            ));
        }
        Ok(v)
    }

    fn sum(&mut self, live: bool) -> R {
        let mut v = self.product(live)?;
        while let Some(op) = self.peek_op(&["+", "-"]) {
            self.pos += 1;
            let right = self.product(live)?;
            let (a, b) = (number(&v, op)?, number(&right, op)?);
            v = Value::Num(if op == "+" { a + b } else { a - b });
        }
        Ok(v)
    }

    fn product(&mut self, live: bool) -> R {
        let mut v = self.unary(live)?;
        while let Some(op) = self.peek_op(&["*", "/"]) {
            self.pos += 1;
            let right = self.unary(live)?;
            let (a, b) = (number(&v, op)?, number(&right, op)?);
            v = Value::Num(if op == "*" { a * b } else { a / b });
        }
        Ok(v)
    }

    fn nested<T>(&mut self, f: impl FnOnce(&mut Self) -> Result<T, CondError>) -> Result<T, CondError> {
        if self.depth >= MAX_EXPR_DEPTH {
            return Err(CondError::Syntax(format!("the expression nests deeper than {MAX_EXPR_DEPTH}")));
        }
        self.depth += 1;
        let result = f(self);
        self.depth -= 1;
        result
    }

    fn unary(&mut self, live: bool) -> R {
        if let Some(op) = self.peek_op(&["!", "-"]) {
            self.pos += 1;
            let v = self.nested(|p| p.unary(live))?;
            return Ok(if op == "!" { bool_value(!v.truth()) } else { Value::Num(-number(&v, "-")?) });
        }
        self.primary(live)
    }

    fn primary(&mut self, live: bool) -> R {
        let Some(token) = self.tokens.get(self.pos).cloned() else {
            return Err(CondError::Syntax("the expression ends where a value is expected".into()));
        };
        self.pos += 1;
        match token {
            Tok::Num(n) => Ok(Value::Num(n)),
            Tok::Str(s) => Ok(Value::Str(s)),
            Tok::Var(_) if !live => Ok(Value::Num(0.0)),
            Tok::Var(name) => (self.lookup)(&name).ok_or(CondError::Undefined(name)),
            Tok::Op("(") => {
                let v = self.nested(|p| p.or(live))?;
                self.expect(")")?;
                Ok(v)
            }
            Tok::Ident(f) if f == "defined" => {
                self.expect("(")?;
                let name = match self.tokens.get(self.pos).cloned() {
                    Some(Tok::Ident(n) | Tok::Var(n)) => {
                        self.pos += 1;
                        n
                    }
                    _ => self.nested(|p| p.or(live))?.text(),
                };
                self.expect(")")?;
                Ok(bool_value(live && (self.lookup)(&name).is_some()))
            }
            Tok::Ident(f) if f == "concat" => {
                self.expect("(")?;
                let a = self.nested(|p| p.or(live))?;
                self.expect(",")?;
                let b = self.nested(|p| p.or(live))?;
                self.expect(")")?;
                let (a, b) = self.texts(&a, &b)?;
                Ok(Value::Str(a + &b))
            }
            Tok::Ident(word) => Err(CondError::Syntax(format!(
                "unexpected word `{word}` (a variable is written `${word}`, a string '{word}')"
            ))),
            other => Err(CondError::Syntax(format!("unexpected {} where a value is expected", other.describe()))),
        }
    }
}

/// Whether `text` matches the glob `pattern`: `*` any run of characters, `?` any one, `[...]` one
/// of a set (ranges `a-z`, negated by a leading `!` or `^`); anything else itself. At most
/// `text` times `pattern` steps (a `*` is retried from where the last one matched, never nested),
/// each taken from `budget`: `None` when it runs out.
pub fn glob(pattern: &str, text: &str, budget: &mut usize) -> Option<bool> {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut pi, mut ti) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        *budget = budget.checked_sub(1)?;
        let step = match p.get(pi) {
            Some('*') => {
                star = Some((pi, ti));
                pi += 1;
                continue;
            }
            Some('?') => Some(pi + 1),
            Some('[') => class(&p, pi, t[ti]),
            Some(&c) => (c == t[ti]).then_some(pi + 1),
            None => None,
        };
        match (step, star) {
            (Some(next), _) => {
                pi = next;
                ti += 1;
            }
            (None, Some((sp, st))) => {
                pi = sp + 1;
                ti = st + 1;
                star = Some((sp, st + 1));
            }
            (None, None) => return Some(false),
        }
    }
    Some(p[pi..].iter().all(|&c| c == '*'))
}

/// The pattern position after the class at `p[at] == '['` if it matches `c`; a `[` with no `]`
/// is itself.
fn class(p: &[char], at: usize, c: char) -> Option<usize> {
    let mut i = at + 1;
    let negated = matches!(p.get(i), Some('!' | '^'));
    if negated {
        i += 1;
    }
    let mut matched = false;
    let mut first = true;
    loop {
        match p.get(i) {
            None => return (c == '[').then_some(at + 1),
            Some(']') if !first => break,
            Some(&lo) => {
                if p.get(i + 1) == Some(&'-') && p.get(i + 2).is_some_and(|&hi| hi != ']') {
                    let hi = p[i + 2];
                    matched |= lo <= c && c <= hi;
                    i += 3;
                } else {
                    matched |= lo == c;
                    i += 1;
                }
            }
        }
        first = false;
    }
    (matched != negated).then_some(i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vars(name: &str) -> Option<Value> {
        match name {
            "Frame" => Some(Value::Num(12.0)),
            "user:pass" => Some(Value::Str("shadow".into())),
            "user:level" => Some(Value::Num(2.0)),
            _ => None,
        }
    }

    fn eval(e: &str) -> Result<bool, CondError> {
        evaluate(e, &vars, &mut CONDITION_BUDGET.clone())
    }

    fn matches(pattern: &str, text: &str) -> bool {
        glob(pattern, text, &mut CONDITION_BUDGET.clone()).expect("within the budget")
    }

    #[test]
    fn comparisons_and_logic() {
        assert_eq!(eval("$Frame == 12"), Ok(true));
        assert_eq!(eval("$Frame > 10 && $Frame <= 12"), Ok(true));
        assert_eq!(eval("$Frame < 10 || $user:level == 2"), Ok(true));
        assert_eq!(eval("!($Frame == 12)"), Ok(false));
        assert_eq!(eval("$user:pass == 'shadow'"), Ok(true));
        assert_eq!(eval("$user:pass != \"shadow\""), Ok(false));
        assert_eq!(eval("$Frame == '12'"), Ok(true));
        assert_eq!(eval("'abc' < 'abd'"), Ok(true));
        assert_eq!(eval("$Frame * 2 - 4 == 20"), Ok(true));
        assert_eq!(eval("1 + 2 * 3 == 7"), Ok(true));
        assert_eq!(eval("-$user:level == -2"), Ok(true));
        assert_eq!(eval("0"), Ok(false));
        assert_eq!(eval("'any string'"), Ok(true));
        assert_eq!(eval("${Frame} == 12"), Ok(true));
        assert_eq!(eval("1.5e1 == 15"), Ok(true));
    }

    #[test]
    fn glob_match() {
        assert_eq!(eval("$user:pass =~ 'sh*'"), Ok(true));
        assert_eq!(eval("$user:pass =~ '*dow'"), Ok(true));
        assert_eq!(eval("$user:pass =~ 's?adow'"), Ok(true));
        assert_eq!(eval("$user:pass =~ 'beauty*'"), Ok(false));
        assert!(matches("[a-c]x", "bx"));
        assert!(!matches("[!a-c]x", "bx"));
        assert!(matches("*a*b*c*", "xxaxxbxxcxx"));
        assert!(!matches("*a*b*c*d", "xxaxxbxxcxx"));
        assert!(matches("", ""));
        assert!(!matches("", "a"));
        assert!(matches("a[", "a["));
        // Many stars against a long text stay fast (no backtracking blow-up).
        let long = "a".repeat(10_000);
        assert!(!matches(&"*a".repeat(50).replace("*a*a", "*a*b"), &long));
        // A match past the budget stops.
        let mut budget = 1000;
        assert_eq!(glob(&"*a".repeat(50).replace("*a*a", "*a*b"), &long, &mut budget), None);
        assert_eq!(budget, 0);
    }

    #[test]
    fn defined_concat_and_short_circuit() {
        assert_eq!(eval("defined(user:pass)"), Ok(true));
        assert_eq!(eval("defined($user:nothing)"), Ok(false));
        assert_eq!(eval("concat($user:pass, 'map') == 'shadowmap'"), Ok(true));
        // The untaken side reads no variable.
        assert_eq!(eval("defined(user:nothing) && $user:nothing == 1"), Ok(false));
        assert_eq!(eval("$Frame == 12 || $user:nothing"), Ok(true));
        assert_eq!(eval("$user:nothing == 1"), Err(CondError::Undefined("user:nothing".into())));
    }

    #[test]
    fn errors_never_panic() {
        for bad in
            ["", "(", "$", "1 +", "'open", "== 1", "1 2", "frame == 1", "concat(1)", "$Frame @ 2", "${x", "'a' + 1"]
        {
            assert!(matches!(eval(bad), Err(CondError::Syntax(_))), "{bad}");
        }
        let deep = format!("{}1{}", "(".repeat(100), ")".repeat(100));
        assert!(matches!(eval(&deep), Err(CondError::Syntax(m)) if m.contains("deeper")));
        let nots = "!".repeat(100_000) + "1";
        assert!(eval(&nots).is_err());
        let long = vec!["1"; 100_000].join(" + ");
        assert_eq!(eval(&format!("{long} == 100000")), Ok(true));
    }

    use crate::rib::{parse_str, RequestKind as K, RibParse, Severity};

    /// The colours the requests kept set, in order: each branch in the tests sets its own.
    fn colors(parse: &RibParse) -> Vec<f32> {
        parse.requests.iter().filter_map(|r| if let K::Color(c) = r.kind { Some(c[0]) } else { None }).collect()
    }

    fn errors(parse: &RibParse) -> Vec<String> {
        parse.diagnostics.iter().filter(|d| d.severity == Severity::Error).map(|d| d.to_string()).collect()
    }

    #[test]
    fn rib_branches_follow_frame_and_user_options() {
        let text = r#"
Option "user" "string pass" "shadow"
FrameBegin 3
IfBegin "$user:pass == 'beauty'"
  Color 1 0 0
ElseIf "$Frame == 3 && $user:pass =~ 'sha*'"
  Color 2 0 0
  IfBegin "$Frame > 5"
    Color 3 0 0
  Else
    Color 4 0 0
  IfEnd
Else
  Color 5 0 0
IfEnd
FrameEnd
FrameBegin 7
IfBegin "$Frame > 5"
  Color 6 0 0
ElseIf "1"
  Color 7 0 0
IfEnd
FrameEnd
"#;
        let parse = parse_str(text, "cond.rib");
        assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
        assert_eq!(colors(&parse), [2.0, 4.0, 6.0]);
        // The conditionals themselves are not in the list.
        assert!(!parse.requests.iter().any(|r| matches!(r.kind, K::IfBegin(_) | K::ElseIf(_) | K::Else | K::IfEnd)));
    }

    #[test]
    fn rib_attributes_are_scoped_and_options_end_with_their_frame() {
        let text = r#"
FrameBegin 1
Option "user" "float level" 2
WorldBegin
AttributeBegin
  Attribute "user" "string part" "wheel"
  IfBegin "$user:part == 'wheel' && $Option:user:level == 2"
    Color 1 0 0
  IfEnd
AttributeEnd
IfBegin "defined(user:part)"
  Color 2 0 0
IfEnd
IfBegin "$Attribute:user:part == 'wheel'"
  Color 3 0 0
IfEnd
WorldEnd
FrameEnd
FrameBegin 2
IfBegin "defined(Option:user:level)"
  Color 4 0 0
Else
  Color 5 0 0
IfEnd
FrameEnd
"#;
        let parse = parse_str(text, "cond.rib");
        // `$Attribute:user:part` outside its block is undefined: a warning, and false.
        assert_eq!(colors(&parse), [1.0, 5.0]);
        assert_eq!(parse.diagnostics.len(), 1, "{:?}", parse.diagnostics);
        assert_eq!(parse.diagnostics[0].severity, Severity::Warning);
        assert_eq!(parse.diagnostics[0].loc.line, 14);
    }

    #[test]
    fn rib_skipped_branches_read_nothing() {
        let text = r#"
IfBegin "0"
  ReadArchive "does-not-exist.rib"
  Declare "x" "color"
  ArchiveBegin "a"
  ArchiveEnd
  Bogus 1 2 3
IfEnd
Surface "s" "x" [1 2 3]
"#;
        let parse = parse_str(text, "cond.rib");
        assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
        let K::Surface(s) = &parse.requests[0].kind else { panic!("{:?}", parse.requests) };
        // `x` was not declared a colour: three values of an implicit float.
        assert_eq!(s.params[0].value.len(), 3);
        assert_ne!(s.params[0].decl.ty, crate::rib::Ty::Color);
    }

    #[test]
    fn rib_inline_archives_evaluate_where_read() {
        let text = r#"
ArchiveBegin "part"
  IfBegin "$user:pass == 'shadow'"
    Color 1 0 0
  Else
    Color 2 0 0
  IfEnd
ArchiveEnd
Option "user" "string pass" "shadow"
ReadArchive "part"
Option "user" "string pass" "beauty"
ReadArchive "part"
"#;
        let parse = parse_str(text, "cond.rib");
        assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
        assert_eq!(colors(&parse), [1.0, 2.0]);
    }

    #[test]
    fn rib_malformed_conditionals_are_located_errors() {
        let text = "IfEnd\nElse\nIfBegin \"$Frame ==\"\nColor 1 0 0\nElse\nColor 2 0 0\nElse\nColor 3 0 0\nIfEnd\nIfBegin \"1\"\nColor 4 0 0\n";
        let parse = parse_str(text, "cond.rib");
        let errors = errors(&parse);
        assert_eq!(errors.len(), 4, "{errors:?}");
        assert!(errors[0].starts_with("cond.rib:1:1: error: `IfEnd` without `IfBegin`"), "{errors:?}");
        assert!(errors[1].starts_with("cond.rib:2:1:"), "{errors:?}");
        assert!(errors[2].starts_with("cond.rib:3:1:") && errors[2].contains("it is false"), "{errors:?}");
        assert!(errors[3].starts_with("cond.rib:7:1:") && errors[3].contains("second `Else`"), "{errors:?}");
        // The malformed condition is false, so `Else` is taken; the unclosed block ends with the file.
        assert_eq!(colors(&parse), [2.0, 4.0]);
        let unclosed = parse.diagnostics.iter().find(|d| d.message.contains("no `IfEnd`")).expect("a warning");
        assert_eq!((unclosed.severity, unclosed.loc.line), (Severity::Warning, 10));
    }

    #[test]
    fn rib_conditions_share_a_budget() {
        // An inline archive whose condition is read many times: past the budget, false.
        // One star before many letters: each retry of the star matches them again.
        let pattern = format!("*{}", "a".repeat(2000));
        let text = format!(
            "Option \"user\" \"string s\" \"{}\"\nArchiveBegin \"x\"\nIfBegin \"$user:s =~ '{pattern}b'\"\nIfEnd\n\
             ArchiveEnd\n{}",
            "a".repeat(4000),
            "ReadArchive \"x\"\n".repeat(20)
        );
        let parse = parse_str(&text, "cond.rib");
        let errors = errors(&parse);
        assert!(!errors.is_empty() && errors.iter().all(|e| e.contains("budget")), "{errors:?}");
    }

    #[test]
    fn rib_nesting_is_bounded() {
        let depth = MAX_IF_DEPTH + 10;
        let text = "IfBegin \"1\"\n".repeat(depth) + "Color 1 0 0\n" + &"IfEnd\n".repeat(depth) + "Color 2 0 0\n";
        let parse = parse_str(&text, "cond.rib");
        assert_eq!(errors(&parse).len(), 1, "{:?}", errors(&parse));
        // The blocks past the limit are skipped; every IfEnd finds its block.
        assert_eq!(colors(&parse), [2.0]);
    }
}

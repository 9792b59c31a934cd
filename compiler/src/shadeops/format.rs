//! `format` and `printf` (RISpec 3.2 section 15.5): C-style formatting of shader values into a string.
//!
//! A directive is `%`, then optional flags (`-` left-justify, `+` always a sign, space for a sign
//! place, `0` zero-pad, `#` alternate form), an optional width, an optional `.precision`, optional C
//! length modifiers (`h l L q j z t`, accepted and ignored) and a conversion:
//! - `%f %F %e %E %g %G`: a float as C's `printf` prints a `double` (`%g` drops trailing zeros unless
//!   `#` is given); infinities and NaN print as `inf`, `-inf`, `nan` (upper case for `F E G`), padded
//!   with spaces even under `0`.
//! - `%d %i`: a float truncated toward zero and printed as an integer; a precision is a minimum number
//!   of digits (as in C).
//! - `%s`: a string; a precision truncates it to that many characters. A non-string argument is
//!   printed as `%g` would print it (with the directive's flags, width and precision).
//! - `%c` (colour), `%p` (point, vector or normal): the three components, as `%g` formats each,
//!   separated by single spaces; `%m` (matrix): the sixteen elements in row-major order, likewise.
//!   The flags, width and precision apply to each component.
//! - `%%`: a single `%`, consuming no argument.
//!
//! Arguments are consumed left to right, one per directive except `%%`. Mismatches format what they
//! can: a numeric conversion given a triple or matrix formats every component that way (so `%.2f` of a
//! colour is `0.50 0.25 1.00`); `%c`, `%p` or `%m` given a float prints the one float; any conversion
//! but `%s` given a string prints the string (with the width, without truncation). A directive with no
//! argument left prints itself literally followed by `<missing>` (`%5.2f<missing>`). An incomplete or
//! unknown directive (`%` at the end, `%5`, `%q`, `%*d`) prints its text literally and consumes no
//! argument. Extra arguments are ignored. Widths and precisions above 512 are clamped to 512.
//! Backslash escapes were resolved by the lexer; nothing here treats `\` specially. Nothing panics.

use super::{M4, V3};

/// One argument of `format` or `printf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FormatArg<'a> {
    Float(f32),
    /// A colour, point, vector or normal.
    Triple(V3),
    Matrix(&'a M4),
    Str(&'a str),
}

/// The most a width or precision can be (larger ones are clamped).
const MAX_WIDTH: usize = 512;

/// A parsed directive's flags, width and precision.
#[derive(Clone, Copy, Debug, Default)]
struct Spec {
    left: bool,
    plus: bool,
    space: bool,
    zero: bool,
    alt: bool,
    width: usize,
    precision: Option<usize>,
}

/// The longest string, in bytes, that `concat` and `format` make and `printf` prints: a longer
/// one is cut to its first `MAX_STRING_LEN` bytes (at a character boundary), and the back end
/// reports the place once. A loop that doubles a string stops growing there.
pub const MAX_STRING_LEN: usize = 65_536;

/// The bytes of strings the shader makes (`concat`, `format`) that one batch of the JIT may hold,
/// or one run of the interpreter (a batch of one point): each distinct string counts its length
/// and [`STRING_OVERHEAD`]. Past it a new string is the empty string, and the back end reports the
/// place once. A batch keeps every string it made until it is reset.
pub const STRING_BYTES_BUDGET: usize = 16 << 20;

/// What a string counts against [`STRING_BYTES_BUDGET`] besides its bytes: what keeping it takes
/// (the table's entries), so that many short strings are bounded too.
pub const STRING_OVERHEAD: usize = 64;

/// Cuts `s` to at most [`MAX_STRING_LEN`] bytes, at a character boundary; whether it was longer.
pub fn cut(s: &mut String) -> bool {
    if s.len() <= MAX_STRING_LEN {
        return false;
    }
    let mut end = MAX_STRING_LEN;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    s.truncate(end);
    true
}

/// RSL's `concat(parts...)`, cut as [`cut`] does (without building more than the cut string);
/// whether it was cut.
pub fn concat<'a>(parts: impl IntoIterator<Item = &'a str>) -> (String, bool) {
    let mut out = String::new();
    for p in parts {
        if out.len() + p.len() > MAX_STRING_LEN {
            let room = MAX_STRING_LEN - out.len();
            let mut end = room.min(p.len());
            while !p.is_char_boundary(end) {
                end -= 1;
            }
            out.push_str(&p[..end]);
            return (out, true);
        }
        out.push_str(p);
    }
    (out, false)
}

/// RSL's `format(fmt, args...)` (and the text `printf` prints): `fmt` with each directive replaced by
/// its argument formatted as the module documentation describes. Never panics: malformed directives
/// print literally, missing arguments print as `<missing>` after the directive, extra ones are ignored.
/// Not cut: see [`format_cut`].
pub fn format(fmt: &str, args: &[FormatArg]) -> String {
    format_up_to(fmt, args, usize::MAX)
}

/// [`format`] cut as [`cut`] does, without formatting far past the cut; whether it was cut.
pub fn format_cut(fmt: &str, args: &[FormatArg]) -> (String, bool) {
    let mut out = format_up_to(fmt, args, MAX_STRING_LEN);
    let was_cut = cut(&mut out);
    (out, was_cut)
}

/// [`format`], stopping at the first directive that ends past `limit` bytes.
fn format_up_to(fmt: &str, args: &[FormatArg], limit: usize) -> String {
    let mut out = String::with_capacity(fmt.len().min(limit) + 16 * args.len().min(64));
    let mut args = args.iter();
    let mut rest = fmt;
    while let Some(pos) = rest.find('%') {
        if out.len() > limit {
            return out;
        }
        out.push_str(&rest[..pos]);
        let directive = &rest[pos..];
        let (len, spec, conv) = parse_directive(directive);
        let text = &directive[..len];
        rest = &directive[len..];
        match conv {
            Some('%') => out.push('%'),
            Some(conv) => match args.next() {
                Some(arg) => format_arg(&mut out, &spec, conv, arg),
                None => {
                    out.push_str(text);
                    out.push_str("<missing>");
                }
            },
            None => out.push_str(text),
        }
    }
    out.push_str(rest);
    out
}

/// Parses the directive at the start of `s` (which starts with `%`): its length in bytes, its spec, and
/// its conversion, or `None` for an incomplete or unknown directive (whose text then ends just after
/// the first character that does not fit, or at the end of `s`).
fn parse_directive(s: &str) -> (usize, Spec, Option<char>) {
    let mut spec = Spec::default();
    let mut chars = s.char_indices().skip(1).peekable();
    while let Some(&(_, c)) = chars.peek() {
        match c {
            '-' => spec.left = true,
            '+' => spec.plus = true,
            ' ' => spec.space = true,
            '0' => spec.zero = true,
            '#' => spec.alt = true,
            _ => break,
        }
        chars.next();
    }
    spec.width = digits(&mut chars);
    if let Some(&(_, '.')) = chars.peek() {
        chars.next();
        spec.precision = Some(digits(&mut chars));
    }
    while let Some(&(_, c)) = chars.peek() {
        if !"hlLqjzt".contains(c) {
            break;
        }
        chars.next();
    }
    match chars.next() {
        Some((i, c)) => {
            let len = i + c.len_utf8();
            let known = "%fFeEgGdiscpm".contains(c);
            (len, spec, known.then_some(c))
        }
        None => (s.len(), spec, None),
    }
}

/// Reads a decimal number (possibly empty, which is 0), clamped to [`MAX_WIDTH`].
fn digits(chars: &mut std::iter::Peekable<impl Iterator<Item = (usize, char)>>) -> usize {
    let mut n: usize = 0;
    while let Some(&(_, c)) = chars.peek() {
        match c.to_digit(10) {
            Some(d) => n = n.saturating_mul(10).saturating_add(d as usize),
            None => break,
        }
        chars.next();
    }
    n.min(MAX_WIDTH)
}

fn format_arg(out: &mut String, spec: &Spec, conv: char, arg: &FormatArg) {
    // The conversion each number is formatted with.
    let num_conv = match conv {
        's' | 'c' | 'p' | 'm' => 'g',
        c => c,
    };
    let mut components = |values: &[f32]| {
        for (k, v) in values.iter().enumerate() {
            if k > 0 {
                out.push(' ');
            }
            out.push_str(&number(spec, num_conv, *v));
        }
    };
    match arg {
        FormatArg::Float(x) => components(&[*x]),
        FormatArg::Triple(v) => components(v),
        FormatArg::Matrix(m) => components(&m[..]),
        FormatArg::Str(s) => {
            let s = match (conv, spec.precision) {
                ('s', Some(p)) => s.char_indices().nth(p).map_or(*s, |(i, _)| &s[..i]),
                _ => s,
            };
            out.push_str(&pad(spec, "", s, false));
        }
    }
}

/// Pads `prefix` + `body` to the width: left-justified with spaces, or zero-padded between the two
/// when `zero_ok`, or right-justified with spaces.
fn pad(spec: &Spec, prefix: &str, body: &str, zero_ok: bool) -> String {
    let len = prefix.chars().count() + body.chars().count();
    let fill = spec.width.saturating_sub(len);
    let mut s = String::with_capacity(len + fill);
    if spec.left {
        s.push_str(prefix);
        s.push_str(body);
        s.extend(std::iter::repeat_n(' ', fill));
    } else if spec.zero && zero_ok {
        s.push_str(prefix);
        s.extend(std::iter::repeat_n('0', fill));
        s.push_str(body);
    } else {
        s.extend(std::iter::repeat_n(' ', fill));
        s.push_str(prefix);
        s.push_str(body);
    }
    s
}

/// One number formatted by a numeric conversion (`f F e E g G d i`).
fn number(spec: &Spec, conv: char, x: f32) -> String {
    let upper = conv.is_ascii_uppercase();
    let x = f64::from(x);
    let negative = x.is_sign_negative() && !x.is_nan();
    if !x.is_finite() {
        let body = match (x.is_nan(), upper) {
            (true, false) => "nan",
            (true, true) => "NAN",
            (false, false) => "inf",
            (false, true) => "INF",
        };
        return pad(spec, sign(spec, negative), body, false);
    }
    let a = x.abs();
    match conv {
        'd' | 'i' => {
            let t = a.trunc();
            let mut digits = format!("{t:.0}");
            if let Some(p) = spec.precision {
                if digits.len() < p {
                    digits.insert_str(0, &"0".repeat(p - digits.len()));
                }
            }
            // A precision turns the 0 flag off, as in C.
            pad(spec, sign(spec, negative && t != 0.0), &digits, spec.precision.is_none())
        }
        'e' | 'E' => {
            let body = fmt_e(a, spec.precision.unwrap_or(6), spec.alt, upper);
            pad(spec, sign(spec, negative), &body, true)
        }
        'g' | 'G' => {
            let body = fmt_g(a, spec.precision.unwrap_or(6), spec.alt, upper);
            pad(spec, sign(spec, negative), &body, true)
        }
        _ => {
            let body = fmt_f(a, spec.precision.unwrap_or(6), spec.alt);
            pad(spec, sign(spec, negative), &body, true)
        }
    }
}

fn sign(spec: &Spec, negative: bool) -> &'static str {
    if negative {
        "-"
    } else if spec.plus {
        "+"
    } else if spec.space {
        " "
    } else {
        ""
    }
}

/// C's `%f` of a non-negative finite value.
fn fmt_f(a: f64, precision: usize, alt: bool) -> String {
    let mut s = format!("{a:.precision$}");
    if alt && precision == 0 {
        s.push('.');
    }
    s
}

/// C's `%e` of a non-negative finite value: the mantissa, then `e`, the exponent's sign and at least
/// two digits.
fn fmt_e(a: f64, precision: usize, alt: bool, upper: bool) -> String {
    let (mantissa, exp) = split_e(a, precision);
    let mut s = mantissa.to_string();
    if alt && precision == 0 {
        s.push('.');
    }
    s.push(if upper { 'E' } else { 'e' });
    s.push_str(&format!("{exp:+03}"));
    s
}

/// Rust's `{:e}` text of `a` with `precision` digits after the point, split into the mantissa and the
/// decimal exponent (after rounding).
fn split_e(a: f64, precision: usize) -> (String, i32) {
    let s = format!("{a:.precision$e}");
    match s.split_once('e') {
        Some((m, e)) => (m.to_string(), e.parse().unwrap_or(0)),
        None => (s, 0),
    }
}

/// C's `%g` of a non-negative finite value: `%e` style when the exponent is below -4 or at least the
/// precision, `%f` style otherwise, with trailing zeros (and a trailing point) removed unless `alt`.
fn fmt_g(a: f64, precision: usize, alt: bool, upper: bool) -> String {
    let p = precision.max(1);
    let exp = if a == 0.0 { 0 } else { split_e(a, p - 1).1 };
    let (mut s, e_part) = if exp < -4 || exp >= p as i32 {
        let e = fmt_e(a, p - 1, alt, upper);
        let at = e.find(['e', 'E']).unwrap_or(e.len());
        (e[..at].to_string(), e[at..].to_string())
    } else {
        (fmt_f(a, (p as i32 - 1 - exp).max(0) as usize, alt), String::new())
    };
    if !alt && s.contains('.') {
        let trimmed = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(trimmed);
    }
    s.push_str(&e_part);
    s
}

/// Patterns compiled by one thread and kept for its next calls: a shader's pattern is most often
/// the same string at every shading point.
const KEPT_PATTERNS: usize = 8;

/// The most memory a compiled pattern may take (the regex crate's `size_limit`); a larger one is
/// refused and matches nothing.
const MAX_PATTERN_BYTES: usize = 1 << 20;

/// RSL `match(pattern, subject)`: whether the regular expression `pattern` matches anywhere in
/// `subject` (PRMan: "any regular expression, as described in the Unix manual page on regex(5)";
/// the regex crate's syntax is the extended one: classes, `+`, `?`, `|`, groups, counts, anchors,
/// escapes). Matching takes time linear in the subject whatever the pattern; a malformed pattern,
/// or one larger than [`MAX_PATTERN_BYTES`] compiled, matches nothing. The interpreter and the JIT
/// both call this one.
pub fn regex_match(pattern: &str, subject: &str) -> bool {
    use std::cell::RefCell;
    thread_local! {
        static KEPT: RefCell<Vec<(String, Option<regex::Regex>)>> = const { RefCell::new(Vec::new()) };
    }
    KEPT.with(|kept| {
        let mut kept = kept.borrow_mut();
        let at = match kept.iter().position(|(p, _)| p == pattern) {
            Some(at) => at,
            None => {
                let compiled = regex::RegexBuilder::new(pattern).size_limit(MAX_PATTERN_BYTES).build().ok();
                if kept.len() == KEPT_PATTERNS {
                    kept.pop();
                }
                kept.push((pattern.to_string(), compiled));
                kept.len() - 1
            }
        };
        // The pattern used last goes first, so that a shader's one pattern is found at once.
        let entry = kept.remove(at);
        let found = entry.1.as_ref().is_some_and(|r| r.is_match(subject));
        kept.insert(0, entry);
        found
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use FormatArg::*;

    #[test]
    fn match_takes_regular_expressions() {
        assert!(regex_match("^foo", "foobar"));
        assert!(!regex_match("^bar", "foobar"));
        assert!(regex_match("o*b", "foobar"));
        assert!(regex_match("ar$", "foobar"));
        assert!(regex_match("f.o", "xfoo"));
        assert!(!regex_match("z", "foobar"));
        // The extended syntax that regex(5) describes.
        assert!(regex_match("[0-9]+", "ab12"));
        assert!(!regex_match("^[0-9]+$", "ab12"));
        assert!(regex_match("a|b", "b"));
        assert!(regex_match("colou?r", "color"));
        assert!(regex_match("\\.tif$", "x.tif"));
        assert!(!regex_match("\\.tif$", "xtif"));
        assert!(regex_match("a{2}", "caab"));
        assert!(!regex_match("a{3}", "caab"));
        assert!(regex_match("^(red|green)_[a-z]+$", "green_leaf"));
        // Malformed patterns match nothing.
        assert!(!regex_match("[", "x["));
        assert!(!regex_match("(a", "a"));
    }

    #[test]
    fn match_takes_linear_time_on_patterns_that_backtrack() {
        // Fourteen `a*` before a `b` that never comes: a backtracking matcher tries about 36^14
        // ways before it gives up.
        let pattern = format!("{}b", "a*".repeat(14));
        let subject = "a".repeat(36);
        assert!(!regex_match(&pattern, &subject));
        assert!(regex_match(&pattern, &(subject.clone() + "b")));
    }

    #[test]
    fn match_keeps_each_threads_patterns_apart() {
        // More patterns than are kept, used in turn: each answer is its own pattern's.
        for round in 0..3 {
            for k in 0..2 * KEPT_PATTERNS {
                let pattern = format!("^x{k}$");
                assert!(regex_match(&pattern, &format!("x{k}")), "round {round}, pattern {k}");
                assert!(!regex_match(&pattern, &format!("x{}", k + 1)), "round {round}, pattern {k}");
            }
        }
    }

    fn f(fmt: &str, x: f32) -> String {
        format(fmt, &[Float(x)])
    }

    #[test]
    fn floats() {
        assert_eq!(f("%f", 1.5), "1.500000");
        assert_eq!(f("%5.2f", 1.23456), " 1.23");
        assert_eq!(f("%-6.1f|", 2.0), "2.0   |");
        assert_eq!(f("%+.1f", 2.0), "+2.0");
        assert_eq!(f("% .1f", 2.0), " 2.0");
        assert_eq!(f("%08.3f", -3.5), "-003.500");
        assert_eq!(f("%.0f", 2.5), "2");
        assert_eq!(f("%.f", 3.7), "4");
        assert_eq!(f("%#.0f", 3.0), "3.");
        assert_eq!(f("%lf", 0.25), "0.250000");
        assert_eq!(f("%.3f", -0.0), "-0.000");
        assert_eq!(f("%F", 1.0), "1.000000");
    }

    #[test]
    fn exponents_and_general() {
        assert_eq!(f("%e", 12345.678), "1.234568e+04");
        assert_eq!(f("%.2E", 0.000123), "1.23E-04");
        assert_eq!(f("%e", 0.0), "0.000000e+00");
        assert_eq!(f("%.0e", 5.0), "5e+00");
        assert_eq!(f("%#.0e", 5.0), "5.e+00");
        assert_eq!(f("%e", 1e38), "1.000000e+38");
        assert_eq!(f("%12.3e|", -1.5), "  -1.500e+00|");
        assert_eq!(f("%g", 0.0001), "0.0001");
        assert_eq!(f("%g", 0.00001), "1e-05");
        assert_eq!(f("%g", 123456.0), "123456");
        assert_eq!(f("%g", 1234567.0), "1.23457e+06");
        assert_eq!(f("%g", 100.0), "100");
        assert_eq!(f("%g", 0.5), "0.5");
        assert_eq!(f("%g", 0.1), "0.1");
        assert_eq!(f("%g", 0.0), "0");
        assert_eq!(f("%g", -2.0), "-2");
        assert_eq!(f("%#g", 1.0), "1.00000");
        assert_eq!(f("%.3g", 1.23456), "1.23");
        assert_eq!(f("%.0g", 3.7), "4");
        assert_eq!(f("%G", 1e-10), "1E-10");
        assert_eq!(f("%g", 999999.5), "1e+06");
        assert_eq!(f("%08g", -1.5), "-00001.5");
    }

    #[test]
    fn integers() {
        assert_eq!(f("%d", 3.7), "3");
        assert_eq!(f("%d", -3.7), "-3");
        assert_eq!(f("%d", -0.3), "0");
        assert_eq!(f("%i", 42.0), "42");
        assert_eq!(f("%5d", 42.0), "   42");
        assert_eq!(f("%-5d|", 42.0), "42   |");
        assert_eq!(f("%05d", -42.0), "-0042");
        assert_eq!(f("%+d", 7.0), "+7");
        assert_eq!(f("%.4d", 7.0), "0007");
        assert_eq!(f("%06.3d", 7.0), "   007");
        assert_eq!(f("%d", 1e10), "10000000000");
        assert_eq!(f("%ld", 9.0), "9");
    }

    #[test]
    fn non_finite() {
        assert_eq!(f("%f", f32::INFINITY), "inf");
        assert_eq!(f("%5.1f", f32::NAN), "  nan");
        assert_eq!(f("%E", f32::NEG_INFINITY), "-INF");
        assert_eq!(f("%d", f32::NAN), "nan");
        assert_eq!(f("%05f", f32::INFINITY), "  inf");
        assert_eq!(f("%+g", f32::INFINITY), "+inf");
        assert_eq!(f("%G", f32::NAN), "NAN");
    }

    #[test]
    fn strings() {
        assert_eq!(format("%s", &[Str("hi")]), "hi");
        assert_eq!(format("%5s|", &[Str("hi")]), "   hi|");
        assert_eq!(format("%-5s|", &[Str("hi")]), "hi   |");
        assert_eq!(format("%.2s", &[Str("hello")]), "he");
        assert_eq!(format("%.9s", &[Str("héllo")]), "héllo");
        assert_eq!(format("%.2s", &[Str("héllo")]), "hé");
        assert_eq!(format("%s", &[Float(0.5)]), "0.5");
        assert_eq!(format("%s", &[Triple([1.0, 2.0, 3.0])]), "1 2 3");
        assert_eq!(format("[%s]", &[Str("")]), "[]");
        assert_eq!(format("é %s ü", &[Str("ß")]), "é ß ü");
    }

    #[test]
    fn triples_and_matrices() {
        let c = Triple([1.0, 0.5, 0.0]);
        assert_eq!(format("%c", &[c]), "1 0.5 0");
        assert_eq!(format("%p", &[Triple([-1.25, 2.0, 1e7])]), "-1.25 2 1e+07");
        assert_eq!(format("%.2f", &[c]), "1.00 0.50 0.00");
        assert_eq!(format("%4.1p|", &[c]), "   1  0.5    0|");
        assert_eq!(format("%d", &[Triple([1.5, 2.5, -3.5])]), "1 2 -3");
        let id = crate::shadeops::matrix::IDENTITY;
        assert_eq!(format("%m", &[Matrix(&id)]), "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1");
        assert_eq!(format("%.1f", &[Matrix(&id)]).split(' ').count(), 16);
        assert_eq!(format("%m", &[Float(2.0)]), "2");
        assert_eq!(format("%c", &[Float(0.25)]), "0.25");
        assert_eq!(format("%m", &[c]), "1 0.5 0");
    }

    #[test]
    fn percent_missing_and_extra() {
        assert_eq!(format("%%", &[]), "%");
        assert_eq!(format("100%%", &[Float(1.0)]), "100%");
        assert_eq!(format("%d%%", &[Float(50.0)]), "50%");
        assert_eq!(format("%f %f", &[Float(1.0)]), "1.000000 %f<missing>");
        assert_eq!(format("%5.2f", &[]), "%5.2f<missing>");
        assert_eq!(format("%f", &[Float(1.0), Float(2.0)]), "1.000000");
        assert_eq!(format("no directives", &[Float(1.0)]), "no directives");
        assert_eq!(format("", &[]), "");
        assert_eq!(format("%f", &[Str("text")]), "text");
        assert_eq!(format("%8d|", &[Str("text")]), "    text|");
    }

    #[test]
    fn malformed() {
        assert_eq!(format("abc%", &[Float(1.0)]), "abc%");
        assert_eq!(format("%q %f", &[Float(1.0)]), "%q 1.000000");
        assert_eq!(format("%5", &[Float(1.0)]), "%5");
        assert_eq!(format("%-+", &[]), "%-+");
        assert_eq!(format("%*d", &[Float(1.0)]), "%*d");
        assert_eq!(format("%é", &[]), "%é");
        assert_eq!(format("%.", &[]), "%.");
        assert_eq!(format("%l", &[]), "%l");
        // Huge widths and precisions are clamped, not allocated.
        assert_eq!(f("%99999999999999999999f", 1.0).len(), MAX_WIDTH);
        assert_eq!(f("%.99999999999999999999f", 1.0).len(), MAX_WIDTH + 2);
        assert_eq!(format("%999s", &[Str("x")]).len(), MAX_WIDTH);
        // Random strings over the directive alphabet format without panicking.
        let alphabet: Vec<char> = "%%%-+ #0123456789.lhqfFeEgGdiscpmé*x".chars().collect();
        let mut state = 12345u32;
        let args = [Float(-1.5), Str("ab"), Triple([1.0, f32::NAN, 2.0]), Matrix(&[0.5; 16]), Float(f32::INFINITY)];
        for _ in 0..5000 {
            let mut fmt = String::new();
            for _ in 0..12 {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                fmt.push(alphabet[state as usize % alphabet.len()]);
            }
            let _ = format(&fmt, &args[..(state as usize >> 8) % (args.len() + 1)]);
        }
        // Every prefix of a tricky string formats without panicking.
        let tricky = "%-+ #012.5lf|%%|%.s|%c|%é|%";
        for end in (0..=tricky.len()).filter(|i| tricky.is_char_boundary(*i)) {
            let _ = format(&tricky[..end], &[Float(1.0), Str("s"), Triple([1.0; 3])]);
        }
    }
}

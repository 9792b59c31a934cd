//! The front end never panics: random bytes and randomly mutated real shaders go through the
//! preprocessor, lexer, parser and checker and come out as diagnostics.

use proptest::prelude::*;
use rtsl_compiler::{compile_source, compile_source_at, Options};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Real shaders to mutate: the library and the corpus, with their text.
fn seeds() -> &'static [(PathBuf, String)] {
    static SEEDS: OnceLock<Vec<(PathBuf, String)>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let mut out = Vec::new();
        for dir in ["../stdlib_shaders", "../tests/corpus"] {
            let mut stack = vec![PathBuf::from(dir)];
            while let Some(d) = stack.pop() {
                for e in std::fs::read_dir(&d).expect("directory").flatten() {
                    let p = e.path();
                    if p.is_dir() {
                        stack.push(p);
                    } else if p.extension().is_some_and(|x| x == "sl" || x == "h") {
                        let text = std::fs::read_to_string(&p).expect("readable");
                        out.push((p, text));
                    }
                }
            }
        }
        out.sort();
        out
    })
}

fn options() -> Options {
    let mut o = Options::default();
    o.preprocessor.include_paths.push(Path::new("../tests/corpus/include").to_path_buf());
    o
}

/// Fragments that stress the grammar and the preprocessor when spliced in anywhere.
const FRAGMENTS: &[&str] = &[
    "(",
    ")",
    "{",
    "}",
    "[",
    "]",
    ";",
    ",",
    ".",
    "^",
    "?",
    ":",
    "=",
    "+=",
    "++",
    "#",
    "##",
    "\n#define X(a) a##a\n",
    "\n#if 1\n",
    "\n#endif\n",
    "\n#else\n",
    "\n#include \"noises.h\"\n",
    "\"",
    "/*",
    "*/",
    "//",
    "\\\n",
    "float",
    "color",
    "point",
    "uniform",
    "varying",
    "output",
    "extern",
    "illuminance(P)",
    "illuminate(P)",
    "solar()",
    "gather(\"\", P, N, 1, 1)",
    "break 3;",
    "continue;",
    "return",
    "surface",
    "light",
    "matrix \"world\" 1",
    "color \"hsv\" (1,0,0)",
    "noise(",
    "texture(\"x\"[",
    "Ci",
    "L",
    "Cl",
    "0x",
    "1e999",
    ".",
    "@",
    "$",
    "'",
    "float f(output float x) { return x; }",
    "f(1)",
    "(1,2,3)",
    "{1,2}",
    "-",
    "!",
    "&&",
    "||",
];

#[derive(Debug, Clone)]
enum Mutation {
    Delete { at: usize, len: usize },
    Insert { at: usize, fragment: usize },
    Duplicate { at: usize, len: usize },
    Truncate { at: usize },
    Swap { a: usize, b: usize, len: usize },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1usize..40).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (any::<usize>(), 0..FRAGMENTS.len()).prop_map(|(at, fragment)| Mutation::Insert { at, fragment }),
        (any::<usize>(), 1usize..80).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        any::<usize>().prop_map(|at| Mutation::Truncate { at }),
        (any::<usize>(), any::<usize>(), 1usize..20).prop_map(|(a, b, len)| Mutation::Swap { a, b, len }),
    ]
}

fn floor_char(s: &str, i: usize) -> usize {
    let mut i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn apply(text: &str, m: &Mutation) -> String {
    let n = text.len().max(1);
    match *m {
        Mutation::Delete { at, len } => {
            let a = floor_char(text, at % n);
            let b = floor_char(text, a + len);
            format!("{}{}", &text[..a], &text[b..])
        }
        Mutation::Insert { at, fragment } => {
            let a = floor_char(text, at % n);
            format!("{}{}{}", &text[..a], FRAGMENTS[fragment], &text[a..])
        }
        Mutation::Duplicate { at, len } => {
            let a = floor_char(text, at % n);
            let b = floor_char(text, a + len);
            format!("{}{}{}", &text[..b], &text[a..b], &text[b..])
        }
        Mutation::Truncate { at } => text[..floor_char(text, at % n)].to_string(),
        Mutation::Swap { a, b, len } => {
            let a0 = floor_char(text, a % n);
            let a1 = floor_char(text, a0 + len);
            let b0 = floor_char(text, b % n);
            let b1 = floor_char(text, b0 + len);
            if a1 <= b0 {
                format!("{}{}{}{}{}", &text[..a0], &text[b0..b1], &text[a1..b0], &text[a0..a1], &text[b1..])
            } else {
                text.to_string()
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_give_diagnostics_not_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let text = String::from_utf8_lossy(&bytes);
        let c = compile_source("random.sl", &text, &options());
        // Rendering must not panic either, whatever the spans.
        let _ = c.render();
    }

    #[test]
    fn mutated_shaders_give_diagnostics_not_panics(
        seed in any::<proptest::sample::Index>(),
        mutations in proptest::collection::vec(mutation(), 1..6),
    ) {
        let seeds = seeds();
        let (path, text) = &seeds[seed.index(seeds.len())];
        let mut text = text.clone();
        for m in &mutations {
            text = apply(&text, m);
        }
        let c = compile_source_at(path, &text, &options());
        let _ = c.render();
        for d in &c.diagnostics {
            let _ = d.to_json(&c.sources);
        }
    }

    #[test]
    fn token_soup_gives_diagnostics_not_panics(parts in proptest::collection::vec(0..FRAGMENTS.len(), 0..60)) {
        let text: String = parts.iter().map(|&i| FRAGMENTS[i]).collect::<Vec<_>>().join(" ");
        let c = compile_source("soup.sl", &text, &options());
        let _ = c.render();
    }
}

#[test]
fn every_seed_still_compiles_unmutated() {
    // A sanity check of the harness: the seeds are valid shaders and headers.
    for (path, text) in seeds() {
        if path.extension().is_some_and(|x| x == "sl") {
            let c = compile_source_at(path, text, &options());
            assert!(c.ok(), "{}:\n{}", path.display(), c.render());
        }
    }
}

/// `#if` expressions recurse once per level of parentheses, unary operators or `?:`; a deep one is
/// refused with a located diagnostic instead of overflowing the stack (test threads have small
/// stacks, so an unbounded evaluator fails here).
#[test]
fn deep_if_expressions_are_refused_with_a_location() {
    let cases = [
        format!("{}1{}", "(".repeat(6000), ")".repeat(6000)),
        format!("{}1", "!".repeat(20_000)),
        format!("{}1{}", "1 ? ".repeat(6000), " : 1".repeat(6000)),
        format!("{}1", "-~".repeat(10_000)),
    ];
    for expr in &cases {
        let src = format!("// deep\n#if {expr}\n#endif\nsurface s() {{}}\n");
        let c = compile_source("deep.sl", &src, &options());
        assert!(!c.ok());
        let lines: Vec<String> = c.diagnostics.iter().map(|d| d.one_line(&c.sources)).collect();
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(lines[0].starts_with("deep.sl:2:"), "{}", lines[0]);
        assert!(lines[0].contains("error[E0006]"), "{}", lines[0]);
        assert!(lines[0].contains("nests more than 400 levels deep"), "{}", lines[0]);
    }
    // Nesting within the limit still evaluates.
    let src = format!("#if {}0{}\n#error reached\n#endif\n", "!(".repeat(151), ")".repeat(151));
    let c = compile_source("shallow.sl", &src, &options());
    let codes: Vec<&str> = c.diagnostics.iter().map(|d| d.code.as_str()).collect();
    assert_eq!(codes, ["E0009"], "{}", c.render());
}

/// A line of 10,000 bad characters: one error each, but only the first hundred are shown, each
/// with a window of the line rather than all of it, and a final note counts the rest.
#[test]
fn thousands_of_errors_on_one_line_give_bounded_output() {
    let src = format!("surface s() {{ {} }}\n", "@".repeat(10_000));
    let c = compile_source("at.sl", &src, &options());
    assert!(!c.ok());
    assert_eq!(c.diagnostics.len(), rtsl_compiler::diagnostic::MAX_REPORTED);
    assert_eq!(c.errors(), 10_000);
    let out = c.render();
    assert!(out.len() < 100 * 1000, "{} bytes of diagnostics", out.len());
    assert!(out.ends_with("note: 9900 more errors not shown (only the first 100 diagnostics of a file are reported)\n"));
    // Columns stay those of the real line.
    assert!(out.contains("at.sl:1:15\n"), "{}", &out[..out.len().min(2000)]);
    assert!(out.contains("at.sl:1:114\n"));
}

/// A mistake far into a long line is shown with its neighbourhood, between `...`, at its real
/// column.
#[test]
fn a_long_line_is_clipped_around_the_mistake() {
    let filler = "x = x + 1; ".repeat(500);
    let src = format!("surface s() {{ float x = 0; {filler}x = @; {filler}Ci = x; }}\n");
    let c = compile_source("long.sl", &src, &options());
    let out = c.render();
    assert!(out.len() < 2000, "{out}");
    let column = src.find('@').expect("an @") + 1;
    assert!(out.contains(&format!("long.sl:1:{column}\n")), "{out}");
    let shown = out.lines().find(|l| l.contains('@')).expect("the line is shown");
    assert!(shown.contains("...") && shown.ends_with("..."), "{shown}");
    let caret = out.lines().find(|l| l.contains('^') && !l.contains('@')).expect("a caret");
    assert_eq!(caret.find('^'), shown.find('@'), "the caret is under the `@`:\n{out}");
}

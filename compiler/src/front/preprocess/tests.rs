use super::*;
use crate::diagnostic::Diagnostics;

/// Preprocesses `main` (with extra virtual headers written to a temporary directory) and returns the
/// output spelled back as text, plus the diagnostic codes.
fn run_with(main: &str, headers: &[(&str, &str)], options: Options) -> (String, Vec<&'static str>) {
    let dir = std::env::temp_dir().join(format!("rtsl-pp-{}-{}", std::process::id(), unique()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in headers {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(path, text).unwrap();
    }
    let main_path = dir.join("main.sl");
    std::fs::write(&main_path, main).unwrap();
    let mut sources = SourceMap::new();
    let mut interner = Interner::new();
    let mut diags = Diagnostics::default();
    let file = sources.load(&main_path).unwrap();
    let out =
        preprocess(Vec::new(), file, &mut sources, &mut interner, &mut HeaderCache::default(), &options, &mut diags);
    let text: Vec<String> = out
        .tokens
        .iter()
        .filter(|t| t.kind != TokenKind::Eof)
        .map(|t| match t.kind {
            TokenKind::Ident | TokenKind::Number => interner.resolve(t.sym).to_string(),
            TokenKind::String => format!("\"{}\"", interner.resolve(t.sym)),
            k => k.spelling().to_string(),
        })
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    (text.join(" "), diags.list.iter().map(|d| d.code.as_str()).collect())
}

fn unique() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    N.fetch_add(1, Ordering::Relaxed)
}

fn run(main: &str) -> (String, Vec<&'static str>) {
    run_with(main, &[], Options::default())
}

#[test]
fn object_and_function_macros() {
    let (out, d) = run("#define PI 3.14\n#define SQR(x) ((x)*(x))\nSQR(PI + 1)");
    assert_eq!(out, "( ( 3.14 + 1 ) * ( 3.14 + 1 ) )");
    assert!(d.is_empty());
}

#[test]
fn function_macro_name_without_parens_is_not_expanded() {
    let (out, _) = run("#define f(x) x\nf + f(2)");
    assert_eq!(out, "f + 2");
}

#[test]
fn self_reference_is_not_expanded_again() {
    let (out, _) = run("#define foo foo + 1\n#define a b\n#define b a\nfoo a");
    assert_eq!(out, "foo + 1 a");
}

#[test]
fn stringify_and_paste() {
    let (out, d) = run("#define S(x) #x\n#define CAT(a, b) a##b\nS(hello world) CAT(foo, 2) CAT(, z)");
    assert_eq!(out, "\"hello world\" foo2 z");
    assert!(d.is_empty(), "{d:?}");
}

#[test]
fn arguments_are_expanded_before_substitution() {
    let (out, _) = run("#define ONE 1\n#define ID(x) x\n#define S(x) #x\n#define XS(x) S(x)\nID(ONE) S(ONE) XS(ONE)");
    assert_eq!(out, "1 \"ONE\" \"1\"");
}

#[test]
fn conditionals() {
    let src = "#define A 2\n#if A > 1 && defined(A)\nyes\n#elif 1\nno1\n#else\nno2\n#endif\n#ifdef B\nno3\n#else\nyes2\n#endif\n#ifndef B\nyes3\n#endif\n#if 0\n#if 1\nno4\n#endif\n#else\nyes4\n#endif";
    let (out, d) = run(src);
    assert_eq!(out, "yes yes2 yes3 yes4");
    assert!(d.is_empty(), "{d:?}");
}

#[test]
fn excluded_code_is_not_lexed_for_errors() {
    let (out, d) = run("#if 0\nit's @ bad \"\n#endif\nok");
    assert_eq!(out, "ok");
    assert!(d.is_empty(), "{d:?}");
}

#[test]
fn includes_with_guards_and_search_path() {
    let headers =
        [("inc/a.h", "#ifndef A_H\n#define A_H\n#include \"b.h\"\nfloat a;\n#endif\n"), ("inc/b.h", "float b;\n")];
    let options = Options { include_paths: vec![], ..Options::default() };
    let (out, d) = run_with("#include \"inc/a.h\"\n#include \"inc/a.h\"\nx", &headers, options);
    assert_eq!(out, "float b ; float a ; x");
    assert!(d.is_empty(), "{d:?}");
}

#[test]
fn include_errors() {
    let (_, d) = run("#include \"nope.h\"\n");
    assert_eq!(d, vec!["E0001"]);
    let headers = [("self.h", "#include \"self.h\"\n")];
    let (_, d) = run_with("#include \"self.h\"\n", &headers, Options::default());
    assert_eq!(d, vec!["E0002"]);
}

#[test]
fn directive_errors() {
    assert_eq!(run("#if 1\nx").1, vec!["E0003"]);
    assert_eq!(run("#endif\n").1, vec!["E0004"]);
    assert_eq!(run("#define\n").1, vec!["E0005"]);
    assert_eq!(run("#if 1 +\n#endif\n").1, vec!["E0006"]);
    assert_eq!(run("#define F(a,b) a\nF(1)").1, vec!["E0007"]);
    assert_eq!(run("#define F(a) a\nF(1").1, vec!["E0008"]);
    assert_eq!(run("#error stop here\n").1, vec!["E0009"]);
    assert_eq!(run("#pragma foo\n#bogus\n").1, vec!["W0005", "W0005"]);
    assert_eq!(run("#define A 1\n#define A 2\n").1, vec!["W0006"]);
    assert_eq!(run("#define A 1\n#define A 1\n").1, Vec::<&str>::new());
}

#[test]
fn command_line_and_predefined_macros() {
    let options =
        Options { defines: vec![("FOO".into(), Some("3".into())), ("BAR".into(), None)], ..Options::default() };
    let (out, _) = run_with("FOO BAR RTSL\n#ifdef RTSL_VERSION\nv\n#endif", &[], options);
    assert_eq!(out, "3 1 1 v");
}

#[test]
fn runaway_expansion_is_stopped() {
    // Each level doubles the output: 2^40 tokens would never finish.
    let mut src = String::from("#define L0 x x\n");
    for i in 1..40 {
        src.push_str(&format!("#define L{i} L{p} L{p}\n", p = i - 1));
    }
    src.push_str("L39\n");
    let (_, d) = run(&src);
    assert_eq!(d, vec!["E0010"]);
}

#[test]
fn multiline_macro_call_and_continuation() {
    let (out, _) = run("#define ADD(a, b) \\\n  (a + b)\nADD(1,\n 2)");
    assert_eq!(out, "( 1 + 2 )");
}

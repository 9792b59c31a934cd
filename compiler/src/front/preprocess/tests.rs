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
    // A conditional open at the end of its file ends there, with a warning; the shader is kept.
    assert_eq!(run("#if 1\nx"), ("x".to_string(), vec!["W0011"]));
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

#[test]
fn standard_headers_are_found_last_on_the_include_path() {
    let (out, codes) = run_with("#include \"filterwidth.h\"\nMINFILTWIDTH\n", &[], Options::default());
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(out, "1.0e-6");
    // A header of the same name beside the shader wins.
    let (out, codes) =
        run_with("#include <filterwidth.h>\nMINFILTWIDTH\n", &[("filterwidth.h", "#define MINFILTWIDTH 7\n")], Options::default());
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!(out, "7");
}

#[test]
fn every_standard_header_compiles_in_a_shader_that_uses_it() {
    let src = "#include \"noises.h\"\n#include \"patterns.h\"\n\
               surface s(float freq = 4) {\n\
                 point p = transform(\"shader\", P) * freq;\n\
                 float fw = filterwidthp(p);\n\
                 float n = fBm(p, fw, 6, 2, 0.5) + turbulence(p, fw, 4, 2, 0.5);\n\
                 vector vn = vfBm(p, fw, 3, 2, 0.5);\n\
                 float f1; point pos1;\n\
                 voronoi_f1_3d(p, 1, f1, pos1);\n\
                 float stripes = filteredpulsetrain(0.5, 1, s * 10, filterwidth(s * 10));\n\
                 float edges = filteredpulse(0.2, 0.8, t, filterwidth(t)) * smoothpulse(0, .1, .9, 1, s);\n\
                 float a = filteredabs(s - 0.5, filterwidth(s)) + filteredstep(0.5, t, filterwidth(t))\n\
                           + filteredsmoothstep(0, 1, s, filterwidth(s)) + pulsetrain(0.5, 1, s)\n\
                           + smoothpulsetrain(0, .1, .4, .5, 1, t) + pulse(0, 1, s);\n\
                 Ci = color(n, stripes * edges, f1) + (color vn) + fadeout(a, 0.5, 1, fw) + distance(pos1, p);\n\
               }\n";
    let c = crate::compile_source("uses.sl", src, &crate::Options::default());
    let errors: Vec<String> = c.diagnostics.iter().map(|d| d.message.clone()).collect();
    assert!(c.ok(), "{errors:?}");
    // No warnings either: `--werror` builds include these too.
    assert!(c.diagnostics.is_empty(), "{errors:?}");
    let module = c.module.expect("a module");
    crate::back::jit::compile(&module).expect("the JIT compiles it");
}

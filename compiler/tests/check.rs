//! The broken-shader suite: every file in `tests/check/err/` holds one mistake, names the diagnostic
//! code it must produce on its first line (`// expect: E0100`), and has the full rendered diagnostics
//! beside it in `<name>.stderr`. `RTSL_BLESS=1 cargo test` rewrites the `.stderr` files.

use rtsl_compiler::{compile_file, Code, Options, Severity};
use std::path::{Path, PathBuf};

fn err_dir() -> PathBuf {
    Path::new("tests").join("check").join("err")
}

fn shaders(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("the err directory exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "sl"))
        .collect();
    v.sort();
    v
}

#[test]
fn broken_shaders_report_the_expected_diagnostics() {
    let bless = std::env::var_os("RTSL_BLESS").is_some();
    let mut options = Options::default();
    options.preprocessor.include_paths.push(err_dir().join("include"));
    let mut failures = Vec::new();
    let mut error_kinds = std::collections::BTreeSet::new();
    let files = shaders(&err_dir());
    assert!(files.len() >= 40, "the suite has {} files", files.len());
    for path in &files {
        let text = std::fs::read_to_string(path).expect("readable");
        let expected = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("// expect: "))
            .unwrap_or_else(|| panic!("{} has no `// expect:` line", path.display()))
            .trim()
            .to_string();
        let c = compile_file(path, &options).expect("readable");
        let codes: Vec<&str> = c.diagnostics.iter().map(|d| d.code.as_str()).collect();
        if !codes.contains(&expected.as_str()) {
            failures.push(format!("{}: expected {expected}, got {codes:?}\n{}", path.display(), c.render()));
            continue;
        }
        let code = Code::ALL.iter().find(|c| c.as_str() == expected).expect("a known code");
        if code.severity() == Severity::Error {
            error_kinds.insert(expected.clone());
            assert!(c.module.is_none(), "{}: an error still produced IR", path.display());
        } else {
            assert!(c.ok(), "{}: a warning case has errors:\n{}", path.display(), c.render());
        }
        let rendered = c.render();
        let golden = path.with_extension("stderr");
        if bless {
            std::fs::write(&golden, &rendered).expect("writable");
        } else {
            match std::fs::read_to_string(&golden) {
                Ok(want) if want == rendered => {}
                Ok(want) => failures.push(format!(
                    "{}: rendered diagnostics differ (RTSL_BLESS=1 to accept)\n--- expected\n{want}\n--- got\n{rendered}",
                    path.display()
                )),
                Err(_) => failures.push(format!("{}: missing {} (RTSL_BLESS=1 to write it)", path.display(), golden.display())),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    assert!(error_kinds.len() >= 30, "only {} distinct error kinds are tested: {error_kinds:?}", error_kinds.len());
}

/// Warnings the shader's author did not ask for are not shown: unused variables and parameters in
/// an included header (library code), and any warning on the line after `#pragma nolint`, which
/// is itself taken without a word. The compiled file's own unused variable is still reported.
#[test]
fn headers_unused_names_and_nolint_lines_are_quiet() {
    let path = Path::new("tests").join("check").join("quiet").join("quiet.sl");
    let c = compile_file(&path, &Options::default()).expect("readable");
    assert!(c.ok(), "{}", c.render());
    let shown: Vec<(&str, &str)> = c.diagnostics.iter().map(|d| (d.code.as_str(), d.message.as_str())).collect();
    assert_eq!(shown, [("W0001", "unused variable `noisy`")], "{}", c.render());
}

/// `docs/diagnostics.md` is generated from the code table; `RTSL_BLESS=1` regenerates it.
#[test]
fn every_diagnostic_code_is_documented() {
    let mut text = String::from(
        "# Diagnostics\n\nEvery diagnostic the compiler emits has a stable code. Errors stop a shader from compiling;\n\
         warnings do not (unless `rtsl compile --werror`). Each code has at least one example in\n\
         `compiler/tests/check/err/`, with its rendered output beside it.\n\n\
         This file is generated from `Code::ALL` in `compiler/src/diagnostic.rs` (`RTSL_BLESS=1 cargo test`).\n\n\
         | code | severity | meaning |\n|---|---|---|\n",
    );
    for code in Code::ALL {
        let sev = if code.severity() == Severity::Error { "error" } else { "warning" };
        text.push_str(&format!("| {} | {sev} | {} |\n", code.as_str(), code.description().replace('|', "\\|")));
    }
    let path = Path::new("..").join("docs").join("diagnostics.md");
    if std::env::var_os("RTSL_BLESS").is_some() {
        std::fs::write(&path, &text).expect("writable");
    }
    let docs = std::fs::read_to_string(&path).unwrap_or_default();
    assert_eq!(docs, text, "docs/diagnostics.md is out of date: run with RTSL_BLESS=1");
}

/// Six functions, each nesting 390 levels deep and calling the next at its innermost level: each
/// is within the checker's nesting limit, but inlined they nest 2,340 levels, which overflowed the
/// stack of the back ends that recurse over blocks. The checker refuses it at the call.
#[test]
fn nesting_that_adds_up_along_a_chain_of_calls_is_refused() {
    let depth = 390;
    let mut src = String::from("float f0(float x) { return x; }\n");
    for i in 1..6 {
        src += &format!("float f{i}(float x) {{ float r = x;\n");
        src += &"if (x > 0) {\n".repeat(depth);
        src += &format!("r = f{}(x);\n", i - 1);
        src += &"}\n".repeat(depth);
        src += "return r; }\n";
    }
    src += "surface s() { Ci = f5(s); }\n";
    let c = rtsl_compiler::compile_source("chain.sl", &src, &Options::default());
    assert!(c.module.is_none(), "refused");
    let e = c.diagnostics.iter().find(|d| d.code == Code::InlineBudget).expect("E0137");
    let shown = e.one_line(&c.sources);
    assert!(shown.contains("`f5`") && shown.contains("past the limit of 512"), "{shown}");
    // A short chain of the same functions is fine.
    let short = src.replace("Ci = f5(s)", "Ci = f1(s)");
    let c = rtsl_compiler::compile_source("short.sl", &short, &Options::default());
    assert!(c.module.is_some(), "{}", c.render());
}

/// Context rules (which globals a shader type has, where light loops run) apply where a function
/// is used, as in PRMan and Aqsis: a header's helpers for other shader types do not fail a shader
/// that does not call them.
#[test]
fn context_rules_apply_to_the_functions_a_shader_calls() {
    let helpers = "color lighting(normal Nn) {\n\
                     extern point P;\n\
                     color C = 0;\n\
                     illuminance(P, Nn, PI/2) { C += Cl; }\n\
                     return C;\n\
                   }\n\
                   float facing() { extern vector I; extern normal N; return normalize(N) . normalize(I); }\n";
    let uncalled =
        format!("{helpers}displacement d(float Km = 0.1) {{ P += Km * normalize(N); N = calculatenormal(P); }}\n");
    let c = rtsl_compiler::compile_source("uncalled.sl", &uncalled, &Options::default());
    assert!(c.ok() && c.diagnostics.is_empty(), "{}", c.render());
    let light = format!("{helpers}light l(float intensity = 1) {{ illuminate(Ps) {{ Cl = intensity; }} }}\n");
    let c = rtsl_compiler::compile_source("light.sl", &light, &Options::default());
    assert!(c.ok(), "{}", c.render());

    // Called, the same helpers fail the shader, each error where the helper breaks the rule.
    let called = format!(
        "{helpers}displacement d(float Km = 0.1) {{ P += Km * normalize(N) * comp(lighting(N), 0); N = calculatenormal(P); }}\n"
    );
    let c = rtsl_compiler::compile_source("called.sl", &called, &Options::default());
    let codes: Vec<&str> = c.diagnostics.iter().map(|d| d.code.as_str()).collect();
    assert!(!c.ok() && codes.contains(&"E0111") && codes.contains(&"E0100"), "{}", c.render());
    assert!(c.render().contains("in a function this shader calls"), "{}", c.render());
    let called = format!("{helpers}light l() {{ illuminate(Ps) {{ Cl = facing(); }} }}\n");
    let c = rtsl_compiler::compile_source("called_light.sl", &called, &Options::default());
    assert!(!c.ok() && c.render().contains("`I` is not available in light shaders"), "{}", c.render());
}

/// Another renderer's name for a built-in is read as rtsl's with W0012; a function the shader
/// defines under that name is its own.
#[test]
fn vendor_names_are_read_as_rtsl_s_built_ins_unless_defined() {
    let c = rtsl_compiler::compile_source("v.sl", "surface v() { Ci = raylevel(); }\n", &Options::default());
    let codes: Vec<&str> = c.diagnostics.iter().map(|d| d.code.as_str()).collect();
    assert!(c.ok() && codes == ["W0012"], "{}", c.render());
    let own = "float raylevel() { return 7; }\nsurface v() { Ci = raylevel(); }\n";
    let c = rtsl_compiler::compile_source("own.sl", own, &Options::default());
    assert!(c.ok() && c.diagnostics.is_empty(), "{}", c.render());
    // lucille's `turb` likewise: a library's own `turb` (often a float of one point) is used.
    let own = "float turb(point p) { return xcomp(p); }\nsurface v() { Ci = turb(P); }\n";
    let c = rtsl_compiler::compile_source("own.sl", own, &Options::default());
    assert!(c.ok() && c.diagnostics.is_empty(), "{}", c.render());
}

/// The shader-type words begin a shader only at the top level; elsewhere RenderMan shaders use them
/// as ordinary names (`color light = color (1,.3,.2);` ... `base = mix(dark,light,nz);`), and
/// message passing still calls `surface("Kd", x)`. Type names and statement keywords stay reserved.
#[test]
fn shader_type_words_are_ordinary_names_below_the_top_level() {
    let src = r#"
        float imager(float light; float surface[2]) { return light + surface[1]; }
        surface tissue(float volume = 1; color displacement = 0;)
        {
            color dark = color(.5, .1, .1), light = color (1,.3,.2);
            color glow, light2[2];
            float camera = 0, pixel;
            float nz = noise(P * light[0]);
            light2[1] = mix(dark, light, nz);
            glow = light2[1] + displacement;
            float two[2] = {1, 2};
            nz = imager(nz, two);
            camera += volume * nz;
            pixel = surface("Kd", camera);
            float x = 0;
            float lightfield(float light) { return light * 2; }
            x = lightfield(pixel);
            Ci = glow * camera * x;
            Oi = Os;
        }
    "#;
    let c = rtsl_compiler::compile_source("tissue.sl", src, &Options::default());
    assert!(c.ok() && c.diagnostics.is_empty(), "{}", c.render());
    let iface = c.interface.expect("a shader");
    let names: Vec<&str> = iface.parameters.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["volume", "displacement"]);

    // Every shader type still begins a definition, with any of the words as a name inside it.
    let words = ["surface", "light", "displacement", "volume", "imager", "pixel", "camera", "lightfield"];
    for kind in words {
        for word in words {
            let src = format!(
                "{kind} t(float {word} = 1;) {{\n\
                   float a[2] = {{{word}, 0}}; {word} = a[0] * 2; printf(\"%f\", {word});\n\
                   {{ float {word}[2] = {{1, 2}}; {word}[1] += 1; printf(\"%f\", {word}[1]); }}\n\
                 }}\n"
            );
            let c = rtsl_compiler::compile_source("t.sl", &src, &Options::default());
            assert!(c.ok(), "{src}{}", c.render());
            let want = if kind == "pixel" { "imager" } else { kind };
            assert_eq!(c.interface.as_ref().map(|i| i.kind.name()), Some(want), "{src}");
        }
    }

    // Other keywords are not names.
    for src in ["surface t() { float float = 1; }", "surface t() { float if = 1; }", "surface t(float color = 1) { }"] {
        let c = rtsl_compiler::compile_source("t.sl", src, &Options::default());
        assert!(c.diagnostics.iter().any(|d| d.code == Code::Syntax), "{src}: {}", c.render());
    }
}

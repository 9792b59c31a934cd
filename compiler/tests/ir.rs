//! IR golden tests: each `tests/ir/<name>.sl` compiles to IR whose text form is `<name>.ir`
//! (`RTSL_BLESS=1` rewrites them). The validator must accept the IR of every test and of the corpus.

use rtsl_compiler::ir::print;
use rtsl_compiler::{compile_file, Options};
use std::path::Path;

#[test]
fn ir_matches_golden_text() {
    let bless = std::env::var_os("RTSL_BLESS").is_some();
    let mut files: Vec<_> = std::fs::read_dir("tests/ir")
        .expect("tests/ir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "sl"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    let mut failures = Vec::new();
    for path in files {
        let c = compile_file(&path, &Options::default()).expect("readable");
        let Some(module) = &c.module else {
            failures.push(format!("{} does not compile:\n{}", path.display(), c.render()));
            continue;
        };
        let text = print::module(module);
        let golden = path.with_extension("ir");
        if bless {
            std::fs::write(&golden, &text).expect("writable");
        } else if std::fs::read_to_string(&golden).ok().as_deref() != Some(text.as_str()) {
            failures.push(format!(
                "{}: IR differs from {} (RTSL_BLESS=1 to accept):\n{text}",
                path.display(),
                golden.display()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn inference_results() {
    let c = compile_file(Path::new("tests/ir/uniformity.sl"), &Options::default()).expect("readable");
    let m = c.module.expect("compiles");
    let body = m.function(m.shader.as_ref().expect("shader").body);
    let storage = |name: &str| body.vars.iter().find(|v| v.name == name).map(|v| v.varying);
    assert_eq!(storage("k"), Some(false), "twice(uniform) is uniform");
    assert_eq!(storage("n"), Some(true), "noise(P) is varying");
    assert_eq!(storage("acc"), Some(true), "assigned under a varying condition");
    assert_eq!(storage("depth"), Some(false), "rayinfo results are uniform");
    let twice = m.functions.iter().find(|f| f.name == "twice").expect("twice");
    assert!(!twice.reads_varying);
}

#[test]
fn validator_rejects_broken_ir() {
    let c = compile_file(Path::new("tests/ir/conversions.sl"), &Options::default()).expect("readable");
    let mut m = c.module.expect("compiles");
    assert!(rtsl_compiler::valid::validate(&m).is_ok());
    // Use one expression twice: IR must stay a tree.
    let body = m.shader.as_ref().expect("shader").body.0 as usize;
    let f = &mut m.functions[body];
    let first = f.body.stmts[0].clone();
    f.body.stmts.push(first);
    let errors = rtsl_compiler::valid::validate(&m).expect_err("a shared expression is invalid");
    assert!(errors.iter().any(|e| e.contains("used 2 times")), "{errors:?}");
}

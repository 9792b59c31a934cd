//! The shader library and the conformance corpus compile; the library without a single warning.

mod common;

use rtsl_compiler::{compile_file, Options};
use std::path::{Path, PathBuf};

fn compile_all(dir: &Path, include: Option<&Path>) -> Vec<(PathBuf, rtsl_compiler::Compilation)> {
    let mut files = Vec::new();
    files.extend(common::shader_files(dir));
    let mut options = Options::default();
    options.preprocessor.include_paths.extend(include.map(Path::to_path_buf));
    files
        .into_iter()
        .map(|f| {
            let c = compile_file(&f, &options).expect("readable");
            (f, c)
        })
        .collect()
}

#[test]
fn the_shader_library_compiles_without_warnings() {
    let results = compile_all(Path::new("../stdlib_shaders"), None);
    assert!(results.len() >= 25);
    for (path, c) in &results {
        assert!(c.diagnostics.is_empty(), "{}:\n{}", path.display(), c.render());
        assert!(c.interface.is_some(), "{} defines no shader", path.display());
    }
    let names: Vec<&str> = results.iter().filter_map(|(_, c)| c.shader.as_ref().map(|s| s.1.as_str())).collect();
    for required in [
        "constant",
        "matte",
        "metal",
        "shinymetal",
        "plastic",
        "paintedplastic",
        "ambientlight",
        "distantlight",
        "pointlight",
        "spotlight",
        "depthcue",
        "fog",
        "bumpy",
        "arealight",
        "wood",
        "marble",
        "granite",
        "checker",
        "brick",
        "mirror",
        "glass",
        "bumpymirror",
        "texmap",
        "material",
    ] {
        assert!(names.contains(&required), "the library lacks `{required}`");
    }
}

#[test]
fn the_conformance_corpus_compiles() {
    let results = compile_all(Path::new("../tests/corpus"), Some(Path::new("../tests/corpus/include")));
    assert!(results.len() >= 50);
    let failed: Vec<String> =
        results.iter().filter(|(_, c)| !c.ok()).map(|(p, c)| format!("{}:\n{}", p.display(), c.render())).collect();
    assert!(failed.is_empty(), "{}", failed.join("\n"));
    // Every shader type appears.
    let kinds: std::collections::BTreeSet<&str> =
        results.iter().filter_map(|(_, c)| c.shader.as_ref().map(|s| s.0.name())).collect();
    for k in ["surface", "light", "displacement", "volume", "imager", "camera", "lightfield"] {
        assert!(kinds.contains(k), "no {k} shader in the corpus");
    }
}

/// The second batch stresses idioms of the classic collections (an uber light, filtered patterns,
/// fBm with early exits, preprocessor-heavy code, PI without a definition, string arrays as map names).
#[test]
fn the_second_corpus_compiles_without_warnings() {
    let results = compile_all(Path::new("../tests/corpus2"), Some(Path::new("../tests/corpus2/include")));
    assert!(results.len() >= 25);
    let bad: Vec<String> = results
        .iter()
        .filter(|(_, c)| !c.diagnostics.is_empty())
        .map(|(p, c)| format!("{}:\n{}", p.display(), c.render()))
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn interfaces_report_parameters_and_defaults() {
    let c = compile_file(Path::new("../stdlib_shaders/surface/plastic.sl"), &Options::default()).expect("readable");
    let iface = c.interface.expect("plastic is a shader");
    assert_eq!(iface.name, "plastic");
    let ks = iface.parameters.iter().find(|p| p.name == "Ks").expect("Ks");
    assert_eq!(ks.default, Some(rtsl_compiler::interface::Value::Float(0.5)));
    assert_eq!(ks.storage, "uniform");
    let spec = iface.parameters.iter().find(|p| p.name == "specularcolor").expect("specularcolor");
    assert_eq!(spec.default.as_ref().map(|v| v.to_string()).as_deref(), Some("[1 1 1]"));
    let c = compile_file(Path::new("../stdlib_shaders/light/spotlight.sl"), &Options::default()).expect("readable");
    let iface = c.interface.expect("spotlight");
    let from = iface.parameters.iter().find(|p| p.name == "from").expect("from");
    assert_eq!(from.default.as_ref().map(|v| v.to_string()).as_deref(), Some("\"shader\" [0 0 0]"));
    let cone = iface.parameters.iter().find(|p| p.name == "coneangle").expect("coneangle");
    match cone.default {
        Some(rtsl_compiler::interface::Value::Float(v)) => assert!((v - 30f32.to_radians()).abs() < 1e-6),
        ref other => panic!("coneangle default {other:?}"),
    }
}

/// Every library and corpus shader stays far within the inlining budget (`ir::INLINE_BUDGET`), so
/// the budget refuses only runaway call trees, never a real shader.
#[test]
fn every_shader_is_far_within_the_inlining_budget() {
    let (files, options) = common::library_and_corpora();
    let mut largest = (0, PathBuf::new());
    for f in files {
        let c = compile_file(&f, &options).expect("readable");
        let Some(m) = &c.module else { continue };
        let Some(shader) = &m.shader else { continue };
        let size = rtsl_compiler::ir::inlined_sizes(m)[shader.body.0 as usize];
        if size > largest.0 {
            largest = (size, f);
        }
    }
    println!("largest inlined shader: {} ({} IR nodes)", largest.1.display(), largest.0);
    assert!(largest.0 > 0);
    assert!(
        largest.0 * 8 <= rtsl_compiler::ir::INLINE_BUDGET,
        "{} inlines to {} IR nodes: within 8x of the budget of {}",
        largest.1.display(),
        largest.0,
        rtsl_compiler::ir::INLINE_BUDGET
    );
}

/// Every library and corpus shader stays far within the storage budget (`ir::STORAGE_BUDGET`)
/// and, with its arrays counted by their floats, within the inlining budget, so the budgets refuse
/// only runaway arrays, never a real shader.
#[test]
fn every_shader_is_far_within_the_storage_budget() {
    let (files, options) = common::library_and_corpora();
    let (mut floats, mut nodes) = ((0, PathBuf::new()), (0, PathBuf::new()));
    for f in files {
        let c = compile_file(&f, &options).expect("readable");
        let Some(m) = &c.module else { continue };
        let measure = rtsl_compiler::ir::storage::measure(m);
        if measure.floats > floats.0 {
            floats = (measure.floats, f.clone());
        }
        if measure.nodes > nodes.0 {
            nodes = (measure.nodes, f);
        }
    }
    println!("most storage: {} ({} floats)", floats.1.display(), floats.0);
    println!("largest with arrays counted: {} ({} IR nodes)", nodes.1.display(), nodes.0);
    assert!(floats.0 > 0 && nodes.0 > 0);
    let budget = rtsl_compiler::ir::STORAGE_BUDGET;
    assert!(
        floats.0 * 8 <= budget,
        "{} holds {} floats: within 8x of the budget of {budget}",
        floats.1.display(),
        floats.0
    );
    let budget = rtsl_compiler::ir::INLINE_BUDGET;
    assert!(
        nodes.0 * 8 <= budget,
        "{} counts {} IR nodes: within 8x of the budget of {budget}",
        nodes.1.display(),
        nodes.0
    );
}

//! Helpers shared by the integration tests.

use rtsl_compiler::Options;
use std::path::{Path, PathBuf};

/// Every `.sl` file under `dir`, recursively, in a stable order.
pub fn shader_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    walk(dir, &mut out);
    out
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).expect("directory").filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, out);
        } else if p.extension().is_some_and(|e| e == "sl") {
            out.push(p);
        }
    }
}

/// Every shader of the library and both corpora, with the options (include paths) they need.
#[allow(dead_code)] // Not every test file uses it.
pub fn library_and_corpora() -> (Vec<PathBuf>, Options) {
    let mut files = Vec::new();
    for dir in ["../stdlib_shaders", "../tests/corpus", "../tests/corpus2"] {
        files.extend(shader_files(Path::new(dir)));
    }
    let mut options = Options::default();
    options.preprocessor.include_paths.push(PathBuf::from("../tests/corpus/include"));
    options.preprocessor.include_paths.push(PathBuf::from("../tests/corpus2/include"));
    (files, options)
}

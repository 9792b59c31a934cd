//! Embeds the shader library (`../stdlib_shaders`) in the runtime: writes `stdlib.rs` into
//! `OUT_DIR`, a table of each library file's path (relative to the library) and its text, so a
//! binary finds the library wherever it is installed (`src/shading/library.rs`).

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "sl" || e == "h") {
            out.push(path);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let library = manifest.join("..").join("stdlib_shaders");
    println!("cargo:rerun-if-changed={}", library.display());
    let mut found = Vec::new();
    files(&library, &mut found);
    let mut table = String::from(
        "/// Each library file: its path in the library and its text.\npub(crate) static FILES: &[(&str, &str)] = &[\n",
    );
    for path in &found {
        println!("cargo:rerun-if-changed={}", path.display());
        let relative = path.strip_prefix(&library).expect("under the library").to_string_lossy().replace('\\', "/");
        table.push_str(&format!("    ({relative:?}, include_str!({:?})),\n", path.display().to_string()));
    }
    table.push_str("];\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("stdlib.rs");
    std::fs::write(&out, table).expect("writing the embedded library's table");
}

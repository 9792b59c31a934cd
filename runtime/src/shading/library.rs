//! The shader library shipped with rtsl (`stdlib_shaders/` in the source tree), embedded in the
//! binary by `build.rs`, so an installed or copied binary has it wherever it runs. A shader is
//! looked up on the application's search path first, then in the directory `RTSL_STDLIB` names
//! (a library kept beside the binary, or a working copy being edited, which hot reload watches),
//! then here.

use std::path::{Path, PathBuf};

include!(concat!(env!("OUT_DIR"), "/stdlib.rs"));

/// The folders of the library, one per shader type, in the order they are searched.
pub const FOLDERS: [&str; 8] =
    ["surface", "light", "displacement", "volume", "imager", "camera", "pixel", "lightfield"];

/// The environment variable naming a library directory searched before the embedded one.
pub const LIBRARY_VARIABLE: &str = "RTSL_STDLIB";

/// A shader of the embedded library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LibraryShader {
    /// Its path in the library (`surface/plastic.sl`).
    pub path: &'static str,
    pub source: &'static str,
}

impl LibraryShader {
    /// The name it is compiled under: its path in the library, marked as built in, so that
    /// diagnostics say where its text came from.
    pub fn label(&self) -> String {
        format!("<built-in library>/{}", self.path)
    }
}

/// Shader `name` of the embedded library (`NAME.sl` in one of its [`FOLDERS`]).
pub fn find(name: &str) -> Option<LibraryShader> {
    FOLDERS.iter().find_map(|folder| {
        let path = format!("{folder}/{name}.sl");
        FILES.iter().find(|(p, _)| *p == path).map(|&(path, source)| LibraryShader { path, source })
    })
}

/// Every file of the embedded library: its path in the library and its text.
pub fn files() -> impl Iterator<Item = LibraryShader> {
    FILES.iter().map(|&(path, source)| LibraryShader { path, source })
}

/// The library directory `RTSL_STDLIB` names, when it is set and not empty.
pub fn override_dir() -> Option<PathBuf> {
    std::env::var_os(LIBRARY_VARIABLE).filter(|v| !v.is_empty()).map(PathBuf::from)
}

/// Writes the embedded library under `dir` with its layout (`dir/surface/plastic.sl`...): a copy
/// to edit, or to compile into artifacts.
pub fn write_to(dir: &Path) -> std::io::Result<()> {
    for file in files() {
        let to = dir.join(file.path);
        if let Some(parent) = to.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&to, file.source)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_library_is_embedded_whole() {
        let plastic = find("plastic").expect("plastic is in the library");
        assert_eq!(plastic.path, "surface/plastic.sl");
        assert!(plastic.source.contains("surface plastic"), "{}", plastic.source);
        assert!(find("pointlight").is_some_and(|s| s.path == "light/pointlight.sl"));
        assert!(find("nosuchshader").is_none());
        // Every shader file of the source tree is in the table, with its text.
        let tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../stdlib_shaders");
        let mut count = 0;
        for folder in FOLDERS {
            let Ok(entries) = std::fs::read_dir(tree.join(folder)) else { continue };
            for entry in entries.flatten() {
                let name = entry.file_name().to_string_lossy().into_owned();
                let Some(stem) = name.strip_suffix(".sl") else { continue };
                let text = std::fs::read_to_string(entry.path()).expect("a library file");
                assert_eq!(find(stem).map(|s| s.source), Some(text.as_str()), "{folder}/{name}");
                count += 1;
            }
        }
        assert!(count > 30, "{count} library shaders");
        let dir = tempfile::tempdir().expect("a temporary directory");
        write_to(dir.path()).expect("written");
        assert!(dir.path().join("surface/plastic.sl").is_file());
    }
}

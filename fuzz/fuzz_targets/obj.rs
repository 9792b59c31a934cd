//! An OBJ file and its material library (the input split at its first NUL byte), read from a
//! temporary folder as `rtsl render` reads them. Its contexts share the run's shaders
//! (`shared_shaders.rs`).
#![no_main]

mod shared_shaders;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let Ok(dir) = tempfile::tempdir() else { return };
    let mut text = b"mtllib fuzz.mtl\n".to_vec();
    text.extend_from_slice(obj);
    let path = dir.path().join("fuzz.obj");
    if std::fs::write(&path, text).is_err() || std::fs::write(dir.path().join("fuzz.mtl"), mtl).is_err() {
        return;
    }
    let mut rt = shared_shaders::context();
    let _ = rtsl_runtime::scene_file::add_model_file(&mut rt, &path);
});

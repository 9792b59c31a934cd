//! Any bytes as a glTF file (JSON, or binary `.glb` when it starts with the GLB magic), read from
//! a temporary folder: hierarchies, buffers and accessors are checked before they are used.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(dir) = tempfile::tempdir() else { return };
    let name = if data.starts_with(b"glTF") { "fuzz.glb" } else { "fuzz.gltf" };
    let path = dir.path().join(name);
    if std::fs::write(&path, data).is_ok() {
        let mut rt = rtsl_runtime::api::Context::new();
        let _ = rtsl_runtime::scene_file::add_model_file(&mut rt, &path);
    }
});

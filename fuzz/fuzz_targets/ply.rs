//! Any bytes as a PLY file (ASCII or binary), read from a temporary folder.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(dir) = tempfile::tempdir() else { return };
    let path = dir.path().join("fuzz.ply");
    if std::fs::write(&path, data).is_ok() {
        let _ = rtsl_runtime::load_mesh(&path);
    }
});

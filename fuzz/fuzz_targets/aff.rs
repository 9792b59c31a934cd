//! AFF text (BART's NFF with keyframes) through the reader, and what it reads onto a `Context`.
//! Its contexts share the run's shaders (`shared_shaders.rs`).
#![no_main]

mod shared_shaders;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = std::path::Path::new("fuzz.aff");
    if let Ok(scene) = rtsl_runtime::bart::parse_str(&text, path) {
        let mut rt = shared_shaders::context();
        let _ = rtsl_runtime::bart::load_parsed(&mut rt, scene, path);
    }
});

//! RIB text through the reader and onto a `Context` (requests, declarations, geometry, shaders
//! named by the file): errors and warnings, never a panic, a hang or an allocation sized by a count
//! in the file.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut rt = rtsl_runtime::api::Context::new();
    let _ = rtsl_runtime::rib::load::load_str(&mut rt, &text, std::path::Path::new("fuzz.rib"));
});

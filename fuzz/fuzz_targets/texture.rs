//! Any bytes as a texture file, its format chosen by the first byte: decoded, or refused with an
//! error.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else { return };
    let name = ["fuzz.png", "fuzz.jpg", "fuzz.tga", "fuzz.ppm", "fuzz.exr"][usize::from(kind) % 5];
    let mut rt = rtsl_runtime::api::Context::new();
    let _ = rt.texture_file_in_memory(name, bytes);
});

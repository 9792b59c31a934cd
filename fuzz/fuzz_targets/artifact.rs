//! Any bytes as a compiled shader artifact (`.rtso`): refused with an error, or decoded into IR
//! that passed the validator.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = rtsl_compiler::artifact::decode(std::path::Path::new("fuzz.rtso"), data);
});

//! Any bytes as a compiled shader artifact (`.rtso`): refused with an error, or decoded into IR
//! that passed the validator. Each input is also framed again with a correct checksum
//! (`artifact::reframe`), as a forger changing the payload would, so that mutations of the payload
//! reach the decoder and the validator rather than stopping at the checksum; IR that decodes is
//! compiled by the JIT, which relies on the validator.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz.rtso");
    let reframed = rtsl_compiler::artifact::reframe(data);
    for bytes in std::iter::once(data).chain(reframed.as_deref()) {
        if let Ok(artifact) = rtsl_compiler::artifact::decode(path, bytes) {
            let _ = rtsl_compiler::back::jit::compile(&artifact.module);
        }
    }
});

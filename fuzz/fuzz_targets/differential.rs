//! The JIT against the reference interpreter: any bytes that compile to a shader run in both back
//! ends over random inputs and masks, and every active lane must agree (the compiler tests'
//! differential harness, `compiler/tests/common`), with inactive lanes untouched. A finding is
//! either a back-end bug or a documented difference (e.g. the loop budget, counted per chunk of
//! four lanes in the JIT and per point in the interpreter, or `random()` assigned to a uniform
//! variable, one number a chunk in the JIT) to triage.
#![no_main]

#[path = "../../compiler/tests/common/mod.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let c = rtsl_compiler::compile_source("fuzz.sl", &text, &rtsl_compiler::Options::default());
    let Some(module) = c.module else { return };
    let Ok(shader) = rtsl_compiler::back::jit::compile(&module) else { return };
    let seed = data.iter().fold(0u64, |h, &b| h.rotate_left(5) ^ u64::from(b));
    common::differential(&module, &shader, 13, seed, 0.5);
});

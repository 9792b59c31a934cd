//! The JIT against the reference interpreter: any bytes that compile to a shader run in both back
//! ends over random inputs and masks, and every active lane must agree (the compiler tests'
//! differential harness, `compiler/tests/common`), with inactive lanes untouched. A finding is
//! either a back-end bug or a documented difference (e.g. the loop budget, counted per chunk of
//! four lanes in the JIT and per point in the interpreter, or `random()` assigned to a uniform
//! variable, one number a chunk in the JIT) to triage. Runs that meet the (small) budgets are run
//! to the end but not compared (`differential_with`).
#![no_main]

#[path = "../../compiler/tests/common/mod.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

/// Loop iterations a run may take, in both back ends: the renderer's budget (a million) lets one
/// runaway loop take seconds per input in the interpreter; budgets are compared elsewhere.
const LOOP_BUDGET: u32 = 4096;
/// The interpreter's calls, lights and gather samples a run may take.
const STEP_BUDGET: u64 = 100_000;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let c = rtsl_compiler::compile_source("fuzz.sl", &text, &rtsl_compiler::Options::default());
    let Some(module) = c.module else { return };
    let options = rtsl_compiler::back::jit::JitOptions { loop_budget: LOOP_BUDGET };
    let Ok(shader) = rtsl_compiler::back::jit::compile_with(&module, None, &options) else { return };
    let seed = data.iter().fold(0u64, |h, &b| h.rotate_left(5) ^ u64::from(b));
    let limits = rtsl_compiler::interp::Limits { steps: STEP_BUDGET, loop_iterations: LOOP_BUDGET };
    common::differential_with(&module, &shader, 13, seed, 0.5, limits);
});

//! Any bytes through the whole front end (preprocessor, lexer, parser, checker, validator): the
//! result must be diagnostics or IR, never a panic, and rendering the diagnostics must not panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let c = rtsl_compiler::compile_source("fuzz.sl", &text, &rtsl_compiler::Options::default());
    let _ = c.render();
});

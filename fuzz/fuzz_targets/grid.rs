//! Any bytes as a 3-D grid (`RTSLGRID`): read, or refused with an error.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut rt = rtsl_runtime::api::Context::new();
    let _ = rt.grid_file_in_memory("fuzz.grid", data);
});

//! VRML text, 97 or 1.0 by its header, through the reader and onto a `Context`, then its
//! animation run at a few times: errors and warnings, never a panic, a hang or an allocation
//! sized by a count in the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::vrml;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut rt = rtsl_runtime::api::Context::new();
    let path = Path::new("fuzz.wrl");
    let built = if vrml::is_vrml1(&text) {
        vrml::v1::build_str_with(&mut rt, &text, path, &vrml::VrmlOptions::default())
    } else {
        vrml::build_str(&mut rt, &text, path)
    };
    if let Ok(mut scene) = built {
        for time in [0.0, 0.5, 1.25, 7.0, 0.25] {
            let _ = scene.advance_to(time, &mut rt);
        }
    }
});

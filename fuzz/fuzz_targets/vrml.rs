//! VRML text, 97 or 1.0 by its header, through the reader and onto a `Context`, then its
//! animation run at a few times and its sensors given a pointer: errors and warnings, never a
//! panic, a hang or an allocation sized by a count in the file.
//! Its contexts share the run's shaders (`shared_shaders.rs`).
#![no_main]

mod shared_shaders;

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::vrml;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut rt = shared_shaders::context();
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
        // The pointer over the first shape, pressed, dragged and released.
        use vrml::sensors::PointerRay;
        let ray = |x: f32| PointerRay {
            origin: rtsl_runtime::glam::Vec3A::new(x, 0.0, 10.0),
            direction: rtsl_runtime::glam::Vec3A::NEG_Z,
        };
        if let Some(first) = scene.shapes.first().map(|s| s.made) {
            if let Some(hit) = scene.pointer_hit(&rt, first, 0, (0.3, 0.3)) {
                let _ = scene.pointer_move(Some(&hit), 0.5, &mut rt);
                let _ = scene.pointer_press(&hit, ray(0.0), 0.6, &mut rt);
                let _ = scene.pointer_drag(ray(0.5), 0.7, &mut rt);
                let _ = scene.pointer_release(Some(&hit), 0.8, &mut rt);
            }
        }
    }
});

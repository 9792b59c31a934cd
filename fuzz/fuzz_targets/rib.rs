//! RIB text through the reader and onto a `Context` (requests, declarations, geometry, shaders
//! named by the file): errors and warnings, never a panic, a hang or an allocation sized by a count
//! in the file. Read whole and image by image (`load_str_frames`, as `rtsl render` reads a file of
//! many frames), where each image's picture is the one loading that image alone gives.
//! Its contexts share the run's shaders (`shared_shaders.rs`).
#![no_main]

mod shared_shaders;

use libfuzzer_sys::fuzz_target;
use shared_shaders::context;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut rt = context();
    let _ = rtsl_runtime::rib::load::load_str(&mut rt, &text, std::path::Path::new("fuzz.rib"));
    let mut first = None;
    let read = rtsl_runtime::rib::load::load_str_frames(
        &text,
        "fuzz.rib",
        context,
        |_, _| true,
        |image| -> Result<_, rtsl_runtime::scene_file::SceneFileError> {
            first = Some(image.rt.options.clone());
            Ok(std::ops::ControlFlow::Break(()))
        },
    );
    // The first image read image by image is the first image read whole (its options stand for
    // the rest of its state; both loads fail alike).
    if let (Ok(_), Some(options)) = (read, first) {
        assert_eq!(format!("{:?}", options), format!("{:?}", rt.options));
    }
});

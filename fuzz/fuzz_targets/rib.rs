//! RIB text through the reader and onto a `Context` (requests, declarations, geometry, shaders
//! named by the file): errors and warnings, never a panic, a hang or an allocation sized by a count
//! in the file. Read whole and image by image (`load_str_frames`, as `rtsl render` reads a file of
//! many frames), where each image's picture is the one loading that image alone gives.
//!
//! The contexts of every input share one cache of compiled shaders, as the frames of one render
//! do: the library shaders a RIB file names are compiled once for the whole run rather than for
//! each input (compiling them was nearly all of an input's time, about one input a second), so the
//! run spends its time on the RIB reader and the loader. The `compile` and `differential` targets
//! fuzz the compiler.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtsl_runtime::api::{Context, ShaderCache};
use std::sync::{Arc, OnceLock};

/// A context that takes its shaders from the run's cache.
fn context() -> Context {
    static SHADERS: OnceLock<Arc<ShaderCache>> = OnceLock::new();
    let mut rt = Context::new();
    rt.share_shader_cache(SHADERS.get_or_init(Default::default).clone());
    rt
}

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

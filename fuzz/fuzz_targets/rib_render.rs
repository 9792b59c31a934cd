//! RIB text loaded onto a `Context` and rendered: whatever geometry, shaders and options the file
//! gives (quadrics, patches, subdivision meshes, blobbies, curves, CSG, displacement, imagers),
//! the frame renders or fails with an error, never a panic or a hang. The image is made small (at
//! most 12x12, one sample a pixel, shallow rays) so that an input's time goes to what the file
//! builds, not to pixels.
#![no_main]

mod shared_shaders;

use libfuzzer_sys::fuzz_target;
use shared_shaders::context;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let mut rt = context();
    if rtsl_runtime::rib::load::load_str(&mut rt, &text, std::path::Path::new("fuzz.rib")).is_err() {
        return;
    }
    let o = &mut rt.options;
    o.width = o.width.clamp(1, 12);
    o.height = o.height.clamp(1, 12);
    o.samples = (1, 1);
    o.max_ray_depth = o.max_ray_depth.min(2);
    o.max_transparent_layers = o.max_transparent_layers.min(4);
    let _ = rt.render_frame();
});

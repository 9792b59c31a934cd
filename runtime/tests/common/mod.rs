//! Helpers shared by the runtime's integration tests: a context and the quads, cube and lit scene
//! built in it, RIB loading, rendering a frame, pixel sums and writing files. Each test file is its
//! own crate and uses only some of these.
#![allow(dead_code)]

use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, Primitive};
use rtsl_runtime::render::{render_frame, Framebuffer};
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::shading::ParamValue;
use std::path::{Path, PathBuf};

/// A displacement shader that bends the normal by ridges around the object's z axis without
/// moving the point (bump mapping by hand): true displacement leaves such an object as it was.
pub const BUMP_ONLY: &str = "displacement bumponly(float amount = 0.25) {
    point Po = transform(\"object\", P);
    N = calculatenormal(P + amount * sin(10 * zcomp(Po)) * normalize(N));
}";

/// The image size of `context()`.
pub const W: u32 = 64;
pub const H: u32 = 48;

/// A context rendering `W` x `H` images.
pub fn context() -> Context {
    let mut rt = Context::new();
    rt.options.width = W;
    rt.options.height = H;
    rt
}

/// One quad with the corners in order.
pub fn quad(rt: &mut Context, corners: [[f32; 3]; 4]) -> Result<(), ApiError> {
    rt.begin(Primitive::Quads)?;
    for c in corners {
        rt.vertex(c[0], c[1], c[2])?;
    }
    rt.end()
}

/// The cube from -1 to 1 on every axis, as six quads.
pub fn cube(rt: &mut Context) -> Result<(), ApiError> {
    let faces: [[[f32; 3]; 4]; 6] = [
        [[-1., -1., 1.], [1., -1., 1.], [1., 1., 1.], [-1., 1., 1.]],
        [[1., -1., -1.], [-1., -1., -1.], [-1., 1., -1.], [1., 1., -1.]],
        [[-1., 1., 1.], [1., 1., 1.], [1., 1., -1.], [-1., 1., -1.]],
        [[-1., -1., -1.], [1., -1., -1.], [1., -1., 1.], [-1., -1., 1.]],
        [[1., -1., 1.], [1., -1., -1.], [1., 1., -1.], [1., 1., 1.]],
        [[-1., -1., -1.], [-1., -1., 1.], [-1., 1., 1.], [-1., 1., -1.]],
    ];
    for f in faces {
        quad(rt, f)?;
    }
    Ok(())
}

/// A floor and a floating cube under a point light, shaded with `plastic`.
pub fn shadow_scene(rt: &mut Context) -> Result<rtsl_runtime::api::LightId, ApiError> {
    shadow_scene_with_cube_opacity(rt, 1.0)
}

/// [`shadow_scene`] with a cube of the given opacity.
pub fn shadow_scene_with_cube_opacity(rt: &mut Context, opacity: f32) -> Result<rtsl_runtime::api::LightId, ApiError> {
    shadow_scene_with(rt, opacity, (0.0, 0.0))
}

/// [`shadow_scene`] with a cube of the given opacity, and the floor's and the cube's trace biases
/// (`Context::trace_bias`). The cube floats from 0.9 to 2.1 above the floor, the light is at
/// (1, 5, 1).
pub fn shadow_scene_with(
    rt: &mut Context,
    opacity: f32,
    (floor_bias, cube_bias): (f32, f32),
) -> Result<rtsl_runtime::api::LightId, ApiError> {
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 4.0, 7.0), Vec3A::new(0.0, 0.5, 0.0), Vec3A::Y, 45.0);
    rt.trace_bias(floor_bias);
    let floor = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    quad(rt, [[-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0], [-5.0, 0.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    rt.trace_bias(cube_bias);
    let boxy = rt.begin_object()?;
    rt.color(0.9, 0.3, 0.2);
    rt.opacity(opacity, opacity, opacity);
    cube(rt)?;
    rt.end_object()?;
    rt.push_matrix();
    rt.translate(0.0, 1.5, 0.0);
    rt.scale(0.6, 0.6, 0.6);
    rt.instantiate_object(boxy)?;
    rt.pop_matrix()?;
    rt.light_source(light, &[("intensity", ParamValue::Float(30.0)), ("from", ParamValue::Point([1.0, 5.0, 1.0]))])
}

/// The sum of a pixel's red, green and blue.
pub fn luminance(fb: &Framebuffer, x: u32, y: u32) -> f32 {
    let p = fb.pixel(x, y);
    p[0] + p[1] + p[2]
}

/// Constant white where opaque: a sample is exactly 1 on the surface and 0 off it.
pub const FLAT: &str = "surface flat(color c = 1;) { Oi = Os; Ci = Os * c; }";

/// Loads a RIB scene from `rib` (as `test.rib`) into a fresh context, with the load's warnings.
pub fn load(rib: &str) -> (Context, Vec<String>) {
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, rib, Path::new("test.rib")).unwrap_or_else(|e| panic!("{e}"));
    (rt, loaded.warnings.iter().map(ToString::to_string).collect())
}

/// Builds the context's world, renders one frame and hands the scene back.
pub fn render(rt: &mut Context) -> Framebuffer {
    let world = rt.build_world().unwrap_or_else(|e| panic!("{e}"));
    let (fb, _) = render_frame(&world, None);
    rt.return_scene(world);
    fb
}

/// Writes `text` to `dir/name` and returns the file's path.
pub fn write(dir: &Path, name: &str, text: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write");
    path
}

/// A scene of `../shared/scenes`, or `None` (with a message) where the shared test data is absent.
pub fn shared(path: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes").join(path);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent (the shared test scenes are not here)", p.display());
        None
    }
}

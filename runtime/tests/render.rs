//! The engine through its API: shading on hits, lights and shadows, vertex-scope parameters,
//! transparency, `trace`, frame semantics, determinism, and typed errors for misuse.

use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, Primitive};
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::shading::{ParamError, ParamValue, ShaderProgram};

const W: u32 = 64;
const H: u32 = 48;

fn context() -> Context {
    let mut rt = Context::new();
    rt.options.width = W;
    rt.options.height = H;
    rt
}

fn quad(rt: &mut Context, corners: [[f32; 3]; 4]) -> Result<(), ApiError> {
    rt.begin(Primitive::Quads)?;
    for c in corners {
        rt.vertex(c[0], c[1], c[2])?;
    }
    rt.end()
}

fn cube(rt: &mut Context) -> Result<(), ApiError> {
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
fn shadow_scene(rt: &mut Context) -> Result<rtsl_runtime::api::LightId, ApiError> {
    shadow_scene_with_cube_opacity(rt, 1.0)
}

/// [`shadow_scene`] with a cube of the given opacity.
fn shadow_scene_with_cube_opacity(rt: &mut Context, opacity: f32) -> Result<rtsl_runtime::api::LightId, ApiError> {
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 4.0, 7.0), Vec3A::new(0.0, 0.5, 0.0), Vec3A::Y, 45.0);
    let floor = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    quad(rt, [[-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0], [-5.0, 0.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
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

fn luminance(fb: &Framebuffer, x: u32, y: u32) -> f32 {
    let p = fb.pixel(x, y);
    p[0] + p[1] + p[2]
}

#[test]
fn shadows_darken_only_what_the_cube_hides() -> Result<(), ApiError> {
    let mut rt = context();
    let light = shadow_scene(&mut rt)?;
    let (lit, report) = rt.render_frame()?;
    assert!(report.shadow_rays > 0, "{report}");
    rt.set_light(light, true, false)?;
    let (unshadowed, _) = rt.render_frame()?;
    let mut darker = 0;
    for y in 0..H {
        for x in 0..W {
            let (a, b) = (luminance(&lit, x, y), luminance(&unshadowed, x, y));
            assert!(a <= b + 1e-5, "pixel ({x}, {y}) brighter with shadows: {a} > {b}");
            if a < 0.5 * b {
                darker += 1;
            }
        }
    }
    assert!(darker > 20, "only {darker} pixels in shadow");
    // The lit floor is lit at all, and misses are black with zero alpha.
    assert!(luminance(&unshadowed, W / 2, H - 2) > 0.05);
    assert_eq!(lit.pixel(0, 0), [0.0; 4], "the sky is empty");
    Ok(())
}

#[test]
fn a_translucent_cube_passes_light_through_both_of_its_walls() -> Result<(), ApiError> {
    // Every shadow ray under the cube crosses two of its faces, each letting half the light
    // through: the floor there gets a quarter of the light (no ambient light in the scene).
    let render = |opacity: f32, shadows: bool| -> Result<Framebuffer, ApiError> {
        let mut rt = context();
        let light = shadow_scene_with_cube_opacity(&mut rt, opacity)?;
        rt.set_light(light, true, shadows)?;
        Ok(rt.render_frame()?.0)
    };
    let (opaque, translucent) = (render(1.0, true)?, render(0.5, true)?);
    let (unshadowed, opaque_unshadowed) = (render(0.5, false)?, render(1.0, false)?);
    let (mut shadowed, mut quarter) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let (o, t, u) = (luminance(&opaque, x, y), luminance(&translucent, x, y), luminance(&unshadowed, x, y));
            // Without shadows the cube's opacity shows only where the camera sees the cube.
            let floor_seen = unshadowed.pixel(x, y) == opaque_unshadowed.pixel(x, y);
            if floor_seen && u > 0.05 && o < 1e-4 {
                shadowed += 1;
                if (t / u - 0.25).abs() < 0.01 {
                    quarter += 1;
                }
            }
        }
    }
    assert!(shadowed > 20, "only {shadowed} pixels in the cube's shadow");
    // Rays that graze an edge or a corner may cross one face only.
    assert!(quarter * 10 >= shadowed * 9, "{quarter} of {shadowed} shadowed pixels get a quarter of the light");
    Ok(())
}

#[test]
fn the_image_does_not_depend_on_the_thread_count() -> Result<(), ApiError> {
    let mut rt = context();
    shadow_scene(&mut rt)?;
    let mut images = Vec::new();
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool");
        let world = rt.build_world()?;
        let (fb, _) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
        rt.return_scene(world);
        images.push(fb);
    }
    assert!(images.windows(2).all(|w| w[0] == w[1]));
    Ok(())
}

#[test]
fn shader_timing_can_be_turned_off_without_changing_the_image() -> Result<(), ApiError> {
    use rtsl_compiler::front::parse::ast::ShaderKind;
    let mut rt = context();
    shadow_scene(&mut rt)?;
    let (timed_image, timed) = rt.render_frame()?;
    assert!(timed.shading > std::time::Duration::ZERO, "{timed}");
    assert!(timed.shader_time(ShaderKind::Surface) > std::time::Duration::ZERO, "{timed}");
    assert!(!timed.by_shader.is_empty());
    rt.options.time_shaders = false;
    let (untimed_image, untimed) = rt.render_frame()?;
    assert_eq!(untimed.shading, std::time::Duration::ZERO, "{untimed}");
    assert!(untimed.by_kind.iter().all(|t| t.is_zero()), "{untimed}");
    assert!(untimed.by_shader.is_empty());
    assert_eq!((untimed.primary_rays, untimed.shadow_rays), (timed.primary_rays, timed.shadow_rays));
    assert!(untimed_image == timed_image);
    // Timing comes back with the option: nothing of the untimed frame stays switched off.
    rt.options.time_shaders = true;
    assert!(rt.render_frame()?.1.shader_time(ShaderKind::Surface) > std::time::Duration::ZERO);
    Ok(())
}

const SHADOWED: &str = r#"
surface shadowed(string map = ""; float blur = 0; float width = 1; float bias = 0;)
{
    Oi = 1;
    Ci = shadow(map, P, "blur", blur, "width", width, "bias", bias);
}
"#;

/// The shadow map of an occluder at depth 4 over the half x < 0 of an orthographic light looking
/// down -z from z = 5 onto x, y in [-4, 4] (64x64 texels of 0.125).
fn write_half_occluded_map(path: &std::path::Path) {
    let depth: Vec<f32> = (0..64 * 64).map(|i| if i % 64 < 32 { 4.0 } else { 1e30 }).collect();
    let world_to_camera = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 5.0, 1.0];
    let world_to_ndc = [0.125, 0.0, 0.0, 0.0, 0.0, -0.125, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.5, 0.0, 1.0];
    rtsl_runtime::texture::write_shadow_map(path, &depth, 64, 64, world_to_camera, world_to_ndc).expect("a shadow map");
}

#[test]
fn shadow_maps_honour_blur_bias_and_the_pixel_footprint() -> Result<(), ApiError> {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let map = dir.path().join("half.shad");
    write_half_occluded_map(&map);
    // The plane z = 0 seen head-on: a pixel is 0.125 across, one texel of the map.
    let row = |params: &[(&str, ParamValue)]| -> Result<Vec<f32>, ApiError> {
        let mut rt = context();
        let shader = rt.compile_shader("shadowed.sl", SHADOWED)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, Vec3A::Y, 90.0);
        let o = rt.begin_object()?;
        rt.bind_shader(shader)?;
        rt.parameter("map", ParamValue::String(map.display().to_string()))?;
        for (name, value) in params {
            rt.parameter(name, value.clone())?;
        }
        quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        let (fb, _) = rt.render_frame()?;
        Ok((0..W).map(|x| fb.pixel(x, H / 2)[0]).collect())
    };
    let penumbra = |r: &[f32]| r.iter().filter(|v| **v > 0.02 && **v < 0.98).count();
    let sharp = row(&[])?;
    assert_eq!((sharp[0], sharp[W as usize - 1]), (1.0, 0.0), "shadowed left, lit right: {sharp:?}");
    assert!(sharp.windows(2).all(|p| p[0] >= p[1]), "{sharp:?}");
    assert!(penumbra(&sharp) <= 3, "the default kernel is 2 texels: {sharp:?}");
    // "width" scales the pixel footprint the shader's derivatives of P give (8 texels here)...
    let wide = row(&[("width", ParamValue::Float(8.0))])?;
    assert!(penumbra(&wide) >= 6, "{wide:?}");
    // ...and "blur" adds its own width, in map coordinates.
    let blurred = row(&[("blur", ParamValue::Float(0.125))])?;
    assert!(penumbra(&blurred) >= 6, "{blurred:?}");
    // The bias moves the compared depth towards the light, past the occluder.
    let biased = row(&[("bias", ParamValue::Float(2.0))])?;
    assert!(biased.iter().all(|v| *v == 0.0), "{biased:?}");
    Ok(())
}

const VERTEX_TINT: &str = "surface tint(varying color tint = 0;) { Oi = 1; Ci = tint; }";

#[test]
fn vertex_values_are_interpolated_at_the_hit() -> Result<(), ApiError> {
    let mut rt = context();
    let tint = rt.compile_shader("tint.sl", VERTEX_TINT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, Vec3A::Y, 90.0);
    let o = rt.begin_object()?;
    rt.bind_shader(tint)?;
    rt.begin(Primitive::Quads)?;
    // Red along the left edge, green along the right.
    for (x, y) in [(-4.0, -4.0), (4.0, -4.0), (4.0, 4.0), (-4.0, 4.0)] {
        let red = if x < 0.0 { 1.0 } else { 0.0 };
        rt.vertex_parameter("tint", ParamValue::Color([red, 1.0 - red, 0.0]))?;
        rt.vertex(x, y, 0.0)?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    let (fb, _) = rt.render_frame()?;
    let left = fb.pixel(2, H / 2);
    let right = fb.pixel(W - 3, H / 2);
    assert!(left[0] > 0.6 && left[1] < 0.4, "left {left:?}");
    assert!(right[1] > 0.6 && right[0] < 0.4, "right {right:?}");
    let mid = fb.pixel(W / 2, H / 2);
    assert!((mid[0] + mid[1] - 1.0).abs() < 1e-3, "the two weights sum to one: {mid:?}");
    Ok(())
}

const FLAT: &str = "surface flat(color c = 1;) { Oi = Os; Ci = Os * c; }";

#[test]
fn transparent_surfaces_composite_front_to_back() -> Result<(), ApiError> {
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let back = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.parameter("c", ParamValue::Color([1.0, 0.0, 0.0]))?;
    quad(&mut rt, [[-10.0, -10.0, -1.0], [10.0, -10.0, -1.0], [10.0, 10.0, -1.0], [-10.0, 10.0, -1.0]])?;
    rt.end_object()?;
    let front = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.parameter("c", ParamValue::Color([0.0, 0.0, 1.0]))?;
    rt.opacity(0.25, 0.25, 0.25);
    quad(&mut rt, [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])?;
    rt.end_object()?;
    rt.instantiate_object(back)?;
    rt.instantiate_object(front)?;
    let (fb, report) = rt.render_frame()?;
    assert!(report.transparency_rays > 0);
    let p = fb.pixel(W / 2, H / 2);
    assert!((p[0] - 0.75).abs() < 1e-4 && (p[2] - 0.25).abs() < 1e-4 && p[1].abs() < 1e-6, "{p:?}");
    assert!((p[3] - 1.0).abs() < 1e-6);
    assert_eq!(fb.pixel(0, 0)[..3], [1.0, 0.0, 0.0]);
    Ok(())
}

const MIRROR: &str = "surface mirrored() { Oi = 1; Ci = 0.5 * trace(P, reflect(I, normalize(N))); }";

#[test]
fn trace_sees_what_a_mirror_reflects_up_to_the_depth_limit() -> Result<(), ApiError> {
    let mut rt = context();
    let mirror = rt.compile_shader("mirrored.sl", MIRROR)?;
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A mirror facing the camera, and a green wall behind the camera that it reflects.
    let m = rt.begin_object()?;
    rt.bind_shader(mirror)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    let wall = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.parameter("c", ParamValue::Color([0.0, 1.0, 0.0]))?;
    quad(&mut rt, [[-10.0, 10.0, 8.0], [10.0, 10.0, 8.0], [10.0, -10.0, 8.0], [-10.0, -10.0, 8.0]])?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    rt.instantiate_object(wall)?;
    let (fb, report) = rt.render_frame()?;
    assert!(report.secondary_rays >= u64::from(W * H));
    let p = fb.pixel(W / 2, H / 2);
    assert!((p[1] - 0.5).abs() < 1e-5 && p[0] == 0.0, "{p:?}");

    // Two facing mirrors: each bounce halves, and recursion stops at the depth limit.
    let mut rt = context();
    let mirror = rt.compile_shader("mirrored.sl", MIRROR)?;
    rt.options.max_ray_depth = 3;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    let m = rt.begin_object()?;
    rt.bind_shader(mirror)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    quad(&mut rt, [[-10.0, 10.0, 8.0], [10.0, 10.0, 8.0], [10.0, -10.0, 8.0], [-10.0, -10.0, 8.0]])?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    let (_, report) = rt.render_frame()?;
    // Depth 1, 2 and 3 rays for every pixel, none deeper.
    assert_eq!(report.secondary_rays, 3 * u64::from(W * H));
    Ok(())
}

/// A floor shaded with `floor_src` (which traces), under a red plastic cube and a point light.
fn reflecting_floor(rt: &mut Context, floor_src: &str) -> Result<(), ApiError> {
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    let tracing = rt.compile_shader("floor.sl", floor_src)?;
    rt.camera_look_at(Vec3A::new(0.0, 2.0, 7.0), Vec3A::new(0.0, 0.5, 0.0), Vec3A::Y, 45.0);
    let floor = rt.begin_object()?;
    rt.bind_shader(tracing)?;
    quad(rt, [[-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0], [-5.0, 0.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    let boxy = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    rt.color(0.9, 0.3, 0.2);
    cube(rt)?;
    rt.end_object()?;
    rt.push_matrix();
    rt.translate(0.0, 1.2, 0.0);
    rt.scale(0.6, 0.6, 0.6);
    rt.instantiate_object(boxy)?;
    rt.pop_matrix()?;
    rt.light_source(light, &[("intensity", ParamValue::Float(30.0)), ("from", ParamValue::Point([1.0, 5.0, 3.0]))])?;
    Ok(())
}

/// Two reflections: the second ray's direction depends on what the first one saw, so a batch's
/// first run (whose `trace` answers black) notes a different second ray than its second run asks.
/// The shader also changes a global it reads (`N`), which the second run must find as it was.
const BENT: &str = r#"
surface bent()
{
    N = normalize(N + normal(0.2, 0, 0));
    normal Nf = faceforward(normalize(N), I);
    vector R = reflect(normalize(I), Nf);
    color first = trace(P, R);
    vector V = normalize(R + vector(0, comp(first, 0), 0));
    color second = trace(P, V);
    Oi = 1;
    Ci = 0.5 * first + 0.25 * second + 0.25 * diffuse(Nf);
}
"#;

/// A batch whose shader traces runs twice so that its chunks' rays are traced together
/// (`RenderOptions::trace_ahead`): the image is the one of tracing each chunk's rays on its own,
/// bit for bit, also where a ray depends on an earlier one's answer.
#[test]
fn tracing_a_batchs_rays_ahead_changes_no_pixel() -> Result<(), ApiError> {
    for floor in [MIRROR, BENT] {
        let mut rt = context();
        reflecting_floor(&mut rt, floor)?;
        let (ahead, ahead_report) = rt.render_frame()?;
        rt.options.trace_ahead = false;
        let (chunked, chunked_report) = rt.render_frame()?;
        assert!(ahead == chunked, "{floor}");
        // The floor reflects the cube: some pixels are red.
        let red = (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| {
            let p = ahead.pixel(x, y);
            p[0] > 0.05 && p[0] > 2.0 * p[2]
        });
        assert!(red.count() > 20, "{floor}");
        assert!(chunked_report.secondary_rays > u64::from(W * H) / 2, "{chunked_report}");
        if floor == MIRROR {
            // No ray depends on another: each is traced once either way.
            assert_eq!(ahead_report.secondary_rays, chunked_report.secondary_rays);
        } else {
            // The second rays of the first runs were the wrong ones where the first rays saw red.
            assert!(ahead_report.secondary_rays > chunked_report.secondary_rays);
        }
    }
    Ok(())
}

const GLOSSY: &str = r#"
surface glossy(float samples = 8; float cone = 0.2;)
{
    vector R = normalize(reflect(I, normalize(N)));
    color hitc = 0, sum = 0;
    float len = 0, total = 0, n = 0, misses = 0;
    gather("illuminance", P, R, cone, samples, "surface:Ci", hitc, "ray:length", len) {
        sum += hitc;
        total += len;
        n += 1;
    }
    gather("illuminance", P, -N, cone, samples) {
        n += 1000;
    } else {
        misses += 1;
    }
    Oi = 1;
    Ci = color(comp(sum, 1) / samples, total / max(n, 1) / 100, misses / samples);
}
"#;

#[test]
fn gather_samples_a_cone_of_shaded_rays() -> Result<(), ApiError> {
    let mut rt = context();
    let glossy = rt.compile_shader("glossy.sl", GLOSSY)?;
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A glossy quad facing the camera; a green wall behind the camera that its cone of reflected
    // rays meets at a distance of 8 to 8 / cos(0.2); nothing behind the quad.
    let m = rt.begin_object()?;
    rt.bind_shader(glossy)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    let wall = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.parameter("c", ParamValue::Color([0.0, 1.0, 0.0]))?;
    quad(&mut rt, [[-40.0, 40.0, 8.0], [40.0, 40.0, 8.0], [40.0, -40.0, 8.0], [-40.0, -40.0, 8.0]])?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    rt.instantiate_object(wall)?;
    let (fb, report) = rt.render_frame()?;
    // Two gathers of 8 rays for every pixel.
    assert!(report.secondary_rays >= 16 * u64::from(W * H), "{}", report.secondary_rays);
    for (x, y) in [(W / 2, H / 2), (3, 4), (W - 2, H - 3)] {
        let p = fb.pixel(x, y);
        assert!((p[0] - 1.0).abs() < 1e-5, "every reflected ray sees the green wall: {p:?}");
        assert!(p[1] >= 0.08 - 1e-4 && p[1] <= 0.08 / 0.2f32.cos() * 1.1, "mean length / 100: {p:?}");
        assert_eq!(p[2], 1.0, "every ray behind the quad misses: {p:?}");
    }
    Ok(())
}

#[test]
fn frames_bind_shaders_when_rendered() -> Result<(), ApiError> {
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let o = rt.begin_object()?;
    rt.bind_shader(flat)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    let inst = rt.instantiate_object(o)?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [1.0; 4]);
    // Same id, new code: the next frame uses it.
    let half = ShaderProgram::from_source("flat.sl", "surface flat(color c = 1;) { Oi = 1; Ci = 0.5 * c; }", &[])?;
    rt.replace_shader(flat, half)?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [0.5, 0.5, 0.5, 1.0]);
    // A moved instance moves in the next frame.
    rt.set_instance_transform(inst, glam::Affine3A::from_translation(glam::Vec3::new(100.0, 0.0, 0.0)))?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [0.0; 4]);
    Ok(())
}

#[test]
fn misuse_is_a_typed_error() -> Result<(), ApiError> {
    let mut rt = context();
    assert!(matches!(rt.end(), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.end_object(), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.vertex(0.0, 0.0, 0.0), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.begin(Primitive::Triangles), Err(ApiError::NoObject(_))));
    assert!(matches!(rt.pop_matrix(), Err(ApiError::MatrixStackEmpty)));
    assert!(matches!(rt.parameter("Kd", ParamValue::Float(1.0)), Err(ApiError::NoShaderBound(_))));
    assert!(matches!(rt.instantiate_object(rtsl_runtime::api::ObjectId(7)), Err(ApiError::UnknownObject(7))));
    assert!(matches!(rt.bind_shader(rtsl_runtime::api::ShaderId(3)), Err(ApiError::UnknownShader(3))));
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    assert!(matches!(rt.bind_shader(light), Err(ApiError::WrongKind { .. })));
    assert!(matches!(rt.light_source(plastic, &[]), Err(ApiError::WrongKind { .. })));
    rt.bind_shader(plastic)?;
    assert!(matches!(
        rt.parameter("Kd", ParamValue::String("x".into())),
        Err(ApiError::Param(ParamError::TypeMismatch { .. }))
    ));
    assert!(matches!(
        rt.parameter("nonsense", ParamValue::Float(1.0)),
        Err(ApiError::Param(ParamError::NoSuchParameter { .. }))
    ));
    assert!(matches!(rt.vertex_parameter("Kd", ParamValue::Float(1.0)), Err(ApiError::NotVarying { .. })));
    rt.begin_object()?;
    assert!(matches!(rt.begin_object(), Err(ApiError::Nested(..))));
    rt.begin(Primitive::Triangles)?;
    rt.vertex(0.0, 0.0, 0.0)?;
    rt.vertex(1.0, 0.0, 0.0)?;
    assert!(matches!(rt.end(), Err(ApiError::IncompletePrimitive(2, _))));
    assert!(matches!(rt.render_frame(), Err(ApiError::Nested(..))));
    rt.end_object()?;
    assert!(matches!(rt.find_shader("no_such_shader"), Err(ApiError::Shader(_))));
    assert!(matches!(rt.compile_shader("bad.sl", "surface bad( { }"), Err(ApiError::Shader(_))));
    Ok(())
}

#[test]
fn adaptive_sampling_adds_rays_only_where_neighbours_differ() -> Result<(), ApiError> {
    use rtsl_runtime::render::Antialiasing;
    let render = |aa: Antialiasing, samples: (u32, u32)| -> Result<(Framebuffer, u64), ApiError> {
        let mut rt = context();
        let flat = rt.compile_shader("flat.sl", FLAT)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
        let o = rt.begin_object()?;
        rt.bind_shader(flat)?;
        // A square tilted in the image, so its edges cut pixels.
        rt.rotate(20.0, 0.0, 0.0, 1.0);
        quad(&mut rt, [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])?;
        rt.end_object()?;
        rt.load_identity();
        rt.instantiate_object(o)?;
        rt.options.samples = samples;
        rt.options.antialiasing = aa;
        let (fb, report) = rt.render_frame()?;
        Ok((fb, report.primary_rays))
    };
    let (one, one_rays) = render(Antialiasing::Grid { jitter: true }, (1, 1))?;
    let (_, grid_rays) = render(Antialiasing::Grid { jitter: true }, (2, 2))?;
    let (adaptive, adaptive_rays) = render(Antialiasing::Adaptive { threshold: 0.05 }, (2, 2))?;
    assert_eq!(one_rays, u64::from(W * H));
    assert_eq!(grid_rays, 4 * u64::from(W * H));
    assert!(adaptive_rays > one_rays && adaptive_rays < grid_rays / 2, "{adaptive_rays} rays");
    let mut edge_pixels = 0;
    for i in 0..(W * H) as usize {
        let (a, b) = (&one.rgba[4 * i..4 * i + 4], &adaptive.rgba[4 * i..4 * i + 4]);
        if a != b {
            edge_pixels += 1;
            // A refined pixel changed only because its samples disagree: it is partly covered.
            assert!(b[3] > 0.0 && b[3] < 1.0, "{a:?} -> {b:?}");
        }
    }
    assert!(edge_pixels > 0 && edge_pixels < (W * H / 4) as usize, "{edge_pixels} pixels refined");
    // Inside the square and in the empty corners, nothing changed.
    assert_eq!(adaptive.pixel(W / 2, H / 2), one.pixel(W / 2, H / 2));
    assert_eq!(adaptive.pixel(0, 0), one.pixel(0, 0));

    // Interleaved sampling: every sample within its pixel, neighbours on different points.
    let (inter, _) = render(Antialiasing::Interleaved, (2, 2))?;
    assert_eq!(inter.pixel(W / 2, H / 2), [1.0; 4]);
    assert!(Antialiasing::parse("adaptive:0.1") == Ok(Antialiasing::Adaptive { threshold: 0.1 }));
    assert!(Antialiasing::parse("qmc") == Ok(Antialiasing::Interleaved));
    assert!(Antialiasing::parse("adaptive:x").is_err() && Antialiasing::parse("fancy").is_err());
    Ok(())
}

#[test]
fn a_moved_instance_costs_only_the_top_level_and_an_edited_object_only_its_own_bvh() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.0, 2.0, 8.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    let boxy = rt.begin_object()?;
    cube(&mut rt)?;
    rt.end_object()?;
    let floor = rt.begin_object()?;
    quad(&mut rt, [[-5.0, -1.0, 5.0], [5.0, -1.0, 5.0], [5.0, -1.0, -5.0], [-5.0, -1.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    let moving = rt.instantiate_object(boxy)?;
    rt.instantiate_object(boxy)?;

    let (_, first) = rt.render_frame()?;
    assert_eq!(first.accel.objects_rebuilt, 2, "both objects are built once");
    assert_eq!(first.accel.instances, 3);
    assert!(first.accel.memory_bytes > 0);

    rt.set_instance_transform(moving, glam::Affine3A::from_translation(glam::Vec3::new(2.0, 0.0, 0.0)))?;
    let (_, moved) = rt.render_frame()?;
    assert_eq!(moved.accel.objects_rebuilt, 0, "moving an instance rebuilds no object BVH");
    assert_eq!(moved.accel.instances, 3);

    rt.redefine_object(floor)?;
    quad(&mut rt, [[-6.0, -1.0, 6.0], [6.0, -1.0, 6.0], [6.0, -1.0, -6.0], [-6.0, -1.0, -6.0]])?;
    rt.end_object()?;
    let (_, edited) = rt.render_frame()?;
    assert_eq!(edited.accel.objects_rebuilt, 1, "only the edited object");
    assert_eq!(edited.accel.memory_bytes, moved.accel.memory_bytes, "same size of geometry");
    assert!(edited.to_string().contains("BVH update"), "{edited}");
    Ok(())
}

/// A light whose colour is the lit surface's `Kd` (message passing from light to surface).
const KD_LIGHT: &str = r#"
light kdlight() {
    float kd = -1;
    if (surface("Kd", kd) == 0) kd = 0.25;
    solar(vector(0, 0, -1), 0) Cl = kd;
}"#;

/// A surface that shows its displacement shader's `height` and `tint` and its light.
const MESSAGES: &str = r#"
surface messages(float Kd = 0.5;) {
    float h = -1;
    color tint = 0;
    displacement("height", h);
    displacement("tint", tint);
    color lit = 0;
    illuminance(P) { lit += Cl; }
    Ci = color(h, comp(tint, 1), comp(lit, 0));
    Oi = 1;
}"#;

const HEIGHT: &str = "displacement lift(float height = 0.75; color tint = color(0, 0.5, 0);) { }";

#[test]
fn shaders_read_the_parameters_of_the_shaders_bound_with_them() -> Result<(), ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader("messages.sl", MESSAGES)?;
    let lift = rt.compile_shader("lift.sl", HEIGHT)?;
    let light = rt.compile_shader("kdlight.sl", KD_LIGHT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    rt.light_source(light, &[])?;
    // Left: Kd bound to 0.9 and a displacement shader with its defaults but `tint`; right: Kd
    // by default and no displacement shader.
    let left = rt.begin_object()?;
    rt.bind_shader(surface)?;
    rt.parameter("Kd", ParamValue::Float(0.9))?;
    rt.displacement(Some(lift), &[("tint", ParamValue::Color([0.0, 0.3, 0.0]))])?;
    quad(&mut rt, [[-3.0, -1.0, 0.0], [-0.5, -1.0, 0.0], [-0.5, 1.0, 0.0], [-3.0, 1.0, 0.0]])?;
    rt.end_object()?;
    rt.displacement(None, &[])?;
    let right = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[0.5, -1.0, 0.0], [3.0, -1.0, 0.0], [3.0, 1.0, 0.0], [0.5, 1.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(left)?;
    rt.instantiate_object(right)?;
    let (fb, _) = rt.render_frame()?;
    let l = fb.pixel(W / 4, H / 2);
    let r = fb.pixel(3 * W / 4, H / 2);
    let near = |a: f32, b: f32| (a - b).abs() < 1e-5;
    assert!(near(l[0], 0.75) && near(l[1], 0.3) && near(l[2], 0.9), "bound displacement and Kd: {l:?}");
    assert!(near(r[0], -1.0) && near(r[1], 0.0) && near(r[2], 0.5), "no displacement, default Kd: {r:?}");
    Ok(())
}

/// A surface showing the `density` of the volume its ray comes from (red) and of the one behind it
/// (green), -1 where there is none.
const SIDES: &str = r#"
surface sides() {
    float from = -1, to = -1;
    incident("density", from);
    opposite("density", to);
    Ci = color(from, to, 0);
    Oi = 1;
}"#;

#[test]
fn incident_and_opposite_read_the_volumes_on_either_side() -> Result<(), ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader("sides.sl", SIDES)?;
    let inside = rt.compile_shader("inside.sl", "volume inside(float density = 0.25;) { }")?;
    let outside = rt.compile_shader("outside.sl", "volume outside(float density = 0.125;) { }")?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    rt.interior(Some(inside), &[("density", ParamValue::Float(0.5))])?;
    // Left: the camera sees the front of the surface (its ray comes from outside); right: the back.
    let front = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-3.0, -1.0, 0.0], [-0.5, -1.0, 0.0], [-0.5, 1.0, 0.0], [-3.0, 1.0, 0.0]])?;
    rt.end_object()?;
    let back = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[0.5, -1.0, 0.0], [0.5, 1.0, 0.0], [3.0, 1.0, 0.0], [3.0, -1.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(front)?;
    rt.instantiate_object(back)?;
    let sample = |rt: &mut Context| -> Result<([f32; 4], [f32; 4]), ApiError> {
        let (fb, _) = rt.render_frame()?;
        Ok((fb.pixel(W / 4, H / 2), fb.pixel(3 * W / 4, H / 2)))
    };
    // Without an atmosphere the outside has no volume to ask.
    let (f, b) = sample(&mut rt)?;
    assert_eq!((f[0], f[1]), (-1.0, 0.5), "front: from outside into the interior");
    assert_eq!((b[0], b[1]), (0.5, -1.0), "back: from the interior out");
    // The atmosphere is the volume outside.
    rt.atmosphere(Some(outside), &[])?;
    let (f, b) = sample(&mut rt)?;
    assert_eq!((f[0], f[1]), (0.125, 0.5), "front, with an atmosphere");
    assert_eq!((b[0], b[1]), (0.5, 0.125), "back, with an atmosphere");
    Ok(())
}

/// A surface showing its diffuse and specular light in red and green.
const LIGHT_PARTS: &str = r#"
surface lightparts() {
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    Ci = color(comp(diffuse(Nf), 0), comp(specular(Nf, V, 0.3), 0), 0);
    Oi = 1;
}"#;

/// A head-on light with RenderMan's flags; `computed` sets `__nondiffuse` in the light's body.
const FLAGGED: &str = r#"
light flagged(output float __nondiffuse = 0; output float __nonspecular = 0; float computed = 0;) {
    solar(vector(0, 0, -1), 0) {
        Cl = 1;
        if (computed != 0) __nondiffuse = 1;
    }
}"#;

#[test]
fn diffuse_and_specular_skip_lights_flagged_nondiffuse_and_nonspecular() -> Result<(), ApiError> {
    let render = |params: &[(&str, ParamValue)]| -> Result<[f32; 4], ApiError> {
        let mut rt = context();
        let surface = rt.compile_shader("lightparts.sl", LIGHT_PARTS)?;
        let light = rt.compile_shader("flagged.sl", FLAGGED)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
        rt.light_source(light, params)?;
        let o = rt.begin_object()?;
        rt.bind_shader(surface)?;
        quad(&mut rt, [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]])?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        Ok(rt.render_frame()?.0.pixel(W / 2, H / 2))
    };
    let both = render(&[])?;
    assert!(both[0] > 0.9 && both[1] > 0.1, "a plain light gives diffuse and specular: {both:?}");
    let no_spec = render(&[("__nonspecular", ParamValue::Float(1.0))])?;
    assert_eq!((no_spec[0], no_spec[1]), (both[0], 0.0), "{no_spec:?}");
    let no_diff = render(&[("__nondiffuse", ParamValue::Float(1.0))])?;
    assert_eq!((no_diff[0], no_diff[1]), (0.0, both[1]), "{no_diff:?}");
    let computed = render(&[("computed", ParamValue::Float(1.0))])?;
    assert_eq!((computed[0], computed[1]), (0.0, both[1]), "the value the light computed counts: {computed:?}");
    Ok(())
}

/// A surface that adds, per light, `Cl` scaled by the light's `gain` parameter (message passing in
/// an illuminance loop; 1 where a light has no such parameter).
const PER_LIGHT: &str = r#"
surface perlight() {
    color sum = 0;
    illuminance(P) {
        float gain = 1;
        lightsource("gain", gain);
        sum += gain * Cl;
    }
    Ci = sum;
    Oi = 1;
}"#;

const GAIN_LIGHT: &str = "light gainlight(float gain = 1; color c = 1;) { solar(vector(0, 0, -1), 0) Cl = c; }";
const PLAIN_LIGHT: &str = "light plainlight(color c = 1;) { solar(vector(0, 0, -1), 0) Cl = c; }";

#[test]
fn lightsource_in_an_illuminance_loop_reads_the_current_light() -> Result<(), ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader("perlight.sl", PER_LIGHT)?;
    let gain = rt.compile_shader("gainlight.sl", GAIN_LIGHT)?;
    let plain = rt.compile_shader("plainlight.sl", PLAIN_LIGHT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    // Red with gain 0.5, green with its default gain 1, blue with no gain parameter at all.
    rt.light_source(gain, &[("gain", ParamValue::Float(0.5)), ("c", ParamValue::Color([1.0, 0.0, 0.0]))])?;
    rt.light_source(gain, &[("c", ParamValue::Color([0.0, 1.0, 0.0]))])?;
    rt.light_source(plain, &[("c", ParamValue::Color([0.0, 0.0, 1.0]))])?;
    let o = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    let p = rt.render_frame()?.0.pixel(W / 2, H / 2);
    assert_eq!(p[..3], [0.5, 1.0, 1.0], "each light's own gain: {p:?}");
    Ok(())
}

/// A surface showing its point in raster space (x, y), NDC x and screen y.
const RASTER: &str = r#"
surface rasterpos() {
    point r = transform("raster", P);
    point n = transform("NDC", P);
    point s = transform("screen", P);
    Ci = color(xcomp(r), ycomp(r), 10 * xcomp(n) + ycomp(s));
    Oi = 1;
}"#;

/// Renders `RASTER` on a wall filling the view of a 64x48 image with `window` as RIB's
/// `ScreenWindow`.
fn projected_spaces(window: Option<[f32; 4]>) -> Result<rtsl_runtime::render::Framebuffer, ApiError> {
    let mut rt = context();
    rt.options.screen_window = window;
    let surface = rt.compile_shader("rasterpos.sl", RASTER)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let o = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-30.0, -30.0, 0.0], [30.0, -30.0, 0.0], [30.0, 30.0, 0.0], [-30.0, 30.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    Ok(rt.render_frame()?.0)
}

#[test]
fn raster_ndc_and_screen_spaces_follow_renderman() -> Result<(), ApiError> {
    // The default window of a 4:3 image: screen x in [-4/3, 4/3], y in [-1, 1]; and a window
    // zoomed 2x on the upper right quarter.
    for (window, (b, t)) in [(None, (-1.0, 1.0)), (Some([0.0, 1.0, 0.0, 0.75]), (0.0, 0.75))] {
        let fb = projected_spaces(window)?;
        for (x, y) in [(48, 12), (5, 40), (63, 0)] {
            let p = fb.pixel(x, y);
            let (rx, ry) = (x as f32 + 0.5, y as f32 + 0.5);
            // Pixel centres in raster space; NDC is raster over the image size; screen y runs
            // from t at the top to b at the bottom.
            let (ndc_x, screen_y) = (rx / W as f32, t - (t - b) * ry / H as f32);
            let near = |a: f32, b: f32| (a - b).abs() < 2e-3 * (1.0 + b.abs());
            assert!(near(p[0], rx) && near(p[1], ry), "{window:?} ({x}, {y}): raster {p:?}");
            assert!(near(p[2], 10.0 * ndc_x + screen_y), "{window:?} ({x}, {y}): NDC x and screen y {p:?}");
        }
    }
    Ok(())
}

#[test]
fn the_screen_window_chooses_what_the_camera_sees() -> Result<(), ApiError> {
    // With the window on the upper right quarter of the default view, the image's centre pixel
    // sees what the default view showed at its upper right quarter's centre.
    let whole = projected_spaces(None)?;
    let quarter = projected_spaces(Some([0.0, 4.0 / 3.0, 0.0, 1.0]))?;
    let there = whole.pixel(48, 12);
    let here = quarter.pixel(32, 24);
    // Raster positions differ (each image's own), screen y agrees (within the half-pixel offsets
    // of the two pixel grids): the same point of the wall. Ignoring the window would put the
    // centre pixel at screen y 0.
    let screen_y = |p: [f32; 4]| p[2] - 10.0 * p[0] / W as f32;
    assert!((screen_y(there) - 0.479).abs() < 1e-2, "{there:?}");
    assert!((screen_y(there) - screen_y(here)).abs() < 0.02, "{there:?} vs {here:?}");
    Ok(())
}

/// A surface lit from both sides: `diffuse()` of the side facing the eye first, then the lights of
/// the far side through an illuminance loop.
const BACKLIT: &str = r#"
surface backlit() {
    normal Nf = faceforward(normalize(N), I);
    color front = diffuse(Nf);
    color back = 0;
    illuminance(P, -Nf, PI / 2) {
        back += Cl;
    }
    Ci = front + back;
    Oi = 1;
}"#;

/// A wall facing the eye, a point light behind it and a card between the two that hides the light
/// from the wall's middle; the wall shaded with `surface`. Returns the frame and its shadow rays.
fn wall_lit_from_behind(surface: &str, src: &str) -> Result<(Framebuffer, u64), ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader(surface, src)?;
    let light = rt.find_shader("pointlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    rt.light_source(light, &[("intensity", ParamValue::Float(20.0)), ("from", ParamValue::Point([0.0, 0.0, -3.0]))])?;
    let wall = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(wall)?;
    let card = rt.begin_object()?;
    quad(&mut rt, [[-0.5, -0.5, -1.5], [0.5, -0.5, -1.5], [0.5, 0.5, -1.5], [-0.5, 0.5, -1.5]])?;
    rt.end_object()?;
    rt.instantiate_object(card)?;
    let (fb, report) = rt.render_frame()?;
    Ok((fb, report.shadow_rays))
}

#[test]
fn shadows_of_lights_behind_a_surface_are_traced_only_when_a_shader_asks_for_them() -> Result<(), ApiError> {
    // `plastic` sums the lights in front of the wall only: the light behind it needs no shadow ray.
    let (plain, rays) = wall_lit_from_behind(
        "plasticwall.sl",
        &std::fs::read_to_string("../stdlib_shaders/surface/plastic.sl").expect("plastic"),
    )?;
    assert_eq!(rays, 0, "no shadow ray toward a light behind every point");
    assert_eq!(plain.pixel(W / 2, H / 2)[..3], [0.0; 3]);
    // A shader asking for the far side after `diffuse()` gets those lights shadowed all the same:
    // dark where the card hides the light, lit around it.
    let (backlit, rays) = wall_lit_from_behind("backlit.sl", BACKLIT)?;
    assert!(rays > 0);
    assert!(luminance(&backlit, W / 2, H / 2) < 1e-6, "the card's shadow: {:?}", backlit.pixel(W / 2, H / 2));
    assert!(
        luminance(&backlit, W / 2 + W / 4, H / 2) > 0.05,
        "lit beside it: {:?}",
        backlit.pixel(W / 2 + W / 4, H / 2)
    );
    Ok(())
}

/// Three quads side by side in one object, in parts: red and green ended by `end_part`, the last
/// one taking the appearance current at `end_object` (blue).
fn object_in_parts(rt: &mut Context) -> Result<(), ApiError> {
    let constant = rt.find_shader("constant")?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    rt.bind_shader(constant)?;
    let strip = rt.begin_object()?;
    let column = |x0: f32| [[x0, -1.0, 0.0], [x0 + 1.0, -1.0, 0.0], [x0 + 1.0, 1.0, 0.0], [x0, 1.0, 0.0]];
    quad(rt, column(-1.5))?;
    rt.color(1.0, 0.0, 0.0);
    rt.end_part()?;
    // A part without triangles is dropped.
    rt.end_part()?;
    quad(rt, column(-0.5))?;
    rt.color(0.0, 1.0, 0.0);
    rt.end_part()?;
    quad(rt, column(0.5))?;
    rt.color(0.0, 0.0, 1.0);
    rt.end_object()?;
    rt.instantiate_object(strip)?;
    Ok(())
}

#[test]
fn an_object_built_in_parts_shades_each_part_with_its_own_appearance() -> Result<(), ApiError> {
    let mut rt = context();
    object_in_parts(&mut rt)?;
    let world = rt.build_world()?;
    assert_eq!(world.instances.len(), 1, "one object, one instance");
    assert_eq!(world.materials.len(), 4, "the default material and one for each part");
    rt.return_scene(world);
    let fb = rt.render_frame()?.0;
    let rgb = |x: u32| {
        let p = fb.pixel(x, H / 2);
        [p[0], p[1], p[2]]
    };
    // The strip spans the middle of the image; its thirds are each a part.
    let third = |k: u32| {
        let x = (0..W).filter(|&x| fb.pixel(x, H / 2)[3] > 0.0).collect::<Vec<_>>();
        let (lo, hi) = (x[0], x[x.len() - 1]);
        lo + (hi - lo) * (2 * k + 1) / 6
    };
    assert_eq!(rgb(third(0)), [1.0, 0.0, 0.0]);
    assert_eq!(rgb(third(1)), [0.0, 1.0, 0.0]);
    assert_eq!(rgb(third(2)), [0.0, 0.0, 1.0]);
    // Each part is its own shader in the frame's ids (what adaptive sampling compares).
    let ids: std::collections::HashSet<u32> = (0..3).map(|k| fb.object_id[(H / 2 * W + third(k)) as usize]).collect();
    assert_eq!(ids.len(), 1, "one object id for the three parts");
    // Outside an object there is no part to end.
    assert!(rt.end_part().is_err());
    Ok(())
}

/// A plastic floor that the camera looks straight down at from y = 2; returns `distantlight`, for
/// a light straight down (what lies above the camera it does not see).
fn floor_seen_from_above(rt: &mut Context) -> Result<rtsl_runtime::api::ShaderId, ApiError> {
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("distantlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 2.0, 0.0), Vec3A::ZERO, Vec3A::NEG_Z, 60.0);
    rt.bind_shader(plastic)?;
    let floor = rt.begin_object()?;
    quad(rt, [[-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0], [-5.0, 0.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    Ok(light)
}

#[test]
fn shadows_through_a_stack_of_sheets_multiply_the_nearest_layers() -> Result<(), ApiError> {
    // A light straight down through `sheets` parallel sheets, each letting 0.9 of the light
    // through, onto a floor the camera looks straight down at (the sheets are behind it): the floor
    // gets 0.9 to the power of the sheets crossed, at most `max_transparent_layers` (16) of them.
    let render = |sheets: usize| -> Result<Framebuffer, ApiError> {
        let mut rt = context();
        let light = floor_seen_from_above(&mut rt)?;
        if sheets > 0 {
            let stack = rt.begin_object()?;
            rt.opacity(0.1, 0.1, 0.1);
            for k in 0..sheets {
                let y = 3.0 + 0.05 * k as f32;
                quad(&mut rt, [[-6.0, y, 6.0], [6.0, y, 6.0], [6.0, y, -6.0], [-6.0, y, -6.0]])?;
            }
            rt.end_object()?;
            rt.instantiate_object(stack)?;
        }
        let (from, to) = (ParamValue::Point([0.0, 0.0, 0.0]), ParamValue::Point([0.0, -1.0, 0.0]));
        rt.light_source(light, &[("intensity", ParamValue::Float(1.0)), ("from", from), ("to", to)])?;
        Ok(rt.render_frame()?.0)
    };
    let open = render(0)?;
    for (sheets, crossed) in [(3, 3), (20, 16)] {
        let through = render(sheets)?;
        let expected = 0.9f32.powi(crossed);
        for y in 0..H {
            for x in 0..W {
                let (o, t) = (luminance(&open, x, y), luminance(&through, x, y));
                assert!(o > 0.05, "the open floor is lit at ({x}, {y})");
                assert!((t / o - expected).abs() < 1e-3, "{sheets} sheets at ({x}, {y}): {} of the light", t / o);
            }
        }
    }
    Ok(())
}

#[test]
fn shadows_pass_through_the_transparent_part_of_an_object_only() -> Result<(), ApiError> {
    // The camera looks straight down at a floor, under a roof it cannot see (the roof is behind
    // it); a light straight down casts the roof's shadow over the whole view. The roof is one
    // object in two parts: the half over x < 0 opaque, the other opaque or clear.
    let render = |clear_part: bool| -> Result<Framebuffer, ApiError> {
        let mut rt = context();
        let light = floor_seen_from_above(&mut rt)?;
        let roof = rt.begin_object()?;
        quad(&mut rt, [[-4.0, 3.0, 4.0], [0.0, 3.0, 4.0], [0.0, 3.0, -4.0], [-4.0, 3.0, -4.0]])?;
        rt.end_part()?;
        quad(&mut rt, [[0.0, 3.0, 4.0], [4.0, 3.0, 4.0], [4.0, 3.0, -4.0], [0.0, 3.0, -4.0]])?;
        if clear_part {
            rt.opacity(0.0, 0.0, 0.0);
        }
        rt.end_object()?;
        rt.instantiate_object(roof)?;
        let (from, to) = (ParamValue::Point([0.0, 0.0, 0.0]), ParamValue::Point([0.0, -1.0, 0.0]));
        rt.light_source(light, &[("intensity", ParamValue::Float(1.0)), ("from", from), ("to", to)])?;
        Ok(rt.render_frame()?.0)
    };
    let (opaque, clear) = (render(false)?, render(true)?);
    for y in 0..H {
        for x in 0..W {
            let (o, c) = (luminance(&opaque, x, y), luminance(&clear, x, y));
            assert!(o < 1e-4, "the opaque roof shadows all the floor: {o} at ({x}, {y})");
            if x + 2 < W / 2 {
                assert!(c < 1e-4, "under the opaque part: {c} at ({x}, {y})");
            } else if x > W / 2 + 2 {
                assert!(c > 0.05, "under the clear part: {c} at ({x}, {y})");
            }
        }
    }
    Ok(())
}

#[test]
fn frames_reuse_unchanged_materials_and_rebuild_them_for_a_new_program() -> Result<(), Box<dyn std::error::Error>> {
    const FLAT: &str = "surface flat(float k = 1;) { Oi = 1; Ci = k; }";
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.bind_shader(flat)?;
    rt.parameter("k", ParamValue::Float(0.5))?;
    let object = rt.begin_object()?;
    quad(&mut rt, [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(object)?;
    let surface = |world: &rtsl_runtime::render::World| world.materials.get(1).and_then(|m| m.surface.clone());
    let first = rt.build_world()?;
    let built = surface(&first).ok_or("the object's material")?;
    rt.return_scene(first);
    let second = rt.build_world()?;
    let reused = surface(&second).ok_or("the object's material")?;
    rt.return_scene(second);
    assert!(std::sync::Arc::ptr_eq(&built, &reused), "nothing changed: the same shader instance");
    let program = ShaderProgram::from_source("flat.sl", "surface flat(float k = 1;) { Oi = 1; Ci = 2 * k; }", &[])?;
    rt.replace_shader(flat, program)?;
    let third = rt.build_world()?;
    let rebuilt = surface(&third).ok_or("the object's material")?;
    assert!(!std::sync::Arc::ptr_eq(&built, &rebuilt), "a new program: a new shader instance");
    assert!(!std::sync::Arc::ptr_eq(&built.program, &rebuilt.program));
    assert_eq!(rebuilt.params.len(), 1, "k stays bound");
    Ok(())
}

/// `ShaderProgram::lane_invariant`: a light computed from its parameters alone is; one that reads
/// a global, draws random numbers, calls a built-in or illuminates is not.
#[test]
fn lights_computed_from_their_parameters_alone_are_lane_invariant() -> Result<(), Box<dyn std::error::Error>> {
    let cases = [
        ("light a(float intensity = 1; color lightcolor = 1;) { Cl = intensity * lightcolor; }", true),
        (
            "light a(color c = 1; output float __nondiffuse = 1;) { color k = c; if (k != color(0)) k *= 2; Cl = k; }",
            true,
        ),
        ("light a(color c = 1;) { color k = c; if (comp(k, 0) > 0.5) k *= 2; Cl = k; }", false),
        ("light a(color c = 1;) { Cl = c * xcomp(Ps); }", false),
        ("light a(color c = 1;) { Cl = c * random(); }", false),
        ("light a(color c = 1;) { Cl = c * float texture(\"x.tex\", 0.5, 0.5); }", false),
        ("light a(color c = 1;) { Cl = c * sqrt(2); }", false),
        ("light a(color c = 1;) { Cl = c; Cl += Cl; }", true),
        ("light a(color c = 1;) { Cl += c; }", false),
        ("light a(color c = 1;) { illuminate(point(0, 0, 0)) Cl = c; }", false),
    ];
    for (source, invariant) in cases {
        let program = ShaderProgram::from_source("a.sl", source, &[])?;
        assert_eq!(program.lane_invariant, invariant, "{source}");
    }
    Ok(())
}

/// An ambient light run on one lane for the whole batch (lane-invariant) lights every pixel as the
/// same light run on every lane does: partly covered packets, `__nondiffuse` and several lights.
#[test]
fn a_lane_invariant_ambient_light_lights_as_one_run_on_every_lane() -> Result<(), ApiError> {
    const SURFACE: &str = "surface lit(float k = 1;) { normal Nf = faceforward(normalize(N), I); \
                           Ci = k * ambient() + diffuse(Nf); Oi = 1; }";
    let render = |ambient_source: &str| -> Result<Framebuffer, ApiError> {
        let mut rt = context();
        let surface = rt.compile_shader("lit.sl", SURFACE)?;
        let ambient = rt.compile_shader("amb.sl", ambient_source)?;
        let sun = rt.compile_shader("sun.sl", "light sun() { solar(vector(0, 0, -1), 0) Cl = color(0, 0.25, 0); }")?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
        rt.light_source(ambient, &[("c", ParamValue::Color([0.5, 0.25, 0.125]))])?;
        rt.light_source(sun, &[])?;
        rt.light_source(ambient, &[("c", ParamValue::Color([0.25, 0.0, 0.5]))])?;
        let o = rt.begin_object()?;
        rt.bind_shader(surface)?;
        // A triangle's slanted edge leaves packets partly covered.
        rt.begin(Primitive::Triangles)?;
        for c in [[-3.0, -2.0, 0.0], [2.5, -1.5, 0.0], [-1.0, 2.7, 0.0]] {
            rt.vertex(c[0], c[1], c[2])?;
        }
        rt.end()?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        Ok(rt.render_frame()?.0)
    };
    let invariant = "light amb(color c = 1; output float __nondiffuse = 1;) { Cl = 2 * c; }";
    // Reads `Ps` (to multiply by zero): run on every lane.
    let per_lane = "light amb(color c = 1; output float __nondiffuse = 1;) { Cl = 2 * c + 0 * xcomp(Ps); }";
    assert!(ShaderProgram::from_source("amb.sl", invariant, &[]).is_ok_and(|p| p.lane_invariant));
    assert!(ShaderProgram::from_source("amb.sl", per_lane, &[]).is_ok_and(|p| !p.lane_invariant));
    let (a, b) = (render(invariant)?, render(per_lane)?);
    let mut lit = 0;
    for y in 0..H {
        for x in 0..W {
            assert_eq!(a.pixel(x, y), b.pixel(x, y), "pixel ({x}, {y})");
            lit += u32::from(a.pixel(x, y)[3] > 0.0);
        }
    }
    assert!(lit > 100 && lit < W * H / 2, "the triangle covers part of the image: {lit} pixels");
    assert_eq!(a.pixel(W / 3, H / 2)[..3], [1.5, 0.75, 1.25], "both ambient lights, doubled, and the sun");
    Ok(())
}

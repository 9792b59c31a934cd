//! The engine through its API: secondary rays. `trace` sees what a mirror reflects up to the depth
//! limit, tracing a batch's rays ahead changes no pixel (also past the calls a first run notes),
//! `gather` samples a cone of shaded rays, and a mirror reflects only what traced rays see.

mod common;

use common::{context, cube, quad, FLAT, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, ShaderId};
use rtsl_runtime::render::{RayKind, RAY_TREE_BUDGET};
use rtsl_runtime::shading::ParamValue;

/// A quad at z = 0 facing the camera, shaded by `surface`, and a green wall `2 * half` wide at
/// z = 8, behind the camera, that the quad's reflected rays meet, hidden from the rays of
/// `wall_hidden_from` (RIB `Attribute "visibility"`).
fn before_a_green_wall(
    rt: &mut Context,
    surface: ShaderId,
    half: f32,
    wall_hidden_from: Option<RayKind>,
) -> Result<(), ApiError> {
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    let m = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.push_attributes();
    if let Some(kind) = wall_hidden_from {
        rt.ray_visibility(kind, false);
    }
    let wall = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.parameter("c", ParamValue::Color([0.0, 1.0, 0.0]))?;
    quad(rt, [[-half, half, 8.0], [half, half, 8.0], [half, -half, 8.0], [-half, -half, 8.0]])?;
    rt.end_object()?;
    rt.pop_attributes()?;
    rt.instantiate_object(m)?;
    rt.instantiate_object(wall)?;
    Ok(())
}

const MIRROR: &str = "surface mirrored() { Oi = 1; Ci = 0.5 * trace(P, reflect(I, normalize(N))); }";

#[test]
fn trace_sees_what_a_mirror_reflects_up_to_the_depth_limit() -> Result<(), ApiError> {
    let mut rt = context();
    let mirror = rt.compile_shader("mirrored.sl", MIRROR)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A mirror facing the camera, and a green wall behind the camera that it reflects.
    before_a_green_wall(&mut rt, mirror, 10.0, None)?;
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

/// Traces in a long loop, each ray its own (none depends on an answer).
const LOOPED: &str = r#"
surface looped()
{
    color c = 0;
    float i;
    for (i = 0; i < 200; i += 1)
        c += trace(P, reflect(I, normalize(N)) + vector(0, i * 0.001, 0));
    Oi = 1;
    Ci = c / 200;
}
"#;

/// A batch's first run notes a bounded number of `trace` calls (a 16-by-16 tile's 64 chunks times
/// 200 calls is past it): the calls past it are traced in the second run, each once, and the
/// image is the one of tracing chunk by chunk.
#[test]
fn trace_in_a_long_loop_traces_each_ray_once_and_changes_no_pixel() -> Result<(), ApiError> {
    let (w, h) = (16, 16);
    let mut rt = context();
    rt.options.width = w;
    rt.options.height = h;
    let looped = rt.compile_shader("looped.sl", LOOPED)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A quad filling the view that reflects a green wall behind the camera.
    before_a_green_wall(&mut rt, looped, 10.0, None)?;
    let (ahead, ahead_report) = rt.render_frame()?;
    rt.options.trace_ahead = false;
    let (chunked, chunked_report) = rt.render_frame()?;
    assert!(ahead == chunked);
    assert_eq!(chunked_report.secondary_rays, 200 * u64::from(w * h));
    assert_eq!(ahead_report.secondary_rays, chunked_report.secondary_rays);
    let p = ahead.pixel(w / 2, h / 2);
    assert!(p[1] > 0.4 && p[0] == 0.0, "{p:?}");
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
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A glossy quad facing the camera; a green wall behind the camera that its cone of reflected
    // rays meets at a distance of 8 to 8 / cos(0.2); nothing behind the quad.
    before_a_green_wall(&mut rt, glossy, 40.0, None)?;
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

/// Two rays a hit, each a little off the reflection: between two facing mirrors, a tree of
/// 2^depth rays per camera ray.
const SPLIT: &str = r#"
surface split()
{
    vector R = reflect(I, normalize(N));
    Oi = 1;
    Ci = 0.25 + 0.375 * trace(P, R + vector(0.001, 0, 0)) + 0.375 * trace(P, R - vector(0, 0.001, 0));
}
"#;

/// A `w` x `h` context, the camera between two facing mirrors shaded with `SPLIT`, rays `depth`
/// deep at most.
fn between_splitting_mirrors(w: u32, h: u32, depth: u32) -> Result<Context, ApiError> {
    let mut rt = context();
    (rt.options.width, rt.options.height, rt.options.max_ray_depth) = (w, h, depth);
    let split = rt.compile_shader("split.sl", SPLIT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 10.0);
    let m = rt.begin_object()?;
    rt.bind_shader(split)?;
    quad(&mut rt, [[-50.0, -50.0, 0.0], [50.0, -50.0, 0.0], [50.0, 50.0, 0.0], [-50.0, 50.0, 0.0]])?;
    quad(&mut rt, [[-50.0, 50.0, 8.0], [50.0, 50.0, 8.0], [50.0, -50.0, 8.0], [-50.0, -50.0, 8.0]])?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    Ok(rt)
}

/// The ray depth bounds how deep rays nest, not how many there are: at the deepest ray depth a
/// frame of a shader that traces twice a hit ends, each camera sample spawning at most its budget,
/// the rays past it counted and warned of.
#[test]
fn a_camera_samples_ray_tree_stops_at_its_budget() -> Result<(), ApiError> {
    let (w, h) = (2, 1);
    let mut rt = between_splitting_mirrors(w, h, 64)?;
    let (fb, report) = rt.render_frame()?;
    let samples = u64::from(w * h);
    let budget = u64::from(RAY_TREE_BUDGET);
    assert!(report.secondary_rays <= samples * budget, "{report}");
    assert!(report.secondary_rays >= samples * (budget - 64), "the budget is spent: {report}");
    assert!(report.rays_cut > 0);
    let warnings = report.warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains(&RAY_TREE_BUDGET.to_string()), "{warnings:?}");
    let p = fb.pixel(0, 0);
    assert!(p[0] > 0.25 && p[0] < 1.0, "{p:?}");
    Ok(())
}

/// Within its budget a sample's tree is traced whole, with and without tracing ahead; past it,
/// only the samples that pass it change.
#[test]
fn a_tree_within_its_budget_is_traced_whole() -> Result<(), ApiError> {
    // 2 + 4 + ... + 2^10 rays per camera sample.
    let (w, h, depth) = (8, 4, 10);
    let mut rt = between_splitting_mirrors(w, h, depth)?;
    let (ahead, ahead_report) = rt.render_frame()?;
    rt.options.trace_ahead = false;
    let (chunked, chunked_report) = rt.render_frame()?;
    assert!(ahead == chunked);
    for report in [&ahead_report, &chunked_report] {
        assert_eq!(report.secondary_rays, u64::from(w * h) * ((2 << depth) - 2), "{report}");
        assert_eq!(report.rays_cut, 0);
        assert!(report.warnings().is_empty());
    }
    Ok(())
}

/// A floor with a box standing on it, seen from above at an angle, every surface shaded by
/// `shader` (named `ao`).
fn floor_and_box(shader: &str) -> Context {
    let rib = r#"
        Format 48 36 1
        Projection "perspective" "fov" 50
        Translate 0 -0.5 5
        Rotate -30 1 0 0
        WorldBegin
        Surface "ao"
        Polygon "P" [-3 -1 -3  3 -1 -3  3 -1 3  -3 -1 3]
        Polygon "P" [-0.5 -1 -0.5  -0.5 0 -0.5  0.5 0 -0.5  0.5 -1 -0.5]
        Polygon "P" [-0.5 -1 0.5  0.5 -1 0.5  0.5 0 0.5  -0.5 0 0.5]
        Polygon "P" [-0.5 -1 -0.5  -0.5 -1 0.5  -0.5 0 0.5  -0.5 0 -0.5]
        Polygon "P" [0.5 -1 -0.5  0.5 0 -0.5  0.5 0 0.5  0.5 -1 0.5]
        Polygon "P" [-0.5 0 -0.5  -0.5 0 0.5  0.5 0 0.5  0.5 0 -0.5]
        WorldEnd
    "#;
    let mut rt = Context::new();
    rt.compile_shader("ao", shader).expect("the test shader compiles");
    rtsl_runtime::rib::load::load_str(&mut rt, rib, std::path::Path::new("<floor>")).expect("the floor loads");
    rt
}

/// A batch whose shader calls `occlusion` runs twice so that its chunks' hemisphere rays are
/// traced together (`RenderOptions::trace_ahead`): the image is the one of tracing each chunk's
/// rays on its own, bit for bit, also where a point's second query depends on its first one's
/// answer (the first run's placeholder sends it elsewhere, so it is traced again in the second);
/// where nothing depends on an answer, each point's rays are traced once either way.
#[test]
fn tracing_a_batchs_occlusion_rays_ahead_changes_no_pixel() {
    let plain = "surface ao() {
        normal Nf = faceforward(normalize(N), I);
        Ci = 1 - occlusion(P, Nf, 24);
        Oi = 1;
    }";
    let dependent = "surface ao() {
        normal Nf = faceforward(normalize(N), I);
        float first = occlusion(P, Nf, 24);
        normal bent = Nf;
        if (first > 0.1)
            bent = normalize(Nf + normal(0.3, 0.1, 0.2));
        Ci = 1 - 0.5 * (first + occlusion(P, bent, 16));
        Oi = 1;
    }";
    for (shader, independent) in [(plain, true), (dependent, false)] {
        let mut rt = floor_and_box(shader);
        let (ahead, ahead_report) = rt.render_frame().expect("a frame");
        rt.options.trace_ahead = false;
        let (chunked, chunked_report) = rt.render_frame().expect("a frame");
        assert!(ahead == chunked, "independent: {independent}");
        // The box darkens the floor around it, and the open sky leaves most of it lit.
        let pixels: Vec<f32> =
            (0..36).flat_map(|y| (0..48).map(move |x| (x, y))).map(|(x, y)| ahead.pixel(x, y)[0]).collect();
        let shaded = pixels.iter().filter(|&&v| v > 0.05 && v < 0.95).count();
        let open = pixels.iter().filter(|&&v| v >= 0.95).count();
        assert!(shaded > 40 && open > 200, "independent: {independent}: {shaded} shaded, {open} open");
        if independent {
            assert_eq!(ahead_report.secondary_rays, chunked_report.secondary_rays);
        } else {
            assert!(ahead_report.secondary_rays > chunked_report.secondary_rays, "{ahead_report}\n{chunked_report}");
        }
    }
}

/// A surface hidden from traced rays (RIB `Attribute "visibility" "trace" 0`) is not what a
/// mirror reflects; hidden from the camera or from shadow rays, it still is.
#[test]
fn a_mirror_reflects_only_surfaces_traced_rays_see() -> Result<(), ApiError> {
    for (hidden, green) in
        [(None, 0.5), (Some(RayKind::Trace), 0.0), (Some(RayKind::Camera), 0.5), (Some(RayKind::Shadow), 0.5)]
    {
        let mut rt = context();
        let mirror = rt.compile_shader("mirrored.sl", MIRROR)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
        before_a_green_wall(&mut rt, mirror, 10.0, hidden)?;
        let (fb, _) = rt.render_frame()?;
        let p = fb.pixel(W / 2, H / 2);
        assert!((p[1] - green).abs() < 1e-5 && p[0] == 0.0, "{hidden:?}: {p:?}");
    }
    Ok(())
}

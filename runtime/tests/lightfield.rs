//! Two-plane light fields: a light field captured by the engine (`lightfield::capture`) and shown
//! on a rectangle by the `twoplane` lightfield shader looks like the scene it was captured from,
//! seen from a new eye point between the cameras (parallax included).

use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, Primitive};
use rtsl_runtime::lightfield::{capture, LightfieldSpec};
use rtsl_runtime::render::{Antialiasing, Framebuffer};
use rtsl_runtime::shading::ParamValue;

const W: u32 = 48;
const H: u32 = 48;

fn card(rt: &mut Context, color: [f32; 3], corners: [[f32; 3]; 4]) -> Result<(), ApiError> {
    let constant = rt.find_shader("constant")?;
    let id = rt.begin_object()?;
    rt.bind_shader(constant)?;
    rt.color(color[0], color[1], color[2]);
    rt.begin(Primitive::Quads)?;
    for c in corners {
        rt.vertex(c[0], c[1], c[2])?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.instantiate_object(id)?;
    Ok(())
}

/// Two cards at different depths around the origin, so the view changes with the eye point.
fn cards(rt: &mut Context) -> Result<(), ApiError> {
    card(rt, [0.9, 0.2, 0.1], [[-0.8, -0.6, 0.6], [0.2, -0.6, 0.6], [0.2, 0.5, 0.6], [-0.8, 0.5, 0.6]])?;
    card(rt, [0.1, 0.8, 0.3], [[0.0, -0.2, -0.4], [0.5, -0.2, -0.4], [0.5, 0.3, -0.4], [0.0, 0.3, -0.4]])
}

fn context(eye: Vec3A) -> Context {
    let mut rt = Context::new();
    rt.options.width = W;
    rt.options.height = H;
    rt.options.samples = (2, 2);
    rt.options.antialiasing = Antialiasing::Grid { jitter: false };
    rt.camera_look_at(eye, Vec3A::ZERO, Vec3A::Y, 30.0);
    rt
}

fn mean_difference(a: &Framebuffer, b: &Framebuffer) -> f32 {
    let n = a.rgba.len() as f32;
    a.rgba.iter().zip(&b.rgba).map(|(x, y)| (x - y).abs()).sum::<f32>() / n
}

#[test]
fn a_captured_light_field_looks_like_its_scene_from_a_new_eye_point() -> Result<(), Box<dyn std::error::Error>> {
    // Capture: the uv square of half side 1 at the origin, cameras on the -z side, 3 units away.
    let mut capture_rt = context(Vec3A::new(0.0, 0.0, -3.0));
    cards(&mut capture_rt)?;
    let mut spec = LightfieldSpec::facing(Vec3A::ZERO, 1.0, Vec3A::NEG_Z, Vec3A::Y);
    spec.distance = 3.0;
    spec.views = 9;
    spec.view_size = 32;
    let mut views_done = 0;
    let atlas = capture(&mut capture_rt, &spec, &mut |done, _| views_done = done)?;
    assert_eq!(views_done, 81);
    assert_eq!(atlas.side, 9 * 32);

    // A new eye point between the cameras, a little off the axis.
    let eye = Vec3A::new(0.37, -0.21, -3.0);
    let mut real = context(eye);
    cards(&mut real)?;
    let (truth, _) = real.render_frame()?;

    let mut shown = context(eye);
    let side = atlas.side;
    shown.tex_image_2d("lf", side as usize, side as usize, 4, &atlas.rgba)?;
    let twoplane = shown.find_shader("twoplane")?;
    let id = shown.begin_object()?;
    shown.bind_shader(twoplane)?;
    shown.parameter("lightfield", ParamValue::String("lf".into()))?;
    shown.parameter("nviews", ParamValue::Float(9.0))?;
    shown.parameter("viewsize", ParamValue::Float(32.0))?;
    shown.parameter("distance", ParamValue::Float(3.0))?;
    shown.begin(Primitive::Quads)?;
    for c in [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        shown.vertex(c[0], c[1], c[2])?;
    }
    shown.end()?;
    shown.end_object()?;
    shown.load_matrix(spec.world_from_object());
    shown.instantiate_object(id)?;
    let (seen, _) = shown.render_frame()?;
    // (A build for plain x86-64 on a newer CPU says so, in the process's first context.)
    assert!(shown.take_warnings().iter().all(|w| Some(w.as_str()) == rtsl_runtime::cpu::build_note()));

    let covered = |fb: &Framebuffer| fb.rgba.chunks(4).filter(|p| p[3] > 0.5).count();
    assert!(covered(&truth) > 200, "the cards fill part of the view");
    let error = mean_difference(&truth, &seen);
    // Against a view from a wrong eye point, the error is several times larger.
    let mut elsewhere = context(Vec3A::new(-0.9, 0.7, -3.0));
    cards(&mut elsewhere)?;
    let (other, _) = elsewhere.render_frame()?;
    let wrong = mean_difference(&other, &seen);
    assert!(error < 0.03, "the light field reproduces the view: mean error {error} (other view {wrong})");
    assert!(wrong > 3.0 * error, "parallax matters: {wrong} vs {error}");
    Ok(())
}

/// The API checks the atlas too, however many views it is asked for (their product overflows
/// `u32` here), before anything is allocated.
#[test]
fn an_atlas_past_the_image_limits_is_an_error() {
    let mut rt = context(Vec3A::new(0.0, 0.0, 3.0));
    let mut spec = LightfieldSpec::facing(Vec3A::ZERO, 1.0, Vec3A::Z, Vec3A::Y);
    (spec.views, spec.view_size) = (1 << 20, 1 << 20);
    let e = capture(&mut rt, &spec, &mut |_, _| {}).err().expect("refused");
    assert!(matches!(e, ApiError::ImageSize(_)), "{e}");
    assert!(e.to_string().contains("at most 32768 pixels a side"), "{e}");
    (spec.views, spec.view_size) = (64, 128);
    assert!(spec.atlas_side().is_err_and(|e| e.contains("at most 33554432")));
    (spec.views, spec.view_size) = (8, 32);
    assert_eq!(spec.atlas_side(), Ok(256));
}

#[test]
fn a_light_field_seen_from_behind_or_without_an_image_is_transparent() -> Result<(), ApiError> {
    let mut rt = context(Vec3A::new(0.0, 0.0, 3.0));
    let twoplane = rt.find_shader("twoplane")?;
    let id = rt.begin_object()?;
    rt.bind_shader(twoplane)?;
    rt.begin(Primitive::Quads)?;
    for c in [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        rt.vertex(c[0], c[1], c[2])?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.load_matrix(LightfieldSpec::facing(Vec3A::ZERO, 1.0, Vec3A::NEG_Z, Vec3A::Y).world_from_object());
    rt.instantiate_object(id)?;
    let (fb, report) = rt.render_frame()?;
    assert!(report.shaded_points > 0);
    assert!(fb.rgba.iter().all(|v| *v == 0.0));
    Ok(())
}

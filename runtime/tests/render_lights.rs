//! The engine through its API: lights. `diffuse` and `specular` skip lights flagged against them,
//! `lightsource` reads the current light in an illuminance loop, and lights computed from their
//! parameters alone run once for every lane.

mod common;

use common::{context, quad, H, W};
use glam::Vec3A;
use rtsl_compiler::abi::MAX_LIGHTS;
use rtsl_runtime::api::{ApiError, Context, Primitive, ShaderId};
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::shading::{ParamValue, ShaderProgram};

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

/// The centre pixel of a quad facing the camera, shaded by [`LIGHT_PARTS`] and lit head-on by the
/// light `light` gives (its shader, and the parameters that point it at the quad) with `params`.
fn light_parts(
    light: impl Fn(&mut Context) -> Result<(ShaderId, Vec<(&'static str, ParamValue)>), ApiError>,
    params: &[(&str, ParamValue)],
) -> Result<[f32; 4], ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader("lightparts.sl", LIGHT_PARTS)?;
    let (light, mut all) = light(&mut rt)?;
    all.extend(params.iter().cloned());
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    rt.light_source(light, &all)?;
    let o = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    Ok(rt.render_frame()?.0.pixel(W / 2, H / 2))
}

#[test]
fn diffuse_and_specular_skip_lights_flagged_nondiffuse_and_nonspecular() -> Result<(), ApiError> {
    let flagged = |rt: &mut Context| Ok((rt.compile_shader("flagged.sl", FLAGGED)?, Vec::new()));
    let both = light_parts(flagged, &[])?;
    assert!(both[0] > 0.9 && both[1] > 0.1, "a plain light gives diffuse and specular: {both:?}");
    let no_spec = light_parts(flagged, &[("__nonspecular", ParamValue::Float(1.0))])?;
    assert_eq!((no_spec[0], no_spec[1]), (both[0], 0.0), "{no_spec:?}");
    let no_diff = light_parts(flagged, &[("__nondiffuse", ParamValue::Float(1.0))])?;
    assert_eq!((no_diff[0], no_diff[1]), (0.0, both[1]), "{no_diff:?}");
    let computed = light_parts(flagged, &[("computed", ParamValue::Float(1.0))])?;
    assert_eq!((computed[0], computed[1]), (0.0, both[1]), "the value the light computed counts: {computed:?}");

    // The library's lights take the flags too (RIB files exported for PRMan pass them).
    let distant = |rt: &mut Context| {
        let aimed = vec![("from", ParamValue::Point([0.0, 0.0, 1.0])), ("to", ParamValue::Point([0.0; 3]))];
        Ok((rt.find_shader("distantlight")?, aimed))
    };
    let both = light_parts(distant, &[])?;
    assert!(both[0] > 0.9 && both[1] > 0.1, "{both:?}");
    assert_eq!(light_parts(distant, &[("__nondiffuse", ParamValue::Float(1.0))])?[..2], [0.0, both[1]]);
    assert_eq!(light_parts(distant, &[("__nonspecular", ParamValue::Float(1.0))])?[..2], [both[0], 0.0]);
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

/// Past `MAX_LIGHTS` lights at a shading point (an area light's samples each one), the lights
/// left out are counted and the frame warns, naming the limit; within it, nothing is said.
#[test]
fn lights_past_the_per_point_limit_are_counted_and_warned_of() -> Result<(), ApiError> {
    let render = |lights: usize| -> Result<rtsl_runtime::render::FrameReport, ApiError> {
        let mut rt = context();
        (rt.options.width, rt.options.height) = (8, 8);
        let matte = rt.find_shader("matte")?;
        let point = rt.find_shader("pointlight")?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
        for k in 0..lights {
            let from = ParamValue::Point([k as f32 * 0.1 - 2.0, 1.0, 3.0]);
            rt.light_source(point, &[("from", from), ("intensity", ParamValue::Float(1.0))])?;
        }
        let o = rt.begin_object()?;
        rt.bind_shader(matte)?;
        quad(&mut rt, [[-5.0, -5.0, 0.0], [5.0, -5.0, 0.0], [5.0, 5.0, 0.0], [-5.0, 5.0, 0.0]])?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        Ok(rt.render_frame()?.1)
    };
    let within = render(MAX_LIGHTS)?;
    assert_eq!(within.lights_dropped, 0);
    assert!(within.warnings().is_empty(), "{:?}", within.warnings());
    let past = render(MAX_LIGHTS + 3)?;
    // Every pixel sees the quad, and every light reaches it.
    assert_eq!(past.lights_dropped, 3 * 64, "{past}");
    let warnings = past.warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains(&format!("more than {MAX_LIGHTS} lights")), "{warnings:?}");
    Ok(())
}

/// Pixie's globals (warning W0012 at compile time): a light shader's `I` (from the eye to the lit
/// point) and `Ns` (the lit surface's normal, faced toward the eye), an imager's `s` and `t` (the
/// pixel's place over the image), and a light's `N` and a surface's `I` written.
#[test]
fn pixies_globals_have_their_documented_values() -> Result<(), ApiError> {
    let mut rt = context();
    let light = rt.compile_shader(
        "facing.sl",
        "light facing() { N = normal(0, 1, 0); illuminate(point(0, 0, 0)) { Cl = Ns . normalize(-I); } }",
    )?;
    let surface = rt.compile_shader(
        "showcl.sl",
        "surface showcl() { color c = 0; illuminance(P) { c += Cl; } I = -I; Ci = c; Oi = 1; }",
    )?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    let o = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    rt.light_source(light, &[])?;
    let (fb, _) = rt.render_frame()?;
    let (centre, corner) = (fb.pixel(W / 2, H / 2)[0], fb.pixel(0, 0)[0]);
    assert!((centre - 1.0).abs() < 0.01, "the eye looks straight at the lit point: {centre}");
    assert!(corner > 0.8 && corner < centre, "obliquely, the cosine between Ns and -I: {corner}");
    // An imager reading s and t.
    let imager = rt.compile_shader("st.sl", "imager st() { Ci = color(s, t, 0); }")?;
    rt.pixel_shader(Some(imager), &[])?;
    let (fb, _) = rt.render_frame()?;
    let p = fb.pixel(W / 4, H / 2);
    assert!((p[0] - (W as f32 / 4.0 + 0.5) / W as f32).abs() < 1e-6, "{p:?}");
    assert!((p[1] - (H as f32 / 2.0 + 0.5) / H as f32).abs() < 1e-6, "{p:?}");
    Ok(())
}

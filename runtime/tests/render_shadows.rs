//! The engine through its API: shadows and transparency. Shadows darken only what is hidden and
//! pass through translucent and cut-out surfaces, multiplying the nearest layers; shadow maps
//! honour blur, bias and the pixel footprint; lights behind a surface cast shadows only when a
//! shader asks; transparent surfaces composite front to back.

mod common;

use common::{context, luminance, quad, shadow_scene, shadow_scene_with_cube_opacity, FLAT, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::shading::ParamValue;

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

const SHADOWED_BY_DEFAULT: &str = r#"
surface shadowed_by_default(string map = ""; float bias = -1;)
{
    Oi = 1;
    Ci = bias < 0 ? shadow(map, P) : shadow(map, P, "bias", bias);
}
"#;

#[test]
fn shadow_lookups_without_a_bias_take_the_frame_s() -> Result<(), ApiError> {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let map = dir.path().join("half.shad");
    write_half_occluded_map(&map);
    // The plane z = 0, one unit behind the occluder as the light sees it; the left column.
    let shadowed = |frame_bias: [f32; 2], call_bias: f32| -> Result<f32, ApiError> {
        let mut rt = context();
        rt.options.shadow_bias = frame_bias;
        let shader = rt.compile_shader("shadowed_by_default.sl", SHADOWED_BY_DEFAULT)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, Vec3A::Y, 90.0);
        let o = rt.begin_object()?;
        rt.bind_shader(shader)?;
        rt.parameter("map", ParamValue::String(map.display().to_string()))?;
        rt.parameter("bias", ParamValue::Float(call_bias))?;
        quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        let (fb, _) = rt.render_frame()?;
        Ok(fb.pixel(0, H / 2)[0])
    };
    let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
    assert_eq!(shadowed([0.0; 2], -1.0)?, 1.0, "no bias by default");
    assert_eq!(shadowed([2.0; 2], -1.0)?, 0.0, "the frame's bias reaches past the occluder");
    // Aqsis's bias0 and bias1: the point is half-way up the ramp from 0.5 to 1.5.
    let ramp = shadowed([0.5, 1.5], -1.0)?;
    assert!(close(ramp, 0.5), "{ramp}");
    // A call's own bias wins, a zero one too.
    assert_eq!(shadowed([2.0; 2], 0.0)?, 1.0);
    assert_eq!(shadowed([0.0; 2], 2.0)?, 0.0);
    Ok(())
}

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

/// A floor seen from straight above, lit from low on one side past a square at y = 1, whose
/// shadow falls on the other side: the floor's brightness there (x = -2.6, beside the square), over
/// what it is with no square.
fn shadow_beside_a_square(square: &str) -> f32 {
    let floor = |square: &str| common::luminance(&floor_lit_past_a_square(square), 4, 16);
    let open = floor("");
    assert!(open > 0.0, "the floor is lit");
    floor(square) / open
}

/// The frame [`shadow_beside_a_square`] looks at.
fn floor_lit_past_a_square(square: &str) -> rtsl_runtime::render::Framebuffer {
    {
        let rib = format!(
            "Format 32 32 1 Projection \"perspective\" \"fov\" 60
         Rotate -90 1 0 0 Translate 0 -6 0
         WorldBegin
           Attribute \"light\" \"shadows\" \"on\"
           LightSource \"pointlight\" 1 \"intensity\" [30] \"from\" [3 2 0]
           Surface \"matte\"
           Polygon \"P\" [-5 0 -5  5 0 -5  5 0 5  -5 0 5]
           {square}
         WorldEnd"
        );
        let (mut rt, warnings) = common::load(&rib);
        assert!(warnings.is_empty(), "{warnings:?}");
        common::render(&mut rt)
    }
}

#[test]
fn one_sided_surfaces_and_clipped_parts_cast_no_shadow_from_behind() {
    // Wound so that its outside faces up: shadow rays from the floor meet its back.
    let facing_up = "Polygon \"P\" [-1.5 1 -1.5  -1.5 1 1.5  1.5 1 1.5  1.5 1 -1.5]";
    let two_sided = shadow_beside_a_square(facing_up);
    let one_sided = shadow_beside_a_square(&format!("AttributeBegin Sides 1 {facing_up} AttributeEnd"));
    let clipped = shadow_beside_a_square(&format!("ClippingPlane 0 0.5 0  0 1 0 {facing_up}"));
    assert!(two_sided < 0.1, "a two-sided square shadows the floor: {two_sided}");
    assert!(one_sided > 0.5, "a one-sided square seen from behind casts no shadow: {one_sided}");
    assert!(clipped > 0.5, "a clipped square casts no shadow: {clipped}");
}

#[test]
fn surfaces_hidden_from_some_rays_are_met_by_the_others_only() {
    let square = "Polygon \"P\" [-1.5 1 -1.5  -1.5 1 1.5  1.5 1 1.5  1.5 1 -1.5]";
    let hidden = |attribute: &str| format!("AttributeBegin Attribute {attribute} {square} AttributeEnd");
    let from_camera = hidden("\"visibility\" \"int camera\" [0]");
    // Hidden from the camera, the square still shadows the floor; the camera sees the floor through it.
    assert!(shadow_beside_a_square(&from_camera) < 0.1, "{}", shadow_beside_a_square(&from_camera));
    let depth_at_centre = |square: &str| {
        let fb = floor_lit_past_a_square(square);
        fb.depth[(16 * fb.width + 16) as usize]
    };
    assert!((depth_at_centre(square) - 5.0).abs() < 0.01, "{}", depth_at_centre(square));
    assert!((depth_at_centre(&from_camera) - 6.0).abs() < 0.01, "{}", depth_at_centre(&from_camera));
    // Hidden from shadow rays, it casts no shadow, and the camera still sees it.
    for shadowless in [
        "\"visibility\" \"int transmission\" [0]",
        "\"visibility\" \"string transmission\" [\"transparent\"]",
        "\"render\" \"string casts_shadows\" [\"none\"]",
        // BMRT's bits: 1 camera, 2 reflection, 4 shadow rays.
        "\"render\" \"integer visibility\" [3]",
    ] {
        let square = hidden(shadowless);
        let lit = shadow_beside_a_square(&square);
        assert!(lit > 0.99, "{shadowless}: {lit}");
        assert!((depth_at_centre(&square) - 5.0).abs() < 0.01, "{shadowless}");
    }
    let opaque = hidden("\"visibility\" \"string transmission\" [\"opaque\"]");
    assert!(shadow_beside_a_square(&opaque) < 0.1);
}

/// `Matte 1` makes a holdout: camera rays that meet it leave the pixel transparent black and see
/// nothing behind it, while it still shadows what other rays light.
#[test]
fn a_matte_surface_is_a_transparent_black_hole_that_still_casts_shadows() {
    let square = "Polygon \"P\" [-1.5 1 -1.5  -1.5 1 1.5  1.5 1 1.5  1.5 1 -1.5]";
    let matte = format!("AttributeBegin Matte 1 {square} AttributeEnd");
    assert!(shadow_beside_a_square(&matte) < 0.1, "{}", shadow_beside_a_square(&matte));
    let fb = floor_lit_past_a_square(&matte);
    let centre = (16 * fb.width + 16) as usize;
    assert_eq!(fb.pixel(16, 16), [0.0; 4]);
    assert!((fb.depth[centre] - 5.0).abs() < 0.01, "{}", fb.depth[centre]);
    assert!(
        fb.pixel(28, 16)[3] == 1.0 && common::luminance(&fb, 28, 16) > 0.0,
        "the floor beside it is lit and opaque"
    );
    // Seen through a half-transparent sheet, the sheet's own share is all the pixel holds.
    let sheet = "AttributeBegin Surface \"constant\" Color [1 0 0] Opacity [0.5 0.5 0.5] \
                 Polygon \"P\" [-5 3 -5  -5 3 5  5 3 5  5 3 -5] AttributeEnd";
    let through = floor_lit_past_a_square(&format!("{sheet} {matte}"));
    let p = through.pixel(16, 16);
    assert!((p[0] - 0.5).abs() < 1e-4 && p[1] == 0.0 && (p[3] - 0.5).abs() < 1e-4, "{p:?}");
    let beside = through.pixel(28, 16);
    assert!(beside[1] > 0.0 && beside[3] == 1.0, "the floor shows through the sheet beside it: {beside:?}");
    // `Matte 0` is an ordinary surface again.
    let ordinary = floor_lit_past_a_square(&format!("AttributeBegin Matte 1 Matte 0 {square} AttributeEnd"));
    assert_eq!(ordinary.pixel(16, 16)[3], 1.0);
}

/// `Hider "hidden" "depthfilter" "midpoint"` gives each pixel the depth halfway between the
/// surface its camera ray meets and the next one behind it (infinite where none is): what
/// midpoint shadow maps store.
#[test]
fn the_midpoint_depth_filter_takes_depth_halfway_to_the_next_surface() {
    let depths = |hider: &str| {
        let rib = format!(
            "Format 32 32 1 {hider} Projection \"perspective\" \"fov\" 30 Translate 0 0 5
             WorldBegin Sphere 1 -1 1 360
             AttributeBegin Translate 0 0 5 Polygon \"P\" [-2.5 -2.5 0  2.5 -2.5 0  2.5 2.5 0  -2.5 2.5 0] AttributeEnd
             WorldEnd"
        );
        let (mut rt, warnings) = common::load(&rib);
        let fb = common::render(&mut rt);
        // The sphere's centre, the square behind it beside the sphere, and nothing.
        let at = |x: u32, y: u32| fb.depth[(y * fb.width + x) as usize];
        (at(16, 16), at(16, 2), at(0, 0), warnings)
    };
    let (sphere, square, nothing, warnings) = depths("");
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(
        (sphere - 4.0).abs() < 0.01 && (square - 10.0).abs() < 0.05 && nothing == f32::INFINITY,
        "{sphere} {square} {nothing}"
    );
    // The sphere's front at 4 and back at 6, then the square at 10 behind it.
    let (sphere, square, nothing, warnings) = depths("Hider \"hidden\" \"depthfilter\" \"midpoint\"");
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!((sphere - 5.0).abs() < 0.01, "{sphere}");
    assert!(square == f32::INFINITY && nothing == f32::INFINITY, "{square} {nothing}");
    let (sphere, .., warnings) = depths("Hider \"hidden\" \"depthfilter\" \"average\"");
    assert!((sphere - 4.0).abs() < 0.01 && warnings.len() == 1 && warnings[0].contains("\"average\""), "{warnings:?}");
}

/// Surfaces whose shader gives their shadow's opacity (`transmissionhitmode "shader"`) are shaded
/// for the shadow rays that cross them, and their shaders' light queries trace shadows in turn:
/// those take the surfaces' opacity rather than running the shaders again, so a wooden cylinder
/// between two shadowed lights renders instead of recursing until the stack overflows (as it did,
/// found by fuzzing).
#[test]
fn shadows_cast_while_shading_for_a_shadow_run_no_shader_again() {
    let rib = r#"
        Format 12 12 1
        Option "trace" "maxdepth" [2]
        WorldBegin
        Attribute "light" "shadows" "on"
        LightSource "pointlight" 1 "intensity" [0.3] "from" [0.3 0.5 0.35]
        Attribute "shade" "transmissionhitmode" "shader"
        LightSource "pointlight" 2 "intensity" [40] "from" [-3 7 -4]
        Rotate -90 1 0 0
        Surface "wood" "ringscale" [14]
        Cylinder 0.45 0 1.4 360
        Disk 1.4 0.45 360
        WorldEnd
    "#;
    let (mut rt, warnings) = common::load(rib);
    assert!(warnings.is_empty(), "{warnings:?}");
    // (The camera, RenderMan's default at the origin, looks from inside the cylinder.)
    let fb = common::render(&mut rt);
    let covered = fb.rgba.chunks_exact(4).filter(|p| p[3] > 0.0).count();
    assert!(covered > 0, "the wood shows");
    assert!(fb.rgba.iter().all(|v| v.is_finite()));
}

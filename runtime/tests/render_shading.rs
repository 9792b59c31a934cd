//! The engine through its API: what shaders see. Vertex values interpolated at the hit, the
//! parameters of the shaders bound with them, the volumes on either side, the raster, NDC and
//! screen spaces and the screen window, and each part of an object built in parts.

mod common;

use common::{context, quad, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, Primitive};
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::shading::ParamValue;

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
    read_bound_parameters(MESSAGES, KD_LIGHT)?;
    // Uniform destinations, as RenderMan light shaders declare them, take the bound values too (a
    // batch's shaders are bound the same in every lane).
    let surface = MESSAGES.replace("float h", "uniform float h").replace("color tint", "uniform color tint");
    let light = KD_LIGHT.replace("float kd", "uniform float kd");
    assert!(surface.matches("uniform").count() == 2 && light.contains("uniform"));
    read_bound_parameters(&surface, &light)
}

fn read_bound_parameters(surface: &str, light: &str) -> Result<(), ApiError> {
    let mut rt = context();
    let surface = rt.compile_shader("messages.sl", surface)?;
    let lift = rt.compile_shader("lift.sl", HEIGHT)?;
    let light = rt.compile_shader("kdlight.sl", light)?;
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

/// Renders an 8x8 frame of two halves shaded by surface shader `name` (`source`): the left half
/// with the attributes `left` (inside its own attribute block), the right without; `options`
/// come before the frame. Loading must not warn.
fn two_halves(name: &str, source: &str, options: &str, left: &str) -> Framebuffer {
    let dir = tempfile::tempdir().expect("tempdir");
    common::write(dir.path(), &format!("{name}.sl"), source);
    let rib = format!(
        "Option \"searchpath\" \"shader\" [\".:&\"] {options}
        Format 8 8 1 Projection \"perspective\" \"fov\" 60
        WorldBegin Translate 0 0 3 Surface \"{name}\"
        AttributeBegin {left} Polygon \"P\" [-5 -5 0 0 -5 0 0 5 0 -5 5 0] AttributeEnd
        Polygon \"P\" [0 -5 0 5 -5 0 5 5 0 0 5 0]
        WorldEnd"
    );
    let mut rt = Context::new();
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, &rib, dir.path().join("halves.rib")).expect("loads");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    common::render(&mut rt)
}

/// RenderMan's user data: `Option "user"` and `Attribute "user"` values reach shaders through
/// `option("user:name")` and `attribute("user:name")` (the shaded object's own), with the
/// standard `attribute("Sides")`; a name nothing sets answers 0 and leaves the variable.
#[test]
fn shaders_read_user_options_and_attributes() {
    let source = "surface userdata() {
        string pass = \"none\"; color tint = color(0, 0, 1); float sides = 0, missing = 7;
        float found = option(\"user:pass\", pass) + attribute(\"user:tint\", tint);
        found += attribute(\"Sides\", sides) + attribute(\"user:nothing\", missing) + option(\"user:nothing\", missing);
        Oi = 1;
        Ci = pass == \"beauty\" ? tint * sides / 2 * found / 3 * missing / 7 : color(0, 1, 0);
    }";
    let pass = "Option \"user\" \"string pass\" [\"beauty\"]";
    let tint = "Attribute \"user\" \"color tint\" [1 0.5 0.25]";
    let fb = two_halves("userdata", source, pass, tint);
    // Left: the attribute's tint; right: no tint attribute, so its default, and one less found.
    let (left, right) = (fb.pixel(1, 4), fb.pixel(6, 4));
    assert_eq!(&left[..3], &[1.0, 0.5, 0.25], "{left:?}");
    assert!((right[2] - 2.0 / 3.0).abs() < 1e-6 && right[0] == 0.0, "{right:?}");
    // Without the option the pass reads "none".
    assert_eq!(two_halves("userdata", source, "", tint).pixel(1, 4), [0.0, 1.0, 0.0, 1.0]);
}

/// PRMan's `Ri:` names of standard attributes: `attribute("Ri:Color")` and `"Ri:Opacity"` read the
/// object's `Color` and `Opacity`, `"Ri:Sides"` and `"Ri:Matte"` the same as `"Sides"` and
/// `"Matte"`.
#[test]
fn shaders_read_standard_attributes_by_their_ri_names() {
    let source = "surface standard() {
        color c = 0, o = 0; float sides = 0, matte = 7, plain = 0;
        float found = attribute(\"Ri:Color\", c) + attribute(\"Ri:Opacity\", o);
        found += attribute(\"Ri:Sides\", sides) + attribute(\"Ri:Matte\", matte) + attribute(\"Sides\", plain);
        Oi = 1;
        Ci = found == 5 && sides == plain && matte == 0 ? c * comp(o, 1) * sides / 2 : color(1, 0, 1);
    }";
    let left = "Color [0.2 0.4 0.8] Opacity [1 0.5 1]";
    let fb = two_halves("standard", source, "", left);
    // Left: its colour, halved by its opacity's green; right: the defaults. Both have two sides.
    let (l, r) = (fb.pixel(1, 4), fb.pixel(6, 4));
    assert!(l[..3].iter().zip([0.1, 0.2, 0.4]).all(|(a, b)| (a - b).abs() < 1e-6), "{l:?}");
    assert_eq!(&r[..3], &[1.0, 1.0, 1.0], "{r:?}");
}

/// `Attribute "identifier" "name"` names the objects of its block: `attribute("identifier:name")`
/// reads the shaded object's name, and answers 0 for an object without one.
#[test]
fn shaders_read_the_name_of_the_object_they_shade() {
    let source = "surface named() {
        string id = \"none\";
        float found = attribute(\"identifier:name\", id);
        Ci = id == \"left\" ? color(found, 0, 0) : id == \"none\" ? color(0, 1 - found, 0) : color(0, 0, 1);
        Oi = 1;
    }";
    let fb = two_halves("named", source, "", "Attribute \"identifier\" \"name\" [\"left\"]");
    assert_eq!((fb.pixel(1, 4), fb.pixel(6, 4)), ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]));
}

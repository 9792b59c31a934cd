//! The conveniences of the application API: `From` conversions to `ParamValue` as `parameter()` and
//! `params!` take them (accepted for the declared types they fit, refused for the others), the
//! quadric and box helpers against the RIB reader's tessellation, `Framebuffer::save` read back,
//! and paths given as any `AsRef<Path>`.

mod common;

use common::{context, quad, write};
use rtsl_runtime::api::{params, ApiError, Context, ObjectId, ParamValue, Quadric, Tessellation, WriteOptions};
use rtsl_runtime::glam::{Affine3A, Mat4, Quat, Vec3, Vec3A};
use rtsl_runtime::shading::{bind_param, ParamError};
use rtsl_runtime::Transfer;
use std::path::Path;

/// A surface with a parameter of every kind; it shows `c` so that frames tell which value is bound.
const PROBE: &str = r#"
surface probe(float f = 0; color c = 0; point pt = 0; vector vec = 0; normal nrm = 0;
              string str = ""; matrix m = 1; float a[3] = {0, 0, 0}; point pts[2] = {0, 0};)
{
    Oi = 1;
    Ci = c;
}
"#;

/// A context with `probe` bound outside any object, under a translation by (10, 0, 0) so that
/// points are seen to be moved and vectors not.
fn probe_context() -> (Context, rtsl_runtime::api::ShaderId) {
    let mut rt = context();
    let probe = rt.compile_shader("probe", PROBE).expect("the probe compiles");
    rt.translate(10.0, 0.0, 0.0);
    rt.bind_shader(probe).expect("a surface shader binds");
    (rt, probe)
}

fn mismatch(e: ApiError) -> (String, String) {
    match e {
        ApiError::Param(ParamError::TypeMismatch { expected, given, .. }) => (expected, given),
        other => panic!("expected a type mismatch, got {other}"),
    }
}

#[test]
fn converted_values_bind_to_the_declared_types_they_fit() {
    let (mut rt, _) = probe_context();
    // f32: a float, or copied to a triple.
    rt.parameter("f", 0.5).expect("f32 for float");
    rt.parameter("c", 0.5).expect("f32 for color");
    rt.parameter("pt", 0.5).expect("f32 for point");
    // Triples: an array, glam vectors, for any of the four triple types.
    for name in ["c", "pt", "vec", "nrm"] {
        rt.parameter(name, [1.0, 2.0, 3.0]).expect("[f32; 3] for a triple");
        rt.parameter(name, Vec3::new(1.0, 2.0, 3.0)).expect("Vec3 for a triple");
        rt.parameter(name, Vec3A::new(1.0, 2.0, 3.0)).expect("Vec3A for a triple");
    }
    rt.parameter("str", "grid.tex").expect("&str for string");
    rt.parameter("str", String::from("grid.tex")).expect("String for string");
    rt.parameter("m", Mat4::from_scale(Vec3::splat(2.0))).expect("Mat4 for matrix");
    rt.parameter("m", Affine3A::from_translation(Vec3::X)).expect("Affine3A for matrix");
    rt.parameter("a", vec![1.0, 2.0, 3.0]).expect("Vec<f32> for float[3]");
    rt.parameter("a", &[1.0, 2.0, 3.0][..]).expect("&[f32] for float[3]");
    rt.parameter("pts", vec![Vec3::X, Vec3::Y]).expect("Vec<Vec3> for point[2]");
    rt.parameter("pts", vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).expect("Vec<[f32; 3]> for point[2]");
    // The explicit variants still do.
    rt.parameter("c", ParamValue::Color([0.1, 0.2, 0.3])).expect("ParamValue");
}

#[test]
fn converted_values_are_refused_where_they_do_not_fit() {
    let (mut rt, _) = probe_context();
    assert_eq!(mismatch(rt.parameter("f", "text").unwrap_err()), ("float".into(), "string".into()));
    assert_eq!(mismatch(rt.parameter("f", [1.0, 2.0, 3.0]).unwrap_err()), ("float".into(), "color".into()));
    assert_eq!(mismatch(rt.parameter("str", 1.0).unwrap_err()), ("string".into(), "float".into()));
    assert_eq!(mismatch(rt.parameter("c", "red").unwrap_err()), ("color".into(), "string".into()));
    assert_eq!(mismatch(rt.parameter("m", Vec3::ONE).unwrap_err()), ("matrix".into(), "point".into()));
    // A float array takes floats, not a colour, and only of its length.
    assert_eq!(mismatch(rt.parameter("a", [1.0, 2.0, 3.0]).unwrap_err()), ("float[3]".into(), "color".into()));
    assert_eq!(mismatch(rt.parameter("a", vec![1.0, 2.0]).unwrap_err()), ("float[3]".into(), "float[2]".into()));
    assert_eq!(mismatch(rt.parameter("pts", vec![Vec3::X]).unwrap_err()), ("point[2]".into(), "triple[1]".into()));
    assert!(matches!(rt.parameter("nope", 1.0), Err(ApiError::Param(ParamError::NoSuchParameter { .. }))));
}

#[test]
fn the_declaration_decides_how_a_converted_triple_is_placed() {
    let (rt, probe) = probe_context();
    let program = rt.program(probe).expect("loaded").clone();
    let m = rt.current_matrix();
    let floats = |name: &str, value: ParamValue| bind_param(&program, name, &value, &m).expect("binds").floats;
    // A glam vector is a `Point` value, an array a `Color`: either is moved as a point for a
    // point, turned only for a vector, and kept for a colour.
    assert_eq!(floats("pt", Vec3::new(1.0, 2.0, 3.0).into()), [11.0, 2.0, 3.0]);
    assert_eq!(floats("pt", [1.0, 2.0, 3.0].into()), [11.0, 2.0, 3.0]);
    assert_eq!(floats("vec", Vec3::new(1.0, 2.0, 3.0).into()), [1.0, 2.0, 3.0]);
    assert_eq!(floats("c", Vec3::new(1.0, 2.0, 3.0).into()), [1.0, 2.0, 3.0]);
    // glam's column-major array is RenderMan's row-major matrix: the translation comes last.
    let placed = Affine3A::from_rotation_translation(Quat::from_rotation_y(0.5), Vec3::new(4.0, 5.0, 6.0));
    let matrix = floats("m", placed.into());
    assert_eq!(matrix, Mat4::from(placed).to_cols_array());
    assert_eq!(&matrix[12..], [4.0, 5.0, 6.0, 1.0]);
}

/// A quad filling the frame, shaded by `probe` with `values` given as one list; the quad is
/// placed whether or not the list is taken.
fn probe_quad(
    rt: &mut Context,
    probe: rtsl_runtime::api::ShaderId,
    values: &[(&str, ParamValue)],
) -> Result<(), ApiError> {
    rt.camera_look_at([0.0, 0.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0);
    let object = rt.begin_object().expect("begins");
    rt.bind_shader(probe).expect("binds");
    let set = rt.parameters(values);
    quad(rt, [[-4.0, -4.0, 0.0], [4.0, -4.0, 0.0], [4.0, 4.0, 0.0], [-4.0, 4.0, 0.0]]).expect("the quad");
    rt.end_object().expect("ends");
    rt.instantiate_object(object).expect("placed");
    set
}

#[test]
fn parameters_set_a_list_like_a_light_and_refuse_it_whole() {
    let mut rt = context();
    let probe = rt.compile_shader("probe", PROBE).expect("the probe compiles");
    probe_quad(&mut rt, probe, params!["c" => [0.0, 1.0, 0.0], "f" => 2.0]).expect("both values fit");
    let (image, _) = rt.render_frame().expect("renders");
    assert_eq!(&image.pixel(32, 24)[..3], [0.0, 1.0, 0.0]);

    // One bad value: the error names it, and the good one before it is not set either.
    let mut rt = context();
    let probe = rt.compile_shader("probe", PROBE).expect("the probe compiles");
    let e = probe_quad(&mut rt, probe, params!["c" => [0.0, 1.0, 0.0], "f" => "two"]).unwrap_err();
    assert!(e.to_string().contains("parameter f of shader probe"), "{e}");
    let (image, _) = rt.render_frame().expect("renders");
    assert_eq!(&image.pixel(32, 24)[..3], [0.0, 0.0, 0.0], "the default colour: the list was refused");

    // With nothing bound the error names the first parameter; an empty list sets nothing.
    let mut rt = context();
    assert!(matches!(rt.parameters(params!["Kd" => 1.0]), Err(ApiError::NoShaderBound(name)) if name == "Kd"));
    rt.parameters(params![]).expect("nothing to set");
}

#[test]
fn the_other_bindings_take_the_same_list() {
    let mut rt = context();
    let light = rt.find_shader("pointlight").expect("library");
    let distant = rt.find_shader("distantlight").expect("library");
    let gamma = rt.find_shader("gamma").expect("library");
    rt.light_source(light, params!["intensity" => 3.0, "from" => Vec3::ONE, "lightcolor" => [1.0, 0.5, 0.5]])
        .expect("a point light");
    rt.light_source(distant, params!["to" => Vec3A::NEG_Y]).expect("a distant light");
    let e = rt.light_source(light, params!["from" => "up"]).unwrap_err();
    assert_eq!(mismatch(e), ("point".into(), "string".into()));
    let e = rt.pixel_shader(Some(gamma), params!["nope" => 1.0]).unwrap_err();
    assert!(matches!(e, ApiError::Param(ParamError::NoSuchParameter { .. })), "{e}");
}

#[test]
fn quadrics_are_tessellated_as_the_rib_reader_tessellates_them() {
    let rib = "WorldBegin\nAttributeBegin\nTranslate 1 2 3\nSphere 2 -2 2 360\nAttributeEnd\n\
               AttributeBegin\nTorus 1 0.25 0 360 270\nAttributeEnd\nWorldEnd\n";
    let mut from_rib = context();
    rtsl_runtime::rib::load::load_str(&mut from_rib, rib, Path::new("<quadrics>")).expect("loads");

    let mut rt = context();
    rt.translate(1.0, 2.0, 3.0);
    let sphere = rt.begin_object().expect("begins");
    rt.sphere(2.0).expect("a sphere");
    rt.end_object().expect("ends");
    rt.load_identity();
    let torus = rt.begin_object().expect("begins");
    let q = Quadric::Torus { major_radius: 1.0, minor_radius: 0.25, phimin: 0.0, phimax: 360.0, thetamax: 270.0 };
    rt.quadric(&q).expect("a torus");
    rt.end_object().expect("ends");

    for (api, rib) in [(sphere, ObjectId(0)), (torus, ObjectId(1))] {
        let a = rt.object_mesh(api).expect("the API's mesh");
        let b = from_rib.object_mesh(rib).expect("the RIB reader's mesh");
        assert_eq!(a.triangle_count(), b.triangle_count());
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.normals, b.normals);
        // The RIB reader maps (u, v) through the default `TextureCoordinates`, which rounds.
        let (a_uv, b_uv) = (a.uvs.as_ref().expect("uvs"), b.uvs.as_ref().expect("uvs"));
        assert!(a_uv.iter().zip(b_uv).all(|(x, y)| x.distance(*y) < 1e-6));
    }
}

#[test]
fn geometry_helpers_are_placed_by_the_current_matrix() {
    let mut rt = context();
    let object = rt.begin_object().expect("begins");
    rt.push_matrix();
    rt.translate(0.0, 0.0, 5.0);
    rt.scale(2.0, 2.0, 2.0);
    rt.cylinder(1.0, 0.0, 1.0).expect("a cylinder");
    rt.pop_matrix().expect("pops");
    rt.box_mesh(Vec3::splat(-1.0), [1.0, 1.0, 1.0]).expect("a box");
    rt.end_object().expect("ends");
    let mesh = rt.object_mesh(object).expect("a mesh");
    let cylinder = Quadric::Cylinder { radius: 1.0, zmin: 0.0, zmax: 1.0, thetamax: 360.0 };
    let tessellated = cylinder.tessellate(cylinder.default_tessellation()).expect("tessellates");
    let n = tessellated.positions.len();
    for (got, p) in mesh.positions[..n].iter().zip(&tessellated.positions) {
        assert!(got.distance(*p * 2.0 + Vec3::new(0.0, 0.0, 5.0)) < 1e-5);
    }
    // The box after it, back in the object's own space.
    assert_eq!(mesh.positions.len(), n + 24);
    assert!(mesh.positions[n..].iter().all(|p| p.abs().max_element() == 1.0));
    assert_eq!(mesh.triangle_count(), tessellated.triangle_count() + 12);
}

#[test]
fn geometry_helpers_report_misuse() {
    let mut rt = context();
    assert!(matches!(rt.sphere(1.0), Err(ApiError::NoObject(_))));
    assert!(matches!(rt.box_mesh(Vec3::ZERO, Vec3::ONE), Err(ApiError::NoObject(_))));
    rt.begin_object().expect("begins");
    rt.begin(rtsl_runtime::api::Primitive::Triangles).expect("a primitive");
    assert!(matches!(rt.sphere(1.0), Err(ApiError::Nested(..))));
    assert!(matches!(rt.box_mesh(Vec3::ZERO, Vec3::ONE), Err(ApiError::Nested(..))));
    rt.end().expect("ends the empty primitive");
    assert!(matches!(rt.sphere(f32::NAN), Err(ApiError::Mesh(_))));
    assert!(matches!(rt.box_mesh([0.0, f32::INFINITY, 0.0], Vec3::ONE), Err(ApiError::Mesh(_))));
    let fine = Tessellation { u_segments: 8, v_segments: 4 };
    rt.quadric_tessellated(&Quadric::Disk { height: 0.0, radius: 1.0, thetamax: 360.0 }, fine).expect("a disk");
    rt.end_object().expect("the object ends with the disk alone");
}

#[test]
fn framebuffer_save_round_trips_through_read_image() {
    let mut rt = context();
    let probe = rt.compile_shader("probe", PROBE).expect("the probe compiles");
    // Half the frame covered: the other half keeps the background's zero alpha.
    rt.camera_look_at([0.0, 0.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0);
    let object = rt.begin_object().expect("begins");
    rt.bind_shader(probe).expect("binds");
    rt.parameter("c", [0.25, 0.5, 1.0]).expect("a colour");
    quad(&mut rt, [[0.0, -4.0, 0.0], [4.0, -4.0, 0.0], [4.0, 4.0, 0.0], [0.0, 4.0, 0.0]]).expect("the quad");
    rt.end_object().expect("ends");
    rt.instantiate_object(object).expect("placed");
    let (image, _) = rt.render_frame().expect("renders");
    assert_eq!(image.pixel(60, 24), [0.25, 0.5, 1.0, 1.0]);

    let dir = tempfile::tempdir().expect("a temporary directory");
    let exr = dir.path().join("frame.exr");
    image.save(&exr).expect("EXR");
    let back = rtsl_runtime::read_image(&exr).expect("reads");
    assert_eq!((back.width, back.height), (image.width as usize, image.height as usize));
    assert_eq!(back.pixels, image.rgba, "32-bit EXR keeps every value");

    // 8-bit files hold the sRGB encoding of the colour, and alpha as it is.
    let encoded: Vec<f32> =
        image.rgba.iter().enumerate().map(|(i, &v)| if i % 4 == 3 { v } else { Transfer::Srgb.encode(v) }).collect();
    for ext in ["png", "tga", "PNG"] {
        let path = dir.path().join(format!("frame.{ext}"));
        image.save(path.to_str().expect("a UTF-8 path")).expect("8-bit");
        let back = rtsl_runtime::read_image(&path).expect("reads");
        let worst = back.pixels.iter().zip(&encoded).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!(worst <= 0.5 / 255.0 + 1e-6, "{ext}: off by {worst}");
    }
    let half = dir.path().join("half.exr");
    image.save_with(&half, &WriteOptions { exr_half: true, ..WriteOptions::default() }).expect("half EXR");
    assert_eq!(rtsl_runtime::read_image(&half).expect("reads").pixels, image.rgba, "these values are exact in half");
    let e = image.save(dir.path().join("frame.bmp")).unwrap_err();
    assert!(e.to_string().contains("unsupported image format"), "{e}");
}

#[test]
fn paths_are_taken_as_any_as_ref_path() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = write(dir.path(), "flat.sl", "surface flat(color tint = 1;) { Oi = 1; Ci = tint; }");
    let mut rt = context();
    let by_path = rt.shader_file(&file).expect("a &PathBuf");
    let by_str = rt.shader_file(file.to_str().expect("UTF-8")).expect("a &str");
    assert_ne!(by_path, by_str);
    write(dir.path(), "searched.sl", "surface searched() { Oi = 1; Ci = 1; }");
    let dir_str = dir.path().to_str().expect("UTF-8");
    rt.set_shader_search_path([dir_str]);
    assert_eq!(rt.shader_search_path(), [dir.path()]);
    let found = rt.find_shader("searched").expect("found on the search path");
    assert_eq!(rt.program(found).expect("loaded").name, "searched");
    rt.set_include_paths(vec![dir.path().to_path_buf()]);
    assert_eq!(rt.include_paths(), [dir.path()]);
    rt.add_texture_search_path(dir_str);
    assert!(rtsl_runtime::api::find_shader_file("flat", &[dir_str]).is_some());
}

#[test]
fn shader_files_with_latin1_comments_load() {
    // Collections from the 1990s are Latin-1 (the RenderMan Repository's GNember.sl): the
    // compiler reads them, and so does the engine where it loads a shader by file.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let text = b"/* \xa9 1999 Ga\xebl */\nsurface latin(color tint = 1;) { Oi = 1; Ci = tint; }\n".to_vec();
    assert!(String::from_utf8(text.clone()).is_err());
    let file = dir.path().join("latin.sl");
    std::fs::write(&file, &text).expect("written");
    let mut rt = context();
    let id = rt.shader_file(&file).expect("loads");
    assert_eq!(rt.program(id).expect("loaded").name, "latin");
}

/// The mean brightness of the left and right halves of a frame.
fn halves(rt: &mut Context) -> (f32, f32) {
    let (fb, _) = rt.render_frame().expect("renders");
    let (mut left, mut right) = (0.0, 0.0);
    for y in 0..fb.height {
        for x in 0..fb.width {
            let p = fb.pixel(x, y);
            let v = p[0] + p[1] + p[2];
            if x < fb.width / 2 {
                left += v;
            } else {
                right += v;
            }
        }
    }
    (left, right)
}

#[test]
fn a_light_moves_and_changes_between_frames() {
    let mut rt = context();
    let matte = rt.find_shader("matte").expect("the library's matte");
    let floor = rt.begin_object().expect("an object");
    rt.bind_shader(matte).expect("binds");
    quad(&mut rt, [[-4.0, 0.0, -3.0], [-4.0, 0.0, 3.0], [4.0, 0.0, 3.0], [4.0, 0.0, -3.0]]).expect("a quad");
    rt.end_object().expect("made");
    rt.instantiate_object(floor).expect("placed");
    rt.camera_look_at(Vec3A::new(0.0, 6.0, 0.01), Vec3A::ZERO, Vec3A::NEG_Z, 70.0);
    let point = rt.find_shader("pointlight").expect("the library's pointlight");
    // A light given at (0, 1, 0) of a space moved 2 to the left.
    rt.translate(-2.0, 0.0, 0.0);
    let light =
        rt.light_source(point, params!["intensity" => 4.0, "from" => Vec3::new(0.0, 1.0, 0.0)]).expect("a light");
    rt.load_identity();
    assert_eq!(rt.light_transform(light).expect("placed"), Affine3A::from_translation(Vec3::new(-2.0, 0.0, 0.0)));
    let (left, right) = halves(&mut rt);
    assert!(left > 2.0 * right, "the light is on the left: {left} {right}");
    // Its space moved 2 to the right: `from` moves with it.
    rt.set_light_transform(light, Affine3A::from_translation(Vec3::new(2.0, 0.0, 0.0))).expect("moved");
    let (moved_left, moved_right) = halves(&mut rt);
    assert!(moved_right > 2.0 * moved_left, "the light is on the right: {moved_left} {moved_right}");
    assert!((moved_right - left).abs() < 0.01 * left, "the same light, mirrored: {left} {moved_right}");
    // New values are read in the light's own space, whatever the current matrix.
    rt.translate(100.0, 0.0, 0.0);
    rt.set_light_parameters(light, params!["from" => Vec3::new(-4.0, 1.0, 0.0), "intensity" => 8.0]).expect("changed");
    let (back_left, back_right) = halves(&mut rt);
    assert!(back_left > 2.0 * back_right, "back on the left: {back_left} {back_right}");
    assert!((back_left - 2.0 * left).abs() < 0.01 * left, "twice as bright: {left} {back_left}");
    // Refused values change nothing; an unknown light is an error.
    assert!(rt.set_light_parameters(light, params!["intensity" => 0.0, "nosuch" => 1.0]).is_err());
    assert_eq!(halves(&mut rt), (back_left, back_right));
    assert!(matches!(
        rt.set_light_transform(rtsl_runtime::api::LightId(9), Affine3A::IDENTITY),
        Err(ApiError::UnknownLight(9))
    ));
}

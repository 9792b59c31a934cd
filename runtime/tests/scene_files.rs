//! Scenes from files: RIB requests onto the engine (camera, attributes, shaders, lights, area lights,
//! retained objects, archives, warnings with locations), models (OBJ, PLY, glTF) and textures.

mod common;

use common::{load, render, shared};
use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::render::render_frame;
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::scene_file::{add_model_file, SceneFileError, MAX_MODEL_TRIANGLES};
use std::path::Path;

const CAMERA: &str = r#"
Format 64 48 1
Projection "perspective" "fov" [40]
Translate 0 0 5
WorldBegin
"#;

#[test]
fn the_camera_is_the_transform_at_world_begin() {
    // A constant red square straight ahead of the camera (RenderMan's camera looks down +z).
    let (mut rt, warnings) = load(&format!(
        "{CAMERA} Surface \"constant\" Color [1 0 0] Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] WorldEnd"
    ));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!((rt.options.width, rt.options.height), (64, 48));
    let fb = render(&mut rt);
    assert_eq!(fb.pixel(32, 24), [1.0, 0.0, 0.0, 1.0]);
    assert_eq!(fb.pixel(0, 0), [0.0; 4]);
}

#[test]
fn coord_sys_transform_places_geometry_in_the_standard_spaces() {
    // A backplane in camera space, as Slim writes one (RenderMan Repository's TLShaders): in front
    // of the camera whichever way it looks. "world" undoes the camera's transform; "object" keeps
    // the current one; the projective spaces are not supported and leave the transform alone.
    let quad = r#"Polygon "P" [-1 -1 4  1 -1 4  1 1 4  -1 1 4]"#;
    let (mut rt, warnings) = load(&format!(
        r#"Format 64 48 1
        Projection "perspective" "fov" [40]
        Rotate 150 0 1 0
        Translate 3 1 -2
        WorldBegin
        Surface "constant"
        AttributeBegin
          Color [1 0 0]
          Rotate 30 1 0 0
          CoordSysTransform "camera"
          {quad}
        AttributeEnd
        AttributeBegin
          Translate 0 50 0
          CoordSysTransform "world"
          CoordSysTransform "object"
          Color [0 1 0]
          # A small square three units straight ahead of the eye at (-3 -1 2), in world coordinates.
          Polygon "P" [-4.76 -1.3 -0.448  -4.24 -1.3 -0.748  -4.24 -0.7 -0.748  -4.76 -0.7 -0.448]
        AttributeEnd
        CoordSysTransform "raster"
        WorldEnd"#
    ));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("projective space \"raster\" is not supported"), "{warnings:?}");
    let fb = render(&mut rt);
    assert_eq!(fb.pixel(32, 24)[..3], [0.0, 1.0, 0.0], "the square in world space, ahead of the eye");
    assert_eq!(fb.pixel(44, 24)[..3], [1.0, 0.0, 0.0], "the backplane around it");
    assert_eq!(fb.pixel(1, 1), [0.0; 4], "and not in the view's corners");
}

#[test]
fn attribute_blocks_scope_colour_and_shaders() {
    let (mut rt, warnings) = load(&format!(
        r#"{CAMERA}
        Surface "constant"
        AttributeBegin
          Color [0 1 0]
          Translate -1.2 0 0
          Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
        AttributeEnd
        Translate 1.2 0 0
        Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
        WorldEnd"#
    ));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    // RenderMan's camera is left-handed: world -x is on the image's left.
    assert_eq!(fb.pixel(14, 24)[..3], [0.0, 1.0, 0.0], "inside the block");
    assert_eq!(fb.pixel(50, 24)[..3], [1.0, 1.0, 1.0], "after it, the colour is back to white");
}

#[test]
fn values_for_the_whole_primitive_reach_its_shaders_and_colour() {
    // RISpec: a primitive's constant variables (and uniform ones, one a facet, on a primitive of
    // one face) are passed to its shaders; Cs and Os are its colour and opacity. Here the left
    // square's "constant color Cs" makes it green, the right one's "uniform float Ka" halves what
    // `matte` reflects, and the sphere's "uniform color Cs" (one face) makes it red; a square
    // after them is as the attribute state says.
    let (mut rt, warnings) = load(&format!(
        r#"{CAMERA}
        LightSource "ambientlight" 1 "intensity" [1]
        Surface "matte"
        AttributeBegin
          Translate -1.2 0.5 0
          Scale 0.5 0.5 1
          Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "constant color Cs" [0 1 0]
        AttributeEnd
        AttributeBegin
          Translate 1.2 0.5 0
          Scale 0.5 0.5 1
          Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "uniform float Ka" [0.5]
        AttributeEnd
        AttributeBegin
          Translate -1.2 -0.7 0
          Sphere 0.4 -0.4 0.4 360 "uniform color Cs" [1 0 0]
        AttributeEnd
        AttributeBegin
          Translate 1.2 -0.7 0
          Scale 0.4 0.4 1
          Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "constant color Cs" [1 0 0 0 1 0]
        AttributeEnd
        WorldEnd"#
    ));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("\"Cs\" (constant color) has 2 values"), "{warnings:?}");
    let fb = render(&mut rt);
    let at = |x: u32, y: u32| fb.pixel(x, y)[..3].to_vec();
    // RenderMan's camera is left-handed: world -x is on the image's left, +y up.
    assert_eq!(at(17, 17), [0.0, 1.0, 0.0], "constant Cs");
    assert_eq!(at(46, 17), [0.5, 0.5, 0.5], "uniform Ka on a polygon");
    assert_eq!(at(17, 31), [1.0, 0.0, 0.0], "uniform Cs on a sphere");
    assert_eq!(at(46, 31), [1.0, 1.0, 1.0], "a value of the wrong count is dropped");
}

#[test]
fn constant_points_are_in_the_primitive_s_space_and_undeclared_or_retained_values_warn() {
    // A shader that shows how far its point parameter is from world (0, 0, 0): given as the
    // square's own centre in its space, moved 1 along x, the point is 1 from the world origin.
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(
        dir.path().join("away.sl"),
        "surface away(point centre = 0;) { Ci = distance(centre, point \"world\" (0, 0, 0)); Oi = 1; }",
    )
    .expect("write the shader");
    let scene = format!(
        r#"{CAMERA}
        Surface "away"
        Translate 1 0 0
        Rotate 90 0 0 1
        Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "constant point centre" [0 0 0]
        WorldEnd"#
    );
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, &scene, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let fb = render(&mut rt);
    assert!((fb.pixel(40, 24)[0] - 1.0).abs() < 1e-4, "{:?}", fb.pixel(40, 24));
    // Inside ObjectBegin a primitive cannot have parameters of its own: a warning says so.
    let (_, warnings) = load(&format!(
        r#"{CAMERA}
        Surface "matte"
        ObjectBegin 1
          Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "constant float Kd" [0.5]
        ObjectEnd
        ObjectInstance 1
        WorldEnd"#
    ));
    assert!(warnings.iter().any(|w| w.contains("inside ObjectBegin")), "{warnings:?}");
    // A variable without a declaration has no class or size: a warning at its name.
    let (_, warnings) = load(&format!(
        r#"{CAMERA}
        Surface "matte"
        Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "foo" [0.2 0.4 0.6 0.8]
        WorldEnd"#
    ));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("\"foo\" is not declared"), "{warnings:?}");
}

#[test]
fn per_vertex_points_vectors_and_normals_reach_shaders_in_the_current_space() {
    // RISpec: point, vector and normal primitive variables are given in object space. The square
    // is stretched, turned and moved; a copy of its "P" (and of it as hpoints with w = 2) must
    // arrive where P is, the vector (1, 0, 0) as (0, 2, 0) and the normal (1, 0, 0) as (0, 0.5, 0).
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(
        dir.path().join("spaces.sl"),
        "surface spaces(varying point Pref = 0; varying point Ph = 0; varying vector d = 0; varying normal nn = 0;) \
         { Ci = color(distance(Pref, P) + distance(Ph, P), ycomp(d) / 4, ycomp(nn)); Oi = 1; }",
    )
    .expect("write the shader");
    let scene = format!(
        r#"{CAMERA}
        Surface "spaces"
        Translate 1 0 0
        Rotate 90 0 0 1
        Scale 2 1 1
        Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
          "vertex point Pref" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
          "vertex hpoint Ph" [-2 -2 0 2  2 -2 0 2  2 2 0 2  -2 2 0 2]
          "varying vector d" [1 0 0  1 0 0  1 0 0  1 0 0]
          "varying normal nn" [1 0 0  1 0 0  1 0 0  1 0 0]
        WorldEnd"#
    );
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, &scene, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let fb = render(&mut rt);
    for (x, y) in [(36, 10), (40, 24), (44, 38)] {
        let [distance, vector, normal, _] = fb.pixel(x, y);
        assert!(distance.abs() < 1e-4, "the points are where P is at ({x}, {y}): {distance}");
        assert!((vector - 0.5).abs() < 1e-5, "the vector at ({x}, {y}): {vector}");
        assert!((normal - 0.5).abs() < 1e-5, "the normal at ({x}, {y}): {normal}");
    }
}

#[test]
fn polygons_are_parameterised_by_their_x_and_y() {
    // RISpec: "The surface parameters of a polygon are its (x,y) coordinates ... Texture
    // coordinates are set equal to the surface parameters unless texture coordinates are given
    // explicitly". The shader shows how far (s, t) and (u, v) are from the point's object (x, y),
    // on a polygon turned and moved (left), and "s" given alone replaces s only (right).
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(
        dir.path().join("xy.sl"),
        "surface xy() { point o = transform(\"object\", P); \
         Ci = color(abs(s - xcomp(o)) + abs(u - xcomp(o)), abs(t - ycomp(o)) + abs(v - ycomp(o)), s); Oi = 1; }",
    )
    .expect("write the shader");
    let scene = format!(
        r#"{CAMERA}
        Surface "xy"
        AttributeBegin
          Translate -1 0 0
          Rotate 30 0 0 1
          Polygon "P" [-0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0  -0.7 0 0]
        AttributeEnd
        AttributeBegin
          Translate 1 0 0
          Polygon "P" [-0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0] "varying float s" [2 2 2 2]
        AttributeEnd
        WorldEnd"#
    );
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, &scene, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let fb = render(&mut rt);
    for (x, y) in [(19, 21), (21, 26), (16, 24)] {
        let [ds, dt, _, alpha] = fb.pixel(x, y);
        assert_eq!(alpha, 1.0, "the left polygon is at ({x}, {y})");
        assert!(ds < 1e-4 && dt < 1e-4, "(s, t) and (u, v) are the object's (x, y) at ({x}, {y}): {ds} {dt}");
    }
    let [_, dt, s, alpha] = fb.pixel(44, 24);
    assert_eq!(alpha, 1.0, "the right polygon");
    assert!(dt < 1e-4 && (s - 2.0).abs() < 1e-6, "s given, t the object's y: {dt} {s}");
}

#[test]
fn an_imager_that_sets_oi_gives_the_pixels_that_opacity() {
    // RISpec: an imager's `Oi` out is the output pixel's opacity. An empty world has coverage 0:
    // the pixel's alpha is the shader's `alpha` where its code sets that, the mean of its `Oi`
    // where it sets only that, and the coverage where it sets neither.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let shaders =
        [("lens", "Oi = xcomp(P) < 32 ? color(0, 0.25, 0.5) : 1;"), ("both", "Oi = 1; alpha = 0.75;"), ("colour", "")];
    for (name, body) in shaders {
        let source = format!("imager {name}() {{ Ci = color(1, 0.5, 0.25); {body} }}");
        std::fs::write(dir.path().join(format!("{name}.sl")), source).expect("write the shader");
    }
    let alpha_at = |name: &str| -> [f32; 2] {
        let scene = format!("{CAMERA}WorldEnd").replace("WorldBegin", &format!("Imager \"{name}\"\nWorldBegin"));
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &scene, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let fb = render(&mut rt);
        assert_eq!(&fb.pixel(10, 10)[..3], [1.0, 0.5, 0.25], "the imager's colour");
        [fb.pixel(10, 10)[3], fb.pixel(50, 10)[3]]
    };
    assert_eq!(alpha_at("lens"), [0.25, 1.0], "Oi alone: its mean");
    assert_eq!(alpha_at("both"), [0.75, 0.75], "alpha set");
    assert_eq!(alpha_at("colour"), [0.0, 0.0], "neither: the coverage");
}

#[test]
fn shader_parameters_need_no_declaration_and_bad_ones_warn_with_their_location() {
    let (mut rt, warnings) = load(&format!(
        "{CAMERA}\nSurface \"constant\"\nSurface \"plastic\" \"Kd\" [0.2] \"nosuch\" [1] \"Ks\" [1 2 3]\n\
         LightSource \"distantlight\" 1 \"intensity\" [1]\nPolygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\nWorldEnd"
    ));
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0] == "test.rib:8:30: warning: shader plastic has no parameter nosuch", "{warnings:?}");
    assert!(warnings[1].starts_with("test.rib:8:43: warning: parameter Ks of shader plastic is float"), "{warnings:?}");
    let fb = render(&mut rt);
    assert!(fb.pixel(32, 24)[0] > 0.0);
}

#[test]
fn requests_with_syntax_errors_are_skipped_and_named_and_the_rest_loads() {
    let mut rt = Context::new();
    let loaded = load_str(
        &mut rt,
        "WorldBegin\nTranslate 1 2\nSphere 1 ]\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]\nWorldEnd\n",
        Path::new("bad.rib"),
    )
    .expect("the readable requests load");
    let text: Vec<String> = loaded.warnings.iter().map(ToString::to_string).collect();
    assert!(text[0].starts_with("bad.rib:2:1: error:") && text[1].starts_with("bad.rib:3:10: error:"), "{text:?}");
    assert_eq!((loaded.errors(), loaded.omissions()), (2, 2));
    assert_eq!(rt.world_instance_ids().len(), 1, "the polygon after them");
}

#[test]
fn unknown_shaders_are_reported_not_fatal() {
    let mut rt = Context::new();
    let err = load_str(&mut rt, "WorldBegin\nSurface \"no_such_shader\"\nWorldEnd\n", Path::new("s.rib"));
    match err {
        Ok(loaded) => {
            assert!(loaded
                .warnings
                .iter()
                .any(|w| w.to_string().contains("s.rib:2:1") && w.message.contains("no_such_shader")));
            assert_eq!(loaded.omissions(), 1, "a missing shader is part of the scene missing");
        }
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn omissions_count_what_is_missing_from_the_picture_and_not_what_is_approximated() {
    let rib = r#"Option "ribparse" "string varsubst" ["$"]
        PixelVariance 0.01
        Projection "stereographic"
        WorldBegin
          Attribute "trace" "int displacements" [1]
          Displacement "bumpy"
          Surface "plastic" "nosuchparam" [1]
          Blobby 0 [] [] []
          ReadArchive "missing-model.obj"
          ObjectInstance 7
          Exterior "fog"
          GeometricRepresentation "primitive"
          GeometricRepresentation "lines"
          Sphere 1 -1 1 360
        WorldEnd
    "#;
    let loaded = load_str(&mut Context::new(), rib, Path::new("s.rib")).expect("loads with warnings");
    let text = loaded.warnings.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n");
    for approximated in ["\"ribparse\"", "PixelVariance", "stereographic", "nosuchparam", "\"lines\""] {
        assert!(text.contains(approximated), "{approximated} is warned about: {text}");
    }
    // The Blobby without code (an error at the request), the archive, the object instance and the
    // exterior shader are not in the picture.
    assert_eq!(loaded.omissions(), 4, "{text}");
    // `GeometricRepresentation "primitive"` is what rtsl draws anyway: no warning.
    assert_eq!(loaded.warnings.len(), 9, "{text}");
    assert!(!text.contains("primitive"), "{text}");
}

#[test]
fn blobbies_load_as_meshes_and_their_problems_are_located() {
    let rib = r#"WorldBegin
  Surface "plastic"
  Blobby 2 [1001 0 1003 0 16 0 2 0 1]
    [1 0 0 0  0 1 0 0  0 0 1 0  0 0 3 1  0.1 0.2 0.3 0.4] ["ground.z"] "Cs" [1 0 0  0 0 1]
  Blobby 1 [1001 40] [1 0 0 0  0 1 0 0  0 0 1 0  0 0 3 1] []
WorldEnd
"#;
    let loaded = load_str(&mut Context::new(), rib, Path::new("s.rib")).expect("loads with warnings");
    let text = loaded.warnings.iter().map(ToString::to_string).collect::<Vec<_>>();
    assert_eq!(text.len(), 2, "{text:?}");
    assert!(text[0].starts_with("s.rib:3:3: warning: repelling ground planes (1003) are not supported"), "{text:?}");
    assert!(
        text[1].starts_with("s.rib:5:3: warning: instruction 0 (opcode 1001 at code[0]) reads 16 floats from 40"),
        "{text:?}"
    );
    // The second is missing from the picture; the first is there, approximated.
    assert_eq!(loaded.omissions(), 1, "{text:?}");
}

#[test]
fn illuminate_switches_lights_and_area_lights_cast_soft_shadows() {
    let scene = |extra: &str| {
        format!(
            r#"Format 64 48 1
            Projection "perspective" "fov" [50]
            Rotate -60 1 0 0
            Translate 0 -4 2.5
            WorldBegin
              AttributeBegin
                AreaLightSource "arealight" 1 "intensity" [4]
                Attribute "light" "nsamples" [16]
                Translate 0 3 0
                Rotate 90 1 0 0
                Disk 0 0.8 360
              AttributeEnd
              {extra}
              Surface "matte"
              Polygon "P" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]
              AttributeBegin
                Translate 0 1 0
                Sphere 0.5 -0.5 0.5 360
              AttributeEnd
            WorldEnd"#
        )
    };
    let (mut rt, warnings) = load(&scene(""));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    // Along a row through the shadow, brightness takes many values (a penumbra), not two.
    let row: Vec<f32> = (0..64).map(|x| fb.pixel(x, 30)[0]).collect();
    let mut levels: Vec<u32> = row.iter().map(|v| (v * 200.0) as u32).collect();
    levels.sort_unstable();
    levels.dedup();
    assert!(levels.len() > 8, "a soft shadow has a gradient: {row:?}");
    let (mut off, _) = load(&scene("Illuminate 1 0"));
    let dark = render(&mut off);
    assert!(dark.rgba.chunks(4).all(|p| p[0] == 0.0), "with the only light off, all is black");
}

#[test]
fn retained_objects_are_instanced() {
    let (mut rt, warnings) = load(&format!(
        r#"{CAMERA}
        ObjectBegin "square"
          Polygon "P" [-0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0]
        ObjectEnd
        Surface "constant"
        AttributeBegin Translate -1 0 0 ObjectInstance "square" AttributeEnd
        AttributeBegin Translate 1 0 0 ObjectInstance "square" AttributeEnd
        ObjectInstance "nosuch"
        WorldEnd"#
    ));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let fb = render(&mut rt);
    let covered = fb.rgba.chunks(4).filter(|p| p[3] > 0.5).count();
    assert!(fb.pixel(32, 24)[3] == 0.0, "nothing between the two");
    assert!(covered > 200, "two squares: {covered} pixels");
}

#[test]
fn instances_take_the_attributes_where_they_stand_unless_their_object_has_its_own() {
    // RISpec 3.2: "All of an object's attributes are inherited at the time it is instanced". An
    // object defined before the world (as RenderMan for Maya writes them), instanced under three
    // colours and two shaders; and one whose block sets its colour, which keeps that and takes
    // the rest.
    let square = r#"Polygon "P" [-0.4 -0.4 0  0.4 -0.4 0  0.4 0.4 0  -0.4 0.4 0]"#;
    let (mut rt, warnings) = load(&format!(
        r#"Format 64 48 1
        Projection "perspective" "fov" [40]
        ObjectBegin 1 {square} ObjectEnd
        ObjectBegin 2 Color [0 0 1] {square} ObjectEnd
        Translate 0 0 5
        WorldBegin
        Surface "constant"
        AttributeBegin Translate -1 0.5 0 Color [1 0 0] ObjectInstance 1 AttributeEnd
        AttributeBegin Translate 0 0.5 0 Color [0 1 0] ObjectInstance 1 AttributeEnd
        AttributeBegin Translate 1 0.5 0 Color [1 0 0] ObjectInstance 1 AttributeEnd
        AttributeBegin Translate -1 -0.5 0 Color [0.5 0.5 0.5] Surface "matte" ObjectInstance 1 AttributeEnd
        AttributeBegin Translate 1 -0.5 0 Color [1 0 0] ObjectInstance 2 AttributeEnd
        WorldEnd"#
    ));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    let rgb = |x: u32, y: u32| fb.pixel(x, y)[..3].to_vec();
    let (left, middle, right, top, bottom) = (17, 32, 47, 17, 31);
    assert_eq!(rgb(left, top), [1.0, 0.0, 0.0]);
    assert_eq!(rgb(middle, top), [0.0, 1.0, 0.0]);
    assert_eq!(rgb(right, top), [1.0, 0.0, 0.0]);
    // `matte` with no light: black, not the constant grey.
    assert_eq!(fb.pixel(left, bottom), [0.0, 0.0, 0.0, 1.0]);
    // Its own colour, and the surface shader where it stands (PRMan's rule: what the block sets
    // wins, the rest is inherited).
    assert_eq!(rgb(right, bottom), [0.0, 0.0, 1.0], "the block's own colour, constant");
    // The two red instances share one material: one group of hits, as one object's would be.
    let world = rt.build_world().expect("a world");
    let materials: Vec<u32> = world.instances.iter().map(|i| i.material).collect();
    assert_eq!(materials[0], materials[2], "{materials:?}");
    assert_ne!(materials[0], materials[1], "{materials:?}");
}

#[test]
fn textures_from_memory_are_looked_up_by_name() -> Result<(), ApiError> {
    let mut rt = Context::new();
    rt.options.width = 32;
    rt.options.height = 24;
    // An 8x1 texture: red on the left half, blue on the right.
    let texels: Vec<f32> = (0..8).flat_map(|i| if i < 4 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] }).collect();
    rt.tex_image_2d("halves", 8, 1, 3, &texels)?;
    assert!(matches!(rt.tex_image_2d("bad", 2, 2, 3, &[0.0; 5]), Err(ApiError::BadTexture { .. })));
    let shader = rt.compile_shader("tex.sl", "surface tex() { Oi = 1; Ci = color texture(\"halves\", s, t); }")?;
    screen_filling_quad(&mut rt, shader)?;
    let fb = render(&mut rt);
    let (left, right) = (fb.pixel(4, 12), fb.pixel(27, 12));
    assert!(left[0] > 0.9 && left[2] < 0.1, "{left:?}");
    assert!(right[2] > 0.9 && right[0] < 0.1, "{right:?}");
    Ok(())
}

/// A quad shaded by `shader` that fills the camera's view, which this places: s runs 0 to 1 from
/// left to right and t from top to bottom.
fn screen_filling_quad(rt: &mut Context, shader: rtsl_runtime::api::ShaderId) -> Result<(), ApiError> {
    rt.camera_look_at(glam::Vec3A::new(0.0, 0.0, 3.0), glam::Vec3A::ZERO, glam::Vec3A::Y, 60.0);
    let o = rt.begin_object()?;
    rt.bind_shader(shader)?;
    rt.begin(rtsl_runtime::api::Primitive::Quads)?;
    for (x, y, s, t) in [(-5.0, -5.0, 0.0, 1.0), (5.0, -5.0, 1.0, 1.0), (5.0, 5.0, 1.0, 0.0), (-5.0, 5.0, 0.0, 0.0)] {
        rt.tex_coord(s, t);
        rt.vertex(x, y, 0.0)?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    Ok(())
}

/// A frame of a screen-filling quad (s and t run 0 to 1 across it) shaded by `surface`, with the
/// lat-long map "stripes" in memory: 64 x 32 texels, red in stripes 4 texels wide (red at
/// s = 0.5 + 2/64, the middle of one), green 0.25 and blue the row's t.
fn stripes_frame(surface: &str) -> Result<rtsl_runtime::render::Framebuffer, ApiError> {
    let mut rt = Context::new();
    rt.options.width = 32;
    rt.options.height = 24;
    let texels: Vec<f32> = (0..32)
        .flat_map(|row| (0..64).map(move |i| (row, i)))
        .flat_map(|(row, i)| [if (i / 4) % 2 == 0 { 1.0 } else { 0.0 }, 0.25, (row as f32 + 0.5) / 32.0])
        .collect();
    rt.tex_image_2d("stripes", 64, 32, 3, &texels)?;
    let shader = rt.compile_shader("env.sl", surface)?;
    screen_filling_quad(&mut rt, shader)?;
    Ok(render(&mut rt))
}

#[test]
fn environment_lookups_filter_over_their_footprint_and_read_the_channel_asked_for() -> Result<(), ApiError> {
    // The middle of a red stripe on the horizon: s = 0.5 + atan2(x, z) / (2 pi) = 0.5 + 2/64.
    let red = "vector(tan(PI / 16), 0, 1)";
    let at_centre = |body: &str| -> Result<[f32; 4], ApiError> {
        let fb = stripes_frame(&format!("surface env() {{ Oi = 1; {body} }}"))?;
        Ok(fb.pixel(16, 12))
    };
    let point = at_centre(&format!("Ci = color environment(\"stripes\", {red});"))?;
    assert!((point[0] - 1.0).abs() < 1e-3 && (point[1] - 0.25).abs() < 1e-3, "a point sample: {point:?}");
    assert!((point[2] - 0.5).abs() < 0.05, "the horizon is the middle row: {point:?}");
    // "blur" 0.25 covers four stripes in s: half red.
    let blurred = at_centre(&format!("Ci = color environment(\"stripes\", {red}, \"blur\", 0.25);"))?;
    assert!((blurred[0] - 0.5).abs() < 0.1, "blurred: {blurred:?}");
    assert!((blurred[1] - 0.25).abs() < 1e-3, "a constant channel stays: {blurred:?}");
    // The channel from the name's index or the "channel" option; channels the map lacks are "fill".
    let green = at_centre(&format!("Ci = float environment(\"stripes\"[1], {red});"))?;
    assert!(green[..3].iter().all(|c| (c - 0.25).abs() < 1e-3), "channel 1: {green:?}");
    let shifted = at_centre(&format!("Ci = color environment(\"stripes\", {red}, \"channel\", 1, \"fill\", 0.75);"))?;
    assert!((shifted[0] - 0.25).abs() < 1e-3 && (shifted[2] - 0.75).abs() < 1e-3, "channels 1..3: {shifted:?}");
    // The four-direction form filters over the region its directions span: a quarter of the map.
    let four = at_centre(&format!(
        "vector d = {red}; Ci = color environment(\"stripes\", d, rotate(d, PI / 2, point(0, 0, 0), point(0, 1, 0)), \
         d + vector(0, 0.3, 0), rotate(d, PI / 2, point(0, 0, 0), point(0, 1, 0)) + vector(0, 0.3, 0));"
    ))?;
    assert!((four[0] - 0.5).abs() < 0.15, "over a region: {four:?}");
    // A direction that turns 1.5 radians per pixel across the image: the footprint from its
    // derivatives averages the stripes, where a point sample ("width" 0) sees each one's colour.
    let sweep = |options: &str| -> Result<f32, ApiError> {
        let fb = stripes_frame(&format!(
            "surface env() {{ Oi = 1; float a = 48 * s; Ci = environment(\"stripes\", vector(sin(a), 0, cos(a)){options}); }}"
        ))?;
        let row: Vec<f32> = (4..28).map(|x| fb.pixel(x, 12)[0]).collect();
        Ok(row.iter().map(|r| (r - 0.5).abs()).sum::<f32>() / row.len() as f32)
    };
    let (filtered, sampled) = (sweep("")?, sweep(", \"width\", 0")?);
    assert!(filtered < 0.2, "filtered: mean distance from grey {filtered}");
    assert!(sampled > 0.3, "point samples: mean distance from grey {sampled}");
    Ok(())
}

#[test]
fn texture_channels_the_map_lacks_read_the_fill_value() -> Result<(), ApiError> {
    // "stripes" has three channels: its alpha reads "fill", each shading point's own where it varies.
    let fb = stripes_frame(
        "surface t() { Oi = 1; Ci = color(float texture(\"stripes\"[1], s, t, \"fill\", 0.6), \
         float texture(\"stripes\"[3], s, t, \"fill\", 0.6), float texture(\"stripes\", s, t, \"channel\", 3, \"fill\", s)); }",
    )?;
    for (x, y) in [(4, 4), (16, 12), (27, 20)] {
        let [green, alpha, varying, _] = fb.pixel(x, y);
        assert!((green - 0.25).abs() < 1e-3, "channel 1 is the map's at ({x}, {y}): {green}");
        assert!((alpha - 0.6).abs() < 1e-6, "channel 3 is the fill at ({x}, {y}): {alpha}");
        // The quad fills the image, s running left to right across it.
        assert!(varying > 0.0 && varying < 1.0, "a varying fill at ({x}, {y}): {varying}");
    }
    assert!(fb.pixel(27, 12)[2] > fb.pixel(4, 12)[2] + 0.2, "the fill follows s");
    Ok(())
}

#[test]
fn absurd_lookup_options_and_hpoints_at_infinity_render_without_failing() -> Result<(), ApiError> {
    // Widths past f32's range, negative blur, an infinite fill and a NaN direction: a frame, whatever
    // the values in it.
    let fb = stripes_frame(
        "surface t() { Oi = 1; Ci = color environment(\"stripes\", vector(0/0, 1, 0), \"width\", 1e38, \"blur\", -5) \
         + color texture(\"stripes\"[2], s, t, \"fill\", 1/0, \"width\", 1e38, \"tblur\", 1e30); }",
    )?;
    assert_eq!(fb.pixel(16, 12)[3], 1.0, "the quad is drawn");
    // An hpoint with w = 0 (a point at infinity) divides to infinities, not to a failure.
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(dir.path().join("h.sl"), "surface h(varying point Ph = 0;) { Ci = color(Ph); Oi = 1; }")
        .expect("write the shader");
    let scene = format!(
        r#"{CAMERA}
        Surface "h"
        Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "vertex hpoint Ph" [0 0 0 0  1 1 1 0  1e30 1e30 1e30 1e-30  -1 0 0 0]
        WorldEnd"#
    );
    let mut rt = Context::new();
    load_str(&mut rt, &scene, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(render(&mut rt).pixel(32, 24)[3], 1.0, "the polygon is drawn");
    Ok(())
}

#[test]
fn models_load_from_obj_ply_and_gltf() -> Result<(), SceneFileError> {
    for (file, triangles) in [
        ("cornell_box/cornell_box.obj", 36),
        ("stanford_dragon/dragon_vrip_res2.ply", 202_520),
        ("box_animated_gltf/BoxAnimated.gltf", 254),
    ] {
        let Some(path) = shared(file) else { continue };
        let mut rt = Context::new();
        rt.options.width = 32;
        rt.options.height = 24;
        let (lo, hi) = add_model_file(&mut rt, &path)?;
        assert!(lo.cmplt(hi).all(), "{file}: bounds {lo} {hi}");
        rtsl_runtime::scene_file::frame_bounds(&mut rt, (lo, hi))?;
        let world = rt.build_world()?;
        let count: usize = (0..world.instances.len())
            .filter_map(|i| world.scene.mesh(rtsl_runtime::ObjectId(world.instances[i].object)))
            .map(|m| m.triangle_count())
            .sum();
        assert!(count >= triangles, "{file}: {count} triangles");
        let (fb, _) = render_frame(&world, None);
        assert!(fb.rgba.chunks(4).any(|p| p[3] > 0.0), "{file}: the model is in view");
    }
    let mut rt = Context::new();
    assert!(matches!(add_model_file(&mut rt, Path::new("x.blend")), Err(SceneFileError::UnknownType { .. })));
    assert!(add_model_file(&mut rt, Path::new("/nonexistent/x.obj")).is_err());
    Ok(())
}

#[test]
fn broken_model_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, bytes) in [
        ("broken.gltf", &b"{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ { \"primitives\": 7 } ] }"[..]),
        ("garbage.glb", &b"glTF\x02\x00\x00\x00\xff\xff\xff\xff"[..]),
        ("broken.ply", &b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n"[..]),
        ("broken.obj", &b"v 0 0 0\nv 1 0 0\nf 1 2 9\n"[..]),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        let mut rt = Context::new();
        match add_model_file(&mut rt, &path) {
            Err(e) => assert!(e.to_string().contains(name), "{name}: {e}"),
            Ok(_) => panic!("{name} loaded"),
        }
    }
}

/// A model file past `MAX_MODEL_TRIANGLES` is refused, naming the file, from its counts alone:
/// here a glTF file's many primitives share one accessor of indices, so that the file is small
/// and what it asks for is not.
#[test]
fn a_model_file_past_the_triangle_limit_is_refused_before_it_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let per_primitive = 1usize << 17;
    let primitives = MAX_MODEL_TRIANGLES / per_primitive + 1;
    let indices = 3 * per_primitive;
    std::fs::write(dir.path().join("many.bin"), vec![0u8; 12 + indices]).expect("write");
    let primitive = r#"{ "attributes": { "POSITION": 0 }, "indices": 1 }"#;
    let gltf = format!(
        r#"{{ "asset": {{ "version": "2.0" }},
            "buffers": [ {{ "uri": "many.bin", "byteLength": {total} }} ],
            "bufferViews": [ {{ "buffer": 0, "byteLength": 12 }}, {{ "buffer": 0, "byteOffset": 12, "byteLength": {indices} }} ],
            "accessors": [
                {{ "bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0] }},
                {{ "bufferView": 1, "componentType": 5121, "count": {indices}, "type": "SCALAR" }}
            ],
            "meshes": [ {{ "primitives": [ {prims} ] }} ],
            "nodes": [ {{ "mesh": 0 }} ],
            "scenes": [ {{ "nodes": [0] }} ]
        }}"#,
        total = 12 + indices,
        prims = vec![primitive; primitives].join(", ")
    );
    let path = dir.path().join("many.gltf");
    std::fs::write(&path, gltf).expect("write");
    let mut rt = Context::new();
    let e = add_model_file(&mut rt, &path).expect_err("refused");
    assert!(matches!(e, SceneFileError::TooLarge { .. }), "{e}");
    let message = e.to_string();
    assert!(message.contains("many.gltf") && message.contains(&MAX_MODEL_TRIANGLES.to_string()), "{message}");
    assert!(rt.world_instance_ids().is_empty(), "nothing was added");
}

/// An 8x8 RGBA picture whose left half (s < 0.5) is opaque white and right half transparent.
fn write_cutout(path: &Path) {
    let img = image::RgbaImage::from_fn(8, 8, |x, _| image::Rgba(if x < 4 { [255; 4] } else { [255, 255, 255, 0] }));
    img.save(path).expect("write the cut-out picture");
}

#[test]
fn a_retained_object_holds_every_material_of_a_mesh_file_and_its_cut_outs() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    write_cutout(&dir.path().join("cutout.png"));
    std::fs::write(dir.path().join("card.mtl"), "newmtl leaf\nKd 1 0 0\nmap_Kd cutout.png\nnewmtl bark\nKd 0 0 1\n")
        .expect("write the mtl");
    // A leaf card above y = 0 (s across x) and a bark card below.
    std::fs::write(
        dir.path().join("card.obj"),
        "mtllib card.mtl\nv -1 0 0\nv 1 0 0\nv 1 1 0\nv -1 1 0\nv -1 -1 0\nv 1 -1 0\nv 1 -0.1 0\nv -1 -0.1 0\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl leaf\nf 1/1 2/2 3/3 4/4\nusemtl bark\nf 5/1 6/2 7/3 8/4\n",
    )
    .expect("write the obj");
    let rib = format!(
        r#"{CAMERA}
        Surface "constant"
        ObjectBegin "tree"
          TransformBegin Translate 0 0 0.5 ReadArchive "card.obj" TransformEnd
        ObjectEnd
        ObjectInstance "tree"
        WorldEnd"#
    );
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, &rib, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let world = rt.build_world().expect("a world");
    assert_eq!(world.scene.instance_count(), 2, "one ObjectInstance places the leaf and the bark objects");
    let (fb, _) = render_frame(&world, None);
    // Rows 17 (y = 0.5) and 31 (y = -0.5); columns 26 (x = -0.5) and 38 (x = 0.5).
    assert_eq!(fb.pixel(26, 17), [1.0, 0.0, 0.0, 1.0], "the covered half of the leaf card");
    assert_eq!(fb.pixel(38, 17)[3], 0.0, "the cut-out half lets the ray through");
    assert_eq!(fb.pixel(38, 31), [0.0, 0.0, 1.0, 1.0], "the bark card has no mask");
}

#[test]
fn the_alphamask_attribute_cuts_rib_geometry_until_its_block_ends() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    write_cutout(&dir.path().join("cutout.png"));
    let square = r#"Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "st" [0 0  1 0  1 1  0 1]"#;
    let rib = format!(
        r#"{CAMERA}
        Surface "constant"
        AttributeBegin
          Attribute "trace" "string alphamask" ["cutout.png"]
          Translate 0 0.7 0 Scale 1 0.5 1 {square}
        AttributeEnd
        Translate 0 -0.7 0 Scale 1 0.5 1 {square}
        WorldEnd"#
    );
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, &rib, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let fb = render(&mut rt);
    assert_eq!(fb.pixel(26, 14)[3], 1.0, "s < 0.5 of the masked square");
    assert_eq!(fb.pixel(38, 14)[3], 0.0, "s > 0.5 of the masked square is cut");
    assert_eq!(fb.pixel(38, 34)[3], 1.0, "the square after the block is whole");
}

/// `TrimCurve` is attribute state: a circular hole trims the `NuPatch`es of its block (and
/// `"sense" "outside"` keeps only the disk), not the one after `AttributeEnd`.
#[test]
fn trim_curves_hold_until_their_attribute_block_ends() {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let circle = [
        (1., 0., 1.),
        (1., 1., s),
        (0., 1., 1.),
        (-1., 1., s),
        (-1., 0., 1.),
        (-1., -1., s),
        (0., -1., 1.),
        (1., -1., s),
        (1., 0., 1.),
    ];
    let list = |f: &dyn Fn((f32, f32, f32)) -> f32| circle.map(f).map(|x| x.to_string()).join(" ");
    let trim = format!(
        "TrimCurve [1] [3] [0 0 0 .25 .25 .5 .5 .75 .75 1 1 1] [0] [1] [9] [{}] [{}] [{}]",
        list(&|(x, _, w)| (0.5 + 0.3 * x) * w),
        list(&|(_, y, w)| (0.5 + 0.3 * y) * w),
        list(&|(_, _, w)| w)
    );
    // The unit square about the origin, u along x and v along y.
    let patch = r#"NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [-.5 -.5 0  .5 -.5 0  -.5 .5 0  .5 .5 0]"#;
    let (mut rt, warnings) = load(&format!(
        r#"{CAMERA}
        Surface "constant"
        AttributeBegin
          {trim}
          Translate -1.5 0 0 {patch}
          Attribute "trimcurve" "sense" ["outside"]
          Translate 1.5 0 0 {patch}
        AttributeEnd
        Translate 1.5 0 0 {patch}
        WorldEnd"#
    ));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    // 12 pixels a unit about the image's middle (32, 24); the squares' corners are 0.4 from their middles.
    assert_eq!(fb.pixel(14, 24)[3], 0.0, "the hole in the first square");
    assert_eq!(fb.pixel(9, 19)[3], 1.0, "the first square's corner");
    assert_eq!(fb.pixel(32, 24)[3], 1.0, "the disk the second square keeps");
    assert_eq!(fb.pixel(37, 19)[3], 0.0, "the second square's corner, trimmed away");
    assert_eq!(fb.pixel(50, 24)[3], 1.0, "the square after the block is whole");

    // A trim curve that cannot be read, and a `Geometry` rtsl lacks, are omissions.
    let (_, warnings) = load(&format!(
        "{CAMERA} TrimCurve [1] [2] [0 1 0 1] [0] [1] [2] [0 1] [0 0] [1 1]\nGeometry \"bunny\"\nWorldEnd"
    ));
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].contains("warning: TrimCurve skipped: trim curve 0: the knots decrease"), "{warnings:?}");
    assert!(warnings[1].contains("warning: unknown Geometry name \"bunny\""), "{warnings:?}");
}

#[test]
fn a_displacement_shader_bumps_the_normal_the_surface_shader_sees() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // Ridges across s: a height of 0.5 + 0.5 sin(2 pi s * 4).
    let ridges = image::GrayImage::from_fn(64, 8, |x, _| {
        image::Luma([(127.5 + 127.5 * (std::f32::consts::TAU * x as f32 / 16.0).sin()) as u8])
    });
    ridges.save(dir.path().join("ridges.png")).expect("write the height map");
    let scene_with = |displacement: &str, primitive: &str| {
        format!(
            r#"{CAMERA}
            LightSource "distantlight" 1 "from" [-1 0.3 -1] "to" [0 0 0]
            Surface "matte"
            {displacement}
            Polygon "P" [-1.5 -1 0  1.5 -1 0  1.5 1 0  -1.5 1 0] "st" [0 0  1 0  1 1  0 1] {primitive}
            WorldEnd"#
        )
    };
    let scene = |displacement: &str| scene_with(displacement, "");
    let row_with = |displacement: &str, primitive: &str| {
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &scene_with(displacement, primitive), dir.path().join("scene.rib"))
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let fb = render(&mut rt);
        (14..50).map(|x| fb.pixel(x, 24)[0]).collect::<Vec<f32>>()
    };
    let row = |displacement: &str| row_with(displacement, "");
    let spread = |r: &[f32]| {
        r.iter().copied().fold(f32::NEG_INFINITY, f32::max) - r.iter().copied().fold(f32::INFINITY, f32::min)
    };
    let flat = row("");
    assert!(spread(&flat) < 1e-4, "an unbumped plane under a distant light is even: {flat:?}");
    let bumped = row(r#"Displacement "bumpy" "amplitude" [0.05] "texturename" ["ridges.png"]"#);
    assert!(spread(&bumped) > 0.2, "the ridges turn the normal: {bumped:?}");
    assert_eq!(row(r#"Displacement "bumpy" "amplitude" [0]"#), flat, "no height, no change");
    // A primitive's constant value reaches the displacement shader as its parameter.
    let given = row_with(
        r#"Displacement "bumpy" "amplitude" [0] "texturename" ["ridges.png"]"#,
        r#""constant float amplitude" [0.05]"#,
    );
    assert_eq!(given, bumped, "the primitive's amplitude");
    // The geometry does not move: the same pixels are covered.
    let mut rt = Context::new();
    load_str(
        &mut rt,
        &scene(r#"Displacement "bumpy" "amplitude" [0.5] "texturename" ["ridges.png"]"#),
        dir.path().join("s.rib"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let covered = render(&mut rt).rgba.chunks(4).filter(|p| p[3] > 0.5).count();
    let mut rt = Context::new();
    load_str(&mut rt, &scene(""), dir.path().join("s.rib")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(covered, render(&mut rt).rgba.chunks(4).filter(|p| p[3] > 0.5).count());
}

#[test]
fn gltf_base_colour_textures_are_mapped_and_mask_mode_cuts() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    write_cutout(&dir.path().join("cutout.png"));
    // A card above y = 0, s across x, t down (glTF's convention), two triangles.
    let mut bin = Vec::new();
    for v in [[-1.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        v.iter().for_each(|x| bin.extend(x.to_le_bytes()));
    }
    for v in [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]] {
        v.iter().for_each(|x| bin.extend(x.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    std::fs::write(dir.path().join("card.bin"), &bin).expect("write the buffer");
    let gltf = |mode: &str| {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
            "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}, "alphaMode": "{mode}"}}],
            "textures": [{{"source": 0}}], "images": [{{"uri": "cutout.png"}}],
            "buffers": [{{"uri": "card.bin", "byteLength": 92}}],
            "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                            {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, 0], "max": [1, 1, 0]}},
                          {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
                          {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#
        )
    };
    let render_mode = |mode: &str| {
        std::fs::write(dir.path().join("card.gltf"), gltf(mode)).expect("write the glTF");
        let rib = format!(r#"{CAMERA} LightSource "ambientlight" 1 "intensity" [5] ReadArchive "card.gltf" WorldEnd"#);
        let mut rt = Context::new();
        let loaded = load_str(&mut rt, &rib, dir.path().join("scene.rib")).unwrap_or_else(|e| panic!("{e}"));
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        render(&mut rt)
    };
    let masked = render_mode("MASK");
    let left = masked.pixel(26, 17);
    assert!(left[..3].iter().all(|c| (c - 1.0).abs() < 1e-3) && left[3] == 1.0, "the texture's white: {left:?}");
    assert_eq!(masked.pixel(38, 17)[3], 0.0, "alpha below the cut-off is cut");
    let opaque = render_mode("OPAQUE");
    assert_eq!(opaque.pixel(38, 17)[3], 1.0, "OPAQUE ignores alpha");
    assert!(opaque.pixel(38, 17)[0] > 0.9, "the (white, transparent) texels' colour: {:?}", opaque.pixel(38, 17));
}

#[test]
fn crop_window_and_frame_aspect_ratio_are_honoured() {
    let wall = r#"Surface "constant" Color [.2 .6 .9] Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"#;
    let render_with = |options: &str| {
        let (mut rt, warnings) = load(&format!(
            "Format 64 48 1\n{options}\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n{wall}\nWorldEnd"
        ));
        assert!(warnings.is_empty(), "{warnings:?}");
        render(&mut rt)
    };
    let whole = render_with("");
    // The top right quarter: columns 32..64 (ceil(64 * 0.5)), rows 0..24.
    let cropped = render_with("CropWindow 0.5 1 0 0.5");
    for y in 0..48 {
        for x in 0..64 {
            let inside = x >= 32 && y < 24;
            let p = cropped.pixel(x, y);
            if inside {
                assert_eq!(p, whole.pixel(x, y), "({x}, {y}) is rendered as without the crop");
            } else {
                assert_eq!(p, [0.0; 4], "({x}, {y}) is outside the crop");
            }
        }
    }
    // A frame aspect ratio of 2 is the screen window [-2, 2] x [-1, 1].
    let aspect = render_with("FrameAspectRatio 2");
    assert!(aspect.rgba == render_with("ScreenWindow -2 2 -1 1").rgba, "FrameAspectRatio 2 is that window");
    let covered = |fb: &rtsl_runtime::render::Framebuffer| fb.rgba.chunks(4).filter(|p| p[3] > 0.5).count();
    // The window is 1.5 times wider than the default [-4/3, 4/3]: the square covers fewer columns.
    assert!(covered(&aspect) < covered(&whole), "{} vs {}", covered(&aspect), covered(&whole));
}

#[test]
fn adaptive_sampling_leaves_pixels_outside_the_crop_window_empty() {
    // The square's edges cross the crop's border, where rendered pixels meet empty ones: neither
    // side is refined for that, and only rendered pixels get extra samples.
    let wall = r#"Surface "constant" Color [.2 .6 .9] Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"#;
    let (mut rt, warnings) = load(&format!(
        "Format 64 48 1\nCropWindow 0.3 0.7 0.3 0.7\nOption \"antialiasing\" \"mode\" [\"adaptive\"]\n\
         Projection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n{wall}\nWorldEnd"
    ));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    let (x0, x1, y0, y1) = rt.options.pixel_range();
    let mut rendered = 0;
    for y in 0..48 {
        for x in 0..64 {
            let inside = (x0..x1).contains(&x) && (y0..y1).contains(&y);
            if inside {
                rendered += usize::from(fb.pixel(x, y)[3] > 0.0);
            } else {
                assert_eq!(fb.pixel(x, y), [0.0; 4], "({x}, {y}) is outside the crop");
            }
        }
    }
    assert!(rendered > 50, "{rendered} covered pixels in the crop");
}

#[test]
fn bad_cut_outs_windows_and_displacements_are_warnings_not_failures() {
    let square = r#"Surface "constant" Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"#;
    let (mut plain, _) = load(&format!("{CAMERA} {square} WorldEnd"));
    let plain = render(&mut plain);
    // A cut-out texture that does not exist: one warning, and the square stays solid.
    let (mut rt, warnings) =
        load(&format!(r#"{CAMERA} Attribute "trace" "string alphamask" ["nosuch.png"] {square} WorldEnd"#));
    assert!(warnings.is_empty(), "{warnings:?}");
    let fb = render(&mut rt);
    assert!(fb.rgba == plain.rgba, "a missing mask cuts nothing");
    let context_warnings = rt.take_warnings();
    assert!(context_warnings.iter().any(|w| w.contains("nosuch.png")), "{context_warnings:?}");
    // A window of zero width is the default window; an empty or inverted crop is refused (the
    // whole image renders) rather than rendering nothing.
    let (mut rt, warnings) = load(&format!("ScreenWindow 1 1 0 0\n{CAMERA} {square} WorldEnd"));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(render(&mut rt).rgba == plain.rgba);
    for crop in ["0.8 0.2 0 1", "0 1 0.5 0.5", "2 3 0 1", "0 1 1 1"] {
        let (mut rt, warnings) = load(&format!("CropWindow {crop}\n{CAMERA} {square} WorldEnd"));
        assert!(
            warnings.len() == 1 && warnings[0].contains("test.rib:1:1") && warnings[0].contains("covers no part"),
            "{crop}: {warnings:?}"
        );
        assert!(render(&mut rt).rgba == plain.rgba, "{crop}");
    }
    // A surface shader named as a displacement: a located warning, and the square still renders.
    let (mut rt, warnings) = load(&format!(r#"{CAMERA} Displacement "plastic" {square} WorldEnd"#));
    assert!(warnings.iter().any(|w| w.contains("test.rib:") && w.contains("plastic")), "{warnings:?}");
    assert!(render(&mut rt).rgba == plain.rgba);
}

#[test]
fn obj_groups_of_one_material_become_one_object() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(dir.path().join("two.mtl"), "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n").expect("write the mtl");
    // Four squares side by side: two groups without a material, a red and a blue group, then a
    // group with normals (which the groups without cannot share a mesh with) and a second red group.
    let square = |x: f32, normals: bool| {
        let v: String = [(0.0, 0.0), (0.5, 0.0), (0.5, 0.5), (0.0, 0.5)]
            .iter()
            .map(|(dx, dy)| format!("v {} {} 0\n", x + dx, dy))
            .collect();
        let f = if normals { "f -4//1 -3//1 -2//1 -1//1\n" } else { "f -4 -3 -2 -1\n" };
        format!("{v}{f}")
    };
    let obj = format!(
        "mtllib two.mtl\nvn 0 0 1\ng a\n{}g b\n{}g c\nusemtl red\n{}g d\nusemtl blue\n{}g e\nusemtl red\n{}g f\nusemtl none\n{}",
        square(-2.0, false),
        square(-1.4, false),
        square(-0.8, false),
        square(-0.2, false),
        square(0.4, false),
        square(1.0, true),
    );
    let path = dir.path().join("groups.obj");
    std::fs::write(&path, obj).expect("write the obj");
    let mut rt = Context::new();
    add_model_file(&mut rt, &path).expect("loads");
    let world = rt.build_world().expect("a world");
    let meshes: Vec<_> = (0..world.instances.len())
        .filter_map(|i| world.scene.mesh(rtsl_runtime::ObjectId(world.instances[i].object)))
        .collect();
    let mut triangles: Vec<(usize, bool)> = meshes.iter().map(|m| (m.triangle_count(), m.normals.is_some())).collect();
    triangles.sort();
    // No material (a, b; f names an unknown one): 4 triangles; red (c, e): 4; blue: 2; f alone:
    // it has normals.
    assert_eq!(triangles, [(2, false), (2, true), (4, false), (4, false)], "{triangles:?}");
}

#[test]
fn the_null_shader_stands_for_no_shader_and_defaultsurface_shades_by_facing() {
    let scene = |surface: &str, extra: &str| {
        format!(
            "{CAMERA}{extra}\n  Color [0.5 1 0.25]\n  Surface \"{surface}\"\n  \
             Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\nWorldEnd\n"
        )
    };
    // Every shader type's null: nothing to warn about, nothing added.
    let nulls = "Imager \"null\"\nLightSource \"null\" 1\nDisplacement \"null\"\nAtmosphere \"null\"\n\
                 Interior \"null\"\nExterior \"null\"";
    let (mut rt, warnings) = load(&scene("null", nulls));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(rt.world_instance_ids().len(), 1);
    let fb = render(&mut rt);
    assert_eq!(fb.pixel(32, 24), [0.0, 0.0, 0.0, 1.0], "a null surface sets nothing: black and opaque");
    // Facing the eye squarely, defaultsurface is Cs * (Ka + Kd) = Cs.
    let (mut rt, warnings) = load(&scene("defaultsurface", ""));
    assert!(warnings.is_empty(), "{warnings:?}");
    let p = render(&mut rt).pixel(32, 24);
    for (got, want) in p.iter().zip([0.5, 1.0, 0.25, 1.0]) {
        assert!((got - want).abs() < 1e-3, "{p:?}");
    }
    // With no surface shader the renderer's own matte faces the viewer the same way, displaced
    // or not: a displacement that scales N (as `calculatenormal` of a moved P does) changes
    // nothing (BMRT's dented.rib rendered white).
    for displacement in ["", "Displacement \"scaled\""] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        std::fs::write(dir.path().join("scaled.sl"), "displacement scaled() { N = 40 * normalize(N); }")
            .expect("written");
        let mut rt = Context::new();
        rt.set_shader_search_path([dir.path()]);
        let rib = format!(
            "{CAMERA} Color [0.5 1 0.25] {displacement} Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] WorldEnd"
        );
        let loaded = load_str(&mut rt, &rib, Path::new("s.rib")).expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let p = render(&mut rt).pixel(32, 24);
        for (got, want) in p.iter().zip([0.5, 1.0, 0.25, 1.0]) {
            assert!((got - want).abs() < 1e-3, "{displacement}: {p:?}");
        }
    }
}

#[test]
fn detail_ranges_pick_one_level_by_the_bound_s_size_on_screen() {
    // Three levels of one unit box, red coarse, green medium, blue fine, by its raster area.
    let levels = |translate_z: f32| {
        format!(
            "Format 100 100 1\nProjection \"perspective\" \"fov\" [90]\nTranslate 0 0 {translate_z}\nWorldBegin\n\
             Surface \"constant\"\nAttributeBegin\nDetail [-1 1 -1 1 -1 1]\n\
             AttributeBegin DetailRange [0 0 100 200] Color [1 0 0] Sphere 1 -1 1 360 AttributeEnd\n\
             AttributeBegin DetailRange [100 200 1000 2000] Color [0 1 0] Sphere 1 -1 1 360 AttributeEnd\n\
             AttributeBegin DetailRange [1000 2000 1e30 1e30] Color [0 0 1] Sphere 1 -1 1 360 AttributeEnd\n\
             AttributeEnd\nWorldEnd"
        )
    };
    let centre = |z: f32| {
        let (mut rt, warnings) = load(&levels(z));
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(rt.world_instance_ids().len(), 1, "one level at {z}");
        let p = render(&mut rt).pixel(50, 50);
        [p[0], p[1], p[2]]
    };
    // Near: the box covers more than 2,000 pixels; five units away, about 25 x 25; far, a few.
    assert_eq!(centre(2.5), [0.0, 0.0, 1.0]);
    assert_eq!(centre(5.0), [0.0, 1.0, 0.0]);
    assert_eq!(centre(40.0), [1.0, 0.0, 0.0]);
    // Without Detail, every level is drawn.
    let (rt, _) = load(&levels(5.0).replace("Detail [-1 1 -1 1 -1 1]\n", ""));
    assert_eq!(rt.world_instance_ids().len(), 3);
}

#[test]
fn make_lat_long_environment_writes_a_map_that_wraps_around_and_stops_at_the_poles() {
    let dir = tempfile::tempdir().unwrap();
    let pixels: Vec<f32> = (0..8 * 4).flat_map(|i| [i as f32 / 32.0, 0.5, 0.25, 1.0]).collect();
    rtsl_runtime::write_image(dir.path().join("sky.png"), 8, 4, &pixels, &Default::default()).unwrap();
    let rib = dir.path().join("env.rib");
    std::fs::write(&rib, "MakeLatLongEnvironment \"sky.png\" \"sky.tex\" \"gaussian\" 2 2\nWorldBegin\nWorldEnd\n")
        .unwrap();
    let loaded = rtsl_runtime::rib::load::load_file(&mut Context::new(), &rib).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let layer = rtsl_runtime::image_io::read_exr(&dir.path().join("sky.tex")).expect("an environment map");
    assert_eq!((layer.width, layer.height), (8, 4));
    assert_eq!(layer.wrap_modes.as_deref(), Some("periodic,clamp"));
}

#[test]
fn make_shadow_of_a_file_that_is_not_a_depth_map_is_a_part_missing() {
    let dir = tempfile::tempdir().unwrap();
    rtsl_runtime::write_image(dir.path().join("photo.png"), 2, 2, &[0.5; 16], &Default::default()).unwrap();
    let rib = dir.path().join("s.rib");
    std::fs::write(
        &rib,
        "MakeShadow \"photo.png\" \"s.shd\"\nMakeShadow \"absent.z\" \"t.shd\"\nWorldBegin\nWorldEnd\n",
    )
    .unwrap();
    let loaded = rtsl_runtime::rib::load::load_file(&mut Context::new(), &rib).expect("the rest loads");
    assert_eq!(loaded.omissions(), 2, "{:?}", loaded.warnings);
    assert!(loaded.warnings.iter().all(|w| w.message.starts_with("MakeShadow: ")), "{:?}", loaded.warnings);
    assert!(!dir.path().join("s.shd").exists() && !dir.path().join("t.shd").exists());
}

/// Contexts sharing what they make of files (`Context::share_files`, as the frames of a render
/// do) read a model file once, and again when it or its material library changes.
#[test]
fn shared_model_files_are_read_once_until_they_or_their_materials_change() -> Result<(), SceneFileError> {
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = dir.path().join("quad.obj");
    std::fs::write(&obj, "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nusemtl paint\nf 1 2 3 4\n")
        .expect("write");
    let paint =
        |kd: &str| std::fs::write(dir.path().join("quad.mtl"), format!("newmtl paint\nKd {kd}\n")).expect("write");
    paint("1 0 0");
    let shared = std::sync::Arc::new(rtsl_runtime::shared_files::SharedFiles::new());
    // The colour at the centre of the model, framed and lit by the model defaults.
    let centre =
        |shared: &std::sync::Arc<rtsl_runtime::shared_files::SharedFiles>| -> Result<[f32; 3], SceneFileError> {
            let mut rt = Context::new();
            rt.share_files(shared.clone());
            rt.options.width = 9;
            rt.options.height = 9;
            rtsl_runtime::load_scene(&mut rt, &obj)?;
            let (fb, _) = render_frame(&rt.build_world()?, None);
            let px = &fb.rgba[(4 * 9 + 4) * 4..][..3];
            Ok([px[0], px[1], px[2]])
        };
    let red = centre(&shared)?;
    assert!(red[0] > 0.0 && red[1] == 0.0 && red[2] == 0.0, "{red:?}");
    assert_eq!(shared.len(), 1, "the model is kept");
    assert_eq!(centre(&shared)?, red);
    paint("0 1 0.25");
    let green = centre(&shared)?;
    assert!(green[0] == 0.0 && green[1] > 0.0, "the changed material library is read again: {green:?}");
    assert_eq!(shared.len(), 1);
    Ok(())
}

/// RISpec gives a polygon its `(x, y)` as surface parameters and texture coordinates. A polygon
/// that stands edge-on to that plane in its own space (a floor in x and z) is not spanned by
/// them: its derivatives along u and v come from its triangles' own parameters instead (as
/// Aqsis's do), so that `Du`, `Dv` and `calculatenormal` work there, and bump and displacement
/// shaders with them; `s` and `t` stay its `x` and `y`.
#[test]
fn a_polygon_edge_on_to_its_own_xy_plane_has_surface_derivatives() {
    let probe = "surface probe() {
        point o = transform(\"object\", P);
        normal c = calculatenormal(P);
        float spans = length(Du(P)) > 0 && length(Dv(P)) > 0 ? 1 : 0;
        float along = length(c) > 0 && abs(normalize(c) . normalize(N)) > 0.999 ? 1 : 0;
        float st = abs(s - xcomp(o)) < 1e-3 && abs(t - ycomp(o)) < 1e-3 ? 1 : 0;
        Oi = 1; Ci = color(spans, along, st);
    }";
    let floors = [
        "Polygon \"P\" [-1 0 -1  1 0 -1  1 0 1  -1 0 1]",
        "PointsPolygons [3 3] [0 1 2  0 2 3] \"P\" [-1 0 -1  1 0 -1  1 0 1  -1 0 1]",
    ];
    assert_probe_is_white_at_the_centre(
        probe,
        floors.map(|floor| format!("Surface \"probe\" Rotate -90 1 0 0 {floor}")),
    );
}

/// Renders each of `scenes` (the world block's contents, under [`CAMERA`]) with the surface shader
/// `probe` on the search path, and asserts that pixels about the image's centre are white: the
/// probe's every check held there.
fn assert_probe_is_white_at_the_centre(probe: &str, scenes: impl IntoIterator<Item = String>) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::write(dir.path().join("probe.sl"), probe).expect("written");
    for scene in scenes {
        let mut rt = Context::new();
        rt.set_shader_search_path([dir.path()]);
        let rib = format!("{CAMERA} {scene} WorldEnd");
        let loaded = load_str(&mut rt, &rib, Path::new("s.rib")).expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let fb = render(&mut rt);
        for (x, y) in [(32, 24), (28, 20), (35, 27)] {
            assert_eq!(fb.pixel(x, y), [1.0; 4], "{scene}: pixel ({x}, {y})");
        }
    }
}

/// RISpec: `u` and `v` are a surface's parameters, from 0 to 1 over a patch or quadric, and
/// `TextureCoordinates` (or `st` given with the surface) maps its texture coordinates `s` and
/// `t` only: a shader sees both, and its derivatives along `u` and `v` go by the parameters.
#[test]
fn texture_coordinates_map_s_and_t_and_leave_u_and_v_the_surface_s_parameters() {
    let probe = "surface probe(float scale = 2) {
        float inside = u >= 0 && u <= 1 && v >= 0 && v <= 1 ? 1 : 0;
        float mapped = abs(s - scale * u) < 1e-3 && abs(t - scale * v) < 1e-3 ? 1 : 0;
        float step = abs(Du(u) - 1) < 1e-3 && abs(Dv(v) - 1) < 1e-3 ? 1 : 0;
        Oi = 1; Ci = color(inside, mapped, step);
    }";
    let surfaces = [
        "TextureCoordinates 0 0 2 0 0 2 2 2 Surface \"probe\" Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]",
        "TextureCoordinates 0 0 2 0 0 2 2 2 Surface \"probe\" Sphere 1 -1 1 360",
        "Surface \"probe\" \"scale\" 3 Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0] \
         \"st\" [0 0  3 0  0 3  3 3]",
        "Surface \"probe\" \"scale\" 1 Sphere 1 -1 1 360",
    ];
    assert_probe_is_white_at_the_centre(probe, surfaces.map(|surface| format!("Rotate -30 1 0 0 {surface}")));
}

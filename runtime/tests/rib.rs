//! The RIB reader through its public API: every request, declarations, archives, error
//! locations and recovery, and robustness against random and mutated input.

use std::path::Path;

use proptest::prelude::*;
use rtsl_runtime::geometry::Quadric;
use rtsl_runtime::rib::{
    self, mesh_from_request, mesh_from_request_with, Basis, Class, Decl, Handle, Orientation, ParamValue, PatchType,
    RequestKind as K, RibParse, Severity, Ty, Wrap,
};

/// A scene using every request the reader knows.
const EVERY_REQUEST: &str = r#"##RenderMan RIB
version 3.03
Option "searchpath" "shader" ["./shaders:&"]
Declare "bump" "uniform float"
Format 640 480 1
FrameAspectRatio 1.333
ScreenWindow -1.333 1.333 -1 1
CropWindow [0 1 0 1]
Projection "perspective" "fov" 45
Clipping 0.1 1000
DepthOfField 8 0.05 10
Shutter 0 1
Display "out.tif" "file" "rgba" "origin" [0 0]
PixelSamples 4 4
Hider "hidden" "integer jitter" [1]
PixelFilter "gaussian" 2 2
Exposure 1 2.2
ShadingRate 1
Imager "background" "background" [0 0 0.2]
Camera "pinhole" "float zoom" 2
Pixel "tonemap" "uniform float exposure" 1.5
FrameBegin 1
Identity
Transform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1]
Perspective 45
Skew 45 0 1 0 1 0 0
WorldBegin
LightSource "ambientlight" 1 "intensity" 0.2
LightSource "spotlight" "key" "from" [0 5 0] "to" [0 0 0] "coneangle" 0.5
LightSource "distantlight" "intensity" 1
Illuminate 1 0
Illuminate "key" 1
AttributeBegin
  Attribute "identifier" "name" "floor"
  Color [0.8 0.8 0.8]
  Opacity 1 1 1
  Surface "plastic" "Kd" 0.5 "uniform float Ks" [0.3] "bump" 2 "constant string texname" "grid.tex"
  Displacement "bumpy" "amplitude" 0.1
  Atmosphere "fog" "distance" 10 "background" [0.5 0.5 0.5]
  Interior "glass"
  Exterior "air"
  AreaLightSource "arealight" 2 "lightcolor" [1 1 0.9]
  Sides 2
  Orientation "rh"
  ReverseOrientation
  Matte 0
  ShadingInterpolation "smooth"
  TextureCoordinates 0 0 2 0 0 2 2 2
  Bound [-1 1 -1 1 -1 1]
  MotionBegin [0 1]
    Translate 0 0 0
    Translate 0 0 1
  MotionEnd
  SolidBegin "primitive"
  SolidEnd
  Basis "bezier" 3 "bezier" 3
  Translate 0 -1 0
  Rotate 90 1 0 0
  Scale 2 2 2
  ConcatTransform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1]
  CoordinateSystem "floorspace"
  TransformBegin
    CoordSysTransform "floorspace"
    Polygon "P" [0 0 0 1 0 0 1 1 0 0 1 0] "st" [0 0 1 0 1 1 0 1]
  TransformEnd
  GeneralPolygon [4 3] "P" [0 0 0 4 0 0 4 4 0 0 4 0 1 1 0 2 1 0 1 2 0]
  PointsPolygons [3 3] [0 1 2 0 2 3] "P" [0 0 0 1 0 0 1 1 0 0 1 0] "varying color Cs" [1 0 0 0 1 0 0 0 1 1 1 1]
  PointsGeneralPolygons [1] [3] [0 1 2] "P" [0 0 0 1 0 0 1 1 0]
  Patch "bilinear" "P" [0 0 0 1 0 0 0 1 0 1 1 0]
  PatchMesh "bilinear" 2 "nonperiodic" 3 "periodic" "P" [0 0 0 1 0 0 0 1 0 1 1 0 0 2 0 1 2 0]
  SubdivisionMesh "catmull-clark" [4 4 4 4 4 4] [0 3 2 1 4 5 6 7 0 1 5 4 1 2 6 5 2 3 7 6 3 0 4 7]
    ["crease" "corner" "hole" "interpolateboundary"] [5 1 1 1 1 0 0 0] [4 5 6 7 4 0 2] [2.5 3]
    "P" [-1 -1 -1 1 -1 -1 1 1 -1 -1 1 -1 -1 -1 1 1 -1 1 1 1 1 -1 1 1] "facevarying float[2] st" [0 0 1 0 1 1 0 1
    0 0 1 0 1 1 0 1 0 0 1 0 1 1 0 1 0 0 1 0 1 1 0 1 0 0 1 0 1 1 0 1 0 0 1 0 1 1 0 1]
  Sphere 1 -1 1 360
  Cylinder 1 0 2 180
  Cone 2 1 360
  Disk 0 1 360
  Torus 2 0.5 0 360 360
  Paraboloid 1 0 2 360
  Hyperboloid 1 0 0 0 1 1 360
  Points "P" [0 0 2 1 0 2] "width" [0.1 0.2] "Cs" [1 0 0 0 1 0] "uniform string type" "disk"
  Curves "cubic" [4] "nonperiodic" "P" [0 0 2 1 1 2 2 1 2 3 0 2] "width" [0.1 0.05] "N" [0 0 1 0 0 1]
AttributeEnd
ObjectBegin 1
  Sphere 0.5 -0.5 0.5 360
ObjectEnd
ObjectBegin "tree"
ObjectEnd
ObjectInstance 1
ObjectInstance "tree"
MakeTexture "grid.tif" "grid.tex" "periodic" "clamp" "box" 1 1 "float fov" 10
WorldEnd
FrameEnd
"#;

fn parse(text: &str) -> RibParse {
    rib::parse_str(text, "scene.rib")
}

fn messages(parse: &RibParse) -> Vec<String> {
    parse.diagnostics.iter().map(ToString::to_string).collect()
}

#[test]
fn every_request_parses() {
    let parsed = parse(EVERY_REQUEST);
    assert!(parsed.diagnostics.is_empty(), "{:#?}", messages(&parsed));
    let names: Vec<String> = parsed
        .requests
        .iter()
        .map(|r| format!("{:?}", r.kind).split(['(', ' ']).next().unwrap_or_default().to_string())
        .collect();
    for expected in [
        "Version",
        "Option",
        "Declare",
        "Format",
        "FrameAspectRatio",
        "ScreenWindow",
        "CropWindow",
        "Projection",
        "Clipping",
        "DepthOfField",
        "Shutter",
        "Display",
        "PixelSamples",
        "PixelFilter",
        "Exposure",
        "ShadingRate",
        "Imager",
        "Camera",
        "Pixel",
        "FrameBegin",
        "Identity",
        "Transform",
        "Perspective",
        "Skew",
        "WorldBegin",
        "LightSource",
        "Illuminate",
        "AttributeBegin",
        "Attribute",
        "Color",
        "Opacity",
        "Surface",
        "Displacement",
        "Atmosphere",
        "Interior",
        "Exterior",
        "AreaLightSource",
        "Sides",
        "Orientation",
        "ReverseOrientation",
        "Matte",
        "ShadingInterpolation",
        "Hider",
        "TextureCoordinates",
        "Bound",
        "MotionBegin",
        "MotionEnd",
        "SolidBegin",
        "SolidEnd",
        "Basis",
        "Translate",
        "Rotate",
        "Scale",
        "ConcatTransform",
        "CoordinateSystem",
        "TransformBegin",
        "CoordSysTransform",
        "Polygon",
        "TransformEnd",
        "GeneralPolygon",
        "PointsPolygons",
        "PointsGeneralPolygons",
        "Patch",
        "PatchMesh",
        "SubdivisionMesh",
        "Quadric",
        "Points",
        "Curves",
        "AttributeEnd",
        "ObjectBegin",
        "ObjectEnd",
        "ObjectInstance",
        "MakeTexture",
        "WorldEnd",
        "FrameEnd",
    ] {
        assert!(names.iter().any(|n| n == expected), "no {expected} in {names:?}");
    }
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(kinds.contains(&&K::Format { xres: 640, yres: 480, pixel_aspect: 1.0 }));
    assert!(kinds.contains(&&K::CropWindow([0.0, 1.0, 0.0, 1.0])));
    assert!(kinds.contains(&&K::PixelFilter { filter: "gaussian".into(), xwidth: 2.0, ywidth: 2.0 }));
    assert!(kinds.contains(&&K::MotionBegin(vec![0.0, 1.0])));
    assert!(kinds.contains(&&K::TextureCoordinates([0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 2.0, 2.0])));
    assert!(kinds.contains(&&K::FrameBegin(Some(1))));
    assert!(kinds.contains(&&K::Illuminate { light: Handle::Number(1), on: false }));
    assert!(kinds.contains(&&K::Illuminate { light: Handle::Name("key".into()), on: true }));
    assert!(kinds.contains(&&K::Rotate { angle: 90.0, axis: [1.0, 0.0, 0.0] }));
    assert!(kinds.contains(&&K::Orientation(Orientation::RightHanded)));
    assert!(kinds.contains(&&K::ObjectBegin(Handle::Name("tree".into()))));
    assert!(kinds.contains(&&K::Basis {
        u: Basis::Named("bezier".into()),
        ustep: 3,
        v: Basis::Named("bezier".into()),
        vstep: 3
    }));
    assert!(kinds.contains(&&K::Quadric {
        quadric: Quadric::Torus { major_radius: 2.0, minor_radius: 0.5, phimin: 0.0, phimax: 360.0, thetamax: 360.0 },
        params: vec![]
    }));
    let lights: Vec<_> = kinds
        .iter()
        .filter_map(|k| match k {
            K::LightSource { shader, handle } => Some((shader.name.as_str(), handle.clone(), shader.params.len())),
            _ => None,
        })
        .collect();
    assert_eq!(
        lights,
        vec![
            ("ambientlight", Some(Handle::Number(1)), 1),
            ("spotlight", Some(Handle::Name("key".into())), 3),
            ("distantlight", None, 1)
        ]
    );
    let patch_mesh = kinds.iter().find(|k| matches!(k, K::PatchMesh { .. })).unwrap();
    assert!(matches!(
        patch_mesh,
        K::PatchMesh { ty: PatchType::Bilinear, nu: 2, uwrap: Wrap::NonPeriodic, nv: 3, vwrap: Wrap::Periodic, .. }
    ));

    // Every geometry request makes a valid mesh.
    let mut diagnostics = Vec::new();
    let meshes: Vec<_> = parsed.requests.iter().filter_map(|r| mesh_from_request(r, &mut diagnostics)).collect();
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    assert_eq!(meshes.len(), 17);
    for mesh in &meshes {
        mesh.validate().unwrap();
        assert!(mesh.triangle_count() > 0);
    }
}

#[test]
fn parameters_take_their_types_from_every_source() {
    let parsed = parse(EVERY_REQUEST);
    let surface = parsed
        .requests
        .iter()
        .find_map(|r| match &r.kind {
            K::Surface(s) => Some(s),
            _ => None,
        })
        .unwrap();
    let summary: Vec<(&str, Decl, &ParamValue)> =
        surface.params.iter().map(|p| (p.name.as_str(), p.decl, &p.value)).collect();
    assert_eq!(
        summary,
        vec![
            ("Kd", Decl::new(Class::Uniform, Ty::Float), &ParamValue::Floats(vec![0.5])),
            ("Ks", Decl::new(Class::Uniform, Ty::Float), &ParamValue::Floats(vec![0.3])),
            ("bump", Decl::new(Class::Uniform, Ty::Float), &ParamValue::Floats(vec![2.0])),
            ("texname", Decl::new(Class::Constant, Ty::String), &ParamValue::Strings(vec!["grid.tex".into()])),
        ]
    );
    assert_eq!(surface.params[0].loc.to_string(), "scene.rib:37:21");
    let display = parsed.requests.iter().find(|r| matches!(r.kind, K::Display { .. })).unwrap();
    let K::Display { params, .. } = &display.kind else { unreachable!() };
    assert_eq!(params[0].ints(), Some(&[0, 0][..]));
    // Array types and counts.
    let parsed =
        parse(r#"Declare "uv2" "varying float[2]" Surface "s" "uv2" [1 2 3 4] "vertex point Pref" [0 0 0 1 1 1]"#);
    assert!(parsed.diagnostics.is_empty(), "{:?}", messages(&parsed));
    let K::Surface(shader) = &parsed.requests[1].kind else { panic!() };
    assert_eq!((shader.params[0].value_count(), shader.params[1].value_count()), (2, 2));
}

#[test]
fn declare_is_global_and_later_declarations_win() {
    let parsed = parse(
        r#"AttributeBegin Declare "k" "uniform color" AttributeEnd
           Surface "a" "k" [1 2 3]
           Declare "k" "uniform float"
           Surface "b" "k" 4
           Surface "c" "k" [1 2 3]"#,
    );
    assert_eq!(parsed.requests.len(), 7);
    let K::Surface(a) = &parsed.requests[3].kind else { panic!() };
    assert_eq!(a.params[0].decl.ty, Ty::Color);
    let K::Surface(b) = &parsed.requests[5].kind else { panic!() };
    assert_eq!(b.params[0].decl.ty, Ty::Float);
    // Three floats are three values of a float: fine.
    assert!(parsed.diagnostics.is_empty(), "{:?}", messages(&parsed));
}

#[test]
fn parameter_problems_are_reported_where_they_are() {
    let parsed = parse(
        "Surface \"plastic\"\n  \"Kdd\" 0.5\n  \"color c\" [1 2]\n  \"uniform flaot x\" 1\n  \"integer n\" 1.5\n  \"string s\" 3\n  \"Kd\" 0.25\n",
    );
    assert_eq!(
        messages(&parsed),
        vec![
            "scene.rib:3:13: error: parameter \"c\" (uniform color): 2 numbers given, which is not a multiple of 3 (numbers per value)",
            "scene.rib:4:3: error: unknown type `flaot` (expected float, integer, color, point, vector, normal, hpoint, string or matrix)",
            "scene.rib:5:15: error: parameter \"n\" (uniform integer): 1.5 is not an integer",
            "scene.rib:6:14: error: parameter \"s\" (uniform string): expected strings, found a number",
        ]
    );
    // The request survives with its good parameters; the undeclared one is kept for the shader to
    // type (the loader warns when the shader has no such parameter).
    let K::Surface(shader) = &parsed.requests[0].kind else { panic!() };
    assert_eq!(shader.params.len(), 2);
    assert_eq!((shader.params[0].name.as_str(), shader.params[0].decl.class), ("Kdd", Class::Implicit));
    assert_eq!(shader.params[1].name, "Kd");
}

#[test]
fn syntax_errors_are_located_and_reading_recovers() {
    let text = "\"stray\" 1\n\
                WorldBegin\n\
                Translate 1 2\n\
                Sphere 1 -1 \"one\" 360\n\
                Color [1 0 0] ]\n\
                Scale 1 1 1 1\n\
                Rotate 90 [0 0 1\n\
                Surface \"x\" 0.5\n\
                Frobnicate 1 2 3 Shader\n\
                Polygon \"P\" [0 0 0 1 0 0 1 1 0] \"Cs\"\n\
                Disk 0 1 360 12abc\n\
                Cone 1 1 360\n\
                WorldEnd\n";
    let parsed = parse(text);
    assert_eq!(
        messages(&parsed),
        vec![
            "scene.rib:1:1: error: expected a request name, found a string",
            "scene.rib:3:1: error: `Translate` needs 3 numbers (dx dy dz) but has 2",
            "scene.rib:4:13: error: `Sphere` expects numbers (radius zmin zmax thetamax), found a string",
            "scene.rib:5:15: error: `]` without a matching `[`",
            "scene.rib:6:13: error: unexpected extra argument to `Scale`: a number",
            "scene.rib:7:11: error: `[` is never closed",
            "scene.rib:8:13: error: expected a parameter name (a string) in `Surface`'s parameter list, found a number",
            "scene.rib:9:1: warning: unknown request `Frobnicate` skipped",
            "scene.rib:9:18: warning: `Shader` is not supported yet and is skipped",
            "scene.rib:10:33: error: parameter \"Cs\" has no value",
            "scene.rib:11:14: error: malformed number `12abc`",
        ]
    );
    // The good requests around the errors are all there; a parameter error keeps its request.
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(
        matches!(kinds[..], [K::WorldBegin, K::Surface(_), K::Polygon(_), K::Quadric { .. }, K::WorldEnd]),
        "{kinds:?}"
    );
    assert_eq!(parsed.errors().count(), 9);
}

#[test]
fn lexical_errors_are_located() {
    let parsed = parse("Sphere 1 -1 1 360\n  Color [1 @ 0]\nSurface \"unterminated\nDisk 0 1 360");
    assert_eq!(
        messages(&parsed),
        vec!["scene.rib:2:12: error: unexpected character `@`", "scene.rib:3:9: error: unterminated string",]
    );
    assert_eq!(parsed.requests.len(), 2);
    assert_eq!(parsed.requests[1].loc.to_string(), "scene.rib:4:1");
}

#[test]
fn read_archive_expands_in_place_relative_to_the_includer() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("parts");
    std::fs::create_dir(&sub).unwrap();
    std::fs::write(
        dir.path().join("main.rib"),
        "WorldBegin\nReadArchive \"parts/a.rib\"\nSurface \"s\" \"shine\" 2\nWorldEnd\n",
    )
    .unwrap();
    std::fs::write(sub.join("a.rib"), "Declare \"shine\" \"uniform float\"\nReadArchive \"b.rib\"\n").unwrap();
    std::fs::write(sub.join("b.rib"), "Sphere 1 -1 1 360\nBogus\n").unwrap();
    let parsed = rib::parse_file(dir.path().join("main.rib")).unwrap();
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(matches!(kinds[..], [K::WorldBegin, K::Declare { .. }, K::Quadric { .. }, K::Surface(_), K::WorldEnd]));
    // The declaration made in the archive holds after it, and locations name the archive.
    let K::Surface(s) = kinds[3] else { panic!() };
    assert_eq!(s.params.len(), 1);
    let sphere_loc = &parsed.requests[2].loc;
    assert_eq!(sphere_loc.file.as_ref(), sub.join("b.rib").as_path());
    assert_eq!((sphere_loc.line, sphere_loc.column), (1, 1));
    assert_eq!(parsed.diagnostics.len(), 1);
    assert!(parsed.diagnostics[0].to_string().ends_with("b.rib:2:1: warning: unknown request `Bogus` skipped"));
}

#[test]
fn archive_cycles_depth_and_missing_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.rib"), "ReadArchive \"b.rib\"\n").unwrap();
    std::fs::write(dir.path().join("b.rib"), "Identity\nReadArchive \"a.rib\"\n").unwrap();
    let parsed = rib::parse_file(dir.path().join("a.rib")).unwrap();
    assert_eq!(parsed.requests.len(), 1);
    assert_eq!(parsed.diagnostics.len(), 1);
    assert!(parsed.diagnostics[0].message.contains("includes itself"), "{:?}", parsed.diagnostics);
    assert!(parsed.diagnostics[0].to_string().contains("b.rib:2:1: error"));

    // A chain 40 archives long stops at the limit.
    for k in 0..40 {
        std::fs::write(dir.path().join(format!("c{k}.rib")), format!("Identity\nReadArchive \"c{}.rib\"\n", k + 1))
            .unwrap();
    }
    let parsed = rib::parse_file(dir.path().join("c0.rib")).unwrap();
    assert_eq!(parsed.requests.len(), rib::MAX_ARCHIVE_DEPTH + 1);
    assert_eq!(parsed.errors().count(), 1);
    assert!(parsed.diagnostics[0].message.contains("archives nest deeper than 32"));

    let missing = rib::parse_str("ReadArchive \"nope.rib\"", dir.path().join("x.rib"));
    assert_eq!(missing.diagnostics.len(), 1);
    assert!(missing.diagnostics[0].message.starts_with("cannot read archive"));
    let err = rib::parse_file(dir.path().join("absent.rib")).unwrap_err();
    assert!(err.to_string().contains("absent.rib: cannot read RIB file"), "{err}");
}

#[test]
fn shared_scene_ribs_parse_without_errors() {
    // Third-party scenes (see ../shared/scenes/README.md); skipped when there are none.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes");
    let mut files = Vec::new();
    let mut dirs = vec![root];
    while let Some(dir) = dirs.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rib")) {
                files.push(path);
            }
        }
    }
    for file in files {
        let parsed = rib::parse_file(&file).unwrap();
        assert!(!parsed.has_errors(), "{}: {:?}", file.display(), messages(&parsed));
        let mut diagnostics = Vec::new();
        for request in &parsed.requests {
            if let Some(mesh) = mesh_from_request(request, &mut diagnostics) {
                mesh.validate().unwrap();
            }
        }
        assert!(diagnostics.iter().all(|d| d.severity == Severity::Warning), "{diagnostics:?}");
    }
}

#[test]
fn example_ribs_parse_and_every_mesh_file_they_name_exists() {
    // The scenes under examples/ name meshes in ../shared/scenes, which a checkout may lack.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let shared = root.join("../shared/scenes").is_dir();
    let mut files = Vec::new();
    let mut dirs = vec![root.join("examples")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rib") {
                files.push(path);
            }
        }
    }
    assert!(files.iter().any(|f| f.ends_with("forest/forest.rib")), "{files:?}");
    for file in files {
        let parsed = rib::parse_file(&file).unwrap();
        assert!(!parsed.has_errors(), "{}: {:?}", file.display(), messages(&parsed));
        for request in &parsed.requests {
            if let (K::MeshArchive(mesh), true) = (&request.kind, shared) {
                assert!(mesh.is_file(), "{}: {} is missing", request.loc, mesh.display());
            }
        }
    }
}

/// Parses, then converts every request's geometry: neither may panic.
fn parse_and_mesh(bytes: &[u8]) {
    parse_and_mesh_with(bytes, rib::MeshOptions::default());
}

/// [`parse_and_mesh`] from `options`, which the stream's `TrimCurve`s and `Basis` change as a load
/// would. Points and curves make the triangles they were counted at.
fn parse_and_mesh_with(bytes: &[u8], mut options: rib::MeshOptions) {
    let parsed = rib::parse_bytes(bytes, Path::new("fuzz.rib"));
    let mut diagnostics = Vec::new();
    for request in &parsed.requests {
        // Trim curves trim the NuPatches after them, as when a scene loads.
        if let K::TrimCurve(t) = &request.kind {
            if let Ok(trim) = rib::trim::trim_from_request(t) {
                options.trim = trim.map(std::sync::Arc::new);
            }
        }
        if let K::Basis { u, ustep, v, vstep } = &request.kind {
            (options.u_basis, options.u_step, options.v_basis, options.v_step) = (u.clone(), *ustep, v.clone(), *vstep);
        }
        // What a load would refuse as too large is not built (the count itself must not panic).
        let counted = rib::request_triangles(request, &options);
        if counted > 100_000 {
            continue;
        }
        let mesh = mesh_from_request_with(request, &options, &mut diagnostics);
        if let Some(mesh) = &mesh {
            assert!(mesh.validate().is_ok());
        }
        if matches!(request.kind, K::Points(_) | K::Curves { .. }) {
            assert_eq!(counted, mesh.map_or(0, |m| m.triangle_count()), "{:?}", request.kind);
        }
    }
    for d in parsed.diagnostics.iter().chain(&diagnostics) {
        let _ = d.to_string();
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        parse_and_mesh(&bytes);
    }

    #[test]
    fn random_tokens_never_panic(tokens in proptest::collection::vec(prop_oneof![
        Just("Sphere".to_string()), Just("Polygon".to_string()), Just("PointsGeneralPolygons".to_string()),
        Just("PatchMesh".to_string()), Just("GeneralPolygon".to_string()), Just("Hyperboloid".to_string()),
        Just("\"P\"".to_string()), Just("\"Pw\"".to_string()), Just("\"Pz\"".to_string()), Just("\"N\"".to_string()),
        Just("\"facevarying float[2] st\"".to_string()), Just("\"uniform color Cs\"".to_string()),
        Just("\"bilinear\"".to_string()), Just("\"periodic\"".to_string()), Just("[".to_string()), Just("]".to_string()),
        Just("Torus".to_string()), Just("Basis".to_string()), Just("\"bicubic\"".to_string()),
        Just("\"b-spline\"".to_string()), Just("PointsPolygons".to_string()), Just("LightSource".to_string()),
        Just("SubdivisionMesh".to_string()), Just("HierarchicalSubdivisionMesh".to_string()), Just("\"catmull-clark\"".to_string()), Just("\"crease\"".to_string()),
        Just("\"hole\"".to_string()), Just("\"interpolateboundary\"".to_string()), Just("[]".to_string()),
        Just("ReadArchive".to_string()), Just("\"scene.rib\"".to_string()), Just("Declare".to_string()),
        (-3i32..8).prop_map(|n| n.to_string()), (-1_000_000i32..1_000_000).prop_map(|k| (k as f32 / 1e3).to_string()),
        Just("1e38".to_string()), Just("-0".to_string()), Just("NaN".to_string()),
        Just("NuPatch".to_string()), Just("TrimCurve".to_string()), Just("Geometry \"teapot\"".to_string()),
        Just("Points".to_string()), Just("Curves".to_string()), Just("\"linear\"".to_string()),
        Just("\"cubic\"".to_string()), Just("\"nonperiodic\"".to_string()), Just("\"width\"".to_string()),
        Just("\"constantwidth\"".to_string()), Just("\"uniform string type\" \"sphere\"".to_string()),
    ], 0..60)) {
        parse_and_mesh(tokens.join(" ").as_bytes());
    }

    /// NURBS patches and trim curves of random sizes, orders, knots (most of them sorted), ranges,
    /// weights and points: built or refused, never a panic.
    #[test]
    fn random_nurbs_never_panic(
        orders in (2i32..6, 2i32..6, 2i32..6),
        extra in (0i32..5, 0i32..5, 0i32..9),
        numbers in proptest::collection::vec(-2.0f32..3.0, 256),
        shuffled in any::<u8>(),
        fractions in proptest::collection::vec(0.0f32..0.6, 6),
        sense in any::<bool>(),
    ) {
        // Now and then an order of 1, which is refused.
        let (uorder, vorder, order) = if shuffled % 13 == 0 { (1, orders.1, orders.2) } else { orders };
        let (nu, nv, n) = (uorder + extra.0, vorder + extra.1, order + extra.2);
        let mut at = 0usize;
        let mut take = |count: i32| -> Vec<f32> {
            let out = (0..count.max(0) as usize).map(|k| numbers[(at + k) % numbers.len()]).collect();
            at += count.max(0) as usize;
            out
        };
        // Knots sorted unless the dice say otherwise, and a range from fractions of their span (now
        // and then past its end).
        let mut direction = |count: i32, order: i32, sort: bool, (a, b): (f32, f32)| {
            let mut k = take(count + order);
            if sort {
                k.sort_by(f32::total_cmp);
            }
            let p = (order - 1).max(0) as usize;
            let (lo, hi) = (k.get(p).copied().unwrap_or(0.0), k.get(count.max(0) as usize).copied().unwrap_or(1.0));
            let text = k.iter().map(ToString::to_string).collect::<Vec<_>>().join(" ");
            (text, lo + a * (hi - lo), lo + (a + b + 0.02) * (hi - lo))
        };
        let (uknots, umin, umax) = direction(nu, uorder, shuffled % 8 != 0, (fractions[0], fractions[1]));
        let (vknots, vmin, vmax) = direction(nv, vorder, shuffled % 7 != 0, (fractions[2], fractions[3]));
        let (tknots, tmin, tmax) = direction(n, order, shuffled % 5 != 0, (fractions[4], fractions[5]));
        let join = |v: Vec<f32>| v.iter().map(ToString::to_string).collect::<Vec<_>>().join(" ");
        // Trim points about the patch's range, weights mostly positive.
        let spread = |v: Vec<f32>, lo: f32, hi: f32| v.into_iter().map(|x| lo + (x + 2.0) / 5.0 * (hi - lo)).collect();
        let (tu, tv, tw) = (spread(take(n), umin, umax), spread(take(n), vmin, vmax), take(n).into_iter().map(|w| w + 1.5).collect());
        let points: Vec<f32> = take(4 * nu * nv).chunks(4).flat_map(|c| [c[0], c[1], c[2], c[3].abs() + 0.05 - 0.1 * f32::from(shuffled % 11 == 0)]).collect();
        let text = format!(
            "Attribute \"trimcurve\" \"sense\" \"{}\"\nTrimCurve [1] [{order}] [{tknots}] [{tmin}] [{tmax}] [{n}] [{}] [{}] [{}]\n\
             NuPatch {nu} {uorder} [{uknots}] {umin} {umax} {nv} {vorder} [{vknots}] {vmin} {vmax} \"Pw\" [{}] \"varying float q\" [{}]",
            if sense { "inside" } else { "outside" },
            join(tu),
            join(tv),
            join(tw),
            join(points),
            join(take((2 + nu - uorder).max(1) * (2 + nv - vorder).max(1))),
        );
        parse_and_mesh(text.as_bytes());
    }

    /// Points and curves of random types, wraps, bases, counts (right or a little off), widths of
    /// every class and sign, normals and colours, seen from random cameras through random
    /// transforms: built at the count they were counted at, or refused, never a panic.
    #[test]
    fn random_points_and_curves_never_panic(
        shape in (any::<bool>(), any::<bool>(), 0usize..5, 1i32..5),
        nvertices in proptest::collection::vec(-1i32..9, 0..5),
        off in (-1i32..2, 0usize..4, 0usize..4, 0usize..3),
        numbers in proptest::collection::vec(-3.0f32..3.0, 96),
        view in (any::<bool>(), -4.0f32..4.0, -4.0f32..4.0, proptest::collection::vec(-2.0f32..2.0, 9)),
    ) {
        let (cubic, periodic, basis, step) = shape;
        let (p_off, width_class, normal_class, colour_class) = off;
        let basis = ["bezier", "b-spline", "catmull-rom", "hermite", "power"][basis];
        let list = |n: usize, from: usize| {
            (0..n).map(|k| numbers[(from + k) % numbers.len()].to_string()).collect::<Vec<_>>().join(" ")
        };
        let total: i32 = nvertices.iter().map(|n| (*n).max(0)).sum();
        let points = (total + p_off).max(0) as usize;
        // Rough counts of each class: right for linear nonperiodic curves, near for the rest.
        let class_count = |class: usize| match class {
            0 => (1, "constant"),
            1 => (nvertices.len(), "uniform"),
            2 => (points, "vertex"),
            _ => (points.saturating_sub(1), "varying"),
        };
        let (wn, wc) = class_count(width_class);
        let (nn, nc) = class_count(normal_class);
        let (cn, cc) = class_count(colour_class);
        let counts = nvertices.iter().map(ToString::to_string).collect::<Vec<_>>().join(" ");
        let text = format!(
            "Basis \"{basis}\" {step} \"{basis}\" {step}\n\
             Curves \"{}\" [{counts}] \"{}\" \"P\" [{}] \"{wc} float width\" [{}] \"{nc} normal N\" [{}] \"{cc} color Cs\" [{}]\n\
             Points \"P\" [{}] \"{wc} float width\" [{}] \"{nc} normal N\" [{}] \"uniform string type\" \"{}\"\n",
            if cubic { "cubic" } else { "linear" },
            if periodic { "periodic" } else { "nonperiodic" },
            list(3 * points, 0),
            list(wn.max(1), 5),
            list(3 * nn.max(1), 11),
            list(3 * cn.max(1), 17),
            list(3 * points, 23),
            list(wn.max(1), 29),
            list(3 * nn.max(1), 31),
            if periodic { "sphere" } else { "disk" },
        );
        let (orthographic, x, y, m) = view;
        let transform = glam::Affine3A::from_mat3_translation(
            glam::Mat3::from_cols_slice(&m),
            glam::Vec3::new(x, y, 1.0),
        );
        let projection = if orthographic {
            rib::view::Projection::Orthographic { forward: glam::Vec3::new(x, 1.0, y), across: 2.0 }
        } else {
            rib::view::Projection::Perspective { eye: glam::Vec3::new(y, x, -3.0), across: 0.7 }
        };
        let options = rib::MeshOptions {
            view: rib::view::View { world_from_object: transform, projection },
            ..rib::MeshOptions::default()
        };
        parse_and_mesh_with(text.as_bytes(), options);
    }

    #[test]
    fn mutated_scene_never_panics(edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8)) {
        let mut bytes = EVERY_REQUEST.as_bytes().to_vec();
        for (at, byte, op) in edits {
            let i = at.index(bytes.len().max(1));
            match op {
                0 if i < bytes.len() => bytes[i] = byte,
                1 => bytes.insert(i.min(bytes.len()), byte),
                _ if i < bytes.len() => { bytes.remove(i); }
                _ => {}
            }
        }
        parse_and_mesh(&bytes);
    }
}

#[test]
fn argument_errors_name_the_request_and_the_argument() {
    let parsed = parse(
        "Declare \"k\" \"uniform colour\"\n\
         ConcatTransform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0]\n\
         Orientation \"sideways\"\n\
         PatchMesh \"bilinear\" 2 \"wrapped\" 2 \"nonperiodic\"\n\
         ObjectBegin\n\
         Format 640.5 480 1\n\
         Color 1 0 0\n\
         FrameBegin\n\
         PointsPolygons [3] [0 1 \"two\"]\n",
    );
    assert_eq!(
        messages(&parsed),
        vec![
            "scene.rib:1:13: error: unknown type `colour` (expected float, integer, color, point, vector, normal, \
             hpoint, string or matrix)",
            "scene.rib:2:1: error: `ConcatTransform` needs 16 numbers (4x4 matrix) but has 15",
            "scene.rib:3:13: error: unknown orientation \"sideways\" (expected \"outside\", \"inside\", \"lh\" or \"rh\")",
            "scene.rib:4:24: error: unknown wrap mode \"wrapped\" (expected \"periodic\" or \"nonperiodic\")",
            "scene.rib:5:1: error: `ObjectBegin` is missing its object handle",
            "scene.rib:6:8: error: `Format` expects an integer (xresolution): 640.5 is not an integer",
            "scene.rib:9:25: error: an array mixes numbers and strings",
        ]
    );
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert_eq!(kinds, vec![&K::Color([1.0, 0.0, 0.0]), &K::FrameBegin(None)]);
}

/// A polygon too large to ear-clip is cut into a fan, with a warning at its request saying so,
/// and that its holes are left out.
#[test]
fn a_polygon_too_large_to_ear_clip_is_fanned_with_a_warning() {
    let n = 5000;
    let ring = |r: f32, count: usize| -> Vec<String> {
        (0..count)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / count as f32;
                format!("{} {} 0", r * a.cos(), r * a.sin())
            })
            .collect()
    };
    let (outline, hole) = (ring(1.0, n), ring(0.5, 4));
    let text = format!("\nGeneralPolygon [{n} 4] \"P\" [{} {}]\n", outline.join(" "), hole.join(" "));
    let parsed = parse(&text);
    assert!(!parsed.has_errors(), "{:?}", messages(&parsed));
    let mut diagnostics = Vec::new();
    let mesh = mesh_from_request(&parsed.requests[0], &mut diagnostics).expect("a mesh");
    assert_eq!(mesh.triangle_count(), n - 2, "a fan of the outline");
    let warnings: Vec<String> = diagnostics.iter().map(ToString::to_string).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert!(w.starts_with("scene.rib:2:1: warning: 1 polygon of more than 4096 vertices"), "{w}");
    assert!(w.contains("the holes of 1 are not cut out"), "{w}");
    // Below the limit: ear-clipped, the hole cut out, nothing to say.
    let small = format!("GeneralPolygon [64 4] \"P\" [{} {}]\n", ring(1.0, 64).join(" "), hole.join(" "));
    let parsed = parse(&small);
    let mut diagnostics = Vec::new();
    let mesh = mesh_from_request(&parsed.requests[0], &mut diagnostics).expect("a mesh");
    assert_eq!(mesh.triangle_count(), 64 + 4, "the ring around its hole");
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
}

/// The requests of a parse without their locations, for comparing two encodings of one scene.
fn kinds_of(parsed: &RibParse) -> Vec<String> {
    let without_locations = |text: String| {
        text.split("loc: Location {")
            .enumerate()
            .map(|(i, part)| if i == 0 { part } else { part.split_once('}').map_or(part, |(_, rest)| rest) })
            .collect::<String>()
    };
    parsed.requests.iter().map(|r| without_locations(format!("{:?}", r.kind))).collect()
}

/// A small binary RIB writer (RISpec 3.2 appendix C.2), written from the specification's table.
#[derive(Default)]
struct BinaryRib {
    bytes: Vec<u8>,
    requests: Vec<String>,
}

impl BinaryRib {
    fn request(&mut self, name: &str) -> &mut Self {
        let code = match self.requests.iter().position(|r| r == name) {
            Some(code) => code,
            None => {
                self.requests.push(name.to_string());
                let code = self.requests.len() - 1;
                self.bytes.extend([0o314, code as u8]);
                self.string(name);
                code
            }
        };
        self.bytes.extend([0o246, code as u8]);
        self
    }

    fn string(&mut self, s: &str) -> &mut Self {
        if s.len() < 16 {
            self.bytes.push(0o220 + s.len() as u8);
        } else {
            self.bytes.extend([0o240 + 1, (s.len() >> 8) as u8, s.len() as u8]);
        }
        self.bytes.extend(s.as_bytes());
        self
    }

    fn int(&mut self, v: i32) -> &mut Self {
        if (0..256).contains(&v) {
            self.bytes.extend([0o200, v as u8]);
        } else {
            self.bytes.push(0o203);
            self.bytes.extend(v.to_be_bytes());
        }
        self
    }

    fn float(&mut self, v: f32) -> &mut Self {
        self.bytes.push(0o244);
        self.bytes.extend(v.to_be_bytes());
        self
    }

    fn double(&mut self, v: f64) -> &mut Self {
        self.bytes.push(0o245);
        self.bytes.extend(v.to_be_bytes());
        self
    }

    /// `bytes` of fixed point with the radix point `d` bytes from the right.
    fn fixed(&mut self, d: u8, bytes: &[u8]) -> &mut Self {
        self.bytes.push(0o200 + 4 * d + (bytes.len() as u8 - 1));
        self.bytes.extend(bytes);
        self
    }

    fn floats(&mut self, v: &[f32]) -> &mut Self {
        self.bytes.extend([0o311, (v.len() >> 8) as u8, v.len() as u8]);
        for x in v {
            self.bytes.extend(x.to_be_bytes());
        }
        self
    }

    fn define_string(&mut self, code: u8, s: &str) -> &mut Self {
        self.bytes.extend([0o315, code]);
        self.string(s)
    }

    fn defined_string(&mut self, code: u8) -> &mut Self {
        self.bytes.extend([0o317, code]);
        self
    }

    fn ascii(&mut self, text: &str) -> &mut Self {
        self.bytes.extend(text.as_bytes());
        self
    }
}

#[test]
fn binary_rib_reads_as_its_ascii_equivalent() {
    let ascii = "Format 320 240 1\n\
                 Projection \"perspective\" \"fov\" [45]\n\
                 Translate 0 -1.5 5.25\n\
                 WorldBegin\n\
                 Surface \"plastic\" \"Kd\" [0.5]\n\
                 Polygon \"P\" [0 0 0 1 0 0 1 1 0]\n\
                 Sphere 1 -1 1 360\n\
                 PointsPolygons [3] [0 1 2] \"P\" [0 0 0 1 0 0 1 1 0]\n\
                 Attribute \"identifier\" \"name\" [\"a rather long object name\"]\n\
                 WorldEnd\n";
    let mut b = BinaryRib::default();
    b.request("Format").int(320).int(240).int(1);
    b.request("Projection").string("perspective").string("fov").floats(&[45.0]);
    // 0 as a 1-byte integer, -1.5 as a float, 5.25 as fixed point 5 + 64/256.
    b.request("Translate").int(0).float(-1.5).fixed(1, &[5, 64]);
    b.request("WorldBegin");
    // The shader name by a defined string, its parameter as a double in an ASCII array.
    b.define_string(7, "plastic").request("Surface").defined_string(7).string("Kd").ascii("[").double(0.5).ascii("]");
    b.request("Polygon").string("P").floats(&[0., 0., 0., 1., 0., 0., 1., 1., 0.]);
    // ASCII and binary tokens mix in one stream.
    b.ascii("\nSphere 1 -1 1 360\n");
    b.request("PointsPolygons").ascii("[").int(3).ascii("]").ascii("[0 1 2]");
    b.string("P").floats(&[0., 0., 0., 1., 0., 0., 1., 1., 0.]);
    b.request("Attribute").string("identifier").string("name").ascii("[").string("a rather long object name");
    b.ascii("]").request("WorldEnd");
    let binary = rib::parse_bytes(&b.bytes, Path::new("scene.rib"));
    let text = parse(ascii);
    assert!(binary.diagnostics.is_empty(), "{:?}", binary.diagnostics);
    assert!(text.diagnostics.is_empty(), "{:?}", text.diagnostics);
    assert_eq!(kinds_of(&binary), kinds_of(&text));

    // A negative 4-byte integer is two's complement; an empty float array is `[]`.
    let mut b = BinaryRib::default();
    b.request("Sides").int(-2).request("Polygon").string("P").floats(&[]);
    let parsed = rib::parse_bytes(&b.bytes, Path::new("scene.rib"));
    assert!(matches!(parsed.requests[0].kind, K::Sides(-2)), "{:?}", parsed.requests);
}

#[test]
fn bad_binary_rib_is_reported_not_trusted() {
    let parse_binary = |bytes: &[u8]| rib::parse_bytes(bytes, Path::new("scene.rib"));
    // An undefined request code, a reserved byte, a truncated float, an array longer than the file.
    for (bytes, message) in [
        (&[0o246u8, 9][..], "undefined request"),
        (&[0o250u8][..], "reserved binary RIB byte 0xa8"),
        (&[0o244u8, 1, 2][..], "ends inside a token"),
        (&[0o313u8, 0xFF, 0xFF, 0xFF, 0xFF][..], "longer than the rest of the file"),
        (&[0o317u8, 3][..], "undefined string"),
    ] {
        let parsed = parse_binary(bytes);
        assert!(parsed.requests.is_empty());
        assert!(parsed.diagnostics.iter().any(|d| d.message.contains(message)), "{message}: {:?}", parsed.diagnostics);
    }
    // References to a long defined string cannot expand past the budget.
    let mut b = BinaryRib::default();
    let long = "x".repeat(60_000);
    b.define_string(1, &long).request("Surface");
    for _ in 0..(rib::lex::MAX_ENCODED_EXPANSION / long.len() + 2) {
        b.defined_string(1);
    }
    let parsed = parse_binary(&b.bytes);
    assert!(parsed.diagnostics.iter().any(|d| d.message.contains("expand to more than")), "{:?}", parsed.diagnostics);
}

#[test]
fn gzip_rib_is_read_by_its_content() {
    use std::io::Write;
    let text = "WorldBegin\nSphere 1 -1 1 360\nBogus\nWorldEnd\n";
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(text.as_bytes()).unwrap();
    let bytes = gz.finish().unwrap();
    let dir = tempfile::tempdir().unwrap();
    // No `.gz` name needed, and an archive may be compressed too.
    std::fs::write(dir.path().join("part.rib"), &bytes).unwrap();
    std::fs::write(dir.path().join("main.rib"), "ReadArchive \"part.rib\"\n").unwrap();
    let parsed = rib::parse_file(dir.path().join("main.rib")).unwrap();
    assert_eq!(kinds_of(&parsed), kinds_of(&parse(text)));
    // Locations are lines of the inflated text.
    assert_eq!(parsed.diagnostics.len(), 1);
    assert!(parsed.diagnostics[0].to_string().ends_with("part.rib:3:1: warning: unknown request `Bogus` skipped"));

    let mut truncated = bytes.clone();
    truncated.truncate(bytes.len() / 2);
    let parsed = rib::parse_bytes(&truncated, Path::new("cut.rib"));
    assert!(parsed.requests.is_empty());
    assert!(parsed.diagnostics[0].to_string().starts_with("cut.rib:1:1: error: cannot decompress gzip RIB"));
}

#[test]
fn inline_archives_are_kept_by_name_and_read_where_asked() {
    let parsed = parse(
        "ArchiveBegin \"ball\" \"string note\" \"unused\"\n\
         Sphere 1 -1 1 360\n\
         ArchiveEnd\n\
         WorldBegin\n\
         ReadArchive \"ball\"\n\
         Translate 1 0 0\n\
         ReadArchive \"ball\"\n\
         WorldEnd\n",
    );
    assert!(parsed.diagnostics.is_empty(), "{:?}", parsed.diagnostics);
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(matches!(kinds[..], [K::WorldBegin, K::Quadric { .. }, K::Translate(_), K::Quadric { .. }, K::WorldEnd]));
    // A copy keeps the location of the definition.
    assert_eq!(parsed.requests[3].loc.line, 2);

    let stray = parse("ArchiveEnd\nArchiveBegin \"open\"\nSphere 1 -1 1 360\nReadArchive \"open\"\n");
    assert_eq!(messages(&stray)[0], "scene.rib:1:1: error: `ArchiveEnd` without `ArchiveBegin`");
    // Read before its end, the archive was not yet defined: it is looked for as a file.
    assert!(messages(&stray)[1].contains("cannot read archive \"open\""), "{:?}", messages(&stray));
    assert!(messages(&stray)[2].contains("has no `ArchiveEnd`"), "{:?}", messages(&stray));
}

#[test]
fn a_refused_archive_begin_is_closed_by_its_own_archive_end() {
    // 33 nested definitions: the innermost is one too deep, refused, and its requests (a disk)
    // stay in the archive around it; its `ArchiveEnd` closes nothing, so each outer one closes
    // its own archive and the outermost, "a0", holds the nest.
    let depth = rib::MAX_ARCHIVE_DEPTH + 1;
    let mut text = String::new();
    for k in 0..depth {
        text += &format!("ArchiveBegin \"a{k}\"\n");
    }
    text += "Disk 0 1 360\n";
    text += &"ArchiveEnd\n".repeat(depth);
    text += "WorldBegin\nReadArchive \"a31\"\nWorldEnd\n";
    let parsed = parse(&text);
    assert_eq!(messages(&parsed).len(), 1, "{:?}", messages(&parsed));
    assert!(messages(&parsed)[0].contains("inline archives nest deeper than 32"), "{:?}", messages(&parsed));
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(matches!(kinds[..], [K::WorldBegin, K::Quadric { .. }, K::WorldEnd]), "{kinds:?}");

    // A malformed `ArchiveBegin` (no name) outside a good one: the good one's end closes it, the
    // next closes the refused block, whose sphere was read where it stands.
    let parsed = parse(
        "ArchiveBegin 5\nSphere 1 -1 1 360\nArchiveBegin \"inner\"\nDisk 0 1 360\nArchiveEnd\nArchiveEnd\n\
         WorldBegin\nReadArchive \"inner\"\nWorldEnd\n",
    );
    assert_eq!(messages(&parsed).len(), 1, "{:?}", messages(&parsed));
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(matches!(kinds[..], [K::Quadric { .. }, K::WorldBegin, K::Quadric { .. }, K::WorldEnd]), "{kinds:?}");
}

#[test]
fn inline_archives_cannot_expand_exponentially() {
    let mut text = String::from("ArchiveBegin \"a0\"\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]\nArchiveEnd\n");
    for k in 1..48 {
        text += &format!("ArchiveBegin \"a{k}\"\nReadArchive \"a{0}\"\nReadArchive \"a{0}\"\nArchiveEnd\n", k - 1);
    }
    text += "ReadArchive \"a47\"\n";
    let parsed = parse(&text);
    assert!(parsed.requests.len() < rib::INLINE_ARCHIVE_BUDGET, "{}", parsed.requests.len());
    assert!(messages(&parsed).iter().any(|m| m.contains("inline archives expand past their budget")));
}

#[test]
fn relative_archives_follow_the_archive_search_path_first() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["lib", "scene"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    std::fs::write(dir.path().join("lib/part.rib"), "Sphere 1 -1 1 360\n").unwrap();
    std::fs::write(dir.path().join("scene/part.rib"), "Disk 0 1 360\n").unwrap();
    let main = dir.path().join("scene/main.rib");
    std::fs::write(
        &main,
        "ReadArchive \"part.rib\"\nOption \"searchpath\" \"archive\" \"../lib:&\"\nReadArchive \"part.rib\"\n",
    )
    .unwrap();
    let parsed = rib::parse_file(&main).unwrap();
    assert!(parsed.diagnostics.is_empty(), "{:?}", parsed.diagnostics);
    let quadrics: Vec<&Quadric> = parsed
        .requests
        .iter()
        .filter_map(|r| if let K::Quadric { quadric, .. } = &r.kind { Some(quadric) } else { None })
        .collect();
    assert!(matches!(quadrics[..], [Quadric::Disk { .. }, Quadric::Sphere { .. }]), "{quadrics:?}");
}

#[test]
fn delayed_read_archive_reads_the_archive_and_programs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("part.rib"), "Sphere 1 -1 1 360\n").unwrap();
    let main = dir.path().join("main.rib");
    std::fs::write(
        &main,
        "WorldBegin\nProcedural \"DelayedReadArchive\" [\"part.rib\"] [-1 1 -1 1 -1 1]\n\
         Procedural \"RunProgram\" [\"make-geometry\" \"\"] [-1 1 -1 1 -1 1]\n\
         Procedural \"Other\" [] [-1 1 -1 1 -1 1]\nWorldEnd\n",
    )
    .unwrap();
    let parsed = rib::parse_file(&main).unwrap();
    let kinds: Vec<&K> = parsed.requests.iter().map(|r| &r.kind).collect();
    assert!(matches!(kinds[..], [K::WorldBegin, K::Quadric { .. }, K::WorldEnd]), "{kinds:?}");
    let messages = messages(&parsed);
    assert!(messages[0].contains("main.rib:3:1: warning: `Procedural \"RunProgram\"` runs code"), "{messages:?}");
    assert!(messages[1].contains("main.rib:4:1: error: unknown procedural \"Other\""), "{messages:?}");
    assert_eq!(parsed.diagnostics[0].severity, Severity::Omission);
}

/// Loaded through a camera, disks face the eye and ribbons its side of them, in world space, under
/// a perspective, an orthographic and RenderMan's default (orthographic) projection, and through
/// a rotation and a non-uniform scale.
#[test]
fn loaded_points_and_curves_face_the_camera() {
    use rtsl_runtime::api::Context;
    let geometry = [
        r#"Points "P" [0 0 0  1 1 0  -1 0 1  0.5 -0.5 -1] "constantwidth" 0.3"#,
        r#"Curves "cubic" [4] "nonperiodic" "P" [0 0 0  0.5 1 0  1 1 0.5  1.5 0 1] "constantwidth" 0.1"#,
    ];
    for projection in [r#"Projection "perspective" "fov" [40]"#, r#"Projection "orthographic""#, ""] {
        for (k, primitive) in geometry.iter().enumerate() {
            let text = format!(
                "Format 64 48 1\n{projection}\nRotate -30 1 0 0\nTranslate 0 -1 8\nWorldBegin\n\
                 Translate 1 0.5 0\nRotate 40 0 1 0\nScale 1 2 1\n{primitive}\nWorldEnd\n"
            );
            let mut rt = Context::new();
            let loaded = rtsl_runtime::rib::load::load_str(&mut rt, &text, "facing.rib").expect("loads");
            assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
            let world = rt.build_world().expect("a world");
            let camera = world.camera.world_from_camera;
            let mut faced = 0;
            for inst in &world.instances {
                let mesh = world.scene.mesh(rtsl_runtime::ObjectId(inst.object)).expect("a mesh");
                for t in 0..mesh.triangle_count() {
                    let [a, b, c] = mesh.corners(t).map(|p| inst.world_from_object.transform_point3(p));
                    let Some(n) = (b - a).cross(c - a).try_normalize() else { continue };
                    // A disk's triangles fan out from its centre, their first corner.
                    let from = if k == 0 { a } else { (a + b + c) / 3.0 };
                    let towards = if projection.contains("perspective") {
                        glam::Vec3::from(camera.translation) - from
                    } else {
                        -glam::Vec3::from(camera.matrix3.z_axis)
                    };
                    let cosine = n.dot(towards.normalize());
                    // A disk exactly; a ribbon turns only about its curve.
                    assert!(if k == 0 { cosine > 0.9999 } else { cosine > 0.2 }, "{projection} {primitive}: {cosine}");
                    faced += 1;
                }
            }
            assert!(faced > 0, "{projection} {primitive}");
        }
    }
}

/// The colours of a parse's `Color`, `Opacity` and `Cs` values, in order.
fn colours(parsed: &RibParse) -> Vec<Vec<f32>> {
    let mut out = Vec::new();
    for r in &parsed.requests {
        match &r.kind {
            K::Color(c) | K::Opacity(c) => out.push(c.to_vec()),
            K::Polygon(params) => {
                out.extend(params.iter().filter(|p| p.name == "Cs").filter_map(|p| p.floats().map(<[f32]>::to_vec)))
            }
            _ => {}
        }
    }
    out
}

#[test]
fn color_samples_turn_colours_into_rgb_as_they_are_read() {
    let close = |a: &[f32], b: &[f32]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
    // One sample a colour, which nRGB spreads into RGB; a colour parameter's values one sample each.
    let parsed = parse(
        "ColorSamples 1 [0.2 0.5 0.8] [1 1 1]\n\
         Color [0.5] Opacity 1\n\
         Polygon \"P\" [0 0 0 1 0 0 0 1 0] \"varying color Cs\" [1 0.5 0.25]\n",
    );
    assert!(parsed.diagnostics.is_empty(), "{:?}", messages(&parsed));
    let got = colours(&parsed);
    let want: [&[f32]; 3] = [&[0.1, 0.25, 0.4], &[0.2, 0.5, 0.8], &[0.2, 0.5, 0.8, 0.1, 0.25, 0.4, 0.05, 0.125, 0.2]];
    assert_eq!(got.len(), 3, "{got:?}");
    for (g, w) in got.iter().zip(want) {
        assert!(close(g, w), "{got:?}");
    }
    // Four samples: the spectrum's halves, red and blue; a ColorSamples in a frame holds there.
    let parsed = parse(
        "FrameBegin 1 ColorSamples 4 [1 0 0  1 0 0  0 0 1  0 0 1] [1 1 0 0  0 0 0 0  0 0 1 1]\n\
         Color 0.25 0.25 [0.5 0.5] FrameEnd Color [0.1 0.2 0.3]\n",
    );
    assert!(parsed.diagnostics.is_empty(), "{:?}", messages(&parsed));
    let got = colours(&parsed);
    assert!(close(&got[0], &[0.5, 0.0, 1.0]) && close(&got[1], &[0.1, 0.2, 0.3]), "{got:?}");
    // RGB written as three samples with identity matrices is RGB.
    let parsed = parse("ColorSamples 3 [1 0 0 0 1 0 0 0 1] [1 0 0 0 1 0 0 0 1] Color [0.1 0.2 0.3]");
    assert!(close(&colours(&parsed)[0], &[0.1, 0.2, 0.3]));
}

#[test]
fn malformed_color_samples_are_errors_and_change_nothing() {
    let parsed = parse(
        "ColorSamples 2 [1 0 0] [1 1 1 1 1 1]\n\
         ColorSamples 0 [] []\n\
         ColorSamples 2 [1 0 0 0 1 0] [1 1 1 1 1 1]\n\
         Color [0.5 0.25]\n\
         Polygon \"P\" [0 0 0 1 0 0 0 1 0] \"Cs\" [1 0 0]\n",
    );
    assert_eq!(
        messages(&parsed),
        vec![
            "scene.rib:1:1: error: `ColorSamples 2` needs a nRGB matrix of 6 numbers, not 3; colours stay as they were",
            "scene.rib:2:1: error: `ColorSamples` needs at least 1 sample, not 0; colours stay as they were",
            "scene.rib:5:38: error: parameter \"Cs\" (varying color): 3 numbers given, which is not a multiple of 2 \
             (numbers per value: `ColorSamples` 2 a colour)",
        ]
    );
    // The third took: two samples, the first red, the second green.
    assert_eq!(colours(&parsed), vec![vec![0.5, 0.25, 0.0]]);
}

#[test]
fn s_or_t_alone_replaces_that_coordinate_of_a_surface_s_own() {
    // RISpec lists "s" and "t" as variables of their own: given alone, one replaces that
    // texture coordinate of the surface's (its parameters through TextureCoordinates), and the
    // other stays. The surface's parameters (u, v) stay as they were; texture coordinates that
    // differ from them are an `st` attribute.
    let mesh = |text: &str| {
        let parsed = parse(text);
        assert!(!parsed.has_errors(), "{:?}", messages(&parsed));
        let mut diagnostics = Vec::new();
        let mesh = mesh_from_request(&parsed.requests[0], &mut diagnostics).expect("a mesh");
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let parameters = mesh.uvs.clone().expect("surface parameters");
        let st = mesh
            .attributes
            .iter()
            .find(|a| a.name == "st")
            .map_or_else(|| parameters.clone(), |st| st.data.chunks_exact(2).map(glam::Vec2::from_slice).collect());
        (parameters, st)
    };
    let square = "Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]";
    let (parameters, own) = mesh(square);
    let (with_s_parameters, with_s) = mesh(&format!("{square} \"s\" [0.2 0.2 0.2 0.2]\n"));
    let (with_t_parameters, with_t) = mesh(&format!("{square} \"t\" [0.7 0.7 0.7 0.7]\n"));
    assert_eq!((&with_s_parameters, &with_t_parameters), (&parameters, &parameters));
    assert!(own.iter().any(|uv| uv.x != 0.2) && own.iter().any(|uv| uv.y != 0.7), "{own:?}");
    for ((own, s), t) in own.iter().zip(&with_s).zip(&with_t) {
        assert_eq!((s.x, s.y), (0.2, own.y));
        assert_eq!((t.x, t.y), (own.x, 0.7));
    }
    let (parameters, sphere) = mesh("Sphere 1 -1 1 360 \"t\" [0.1 0.2 0.3 0.4]\n");
    assert!(sphere.iter().all(|uv| (0.1..=0.4).contains(&uv.y)), "{sphere:?}");
    assert!(parameters.iter().any(|uv| uv.y == 0.0) && parameters.iter().any(|uv| uv.y == 1.0), "{parameters:?}");
}

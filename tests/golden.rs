//! Golden images: small renders of the default scene and of every library shader, compared with the
//! references in `tests/golden/` within a tolerance.
//!
//! Regenerate the references (after a deliberate change, and look at them) with
//!
//! ```sh
//! RTSL_BLESS=1 cargo test --release --test golden
//! ```
//!
//! A failing comparison writes `NAME.actual.png` and `NAME.diff.png` (the difference, scaled 8x)
//! next to the reference. Tolerance: the images may differ by at most 0.02 mean absolute error per
//! channel and in at most 1% of pixels by more than 0.1 (floating-point code generation differs a
//! little between CPUs; an edit that changes a shader's look changes far more).

use rtsl_runtime::api::Context;
use rtsl_runtime::image_io::{diff_image, read_image, write_image, Transfer, WriteOptions};
use rtsl_runtime::render::render_frame;
use rtsl_runtime::rib::load::load_str;
use std::path::{Path, PathBuf};

const W: u32 = 128;
const H: u32 = 96;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("golden")
}

fn render_rib(name: &str, rib: &str) -> Vec<f32> {
    let mut rt = Context::new();
    let file = golden_dir().join(format!("{name}.rib"));
    // The references hold sRGB-encoded images of scenes whose textures are decoded so.
    let rib = format!("Option \"image\" \"string transfer\" [\"srgb\"]\n{rib}");
    let loaded = load_str(&mut rt, &rib, &file).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(loaded.warnings.is_empty(), "{name}: {:?}", loaded.warnings);
    rt.options.width = W;
    rt.options.height = H;
    let world = rt.build_world().unwrap_or_else(|e| panic!("{name}: {e}"));
    let (fb, _) = render_frame(&world, None);
    let warnings = world.textures.take_warnings();
    assert!(warnings.is_empty(), "{name}: {warnings:?}");
    fb.rgba
}

/// Compares with (or, under RTSL_BLESS, writes) `tests/golden/NAME.png`.
fn check(name: &str, rgba: &[f32]) -> Result<(), String> {
    let reference = golden_dir().join(format!("{name}.png"));
    let (w, h) = (W as usize, H as usize);
    if std::env::var_os("RTSL_BLESS").is_some() {
        write_image(&reference, w, h, rgba, &WriteOptions::default()).map_err(|e| e.to_string())?;
        return Ok(());
    }
    // Compare what `rtsl render` would write: sRGB-encoded, 8-bit quantised.
    let actual_path = golden_dir().join(format!("{name}.actual.png"));
    let tmp = std::env::temp_dir().join(format!("rtsl-golden-{}-{name}.png", std::process::id()));
    write_image(&tmp, w, h, rgba, &WriteOptions::default()).map_err(|e| e.to_string())?;
    let actual = read_image(&tmp).map_err(|e| e.to_string())?;
    let _ = std::fs::remove_file(&tmp);
    let expected =
        read_image(&reference).map_err(|e| format!("{name}: no reference ({e}); bless with RTSL_BLESS=1"))?;
    let d = diff_image(&expected, &actual).map_err(|e| e.to_string())?;
    let far = d.differing_pixels(0.1);
    if d.mean_abs > 0.02 || far > w * h / 100 {
        // `actual` holds the values stored, encoded already.
        let stored = WriteOptions { transfer: Transfer::Linear, ..WriteOptions::default() };
        let _ = write_image(&actual_path, w, h, &actual.pixels, &stored);
        let diff = d.difference_image(8.0);
        let _ =
            write_image(golden_dir().join(format!("{name}.diff.png")), w, h, &diff.pixels, &WriteOptions::default());
        return Err(format!(
            "{name}: mean abs {:.4}, {far} pixels off by > 0.1 (see {})",
            d.mean_abs,
            actual_path.display()
        ));
    }
    Ok(())
}

/// A sphere with the shader under test on a plastic floor, lit by a shadowed point light and a dim
/// ambient light: `rtsl preview`'s scene.
fn surface_scene(surface: &str) -> String {
    rtsl::preview::scene(surface, W, H, 2)
}

fn light_scene(light: &str) -> String {
    format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [30]
Rotate -20 1 0 0
Translate 0 -1.8 6
WorldBegin
  Attribute "light" "shadows" "on"
  {light}
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Translate 0 1 0
    Rotate -90 1 0 0
    Color [.8 .3 .2]
    Sphere 1 -1 1 360
  AttributeEnd
WorldEnd
"#
    )
}

fn surfaces() -> Vec<(&'static str, String)> {
    let grid = golden_dir().join("textures").join("grid.png").display().to_string();
    [
        ("constant", "Surface \"constant\" Color [.2 .5 .9]".to_string()),
        ("matte", "Surface \"matte\"".into()),
        ("plastic", "Surface \"plastic\" Color [.9 .3 .2]".into()),
        ("metal", "Surface \"metal\" Color [.9 .7 .3]".into()),
        ("shinymetal", "Surface \"shinymetal\"".into()),
        ("paintedplastic", format!("Surface \"paintedplastic\" \"texturename\" \"{grid}\"")),
        ("texmap", format!("Surface \"texmap\" \"texturename\" \"{grid}\"")),
        ("wood", "Surface \"wood\"".into()),
        ("marble", "Surface \"marble\"".into()),
        ("granite", "Surface \"granite\"".into()),
        ("checker", "Surface \"checker\" \"frequency\" [6]".into()),
        ("brick", "Surface \"brick\"".into()),
        ("mirror", "Surface \"mirror\"".into()),
        ("glass", "Surface \"glass\"".into()),
        ("bumpymirror", "Surface \"bumpymirror\"".into()),
        (
            "material",
            format!(
                "Surface \"material\" \"diffusecolor\" [.8 .8 .8] \"specularcolor\" [.5 .5 .5] \"shininess\" [.4] \
                 \"transparency\" [.3] \"texturename\" \"{grid}\""
            ),
        ),
    ]
    .into_iter()
    .collect()
}

#[test]
fn every_library_surface_shader_matches_its_reference() {
    let failures: Vec<String> = surfaces()
        .iter()
        .filter_map(|(name, s)| check(&format!("surface_{name}"), &render_rib(name, &surface_scene(s))).err())
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_library_displacement_shader_matches_its_reference() {
    // `bumpy` over the grid texture: the grid's lines raise ridges on the plastic sphere (as bump
    // mapping: the sphere's outline stays round).
    let grid = golden_dir().join("textures").join("grid.png").display().to_string();
    let surface = format!(
        "Surface \"plastic\" Color [.9 .3 .2] Displacement \"bumpy\" \"amplitude\" [.02] \"texturename\" \"{grid}\""
    );
    if let Err(e) = check("displacement_bumpy", &render_rib("bumpy", &surface_scene(&surface))) {
        panic!("{e}");
    }
}

#[test]
fn every_library_light_shader_matches_its_reference() {
    let lights = [
        ("pointlight", "LightSource \"pointlight\" 1 \"intensity\" [25] \"from\" [2 4 -3]"),
        ("distantlight", "LightSource \"distantlight\" 1 \"intensity\" [1.2] \"from\" [1 3 -2] \"to\" [0 0 0]"),
        (
            "spotlight",
            "LightSource \"spotlight\" 1 \"intensity\" [30] \"from\" [0 5 -1] \"to\" [0 0 0] \"coneangle\" [.35]",
        ),
        ("ambientlight", "LightSource \"ambientlight\" 1 \"intensity\" [0.6]"),
        (
            "vrmlpointlight",
            "LightSource \"vrmlpointlight\" 1 \"intensity\" [.9] \"from\" [2 4 -3] \"linearattenuation\" [.1]",
        ),
        (
            "vrmlspotlight",
            "LightSource \"vrmlspotlight\" 1 \"from\" [0 5 -1] \"to\" [0 0 0] \"beamwidth\" [.2] \"cutoffangle\" [.45]",
        ),
        (
            "arealight",
            "AttributeBegin AreaLightSource \"arealight\" 1 \"intensity\" [12] \
             Translate 0 3.5 0 Rotate 90 1 0 0 Disk 0 1 360 AttributeEnd",
        ),
    ];
    let failures: Vec<String> = lights
        .iter()
        .filter_map(|(name, l)| check(&format!("light_{name}"), &render_rib(name, &light_scene(l))).err())
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_library_pixel_shader_matches_its_reference() {
    let pixels = [
        ("background", "Imager \"background\" \"background\" [.2 .3 .6]"),
        ("exposure", "Pixel \"exposure\" \"stops\" [1]"),
        ("gamma", "Pixel \"gamma\""),
        ("tonemap_reinhard", "Pixel \"tonemap\" \"exposure\" [4]"),
        ("tonemap_filmic", "Pixel \"tonemap\" \"curve\" \"filmic\" \"exposure\" [4]"),
        ("vignette", "Pixel \"vignette\" \"strength\" [.8]"),
    ];
    let light = "LightSource \"pointlight\" 1 \"intensity\" [25] \"from\" [2 4 -3]";
    let failures: Vec<String> = pixels
        .iter()
        .filter_map(|(name, pixel)| {
            let rib = light_scene(light).replacen("WorldBegin", &format!("{pixel}\nWorldBegin"), 1);
            check(&format!("pixel_{name}"), &render_rib(name, &rib)).err()
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_library_scene_matches_its_reference() {
    let rib = include_str!("../examples/scenes/library.rib");
    check("library_scene", &render_rib("library", rib)).unwrap_or_else(|e| panic!("{e}"));
}

fn render_office(rt: &mut Context) -> Vec<f32> {
    rt.options.width = W;
    rt.options.height = H;
    let world = rt.build_world().expect("the office builds");
    let (fb, report) = render_frame(&world, None);
    let warnings = world.textures.take_warnings();
    assert!(warnings.is_empty(), "{warnings:?}");
    // The frame's shading time is split by shader type and by shader.
    use rtsl_compiler::interface::ShaderKind;
    for kind in [ShaderKind::Surface, ShaderKind::Light, ShaderKind::Lightfield] {
        assert!(report.shader_time(kind) > std::time::Duration::ZERO, "no time in {kind:?} shaders");
    }
    for name in ["volumegrid", "twoplane", "bumpymirror", "wood", "marble", "spotlight"] {
        assert!(report.by_shader.iter().any(|(n, _, t)| n == name && !t.is_zero()), "{name}: {:?}", report.by_shader);
    }
    let total: std::time::Duration = report.by_kind.iter().sum();
    assert!(total <= report.shading + std::time::Duration::from_millis(1), "{total:?} > {:?}", report.shading);
    fb.rgba
}

#[test]
fn the_default_scene_is_the_office_and_matches_its_reference() {
    // Every shader type in one frame: surfaces (wood, marble, the bump-mapped mirror), the volume
    // data set, the light field, three lights and an ambient one.
    let mut embedded = Context::new();
    let loaded = rtsl::default_scene::load(&mut embedded).expect("the embedded office loads");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let rgba = render_office(&mut embedded);
    check("office", &rgba).unwrap_or_else(|e| panic!("{e}"));
    // The embedded copy is the scene and data of examples/office/.
    let mut from_files = Context::new();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/office/office.rib");
    rtsl_runtime::rib::load::load_file(&mut from_files, &path).expect("office.rib loads");
    assert_eq!(render_office(&mut from_files), rgba, "the files and the embedded copy differ");
}

#[test]
fn every_library_camera_shader_matches_its_reference() {
    let cameras = [
        ("pinhole", "Camera \"pinhole\""),
        ("thinlens", "Camera \"thinlens\" \"fstop\" [0.4] \"focallength\" [0.5] \"focaldistance\" [6]"),
        ("fisheye", "Camera \"fisheye\" \"fov\" [200]"),
        ("cylindrical", "Camera \"cylindrical\" \"hfov\" [240] \"vfov\" [110]"),
        ("parabolic", "Camera \"parabolic\" \"scale\" [1.5]"),
    ];
    let light = "LightSource \"pointlight\" 1 \"intensity\" [25] \"from\" [2 4 -3]";
    let failures: Vec<String> = cameras
        .iter()
        .filter_map(|(name, camera)| {
            let rib = light_scene(light).replacen("Projection", &format!("{camera}\nProjection"), 1);
            check(&format!("camera_{name}"), &render_rib(name, &rib)).err()
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn motion_blur_matches_its_reference() {
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 4 4
Shutter 0 1
Projection "perspective" "fov" [35]
Rotate -15 1 0 0
Translate 0 -1 5
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "pointlight" 1 "intensity" [25] "from" [2 4 -3]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    MotionBegin [0 1]
      Translate -0.8 0.5 0
      Translate 0.8 0.5 0
    MotionEnd
    Color [.8 .3 .2]
    Sphere 0.45 -0.45 0.45 360
  AttributeEnd
WorldEnd
"#
    );
    check("motion_blur", &render_rib("motion_blur", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// A rational NURBS wall (a third of a cylinder, one rational quadratic span) with an elliptical
/// hole trimmed out of it, beside RenderMan's teapot (z up, so turned to stand on the y-up floor).
#[test]
fn nurbs_and_the_teapot_match_their_reference() {
    // The arc from 30 to 150 degrees about (-1.1, 0.3) in the floor's plane: its middle control
    // point where the ends' tangents meet (twice the radius out), of weight cos 60 = 0.5; it
    // rises from y = 0 to 1.6.
    let (cx, cz, r) = (-1.1, 0.3, 1.2);
    let at = |degrees: f64, distance: f64| {
        let a = degrees.to_radians();
        (cx + distance * a.cos(), cz + distance * a.sin())
    };
    let arc = [(at(30.0, r), 1.0), (at(90.0, 2.0 * r), 0.5), (at(150.0, r), 1.0)];
    let mut pw = Vec::new();
    for y in [0.0, 1.6] {
        for ((x, z), w) in arc {
            pw.extend([x * w, y * w, z * w, w]);
        }
    }
    // An ellipse in parameter space, about as wide as high on the wall: the unit circle's rational
    // quadratic (9 points, weights 1 and cos 45) scaled.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let circle = [
        (1.0, 0.0, 1.0),
        (1.0, 1.0, s),
        (0.0, 1.0, 1.0),
        (-1.0, 1.0, s),
        (-1.0, 0.0, 1.0),
        (-1.0, -1.0, s),
        (0.0, -1.0, 1.0),
        (1.0, -1.0, s),
        (1.0, 0.0, 1.0),
    ];
    let (mut u, mut v, mut w) = (Vec::new(), Vec::new(), Vec::new());
    for (x, y, weight) in circle {
        u.push((0.5 + 0.17 * x) * weight);
        v.push((0.55 + 0.3 * y) * weight);
        w.push(weight);
    }
    let list = |xs: &[f64]| xs.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(" ");
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [34]
Rotate -14 1 0 0
Translate 0 -2.2 6
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "pointlight" 1 "intensity" [25] "from" [2 4 -3]
  LightSource "ambientlight" 2 "intensity" [0.1]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Color [.3 .5 .9]
    TrimCurve [1] [3] [0 0 0 .25 .25 .5 .5 .75 .75 1 1 1] [0] [1] [9] [{}] [{}] [{}]
    NuPatch 3 3 [0 0 0 1 1 1] 0 1 2 2 [0 0 1 1] 0 1 "Pw" [{}]
  AttributeEnd
  AttributeBegin
    Color [.8 .3 .2]
    Translate 1 0 -0.3
    Rotate -90 1 0 0
    Rotate 20 0 0 1
    Scale .4 .4 .4
    Geometry "teapot"
  AttributeEnd
WorldEnd
"#,
        list(&u),
        list(&v),
        list(&w),
        list(&pw)
    );
    check("nupatch_teapot", &render_rib("nupatch_teapot", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// The data set shipped with the examples (`docs/volumes.md`).
fn neghip_grid() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/office/data/neghip32.grid").display().to_string()
}

/// The box -1..1 with counter-clockwise faces seen from outside (outward normals).
const BOX: &str = r#"
    Polygon "P" [1 -1 -1  1 1 -1  1 1 1  1 -1 1]
    Polygon "P" [-1 -1 -1  -1 -1 1  -1 1 1  -1 1 -1]
    Polygon "P" [-1 1 -1  -1 1 1  1 1 1  1 1 -1]
    Polygon "P" [-1 -1 -1  1 -1 -1  1 -1 1  -1 -1 1]
    Polygon "P" [-1 -1 1  1 -1 1  1 1 1  -1 1 1]
    Polygon "P" [-1 -1 -1  -1 1 -1  1 1 -1  1 -1 -1]
"#;

#[test]
fn volume_shaders_match_their_references() {
    let light = "LightSource \"pointlight\" 1 \"intensity\" [25] \"from\" [2 4 -3]";
    // Fog over the lit scene, with a wall behind so that every ray has a segment to fog.
    let fog = light_scene(light).replacen(
        "WorldBegin",
        "WorldBegin\n  Atmosphere \"fog\" \"distance\" [6] \"background\" [.6 .65 .75]\n  \
         AttributeBegin Surface \"matte\" Polygon \"P\" [-9 -1 5  9 -1 5  9 9 5  -9 9 5] AttributeEnd",
        1,
    );
    // A glass ball with a red-absorbing interior before a bright wall: refracted `trace` rays
    // cross it inside.
    let interior =
        surface_scene("Surface \"glass\"\n    Interior \"medium\" \"density\" [1] \"absorption\" [1 .35 .1]").replacen(
            "WorldBegin",
            "WorldBegin\n  AttributeBegin Surface \"constant\" Color [.9 .85 .8] \
         Polygon \"P\" [-9 0 3  9 0 3  9 9 3  -9 9 3] AttributeEnd",
            1,
        );
    // The data set on a box above the floor, its transparent shadow cast by a point light.
    let grid = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [40]
Rotate -15 1 0 0
Translate 0 -1.6 7
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.1]
  LightSource "pointlight" 2 "intensity" [30] "from" [1 6 -1]
  AttributeBegin
    Surface "plastic"
    Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeEnd
  AttributeBegin
    Translate 0 1.4 0
    Attribute "shade" "transmissionhitmode" "shader"
    Surface "volumegrid" "gridname" "{}" "density" [10] "threshold" [0.55]
    {BOX}
  AttributeEnd
WorldEnd
"#,
        neghip_grid()
    );
    let failures: Vec<String> = [("volume_fog", fog), ("volume_interior", interior), ("volume_grid", grid)]
        .iter()
        .filter_map(|(name, rib)| check(name, &render_rib(name, rib)).err())
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_lightfield_shader_matches_its_reference() {
    // The office's light field (a cow captured from examples/office/lightfield_subject.rib) on its
    // rectangle above a plastic floor, seen from off its axis: the floor shows where it is empty.
    let atlas = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/office/data/spot_lightfield.png");
    let light = "LightSource \"pointlight\" 1 \"intensity\" [25] \"from\" [2 4 -3]";
    let rib = light_scene(light).replacen(
        "WorldBegin",
        &format!(
            "WorldBegin\n  AttributeBegin Translate 0.5 0.95 -1.8 Rotate -20 0 1 0 Scale 0.9 0.9 0.9 \
             Attribute \"shade\" \"transmissionhitmode\" \"shader\" Surface \"twoplane\" \"lightfield\" \"{}\" \"nviews\" [10] \"viewsize\" [40] \"distance\" [0.8] \
             Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] AttributeEnd",
            atlas.display()
        ),
        1,
    );
    check("lightfield_twoplane", &render_rib("lightfield", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn subdivision_meshes_match_their_reference() {
    // The same cube twice as a Catmull-Clark subdivision mesh: on the left smooth (a rounded
    // blob), on the right with its top edges infinitely sharp, its upright edges semi-sharp (1.5)
    // and one bottom corner sharp.
    let cube = |tags: &str| {
        format!(
            r#"SubdivisionMesh "catmull-clark" [4 4 4 4 4 4] [0 3 2 1  4 5 6 7  0 1 5 4  1 2 6 5  2 3 7 6  3 0 4 7]
      {tags}
      "P" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1]"#
        )
    };
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [30]
Rotate -20 1 0 0
Translate 0 -2.8 6.5
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.15]
  LightSource "pointlight" 2 "intensity" [25] "from" [2 4 -3]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Color [.8 .3 .2]
    Translate -1.2 0.76 0
    Rotate 30 0 1 0
    Scale 0.9 0.9 0.9
    {}
  AttributeEnd
  AttributeBegin
    Color [.2 .45 .8]
    Translate 1.2 0.85 0
    Rotate -30 0 1 0
    Scale 0.9 0.9 0.9
    Rotate -90 1 0 0
    {}
  AttributeEnd
WorldEnd
"#,
        cube(""),
        cube(
            r#"["crease" "crease" "crease" "crease" "crease" "corner"] [5 1 2 1 2 1 2 1 2 1 1 1]
      [4 5 6 7 4  0 4  1 5  2 6  3 7  1] [10 1.5 1.5 1.5 1.5 10]"#
        )
    );
    check("subdivision_mesh", &render_rib("subdivision_mesh", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// A VRML 97 scene: the four primitives, an extrusion and a face set with per-vertex colours,
/// a PixelTexture repeated by a TextureTransform, a point, a spot and a directional light (one
/// with an ambient part), a Viewpoint and a Background (`docs/vrml.md`).
const VRML_SHAPES: &str = r#"#VRML V2.0 utf8
NavigationInfo { headlight FALSE }
Background { skyColor 0.15 0.2 0.35 }
Viewpoint { position 0 1.6 7 orientation 1 0 0 -0.22 fieldOfView 0.7 }
PointLight { location 3 4 4 intensity 0.8 ambientIntensity 0.25 }
SpotLight { location -3 5 3 direction 0.5 -1 -0.6 cutOffAngle 0.6 beamWidth 0.35 color 1 0.9 0.7 }
DirectionalLight { direction 0.2 -1 -0.4 intensity 0.25 }
DEF Floor Transform { translation 0 -1.1 0 children Shape {
  appearance Appearance { material Material { diffuseColor 0.7 0.7 0.7 } }
  geometry Box { size 9 0.2 6 } } }
Transform { translation -2.4 0 0 children Shape {
  appearance Appearance { material Material { diffuseColor 0.9 0.2 0.1 specularColor 0.6 0.6 0.6 shininess 0.4 } }
  geometry Sphere { radius 0.9 } } }
Transform { translation -0.6 -0.1 0 rotation 0 1 0 0.6 children Shape {
  appearance Appearance {
    material Material { }
    texture PixelTexture { image 2 2 3 0xF0F0F0 0x3050A0 0x3050A0 0xF0F0F0 }
    textureTransform TextureTransform { scale 6 3 } }
  geometry Cylinder { radius 0.6 height 1.8 } } }
Transform { translation 1.1 -0.2 0.2 children Shape {
  appearance Appearance { material Material { diffuseColor 0.2 0.8 0.3 emissiveColor 0.05 0.1 0.05 } }
  geometry Cone { bottomRadius 0.7 height 1.6 } } }
Transform { translation 2.6 -1 -0.5 children Shape {
  appearance Appearance { material Material { diffuseColor 0.9 0.7 0.2 specularColor 0.3 0.3 0.3 } }
  geometry Extrusion {
    crossSection [ 0.3 0, 0.21 0.21, 0 0.3, -0.21 0.21, -0.3 0, -0.21 -0.21, 0 -0.3, 0.21 -0.21, 0.3 0 ]
    spine [ 0 0 0, 0 0.6 0, 0.3 1.2 0, 0.9 1.5 0 ]
    scale [ 1 1, 0.9 0.9, 0.7 0.7, 0.5 0.5 ]
    creaseAngle 1.6 } } }
Transform { translation 0 -0.99 2 children Shape {
  geometry IndexedFaceSet {
    coord Coordinate { point [ -1 0 0, 0 0 -0.8, 1 0 0, 0.3 0 0.2, 0 0 0.9, -0.3 0 0.2 ] }
    coordIndex [ 0 5 4 3 2 1 -1 ]
    color Color { color [ 1 0 0, 1 1 0, 0 1 0, 0 1 1, 0 0 1, 1 0 1 ] } } } }
"#;

#[test]
fn vrml_shapes_match_their_reference() {
    let mut rt = Context::new();
    let file = golden_dir().join("vrml_shapes.wrl");
    let scene = rtsl_runtime::vrml::build_str(&mut rt, VRML_SHAPES, &file).unwrap_or_else(|e| panic!("{e}"));
    let omitted: Vec<String> = scene
        .warnings
        .iter()
        .filter(|w| w.severity != rtsl_runtime::rib::Severity::Warning)
        .map(|w| w.to_string())
        .collect();
    assert!(omitted.is_empty(), "{omitted:?}");
    rt.options.width = W;
    rt.options.height = H;
    rt.options.samples = (2, 2);
    let world = rt.build_world().unwrap_or_else(|e| panic!("{e}"));
    let (fb, _) = render_frame(&world, None);
    let warnings = world.textures.take_warnings();
    assert!(warnings.is_empty(), "{warnings:?}");
    check("vrml_shapes", &fb.rgba).unwrap_or_else(|e| panic!("{e}"));
}

/// Points and curves (RISpec 3.2, sections 5.6 and 5.7): an arc of coloured disks facing the
/// camera above a row of sphere points, a tuft of tapering cubic B-spline hairs shaded from root to
/// tip, and a flat Bezier ribbon lying on the floor (oriented by `N`).
#[test]
fn points_and_curves_match_their_reference() {
    let list = |xs: &[f64]| xs.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" ");
    // The disks: twelve along an arc, growing, hue turning from red through green to blue.
    let (mut disks, mut disk_widths, mut disk_colours) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..12 {
        let f = f64::from(k) / 11.0;
        let a = std::f64::consts::PI * (0.15 + 0.7 * f);
        disks.extend([0.8 + 1.0 * a.cos(), 0.45 + 0.8 * a.sin(), 0.4]);
        disk_widths.push(0.1 + 0.12 * f);
        disk_colours.extend([(1.0 - 2.0 * f).max(0.0), 1.0 - (2.0 * f - 1.0).abs(), (2.0 * f - 1.0).max(0.0)]);
    }
    // The hairs: 40 around a small circle, 6 B-spline control points each (3 segments, so 4
    // varying widths and colours), rising and bending outwards.
    let (mut hairs, mut hair_widths, mut hair_colours) = (Vec::new(), Vec::new(), Vec::new());
    let n = 40;
    for i in 0..n {
        let a = std::f64::consts::TAU * f64::from(i) / f64::from(n) + 0.3 * (f64::from(i) * 2.7).sin();
        let r0 = 0.12 + 0.05 * (f64::from(i) * 1.3).cos();
        let height = 1.0 + 0.25 * (f64::from(i) * 0.9).sin();
        for k in 0..6 {
            let s = f64::from(k) / 5.0;
            let r = r0 + 0.55 * s * s;
            hairs.extend([-1.3 + r * a.cos(), height * (s - 0.08), 0.2 + r * a.sin()]);
        }
        hair_widths.extend([0.035, 0.025, 0.014, 0.004]);
        for s in [0.0, 0.33, 0.67, 1.0] {
            hair_colours.extend([0.25 + 0.7 * s, 0.12 + 0.55 * s, 0.05 + 0.15 * s]);
        }
    }
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [36]
Rotate -10 1 0 0
Translate 0 -1.2 5.5
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.2]
  LightSource "pointlight" 2 "intensity" [25] "from" [2 4 -3]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Points "P" [{}] "width" [{}] "Cs" [{}]
  AttributeEnd
  AttributeBegin
    Points "P" [0.3 0.15 -0.3  0.75 0.15 -0.3  1.2 0.15 -0.3  1.65 0.15 -0.3]
      "constantwidth" [0.3] "uniform string type" "sphere"
      "Cs" [0.9 0.85 0.2  0.2 0.7 0.8  0.85 0.3 0.6  0.9 0.9 0.9]
  AttributeEnd
  AttributeBegin
    Basis "catmull-rom" 1 "b-spline" 1
    Curves "cubic" [{}] "nonperiodic" "P" [{}] "width" [{}] "Cs" [{}]
  AttributeEnd
  AttributeBegin
    Color [.3 .5 .9]
    Curves "cubic" [7] "nonperiodic" "P" [-1.7 0.01 -0.9  -1 0.01 -1.6  -0.2 0.01 -0.1  0.3 0.01 -0.9
      0.8 0.01 -1.7  1.5 0.01 -1.2  1.9 0.01 -0.8]
      "constant normal N" [0 1 0] "width" [0.12 0.2 0.12]
  AttributeEnd
WorldEnd
"#,
        list(&disks),
        list(&disk_widths),
        list(&disk_colours),
        vec!["6"; n as usize].join(" "),
        list(&hairs),
        list(&hair_widths),
        list(&hair_colours),
    );
    check("points_and_curves", &render_rib("points_and_curves", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// Implicit surfaces (RISpec 3.2, section 5.6): a red and a blue ellipsoid added so that they
/// melt into one, their colours blending across the join, a segment blob less a sphere that bites
/// it, and two spheres kept apart by `maximum` (a union without blending), on plastic under a
/// light.
#[test]
fn blobby_matches_its_reference() {
    let rib = r#"
Format 128 96 1
PixelSamples 2 2
Projection "perspective" "fov" [36]
Rotate -4 1 0 0
Translate 0 -0.8 6
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.2]
  LightSource "pointlight" 2 "intensity" [25] "from" [2 4 -3]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Translate -1.6 0.55 0
    Blobby 2 [1001 0 1001 16 0 2 0 1]
      [1.2 0 0 0  0 1.1 0 0  0 0 1.1 0  -0.3 0 0 1
       1 0 0 0  0 1.3 0 0  0 0 1 0  0.35 0.1 0 1] []
      "Cs" [0.9 0.2 0.15  0.2 0.35 0.9]
  AttributeEnd
  AttributeBegin
    Translate 0.1 0.35 -0.2
    Color [0.9 0.8 0.3]
    Blobby 2 [1002 0 1001 23 4 0 1]
      [-0.6 0 0  0.6 0 0.3  0.8  1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1
       0.9 0 0 0  0 0.9 0 0  0 0 0.9 0  0.1 0.3 -0.25 1] []
  AttributeEnd
  AttributeBegin
    Translate 1.6 0.4 0.3
    Color [0.3 0.8 0.4]
    Blobby 2 [1001 0 1001 16 2 2 0 1]
      [1.2 0 0 0  0 1.2 0 0  0 0 1.2 0  -0.3 0 0 1
       1 0 0 0  0 1 0 0  0 0 1 0  0.25 0.3 0 1] []
  AttributeEnd
WorldEnd
"#;
    check("blobby", &render_rib("blobby", rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// Solids (`SolidBegin`/`SolidEnd`), ray traced: a ball with a bite taken out of it (the bite
/// is the red ball's inside, lit through the opening), a lens (the intersection of two balls,
/// green and yellow halves) and a union of two balls with a cube cut out of their middle, all
/// casting their shapes' shadows on the floor.
#[test]
fn solids_match_their_reference() {
    let rib = r#"
Format 128 96 1
PixelSamples 2 2
Projection "perspective" "fov" [38]
Rotate -15 1 0 0
Translate 0 -2.9 7.5
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "ambientlight" 1 "intensity" [0.2]
  LightSource "pointlight" 2 "intensity" [30] "from" [2 5 -4]
  Surface "plastic"
  Polygon "P" [-7 0 -7  7 0 -7  7 0 7  -7 0 7]
  AttributeBegin
    Translate -2.3 1 0
    Rotate 50 0 1 0
    Color [0.9 0.85 0.7]
    SolidBegin "difference"
      SolidBegin "primitive" Sphere 1 -1 1 360 SolidEnd
      SolidBegin "primitive"
        Color [0.9 0.2 0.15] Translate 0 0.5 -0.8 Sphere 0.7 -0.7 0.7 360
      SolidEnd
    SolidEnd
  AttributeEnd
  AttributeBegin
    Translate 0 1 0
    Rotate -35 0 1 0
    SolidBegin "intersection"
      SolidBegin "primitive" Color [0.3 0.8 0.4] Translate -0.4 0 0 Sphere 1 -1 1 360 SolidEnd
      SolidBegin "primitive" Color [0.9 0.8 0.3] Translate 0.8 0 0 Sphere 1 -1 1 360 SolidEnd
    SolidEnd
  AttributeEnd
  AttributeBegin
    Translate 2.3 1 0.3
    Color [0.3 0.5 0.9]
    SolidBegin "difference"
      SolidBegin "union"
        SolidBegin "primitive" TransformBegin Translate 0 0.2 0 Sphere 0.8 -0.8 0.8 360 TransformEnd SolidEnd
        SolidBegin "primitive" TransformBegin Translate 0 -0.4 0 Sphere 0.6 -0.6 0.6 360 TransformEnd SolidEnd
      SolidEnd
      SolidBegin "primitive"
        Color [0.95 0.95 0.95]
        Translate 0 0.1 -0.9 Rotate 45 0 1 0 Rotate 30 1 0 0
        Polygon "P" [-0.5 -0.5 -0.5  -0.5 0.5 -0.5  0.5 0.5 -0.5  0.5 -0.5 -0.5]
        Polygon "P" [-0.5 -0.5 0.5  0.5 -0.5 0.5  0.5 0.5 0.5  -0.5 0.5 0.5]
        Polygon "P" [-0.5 -0.5 -0.5  0.5 -0.5 -0.5  0.5 -0.5 0.5  -0.5 -0.5 0.5]
        Polygon "P" [-0.5 0.5 -0.5  -0.5 0.5 0.5  0.5 0.5 0.5  0.5 0.5 -0.5]
        Polygon "P" [-0.5 -0.5 -0.5  -0.5 -0.5 0.5  -0.5 0.5 0.5  -0.5 0.5 -0.5]
        Polygon "P" [0.5 -0.5 -0.5  0.5 0.5 -0.5  0.5 0.5 0.5  0.5 -0.5 0.5]
      SolidEnd
    SolidEnd
  AttributeEnd
WorldEnd
"#;
    check("solids", &render_rib("solids", rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// Deformation blur (`MotionBegin` around geometry) over a shutter of 0 to 1: a sphere closing
/// from a full turn to half of one while it shrinks, a square whose corner folds to its middle, a
/// cubic curve bending down and points drifting apart as they grow, over a still floor.
#[test]
fn deformation_blur_matches_its_reference() {
    let rib = r#"
Format 128 96 1
PixelSamples 4 4
Shutter 0 1
Projection "perspective" "fov" [40]
Translate 0 -0.2 6
WorldBegin
  LightSource "ambientlight" 1 "intensity" [0.25]
  LightSource "distantlight" 2 "intensity" [1] "from" [1 2 -3] "to" [0 0 0]
  Surface "matte"
  Color [0.6 0.6 0.6]
  Polygon "P" [-5 -1.5 -3  5 -1.5 -3  5 -1.5 5  -5 -1.5 5]
  AttributeBegin
    Translate -1.4 0.4 0
    Rotate -60 0 1 0
    Color [0.9 0.35 0.2]
    MotionBegin [0 1]
      Sphere 1 -1 1 360
      Sphere 0.7 -0.7 0.7 180
    MotionEnd
  AttributeEnd
  AttributeBegin
    Translate 1.3 0.6 0
    Color [0.2 0.5 0.9]
    MotionBegin [0 1]
      PointsPolygons [3 3] [0 1 2  0 2 3] "P" [-0.8 -0.8 0  -0.8 0.8 0  0.8 0.8 0  0.8 -0.8 0]
      PointsPolygons [3 3] [0 1 2  0 2 3] "P" [0 0 0  -0.8 0.8 0  0.8 0.8 0  0.8 -0.8 0]
    MotionEnd
  AttributeEnd
  AttributeBegin
    Translate -0.6 -0.9 -0.5
    Color [0.3 0.8 0.3]
    MotionBegin [0 1]
      Curves "cubic" [4] "nonperiodic" "P" [0 0 0  0.5 0 0  1 0 0  1.5 0 0] "constantwidth" [0.12]
      Curves "cubic" [4] "nonperiodic" "P" [0 0 0  0.5 -0.4 0  1 -0.4 0  1.5 0.3 0] "constantwidth" [0.12]
    MotionEnd
    Translate 1.8 0 0
    Color [0.95 0.85 0.2]
    MotionBegin [0 1]
      Points "P" [0 0 0  0.3 0 0  0.6 0 0] "width" [0.1 0.1 0.1]
      Points "P" [-0.2 0.3 0  0.3 -0.2 0  0.8 0.3 0] "width" [0.3 0.3 0.3]
    MotionEnd
  AttributeEnd
WorldEnd
"#;
    check("deformation_blur", &render_rib("deformation_blur", rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// Three boxes open towards the camera (the box above without its front face): two-sided, `Sides
/// 1` (the inside walls are backs, so the floor shows through them), and `Sides 1` after
/// `ReverseOrientation` (now the outside walls are backs: the top is gone and the inside shows).
#[test]
fn one_sided_boxes_match_their_reference() {
    let open_box = BOX.lines().filter(|l| !l.contains("[-1 -1 -1  -1 1 -1  1 1 -1  1 -1 -1]")).collect::<Vec<_>>();
    let open_box = open_box.join("\n");
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [40]
Rotate -15 1 0 0
Translate 0 -3.5 12
WorldBegin
  Attribute "light" "shadows" "on"
  LightSource "pointlight" 1 "intensity" [40] "from" [1 6 -5]
  LightSource "ambientlight" 2 "intensity" [0.15]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  Color [.3 .6 .9]
  AttributeBegin
    Translate -3.2 1.02 0 Rotate 30 0 1 0
    {open_box}
  AttributeEnd
  AttributeBegin
    Sides 1
    Translate 0 1.02 0 Rotate 30 0 1 0
    {open_box}
  AttributeEnd
  AttributeBegin
    Sides 1
    ReverseOrientation
    Translate 3.2 1.02 0 Rotate 30 0 1 0
    {open_box}
  AttributeEnd
WorldEnd
"#
    );
    check("sides_one_sided_boxes", &render_rib("sides", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// Two clipping planes: one through the ball's centre facing the camera and up, so rays see into
/// the ball (the light falls in through the opening: the part cut away casts no shadow), one
/// cutting the floor right of x = 1.5 (the background shows there).
#[test]
fn clipping_planes_match_their_reference() {
    let rib = format!(
        r#"
Format {W} {H} 1
PixelSamples 2 2
Projection "perspective" "fov" [30]
Rotate -20 1 0 0
Translate 0 -2.6 7
WorldBegin
  ClippingPlane 0 1.2 0  0 1 -0.4
  ClippingPlane 1.5 0 0  1 0 0
  Attribute "light" "shadows" "on"
  LightSource "pointlight" 1 "intensity" [25] "from" [1 4 -4]
  LightSource "ambientlight" 2 "intensity" [0.2]
  Surface "plastic"
  Polygon "P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6]
  AttributeBegin
    Translate 0 1 0
    Rotate -90 1 0 0
    Color [.8 .3 .2]
    Sphere 1 -1 1 360
  AttributeEnd
WorldEnd
"#
    );
    check("clipping_planes", &render_rib("clipping_planes", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// A mirror ball (`shinymetal`) reflecting a map made by `MakeCubeFaceEnvironment` from six faces
/// of one colour each, each with a white corner up and to the right: +x red, -x cyan, +y pale
/// blue (the sky), -y dark green (the ground), +z blue, -z yellow.
#[test]
fn cube_face_environment_matches_its_reference() {
    let dir = tempfile::tempdir().expect("a directory");
    let colours: [[f32; 3]; 6] = [
        [0.7, 0.03, 0.02],
        [0.02, 0.55, 0.6],
        [0.4, 0.55, 0.9],
        [0.01, 0.1, 0.02],
        [0.02, 0.05, 0.7],
        [0.8, 0.65, 0.03],
    ];
    let mut faces = Vec::new();
    for (k, [r, g, b]) in colours.into_iter().enumerate() {
        let n = 16;
        let rgba: Vec<f32> = (0..n * n)
            .flat_map(|i| if i / n < n / 4 && i % n >= 3 * n / 4 { [1.0; 4] } else { [r, g, b, 1.0] })
            .collect();
        let path = dir.path().join(format!("face{k}.png"));
        write_image(&path, n, n, &rgba, &WriteOptions::default()).expect("a face");
        faces.push(format!("\"{}\"", path.display()));
    }
    let map = dir.path().join("env.tex").display().to_string();
    let rib = light_scene("LightSource \"ambientlight\" 1 \"intensity\" [0.3]")
        .replacen(
            "WorldBegin",
            &format!("MakeCubeFaceEnvironment {} \"{map}\" 90 \"gaussian\" 2 2\nWorldBegin", faces.join(" ")),
            1,
        )
        .replacen("Color [.8 .3 .2]", &format!("Color [1 1 1] Surface \"shinymetal\" \"texturename\" \"{map}\""), 1);
    check("cube_face_environment", &render_rib("cube_face_environment", &rib)).unwrap_or_else(|e| panic!("{e}"));
}

/// A VRML 97 animation at one time: a box slid and turned by Position and Orientation
/// interpolators, its colour mixed by a ColorInterpolator, a face set bent by a
/// CoordinateInterpolator and a blue light switched on by the TimeSensor's isActive, all through
/// ROUTEs from one looping TimeSensor (`docs/vrml.md`, *Animation*), shown at time 1.25.
const VRML_ANIMATED: &str = r#"#VRML V2.0 utf8
NavigationInfo { headlight FALSE }
Background { skyColor 0.1 0.12 0.2 }
Viewpoint { position 0 1 7 orientation 1 0 0 -0.12 }
PointLight { location 2 4 4 intensity 0.9 }
DEF Lamp PointLight { location -3 2 2 color 0.3 0.5 1 on FALSE }
Transform { translation 0 -1.1 0 children Shape {
  appearance Appearance { material Material { diffuseColor 0.7 0.7 0.7 } }
  geometry Box { size 8 0.2 5 } } }
DEF Mover Transform { children Shape {
  appearance Appearance { material DEF Paint Material { diffuseColor 1 0 0 specularColor 0.4 0.4 0.4 } }
  geometry Box { size 1.2 1.2 1.2 } } }
Transform { translation 0 -1 1.5 children Shape {
  appearance Appearance { material Material { diffuseColor 0.9 0.8 0.2 } }
  geometry IndexedFaceSet { solid FALSE
    coord DEF Sheet Coordinate { point [ -1 0 0, 1 0 0, 1 0.1 -1, -1 0.1 -1 ] }
    coordIndex [ 0 1 2 3 -1 ] } } }
DEF Clock TimeSensor { cycleInterval 4 loop TRUE }
DEF Slide PositionInterpolator { key [0 0.5 1] keyValue [-2 0 0, 2 0.5 0, -2 0 0] }
DEF Turn OrientationInterpolator { key [0 1] keyValue [0 1 0 0, 0 1 0 6.2] }
DEF Tint ColorInterpolator { key [0 1] keyValue [1 0 0, 0 0.4 1] }
DEF Bend CoordinateInterpolator { key [0 1] keyValue [
  -1 0 0, 1 0 0, 1 0.1 -1, -1 0.1 -1,
  -1 0 0, 1 0.8 0, 1 1.2 -1, -1 0.1 -1 ] }
ROUTE Clock.fraction_changed TO Slide.set_fraction
ROUTE Clock.fraction_changed TO Turn.set_fraction
ROUTE Clock.fraction_changed TO Tint.set_fraction
ROUTE Clock.fraction_changed TO Bend.set_fraction
ROUTE Slide.value_changed TO Mover.set_translation
ROUTE Turn.value_changed TO Mover.set_rotation
ROUTE Tint.value_changed TO Paint.set_diffuseColor
ROUTE Bend.value_changed TO Sheet.set_point
ROUTE Clock.isActive TO Lamp.set_on
"#;

#[test]
fn vrml_animated_frame_matches_its_reference() {
    let mut rt = Context::new();
    let file = golden_dir().join("vrml_animated.wrl");
    let mut scene = rtsl_runtime::vrml::build_str(&mut rt, VRML_ANIMATED, &file).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert!(scene.advance_to(1.25, &mut rt).unwrap_or_else(|e| panic!("{e}")));
    assert!(scene.take_warnings().is_empty());
    rt.options.width = W;
    rt.options.height = H;
    rt.options.samples = (2, 2);
    let world = rt.build_world().unwrap_or_else(|e| panic!("{e}"));
    let (fb, _) = render_frame(&world, None);
    check("vrml_animated", &fb.rgba).unwrap_or_else(|e| panic!("{e}"));
}

/// A VRML 1.0 scene (`docs/vrml.md`, *VRML 1.0*): Separators keeping their state, a
/// PerspectiveCamera, a PointLight and a DirectionalLight, a Material of three values bound per
/// face to a face set, one bound per vertex to another, the four primitives (a Cylinder without its
/// top), a MatrixTransform, clockwise faces and a USE of a Separator.
const VRML1_SHAPES: &str = r#"#VRML V1.0 ascii
Separator {
  PerspectiveCamera { position 0 1.4 7 orientation 1 0 0 -0.2 heightAngle 0.7 }
  PointLight { location 3 4 4 intensity 0.8 }
  DirectionalLight { direction -0.3 -1 -0.5 intensity 0.4 }
  Separator {
    Material { diffuseColor 0.7 0.7 0.7 }
    Translation { translation 0 -1.1 0 }
    Cube { width 9 height 0.2 depth 6 }
  }
  DEF Ball Separator {
    Translation { translation -2.4 0 0 }
    Material { diffuseColor 0.9 0.2 0.1 specularColor 0.5 0.5 0.5 shininess 0.4 }
    Sphere { radius 0.8 }
  }
  Separator {
    Translation { translation -0.8 0 0 }
    Rotation { rotation 0 1 0 0.5 }
    Material { diffuseColor 0.2 0.5 0.9 }
    Cylinder { parts (SIDES | BOTTOM) radius 0.5 height 1.6 }
  }
  Separator {
    MatrixTransform { matrix 1 0 0 0  0 1 0 0  0 0 1 0  0.8 -0.2 0.3 1 }
    Material { diffuseColor 0.2 0.8 0.3 }
    Cone { bottomRadius 0.6 height 1.4 }
  }
  Separator {
    Translation { translation 2.4 -0.5 0 }
    Material { diffuseColor [ 1 0.2 0.2, 0.2 1 0.2, 0.2 0.2 1 ] }
    MaterialBinding { value PER_FACE_INDEXED }
    ShapeHints { vertexOrdering CLOCKWISE creaseAngle 0 }
    Coordinate3 { point [ -0.6 0 0.6, 0.6 0 0.6, 0.6 0 -0.6, -0.6 0 -0.6, 0 1.2 0 ] }
    IndexedFaceSet { coordIndex [ 0 4 1 -1  1 4 2 -1  2 4 3 -1  3 4 0 -1 ] materialIndex [ 0 1 2 1 ] }
  }
  Separator {
    Translation { translation 0 -0.99 2 }
    Material { diffuseColor [ 1 0 0, 1 1 0, 0 1 0, 0 0 1 ] }
    MaterialBinding { value PER_VERTEX_INDEXED }
    Coordinate3 { point [ -1 0 0, 0 0 -0.8, 1 0 0, 0 0 0.8 ] }
    IndexedFaceSet { coordIndex [ 0 3 2 1 -1 ] materialIndex [ 0 3 2 1 -1 ] }
  }
  Translation { translation 4.4 1.6 -1 }
  USE Ball
}
"#;

#[test]
fn vrml1_shapes_match_their_reference() {
    let mut rt = Context::new();
    let file = golden_dir().join("vrml1_shapes.wrl");
    let scene = rtsl_runtime::vrml::v1::build_str_with(&mut rt, VRML1_SHAPES, &file, &Default::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.shapes.len(), 7);
    rt.options.width = W;
    rt.options.height = H;
    rt.options.samples = (2, 2);
    let world = rt.build_world().unwrap_or_else(|e| panic!("{e}"));
    let (fb, _) = render_frame(&world, None);
    check("vrml1_shapes", &fb.rgba).unwrap_or_else(|e| panic!("{e}"));
}

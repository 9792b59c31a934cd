//! Volume shaders in the renderer (`docs/volumes.md`): the atmosphere on the segments of camera
//! rays, the interior of closed objects on segments that travel inside them, their bindings in the
//! API and in RIB, and `texture3d` grids read through the texture cache.

use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::render::{render_frame, Antialiasing};
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::shading::ParamValue;
use rtsl_runtime::texture::{Grid, GridType};
use std::path::Path;

const SIZE: u32 = 9;

/// Renders RIB at 9x9, one sample at each pixel's centre; returns RGBA and the load's warnings.
fn render(rib: &str, setup: impl FnOnce(&mut Context)) -> (Vec<f32>, Vec<String>) {
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, rib, Path::new("volume-test.rib")).expect("the scene loads");
    setup(&mut rt);
    rt.options.width = SIZE;
    rt.options.height = SIZE;
    rt.options.samples = (1, 1);
    rt.options.antialiasing = Antialiasing::Grid { jitter: false };
    let world = rt.build_world().expect("the world builds");
    let (fb, _) = render_frame(&world, None);
    let mut warnings: Vec<String> = loaded.warnings.iter().map(ToString::to_string).collect();
    warnings.extend(world.textures.take_warnings().iter().map(ToString::to_string));
    (fb.rgba, warnings)
}

fn pixel(rgba: &[f32], x: u32, y: u32) -> [f32; 3] {
    let i = 4 * (y * SIZE + x) as usize;
    [rgba[i], rgba[i + 1], rgba[i + 2]]
}

fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
}

/// A white constant wall 2.4 wide at z = 5, seen from the origin looking down +z.
const WALL: &str = r#"
Projection "perspective" "fov" [40]
WorldBegin
  AttributeBegin
    Surface "constant"
    Polygon "P" [-1.2 -1.2 5  1.2 -1.2 5  1.2 1.2 5  -1.2 1.2 5]
  AttributeEnd
"#;

#[test]
fn fog_attenuates_by_the_distance_travelled_and_misses_stay_unfogged() {
    let rib = format!("{WALL}\n  Atmosphere \"fog\" \"distance\" [2.5] \"background\" [0 0 1]\nWorldEnd\n");
    let (rgba, warnings) = render(&rib, |rt| rt.options.background = [0.2, 0.3, 0.4]);
    assert!(warnings.is_empty(), "{warnings:?}");
    // The centre ray travels 5 units: T = exp(-5 / 2.5), blended towards the fog's blue.
    let t = (-2.0f32).exp();
    let centre = pixel(&rgba, SIZE / 2, SIZE / 2);
    assert!(close(centre, [t, t, t + (1.0 - t)], 1e-3), "{centre:?}");
    // Off-centre rays travel further, so they are fogged more.
    assert!(pixel(&rgba, SIZE / 2 + 2, SIZE / 2)[0] < centre[0]);
    // The wall (2.4 wide at 5, a 27-degree cone) leaves the 40-degree view's corners: they miss it
    // and show the background unfogged (RenderMan runs no atmosphere on misses).
    assert!(close(pixel(&rgba, 0, 0), [0.2, 0.3, 0.4], 1e-6), "{:?}", pixel(&rgba, 0, 0));
    // Without the atmosphere the wall is plain white.
    let (clear, _) = render(&format!("{WALL}\nWorldEnd\n"), |_| {});
    assert!(close(pixel(&clear, SIZE / 2, SIZE / 2), [1.0; 3], 1e-6));
}

#[test]
fn the_api_binds_and_removes_the_atmosphere_and_checks_its_kind() {
    let rib = format!("{WALL}\nWorldEnd\n");
    let (fogged, _) = render(&rib, |rt| {
        let fog = rt.find_shader("fog").unwrap();
        rt.atmosphere(Some(fog), &[("distance", ParamValue::Float(5.0))]).unwrap();
    });
    let t = (-1.0f32).exp();
    assert!(close(pixel(&fogged, SIZE / 2, SIZE / 2), [t; 3], 1e-3), "{:?}", pixel(&fogged, 4, 4));
    let (removed, _) = render(&rib, |rt| {
        let fog = rt.find_shader("fog").unwrap();
        rt.atmosphere(Some(fog), &[]).unwrap();
        rt.atmosphere(None, &[]).unwrap();
    });
    assert!(close(pixel(&removed, SIZE / 2, SIZE / 2), [1.0; 3], 1e-6));

    let mut rt = Context::new();
    let plastic = rt.find_shader("plastic").unwrap();
    let fog = rt.find_shader("fog").unwrap();
    assert!(matches!(rt.atmosphere(Some(plastic), &[]), Err(ApiError::WrongKind { .. })));
    assert!(matches!(rt.interior(Some(plastic), &[]), Err(ApiError::WrongKind { .. })));
    assert!(rt.atmosphere(Some(fog), &[("nosuch", ParamValue::Float(1.0))]).is_err());
    assert!(rt.interior(Some(fog), &[("distance", ParamValue::String("far".into()))]).is_err());
}

/// An invisible sphere (constant, opacity 0) of radius 1 at z = 5 in front of a white wall at
/// z = 10, with `interior` inside it.
fn sphere_scene(interior: &str) -> String {
    format!(
        r#"
Projection "perspective" "fov" [40]
WorldBegin
  AttributeBegin
    Surface "constant"
    Polygon "P" [-20 -20 10  20 -20 10  20 20 10  -20 20 10]
  AttributeEnd
  AttributeBegin
    Translate 0 0 5
    Rotate 90 1 0 0
    Surface "constant"
    Opacity [0 0 0]
    {interior}
    Sphere 1 -1 1 360
  AttributeEnd
WorldEnd
"#
    )
}

#[test]
fn the_interior_absorbs_along_the_segment_inside_the_object() {
    let rib = sphere_scene("Interior \"medium\" \"density\" [0.5] \"absorption\" [1 0 0.25]");
    let (rgba, warnings) = render(&rib, |_| {});
    assert!(warnings.is_empty(), "{warnings:?}");
    // The centre ray crosses the sphere through its centre: about 2 units inside (less a little
    // for the tessellation's flat facets). Red keeps exp(-0.5 * 2), blue exp(-0.125 * 2).
    let centre = pixel(&rgba, SIZE / 2, SIZE / 2);
    let (red, blue) = ((-1.0f32).exp(), (-0.25f32).exp());
    assert!(close(centre, [red, 1.0, blue], 0.02), "{centre:?} vs [{red}, 1, {blue}]");
    // A corner ray misses the sphere: the wall is white.
    assert!(close(pixel(&rgba, 0, 0), [1.0; 3], 1e-6));
    // With no interior the sphere is invisible, and the atmosphere does not run inside objects
    // that have an interior.
    let (clear, _) = render(&sphere_scene(""), |_| {});
    assert!(close(pixel(&clear, SIZE / 2, SIZE / 2), [1.0; 3], 1e-6));
}

#[test]
fn an_interior_is_an_attribute_scoped_like_the_surface() {
    // Bound inside the attribute block, popped before a second sphere: only the first has it.
    let rib = r#"
Projection "perspective" "fov" [60]
WorldBegin
  AttributeBegin
    Surface "constant"
    Polygon "P" [-20 -20 10  20 -20 10  20 20 10  -20 20 10]
  AttributeEnd
  Surface "constant"
  Opacity [0 0 0]
  AttributeBegin
    Interior "medium" "density" [2]
    Translate -1.5 0 5
    Sphere 1 -1 1 360
  AttributeEnd
  AttributeBegin
    Translate 1.5 0 5
    Sphere 1 -1 1 360
  AttributeEnd
WorldEnd
"#;
    let (rgba, warnings) = render(rib, |_| {});
    assert!(warnings.is_empty(), "{warnings:?}");
    let left = pixel(&rgba, 2, SIZE / 2);
    let right = pixel(&rgba, SIZE - 3, SIZE / 2);
    assert!(left[0] < 0.5, "the left sphere's medium darkens: {left:?}");
    assert!(close(right, [1.0; 3], 1e-6), "the right sphere has no medium: {right:?}");
}

#[test]
fn rib_volume_statements_need_volume_shaders() {
    // A surface shader is no atmosphere: a warning with the location, and the load goes on.
    let mut rt = Context::new();
    let loaded = load_str(&mut rt, "WorldBegin\nAtmosphere \"plastic\"\nWorldEnd\n", Path::new("v.rib")).unwrap();
    assert!(
        loaded.warnings.len() == 1
            && loaded.warnings[0].to_string().contains("v.rib:2:1")
            && loaded.warnings[0].message.contains("not a volume shader"),
        "{:?}",
        loaded.warnings
    );
    let mut rt = Context::new();
    let loaded = load_str(
        &mut rt,
        "WorldBegin\nAtmosphere \"fog\"\nAtmosphere \"\"\nInterior \"depthcue\"\nWorldEnd\n",
        Path::new("v.rib"),
    )
    .expect("volume statements load");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}

#[test]
fn texture3d_reads_grids_through_the_texture_cache() {
    // A 2x2x2 grid over (-1,-1,-1)..(1,1,1) that is 1 on the +x side and 0 on the -x side; a
    // shader on a wall at z = 5 shows the lookup at P - (0, 0, 5): the wall's plane moved to z = 0.
    let dir = std::env::temp_dir().join(format!("rtsl-volume-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let grid = Grid::new([2, 2, 2], [-1.0; 3], [1.0; 3], vec![0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]).unwrap();
    let path = dir.join("ramp.grid");
    std::fs::write(&path, grid.to_bytes(GridType::F32)).unwrap();
    let shader = r#"surface show3d(string gridname = "") {
        float v = texture3d(gridname, P - point(0, 0, 5), "fill", 0.25);
        Ci = color(v, v, v); Oi = 1; }"#;
    let run = |name: &str| {
        let mut rt = Context::new();
        let id = rt.compile_shader("show3d", shader).unwrap();
        rt.bind_shader(id).unwrap();
        rt.parameter("gridname", ParamValue::String(name.to_string())).unwrap();
        let quad = rt.begin_object().unwrap();
        rt.begin(rtsl_runtime::api::Primitive::Quads).unwrap();
        for (x, y) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
            rt.vertex(x, y, 5.0).unwrap();
        }
        rt.end().unwrap();
        rt.end_object().unwrap();
        rt.instantiate_object(quad).unwrap();
        rt.camera_look_at(glam::Vec3A::ZERO, glam::Vec3A::Z, glam::Vec3A::Y, 40.0);
        rt.options.width = SIZE;
        rt.options.height = SIZE;
        rt.options.antialiasing = Antialiasing::Grid { jitter: false };
        let world = rt.build_world().unwrap();
        let (fb, _) = render_frame(&world, None);
        let warnings: Vec<String> = world.textures.take_warnings().iter().map(ToString::to_string).collect();
        (fb.rgba, warnings)
    };
    let (rgba, warnings) = run(path.to_str().unwrap());
    assert!(warnings.is_empty(), "{warnings:?}");
    // The centre is x = 0: halfway. The image's x runs with world x or against it depending on
    // the camera's handedness; either way the two sides differ and mirror around 0.5.
    let centre = pixel(&rgba, SIZE / 2, SIZE / 2)[0];
    assert!((centre - 0.5).abs() < 1e-3, "{centre}");
    let (l, r) = (pixel(&rgba, 2, SIZE / 2)[0], pixel(&rgba, SIZE - 3, SIZE / 2)[0]);
    assert!((l + r - 1.0).abs() < 1e-3 && (l - r).abs() > 0.2, "{l} {r}");
    // A missing file warns once, naming it, and lookups use the fill value.
    let (missing, warnings) = run("no-such.grid");
    assert!(close(pixel(&missing, SIZE / 2, SIZE / 2), [0.25; 3], 1e-6));
    assert!(warnings.len() == 1 && warnings[0].contains("no-such.grid"), "{warnings:?}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn files_in_memory_are_used_by_name_and_corrupt_bytes_are_errors() {
    // A grid that is 1 everywhere, given as a file's bytes: texture3d finds it by its name.
    let grid = Grid::new([2, 2, 2], [-1.0; 3], [1.0; 3], vec![1.0; 8]).expect("a grid");
    let mut rt = Context::new();
    rt.grid_file_in_memory("mem/ones.grid", &grid.to_bytes(GridType::F32)).expect("a valid grid file");
    let found = rt.textures().get_grid("mem/ones.grid").expect("the grid is in the cache");
    assert_eq!(found.lookup([0.2, -0.3, 0.5]), 1.0);
    // A PNG's bytes: decoded like the file would be (8-bit colour as sRGB).
    let png = std::env::temp_dir().join(format!("rtsl-mem-{}.png", std::process::id()));
    rtsl_runtime::write_image(&png, 1, 1, &[0.5, 0.5, 0.5, 1.0], &rtsl_runtime::WriteOptions::default())
        .expect("writes");
    let bytes = std::fs::read(&png).expect("reads");
    let _ = std::fs::remove_file(&png);
    rt.texture_file_in_memory("mem/grey.png", &bytes).expect("a valid PNG");
    assert!(rt.textures().get_texture("mem/grey.png", false).is_some());
    // Corrupt bytes are typed errors naming the file, never panics.
    for (name, result) in [
        ("bad.grid", rt.grid_file_in_memory("bad.grid", b"RTSLGRID garbage")),
        ("bad.png", rt.texture_file_in_memory("bad.png", &bytes[..bytes.len() / 2])),
        ("empty.png", rt.texture_file_in_memory("empty.png", b"")),
    ] {
        match result {
            Err(e @ ApiError::BadTextureFile { .. }) => assert!(e.to_string().contains(name), "{e}"),
            other => panic!("{name}: {other:?}"),
        }
    }
}

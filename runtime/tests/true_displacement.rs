//! True displacement (`render/true_displacement.rs`): a displacement shader that moves `P` moves
//! the geometry of objects that ask for it (RIB `Attribute "displacementbound"` above 0, PRMan's
//! `"trace" "displacements"`, BMRT's `"render" "truedisplacement"`): silhouettes and shadows
//! follow; without, or where the shader sets `N` only, displacement is bump mapping.

mod common;

use common::{render, BUMP_ONLY};
use rtsl_runtime::api::Context;
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::scene::ObjectId;

/// Moves every point `amount` along its normal (RISpec's usual form).
const INFLATE: &str = "displacement inflate(float amount = 0.25) {
    P += amount * normalize(N);
    N = calculatenormal(P);
}";

/// Shows the shading normal as a colour.
const NORMALS: &str = "surface normals() {
    normal n = normalize(N);
    Oi = 1;
    Ci = 0.5 + 0.5 * color(xcomp(n), ycomp(n), zcomp(n));
}";

/// Ridges around the sphere's z axis: points move by different amounts, so a crack between
/// triangles would open.
const RIDGES: &str = "displacement ridges(float amount = 0.2) {
    point Po = transform(\"object\", P);
    P += amount * (0.5 + 0.5 * sin(20 * zcomp(Po))) * normalize(N);
    N = calculatenormal(P);
}";

const SIZE: u32 = 64;

/// A frame of a unit sphere 4 units in front of the camera, shaded `constant`, with
/// `attributes` and `displacement` in its block, and the warnings loading it gave.
fn sphere(attributes: &str, displacement: &str) -> (Framebuffer, Vec<String>) {
    let rib = format!(
        "Format {SIZE} {SIZE} 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
         AttributeBegin {attributes} {displacement} Surface \"constant\" Sphere 1 -1 1 360 AttributeEnd\nWorldEnd\n"
    );
    let mut rt = Context::new();
    for (name, source) in [("inflate.sl", INFLATE), ("bumponly.sl", BUMP_ONLY), ("ridges.sl", RIDGES)] {
        rt.compile_shader(name, source).expect("the displacement compiles");
    }
    let loaded = load_str(&mut rt, &rib, "sphere.rib").expect("loads");
    let warnings = loaded.warnings.iter().map(|w| w.message.clone()).collect();
    (render(&mut rt), warnings)
}

/// Pixels the sphere covers.
fn covered(fb: &Framebuffer) -> usize {
    (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).filter(|&(x, y)| fb.pixel(x, y)[3] > 0.5).count()
}

#[test]
fn a_displacement_bound_lets_the_shader_move_the_silhouette() {
    let (plain, warnings) = sphere("", "");
    assert!(warnings.is_empty(), "{warnings:?}");
    let (bumped, _) = sphere("", "Displacement \"inflate\"");
    let (moved, warnings) = sphere("Attribute \"displacementbound\" \"sphere\" [0.25]", "Displacement \"inflate\"");
    assert!(warnings.is_empty(), "{warnings:?}");
    let (plain, bumped, moved) = (covered(&plain), covered(&bumped), covered(&moved));
    // Without a bound the shader bends normals only: the outline stays.
    assert_eq!(bumped, plain);
    // A sphere of radius 1.25 covers about 1.25^2 as many pixels (a little more in perspective).
    let ratio = moved as f32 / plain as f32;
    assert!((1.45..1.75).contains(&ratio), "covered {moved} against {plain}: {ratio}");
}

#[test]
fn the_trace_displacements_attributes_ask_for_it_and_can_refuse_it() {
    let plain = covered(&sphere("", "").0);
    for asked in ["Attribute \"trace\" \"int displacements\" [1]", "Attribute \"render\" \"truedisplacement\" [1]"] {
        let (moved, warnings) = sphere(asked, "Displacement \"inflate\"");
        assert!(warnings.is_empty(), "{asked}: {warnings:?}");
        assert!(covered(&moved) as f32 > 1.4 * plain as f32, "{asked}");
    }
    // Said off, a bound does not turn it on.
    let refused = "Attribute \"displacementbound\" \"sphere\" [0.25] Attribute \"trace\" \"displacements\" [0]";
    assert_eq!(covered(&sphere(refused, "Displacement \"inflate\"").0), plain);
}

#[test]
fn a_shader_that_sets_only_the_normal_leaves_the_geometry_and_the_image_as_bump_mapping() {
    let bound = "Attribute \"displacementbound\" \"sphere\" [0.25]";
    let (bumped, _) = sphere("", "Displacement \"bumponly\"");
    let (asked, _) = sphere(bound, "Displacement \"bumponly\"");
    assert_eq!(bumped.rgba, asked.rgba);
}

#[test]
fn displaced_surfaces_stay_closed() {
    // A closed displaced sphere covers every pixel inside the undisplaced sphere's outline (a
    // unit sphere 4 units away in a 40 degree view: about 23 pixels in radius).
    let (fb, warnings) = sphere("Attribute \"displacementbound\" \"sphere\" [0.2]", "Displacement \"ridges\"");
    assert!(warnings.is_empty(), "{warnings:?}");
    let centre = SIZE as f32 / 2.0;
    let outline = 0.5 * SIZE as f32 * 0.25f32.asin().tan() / 20f32.to_radians().tan();
    let radius = 0.9 * outline;
    let mut inside = 0;
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (dx, dy) = (x as f32 + 0.5 - centre, y as f32 + 0.5 - centre);
            if (dx * dx + dy * dy).sqrt() < radius {
                inside += 1;
                assert!(fb.pixel(x, y)[3] > 0.999, "a hole at ({x}, {y})");
            }
        }
    }
    assert!(inside > 200, "{inside} pixels tested");
}

#[test]
fn a_bad_displacement_bound_or_shading_rate_warns() {
    let (_, warnings) = sphere("Attribute \"displacementbound\" \"sphere\" [-1]", "");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("displacementbound"), "{warnings:?}");
    for rate in ["0", "-4"] {
        let (_, warnings) = sphere(&format!("ShadingRate {rate}"), "");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("ShadingRate"), "{warnings:?}");
    }
}

#[test]
fn displaced_meshes_are_kept_from_frame_to_frame() {
    let rib = "Format 32 32 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
               Attribute \"displacementbound\" \"sphere\" [0.25] Displacement \"inflate\" Surface \"constant\"\n\
               Sphere 1 -1 1 360\nWorldEnd\n";
    let mut rt = Context::new();
    rt.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
    load_str(&mut rt, rib, "kept.rib").expect("loads");
    let (first, report) = rt.render_frame().expect("renders");
    // The sphere's own object and its displaced mesh.
    assert_eq!(report.accel.objects_rebuilt, 2);
    let (second, report) = rt.render_frame().expect("renders");
    assert_eq!(report.accel.objects_rebuilt, 0, "nothing changed, nothing is diced again");
    assert_eq!(first.rgba, second.rgba);
}

/// A camera moving a little from frame to frame over a floor split before dicing keeps its
/// displaced mesh (some of its many pieces' distances cross a step of the dicing ladder at any
/// move; a mesh within a step of what the frame asks serves), and dices again once it has moved
/// far.
#[test]
fn a_camera_moving_a_little_keeps_a_split_floor_s_displaced_mesh() {
    let rib = "Format 48 32 1\nShadingRate 4\nProjection \"perspective\" \"fov\" [40]\n\
               Rotate -6 1 0 0 Translate 0 -1 0\nWorldBegin\n\
               Attribute \"displacementbound\" \"sphere\" [0.2] Displacement \"ridges\" Surface \"constant\"\n\
               Polygon \"P\" [-20 0 1  -20 0 60  20 0 60  20 0 1]\nWorldEnd\n";
    let mut rt = Context::new();
    rt.compile_shader("ridges.sl", RIDGES).expect("the displacement compiles");
    load_str(&mut rt, rib, "floor.rib").expect("loads");
    let (_, report) = rt.render_frame().expect("renders");
    assert_eq!(report.accel.objects_rebuilt, 2, "the floor and its displaced mesh");
    let start = *rt.camera();
    let moved = |rt: &mut Context, by: f32| {
        let mut camera = start;
        camera.world_from_camera.translation += glam::Vec3A::new(0.0, 0.0, by);
        rt.set_camera(camera);
        rt.render_frame().expect("renders").1.accel.objects_rebuilt
    };
    let rebuilt: Vec<usize> = [0.01, 0.02, 0.03, 0.04].iter().map(|&by| moved(&mut rt, by)).collect();
    assert_eq!(rebuilt, [0; 4], "moving 1 cm at a time, 1 unit above the floor");
    assert_eq!(moved(&mut rt, 4.0), 1, "moved 4 units, the floor is diced again");
}

/// An object built in parts: the part whose material asks for true displacement moves, the
/// other keeps its shape and its own displacement shader's bump mapping.
#[test]
fn only_the_parts_that_ask_move() {
    use rtsl_runtime::api::Quadric;
    let image = |first_moves: bool| -> Framebuffer {
        let mut rt = Context::new();
        rt.options.width = SIZE;
        rt.options.height = SIZE;
        let inflate = rt.compile_shader("inflate.sl", INFLATE).expect("compiles");
        let bump = rt.compile_shader("bumponly.sl", BUMP_ONLY).expect("compiles");
        let normals = rt.compile_shader("normals.sl", NORMALS).expect("compiles");
        rt.bind_shader(normals).expect("binds");
        rt.translate(0.0, 0.0, 4.0);
        rt.begin_object().expect("begins");
        rt.push_matrix();
        let sphere = Quadric::Sphere { radius: 1.0, zmin: -1.0, zmax: 1.0, thetamax: 360.0 };
        rt.translate(-1.7, 0.0, 0.0);
        rt.quadric(&sphere).expect("adds");
        rt.displacement(Some(inflate), &[]).expect("binds");
        rt.true_displacement(Some(first_moves));
        rt.end_part().expect("ends the part");
        rt.translate(3.4, 0.0, 0.0);
        rt.quadric(&sphere).expect("adds");
        rt.displacement(Some(bump), &[]).expect("binds");
        rt.true_displacement(None);
        rt.pop_matrix().expect("pops");
        let object = rt.end_object().expect("ends");
        rt.instantiate_object(object).expect("places");
        render(&mut rt)
    };
    let (moved, bumped) = (image(true), image(false));
    let half = |fb: &Framebuffer, left: bool| -> Vec<[f32; 4]> {
        let xs: Vec<u32> = if left { (0..SIZE / 2).collect() } else { (SIZE / 2..SIZE).collect() };
        (0..SIZE).flat_map(|y| xs.iter().map(move |&x| fb.pixel(x, y))).collect()
    };
    let covered = |px: &[[f32; 4]]| px.iter().filter(|p| p[3] > 0.5).count();
    let (grown, kept) = (covered(&half(&moved, true)), covered(&half(&bumped, true)));
    assert!(kept > 100 && grown as f32 > 1.3 * kept as f32, "{grown} pixels against {kept}");
    // The right sphere is bump-mapped the same in both (its normals show it).
    assert!(covered(&half(&bumped, false)) > 100);
    // (The same surface diced: its points and normals agree to rounding.)
    let (a, b) = (half(&moved, false), half(&bumped, false));
    let differ = a.iter().zip(&b).filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| (x - y).abs() > 1e-3)).count();
    assert!(differ == 0, "the right sphere differs at {differ} pixels");
}

/// The displaced shape casts the shadow: a sphere inflated by a quarter of its radius shades
/// about 1.25^2 as much of the floor behind it as the bump-mapped sphere does.
#[test]
fn shadows_have_the_displaced_shape() {
    let shadow = |attributes: &str| -> usize {
        let rib = format!(
            "Format {SIZE} {SIZE} 1\nProjection \"perspective\" \"fov\" [60]\nWorldBegin\n\
             Attribute \"light\" \"shadows\" \"on\"\n\
             LightSource \"distantlight\" 1 \"from\" [0 0 0] \"to\" [1.2 0 1] \"intensity\" [1]\n\
             AttributeBegin Surface \"matte\" Polygon \"P\" [-20 -20 9  20 -20 9  20 20 9  -20 20 9] AttributeEnd\n\
             AttributeBegin {attributes} Displacement \"inflate\" Surface \"constant\" Translate -1 0 5\n\
             Sphere 1 -1 1 360 AttributeEnd\nWorldEnd\n"
        );
        let mut rt = Context::new();
        rt.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
        let loaded = load_str(&mut rt, &rib, "shadow.rib").expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let fb = render(&mut rt);
        let dark = |x: u32, y: u32| fb.pixel(x, y)[..3].iter().all(|c| *c < 0.05);
        (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).filter(|&(x, y)| dark(x, y)).count()
    };
    let bumped = shadow("");
    let moved = shadow("Attribute \"displacementbound\" \"sphere\" [0.25]");
    assert!(bumped > 50, "a shadow of {bumped} pixels");
    let ratio = moved as f32 / bumped as f32;
    assert!((1.3..1.9).contains(&ratio), "{moved} shadowed pixels against {bumped}: {ratio}");
}

/// Points moved out of float range, or to NaN, or very far, neither crash nor hang the frame: a
/// point whose displaced position is not a number stays where it was.
#[test]
fn absurd_displacements_render() {
    // Each move from a displacement shader, and from a surface shader (which truly displaces too).
    let shaders = |moved: &str| {
        [
            (
                format!("displacement absurd() {{ P = {moved}; N = calculatenormal(P); }}"),
                "Displacement \"absurd\" Surface \"matte\"",
            ),
            (format!("surface absurd() {{ P = {moved}; Oi = 1; Ci = diffuse(normalize(N)); }}"), "Surface \"absurd\""),
        ]
    };
    for moved in ["P * 1e30 * 1e30", "P + (0 / 0) * N", "P + 1e30 * normalize(N)", "point(0, 0, 0)"] {
        for (source, shading) in shaders(moved) {
            let rib = format!(
                "Format 16 16 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
                 Attribute \"displacementbound\" \"sphere\" [1] {shading}\n\
                 LightSource \"pointlight\" 1 \"from\" [0 0 0] \"intensity\" [4]\nSphere 1 -1 1 360\nWorldEnd\n"
            );
            let mut rt = Context::new();
            rt.compile_shader("absurd.sl", &source).expect("compiles");
            load_str(&mut rt, &rib, "absurd.rib").expect("loads");
            let fb = render(&mut rt);
            assert!(fb.rgba.iter().all(|c| c.is_finite()), "{source}");
        }
    }
}

/// Instances of one object placed alike (each with the attributes of its `ObjectInstance`, so
/// materials of their own, made again each frame) share one displaced mesh from the second frame
/// on, which is not diced again, and each is displaced in every frame.
#[test]
fn instances_placed_alike_are_all_displaced() {
    let rib = "Format 32 32 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
               Attribute \"displacementbound\" \"sphere\" [0.25] Displacement \"inflate\" Surface \"constant\"\n\
               ObjectBegin 1 Sphere 1 -1 1 360 ObjectEnd\nObjectInstance 1\nObjectInstance 1\nWorldEnd\n";
    let mut rt = Context::new();
    rt.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
    load_str(&mut rt, rib, "alike.rib").expect("loads");
    let single = {
        let mut one = Context::new();
        one.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
        let rib = rib.replace("ObjectInstance 1\nObjectInstance 1", "ObjectInstance 1");
        load_str(&mut one, &rib, "one.rib").expect("loads");
        one.render_frame().expect("renders").0
    };
    // Each instance counts its object's triangles: the displaced mesh's, in every frame.
    let mut triangles = None;
    for frame in 0..3 {
        let (fb, report) = rt.render_frame().expect("renders");
        assert_eq!(covered_in(&fb, 32), covered_in(&single, 32), "frame {frame}");
        let counted = *triangles.get_or_insert(report.accel.instanced_triangles);
        assert_eq!(report.accel.instanced_triangles, counted, "frame {frame}");
        if frame > 0 {
            assert_eq!(report.accel.objects_rebuilt, 0, "frame {frame}");
        }
    }
}

fn covered_in(fb: &Framebuffer, size: u32) -> usize {
    (0..size).flat_map(|y| (0..size).map(move |x| (x, y))).filter(|&(x, y)| fb.pixel(x, y)[3] > 0.5).count()
}

/// A deforming mesh is displaced at both ends of its deformation: a sphere growing from radius
/// 0.5 to 1 over the shutter, inflated by 0.25, blurs from radius 0.75 to 1.25 (bump-mapped, from
/// 0.5 to 1). Displaced at the opening alone it would stand at 0.75 throughout.
#[test]
fn deforming_meshes_are_displaced_at_both_ends() {
    let frame = |attributes: &str| -> Framebuffer {
        let rib = format!(
            "Format {SIZE} {SIZE} 1\nPixelSamples 4 4\nShutter 0 1\nProjection \"perspective\" \"fov\" [40]\n\
             Translate 0 0 4\nWorldBegin\nAttributeBegin {attributes} Displacement \"inflate\" Surface \"constant\"\n\
             MotionBegin [0 1] Sphere 0.5 -0.5 0.5 360 Sphere 1 -1 1 360 MotionEnd\nAttributeEnd\nWorldEnd\n"
        );
        let mut rt = Context::new();
        rt.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
        load_str(&mut rt, &rib, "growing.rib").expect("loads");
        render(&mut rt)
    };
    let (bumped, moved) = (frame(""), frame("Attribute \"displacementbound\" \"sphere\" [0.25]"));
    let pixels = |fb: &Framebuffer, alpha: &dyn Fn(f32) -> bool| {
        (0..SIZE).flat_map(|y| (0..SIZE).map(move |x| (x, y))).filter(|&(x, y)| alpha(fb.pixel(x, y)[3])).count()
    };
    // Covered at some time: the closing shape's disc.
    let (ever_bumped, ever_moved) = (pixels(&bumped, &|a| a > 0.02), pixels(&moved, &|a| a > 0.02));
    let ratio = ever_moved as f32 / ever_bumped as f32;
    assert!((1.3..1.8).contains(&ratio), "covered at some time: {ever_moved} against {ever_bumped}");
    // Covered throughout: the opening shape's disc.
    let (always_bumped, always_moved) = (pixels(&bumped, &|a| a > 0.98), pixels(&moved, &|a| a > 0.98));
    let ratio = always_moved as f32 / always_bumped as f32;
    assert!((1.8..2.8).contains(&ratio), "covered throughout: {always_moved} against {always_bumped}");
}

/// The world of `rib`, a floor displaced by `ridges`, whose first instance is truly displaced.
fn displaced_floor(rib: &str) -> (Context, rtsl_runtime::render::World) {
    let mut rt = Context::new();
    rt.compile_shader("ridges.sl", RIDGES).expect("the displacement compiles");
    load_str(&mut rt, rib, "floor.rib").expect("loads");
    let world = rt.build_world().expect("a world");
    assert!(world.instances.first().expect("the floor").displaced);
    (rt, world)
}

/// A large polygon (a floor of two triangles filling a 128-pixel frame) is diced to about a pixel
/// a micropolygon edge, finer than 64 pieces an edge, and coarser at a larger shading rate.
#[test]
fn large_polygons_are_diced_to_the_shading_rate() {
    let diced = |shading_rate: f32| -> usize {
        let rib = format!(
            "Format 128 128 1\nShadingRate {shading_rate}\nProjection \"perspective\" \"fov\" [60]\nTranslate 0 0 2\n\
             WorldBegin\nAttribute \"displacementbound\" \"sphere\" [0.25] Displacement \"ridges\" Surface \"constant\"\n\
             Polygon \"P\" [-1.2 -1.2 0  1.2 -1.2 0  1.2 1.2 0  -1.2 1.2 0]\nWorldEnd\n"
        );
        let (_, world) = displaced_floor(&rib);
        let mesh = world.scene.mesh(ObjectId(world.instances[0].object)).expect("the displaced mesh");
        mesh.triangle_count()
    };
    // The floor's triangles have edges of about 140 pixels: cut into at least 96 pieces an edge at
    // ShadingRate 1, about half as many at ShadingRate 4.
    let (fine, coarse) = (diced(1.0), diced(4.0));
    assert!(fine >= 2 * 96 * 96, "{fine} triangles");
    assert!((fine / 8..=fine / 2).contains(&coarse), "{coarse} triangles against {fine}");
}

/// A floor of many quads receding from the camera: each triangle and edge is diced at the rate
/// its own distance asks (many more points near than far, where one rate for the whole mesh
/// would put as many in each half), and the floor stays closed where rates change (no pixel of
/// background shows below the floor's far edge).
#[test]
fn receding_meshes_are_diced_finer_near_and_stay_closed() {
    let (columns, rows) = (8usize, 32usize);
    let (width, near, far) = (12.0f32, 1.0f32, 40.0f32);
    let mut points = Vec::new();
    for r in 0..=rows {
        for c in 0..=columns {
            let x = -width + 2.0 * width * c as f32 / columns as f32;
            let z = near + (far - near) * r as f32 / rows as f32;
            points.push(format!("{x} 0 {z}"));
        }
    }
    let mut indices = Vec::new();
    for r in 0..rows {
        for c in 0..columns {
            let at = |r: usize, c: usize| r * (columns + 1) + c;
            indices.push(format!("{} {} {} {}", at(r, c), at(r + 1, c), at(r + 1, c + 1), at(r, c + 1)));
        }
    }
    let rib = format!(
        "Format 96 64 1\nShadingRate 4\nProjection \"perspective\" \"fov\" [40]\n\
         Rotate -6 1 0 0 Translate 0 -1 0\nWorldBegin\n\
         Attribute \"displacementbound\" \"sphere\" [0.2] Displacement \"ridges\" Surface \"constant\"\n\
         PointsPolygons [{}] [{}] \"P\" [{}]\nWorldEnd\n",
        vec!["4"; rows * columns].join(" "),
        indices.join(" "),
        points.join(" ")
    );
    let (rt, world) = displaced_floor(&rib);
    let mesh = world.scene.mesh(ObjectId(world.instances[0].object)).expect("the displaced mesh");
    let middle = (near + far) / 2.0;
    let near_points = mesh.positions.iter().filter(|p| p.z < middle).count();
    let far_points = mesh.positions.len() - near_points;
    assert!(near_points > 4 * far_points, "{near_points} points near, {far_points} far");
    assert_the_floor_is_closed(rt, world);
}

/// One polygon of two triangles receding from the camera: each triangle is split into pieces
/// before it is diced, each piece at the rate its own distance asks, so that near the camera it is
/// diced much finer than far (one rate for each whole triangle would dice the near half as its
/// far half), and the floor stays closed.
#[test]
fn one_large_receding_polygon_is_diced_finer_near_and_stays_closed() {
    let (near, far) = (1.0f32, 60.0f32);
    let rib = format!(
        "Format 96 64 1\nShadingRate 4\nProjection \"perspective\" \"fov\" [40]\n\
         Rotate -6 1 0 0 Translate 0 -1 0\nWorldBegin\n\
         Attribute \"displacementbound\" \"sphere\" [0.2] Displacement \"ridges\" Surface \"constant\"\n\
         Polygon \"P\" [-20 0 {near}  -20 0 {far}  20 0 {far}  20 0 {near}]\nWorldEnd\n"
    );
    let (rt, world) = displaced_floor(&rib);
    let mesh = world.scene.mesh(ObjectId(world.instances[0].object)).expect("the displaced mesh");
    let nearest_tenth = near + (far - near) / 10.0;
    let near_points = mesh.positions.iter().filter(|p| p.z < nearest_tenth).count();
    let far_points = mesh.positions.iter().filter(|p| p.z >= far - (far - near) / 2.0).count();
    assert!(near_points > 4 * far_points, "{near_points} points in the nearest tenth, {far_points} in the far half");
    // Near the camera, micropolygons of 2 pixels: the 40 units across are seen 64 pixels wide
    // from 2 units away, and cut into at least a hundred pieces.
    let nearest: Vec<f32> =
        mesh.positions.iter().filter(|p| p.z < near + 0.5 && p.x.abs() < 1.0).map(|p| p.x).collect();
    assert!(nearest.len() > 50, "{} points by the camera", nearest.len());
    assert_the_floor_is_closed(rt, world);
}

/// From the bottom row up each column of a frame of `world` is covered, then (past the floor's
/// far edge) background, never covered again; and the floor covers a third of the frame.
fn assert_the_floor_is_closed(mut rt: Context, world: rtsl_runtime::render::World) {
    let (fb, _) = rtsl_runtime::render::render_frame(&world, None);
    rt.return_scene(world);
    let (w, h) = (fb.width, fb.height);
    let mut covered = 0;
    for x in 0..w {
        // From the bottom row up: covered, then (past the far edge) background, never covered again.
        let column: Vec<bool> = (0..h).rev().map(|y| fb.pixel(x, y)[3] > 0.5).collect();
        let edge = column.iter().position(|&c| !c).unwrap_or(column.len());
        assert!(column[edge..].iter().all(|&c| !c), "column {x}: background below the floor's far edge");
        covered += edge;
    }
    assert!(covered > (w * h / 3) as usize, "the floor covers {covered} pixels");
}

/// Moves every point `amount` along its normal from a surface shader, and shades with the normal
/// turned around (which must not become the displaced mesh's).
const GROW: &str = "surface grow(float amount = 0.25) {
    P += amount * normalize(N);
    N = -N;
    Oi = 1;
    Ci = 1;
}";

/// The world of `rib` (with `inflate` and `grow` compiled) and its first frame's covered pixels.
fn world_and_coverage(rib: &str) -> (rtsl_runtime::render::World, usize) {
    let mut rt = Context::new();
    rt.compile_shader("inflate.sl", INFLATE).expect("the displacement compiles");
    rt.compile_shader("grow.sl", GROW).expect("the surface compiles");
    let loaded = load_str(&mut rt, rib, "scene.rib").expect("loads");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let covered = covered(&render(&mut rt));
    (rt.build_world().expect("a world"), covered)
}

/// A REYES renderer moves the micropolygons wherever the surface shader leaves them: within a
/// displacement bound a surface shader that moves `P` moves the geometry (the inverted hull of a
/// toon outline), its normals left as they were. A displacement shader, where there is one, is
/// what moves the geometry.
#[test]
fn a_surface_shader_that_moves_p_moves_the_geometry_within_a_bound() {
    let sphere_with = |attributes: &str| {
        world_and_coverage(&format!(
            "Format {SIZE} {SIZE} 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
             AttributeBegin {attributes} Surface \"grow\" Sphere 1 -1 1 360 AttributeEnd\nWorldEnd\n"
        ))
    };
    let plain = covered(&sphere("", "").0);
    let (world, unbound) = sphere_with("");
    assert!(!world.instances[0].displaced);
    assert_eq!(unbound, plain);
    let (world, moved) = sphere_with("Attribute \"displacementbound\" \"sphere\" [0.25]");
    let ratio = moved as f32 / plain as f32;
    assert!((1.45..1.75).contains(&ratio), "covered {moved} against {plain}: {ratio}");
    let inst = &world.instances[0];
    assert!(inst.displaced);
    let mesh = world.scene.mesh(ObjectId(inst.object)).expect("the displaced mesh");
    let normals = mesh.normals.as_ref().expect("normals");
    // Every point moved out to radius 1.25, every normal still outward.
    for (p, n) in mesh.positions.iter().zip(normals) {
        assert!((p.length() - 1.25).abs() < 0.01, "a point at {p}");
        assert!(n.dot(*p) > 0.9 * p.length(), "normal {n} at {p}");
    }
    // With a displacement shader, only its `P` moves the geometry: radius 1.25, not 1.5.
    let (_, both) = sphere_with("Attribute \"displacementbound\" \"sphere\" [0.5] Displacement \"inflate\"");
    let ratio = both as f32 / plain as f32;
    assert!((1.45..1.75).contains(&ratio), "covered {both} against {plain}: {ratio}");
}

/// An `ObjectInstance` takes the displacement bound, the attribute that turns true displacement
/// on, and the shading rate where it stands, unless the object's own block set them (RISpec 3.2
/// and PRMan's rule for instanced attributes), as its shaders already were.
#[test]
fn object_instances_take_the_displacement_attributes_where_they_stand() {
    let instance = |inside: &str, at: &str| {
        world_and_coverage(&format!(
            "Format {SIZE} {SIZE} 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
             ObjectBegin 1 {inside} Sphere 1 -1 1 360 ObjectEnd\n\
             AttributeBegin {at} Displacement \"inflate\" Surface \"constant\" ObjectInstance 1 AttributeEnd\nWorldEnd\n"
        ))
    };
    let plain = covered(&sphere("", "").0);
    let bound = "Attribute \"displacementbound\" \"sphere\" [0.25]";
    let displaced = |(world, covered): (rtsl_runtime::render::World, usize)| {
        let ratio = covered as f32 / plain as f32;
        let moved = world.instances[0].displaced;
        assert_eq!(moved, (1.45..1.75).contains(&ratio), "covered {covered} against {plain}");
        assert!(moved || covered == plain, "covered {covered} against {plain}");
        moved
    };
    assert!(!displaced(instance("", "")));
    assert!(displaced(instance("", bound)));
    assert!(displaced(instance(bound, "")));
    // The block set an attribute of its own: the object's attributes are the block's.
    assert!(!displaced(instance("Attribute \"identifier\" \"name\" \"ball\"", bound)));
    // The shading rate where the instance stands sets the dicing, unless the block set one.
    let triangles = |inside: &str, at: &str| {
        let (world, _) = instance(inside, &format!("{bound} {at}"));
        world.scene.mesh(ObjectId(world.instances[0].object)).expect("the displaced mesh").triangle_count()
    };
    let (fine, coarse) = (triangles("", "ShadingRate 1"), triangles("", "ShadingRate 64"));
    assert!(coarse < fine / 4, "{coarse} triangles at ShadingRate 64 against {fine} at 1");
    assert_eq!(triangles("ShadingRate 64", "ShadingRate 1"), coarse);
}

/// A surface shader that displaces shades the surface as it was and moves it once, as a REYES
/// grid's points are moved (a shader that bumps what it displaces bumps once, not twice), while
/// rays going on through it start where the ray met the displaced surface.
#[test]
fn a_displacing_surface_shader_moves_its_point_once_and_rays_go_on_from_the_displaced_surface() {
    const RADIUS: &str = "surface radius(float amount = 0.25; float opacity = 1) {
        P += amount * normalize(N);
        Ci = opacity * length(transform(\"object\", P)) / 2;
        Oi = opacity;
    }";
    let centre = |shader: &str, more: &str| -> [f32; 4] {
        let rib = format!(
            "Format {SIZE} {SIZE} 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 4\nWorldBegin\n\
             AttributeBegin Attribute \"displacementbound\" \"sphere\" [0.25] {shader} Sphere 1 -1 1 360 AttributeEnd\n\
             {more}\nWorldEnd\n"
        );
        let mut rt = Context::new();
        rt.compile_shader("radius.sl", RADIUS).expect("the surface compiles");
        let loaded = load_str(&mut rt, &rib, "once.rib").expect("loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        render(&mut rt).pixel(SIZE / 2, SIZE / 2)
    };
    // Moved from radius 1 to 1.25 once (twice would be 1.5).
    let once = centre("Surface \"radius\"", "")[0];
    assert!((once - 0.625).abs() < 0.01, "{once}");
    // A red square between the sphere as it was (z = -1) and as displaced (z = -1.25) shows
    // through the half-transparent displaced front.
    let square = "AttributeBegin Color [1 0 0] Surface \"constant\" \
                  Polygon \"P\" [-0.2 -0.2 -1.1  0.2 -0.2 -1.1  0.2 0.2 -1.1  -0.2 0.2 -1.1] AttributeEnd";
    let [red, green, ..] = centre("Surface \"radius\" \"opacity\" [0.5]", square);
    assert!(red > green + 0.4, "red {red}, green {green}");
}

use super::*;
use crate::api::Context;
use crate::vrml::VrmlScene;

fn load(text: &str) -> (Context, VrmlScene) {
    let mut rt = Context::new();
    let scene = build_str(&mut rt, &format!("#VRML V2.0 utf8\n{text}"), Path::new("test.wrl"))
        .unwrap_or_else(|e| panic!("{e}"));
    (rt, scene)
}

fn load_err(text: &str) -> String {
    let mut rt = Context::new();
    match build_str(&mut rt, &format!("#VRML V2.0 utf8\n{text}"), Path::new("test.wrl")) {
        Ok(_) => panic!("loaded: {text}"),
        Err(e) => e.to_string(),
    }
}

fn close(a: Vec3A, b: Vec3) -> bool {
    a.abs_diff_eq(Vec3A::from(b), 1e-4)
}

#[test]
fn a_transformed_box_has_its_world_bounds() {
    // Box 2x2x6, scaled 2 along x, turned 90 degrees about z, moved by (1, 2, 3).
    let (rt, scene) = load(
        "Transform { translation 1 2 3 rotation 0 0 1 1.5707963 scale 2 1 1
           children Shape { geometry Box { size 2 2 6 } } }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let (lo, hi) = scene.bounds;
    assert!(close(lo, Vec3::new(0.0, 0.0, 0.0)) && close(hi, Vec3::new(2.0, 4.0, 6.0)), "{lo} {hi}");
    assert_eq!(scene.shapes.len(), 1);
    assert_eq!(rt.world_instance_ids().len(), 1);
    // center and scaleOrientation: a half turn about y around x = 1 moves the unit box to x 1..3.
    let (_, scene) = load(
        "Transform { center 1 0 0 rotation 0 1 0 3.14159265 scaleOrientation 0 0 1 0.7853982 scale 1 1 1
           children Shape { geometry Box {} } }",
    );
    let (lo, hi) = scene.bounds;
    assert!(close(lo, Vec3::new(1.0, -1.0, -1.0)) && close(hi, Vec3::new(3.0, 1.0, 1.0)), "{lo} {hi}");
    // A scale along a turned axis shears the box: its bounds grow along both turned axes.
    let (_, scene) =
        load("Transform { scaleOrientation 0 0 1 0.7853982 scale 2 1 1 children Shape { geometry Box {} } }");
    let (lo, hi) = scene.bounds;
    assert!(hi.x > 1.5 && hi.y > 1.5 && lo.z < -0.99 && hi.z < 1.01, "{lo} {hi}");
    // A scale of 0 hides a shape: nothing is placed, and the scene still renders.
    let (mut rt, scene) =
        load("Transform { scale 0 1 1 children Shape { geometry Box {} } } Shape { geometry Sphere {} }");
    assert_eq!(scene.shapes.len(), 1);
    assert!(scene.warnings[0].message.contains("scale it to nothing"), "{:?}", scene.warnings);
    rt.options.width = 4;
    rt.options.height = 4;
    rt.render_frame().expect("renders");
}

#[test]
fn an_indexed_face_set_with_a_concave_face_and_separators() {
    let (rt, scene) = load(
        "Shape { appearance Appearance { material Material { diffuseColor 1 0 0 } }
           geometry IndexedFaceSet {
             coord Coordinate { point [ 0 0 0, 2 0 0, 2 1 0, 1 1 0, 1 2 0, 0 2 0, 5 0 0 ] }
             coordIndex [ 0 1 2 3 4 5 -1 1 6 2 -1 ]
           } }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let (_, _, id) = scene.objects[0];
    let mesh = rt.object_mesh(id).expect("a mesh");
    assert_eq!(mesh.triangle_count(), 5);
    let area: f32 = (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            0.5 * (b - a).cross(c - a).z
        })
        .sum();
    assert!((area - 4.5).abs() < 1e-5, "the L is cut into ears, not fanned over its notch: {area}");
    assert_eq!(scene.triangles, 5);
}

#[test]
fn crease_angle_shares_smoothed_normals() {
    // A gently folded strip: with a crease angle above the fold, the fold's points are shared.
    let strip = |crease: f32| {
        format!(
            "Shape {{ geometry IndexedFaceSet {{ creaseAngle {crease}
               coord Coordinate {{ point [ 0 0 0, 0 0 1, 1 0.1 0, 1 0.1 1, 2 0 0, 2 0 1 ] }}
               coordIndex [ 0 1 3 2 -1 2 3 5 4 -1 ] }} }}"
        )
    };
    let (rt, scene) = load(&strip(0.5));
    let mesh = rt.object_mesh(scene.objects[0].2).expect("a mesh");
    assert_eq!(mesh.positions.len(), 6);
    let normals = mesh.normals.as_ref().expect("smooth normals");
    let fold = mesh.positions.iter().position(|p| *p == Vec3::new(1.0, 0.1, 0.0)).expect("the fold");
    assert!(normals[fold].abs_diff_eq(Vec3::Y, 1e-5), "{}", normals[fold]);
    let (rt, scene) = load(&strip(0.0));
    let mesh = rt.object_mesh(scene.objects[0].2).expect("a mesh");
    assert_eq!(mesh.positions.len(), 6, "flat faces share points too: they carry no normals");
    assert!(mesh.normals.is_none());
    let (rt, scene) = load(&strip(0.05));
    let mesh = rt.object_mesh(scene.objects[0].2).expect("a mesh");
    assert_eq!(mesh.positions.len(), 8, "below the fold's angle the fold's points split");
}

#[test]
fn use_instances_one_object_and_protos_take_their_fields() {
    let (rt, scene) = load(
        "DEF G Group { children DEF S Shape { geometry Box {} } }
         Transform { translation 5 0 0 children [ USE G USE S ] }
         PROTO Pillar [ field SFFloat h 2 field SFNode look NULL ] {
           Shape { appearance IS look geometry Cylinder { height IS h } }
         }
         Transform { translation 0 0 -10 children Pillar { h 10 } }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.objects.len(), 2, "the box once, the pillar once");
    assert_eq!(rt.world_instance_ids().len(), 4);
    let boxes: Vec<_> = scene.shapes.iter().filter(|s| s.world.translation.z > -5.0).collect();
    assert_eq!(boxes.len(), 3);
    // Each placed shape keeps the nodes it was reached through.
    let doc = &scene.documents[0].1;
    let used = boxes.iter().find(|s| s.path.len() == 2).expect("USE G inside the Transform");
    assert_eq!(doc.node(used.path[0].node).type_name, "Transform");
    assert_eq!(doc.node(used.path[1].node).def.as_deref(), Some("G"));
    assert!(close(scene.bounds.0, Vec3::new(-1.0, -5.0, -11.0)), "{}", scene.bounds.0);
    assert!(close(scene.bounds.1, Vec3::new(6.0, 5.0, 1.0)), "{}", scene.bounds.1);
}

#[test]
fn switch_lod_and_billboard_choose_their_children() {
    let (rt, scene) = load(
        "Switch { whichChoice 1 choice [ Shape { geometry Box {} } Shape { geometry Sphere {} } ] }
         Switch { choice Shape { geometry Box {} } }
         LOD { level [ Shape { geometry Cone {} } Shape { geometry Box {} } ] }
         Billboard { children Shape { geometry Sphere { radius 2 } } }",
    );
    assert_eq!(rt.world_instance_ids().len(), 3);
    let kinds: Vec<&str> =
        scene.objects.iter().map(|(g, _, _)| scene.documents[0].1.node(g.node).type_name.as_str()).collect();
    // Every LOD level is made (the camera chooses among them as it moves), only the chosen one
    // (the first: no ranges) drawn.
    assert_eq!(kinds, ["Sphere", "Cone", "Box", "Sphere"]);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn unknown_nodes_and_fields_warn_once_with_their_place() {
    let (_, scene) = load(
        "Group { children [
           Frob { a 1 }
           Frob { }
           Shape { geometry Box { size 1 1 1 sise 2 } }
           Shape { geometry Box { sise 3 } }
           IndexedLineSet { }
           PointSet { }
           TimeSensor { loop TRUE }
           Sound { }
           Shape { geometry Sphere { radius \"big\" } }
         ] }",
    );
    let shown: Vec<String> = scene.warnings.iter().map(|w| w.to_string()).collect();
    // A TimeSensor is run by animation; a Sound is not.
    assert_eq!(shown.len(), 6, "{shown:#?}");
    assert!(shown[0].starts_with("test.wrl:3:12: warning: unknown node type Frob"), "{shown:#?}");
    assert!(shown[1].starts_with("test.wrl:5:46: warning: Box has no field `sise`"), "{shown:#?}");
    assert!(shown.iter().any(|s| s.contains("IndexedLineSet is not drawn")), "{shown:#?}");
    assert!(shown.iter().any(|s| s.contains("PointSet is not drawn")), "{shown:#?}");
    assert!(shown.iter().any(|s| s.contains("Sound is skipped")), "{shown:#?}");
    assert!(shown.iter().any(|s| s.contains("Sphere.radius expects one number")), "{shown:#?}");
    let omissions = scene.warnings.iter().filter(|w| w.severity == Severity::Omission).count();
    assert_eq!(omissions, 3, "unknown and undrawn nodes are missing from the picture");
}

#[test]
fn lights_viewpoints_and_the_headlight() {
    let (rt, scene) = load(
        "Transform { translation 0 5 0 children [
           PointLight { location 1 0 0 ambientIntensity 0.5 }
           SpotLight { direction 0 -1 0 }
           DirectionalLight { on FALSE }
         ] }
         Transform { translation 0 1 0 children DEF Cam Viewpoint { position 0 0 4 fieldOfView 0.5 description \"near\" } }
         Viewpoint { position 9 9 9 }",
    );
    // Point, its ambient part, spot, directional; and the headlight (no NavigationInfo says no).
    assert_eq!(scene.lights.len(), 4);
    assert_eq!(scene.viewpoints.len(), 2);
    assert_eq!(scene.viewpoints[0].made.description, "near");
    let camera = rt.camera();
    assert!(close(camera.eye(), Vec3::new(0.0, 1.0, 4.0)), "{}", camera.eye());
    assert!((camera.fov_degrees - 0.5f32.to_degrees()).abs() < 1e-3);
    assert!(close(camera.world_from_camera.matrix3 * Vec3A::Z, Vec3::NEG_Z), "looks along -z");
    let world = {
        let mut rt = rt;
        rt.build_world().expect("a world")
    };
    assert_eq!(world.lights.len(), 4, "the lights that are on, and the headlight");
    let (rt, _) = load("NavigationInfo { headlight FALSE } Shape { geometry Box {} }");
    let mut rt = rt;
    assert_eq!(rt.build_world().expect("a world").lights.len(), 0);
}

#[test]
fn without_a_viewpoint_the_scene_is_framed() {
    let (rt, _) = load("Transform { translation 100 0 0 children Shape { geometry Sphere {} } }");
    let camera = rt.camera();
    let forward = camera.world_from_camera.matrix3 * Vec3A::Z;
    let to_centre = (Vec3A::new(100.0, 0.0, 0.0) - camera.eye()).normalize();
    assert!(forward.dot(to_centre) > 0.999, "the camera looks at the sphere");
}

#[test]
fn a_background_colours_what_rays_miss() {
    let (mut rt, _) = load("Background { skyColor 0.2 0.4 0.6 } NavigationInfo { headlight FALSE }");
    rt.options.width = 4;
    rt.options.height = 4;
    let (fb, _) = rt.render_frame().expect("rendered");
    let p = fb.pixel(1, 1);
    let want = linear(Vec3::new(0.2, 0.4, 0.6));
    assert!((0..3).all(|i| (p[i] - want[i]).abs() < 1e-3) && p[3] == 1.0, "{p:?}");
}

/// Sky and ground gradients and panorama images are seen along the camera rays that miss: up is
/// sky, down ground, and the front image (at -z, where the default Viewpoint looks) upright and
/// not mirrored.
#[test]
fn a_background_shows_its_gradients_and_panorama_along_the_camera_rays() {
    let (mut rt, scene) = load(
        "Background { skyColor [ 0 0 1, 0 0 1 ] skyAngle [ 1.6 ] groundColor [ 0 1 0, 0 1 0 ] groundAngle [ 1.5 ] }
         Viewpoint { position 0 0 0 orientation 1 0 0 1.2 fieldOfView 0.3 }
         NavigationInfo { headlight FALSE }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    rt.options.width = 8;
    rt.options.height = 8;
    let (fb, _) = rt.render_frame().expect("rendered");
    let p = fb.pixel(4, 4);
    assert!(p[2] > 0.9 && p[1] < 0.1, "looking up: sky {p:?}");

    let dir = tempfile::tempdir().expect("a temporary directory");
    // The front image: red on its left half, green on its right.
    let mut front = image::RgbImage::new(8, 8);
    for (x, _, px) in front.enumerate_pixels_mut() {
        *px = if x < 4 { image::Rgb([255, 0, 0]) } else { image::Rgb([0, 255, 0]) };
    }
    front.save(dir.path().join("front.png")).expect("saved");
    let main = dir.path().join("bg.wrl");
    std::fs::write(
        &main,
        "#VRML V2.0 utf8\nBackground { skyColor 0 0 1 frontUrl \"front.png\" groundColor [ 0 1 0, 0 1 0 ] groundAngle [ 1.5 ] }\n\
         Viewpoint { position 0 0 0 fieldOfView 0.5 }\nNavigationInfo { headlight FALSE }\n",
    )
    .expect("written");
    let mut rt = Context::new();
    let scene = build(&mut rt, &main).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    rt.options.width = 16;
    rt.options.height = 8;
    let (fb, _) = rt.render_frame().expect("rendered");
    let (left, right) = (fb.pixel(3, 4), fb.pixel(12, 4));
    // A panorama face that is not an image, or not there, is a warning naming the field; the
    // rest of the Background is drawn.
    std::fs::write(dir.path().join("bad.png"), b"not an image").expect("written");
    std::fs::write(
        &main,
        "#VRML V2.0 utf8\nBackground { skyColor [0 0 1, 1 1 1] skyAngle [1] backUrl \"bad.png\" topUrl \"gone.png\" }\n",
    )
    .expect("written");
    let mut bad = Context::new();
    let scene = build(&mut bad, &main).expect("loads");
    let messages: Vec<&str> = scene.warnings.iter().map(|w| w.message.as_str()).collect();
    assert!(
        messages.iter().any(|m| m.contains("backUrl")) && messages.iter().any(|m| m.contains("topUrl")),
        "{messages:?}"
    );
    bad.options.width = 4;
    bad.options.height = 4;
    bad.render_frame().expect("renders");
    assert!(left[0] > 0.9 && left[1] < 0.1, "the image's left half on the left: {left:?}");
    assert!(right[1] > 0.9 && right[0] < 0.1, "its right half on the right: {right:?}");
}

/// A Billboard turns its children's +z toward the viewer about its axis, and turns again as the
/// camera moves; an LOD shows the level its ranges choose for the viewer's distance, and changes
/// level as the viewer moves (ISO/IEC 14772-1, 6.6 and 6.26).
#[test]
fn billboards_and_lods_follow_the_camera() {
    let (mut rt, mut scene) = load(
        "Billboard { children Transform { translation 0 0 1 children Shape { geometry Box { size 0.2 0.2 0.2 } } } }
         LOD { range [ 10 ] level [ Shape { geometry Box { size 0.1 0.1 0.1 } } Shape { geometry Sphere { radius 0.1 } } ] }
         Viewpoint { position 5 0 0 orientation 0 1 0 1.5707963 }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let at = |scene: &VrmlScene| Vec3::from(scene.shapes[0].world.translation);
    // The viewer on +x: the child at local +z swings round to +x.
    assert!(at(&scene).abs_diff_eq(Vec3::X, 1e-4), "{}", at(&scene));
    assert!(scene.hidden_shapes.contains(&2) && !scene.hidden_shapes.contains(&1), "near: the first level");
    rt.camera_look_at(Vec3::new(0.0, 3.0, -50.0), Vec3::ZERO, Vec3::Y, 40.0);
    scene.advance_to(0.0, &mut rt).expect("advanced");
    // About the y axis only: the viewer's height does not tilt it.
    assert!(at(&scene).abs_diff_eq(Vec3::new(0.0, 0.0, -1.0), 1e-3), "{}", at(&scene));
    assert!(scene.hidden_shapes.contains(&1) && !scene.hidden_shapes.contains(&2), "far: the second level");
    let (fb, _) = rt.render_frame().expect("renders");
    assert_eq!(fb.width, rt.options.width);
}

/// The headlight points where the user looks: it turns with the camera.
#[test]
fn the_headlight_turns_with_the_camera() {
    let (mut rt, mut scene) = load("Viewpoint { position 0 0 5 } Shape { geometry Box {} }");
    let (light, made_for) = scene.headlight.expect("a headlight");
    assert!(rt.light_transform(light).expect("a light").abs_diff_eq(Affine3A::IDENTITY, 1e-5));
    rt.camera_look_at(Vec3::new(5.0, 0.0, 0.0), Vec3::ZERO, Vec3::Y, 45.0);
    assert!(scene.advance_to(0.0, &mut rt).expect("advanced"), "the scene changed");
    let now = rt.camera().world_from_camera;
    let turned = rt.light_transform(light).expect("a light");
    assert!(turned.abs_diff_eq(now * made_for.inverse(), 1e-4), "{turned:?}");
    // Its direction is now the camera's: from +x toward the origin.
    assert!(turned.transform_vector3(Vec3::NEG_Z).abs_diff_eq(Vec3::NEG_X, 1e-4));
}

/// Fog blends toward its colour by the distance from the eye as 6.19 says: LINEAR keeps
/// (range - d) / range of the surface's colour, EXPONENTIAL exp(-d / (range - d)).
#[test]
fn fog_blends_by_distance_as_vrml_says() {
    for (kind, kept) in [("LINEAR", 0.5f32), ("EXPONENTIAL", (-1.0f32).exp())] {
        let (mut rt, scene) = load(&format!(
            "Fog {{ color 1 0 0 visibilityRange 8 fogType \"{kind}\" }}
             Viewpoint {{ position 0 0 5 }}
             NavigationInfo {{ headlight FALSE }}
             Shape {{ appearance Appearance {{ material Material {{ diffuseColor 0 0 0 emissiveColor 0 0 1 }} }}
                      geometry Box {{ size 2 2 2 }} }}"
        ));
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        rt.options.width = 9;
        rt.options.height = 9;
        let (fb, _) = rt.render_frame().expect("rendered");
        // The centre ray meets the box's front face 4 from the eye.
        let p = fb.pixel(4, 4);
        assert!((p[2] - kept).abs() < 2e-3 && (p[0] - (1.0 - kept)).abs() < 2e-3, "{kind}: {p:?}");
    }
}

#[test]
fn inline_files_are_read_relative_and_refused_outside() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sub = dir.path().join("parts");
    std::fs::create_dir(&sub).expect("made");
    std::fs::write(sub.join("box.wrl"), "#VRML V2.0 utf8\nShape { geometry Box {} }\n").expect("written");
    let main = dir.path().join("main.wrl");
    let write = |text: &str| std::fs::write(&main, format!("#VRML V2.0 utf8\n{text}\n")).expect("written");
    write(
        "Inline { url \"parts/box.wrl\" }
         Transform { translation 4 0 0 children Inline { url [ \"http://example.com/x.wrl\" \"parts/box.wrl\" ] } }",
    );
    let mut rt = Context::new();
    let scene = build(&mut rt, &main).expect("loads");
    assert_eq!(scene.documents.len(), 2, "the inlined file is read once");
    assert_eq!(scene.objects.len(), 1, "and its box is one object");
    assert_eq!(rt.world_instance_ids().len(), 2);
    assert_eq!(scene.files(), vec![main.clone(), dir.path().join("parts/box.wrl")]);

    for (url, says) in [
        ("/etc/x.wrl", "absolute"),
        ("../x.wrl", "climbs out"),
        ("parts/../../x.wrl", "climbs out"),
        ("file:parts/box.wrl", "scheme"),
    ] {
        write(&format!("Group {{ children Inline {{ url \"{url}\" }} }}"));
        let e = build(&mut Context::new(), &main).expect_err(url).to_string();
        assert!(e.contains("main.wrl:2:") && e.contains(says), "{url}: {e}");
    }
    // A cycle.
    std::fs::write(sub.join("loop.wrl"), "#VRML V2.0 utf8\nInline { url \"loop.wrl\" }\n").expect("written");
    write("Inline { url \"parts/loop.wrl\" }");
    let e = build(&mut Context::new(), &main).expect_err("a cycle").to_string();
    assert!(e.contains("loop.wrl:2:10") && e.contains("cycle"), "{e}");
    // A missing file is left out with a warning.
    write("Inline { url \"parts/none.wrl\" }");
    let scene = build(&mut Context::new(), &main).expect("loads");
    assert_eq!(scene.warnings[0].severity, Severity::Omission);
    assert!(scene.warnings[0].message.contains("not found"), "{:?}", scene.warnings);
}

#[test]
fn textures_materials_and_pixel_textures() {
    let (rt, scene) = load(
        "Shape {
           appearance Appearance {
             material Material { diffuseColor 0.5 0.5 0.5 transparency 0.25 }
             texture PixelTexture { image 2 2 3 0xFF0000 0x00FF00 0x0000FF 0xFFFFFF repeatS FALSE }
             textureTransform TextureTransform { scale 2 2 }
           }
           geometry IndexedFaceSet {
             coord Coordinate { point [ 0 0 0, 1 0 0, 1 1 0, 0 1 0 ] }
             coordIndex [ 0 1 2 3 ]
             texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1, 0 1 ] }
           } }
         Shape { geometry Box {} }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let mesh = rt.object_mesh(scene.objects[0].2).expect("a mesh");
    let uvs = mesh.uvs.as_ref().expect("texture coordinates");
    // VRML (1, 1) scaled by 2 is (2, 2); rtsl's t runs down: 1 - 2.
    let corner = mesh.positions.iter().position(|p| *p == Vec3::new(1.0, 1.0, 0.0)).expect("corner");
    assert_eq!(uvs[corner], Vec2::new(2.0, -1.0));
    let origin = mesh.positions.iter().position(|p| *p == Vec3::ZERO).expect("origin");
    assert_eq!(uvs[origin], Vec2::new(0.0, 1.0));
    let mut rt = rt;
    rt.options.width = 8;
    rt.options.height = 8;
    rt.render_frame().expect("renders");
}

#[test]
fn syntax_errors_name_file_line_and_column() {
    let e = load_err("Group {\n  children [ Shape { geometry Box { size 1 2 } ]\n}");
    assert!(e.starts_with("test.wrl:3:48: expected a field name or `}`"), "{e}");
    let mut rt = Context::new();
    let e = build_str(&mut rt, "#VRML V1.0 ascii\nSeparator {}", Path::new("old.wrl")).expect_err("1.0").to_string();
    assert!(e.starts_with("old.wrl:1:1: a VRML 1.0 file is read by `vrml::v1`"), "{e}");
}

#[test]
fn bounds_on_what_the_graph_makes() {
    // USE doubling at every level: 2^40 paths to the box.
    let mut text = String::from("DEF L0 Group { children Shape { geometry Box {} } }\n");
    for k in 1..40 {
        text.push_str(&format!("DEF L{k} Group {{ children [ USE L{} USE L{} ] }}\n", k - 1, k - 1));
    }
    let e = load_err(&text);
    assert!(e.contains(&VRML_TRAVERSAL_BUDGET.to_string()), "{e}");
    // Nesting to the limit loads (on a test thread's small stack); past it is an error.
    let nest = |levels: usize| {
        "Transform { translation 0 1 0 children [ ".repeat(levels)
            + "Shape { geometry Box {} }"
            + &" ] }".repeat(levels)
    };
    let (_, scene) = load(&nest(MAX_VRML_NESTING - 2));
    assert!(close(scene.bounds.1, Vec3::new(1.0, MAX_VRML_NESTING as f32 - 1.0, 1.0)), "{}", scene.bounds.1);
    assert!(load_err(&nest(MAX_VRML_NESTING)).contains("nest deeper"));
    // A short extrusion that asks for too many triangles.
    let e = load_err(&format!(
        "Shape {{ geometry Extrusion {{ spine [ {} ] crossSection [ {} ] }} }}",
        "0 0 0 ".repeat(10_000),
        "0 0 ".repeat(10_000)
    ));
    assert!(e.contains(&MAX_MODEL_TRIANGLES.to_string()), "{e}");
    // An elevation grid whose dimensions its heights do not fill is skipped.
    let (_, scene) = load("Shape { geometry ElevationGrid { xDimension 100000 zDimension 100000 height [ 1 2 ] } }");
    assert!(scene.warnings[0].message.contains("heights"), "{:?}", scene.warnings);
    assert_eq!(scene.triangles, 0);
}

#[test]
fn relative_paths() {
    assert_eq!(relative_path("a/b%20c.png#x"), Ok(PathBuf::from("a/b c.png")));
    assert_eq!(relative_path("a/../b.png"), Ok(PathBuf::from("a/../b.png")));
    assert!(relative_path("../b.png").is_err());
    assert!(relative_path("/b.png").is_err());
    assert!(relative_path("http://x/b.png").is_err());
    assert!(relative_path("C:/b.png").is_err());
    assert!(relative_path("%zz").is_err());
}

mod robustness {
    use super::*;
    use proptest::prelude::*;

    const SAMPLE: &str = r#"#VRML V2.0 utf8
PROTO P [ field SFFloat r 1 exposedField SFColor c 1 0 0 ] { Shape { appearance Appearance { material Material { diffuseColor IS c } } geometry Sphere { radius IS r } } }
DEF T Transform { translation 1 2 3 rotation 0 1 0 0.5 children [
  Shape { geometry IndexedFaceSet { coord Coordinate { point [ 0 0 0, 1 0 0, 1 1 0, 0 1 0 ] } coordIndex [ 0 1 2 3 -1 0 2 1 ] creaseAngle 1 } }
  P { r 2 }
  Switch { whichChoice 0 choice [ Shape { geometry ElevationGrid { xDimension 2 zDimension 2 height [ 0 1 2 3 ] } } ] }
  Shape { geometry Extrusion { spine [ 0 0 0, 0 1 0, 1 2 0 ] } }
  SpotLight { location 0 4 0 } Viewpoint { position 0 0 5 } DirectionalLight { direction 0 -1 0 }
] }
Transform { children USE T }
ROUTE T.translation_changed TO T.set_translation
"#;

    const SENSORS: &str = r#"#VRML V2.0 utf8
Viewpoint { position 0 0 10 }
DEF G Transform { children [
  DEF Touch TouchSensor { } DEF Plane PlaneSensor { minPosition -1 -1 maxPosition 1 1 }
  DEF Ball SphereSensor { } DEF Knob CylinderSensor { diskAngle 0.5 maxAngle 1 }
  Shape { geometry Box { } }
  DEF L SpotLight { location 0 4 0 ambientIntensity 0.2 }
] }
DEF Near ProximitySensor { size 30 30 30 }
DEF Seen VisibilitySensor { size 1 1 1 }
ROUTE Plane.translation_changed TO G.set_translation
ROUTE Ball.rotation_changed TO G.set_rotation
ROUTE Knob.rotation_changed TO G.set_rotation
ROUTE Touch.hitPoint_changed TO L.set_location
ROUTE Near.position_changed TO L.set_direction
ROUTE Seen.isActive TO L.on
"#;

    /// The sensors' pointer and camera events of a scene, as the viewer sends them.
    fn sense(rt: &mut Context, scene: &mut VrmlScene) {
        use crate::vrml::sensors::PointerRay;
        let _ = scene.advance_to(0.0, rt);
        let ray = |x: f32| PointerRay { origin: Vec3A::new(x, 0.0, 10.0), direction: Vec3A::new(0.0, 0.0, -1.0) };
        if let Some(first) = scene.shapes.first().map(|s| s.made) {
            if let Some(hit) = scene.pointer_hit(rt, first, 0, (0.3, 0.3)) {
                let _ = scene.pointer_move(Some(&hit), 0.1, rt);
                let _ = scene.pointer_press(&hit, ray(0.0), 0.2, rt);
                let _ = scene.pointer_drag(ray(0.5), 0.3, rt);
                let _ = scene.pointer_drag(ray(f32::NAN), 0.35, rt);
                let _ = scene.pointer_release(Some(&hit), 0.4, rt);
                let _ = scene.pointer_move(None, 0.5, rt);
            }
        }
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 100.0), Vec3A::ZERO, Vec3A::Y, 40.0);
        let _ = scene.advance_to(1.0, rt);
    }

    #[test]
    fn the_sensor_sample_runs_without_warnings() {
        let mut rt = Context::new();
        let mut scene = build_str(&mut rt, SENSORS, Path::new("sensors.wrl")).unwrap_or_else(|e| panic!("{e}"));
        sense(&mut rt, &mut scene);
        assert!(scene.take_warnings().is_empty());
        assert!(scene.events.dirty.is_empty());
    }

    /// `text` with each cut's bytes (at most `len` from `at`) replaced by its one byte.
    fn mutated(text: &str, cuts: &[(usize, usize, u8)]) -> Vec<u8> {
        let mut bytes = text.as_bytes().to_vec();
        for &(at, len, byte) in cuts {
            let at = at.min(bytes.len());
            let end = (at + len).min(bytes.len());
            bytes.splice(at..end, std::iter::once(byte));
        }
        bytes
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        #[test]
        fn mutated_sensor_scenes_never_panic(cuts in proptest::collection::vec((0usize..SENSORS.len(), 0usize..8, any::<u8>()), 1..6)) {
            let bytes = mutated(SENSORS, &cuts);
            let text = String::from_utf8_lossy(&bytes);
            let mut rt = Context::new();
            if let Ok(mut scene) = build_str(&mut rt, &text, Path::new("mutated.wrl")) {
                sense(&mut rt, &mut scene);
            }
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let text = String::from_utf8_lossy(&bytes);
            let mut rt = Context::new();
            let _ = build_str(&mut rt, &text, Path::new("random.wrl"));
        }

        #[test]
        fn mutated_scenes_never_panic(cuts in proptest::collection::vec((0usize..SAMPLE.len(), 0usize..8, any::<u8>()), 1..6)) {
            let bytes = mutated(SAMPLE, &cuts);
            let text = String::from_utf8_lossy(&bytes);
            let mut rt = Context::new();
            let _ = build_str(&mut rt, &text, Path::new("mutated.wrl"));
        }
    }
}

#[test]
fn a_directional_light_lights_only_its_group() {
    // One box, USEd in the group with the light and beside it; a sphere in a group with a light
    // of its own, which lights the sphere alone.
    let (mut rt, scene) = load(
        "NavigationInfo { headlight FALSE }
         Viewpoint { position 0 0 12 fieldOfView 0.9 }
         Transform { translation -3 0 0 children [
           DEF B Shape { appearance Appearance { material Material { } } geometry Box { } }
           DirectionalLight { direction 0 0 -1 }
         ] }
         Transform { translation 0 0 0 children USE B }
         Transform { translation 3 0 0 children [
           Shape { appearance Appearance { material Material { } } geometry Sphere { } }
           DirectionalLight { direction 0 0 -1 color 1 0 0 }
         ] }",
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.objects.len(), 3, "the box in and out of the light's group are two objects");
    rt.options.width = 120;
    rt.options.height = 40;
    let (fb, _) = rt.render_frame().expect("renders");
    let at = |x: u32| {
        let p = fb.pixel(x, 20);
        [p[0], p[1], p[2]]
    };
    // 3 units at the boxes' front faces are 11 pixels.
    let (left, middle, right) = (at(60 - 11), at(60), at(60 + 11));
    assert!(left[0] > 0.2 && (left[0] - left[1]).abs() < 1e-3, "the lit box, white: {left:?}");
    assert!(middle.iter().all(|&c| c < 0.01), "the box outside the group is unlit: {middle:?}");
    assert!(right[0] > 0.2 && right[1] < 0.01, "the sphere, lit red by its own light only: {right:?}");
    // A DirectionalLight at the scene file's top level lights everything, scoped or not.
    let (mut rt, scene) = load(
        "NavigationInfo { headlight FALSE }
         Viewpoint { position 0 0 12 fieldOfView 0.9 }
         DirectionalLight { direction 0 0 -1 }
         Shape { appearance Appearance { material Material { } } geometry Box { } }",
    );
    assert_eq!(scene.objects.len(), 1);
    rt.options.width = 120;
    rt.options.height = 40;
    let (fb, _) = rt.render_frame().expect("renders");
    assert!(fb.pixel(60, 20)[0] > 0.2);
}

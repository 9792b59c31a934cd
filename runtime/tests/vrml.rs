//! VRML 97 scenes through `load_scene`: the real castle scene of `../shared/scenes` (skipped when
//! absent) loads, frames and renders, and a gzip-compressed file loads like a plain one.

mod common;

use common::shared;
use rtsl_runtime::api::Context;
use rtsl_runtime::load_scene;
use rtsl_runtime::rib::Severity;

#[test]
fn the_castle_loads_and_renders() {
    let Some(path) = shared("castle_with_trees_vrml97/castle_with_trees.wrl") else { return };
    let mut rt = Context::new();
    let loaded = load_scene(&mut rt, &path).unwrap_or_else(|e| panic!("{e}"));
    // Nothing of the castle is missing: only approximations are reported (the Background's
    // ground colour).
    let omissions: Vec<String> =
        loaded.warnings.iter().filter(|w| w.severity != Severity::Warning).map(|w| w.to_string()).collect();
    assert!(omissions.is_empty(), "{omissions:#?}");
    assert_eq!(loaded.files, vec![path.clone()]);

    // Its shapes, the trees and towers instanced where the file USEs them.
    let mut scene = Context::new();
    let vrml = rtsl_runtime::vrml::load_file(&mut scene, &path).expect("loads");
    assert_eq!(vrml.triangles, 3_293, "the README's count");
    assert!(vrml.shapes.len() > vrml.objects.len(), "{} shapes, {} objects", vrml.shapes.len(), vrml.objects.len());
    assert_eq!(vrml.lights.len(), 3, "three spot lights, no headlight");
    assert_eq!(vrml.viewpoints.len(), 1);

    rt.options.width = 48;
    rt.options.height = 27;
    let (fb, _) = rt.render_frame().expect("renders");
    // The sky is the Background's colour; the castle, trees and lawns are something else.
    let sky = fb.pixel(47, 0);
    let differs = |p: [f32; 4]| (0..3).any(|i| (p[i] - sky[i]).abs() > 0.02);
    let lit = (0..27).flat_map(|y| (0..48).map(move |x| (x, y))).filter(|&(x, y)| differs(fb.pixel(x, y))).count();
    assert!(lit > 48 * 27 / 2, "{lit} pixels of {} show the scene", 48 * 27);
    assert!(sky[2] > sky[0] && sky[3] == 1.0, "a blue, opaque sky: {sky:?}");
}

#[test]
fn gzip_compressed_files_load_by_content() {
    use std::io::Write;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let text = "#VRML V2.0 utf8\nShape { geometry Box { size 1 1 1 } }\nViewpoint { position 0 0 4 }\n";
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(text.as_bytes()).expect("written");
    let bytes = gz.finish().expect("finished");
    for name in ["box.wrz", "box.wrl.gz", "plain.WRL"] {
        let path = dir.path().join(name);
        std::fs::write(&path, if name.starts_with("plain") { text.as_bytes() } else { &bytes[..] }).expect("written");
        let mut rt = Context::new();
        let loaded = load_scene(&mut rt, &path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(loaded.warnings.is_empty(), "{name}: {:?}", loaded.warnings);
        assert_eq!(rt.world_instance_ids().len(), 1, "{name}");
    }
    let broken = dir.path().join("broken.wrl");
    std::fs::write(&broken, "#VRML V2.0 utf8\nShape { geometry Box { size 1 1 } }\n").expect("written");
    let mut rt = Context::new();
    let loaded = load_scene(&mut rt, &broken).expect("loads, the size ignored");
    assert!(loaded.warnings[0].to_string().contains("broken.wrl:2:24"), "{:?}", loaded.warnings);
    std::fs::write(&broken, "#VRML V2.0 utf8\nShape { geometry Box { size 1 1 1 }\n").expect("written");
    let e = load_scene(&mut Context::new(), &broken).expect_err("a syntax error").to_string();
    assert!(e.contains("broken.wrl:3:1") && e.contains("ends"), "{e}");
}

/// The paper's browser swapped VRML's lighting model for other shaders: `VrmlOptions::surface`
/// gives every shape that shader, its diffuse colour as `Cs`.
#[test]
fn a_swapped_surface_shader_gets_the_diffuse_colour_as_cs() {
    use rtsl_runtime::vrml::{build_str_with, VrmlOptions};
    let scene = "#VRML V2.0 utf8\nViewpoint { position 0 0 5 }\n\
                 Shape { appearance Appearance { material Material { diffuseColor 0.2 0.4 0.6 } } geometry Sphere { } }\n";
    let render = |surface: Option<&str>| {
        let mut rt = Context::new();
        let options = VrmlOptions { surface: surface.map(str::to_string) };
        build_str_with(&mut rt, scene, std::path::Path::new("s.wrl"), &options).expect("the scene builds");
        rt.options.width = 16;
        rt.options.height = 16;
        let world = rt.build_world().expect("a world");
        let (fb, _) = rtsl_runtime::render::render_frame(&world, None);
        (fb.pixel(8, 8), fb.pixel(5, 8))
    };
    let linear = |c: f32| rtsl_runtime::texture::srgb_to_linear(c);
    let (centre, edge) = render(Some("constant"));
    for (got, want) in centre.iter().zip([linear(0.2), linear(0.4), linear(0.6)]) {
        assert!((got - want).abs() < 1e-4, "{centre:?}");
    }
    assert_eq!(centre, edge, "constant is flat");
    // VRML's own model lights it by the headlight: darker towards the rim.
    let (centre, edge) = render(None);
    assert!(edge[2] < 0.9 * centre[2], "{centre:?} {edge:?}");
    let mut rt = Context::new();
    let options = VrmlOptions { surface: Some("no_such_shader".into()) };
    assert!(build_str_with(&mut rt, scene, std::path::Path::new("s.wrl"), &options).is_err());
}

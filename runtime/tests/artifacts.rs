//! Shaders loaded from a compiled library render exactly as their sources do, and a stale artifact
//! on the search path is recompiled from its source.

use glam::Vec3A;
use rtsl_compiler::artifact;
use rtsl_runtime::api::{find_shader_file, ApiError, Context, Primitive};
use rtsl_runtime::shading::ParamValue;
use std::path::Path;

fn compile_to(src: &Path, out: &Path) {
    let options = rtsl_compiler::Options::default();
    let c = rtsl_compiler::compile_file(src, &options).expect("readable");
    let bytes = artifact::encode(&c, &options).expect("a shader");
    let name = c.interface.as_ref().expect("interface").name.clone();
    artifact::write_atomically(&out.join(format!("{name}.{}", artifact::EXTENSION)), &bytes).expect("write");
}

/// A lit, textured-by-noise floor and a sphere-ish box: plastic, marble and a point light.
fn render(search: &[std::path::PathBuf]) -> Result<Vec<f32>, ApiError> {
    let mut rt = Context::new();
    rt.options.width = 48;
    rt.options.height = 32;
    rt.set_shader_search_path(search.to_vec());
    let plastic = rt.find_shader("plastic")?;
    let marble = rt.find_shader("marble")?;
    let light = rt.find_shader("pointlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 3.0, 6.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    for (shader, y) in [(plastic, 0.0f32), (marble, 1.0)] {
        let o = rt.begin_object()?;
        rt.bind_shader(shader)?;
        rt.begin(Primitive::Quads)?;
        for (x, z) in [(-3.0, 3.0), (3.0, 3.0), (3.0, -3.0), (-3.0, -3.0)] {
            rt.vertex(x * (1.0 - y * 0.6), y, z * (1.0 - y * 0.6))?;
        }
        rt.end()?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
    }
    rt.light_source(light, &[("from", ParamValue::Point([1.0, 4.0, 2.0])), ("intensity", ParamValue::Float(12.0))])?;
    let (fb, _) = rt.render_frame()?;
    Ok(fb.rgba.clone())
}

#[test]
fn a_compiled_library_renders_exactly_as_its_sources() -> Result<(), ApiError> {
    let lib = tempfile::tempdir().expect("tempdir");
    let sources = tempfile::tempdir().expect("tempdir");
    rtsl_runtime::shading::library::write_to(sources.path()).expect("the library written out");
    let std = sources.path();
    for f in ["surface/plastic.sl", "surface/marble.sl", "light/pointlight.sl"] {
        compile_to(&std.join(f), lib.path());
    }
    let search = vec![lib.path().to_path_buf()];
    let found = find_shader_file("marble", &search).expect("found");
    assert_eq!(found.extension().and_then(|e| e.to_str()), Some(artifact::EXTENSION), "{}", found.display());
    let from_source = render(&[])?;
    let from_artifacts = render(&search)?;
    assert!(from_source.iter().any(|v| *v > 0.05), "the scene is lit");
    assert_eq!(from_source, from_artifacts);
    Ok(())
}

#[test]
fn a_stale_artifact_on_the_search_path_is_recompiled_from_its_source() -> Result<(), ApiError> {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = dir.path().join("flat.sl");
    std::fs::write(&src, "surface flat() { Oi = 1; Ci = color(1, 0, 0); }\n").expect("write");
    compile_to(&src, dir.path());
    std::fs::write(&src, "surface flat() { Oi = 1; Ci = color(0, 0, 1); }\n").expect("write");
    let mut rt = Context::new();
    rt.options.width = 8;
    rt.options.height = 8;
    rt.set_shader_search_path(vec![dir.path().to_path_buf()]);
    let flat = rt.find_shader("flat")?;
    assert!(rt.program(flat)?.warnings.contains("recompiled from source"), "{}", rt.program(flat)?.warnings);
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let o = rt.begin_object()?;
    rt.bind_shader(flat)?;
    rt.begin(Primitive::Quads)?;
    for (x, y) in [(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)] {
        rt.vertex(x, y, 0.0)?;
    }
    rt.end()?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(4, 4), [0.0, 0.0, 1.0, 1.0]);
    Ok(())
}

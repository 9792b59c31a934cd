//! The reference interpreter runs every shader of the library and the corpus on the test host: each
//! run (with ray differentials for a plane seen head on) finishes with finite outputs, or stops with an
//! explicit "not supported yet" (`bump`,
//! `gather`), never a panic or a runaway.

mod common;

use rtsl_compiler::compile_file;
use rtsl_compiler::interp::{self, InterpError, Limits, ShadingPoint, TestHost, Value};

fn finite(v: &Value) -> bool {
    match v {
        Value::Float(x) => x.is_finite(),
        Value::Triple(t) => t.iter().all(|x| x.is_finite()),
        Value::Matrix(m) => m.iter().all(|x| x.is_finite()),
        Value::Array(items) => items.iter().all(finite),
        _ => true,
    }
}

#[test]
fn the_library_and_corpus_run_in_the_interpreter() {
    let (files, options) = common::library_and_corpora();
    let (mut ran, mut unsupported) = (0, 0);
    for path in &files {
        let c = compile_file(path, &options).expect("readable");
        let module = c.module.unwrap_or_else(|| panic!("{} does not compile", path.display()));
        let kind = module.shader.as_ref().expect("a shader").kind;
        let mut point = ShadingPoint::new(kind);
        // A point a little off the origin, facing the camera, with texture coordinates inside.
        point.set("P", Value::Triple([0.3, 0.2, 0.1]));
        point.set("Ps", Value::Triple([0.3, 0.2, 0.1]));
        point.set("s", Value::Float(0.3));
        point.set("t", Value::Float(0.7));
        point.set("u", Value::Float(0.3));
        point.set("v", Value::Float(0.7));
        point.set("du", Value::Float(0.01));
        point.set("dv", Value::Float(0.01));
        point.set("dPdu", Value::Triple([1.0, 0.0, 0.0]));
        point.set("dPdv", Value::Triple([0.0, 1.0, 0.0]));
        // Ray differentials of a plane seen head on: one pixel is 0.01 in u (x) and v (y).
        point.set_derivs("u", Value::Float(0.01), Value::Float(0.0));
        point.set_derivs("v", Value::Float(0.0), Value::Float(0.01));
        point.set_derivs("s", Value::Float(0.01), Value::Float(0.0));
        point.set_derivs("t", Value::Float(0.0), Value::Float(0.01));
        point.set_derivs("P", Value::Triple([0.01, 0.0, 0.0]), Value::Triple([0.0, 0.01, 0.0]));
        let mut host = TestHost::default();
        match interp::run(&module, &[], &mut point, &mut host, Limits::default()) {
            Ok(result) => {
                ran += 1;
                for (name, v) in &result.params {
                    assert!(finite(v), "{}: parameter {name} is {v:?}", path.display());
                }
                for g in ["Ci", "Oi", "P", "N", "Cl", "L"] {
                    let v = point.get(g).expect("global");
                    assert!(finite(v), "{}: {g} is {v:?}", path.display());
                }
            }
            Err(InterpError::Unsupported(_)) => unsupported += 1,
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
    eprintln!("interpreter: {ran} shaders ran, {unsupported} need gather or bump");
    assert!(
        ran >= files.len() / 2,
        "only {ran} of {} shaders ran ({unsupported} need unsupported features)",
        files.len()
    );
}

/// Shader-type words name variables, parameters and functions below the top level, as in
/// RenderMan shaders (`color light = ...; base = mix(dark, light, nz);`): each holds its own value
/// in the interpreter and the JIT, and `surface("Kd", x)` is still the message-passing call.
#[test]
fn shader_type_words_name_variables_that_hold_their_values() {
    let src = r#"
        float imager(float light) { return light * 2; }
        surface names(float volume = 0.25; float Kd = 0.5;)
        {
            color dark = color(0.1, 0.2, 0.3), light = color(1, 0.3, 0.2);
            float displacement[2] = {0.5, imager(volume)};
            float x = 7;
            float found = surface("Kd", x);
            Ci = light;
            light += (found + x) * 0;
            Oi = mix(dark, light, displacement[1]) * Kd * 2;
        }
    "#;
    let c = rtsl_compiler::compile_source("names.sl", src, &Default::default());
    assert!(c.ok() && c.diagnostics.is_empty(), "{}", c.render());
    let module = c.module.expect("module");
    let mut point = ShadingPoint::new(module.shader.as_ref().expect("a shader").kind);
    interp::run(&module, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
    // mix(dark, light, 0.5): halfway between the two colours.
    let (ci, oi) = ([1.0, 0.3, 0.2], [0.55, 0.25, 0.25]);
    let close = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-6);
    assert_eq!(point.get("Ci"), Some(&Value::Triple(ci)));
    let Some(Value::Triple(got)) = point.get("Oi") else { panic!("Oi") };
    assert!(close(got, &oi), "Oi = {got:?}");

    let shader = rtsl_compiler::back::jit::compile(&module).expect("JIT");
    let mut batch = shader.batch(3);
    shader.shade(&mut batch);
    for lane in 0..3 {
        assert_eq!(batch.global("Ci", lane), Some(ci.to_vec()), "lane {lane}");
        let got = batch.global("Oi", lane).expect("Oi");
        assert!(close(&got, &oi), "lane {lane}: Oi = {got:?}");
    }
}

//! The shader library and both corpora through the packet JIT, each shader the interpreter can run
//! checked against it; and a rough speed comparison of the two back ends.

mod common;

use common::{differential, module, random_global, Rng};
use rtsl_compiler::back::jit::{self, JitError};
use rtsl_compiler::compile_file;
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost, Value};
use std::time::Instant;

#[test]
fn the_library_and_corpus_compile_or_report_unsupported() {
    let (files, options) = common::library_and_corpora();
    let (mut compiled, mut ran) = (Vec::new(), 0);
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    for path in &files {
        let c = compile_file(path, &options).expect("readable");
        let m = c.module.unwrap_or_else(|| panic!("{} does not compile", path.display()));
        let start = Instant::now();
        match jit::compile(&m) {
            Ok(shader) => {
                let us = start.elapsed().as_micros();
                compiled.push((path.display().to_string(), us, shader.ir_insts));
                // Shaders the interpreter can run are checked against it too.
                let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
                if interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).is_ok() {
                    for seed in 0..3 {
                        differential(&m, &shader, 13, seed, 0.0);
                    }
                    ran += 1;
                }
            }
            Err(JitError::Unsupported(what)) => {
                eprintln!("jit: {}: unsupported: {what}", path.display());
                *reasons.entry(what).or_default() += 1
            }
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
    for (p, us, n) in &compiled {
        eprintln!("jit: {p}: {us} us, {n} Cranelift instructions");
    }
    for (what, n) in &reasons {
        eprintln!("jit: unsupported: {what} ({n})");
    }
    eprintln!("jit: {} of {} shaders compile; {ran} checked against the interpreter", compiled.len(), files.len());
    assert!(compiled.iter().any(|(p, _, _)| p.ends_with("constant.sl")));
    // Every shader, derivatives included (with random ray differentials): none may fall back.
    assert!(reasons.is_empty(), "unsupported: {reasons:?}");
    assert_eq!((compiled.len(), ran), (files.len(), files.len()), "every shader compiles and is checked");
}

/// A rough speed comparison; run with `cargo test --release -p rtsl-compiler --test jit_corpus -- --ignored --nocapture`.
#[test]
#[ignore]
fn speed_against_the_interpreter() {
    let src = r#"
        surface t(float Kd = 0.8; output varying float o = 0;)
        {
            normal Nf = faceforward(normalize(N), I);
            float d = max(0, Nf . normalize(-I));
            float i, acc = 0;
            for (i = 0; i < 8; i += 1) { acc += sin(s * i) * 0.1 + noise(P * i); }
            o = acc;
            Ci = Cs * Kd * d * smoothstep(0.2, 0.8, t) + color(acc);
            Oi = Os;
        }
    "#;
    let m = module(src);
    let shader = jit::compile(&m).expect("jit");
    let mut batch = shader.batch(64);
    let mut rng = Rng(7);
    for l in 0..64 {
        for g in shader.layout().globals.clone() {
            batch.set_global(g.name, l, &random_global(&mut rng, g.name, g.components));
        }
    }
    let n = 2000;
    let start = Instant::now();
    for _ in 0..n {
        shader.shade_with(&mut batch, &mut TestHost::default());
    }
    let jit_ns = start.elapsed().as_nanos() as f64 / (n * 64) as f64;
    let start = Instant::now();
    for k in 0..n * 64 / 16 {
        let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
        point.set("P", Value::Triple([k as f32 * 0.001, 0.2, 0.3]));
        point.set("s", Value::Float(0.3));
        interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
    }
    let interp_ns = start.elapsed().as_nanos() as f64 / (n * 64 / 16) as f64;
    eprintln!("jit {jit_ns:.1} ns/lane, interpreter {interp_ns:.1} ns/lane ({:.1}x)", interp_ns / jit_ns);
}

//! The packet JIT's runtime checks: the loop budget (per invocation, as in the interpreter) and
//! array indices out of range, each stopped or clamped and reported once with its place.

mod common;

use common::{floats_of, module};
use rtsl_compiler::back::jit::{self, CompiledShader};
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost, Value};
use rtsl_compiler::{compile_source, Options};

fn compiled_with_sources(src: &str, budget: u32) -> CompiledShader {
    let c = compile_source("checks.sl", src, &Options::default());
    assert!(c.ok(), "{}", c.render());
    let m = c.module.as_ref().expect("a module");
    jit::compile_with(m, Some(&c.sources), &jit::JitOptions { loop_budget: budget }).expect("jit")
}

#[test]
fn a_loop_that_never_ends_is_stopped_and_reported_once() {
    let shader = compiled_with_sources(
        "surface spin() {\n  float x = 0;\n  while (1) {\n    x += 1;\n  }\n  Ci = color(x);\n  Oi = 1;\n}\n",
        1000,
    );
    let mut batch = shader.batch(7);
    assert!(!shader.stopped_a_loop());
    shader.shade(&mut batch);
    assert!(shader.stopped_a_loop(), "read before the report, and not marking it read");
    // The loop body ran the budget's worth of times, then the shader went on.
    assert_eq!(batch.global("Ci", 6), Some(vec![1000.0; 3]));
    let errors = shader.runtime_errors();
    assert_eq!(errors, vec!["the loop at checks.sl:3:3 was stopped: the shader ran more than 1000 loop iterations"]);
    shader.shade(&mut batch);
    assert!(shader.runtime_errors().is_empty(), "each place is reported once");
}

/// The loop budget counts every loop of an invocation together, in the JIT as in the interpreter:
/// nested runaway loops stop after one budget, not one per entry of the inner loop, and both back
/// ends stop at the same iteration.
#[test]
fn the_loop_budget_holds_per_invocation_in_both_back_ends() {
    let budget = 1000;
    let cases = [
        // Nested runaway loops: the outer one stops at its next test.
        ("surface t() {\n  float x = 0;\n  while (1) {\n    while (1) { x += 1; }\n    x += 1000000;\n  }\n  Ci = x;\n}\n", 1_000_999.0, 2),
        // Loops in sequence share the budget.
        ("surface t() {\n  float a = 0, b = 0, i;\n  for (i = 0; i < 600; i += 1) a += 1;\n  for (i = 0; i < 600; i += 1) b += 1;\n  Ci = a * 1000 + b;\n}\n", 600_399.0, 1),
        // Loops in (inlined) functions share it too.
        ("float spin() { float n = 0; while (1) n += 1; return n; }\nsurface t() {\n  Ci = spin() + spin();\n}\n", 1000.0, 1),
        // A uniform loop ahead of the varying work runs in the JIT's once-per-batch prologue.
        ("surface t(float k = 700;) {\n  uniform float i, a = 0;\n  for (i = 0; i < k; i += 1) a += 1;\n  float b = 0;\n  while (s >= 0) b += 1;\n  Ci = a * 1000 + b;\n}\n", 700_299.0, 1),
    ];
    for (src, want, stopped) in cases {
        let shader = compiled_with_sources(src, budget);
        let mut batch = shader.batch(6);
        for lane in 0..6 {
            batch.set_global("s", lane, &[lane as f32]);
        }
        shader.shade(&mut batch);
        let m = module(src);
        let errors = shader.runtime_errors();
        assert_eq!(errors.len(), stopped, "{src}: {errors:?}");
        assert!(errors.iter().all(|e| e.ends_with("the shader ran more than 1000 loop iterations")), "{errors:?}");
        for lane in 0..6 {
            assert_eq!(batch.global("Ci", lane).expect("Ci")[0], want, "{src}: JIT, lane {lane}");
            let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
            point.set("s", Value::Float(lane as f32));
            let limits = Limits { loop_iterations: budget, ..Limits::default() };
            let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), limits).expect("runs");
            let ci = floats_of(point.get("Ci").expect("Ci"))[0];
            assert_eq!(ci, want, "{src}: interpreter, lane {lane}");
            assert_eq!(r.stopped_loops.len(), stopped, "{src}");
        }
    }
}

/// A ray march that steps by `clamp(step, smallest, end - d)`, as Advanced RenderMan's `smoke`
/// volume shader does, ends: at its last step `lo > hi`, and RISpec's `clamp` then gives `lo` for
/// a step below `lo` (moving past the end) where `min(max(x, lo), hi)` would give 0 for ever.
#[test]
fn a_ray_march_clamped_to_its_end_ends_in_both_back_ends() {
    let src = "surface t() {\n  float d = 0, end = 1 + s, ss = 0.3, steps = 0;\n  while (d <= end) {\n    ss = clamp(ss, 0.005, end - d);\n    d += ss;\n    steps += 1;\n  }\n  Ci = color(d - end, steps, clamp(s, 0.75, 0.25));\n}\n";
    let shader = compiled_with_sources(src, 1000);
    let mut batch = shader.batch(6);
    let s_of = |lane: usize| 0.05 + 0.17 * lane as f32;
    for lane in 0..6 {
        batch.set_global("s", lane, &[s_of(lane)]);
    }
    shader.shade(&mut batch);
    assert!(shader.runtime_errors().is_empty(), "{:?}", shader.runtime_errors());
    let m = module(src);
    for lane in 0..6 {
        let jit = batch.global("Ci", lane).expect("Ci");
        let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
        point.set("s", Value::Float(s_of(lane)));
        let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
        assert!(r.stopped_loops.is_empty(), "lane {lane}");
        assert_eq!(floats_of(point.get("Ci").expect("Ci")), jit, "lane {lane}");
        // Past the end by at most the smallest step, in a handful of steps.
        assert!(jit[0] > 0.0 && jit[0] <= 0.005, "lane {lane}: {jit:?}");
        assert!(jit[1] < 12.0, "lane {lane}: {jit:?}");
        // Below `lo` where `lo > hi`: `lo`; otherwise `hi`.
        assert_eq!(jit[2], if s_of(lane) < 0.75 { 0.75 } else { 0.25 }, "lane {lane}");
    }
}

#[test]
fn an_index_out_of_range_is_clamped_and_reported() {
    let shader = compiled_with_sources(
        "surface pick(float k = 0;) {\n  float a[3] = {1, 2, 3};\n  Ci = color(a[k * s]);\n  Oi = 1;\n}\n",
        1 << 20,
    );
    let mut batch = shader.batch(4);
    for lane in 0..4 {
        batch.set_global("s", lane, &[lane as f32]);
    }
    batch.set_param("k", 0, &[1.0]);
    shader.shade(&mut batch);
    // Lanes 0..2 index in range; lane 3's index 3 is clamped to the last element (the interpreter's
    // rule) and reported once, with its place.
    let got: Vec<f32> = (0..4).map(|l| batch.global("Ci", l).expect("Ci")[0]).collect();
    assert_eq!(got, vec![1.0, 2.0, 3.0, 3.0]);
    let errors = shader.runtime_errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].starts_with("an array index at checks.sl:3:") && errors[0].ends_with("was clamped"),
        "{errors:?}"
    );
    // In range everywhere: nothing to report.
    batch.set_param("k", 0, &[0.5]);
    shader.shade(&mut batch);
    assert!(shader.runtime_errors().is_empty());
}

/// Runs `src` in both back ends over `lanes` lanes (agreeing lane by lane, `common::differential`)
/// and once more in each; returns the JIT's batch, its runtime errors (of both runs, each place
/// once) and the interpreter's result.
fn strings_in_both(src: &str, lanes: usize) -> (jit::BatchData, Vec<String>, interp::RunResult) {
    let shader = compiled_with_sources(src, 1 << 20);
    let m = module(src);
    common::differential(&m, &shader, lanes, 1, 0.0);
    let mut batch = shader.batch(lanes);
    shader.shade_with(&mut batch, &mut TestHost::default());
    let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
    let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
    (batch, shader.runtime_errors(), r)
}

/// A string that doubles 40 times stops at `MAX_STRING_LEN` bytes, cut in both back ends (by
/// `concat`, by `format` and in the text `printf` prints), each place reported once.
#[test]
fn strings_longer_than_the_limit_are_cut_and_reported() {
    use rtsl_compiler::shadeops::format::MAX_STRING_LEN;
    let src = "surface doubling(output string w = \"\"; output string f = \"\";) {\n  float i;\n  w = \"ab\";\n  \
               for (i = 0; i < 40; i += 1) w = concat(w, w);\n  f = format(\"%s!\", w);\n  printf(\"%s%s\", w, w);\n}\n";
    let (batch, errors, r) = strings_in_both(src, 5);
    let w = batch.string_param("w").expect("w");
    assert_eq!(w.len(), MAX_STRING_LEN);
    assert!(w.bytes().enumerate().all(|(i, b)| b == if i % 2 == 0 { b'a' } else { b'b' }));
    assert_eq!(batch.string_param("f"), Some(w));
    assert_eq!(r.params.iter().map(|(_, v)| v.s().len()).collect::<Vec<_>>(), vec![MAX_STRING_LEN; 2]);
    let mut errors = errors;
    errors.sort();
    let cut = |at: &str| format!("a string made at checks.sl:{at} was longer than {MAX_STRING_LEN} bytes and was cut");
    assert_eq!(errors, vec![cut("4:35"), cut("5:7"), cut("6:3")]);
    let limits: Vec<_> = r.string_limits.iter().map(|(l, s)| (*l, s.start)).collect();
    let starts =
        [src.find("concat").expect("concat"), src.find("format").expect("format"), src.find("printf").expect("printf")];
    assert_eq!(limits, starts.map(|s| (interp::StringLimit::Cut, s as u32)).to_vec());
}

/// Past `STRING_BYTES_BUDGET` of strings made in a batch (a run of the interpreter), new strings
/// are empty, in both back ends alike, and the place is reported once.
#[test]
fn strings_past_the_batch_budget_are_empty_and_reported() {
    use rtsl_compiler::shadeops::format::{MAX_STRING_LEN, STRING_BYTES_BUDGET, STRING_OVERHEAD};
    // `big` is exactly `MAX_STRING_LEN` bytes; each `x` is a different string of that length.
    let src =
        "surface many(output varying float n = 0; output string last = \"\";) {\n  string big = \"abcdefgh\";\n  \
               float i;\n  for (i = 0; i < 13; i += 1) big = concat(big, big);\n  for (i = 0; i < 300; i += 1) {\n    \
               string x = concat(format(\"%d \", i), big);\n    if (x != \"\") n += 1;\n    last = x;\n  }\n}\n";
    let (batch, errors, r) = strings_in_both(src, 5);
    let n = batch.param("n", 0).expect("n")[0];
    let fit = (STRING_BYTES_BUDGET / (MAX_STRING_LEN + STRING_OVERHEAD)) as f32;
    assert!(n < fit && n > fit - 5.0, "{n} strings made, {fit} fit in the budget");
    assert_eq!(batch.string_param("last"), Some(""));
    assert_eq!(r.params[0].1, Value::Float(n), "the interpreter stops at the same string");
    assert!(
        errors.contains(&format!(
        "a string made at checks.sl:6:16 was left empty: the batch's strings took more than {STRING_BYTES_BUDGET} bytes"
    )),
        "{errors:?}"
    );
    assert!(r.string_limits.iter().any(|(l, _)| *l == interp::StringLimit::Dropped));
}

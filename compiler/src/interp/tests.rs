use super::*;
use crate::compile_source;

fn run_src(src: &str, bound: &[(&str, Value)]) -> (ShadingPoint, RunResult, TestHost) {
    let c = compile_source("test.sl", src, &crate::Options::default());
    assert!(c.ok(), "does not compile:\n{}", c.render());
    let m = c.module.expect("compiles");
    let kind = m.shader.as_ref().map(|s| s.kind).unwrap_or(ShaderKind::Surface);
    let mut point = ShadingPoint::new(kind);
    let mut host = TestHost::default();
    let r = run(&m, bound, &mut point, &mut host, Limits::default()).expect("runs");
    (point, r, host)
}

fn ci(p: &ShadingPoint) -> V3 {
    p.get("Ci").map(Value::v3).unwrap_or_default()
}

fn close(a: V3, b: V3) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5)
}

#[test]
fn matte_lit_by_the_test_host() {
    let src = include_str!("../../../stdlib_shaders/surface/matte.sl");
    let (p, _, _) = run_src(src, &[]);
    // Ka * ambient (0.1) + Kd * diffuse (the distant light straight on) = 1 + 0.1.
    assert!(close(ci(&p), [1.1; 3]), "{:?}", ci(&p));
    let (p, _, _) = run_src(src, &[("Kd", Value::Float(0.5))]);
    assert!(close(ci(&p), [0.6; 3]), "{:?}", ci(&p));
}

#[test]
fn control_flow_functions_and_outputs() {
    let src = r#"
        float twice(float x; output float y) { y = x + 1; return 2 * x; }
        surface t(output varying float o = 0; float n = 5;)
        {
            float acc = 0, i, j, extra;
            for (i = 0; i < n; i += 1) {
                for (j = 0; j < n; j++) {
                    if (j == 2) continue;
                    if (i == 3) break 2;
                    acc += 1;
                }
            }
            float arr[3] = {1, 2, 3};
            arr[1] = twice(arr[2], extra);
            float scale = 10;
            float scaled(float x) { extern float scale; scale += 1; return x * scale; }
            o = acc * 1000 + arr[1] * 100 + extra * 10 + scaled(1) - 11 + scale - 11;
            Ci = color "hsv" (0, 0, 1);
            printf("%f done\n", acc);
        }
    "#;
    let (p, r, host) = run_src(src, &[]);
    // 3 outer iterations x 4 inner counts (j = 2 skipped), arr[1] = 6, extra = 4, scale ends at 11.
    assert_eq!(r.params[0], ("o".to_string(), Value::Float(12.0 * 1000.0 + 600.0 + 40.0 + 11.0 - 11.0 + 0.0)));
    assert!(close(ci(&p), [1.0; 3]), "value 1, saturation 0 is white: {:?}", ci(&p));
    assert_eq!(host.printed.len(), 1);
    assert!(host.printed[0].starts_with("12"), "{:?}", host.printed);
}

#[test]
fn light_loops_and_cones() {
    let src = r#"
        surface t()
        {
            color sum = 0;
            float count = 0;
            illuminance(P, N, radians(10)) { sum += Cl; count += 1; }
            illuminance(P, -N, radians(10)) { count += 100; }
            Ci = sum + count;
        }
    "#;
    let (p, _, _) = run_src(src, &[]);
    assert!(close(ci(&p), [2.0; 3]), "one light within the cone, none behind: {:?}", ci(&p));
}

/// Runs `src` with a loop budget of `loops` iterations; returns `Ci`'s first component and where
/// loops were stopped (as byte offsets).
fn run_budgeted(src: &str, loops: u32) -> (f32, Vec<u32>) {
    let c = compile_source("t.sl", src, &crate::Options::default());
    let m = c.module.expect("compiles");
    let mut point = ShadingPoint::new(ShaderKind::Surface);
    let limits = Limits { loop_iterations: loops, ..Limits::default() };
    let r = run(&m, &[], &mut point, &mut TestHost::default(), limits).expect("runs");
    let ci = point.get("Ci").expect("Ci").clone();
    (ci.f(), r.stopped_loops.iter().map(|s| s.start).collect())
}

#[test]
fn runaway_loops_are_stopped_and_the_shader_goes_on() {
    let (ci, stopped) = run_budgeted("surface t() { float x = 0; while (1) { x += 1; } Ci = x; }", 1000);
    assert_eq!(ci, 1000.0);
    assert_eq!(stopped.len(), 1);
}

#[test]
fn the_loop_budget_holds_for_the_whole_run_not_per_loop() {
    // Nested: the inner loop uses up the budget; the outer loop stops at its next test instead of
    // entering the inner one again for another budget's worth.
    let (ci, stopped) =
        run_budgeted("surface t() { float x = 0; while (1) { while (1) { x += 1; } x += 1000000; } Ci = x; }", 1000);
    assert_eq!(ci, 1000000.0 + 999.0);
    assert_eq!(stopped.len(), 2, "both loops are reported");
    // In sequence: the first loop's 600 iterations (and its failing test) count against the second.
    let (ci, _) = run_budgeted(
        "surface t() { float a = 0, b = 0, i; for (i = 0; i < 600; i += 1) a += 1;\n\
         for (i = 0; i < 600; i += 1) b += 1; Ci = a * 1000 + b; }",
        1000,
    );
    assert_eq!(ci, 600.0 * 1000.0 + 399.0);
    // Loops in called functions share the counter.
    let (ci, _) = run_budgeted(
        "float spin() { float n = 0; while (1) n += 1; return n; }\n\
         surface t() { Ci = spin() + spin(); }",
        1000,
    );
    assert_eq!(ci, 1000.0);
}

/// A point with screen derivatives of `u` and `v`: `u_x, u_y, v_x, v_y` = 0.3, 0.1, -0.05, 0.2.
fn uv_point(u: f32, v: f32) -> ShadingPoint {
    let mut p = ShadingPoint::new(ShaderKind::Surface);
    p.set("u", Value::Float(u));
    p.set("v", Value::Float(v));
    p.set_derivs("u", Value::Float(0.3), Value::Float(0.1));
    p.set_derivs("v", Value::Float(-0.05), Value::Float(0.2));
    p.set("du", Value::Float(0.01));
    p.set("dv", Value::Float(0.02));
    p.set("dPdu", Value::Triple([1.0, 0.0, 0.0]));
    p.set("dPdv", Value::Triple([0.0, 1.0, 0.0]));
    p
}

fn run_point(src: &str, point: &mut ShadingPoint) -> RunResult {
    let c = compile_source("test.sl", src, &crate::Options::default());
    assert!(c.ok(), "does not compile:\n{}", c.render());
    let m = c.module.expect("compiles");
    run(&m, &[], point, &mut TestHost::default(), Limits::default()).expect("runs")
}

fn out(r: &RunResult, name: &str) -> Value {
    r.params.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).expect("output")
}

#[test]
fn derivatives_of_an_analytic_surface() {
    // P = (u, v, uv): Du(P) = (1, 0, v), Dv(P) = (0, 1, u), calculatenormal = (-v, -u, 1),
    // area = du dv |(-v, -u, 1)|; through a user function, a loop and an array.
    let src = r#"
        point surf(float a, b) { return point(a, b, a * b); }
        surface t(output varying vector pu = 0, pv = 0; output varying normal n = 0;
                  output varying float ar = 0, dd = 0, fs = 0, ds = 0;)
        {
            point q = surf(u, v);
            float k, acc = 0, arr[2];
            for (k = 0; k < 3; k += 1) acc += u * u;
            arr[1] = acc;
            pu = Du(q);
            pv = Dv(q);
            n = calculatenormal(q);
            ar = area(q);
            dd = Deriv(arr[1], u);
            fs = filterstep(0.5, u * 10);
            ds = Du(s) + Dv(sin(u) * 2);
        }
    "#;
    let (u, v) = (0.25, 0.75);
    let r = run_point(src, &mut uv_point(u, v));
    let near = |a: V3, b: V3| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
    assert!(near(out(&r, "pu").v3(), [1.0, 0.0, v]), "{:?}", out(&r, "pu"));
    assert!(near(out(&r, "pv").v3(), [0.0, 1.0, u]), "{:?}", out(&r, "pv"));
    assert!(near(out(&r, "n").v3(), [-v, -u, 1.0]), "{:?}", out(&r, "n"));
    let want = 0.01 * 0.02 * (v * v + u * u + 1.0f32).sqrt();
    assert!((out(&r, "ar").f() - want).abs() < 1e-8, "{:?} vs {want}", out(&r, "ar"));
    // d(3u^2)/du = 6u.
    assert!((out(&r, "dd").f() - 6.0 * u).abs() < 1e-5, "{:?}", out(&r, "dd"));
    // Width |10 du| = 0.1: (2.5 - 0.5) / 0.1 + 0.5 clamps to 1.
    assert_eq!(out(&r, "fs").f(), 1.0);
    // s has no derivatives here; Dv(2 sin u) = 0.
    assert!(out(&r, "ds").f().abs() < 1e-6, "{:?}", out(&r, "ds"));

    // The orientation follows Ng: with Ng against dPdu ^ dPdv the normal flips.
    let mut p = uv_point(u, v);
    p.set("Ng", Value::Triple([0.0, 0.0, -1.0]));
    let r = run_point(src, &mut p);
    assert!(near(out(&r, "n").v3(), [v, u, -1.0]), "{:?}", out(&r, "n"));

    // Renderer-supplied derivatives of P itself (a plane x = 2u, y = 3v).
    let src = "surface t(output varying vector pu = 0;) { pu = Du(P) + Dv(P); }";
    let mut p = uv_point(u, v);
    p.set_derivs("P", Value::Triple([0.6, -0.15, 0.0]), Value::Triple([0.2, 0.6, 0.0]));
    let r = run_point(src, &mut p);
    assert!(near(out(&r, "pu").v3(), [2.0, 3.0, 0.0]), "{:?}", out(&r, "pu"));
}

#[test]
fn gather_runs_body_for_hits_and_else_for_misses() {
    // The test host's ceiling is 10 above the point: a ray straight up hits it at length 10, a ray
    // straight down misses; a cone of 0.5 radians around +z hits at 10 / cos(angle).
    let src = r#"
        surface t(output varying float hits = 0, misses = 0, total = 0, longest = 0, pattern = 0;
                  output varying color seen = 0; vector axis = vector(0, 0, 1); float cone = 0;
                  float n = 5; float maxdist = 0;)
        {
            float len = -1;
            color c = 0;
            vector d = 0;
            gather("illuminance", P, axis, cone, n, "ray:length", len, "surface:Ci", c,
                   "ray:direction", d, "maxdist", maxdist) {
                hits += 1;
                total += len;
                longest = max(longest, len);
                seen += c;
            } else {
                misses += 1;
                total += zcomp(d);
            }
            gather("samplepattern", P, axis, cone, n, "ray:direction", d) {
                pattern += zcomp(d);
            }
        }
    "#;
    let param = |r: &RunResult, name: &str| match r.params.iter().find(|(n, _)| n == name) {
        Some((_, Value::Float(x))) => *x,
        other => panic!("{name}: {other:?}"),
    };
    let (_, r, _) = run_src(src, &[]);
    assert_eq!((param(&r, "hits"), param(&r, "misses")), (5.0, 0.0));
    assert_eq!(param(&r, "total"), 50.0);
    assert_eq!(param(&r, "pattern"), 5.0, "samplepattern runs every sample without tracing");
    // Straight down: every sample misses, and the else branch sees the direction (0, 0, -1).
    let (_, r, _) = run_src(src, &[("axis", Value::Triple([0.0, 0.0, -1.0])), ("n", Value::Float(2.5))]);
    assert_eq!((param(&r, "hits"), param(&r, "misses"), param(&r, "total")), (0.0, 3.0, -3.0));
    // A cone: every length lies between 10 and 10 / cos(0.5); maxdist 10.5 cuts the longest.
    let cone = [("cone", Value::Float(0.5)), ("n", Value::Float(64.0))];
    let (_, r, _) = run_src(src, &cone);
    let longest = param(&r, "longest");
    assert!(longest > 10.5 && longest <= 10.0 / 0.5f32.cos() + 1e-3, "{longest}");
    assert!(param(&r, "pattern") > 64.0 * 0.5f32.cos() && param(&r, "pattern") < 64.0);
    let (_, r, _) = run_src(src, &[cone[0].clone(), cone[1].clone(), ("maxdist", Value::Float(10.5))]);
    assert!(param(&r, "longest") <= 10.5 && param(&r, "misses") > 0.0 && param(&r, "hits") > 0.0);
    assert_eq!(param(&r, "hits") + param(&r, "misses"), 64.0);
}

#[test]
fn bump_perturbs_the_normal_across_a_height_step() {
    // The test host's textures are an 8x8 checkerboard: channel 0 is 1 in white cells and 0 in
    // black ones. Just left of s = 1/8 a step of `BUMP_STEP` crosses from white to black, so the
    // height falls by 1 over the step; mid-cell nothing changes; an unreadable map is flat.
    let src = r#"
        surface t(string map = "bumps"; output varying normal o = 0;)
        {
            o = bump(map, normal(0, 0, 1), vector(1, 0, 0), vector(0, 1, 0));
        }
    "#;
    let c = compile_source("test.sl", src, &crate::Options::default());
    let m = c.module.expect("compiles");
    let run_at = |s: f32, map: &str| {
        let mut point = ShadingPoint::new(ShaderKind::Surface);
        point.set("s", Value::Float(s));
        point.set("t", Value::Float(0.01));
        let bound = [("map", Value::String(map.into()))];
        let r = run(&m, &bound, &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
        r.params[1].1.v3()
    };
    assert_eq!(run_at(0.05, "bumps"), [0.0, 0.0, 1.0]);
    assert_eq!(run_at(0.05, "missing"), [0.0, 0.0, 1.0]);
    let n = run_at(0.125 - geom::BUMP_STEP / 2.0, "bumps");
    // h_s = -1 / step: N + h_s (n x dPdt) = (0, 0, 1) - (1/step) * (-1, 0, 0).
    assert!((n[0] - 1.0 / geom::BUMP_STEP).abs() < 1.0 && n[1] == 0.0 && n[2] == 1.0, "{n:?}");
}

#[test]
fn the_standard_pattern_headers_filter_by_the_box() {
    // Each filtered function is the average of its unfiltered one over [x - dx/2, x + dx/2].
    let src = "#include \"patterns.h\"\n\
               surface s(output float train = 0, train_half = 0, pulse_in = 0, pulse_edge = 0, absolute = 0, \
               stepped = 0) {\n\
                 train = filteredpulsetrain(0.25, 1, 0.3, 1);\n\
                 train_half = filteredpulsetrain(0.5, 1, 0.25, 0.5);\n\
                 pulse_in = filteredpulse(0.2, 0.8, 0.5, 0.2);\n\
                 pulse_edge = filteredpulse(0.2, 0.8, 0.8, 0.2);\n\
                 absolute = filteredabs(0, 1);\n\
                 stepped = filteredstep(0.5, 0.5, 0.4);\n\
               }\n";
    let (_, r, _) = run_src(src, &[]);
    let get = |name: &str| r.params.iter().find(|(n, _)| n == name).map(|(_, v)| v.f()).expect(name);
    // A whole period holds a quarter of pulse; [0, 0.5] lies inside the first half of the period.
    assert!((get("train") - 0.25).abs() < 1e-5, "{}", get("train"));
    assert!((get("train_half") - 1.0).abs() < 1e-5, "{}", get("train_half"));
    assert!((get("pulse_in") - 1.0).abs() < 1e-5);
    assert!((get("pulse_edge") - 0.5).abs() < 1e-5);
    // The mean of |x| over [-1/2, 1/2] is 1/4; a step averaged across its edge is 1/2.
    assert!((get("absolute") - 0.25).abs() < 1e-5, "{}", get("absolute"));
    assert!((get("stepped") - 0.5).abs() < 1e-5);
}

#[test]
fn filterstep_filters_the_interval_and_scales_the_width_rispec_gives() {
    // RISpec: the two-value form filters "in the range between the two values"; "width" (aka
    // "swidth") multiplies the width filtered. At u = 0.4 the one-value width of `u` is
    // |Du(u) du| + |Dv(u) dv| = |1 * 0.01| + |0 * 0.02| = 0.01.
    let src = r#"
        surface t(output varying float between = 0, reversed = 0, widened = 0, narrow = 0, wide = 0,
                  aliased = 0;)
        {
            between = filterstep(0.5, 0.4, 0.8);
            reversed = filterstep(0.5, 0.8, 0.4);
            widened = filterstep(0.5, 0.4, 0.8, "width", 2);
            narrow = filterstep(0.4025, u);
            wide = filterstep(0.41, u, "width", 4);
            aliased = filterstep(0.41, u, "swidth", 4);
        }
    "#;
    let mut p = ShadingPoint::new(ShaderKind::Surface);
    p.set("u", Value::Float(0.4));
    p.set("v", Value::Float(0.5));
    p.set_derivs("u", Value::Float(1.0), Value::Float(0.0));
    p.set_derivs("v", Value::Float(0.0), Value::Float(1.0));
    p.set("du", Value::Float(0.01));
    p.set("dv", Value::Float(0.02));
    let r = run_point(src, &mut p);
    let get = |name: &str| out(&r, name).f();
    // [0.4, 0.8]: three quarters at or above 0.5; widened about 0.6 to [0.2, 1.0]: five eighths.
    assert!((get("between") - 0.75).abs() < 1e-6, "{}", get("between"));
    assert!((get("reversed") - 0.75).abs() < 1e-6, "{}", get("reversed"));
    assert!((get("widened") - 0.625).abs() < 1e-6, "{}", get("widened"));
    // [0.395, 0.405] from 0.4025: a quarter; [0.38, 0.42] from 0.41: a quarter.
    assert!((get("narrow") - 0.25).abs() < 1e-4, "{}", get("narrow"));
    assert!((get("wide") - 0.25).abs() < 1e-4, "{}", get("wide"));
    assert_eq!(get("aliased"), get("wide"));
}

#[test]
fn transform_from_a_space_through_a_matrix_goes_into_current_space_first() {
    // The test host's "shader" space is translated by (1, 2, 3) from "current"; m scales by 2 and
    // then translates by (1, 0, 0). PRMan: the point goes "from the FROM coordinate system and then
    // through matrix M": (1, 1, 1) -> (2, 3, 4) -> (5, 6, 8). A scale does not commute with the
    // translation, so the other order, (3, 2, 2) -> (4, 4, 5), would show.
    let src = r#"
        surface t(output point moved = 0; output vector turned = 0;)
        {
            matrix m = matrix(2, 0, 0, 0,  0, 2, 0, 0,  0, 0, 2, 0,  1, 0, 0, 1);
            moved = transform("shader", m, point(1, 1, 1));
            turned = vtransform("shader", m, vector(1, 1, 1));
        }
    "#;
    let (_, r, _) = run_src(src, &[]);
    let get = |name: &str| r.params.iter().find(|(n, _)| n == name).map(|(_, v)| v.v3()).expect(name);
    assert!(close(get("moved"), [5.0, 6.0, 8.0]), "{:?}", get("moved"));
    // Vectors take no translation: (1, 1, 1) -> (1, 1, 1) -> (2, 2, 2).
    assert!(close(get("turned"), [2.0, 2.0, 2.0]), "{:?}", get("turned"));
}

#[test]
fn texture_blurs_in_s_and_t_apart() {
    // RISpec: "sblur" and "tblur" blur in one direction each. The test host averages its checker
    // (0.5) once a lookup's footprint and blur pass a cell, and point-samples it otherwise (1 at
    // (0.01, 0.01)).
    let src = r#"
        surface t(output varying float none = 0, in_s = 0, in_t = 0, both = 0;)
        {
            none = float texture("foo", 0.01, 0.01);
            in_s = float texture("foo", 0.01, 0.01, "sblur", 0.6);
            in_t = float texture("foo", 0.01, 0.01, "tblur", 0.6);
            both = float texture("foo", 0.01, 0.01, "blur", 0.6, "sblur", 0, "tblur", 0);
        }
    "#;
    let (_, r, _) = run_src(src, &[]);
    let get = |name: &str| r.params.iter().find(|(n, _)| n == name).map(|(_, v)| v.f()).expect(name);
    assert_eq!(get("none"), 1.0);
    assert_eq!(get("in_s"), 0.5);
    assert_eq!(get("in_t"), 0.5);
    assert_eq!(get("both"), 1.0, "sblur and tblur take the place of blur");
}

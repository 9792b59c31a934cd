//! What the JIT decides while it compiles, checked against the interpreter where it shades: the
//! chunk loop's handling of globals, loop invariants, hoisted uniform statements and batch
//! constants, uniform inference, the ray built-ins a shader calls, what it reports unsupported, and
//! the batch layout it records (globals needing no value on entry, derivatives read, resets).

mod common;

use common::{check, module};
use rtsl_compiler::back::jit;
use rtsl_compiler::{compile_source, Options};

#[test]
fn constant_surface() {
    check("surface constant() { Oi = Os; Ci = Os * Cs; }");
}

/// Globals the body assigns whole before reading (`Ci`, `Oi` here) start each chunk empty and are
/// blended back under the chunk's mask at its end; writes at the top level skip the merge. Writes
/// under varying control flow, in loops and in user functions, and component writes, must still
/// keep the lanes that did not run, and inactive lanes the sentinel.
#[test]
fn globals_assigned_before_read_keep_the_lanes_that_did_not_run() {
    check(
        r#"
        void tint(output color c; float f) { if (f > 0.3) c *= color(f, 1, 0.5); }
        void paint(float f) { if (f > 0.6) return; Ci = color(0, f, 0); }
        surface fresh(float k = 0.5;)
        {
            Ci = color(s, t, 1);
            if (s > k) Ci = color(t, 0, s); else Oi = 1;
            Oi = Ci * 0.5;
            setcomp(Ci, 1, t * 2);
            for (uniform float i = 0; i < 2; i += 1) Ci += color(i, 0, 0);
            float j = 0;
            while (j < s * 3) { Ci += 0.25; j += 1; }
            tint(Ci, u);
            paint(v);
            Oi = (t > 0.5) ? Oi : Ci;
        }
        "#,
    );
}

/// The chunk loop's uses of loop invariants (a sine's polynomial constants, the prologue's uniform
/// values, a space's matrix entries) load from memory beside each use (`invariants.rs`), and the
/// results still agree with the interpreter lane for lane, in full and partial chunks.
#[test]
fn loop_invariants_are_loaded_where_used_and_agree_with_the_interpreter() {
    let src = r#"
        surface waves(float freq = 7; float k = 0.5;)
        {
            uniform float scale = freq * 2 + k;
            float a = sin(s * scale) * cos(t * freq);
            vector d = vector "object" (a, s - k, t * scale);
            Ci = color(a, xcomp(d), zcomp(d) * k);
            Oi = (s > k) ? color(scale, 1, a) : Os;
        }
        "#;
    check(src);
    let shader = jit::compile(&module(src)).expect("compiles");
    assert!(shader.invariant_loads >= 10, "only {} invariant loads", shader.invariant_loads);
    let plain = jit::compile(&module("surface plain() { Ci = Cs; Oi = Os; }")).expect("compiles");
    assert!(plain.invariant_loads < shader.invariant_loads);
}

/// A compiled shader tells which built-ins that shoot rays it calls (the renderer runs a batch of
/// a shader that traces twice, to trace its rays together), also through a user function.
#[test]
fn compiled_shaders_tell_which_ray_built_ins_they_call() {
    let calls = |src: &str| jit::compile(&module(src)).expect("compiles").ray_calls();
    assert_eq!(calls("surface plain() { Ci = Cs; Oi = Os; }"), jit::RayCalls::default());
    let mirror =
        calls("color seen(vector d) { return trace(P, d); } surface m() { Ci = seen(reflect(I, N)); Oi = 1; }");
    assert_eq!(mirror, jit::RayCalls { trace: true, ..jit::RayCalls::default() });
    let shadows = calls("surface o() { Ci = transmission(P, P + N) * (1 - occlusion(P, N, 4)); Oi = 1; }");
    assert_eq!(
        shadows,
        jit::RayCalls { transmission: true, hemisphere: true, occlusion: true, ..jit::RayCalls::default() }
    );
    let bounced = calls("surface b() { Ci = indirectdiffuse(P, N, 8); Oi = 1; }");
    assert_eq!(bounced, jit::RayCalls { hemisphere: true, indirect: true, ..jit::RayCalls::default() });
}

#[test]
fn hoisted_uniform_statements_match_per_chunk_execution() {
    // The leading uniform statements run once per batch (`back/jit/hoist.rs`); each chunk must still
    // see what it would have computed itself: queries, a uniform `if`, a space's matrix, strings,
    // and locals that the rest of the body changes or that start at zero in every chunk.
    check(
        r#"
        surface t(float fov = 0; float k = 2; output float uo = 0; output varying float vo = 0;)
        {
            uniform float f = fov;
            if (f <= 0)
                option("FieldOfView", f);
            uniform float half = tan(radians(f) / 2) * k;
            uniform float fmt[3];
            option("Format", fmt);
            uniform point o = point "camera" (0, 0, 1);
            uniform string msg = format("%g", half);
            uniform float count;
            vo = s * half;
            count += 1;
            f = f * 2;
            uo = count + f + fmt[0] + xcomp(o) + (msg == "" ? 100 : 0);
            vo += count + t;
            Ci = Cs * half;
        }
        "#,
    );
    // Uniform calls inside varying statements, loops and divergent branches are evaluated once per
    // batch when they read only constants and parameters nothing writes; `k` is written, so
    // `sin(k)` is not.
    check(
        r#"
        surface t(float fov = 60; float k = 2; output varying float vo = 0;)
        {
            vo = s * tan(radians(fov) / 2) + xcomp(point "camera" (0, 0, 1));
            point q = point "camera" (s, t * fov, 1);
            vo += ycomp(q) + zcomp(normal "world" (t, 1, s)) + xcomp(Du(point "camera" (s * s, t, 0)));
            if (t > 0.5)
                vo += sin(k) + ycomp(vector "world" (1, fov, 0));
            k = k + 1;
            float i;
            for (i = 0; i < 3; i += 1)
                vo += cos(radians(fov)) * i + sin(k);
            Ci = Cs * vo;
        }
        "#,
    );
    // Hoisting stops at the first statement it cannot move: a varying one, `random()`, `printf`.
    check(
        r#"
        surface t(float k = 3; output varying float vo = 0;)
        {
            uniform float a = k * 2;
            float r = random();
            uniform float b = a * 3;
            vo = a + b + r + s;
        }
        "#,
    );
    check(
        r#"
        surface t(float k = 3; output varying float vo = 0;)
        {
            uniform float a = sin(k);
            printf("%f\n", a);
            uniform float b = cos(a);
            vo = a + b * t;
        }
        "#,
    );
}

/// In a camera shader the lens sample (`u`, `v`) is uniform: locals computed from it are inferred
/// uniform, the leading statements that map it onto a disc run once per batch, and the uniform
/// calls after them (`cos`, `sin` of those locals, a space cast) are batch constants. Every chunk
/// must still see what it would have computed itself, also when the body changes a local after
/// the hoisted statements (`phi`: its `cos` must not be taken from the prologue).
#[test]
fn the_lens_sample_is_uniform_in_camera_shaders_and_its_mapping_runs_once_per_batch() {
    let src = r#"
        camera t(float radius = 0.5; output varying float vo = 0;)
        {
            float a = 2 * u - 1, b = 2 * v - 1;
            float r = 0, phi = 0;
            if (abs(a) > abs(b)) {
                r = a;
                phi = (PI / 4) * (b / a);
            } else if (b != 0) {
                r = b;
                phi = PI / 2 - (PI / 4) * (a / b);
            }
            E = point "camera" (radius * r * cos(phi), radius * r * sin(phi), 0);
            I = point "camera" (s, t, 1) - E;
            phi = phi + 1;
            vo = cos(phi) * s + sin(radius * r);
            Ci = 1;
        }
    "#;
    let shader = jit::compile(&module(src)).expect("JIT");
    for name in ["u", "v"] {
        assert!(shader.layout().globals.iter().any(|g| g.name == name && !g.varying), "{name} is uniform");
    }
    check(src);
    // A uniform lens sample differentiates to zero.
    check(
        r#"
        camera t(output varying float o = 0;)
        {
            o = Du(s * u) + Dv(t + v) + Deriv(u * s, s);
            E = point "camera" (0, 0, 0);
            I = vector "camera" (s, t, 1);
            Ci = 1;
        }
        "#,
    );
    // Elsewhere the lens globals are varying: a uniform variable cannot hold them.
    let surface = compile_source("t.sl", "surface t() { uniform float a = u; Ci = a; }", &Options::default());
    assert!(!surface.ok(), "u is varying in a surface shader");
    let surface = jit::compile(&module("surface t() { Ci = u + v; }")).expect("JIT");
    assert!(surface.layout().globals.iter().filter(|g| g.name == "u" || g.name == "v").all(|g| g.varying));
}

#[test]
fn uniform_calls_into_uniform_storage() {
    // The callee's locals are inferred varying (for all call sites); called with uniform arguments
    // it is lowered in uniform mode, so its result may initialise a uniform variable.
    check(
        r#"
        float halvings(float x, lim) {
            float n = 0, y = x;
            while (y >= lim) { y /= 2; n += 1; if (n > 30) break; }
            return n;
        }
        surface t(float cellsize = 0.1; output varying float o = 0;)
        {
            uniform float h = halvings(1 / max(cellsize, 0.001), 1);
            o = h + halvings(s * 40, 1);
            Ci = color(o);
        }
        "#,
    );
}

/// A built-in the checker proves uniform (`depth` of a uniform point) that the JIT lowers through a
/// per-lane host call still initialises and assigns uniform variables, in the body and in a helper
/// whose result is uniform: the running lanes agree, so the first one's value is taken.
#[test]
fn uniform_built_ins_lowered_per_lane_into_uniform_storage() {
    check(
        r#"
        float depthof(point p) { float a = depth(p); return a; }
        surface t(output varying float o = 0;)
        {
            uniform float k = 0;
            float a = depth(point(0, 0, 3));
            k = a;
            uniform float d = depthof(point(0, 0, 1));
            if (s > 0.5) { o = k + d; } else { o = depthof(P); }
            Ci = color(o);
        }
        "#,
    );
}

/// A global is marked as needing no value on entry only when the shader assigns the whole of it in
/// a top-level statement that every lane reaches, before any statement that might read it (reads
/// after that see the shader's own value).
#[test]
fn entry_unused_marks_only_globals_assigned_before_any_use() {
    let cases: [(&str, &[(&str, bool)]); 8] = [
        (
            "camera c() { E = point \"camera\" (0, 0, 0); I = vector (s, t, 1); Ci = 1; }",
            &[("E", true), ("I", true), ("Ci", true)],
        ),
        ("camera c() { if (s > 0) I = vector (s, t, 1); E = point (0, 0, 0); }", &[("I", false), ("E", true)]),
        ("camera c() { E = point (0, 0, 0); I = I * 2; }", &[("I", false), ("E", true)]),
        ("camera c() { float k; for (k = 0; k < s; k += 1) I = vector (s, t, 1); }", &[("I", false)]),
        ("camera c() { I = vector (s, t, 1); setxcomp(I, 1); Ci = 1; Ci += 1; }", &[("I", true), ("Ci", true)]),
        // Read by an earlier statement, or by the assignment's own value.
        (
            "camera c() { I = vector (s, t, 1) * xcomp(E); E = point (0, 0, 0); Ci = Ci + 1; }",
            &[("I", true), ("E", false), ("Ci", false)],
        ),
        // Assigned under a condition first, or after a user function (which may read anything).
        (
            "float f() { return s; } camera c() { if (s > 0) E = point (1, 0, 0); E = point (0, 0, 0); \
             float x = f(); I = vector (x, t, 1); }",
            &[("E", false), ("I", false)],
        ),
        (
            "camera c() { E = point (0, 0, 0); I = vector (s, t, 1) - E; Ci = 1; Ci *= 0.5; }",
            &[("E", true), ("I", true), ("Ci", true)],
        ),
    ];
    for (src, want) in cases {
        let shader = jit::compile(&module(src)).expect("compiles");
        for &(name, unused) in want {
            let g = shader.layout().global(name).expect("the global is in the layout");
            assert_eq!(g.entry_unused, unused, "{name} in {src}");
        }
    }
}

/// A global is marked as having its derivatives read exactly when the code keeps tangents for it:
/// what a derivative built-in or a texture's footprint differentiates depends on, and `u`, `v` in
/// any module that calls a derivative built-in. A renderer fills only these.
#[test]
fn derivs_marks_the_globals_whose_derivatives_the_code_reads() {
    let cases: [(&str, &[(&str, bool)]); 4] = [
        (
            "surface m(string name = \"x.tex\") { Ci = color texture(name, s, t) * (N . I) + color(xcomp(P), 0, 0); }",
            &[("s", true), ("t", true), ("u", false), ("v", false), ("N", false), ("I", false), ("P", false)],
        ),
        (
            "surface m() { Ci = Du(P . N) + Dv(t); }",
            &[("P", true), ("N", true), ("t", true), ("u", true), ("v", true), ("s", false), ("I", false)],
        ),
        ("surface m() { float x = s * 2; Ci = Du(x); }", &[("s", true), ("t", false), ("P", false)]),
        ("surface m() { Ci = Cs * (N . I); }", &[("N", false), ("I", false), ("Cs", false)]),
    ];
    for (src, want) in cases {
        let shader = jit::compile(&module(src)).expect("compiles");
        for &(name, derivs) in want {
            // A global the shader does not use is not in the layout: nothing to fill.
            let got = shader.layout().global(name).is_some_and(|g| g.derivs);
            assert_eq!(got, derivs, "{name} in {src}");
        }
    }
}

/// A reset zeroes the derivatives the code reads, so an earlier batch's never reach a shader;
/// the rows nobody reads are left alone (zeroing them was most of a reset).
#[test]
fn a_reset_zeroes_the_derivatives_the_code_reads() {
    let m = module("surface m() { Ci = Du(s) + Dv(s); }");
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(4);
    for lane in 0..4 {
        assert!(batch.set_global_derivs("s", lane, &[0.5], &[0.25]));
    }
    batch.reset(4);
    let s = batch.global_slot("s").expect("s is varying");
    let stride = batch.raw_mut().stride;
    assert!(shader.layout().global("s").is_some_and(|g| g.derivs));
    assert_eq!(&batch.derivs()[2 * s * stride..2 * (s + 1) * stride], &[0.0; 8]);
}

/// `reset_except` keeps the slots a caller promises to fill and zeroes every other one, so a
/// value from an earlier call never reaches a slot nobody writes, at any batch size.
#[test]
fn a_reset_keeps_only_the_slots_its_caller_fills() {
    let m = module("surface s() { Ci = Cs * (N . I) + color(xcomp(P), 0, 0); }");
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(8);
    for lane in 0..8 {
        for name in ["P", "N", "I", "Cs"] {
            assert!(batch.set_global(name, lane, &[1.0, 2.0, 3.0]), "{name}");
        }
    }
    batch.set_active(3, false);
    let p = batch.global_slot("P").expect("P is varying");
    let kept = p..p + 3;
    let filled = std::slice::from_ref(&kept);
    batch.reset_except(8, filled);
    for lane in 0..8 {
        assert_eq!(batch.global("P", lane), Some(vec![1.0, 2.0, 3.0]), "lane {lane}");
        for name in ["N", "I", "Cs"] {
            assert_eq!(batch.global(name, lane), Some(vec![0.0; 3]), "{name}, lane {lane}");
        }
    }
    assert_eq!(batch.raw_mut().mask[3], -1, "every lane active again");
    // Another size moves the rows: the kept ones hold nothing meaningful (their caller writes
    // them), the others are zero again, and so are the kept ones' padding lanes.
    for lane in 0..8 {
        assert!(batch.set_global("N", lane, &[1.0, 2.0, 3.0]));
    }
    batch.reset_except(10, filled);
    for lane in 0..10 {
        for name in ["N", "I", "Cs"] {
            assert_eq!(batch.global(name, lane), Some(vec![0.0; 3]), "{name}, lane {lane}");
        }
    }
    let raw = batch.raw_mut();
    assert_eq!(raw.stride, 12);
    for k in 0..3 {
        assert_eq!(&raw.varying[(p + k) * 12 + 10..(p + k + 1) * 12], &[0.0, 0.0], "P's padding lanes");
    }
}

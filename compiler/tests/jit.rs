//! The packet JIT against the reference interpreter, lane by lane.
//!
//! Every test compiles a shader with both back ends, fills a batch with random inputs under a random
//! mask (inactive and padding lanes hold a NaN sentinel), shades it with the JIT and runs the
//! interpreter once per active lane with the same inputs. Outputs (written globals and output
//! parameters) must agree within `TOL` relative (the JIT evaluates the interpreter's operations in
//! the same order and calls the same scalar code for transcendental and noise functions, so they
//! agree exactly in practice; the tolerance only absorbs what a future polynomial may change), and
//! inactive lanes must keep the sentinel's exact bits.

mod common;

use proptest::prelude::*;
use rtsl_compiler::back::jit::{self, BatchData, CompiledShader, JitError};
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost, Value};
use rtsl_compiler::ir::Module;
use rtsl_compiler::{compile_file, compile_source, Options};
use std::time::Instant;

const TOL: f32 = 1e-5;
const SENTINEL: u32 = 0x7fc0_1234;

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    /// Uniform in [lo, hi).
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
}

fn module(src: &str) -> Module {
    let c = compile_source("jit_test.sl", src, &Options::default());
    assert!(c.ok(), "does not compile:\n{}", c.render());
    c.module.expect("module")
}

fn value_of(floats: &[f32], comps: usize) -> Value {
    match (comps, floats.len()) {
        (1, 1) => Value::Float(floats[0]),
        (3, 3) => Value::Triple([floats[0], floats[1], floats[2]]),
        (16, 16) => Value::Matrix(std::array::from_fn(|i| floats[i])),
        (c, _) => Value::Array(floats.chunks(c).map(|e| value_of(e, c)).collect()),
    }
}

fn floats_of(v: &Value) -> Vec<f32> {
    match v {
        Value::Float(x) => vec![*x],
        Value::Triple(t) => t.to_vec(),
        Value::Matrix(m) => m.to_vec(),
        Value::Array(items) => items.iter().flat_map(floats_of).collect(),
        other => panic!("unexpected value {other:?}"),
    }
}

fn close(a: f32, b: f32) -> bool {
    (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() <= TOL * b.abs().max(1.0)
}

/// Strings a random string parameter may hold: spaces (known and unknown), colour spaces, texture
/// names (readable and not), categories, message names.
const STRINGS: &[&str] =
    &["", "world", "object", "camera", "shader", "nowhere", "hsv", "rgb", "missing", "grid.tx", "Format"];

/// Random inputs for one lane: a global's value.
fn random_global(rng: &mut Rng, name: &str, comps: usize) -> Vec<f32> {
    if comps == 1 && !matches!(name, "s" | "t" | "u" | "v" | "du" | "dv") {
        return vec![rng.f(0.0, 1.0)];
    }
    match name {
        "s" | "t" | "u" | "v" => vec![rng.f(0.0, 1.0)],
        "du" | "dv" => vec![rng.f(0.001, 0.1)],
        "N" | "Ng" | "I" => {
            let v = [rng.f(-1.0, 1.0), rng.f(-1.0, 1.0), rng.f(-1.0, 1.0)];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-3);
            v.iter().map(|x| x / l).collect()
        }
        "Cs" | "Os" | "Ci" | "Oi" => vec![rng.f(0.0, 1.0), rng.f(0.0, 1.0), rng.f(0.0, 1.0)],
        _ => vec![rng.f(-2.0, 2.0), rng.f(-2.0, 2.0), rng.f(-2.0, 2.0)],
    }
}

/// A global's name and its d/dx and d/dy in one lane.
type LaneDerivs = (String, Vec<f32>, Vec<f32>);

/// Random screen-space derivatives (ray differentials) of a varying global: `u` mostly along x and
/// `v` along y (so the parameter Jacobian is well conditioned), small ones for everything else.
fn random_derivs(rng: &mut Rng, name: &str, comps: usize) -> (Vec<f32>, Vec<f32>) {
    match name {
        "u" => (vec![rng.f(0.005, 0.02)], vec![rng.f(-0.005, 0.005)]),
        "v" => (vec![rng.f(-0.005, 0.005)], vec![rng.f(0.005, 0.02)]),
        _ => ((0..comps).map(|_| rng.f(-0.05, 0.05)).collect(), (0..comps).map(|_| rng.f(-0.05, 0.05)).collect()),
    }
}

/// The test host with a point light among the random points, so that lanes differ in their
/// lights (direction, colour, which side of the surface).
fn lit_host() -> TestHost {
    TestHost { point_light: Some([0.5, 2.0, 1.0]), ..TestHost::default() }
}

/// Shades `lanes` random lanes with both back ends and compares. Returns how many lanes ran.
fn differential(m: &Module, shader: &CompiledShader, lanes: usize, seed: u64, bind_prob: f32) -> usize {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let layout = shader.layout().clone();
    let mut batch: BatchData = shader.batch(lanes);
    batch.fill_varying(f32::from_bits(SENTINEL));
    let mut active = vec![false; lanes];
    // Random masks: sometimes all on, sometimes sparse.
    let density = match seed % 3 {
        0 => 1.0,
        1 => 0.5,
        _ => 0.15,
    };
    for (l, a) in active.iter_mut().enumerate() {
        *a = rng.f(0.0, 1.0) < density;
        batch.set_active(l, *a);
    }
    // Uniform globals and parameters: the same for every lane.
    let mut uniform_bound: Vec<(String, Vec<f32>)> = Vec::new();
    for g in layout.globals.iter().filter(|g| !g.varying) {
        let v = if g.name == "ncomps" { vec![3.0] } else { vec![rng.f(0.0, 1.0)] };
        batch.set_global(g.name, 0, &v);
        uniform_bound.push((g.name.to_string(), v));
    }
    let mut bound_params: Vec<(String, Option<Vec<f32>>)> = Vec::new();
    let mut bound_strings: Vec<(String, String)> = Vec::new();
    for p in &layout.params {
        let bind = rng.f(0.0, 1.0) < bind_prob;
        if bind && p.string {
            let s = STRINGS[(rng.next() % STRINGS.len() as u64) as usize];
            assert!(batch.set_string_param(&p.name, s));
            bound_strings.push((p.name.clone(), s.to_string()));
            bound_params.push((p.name.clone(), None));
        } else if bind && !p.varying {
            let v: Vec<f32> = (0..p.floats()).map(|_| rng.f(-1.0, 2.0)).collect();
            batch.set_param(&p.name, 0, &v);
            bound_params.push((p.name.clone(), Some(v)));
        } else {
            bound_params.push((p.name.clone(), if bind { Some(Vec::new()) } else { None }));
        }
    }
    // Every lane its own `random()` seed, in both back ends.
    let seeds: Vec<u64> = (0..lanes).map(|_| rng.next()).collect();
    let mut lane_inputs: Vec<Vec<(String, Vec<f32>)>> = vec![Vec::new(); lanes];
    let mut lane_derivs: Vec<Vec<LaneDerivs>> = vec![Vec::new(); lanes];
    let mut lane_params: Vec<Vec<(String, Vec<f32>)>> = vec![Vec::new(); lanes];
    for l in 0..lanes {
        if !active[l] {
            continue;
        }
        assert_eq!(batch.set_seed(l, seeds[l]), layout.seed.is_some());
        for g in layout.globals.iter().filter(|g| g.varying) {
            let v = random_global(&mut rng, g.name, g.components);
            assert!(batch.set_global(g.name, l, &v));
            lane_inputs[l].push((g.name.to_string(), v));
            let (dx, dy) = random_derivs(&mut rng, g.name, g.components);
            // Only shaders that differentiate have a derivative buffer.
            assert_eq!(batch.set_global_derivs(g.name, l, &dx, &dy), layout.deriv_slots > 0);
            lane_derivs[l].push((g.name.to_string(), dx, dy));
        }
        for (p, (_, b)) in layout.params.iter().zip(&bound_params) {
            if p.varying && b.is_some() {
                let v: Vec<f32> = (0..p.floats()).map(|_| rng.f(-1.0, 2.0)).collect();
                assert!(batch.set_param(&p.name, l, &v));
                lane_params[l].push((p.name.clone(), v));
            }
        }
    }
    let mut jit_host = lit_host();
    shader.shade_with(&mut batch, &mut jit_host);
    let mut printed = Vec::new();

    let kind = m.shader.as_ref().expect("shader").kind;
    let mut ran = 0;
    for l in 0..lanes {
        if !active[l] {
            continue;
        }
        ran += 1;
        let mut point = ShadingPoint::new(kind);
        point.seed = seeds[l];
        for (name, v) in uniform_bound.iter().chain(&lane_inputs[l]) {
            point.set(name, value_of(v, v.len().min(3)));
        }
        for (name, dx, dy) in &lane_derivs[l] {
            point.set_derivs(name, value_of(dx, dx.len()), value_of(dy, dy.len()));
        }
        let mut bound: Vec<(&str, Value)> = Vec::new();
        for (p, (name, b)) in layout.params.iter().zip(&bound_params) {
            let floats = match b {
                Some(v) if !p.varying => v.clone(),
                Some(_) => lane_params[l].iter().find(|(n, _)| n == name).expect("bound").1.clone(),
                None => continue,
            };
            bound.push((name.as_str(), value_of(&floats, p.components)));
        }
        for (name, s) in &bound_strings {
            bound.push((name.as_str(), Value::String(s.as_str().into())));
        }
        let mut host = lit_host();
        let r = interp::run(m, &bound, &mut point, &mut host, Limits::default()).expect("the interpreter runs");
        printed.extend(host.printed);
        for g in layout.globals.iter().filter(|g| g.written) {
            let want = floats_of(point.get(g.name).expect("global"));
            let got = batch.global(g.name, l).expect("global");
            for (a, b) in got.iter().zip(&want) {
                assert!(close(*a, *b), "lane {l}: {} is {got:?}, the interpreter says {want:?}", g.name);
            }
        }
        for (p, (name, value)) in layout.params.iter().zip(&r.params) {
            if !p.output {
                continue;
            }
            if p.string {
                assert_eq!(batch.string_param(name), Some(value.s()), "lane {l}: output {name}");
                continue;
            }
            let want = floats_of(value);
            let got = batch.param(name, l).expect("param");
            for (a, b) in got.iter().zip(&want) {
                assert!(close(*a, *b), "lane {l}: output {name} is {got:?}, the interpreter says {want:?}");
            }
        }
    }
    // The same lines printed (the JIT prints statement by statement over a chunk's lanes, the
    // interpreter lane by lane: compared as multisets).
    let mut jit_printed = jit_host.printed;
    jit_printed.sort();
    printed.sort();
    assert_eq!(jit_printed, printed, "printf output");
    // Inactive and padding lanes keep the sentinel's bits in every varying slot.
    let stride = batch.stride();
    for (i, x) in batch.varying().iter().enumerate() {
        let lane = i % stride;
        if lane >= lanes || !active[lane] {
            assert_eq!(x.to_bits(), SENTINEL, "inactive lane {lane} of slot {} was written", i / stride);
        }
    }
    ran
}

fn check(src: &str) {
    let m = module(src);
    let shader = jit::compile(&m).unwrap_or_else(|e| panic!("JIT: {e}\n{src}"));
    for (seed, lanes) in [(1, 13), (2, 64), (3, 64), (4, 1), (5, 7), (6, 13)] {
        for bind in [0.0, 1.0] {
            differential(&m, &shader, lanes, seed, bind);
        }
    }
}

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
    assert_eq!(shadows, jit::RayCalls { transmission: true, hemisphere: true, ..jit::RayCalls::default() });
}

#[test]
fn float_and_triple_math() {
    check(
        r#"
        surface t(float Kd = 0.7; color tint = color(1, 0.5, 0.25); varying float w = 0.5;
                  output varying float o = 0; output varying vector ov = 0;)
        {
            normal Nf = faceforward(normalize(N), I);
            vector V = -normalize(I);
            float d = Nf . V;
            vector r = reflect(I, Nf);
            point q = P * 2 - vector(1, 2, 3);
            color c = Cs * tint * Kd + color(abs(d), sign(d - 0.1), floor(s * 4) / 4);
            c += color(ceil(t * 3), round(u * 5 - 2.5), sqrt(v)) * 0.1;
            c *= mix(color(1, 0, 0), color(0, 1, 0), smoothstep(0.2, 0.8, s));
            o = length(q) + distance(P, Ng) + inversesqrt(1 + v) + mod(s * 7, 1.5) + step(0.5, t);
            o += min(s, t, u) - max(s, t) + clamp(w * 3, 0.2, 0.9) + radians(degrees(v));
            o += xcomp(r) + ycomp(r) * zcomp(r) + comp(c, 1) + w;
            o += sin(s * 6) + cos(t * 6) + tan(u) + asin(v) + acos(u) + atan(s, t) + atan(v);
            o += exp(u) + log(1 + v) + log(2 + s, 10) + pow(s, 2.5);
            ov = (P ^ N) + vector noise(P * 3) + vector(cellnoise(s * 10, t * 10));
            ov += vector(noise(s * 4), noise(s, t), noise(P, u));
            setxcomp(ov, xcomp(ov) + ptlined(P, point(0, 0, 0), point(1, 1, 1)));
            setcomp(ov, 2, o * 0.5);
            Ci = c;
            Oi = Os * (1 - d * d);
        }
        "#,
    );
}

/// `sin` and `cos` of one value share one `rtsl_sincos` call within a block: pairs in one
/// expression, pairs split between a branch and the code after it, in varying and uniform branches
/// and in loops, agree with the interpreter (and pass Cranelift's verifier in debug builds).
#[test]
fn sine_and_cosine_of_one_value_share_a_call_only_within_a_block() {
    check(
        r#"
        surface t(float turns = 1.5; output varying float o = 0; output varying float o2 = 0;)
        {
            float a = s * 10 - 3;
            float x = 0;
            if (t > 0.5)
                x = cos(a);
            o = x + sin(a);
            if (turns > 1)
                x = cos(a);
            else
                x = sin(a) * 3;
            if (t < 0.3)
                x += sin(a);
            else
                x -= cos(a);
            o += x;
            uniform float k = turns * 2;
            uniform float y = 0;
            if (turns > 1)
                y = sin(k);
            o2 = y + cos(k) + sin(k);
            float z = 0;
            for (float i = 0; i < 3 * u; i += 1)
                z += cos(a + i) * sin(a + i);
            point q = point(cos(a) * 2, sin(a) * 2, sin(a) - cos(a * 2));
            Ci = color(xcomp(q), ycomp(q) + z, zcomp(q) + cos(a * 2) * sin(a * 2));
        }
        "#,
    );
}

/// Inline `sin`/`cos` (a chunk's own code, with the helper as the fallback for a chunk that has a
/// lane beyond its range) give the interpreter's bits exactly, whatever mix of lanes a chunk holds:
/// ordinary values, values near multiples of pi/4, the edges of the range, huge, infinite and NaN
/// arguments, signed zeros and subnormals.
#[test]
fn inline_sine_and_cosine_are_the_interpreters_bits_in_every_chunk() {
    use rtsl_compiler::shadeops::transcendental;
    let m =
        module("surface t(output varying float so = 0; output varying float co = 0;) { so = sin(s); co = cos(s); }");
    let shader = jit::compile(&m).expect("JIT");
    let quarter = std::f32::consts::FRAC_PI_4;
    let mut special = vec![0.0, -0.0, 1e-40, -1e-40, 8192.0, -8192.0, 8192.001, 1e9, f32::INFINITY, f32::NAN];
    special.extend((-40..40).map(|k| k as f32 * quarter));
    special.extend((-40..40).map(|k| f32::from_bits((k as f32 * quarter).to_bits() + 1)));
    let mut rng = Rng(77);
    let values: Vec<f32> = (0..4000)
        .map(|i| match i % 5 {
            0 => special[(rng.next() % special.len() as u64) as usize],
            1 => rng.f(-10.0, 10.0),
            2 => rng.f(-9000.0, 9000.0),
            _ => rng.f(-1.0, 1.0),
        })
        .collect();
    for lanes in values.chunks(64) {
        let mut batch: BatchData = shader.batch(lanes.len());
        for (l, x) in lanes.iter().enumerate() {
            assert!(batch.set_global("s", l, &[*x]));
        }
        shader.shade_with(&mut batch, &mut lit_host());
        for (l, x) in lanes.iter().enumerate() {
            let (so, co) = (batch.param("so", l).expect("so")[0], batch.param("co", l).expect("co")[0]);
            let (want_s, want_c) = (transcendental::sin(*x), transcendental::cos(*x));
            let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            assert!(same(so, want_s), "sin({x:e}) = {so:e}, the interpreter says {want_s:e}");
            assert!(same(co, want_c), "cos({x:e}) = {co:e}, the interpreter says {want_c:e}");
        }
    }
}

/// The inline sine's fallback for a chunk with a lane beyond its range goes through a trampoline
/// that keeps every register: the many values live across that call (here in registers, not
/// spilled) must arrive intact, in chunks that take the fallback and chunks that do not.
#[test]
fn values_live_across_the_sine_fallback_survive_it() {
    check(
        r#"
        surface keep(output varying float o = 0;)
        {
            float a = s * t, b = s + u, c = t - v, d = u * v, e = s / (1 + t), f = t * t + u;
            vector w = vector(a, b, c) + vector(d, e, f);
            float x = sin(s * 20000) + cos(t * 30000);
            float y = sin(u * 3) * cos(v * 2);
            Ci = color(x * a + b, y * c + d, e * f - x) + color(xcomp(w), ycomp(w), zcomp(w));
            o = a + b + c + d + e + f + x * y + xcomp(w) * ycomp(w) * zcomp(w);
        }
        "#,
    );
}

/// A cast by a uniform space lookup branches once around the transform: the known space's
/// transform, and for an unknown one the value unchanged, whichever the lookup answers.
#[test]
fn casts_of_varying_values_to_known_and_unknown_spaces() {
    check(
        r#"
        surface c(string sp = "object"; output varying float o = 0;)
        {
            vector a = vector "camera" (s, t, 1);
            point b = point "nowhere" (u, v, s);
            vector d = vector "nowhere" (t, -s, u);
            point e = transform(sp, P) + transform("nowhere", P);
            point f = point "world" (s * t, u, -v);
            o = xcomp(a) + ycomp(b) * zcomp(d) + xcomp(e) - zcomp(f) + ycomp(a) * xcomp(b);
            Ci = color(zcomp(a), xcomp(d), ycomp(e));
        }
        "#,
    );
}

/// A varying choice against zero (`c ? x : 0`, `c ? 0 : x`, a square root's guard) is an `and`
/// of the mask, not a blend: the same values either way round.
#[test]
fn choices_against_zero_keep_the_chosen_side() {
    check(
        r#"
        surface z(output varying float o = 0;)
        {
            float a = (s > 0.5) ? t : 0;
            float b = (t > 0.3) ? 0 : u;
            color c = (u > v) ? color(s, t, u) : color(0);
            color d = (v > 0.6) ? color(0) : color(v, s, t);
            Ci = color(a, b, sqrt(s - 0.5)) + c - d;
            o = step(0.4, s) * t + ((s < t) ? -u : 0);
        }
        "#,
    );
}

#[test]
fn divergent_if_else_and_ternary() {
    check(
        r#"
        surface t(output varying float o = 0;)
        {
            if (s > 0.5) {
                Ci = Cs;
                if (t < 0.3) Ci *= 2; else Ci = color(t, 0, 0);
            } else if (u > 0.2 && v < 0.8 || s < 0.1) {
                Ci = color(1, 0, 1);
            } else {
                Ci = 0;
            }
            o = s > t ? s - t : (u < 0.5 ? u : -v);
            float k = 0;
            k = (s > 0.5) ? (o += 1) : (o -= 1);
            Oi = color(k, o, !(s > 0.3) ? 1 : 0);
        }
        "#,
    );
}

#[test]
fn loops_with_varying_bounds_break_continue() {
    check(
        r#"
        surface t(float n = 6; output varying float o = 0; output varying float cnt = 0;)
        {
            float i, j, acc = 0;
            for (i = 0; i < s * 10; i += 1) {
                if (i > t * 8) break;
                if (mod(i, 2) == 1) continue;
                acc += i;
            }
            for (i = 0; i < n; i += 1) {
                for (j = 0; j < 5; j += 1) {
                    if (j > u * 5) continue 2;
                    if (i * j > v * 12) break 2;
                    cnt += 1;
                }
            }
            float x = s;
            while (x < 4) { x = x * 2 + 0.1; }
            o = acc + x;
            Ci = color(acc, cnt, i);
        }
        "#,
    );
}

#[test]
fn uniform_loops_and_branches() {
    check(
        r#"
        surface t(float n = 4; float gain = 2; output float uo = 0;)
        {
            float i, total = 0;
            for (i = 0; i < n; i += 1) {
                if (i == 2) continue;
                total += i * gain;
                if (total > 100) break;
            }
            uo = total;
            if (gain > 1) Ci = Cs * total; else Ci = Cs;
            Oi = color(total > 3 ? 1 : 0.5);
        }
        "#,
    );
}

#[test]
fn functions_with_outputs_and_returns() {
    check(
        r#"
        float twice(float x; output float y) { y = x + 1; return 2 * x; }
        float early(float x) {
            if (x > 0.5) return 1;
            float k;
            for (k = 0; k < 10; k += 1) {
                if (k * 0.1 > x) return k;
            }
            return -1;
        }
        color shade_it(color c; float a) { return c * a + color(a); }
        void bump_it(output point p; float amt) { p += amt * N; }
        surface t(output varying float o = 0; output varying float e = 0;)
        {
            float y;
            o = twice(s, y) + y * 10;
            e = early(t) + early(0.7);
            float scale = 10;
            float scaled(float x) { extern float scale; scale += 1; return x * scale; }
            o += scaled(u) + scale;
            point p = P;
            bump_it(p, 0.1);
            Ci = shade_it(Cs, v) + color(p);
            Oi = Os;
        }
        "#,
    );
}

#[test]
fn arrays_and_components() {
    check(
        r#"
        surface t(float w[3] = {0.2, 0.3, 0.5}; varying float vw[2] = {1, 2}; output varying float o = 0;)
        {
            float a[4] = {s, t, u, v};
            color cs[2] = {Cs, color(1, 0, 0)};
            float i = floor(s * 6) - 1;
            a[i] = a[i] * 10 + w[t * 3];
            a[2] += vw[u * 2];
            cs[1][2] = a[3];
            point p = P;
            p[1] = p[2] + p[t * 3];
            o = a[0] + a[1] + a[2] + a[3] + a[-1] + a[9] + cs[s * 2][1] + cs[1][2] + p[1];
            Ci = cs[1];
        }
        "#,
    );
}

#[test]
fn imager_and_volume_shaders() {
    check(
        r#"
        imager background(color background = 1;)
        {
            Ci += (1 - alpha) * background;
            Oi = 1;
            alpha = 1;
        }
        "#,
    );
    check(
        r#"
        volume fogish(float distance = 1; color background = 0;)
        {
            float d = 1 - exp(-length(I) / distance);
            Ci = mix(Ci, background, d);
            Oi = mix(Oi, color(1, 1, 1), d);
        }
        "#,
    );
}

#[test]
fn unsupported_constructs_are_reported_not_panicked() {
    for src in [
        "surface t() { string n = \"maxdist\"; gather(\"illuminance\", P, N, 1, 4, n, 2) { Ci = 1; } }",
        "surface t() { string c = s > 0.5 ? \"a\" : \"b\"; illuminance(c, P) { Ci += Cl; } }",
    ] {
        let m = module(src);
        match jit::compile(&m) {
            Err(JitError::Unsupported(_)) => {}
            Err(e) => panic!("{src}: {e}"),
            Ok(_) => panic!("{src} compiled"),
        }
    }
}

#[test]
fn varying_strings_select_format_and_split_calls_per_string() {
    // Strings that differ between lanes: assigned under varying conditions, selected, compared,
    // built by format/concat from varying values, matched, passed to and returned from functions,
    // indexed from arrays by varying indices, and used as texture names, space names, colour
    // spaces and environment names (calls run once per distinct string).
    check(
        r#"
        string pick(float x; string a, b) { return x > 0.5 ? a : b; }
        surface t(string tex = "grid"; string sp = "camera"; output varying float o = 0;
                  output varying color oc = 0; output varying point op = 0;)
        {
            string names[3] = {"missing", tex, "other"};
            string n = names[clamp(floor(s * 3), 0, 2)];
            string space = "shader";
            if (t > 0.3) space = sp;
            if (t > 0.7) space = "nowhere";
            string cs = pick(u, "hsv", "rgb");
            string label = format("%d-%s", floor(v * 4), n);
            string both = concat(label, "/", space);
            o = (n == "missing" ? 1 : 0) + (n != tex ? 10 : 0) + match("^1-", label) * 100
                + match("camera$", both) * 1000 + (label == "2-other" ? 10000 : 0);
            oc = color texture(n, s, t) + ctransform(cs, "rgb", color(s, t, 0.5)) + color environment(n, vector(u, v, 1));
            op = transform(space, P) + transform(space, "world", P) + vector "object" (s, 0, 0);
            float x = texture(names[1], s, t) + float texture(n[0], t, s);
            o += x + comp(ctransform(cs, color(s, t, u)), 1);
            if (u > 0.8)
                printf("%s %s %f\n", n, label, s);
            Ci = oc;
        }
        "#,
    );
}

#[test]
fn bump_agrees_lane_by_lane_across_height_steps() {
    // Lanes straddling the test host's checkerboard edge at s = 1/8 (heights 1 then 0), where
    // `bump` differences across cells, and lanes inside a cell; random lanes go through `check`.
    let src = r#"
        surface t(string map = "bumps"; output varying normal o = 0;)
        {
            o = bump(map, normalize(N), dPdu, dPdv);
            Ci = color(o);
        }
    "#;
    check(src);
    let m = module(src);
    let shader = jit::compile(&m).expect("compiles");
    let step = rtsl_compiler::shadeops::geom::BUMP_STEP;
    let ss = [0.125 - step / 2.0, 0.125 - 2.0 * step, 0.125 + step / 2.0, 0.3, 0.25 - step / 4.0, 0.01, 0.99, 0.5];
    let mut batch = shader.batch(ss.len());
    let lane_globals = |s: f32| {
        [
            ("s", vec![s]),
            ("t", vec![0.01]),
            ("N", vec![0.2, 0.1, 1.0]),
            ("dPdu", vec![1.0, 0.0, 0.1]),
            ("dPdv", vec![0.0, 2.0, 0.0]),
        ]
    };
    for (l, s) in ss.iter().enumerate() {
        for (name, v) in lane_globals(*s) {
            batch.set_global(name, l, &v);
        }
    }
    shader.shade_with(&mut batch, &mut TestHost::default());
    let mut bumped = 0;
    for (l, s) in ss.iter().enumerate() {
        let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
        for (name, v) in lane_globals(*s) {
            point.set(name, value_of(&v, v.len()));
        }
        let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
        let want = r.params[1].1.v3();
        let got = batch.param("o", l).expect("o");
        assert_eq!(got, want.to_vec(), "lane {l} (s = {s})");
        bumped += usize::from(want != rtsl_compiler::shadeops::geom::normalize([0.2, 0.1, 1.0]));
    }
    assert_eq!(bumped, 2, "the two lanes less than a step short of an edge are bumped");
}

#[test]
fn point_clouds_and_photon_maps_return_zero_and_are_reported_once() {
    let src = r#"
        surface t(output varying float o = 0; output varying color c = 1;)
        {
            if (s > 2) o = bake3d("cloud.ptc", "", P, N, "value", s);
            o += texture3d("cloud.ptc", P, N, "value", o) + 1;
            c = photonmap("global", P, N);
        }
    "#;
    check(src);
    let m = module(src);
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(8);
    shader.shade_with(&mut batch, &mut TestHost::default());
    assert_eq!(batch.param("o", 3), Some(vec![1.0]));
    assert_eq!(batch.param("c", 5), Some(vec![0.0; 3]));
    let errors = shader.runtime_errors();
    // `bake3d` sits under a condition no lane meets: only the two calls that ran are reported.
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(errors[0].contains("`texture3d` at") && errors[1].contains("`photonmap` at"), "{errors:?}");
    assert!(errors.iter().all(|e| e.contains("not supported")), "{errors:?}");
    shader.shade_with(&mut batch, &mut TestHost::default());
    assert!(shader.runtime_errors().is_empty(), "reported once");
}

/// A shader calling every overload of `bi` once, with arguments of exactly the overload's types
/// (locals seeded from the globals, so values vary per lane), or `None` for built-ins that only
/// make sense elsewhere (message passing into light shaders and the like is covered by the corpus).
fn every_overload_shader(bi: rtsl_compiler::builtins::Builtin) -> String {
    use rtsl_compiler::builtins::signatures;
    use rtsl_compiler::ir::BaseType as T;
    fn name(t: Option<T>) -> &'static str {
        match t {
            Some(T::Color) => "color",
            Some(T::Point) => "point",
            Some(T::Vector) => "vector",
            Some(T::Normal) => "normal",
            Some(T::Matrix) => "matrix",
            Some(T::String) => "string",
            _ => "float",
        }
    }
    let mut body = String::new();
    let mut sum = String::from("0");
    for (k, sig) in signatures(bi).iter().enumerate() {
        let mut args = Vec::new();
        for (j, p) in sig.params.iter().enumerate() {
            let ty = name(p.ty);
            let var = format!("a{k}_{j}");
            let init = match p.ty {
                Some(T::String) => format!("\"{}\"", ["grid", "shader", "catmull-rom", "%f %g"][j % 4]),
                Some(T::Matrix) => "matrix \"shader\" 1".to_string(),
                Some(T::Color | T::Point | T::Vector | T::Normal) => format!("{ty}(s + {j}, t * 2 - 1, u + 0.5)"),
                _ => format!("s * {} + t - 0.25", j + 1),
            };
            if p.array {
                body.push_str(&format!("    {ty} {var}[4] = {{{init}, {init}, {init}, {init}}};\n"));
            } else {
                body.push_str(&format!("    {ty} {var} = {init};\n"));
            }
            args.push(var);
        }
        let call = format!("{}({})", bi.name(), args.join(", "));
        match sig.ret {
            T::Void => body.push_str(&format!("    {call};\n")),
            T::String => body.push_str(&format!("    string r{k} = {call};\n    o += match(\"1\", r{k});\n")),
            T::Matrix => {
                body.push_str(&format!("    matrix r{k} = {call};\n"));
                sum.push_str(&format!(" + comp(r{k}, 1, 2) + comp(r{k}, 3, 0)"));
            }
            T::Float => {
                body.push_str(&format!("    float r{k} = float {call};\n"));
                sum.push_str(&format!(" + r{k}"));
            }
            t => {
                let ty = name(Some(t));
                body.push_str(&format!("    {ty} r{k} = {ty} {call};\n"));
                sum.push_str(&format!(" + comp(r{k}, 0) + comp(r{k}, 2)"));
            }
        }
        for (j, p) in sig.params.iter().enumerate() {
            if p.output && !p.array && matches!(p.ty, None | Some(T::Float)) {
                sum.push_str(&format!(" + a{k}_{j}"));
            }
        }
    }
    format!("surface every(output varying float o = 0;)\n{{\n{body}    o += {sum};\n    Ci = o;\n}}\n")
}

#[test]
fn every_builtin_overload_agrees_with_the_interpreter() {
    use rtsl_compiler::builtins::Builtin;
    let mut failed = Vec::new();
    let mut ran = 0;
    for bi in Builtin::ALL {
        let src = every_overload_shader(*bi);
        let c = compile_source("every.sl", &src, &Options::default());
        let ok = c.ok();
        let rendered = c.render();
        let Some(m) = c.module.filter(|_| ok) else {
            failed.push(format!("{}: does not check\n{src}\n{rendered}", bi.name()));
            continue;
        };
        match jit::compile(&m) {
            Ok(shader) => {
                for seed in 0..2 {
                    differential(&m, &shader, 13, seed, 0.0);
                }
                ran += 1;
            }
            Err(e) => failed.push(format!("{}: {e}", bi.name())),
        }
    }
    assert!(failed.is_empty(), "{} of {} built-ins:\n{}", failed.len(), Builtin::ALL.len(), failed.join("\n"));
    assert_eq!(ran, Builtin::ALL.len());
}

#[test]
fn gather_samples_outputs_branches_and_loop_exits() {
    // The test host's ceiling (z = P.z + 10) is hit by rays with a positive z component: axes
    // along N (random) and cones from 0.3 to 2.3 radians give hits and misses in one chunk.
    // Varying sample counts (0 to 5, and NaN-free negatives), options, every output kind,
    // `break`/`continue` in both branches, a `return` from a function, and "samplepattern".
    check(
        r#"
        float firsthit(point p; vector d; float cone)
        {
            float len = -1;
            gather("illuminance", p, d, cone, 8, "ray:length", len) {
                return len;
            }
            return -2;
        }
        surface t(float Kd = 0.5; string dist = "cosine"; output varying float o = 0;
                  output varying color oc = 0; output varying vector ov = 0;)
        {
            color hitc = 0, sum = 0, opac = 0;
            float len = 0, nhit = 0, nmiss = 0, k = 0;
            vector dir = 0; point org = 0, hp = 0; normal hn = 0;
            float arr[3] = {7, 8, 9};
            float cone = 0.3 + 2 * s;
            gather("illuminance", P, N, cone, floor(t * 6) - 0.5,
                   "surface:Ci", hitc, "surface:Oi", opac, "ray:length", len, "ray:direction", dir,
                   "ray:origin", org, "surface:P", hp, "surface:N", hn, "maxdist", 8 + 20 * u,
                   "bias", v * 0.01, "distribution", dist, "label", "x", "ray:length", arr[1],
                   "surface:Ci", len) {
                sum += hitc * opac + color(hp * 0.01 + hn);
                nhit += 1;
                if (len > 14) break;
                k += len;
            } else {
                nmiss += 1;
                ov += dir + org * 0.1;
                if (nmiss > 2) continue;
                k -= 1;
            }
            float pat = 0;
            gather("samplepattern", P, vector(0, 0, 1), 0.5, 3, "ray:direction", dir, "surface:Ci", hitc) {
                pat += zcomp(dir) + comp(hitc, 0);
            }
            o = nhit * 100 + nmiss * 10 + k + arr[1] + pat + firsthit(P, N, cone);
            oc = sum * Kd;
            ov += dir;
            Ci = oc;
        }
        "#,
    );
}

// ---- Random expression trees (cranelift-fuzzgen style, small and fast) ----

fn leaf() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("s".to_string()),
        Just("t".to_string()),
        Just("u".to_string()),
        Just("xcomp(P)".to_string()),
        Just("zcomp(N)".to_string()),
        Just("a".to_string()),
        Just("w".to_string()),
        // Thousandths from an integer range: proptest 1.12's f32 range sampler can trip its own
        // debug assertion.
        (-4000i32..4000).prop_map(|k| format!("({:.3})", k as f32 / 1000.0)),
    ]
}

fn expr() -> impl Strategy<Value = String> {
    leaf().prop_recursive(4, 24, 3, |inner| {
        prop_oneof![
            (inner.clone(), inner.clone(), prop::sample::select(vec!["+", "-", "*", "/"]))
                .prop_map(|(a, b, op)| format!("({a} {op} {b})")),
            inner.clone().prop_map(|a| format!("(-({a}))")),
            (
                inner.clone(),
                prop::sample::select(vec!["abs", "floor", "ceil", "round", "sqrt", "sin", "cos", "exp", "sign"])
            )
                .prop_map(|(a, f)| format!("{f}({a})")),
            (inner.clone(), inner.clone(), prop::sample::select(vec!["min", "max", "mod", "pow", "step"]))
                .prop_map(|(a, b, f)| format!("{f}({a}, {b})")),
            (inner.clone(), inner.clone(), inner.clone(), prop::sample::select(vec!["clamp", "mix", "smoothstep"]))
                .prop_map(|(a, b, c, f)| format!("{f}({a}, {b}, {c})")),
            (
                inner.clone(),
                inner.clone(),
                inner.clone(),
                inner.clone(),
                prop::sample::select(vec!["<", ">", "<=", ">=", "==", "!="])
            )
                .prop_map(|(a, b, c, d, op)| format!("(({a} {op} {b}) ? {c} : {d})")),
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, .. ProptestConfig::default() })]
    #[test]
    fn random_expressions_agree(e in expr(), seed in 0u64..1000) {
        let src = format!(
            "surface t(float a = 0.5; varying float w = 0.25; output varying float o = 0, od = 0;) \
             {{ o = {e}; od = Du(o) + Dv(o) * 0.5; Ci = color(o, o * 0.5, 1 - o); }}"
        );
        let m = module(&src);
        let shader = jit::compile(&m).unwrap_or_else(|err| panic!("JIT: {err}\n{src}"));
        differential(&m, &shader, 13, seed, 0.5);
        differential(&m, &shader, 16, seed + 1, 1.0);
    }
}

// ---- The shader library and corpus ----

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

/// A rough speed comparison; run with `cargo test --release -p rtsl-compiler --test jit -- --ignored --nocapture`.
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

// ---- Strings, matrices and the renderer's services (through `TestHost` for both back ends) ----

#[test]
fn strings_as_uniform_handles() {
    check(
        r#"
        surface t(string space = "world"; string other = "camera"; output varying float o = 0;
                  output string copy = "";)
        {
            string k = "hsv";
            if (space == "world") o = 1; else if (space != other) o = 2;
            if (k == "hsv" && other != "") o += 10;
            string pick = space == "object" ? space : other;
            copy = pick;
            o += (copy == other) ? 100 : 0;
            Ci = color(o);
        }
        "#,
    );
}

#[test]
fn matrices_arithmetic_and_components() {
    check(
        r#"
        surface t(matrix mp = 1; varying float w = 0.5; output varying float o = 0; output matrix um = 0;)
        {
            matrix a = matrix(1, 0, 0, 0, 0, 2, 0, 0, 0, 0, 3, 0, s, t, u, 1);
            matrix b = translate(rotate(scale(a, vector(2, 1, 0.5)), radians(30 * v), vector(0, 1, 1)), point(1, 2, 3));
            matrix c = a * b - mp / (b + 2);
            matrix id;
            setcomp(c, 3, 0, w);
            o = determinant(c) + comp(c, 1, 2) + comp(b, s * 4, t * 4) + determinant(id);
            o += (a == b) ? 1 : 0;
            o += (id != matrix 1) ? 10 : 0;
            point p = transform(c, P);
            vector q = vtransform(b, vector(1, 1, 1));
            normal n = ntransform(a, N);
            um = mp * 2;
            Ci = color(p) + color(q) + color(n) * o;
        }
        "#,
    );
}

/// Transforms by projective matrices (w of 0, 1, negative, infinite and ordinary, lane by lane, and
/// uniform) and by a uniform affine one, which the JIT computes in its own code: the same bits as
/// the interpreter.
#[test]
fn projective_transforms_divide_like_the_interpreter() {
    check(
        r#"
        surface t(float k = 0.25; output varying float o = 0;)
        {
            float w = (s < 0.2) ? 0 : (s < 0.4) ? 1 : (s < 0.6) ? 1 / (t - t) : (s < 0.8) ? -2 * u : u + 0.5;
            matrix pm = matrix(2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, s, t, u, w);
            matrix um = matrix(1, 0, 0, k, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 - k);
            point p = transform(pm, P) + transform(um, P) + transform(um, point(1, 2, 3));
            vector q = vtransform(pm, I) + vtransform(um, vector(s, t, u));
            // A uniform affine matrix (which skips the divide), also of a point with an infinite
            // coordinate (whose w is NaN).
            matrix ua = matrix(2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 2, 3, 1);
            point a = transform(ua, P) + transform(ua, point((s < 0.5) ? 1 / (t - t) : s, t, u));
            // Projective with a last entry of 1 all the same.
            matrix up = matrix(1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1);
            a += transform(up, P);
            o = comp(pm, 3, 3);
            Ci = color(p) + color(q) + color(a);
        }
        "#,
    );
}

#[test]
fn space_casts_and_transforms() {
    check(
        r#"
        surface t(string sp = "object"; output varying float o = 0;)
        {
            point a = point "object" (s, t, u);
            vector b = vector "camera" (1, 2, 3);
            normal n = normal "shader" N;
            point c = transform(sp, "current", P);
            color h = color "hsv" (s, 1, 1) + color "hsl" (t, u, v);
            matrix m = matrix "object" 1;
            matrix m2 = mtransform("camera", m) + mtransform("object", "world", m) + mtransform(sp, m);
            m2 += matrix "nowhere" m2;
            point d = transform("camera", P) + transform("object", "camera", P) + transform(sp, m, P);
            vector e = vtransform("world", sp, I) + ntransform("nowhere", N);
            // An unknown space leaves the value as it is (a uniform choice between vectors).
            e += vector(point "nowhere" (s, t, 1)) + vector "nowhere" (u, v, 1);
            color f = ctransform("hsv", Cs) + ctransform("hsv", "rgb", Cs) + ctransform("nowhere", Cs);
            o = depth(P) + comp(m2, 3, 2);
            Ci = color(a + b + n + c + d + e) + h + f;
        }
        "#,
    );
}

#[test]
fn lights_loops_and_shading_models() {
    check(
        r#"
        surface t(float Ks = 0.5; float roughness = 0.2; output varying float cnt = 0;)
        {
            normal Nf = faceforward(normalize(N), I);
            vector V = -normalize(I);
            color c = 0;
            illuminance(P, Nf, 1.5707964) {
                cnt += 1;
                c += Cl * (normalize(L) . Nf);
            }
            illuminance("specular", P) {
                if (s > 0.5) break;
                cnt += 10;
            }
            illuminance(P, vector(0, 0, 1), 0.1 + s) { cnt += 100; }
            Ci = c + ambient() + diffuse(Nf) + Ks * specular(Nf, V, roughness) + phong(Nf, V, 20);
            Oi = Os;
        }
        "#,
    );
}

#[test]
fn light_shaders_illuminate_and_solar() {
    check(
        r#"
        light spot(point from = point(0, 0, 0); vector axis = vector(0, 0, 1); float angle = 0.8;)
        {
            illuminate(from, axis, angle) {
                Cl = color(1, 0.5, 0.25) / (L . L + 1);
            }
        }
        "#,
    );
    check(
        r#"
        light pt(point from = point(0.2, 0.1, 0);)
        {
            illuminate(from) { Cl = color(length(L)); }
        }
        "#,
    );
    check(
        r#"
        light sun(vector to = vector(0, 0, -1);)
        {
            solar(to, 0) { Cl = color(1, 1, 0.9) * s; }
        }
        "#,
    );
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
fn textures_rays_and_messages() {
    check(
        r#"
        surface t(string tex = "grid.tx"; output varying float o = 0; output varying float found = 0;)
        {
            color c = texture(tex) + color texture(tex, s * 2, t) + color texture("missing", s, t, "fill", 0.5);
            float x = float texture(tex[1], s, t) + texture(tex, s, t, "channel", 2);
            c += color environment("sky", I) + color environment("missing", I, "fill", 0.25);
            x += shadow("shad", P) + float trace(P, N) + occlusion(P, N) + occlusion(P, N, 8);
            c += trace(P, reflect(I, N)) + transmission(P, point(0, 0, 0)) + indirectdiffuse(P, N, 4);
            x += float visibility(P, point(1, 1, 1)) + raydepth();
            color kd = 0;
            float fmt[3];
            string r = "";
            found = surface("Kd", kd) + option("Format", fmt) * 10 + rendererinfo("renderer", r) * 100;
            found += attribute("identifier:name", r) * 1000 + (r == "rtsl" ? 10000 : 0);
            if (shadername() != "") found += 100000;
            o = x + fmt[0] + fmt[2];
            Ci = c + kd;
        }
        "#,
    );
}

#[test]
fn shadow_lookups_pass_their_region_and_options() {
    // The test host's shadow() is a function of every field of the query (the point, the four
    // corners, each option), so the JIT and the interpreter agree only when both pass the same.
    check(
        r#"
        surface t(float b = 0.05; output varying float o = 0; output varying float o2 = 0;)
        {
            o = shadow("shad", P) + shadow("shad", P * 2, "bias", b, "samples", 4 + s);
            o += shadow("shad", P, "blur", 0.1, "tblur", 0.3 * t, "width", 2, "swidth", 0.5);
            o2 = shadow("shad", P, P + dPdu, P + dPdv, P + dPdu + dPdv, "sblur", 0.2);
            point q = P + vector(u, v, 0);
            if (u > 0.3)
                o2 += float shadow("shad", q, "twidth", 3);
            Ci = color shadow("shad", transform("shader", P));
        }
        "#,
    );
}

#[test]
fn incident_and_opposite_ask_the_volume_on_each_side() {
    // The test host answers "side" 1 inside and 2 outside, and "ior" inside only; the globals I and
    // Ng are random per lane, so lanes see both sides.
    check(
        r#"
        surface t(output varying float a = 0; output varying float b = 0; output varying float c = 0;)
        {
            float side = 0, ior = 0;
            a = incident("side", side) * 10 + side;
            b = opposite("side", side) * 10 + side;
            c = incident("ior", ior) + opposite("ior", ior) * 2 + ior + incident("side", ior);
            color nope = 0;
            if (incident("side", nope) == 0 && opposite("nosuch", side) == 0)
                c += 100;
            Ci = color(a, b, c);
        }
        "#,
    );
}

#[test]
fn texture3d_grid_lookups() {
    // The test host's grids are the ramp x/4 + y/2 + z/8; "missing" cannot be read (fill).
    check(
        r#"
        surface t(string grid = "ramp.grid"; output varying float a = 0; output varying color b = 0;)
        {
            a = texture3d(grid, P) + texture3d("missing", P * 2, "fill", 0.25 + s);
            if (u > 0.5)
                b = color texture3d(grid, transform("shader", P));
            else
                b = texture3d("missing", P);
            Ci = b + a;
        }
        "#,
    );
    let mut host = TestHost::default();
    use rtsl_compiler::interp::Services;
    assert_eq!(host.texture3d("ramp.grid", [4.0, 2.0, 8.0]), Some(3.0));
    assert_eq!(host.texture3d("missing", [0.0; 3]), None);
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

// ---- Splines, periodic noise, filterstep, random and string built-ins ----

#[test]
fn splines_all_bases_forms_and_shapes() {
    check(
        r#"
        surface t(string basis = "bezier"; float knots[5] = {0, 1, 0.5, 2, 1};
                  varying float vk[4] = {0, 1, 2, 3};
                  output varying float o = 0; output varying color oc = 0; output float uo = 0;)
        {
            float x = s * 1.4 - 0.2;
            o = spline(x, 0, 1, 4, 2, 3) + spline("catmull-rom", t, 1, 2, 3, 4);
            o += spline("bspline", x, 5, -1, 2, 0, 3, 7) + spline("b-spline", u, 0, 1, 2, 3);
            o += spline("bezier", x, 1, 5, -3, 2, 8, 0, 6) + spline("Bezier", v, 1, 5, -3, 2, 100);
            o += spline("hermite", x, 1, 0, 3, 0, 2, 1) + spline("linear", x, -100, 10, 20, 40, 100);
            o += spline("constant", x, 1, 2, 3, 4, 5, 6) + spline("nonsense", x, 0, 1, 2, 3);
            o += spline(basis, x, knots) + spline(x, knots) + spline("linear", t, vk) + spline(basis, x, s, t, u, v);
            float k3[3] = {7, 8, 9};
            o += spline(x, k3) + spline("bezier", x * 3, vk);
            uo = spline(basis, 0.3, knots) + spline("hermite", 0.7, 1, 0, 3, 0, 2, 1);
            color cols[6] = {color(1, 0, 0), color(0, 1, 0), color(0, 0, 1), Cs, color(s, t, u), color(0.5)};
            oc = spline(x, color(1, 0, 0), color(0, 1, 0), Cs, color(0, 0, 1))
                + spline("bspline", t, cols) + spline(basis, u, cols) + spline("linear", 0.5, cols);
            point p = spline("catmull-rom", v, P, point(1, 2, 3), point(0), point(-1, 1, 0), P * 2);
            if (s > 0.5) oc += color spline("constant", t, vector(1), vector(2), vector(3), vector(4));
            Ci = oc + color(p);
        }
        "#,
    );
}

#[test]
fn pnoise_every_form() {
    check(
        r#"
        surface t(float per = 4; output varying float o = 0; output varying vector ov = 0;)
        {
            o = pnoise(s * 8, per) + pnoise(s * 8, t * 8, per, 3) + pnoise(P * 3, point(per, 2, 5))
              + pnoise(P * 3, u * 4, point(2, per, 3), 2) + float pnoise(1.5, per);
            ov = vector pnoise(s * 8, per) + vector pnoise(s * 8, t * 8, per, 3)
               + vector pnoise(P * 3, point(per, 2, 5)) + vector pnoise(P * 3, u * 4, point(2, 3, 4), per);
            color c = color pnoise(P, point(1, 1, 1));
            Ci = c + color(o);
        }
        "#,
    );
}

#[test]
fn filterstep_with_explicit_widths() {
    check(
        r#"
        surface t(float w = 0.1; output varying float o = 0; output float uo = 0;)
        {
            o = filterstep(0.5, s, "width", w) + filterstep(0.5, t, "width", u * 0.5);
            o += filterstep(0.3, s, s + v * 0.2) + filterstep(0.5, t, t - 0.1, "filter", "box");
            o += filterstep(0.5, s, "width", 0) + filterstep(0.5, s, "width", -1);
            uo = filterstep(0.2, 0.25, "width", w) + filterstep(0.2, 0.25, 0.4);
            Ci = color(o);
        }
        "#,
    );
}

#[test]
fn random_per_lane_and_per_call() {
    check(
        r#"
        float jitter(float a) { return a + random() - 0.5; }
        surface t(output varying float o = 0; output varying float cnt = 0;)
        {
            o = random();
            if (s > 0.5) o += random() * 10;
            else { color c = random(); o += comp(c, 0) + comp(c, 2) * 100; }
            float i;
            for (i = 0; i < t * 5; i += 1) {
                if (random() > 0.5) { cnt += 1; continue; }
                o += jitter(i);
            }
            o += jitter(0.25);
            point p = point random();
            Ci = color(p) + color(random());
        }
        "#,
    );
}

#[test]
fn strings_format_concat_match_printf() {
    check(
        r#"
        surface t(string name = "quilt"; float k = 2; output string label = ""; output string f = "";
                  output varying float o = 0;)
        {
            uniform string a = concat("material(", name, ")");
            label = concat(a, "/", format("%d", k));
            f = format("%s %f %5.2f %c %p %m %g %s%%", name, k, 1 / 3, color(1, 0.5, 0.25), point(1, 2, 3),
                       matrix 1, k > 1, "");
            o = match("^q", name) + match("l.*t$", name) * 10 + match("x", "") * 100 + match("", name) * 1000;
            if (match("world", name) != 0) o += 5;
            printf("%s %f\n", label, k);
            if (s > 0.5) printf("lane at s=%f P=%p Cs=%c %s\n", s, P, Cs, f);
            printf("%f %d <%s>\n", t, k, a);
            Ci = color(o);
        }
        "#,
    );
}

#[test]
fn derivatives_agree_with_the_interpreter() {
    // Every derivative built-in, on values that reach them through the rules: arithmetic, user
    // functions (value, output and captured parameters, returns under varying conditions),
    // loops, arrays, selects, space casts, compound assignments and the built-ins with rules.
    check(
        r#"
        float wave(float x) { if (x > 0.5) return sin(x * 7); return cos(x * 3) * x; }
        void bend(output point p; float k) { p += vector(0, 0, k * xcomp(p) * ycomp(p)); }
        surface t(float amp = 0.3; output varying float o = 0; output varying vector ov = 0;
                  output varying normal on = 0; output varying float fa = 0;)
        {
            point q = P + N * amp * wave(s);
            bend(q, 2);
            float arr[3], i;
            for (i = 0; i < 3; i += 1) arr[i] = u * (i + 1) + v * v;
            float a = arr[1] * (s > 0.3 ? exp(t) : sqrt(abs(u - 0.5)));
            a += min(u, v, s) * max(t, u) + clamp(u * 3, 0.2, 0.9) + mix(s, t, v);
            vector dir = normalize(vector "object" (q)) * length(q - P);
            point w = transform("object", q);
            o = Du(a) + Dv(a) * 2 + Deriv(a, v) + Du(comp(dir, 1)) + filterstep(0.5, a);
            o += filterstep(0.3, u, "filter", "gaussian") + Dv(xcomp(w));
            ov = Du(dir) + Dv(q);
            on = calculatenormal(q);
            fa = area(q) + area(P);
            Ci = color(Du(s), Dv(t), Du(u) + Dv(v));
        }
        "#,
    );
}

#[test]
fn difference_rule_derivatives_agree_with_the_interpreter() {
    // noise, the space transforms and the other built-ins differentiated by a central difference
    // (`ir::deriv::has_difference_rule`), as bump mapping uses them.
    check(
        r#"
        surface t(float amp = 0.2; output varying normal nb = 0; output varying float o = 0;
                  output varying vector ov = 0;)
        {
            point pp = 4 * transform("object", P);
            float h = (float noise(pp) - .5) + .5 * (float pnoise(2 * pp, point(8, 8, 8)) - .5);
            vector n3 = vector noise(pp * 0.5);
            nb = calculatenormal(P + amp * h * normalize(N));
            o = Du(smoothstep(0.2, 0.8, u)) + Dv(distance(P, point(1, 2, 3)))
                + Du(spline(u, 0, 0.3, 0.9, 1)) + Dv(radians(degrees(v)))
                + Du(pow(u + 1, 2.5)) + Dv(log(v + 2)) + Du(tan(u)) + Dv(asin(v * 0.5))
                + Du(acos(u * 0.5)) + Dv(atan(v, u + 1)) + Du(inversesqrt(u + 1));
            ov = Du(vtransform("object", n3)) + Dv(reflect(normalize(I), normalize(N)))
                + Du(rotate(P, u, point(0, 0, 0), point(0, 1, 0)));
            Ci = color(o, 0, 1);
        }
        "#,
    );
}

#[test]
fn derivatives_of_an_analytic_surface() {
    // P = (u, v, uv) built from u and v: Du(P) = (1, 0, v), Dv(P) = (0, 1, u),
    // calculatenormal(P) = (-v, -u, 1) (Ng agrees with dPdu ^ dPdv), area = du dv |(-v, -u, 1)|.
    // Through built-ins with a difference rule: Du(smoothstep(-1, 2, u)) = 2 w (1 - w) with
    // w = (u + 1) / 3, up to the central difference's error; a noise bump turns the normal.
    let m = module(
        "surface t(output varying vector pu = 0, pv = 0; output varying normal n = 0; output varying float ar = 0;
                   output varying float sm = 0; output varying normal bn = 0;)
         { point q = point(u, v, u * v); pu = Du(q); pv = Dv(q); n = calculatenormal(q); ar = area(q);
           sm = Du(smoothstep(-1, 2, u));
           bn = calculatenormal(q + normal(0, 0, 1) * 0.2 * float noise(q * 4)); }",
    );
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(5);
    for l in 0..5 {
        let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
        assert!(batch.set_global("u", l, &[u]) && batch.set_global("v", l, &[v]));
        assert!(batch.set_global("du", l, &[0.01]) && batch.set_global("dv", l, &[0.02]));
        assert!(batch.set_global("dPdu", l, &[1.0, 0.0, 0.0]) && batch.set_global("dPdv", l, &[0.0, 1.0, 0.0]));
        assert!(batch.set_global("Ng", l, &[0.0, 0.0, 1.0]));
        assert!(batch.set_global_derivs("u", l, &[0.3], &[0.1]));
        assert!(batch.set_global_derivs("v", l, &[-0.05], &[0.2]));
    }
    // The raw layout a renderer fills: u's d/dy of lane 2.
    let (slot, stride) = (batch.global_slot("u").expect("u is varying"), batch.stride());
    assert_eq!(batch.derivs_mut()[(2 * slot + 1) * stride + 2], 0.1);
    shader.shade(&mut batch);
    let near = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
    for l in 0..5 {
        let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
        assert!(near(&batch.param("pu", l).unwrap(), &[1.0, 0.0, v]), "lane {l}: {:?}", batch.param("pu", l));
        assert!(near(&batch.param("pv", l).unwrap(), &[0.0, 1.0, u]), "lane {l}: {:?}", batch.param("pv", l));
        assert!(near(&batch.param("n", l).unwrap(), &[-v, -u, 1.0]), "lane {l}: {:?}", batch.param("n", l));
        let want = 0.01 * 0.02 * (v * v + u * u + 1.0f32).sqrt();
        assert!(near(&batch.param("ar", l).unwrap(), &[want]), "lane {l}: {:?}", batch.param("ar", l));
        let sm = batch.param("sm", l).unwrap()[0];
        let w = (u + 1.0) / 3.0;
        assert!((sm - 2.0 * w * (1.0 - w)).abs() < 0.01, "lane {l}: Du(smoothstep) {sm}");
    }
    let bumped = (0..5)
        .filter(|&l| {
            let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
            let bn = batch.param("bn", l).unwrap();
            bn.iter().zip([-v, -u, 1.0]).any(|(a, b)| (a - b).abs() > 1e-2)
        })
        .count();
    assert!(bumped >= 4, "the noise bump turned the normal on only {bumped} of 5 lanes");
    // Without derivatives (a fresh batch), every derivative is 0.
    let mut batch = shader.batch(4);
    shader.shade(&mut batch);
    assert_eq!(batch.param("pu", 0).unwrap(), vec![0.0; 3]);
}

#[test]
fn texture_footprints_from_derivatives() {
    // The test host averages a lookup whose footprint exceeds a checker cell, so the outputs depend
    // on the footprint both back ends pass: every form, with the width and blur options.
    check(
        r#"
        surface t(output varying color a = 0, b = 0, c = 0, d = 0; output varying float e = 0;)
        {
            a = texture("grid.tx");
            b = texture("grid.tx", s * 3, t * u * 4);
            c = texture("grid.tx", s, t, "width", 2 + 4 * u, "blur", v * 0.1);
            d = texture("grid.tx", s, t, s + 0.1 * u, t, s, t + 0.2 * v, s, t, "swidth", 1, "twidth", 3);
            e = float texture("grid.tx"[1], s * 2, t, "fill", 0.5);
        }
        "#,
    );
    let mut host = TestHost::default();
    use rtsl_compiler::interp::Services;
    let fp = interp::TextureFootprint { dsdx: 0.1, dtdx: 0.0, dsdy: 0.1, dtdy: 0.0, blur: 0.0 };
    assert_eq!(host.texture_filtered("grid.tx", 0.01, 0.01, &fp, 0, 1), Some(vec![0.5]));
}

// ---- Runtime checks ----

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
    shader.shade(&mut batch);
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

/// Found by `random_expressions_agree`: where no argument moves along a screen direction the
/// derivative is zero, also where the function is NaN (pow of a negative base); the JIT's central
/// difference gave NaN - NaN.
#[test]
fn a_zero_tangent_gives_a_zero_difference_derivative_even_where_the_function_is_nan() {
    let e = "pow(min(a, xcomp(P)), a)";
    let src = format!(
        "surface t(float a = 0.5; varying float w = 0.25; output varying float o = 0, od = 0;) \
         {{ o = {e}; od = Du(o) + Dv(o) * 0.5; Ci = color(o, o * 0.5, 1 - o); }}"
    );
    let m = module(&src);
    let shader = jit::compile(&m).unwrap_or_else(|err| panic!("JIT: {err}\n{src}"));
    differential(&m, &shader, 13, 213, 0.5);
    differential(&m, &shader, 16, 214, 1.0);
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

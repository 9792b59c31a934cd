//! Arithmetic in the packet JIT against the interpreter, lane by lane: float and triple math,
//! inline sine and cosine, choices, matrices, space casts and projective transforms, and random
//! expression trees (cranelift-fuzzgen style, small and fast).

mod common;

use common::{check, differential, lit_host, module, Rng};
use proptest::prelude::*;
use rtsl_compiler::back::jit::{self, BatchData};

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
/// lucille's `turb`: the JIT's four-lane helper gives the interpreter's bits, as a float and as a
/// colour, and its derivatives (a central difference, as `noise`) agree too.
#[test]
fn lucille_turb_matches_the_interpreter() {
    check(
        r#"
        surface t(output varying float f = 0; output varying float d = 0;)
        {
            f = turb(P * 7);
            d = Du(turb(P * 3)) + Dv(f);
            Ci = (0.25 + 0.75 * turb(10.0 * P)) * Cs;
        }
        "#,
    );
    // The definition, read directly: 15 octaves from scale 2, each `scale * (2 noise(p / scale) - 1)`.
    let p = [0.3, 1.7, -2.2];
    let mut sum = 0.0f32;
    let mut scale = 2.0f32;
    while scale > 1e-4 {
        sum += scale * (2.0 * rtsl_compiler::shadeops::noise::noise3([p[0] / scale, p[1] / scale, p[2] / scale]) - 1.0);
        scale *= 0.5;
    }
    assert_eq!(rtsl_compiler::shadeops::noise::lucille_turb(p), sum);
}

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

//! The stated accuracy of the JIT's transcendental functions (`docs/packet-abi.md`, "Accuracy"):
//! each is run through JIT-compiled code over a dense sweep of its domain and compared with an `f64`
//! reference rounded to `f32`. The bound is in units in the last place of the `f32` result.

use rtsl_compiler::compile_source;
use rtsl_compiler::interp::TestHost;
use rtsl_compiler::testshade::Grid;

const POINTS: usize = 8192;

/// Runs `expr` (a function of `x`) at `POINTS` values of `x` spread over `[lo, hi]`; returns the
/// pairs (x, result) exactly as the shader saw and produced them.
fn sweep(expr: &str, lo: f32, hi: f32) -> Vec<(f32, f32)> {
    let src = format!(
        "surface acc(float lo = 0; float hi = 1;) {{ float x = lo + (hi - lo) * s; Ci = color({expr}, x, 0); }}"
    );
    let c = compile_source("acc.sl", &src, &Default::default());
    assert!(c.ok(), "{}", c.render());
    let params = [
        ("lo".to_string(), rtsl_compiler::testshade::parse_param(&format!("lo={lo}")).expect("param").1),
        ("hi".to_string(), rtsl_compiler::testshade::parse_param(&format!("hi={hi}")).expect("param").1),
    ];
    let module = c.module.as_ref().expect("module");
    let mut grid = Grid::new(module, POINTS, 1, &params).expect("a grid");
    grid.shade(&mut TestHost::default());
    grid.image().chunks(4).map(|p| (p[1], p[0])).collect()
}

/// Distance in representable `f32`s between `got` and the correctly rounded `want`.
fn ulps(got: f32, want: f64) -> u64 {
    let want = want as f32;
    if got.is_nan() || want.is_nan() {
        return if got.is_nan() && want.is_nan() { 0 } else { u64::MAX };
    }
    // Floats ordered as integers: negative ones mirrored below zero, so that -0 and +0 meet.
    let ordered = |v: f32| {
        let b = v.to_bits() as i32 as i64;
        if b < 0 {
            i32::MIN as i64 - b
        } else {
            b
        }
    };
    (ordered(got) - ordered(want)).unsigned_abs()
}

fn max_ulps(expr: &str, lo: f32, hi: f32, reference: impl Fn(f64) -> f64) -> (u64, f32) {
    sweep(expr, lo, hi)
        .into_iter()
        .map(|(x, y)| (ulps(y, reference(x as f64)), x))
        .max_by_key(|(u, _)| *u)
        .unwrap_or((0, 0.0))
}

#[test]
fn transcendentals_are_within_their_stated_ulps() {
    // (shader expression, domain, f64 reference, stated bound in ulps)
    type Case = (&'static str, f32, f32, fn(f64) -> f64, u64);
    let cases: [Case; 12] = [
        ("sin(x)", -8.0, 8.0, f64::sin, 2),
        ("cos(x)", -8.0, 8.0, f64::cos, 2),
        ("tan(x)", -1.5, 1.5, f64::tan, 2),
        ("asin(x)", -1.0, 1.0, f64::asin, 2),
        ("acos(x)", -1.0, 1.0, f64::acos, 2),
        ("atan(x)", -50.0, 50.0, f64::atan, 2),
        ("atan(x, 0.75)", -50.0, 50.0, |x| x.atan2(0.75), 2),
        ("exp(x)", -80.0, 80.0, f64::exp, 2),
        ("log(x)", 1e-6, 1e6, f64::ln, 2),
        ("log(x, 10)", 1e-3, 1e6, |x| x.ln() / 10f64.ln(), 3),
        ("pow(x, 2.4)", 1e-3, 100.0, |x| x.powf(2.4f32 as f64), 2),
        ("sqrt(x)", 0.0, 1e4, f64::sqrt, 0),
    ];
    let mut report = String::new();
    for (expr, lo, hi, reference, bound) in cases {
        let (worst, at) = max_ulps(expr, lo, hi, reference);
        report.push_str(&format!("{expr}: {worst} ulp at x = {at}\n"));
        assert!(worst <= bound, "{expr}: {worst} ulps at x = {at} (stated {bound})\n{report}");
    }
    eprintln!("{report}");
}

#[test]
fn domain_edges_give_the_documented_values() {
    // docs/packet-abi.md, "Accuracy and edge cases".
    let at = |expr: &str, x: f32| sweep(expr, x, x)[0].1;
    assert_eq!(at("sqrt(x)", -4.0), 0.0);
    assert_eq!(at("asin(x)", 2.0), std::f32::consts::FRAC_PI_2);
    assert_eq!(at("acos(x)", -3.0), std::f32::consts::PI);
    assert_eq!(at("log(x)", 0.0), f32::NEG_INFINITY);
    assert!(at("log(x)", -1.0).is_nan());
    assert_eq!(at("1 / x", 0.0), f32::INFINITY);
    assert_eq!(at("-1 / x", 0.0), f32::NEG_INFINITY);
    assert!(at("x / x", 0.0).is_nan());
    assert_eq!(at("exp(x)", 100.0), f32::INFINITY);
}

//! Transcendental functions of `f32`: one lane at a time for the interpreter, four at a time for
//! the JIT's per-chunk helpers, with the same bits either way.
//!
//! Each trigonometric function is a branch-free polynomial kernel after Cephes' single-precision
//! routines (Moshier), used where its argument reduction is accurate, and Rust's `f32` function
//! (libm) for the rest: |x| > 8192, infinities and NaN (and atan2's zero and infinite cases). The four-lane
//! forms run the same kernel on every lane (the compiler may vectorise it; Rust never fuses a
//! multiply and an add, so vector and scalar arithmetic round alike), then redo the lanes outside the
//! kernel's range one by one. Hence `sin4(x)[l] == sin(x[l])` bit for bit, which keeps the JIT equal
//! to the reference interpreter.
//!
//! Accuracy against the true value, measured over the kernels' ranges by the tests below (`ulp` of
//! the result; a result below 1e-30 is compared absolutely):
//!
//! | function | kernel range | max error |
//! |---|---|---|
//! | `sin`, `cos` | \|x\| <= 8192 | 2 ulp, or 3e-8 absolute near a zero of the function |
//! | `tan` | \|x\| <= 8192 | 3 ulp (away from the poles, where tan itself is ill-conditioned) |
//! | `asin` | \[-1, 1\] | 3 ulp |
//! | `acos` | \[-1, 1\] | 2 ulp |
//! | `atan` | finite | 3 ulp |
//! | `atan2` | finite, `x != 0` | 4 ulp |
//!
//! On x86-64 the four-lane forms are written in SSE2 (`sse2.rs`), the same operations in the same
//! order, so the bit-for-bit equality holds for them too (tested); elsewhere they run the scalar
//! kernel lane by lane ([`portable`]).
//!
//! `exp`, `ln` and `pow` are glibc's (`pow`'s common case computed as glibc computes it, four lanes
//! at once in AVX2: `powf.rs`), which were faster here than such kernels.

// The constants are Cephes' as published, digits and all.
#![allow(clippy::excessive_precision)]

type F4 = [f32; 4];

pub(crate) const FOPI: f32 = 1.27323954473516; // 4 / pi
pub(crate) const DP1: f32 = 0.78515625;
pub(crate) const DP2: f32 = 2.4187564849853515625e-4;
pub(crate) const DP3: f32 = 3.77489497744594108e-8;
const PIO2: f32 = std::f32::consts::FRAC_PI_2;
const PIO4: f32 = std::f32::consts::FRAC_PI_4;
const PI: f32 = std::f32::consts::PI;

/// The largest |x| for which the three-part reduction by pi/4 stays accurate.
pub(crate) const TRIG_MAX: f32 = 8192.0;

/// Runs `kernel` on all four lanes, then `fallback` on the lanes where `in_range` fails.
#[inline(always)]
fn four(x: F4, kernel: impl Fn(f32) -> f32, in_range: impl Fn(f32) -> bool, fallback: impl Fn(f32) -> f32) -> F4 {
    let mut r = x.map(kernel);
    for l in 0..4 {
        if !in_range(x[l]) {
            r[l] = fallback(x[l]);
        }
    }
    r
}

#[inline(always)]
fn four2(
    x: F4,
    y: F4,
    kernel: impl Fn(f32, f32) -> f32,
    in_range: impl Fn(f32, f32) -> bool,
    fallback: impl Fn(f32, f32) -> f32,
) -> F4 {
    let mut r: F4 = std::array::from_fn(|l| kernel(x[l], y[l]));
    for l in 0..4 {
        if !in_range(x[l], y[l]) {
            r[l] = fallback(x[l], y[l]);
        }
    }
    r
}

/// `|x|` reduced by the nearest even multiple `j` of pi/4 (Cody and Waite, three parts).
#[inline(always)]
fn reduce_quarter_pi(ax: f32) -> (f32, u32) {
    // `as` saturates; lanes beyond TRIG_MAX are recomputed anyway. (A signed conversion: SSE2 has
    // no unsigned one.)
    let j = ((ax * FOPI) as i32 as u32).wrapping_add(1) & !1;
    let y = j as f32;
    (((ax - y * DP1) - y * DP2) - y * DP3, j)
}

/// The coefficients of [`sin_poly`] and [`cos_poly`] (the JIT's inline `sin`/`cos` uses them too).
pub(crate) const SIN_POLY: [f32; 3] = [-1.9515295891e-4, 8.3321608736e-3, 1.6666654611e-1];
pub(crate) const COS_POLY: [f32; 3] = [2.443315711809948e-5, 1.388731625493765e-3, 4.166664568298827e-2];

/// sin on [-pi/4, pi/4].
#[inline(always)]
fn sin_poly(z: f32) -> f32 {
    let zz = z * z;
    let [a, b, c] = SIN_POLY;
    ((a * zz + b) * zz - c) * zz * z + z
}

/// cos on [-pi/4, pi/4].
#[inline(always)]
fn cos_poly(z: f32) -> f32 {
    let zz = z * z;
    let [a, b, c] = COS_POLY;
    ((a * zz - b) * zz + c) * zz * zz - 0.5 * zz + 1.0
}

#[inline(always)]
fn with_sign(v: f32, negative: bool) -> f32 {
    f32::from_bits(v.to_bits() ^ (u32::from(negative) << 31))
}

#[inline(always)]
fn sin_kernel(x: f32) -> f32 {
    let (z, j) = reduce_quarter_pi(x.abs());
    // j mod 8: 0 sin, 2 cos, 4 -sin, 6 -cos.
    let v = if j & 2 != 0 { cos_poly(z) } else { sin_poly(z) };
    with_sign(v, x.is_sign_negative() ^ (j & 4 != 0))
}

#[inline(always)]
fn cos_kernel(x: f32) -> f32 {
    let (z, j) = reduce_quarter_pi(x.abs());
    // j mod 8: 0 cos, 2 -sin, 4 -cos, 6 sin.
    let v = if j & 2 != 0 { sin_poly(z) } else { cos_poly(z) };
    with_sign(v, ((j >> 1) ^ (j >> 2)) & 1 != 0)
}

#[inline(always)]
fn tan_kernel(x: f32) -> f32 {
    let (z, j) = reduce_quarter_pi(x.abs());
    let zz = z * z;
    let p = (((((9.38540185543e-3 * zz + 3.11992232697e-3) * zz + 2.44301354525e-2) * zz + 5.34112807005e-2) * zz
        + 1.33387994085e-1)
        * zz
        + 3.33331568548e-1)
        * zz
        * z
        + z;
    let v = if j & 2 != 0 { -1.0 / p } else { p };
    with_sign(v, x.is_sign_negative())
}

fn trig_in_range(x: f32) -> bool {
    x.abs() <= TRIG_MAX
}

pub fn sin(x: f32) -> f32 {
    if trig_in_range(x) {
        sin_kernel(x)
    } else {
        x.sin()
    }
}

pub fn cos(x: f32) -> f32 {
    if trig_in_range(x) {
        cos_kernel(x)
    } else {
        x.cos()
    }
}

pub fn tan(x: f32) -> f32 {
    if trig_in_range(x) {
        tan_kernel(x)
    } else {
        x.tan()
    }
}

/// The four-lane functions: SSE2 on x86-64, the lane-by-lane kernels ([`portable`]) elsewhere.
macro_rules! four_lanes {
    ($($name:ident($($arg:ident),+);)*) => {$(
        pub fn $name($($arg: F4),+) -> F4 {
            #[cfg(target_arch = "x86_64")]
            return sse2::$name($($arg),+);
            #[cfg(not(target_arch = "x86_64"))]
            return portable::$name($($arg),+);
        }
    )*};
}

four_lanes! {
    sin4(x);
    cos4(x);
    tan4(x);
    asin4(x);
    acos4(x);
    atan4(x);
    atan24(y, x);
}

/// `(sin4(x), cos4(x))`, bit for bit, for the price of about one of them (one range reduction).
pub fn sincos4(x: F4) -> (F4, F4) {
    #[cfg(target_arch = "x86_64")]
    return sse2::sincos4(x);
    #[cfg(not(target_arch = "x86_64"))]
    return (portable::sin4(x), portable::cos4(x));
}

/// asin of `|x| <= 1`.
#[inline(always)]
fn asin_kernel(x: f32) -> f32 {
    let a = x.abs();
    let big = a > 0.5;
    let z = if big { 0.5 * (1.0 - a) } else { a * a };
    let s = if big { z.sqrt() } else { a };
    let p = ((((4.2163199048e-2 * z + 2.4181311049e-2) * z + 4.5470025998e-2) * z + 7.4953002686e-2) * z
        + 1.6666752422e-1)
        * z
        * s
        + s;
    let v = if big { PIO2 - (p + p) } else { p };
    with_sign(v, x.is_sign_negative())
}

/// acos of `|x| <= 1`: `pi - 2 asin(sqrt((1 + x) / 2))` below -1/2, `2 asin(sqrt((1 - x) / 2))`
/// above 1/2, `pi/2 - asin(x)` between.
#[inline(always)]
fn acos_kernel(x: f32) -> f32 {
    let low = x < -0.5;
    let high = x > 0.5;
    let outer = if low { 0.5 * (1.0 + x) } else { 0.5 * (1.0 - x) };
    let arg = if low || high { outer.sqrt() } else { x };
    let a = asin_kernel(arg);
    if low {
        PI - (a + a)
    } else if high {
        a + a
    } else {
        PIO2 - a
    }
}

// The argument is clamped to [-1, 1] first, as RSL shaders expect, so the kernels cover every
// argument (a NaN stays NaN).

pub fn asin(x: f32) -> f32 {
    asin_kernel(x.clamp(-1.0, 1.0))
}

pub fn acos(x: f32) -> f32 {
    acos_kernel(x.clamp(-1.0, 1.0))
}

#[inline(always)]
fn atan_kernel(x: f32) -> f32 {
    let a = x.abs();
    let far = a > 2.414213562373095; // tan(3 pi / 8)
    let mid = a > 0.4142135623730950; // tan(pi / 8)
    let base = if far {
        PIO2
    } else if mid {
        PIO4
    } else {
        0.0
    };
    let t = if far {
        -1.0 / a
    } else if mid {
        (a - 1.0) / (a + 1.0)
    } else {
        a
    };
    let z = t * t;
    let v = base
        + ((((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * t + t);
    with_sign(v, x.is_sign_negative())
}

fn atan_in_range(x: f32) -> bool {
    x.is_finite()
}

/// atan2 from atan of the quotient, turned into the right quadrant.
#[inline(always)]
fn atan2_kernel(y: f32, x: f32) -> f32 {
    let a = atan_kernel(y / x);
    if x < 0.0 {
        a + with_sign(PI, y.is_sign_negative())
    } else {
        a
    }
}

/// Finite non-zero `x`, finite `y`, and a finite quotient (signed zeros and infinities take libm's
/// special cases).
fn atan2_in_range(y: f32, x: f32) -> bool {
    x != 0.0 && x.is_finite() && y.is_finite() && (y / x).is_finite()
}

pub fn atan(x: f32) -> f32 {
    if atan_in_range(x) {
        atan_kernel(x)
    } else {
        x.atan()
    }
}

pub fn atan2(y: f32, x: f32) -> f32 {
    if atan2_in_range(y, x) {
        atan2_kernel(y, x)
    } else {
        y.atan2(x)
    }
}

/// The four-lane functions written lane by lane: what other targets run, and the baseline that
/// `benches/transcendental.rs` compares the SSE2 forms with.
pub mod portable {
    use super::*;

    pub fn sin4(x: F4) -> F4 {
        four(x, sin_kernel, trig_in_range, f32::sin)
    }

    pub fn cos4(x: F4) -> F4 {
        four(x, cos_kernel, trig_in_range, f32::cos)
    }

    pub fn tan4(x: F4) -> F4 {
        four(x, tan_kernel, trig_in_range, f32::tan)
    }

    pub fn asin4(x: F4) -> F4 {
        x.map(asin)
    }

    pub fn acos4(x: F4) -> F4 {
        x.map(acos)
    }

    pub fn atan4(x: F4) -> F4 {
        four(x, atan_kernel, atan_in_range, f32::atan)
    }

    pub fn atan24(y: F4, x: F4) -> F4 {
        four2(y, x, atan2_kernel, atan2_in_range, f32::atan2)
    }
}

#[cfg(target_arch = "x86_64")]
mod sse2;

// Fused multiply-adds where glibc's `powf` for FMA processors has them: without FMA, `mul_add` is a
// library call, and `powf` itself is the faster way.
#[cfg(target_feature = "fma")]
mod powf;

// `exp` and `ln` are glibc's: its `expf` and `logf` (table-driven, correctly rounded or nearly)
// ran faster per lane than Cephes-style kernels here (`benches/transcendental.rs`), so these only
// give both shapes one definition. `pow` is glibc's `powf` too, its common case computed here
// (`powf.rs`: the same algorithm and bits, four lanes at once where the target has AVX2 and FMA).

pub fn exp(x: f32) -> f32 {
    x.exp()
}

pub fn exp4(x: F4) -> F4 {
    x.map(f32::exp)
}

/// The natural logarithm.
pub fn ln(x: f32) -> f32 {
    x.ln()
}

pub fn ln4(x: F4) -> F4 {
    x.map(f32::ln)
}

pub fn pow(x: f32, y: f32) -> f32 {
    #[cfg(target_feature = "fma")]
    if let Some(p) = powf::pow(x, y) {
        return p;
    }
    if underflows_to_zero(x, y) {
        return 0.0;
    }
    x.powf(y)
}

pub fn pow4(x: F4, y: F4) -> F4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))]
    {
        let (mut p, taken) = powf::pow4(x, y);
        if taken != 0b1111 {
            for l in (0..4).filter(|l| taken >> l & 1 == 0) {
                p[l] = pow(x[l], y[l]);
            }
        }
        p
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma")))]
    std::array::from_fn(|l| pow(x[l], y[l]))
}

/// Whether `x^y` is certainly below 2^-151, so that `powf` rounds it to zero: then it is zero
/// here without the call. glibc's `powf` takes a slow path for results that underflow (it sets
/// `errno`), and specular highlights raise small cosines to large exponents all the time.
#[inline]
fn underflows_to_zero(x: f32, y: f32) -> bool {
    if !(x > 0.0 && x < 1.0 && y > 0.0) {
        return false;
    }
    // With x = (1 + m) 2^e, log2(x) = e + log2(1 + m) <= e + m / ln 2; for subnormal x the same
    // sum, with e = -127, is still above log2(x). A margin of a whole power of two covers the
    // rounding of the sum and the product.
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = (bits & 0x007f_ffff) as f32 * (1.0 / 8_388_608.0);
    y * (e as f32 + m * std::f32::consts::LOG2_E) < -151.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where `pow` answers zero without `powf`, `powf` gives zero too; and near the edge (results
    /// around the smallest subnormal) it leaves the answer to `powf`.
    #[test]
    fn pow_skips_only_what_powf_rounds_to_zero() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut skipped = 0;
        for _ in 0..200_000 {
            let x = next() * next();
            let y = (next() * 11.0).exp2();
            if underflows_to_zero(x, y) {
                skipped += 1;
                assert_eq!(x.powf(y).to_bits(), 0, "{x}^{y}");
            }
            assert_eq!(pow(x, y).to_bits(), x.powf(y).to_bits(), "{x}^{y}");
        }
        assert!(skipped > 10_000, "{skipped}");
        // The smallest subnormal is 2^-149: 2^-149.5 rounds up to it, and is not skipped.
        for (x, y) in [(0.5f32, 149.5f32), (0.25, 74.75), (f32::from_bits(1), 1.0), (0.5, 150.0)] {
            assert!(!underflows_to_zero(x, y), "{x}^{y}");
        }
        assert!(underflows_to_zero(0.5, 151.5));
        assert!(underflows_to_zero(f32::from_bits(1), 1.2));
        for (x, y) in
            [(0.0f32, 2.0f32), (-0.5, 200.0), (1.0, 1e9), (0.5, f32::INFINITY), (0.5, -200.0), (f32::NAN, 9.0)]
        {
            assert_eq!(pow(x, y).to_bits(), x.powf(y).to_bits(), "{x}^{y}");
        }
    }

    /// Distance in units in the last place of the f32 result, against an f64 reference.
    fn ulps(got: f32, want: f64) -> f64 {
        if want.is_nan() {
            return if got.is_nan() { 0.0 } else { f64::INFINITY };
        }
        let w = want as f32;
        if w == got {
            return 0.0;
        }
        let ulp = f64::from(f32::from_bits(w.abs().to_bits() + 1) - w.abs()).max(f64::from(f32::MIN_POSITIVE));
        (f64::from(got) - want).abs() / ulp
    }

    /// Samples spread over `lo..hi`, plus the ends and a few hand-picked values.
    fn samples(lo: f32, hi: f32, n: usize) -> Vec<f32> {
        let mut v: Vec<f32> = (0..=n).map(|i| lo + (hi - lo) * (i as f32 / n as f32)).collect();
        // A deterministic scramble: values between the grid points too.
        let mut s = 0x2545_f491_u32;
        for _ in 0..n {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            v.push(lo + (hi - lo) * (s as f32 / u32::MAX as f32));
        }
        v
    }

    /// The worst error of `f` against `reference` over `xs`, where an error counts in ulp unless it
    /// is within `abs` absolutely.
    fn worst(xs: &[f32], f: impl Fn(f32) -> f32, reference: impl Fn(f64) -> f64, abs: f64) -> (f64, f32) {
        let mut worst = (0.0, 0.0);
        for &x in xs {
            let want = reference(f64::from(x));
            let got = f(x);
            let e = if (f64::from(got) - want).abs() <= abs { 0.0 } else { ulps(got, want) };
            if e > worst.0 {
                worst = (e, x);
            }
        }
        worst
    }

    #[test]
    fn errors_stay_within_the_documented_bounds() {
        let trig = samples(-TRIG_MAX, TRIG_MAX, 200_000);
        let near = samples(-10.0, 10.0, 100_000);
        for xs in [&trig, &near] {
            let (e, at) = worst(xs, sin, f64::sin, 3e-8);
            assert!(e <= 2.0, "sin: {e} ulp at {at}");
            let (e, at) = worst(xs, cos, f64::cos, 3e-8);
            assert!(e <= 2.0, "cos: {e} ulp at {at}");
        }
        let tan_xs: Vec<f32> = near.iter().copied().filter(|x| (f64::from(*x).cos()).abs() > 1e-3).collect();
        let (e, at) = worst(&tan_xs, tan, f64::tan, 3e-8);
        assert!(e <= 3.0, "tan: {e} ulp at {at}");
        let unit = samples(-1.0, 1.0, 100_000);
        let (e, at) = worst(&unit, asin, f64::asin, 0.0);
        assert!(e <= 3.0, "asin: {e} ulp at {at}");
        let (e, at) = worst(&unit, acos, f64::acos, 0.0);
        assert!(e <= 2.0, "acos: {e} ulp at {at}");
        let wide = samples(-1e4, 1e4, 100_000);
        for xs in [&wide, &near, &unit] {
            let (e, at) = worst(xs, atan, f64::atan, 0.0);
            assert!(e <= 3.0, "atan: {e} ulp at {at}");
        }
        let mut worst_atan2 = (0.0, 0.0, 0.0);
        for (i, &y) in near.iter().enumerate().step_by(7) {
            for &x in near.iter().skip(i % 13).step_by(997) {
                let e = ulps(atan2(y, x), f64::from(y).atan2(f64::from(x)));
                if e > worst_atan2.0 {
                    worst_atan2 = (e, y, x);
                }
            }
        }
        assert!(worst_atan2.0 <= 4.0, "atan2: {worst_atan2:?}");
    }

    #[test]
    fn four_lanes_equal_one_lane_bit_for_bit() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -0.5,
            PIO2,
            PI,
            1e-30,
            1e-45,
            f32::MIN_POSITIVE,
            TRIG_MAX,
            TRIG_MAX * 1.5,
            1e30,
            -1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            88.0,
            89.0,
            -87.0,
            -104.0,
        ];
        let mut xs: Vec<f32> = samples(-100.0, 100.0, 4000);
        xs.extend(specials);
        xs.extend(samples(-1.5, 1.5, 400));
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for c in xs.chunks(4).filter(|c| c.len() == 4) {
            let x: F4 = [c[0], c[1], c[2], c[3]];
            let y: F4 = [c[3], c[0], c[2] * 0.25, c[1]];
            let (sin_of_pair, cos_of_pair) = sincos4(x);
            let checks: [(F4, [f32; 4]); 8] = [
                (sin4(x), x.map(sin)),
                (cos4(x), x.map(cos)),
                (sin_of_pair, x.map(sin)),
                (cos_of_pair, x.map(cos)),
                (tan4(x), x.map(tan)),
                (asin4(x), x.map(asin)),
                (acos4(x), x.map(acos)),
                (atan4(x), x.map(atan)),
            ];
            for (k, (four, one)) in checks.iter().enumerate() {
                for l in 0..4 {
                    assert!(same(four[l], one[l]), "function {k} at {}: {} vs {}", x[l], four[l], one[l]);
                }
            }
            let a = atan24(y, x);
            for l in 0..4 {
                assert!(same(a[l], atan2(y[l], x[l])), "atan2({}, {})", y[l], x[l]);
            }
        }
    }

    /// The four-lane functions (SSE2 on x86-64) against the lane-by-lane forms, bit for bit, on
    /// raw bit patterns (every exponent, subnormals, infinities, NaNs) and on the kernels' ranges.
    #[test]
    fn vector_forms_equal_the_portable_ones_bit_for_bit() {
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for i in 0..150_000 {
            let mut value = || {
                let bits = next();
                let unit = bits as f32 / u32::MAX as f32;
                match i % 3 {
                    0 => f32::from_bits(bits),
                    1 => (unit - 0.5) * 40.0,
                    _ => (unit - 0.5) * 2.4,
                }
            };
            let x: F4 = std::array::from_fn(|_| value());
            let y: F4 = std::array::from_fn(|_| value());
            type Pair = (fn(F4) -> F4, fn(F4) -> F4, &'static str);
            let pairs: [Pair; 8] = [
                (sin4, portable::sin4, "sin"),
                (cos4, portable::cos4, "cos"),
                (|x| sincos4(x).0, portable::sin4, "sin of sincos"),
                (|x| sincos4(x).1, portable::cos4, "cos of sincos"),
                (tan4, portable::tan4, "tan"),
                (asin4, portable::asin4, "asin"),
                (acos4, portable::acos4, "acos"),
                (atan4, portable::atan4, "atan"),
            ];
            for (fast, reference, name) in pairs {
                let (a, b) = (fast(x), reference(x));
                for l in 0..4 {
                    assert!(same(a[l], b[l]), "{name}({:e}): {:e} vs {:e}", x[l], a[l], b[l]);
                }
            }
            let (a, b) = (atan24(y, x), portable::atan24(y, x));
            for l in 0..4 {
                assert!(same(a[l], b[l]), "atan2({:e}, {:e}): {:e} vs {:e}", y[l], x[l], a[l], b[l]);
            }
        }
    }

    #[test]
    fn special_values_follow_the_standard_library() {
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        // Outside the kernels' ranges the standard library answers.
        for x in [f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e30, -1e30, -0.0, 0.0, 1e-40, -1.0] {
            assert!(same(sin(x), x.sin()) || trig_in_range(x), "sin({x})");
            assert!(same(cos(x), x.cos()) || trig_in_range(x), "cos({x})");
            assert!(same(tan(x), x.tan()) || trig_in_range(x), "tan({x})");
            assert!(same(atan(x), x.atan()) || atan_in_range(x), "atan({x})");
        }
        assert_eq!(sin(0.0), 0.0);
        assert_eq!(sin(-0.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(cos(0.0), 1.0);
        assert_eq!(atan2(0.0, -1.0), PI);
        assert_eq!(atan2(-0.0, -1.0), -PI);
        assert_eq!(atan2(1.0, 0.0), PIO2);
        assert_eq!(asin(2.0), PIO2);
        assert_eq!(acos(-3.0), PI);
        assert!(sin(f32::INFINITY).is_nan() && cos(f32::NAN).is_nan());
    }
}

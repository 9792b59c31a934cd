//! The four-lane kernels in SSE2, which every x86-64 processor has.
//!
//! Each function is its scalar kernel (the parent module) transcribed operation for operation:
//! the same constants, the same order of additions and multiplications, selects instead of
//! branches, so every lane rounds exactly as the scalar kernel does (SSE2 has no fused
//! multiply-add to differ by). Lanes outside a kernel's range are then recomputed one by one by
//! the standard library, as in [`super::portable`]. The parent's tests check the result bit for bit
//! against the one-lane functions.

// The constants are Cephes' as published, digits and all.
#![allow(clippy::excessive_precision)]

use super::{DP1, DP2, DP3, F4, FOPI, PI, PIO2, PIO4, TRIG_MAX};
use std::arch::x86_64::*;

type V = __m128;

#[inline]
#[target_feature(enable = "sse2")]
fn load(x: F4) -> V {
    // SAFETY: `x` is four contiguous `f32`s; the load has no alignment requirement.
    unsafe { _mm_loadu_ps(x.as_ptr()) }
}

#[inline]
#[target_feature(enable = "sse2")]
fn store(v: V) -> F4 {
    let mut r = [0.0; 4];
    // SAFETY: `r` has room for four `f32`s; the store has no alignment requirement.
    unsafe { _mm_storeu_ps(r.as_mut_ptr(), v) };
    r
}

#[inline]
#[target_feature(enable = "sse2")]
fn splat(v: f32) -> V {
    _mm_set1_ps(v)
}

#[inline]
#[target_feature(enable = "sse2")]
fn add(a: V, b: V) -> V {
    _mm_add_ps(a, b)
}

#[inline]
#[target_feature(enable = "sse2")]
fn sub(a: V, b: V) -> V {
    _mm_sub_ps(a, b)
}

#[inline]
#[target_feature(enable = "sse2")]
fn mul(a: V, b: V) -> V {
    _mm_mul_ps(a, b)
}

#[inline]
#[target_feature(enable = "sse2")]
fn div(a: V, b: V) -> V {
    _mm_div_ps(a, b)
}

/// `mask ? a : b` per lane (`mask` lanes are all ones or all zeros).
#[inline]
#[target_feature(enable = "sse2")]
fn select(mask: V, a: V, b: V) -> V {
    _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b))
}

#[inline]
#[target_feature(enable = "sse2")]
fn abs(x: V) -> V {
    _mm_andnot_ps(splat(-0.0), x)
}

/// The sign bits of `x`, everything else zero.
#[inline]
#[target_feature(enable = "sse2")]
fn sign_of(x: V) -> V {
    _mm_and_ps(splat(-0.0), x)
}

/// Lanes of `v`, with those whose bit in `done` is clear replaced by `fallback` of the inputs.
#[inline]
#[target_feature(enable = "sse2")]
fn patch(v: V, done: V, x: F4, fallback: impl Fn(f32) -> f32) -> F4 {
    let mut r = store(v);
    let done = _mm_movemask_ps(done);
    if done != 0b1111 {
        for l in 0..4 {
            if done >> l & 1 == 0 {
                r[l] = fallback(x[l]);
            }
        }
    }
    r
}

/// `|x|` reduced by the nearest even multiple `j` of pi/4 (as `reduce_quarter_pi`).
#[inline]
#[target_feature(enable = "sse2")]
fn reduce_quarter_pi(ax: V) -> (V, __m128i) {
    let j = _mm_and_si128(_mm_add_epi32(_mm_cvttps_epi32(mul(ax, splat(FOPI))), _mm_set1_epi32(1)), _mm_set1_epi32(!1));
    // `j` is below 2^14 on the lanes that count, so the signed conversion is the scalar's unsigned one.
    let y = _mm_cvtepi32_ps(j);
    (sub(sub(sub(ax, mul(y, splat(DP1))), mul(y, splat(DP2))), mul(y, splat(DP3))), j)
}

#[inline]
#[target_feature(enable = "sse2")]
fn sin_poly(z: V) -> V {
    let zz = mul(z, z);
    let p = sub(mul(add(mul(splat(-1.9515295891e-4), zz), splat(8.3321608736e-3)), zz), splat(1.6666654611e-1));
    add(mul(mul(p, zz), z), z)
}

#[inline]
#[target_feature(enable = "sse2")]
fn cos_poly(z: V) -> V {
    let zz = mul(z, z);
    let p = add(
        mul(sub(mul(splat(2.443315711809948e-5), zz), splat(1.388731625493765e-3)), zz),
        splat(4.166664568298827e-2),
    );
    add(sub(mul(mul(p, zz), zz), mul(splat(0.5), zz)), splat(1.0))
}

/// Lanes where `bit` is set in `j`, as a select mask.
#[inline]
#[target_feature(enable = "sse2")]
fn has_bit(j: __m128i, bit: i32) -> V {
    let b = _mm_set1_epi32(bit);
    _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(j, b), b))
}

#[inline]
#[target_feature(enable = "sse2")]
fn trig_in_range(x: V) -> V {
    _mm_cmple_ps(abs(x), splat(TRIG_MAX))
}

#[target_feature(enable = "sse2")]
fn sin4_sse2(x4: F4) -> F4 {
    let x = load(x4);
    let (z, j) = reduce_quarter_pi(abs(x));
    let v = select(has_bit(j, 2), cos_poly(z), sin_poly(z));
    let flip = _mm_castsi128_ps(_mm_slli_epi32::<29>(_mm_and_si128(j, _mm_set1_epi32(4))));
    let r = _mm_xor_ps(v, _mm_xor_ps(sign_of(x), flip));
    patch(r, trig_in_range(x), x4, f32::sin)
}

#[target_feature(enable = "sse2")]
fn cos4_sse2(x4: F4) -> F4 {
    let x = load(x4);
    let (z, j) = reduce_quarter_pi(abs(x));
    let v = select(has_bit(j, 2), sin_poly(z), cos_poly(z));
    let odd = _mm_and_si128(_mm_xor_si128(_mm_srli_epi32::<1>(j), _mm_srli_epi32::<2>(j)), _mm_set1_epi32(1));
    let r = _mm_xor_ps(v, _mm_castsi128_ps(_mm_slli_epi32::<31>(odd)));
    patch(r, trig_in_range(x), x4, f32::cos)
}

/// `sin4_sse2` and `cos4_sse2` of the same lanes with one range reduction: each result is the
/// same bits as its own function's (the same reduction, polynomials and sign rules).
#[target_feature(enable = "sse2")]
fn sincos4_sse2(x4: F4) -> (F4, F4) {
    let x = load(x4);
    let (z, j) = reduce_quarter_pi(abs(x));
    let (s, c) = (sin_poly(z), cos_poly(z));
    let swapped = has_bit(j, 2);
    let flip = _mm_castsi128_ps(_mm_slli_epi32::<29>(_mm_and_si128(j, _mm_set1_epi32(4))));
    let sin = _mm_xor_ps(select(swapped, c, s), _mm_xor_ps(sign_of(x), flip));
    let odd = _mm_and_si128(_mm_xor_si128(_mm_srli_epi32::<1>(j), _mm_srli_epi32::<2>(j)), _mm_set1_epi32(1));
    let cos = _mm_xor_ps(select(swapped, s, c), _mm_castsi128_ps(_mm_slli_epi32::<31>(odd)));
    let in_range = trig_in_range(x);
    (patch(sin, in_range, x4, f32::sin), patch(cos, in_range, x4, f32::cos))
}

#[target_feature(enable = "sse2")]
fn tan4_sse2(x4: F4) -> F4 {
    let x = load(x4);
    let (z, j) = reduce_quarter_pi(abs(x));
    let zz = mul(z, z);
    let mut p = splat(9.38540185543e-3);
    for c in [3.11992232697e-3, 2.44301354525e-2, 5.34112807005e-2, 1.33387994085e-1, 3.33331568548e-1] {
        p = add(mul(p, zz), splat(c));
    }
    let p = add(mul(mul(p, zz), z), z);
    let v = select(has_bit(j, 2), div(splat(-1.0), p), p);
    patch(_mm_xor_ps(v, sign_of(x)), trig_in_range(x), x4, f32::tan)
}

/// asin of lanes within [-1, 1] (as `asin_kernel`).
#[inline]
#[target_feature(enable = "sse2")]
fn asin_kernel(x: V) -> V {
    let a = abs(x);
    let big = _mm_cmpgt_ps(a, splat(0.5));
    let z = select(big, mul(splat(0.5), sub(splat(1.0), a)), mul(a, a));
    let s = select(big, _mm_sqrt_ps(z), a);
    let mut p = splat(4.2163199048e-2);
    for c in [2.4181311049e-2, 4.5470025998e-2, 7.4953002686e-2, 1.6666752422e-1] {
        p = add(mul(p, z), splat(c));
    }
    let p = add(mul(mul(p, z), s), s);
    let v = select(big, sub(splat(PIO2), add(p, p)), p);
    _mm_xor_ps(v, sign_of(x))
}

/// `x.clamp(-1.0, 1.0)`, NaN included: `min`/`max` return their second operand when either is NaN.
#[inline]
#[target_feature(enable = "sse2")]
fn clamp_unit(x: V) -> V {
    _mm_max_ps(splat(-1.0), _mm_min_ps(splat(1.0), x))
}

#[target_feature(enable = "sse2")]
fn asin4_sse2(x4: F4) -> F4 {
    store(asin_kernel(clamp_unit(load(x4))))
}

#[target_feature(enable = "sse2")]
fn acos4_sse2(x4: F4) -> F4 {
    let x = clamp_unit(load(x4));
    let low = _mm_cmplt_ps(x, splat(-0.5));
    let high = _mm_cmpgt_ps(x, splat(0.5));
    let outer = select(low, mul(splat(0.5), add(splat(1.0), x)), mul(splat(0.5), sub(splat(1.0), x)));
    let arg = select(_mm_or_ps(low, high), _mm_sqrt_ps(outer), x);
    let a = asin_kernel(arg);
    let twice = add(a, a);
    store(select(low, sub(splat(PI), twice), select(high, twice, sub(splat(PIO2), a))))
}

/// atan of finite lanes (as `atan_kernel`).
#[inline]
#[target_feature(enable = "sse2")]
fn atan_kernel(x: V) -> V {
    let a = abs(x);
    let far = _mm_cmpgt_ps(a, splat(2.414213562373095));
    let mid = _mm_cmpgt_ps(a, splat(0.4142135623730950));
    let base = select(far, splat(PIO2), select(mid, splat(PIO4), splat(0.0)));
    let one = splat(1.0);
    let t = select(far, div(splat(-1.0), a), select(mid, div(sub(a, one), add(a, one)), a));
    let z = mul(t, t);
    let p = sub(
        mul(add(mul(sub(mul(splat(8.05374449538e-2), z), splat(1.38776856032e-1)), z), splat(1.99777106478e-1)), z),
        splat(3.33329491539e-1),
    );
    let v = add(base, add(mul(mul(p, z), t), t));
    _mm_xor_ps(v, sign_of(x))
}

#[inline]
#[target_feature(enable = "sse2")]
fn finite(x: V) -> V {
    _mm_cmplt_ps(abs(x), splat(f32::INFINITY))
}

#[target_feature(enable = "sse2")]
fn atan4_sse2(x4: F4) -> F4 {
    let x = load(x4);
    patch(atan_kernel(x), finite(x), x4, f32::atan)
}

#[target_feature(enable = "sse2")]
fn atan24_sse2(y4: F4, x4: F4) -> F4 {
    let (y, x) = (load(y4), load(x4));
    let q = div(y, x);
    let a = atan_kernel(q);
    let r = select(_mm_cmplt_ps(x, splat(0.0)), add(a, _mm_or_ps(splat(PI), sign_of(y))), a);
    let ok = _mm_and_ps(_mm_and_ps(_mm_cmpneq_ps(x, splat(0.0)), finite(x)), _mm_and_ps(finite(y), finite(q)));
    let mut out = store(r);
    let ok = _mm_movemask_ps(ok);
    for l in 0..4 {
        if ok >> l & 1 == 0 {
            out[l] = y4[l].atan2(x4[l]);
        }
    }
    out
}

/// Safe entry points to the `#[target_feature]` functions above.
macro_rules! safe_entry_points {
    ($($name:ident => $imp:ident($($arg:ident),+);)*) => {$(
        pub fn $name($($arg: F4),+) -> F4 {
            // SAFETY: SSE2 is part of the x86-64 baseline, so every processor that runs this build
            // has it.
            unsafe { $imp($($arg),+) }
        }
    )*};
}

/// [`sincos4_sse2`]'s safe entry point.
pub fn sincos4(x: F4) -> (F4, F4) {
    // SAFETY: SSE2 is part of the x86-64 baseline.
    unsafe { sincos4_sse2(x) }
}

safe_entry_points! {
    sin4 => sin4_sse2(x4);
    cos4 => cos4_sse2(x4);
    tan4 => tan4_sse2(x4);
    asin4 => asin4_sse2(x4);
    acos4 => acos4_sse2(x4);
    atan4 => atan4_sse2(x4);
    atan24 => atan24_sse2(y4, x4);
}

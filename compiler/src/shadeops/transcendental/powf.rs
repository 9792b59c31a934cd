//! `pow` of positive normal bases with results well inside `f32`'s range, one lane and four lanes
//! (AVX2), computed as glibc's `powf` computes them on a processor with FMA.
//!
//! The algorithm (Szabolcs Nagy's, in ARM's optimized-routines and from there in glibc and musl):
//! `log2(x)` in `f64` from a 16-entry table of `1/c` and `log2(c)` over the subintervals of the
//! mantissa and a degree-5 polynomial in `z/c - 1`, times `y`, then `2^(y log2 x)` from a 32-entry
//! table of `2^(i/32)` and a degree-3 polynomial, rounded once to `f32` (at most 0.82 ulp from the
//! true power). The coefficients are that implementation's, and the multiply-adds fused where
//! glibc's `x86-64` build for FMA processors (`__powf_fma`) fuses them, so results are glibc's bit
//! for bit (a test compares them over millions of arguments): images keep their bits, and
//! `pow` is one function whether a shader runs in the JIT (four lanes here) or the interpreter.
//!
//! Lanes outside the fast path (zero, negative, subnormal, infinite or NaN bases; zero, infinite or
//! NaN exponents; `y log2 x >= 126`, where the result may overflow; `y log2 x` in `(-150, -149)`,
//! where glibc's answer depends on how it was built) are the caller's: glibc's own `powf` answers
//! them. Below that, results that underflow are glibc's too: `+0` from `y log2 x <= -150`, and the
//! same `2^(y log2 x)`, rounded once to a subnormal, from `-149` to `-126` (small cosines to a
//! sharp highlight's large exponents).

// The coefficients as the reference implementation prints them, every digit.
#![allow(clippy::excessive_precision, clippy::unreadable_literal)]

/// `(1/c, log2(c))` of each of the 16 subintervals of `[OFF, 2 OFF)` that the mantissa is cut into.
const LOG2_TABLE: [(f64, f64); 16] = [
    (f64::from_bits(0x3ff661ec79f8f3be), -f64::from_bits(0x3fdefec65b963019)),
    (f64::from_bits(0x3ff571ed4aaf883d), -f64::from_bits(0x3fdb0b6832d4fca4)),
    (f64::from_bits(0x3ff49539f0f010b0), -f64::from_bits(0x3fd7418b0a1fb77b)),
    (f64::from_bits(0x3ff3c995b0b80385), -f64::from_bits(0x3fd39de91a6dcf7b)),
    (f64::from_bits(0x3ff30d190c8864a5), -f64::from_bits(0x3fd01d9bf3f2b631)),
    (f64::from_bits(0x3ff25e227b0b8ea0), -f64::from_bits(0x3fc97c1d1b3b7af0)),
    (f64::from_bits(0x3ff1bb4a4a1a343f), -f64::from_bits(0x3fc2f9e393af3c9f)),
    (f64::from_bits(0x3ff12358f08ae5ba), -f64::from_bits(0x3fb960cbbf788d5c)),
    (f64::from_bits(0x3ff0953f419900a7), -f64::from_bits(0x3faa6f9db6475fce)),
    (1.0, 0.0),
    (f64::from_bits(0x3fee608cfd9a47ac), f64::from_bits(0x3fb338ca9f24f53d)),
    (f64::from_bits(0x3feca4b31f026aa0), f64::from_bits(0x3fc476a9543891ba)),
    (f64::from_bits(0x3feb2036576afce6), f64::from_bits(0x3fce840b4ac4e4d2)),
    (f64::from_bits(0x3fe9c2d163a1aa2d), f64::from_bits(0x3fd40645f0c6651c)),
    (f64::from_bits(0x3fe886e6037841ed), f64::from_bits(0x3fd88e9c2c1b9ff8)),
    (f64::from_bits(0x3fe767dcf5534862), f64::from_bits(0x3fdce0a44eb17bcc)),
];

/// Column `k` of the table (0: `1/c`, 1: `log2(c)`) as a row, for the four-lane gathers.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
const fn log2_column(k: usize) -> [f64; 16] {
    let mut r = [0.0; 16];
    let mut i = 0;
    while i < 16 {
        r[i] = if k == 0 { LOG2_TABLE[i].0 } else { LOG2_TABLE[i].1 };
        i += 1;
    }
    r
}
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
static INV_C: [f64; 16] = log2_column(0);
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
static LOG2_C: [f64; 16] = log2_column(1);

/// `log2(1 + r)`'s polynomial, highest degree first.
const LOG2_POLY: [f64; 5] = [
    f64::from_bits(0x3fd27616c9496e0b),
    -f64::from_bits(0x3fd71969a075c67a),
    f64::from_bits(0x3fdec70a6ca7badd),
    -f64::from_bits(0x3fe7154748bef6c8),
    f64::from_bits(0x3ff71547652ab82b),
];

/// The mantissa range `[OFF, 2 OFF)` (as `f32` bits) that the table covers.
const OFF: u32 = 0x3f33_0000;

/// `2^(i/32)` as bits, less `i << 47`: adding `k << 47` to entry `k % 32` gives `2^(k/32)`.
static EXP2_TABLE: [u64; 32] = [
    0x3ff0000000000000,
    0x3fefd9b0d3158574,
    0x3fefb5586cf9890f,
    0x3fef9301d0125b51,
    0x3fef72b83c7d517b,
    0x3fef54873168b9aa,
    0x3fef387a6e756238,
    0x3fef1e9df51fdee1,
    0x3fef06fe0a31b715,
    0x3feef1a7373aa9cb,
    0x3feedea64c123422,
    0x3feece086061892d,
    0x3feebfdad5362a27,
    0x3feeb42b569d4f82,
    0x3feeab07dd485429,
    0x3feea47eb03a5585,
    0x3feea09e667f3bcd,
    0x3fee9f75e8ec5f74,
    0x3feea11473eb0187,
    0x3feea589994cce13,
    0x3feeace5422aa0db,
    0x3feeb737b0cdc5e5,
    0x3feec49182a3f090,
    0x3feed503b23e255d,
    0x3feee89f995ad3ad,
    0x3feeff76f2fb5e47,
    0x3fef199bdd85529c,
    0x3fef3720dcef9069,
    0x3fef5818dcfba487,
    0x3fef7c97337b9b5f,
    0x3fefa4afa2a490da,
    0x3fefd0765b6e4540,
];

/// `2^r`'s polynomial (less its constant 1), highest degree first.
const EXP2_POLY: [f64; 3] =
    [f64::from_bits(0x3fac6af84b912394), f64::from_bits(0x3fcebfce50fac4f3), f64::from_bits(0x3fe62e42ff0c52d6)];

/// `1.5 * 2^52 / 32`: adding it rounds to a multiple of 1/32, whose 32nds land in the low bits.
const SHIFT: f64 = 0x0018_0000_0000_0000_u64 as f64 / 32.0;

/// `(y log2 x)`'s bits, shifted, from which on the result may leave the fast path (`|y log2 x| >=
/// 126`, up to the bits the test looks at).
const LIMIT: u64 = 126.0f64.to_bits() >> 47;

/// At or below this `y log2 x`, glibc's `powf` of a positive base is `+0` (`__math_uflowf`).
const ZERO_BELOW: f64 = -150.0;

/// From this `y log2 x` up to [`LIMIT`]'s, glibc's `powf` computes the (subnormal) result as in the
/// fast path; between [`ZERO_BELOW`] and here, a build that reports underflow answers otherwise.
const SUBNORMAL_FROM: f64 = -149.0;

/// Whether `x` is a positive normal finite float and `y` a nonzero finite one (as bits).
#[inline(always)]
fn in_domain(ix: u32, iy: u32) -> bool {
    ix.wrapping_sub(0x0080_0000) < 0x7f80_0000 - 0x0080_0000 && (iy & 0x7fff_ffff).wrapping_sub(1) < 0x7f7f_ffff
}

#[inline(always)]
fn log2(ix: u32) -> f64 {
    let tmp = ix.wrapping_sub(OFF);
    let (invc, logc) = LOG2_TABLE[(tmp >> 19) as usize % 16];
    let top = tmp & 0xff80_0000;
    let z = f64::from(f32::from_bits(ix.wrapping_sub(top)));
    let k = f64::from(top as i32 >> 23);
    let a = LOG2_POLY;
    let r = z.mul_add(invc, -1.0);
    let y0 = logc + k;
    let r2 = r * r;
    let y = a[0].mul_add(r, a[1]);
    let p = a[2].mul_add(r, a[3]);
    let r4 = r2 * r2;
    let q = a[4].mul_add(r, y0);
    let q = p.mul_add(r2, q);
    y.mul_add(r4, q)
}

#[inline(always)]
fn exp2(xd: f64) -> f32 {
    let kd = xd + SHIFT;
    let ki = kd.to_bits();
    let r = xd - (kd - SHIFT);
    let s = f64::from_bits(EXP2_TABLE[(ki % 32) as usize].wrapping_add(ki << 47));
    let c = EXP2_POLY;
    let z = c[0].mul_add(r, c[1]);
    let r2 = r * r;
    let y = c[2].mul_add(r, 1.0);
    (z.mul_add(r2, y) * s) as f32
}

/// `x^y` where the fast path takes it (see the module documentation), else `None`.
#[inline]
pub fn pow(x: f32, y: f32) -> Option<f32> {
    let (ix, iy) = (x.to_bits(), y.to_bits());
    if !in_domain(ix, iy) {
        return None;
    }
    let ylogx = f64::from(y) * log2(ix);
    if (ylogx.to_bits() >> 47 & 0xffff) >= LIMIT {
        if ylogx <= ZERO_BELOW {
            return Some(0.0);
        }
        if !(SUBNORMAL_FROM..0.0).contains(&ylogx) {
            return None;
        }
    }
    Some(exp2(ylogx))
}

/// [`pow`] of four lanes, the same operations in AVX2 registers: the results, and the lanes the
/// fast path took (bit `l`: lane `l`); the others' results are for the caller to compute.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))]
pub fn pow4(x: [f32; 4], y: [f32; 4]) -> ([f32; 4], i32) {
    use std::arch::x86_64::*;
    // SAFETY: the loads and stores touch four `f32`s of arrays that have them, without alignment
    // requirements; each gather reads entries of a 16- or 32-entry table at indices masked below
    // its length; the target has AVX2 and FMA (this function's `cfg`).
    unsafe {
        let (xs, ys) = (_mm_loadu_ps(x.as_ptr()), _mm_loadu_ps(y.as_ptr()));
        let (ix, iy) = (_mm_castps_si128(xs), _mm_castps_si128(ys));
        // `in_domain`, as signed comparisons: positive normal finite x, nonzero finite y.
        let x_normal = _mm_and_si128(
            _mm_cmpgt_epi32(ix, _mm_set1_epi32(0x007f_ffff)),
            _mm_cmplt_epi32(ix, _mm_set1_epi32(0x7f80_0000)),
        );
        let ay = _mm_and_si128(iy, _mm_set1_epi32(0x7fff_ffff));
        let y_finite =
            _mm_and_si128(_mm_cmpgt_epi32(ay, _mm_setzero_si128()), _mm_cmplt_epi32(ay, _mm_set1_epi32(0x7f80_0000)));
        let domain = _mm_and_si128(x_normal, y_finite);

        // log2(x)
        let tmp = _mm_sub_epi32(ix, _mm_set1_epi32(OFF as i32));
        let i = _mm_and_si128(_mm_srli_epi32::<19>(tmp), _mm_set1_epi32(15));
        let top = _mm_and_si128(tmp, _mm_set1_epi32(0xff80_0000_u32 as i32));
        let z = _mm256_cvtps_pd(_mm_castsi128_ps(_mm_sub_epi32(ix, top)));
        let k = _mm256_cvtepi32_pd(_mm_srai_epi32::<23>(top));
        let invc = _mm256_i32gather_pd::<8>(INV_C.as_ptr(), i);
        let logc = _mm256_i32gather_pd::<8>(LOG2_C.as_ptr(), i);
        let a = LOG2_POLY.map(|c| _mm256_set1_pd(c));
        let one = _mm256_set1_pd(1.0);
        let r = _mm256_fmsub_pd(z, invc, one);
        let y0 = _mm256_add_pd(logc, k);
        let r2 = _mm256_mul_pd(r, r);
        let p1 = _mm256_fmadd_pd(a[0], r, a[1]);
        let p = _mm256_fmadd_pd(a[2], r, a[3]);
        let r4 = _mm256_mul_pd(r2, r2);
        let q = _mm256_fmadd_pd(a[4], r, y0);
        let q = _mm256_fmadd_pd(p, r2, q);
        let logx = _mm256_fmadd_pd(p1, r4, q);

        let ylogx = _mm256_mul_pd(_mm256_cvtps_pd(ys), logx);
        let high = _mm256_and_si256(_mm256_srli_epi64::<47>(_mm256_castpd_si256(ylogx)), _mm256_set1_epi64x(0xffff));
        let inside = _mm256_cmpgt_epi64(_mm256_set1_epi64x(LIMIT as i64), high);
        let subnormal = _mm256_castpd_si256(_mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GE_OQ>(ylogx, _mm256_set1_pd(SUBNORMAL_FROM)),
            _mm256_cmp_pd::<_CMP_LT_OQ>(ylogx, _mm256_setzero_pd()),
        ));
        let zero = _mm256_castpd_si256(_mm256_cmp_pd::<_CMP_LE_OQ>(ylogx, _mm256_set1_pd(ZERO_BELOW)));
        // The 64-bit lanes' verdicts as four 32-bit ones.
        let halves = |v: __m256i| {
            _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(v, _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6)))
        };
        let zero = halves(zero);
        let computed = halves(_mm256_or_si256(inside, subnormal));
        let taken = _mm_movemask_ps(_mm_castsi128_ps(_mm_and_si128(domain, _mm_or_si128(computed, zero))));

        // 2^(y log2 x)
        let shift = _mm256_set1_pd(SHIFT);
        let kd = _mm256_add_pd(ylogx, shift);
        let ki = _mm256_castpd_si256(kd);
        let r = _mm256_sub_pd(ylogx, _mm256_sub_pd(kd, shift));
        let low = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(ki, _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6)));
        let entry = _mm256_i32gather_epi64::<8>(EXP2_TABLE.as_ptr().cast(), _mm_and_si128(low, _mm_set1_epi32(31)));
        let s = _mm256_castsi256_pd(_mm256_add_epi64(entry, _mm256_slli_epi64::<47>(ki)));
        let c = EXP2_POLY.map(|c| _mm256_set1_pd(c));
        let zc = _mm256_fmadd_pd(c[0], r, c[1]);
        let r2 = _mm256_mul_pd(r, r);
        let yc = _mm256_fmadd_pd(c[2], r, one);
        let power = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_fmadd_pd(zc, r2, yc), s));
        let power = _mm_andnot_ps(_mm_castsi128_ps(zero), power);
        let mut out = [0.0f32; 4];
        _mm_storeu_ps(out.as_mut_ptr(), power);
        (out, taken)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the fast path answers is glibc's `powf` (through Rust's `f32::powf`) bit for bit, over
    /// the arguments a specular highlight and a shader's `pow` meet: cosines in (0, 1] to large
    /// exponents, and bases and exponents spread over many binades, both signs of exponent.
    #[test]
    fn the_fast_path_is_powf_bit_for_bit() {
        let mut h = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            h
        };
        let (mut taken, mut zeros, mut subnormals) = (0, 0, 0);
        for n in 0..2_000_000u32 {
            let bits = next();
            let (x, y) = match n % 4 {
                // A cosine to a Phong or Blinn exponent.
                0 => ((bits >> 40) as f32 / 16_777_216.0, (1 + (bits & 0x7f)) as f32 * 0.37),
                // A cosine to an exponent as large as a sharp highlight's: most results underflow,
                // to subnormals or to zero.
                3 => ((bits >> 40) as f32 / 16_777_216.0, (1 + (bits & 0x3fff)) as f32 * 0.61),
                // Positive bases over 2^-31 .. 2^27 to exponents in (-4, 4).
                1 => (
                    f32::from_bits(0x3000_0000 + (bits >> 33) as u32 % 0x1d00_0000),
                    ((bits & 0xffff) as f32 - 32768.0) / 8192.0,
                ),
                // Bases near 1 (the table's subinterval edges) to large exponents.
                _ => (
                    1.0 + ((bits >> 40) as f32 - 8_388_608.0) / 16_777_216.0,
                    ((bits & 0xfffff) as f32 - 524_288.0) / 64.0,
                ),
            };
            if let Some(p) = pow(x, y) {
                assert_eq!(p.to_bits(), x.powf(y).to_bits(), "{x:e}^{y:e}");
                taken += 1;
                zeros += u32::from(p == 0.0);
                subnormals += u32::from(p.is_subnormal());
            }
        }
        assert!(taken > 1_400_000, "only {taken} arguments took the fast path");
        assert!(zeros > 100_000 && subnormals > 5_000, "underflows taken: {zeros} zeros, {subnormals} subnormals");
    }

    /// The four-lane form gives the one-lane form's answers, and takes the same lanes, whatever
    /// the lanes hold.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))]
    #[test]
    fn four_lanes_are_the_one_lane_form() {
        let specials =
            [0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-40, -3.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e30, 126.0];
        let mut h = 0x9e37_79b9_7f4a_7c15u64;
        for n in 0..400_000u32 {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            let pick = |k: u32| -> f32 {
                let b = (h >> (8 * k)) as u32;
                match (n + k) % 4 {
                    0 => specials[b as usize % specials.len()],
                    1 => f32::from_bits(b),
                    2 => (b >> 8) as f32 / 16_777_216.0,
                    _ => ((b & 0xffff) as f32 - 32768.0) / 256.0,
                }
            };
            let (x, y): ([f32; 4], [f32; 4]) =
                (std::array::from_fn(|l| pick(l as u32)), std::array::from_fn(|l| pick(l as u32 + 4)));
            let (p, taken) = pow4(x, y);
            for l in 0..4 {
                match pow(x[l], y[l]) {
                    Some(q) => {
                        assert!(taken >> l & 1 != 0, "{:e}^{:e} not taken", x[l], y[l]);
                        assert_eq!(p[l].to_bits(), q.to_bits(), "{:e}^{:e}", x[l], y[l]);
                    }
                    None => assert!(taken >> l & 1 == 0, "{:e}^{:e} taken", x[l], y[l]),
                }
            }
        }
    }
}

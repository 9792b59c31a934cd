//! [`super`]'s gradient noise in AVX2 registers, for builds whose target has AVX2 (the default
//! `x86-64-v3` one).
//!
//! The same operations as the portable four-lane code, lane for lane: the floor is the truncation
//! corrected by one (`cvttps2dq`, exact below 2^23, where the portable code's saturating `as i32`
//! gives the same integer), the hash is the same `lowbias32` mix in 32-bit vector multiplies, and a
//! corner's gradient is read from its table held as rows (`vpermps` picks from eight entries by
//! the low three bits of the index, blends pick between the eights) rather than loaded lane by
//! lane. Two corners share a 256-bit register (the pair that differs along the first dimension),
//! so hashes, gradients and dot products take half the instructions of four-lane registers.
//! Products and sums are the portable code's, in its order, without fused multiply-adds, so every
//! lane rounds as the scalar noise does; `super`'s tests check them bit for bit.

use super::super::{GRAD2, GRAD3, GRAD4, SCALE};
use super::{EXACT, X4};
use std::arch::x86_64::*;

/// A gradient table as rows of components (`rows[k][e]`: component `k` of entry `e`), padded to a
/// whole number of eights.
struct Rows<const E: usize> {
    rows: [[f32; E]; 4],
}

const fn rows<const E: usize>(table: &[[f32; 4]; E]) -> Rows<E> {
    let mut rows = [[0.0; E]; 4];
    let mut e = 0;
    while e < E {
        let mut k = 0;
        while k < 4 {
            rows[k][e] = table[e][k];
            k += 1;
        }
        e += 1;
    }
    Rows { rows }
}

static ROWS2: Rows<16> = rows(&GRAD2);
static ROWS3: Rows<16> = rows(&GRAD3);
static ROWS4: Rows<32> = rows(&GRAD4);

/// Four lanes' lattice cells and the lanes that took the fast path (bit `l`: lane `l`).
struct Cells<const N: usize> {
    frac: [__m128; N],
    lo: [__m128i; N],
    hi: [__m128i; N],
    fits: i32,
}

#[inline]
#[target_feature(enable = "avx2")]
fn cells<const N: usize>(p: &[X4; N]) -> Cells<N> {
    let zero = _mm_setzero_ps();
    let mut c = Cells { frac: [zero; N], lo: [_mm_setzero_si128(); N], hi: [_mm_setzero_si128(); N], fits: 0 };
    let magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff));
    let mut fits = _mm_castsi128_ps(_mm_set1_epi32(-1));
    for (k, coordinate) in p.iter().enumerate() {
        // SAFETY: four contiguous `f32`s; the load has no alignment requirement.
        let x = unsafe { _mm_loadu_ps(coordinate.as_ptr()) };
        // An ordered comparison: false for NaN, as `x.abs() < EXACT` is.
        fits = _mm_and_ps(fits, _mm_cmplt_ps(_mm_and_ps(x, magnitude), _mm_set1_ps(EXACT)));
        let t = _mm_cvttps_epi32(x);
        // `t - 1` where `t as f32 > x` (the comparison's lanes are all ones there, i.e. -1).
        let i = _mm_add_epi32(t, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(t), x)));
        c.frac[k] = _mm_sub_ps(x, _mm_cvtepi32_ps(i));
        c.lo[k] = i;
        c.hi[k] = _mm_add_epi32(i, _mm_set1_epi32(1));
    }
    c.fits = _mm_movemask_ps(fits);
    c
}

/// `mix32` of each of eight lanes.
#[inline]
#[target_feature(enable = "avx2")]
fn mix(x: __m256i) -> __m256i {
    let x = _mm256_xor_si256(x, _mm256_srli_epi32::<16>(x));
    let x = _mm256_mullo_epi32(x, _mm256_set1_epi32(0x7feb_352d));
    let x = _mm256_xor_si256(x, _mm256_srli_epi32::<15>(x));
    let x = _mm256_mullo_epi32(x, _mm256_set1_epi32(0x846c_a68b_u32 as i32));
    _mm256_xor_si256(x, _mm256_srli_epi32::<16>(x))
}

/// Two corners' four lanes in one register: `low` in lanes 0-3, `high` in 4-7.
#[inline]
#[target_feature(enable = "avx2")]
fn pair(low: __m128, high: __m128) -> __m256 {
    _mm256_set_m128(high, low)
}

#[inline]
#[target_feature(enable = "avx2")]
fn pair_i(low: __m128i, high: __m128i) -> __m256i {
    _mm256_set_m128i(high, low)
}

/// The portable code's `corner_hashes`, two corners a register: register `j` holds corners `2j`
/// and `2j + 1`, which differ along the first dimension only, so that along every other dimension
/// `k` both take `lo[k]` or both `hi[k]` (bit `k - 1` of `j`).
#[inline]
#[target_feature(enable = "avx2")]
fn corner_hashes<const N: usize>(c: &Cells<N>, seed: u32) -> [__m256i; 8] {
    let mut h = [_mm256_setzero_si256(); 8];
    h[0] = mix(_mm256_xor_si256(mix(pair_i(c.lo[0], c.hi[0])), _mm256_set1_epi32(seed as i32)));
    let mut len = 1;
    for k in 1..N {
        let (lo, hi) = (pair_i(c.lo[k], c.lo[k]), pair_i(c.hi[k], c.hi[k]));
        for j in 0..len {
            let base = h[j];
            h[j] = mix(_mm256_add_epi32(base, lo));
            h[j + len] = mix(_mm256_add_epi32(base, hi));
        }
        len *= 2;
    }
    h
}

/// Entry `index` of each lane (its low bits: three for each eight of `row`) from a row of `E`
/// entries, `E` 16 or 32.
#[inline]
#[target_feature(enable = "avx2")]
fn pick<const E: usize>(row: &[f32; E], index: __m256i) -> __m256 {
    let eight = |at: usize| {
        // SAFETY: `at + 8 <= E`: eight contiguous `f32`s, no alignment requirement.
        let entries = unsafe { _mm256_loadu_ps(row.as_ptr().add(at)) };
        _mm256_permutevar8x32_ps(entries, index)
    };
    // Bit 3 of the index, then bit 4, moved to the sign bits that `blendv` reads.
    let by_bit3 = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(index));
    let low = _mm256_blendv_ps(eight(0), eight(8), by_bit3);
    if E == 16 {
        return low;
    }
    let by_bit4 = _mm256_castsi256_ps(_mm256_slli_epi32::<27>(index));
    _mm256_blendv_ps(low, _mm256_blendv_ps(eight(16), eight(24), by_bit3), by_bit4)
}

/// The portable `gradient::<N>` of each lane's hash: its first `N` components.
#[inline]
#[target_feature(enable = "avx2")]
fn gradient<const N: usize>(h: __m256i) -> [__m256; N] {
    let top5 = _mm256_srli_epi32::<27>(h);
    std::array::from_fn(|k| match N {
        // `((h >> 24) as i32 * 2 - 255) as f32`: an odd integer in [-255, 255], converted exactly.
        1 => {
            let top8 = _mm256_srli_epi32::<24>(h);
            _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_add_epi32(top8, top8), _mm256_set1_epi32(255)))
        }
        2 => pick(&ROWS2.rows[k], top5),
        3 => pick(&ROWS3.rows[k], top5),
        _ => pick(&ROWS4.rows[k], top5),
    })
}

/// The portable `fade` of each lane, in its order of operations.
#[inline]
#[target_feature(enable = "avx2")]
fn fade(t: __m128) -> __m128 {
    let t3 = _mm_mul_ps(_mm_mul_ps(t, t), t);
    let inner =
        _mm_add_ps(_mm_mul_ps(t, _mm_sub_ps(_mm_mul_ps(t, _mm_set1_ps(6.0)), _mm_set1_ps(15.0))), _mm_set1_ps(10.0));
    _mm_mul_ps(t3, inner)
}

/// The portable `gradient_noise`, two corners a register (see [`corner_hashes`]).
#[inline]
#[target_feature(enable = "avx2")]
fn gradient_noise<const N: usize>(c: &Cells<N>, seed: u32) -> __m128 {
    let h = corner_hashes(c, seed);
    let one = _mm_set1_ps(1.0);
    let below: [__m128; N] = std::array::from_fn(|k| _mm_sub_ps(c.frac[k], one));
    // Each dimension's offsets from the corners: along the first, the pair's own two; along the
    // others, one of them for both corners of a pair.
    let first = pair(c.frac[0], below[0]);
    let near: [__m256; N] = std::array::from_fn(|k| pair(c.frac[k], c.frac[k]));
    let far: [__m256; N] = std::array::from_fn(|k| pair(below[k], below[k]));
    let mut v = [_mm256_setzero_ps(); 8];
    for j in 0..1 << (N - 1) {
        let g = gradient::<N>(h[j]);
        let mut dot = _mm256_add_ps(_mm256_setzero_ps(), _mm256_mul_ps(g[0], first));
        for k in 1..N {
            let d = if (j >> (k - 1)) & 1 == 0 { near[k] } else { far[k] };
            dot = _mm256_add_ps(dot, _mm256_mul_ps(g[k], d));
        }
        v[j] = dot;
    }
    for k in (1..N).rev() {
        let t = fade(c.frac[k]);
        let t = pair(t, t);
        let half = 1 << (k - 1);
        for j in 0..half {
            v[j] = _mm256_add_ps(v[j], _mm256_mul_ps(t, _mm256_sub_ps(v[j + half], v[j])));
        }
    }
    let (a, b) = (_mm256_castps256_ps128(v[0]), _mm256_extractf128_ps::<1>(v[0]));
    let x = _mm_add_ps(a, _mm_mul_ps(fade(c.frac[0]), _mm_sub_ps(b, a)));
    // `(0.5 + x * scale).clamp(0.0, 1.0)`: below 0 becomes 0, then above 1 becomes 1.
    let r = _mm_add_ps(_mm_set1_ps(0.5), _mm_mul_ps(x, _mm_set1_ps(SCALE[N - 1])));
    let zero = _mm_setzero_ps();
    let r = _mm_blendv_ps(r, zero, _mm_cmplt_ps(r, zero));
    _mm_blendv_ps(r, one, _mm_cmpgt_ps(r, one))
}

#[inline]
#[target_feature(enable = "avx2")]
fn store(v: __m128) -> X4 {
    let mut r = [0.0; 4];
    // SAFETY: `r` has room for four `f32`s; the store has no alignment requirement.
    unsafe { _mm_storeu_ps(r.as_mut_ptr(), v) };
    r
}

/// `noise_n` of the lanes that fit the fast path (bit `l` of the mask: lane `l`); the others'
/// values are for the caller to recompute.
#[target_feature(enable = "avx2")]
pub(super) fn noise<const N: usize>(p: &[X4; N], seed: u32) -> (X4, i32) {
    let c = cells(p);
    (store(gradient_noise(&c, seed)), c.fits)
}

/// `vnoise_n` of the lanes that fit, as [`noise`]: the three components' seeds share the cells.
#[target_feature(enable = "avx2")]
pub(super) fn vnoise<const N: usize>(p: &[X4; N], seeds: [u32; 3]) -> ([X4; 3], i32) {
    let c = cells(p);
    (seeds.map(|seed| store(gradient_noise(&c, seed))), c.fits)
}

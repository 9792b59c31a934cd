//! The noise family of RISpec 3.2 section 15.1: `noise`, `pnoise`, `cellnoise` and `random`.
//!
//! `noise` is Perlin gradient noise in the style of Ken Perlin's "improved noise" (2002): a
//! pseudo-random gradient at every integer lattice point, chosen by hashing the lattice coordinates,
//! and the quintic fade `6t^5 - 15t^4 + 10t^3` to blend the corner contributions, so the noise is
//! C2-continuous everywhere (value, first and second derivatives). As in RenderMan, the result is
//! remapped to lie in `[0,1]` and is centred on 0.5: each gradient set averages to zero, so the mean
//! is 0.5, and the value is exactly 0.5 at every integer lattice point. Each dimension's scale (see
//! `SCALE`) makes its observed range cover PhotoRealistic RenderMan's (Pixar's Application Note 13,
//! "Properties of RenderMan Noise Functions": 1-D `[0.209, 0.779]`, 2-D `[0.089, 0.906]`, 3-D
//! `[0.061, 0.954]`, 4-D `[0.033, 0.959]`), so a shader testing a threshold PRMan's noise reaches
//! reaches it here too, and beyond: every dimension spans nearly all of `[0,1]`, so that shaders
//! testing `noise(P) > 0.99` (or `< 0.01`) find points that pass. 1-D and 2-D are scaled by the
//! worst case of their gradient sets, so no input leaves `[0,1]`; 3-D and 4-D, whose values come
//! near that bound too rarely to reach the ends, are scaled further, and a final clamp holds their
//! rare extremes in `[0,1]`. Each function states its observed range, spread and largest slope.
//!
//! `pnoise` is the same noise on a lattice that wraps with a period per dimension, `cellnoise` a
//! pseudo-random value constant over each unit cell, `random` a counter-based generator.
//!
//! Float results come in two shapes: `f32` (RSL's `float noise(...)`) and [`V3`] (the `color`,
//! `point` and `vector` forms, functions prefixed with `v`), whose three components use independent
//! hash seeds and so are decorrelated from each other and from the float form.
//!
//! Determinism: the only float operations are `+ - *`, `floor`, comparisons and conversions between
//! integers and floats, each evaluated in a fixed order, so results are bit-identical on every
//! platform and every run (no `libm`, no fused multiply-add). Lattice coordinates are hashed as 32-bit
//! integers with a bijective integer mix (Chris Wellons' `lowbias32`); they are obtained with
//! saturating float-to-`i64` conversion then truncation to `i32`, i.e. they wrap modulo 2^32, so any
//! finite input, however large, is valid (beyond 2^24 every `f32` is an integer and the fractional
//! part is 0). Non-finite inputs (NaN, infinities) never panic: `noise` and `pnoise` return 0.5,
//! `cellnoise` returns 0.
//!
//! The reference order of operations (which a vectorised implementation must reproduce to agree
//! bit for bit) is the code below: corner hashes as in `corner_hashes`, one dot product per corner
//! summed in dimension order, then linear interpolation `a + t * (b - a)` from the highest dimension
//! down to the first, and finally `0.5 + n * scale` clamped to `[0,1]`.

use super::V3;

pub mod x4;

/// `lowbias32` (Chris Wellons): a bijective 32-bit mix with very low avalanche bias.
const fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// SplitMix64's increment.
const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// One SplitMix64 step from state `z`: the output of the generator whose state was `z`.
const fn mix64(z: u64) -> u64 {
    let mut z = z.wrapping_add(GOLDEN_GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Gradient noise (`noise` and `pnoise`) seeds.
const KIND_GRADIENT: u32 = 0;
/// `cellnoise` seeds.
const KIND_CELL: u32 = 1;

/// The hash seed of a function kind, dimension and component (0 for the float form, 1..=3 for the
/// components of the triple form): every combination hashes independently.
const fn seed(kind: u32, dim: usize, comp: u32) -> u32 {
    mix32(0x7273_6c00 ^ (kind << 8) ^ ((dim as u32) << 4) ^ comp)
}

/// `2^-24`: turns the top 24 bits of a hash into a float in `[0,1)` exactly.
const UNIT24: f32 = 1.0 / 16_777_216.0;

/// The lattice cell of a point: fractional coordinates and the integer coordinates of the two
/// corners along each dimension (`hi` is `lo + 1`, or the wrapped successor for `pnoise`).
struct Cell<const N: usize> {
    frac: [f32; N],
    lo: [i32; N],
    hi: [i32; N],
}

/// The lattice coordinate of an integral float, as an `i64` (saturating beyond 2^63); truncating it
/// to `i32` wraps it modulo 2^32.
fn lattice_coord(floor: f32) -> i64 {
    floor as i64
}

/// The cell of `p` on the infinite lattice, or `None` if a coordinate is not finite.
#[allow(clippy::needless_range_loop)] // index loops: several times faster in unoptimised builds
fn cell<const N: usize>(p: [f32; N]) -> Option<Cell<N>> {
    let mut c = Cell { frac: [0.0; N], lo: [0; N], hi: [0; N] };
    for k in 0..N {
        let x = p[k];
        if !x.is_finite() {
            return None;
        }
        let f = x.floor();
        // `x - floor(x)` is exact except for tiny negative x, where it rounds to 1.0: the value at
        // the upper corner, so continuity is unaffected.
        c.frac[k] = x - f;
        let i = lattice_coord(f) as i32;
        c.lo[k] = i;
        c.hi[k] = i.wrapping_add(1);
    }
    Some(c)
}

/// The integer period of a float period: `floor(period)`, with anything below 1 (and NaN) taken as
/// 1; `+inf` saturates to `i64::MAX`.
fn int_period(period: f32) -> i64 {
    if period >= 1.0 {
        period.floor() as i64
    } else {
        1
    }
}

/// The cell of `p` on the lattice wrapped with `period`, or `None` if a coordinate of `p` is not
/// finite. Lattice coordinates are reduced to `[0, period)`, so for `0 <= p` and `floor(p) + 1 <
/// period` the cell is the same as [`cell`]'s and `pnoise` equals `noise` bit for bit. A period of
/// 2^32 or more (`+inf` included) does not wrap at all: the cell is [`cell`]'s everywhere.
#[allow(clippy::needless_range_loop)] // index loops: several times faster in unoptimised builds
fn periodic_cell<const N: usize>(p: [f32; N], period: [f32; N]) -> Option<Cell<N>> {
    let mut c = Cell { frac: [0.0; N], lo: [0; N], hi: [0; N] };
    for k in 0..N {
        let x = p[k];
        if !x.is_finite() {
            return None;
        }
        let f = x.floor();
        c.frac[k] = x - f;
        let per = int_period(period[k]);
        let i = lattice_coord(f);
        if per > i64::from(u32::MAX) {
            c.lo[k] = i as i32;
            c.hi[k] = (i as i32).wrapping_add(1);
        } else {
            let i = i.rem_euclid(per);
            // i < per <= 2^32, so i + 1 cannot overflow.
            let j = if i + 1 == per { 0 } else { i + 1 };
            c.lo[k] = i as i32;
            c.hi[k] = j as i32;
        }
    }
    Some(c)
}

/// The hash of every corner of a cell; corner `i` takes `hi` along dimension `k` when bit `k` of
/// `i` is set. The hash of corner `(c0, c1, ..)` is `h0 = mix(mix(c0) ^ seed)`, then
/// `h(k) = mix(h(k-1) + ck)` (wrapping), so the first coordinate is scrambled before the seed enters
/// and different seeds give unrelated noises (not translates of one another).
#[allow(clippy::needless_range_loop)] // index loops: several times faster in unoptimised builds
fn corner_hashes<const N: usize>(c: &Cell<N>, seed: u32) -> [u32; 16] {
    let mut h = [0u32; 16];
    h[0] = mix32(mix32(c.lo[0] as u32) ^ seed);
    h[1] = mix32(mix32(c.hi[0] as u32) ^ seed);
    let mut len = 2;
    for k in 1..N {
        let (lo, hi) = (c.lo[k] as u32, c.hi[k] as u32);
        for i in 0..len {
            let base = h[i];
            h[i] = mix32(base.wrapping_add(lo));
            h[i + len] = mix32(base.wrapping_add(hi));
        }
        len *= 2;
    }
    h
}

/// 2-D gradients: 16 unit vectors at angles `(k + 1/2) * 22.5` degrees (none axis-aligned).
const GRAD2: [[f32; 4]; 16] = [
    [0.980_785_25, 0.195_090_32, 0.0, 0.0],
    [0.831_469_6, 0.555_570_24, 0.0, 0.0],
    [0.555_570_24, 0.831_469_6, 0.0, 0.0],
    [0.195_090_32, 0.980_785_25, 0.0, 0.0],
    [-0.195_090_32, 0.980_785_25, 0.0, 0.0],
    [-0.555_570_24, 0.831_469_6, 0.0, 0.0],
    [-0.831_469_6, 0.555_570_24, 0.0, 0.0],
    [-0.980_785_25, 0.195_090_32, 0.0, 0.0],
    [-0.980_785_25, -0.195_090_32, 0.0, 0.0],
    [-0.831_469_6, -0.555_570_24, 0.0, 0.0],
    [-0.555_570_24, -0.831_469_6, 0.0, 0.0],
    [-0.195_090_32, -0.980_785_25, 0.0, 0.0],
    [0.195_090_32, -0.980_785_25, 0.0, 0.0],
    [0.555_570_24, -0.831_469_6, 0.0, 0.0],
    [0.831_469_6, -0.555_570_24, 0.0, 0.0],
    [0.980_785_25, -0.195_090_32, 0.0, 0.0],
];

/// 3-D gradients: Perlin's 12 cube-edge midpoints, padded to 16 with 4 of them repeated.
const GRAD3: [[f32; 4]; 16] = [
    [1.0, 1.0, 0.0, 0.0],
    [-1.0, 1.0, 0.0, 0.0],
    [1.0, -1.0, 0.0, 0.0],
    [-1.0, -1.0, 0.0, 0.0],
    [1.0, 0.0, 1.0, 0.0],
    [-1.0, 0.0, 1.0, 0.0],
    [1.0, 0.0, -1.0, 0.0],
    [-1.0, 0.0, -1.0, 0.0],
    [0.0, 1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0, 0.0],
    [0.0, 1.0, -1.0, 0.0],
    [0.0, -1.0, -1.0, 0.0],
    [1.0, 1.0, 0.0, 0.0],
    [0.0, -1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0, 0.0],
    [0.0, -1.0, -1.0, 0.0],
];

/// 4-D gradients: the 32 vectors with one zero and three `±1` components.
const GRAD4: [[f32; 4]; 32] = [
    [0.0, 1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0, -1.0],
    [0.0, 1.0, -1.0, 1.0],
    [0.0, 1.0, -1.0, -1.0],
    [0.0, -1.0, 1.0, 1.0],
    [0.0, -1.0, 1.0, -1.0],
    [0.0, -1.0, -1.0, 1.0],
    [0.0, -1.0, -1.0, -1.0],
    [1.0, 0.0, 1.0, 1.0],
    [1.0, 0.0, 1.0, -1.0],
    [1.0, 0.0, -1.0, 1.0],
    [1.0, 0.0, -1.0, -1.0],
    [-1.0, 0.0, 1.0, 1.0],
    [-1.0, 0.0, 1.0, -1.0],
    [-1.0, 0.0, -1.0, 1.0],
    [-1.0, 0.0, -1.0, -1.0],
    [1.0, 1.0, 0.0, 1.0],
    [1.0, 1.0, 0.0, -1.0],
    [1.0, -1.0, 0.0, 1.0],
    [1.0, -1.0, 0.0, -1.0],
    [-1.0, 1.0, 0.0, 1.0],
    [-1.0, 1.0, 0.0, -1.0],
    [-1.0, -1.0, 0.0, 1.0],
    [-1.0, -1.0, 0.0, -1.0],
    [1.0, 1.0, 1.0, 0.0],
    [1.0, 1.0, -1.0, 0.0],
    [1.0, -1.0, 1.0, 0.0],
    [1.0, -1.0, -1.0, 0.0],
    [-1.0, 1.0, 1.0, 0.0],
    [-1.0, 1.0, -1.0, 0.0],
    [-1.0, -1.0, 1.0, 0.0],
    [-1.0, -1.0, -1.0, 0.0],
];

/// The gradient of a corner with hash `h` in dimension `N` (padded to 4 components). In 1-D it is
/// one of the 256 odd integers in `[-255, 255]` (the top 8 bits of the hash), so that independent
/// seeds practically never pick the same slopes; otherwise an entry of the dimension's table picked
/// by the top bits of the hash.
fn gradient<const N: usize>(h: u32) -> [f32; 4] {
    let table: &[[f32; 4]] = match N {
        1 => return [((h >> 24) as i32 * 2 - 255) as f32, 0.0, 0.0, 0.0],
        2 => &GRAD2,
        3 => &GRAD3,
        _ => &GRAD4,
    };
    table[(h >> 27) as usize & (table.len() - 1)]
}

/// The remap `0.5 + n * SCALE[dim - 1]`: for 1-D and 2-D, `0.5 / B` where `B` is the largest value
/// the raw noise can take with that gradient set, i.e. the maximum over the unit cell of the sum over
/// corners of (fade weight) x (best gradient's dot product), found by dense search and local
/// refinement: `B1 = 127.5` exactly (at `x = 1/2`, slopes 255 and -255; the scale 1/256 keeps 1-D
/// noise within `[1/512, 1 - 1/512]`), `B2 = 0.695_352_7`; rounded down so the exact result stays
/// within `[0,1]`. 3-D noise at `0.5 / B3` (`B3 = 1.036_353_8`, the known bound of improved noise)
/// comes no nearer than 0.02 to either end over 10^7 inputs, so its scale is 1.1 times that; 4-D
/// at `0.5 / B4` (`B4 = 1.536_582_3`) spans only `[0.14, 0.86]`, so its scale is 1.5 times that.
/// With these, a few in 10^6 inputs pass 0.99 (and as many fall below 0.01); the clamp takes the
/// few values past `[0,1]`.
const SCALE: [f32; 4] = [1.0 / 256.0, 0.719_05, 0.530_7, 0.490_2];

/// The quintic fade `6t^5 - 15t^4 + 10t^3`; exactly 0 at 0 and exactly 1 at 1.
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Gradient noise over a cell with a seed, remapped to `[0,1]`.
#[allow(clippy::needless_range_loop)] // index loops: several times faster in unoptimised builds
fn gradient_noise<const N: usize>(c: &Cell<N>, seed: u32) -> f32 {
    let h = corner_hashes(c, seed);
    let mut v = [0.0f32; 16];
    for i in 0..1 << N {
        let g = gradient::<N>(h[i]);
        let mut dot = 0.0f32;
        for k in 0..N {
            let d = if (i >> k) & 1 == 0 { c.frac[k] } else { c.frac[k] - 1.0 };
            dot += g[k] * d;
        }
        v[i] = dot;
    }
    // Interpolate `a + t * (b - a)` along the highest dimension first.
    for k in (0..N).rev() {
        let t = fade(c.frac[k]);
        let half = 1 << k;
        for i in 0..half {
            v[i] += t * (v[i + half] - v[i]);
        }
    }
    (0.5 + v[0] * SCALE[N - 1]).clamp(0.0, 1.0)
}

fn noise_n<const N: usize>(p: [f32; N]) -> f32 {
    cell(p).map_or(0.5, |c| gradient_noise(&c, seed(KIND_GRADIENT, N, 0)))
}

fn vnoise_n<const N: usize>(p: [f32; N]) -> V3 {
    cell(p).map_or([0.5; 3], |c| [1, 2, 3].map(|k| gradient_noise(&c, seed(KIND_GRADIENT, N, k))))
}

fn pnoise_n<const N: usize>(p: [f32; N], period: [f32; N]) -> f32 {
    periodic_cell(p, period).map_or(0.5, |c| gradient_noise(&c, seed(KIND_GRADIENT, N, 0)))
}

fn vpnoise_n<const N: usize>(p: [f32; N], period: [f32; N]) -> V3 {
    periodic_cell(p, period).map_or([0.5; 3], |c| [1, 2, 3].map(|k| gradient_noise(&c, seed(KIND_GRADIENT, N, k))))
}

/// The hash of the cell containing `p` (the lower corner's hash, as in [`corner_hashes`]), turned
/// into `[0,1)`; 0 if a coordinate is not finite.
fn cell_value<const N: usize>(p: [f32; N], comp: u32) -> f32 {
    match cell(p) {
        Some(c) => (corner_hashes(&c, seed(KIND_CELL, N, comp))[0] >> 8) as f32 * UNIT24,
        None => 0.0,
    }
}

fn cellnoise_n<const N: usize>(p: [f32; N]) -> f32 {
    cell_value(p, 0)
}

fn vcellnoise_n<const N: usize>(p: [f32; N]) -> V3 {
    [1, 2, 3].map(|k| cell_value(p, k))
}

/// 1-D noise `float noise(float x)`: in `[1/512, 1 - 1/512]` (the bound is reached only midway
/// between integers whose slopes are extreme and opposite), mean 0.5, exactly 0.5 at integers,
/// C2-continuous. Observed over 10^6 inputs in `[-1000, 1000)`: range `[0.021, 0.992]`, standard
/// deviation 0.140, largest slope 1.33. NaN and infinities give 0.5.
pub fn noise1(x: f32) -> f32 {
    noise_n([x])
}

/// 2-D noise `float noise(float x, float y)`: in `[0,1]`, mean 0.5, exactly 0.5 at lattice points,
/// C2-continuous. Observed over 10^6 inputs in `[-1000, 1000)^2`: range `[0.002, 0.997]`, standard
/// deviation 0.155, largest slope 1.46. Non-finite input gives 0.5.
pub fn noise2(x: f32, y: f32) -> f32 {
    noise_n([x, y])
}

/// 3-D noise `float noise(point p)`: in `[0,1]`, mean 0.5, exactly 0.5 at lattice points,
/// C2-continuous. Observed over 10^6 inputs in `[-1000, 1000)^3`: range `[0, 1]` (a few in 10^6
/// above 0.99), standard deviation 0.143, largest slope 1.51. Non-finite input gives 0.5.
pub fn noise3(p: V3) -> f32 {
    noise_n(p)
}

/// 4-D noise `float noise(point p, float t)`: in `[0,1]`, mean 0.5, exactly 0.5 at lattice points,
/// C2-continuous. Observed over 10^6 inputs in `[-1000, 1000)^4`: range `[0, 1]` (about 10 in 10^6
/// above 0.99), standard deviation 0.143, largest slope 1.59. Non-finite input gives 0.5.
pub fn noise4(p: V3, t: f32) -> f32 {
    noise_n([p[0], p[1], p[2], t])
}

/// Triple 1-D noise (`color`/`point`/`vector noise(float)`): three independent noises, each with
/// the range and continuity of [`noise1`]. Non-finite input gives `[0.5; 3]`.
pub fn vnoise1(x: f32) -> V3 {
    vnoise_n([x])
}

/// Triple 2-D noise (`color`/`point`/`vector noise(float, float)`): three independent noises with
/// the properties of [`noise2`]. Non-finite input gives `[0.5; 3]`.
pub fn vnoise2(x: f32, y: f32) -> V3 {
    vnoise_n([x, y])
}

/// Triple 3-D noise (`color`/`point`/`vector noise(point)`): three independent noises with the
/// properties of [`noise3`]. Non-finite input gives `[0.5; 3]`.
pub fn vnoise3(p: V3) -> V3 {
    vnoise_n(p)
}

/// Triple 4-D noise (`color`/`point`/`vector noise(point, float)`): three independent noises with
/// the properties of [`noise4`]. Non-finite input gives `[0.5; 3]`.
pub fn vnoise4(p: V3, t: f32) -> V3 {
    vnoise_n([p[0], p[1], p[2], t])
}

/// 1-D periodic noise `float pnoise(float x, float period)`: [`noise1`] on a lattice that wraps
/// every `floor(px)` units, so `pnoise1(x + k * px, px) == pnoise1(x, px)` for integer `px` and `k`
/// (exactly when the addition is exact). A period below 1, or NaN, is taken as 1 (the noise is then
/// the same in every unit interval); one of 2^32 or more, `+inf` included, never wraps. For
/// `0 <= x` and `floor(x) + 1 < floor(px)` it equals `noise1(x)` bit for bit. Same range as
/// [`noise1`]; a non-finite `x` gives 0.5.
pub fn pnoise1(x: f32, px: f32) -> f32 {
    pnoise_n([x], [px])
}

/// 2-D periodic noise `float pnoise(float x, float y, float px, float py)`: [`noise2`] wrapping
/// with a period per dimension, as [`pnoise1`] describes. Non-finite `x` or `y` gives 0.5.
pub fn pnoise2(x: f32, y: f32, px: f32, py: f32) -> f32 {
    pnoise_n([x, y], [px, py])
}

/// 3-D periodic noise `float pnoise(point p, point period)`: [`noise3`] wrapping with a period per
/// dimension, as [`pnoise1`] describes. Non-finite `p` gives 0.5.
pub fn pnoise3(p: V3, period: V3) -> f32 {
    pnoise_n(p, period)
}

/// 4-D periodic noise `float pnoise(point p, float t, point period, float tperiod)`: [`noise4`]
/// wrapping with a period per dimension, as [`pnoise1`] describes. Non-finite `p` or `t` gives 0.5.
pub fn pnoise4(p: V3, t: f32, period: V3, pt: f32) -> f32 {
    pnoise_n([p[0], p[1], p[2], t], [period[0], period[1], period[2], pt])
}

/// Triple 1-D periodic noise: [`vnoise1`] with the wrapping of [`pnoise1`] (the components equal
/// `vnoise1`'s where [`pnoise1`] equals [`noise1`]). Non-finite input gives `[0.5; 3]`.
pub fn vpnoise1(x: f32, px: f32) -> V3 {
    vpnoise_n([x], [px])
}

/// Triple 2-D periodic noise: [`vnoise2`] with the wrapping of [`pnoise2`]. Non-finite input gives
/// `[0.5; 3]`.
pub fn vpnoise2(x: f32, y: f32, px: f32, py: f32) -> V3 {
    vpnoise_n([x, y], [px, py])
}

/// Triple 3-D periodic noise: [`vnoise3`] with the wrapping of [`pnoise3`]. Non-finite input gives
/// `[0.5; 3]`.
pub fn vpnoise3(p: V3, period: V3) -> V3 {
    vpnoise_n(p, period)
}

/// Triple 4-D periodic noise: [`vnoise4`] with the wrapping of [`pnoise4`]. Non-finite input gives
/// `[0.5; 3]`.
pub fn vpnoise4(p: V3, t: f32, period: V3, pt: f32) -> V3 {
    vpnoise_n([p[0], p[1], p[2], t], [period[0], period[1], period[2], pt])
}

/// 1-D `float cellnoise(float x)`: a pseudo-random value in `[0,1)` (a multiple of 2^-24),
/// constant for `x` in `[i, i+1)`. Non-finite input gives 0.
pub fn cellnoise1(x: f32) -> f32 {
    cellnoise_n([x])
}

/// 2-D `float cellnoise(float x, float y)`: constant over each unit square, in `[0,1)`. Non-finite
/// input gives 0.
pub fn cellnoise2(x: f32, y: f32) -> f32 {
    cellnoise_n([x, y])
}

/// 3-D `float cellnoise(point p)`: constant over each unit cube, in `[0,1)`. Non-finite input gives
/// 0.
pub fn cellnoise3(p: V3) -> f32 {
    cellnoise_n(p)
}

/// 4-D `float cellnoise(point p, float t)`: constant over each unit hypercube, in `[0,1)`.
/// Non-finite input gives 0.
pub fn cellnoise4(p: V3, t: f32) -> f32 {
    cellnoise_n([p[0], p[1], p[2], t])
}

/// Triple 1-D cellnoise (`color`/`point`/`vector cellnoise(float)`): three independent values in
/// `[0,1)`, constant over each unit interval. Non-finite input gives `[0; 3]`.
pub fn vcellnoise1(x: f32) -> V3 {
    vcellnoise_n([x])
}

/// Triple 2-D cellnoise: three independent values in `[0,1)` per unit square. Non-finite input
/// gives `[0; 3]`.
pub fn vcellnoise2(x: f32, y: f32) -> V3 {
    vcellnoise_n([x, y])
}

/// Triple 3-D cellnoise: three independent values in `[0,1)` per unit cube. Non-finite input gives
/// `[0; 3]`.
pub fn vcellnoise3(p: V3) -> V3 {
    vcellnoise_n(p)
}

/// Triple 4-D cellnoise: three independent values in `[0,1)` per unit hypercube. Non-finite input
/// gives `[0; 3]`.
pub fn vcellnoise4(p: V3, t: f32) -> V3 {
    vcellnoise_n([p[0], p[1], p[2], t])
}

/// Turns the top 24 bits of a 64-bit hash into `[0,1)`.
fn unit64(h: u64) -> f32 {
    (h >> 40) as f32 * UNIT24
}

/// The seed of the `call`-th `random()` evaluated at shading point `point` (any stable id of the
/// lane: pixel and sample index, ray id, ...; `call` counts the `random()` calls of that point, from
/// 0): `mix64(point) + call * gamma`, so that successive calls at a point walk a SplitMix64 stream
/// started from a hash of the point.
pub fn random_seed(point: u64, call: u64) -> u64 {
    mix64(point).wrapping_add(call.wrapping_mul(GOLDEN_GAMMA))
}

/// RSL's `float random()`, made deterministic: a uniform value in `[0,1)` (a multiple of 2^-24)
/// that is a pure function of `seed`. RenderMan's `random()` takes no argument and differs per call
/// and per shading point; the caller provides that by deriving the seed from the shading point and
/// the call index, e.g. with [`random_seed`]. The generator is counter-based (SplitMix64's output
/// function), so nearby seeds give unrelated values.
pub fn random(seed: u64) -> f32 {
    unit64(mix64(seed))
}

/// RSL's `color`/`point`/`vector random()`: three independent uniform values in `[0,1)` from one
/// seed (see [`random`]); they are unrelated to `random(seed)` and to the triples of other seeds.
pub fn vrandom(seed: u64) -> V3 {
    let base = mix64(seed ^ 0x7672_616e_646f_6d33);
    [0u64, 1, 2].map(|k| unit64(mix64(base.wrapping_add(k.wrapping_mul(GOLDEN_GAMMA)))))
}

/// Octaves of lucille's `turb`: scales 2, 1, 1/2, ... down to the last above 1e-4.
pub const LUCILLE_TURB_OCTAVES: usize = 15;

/// lucille's `turb(p)` (its shader engine's `turb_cp`): the sum over scales 2, 1, 1/2, ... (the
/// [`LUCILLE_TURB_OCTAVES`] above 1e-4) of `scale * snoise(p / scale)`, with `snoise` signed noise
/// (`2 noise - 1`): fractal noise whose amplitude falls with frequency, not the absolute-value
/// turbulence of RISpec's examples. [`x4::lucille_turb`] computes the same, bit for bit.
pub fn lucille_turb(p: V3) -> f32 {
    let mut sum = 0.0f32;
    let mut scale = 2.0f32;
    for _ in 0..LUCILLE_TURB_OCTAVES {
        let n = noise3([p[0] / scale, p[1] / scale, p[2] / scale]);
        sum += scale * (2.0 * n - 1.0);
        scale *= 0.5;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator for test inputs.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(1);
            mix64(self.0)
        }
        /// Uniform in `[lo, hi)`.
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * unit64(self.next())
        }
        fn v3(&mut self, lo: f32, hi: f32) -> V3 {
            [self.range(lo, hi), self.range(lo, hi), self.range(lo, hi)]
        }
    }

    fn in_unit_closed(v: f32) -> bool {
        (0.0..=1.0).contains(&v)
    }

    fn in_unit_open(v: f32) -> bool {
        (0.0..1.0).contains(&v)
    }

    /// Checks range `[0,1]` and mean `0.5 ± 0.02` of a gradient noise over `n` samples.
    fn check_range_mean(name: &str, n: usize, mut f: impl FnMut() -> f32) {
        let mut sum = 0.0f64;
        for _ in 0..n {
            let v = f();
            assert!(in_unit_closed(v), "{name}: {v} outside [0,1]");
            sum += f64::from(v);
        }
        let mean = sum / n as f64;
        assert!((mean - 0.5).abs() < 0.02, "{name}: mean {mean}");
    }

    /// A random period per dimension: mostly integers 1..=16, sometimes fractional or below 1.
    fn period(r: &mut Rng) -> f32 {
        match r.next() % 4 {
            0 => r.range(-2.0, 20.0),
            _ => (1 + r.next() % 16) as f32,
        }
    }

    #[test]
    fn noise_covers_the_range_of_prmans_noise() {
        // PRMan's measured extremes (Application Note 13), less a margin for the fewer samples here:
        // a shader testing a value PRMan's noise reaches reaches it with this one.
        let prman = [(0.2092, 0.7785), (0.0894, 0.9061), (0.0607, 0.9541), (0.0333, 0.9585)];
        let mut r = Rng(7);
        let w = 1000.0;
        for (dim, (lo, hi)) in prman.into_iter().enumerate() {
            let (mut min, mut max) = (1.0f32, 0.0f32);
            for _ in 0..200_000 {
                let v = match dim {
                    0 => noise1(r.range(-w, w)),
                    1 => noise2(r.range(-w, w), r.range(-w, w)),
                    2 => noise3(r.v3(-w, w)),
                    _ => noise4(r.v3(-w, w), r.range(-w, w)),
                };
                (min, max) = (min.min(v), max.max(v));
            }
            assert!(min <= lo + 0.03 && max >= hi - 0.03, "{}-D noise spans [{min}, {max}]", dim + 1);
        }
    }

    /// Shaders that test `noise(P) > 0.99` (or `noise(P, t)`, or `< 0.01`) find points that pass.
    #[test]
    fn point_noise_passes_thresholds_near_both_ends() {
        let mut r = Rng(11);
        let w = 1000.0;
        for dim in [3, 4] {
            let (mut high, mut low) = (0, 0);
            for _ in 0..1_000_000 {
                let v = if dim == 3 { noise3(r.v3(-w, w)) } else { noise4(r.v3(-w, w), r.range(-w, w)) };
                high += usize::from(v > 0.99);
                low += usize::from(v < 0.01);
            }
            assert!(high > 0 && low > 0, "{dim}-D noise: {high} values above 0.99, {low} below 0.01 in 10^6");
        }
    }

    #[test]
    fn noise_and_pnoise_stay_in_unit_interval_centred_on_half() {
        let mut r = Rng(1);
        let n = 25_000;
        let w = 1000.0;
        check_range_mean("noise1", n, || noise1(r.range(-w, w)));
        check_range_mean("noise2", n, || noise2(r.range(-w, w), r.range(-w, w)));
        check_range_mean("noise3", n, || noise3(r.v3(-w, w)));
        check_range_mean("noise4", n, || noise4(r.v3(-w, w), r.range(-w, w)));
        check_range_mean("pnoise1", n, || pnoise1(r.range(-w, w), period(&mut r)));
        check_range_mean("pnoise2", n, || pnoise2(r.range(-w, w), r.range(-w, w), period(&mut r), period(&mut r)));
        check_range_mean("pnoise3", n, || {
            let p = r.v3(-w, w);
            pnoise3(p, [period(&mut r), period(&mut r), period(&mut r)])
        });
        check_range_mean("pnoise4", n, || {
            let (p, t) = (r.v3(-w, w), r.range(-w, w));
            pnoise4(p, t, [period(&mut r), period(&mut r), period(&mut r)], period(&mut r))
        });
    }

    #[test]
    fn cellnoise_and_random_stay_in_half_open_unit_interval() {
        let mut r = Rng(2);
        let w = 1.0e4;
        for _ in 0..25_000 {
            let (x, y, p, t) = (r.range(-w, w), r.range(-w, w), r.v3(-w, w), r.range(-w, w));
            for v in [cellnoise1(x), cellnoise2(x, y), cellnoise3(p), cellnoise4(p, t)] {
                assert!(in_unit_open(v), "cellnoise {v}");
            }
        }
        let mut sum = 0.0f64;
        for seed in 0..100_000u64 {
            let v = random(seed);
            assert!(in_unit_open(v));
            sum += f64::from(v);
            assert!(vrandom(seed).iter().all(|&c| in_unit_open(c)));
        }
        assert!((sum / 100_000.0 - 0.5).abs() < 0.01);
        assert!(in_unit_open(random(u64::MAX)) && in_unit_open(random(0)));
    }

    #[test]
    fn noise_is_exactly_half_at_lattice_points() {
        let mut r = Rng(3);
        let int = |r: &mut Rng| (r.next() % 20_001) as f32 - 10_000.0;
        for _ in 0..2_000 {
            let (x, y, z, t) = (int(&mut r), int(&mut r), int(&mut r), int(&mut r));
            assert_eq!(noise1(x), 0.5);
            assert_eq!(noise2(x, y), 0.5);
            assert_eq!(noise3([x, y, z]), 0.5);
            assert_eq!(noise4([x, y, z], t), 0.5);
            assert_eq!(vnoise3([x, y, z]), [0.5; 3]);
            assert_eq!(vnoise4([x, y, z], t), [0.5; 3]);
            assert_eq!(pnoise3([x, y, z], [3.0, 5.0, 7.0]), 0.5);
            assert_eq!(vpnoise4([x, y, z], t, [3.0, 5.0, 7.0], 2.0), [0.5; 3]);
        }
        // Beyond 2^24 every float is an integer.
        assert_eq!(noise1(3.0e7), 0.5);
        assert_eq!(noise3([1.0e20, -3.0e9, 16_777_216.0]), 0.5);
    }

    /// Lipschitz bound checked by the continuity test: the largest slope observed over 10^6 samples
    /// per dimension is 1.59 (see the doc comments of `noise1`..`noise4`).
    const LIPSCHITZ: f64 = 2.0;

    /// Checks `|f(p + h d) - f(p)| <= LIPSCHITZ * |actual step|` for a random unit direction `d`.
    fn check_continuity<const N: usize>(r: &mut Rng, f: impl Fn([f32; N]) -> f32) {
        for _ in 0..5_000 {
            let p: [f32; N] = std::array::from_fn(|_| r.range(-100.0, 100.0));
            let d: [f32; N] = std::array::from_fn(|_| r.range(-1.0, 1.0));
            let len = d.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-3);
            let q: [f32; N] = std::array::from_fn(|k| p[k] + 1.0e-3 * d[k] / len);
            let step = p.iter().zip(&q).map(|(a, b)| (f64::from(*b) - f64::from(*a)).powi(2)).sum::<f64>().sqrt();
            let diff = (f64::from(f(q)) - f64::from(f(p))).abs();
            assert!(diff <= LIPSCHITZ * step + 1e-6, "N={N} p={p:?} q={q:?}: {diff} over {step}");
        }
    }

    #[test]
    fn noise_is_lipschitz_continuous() {
        let mut r = Rng(4);
        check_continuity(&mut r, |p: [f32; 1]| noise1(p[0]));
        check_continuity(&mut r, |p: [f32; 2]| noise2(p[0], p[1]));
        check_continuity(&mut r, noise3);
        check_continuity(&mut r, |p: [f32; 4]| noise4([p[0], p[1], p[2]], p[3]));
        check_continuity(&mut r, |p: [f32; 3]| pnoise3(p, [4.0, 5.0, 6.0]));
        check_continuity(&mut r, |p: [f32; 3]| vnoise3(p)[2]);
        // Continuous across the wrap of a period of 1 as well: the lattice is then constant.
        check_continuity(&mut r, |p: [f32; 2]| pnoise2(p[0], p[1], 1.0, 1.0));
    }

    /// Checks that shifting each dimension by multiples of its integer period leaves `f` unchanged,
    /// bit for bit (the inputs are multiples of 1/64, so the shifted inputs are exact).
    fn check_periodic<const N: usize>(r: &mut Rng, f: impl Fn([f32; N], [f32; N]) -> V3) {
        for _ in 0..250 {
            let p: [f32; N] = std::array::from_fn(|_| (r.next() % 8_192) as f32 / 64.0 - 64.0);
            let per: [f32; N] = std::array::from_fn(|_| (1 + r.next() % 16) as f32);
            let base = f(p, per);
            for k in 0..N {
                for m in [-3.0, -1.0, 1.0, 2.0, 5.0] {
                    let mut q = p;
                    q[k] += m * per[k];
                    assert_eq!(f(q, per), base, "N={N} p={p:?} per={per:?} k={k} m={m}");
                }
            }
        }
    }

    #[test]
    fn pnoise_is_periodic_in_every_dimension() {
        let mut r = Rng(5);
        check_periodic(&mut r, |p: [f32; 1], per: [f32; 1]| [pnoise1(p[0], per[0]); 3]);
        check_periodic(&mut r, |p: [f32; 2], per: [f32; 2]| [pnoise2(p[0], p[1], per[0], per[1]); 3]);
        check_periodic(&mut r, |p: [f32; 3], per: [f32; 3]| [pnoise3(p, per); 3]);
        check_periodic(&mut r, |p: [f32; 4], per: [f32; 4]| {
            [pnoise4([p[0], p[1], p[2]], p[3], [per[0], per[1], per[2]], per[3]); 3]
        });
        check_periodic(&mut r, |p: [f32; 1], per: [f32; 1]| vpnoise1(p[0], per[0]));
        check_periodic(&mut r, |p: [f32; 2], per: [f32; 2]| vpnoise2(p[0], p[1], per[0], per[1]));
        check_periodic(&mut r, vpnoise3);
        check_periodic(&mut r, |p: [f32; 4], per: [f32; 4]| {
            vpnoise4([p[0], p[1], p[2]], p[3], [per[0], per[1], per[2]], per[3])
        });
        // Arbitrary inputs: equal up to the rounding of the shifted input.
        for _ in 0..2_000 {
            let p = r.v3(-100.0, 100.0);
            let a = pnoise3(p, [3.0, 4.0, 5.0]);
            let b = pnoise3([p[0] + 3.0, p[1] - 8.0, p[2] + 15.0], [3.0, 4.0, 5.0]);
            assert!((a - b).abs() <= 1e-5, "{p:?}: {a} vs {b}");
        }
    }

    #[test]
    fn pnoise_periods_are_floored_and_at_least_one() {
        let mut r = Rng(6);
        for _ in 0..2_000 {
            let x = r.range(-50.0, 50.0);
            let y = r.range(-50.0, 50.0);
            assert_eq!(pnoise1(x, 3.7), pnoise1(x, 3.0));
            assert_eq!(pnoise1(x, 0.3), pnoise1(x, 1.0));
            assert_eq!(pnoise1(x, -5.0), pnoise1(x, 1.0));
            assert_eq!(pnoise1(x, f32::NAN), pnoise1(x, 1.0));
            assert_eq!(pnoise2(x, y, 2.5, f32::NEG_INFINITY), pnoise2(x, y, 2.0, 1.0));
            assert_eq!(vpnoise3([x, y, x], [1.5, 9.9, 0.0]), vpnoise3([x, y, x], [1.0, 9.0, 1.0]));
        }
    }

    #[test]
    fn pnoise_equals_noise_inside_the_first_period() {
        let mut r = Rng(7);
        for _ in 0..2_000 {
            let p = r.v3(0.0, 9.0);
            let t = r.range(0.0, 9.0);
            let big = [10.0; 3];
            assert_eq!(pnoise1(p[0], 10.0), noise1(p[0]));
            assert_eq!(pnoise2(p[0], p[1], 10.0, 10.0), noise2(p[0], p[1]));
            assert_eq!(pnoise3(p, big), noise3(p));
            assert_eq!(pnoise4(p, t, big, 10.0), noise4(p, t));
            assert_eq!(vpnoise3(p, big), vnoise3(p));
            assert_eq!(pnoise3(p, [f32::INFINITY; 3]), noise3(p));
            // Periods of 2^32 and more do not wrap, for negative inputs too.
            let q = r.v3(-1.0e6, 1.0e6);
            assert_eq!(vpnoise4(q, t, [f32::INFINITY, 4_294_967_296.0, 1.0e30], 1.0e10), vnoise4(q, t));
        }
    }

    #[test]
    fn cellnoise_is_constant_per_cell_and_varies_across_cells() {
        let mut r = Rng(8);
        for _ in 0..5_000 {
            let cell = [(r.next() % 2_000) as f32 - 1_000.0, (r.next() % 2_000) as f32 - 1_000.0];
            let (a, b) = (r.range(0.0, 0.999), r.range(0.0, 0.999));
            let (p, q) = ([cell[0] + a, cell[1] + b, cell[0] - a], [cell[0], cell[1], cell[0] - 1.0]);
            // p and q lie in the same cell: [c0, c0+1) x [c1, c1+1) x [c0-1, c0).
            assert_eq!(cellnoise1(cell[0] + a), cellnoise1(cell[0]));
            assert_eq!(cellnoise2(p[0], p[1]), cellnoise2(q[0], q[1]));
            assert_eq!(cellnoise3(p), cellnoise3(q));
            assert_eq!(cellnoise4(p, p[1]), cellnoise4(q, q[1]));
            assert_eq!(vcellnoise3(p), vcellnoise3(q));
            assert_eq!(vcellnoise4(p, p[0]), vcellnoise4(q, q[0]));
        }
        let distinct = |values: Vec<f32>| {
            let n = values.len();
            let mut bits: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
            bits.sort_unstable();
            bits.dedup();
            assert!(bits.len() * 100 > n * 99, "{} distinct of {n}", bits.len());
        };
        let c = |i: i32| i as f32 + 0.5;
        distinct((-500..500).map(|i| cellnoise1(c(i))).collect());
        distinct((0..1_024).map(|i| cellnoise2(c(i % 32), c(i / 32))).collect());
        distinct((0..1_000).map(|i| cellnoise3([c(i % 10), c(i / 10 % 10), c(i / 100)])).collect());
        distinct((0..1_296).map(|i| cellnoise4([c(i % 6), c(i / 6 % 6), c(i / 36 % 6)], c(i / 216))).collect());
        distinct((0..1_000).map(|i| vcellnoise3([c(i % 10), c(i / 10 % 10), c(i / 100)])[1]).collect());
    }

    /// Pearson correlation of two samples.
    fn correlation(a: &[f32], b: &[f32]) -> f64 {
        let n = a.len() as f64;
        let ma = a.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let mb = b.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for (&x, &y) in a.iter().zip(b) {
            let (x, y) = (f64::from(x) - ma, f64::from(y) - mb);
            sab += x * y;
            saa += x * x;
            sbb += y * y;
        }
        sab / (saa * sbb).sqrt()
    }

    /// Checks that the three components of a triple function and its float form are pairwise weakly
    /// correlated and not equal.
    fn check_decorrelated(name: &str, r: &mut Rng, f: impl Fn(&mut Rng) -> (f32, V3)) {
        let n = 3_000;
        let mut cols: [Vec<f32>; 4] = Default::default();
        let mut equal = 0;
        for _ in 0..n {
            let (s, v) = f(r);
            if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                equal += 1;
            }
            cols[0].push(s);
            for k in 0..3 {
                cols[k + 1].push(v[k]);
            }
        }
        assert!(equal < n / 100, "{name}: {equal} triples with equal components");
        for i in 0..4 {
            for j in i + 1..4 {
                let c = correlation(&cols[i], &cols[j]);
                assert!(c.abs() < 0.2, "{name}: correlation {c} between columns {i} and {j}");
            }
        }
    }

    #[test]
    fn triple_components_are_decorrelated() {
        let mut r = Rng(9);
        let w = 500.0;
        check_decorrelated("vnoise1", &mut r, |r| {
            let x = r.range(-w, w);
            (noise1(x), vnoise1(x))
        });
        check_decorrelated("vnoise2", &mut r, |r| {
            let (x, y) = (r.range(-w, w), r.range(-w, w));
            (noise2(x, y), vnoise2(x, y))
        });
        check_decorrelated("vnoise3", &mut r, |r| {
            let p = r.v3(-w, w);
            (noise3(p), vnoise3(p))
        });
        check_decorrelated("vnoise4", &mut r, |r| {
            let (p, t) = (r.v3(-w, w), r.range(-w, w));
            (noise4(p, t), vnoise4(p, t))
        });
        check_decorrelated("vpnoise3", &mut r, |r| {
            let p = r.v3(-w, w);
            (pnoise3(p, [7.0, 8.0, 9.0]), vpnoise3(p, [7.0, 8.0, 9.0]))
        });
        check_decorrelated("vcellnoise1", &mut r, |r| {
            let x = r.range(-w, w);
            (cellnoise1(x), vcellnoise1(x))
        });
        check_decorrelated("vcellnoise2", &mut r, |r| {
            let (x, y) = (r.range(-w, w), r.range(-w, w));
            (cellnoise2(x, y), vcellnoise2(x, y))
        });
        check_decorrelated("vcellnoise4", &mut r, |r| {
            let (p, t) = (r.v3(-w, w), r.range(-w, w));
            (cellnoise4(p, t), vcellnoise4(p, t))
        });
        check_decorrelated("vrandom", &mut r, |r| {
            let seed = r.next();
            (random(seed), vrandom(seed))
        });
        // Successive calls at one point, and the same call at neighbouring points.
        let calls: Vec<f32> = (0..3_001).map(|c| random(random_seed(42, c))).collect();
        assert!(correlation(&calls[1..], &calls[..3_000]).abs() < 0.1);
        let points: Vec<f32> = (0..3_001).map(|p| random(random_seed(p, 0))).collect();
        assert!(correlation(&points[1..], &points[..3_000]).abs() < 0.1);
    }

    #[test]
    fn non_finite_and_huge_inputs_do_not_panic() {
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for b in bad {
            assert_eq!(noise1(b), 0.5);
            assert_eq!(noise2(1.5, b), 0.5);
            assert_eq!(noise3([0.3, b, 0.2]), 0.5);
            assert_eq!(noise4([0.3, 0.7, 0.2], b), 0.5);
            assert_eq!(vnoise1(b), [0.5; 3]);
            assert_eq!(vnoise2(b, 0.1), [0.5; 3]);
            assert_eq!(vnoise3([b; 3]), [0.5; 3]);
            assert_eq!(vnoise4([0.1, 0.2, b], 0.5), [0.5; 3]);
            assert_eq!(pnoise1(b, 4.0), 0.5);
            assert_eq!(pnoise2(b, 0.4, 4.0, 4.0), 0.5);
            assert_eq!(pnoise3([0.5, 0.5, b], [4.0; 3]), 0.5);
            assert_eq!(pnoise4([0.5; 3], b, [4.0; 3], 4.0), 0.5);
            assert_eq!(vpnoise1(b, 2.0), [0.5; 3]);
            assert_eq!(vpnoise2(0.2, b, 2.0, 2.0), [0.5; 3]);
            assert_eq!(vpnoise3([b, 0.1, 0.1], [2.0; 3]), [0.5; 3]);
            assert_eq!(vpnoise4([0.1; 3], b, [2.0; 3], 2.0), [0.5; 3]);
            assert_eq!(cellnoise1(b), 0.0);
            assert_eq!(cellnoise2(0.5, b), 0.0);
            assert_eq!(cellnoise3([b, 0.5, 0.5]), 0.0);
            assert_eq!(cellnoise4([0.5; 3], b), 0.0);
            assert_eq!(vcellnoise1(b), [0.0; 3]);
            assert_eq!(vcellnoise2(b, b), [0.0; 3]);
            assert_eq!(vcellnoise3([0.5, 0.5, b]), [0.0; 3]);
            assert_eq!(vcellnoise4([0.5; 3], b), [0.0; 3]);
            // Non-finite periods are valid.
            assert!(in_unit_closed(pnoise3([0.3, 1.7, -2.2], [b, 2.0, b])));
            assert!(vpnoise4([0.3, 1.7, -2.2], 9.5, [b; 3], b).iter().all(|&v| in_unit_closed(v)));
        }
        let huge = [3.0e38, -3.0e38, 1.0e20, -9.3e18, 4.0e9, -2.2e9, 16_777_217.0, f32::MIN_POSITIVE, -1.0e-40];
        for &x in &huge {
            for &y in &huge {
                let p = [x, y, x * 0.5 + 0.25];
                assert!(in_unit_closed(noise1(x)) && in_unit_closed(noise2(x, y)));
                assert!(in_unit_closed(noise3(p)) && in_unit_closed(noise4(p, y)));
                assert!(vnoise4(p, x).iter().all(|&v| in_unit_closed(v)));
                assert!(in_unit_closed(pnoise3(p, [x, y, 3.0])) && in_unit_closed(pnoise4(p, x, [y; 3], x)));
                assert!(in_unit_closed(pnoise2(x, y, 16_777_216.0, 3.0e9)));
                assert!(in_unit_open(cellnoise2(x, y)) && in_unit_open(cellnoise4(p, y)));
                assert!(vcellnoise3(p).iter().all(|&v| in_unit_open(v)));
            }
        }
        // Just below zero: the fractional part rounds to 1, giving the value at the upper corner.
        assert_eq!(noise1(-1.0e-40), 0.5);
        assert_eq!(cellnoise1(-1.0e-40), cellnoise1(-0.5));
        // Lattice coordinates wrap modulo 2^32 rather than saturate: distinct cells beyond 2^31.
        assert_ne!(cellnoise1(3.0e9), cellnoise1(3.0e9 + 256.0));
    }

    #[test]
    fn outputs_are_bit_exact() {
        // Computed once by this implementation (after the property tests passed); any change to the
        // hashing, gradients or order of operations shows here, as would a platform difference.
        let got = [
            noise1(0.37),
            noise2(-12.25, 3.8),
            noise3([1.5, -2.71, 100.03]),
            noise4([0.1, 0.2, 0.3], -7.9),
            pnoise3([-3.3, 5.6, 12.1], [4.0, 4.0, 6.0]),
            vnoise3([7.77, -0.5, 2.2])[2],
            cellnoise3([1.5, -2.71, 100.03]),
            random(123_456_789),
            vrandom(987)[1],
        ];
        let want: [u32; 9] = [
            0x3f3f_4dee, // 0.74728286
            0x3f32_93e4, // 0.69756913
            0x3ee8_d03b, // 0.45471367
            0x3f04_0aef, // 0.51579183
            0x3eba_63d2, // 0.36404282
            0x3f17_9b38, // 0.5922122
            0x3f4e_ed02, // 0.80830395
            0x3e08_f1d0, // 0.13373494
            0x3c7c_5080, // 0.015400052
        ];
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert_eq!(g.to_bits(), w, "entry {i}: {g} vs {}", f32::from_bits(w));
        }
    }

    /// The straightforward definition, in f64: the sum over corners of (product of fade weights) x
    /// (gradient . offset), with each corner hashed on its own.
    fn direct<const N: usize>(p: [f32; N], seed: u32) -> f64 {
        let mut sum = 0.0;
        for corner in 0..1usize << N {
            let mut w = 1.0;
            let mut d = [0.0f64; N];
            let mut h = 0u32;
            for k in 0..N {
                let f = f64::from(p[k].floor());
                let bit = (corner >> k) & 1;
                let c = f as i32 + bit as i32;
                h = if k == 0 { mix32(mix32(c as u32) ^ seed) } else { mix32(h.wrapping_add(c as u32)) };
                let t = f64::from(p[k]) - f;
                let u = t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
                w *= if bit == 1 { u } else { 1.0 - u };
                d[k] = t - bit as f64;
            }
            let g = gradient::<N>(h);
            sum += w * (0..N).map(|k| f64::from(g[k]) * d[k]).sum::<f64>();
        }
        0.5 + sum * f64::from(SCALE[N - 1])
    }

    #[test]
    fn noise_matches_the_direct_definition() {
        let mut r = Rng(10);
        for _ in 0..1_000 {
            let p = r.v3(-100.0, 100.0);
            let t = r.range(-100.0, 100.0);
            let close = |a: f32, b: f64| (f64::from(a) - b).abs() < 1e-5;
            assert!(close(noise1(t), direct([t], seed(KIND_GRADIENT, 1, 0))));
            assert!(close(noise2(p[0], t), direct([p[0], t], seed(KIND_GRADIENT, 2, 0))));
            assert!(close(noise3(p), direct(p, seed(KIND_GRADIENT, 3, 0))));
            assert!(close(noise4(p, t), direct([p[0], p[1], p[2], t], seed(KIND_GRADIENT, 4, 0))));
            assert!(close(vnoise3(p)[1], direct(p, seed(KIND_GRADIENT, 3, 2))));
        }
    }

    /// Prints the observed ranges, standard deviations and slopes quoted in the doc comments (run
    /// with `--ignored --nocapture`; 10^6 samples per dimension, several seconds).
    #[test]
    #[ignore]
    fn measure() {
        let mut r = Rng(99);
        /// Samples a point and a point at distance `h` from it: `(noise(p), noise(p + h d))`.
        type Sampler<'a> = &'a dyn Fn(&mut Rng, f32) -> (f32, f32);
        let fs: [(&str, Sampler); 4] = [
            ("1", &|r: &mut Rng, h: f32| {
                let x = r.range(-1000.0, 1000.0);
                (noise1(x), noise1(x + h))
            }),
            ("2", &|r: &mut Rng, h: f32| {
                let (x, y) = (r.range(-1000.0, 1000.0), r.range(-1000.0, 1000.0));
                let (dx, dy) = (r.range(-1.0, 1.0), r.range(-1.0, 1.0));
                let l = (dx * dx + dy * dy).sqrt();
                (noise2(x, y), noise2(x + h * dx / l, y + h * dy / l))
            }),
            ("3", &|r: &mut Rng, h: f32| {
                let p = r.v3(-1000.0, 1000.0);
                let d = r.v3(-1.0, 1.0);
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                (noise3(p), noise3([p[0] + h * d[0] / l, p[1] + h * d[1] / l, p[2] + h * d[2] / l]))
            }),
            ("4", &|r: &mut Rng, h: f32| {
                let p = r.v3(-1000.0, 1000.0);
                let t = r.range(-1000.0, 1000.0);
                let d = r.v3(-1.0, 1.0);
                let dt = r.range(-1.0, 1.0);
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + dt * dt).sqrt();
                (noise4(p, t), noise4([p[0] + h * d[0] / l, p[1] + h * d[1] / l, p[2] + h * d[2] / l], t + h * dt / l))
            }),
        ];
        for (name, f) in fs {
            let (mut lo, mut hi, mut sum, mut sq, mut lip) = (1.0f32, 0.0f32, 0.0f64, 0.0f64, 0.0f32);
            let n = 1_000_000;
            for _ in 0..n {
                let (a, b) = f(&mut r, 1.0 / 256.0);
                lo = lo.min(a);
                hi = hi.max(a);
                sum += a as f64;
                sq += (a as f64 - 0.5).powi(2);
                lip = lip.max((b - a).abs() * 256.0);
            }
            println!("noise{name}: [{lo}, {hi}] mean {} sd {} lip {lip}", sum / n as f64, (sq / n as f64).sqrt());
        }
    }
}

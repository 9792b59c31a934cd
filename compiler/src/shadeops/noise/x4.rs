//! Gradient noise (`noise` in 1-4 D, float and triple forms) four lanes at a time, equal bit for bit
//! to the scalar functions lane by lane: the same operations in the order the parent module
//! documents. The JIT's helpers call these once per chunk. Builds for a target with AVX2 (the
//! default `x86-64-v3`) run them in vector registers (`avx2`); others run [`portable`], loops
//! over `[_; 4]` that the compiler vectorises in part (the lattice coordinates' saturating
//! conversions and the gradient tables' loads stay lane by lane there).
//!
//! Where a lane's coordinate is below 2^23 in magnitude, `floor(x)` is the truncation `x as i32`
//! corrected by one and the lattice coordinate fits an `i32`: that is the fast path. Lanes with a
//! larger or non-finite coordinate are recomputed by the scalar code (inactive lanes may hold
//! anything).

use super::{fade, gradient, mix32, noise_n, seed, vnoise_n, KIND_GRADIENT, SCALE, V3};

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod avx2;

/// Four lanes of a float: lane `l` at `[l]`.
pub type X4 = [f32; 4];

/// Four lanes' lattice cells (see the parent's `Cell`), and whether each lane took the fast path.
struct Cells<const N: usize> {
    frac: [X4; N],
    lo: [[u32; 4]; N],
    hi: [[u32; 4]; N],
    fits: [bool; 4],
}

/// Below this magnitude an `f32` may have a fractional part, and `as i32` cannot saturate.
const EXACT: f32 = 8_388_608.0;

#[allow(clippy::needless_range_loop)] // lane loops over fixed arrays: what vectorises
fn cells<const N: usize>(p: &[X4; N]) -> Cells<N> {
    let mut c = Cells { frac: [[0.0; 4]; N], lo: [[0; 4]; N], hi: [[0; 4]; N], fits: [true; 4] };
    for k in 0..N {
        for l in 0..4 {
            let x = p[k][l];
            c.fits[l] &= x.abs() < EXACT;
            let t = x as i32;
            let i = if (t as f32) > x { t.wrapping_sub(1) } else { t };
            c.frac[k][l] = x - i as f32;
            c.lo[k][l] = i as u32;
            c.hi[k][l] = i.wrapping_add(1) as u32;
        }
    }
    c
}

#[allow(clippy::needless_range_loop)]
fn corner_hashes<const N: usize>(c: &Cells<N>, seed: u32) -> [[u32; 4]; 16] {
    let mut h = [[0u32; 4]; 16];
    for l in 0..4 {
        h[0][l] = mix32(mix32(c.lo[0][l]) ^ seed);
        h[1][l] = mix32(mix32(c.hi[0][l]) ^ seed);
    }
    let mut len = 2;
    for k in 1..N {
        for i in 0..len {
            for l in 0..4 {
                let base = h[i][l];
                h[i][l] = mix32(base.wrapping_add(c.lo[k][l]));
                h[i + len][l] = mix32(base.wrapping_add(c.hi[k][l]));
            }
        }
        len *= 2;
    }
    h
}

#[allow(clippy::needless_range_loop)]
fn gradient_noise<const N: usize>(c: &Cells<N>, seed: u32) -> X4 {
    let h = corner_hashes(c, seed);
    let mut v = [[0.0f32; 4]; 16];
    for i in 0..1 << N {
        for l in 0..4 {
            let g = gradient::<N>(h[i][l]);
            let mut dot = 0.0f32;
            for k in 0..N {
                let d = if (i >> k) & 1 == 0 { c.frac[k][l] } else { c.frac[k][l] - 1.0 };
                dot += g[k] * d;
            }
            v[i][l] = dot;
        }
    }
    for k in (0..N).rev() {
        let t = c.frac[k].map(fade);
        let half = 1 << k;
        for i in 0..half {
            for l in 0..4 {
                v[i][l] += t[l] * (v[i + half][l] - v[i][l]);
            }
        }
    }
    v[0].map(|x| (0.5 + x * SCALE[N - 1]).clamp(0.0, 1.0))
}

/// Lane `l` of a chunk of points.
fn lane<const N: usize>(p: &[X4; N], l: usize) -> [f32; N] {
    p.map(|x| x[l])
}

/// `noise_n` of each lane of `p` (`p[k][l]`: coordinate `k` of lane `l`).
pub fn noise<const N: usize>(p: [X4; N]) -> X4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        // SAFETY: compiled only where the target has AVX2.
        let (mut r, fits) = unsafe { avx2::noise(&p, seed(KIND_GRADIENT, N, 0)) };
        for (l, r) in r.iter_mut().enumerate() {
            if fits >> l & 1 == 0 {
                *r = noise_n(lane(&p, l));
            }
        }
        r
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    portable::noise(p)
}

/// `vnoise_n` of each lane of `p`: component `j` of lane `l` at `[j][l]`.
pub fn vnoise<const N: usize>(p: [X4; N]) -> [X4; 3] {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        let seeds = [1, 2, 3].map(|k| seed(KIND_GRADIENT, N, k));
        // SAFETY: compiled only where the target has AVX2.
        let (mut r, fits) = unsafe { avx2::vnoise(&p, seeds) };
        for l in (0..4).filter(|l| fits >> l & 1 == 0) {
            let v: V3 = vnoise_n(lane(&p, l));
            for j in 0..3 {
                r[j][l] = v[j];
            }
        }
        r
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    portable::vnoise(p)
}

/// The four-lane noise written as loops over lanes: what targets without AVX2 run, and the
/// baseline `benches/noise.rs` compares the vector form with.
pub mod portable {
    use super::*;

    /// `noise_n` of each lane of `p` (`p[k][l]`: coordinate `k` of lane `l`).
    #[allow(clippy::needless_range_loop)]
    pub fn noise<const N: usize>(p: [X4; N]) -> X4 {
        let c = cells(&p);
        let mut r = gradient_noise(&c, seed(KIND_GRADIENT, N, 0));
        for l in 0..4 {
            if !c.fits[l] {
                r[l] = noise_n(lane(&p, l));
            }
        }
        r
    }

    /// `vnoise_n` of each lane of `p`: component `j` of lane `l` at `[j][l]`.
    #[allow(clippy::needless_range_loop)]
    pub fn vnoise<const N: usize>(p: [X4; N]) -> [X4; 3] {
        let c = cells(&p);
        let mut r = [1, 2, 3].map(|k| gradient_noise(&c, seed(KIND_GRADIENT, N, k)));
        for l in 0..4 {
            if !c.fits[l] {
                let v: V3 = vnoise_n(lane(&p, l));
                for j in 0..3 {
                    r[j][l] = v[j];
                }
            }
        }
        r
    }
}

/// [`super::lucille_turb`] of four points, with the same operations lane by lane.
pub fn lucille_turb(p: [X4; 3]) -> X4 {
    let mut sum = [0.0f32; 4];
    let mut scale = 2.0f32;
    for _ in 0..super::LUCILLE_TURB_OCTAVES {
        let q: [X4; 3] = std::array::from_fn(|k| std::array::from_fn(|l| p[k][l] / scale));
        let n = noise::<3>(q);
        for l in 0..4 {
            sum[l] += scale * (2.0 * n[l] - 1.0);
        }
        scale *= 0.5;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inputs that exercise every path: lattice points, signed zeros, values just below integers,
    /// the fast path's limit, huge and non-finite values, and a spread of ordinary ones.
    fn samples() -> Vec<f32> {
        let mut v = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -0.5,
            1e-30,
            -1e-30,
            0.999_999_94,
            -0.999_999_94,
            EXACT,
            -EXACT,
            EXACT - 0.5,
            -(EXACT - 0.5),
            3e9,
            -3e9,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut h = 0x1234_5678u32;
        for _ in 0..400 {
            h = mix32(h);
            let scale = [1.0, 10.0, 1000.0, 1e6][(h >> 30) as usize];
            v.push(((h >> 8) as f32 / 16_777_216.0 - 0.5) * 2.0 * scale);
        }
        v
    }

    fn chunk<const N: usize>(s: &[f32], at: usize) -> [X4; N] {
        std::array::from_fn(|k| std::array::from_fn(|l| s[(at + 7 * k + 3 * l) % s.len()]))
    }

    type Noise<const N: usize> = fn([X4; N]) -> X4;
    type VNoise<const N: usize> = fn([X4; N]) -> [X4; 3];

    /// Both forms this build has (the vector one where the target has AVX2, and the portable one).
    fn agree<const N: usize>() {
        let forms: [(&str, Noise<N>, VNoise<N>); 2] =
            [("built", noise::<N>, vnoise::<N>), ("portable", portable::noise::<N>, portable::vnoise::<N>)];
        let s = samples();
        for (form, noise, vnoise) in forms {
            for at in 0..s.len() {
                let p = chunk::<N>(&s, at);
                let (f, v) = (noise(p), vnoise(p));
                for l in 0..4 {
                    let q = lane(&p, l);
                    assert_eq!(f[l].to_bits(), noise_n(q).to_bits(), "{form} noise {q:?}");
                    let w = vnoise_n(q);
                    for j in 0..3 {
                        assert_eq!(v[j][l].to_bits(), w[j].to_bits(), "{form} vnoise {q:?} component {j}");
                    }
                }
            }
        }
    }

    /// Points near lattice planes from both sides, in every octant and at every scale the fast path
    /// takes: where a floor or a fractional part could round differently.
    #[test]
    fn four_lanes_equal_the_scalar_noise_near_lattice_planes() {
        let mut h = 0x9e37_79b9u32;
        let mut value = || {
            h = mix32(h);
            let int = ((h >> 8) % 2001) as f32 - 1000.0;
            let scale = [1.0, 64.0, 4096.0, 4_194_304.0][(h & 3) as usize];
            let nudge = [0.0, f32::EPSILON, -f32::EPSILON, 1e-7, -1e-7, 0.5][((h >> 2) % 6) as usize];
            int * scale + nudge * scale.max(1.0)
        };
        for _ in 0..2000 {
            let p: [X4; 4] = std::array::from_fn(|_| std::array::from_fn(|_| value()));
            let (f3, v4) = (noise::<3>([p[0], p[1], p[2]]), vnoise::<4>(p));
            for l in 0..4 {
                let q = lane(&p, l);
                assert_eq!(f3[l].to_bits(), noise_n([q[0], q[1], q[2]]).to_bits(), "noise {q:?}");
                let w = vnoise_n(q);
                for j in 0..3 {
                    assert_eq!(v4[j][l].to_bits(), w[j].to_bits(), "vnoise {q:?} component {j}");
                }
            }
        }
    }

    #[test]
    fn four_lanes_equal_the_scalar_noise_bit_for_bit() {
        agree::<1>();
        agree::<2>();
        agree::<3>();
        agree::<4>();
    }
}

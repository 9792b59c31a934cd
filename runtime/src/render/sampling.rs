//! Hashing and low-discrepancy sequences for deterministic sampling: every random number of a
//! frame is a function of the pixel, the sample or the shading point, never of the thread or the
//! order of work.

use glam::Vec3A;

/// A cheap well-mixed hash for deterministic sampling (SplitMix64's finaliser).
pub(crate) fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

pub(crate) fn point_seed(p: Vec3A) -> u64 {
    mix(u64::from(p.x.to_bits()) ^ mix(u64::from(p.y.to_bits()) ^ mix(u64::from(p.z.to_bits()))))
}

pub(crate) fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// The radical inverse of `i` in `base` (van der Corput), for Halton points.
pub(crate) fn radical_inverse(mut i: u32, base: u32) -> f32 {
    let (mut inv, mut f) = (0.0f64, 1.0f64 / f64::from(base));
    while i > 0 {
        inv += f64::from(i % base) * f;
        i /= base;
        f /= f64::from(base);
    }
    inv as f32
}

//! `gather`: the sample rays of its cone, its options and what its output parameters read.
//!
//! `gather(category, P, dir, angle, samples, "name", value...) body [else otherwise]` runs once per
//! sample ray: `body` when the ray hits a surface, `otherwise` when it misses. The interpreter and
//! the JIT's helper both build each sample with [`sample_ray`] and fill the outputs from one
//! [`Record`], so they ask the renderer for the same rays and see the same values, bit for bit; the
//! renderer only traces and shades (`Services::gather_ray`, `HostTable::gather`).
//!
//! Conventions (RenderMan's `gather`, as far as a ray tracer without a point cloud can follow it):
//! - `samples` is rounded up and clamped to [`MAX_SAMPLES`]; `angle` (radians, the cone's half
//!   angle) is clamped to [0, pi].
//! - Directions are stratified in the cone's solid angle (`"distribution" "uniform"`, the default)
//!   or cosine-weighted about the axis (`"cosine"`, cone clamped to a hemisphere); the pattern is
//!   rotated per shading point by a hash of the point, so neighbouring points do not share rays.
//! - Options (input parameters): `"maxdist"` (rays end there; default infinity), `"bias"` (the
//!   origin moves that far along the ray), `"distribution"`; other names (`"label"`, `"subset"`,
//!   `"samplebase"`, ...) are accepted and ignored.
//! - Category `"samplepattern"` traces nothing: every sample runs `body` with the `ray:` outputs
//!   set. Every other category (`"illuminance"`, `"environment"`, ...) traces the rays and shades
//!   what they hit.
//! - Outputs: `ray:origin`, `ray:direction` (unit) and `ray:length` are set for hits and misses
//!   (length infinity on a miss); `surface:Ci`, `surface:Oi` (the hit shader's results),
//!   `surface:P` and `surface:N` (the hit point and geometric normal) only for hits. An output of
//!   another name, or whose variable has the wrong type, is left unchanged.

use super::{geom, transcendental, V3};

/// The most samples one `gather` takes per shading point.
pub const MAX_SAMPLES: f32 = 4096.0;

/// What the renderer reports for a gather ray that hit a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GatherHit {
    pub length: f32,
    pub ci: V3,
    pub oi: V3,
    pub p: V3,
    pub n: V3,
}

impl GatherHit {
    /// Rows of `HostTable::gather`'s answer after the hit flag: length, Ci, Oi, P, N.
    pub const ROWS: usize = 13;

    pub fn from_rows(r: &[f32; Self::ROWS]) -> GatherHit {
        let v = |k: usize| [r[k], r[k + 1], r[k + 2]];
        GatherHit { length: r[0], ci: v(1), oi: v(4), p: v(7), n: v(10) }
    }
}

/// A gather output parameter, by its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    RayOrigin,
    RayDirection,
    RayLength,
    SurfaceCi,
    SurfaceOi,
    SurfaceP,
    SurfaceN,
}

impl Output {
    pub const ALL: [Output; 7] = [
        Output::RayOrigin,
        Output::RayDirection,
        Output::RayLength,
        Output::SurfaceCi,
        Output::SurfaceOi,
        Output::SurfaceP,
        Output::SurfaceN,
    ];

    /// The parameter names that ask for this output (what [`Output::parse`] reads).
    pub fn names(self) -> &'static [&'static str] {
        match self {
            Output::RayOrigin => &["ray:origin"],
            Output::RayDirection => &["ray:direction"],
            Output::RayLength => &["ray:length"],
            Output::SurfaceCi => &["surface:Ci"],
            Output::SurfaceOi => &["surface:Oi"],
            Output::SurfaceP => &["surface:P"],
            Output::SurfaceN => &["surface:N", "surface:Ng"],
        }
    }

    pub fn parse(name: &str) -> Option<Output> {
        Some(match name {
            "ray:origin" => Output::RayOrigin,
            "ray:direction" => Output::RayDirection,
            "ray:length" => Output::RayLength,
            "surface:Ci" => Output::SurfaceCi,
            "surface:Oi" => Output::SurfaceOi,
            "surface:P" => Output::SurfaceP,
            "surface:N" | "surface:Ng" => Output::SurfaceN,
            _ => return None,
        })
    }

    /// Floats in the value: 1 for the length, 3 for the rest.
    pub fn components(self) -> usize {
        if self == Output::RayLength {
            1
        } else {
            3
        }
    }

    /// Whether a variable of type `ty` can receive it (a float, or a point, vector, normal or
    /// colour; not an array).
    pub fn fits(self, ty: crate::ir::Type) -> bool {
        !ty.is_array()
            && match self.components() {
                1 => ty.base == crate::ir::BaseType::Float,
                _ => ty.base.is_triple(),
            }
    }

    /// Whether a miss sets it (the `ray:` outputs) or only a hit.
    pub fn on_miss(self) -> bool {
        matches!(self, Output::RayOrigin | Output::RayDirection | Output::RayLength)
    }

    /// Its first row in a [`Record`].
    pub fn row(self) -> usize {
        match self {
            Output::RayOrigin => 1,
            Output::RayDirection => 4,
            Output::RayLength => 7,
            Output::SurfaceCi => 8,
            Output::SurfaceOi => 11,
            Output::SurfaceP => 14,
            Output::SurfaceN => 17,
        }
    }
}

/// One sample, as rows: hit ([`HIT`], [`MISS`] or [`PATTERN`]), origin, direction, length, Ci,
/// Oi, P, N.
pub type Record = [f32; RECORD];
/// Floats in a [`Record`].
pub const RECORD: usize = 20;
/// Row 0 of a [`Record`]: the ray hit a surface (the body runs, every output is set).
pub const HIT: f32 = 1.0;
/// Row 0 of a [`Record`]: the ray missed (`otherwise` runs, only the `ray:` outputs are set).
pub const MISS: f32 = 0.0;
/// Row 0 of a [`Record`]: `"samplepattern"`, nothing traced (the body runs, only the `ray:`
/// outputs are set).
pub const PATTERN: f32 = 2.0;

/// The input parameters of one gather.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub maxdist: f32,
    pub bias: f32,
    pub cosine: bool,
}

impl Default for Options {
    fn default() -> Options {
        Options { maxdist: f32::INFINITY, bias: 0.0, cosine: false }
    }
}

impl Options {
    /// The option a float parameter of this name sets (`None`: ignored).
    pub fn float_slot(name: &str) -> Option<usize> {
        match name {
            "maxdist" => Some(0),
            "bias" => Some(1),
            _ => None,
        }
    }

    pub fn set_float(&mut self, slot: usize, x: f32) {
        match slot {
            0 => self.maxdist = if x > 0.0 { x } else { f32::INFINITY },
            _ => self.bias = x.max(0.0),
        }
    }

    /// `"distribution"`: whether the value asks for cosine weighting.
    pub fn is_cosine(distribution: &str) -> bool {
        distribution == "cosine"
    }
}

/// Whether a category traces rays (everything but `"samplepattern"`).
pub fn traces(category: &str) -> bool {
    category != "samplepattern"
}

/// How many samples `samples` asks for.
pub fn sample_count(samples: f32) -> u32 {
    if samples.is_nan() {
        return 0;
    }
    samples.clamp(0.0, MAX_SAMPLES).ceil() as u32
}

fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit(h: u64) -> f32 {
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

fn fract(x: f32) -> f32 {
    x - x.floor()
}

/// Sample `k` of `n` of the cone around `axis` within `angle` seen from `from`: the ray's origin
/// and unit direction (zero when `axis` is zero or not finite: the sample misses).
pub fn sample_ray(from: V3, axis: V3, angle: f32, k: u32, n: u32, options: &Options) -> (V3, V3) {
    let a = geom::normalize(axis);
    if !a.iter().all(|x| x.is_finite()) || a == [0.0; 3] {
        return (from, [0.0; 3]);
    }
    let seed = mix64(
        u64::from(from[0].to_bits()) ^ (u64::from(from[1].to_bits()) << 21) ^ (u64::from(from[2].to_bits()) << 42),
    );
    let (r1, r2) = (unit(seed), unit(mix64(seed)));
    let u1 = fract((k as f32 + 0.5) / n.max(1) as f32 + r1);
    let u2 = fract(k as f32 * 0.618_034 + r2);
    let angle = if angle.is_nan() { 0.0 } else { angle.clamp(0.0, std::f32::consts::PI) };
    let (sin_t, cos_t) = if options.cosine {
        let s = transcendental::sin(angle.min(std::f32::consts::FRAC_PI_2));
        let st = u1.sqrt() * s;
        (st, (1.0 - st * st).max(0.0).sqrt())
    } else {
        let ct = 1.0 - u1 * (1.0 - transcendental::cos(angle));
        ((1.0 - ct * ct).max(0.0).sqrt(), ct)
    };
    let phi = std::f32::consts::TAU * u2;
    let (t1, t2) = basis(a);
    let (cp, sp) = (transcendental::cos(phi) * sin_t, transcendental::sin(phi) * sin_t);
    let dir = geom::normalize([
        t1[0] * cp + t2[0] * sp + a[0] * cos_t,
        t1[1] * cp + t2[1] * sp + a[1] * cos_t,
        t1[2] * cp + t2[2] * sp + a[2] * cos_t,
    ]);
    let origin = [from[0] + dir[0] * options.bias, from[1] + dir[1] * options.bias, from[2] + dir[2] * options.bias];
    (origin, dir)
}

/// Two unit vectors perpendicular to the unit vector `a` and to each other.
fn basis(a: V3) -> (V3, V3) {
    let helper = if a[0].abs() > 0.9 { [0.0, 1.0, 0.0] } else { [1.0, 0.0, 0.0] };
    let t1 = geom::normalize(geom::cross(a, helper));
    (t1, geom::cross(a, t1))
}

/// The record of a sample: its ray, and what it hit (`traced`: false for `"samplepattern"`).
pub fn record(origin: V3, dir: V3, hit: Option<&GatherHit>, traced: bool) -> Record {
    let mut r = [0.0; RECORD];
    if !traced {
        r[0] = PATTERN;
    }
    r[1..4].copy_from_slice(&origin);
    r[4..7].copy_from_slice(&dir);
    r[7] = f32::INFINITY;
    if let Some(h) = hit {
        r[0] = HIT;
        r[7] = h.length;
        r[8..11].copy_from_slice(&h.ci);
        r[11..14].copy_from_slice(&h.oi);
        r[14..17].copy_from_slice(&h.p);
        r[17..20].copy_from_slice(&h.n);
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn angle(a: V3, b: V3) -> f32 {
        geom::dot(geom::normalize(a), geom::normalize(b)).clamp(-1.0, 1.0).acos()
    }

    #[test]
    fn samples_stay_in_their_cone_and_are_unit_length() {
        for (i, axis) in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [-0.3, 2.0, 0.5], [0.0, -1.0, 0.0]].into_iter().enumerate()
        {
            for cone in [0.0f32, 0.1, 0.7, 1.5, 3.0] {
                for cosine in [false, true] {
                    let o = Options { cosine, ..Options::default() };
                    for k in 0..64 {
                        let (origin, d) = sample_ray([i as f32, 0.5, -2.0], axis, cone, k, 64, &o);
                        assert_eq!(origin, [i as f32, 0.5, -2.0]);
                        assert!((geom::length(d) - 1.0).abs() < 1e-5);
                        let limit = if cosine { cone.min(std::f32::consts::FRAC_PI_2) } else { cone };
                        assert!(angle(d, axis) <= limit + 2e-3, "{:?} cone {cone}: {}", axis, angle(d, axis));
                    }
                }
            }
        }
    }

    #[test]
    fn uniform_samples_cover_the_cone_evenly() {
        // Over a hemisphere, uniform directions have mean cos 1/2; cosine-weighted ones 2/3.
        let n = 4096;
        for (cosine, expect) in [(false, 0.5), (true, 2.0 / 3.0)] {
            let o = Options { cosine, ..Options::default() };
            let mean: f32 = (0..n)
                .map(|k| sample_ray([0.3, 0.1, 0.2], [0.0, 0.0, 1.0], std::f32::consts::FRAC_PI_2, k, n, &o).1[2])
                .sum::<f32>()
                / n as f32;
            assert!((mean - expect).abs() < 0.01, "cosine {cosine}: mean {mean}");
        }
    }

    #[test]
    fn the_pattern_depends_on_the_point_and_bias_moves_the_origin() {
        let o = Options::default();
        let a = sample_ray([0.0; 3], [0.0, 1.0, 0.0], 1.0, 3, 8, &o);
        let b = sample_ray([0.0, 0.0, 1e-3], [0.0, 1.0, 0.0], 1.0, 3, 8, &o);
        assert_ne!(a.1, b.1);
        assert_eq!(a, sample_ray([0.0; 3], [0.0, 1.0, 0.0], 1.0, 3, 8, &o));
        let biased = sample_ray([0.0; 3], [0.0, 1.0, 0.0], 0.0, 0, 1, &Options { bias: 0.5, ..o });
        assert_eq!(biased.0, [0.0, 0.5, 0.0]);
        assert_eq!(sample_ray([0.0; 3], [0.0; 3], 1.0, 0, 1, &o).1, [0.0; 3]);
        assert_eq!(sample_ray([0.0; 3], [f32::NAN, 0.0, 1.0], 1.0, 0, 1, &o).1, [0.0; 3]);
    }

    #[test]
    fn sample_counts_round_up_and_clamp() {
        assert_eq!(sample_count(0.0), 0);
        assert_eq!(sample_count(-3.0), 0);
        assert_eq!(sample_count(2.1), 3);
        assert_eq!(sample_count(f32::NAN), 0);
        assert_eq!(sample_count(f32::INFINITY), MAX_SAMPLES as u32);
    }
}

//! Where a local light's paths leave it: in proportion to what its shader emits each way, so that
//! a spotlight's paths go into its cone rather than over the whole sphere, most of them to be
//! dropped for carrying nothing.
//!
//! The sphere around the light is cut into `ZONES x SECTORS` cells of equal solid angle (zones of
//! equal height in `z`, sectors of equal angle about it). The light's shader is run toward each
//! cell's centre, and a cell's weight is what it emits that way. A path picks a
//! cell with probability `(1 - UNIFORM_SHARE)` times its share of the weights plus `UNIFORM_SHARE`
//! over the number of cells, then a direction uniformly in it, and carries the solid angle it
//! stands for (one over its density). The uniform share keeps every direction's density above
//! zero, so the estimate is unbiased whatever the probes missed (a beam that falls between
//! cells' centres); the power a path carries is still the shader's answer where it lands.
//!
//! Invariant: the table depends only on the light and the scene's size (the probes are fixed), so
//! every frame, thread and rank draws the same paths for the same seed.

use glam::Vec3A;
use std::f32::consts::{PI, TAU};

/// Zones of equal height in `z`.
const ZONES: usize = 16;
/// Sectors of equal angle about `z`.
const SECTORS: usize = 32;
/// Cells of the sphere.
pub(super) const CELLS: usize = ZONES * SECTORS;
/// The share of the paths spread over the whole sphere whatever the probes found.
const UNIFORM_SHARE: f32 = 0.1;

/// The direction at `(a, b)` in `[0, 1]^2` of cell `c` (`a` down its zone, `b` along its sector).
fn direction_in(c: usize, a: f32, b: f32) -> Vec3A {
    let (zone, sector) = (c / SECTORS, c % SECTORS);
    let z = 1.0 - 2.0 * (zone as f32 + a) / ZONES as f32;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * (sector as f32 + b) / SECTORS as f32;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// The direction each cell's weight is measured toward, its centre's, cell after cell. Each is a
/// lane of a run of the light's shader, every frame: one a cell keeps that cheap next to the
/// paths.
pub(super) fn probe_directions() -> Vec<Vec3A> {
    (0..CELLS).map(|c| direction_in(c, 0.5, 0.5)).collect()
}

/// A light's emission by cell, as paths draw it.
#[derive(Clone, Debug)]
pub(super) struct Emission {
    /// Each cell's probability.
    probability: Vec<f32>,
    /// The probabilities' running sums, `CELLS + 1` of them from 0.
    cumulative: Vec<f32>,
}

impl Emission {
    /// The table of the intensities measured toward [`probe_directions`], in their order; `None`
    /// where nothing was measured (paths then go everywhere).
    pub(super) fn of_probes(intensity: &[f32]) -> Option<Emission> {
        if intensity.len() != CELLS {
            return None;
        }
        let weights: Vec<f32> = intensity.iter().map(|&v| if v.is_finite() { v.max(0.0) } else { 0.0 }).collect();
        let total: f32 = weights.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        let probability: Vec<f32> =
            weights.iter().map(|w| (1.0 - UNIFORM_SHARE) * w / total + UNIFORM_SHARE / CELLS as f32).collect();
        let mut cumulative = Vec::with_capacity(CELLS + 1);
        let mut sum = 0.0f32;
        cumulative.push(0.0);
        for p in &probability {
            sum += p;
            cumulative.push(sum);
        }
        Some(Emission { probability, cumulative })
    }

    /// The direction for the stratified pair `(u1, u2)` in `[0, 1)`, and the solid angle it stands
    /// for (one over its density).
    pub(super) fn sample(&self, u1: f32, u2: f32) -> (Vec3A, f32) {
        let total = self.cumulative[CELLS];
        let at = u1 * total;
        // The last cell whose running sum starts at or below `at`.
        let c = (self.cumulative.partition_point(|&s| s <= at).saturating_sub(1)).min(CELLS - 1);
        let p = self.probability[c];
        let a = ((at - self.cumulative[c]) / p).clamp(0.0, 1.0);
        let dir = direction_in(c, a, u2);
        (dir, 4.0 * PI / CELLS as f32 * total / p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::radical_inverse;

    /// A spotlight's intensity: 1 within 0.3 radians of `-y`, falling to 0 at 0.35.
    fn spot(d: Vec3A) -> f32 {
        let angle = (-d.y).clamp(-1.0, 1.0).acos();
        ((0.35 - angle) / 0.05).clamp(0.0, 1.0)
    }

    #[test]
    fn drawn_directions_integrate_what_the_light_emits() {
        let probes: Vec<f32> = probe_directions().into_iter().map(spot).collect();
        let table = Emission::of_probes(&probes).expect("a table");
        let count = 200_000u32;
        let samples: Vec<(Vec3A, f32)> =
            (0..count).map(|i| table.sample((i as f32 + 0.5) / count as f32, radical_inverse(i, 2))).collect();
        // What the light emits over the sphere: the integral of `spot` (by its cone's rings).
        let rings = 100_000;
        let exact: f32 = (0..rings)
            .map(|k| {
                let angle = 0.35 * (k as f32 + 0.5) / rings as f32;
                let d = Vec3A::new(angle.sin(), -angle.cos(), 0.0);
                spot(d) * TAU * angle.sin() * (0.35 / rings as f32)
            })
            .sum();
        let estimate = samples.iter().map(|&(d, w)| spot(d) * w).sum::<f32>() / count as f32;
        assert!((estimate / exact - 1.0).abs() < 0.01, "{estimate}, exactly {exact}");
        // A region the light does not reach is still drawn, with its solid angle.
        let up = samples.iter().filter(|(d, _)| d.y > 0.5).map(|(_, w)| w).sum::<f32>() / count as f32;
        assert!((up / (TAU * 0.5) - 1.0).abs() < 0.01, "{up}");
        // Most paths go into the cone (0.03 of the sphere: paths over the whole sphere would put
        // 3% there); the rest into the cells its edge crosses, and a tenth everywhere.
        let inside = samples.iter().filter(|(d, _)| spot(*d) > 0.0).count() as f32 / count as f32;
        assert!(inside > 0.6, "{inside} of the paths in the cone");
    }

    #[test]
    fn nothing_measured_is_no_table() {
        assert!(Emission::of_probes(&[0.0; CELLS]).is_none());
        assert!(Emission::of_probes(&[1.0; 3]).is_none(), "not one value a probe");
        assert!(Emission::of_probes(&[f32::NAN; CELLS]).is_none());
    }
}

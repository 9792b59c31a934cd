//! Aiming caustic paths: a caustic photon is left only by a path whose first surface is chrome or
//! glass, so paths leave a light only toward the boxes of the instances that have such surfaces
//! (Jensen's projection maps, with a bounding cone or disc per box instead of a map of cells).
//!
//! A light's paths go in the union of its targets' cones (a local light) or discs across its
//! direction (a distant light). A path picks a target with probability proportional to its cone's
//! solid angle (disc's area) and a direction uniformly in that cone (point in that disc); where
//! targets overlap, a direction could have come from each of the targets that hold it, so its
//! density is the number of those over the targets' total, and the path stands for the total over
//! that number (the balance heuristic over the targets). No direction a specular surface can be
//! reached by first is left out, so the map's estimate is unbiased as before: the power each path
//! carries shrinks by as much as the paths are concentrated.
//!
//! Where aiming cannot help (a light inside a target's box, a box that spans more than a
//! hemisphere seen from the light, targets that together cover the sphere), the light's paths
//! go everywhere as before.

use super::hemisphere::orthonormal;
use glam::Vec3A;
use std::f32::consts::{PI, TAU};

/// World-space boxes (lower and upper corners) paths are aimed at.
pub(super) type Targets = [(Vec3A, Vec3A)];

/// How a box's cone or disc is widened past its corners: directions and points computed from
/// rounded corners must not fall just outside.
const WIDEN: f32 = 1e-5;

/// The eight corners of a box.
pub(super) fn corners((lo, hi): (Vec3A, Vec3A)) -> impl Iterator<Item = Vec3A> {
    (0..8).map(move |k| Vec3A::new([lo.x, hi.x][k & 1], [lo.y, hi.y][k >> 1 & 1], [lo.z, hi.z][k >> 2 & 1]))
}

/// The target whose share of `total` holds `u * total` (targets weighted by `weights`), and `u`
/// stretched over that share, so that stratified `u` stay stratified within each target.
fn pick(weights: impl Iterator<Item = f32>, total: f32, u: f32) -> (usize, f32) {
    let at = u * total;
    let mut start = 0.0;
    let mut last = (0, 0.0, 0.0);
    for (k, w) in weights.enumerate() {
        if at < start + w {
            return (k, ((at - start) / w).clamp(0.0, 1.0 - f32::EPSILON));
        }
        last = (k, start, w);
        start += w;
    }
    // `u` at the very end (rounding): the last target.
    let (k, start, w) = last;
    (k, ((at - start) / w.max(f32::MIN_POSITIVE)).clamp(0.0, 1.0 - f32::EPSILON))
}

/// A cone of directions: those within the angle whose cosine is `cos_max` of `axis`.
#[derive(Clone, Copy, Debug)]
struct Cone {
    axis: Vec3A,
    cos_max: f32,
    solid_angle: f32,
}

impl Cone {
    /// The cone from `from` that holds the box (its corners, and so, being narrower than a
    /// hemisphere, the box); `None` where `from` is inside the box or the cone would be wider
    /// than a hemisphere.
    fn around(from: Vec3A, (lo, hi): (Vec3A, Vec3A)) -> Option<Cone> {
        if from.cmpge(lo).all() && from.cmple(hi).all() {
            return None;
        }
        let axis = ((lo + hi) * 0.5 - from).try_normalize()?;
        let nearest = corners((lo, hi)).map(|c| (c - from).normalize_or_zero().dot(axis)).fold(1.0f32, f32::min);
        let cos_max = nearest - WIDEN;
        (cos_max > 0.0).then_some(Cone { axis, cos_max, solid_angle: TAU * (1.0 - cos_max) })
    }

    fn holds(&self, dir: Vec3A) -> bool {
        dir.dot(self.axis) >= self.cos_max
    }
}

/// The directions from a point toward the targets (see the module's notes).
#[derive(Clone, Debug)]
pub(super) struct Cones {
    cones: Vec<Cone>,
    total: f32,
}

impl Cones {
    /// The cones from `from` toward `targets`; `None` where aiming cannot help (then paths go
    /// everywhere).
    pub(super) fn toward(from: Vec3A, targets: &Targets) -> Option<Cones> {
        let cones = targets.iter().map(|&t| Cone::around(from, t)).collect::<Option<Vec<Cone>>>()?;
        let total = cones.iter().map(|c| c.solid_angle).sum::<f32>();
        (total < 4.0 * PI && total.is_finite()).then_some(Cones { cones, total })
    }

    /// The direction for the stratified pair `(u1, u2)` in `[0, 1)`, and the solid angle it stands
    /// for (one over its density).
    pub(super) fn sample(&self, u1: f32, u2: f32) -> (Vec3A, f32) {
        let (j, u) = pick(self.cones.iter().map(|c| c.solid_angle), self.total, u1);
        let cone = &self.cones[j];
        let cos = 1.0 - u * (1.0 - cone.cos_max);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let (t1, t2) = orthonormal(cone.axis);
        let phi = TAU * u2;
        let dir = (t1 * (sin * phi.cos()) + t2 * (sin * phi.sin()) + cone.axis * cos).normalize_or_zero();
        // The cone it came from holds it by construction (whatever rounding says).
        let holding = 1 + self.cones.iter().enumerate().filter(|&(k, c)| k != j && c.holds(dir)).count();
        (dir, self.total / holding as f32)
    }
}

/// A disc of the plane across a distant light's direction.
#[derive(Clone, Copy, Debug)]
struct Disc {
    centre: (f32, f32),
    radius: f32,
    area: f32,
}

impl Disc {
    fn holds(&self, (x, y): (f32, f32)) -> bool {
        let (dx, dy) = (x - self.centre.0, y - self.centre.1);
        dx * dx + dy * dy <= self.radius * self.radius
    }
}

/// The points of the plane across a distant light's direction whose paths reach the targets, in
/// the plane's coordinates along `t1` and `t2` from `centre` (see the module's notes).
#[derive(Clone, Debug)]
pub(super) struct Discs {
    discs: Vec<Disc>,
    total: f32,
}

impl Discs {
    /// The discs of the plane through `centre` spanned by `t1` and `t2` (across the light's
    /// direction) that hold the targets' shadows; `None` where together they are no smaller than
    /// the disc of `radius` paths otherwise start from.
    pub(super) fn across(centre: Vec3A, (t1, t2): (Vec3A, Vec3A), radius: f32, targets: &Targets) -> Option<Discs> {
        let in_plane = |p: Vec3A| ((p - centre).dot(t1), (p - centre).dot(t2));
        let discs: Vec<Disc> = targets
            .iter()
            .map(|&(lo, hi)| {
                let c = in_plane((lo + hi) * 0.5);
                let reach = corners((lo, hi))
                    .map(|p| {
                        let (x, y) = in_plane(p);
                        ((x - c.0).powi(2) + (y - c.1).powi(2)).sqrt()
                    })
                    .fold(0.0f32, f32::max);
                let radius = reach * (1.0 + WIDEN) + WIDEN * (c.0.abs() + c.1.abs());
                Disc { centre: c, radius, area: PI * radius * radius }
            })
            .collect();
        let total = discs.iter().map(|d| d.area).sum::<f32>();
        (total < PI * radius * radius && total.is_finite()).then_some(Discs { discs, total })
    }

    /// The point (in the plane's coordinates) for the stratified pair `(u1, u2)` in `[0, 1)`, and
    /// the area it stands for (one over its density).
    pub(super) fn sample(&self, u1: f32, u2: f32) -> ((f32, f32), f32) {
        let (j, u) = pick(self.discs.iter().map(|d| d.area), self.total, u1);
        let disc = &self.discs[j];
        let (r, phi) = (disc.radius * u.sqrt(), TAU * u2);
        let at = (disc.centre.0 + r * phi.cos(), disc.centre.1 + r * phi.sin());
        let holding = 1 + self.discs.iter().enumerate().filter(|&(k, d)| k != j && d.holds(at)).count();
        (at, self.total / holding as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::radical_inverse;

    /// Hammersley points, as light paths take them.
    fn points(count: u32) -> impl Iterator<Item = (f32, f32)> {
        (0..count).map(move |i| ((i as f32 + 0.5) / count as f32, radical_inverse(i, 2)))
    }

    #[test]
    fn aimed_directions_integrate_over_the_sphere() {
        // Two overlapping boxes and one apart, seen from the origin: the weights of the directions
        // that fall in a region add up to its solid angle, whichever boxes' cones overlap there.
        let targets = [
            (Vec3A::new(2.0, -0.5, -0.5), Vec3A::new(3.0, 0.5, 0.5)),
            (Vec3A::new(2.5, 0.0, -0.3), Vec3A::new(4.0, 1.5, 0.6)),
            (Vec3A::new(-1.0, -4.0, -1.0), Vec3A::new(1.0, -3.0, 1.0)),
        ];
        let cones = Cones::toward(Vec3A::ZERO, &targets).expect("cones");
        let count = 400_000;
        let samples: Vec<(Vec3A, f32)> = points(count).map(|(u1, u2)| cones.sample(u1, u2)).collect();
        // Regions: each box's own cone, and a small cone in the overlap of the first two.
        let mut regions: Vec<Cone> = targets.iter().map(|&t| Cone::around(Vec3A::ZERO, t).expect("a cone")).collect();
        let both = (regions[0].axis + regions[1].axis).normalize();
        let cos = regions[0].axis.dot(both).min(regions[1].axis.dot(both));
        assert!(regions[0].holds(both) && regions[1].holds(both) && cos > regions[0].cos_max);
        let small = 0.999f32;
        regions.push(Cone { axis: both, cos_max: small, solid_angle: TAU * (1.0 - small) });
        for (k, region) in regions.iter().enumerate() {
            let estimate = samples.iter().filter(|(d, _)| region.holds(*d)).map(|(_, w)| w).sum::<f32>() / count as f32;
            let error = (estimate - region.solid_angle).abs() / region.solid_angle;
            assert!(error < 0.01, "region {k}: {estimate} for a solid angle of {}", region.solid_angle);
        }
        // Every direction goes toward a target, and the targets take a small part of the sphere.
        assert!(samples.iter().all(|(d, _)| regions[..3].iter().any(|c| c.holds(*d))));
        assert!(cones.total < 0.5 * 4.0 * PI, "{}", cones.total);
    }

    #[test]
    fn aimed_points_integrate_over_the_plane() {
        let (t1, t2) = (Vec3A::X, Vec3A::Z);
        let targets = [
            (Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 1.0, 1.0)),
            (Vec3A::new(0.5, -2.0, 0.5), Vec3A::new(2.0, 0.0, 1.5)),
        ];
        let discs = Discs::across(Vec3A::ZERO, (t1, t2), 10.0, &targets).expect("discs");
        let count = 400_000;
        let samples: Vec<((f32, f32), f32)> = points(count).map(|(u1, u2)| discs.sample(u1, u2)).collect();
        let square = |(x, y): (f32, f32)| (0.6..0.9).contains(&x) && (0.6..0.9).contains(&y);
        let estimate = samples.iter().filter(|(p, _)| square(*p)).map(|(_, w)| w).sum::<f32>() / count as f32;
        assert!((estimate - 0.09).abs() < 0.09 * 0.01, "{estimate} for an area of 0.09");
        for disc in &discs.discs {
            let estimate = samples.iter().filter(|(p, _)| disc.holds(*p)).map(|(_, w)| w).sum::<f32>() / count as f32;
            assert!((estimate - disc.area).abs() < disc.area * 0.01, "{estimate} for a disc of {}", disc.area);
        }
    }

    #[test]
    fn aiming_gives_way_where_it_cannot_help() {
        let unit_box = (Vec3A::splat(-1.0), Vec3A::splat(1.0));
        // From inside a target, or beside a box wider than a hemisphere sees, paths go everywhere.
        assert!(Cones::toward(Vec3A::ZERO, &[unit_box]).is_none());
        let wide = (Vec3A::new(-100.0, 1.0, -100.0), Vec3A::new(100.0, 1.0, 100.0));
        assert!(Cone::around(Vec3A::ZERO, wide).is_some(), "a flat box above: a cone under a hemisphere");
        let beside = (Vec3A::new(0.0, -100.0, -100.0), Vec3A::new(1.0, 100.0, 100.0));
        assert!(Cones::toward(Vec3A::new(-0.01, 0.0, 0.5), &[beside]).is_none());
        // No targets: nothing to aim at.
        assert!(Cones::toward(Vec3A::new(5.0, 0.0, 0.0), &[]).is_some_and(|c| c.cones.is_empty()));
        let everywhere = Discs::across(Vec3A::ZERO, (Vec3A::X, Vec3A::Z), 1.0, &[unit_box]);
        assert!(everywhere.is_none(), "a target's shadow as large as the light's disc");
    }
}

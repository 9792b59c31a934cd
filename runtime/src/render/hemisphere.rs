//! The hemisphere rays of `occlusion` and of `indirectdiffuse` sampling the hemisphere, made the
//! same way whether a chunk traces them at once or a batch's are traced together
//! (`trace_ahead.rs`).

use super::sampling::{mix, point_seed, unit};
use super::work::launch_epsilon;
use crate::ray::Ray;
use glam::Vec3A;

/// Appends the `count` cosine-weighted rays over the hemisphere around the unit normal `n` at `p`
/// that `occlusion` and `indirectdiffuse` sample, at `time` (their directions a hash of `p`).
pub(super) fn hemisphere_rays(p: Vec3A, n: Vec3A, count: u32, time: f32, rays: &mut Vec<Ray>) {
    let (t1, t2) = orthonormal(n);
    let seed = point_seed(p);
    for i in 0..count {
        let h = mix(seed ^ u64::from(i).wrapping_mul(0x9E37_79B9));
        let (r1, r2) = (unit(h), unit(mix(h)));
        let phi = std::f32::consts::TAU * r1;
        let (s, cz) = (r2.sqrt(), (1.0 - r2).sqrt());
        let dir = t1 * (s * phi.cos()) + t2 * (s * phi.sin()) + n * cz;
        rays.push(Ray::segment(p, dir, launch_epsilon(p), f32::INFINITY).at_time(time));
    }
}

/// Two unit vectors that make an orthonormal frame with the unit vector `n`.
pub(super) fn orthonormal(n: Vec3A) -> (Vec3A, Vec3A) {
    let a = if n.x.abs() > 0.9 { Vec3A::Y } else { Vec3A::X };
    let t1 = n.cross(a).normalize();
    (t1, n.cross(t1))
}

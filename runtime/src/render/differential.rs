//! Ray differentials (Igehy 1999): how a ray's origin and direction change from one pixel to the
//! next, carried to the hit to give the screen-space derivatives of `P`, the surface parameters and
//! every interpolated value. They size texture filters and feed `Du`, `Dv`, `area`,
//! `calculatenormal` and `filterstep`.
//!
//! Primary rays get exact differentials from the camera. Secondary rays (`trace`, occlusion) get a
//! cone: a footprint as wide as the primary ray's at the shading point, spreading like a camera ray
//! (curved mirrors magnify more than that; the cone does not model it).

use crate::ray::PACKET_SIZE;
use glam::Vec3A;

/// The derivatives of a ray's origin and unit direction with respect to the image's x and y.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayDifferential {
    pub dodx: Vec3A,
    pub dody: Vec3A,
    pub dddx: Vec3A,
    pub dddy: Vec3A,
}

impl RayDifferential {
    /// An isotropic cone around unit `dir`: `width` across at the origin, growing by `spread` per
    /// unit of distance.
    pub fn cone(dir: Vec3A, width: f32, spread: f32) -> RayDifferential {
        let a = if dir.x.abs() > 0.9 { Vec3A::Y } else { Vec3A::X };
        let t1 = dir.cross(a).normalize_or_zero();
        let t2 = dir.cross(t1);
        RayDifferential { dodx: t1 * width, dody: t2 * width, dddx: t1 * spread, dddy: t2 * spread }
    }

    /// For a camera ray: `d` the unnormalised direction, `dd_dx`/`dd_dy` its change per pixel.
    pub fn from_camera(d: Vec3A, dd_dx: Vec3A, dd_dy: Vec3A) -> RayDifferential {
        let len = d.length();
        if len == 0.0 {
            return RayDifferential::default();
        }
        let n = d / len;
        // The derivative of d / |d|.
        let along = |v: Vec3A| (v - n * n.dot(v)) / len;
        RayDifferential { dodx: Vec3A::ZERO, dody: Vec3A::ZERO, dddx: along(dd_dx), dddy: along(dd_dy) }
    }

    /// dP/dx and dP/dy where the ray with unit direction `dir` meets the plane through its hit at
    /// distance `t` with normal `n` (the offsets move along the ray onto the tangent plane).
    pub fn at_hit(&self, dir: Vec3A, t: f32, n: Vec3A) -> (Vec3A, Vec3A) {
        let px = self.dodx + self.dddx * t;
        let py = self.dody + self.dddy * t;
        let dn = dir.dot(n);
        if dn.abs() < 1e-6 {
            return (px, py);
        }
        (px - dir * (px.dot(n) / dn), py - dir * (py.dot(n) / dn))
    }
}

/// Three rows of a packet: component `k` of lane `l` at `[k][l]`.
pub type LaneRows3 = [[f32; PACKET_SIZE]; 3];

/// The differentials of a packet's rays by rows (structure of arrays), as the camera makes them:
/// four lanes at a time, with no per-lane records to transpose into (writing those cost as much as
/// a simple camera shader). Shading reads a lane at a time with [`DifferentialRows::lane`].
#[derive(Clone, Debug, PartialEq)]
pub struct DifferentialRows {
    pub dodx: LaneRows3,
    pub dody: LaneRows3,
    pub dddx: LaneRows3,
    pub dddy: LaneRows3,
}

impl Default for DifferentialRows {
    fn default() -> Self {
        let zero = [[0.0; PACKET_SIZE]; 3];
        DifferentialRows { dodx: zero, dody: zero, dddx: zero, dddy: zero }
    }
}

impl DifferentialRows {
    /// Lane `l`'s differential.
    pub fn lane(&self, l: usize) -> RayDifferential {
        let at = |rows: &LaneRows3| Vec3A::new(rows[0][l], rows[1][l], rows[2][l]);
        RayDifferential { dodx: at(&self.dodx), dody: at(&self.dody), dddx: at(&self.dddx), dddy: at(&self.dddy) }
    }

    /// Sets lane `l`'s differential.
    pub fn set_lane(&mut self, l: usize, d: RayDifferential) {
        for (rows, v) in
            [(&mut self.dodx, d.dodx), (&mut self.dody, d.dody), (&mut self.dddx, d.dddx), (&mut self.dddy, d.dddy)]
        {
            for (row, x) in rows.iter_mut().zip(v.to_array()) {
                row[l] = x;
            }
        }
    }

    /// Zeroes the change of the origins (a camera whose rays share one origin).
    pub fn fixed_origin(&mut self) {
        self.dodx = [[0.0; PACKET_SIZE]; 3];
        self.dody = [[0.0; PACKET_SIZE]; 3];
    }
}

/// The change of the barycentric coordinates `(b1, b2)` of a triangle with edges `e1`, `e2` (from
/// its first corner) for a move `dp` in its plane (least squares, so moves off the plane are
/// projected).
pub fn barycentric_change(e1: Vec3A, e2: Vec3A, dp: Vec3A) -> (f32, f32) {
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = a * c - b * b;
    if det.abs() < 1e-30 {
        return (0.0, 0.0);
    }
    let (r1, r2) = (e1.dot(dp), e2.dot(dp));
    ((c * r1 - b * r2) / det, (a * r2 - b * r1) / det)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_ray_on_a_facing_plane_moves_by_the_pixel_step() {
        // A ray straight down -z with a pixel step of 0.01 in x hits z = -2 at distance 2.
        let d = Vec3A::new(0.0, 0.0, -1.0);
        let rd = RayDifferential::from_camera(d, Vec3A::new(0.01, 0.0, 0.0), Vec3A::new(0.0, -0.01, 0.0));
        let (px, py) = rd.at_hit(d, 2.0, Vec3A::Z);
        assert!((px - Vec3A::new(0.02, 0.0, 0.0)).length() < 1e-6, "{px}");
        assert!((py - Vec3A::new(0.0, -0.02, 0.0)).length() < 1e-6, "{py}");
    }

    #[test]
    fn a_slanted_plane_stretches_the_footprint() {
        let d = Vec3A::new(0.0, 0.0, -1.0);
        let rd = RayDifferential::from_camera(d, Vec3A::new(0.01, 0.0, 0.0), Vec3A::ZERO);
        // A plane tilted 60 degrees about y: the x step grows by 1 / cos(60) = 2.
        let n = Vec3A::new(60f32.to_radians().sin(), 0.0, 60f32.to_radians().cos());
        let (px, _) = rd.at_hit(d, 1.0, n);
        assert!((px.length() - 0.02).abs() < 1e-5, "{px}");
        assert!(px.dot(n).abs() < 1e-6, "on the plane");
    }

    #[test]
    fn barycentric_change_inverts_the_edges() {
        let (e1, e2) = (Vec3A::new(2.0, 0.0, 0.0), Vec3A::new(1.0, 3.0, 0.0));
        let dp = e1 * 0.25 + e2 * -0.5;
        let (b1, b2) = barycentric_change(e1, e2, dp);
        assert!((b1 - 0.25).abs() < 1e-6 && (b2 + 0.5).abs() < 1e-6);
    }

    #[test]
    fn cones_are_isotropic_and_grow() {
        let d = Vec3A::new(0.3, -0.4, 0.866).normalize();
        let c = RayDifferential::cone(d, 0.1, 0.01);
        let (px, py) = c.at_hit(d, 10.0, -d);
        assert!((px.length() - 0.2).abs() < 1e-5 && (py.length() - 0.2).abs() < 1e-5);
        assert!(px.dot(py).abs() < 1e-6);
    }
}

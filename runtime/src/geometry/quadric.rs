//! RenderMan's quadric surfaces (RISpec 3.2, section 5.4) and their tessellation into [`Mesh`]es.
//!
//! Each quadric is a map from its surface parameters `(u, v)` in `[0, 1]^2` to object space,
//! exactly as RISpec defines it (angles in degrees): `u` sweeps `theta` from 0 to `thetamax`
//! around the z axis, `v` runs along the profile.
//!
//! Invariants of [`Quadric::tessellate`]:
//! - every vertex lies on the analytic surface, at the `(u, v)` stored as its uv;
//! - every normal is unit length and equals RISpec's geometric normal direction
//!   `dP/du x dP/dv` (which points away from the z axis, or towards +z for the disk, for positive
//!   parameters; negative `thetamax` or a reversed `z` range turn it round, as in RISpec); the
//!   `Orientation`/handedness flip is the caller's, as it is for any primitive;
//! - triangles wind counter-clockwise seen from the side the normals point to;
//! - rows of the grid that collapse to a point (a sphere's pole, a cone's apex, a disk's centre)
//!   produce no zero-area triangles.

use glam::{Vec2, Vec3};

use super::mesh::{Mesh, MeshError};

/// A quadric surface with RISpec's parameters. Angles are in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Quadric {
    /// `Sphere radius zmin zmax thetamax`
    Sphere {
        /// Radius.
        radius: f32,
        /// Lower z clip.
        zmin: f32,
        /// Upper z clip.
        zmax: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Cylinder radius zmin zmax thetamax`
    Cylinder {
        /// Radius.
        radius: f32,
        /// Bottom.
        zmin: f32,
        /// Top.
        zmax: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Cone height radius thetamax` (base at z = 0, apex at z = height).
    Cone {
        /// Apex height.
        height: f32,
        /// Base radius.
        radius: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Disk height radius thetamax` (in the plane z = height).
    Disk {
        /// Plane height.
        height: f32,
        /// Radius.
        radius: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Torus majorradius minorradius phimin phimax thetamax`
    Torus {
        /// Distance from the axis to the tube's centre.
        major_radius: f32,
        /// Tube radius.
        minor_radius: f32,
        /// Start angle around the tube.
        phimin: f32,
        /// End angle around the tube.
        phimax: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Paraboloid rmax zmin zmax thetamax` (radius `rmax` at `zmax`, apex at the origin).
    Paraboloid {
        /// Radius at `zmax`.
        rmax: f32,
        /// Lower z clip.
        zmin: f32,
        /// Upper z clip.
        zmax: f32,
        /// Sweep angle.
        thetamax: f32,
    },
    /// `Hyperboloid x1 y1 z1 x2 y2 z2 thetamax`: the segment from `point1` to `point2` swept
    /// around the z axis.
    Hyperboloid {
        /// Start of the swept segment.
        point1: Vec3,
        /// End of the swept segment.
        point2: Vec3,
        /// Sweep angle.
        thetamax: f32,
    },
}

/// How finely to tessellate: quads along `u` (around the axis) and along `v`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tessellation {
    /// Segments along `u`.
    pub u_segments: u32,
    /// Segments along `v`.
    pub v_segments: u32,
}

/// The most segments in either direction (bounds memory for absurd requests).
pub const MAX_SEGMENTS: u32 = 4096;

/// Segments around a full 360 degree sweep by default.
const FULL_SWEEP_SEGMENTS: f32 = 64.0;

impl Quadric {
    /// The RIB request name.
    pub fn name(&self) -> &'static str {
        match self {
            Quadric::Sphere { .. } => "Sphere",
            Quadric::Cylinder { .. } => "Cylinder",
            Quadric::Cone { .. } => "Cone",
            Quadric::Disk { .. } => "Disk",
            Quadric::Torus { .. } => "Torus",
            Quadric::Paraboloid { .. } => "Paraboloid",
            Quadric::Hyperboloid { .. } => "Hyperboloid",
        }
    }

    fn thetamax(&self) -> f32 {
        match *self {
            Quadric::Sphere { thetamax, .. }
            | Quadric::Cylinder { thetamax, .. }
            | Quadric::Cone { thetamax, .. }
            | Quadric::Disk { thetamax, .. }
            | Quadric::Torus { thetamax, .. }
            | Quadric::Paraboloid { thetamax, .. }
            | Quadric::Hyperboloid { thetamax, .. } => thetamax,
        }
    }

    /// Whether every parameter is finite.
    pub fn is_finite(&self) -> bool {
        let values: &[f32] = match self {
            Quadric::Sphere { radius, zmin, zmax, thetamax } => &[*radius, *zmin, *zmax, *thetamax],
            Quadric::Cylinder { radius, zmin, zmax, thetamax } => &[*radius, *zmin, *zmax, *thetamax],
            Quadric::Cone { height, radius, thetamax } => &[*height, *radius, *thetamax],
            Quadric::Disk { height, radius, thetamax } => &[*height, *radius, *thetamax],
            Quadric::Torus { major_radius, minor_radius, phimin, phimax, thetamax } => {
                &[*major_radius, *minor_radius, *phimin, *phimax, *thetamax]
            }
            Quadric::Paraboloid { rmax, zmin, zmax, thetamax } => &[*rmax, *zmin, *zmax, *thetamax],
            Quadric::Hyperboloid { point1, point2, thetamax } => {
                return point1.is_finite() && point2.is_finite() && thetamax.is_finite()
            }
        };
        values.iter().all(|v| v.is_finite())
    }

    /// A density that keeps chords within about 1.5% of the radius: 64 segments per full sweep
    /// around the axis, 32 per half turn of a curved profile, one segment along profiles that
    /// are straight lines (cylinder, cone, disk, hyperboloid), which is exact.
    pub fn default_tessellation(&self) -> Tessellation {
        // Sweeps beyond a full turn retrace the surface: they get a full turn's segments, so a
        // wild angle cannot ask for millions of triangles by default.
        let sweep = |degrees: f32, per_turn: f32, min: f32| {
            let n = (per_turn * (degrees.abs().min(360.0) / 360.0)).ceil();
            clamp_segments(if n.is_nan() { min } else { n.max(min) })
        };
        let u_segments = sweep(self.thetamax(), FULL_SWEEP_SEGMENTS, 3.0);
        let v_segments = match *self {
            Quadric::Sphere { .. } => {
                let (phimin, phimax) = self.sphere_phi_range();
                sweep((phimax - phimin).to_degrees(), 64.0, 2.0)
            }
            Quadric::Torus { phimin, phimax, .. } => sweep(phimax - phimin, 32.0, 3.0),
            Quadric::Paraboloid { .. } => 16,
            Quadric::Cylinder { .. } | Quadric::Cone { .. } | Quadric::Disk { .. } | Quadric::Hyperboloid { .. } => 1,
        };
        Tessellation { u_segments, v_segments }
    }

    /// The sphere's latitude range in radians, from its z clips (RISpec: `asin(z / radius)`, a
    /// clip at or beyond the radius closing the sphere at that pole).
    fn sphere_phi_range(&self) -> (f32, f32) {
        let Quadric::Sphere { radius, zmin, zmax, .. } = *self else { return (0.0, 0.0) };
        let latitude = |z: f32| if radius == 0.0 { 0.0 } else { (z / radius).clamp(-1.0, 1.0).asin() };
        (latitude(zmin), latitude(zmax))
    }

    /// The point at surface parameters `(u, v)`.
    pub fn position(&self, u: f32, v: f32) -> Vec3 {
        let theta = u * self.thetamax().to_radians();
        let (sin_t, cos_t) = theta.sin_cos();
        match *self {
            Quadric::Sphere { radius, .. } => {
                let (phimin, phimax) = self.sphere_phi_range();
                let (sin_p, cos_p) = lerp(phimin, phimax, v).sin_cos();
                radius * Vec3::new(cos_t * cos_p, sin_t * cos_p, sin_p)
            }
            Quadric::Cylinder { radius, zmin, zmax, .. } => {
                Vec3::new(radius * cos_t, radius * sin_t, lerp(zmin, zmax, v))
            }
            Quadric::Cone { height, radius, .. } => {
                let r = radius * (1.0 - v);
                Vec3::new(r * cos_t, r * sin_t, v * height)
            }
            Quadric::Disk { height, radius, .. } => {
                let r = radius * (1.0 - v);
                Vec3::new(r * cos_t, r * sin_t, height)
            }
            Quadric::Torus { major_radius, minor_radius, phimin, phimax, .. } => {
                let (sin_p, cos_p) = lerp(phimin, phimax, v).to_radians().sin_cos();
                let r = major_radius + minor_radius * cos_p;
                Vec3::new(r * cos_t, r * sin_t, minor_radius * sin_p)
            }
            Quadric::Paraboloid { rmax, zmin, zmax, .. } => {
                let z = lerp(zmin, zmax, v);
                let r = paraboloid_radius(rmax, z, zmax);
                Vec3::new(r * cos_t, r * sin_t, z)
            }
            Quadric::Hyperboloid { point1, point2, .. } => rotate_z(point1.lerp(point2, v), sin_t, cos_t),
        }
    }

    /// The unit geometric normal at `(u, v)`: the direction of `dP/du x dP/dv`, in closed form so
    /// that it is defined at poles and apexes too.
    pub fn normal(&self, u: f32, v: f32) -> Vec3 {
        let thetamax = self.thetamax();
        let theta = u * thetamax.to_radians();
        let (sin_t, cos_t) = theta.sin_cos();
        let sweep_sign = thetamax.signum();
        let n = match *self {
            Quadric::Sphere { .. } => {
                // dP/dtheta x dP/dphi = r^2 cos(phi) thetamax dphi (cos t cos p, sin t cos p, sin p).
                let (phimin, phimax) = self.sphere_phi_range();
                let (sin_p, cos_p) = lerp(phimin, phimax, v).sin_cos();
                sweep_sign * (phimax - phimin).signum() * Vec3::new(cos_t * cos_p, sin_t * cos_p, sin_p)
            }
            Quadric::Cylinder { radius, zmin, zmax, .. } => {
                sweep_sign * (radius * (zmax - zmin)).signum() * Vec3::new(cos_t, sin_t, 0.0)
            }
            Quadric::Cone { height, radius, .. } => {
                sweep_sign * radius.signum() * Vec3::new(height * cos_t, height * sin_t, radius)
            }
            Quadric::Disk { .. } => sweep_sign * Vec3::Z,
            Quadric::Torus { major_radius, minor_radius, phimin, phimax, .. } => {
                let (sin_p, cos_p) = lerp(phimin, phimax, v).to_radians().sin_cos();
                let tube_centre_side = (major_radius + minor_radius * cos_p).signum();
                let sign = sweep_sign * tube_centre_side * (minor_radius * (phimax - phimin)).signum();
                sign * Vec3::new(cos_p * cos_t, cos_p * sin_t, sin_p)
            }
            Quadric::Paraboloid { rmax, zmin, zmax, .. } => {
                // The gradient of x^2 + y^2 - rmax^2 z / zmax, which dP/du x dP/dv is a positive
                // multiple of (times the sweep and z-range signs).
                let r = paraboloid_radius(rmax, lerp(zmin, zmax, v), zmax);
                let dz = if zmax == 0.0 { 0.0 } else { -rmax * rmax / zmax };
                sweep_sign * (zmax - zmin).signum() * Vec3::new(2.0 * r * cos_t, 2.0 * r * sin_t, dz)
            }
            Quadric::Hyperboloid { point1, point2, .. } => {
                let cross_at = |v: f32| {
                    let p = rotate_z(point1.lerp(point2, v), sin_t, cos_t);
                    let dp_du = sweep_sign * Vec3::new(-p.y, p.x, 0.0);
                    let dp_dv = rotate_z(point2 - point1, sin_t, cos_t);
                    dp_du.cross(dp_dv)
                };
                let n = cross_at(v);
                // On the axis the sweep derivative vanishes: take the limit from inside the segment.
                if n.length_squared() > 1e-12 {
                    n
                } else {
                    cross_at(if v > 0.5 { v - 1e-3 } else { v + 1e-3 })
                }
            }
        };
        n.normalize_or(Vec3::Z)
    }

    /// The mesh of `(u_segments + 1) * (v_segments + 1)` vertices over the parameter grid, with
    /// uvs `(u, v)` and unit normals. Fails for parameters that are not finite or whose surface
    /// overflows `f32`.
    /// At most the triangles [`Quadric::tessellate`] makes at `tessellation`: two a grid cell
    /// (fewer where a row collapses to a point).
    pub fn triangle_count(tessellation: Tessellation) -> usize {
        let nu = tessellation.u_segments.clamp(1, MAX_SEGMENTS) as usize;
        let nv = tessellation.v_segments.clamp(1, MAX_SEGMENTS) as usize;
        2 * nu * nv
    }

    pub fn tessellate(&self, tessellation: Tessellation) -> Result<Mesh, MeshError> {
        if !self.is_finite() {
            return Err(MeshError::NonFinite { index: 0 });
        }
        let nu = tessellation.u_segments.clamp(1, MAX_SEGMENTS);
        let nv = tessellation.v_segments.clamp(1, MAX_SEGMENTS);
        let mesh = tessellate_grid(nu, nv, |u, v| (self.position(u, v), self.normal(u, v)));
        // Finite parameters can still overflow (a torus of radius 3e38).
        mesh.validate()?;
        Ok(mesh)
    }
}

fn clamp_segments(n: f32) -> u32 {
    n.clamp(1.0, MAX_SEGMENTS as f32) as u32
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

fn rotate_z(p: Vec3, sin_t: f32, cos_t: f32) -> Vec3 {
    Vec3::new(p.x * cos_t - p.y * sin_t, p.x * sin_t + p.y * cos_t, p.z)
}

fn paraboloid_radius(rmax: f32, z: f32, zmax: f32) -> f32 {
    if zmax == 0.0 {
        0.0
    } else {
        rmax * (z / zmax).max(0.0).sqrt()
    }
}

/// A `nu` x `nv` quad grid over `(u, v)` in `[0, 1]^2`, each quad split into two triangles
/// (`a b c`, `a c d` with `a` at the low corner and `b` along `u`), so triangles wind
/// counter-clockwise around `dP/du x dP/dv`. Triangles with an edge in a row that collapsed to a
/// point are dropped. `surface` returns the position and normal at `(u, v)`.
pub(crate) fn tessellate_grid(nu: u32, nv: u32, surface: impl Fn(f32, f32) -> (Vec3, Vec3)) -> Mesh {
    let columns = nu as usize + 1;
    let rows = nv as usize + 1;
    let mut positions = Vec::with_capacity(columns * rows);
    let mut normals = Vec::with_capacity(columns * rows);
    let mut uvs = Vec::with_capacity(columns * rows);
    for j in 0..rows {
        let v = j as f32 / nv as f32;
        for i in 0..columns {
            let u = i as f32 / nu as f32;
            let (p, n) = surface(u, v);
            positions.push(p);
            normals.push(n);
            uvs.push(Vec2::new(u, v));
        }
    }
    let scale = positions.iter().fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    let collapsed: Vec<bool> = (0..rows)
        .map(|j| {
            let row = &positions[j * columns..(j + 1) * columns];
            row.iter().all(|p| p.distance(row[0]) <= 1e-6 * scale)
        })
        .collect();
    let index = |i: usize, j: usize| (j * columns + i) as u32;
    let mut triangles = Vec::with_capacity(2 * nu as usize * nv as usize);
    for j in 0..nv as usize {
        for i in 0..nu as usize {
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            if !collapsed[j] {
                triangles.push([a, b, c]);
            }
            if !collapsed[j + 1] {
                triangles.push([a, c, d]);
            }
        }
    }
    Mesh { positions, normals: Some(normals), uvs: Some(uvs), triangles, ..Default::default() }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f32 = 1e-4;

    fn sphere(radius: f32, zmin: f32, zmax: f32, thetamax: f32) -> Quadric {
        Quadric::Sphere { radius, zmin, zmax, thetamax }
    }

    /// Checks the module invariants, with `on_surface` the implicit equation (zero on the surface)
    /// and `outward` the expected normal direction at a point.
    fn check(q: Quadric, on_surface: impl Fn(Vec3) -> f32, outward: impl Fn(Vec3) -> Vec3) -> Mesh {
        let mesh = q.tessellate(q.default_tessellation()).unwrap();
        mesh.validate().unwrap();
        let normals = mesh.normals.as_ref().unwrap();
        let uvs = mesh.uvs.as_ref().unwrap();
        for (k, &p) in mesh.positions.iter().enumerate() {
            assert!(on_surface(p).abs() < EPS, "{q:?}: {p} is off the surface by {}", on_surface(p));
            let n = normals[k];
            assert!((n.length() - 1.0).abs() < EPS);
            assert!(p.distance(q.position(uvs[k].x, uvs[k].y)) < EPS);
            let expected = outward(p);
            if expected.length() > 1e-3 {
                assert!(n.dot(expected.normalize()) > 0.99, "{q:?}: normal {n} at {p}, expected {expected}");
            }
        }
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.corners(t);
            let face = (b - a).cross(c - a);
            assert!(face.length() > 0.0, "{q:?}: degenerate triangle {t}");
            let [i, j, k] = mesh.triangles[t];
            let mean = normals[i as usize] + normals[j as usize] + normals[k as usize];
            assert!(face.dot(mean) > 0.0, "{q:?}: triangle {t} winds against its normals");
        }
        mesh
    }

    #[test]
    fn full_sphere() {
        let q = sphere(2.0, -2.0, 2.0, 360.0);
        assert_eq!(q.default_tessellation(), Tessellation { u_segments: 64, v_segments: 32 });
        let mesh = check(q, |p| p.length() - 2.0, |p| p);
        // Two triangles per quad, less one per quad on each pole row.
        assert_eq!(mesh.triangle_count(), 2 * 64 * 32 - 2 * 64);
        assert!(mesh.positions[0].distance(Vec3::new(0.0, 0.0, -2.0)) < EPS);
    }

    #[test]
    fn partial_sphere() {
        let q = sphere(1.0, -0.5, 0.75, 90.0);
        let t = q.default_tessellation();
        assert_eq!(t.u_segments, 16);
        let mesh = check(q, |p| p.length() - 1.0, |p| p);
        assert_eq!(mesh.triangle_count() as u32, 2 * t.u_segments * t.v_segments);
        for p in &mesh.positions {
            assert!(p.z >= -0.5 - EPS && p.z <= 0.75 + EPS && p.x >= -EPS && p.y >= -EPS);
        }
        assert!((q.position(0.0, 0.0).z + 0.5).abs() < EPS && (q.position(1.0, 1.0).y - 0.661_437_8).abs() < EPS);
    }

    #[test]
    fn cylinder_cone_disk() {
        let xy = |p: Vec3| Vec3::new(p.x, p.y, 0.0);
        check(Quadric::Cylinder { radius: 1.5, zmin: -1.0, zmax: 2.0, thetamax: 360.0 }, |p| xy(p).length() - 1.5, xy);
        let cone = Quadric::Cone { height: 2.0, radius: 1.0, thetamax: 270.0 };
        // Radius shrinks linearly to the apex; the outward normal is (h cos t, h sin t, r).
        let mesh = check(
            cone,
            |p| xy(p).length() - (1.0 - p.z / 2.0),
            |p| if xy(p).length() > 1e-3 { 2.0 * xy(p).normalize() + Vec3::Z } else { Vec3::ZERO },
        );
        assert_eq!(mesh.triangle_count(), 48); // apex row collapsed: one triangle per segment
        let disk = check(Quadric::Disk { height: 0.5, radius: 3.0, thetamax: 360.0 }, |p| p.z - 0.5, |_| Vec3::Z);
        assert_eq!(disk.triangle_count(), 64);
        let area: f32 = (0..64)
            .map(|t| {
                let [a, b, c] = disk.corners(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        assert!((area - 9.0 * std::f32::consts::PI).abs() < 0.05);
    }

    #[test]
    fn torus_paraboloid_hyperboloid() {
        let torus =
            Quadric::Torus { major_radius: 2.0, minor_radius: 0.5, phimin: 0.0, phimax: 360.0, thetamax: 360.0 };
        let ring = |p: Vec3| Vec3::new(p.x, p.y, 0.0).normalize() * 2.0;
        check(torus, |p| (p - ring(p)).length() - 0.5, |p| p - ring(p));
        let para = Quadric::Paraboloid { rmax: 1.0, zmin: 0.0, zmax: 2.0, thetamax: 360.0 };
        check(para, |p| p.x * p.x + p.y * p.y - p.z / 2.0, |p| Vec3::new(2.0 * p.x, 2.0 * p.y, -0.5));
        // A one-sheet hyperboloid: the segment (1, -1, -1) to (1, 1, 1) swept about z.
        let hyp = Quadric::Hyperboloid {
            point1: Vec3::new(1.0, -1.0, -1.0),
            point2: Vec3::new(1.0, 1.0, 1.0),
            thetamax: 360.0,
        };
        check(hyp, |p| p.x * p.x + p.y * p.y - p.z * p.z - 1.0, |p| Vec3::new(p.x, p.y, -p.z));
        // A hyperboloid through the axis is a cone: normals stay defined at the apex.
        let through_axis =
            Quadric::Hyperboloid { point1: Vec3::ZERO, point2: Vec3::new(1.0, 0.0, 1.0), thetamax: 360.0 };
        assert!(through_axis.normal(0.3, 0.0).is_finite());
    }

    #[test]
    fn reversed_sweep_turns_normals_round_and_non_finite_is_an_error() {
        assert!(sphere(1.0, -1.0, 1.0, -360.0).normal(0.1, 0.5).dot(Vec3::new(1.0, 0.6, 0.0)) < 0.0);
        assert!(sphere(f32::NAN, -1.0, 1.0, 360.0).tessellate(Tessellation { u_segments: 4, v_segments: 4 }).is_err());
        let huge = sphere(1.0, -1.0, 1.0, 1e30).default_tessellation();
        assert_eq!(huge.u_segments, 64);
        let torus = Quadric::Torus { major_radius: 1.0, minor_radius: 0.5, phimin: 0.0, phimax: 1e30, thetamax: 1e30 };
        assert_eq!(torus.default_tessellation(), Tessellation { u_segments: 64, v_segments: 32 });
        let huge = Tessellation { u_segments: u32::MAX, v_segments: 0 };
        assert_eq!(
            sphere(1.0, -1.0, 1.0, 360.0).tessellate(huge).unwrap().positions.len() as u32,
            (MAX_SEGMENTS + 1) * 2
        );
    }
}

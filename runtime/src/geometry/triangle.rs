//! The ray-triangle test (Möller-Trumbore) and the precomputed triangle layout the BVH leaves use.
//!
//! Invariant: [`intersect`] is generic over the lane type (`f32` for single rays, `wide::f32x8` for
//! a chunk of eight packet lanes, `glam::Vec4` for four) and performs the same IEEE operations in the same order for both, with no
//! fused multiply-add, so a triangle gives bit-identical `t`, `u`, `v` on every traversal path.
//! Acceptance ([`accept`] and its SIMD twin in the packet code) uses only comparisons, never
//! further arithmetic except the single `u + v`, which is also the same everywhere.
//!
//! The test is not watertight: a ray through a shared edge may hit both triangles or, in rare
//! floating-point cases, neither. Self-intersection is handled by offsetting secondary ray origins
//! (see [`crate::ray::offset_ray_origin`]).

use glam::{Vec3, Vec3A, Vec4};
use std::ops::{Add, Div, Mul, Sub};

/// Arithmetic on one lane or several.
pub trait Arith: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    /// Broadcast a scalar.
    fn splat(v: f32) -> Self;
}

impl Arith for f32 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
}

impl Arith for glam::Vec4 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        glam::Vec4::splat(v)
    }
}

impl Arith for wide::f32x8 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        wide::f32x8::splat(v)
    }
}

/// A triangle prepared for intersection: first vertex and the two edges from it (36 bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct PreTriangle {
    /// Vertex 0.
    pub v0: [f32; 3],
    /// Vertex 1 minus vertex 0.
    pub e1: [f32; 3],
    /// Vertex 2 minus vertex 0.
    pub e2: [f32; 3],
}

impl PreTriangle {
    /// Prepares the triangle `(a, b, c)`.
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Self {
        PreTriangle { v0: a.to_array(), e1: (b - a).to_array(), e2: (c - a).to_array() }
    }

    /// The triangle `w` of the way from `self` to `other` (corner by corner, which is field by
    /// field: each is linear in the corners).
    #[inline(always)]
    pub fn lerp(&self, other: &PreTriangle, w: f32) -> PreTriangle {
        let mix = |a: [f32; 3], b: [f32; 3]| std::array::from_fn(|k| a[k] + (b[k] - a[k]) * w);
        PreTriangle { v0: mix(self.v0, other.v0), e1: mix(self.e1, other.e1), e2: mix(self.e2, other.e2) }
    }

    /// The unnormalised geometric normal `e1 x e2`.
    pub fn normal(&self) -> Vec3A {
        Vec3A::from(self.e1).cross(Vec3A::from(self.e2))
    }
}

#[inline(always)]
fn cross<L: Arith>(a: [L; 3], b: [L; 3]) -> [L; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

#[inline(always)]
fn dot<L: Arith>(a: [L; 3], b: [L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Möller-Trumbore: returns `(t, u, v)`. The hit is valid iff [`accept`] holds; degenerate cases
/// produce NaN or infinities, which fail the acceptance comparisons.
#[inline(always)]
pub fn intersect<L: Arith>(o: [L; 3], d: [L; 3], tri: &PreTriangle) -> (L, L, L) {
    intersect_lanes(o, d, tri.v0.map(L::splat), tri.e1.map(L::splat), tri.e2.map(L::splat))
}

/// [`intersect`] with a triangle a lane (a ray against each of a block's triangles, or rays
/// against one): the same operations.
#[inline(always)]
fn intersect_lanes<L: Arith>(o: [L; 3], d: [L; 3], v0: [L; 3], e1: [L; 3], e2: [L; 3]) -> (L, L, L) {
    let pvec = cross(d, e2);
    let det = dot(e1, pvec);
    let inv_det = L::splat(1.0) / det;
    let s = [o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]];
    let u = dot(s, pvec) * inv_det;
    let qvec = cross(s, e1);
    let v = dot(d, qvec) * inv_det;
    let t = dot(e2, qvec) * inv_det;
    (t, u, v)
}

/// The ray-independent part of [`intersect`] for rays that share origin `o`: `s = o - v0`,
/// `q = s x e1` and `e2 . q`.
#[derive(Clone, Copy, Debug)]
pub struct SharedOrigin {
    s: [f32; 3],
    q: [f32; 3],
    tn: f32,
}

impl SharedOrigin {
    /// Precomputes the origin terms of `tri` for origin `o` (same operations as [`intersect`]).
    #[inline(always)]
    pub fn new(o: [f32; 3], tri: &PreTriangle) -> Self {
        let s = [o[0] - tri.v0[0], o[1] - tri.v0[1], o[2] - tri.v0[2]];
        let q = cross(s, tri.e1);
        SharedOrigin { s, q, tn: dot(tri.e2, q) }
    }
}

/// [`intersect`] for a ray whose origin terms were precomputed: bit-identical results, since the
/// splatted terms are the very values [`intersect`] computes per lane.
#[inline(always)]
pub fn intersect_shared<L: Arith>(so: &SharedOrigin, d: [L; 3], tri: &PreTriangle) -> (L, L, L) {
    let e1 = tri.e1.map(L::splat);
    let e2 = tri.e2.map(L::splat);
    let pvec = cross(d, e2);
    let det = dot(e1, pvec);
    let inv_det = L::splat(1.0) / det;
    let u = dot(so.s.map(L::splat), pvec) * inv_det;
    let v = dot(d, so.q.map(L::splat)) * inv_det;
    let t = L::splat(so.tn) * inv_det;
    (t, u, v)
}

/// Whether `(t, u, v)` from [`intersect`] is a hit inside `(tmin, tmax)`.
#[inline(always)]
pub fn accept(t: f32, u: f32, v: f32, tmin: f32, tmax: f32) -> bool {
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > tmin && t < tmax
}

/// [`intersect`] followed by [`accept`] for one ray, leaving out the work that can no longer change
/// the answer: `v` and `t` are computed only when `u` is in `[0, 1]`, and `t` only when `v` passes
/// too. The values are computed by the same operations as in [`intersect`], and the early exits are
/// implied by [`accept`] (`v >= 0` and `u + v <= 1` imply `u <= 1`, since rounding is monotonic), so
/// the result is `Some((t, u, v))` exactly when `accept(intersect(..))` holds.
#[inline(always)]
pub fn intersect_accept(o: [f32; 3], d: [f32; 3], tri: &PreTriangle, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let pvec = cross(d, tri.e2);
    let det = dot(tri.e1, pvec);
    let inv_det = 1.0 / det;
    let s = [o[0] - tri.v0[0], o[1] - tri.v0[1], o[2] - tri.v0[2]];
    let u = dot(s, pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = cross(s, tri.e1);
    let v = dot(d, qvec) * inv_det;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = dot(tri.e2, qvec) * inv_det;
    (t > tmin && t < tmax).then_some((t, u, v))
}

/// Triangles in a block: the lanes of a [`TriangleBlock`].
pub const BLOCK_WIDTH: usize = 4;

/// Four prepared triangles in structure-of-arrays form (144 bytes): coordinate `k` of the first
/// vertex of lane `j` is `v0[k][j]`, and so on. A single ray tests a leaf's triangles at once with
/// nine vector loads; unused lanes hold zeros (a degenerate triangle, which nothing hits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub struct TriangleBlock {
    pub v0: [[f32; 4]; 3],
    pub e1: [[f32; 4]; 3],
    pub e2: [[f32; 4]; 3],
}

impl TriangleBlock {
    /// The block of `tris` (at most [`BLOCK_WIDTH`]) in lane order.
    pub fn new(tris: &[PreTriangle]) -> TriangleBlock {
        let mut b = TriangleBlock::default();
        for (j, t) in tris.iter().take(BLOCK_WIDTH).enumerate() {
            b.set(j, t);
        }
        b
    }

    /// Puts `t` in lane `j` (below [`BLOCK_WIDTH`]).
    #[inline(always)]
    pub fn set(&mut self, j: usize, t: &PreTriangle) {
        for k in 0..3 {
            self.v0[k][j] = t.v0[k];
            self.e1[k][j] = t.e1[k];
            self.e2[k][j] = t.e2[k];
        }
    }

    /// Lane `j`'s triangle.
    #[inline(always)]
    pub fn triangle(&self, j: usize) -> PreTriangle {
        PreTriangle {
            v0: [0, 1, 2].map(|k| self.v0[k][j]),
            e1: [0, 1, 2].map(|k| self.e1[k][j]),
            e2: [0, 1, 2].map(|k| self.e2[k][j]),
        }
    }

    /// [`PreTriangle::lerp`] of every lane (the same operations).
    #[inline(always)]
    pub fn lerp(&self, other: &TriangleBlock, w: f32) -> TriangleBlock {
        let w = Vec4::splat(w);
        let mix = |a: [[f32; 4]; 3], b: [[f32; 4]; 3]| {
            std::array::from_fn(|k| {
                let (a, b) = (Vec4::from_array(a[k]), Vec4::from_array(b[k]));
                (a + (b - a) * w).to_array()
            })
        };
        TriangleBlock { v0: mix(self.v0, other.v0), e1: mix(self.e1, other.e1), e2: mix(self.e2, other.e2) }
    }

    /// [`intersect`] of one ray with each lane's triangle, and the lanes where [`accept`] holds
    /// (bit `j` for lane `j`): the same values bit for bit, the same answers.
    #[inline(always)]
    pub fn intersect(&self, o: [f32; 3], d: [f32; 3], tmin: f32, tmax: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let rows = |r: &[[f32; 4]; 3]| r.map(Vec4::from_array);
        let (t, u, v) =
            intersect_lanes(o.map(Vec4::splat), d.map(Vec4::splat), rows(&self.v0), rows(&self.e1), rows(&self.e2));
        let hit = u.cmpge(Vec4::ZERO)
            & v.cmpge(Vec4::ZERO)
            & (u + v).cmple(Vec4::ONE)
            & t.cmpgt(Vec4::splat(tmin))
            & t.cmplt(Vec4::splat(tmax));
        (hit.bitmask(), t.to_array(), u.to_array(), v.to_array())
    }
}

/// Scalar convenience wrapper: the hit `(t, u, v)` of a ray with a triangle, if any.
pub fn intersect_ray(origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32, tri: &PreTriangle) -> Option<(f32, f32, f32)> {
    let (t, u, v) = intersect(origin.to_array(), dir.to_array(), tri);
    accept(t, u, v, tmin, tmax).then_some((t, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic spread of coordinates in `[-2, 2)` from `seed`, one in 64 exactly zero (for
    /// rays, triangles and intervals, degenerate ones included).
    fn spread(seed: u64) -> impl FnMut() -> f32 {
        let mut x = seed;
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let f = (x >> 40) as f32 / (1u64 << 24) as f32 * 4.0 - 2.0;
            if x & 63 == 0 {
                0.0
            } else {
                f
            }
        }
    }

    #[test]
    fn hits_the_middle() {
        let tri = PreTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let h = intersect_ray(Vec3A::new(0.25, 0.25, 1.0), Vec3A::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY, &tri);
        let (t, u, v) = h.unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (u - 0.25).abs() < 1e-6 && (v - 0.25).abs() < 1e-6);
    }

    #[test]
    fn parallel_ray_misses() {
        let tri = PreTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let h = intersect_ray(Vec3A::new(0.25, 0.25, 0.0), Vec3A::X, 0.0, f32::INFINITY, &tri);
        assert!(h.is_none());
    }

    #[test]
    fn early_exits_agree_with_intersect_and_accept() {
        let mut next = spread(0x2545_f491_4f6c_dd1d);
        let mut hits = 0;
        for _ in 0..200_000 {
            let p = |n: &mut dyn FnMut() -> f32| Vec3::new(n(), n(), n());
            let tri = PreTriangle::new(p(&mut next), p(&mut next), p(&mut next));
            let (o, d) = ([next(), next(), next()], [next(), next(), next()]);
            let (tmin, tmax) = (next().min(0.0), next().abs() * 4.0);
            let (t, u, v) = intersect(o, d, &tri);
            let want = accept(t, u, v, tmin, tmax).then_some((t, u, v));
            let got = intersect_accept(o, d, &tri, tmin, tmax);
            assert_eq!(
                want.map(|(t, u, v)| [t.to_bits(), u.to_bits(), v.to_bits()]),
                got.map(|(t, u, v)| [t.to_bits(), u.to_bits(), v.to_bits()])
            );
            hits += want.is_some() as u32;
        }
        assert!(hits > 1000, "{hits}");
    }

    #[test]
    fn lanes_match_scalar_bit_for_bit() {
        let tri = PreTriangle::new(Vec3::new(0.1, -0.3, 2.0), Vec3::new(1.7, 0.2, 2.5), Vec3::Y);
        let o = [0.3f32, 0.1, -1.0];
        let d = [0.01f32, 0.05, 1.0];
        let s = intersect(o, d, &tri);
        let l = intersect(o.map(glam::Vec4::splat), d.map(glam::Vec4::splat), &tri);
        assert_eq!(s.0.to_bits(), l.0.x.to_bits());
        assert_eq!(s.1.to_bits(), l.1.y.to_bits());
        assert_eq!(s.2.to_bits(), l.2.z.to_bits());
        let so = SharedOrigin::new(o, &tri);
        let sh = intersect_shared(&so, d.map(glam::Vec4::splat), &tri);
        assert_eq!(s.0.to_bits(), sh.0.w.to_bits());
        assert_eq!(s.1.to_bits(), sh.1.x.to_bits());
        assert_eq!(s.2.to_bits(), sh.2.y.to_bits());
        // Eight lanes, each with its own direction, as the packet traversal's chunks.
        let dirs: [[f32; 3]; 8] = std::array::from_fn(|j| [0.01 + 0.03 * j as f32, 0.05 - 0.02 * j as f32, 1.0]);
        let row = |a: usize| wide::f32x8::new(dirs.map(|d| d[a]));
        let d8 = [row(0), row(1), row(2)];
        let wide = intersect(o.map(wide::f32x8::splat), d8, &tri);
        let wide_shared = intersect_shared(&so, d8, &tri);
        for (j, d) in dirs.iter().enumerate() {
            let s = intersect(o, *d, &tri);
            for got in [wide, wide_shared] {
                let got = [got.0, got.1, got.2].map(|v| v.to_array()[j].to_bits());
                assert_eq!(got, [s.0.to_bits(), s.1.to_bits(), s.2.to_bits()], "lane {j}");
            }
        }
    }

    #[test]
    fn blocks_match_scalar_bit_for_bit() {
        let mut next = spread(0x9e37_79b9_7f4a_7c15);
        let mut hits = 0;
        for round in 0..50_000 {
            let p = |n: &mut dyn FnMut() -> f32| Vec3::new(n(), n(), n());
            let lanes = 1 + round % BLOCK_WIDTH;
            let tris: Vec<PreTriangle> =
                (0..lanes).map(|_| PreTriangle::new(p(&mut next), p(&mut next), p(&mut next))).collect();
            let close: Vec<PreTriangle> =
                (0..lanes).map(|_| PreTriangle::new(p(&mut next), p(&mut next), p(&mut next))).collect();
            let (o, d) = ([next(), next(), next()], [next(), next(), next()]);
            let (tmin, tmax) = (next().min(0.0), next().abs() * 4.0);
            let w = next().abs() * 0.5;
            let (block, close_block) = (TriangleBlock::new(&tris), TriangleBlock::new(&close));
            let blended = block.lerp(&close_block, w);
            for (at_close, b) in [(false, block), (true, blended)] {
                let (mask, t4, u4, v4) = b.intersect(o, d, tmin, tmax);
                for j in 0..BLOCK_WIDTH {
                    let Some(tri) = tris.get(j) else {
                        assert_eq!(mask >> j & 1, 0, "an empty lane hit");
                        continue;
                    };
                    let tri = if at_close { tri.lerp(&close[j], w) } else { *tri };
                    assert_eq!(b.triangle(j), tri);
                    let (t, u, v) = intersect(o, d, &tri);
                    assert_eq!(mask >> j & 1 == 1, accept(t, u, v, tmin, tmax), "lane {j}");
                    assert_eq!([t4[j], u4[j], v4[j]].map(f32::to_bits), [t, u, v].map(f32::to_bits));
                    hits += mask >> j & 1;
                }
            }
        }
        assert!(hits > 1000, "{hits}");
    }
}

//! An object: a mesh plus its own BVH, built once and rebuilt only when the object's geometry
//! changes. Many instances share one object.
//!
//! Invariant: `tris[s]` is the prepared form of mesh triangle `bvh.prim_order[s]`, so a leaf slot
//! gives both the triangle to test and the primitive id to report.

use super::bvh4::{BuildQuality, Bvh4};
use super::bvh8::Bvh8;
use crate::geometry::{triangle::PreTriangle, AlphaMask, Mesh};
use glam::Vec3A;
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use std::sync::Arc;

/// Largest leaf the object BVHs are built with (measured on s34k: 2 beats 1, 4 and 8 for packets and
/// single rays alike; see `docs/tracer.md`).
pub const OBJECT_LEAF_SIZE: u32 = 2;

/// An object's BVH with its triangles in leaf order.
#[derive(Clone, Debug, Default)]
pub struct ObjectBvh {
    /// The BVH over the triangles (read by packets).
    pub bvh: Bvh4,
    /// Its 8-wide form (read by single rays; same leaves).
    pub wide: Bvh8,
    /// Prepared triangles in leaf-slot order.
    pub tris: Vec<PreTriangle>,
}

impl ObjectBvh {
    /// Builds the BVH of `mesh`.
    pub fn build(mesh: &Mesh, quality: BuildQuality) -> Self {
        let boxes: Vec<Aabb> = (0..mesh.triangle_count())
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                let (a, b, c) = (Vec3A::from(a), Vec3A::from(b), Vec3A::from(c));
                Aabb::new(a.min(b).min(c), a.max(b).max(c))
            })
            .collect();
        let bvh = Bvh4::build(&boxes, quality, OBJECT_LEAF_SIZE);
        let mut tris = Vec::with_capacity(bvh.prim_order.len());
        bvh.prim_order
            .par_iter()
            .with_min_len(4096)
            .map(|&p| {
                let [a, b, c] = mesh.corners(p as usize);
                PreTriangle::new(a, b, c)
            })
            .collect_into_vec(&mut tris);
        let wide = Bvh8::from_bvh4(&bvh);
        ObjectBvh { bvh, wide, tris }
    }

    /// Heap bytes of the BVH and the prepared triangles.
    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes() + self.wide.memory_bytes() + self.tris.len() * size_of::<PreTriangle>()
    }
}

/// A retained object: its mesh and BVH.
#[derive(Clone, Debug, Default)]
pub struct Object {
    /// The geometry (shared, so that it can be handed out cheaply).
    pub mesh: Arc<Mesh>,
    /// Its BVH.
    pub bvh: ObjectBvh,
    /// Cut-outs: where the mask is uncovered the object has no surface.
    pub alpha: Option<Arc<AlphaMask>>,
}

impl Object {
    /// Builds an object from a mesh.
    pub fn new(mesh: Arc<Mesh>, quality: BuildQuality) -> Self {
        let bvh = ObjectBvh::build(&mesh, quality);
        Object { mesh, bvh, alpha: None }
    }

    /// Whether a candidate hit of triangle `primitive` at barycentrics `(u, v)` is on the surface
    /// (not in a cut-out of the alpha mask).
    #[inline(always)]
    pub fn solid_at(&self, primitive: u32, u: f32, v: f32) -> bool {
        match &self.alpha {
            None => true,
            Some(mask) => mask.covers(&self.mesh, primitive, u, v),
        }
    }
}

//! Object BVHs shared by scenes: the frames of a RIB animation each load their world afresh, and a
//! set that does not move declares the same meshes every frame. A scene that shares a
//! [`BvhStore`] takes the BVH built for an earlier scene's mesh of the same geometry instead of
//! building it again.
//!
//! Invariants:
//! - a BVH is reused only for a mesh whose geometry is bit for bit that of the mesh it was built
//!   from (positions, triangles, and a deformation's close positions and times) at the same
//!   quality: the store keeps that mesh and compares, the digest only finds the candidates. What
//!   else a mesh holds (normals, texture coordinates, attributes) is not in the BVH.
//! - what the store keeps is bounded by what the scenes use: [`BvhStore::end_frame`] lets go of
//!   every BVH the frame that ended did not ask for.

use super::bvh4::BuildQuality;
use super::object::ObjectBvh;
use crate::geometry::Mesh;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

/// Object BVHs by the geometry they were built from (see the module doc), for
/// [`crate::scene::Scene::share_bvhs`] and [`crate::api::Context::share_bvhs`].
#[derive(Default)]
pub struct BvhStore {
    state: Mutex<State>,
}

impl std::fmt::Debug for BvhStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let state = self.state();
        f.debug_struct("BvhStore").field("bvhs", &state.len()).field("reused", &state.reused).finish()
    }
}

#[derive(Default)]
struct State {
    entries: HashMap<u64, Vec<Entry>>,
    /// Frames ended so far.
    frame: u64,
    /// BVHs handed out again rather than built.
    reused: u64,
}

impl State {
    fn len(&self) -> usize {
        self.entries.values().map(Vec::len).sum()
    }
}

struct Entry {
    /// The mesh the BVH was built from, to compare candidates with.
    mesh: Arc<Mesh>,
    quality: BuildQuality,
    bvh: Arc<ObjectBvh>,
    /// The frame that last asked for it.
    used: u64,
}

impl BvhStore {
    pub fn new() -> BvhStore {
        BvhStore::default()
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The BVH of `mesh` at `quality`: the one built for a mesh of the same geometry, else built
    /// now (outside the store's lock) and kept.
    pub fn get_or_build(&self, mesh: &Arc<Mesh>, quality: BuildQuality) -> Arc<ObjectBvh> {
        let digest = geometry_digest(mesh, quality);
        {
            let mut state = self.state();
            let frame = state.frame;
            let found = state.entries.get_mut(&digest).and_then(|candidates| {
                candidates.iter_mut().find(|e| e.quality == quality && same_geometry(&e.mesh, mesh))
            });
            if let Some(entry) = found {
                entry.used = frame;
                let bvh = entry.bvh.clone();
                state.reused += 1;
                return bvh;
            }
        }
        let bvh = Arc::new(ObjectBvh::build(mesh, quality));
        let mut state = self.state();
        let used = state.frame;
        let entry = Entry { mesh: mesh.clone(), quality, bvh: bvh.clone(), used };
        state.entries.entry(digest).or_default().push(entry);
        bvh
    }

    /// A frame ended: the BVHs it did not ask for are let go (they stay with the scenes that
    /// hold them).
    pub fn end_frame(&self) {
        let mut state = self.state();
        let ended = state.frame;
        state.entries.retain(|_, candidates| {
            candidates.retain(|e| e.used == ended);
            !candidates.is_empty()
        });
        state.frame += 1;
    }

    /// How many BVHs it holds.
    pub fn len(&self) -> usize {
        self.state().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// How many times a BVH was handed out again rather than built.
    pub fn reused(&self) -> u64 {
        self.state().reused
    }
}

/// A hash of what a BVH of `mesh` at `quality` is built from (FxHash's step over 32-bit words:
/// it only sorts candidates, which are compared in full).
fn geometry_digest(mesh: &Mesh, quality: BuildQuality) -> u64 {
    const K: u64 = 0x51_7c_c1_b7_27_22_0a_95;
    let step = |h: u64, word: u64| (h.rotate_left(5) ^ word).wrapping_mul(K);
    let words = |h: u64, words: &[u32]| {
        let mut pairs = words.chunks_exact(2);
        let h = pairs.by_ref().fold(h, |h, p| step(h, u64::from(p[0]) | u64::from(p[1]) << 32));
        pairs.remainder().iter().fold(h, |h, &w| step(h, u64::from(w)))
    };
    let mut h = step(0, quality as u64);
    h = step(h, mesh.positions.len() as u64);
    h = words(h, bytemuck::cast_slice(&mesh.positions));
    h = step(h, mesh.triangles.len() as u64);
    h = words(h, bytemuck::cast_slice(&mesh.triangles));
    if let Some(d) = &mesh.deformation {
        h = step(h, u64::from(d.open.to_bits()) | u64::from(d.close.to_bits()) << 32);
        h = words(h, bytemuck::cast_slice(&d.positions));
    }
    h
}

/// Positions as the bits of their coordinates.
fn bits(positions: &[glam::Vec3]) -> &[u32] {
    bytemuck::cast_slice(positions)
}

/// Whether two meshes have bit for bit the geometry a BVH is built from.
fn same_geometry(a: &Arc<Mesh>, b: &Arc<Mesh>) -> bool {
    if Arc::ptr_eq(a, b) {
        return true;
    }
    let deformations = match (&a.deformation, &b.deformation) {
        (None, None) => true,
        (Some(x), Some(y)) => {
            x.open.to_bits() == y.open.to_bits()
                && x.close.to_bits() == y.close.to_bits()
                && bits(&x.positions) == bits(&y.positions)
        }
        _ => false,
    };
    a.triangles == b.triangles && bits(&a.positions) == bits(&b.positions) && deformations
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::wire::tests::grid;
    use crate::geometry::mesh::Deformation;
    use glam::Vec3;

    /// Meshes of the same geometry (not the same mesh) get one BVH; a mesh that differs in one
    /// bit of one position, in a deformation or in the quality asked for gets its own; and the
    /// store keeps only what the last frame asked for.
    #[test]
    fn meshes_of_the_same_geometry_share_one_bvh() {
        let store = BvhStore::new();
        let first = Arc::new(grid(12));
        let built = store.get_or_build(&first, BuildQuality::High);
        // Another mesh with the same geometry, and normals and uvs the first lacks.
        let mut same = grid(12);
        same.normals = Some(vec![Vec3::Z; same.positions.len()]);
        let again = store.get_or_build(&Arc::new(same), BuildQuality::High);
        assert!(Arc::ptr_eq(&built, &again));
        assert_eq!(store.reused(), 1);

        // Zero and minus zero are equal floats but not the same bits.
        let mut signed = grid(12);
        assert_eq!(signed.positions[0].z.to_bits(), 0);
        signed.positions[0].z = -0.0;
        let other = store.get_or_build(&Arc::new(signed), BuildQuality::High);
        assert!(!Arc::ptr_eq(&built, &other));
        let faster = store.get_or_build(&first, BuildQuality::Fast);
        assert!(!Arc::ptr_eq(&built, &faster));
        let mut deforming = grid(12);
        let close = deforming.positions.iter().map(|p| *p + Vec3::Z).collect();
        deforming.deformation = Some(Deformation { positions: close, normals: None, open: 0.0, close: 1.0 });
        let deformed = store.get_or_build(&Arc::new(deforming), BuildQuality::High);
        assert!(deformed.deformed.is_some() && !Arc::ptr_eq(&built, &deformed));
        assert_eq!((store.len(), store.reused()), (4, 1));

        // The BVH reused is the one a build of the mesh makes.
        let fresh = ObjectBvh::build(&first, BuildQuality::High);
        assert_eq!(fresh.bvh.nodes.len(), built.bvh.nodes.len());
        assert_eq!(fresh.bvh.prim_order, built.bvh.prim_order);

        store.end_frame();
        assert_eq!(store.len(), 4, "everything was asked for in the frame that ended");
        store.get_or_build(&first, BuildQuality::High);
        store.end_frame();
        assert_eq!(store.len(), 1, "only what the second frame asked for stays");
        assert!(Arc::ptr_eq(&built, &store.get_or_build(&first, BuildQuality::High)));
    }
}

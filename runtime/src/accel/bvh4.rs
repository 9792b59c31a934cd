//! The 4-wide BVH node layout that both traversal paths read, and its construction from obvhs.
//!
//! obvhs builds a binary BVH (PLOC, optional reinsertion, leaf collapsing); [`Bvh4::build`] then
//! collapses it into 4-wide nodes by repeatedly opening the child with the largest surface area, and
//! lays the nodes out in depth-first pre-order.
//!
//! Node layout ([`Node4`], 128 bytes, one pair of cache lines): the four children's boxes in SoA form
//! (`min_x[4]`, `max_x[4]`, ... ) followed by four child references. A single ray tests all four
//! boxes with one SSE slab test; a packet tests each box against four lanes at a time.
//!
//! Invariants:
//! - A child reference with [`LEAF_BIT`] clear is the index of an inner node. With it set, bits
//!   4..31 hold the first leaf slot and bits 0..3 the slot count (1..=15); a count of 0 marks an
//!   empty child, whose box is inverted (`min = +inf`, `max = -inf`) so that no ray ever enters it.
//! - Leaf slot `s` refers to primitive `prim_order[s]` of the input; leaf slots of one leaf are
//!   contiguous. Every input primitive appears in exactly one leaf slot.
//! - Node 0 is the root (when there is at least one primitive). Child boxes contain their subtree.

use glam::Vec3A;
use obvhs::{
    aabb::Aabb,
    bvh2::{builder::build_bvh2, Bvh2},
    ploc::{PlocSearchDistance, SortPrecision},
    BvhBuildParams,
};
use std::time::Duration;

/// Marks a child reference as a leaf.
pub const LEAF_BIT: u32 = 1 << 31;
/// The reference of an empty child slot.
pub const EMPTY_CHILD: u32 = LEAF_BIT;
/// Largest number of primitives in one leaf.
pub const MAX_LEAF_SIZE: u32 = 15;

/// A 4-wide BVH node (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    /// Child box minima along x.
    pub min_x: [f32; 4],
    /// Child box maxima along x.
    pub max_x: [f32; 4],
    /// Child box minima along y.
    pub min_y: [f32; 4],
    /// Child box maxima along y.
    pub max_y: [f32; 4],
    /// Child box minima along z.
    pub min_z: [f32; 4],
    /// Child box maxima along z.
    pub max_z: [f32; 4],
    /// Child references.
    pub child: [u32; 4],
}

impl Default for Node4 {
    fn default() -> Self {
        let inf = f32::INFINITY;
        Node4 {
            min_x: [inf; 4],
            max_x: [-inf; 4],
            min_y: [inf; 4],
            max_y: [-inf; 4],
            min_z: [inf; 4],
            max_z: [-inf; 4],
            child: [EMPTY_CHILD; 4],
        }
    }
}

impl Node4 {
    fn set_child(&mut self, k: usize, b: &Aabb, child: u32) {
        self.min_x[k] = b.min.x;
        self.min_y[k] = b.min.y;
        self.min_z[k] = b.min.z;
        self.max_x[k] = b.max.x;
        self.max_y[k] = b.max.y;
        self.max_z[k] = b.max.z;
        self.child[k] = child;
    }
}

/// Encodes a leaf reference.
#[inline(always)]
pub fn leaf_ref(first: u32, count: u32) -> u32 {
    debug_assert!(count <= MAX_LEAF_SIZE && first < (1 << 27));
    LEAF_BIT | (first << 4) | count
}

/// Decodes a leaf reference into `(first slot, count)`.
#[inline(always)]
pub fn leaf_range(r: u32) -> (u32, u32) {
    ((r & !LEAF_BIT) >> 4, r & 15)
}

/// How much effort to spend on BVH quality.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildQuality {
    /// Fastest build (per-frame top-level BVHs, huge meshes).
    Fast,
    /// Balanced build: PLOC with the smallest search radius and a little reinsertion.
    Medium,
    /// Slow, best traversal (spatial pre-splits are not used: leaves must own their primitives).
    High,
}

impl BuildQuality {
    fn params(self, max_leaf: u32) -> BvhBuildParams {
        let mut p = match self {
            BuildQuality::Fast => BvhBuildParams::fastest_build(),
            BuildQuality::Medium => BvhBuildParams::very_fast_build(),
            BuildQuality::High => BvhBuildParams::medium_build(),
        };
        p.pre_split = false;
        p.max_prims_per_leaf = max_leaf.clamp(1, MAX_LEAF_SIZE);
        p.collapse_traversal_cost = 3.0;
        p.sort_precision = SortPrecision::U64;
        if self == BuildQuality::Fast {
            p.ploc_search_distance = PlocSearchDistance::Minimum;
        }
        p
    }
}

/// A 4-wide BVH over primitives given by their boxes.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    /// Nodes, root first.
    pub nodes: Vec<Node4>,
    /// Leaf slot to input primitive.
    pub prim_order: Vec<u32>,
    /// Bounds of everything.
    pub bounds: Option<(Vec3A, Vec3A)>,
    /// Number of inner-node levels (a traversal stack needs at most `3 * depth + 1` entries).
    pub depth: usize,
}

impl Bvh4 {
    /// Builds the BVH over `boxes` (one per primitive) with leaves of at most `max_leaf` primitives.
    pub fn build(boxes: &[Aabb], quality: BuildQuality, max_leaf: u32) -> Bvh4 {
        let n = boxes.len();
        if n == 0 {
            return Bvh4::default();
        }
        let mut total = Aabb::empty();
        for b in boxes {
            total = total.union(b);
        }
        let bounds = Some((total.min, total.max));
        if n <= 4 {
            let mut node = Node4::default();
            for (k, b) in boxes.iter().enumerate() {
                node.set_child(k, b, leaf_ref(k as u32, 1));
            }
            return Bvh4 { nodes: vec![node], prim_order: (0..n as u32).collect(), bounds, depth: 1 };
        }
        assert!(n < (1 << 27), "too many primitives in one BVH ({n})");
        let bvh2 = build_bvh2(boxes, quality.params(max_leaf), &mut Duration::default());
        let mut out = Bvh4 { nodes: Vec::with_capacity(n / 2), prim_order: Vec::with_capacity(n), bounds, depth: 0 };
        let root = &bvh2.nodes[0];
        if root.is_leaf() {
            let mut node = Node4::default();
            let r = out.emit_leaf(&bvh2, 0);
            node.set_child(0, &root.aabb, r);
            out.nodes.push(node);
        } else {
            out.emit_inner(&bvh2, 0);
        }
        out.depth = out.compute_depth(0);
        out
    }

    fn compute_depth(&self, r: u32) -> usize {
        if r & LEAF_BIT != 0 {
            return 0;
        }
        let n = &self.nodes[r as usize];
        1 + n.child.iter().map(|&c| self.compute_depth(c)).max().unwrap_or(0)
    }

    fn emit_leaf(&mut self, bvh2: &Bvh2, n2: usize) -> u32 {
        let node = &bvh2.nodes[n2];
        let first = self.prim_order.len() as u32;
        let start = node.first_index as usize;
        let count = node.prim_count as usize;
        self.prim_order.extend_from_slice(&bvh2.primitive_indices[start..start + count]);
        // Leaves larger than a reference can describe are split over several references by the
        // caller; obvhs never produces them with our `max_prims_per_leaf`.
        leaf_ref(first, count as u32)
    }

    /// Emits the 4-wide node for binary inner node `n2` and returns its index.
    fn emit_inner(&mut self, bvh2: &Bvh2, n2: usize) -> u32 {
        let first = bvh2.nodes[n2].first_index as usize;
        let mut kids = [first, first + 1, 0, 0];
        let mut len = 2;
        while len < 4 {
            let mut best = None;
            let mut best_area = -1.0f32;
            for (k, &c) in kids[..len].iter().enumerate() {
                let node = &bvh2.nodes[c];
                if !node.is_leaf() {
                    let a = node.aabb.half_area();
                    if a > best_area {
                        best_area = a;
                        best = Some(k);
                    }
                }
            }
            let Some(k) = best else { break };
            let f = bvh2.nodes[kids[k]].first_index as usize;
            kids[k] = f;
            kids[len] = f + 1;
            len += 1;
        }
        let index = self.nodes.len();
        self.nodes.push(Node4::default());
        let mut node = Node4::default();
        for (k, &c) in kids[..len].iter().enumerate() {
            let child = &bvh2.nodes[c];
            let r = if child.is_leaf() { self.emit_leaf(bvh2, c) } else { self.emit_inner(bvh2, c) };
            node.set_child(k, &child.aabb, r);
        }
        self.nodes[index] = node;
        index as u32
    }

    /// Heap bytes held by the nodes and the slot table.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node4>() + self.prim_order.len() * 4
    }

    /// Whether the BVH holds no primitives.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_subtree(bvh: &Bvh4, node: u32, lo: Vec3A, hi: Vec3A, boxes: &[Aabb], seen: &mut [u32]) {
        let n = &bvh.nodes[node as usize];
        for k in 0..4 {
            let r = n.child[k];
            if r == EMPTY_CHILD {
                continue;
            }
            let clo = Vec3A::new(n.min_x[k], n.min_y[k], n.min_z[k]);
            let chi = Vec3A::new(n.max_x[k], n.max_y[k], n.max_z[k]);
            assert!(clo.cmpge(lo).all() && chi.cmple(hi).all());
            if r & LEAF_BIT != 0 {
                let (first, count) = leaf_range(r);
                for s in first..first + count {
                    let p = bvh.prim_order[s as usize] as usize;
                    seen[p] += 1;
                    assert!(boxes[p].min.cmpge(clo).all() && boxes[p].max.cmple(chi).all());
                }
            } else {
                check_subtree(bvh, r, clo, chi, boxes, seen);
            }
        }
    }

    #[test]
    fn every_primitive_in_exactly_one_leaf() {
        for n in [1usize, 3, 4, 5, 17, 1000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|i| {
                    let f = i as f32;
                    let p = Vec3A::new((f * 0.37).sin() * 10.0, (f * 1.3).cos() * 10.0, f * 0.01);
                    Aabb::new(p, p + Vec3A::splat(0.5))
                })
                .collect();
            let bvh = Bvh4::build(&boxes, BuildQuality::Medium, 4);
            let mut seen = vec![0u32; n];
            let inf = Vec3A::splat(f32::INFINITY);
            check_subtree(&bvh, 0, -inf, inf, &boxes, &mut seen);
            assert!(seen.iter().all(|&c| c == 1), "n = {n}");
        }
    }
}

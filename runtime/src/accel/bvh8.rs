//! The 8-wide node layout that single-ray traversal of object BVHs reads, made from a [`Bvh4`].
//!
//! Single-ray traversal is bound by the latency of its node-to-node chain (load, slab test, mask,
//! child reference, next load), so fewer, wider steps make it faster: an 8-wide node holds up to
//! two levels of the 4-wide tree, and a ray takes about two thirds of the steps (s1500k shadow
//! rays: `docs/tracer.md`). Packets keep the 4-wide nodes, whose tests they amortise over 64 rays.
//!
//! Node layout ([`Node8`], 256 bytes, four cache lines): the eight children's boxes in SoA form, as
//! two halves of four (`min_x[half][4]`, ...), so a single ray tests them with two SSE slab tests
//! that run side by side, followed by eight child references in the encoding of [`super::bvh4`].
//!
//! Invariants:
//! - A child reference with [`LEAF_BIT`] clear is the index of an inner `Node8`; with it set, it
//!   is the 4-wide tree's leaf reference unchanged, so leaf slots, `prim_order` and the prepared
//!   triangles are shared with the [`Bvh4`]. Empty children have inverted boxes, as there.
//! - Nodes are in depth-first pre-order from the root (node 0); child boxes contain their subtree.
//! - The leaves of the `Bvh8` are exactly the leaves of the `Bvh4` it was made from.

use super::bvh4::{Bvh4, EMPTY_CHILD, LEAF_BIT};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// An 8-wide BVH node (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node8 {
    /// Child box minima along x, children 0-3 then 4-7.
    pub min_x: [[f32; 4]; 2],
    /// Child box maxima along x.
    pub max_x: [[f32; 4]; 2],
    /// Child box minima along y.
    pub min_y: [[f32; 4]; 2],
    /// Child box maxima along y.
    pub max_y: [[f32; 4]; 2],
    /// Child box minima along z.
    pub min_z: [[f32; 4]; 2],
    /// Child box maxima along z.
    pub max_z: [[f32; 4]; 2],
    /// Child references.
    pub child: [u32; 8],
}

impl Default for Node8 {
    fn default() -> Self {
        let inf = f32::INFINITY;
        Node8 {
            min_x: [[inf; 4]; 2],
            max_x: [[-inf; 4]; 2],
            min_y: [[inf; 4]; 2],
            max_y: [[-inf; 4]; 2],
            min_z: [[inf; 4]; 2],
            max_z: [[-inf; 4]; 2],
            child: [EMPTY_CHILD; 8],
        }
    }
}

/// A child of an 8-wide node under construction: its box (`min`, `max`), its 4-wide reference,
/// its box's half surface area, and for an inner child its number of (non-empty) children.
#[derive(Clone, Copy, Debug)]
struct Kid {
    min: [f32; 3],
    max: [f32; 3],
    reference: u32,
    half_area: f32,
    fan_out: u32,
}

impl Kid {
    const EMPTY: Kid = Kid { min: [0.0; 3], max: [0.0; 3], reference: EMPTY_CHILD, half_area: 0.0, fan_out: 0 };
}

impl Node8 {
    fn set_child(&mut self, k: usize, kid: &Kid, reference: u32) {
        let (h, j) = (k / 4, k % 4);
        self.min_x[h][j] = kid.min[0];
        self.min_y[h][j] = kid.min[1];
        self.min_z[h][j] = kid.min[2];
        self.max_x[h][j] = kid.max[0];
        self.max_y[h][j] = kid.max[1];
        self.max_z[h][j] = kid.max[2];
        self.child[k] = reference;
    }
}

/// An 8-wide BVH over the leaves of a [`Bvh4`] (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct Bvh8 {
    /// Nodes, root first.
    pub nodes: Vec<Node8>,
}

impl Bvh8 {
    /// The 8-wide form of `b4`: each 8-wide node takes a 4-wide node's children, then repeatedly
    /// replaces the inner child of largest surface area whose children still fit by those children.
    ///
    /// Three passes. 1: from the root down (subtrees in parallel), each 8-wide node's choice marks
    /// the 4-wide nodes it opens as absorbed; every other inner 4-wide node heads an 8-wide node.
    /// 2: the heads, taken in the 4-wide (pre-)order, are a depth-first pre-order of the 8-wide
    /// tree (an 8-wide subtree is the heads of one 4-wide subtree, which is contiguous and starts
    /// with its head), so one scan numbers them. 3: each 8-wide node is made on its own, in
    /// parallel, from its head and the absorbed nodes below it.
    pub fn from_bvh4(b4: &Bvh4) -> Bvh8 {
        if b4.nodes.is_empty() {
            return Bvh8::default();
        }
        let widen = Widen { b4, absorbed: (0..b4.nodes.len()).map(|_| AtomicBool::new(false)).collect() };
        widen.mark(0, 0);
        // The 8-wide index of each head (entries of absorbed nodes are never read).
        let mut index8 = vec![u32::MAX; b4.nodes.len()];
        let mut heads = Vec::new();
        for (i, slot) in index8.iter_mut().enumerate() {
            if !widen.is_absorbed(i as u32) {
                *slot = heads.len() as u32;
                heads.push(i as u32);
            }
        }
        let mut nodes = Vec::with_capacity(heads.len());
        heads.par_iter().with_min_len(1024).map(|&i| widen.node(i, &index8)).collect_into_vec(&mut nodes);
        Bvh8 { nodes }
    }

    /// Heap bytes held by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node8>()
    }

    /// Which inner nodes of `b4` head an 8-wide node of [`Bvh8::from_bvh4`]`(b4)` (the others
    /// are opened into an ancestor's 8-wide node), by 4-wide index. A subtree of `b4` headed by
    /// one of them has the same 8-wide nodes, alone or in the whole tree (pass 1 chooses a node's
    /// children from its own subtree).
    pub fn heads(b4: &Bvh4) -> Vec<bool> {
        if b4.nodes.is_empty() {
            return Vec::new();
        }
        let widen = Widen { b4, absorbed: (0..b4.nodes.len()).map(|_| AtomicBool::new(false)).collect() };
        widen.mark(0, 0);
        widen.absorbed.iter().map(|a| !a.load(Ordering::Relaxed)).collect()
    }
}

/// 8-wide nodes less deep than this have their subtrees marked in parallel.
const PARALLEL_DEPTH: u32 = 5;

/// The 4-to-8-wide conversion (see [`Bvh8::from_bvh4`]).
struct Widen<'a> {
    b4: &'a Bvh4,
    /// Whether each 4-wide node is opened into an 8-wide node headed by an ancestor. Atomic only so
    /// that pass 1's parallel tasks can write it: each entry is written by the one task that makes
    /// the choice for its parent's 8-wide node, and read after all tasks have been joined.
    absorbed: Vec<AtomicBool>,
}

impl Widen<'_> {
    fn is_absorbed(&self, i: u32) -> bool {
        self.absorbed[i as usize].load(Ordering::Relaxed)
    }

    /// Pass 1 for the 8-wide subtree headed by 4-wide node `i`, at 8-wide depth `depth`.
    fn mark(&self, i: u32, depth: u32) {
        let (kids, n) = self.kids(i);
        let mut heads = [0u32; 8];
        let mut count = 0;
        for kid in &kids[..n] {
            if kid.reference & LEAF_BIT == 0 {
                heads[count] = kid.reference;
                count += 1;
            }
        }
        if depth < PARALLEL_DEPTH {
            heads[..count].par_iter().for_each(|&h| self.mark(h, depth + 1));
        } else {
            for &h in &heads[..count] {
                self.mark(h, depth + 1);
            }
        }
    }

    /// The 8-wide node headed by 4-wide node `i`, given every head's 8-wide index (after pass 1).
    fn node(&self, i: u32, index8: &[u32]) -> Node8 {
        let mut kids = [Kid::EMPTY; 8];
        let mut n = self.children(i, &mut kids, 0, false);
        let mut k = 0;
        while k < n {
            let r = kids[k].reference;
            if r & LEAF_BIT == 0 && self.is_absorbed(r) {
                kids[k] = kids[n - 1];
                n = self.children(r, &mut kids, n - 1, false);
            } else {
                k += 1;
            }
        }
        let mut node = Node8::default();
        for (k, kid) in kids[..n].iter().enumerate() {
            let reference = if kid.reference & LEAF_BIT != 0 { kid.reference } else { index8[kid.reference as usize] };
            node.set_child(k, kid, reference);
        }
        node
    }

    /// Appends the non-empty children of 4-wide node `i` to `out[..n]`; returns the new length.
    /// `fan_out` is filled in only when `with_fan_out` is set (it costs a load per inner child).
    fn children(&self, i: u32, out: &mut [Kid; 8], mut n: usize, with_fan_out: bool) -> usize {
        let node = &self.b4.nodes[i as usize];
        for k in 0..4 {
            let reference = node.child[k];
            if reference == EMPTY_CHILD {
                continue;
            }
            let (min, max) =
                ([node.min_x[k], node.min_y[k], node.min_z[k]], [node.max_x[k], node.max_y[k], node.max_z[k]]);
            let d = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
            let fan_out = if reference & LEAF_BIT != 0 || !with_fan_out {
                0
            } else {
                self.b4.nodes[reference as usize].child.iter().filter(|&&c| c != EMPTY_CHILD).count() as u32
            };
            out[n] = Kid { min, max, reference, half_area: d[0] * d[1] + d[1] * d[2] + d[2] * d[0], fan_out };
            n += 1;
        }
        n
    }

    /// Pass 1's choice of the children of the 8-wide node headed by 4-wide node `i` (as 4-wide
    /// references); the 4-wide nodes opened are marked absorbed.
    fn kids(&self, i: u32) -> ([Kid; 8], usize) {
        let mut kids = [Kid::EMPTY; 8];
        let mut n = self.children(i, &mut kids, 0, true);
        loop {
            let mut best = None;
            let mut best_area = -1.0f32;
            for (k, kid) in kids[..n].iter().enumerate() {
                if kid.fan_out > 0 && n - 1 + kid.fan_out as usize <= 8 && kid.half_area > best_area {
                    best_area = kid.half_area;
                    best = Some(k);
                }
            }
            let Some(k) = best else { break };
            let opened = kids[k].reference;
            self.absorbed[opened as usize].store(true, Ordering::Relaxed);
            kids[k] = kids[n - 1];
            n = self.children(opened, &mut kids, n - 1, true);
        }
        (kids, n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh4::{leaf_range, BuildQuality};
    use glam::Vec3A;
    use obvhs::aabb::Aabb;

    /// Boxes scattered in a pseudo-random, deterministic way (a different mix of sizes than the
    /// 4-wide tests', so that some subtrees are deep and some shallow).
    fn boxes(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let f = i as f32;
                let p = Vec3A::new((f * 0.71).sin() * 20.0, (f * 0.13).cos() * 5.0, (f * 2.9).sin() * f.sqrt());
                Aabb::new(p, p + Vec3A::new(0.2, 0.5 + (f * 0.05).sin().abs(), 0.3))
            })
            .collect()
    }

    /// Walks the subtree of 8-wide node `node`, whose box is `lo..hi`: checks containment and the
    /// pre-order, counts each primitive's leaf slots in `seen`, and returns the leaf references.
    fn walk(b8: &Bvh8, b4: &Bvh4, node: u32, lo: Vec3A, hi: Vec3A, seen: &mut [u32], leaves: &mut Vec<u32>) {
        let n = &b8.nodes[node as usize];
        for k in 0..8 {
            let (h, j) = (k / 4, k % 4);
            let r = n.child[k];
            if r == EMPTY_CHILD {
                assert!(n.min_x[h][j] > n.max_x[h][j], "empty children have inverted boxes");
                continue;
            }
            let clo = Vec3A::new(n.min_x[h][j], n.min_y[h][j], n.min_z[h][j]);
            let chi = Vec3A::new(n.max_x[h][j], n.max_y[h][j], n.max_z[h][j]);
            assert!(clo.cmpge(lo).all() && chi.cmple(hi).all(), "a child box sticks out of its parent's");
            if r & LEAF_BIT != 0 {
                leaves.push(r);
                let (first, count) = leaf_range(r);
                for s in first..first + count {
                    seen[b4.prim_order[s as usize] as usize] += 1;
                }
            } else {
                assert!(r > node && (r as usize) < b8.nodes.len(), "children follow their parent");
                walk(b8, b4, r, clo, chi, seen, leaves);
            }
        }
    }

    fn leaves4(b4: &Bvh4) -> Vec<u32> {
        let mut out: Vec<u32> =
            b4.nodes.iter().flat_map(|n| n.child).filter(|&c| c & LEAF_BIT != 0 && c != EMPTY_CHILD).collect();
        out.sort_unstable();
        out
    }

    #[test]
    fn has_the_leaves_of_the_4_wide_tree_each_once_with_containing_boxes() {
        for n in [1usize, 2, 4, 5, 9, 40, 1000, 25_000] {
            let input = boxes(n);
            for (quality, max_leaf) in [(BuildQuality::Fast, 1), (BuildQuality::High, 2), (BuildQuality::Best, 4)] {
                let b4 = Bvh4::build(&input, quality, max_leaf);
                let b8 = Bvh8::from_bvh4(&b4);
                let mut seen = vec![0u32; n];
                let mut leaves = Vec::new();
                let inf = Vec3A::splat(f32::INFINITY);
                walk(&b8, &b4, 0, -inf, inf, &mut seen, &mut leaves);
                assert!(seen.iter().all(|&c| c == 1), "n = {n}: every primitive in exactly one leaf");
                leaves.sort_unstable();
                assert_eq!(leaves, leaves4(&b4), "n = {n}: the same leaves as the 4-wide tree");
                for (i, p) in input.iter().enumerate() {
                    // Primitive boxes are inside the leaf boxes (checked through `walk`'s
                    // containment down to the leaf, and here against the root).
                    let (lo, hi) = b4.bounds.expect("non-empty input has bounds");
                    assert!(p.min.cmpge(lo).all() && p.max.cmple(hi).all(), "box {i}");
                }
                // Every 8-wide node is reached once from the root: no orphans, no sharing.
                let mut parents = vec![0u32; b8.nodes.len()];
                parents[0] = 1;
                for node in &b8.nodes {
                    for &c in node.child.iter().filter(|&&c| c & LEAF_BIT == 0) {
                        parents[c as usize] += 1;
                    }
                }
                assert!(parents.iter().all(|&p| p == 1), "n = {n}: each node has one parent");
                if n >= 1000 {
                    // Wider nodes: markedly fewer of them (about half on real meshes).
                    assert!(b8.nodes.len() * 10 < b4.nodes.len() * 7, "{} vs {}", b8.nodes.len(), b4.nodes.len());
                }
            }
        }
    }

    #[test]
    fn an_empty_tree_stays_empty() {
        let b8 = Bvh8::from_bvh4(&Bvh4::default());
        assert!(b8.nodes.is_empty());
        assert_eq!(b8.memory_bytes(), 0);
    }
}

//! The 8-wide node layout that single-ray traversal of object BVHs reads, made from a [`Bvh4`].
//!
//! Single-ray traversal is bound by the latency of its node-to-node chain (load, slab test, mask,
//! child reference, next load), so fewer, wider steps make it faster. The 8-wide tree is collapsed
//! from the binary tree the 4-wide one was collapsed from, rebuilt from the 4-wide nodes' shape
//! codes ([`Node4::shape`]), so that it is a function of the 4-wide tree alone (which is what
//! travels between processes) and yet groups the binary nodes of largest area, as a collapse
//! straight from the binary tree does (`docs/tracer.md`). Packets keep the 4-wide nodes, whose
//! tests they amortise over 64 rays.
//!
//! Node layout ([`Node8`], 256 bytes, four cache lines): the eight children's boxes in SoA form, as
//! two halves of four (`min_x[half][4]`, ...), so a single ray tests them with two SSE slab tests
//! that run side by side, followed by eight child references in the encoding of [`super::bvh4`].
//!
//! Invariants:
//! - A child reference with [`LEAF_BIT`] clear is the index of an inner `Node8`; with it set, it
//!   is the 4-wide tree's leaf reference unchanged, so leaf slots, `prim_order` and the prepared
//!   triangles are shared with the [`Bvh4`]. Empty children have inverted boxes, as there.
//! - The root is node 0 and nodes are in depth-first pre-order, so every node's children come
//!   after it; child boxes contain their subtree.
//! - The leaves of the `Bvh8` are exactly the leaves of the `Bvh4` it was made from.

use super::bvh4::{Bvh4, Node4, EMPTY_CHILD, LEAF_BIT};
use rayon::prelude::*;
use std::mem::MaybeUninit;
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

/// A binary node of the tree a [`Bvh4`] was collapsed from, as its [`Node4::shape`] codes let
/// it be rebuilt: a leaf reference, or local binary node `local` of 4-wide node `node` (0: the
/// node itself; 1 and 2: the children it opened, in order), whose own box and children come from
/// the 4-wide node.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Binary {
    Leaf(u32),
    Inner { node: u32, local: u8 },
}

/// Where one of a local binary node's two children is: another local node, or a child position of
/// the 4-wide node.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Side {
    Local(u8),
    Position(u8),
}

/// The local binary tree a shape code describes (see [`super::bvh4::shape_code`]): each local
/// node's two children (local node 0 is the 4-wide node itself), and how many children the
/// 4-wide node has; a length of 0 for a code that describes none.
const fn decode_shape(code: u32) -> ([[Side; 2]; 3], usize) {
    let len = (code & 3) as usize + 1;
    let opened = [(code >> 2 & 1) as usize, (code >> 3 & 3) as usize];
    let mut sides = [[Side::Position(0), Side::Position(1)]; 3];
    if code >> 5 != 0 || len < 2 || (len >= 4 && opened[1] >= 3) {
        return (sides, 0);
    }
    // Where each position's child hangs: (local node, side).
    let mut at = [(0usize, 0usize), (0, 1), (0, 0), (0, 0)];
    let mut j = 0;
    while j + 2 < len {
        let (p, local, new) = (opened[j], j + 1, j + 2);
        let (parent, side) = at[p];
        sides[parent][side] = Side::Local(local as u8);
        sides[local] = [Side::Position(p as u8), Side::Position(new as u8)];
        at[p] = (local, 0);
        at[new] = (local, 1);
        j += 1;
    }
    (sides, len)
}

/// A 4-wide node's local binary tree, decoded from its shape code: each local node's two
/// children, and the positions under each local node (bit `k` for position `k`).
#[derive(Clone, Copy, Debug)]
struct Shape {
    sides: [[Side; 2]; 3],
    under: [u8; 3],
    len: usize,
}

/// [`decode_shape`] of every code of five bits, with the positions under each local node.
const SHAPES: [Shape; 32] = {
    let mut table = [Shape { sides: [[Side::Position(0), Side::Position(0)]; 3], under: [0; 3], len: 0 }; 32];
    let mut code = 0;
    while code < 32 {
        let (sides, len) = decode_shape(code as u32);
        let mut under = [0u8; 3];
        // Local node `l`'s children are positions or later local nodes: fill from the last.
        let mut l = 3;
        while l > 0 {
            l -= 1;
            let mut side = 0;
            while side < 2 {
                under[l] |= match sides[l][side] {
                    Side::Position(k) => 1 << k,
                    Side::Local(c) => under[c as usize],
                };
                side += 1;
            }
        }
        table[code] = Shape { sides, under, len };
        code += 1;
    }
    table
};

/// The binary structure of a 4-wide node's children that its shape code describes. `None` where
/// the code does not fit the node's children (unknown, or damaged): the children are then one
/// flat set under local node 0.
#[inline(always)]
fn local_tree(node: &Node4) -> Option<&'static Shape> {
    let shape = SHAPES.get(node.shape as usize)?;
    let filled = node.child.map(|c| c != EMPTY_CHILD);
    let fits = shape.len >= 2 && (0..4).all(|k| filled[k] == (k < shape.len));
    fits.then_some(shape)
}

/// A child of an 8-wide node under construction: the binary node, its box, and its claim to be
/// opened: its box's half surface area if it is an inner node (not yet found too wide to open),
/// else below 0.
#[derive(Clone, Copy, Debug)]
struct Kid {
    binary: Binary,
    min: [f32; 3],
    max: [f32; 3],
    claim: f32,
}

impl Kid {
    const EMPTY: Kid = Kid { binary: Binary::Leaf(EMPTY_CHILD), min: [0.0; 3], max: [0.0; 3], claim: -1.0 };

    fn new(binary: Binary, min: [f32; 3], max: [f32; 3]) -> Kid {
        let d = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
        let half_area = d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
        let claim = match binary {
            Binary::Inner { .. } if half_area >= 0.0 => half_area,
            _ => -1.0,
        };
        Kid { binary, min, max, claim }
    }
}

impl Node8 {
    /// Sets the children of an empty node to `kids`; inner children's references are left at 0.
    fn set_children(&mut self, kids: &[Kid]) {
        for (k, kid) in kids.iter().enumerate() {
            let reference = match kid.binary {
                Binary::Leaf(r) => r,
                Binary::Inner { .. } => 0,
            };
            self.set_child(k, kid, reference);
        }
    }

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
    /// The 8-wide form of `b4`: the binary tree `b4` was collapsed from is rebuilt from its nodes'
    /// shape codes, and collapsed again, eight children to a node: each 8-wide node starts with its
    /// binary node's two children, then repeatedly opens the inner child of largest surface area
    /// (as Embree collapses its binary trees), until it has eight or only leaves.
    ///
    /// Nodes come in depth-first pre-order, children in the order they were chosen. The top levels'
    /// subtrees are made in parallel, each into a [`Piece`] of its own, and the pieces are then
    /// copied into place, also in parallel; the order is the same with any number of threads.
    pub fn from_bvh4(b4: &Bvh4) -> Bvh8 {
        if b4.nodes.is_empty() {
            return Bvh8::default();
        }
        let widen = Widen { b4 };
        let root = Binary::Inner { node: 0, local: 0 };
        // One thread makes the same tree in one piece, which needs no copying.
        let depth = if rayon::current_num_threads() > 1 { parallel_depth(b4.nodes.len()) } else { 0 };
        let piece = widen.piece(root, depth, b4.nodes.len());
        if piece.subs.is_empty() {
            return Bvh8 { nodes: piece.nodes };
        }
        let mut nodes = Vec::with_capacity(piece.size);
        place(&piece, &mut nodes.spare_capacity_mut()[..piece.size], 0);
        // SAFETY: `place` wrote all of the first `piece.size` elements (each piece writes its own
        // nodes and splits the rest of its slice among its sub-pieces by their sizes, which add up
        // to the piece's size).
        unsafe { nodes.set_len(piece.size) };
        Bvh8 { nodes }
    }

    /// Heap bytes held by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node8>()
    }

    /// Which inner nodes of `b4` head an 8-wide node of [`Bvh8::from_bvh4`]`(b4)` (the others
    /// are opened into an ancestor's 8-wide node), by 4-wide index. A subtree of `b4` headed by
    /// one of them has the same 8-wide nodes, alone or in the whole tree (a node's children are
    /// chosen from its own subtree, and a child left unopened would not have been chosen had it
    /// been a leaf).
    pub fn heads(b4: &Bvh4) -> Vec<bool> {
        if b4.nodes.is_empty() {
            return Vec::new();
        }
        let heads: Vec<AtomicBool> = (0..b4.nodes.len()).map(|_| AtomicBool::new(false)).collect();
        heads[0].store(true, Ordering::Relaxed);
        Widen { b4 }.mark(Binary::Inner { node: 0, local: 0 }, &heads, parallel_depth(b4.nodes.len()));
        heads.into_iter().map(AtomicBool::into_inner).collect()
    }
}

/// About how many 4-wide nodes a parallel task of the conversion covers, at least.
const PIECE_NODES4: usize = 256;

/// How many levels of 8-wide nodes have their subtrees made in parallel, for a tree of `nodes4`
/// 4-wide nodes: enough for about one task for every [`PIECE_NODES4`] nodes (8-wide nodes near
/// the root have up to eight inner children).
fn parallel_depth(nodes4: usize) -> u32 {
    let mut depth = 0;
    while depth < 6 && PIECE_NODES4 << (3 * (depth + 1)) <= nodes4 {
        depth += 1;
    }
    depth
}

/// A subtree of the 8-wide tree made by one task: its first nodes in pre-order, with inner child
/// references counted from the piece's first node, followed by the pieces other tasks made (only
/// where the first node is the piece's only node), each with the slot of the first node's child
/// that refers to it (whose reference `place` sets), in pre-order.
struct Piece {
    nodes: Vec<Node8>,
    subs: Vec<(usize, Piece)>,
    /// Nodes in the piece and its sub-pieces.
    size: usize,
}

/// Copies `piece` into `out` (exactly its size), whose first element will be node `base` of the
/// whole tree; sub-pieces in parallel.
fn place(piece: &Piece, out: &mut [MaybeUninit<Node8>], base: u32) {
    let (mine, mut rest) = out.split_at_mut(piece.nodes.len());
    for (dst, node) in mine.iter_mut().zip(&piece.nodes) {
        let mut node = *node;
        for c in &mut node.child {
            if *c & LEAF_BIT == 0 {
                *c += base;
            }
        }
        dst.write(node);
    }
    let mut offset = base + piece.nodes.len() as u32;
    let mut jobs = Vec::with_capacity(piece.subs.len());
    for (slot, sub) in &piece.subs {
        // SAFETY: `mine` was written in full by the loop above.
        unsafe { mine[0].assume_init_mut() }.child[*slot] = offset;
        let (theirs, after) = std::mem::take(&mut rest).split_at_mut(sub.size);
        rest = after;
        jobs.push((sub, theirs, offset));
        offset += sub.size as u32;
    }
    jobs.into_par_iter().for_each(|(sub, out, base)| place(sub, out, base));
}

/// The 4-to-8-wide conversion (see [`Bvh8::from_bvh4`]).
struct Widen<'a> {
    b4: &'a Bvh4,
}

impl Widen<'_> {
    /// The 8-wide subtree headed by binary node `head`, with the subtrees of its children made
    /// in parallel while `parallel_depth` is above 0. `nodes4` is about how many 4-wide nodes
    /// it covers.
    fn piece(&self, head: Binary, parallel_depth: u32, nodes4: usize) -> Piece {
        if parallel_depth == 0 {
            // 8-wide nodes are about two thirds as many as 4-wide ones.
            let mut nodes = Vec::with_capacity(nodes4 / 4 * 3 + 1);
            self.grow(head, &mut nodes);
            return Piece { size: nodes.len(), nodes, subs: Vec::new() };
        }
        let mut nodes = vec![Node8::default()];
        let mut kids = [Kid::EMPTY; 8];
        let n = self.kids(head, &mut kids);
        nodes[0].set_children(&kids[..n]);
        let inner: Vec<(usize, Binary)> = kids[..n]
            .iter()
            .enumerate()
            .filter(|(_, kid)| matches!(kid.binary, Binary::Inner { .. }))
            .map(|(k, kid)| (k, kid.binary))
            .collect();
        let share = nodes4 / inner.len().max(1);
        let subs: Vec<(usize, Piece)> =
            inner.into_par_iter().map(|(k, b)| (k, self.piece(b, parallel_depth - 1, share))).collect();
        let size = 1 + subs.iter().map(|(_, p)| p.size).sum::<usize>();
        Piece { nodes, subs, size }
    }

    /// Appends the 8-wide subtree headed by binary node `head` to `out`, in pre-order, with inner
    /// references counted from `out`'s first node.
    fn grow(&self, head: Binary, out: &mut Vec<Node8>) {
        let me = out.len();
        let mut kids = [Kid::EMPTY; 8];
        let n = self.kids(head, &mut kids);
        out.push(Node8::default());
        out[me].set_children(&kids[..n]);
        for (k, kid) in kids[..n].iter().enumerate() {
            if let Binary::Inner { .. } = kid.binary {
                out[me].child[k] = out.len() as u32;
                self.grow(kid.binary, out);
            }
        }
    }

    /// Marks in `heads` the 4-wide nodes that head an 8-wide node in the subtree headed by binary
    /// node `head` (see [`Bvh8::heads`]).
    fn mark(&self, head: Binary, heads: &[AtomicBool], parallel_depth: u32) {
        let mut kids = [Kid::EMPTY; 8];
        let n = self.kids(head, &mut kids);
        let inner = kids[..n].iter().filter_map(|kid| match kid.binary {
            Binary::Inner { node, local } => Some((node, local)),
            Binary::Leaf(_) => None,
        });
        let inner: Vec<(u32, u8)> = inner.collect();
        let visit = |&(node, local): &(u32, u8)| {
            if local == 0 {
                heads[node as usize].store(true, Ordering::Relaxed);
            }
            self.mark(Binary::Inner { node, local }, heads, parallel_depth.saturating_sub(1));
        };
        if parallel_depth > 0 {
            inner.par_iter().for_each(visit);
        } else {
            inner.iter().for_each(visit);
        }
    }

    /// The children of the 8-wide node headed by binary node `head`: its children, then
    /// repeatedly the inner one of largest surface area (the first of them on a tie) whose
    /// children still fit replaced by them, the last child moving into its place.
    /// They are written to `kids` (all of whose entries are [`Kid::EMPTY`]); returns how many.
    fn kids(&self, head: Binary, kids: &mut [Kid; 8]) -> usize {
        let mut n = self.append_children(head, kids, 0);
        loop {
            let (k, best) = first_largest(kids);
            if best < 0.0 {
                break;
            }
            // A node without children (only in a damaged tree) stays rather than vanish.
            let count = self.child_count(kids[k].binary);
            if count == 0 || n - 1 + count > 8 {
                kids[k].claim = -1.0;
                continue;
            }
            let opened = kids[k].binary;
            kids[k] = kids[n - 1];
            kids[n - 1] = Kid::EMPTY;
            n = self.append_children(opened, kids, n - 1);
        }
        n
    }

    /// How many children binary node `b` has (2, or a flat node's children).
    fn child_count(&self, b: Binary) -> usize {
        match b {
            Binary::Leaf(_) => 0,
            Binary::Inner { node, local } => {
                let n4 = &self.b4.nodes[node as usize];
                match local_tree(n4) {
                    Some(_) => 2,
                    None if local == 0 => n4.child.iter().filter(|&&c| c != EMPTY_CHILD).count(),
                    None => 0,
                }
            }
        }
    }

    /// Appends the children of binary node `b` to `out[..n]`; returns the new length.
    #[inline(always)]
    fn append_children(&self, b: Binary, out: &mut [Kid; 8], mut n: usize) -> usize {
        let Binary::Inner { node, local } = b else { return n };
        let n4 = &self.b4.nodes[node as usize];
        let mut push = |kid: Kid| {
            if n < 8 {
                out[n] = kid;
                n += 1;
            }
        };
        let position = |k: usize| -> Kid {
            let (min, max) = ([n4.min_x[k], n4.min_y[k], n4.min_z[k]], [n4.max_x[k], n4.max_y[k], n4.max_z[k]]);
            let r = n4.child[k];
            let binary = if r & LEAF_BIT != 0 {
                Binary::Leaf(r)
            } else {
                // Its node is read when it is opened or heads a node: start loading it.
                super::prefetch(self.b4.nodes.as_ptr().wrapping_add(r as usize), 2);
                Binary::Inner { node: r, local: 0 }
            };
            Kid::new(binary, min, max)
        };
        match local_tree(n4) {
            Some(shape) => {
                for side in shape.sides[local as usize] {
                    push(match side {
                        Side::Position(k) => position(k as usize),
                        Side::Local(l) => {
                            let (min, max) = union_of_positions(n4, shape.under[l as usize]);
                            Kid::new(Binary::Inner { node, local: l }, min, max)
                        }
                    });
                }
            }
            None if local == 0 => {
                for k in (0..4).filter(|&k| n4.child[k] != EMPTY_CHILD) {
                    push(position(k));
                }
            }
            None => {}
        }
        n
    }
}

/// The index and claim of the first of the kids with the largest claim, found by comparing pairs,
/// then pairs of winners (a chain three comparisons long rather than seven).
#[inline(always)]
fn first_largest(kids: &[Kid; 8]) -> (usize, f32) {
    let pick = |a: (usize, f32), b: (usize, f32)| if b.1 > a.1 { b } else { a };
    let c = |k: usize| (k, kids[k].claim);
    let (a, b) = (pick(c(0), c(1)), pick(c(2), c(3)));
    let (d, e) = (pick(c(4), c(5)), pick(c(6), c(7)));
    pick(pick(a, b), pick(d, e))
}

/// The union of the stored boxes of `n4`'s positions in `mask` (bit `k` for position `k`).
fn union_of_positions(n4: &Node4, mask: u8) -> ([f32; 3], [f32; 3]) {
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for k in (0..4).filter(|&k| mask >> k & 1 != 0) {
        let (lo, hi) = ([n4.min_x[k], n4.min_y[k], n4.min_z[k]], [n4.max_x[k], n4.max_y[k], n4.max_z[k]]);
        for a in 0..3 {
            min[a] = min[a].min(lo[a]);
            max[a] = max[a].max(hi[a]);
        }
    }
    (min, max)
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
                    // Wider nodes: fewer of them (two thirds on the synthetic scenes, three
                    // quarters here with leaves of one; binary nodes left unopened under full nodes
                    // head small ones).
                    assert!(b8.nodes.len() * 5 < b4.nodes.len() * 4, "{} vs {}", b8.nodes.len(), b4.nodes.len());
                }
            }
        }
    }

    /// The nodes are in depth-first pre-order (children in slot order), and the same tree comes
    /// out with any number of threads: every process that receives a 4-wide tree must traverse
    /// the same 8-wide one.
    #[test]
    fn nodes_are_in_pre_order_whatever_the_threads() {
        let b4 = Bvh4::build(&boxes(60_000), BuildQuality::High, 1);
        assert!(parallel_depth(b4.nodes.len()) >= 2, "large enough to be made in pieces");
        let with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
            pool.install(|| Bvh8::from_bvh4(&b4))
        };
        let one = with(1);
        let mut order = Vec::new();
        let mut stack = vec![0u32];
        while let Some(node) = stack.pop() {
            order.push(node);
            let inner = one.nodes[node as usize].child.iter().filter(|&&c| c & LEAF_BIT == 0);
            stack.extend(inner.rev());
        }
        assert!(order.iter().copied().eq(0..one.nodes.len() as u32), "pre-order");
        for threads in [2, 3, 8] {
            assert!(with(threads).nodes == one.nodes, "{threads} threads");
        }
    }

    /// Each shape code [`shape_code`] gives decodes to the binary tree `kids_of`'s openings made:
    /// for every history of openings, the positions under each local node are those the openings
    /// put there (an opened node keeps its left child's position and adds the next one, and
    /// later openings of positions under it add theirs).
    #[test]
    fn shape_codes_decode_to_the_binary_trees_they_came_from() {
        use crate::accel::bvh4::shape_code;
        let mut histories = vec![(2, [0, 0])];
        histories.extend((0..2).map(|p| (3, [p, 0])));
        histories.extend((0..2).flat_map(|p| (0..3).map(move |q| (4, [p, q]))));
        for (len, opened) in histories {
            // The positions under each opened node (and the root): its own two, recursively.
            let (sides, decoded_len) = decode_shape(shape_code(len, opened));
            assert_eq!(decoded_len, len);
            let under = |l: u8| -> Vec<usize> {
                let mut out = Vec::new();
                let mut todo = vec![l];
                while let Some(l) = todo.pop() {
                    for side in sides[l as usize] {
                        match side {
                            Side::Position(k) => out.push(k as usize),
                            Side::Local(c) => todo.push(c),
                        }
                    }
                }
                out.sort_unstable();
                out
            };
            assert_eq!(under(0), (0..len).collect::<Vec<_>>(), "{len} {opened:?}");
            // Opened node j (local j + 1) covers its left position and everything later opened
            // under it, and its right position.
            for (j, &p) in opened[..len - 2].iter().enumerate() {
                let mut want = vec![p, j + 2];
                for (later, &q) in opened[..len - 2].iter().enumerate().skip(j + 1) {
                    if want.contains(&q) {
                        want.push(later + 2);
                    }
                }
                want.sort_unstable();
                assert_eq!(under(j as u8 + 1), want, "{len} {opened:?}, opening {j}");
            }
        }
    }

    /// Whatever shape codes the nodes carry (a damaged or foreign tree), the 8-wide form has the
    /// 4-wide tree's leaves, each once, under boxes that contain them.
    #[test]
    fn any_shape_codes_keep_the_leaves() {
        let input = boxes(3000);
        let mut b4 = Bvh4::build(&input, BuildQuality::High, 4);
        let mut h = 0x9e37_79b9u32;
        for node in &mut b4.nodes {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            node.shape = h % 40;
        }
        let b8 = Bvh8::from_bvh4(&b4);
        let mut seen = vec![0u32; input.len()];
        let mut leaves = Vec::new();
        let inf = Vec3A::splat(f32::INFINITY);
        walk(&b8, &b4, 0, -inf, inf, &mut seen, &mut leaves);
        assert!(seen.iter().all(|&c| c == 1));
        leaves.sort_unstable();
        assert_eq!(leaves, leaves4(&b4));
    }

    /// A tree as deep as a worker accepts ([`super::super::wire::MAX_WIRE_DEPTH`]), of flat nodes
    /// (four children, one of them inner: the 8-wide nodes can open few of them) and of nodes whose
    /// local binary trees nest three deep, converts on a pool's threads (whose stacks are smaller
    /// than the main thread's), every leaf once, in pre-order.
    #[test]
    fn the_deepest_accepted_tree_converts_on_pool_threads() {
        use crate::accel::bvh4::{leaf_ref, shape_code};
        use crate::accel::wire::MAX_WIRE_DEPTH;
        for shape in [0, shape_code(4, [0, 0])] {
            let levels = MAX_WIRE_DEPTH;
            let mut nodes = Vec::with_capacity(levels);
            let mut slot = 0;
            for i in 0..levels {
                let mut node = Node4 { shape, ..Node4::default() };
                for k in 0..4 {
                    let f = i as f32;
                    let (lo, hi) = (f + k as f32 * 0.1, levels as f32 + 1.0 - f);
                    (node.min_x[k], node.min_y[k], node.min_z[k]) = (lo, lo, lo);
                    (node.max_x[k], node.max_y[k], node.max_z[k]) = (hi, hi, hi);
                    node.child[k] = if k == 0 && i + 1 < levels {
                        i as u32 + 1
                    } else {
                        slot += 1;
                        leaf_ref(slot - 1, 1)
                    };
                }
                nodes.push(node);
            }
            let b4 = Bvh4 { nodes, prim_order: (0..slot).collect(), bounds: None, depth: levels };
            let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool");
            let b8 = pool.install(|| Bvh8::from_bvh4(&b4));
            let mut leaves: Vec<u32> =
                b8.nodes.iter().flat_map(|n| n.child).filter(|&c| c & LEAF_BIT != 0 && c != EMPTY_CHILD).collect();
            leaves.sort_unstable();
            assert_eq!(leaves, leaves4(&b4), "shape {shape}");
            for (i, node) in b8.nodes.iter().enumerate() {
                assert!(node.child.iter().all(|&c| c & LEAF_BIT != 0 || c as usize > i), "children after parents");
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

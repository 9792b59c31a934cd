//! The 4-wide BVH node layout that both traversal paths read, and its construction from a binary
//! BVH.
//!
//! A binary BVH is built by binned SAH ([`super::binned`]) or obvhs's PLOC (the fastest qualities),
//! optionally improved by obvhs's reinsertion; [`Bvh4::build`] then collapses it (obvhs's leaf
//! collapse rule) into 4-wide nodes by repeatedly opening the child with the largest surface area, and
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
    bvh2::{node::Bvh2Node, reinsertion::ReinsertionOptimizer, Bvh2},
    ploc::{PlocBuilder, PlocSearchDistance, SortPrecision},
    BvhBuildParams,
};
use std::mem::MaybeUninit;

/// Marks a child reference as a leaf.
pub const LEAF_BIT: u32 = 1 << 31;
/// The reference of an empty child slot.
pub const EMPTY_CHILD: u32 = LEAF_BIT;
/// Largest number of primitives in one leaf.
pub const MAX_LEAF_SIZE: u32 = 15;
/// A leaf slot that holds no primitive: the unused slots of a block ([`LeafSlots::Blocks`]).
pub const NO_PRIMITIVE: u32 = u32::MAX;

/// How the leaves of a 4-wide BVH take their slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafSlots {
    /// As many as the leaf's primitives, leaf after leaf in depth-first order; a leaf reference
    /// holds its first slot.
    Packed,
    /// A block of this many each (the unused ones [`NO_PRIMITIVE`]), leaves of at most as many
    /// primitives: the `b`-th leaf in depth-first order holds slots `width * b ..`, and its
    /// reference holds `b`.
    Blocks(u32),
}

impl LeafSlots {
    /// How many primitives a leaf tests at once: its block's width, or 1 where leaves are packed.
    pub fn block_width(self) -> u32 {
        match self {
            LeafSlots::Packed => 1,
            LeafSlots::Blocks(width) => width.clamp(1, MAX_LEAF_SIZE),
        }
    }
}

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
    /// How the children came from the binary BVH the node was collapsed from ([`shape_code`]),
    /// which the 8-wide form follows; 0 where that is not known (the children are then taken as
    /// they are). In the node's padding: it does not make the node larger.
    pub shape: u32,
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
            shape: 0,
        }
    }
}

/// The shape code of a 4-wide node whose `len` children (2 to 4) came from a binary node by
/// [`kids_of`]: its two children in positions 0 and 1, then `opened[0]` opened (its left child
/// stays in its position, its right child goes to position 2), then `opened[1]` likewise (right
/// child to position 3). Bits 0-1: `len - 1`; bit 2: `opened[0]`; bits 3-4: `opened[1]`.
pub(crate) fn shape_code(len: usize, opened: [usize; 2]) -> u32 {
    (len as u32 - 1) | (opened[0] as u32) << 2 | (opened[1] as u32) << 3
}

impl Node4 {
    /// The box around the children's stored boxes.
    pub(crate) fn children_bounds(&self) -> (Vec3A, Vec3A) {
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for k in (0..4).filter(|&k| self.child[k] != EMPTY_CHILD) {
            lo = lo.min(Vec3A::new(self.min_x[k], self.min_y[k], self.min_z[k]));
            hi = hi.max(Vec3A::new(self.max_x[k], self.max_y[k], self.max_z[k]));
        }
        (lo, hi)
    }

    /// Stores child `k`: box `b` grown outward by [`below`] and [`above`], so that a ray with no
    /// direction along an axis that lies exactly in the plane of a face across it still enters.
    fn set_child(&mut self, k: usize, b: &Aabb, child: u32) {
        self.min_x[k] = below(b.min.x);
        self.min_y[k] = below(b.min.y);
        self.min_z[k] = below(b.min.z);
        self.max_x[k] = above(b.max.x);
        self.max_y[k] = above(b.max.y);
        self.max_z[k] = above(b.max.z);
        self.child[k] = child;
    }
}

/// How far a stored box face lies outward of the geometry's bound: a share of the coordinate's
/// magnitude (at least two units in its last place), and at least [`FACE_MARGIN_MIN`].
///
/// Why: a direction component below `1e-30` is clamped to that (`safe_inv`), so a ray with none
/// along an axis moves across it by `1e-30` per unit of distance. Lying exactly in a face's plane,
/// it would leave the slab at distance 0 and miss the box, while the triangle test, which has no
/// such clamp, can hit an edge or corner in that face. With the face moved out by `m`, the ray
/// leaves at `m * 1e30` or later: beyond any distance a hit can have while `m` is at least
/// [`FACE_MARGIN_MIN`] (`5e10`) or the coordinate's share (`2.4e23` times the coordinate).
const FACE_MARGIN: f32 = 1.0 / (1u32 << 22) as f32;

/// The least margin of a face (`2^-64`), for faces at or near 0 (see [`FACE_MARGIN`]).
const FACE_MARGIN_MIN: f32 = 1.0 / (1u64 << 63) as f32 / 2.0;

/// A box minimum moved outward (see [`FACE_MARGIN`]); monotonic, so that a child's stored box
/// stays inside its parent's.
#[inline]
fn below(x: f32) -> f32 {
    if x > 0.0 {
        x * (1.0 - FACE_MARGIN) - FACE_MARGIN_MIN
    } else {
        x * (1.0 + FACE_MARGIN) - FACE_MARGIN_MIN
    }
}

/// A box maximum moved outward (see [`below`]).
#[inline]
fn above(x: f32) -> f32 {
    -below(-x)
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

/// How much effort to spend on BVH quality. Every level builds a binary BVH with leaves of one
/// primitive (no spatial pre-splits: leaves must own their primitives) and collapses it in
/// [`Bvh4::from_bvh2`]. Measured in `docs/tracer.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildQuality {
    /// Fastest build (large per-frame top-level BVHs): obvhs's PLOC, search radius 1, no
    /// reinsertion.
    Fast,
    /// PLOC search radius 1 and reinsertion of 1% of the nodes.
    Medium,
    /// The default: top-down binned SAH ([`super::binned`]), whose trees cost less to traverse than
    /// PLOC's at any search radius, built in about the time of PLOC at radius 2.
    High,
    /// For static geometry: binned SAH, then reinsertion of 8% of the nodes (a little better
    /// trees for several times `High`'s build time on large inputs).
    Best,
}

impl BuildQuality {
    /// Whether this quality builds by binned SAH ([`super::binned`]) rather than PLOC.
    pub fn is_binned(self) -> bool {
        matches!(self, BuildQuality::High | BuildQuality::Best)
    }

    /// The obvhs parameters of this quality for leaves of at most `max_leaf` primitives (the
    /// search radius is PLOC's, which the binned qualities do not use).
    pub fn params(self, max_leaf: u32) -> BvhBuildParams {
        let (distance, reinsertion) = match self {
            BuildQuality::Fast => (PlocSearchDistance::Minimum, 0.0),
            BuildQuality::Medium => (PlocSearchDistance::Minimum, 0.01),
            BuildQuality::High => (PlocSearchDistance::VeryLow, 0.0),
            BuildQuality::Best => (PlocSearchDistance::VeryLow, 0.08),
        };
        BvhBuildParams {
            pre_split: false,
            ploc_search_distance: distance,
            // The search radius is used at every depth.
            search_depth_threshold: 0,
            reinsertion_batch_ratio: reinsertion,
            post_collapse_reinsertion_batch_ratio_multiplier: 0.0,
            sort_precision: SortPrecision::U64,
            max_prims_per_leaf: max_leaf.clamp(1, MAX_LEAF_SIZE),
            collapse_traversal_cost: 3.0,
        }
    }
}

/// obvhs's binary BVH of `boxes` with leaves of one primitive (the `Fast` and `Medium` qualities):
/// PLOC, then reinsertion. The leaf
/// collapse (`p.max_prims_per_leaf`, `p.collapse_traversal_cost`) is left to [`Bvh4::from_bvh2`],
/// which does it in the same pass as the 4-wide conversion; `p.pre_split` and
/// `p.post_collapse_reinsertion_batch_ratio_multiplier` are not used.
///
/// Runs of more than [`SAME_BOX_RUN`] primitives with the same box (bit for bit) go to PLOC as
/// one box each, and each such leaf is then replaced by a balanced subtree of the run's primitives
/// ([`same_box_runs`]). PLOC merges a pair of clusters only when each is the other's best
/// neighbour, and among identical boxes every cost ties, so it merged one pair per pass: a build
/// quadratic in the number of coincident primitives, with a binary tree as deep as their count.
pub fn build_binary(boxes: &[Aabb], p: &BvhBuildParams) -> Bvh2 {
    let runs = same_box_runs(boxes);
    let items: &[Aabb] = runs.as_ref().map_or(boxes, |r| &r.boxes);
    let mut bvh2 = PlocBuilder::with_capacity(items.len()).build(
        p.ploc_search_distance,
        items,
        (0..items.len() as u32).collect::<Vec<_>>(),
        p.sort_precision,
        p.search_depth_threshold,
    );
    if p.reinsertion_batch_ratio > 0.0 {
        ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
    }
    if let Some(runs) = runs {
        runs.expand(&mut bvh2, boxes);
    }
    bvh2
}

/// Runs of primitives with the same box longer than this are built apart ([`build_binary`]): any
/// tree over them is as good as any other, and shorter runs cost PLOC little.
pub const SAME_BOX_RUN: usize = 32;

/// The input of PLOC when some primitives share their box: one item per primitive, except one per
/// run of more than [`SAME_BOX_RUN`] primitives with the same box.
struct SameBoxRuns {
    /// The items' boxes.
    boxes: Vec<Aabb>,
    /// Each item's primitives: `members[starts[i]..starts[i + 1]]`.
    starts: Vec<u32>,
    members: Vec<u32>,
}

/// The box's bits, equal exactly when the boxes are the same bit for bit.
fn box_bits(b: &Aabb) -> [u32; 6] {
    [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z].map(f32::to_bits)
}

/// Whether more than [`SAME_BOX_RUN`] of `boxes` may share one box: false is certain (equal boxes
/// hash to one bucket, and no bucket holds that many), true is to be confirmed by sorting. Sorting
/// every input to find runs that are almost never there cost a good share of a large build;
/// counting into a table that fits in cache costs little, and with at least one bucket for every
/// box a bucket fills past the limit by chance only for inputs of millions of times its size.
/// The table has one bucket for every box, up to 2^20: a top level of a few hundred instances,
/// built every frame, zeroed a megabyte (fresh pages, faulted in) each time with a table of the
/// largest size.
fn may_share_boxes(boxes: &[Aabb]) -> bool {
    use rayon::prelude::*;
    let bucket_bits = boxes.len().next_power_of_two().trailing_zeros().clamp(6, 20);
    let bucket = |b: &Aabb| {
        let h = box_bits(b).iter().fold(0u64, |h, &v| (h ^ u64::from(v)).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        (h >> (64 - bucket_bits)) as usize
    };
    let chunk = boxes.len().div_ceil(rayon::current_num_threads().max(1)).max(1 << 16);
    let counts = boxes
        .par_chunks(chunk)
        .map(|part| {
            let mut counts = vec![0u8; 1 << bucket_bits];
            for b in part {
                let c = &mut counts[bucket(b)];
                *c = c.saturating_add(1);
            }
            counts
        })
        .reduce_with(|mut a, b| {
            for (x, y) in a.iter_mut().zip(&b) {
                *x = x.saturating_add(*y);
            }
            a
        });
    counts.is_some_and(|c| c.iter().any(|&n| usize::from(n) > SAME_BOX_RUN))
}

/// Groups the primitives that share their box, or `None` when no run is longer than
/// [`SAME_BOX_RUN`] (the usual case: the input goes to PLOC as it is).
fn same_box_runs(boxes: &[Aabb]) -> Option<SameBoxRuns> {
    use rayon::slice::ParallelSliceMut;
    if boxes.len() <= SAME_BOX_RUN || !may_share_boxes(boxes) {
        return None;
    }
    let mut order: Vec<([u32; 6], u32)> = boxes.iter().enumerate().map(|(i, b)| (box_bits(b), i as u32)).collect();
    order.par_sort_unstable();
    let mut long = false;
    let mut run_start = 0;
    for k in 1..=order.len() {
        if k == order.len() || order[k].0 != order[run_start].0 {
            long |= k - run_start > SAME_BOX_RUN;
            run_start = k;
        }
    }
    if !long {
        return None;
    }
    let mut runs = SameBoxRuns { boxes: Vec::new(), starts: vec![0], members: Vec::with_capacity(boxes.len()) };
    let mut run_start = 0;
    for k in 1..=order.len() {
        if k < order.len() && order[k].0 == order[run_start].0 {
            continue;
        }
        let run = &order[run_start..k];
        let long = run.len() > SAME_BOX_RUN;
        for (j, &(_, prim)) in run.iter().enumerate() {
            runs.members.push(prim);
            if !long || j + 1 == run.len() {
                runs.boxes.push(boxes[prim as usize]);
                runs.starts.push(runs.members.len() as u32);
            }
        }
        run_start = k;
    }
    Some(runs)
}

impl SameBoxRuns {
    /// Turns PLOC's tree over the items into one over the primitives: each leaf's items are
    /// replaced by their primitives, in a balanced subtree where there is more than one.
    fn expand(&self, bvh2: &mut Bvh2, boxes: &[Aabb]) {
        let items = std::mem::take(&mut bvh2.primitive_indices);
        let mut slots = Vec::with_capacity(self.members.len());
        let mut prims = Vec::new();
        for i in 0..bvh2.nodes.len() {
            let node = bvh2.nodes[i];
            if !node.is_leaf() {
                continue;
            }
            prims.clear();
            let first = node.first_index as usize;
            for &item in items.get(first..first + node.prim_count as usize).unwrap_or(&[]) {
                let item = item as usize;
                let (a, b) = (self.starts[item] as usize, self.starts[item + 1] as usize);
                prims.extend_from_slice(&self.members[a..b]);
            }
            if prims.len() <= 1 {
                bvh2.nodes[i].first_index = slots.len() as u32;
                slots.extend_from_slice(&prims);
            } else {
                balanced(bvh2, i, &prims, boxes, &mut slots);
            }
        }
        bvh2.primitive_indices = slots;
        // The maps obvhs keeps beside the nodes no longer match them; they are rebuilt on demand
        // from empty ones.
        bvh2.primitives_to_nodes.clear();
        bvh2.parents.clear();
        bvh2.children_are_ordered_after_parents = false;
        let longest = self.starts.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(1);
        bvh2.max_depth += (u32::BITS - longest.leading_zeros()) as usize;
    }
}

/// Makes node `at` the root of a balanced binary subtree with leaves of one primitive of `prims`
/// each (appending its nodes and slots).
fn balanced(bvh2: &mut Bvh2, at: usize, prims: &[u32], boxes: &[Aabb], slots: &mut Vec<u32>) {
    let mut aabb = Aabb::empty();
    for &p in prims {
        aabb = aabb.union(&boxes[p as usize]);
    }
    if let [prim] = prims {
        bvh2.nodes[at] = Bvh2Node::new(aabb, 1, slots.len() as u32);
        slots.push(*prim);
        return;
    }
    let kids = bvh2.nodes.len();
    bvh2.nodes[at] = Bvh2Node::new(aabb, 0, kids as u32);
    bvh2.nodes.extend([Bvh2Node::default(); 2]);
    let (left, right) = prims.split_at(prims.len() / 2);
    balanced(bvh2, kids, left, boxes, slots);
    balanced(bvh2, kids + 1, right, boxes, slots);
}

/// A 4-wide BVH over primitives given by their boxes.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    /// Nodes, root first.
    pub nodes: Vec<Node4>,
    /// Leaf slot to input primitive.
    pub prim_order: Vec<u32>,
    /// Bounds of everything, as stored: the box around the root's child boxes, which lie a little
    /// outside the primitives' bound (see [`FACE_MARGIN`]).
    pub bounds: Option<(Vec3A, Vec3A)>,
    /// Number of inner-node levels (a traversal stack needs at most `3 * depth + 1` entries).
    pub depth: usize,
}

/// The most primitives one BVH holds: a leaf's reference keeps its first primitive's slot in 27
/// bits.
pub const MAX_PRIMITIVES: usize = (1 << 27) - 1;

impl Bvh4 {
    /// Builds the BVH over `boxes` (one per primitive) with leaves of at most `max_leaf` primitives.
    pub fn build(boxes: &[Aabb], quality: BuildQuality, max_leaf: u32) -> Bvh4 {
        Bvh4::build_with(boxes, quality, max_leaf, LeafSlots::Packed)
    }

    /// [`Bvh4::build`] with the leaves' slots laid out as `slots` says. Where they are blocks, the
    /// binned builder counts a side's primitives in blocks ([`super::binned`]).
    pub fn build_with(boxes: &[Aabb], quality: BuildQuality, max_leaf: u32, slots: LeafSlots) -> Bvh4 {
        Bvh4::build_costed(boxes, quality, max_leaf, slots, slots.block_width())
    }

    /// [`Bvh4::build_with`] whose binned builder counts primitives in blocks of `block` whatever the
    /// slots' layout.
    pub(crate) fn build_costed(
        boxes: &[Aabb],
        quality: BuildQuality,
        max_leaf: u32,
        slots: LeafSlots,
        block: u32,
    ) -> Bvh4 {
        let n = boxes.len();
        if n == 0 {
            return Bvh4::default();
        }
        if n <= 4 {
            let mut node = Node4::default();
            for (k, b) in boxes.iter().enumerate() {
                node.set_child(k, b, leaf_ref(k as u32, 1));
            }
            let bounds = Some(node.children_bounds());
            let prim_order = match slots {
                LeafSlots::Packed => (0..n as u32).collect(),
                LeafSlots::Blocks(width) => (0..n as u32)
                    .flat_map(|k| {
                        std::iter::once(k).chain(std::iter::repeat_n(NO_PRIMITIVE, width.max(1) as usize - 1))
                    })
                    .collect(),
            };
            return Bvh4 { nodes: vec![node], prim_order, bounds, depth: 1 };
        }
        // Meshes and top levels are refused past it before they get here (`Mesh::validate`,
        // `Context::instantiate_object`).
        assert!(n <= MAX_PRIMITIVES, "too many primitives in one BVH ({n})");
        let p = quality.params(max_leaf);
        let mut bvh2 = if quality.is_binned() {
            if p.reinsertion_batch_ratio > 0.0 {
                // Reinsertion moves single primitives, and reads every node slot.
                let mut bvh2 = super::binned::build_binned(boxes);
                ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
                bvh2
            } else {
                // The collapse's first pass done by the build, each node as it is finished.
                let leaf = super::binned::merged_leaf_size(p.max_prims_per_leaf, p.collapse_traversal_cost);
                let rule = CollapseRule::new(p.max_prims_per_leaf, p.collapse_traversal_cost, slots);
                let summary = |node: &Bvh2Node, below: &super::binned::Finished| rule.summary(node, |j| below.node(j));
                let mut bvh2 = super::binned::build_binned_summarised(boxes, leaf, block, &summary);
                return Bvh4::from_summarised_bvh2(&mut bvh2, rule);
            }
        } else {
            build_binary(boxes, &p)
        };
        Bvh4::from_bvh2_with(&mut bvh2, p.max_prims_per_leaf, p.collapse_traversal_cost, slots)
    }

    /// Collapses obvhs's binary BVH (not yet leaf-collapsed: leaves of one primitive) into 4-wide
    /// nodes with leaves of at most `max_leaf` primitives (see the module documentation). Both
    /// passes run in parallel on the current rayon pool. The binary nodes' `meta1` and `meta2` fields
    /// are overwritten.
    pub fn from_bvh2(bvh2: &mut Bvh2, max_leaf: u32, collapse_traversal_cost: f32) -> Bvh4 {
        Bvh4::from_bvh2_with(bvh2, max_leaf, collapse_traversal_cost, LeafSlots::Packed)
    }

    /// [`Bvh4::from_bvh2`] with the leaves' slots laid out as `slots` says.
    pub fn from_bvh2_with(bvh2: &mut Bvh2, max_leaf: u32, collapse_traversal_cost: f32, slots: LeafSlots) -> Bvh4 {
        let rule = CollapseRule::new(max_leaf, collapse_traversal_cost, slots);
        if bvh2.nodes.is_empty() {
            return Bvh4::default();
        }
        Converter::new(bvh2, rule).analyse(0, 0);
        Bvh4::from_summarised_bvh2(bvh2, rule)
    }

    /// [`Bvh4::from_bvh2_with`] of a binary BVH whose nodes already hold pass 1's results under
    /// `rule` (each node's [`CollapseRule::summary`] in its `meta1` and `meta2`, as
    /// `binned::build_binned_summarised` leaves them): pass 2 alone.
    pub fn from_summarised_bvh2(bvh2: &mut Bvh2, rule: CollapseRule) -> Bvh4 {
        let Some(&root) = bvh2.nodes.first() else { return Bvh4::default() };
        let conv = Converter::new(bvh2, rule);
        let n = conv.slots(0) as usize;
        let mut prim_order = vec![0u32; n];
        if conv.is_leaf(0) {
            // Only for tiny inputs: the whole tree is one leaf.
            let prims = conv.prim_count(0);
            let (held, unused) = prim_order.split_at_mut(prims as usize);
            conv.gather(0, held);
            unused.fill(NO_PRIMITIVE);
            let mut node = Node4::default();
            node.set_child(0, &root.aabb, leaf_ref(0, prims));
            return Bvh4 { bounds: Some(node.children_bounds()), nodes: vec![node], prim_order, depth: 1 };
        }
        let count = conv.nodes4(0) as usize;
        let mut nodes: Vec<Node4> = Vec::with_capacity(count);
        let depth = conv.emit(0, &mut nodes.spare_capacity_mut()[..count], 0, &mut prim_order, 0);
        // SAFETY: `emit` writes every node of its range: the head, then the kids' subtrees in
        // ranges of `nodes4(kid)` entries that together with the head fill the range exactly
        // (`nodes4(i) = 1 + sum of nodes4(kids)`, pass 1).
        unsafe { nodes.set_len(count) };
        Bvh4 { bounds: Some(nodes[0].children_bounds()), nodes, prim_order, depth }
    }

    /// The SAH cost of the tree relative to its root box (inner-node test cost 1, primitive test
    /// cost 1): a quality figure for comparing builders, lower is better.
    pub fn sah_cost(&self) -> f64 {
        let Some((lo, hi)) = self.bounds else { return 0.0 };
        let half_area = |d: Vec3A| (d.x * d.y + d.y * d.z + d.z * d.x) as f64;
        let root = half_area(hi - lo).max(f64::MIN_POSITIVE);
        let mut cost = 1.0;
        for n in &self.nodes {
            for k in 0..4 {
                let r = n.child[k];
                if r == EMPTY_CHILD {
                    continue;
                }
                let d = Vec3A::new(n.max_x[k] - n.min_x[k], n.max_y[k] - n.min_y[k], n.max_z[k] - n.min_z[k]);
                let a = half_area(d) / root;
                cost += a * if r & LEAF_BIT != 0 { leaf_range(r).1 as f64 } else { 1.0 };
            }
        }
        cost
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

/// Binary subtrees with at least this many primitives are emitted in parallel.
const PARALLEL_PRIMS: u32 = 4096;
/// Binary nodes less deep than this are analysed in parallel (sizes are not known yet then).
const PARALLEL_DEPTH: u32 = 10;
/// Marks a binary node whose subtree becomes one leaf (in `meta1`, see [`Converter`]).
const AS_LEAF: u32 = 1 << 31;

/// The leaf collapse's rule and the layout of its leaves: what pass 1 of the conversion
/// ([`Converter`]) works out for each binary node from its subtree's results.
#[derive(Clone, Copy, Debug)]
pub struct CollapseRule {
    max_leaf: u32,
    traversal_cost: f32,
    /// The slots of a leaf: its primitives (`None`), or a block of this many.
    block: Option<u32>,
}

impl CollapseRule {
    /// Leaves of at most `max_leaf` primitives (and at most a block's), merged by obvhs's rule with
    /// traversal cost `traversal_cost`, taking their slots as `slots` says.
    pub fn new(max_leaf: u32, traversal_cost: f32, slots: LeafSlots) -> CollapseRule {
        let block = match slots {
            LeafSlots::Packed => None,
            LeafSlots::Blocks(_) => Some(slots.block_width()),
        };
        CollapseRule { max_leaf: max_leaf.clamp(1, block.unwrap_or(MAX_LEAF_SIZE)), traversal_cost, block }
    }

    /// Pass 1's result for binary node `node` (`meta1`, `meta2`; see [`Converter`]), where `below(j)`
    /// is node `j` of its subtree with that node's own result already in it.
    #[inline(always)]
    pub fn summary(&self, node: &Bvh2Node, below: impl Fn(usize) -> Bvh2Node) -> (u32, u32) {
        if node.is_leaf() {
            assert!(node.prim_count <= MAX_LEAF_SIZE, "binary leaf of {} primitives", node.prim_count);
            return (node.prim_count | AS_LEAF, 0);
        }
        let (l, r) = (below(node.first_index as usize), below(node.first_index as usize + 1));
        let (cl, cr) = (l.meta1 & !AS_LEAF, r.meta1 & !AS_LEAF);
        let total = cl + cr;
        if l.meta1 & r.meta1 & AS_LEAF != 0 && total <= self.max_leaf {
            let collapse_cost = node.aabb.half_area() * (total as f32 - self.traversal_cost);
            let base_cost = l.aabb.half_area() * cl as f32 + r.aabb.half_area() * cr as f32;
            if collapse_cost <= base_cost {
                return (total | AS_LEAF, 0);
            }
        }
        // `kids_of` reads the leaf flags of the children and grandchildren only.
        let (kids, len, _) = kids_of(node, &below);
        let nodes4: u32 = kids[..len].iter().map(|&c| below(c).meta2).sum();
        (self.slots(&l) + self.slots(&r), 1 + nodes4)
    }

    /// The leaf slots the subtree of a node with pass 1's result takes.
    #[inline(always)]
    fn slots(&self, node: &Bvh2Node) -> u32 {
        match self.block {
            Some(width) if node.meta1 & AS_LEAF != 0 => width,
            _ => node.meta1 & !AS_LEAF,
        }
    }
}

/// The binary nodes that become the children of the 4-wide node headed by inner node `node`
/// (`below(j)`: binary node `j` of its subtree, with pass 1's result): its two children, then
/// repeatedly the (not-leaf) one of largest surface area is opened.
#[inline(always)]
fn kids_of(node: &Bvh2Node, below: impl Fn(usize) -> Bvh2Node) -> ([usize; 4], usize, u32) {
    let first = node.first_index as usize;
    let mut kids = [first, first + 1, 0, 0];
    let mut len = 2;
    let mut opened = [0; 2];
    while len < 4 {
        let mut best = None;
        let mut best_area = -1.0f32;
        for (k, &c) in kids[..len].iter().enumerate() {
            let n = below(c);
            if n.meta1 & AS_LEAF == 0 {
                let a = n.aabb.half_area();
                if a > best_area {
                    best_area = a;
                    best = Some(k);
                }
            }
        }
        let Some(k) = best else { break };
        let f = below(kids[k]).first_index as usize;
        kids[k] = f;
        kids[len] = f + 1;
        opened[len - 2] = k;
        len += 1;
    }
    (kids, len, shape_code(len, opened))
}

/// The binary-to-4-wide conversion. Pass 1 ([`Converter::analyse`], bottom-up) decides the leaf
/// collapse (obvhs's SAH rule: two sibling leaves merge when `area(parent) * (count - cost)` is at
/// most the children's `area * count`) and counts, for every binary inner node, the 4-wide nodes of
/// the subtree it would head; pass 2 ([`Converter::emit`], top-down) writes each subtree into its
/// own disjoint range of the node and slot arrays, so subtrees are written in parallel and the
/// layout is the same depth-first pre-order as a sequential conversion.
///
/// Pass 1 keeps its results in the binary nodes' spare `meta1` and `meta2` fields, in the cache line
/// the traversal reads anyway: `meta1` holds a subtree's primitive count with [`AS_LEAF`] set when
/// the subtree becomes one leaf, else its slot count (its primitive count unless leaves take blocks,
/// [`LeafSlots::Blocks`]: then the blocks' slots); `meta2` its 4-wide node count (0 for leaves).
///
/// Safety invariant (the nodes are shared between threads through a raw pointer): node `i` is
/// written only by the analysis of node `i`, after the analysis of its subtree has finished (same
/// thread, or joined by `rayon::join`), and it is read only by that analysis, by its ancestors'
/// analyses (after their joins) and by pass 2 (after pass 1). So no node is read while written.
struct Converter<'a> {
    nodes: *mut Bvh2Node,
    len: usize,
    primitive_indices: &'a [u32],
    rule: CollapseRule,
}

// SAFETY: see the safety invariant of `Converter`: concurrent tasks touch disjoint nodes or only
// read.
unsafe impl Sync for Converter<'_> {}

/// A subtree to emit: binary node, its node range and first index, its slot range and first slot.
type Job<'s> = (usize, &'s mut [MaybeUninit<Node4>], u32, &'s mut [u32], u32);

impl<'a> Converter<'a> {
    fn new(bvh2: &'a mut Bvh2, rule: CollapseRule) -> Self {
        Converter {
            nodes: bvh2.nodes.as_mut_ptr(),
            len: bvh2.nodes.len(),
            primitive_indices: &bvh2.primitive_indices,
            rule,
        }
    }

    /// A copy of binary node `i`.
    #[inline(always)]
    fn node(&self, i: usize) -> Bvh2Node {
        assert!(i < self.len);
        // SAFETY: in bounds; no other thread writes node `i` now (type-level safety invariant).
        unsafe { self.nodes.add(i).read() }
    }

    /// Records pass 1's result for node `i`.
    #[inline(always)]
    fn set_info(&self, i: usize, prims: u32, nodes4: u32) {
        assert!(i < self.len);
        // SAFETY: in bounds; only this task accesses node `i` now (type-level safety invariant).
        unsafe {
            let p = self.nodes.add(i);
            std::ptr::addr_of_mut!((*p).meta1).write(prims);
            std::ptr::addr_of_mut!((*p).meta2).write(nodes4);
        }
    }

    /// Starts loading binary nodes `i` and `i + 1` into the cache.
    #[inline(always)]
    fn prefetch(&self, i: usize) {
        #[cfg(target_arch = "x86_64")]
        if i + 1 < self.len {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            // SAFETY: prefetching has no side effects; the addresses are in bounds.
            unsafe {
                let p = self.nodes.add(i) as *const i8;
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.add(64));
            }
        }
    }

    #[inline(always)]
    fn is_leaf(&self, i: usize) -> bool {
        self.node(i).meta1 & AS_LEAF != 0
    }

    #[inline(always)]
    fn prim_count(&self, i: usize) -> u32 {
        self.node(i).meta1 & !AS_LEAF
    }

    /// The leaf slots the subtree of binary node `i` takes (after pass 1 has been over it).
    #[inline(always)]
    fn slots(&self, i: usize) -> u32 {
        self.rule.slots(&self.node(i))
    }

    #[inline(always)]
    fn nodes4(&self, i: usize) -> u32 {
        self.node(i).meta2
    }

    /// The binary nodes that become the children of the 4-wide node headed by inner node `i`
    /// ([`kids_of`]).
    #[inline]
    fn kids(&self, i: usize) -> ([usize; 4], usize, u32) {
        kids_of(&self.node(i), |j| self.node(j))
    }

    /// Pass 1 over the subtree of binary node `i` at binary depth `depth`.
    fn analyse(&self, i: usize, depth: u32) {
        let node = self.node(i);
        if !node.is_leaf() {
            let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
            if depth < PARALLEL_DEPTH {
                rayon::join(|| self.analyse(l, depth + 1), || self.analyse(r, depth + 1));
            } else {
                self.analyse(l, depth + 1);
                self.analyse(r, depth + 1);
            }
        }
        let (meta1, meta2) = self.rule.summary(&node, |j| self.node(j));
        self.set_info(i, meta1, meta2);
    }

    /// Writes the primitives of the binary subtree `i` into `out`, left to right.
    fn gather(&self, i: usize, out: &mut [u32]) {
        let node = self.node(i);
        if node.is_leaf() {
            let start = node.first_index as usize;
            out.copy_from_slice(&self.primitive_indices[start..start + node.prim_count as usize]);
            return;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        let (a, b) = out.split_at_mut(self.prim_count(l) as usize);
        self.gather(l, a);
        self.gather(r, b);
    }

    /// Pass 2: writes the 4-wide node headed by binary inner node `i` to `nodes[0]` (global index
    /// `base`) and its subtree after it, and the subtree's leaf slots to `prims` (first global slot
    /// `pbase`). Returns the number of inner-node levels.
    fn emit(&self, i: usize, nodes: &mut [MaybeUninit<Node4>], base: u32, prims: &mut [u32], pbase: u32) -> usize {
        let (kids, len, shape) = self.kids(i);
        // The kids' `kids` (or `gather` for collapsed leaves) will read the children of these kids:
        // start loading them (pass 2 is bound by cache misses on the binary nodes).
        for &c in &kids[..len] {
            let n = self.node(c);
            if !n.is_leaf() {
                self.prefetch(n.first_index as usize);
            }
        }
        let Some((head, mut rest_nodes)) = nodes.split_first_mut() else { unreachable!("nodes4 >= 1") };
        let mut rest_prims = prims;
        let mut node = Node4 { shape, ..Node4::default() };
        let (mut nb, mut pb) = (base + 1, pbase);
        let mut jobs: [Option<Job>; 4] = [None, None, None, None];
        for (k, &c) in kids[..len].iter().enumerate() {
            let count = self.slots(c);
            let (mine, after) = std::mem::take(&mut rest_prims).split_at_mut(count as usize);
            rest_prims = after;
            let aabb = &self.node(c).aabb;
            if self.is_leaf(c) {
                let prims = self.prim_count(c);
                let (held, unused) = mine.split_at_mut(prims as usize);
                self.gather(c, held);
                unused.fill(NO_PRIMITIVE);
                // A block's index: `pb` is a multiple of its width (every leaf before took one).
                node.set_child(k, aabb, leaf_ref(self.rule.block.map_or(pb, |width| pb / width), prims));
            } else {
                let nc = self.nodes4(c);
                let (sub, after) = std::mem::take(&mut rest_nodes).split_at_mut(nc as usize);
                rest_nodes = after;
                node.set_child(k, aabb, nb);
                jobs[k] = Some((c, sub, nb, mine, pb));
                nb += nc;
            }
            pb += count;
        }
        head.write(node);
        let parallel = self.slots(i) >= PARALLEL_PRIMS;
        1 + self.run(&mut jobs[..len], parallel)
    }

    /// Emits the subtrees of `jobs`, two halves in parallel when `parallel`; returns the deepest.
    fn run(&self, jobs: &mut [Option<Job>], parallel: bool) -> usize {
        match jobs {
            [] => 0,
            [job] => job.take().map_or(0, |(c, n, nb, p, pb)| self.emit(c, n, nb, p, pb)),
            _ => {
                let (a, b) = jobs.split_at_mut(jobs.len() / 2);
                let (da, db) = if parallel {
                    rayon::join(|| self.run(a, true), || self.run(b, true))
                } else {
                    (self.run(a, false), self.run(b, false))
                };
                da.max(db)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::bvh2::builder::build_bvh2;
    use std::time::Duration;

    /// Stored faces lie strictly outside the geometry's bound, far enough that a ray with a
    /// clamped zero direction component (inverse `1e30`) lying in the bound's plane leaves them
    /// only beyond `5e10`; and growing keeps order, so a child's box stays inside its parent's.
    #[test]
    fn faces_grow_outward_and_keep_their_order() {
        let mut xs = vec![0.0f32, -0.0, f32::MIN_POSITIVE, 1e-30, 1e-20, 0.25, 1.0, 3.0, 1e4, 1e7 + 250.0, 1e9, 3e38];
        xs.extend(xs.clone().iter().map(|x| -x));
        xs.extend((0..2000).map(|i| ((i as f32 * 0.618_034).fract() - 0.5) * 10f32.powi(i % 24 - 12)));
        for &x in &xs {
            let (lo, hi) = (below(x), above(x));
            assert!(lo < x && hi > x, "{x}: {lo} {hi}");
            if x.abs() < 1e38 {
                assert!((x - lo) * 1e30 >= 5e10 && (hi - x) * 1e30 >= 5e10, "{x}: {lo} {hi}");
            }
        }
        xs.sort_by(f32::total_cmp);
        for w in xs.windows(2) {
            assert!(below(w[0]) <= below(w[1]) && above(w[0]) <= above(w[1]), "{} {}", w[0], w[1]);
        }
    }

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

    /// The straightforward sequential conversion of an obvhs-collapsed binary BVH (the previous
    /// implementation), as a reference for the parallel one.
    struct Reference {
        out: Bvh4,
    }

    impl Reference {
        fn convert(bvh2: &Bvh2) -> Bvh4 {
            let root = &bvh2.nodes[0];
            let mut r = Reference { out: Bvh4 { nodes: vec![], prim_order: vec![], bounds: None, depth: 0 } };
            if root.is_leaf() {
                let mut node = Node4::default();
                let l = r.emit_leaf(bvh2, 0);
                node.set_child(0, &root.aabb, l);
                r.out.nodes.push(node);
            } else {
                r.emit_inner(bvh2, 0);
            }
            r.out.depth = r.compute_depth(0);
            r.out.bounds = r.out.nodes.first().map(Node4::children_bounds);
            r.out
        }

        fn compute_depth(&self, r: u32) -> usize {
            if r & LEAF_BIT != 0 {
                return 0;
            }
            let n = &self.out.nodes[r as usize];
            1 + n.child.iter().map(|&c| self.compute_depth(c)).max().unwrap_or(0)
        }

        fn emit_leaf(&mut self, bvh2: &Bvh2, n2: usize) -> u32 {
            let node = &bvh2.nodes[n2];
            let first = self.out.prim_order.len() as u32;
            let start = node.first_index as usize;
            let count = node.prim_count as usize;
            self.out.prim_order.extend_from_slice(&bvh2.primitive_indices[start..start + count]);
            // Leaves larger than a reference can describe are split over several references by the
            // caller; obvhs never produces them with our `max_prims_per_leaf`.
            leaf_ref(first, count as u32)
        }

        /// Emits the 4-wide node for binary inner node `n2` and returns its index.
        fn emit_inner(&mut self, bvh2: &Bvh2, n2: usize) -> u32 {
            let first = bvh2.nodes[n2].first_index as usize;
            let mut kids = [first, first + 1, 0, 0];
            let mut len = 2;
            let mut opened = [0; 2];
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
                opened[len - 2] = k;
                len += 1;
            }
            let index = self.out.nodes.len();
            self.out.nodes.push(Node4::default());
            let mut node = Node4 { shape: shape_code(len, opened), ..Node4::default() };
            for (k, &c) in kids[..len].iter().enumerate() {
                let child = &bvh2.nodes[c];
                let r = if child.is_leaf() { self.emit_leaf(bvh2, c) } else { self.emit_inner(bvh2, c) };
                node.set_child(k, &child.aabb, r);
            }
            self.out.nodes[index] = node;
            index as u32
        }
    }

    #[test]
    fn parallel_conversion_matches_obvhs_collapse_and_sequential_conversion() {
        for n in [5usize, 17, 1000, 20_000] {
            let boxes = test_boxes(n);
            for q in [BuildQuality::Fast, BuildQuality::Medium] {
                let mut p = q.params(2);
                p.post_collapse_reinsertion_batch_ratio_multiplier = 0.0;
                let bvh2 = build_bvh2(&boxes, p, &mut Duration::default());
                let reference = Reference::convert(&bvh2);
                let ours = Bvh4::build(&boxes, q, 2);
                assert_eq!(ours.nodes, reference.nodes, "n = {n}, {q:?}");
                assert_eq!(ours.prim_order, reference.prim_order, "n = {n}, {q:?}");
                assert_eq!(ours.depth, reference.depth, "n = {n}, {q:?}");
                assert_eq!(ours.bounds, reference.bounds, "n = {n}, {q:?}");
            }
        }
    }

    /// The binned build's own first pass of the collapse (`build_binned_summarised`, each node
    /// summarised as it is finished) leaves the same results as the conversion's pass over the
    /// finished tree, so the 4-wide trees are the same: spread, coincident and extreme boxes (NaN
    /// corners, extents that overflow).
    #[test]
    fn the_collapse_summarised_by_the_build_is_the_collapse_of_the_built_tree() {
        use super::super::binned::{build_binned_summarised, merged_leaf_size};
        let coincident = vec![Aabb::new(Vec3A::ONE, Vec3A::splat(2.0)); 3000];
        // Extreme magnitudes (centroid boxes whose extents overflow) and NaN corners, whose areas
        // and costs are NaN.
        let extreme: Vec<Aabb> = (0..3000)
            .map(|i| {
                let x = [3e38f32, -3e38, 1e-30, 0.0, f32::NAN][i % 5] * if i % 2 == 0 { 1.0 } else { 0.5 };
                Aabb::new(Vec3A::new(x, i as f32, 0.0), Vec3A::new(x, i as f32 + 1.0, 1.0))
            })
            .collect();
        let inputs = [2usize, 3, 5, 6, 17, 1000, 20_000].map(test_boxes).into_iter().chain([coincident, extreme]);
        for boxes in inputs {
            let n = boxes.len();
            for (max_leaf, cost, slots) in [
                (4, 3.0, LeafSlots::Blocks(4)),
                (4, 3.0, LeafSlots::Packed),
                (2, 1.0, LeafSlots::Packed),
                (4, 1.5, LeafSlots::Blocks(4)),
            ] {
                let leaf = merged_leaf_size(max_leaf, cost);
                let rule = CollapseRule::new(max_leaf, cost, slots);
                let block = slots.block_width();
                let mut built = build_binned_summarised(&boxes, leaf, block, &|_, _| (0, 0));
                let reference = Bvh4::from_bvh2_with(&mut built, max_leaf, cost, slots);
                let mut summarised =
                    build_binned_summarised(&boxes, leaf, block, &|node, below| rule.summary(node, |j| below.node(j)));
                let metas = |b: &Bvh2| b.nodes.iter().map(|n| (n.meta1, n.meta2)).collect::<Vec<_>>();
                // The conversion's pass wrote its results into `built`'s nodes.
                assert_eq!(metas(&summarised), metas(&built), "n = {n}, leaves of {max_leaf}, cost {cost}, {slots:?}");
                let ours = Bvh4::from_summarised_bvh2(&mut summarised, rule);
                // Compared as printed, where NaN boxes are equal.
                let printed = |b: &Bvh4| format!("{:?}", (&b.nodes, b.depth, b.bounds));
                let same = printed(&ours) == printed(&reference);
                assert!(same, "n = {n}, leaves of {max_leaf}, cost {cost}, {slots:?}");
                assert_eq!(ours.prim_order, reference.prim_order);
            }
        }
    }

    fn test_boxes(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let f = i as f32;
                let p = Vec3A::new((f * 0.37).sin() * 10.0, (f * 1.3).cos() * 10.0, f * 0.01);
                Aabb::new(p, p + Vec3A::splat(0.5))
            })
            .collect()
    }

    /// Coincident primitives (a mesh with a triangle repeated many times) build in n log n: runs of
    /// the same box become balanced subtrees, so the tree stays shallow and every primitive is
    /// still in exactly one leaf whose box holds it.
    #[test]
    fn many_coincident_primitives_build_a_shallow_tree() {
        let n = 100_000;
        let same = Aabb::new(Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0));
        let mut boxes = vec![same; n];
        // A few others among them, and a second run of another box.
        for (k, b) in boxes.iter_mut().enumerate().step_by(997) {
            *b = Aabb::new(Vec3A::splat(k as f32), Vec3A::splat(k as f32 + 0.5));
        }
        let other = Aabb::new(Vec3A::splat(-3.0), Vec3A::splat(-2.0));
        boxes[50_000..50_500].fill(other);
        for q in [BuildQuality::Fast, BuildQuality::High] {
            let bvh = Bvh4::build(&boxes, q, 4);
            let mut seen = vec![0u32; n];
            let (lo, hi) = bvh.bounds.expect("bounds");
            check_subtree(&bvh, 0, lo, hi, &boxes, &mut seen);
            assert!(seen.iter().all(|&c| c == 1), "{q:?}");
            assert!(bvh.depth <= 24, "{q:?}: depth {}", bvh.depth);
            assert!(bvh.nodes.len() <= n / 2, "{q:?}: {} nodes", bvh.nodes.len());
        }
    }

    /// Inputs without long runs of the same box go to PLOC as they are.
    #[test]
    fn short_runs_of_the_same_box_are_not_grouped() {
        let mut boxes = test_boxes(1000);
        let first = boxes[0];
        // `first` and its copies: a run of `SAME_BOX_RUN`, then one longer.
        boxes[100..99 + SAME_BOX_RUN].fill(first);
        assert!(same_box_runs(&boxes).is_none());
        boxes[100..100 + SAME_BOX_RUN].fill(first);
        let runs = same_box_runs(&boxes).expect("a run");
        assert_eq!(runs.boxes.len(), 1000 - SAME_BOX_RUN);
        assert_eq!(runs.members.len(), 1000);
        // A small input counts into a small table, and finds its run all the same.
        let mut few = test_boxes(40);
        let first = few[0];
        few[..=SAME_BOX_RUN].fill(first);
        assert_eq!(same_box_runs(&few).expect("a run").boxes.len(), 40 - SAME_BOX_RUN);
    }

    #[test]
    fn every_primitive_in_exactly_one_leaf() {
        let qualities = [BuildQuality::Fast, BuildQuality::Medium, BuildQuality::High, BuildQuality::Best];
        for n in [1usize, 3, 4, 5, 17, 1000, 30_000] {
            let boxes = test_boxes(n);
            for (q, max_leaf) in qualities.into_iter().flat_map(|q| [(q, 1), (q, 2), (q, 4)]) {
                let bvh = Bvh4::build(&boxes, q, max_leaf);
                let mut seen = vec![0u32; n];
                let inf = Vec3A::splat(f32::INFINITY);
                check_subtree(&bvh, 0, -inf, inf, &boxes, &mut seen);
                assert!(seen.iter().all(|&c| c == 1), "n = {n}, {q:?}, leaves of {max_leaf}");
                let mut worst = 0;
                for node in &bvh.nodes {
                    for &r in &node.child {
                        if r & LEAF_BIT != 0 {
                            worst = worst.max(leaf_range(r).1);
                        }
                    }
                }
                assert!(worst <= max_leaf, "n = {n}, {q:?}: leaf of {worst} > {max_leaf}");
                assert!(bvh.depth >= 1 && bvh.sah_cost() >= 1.0);
            }
        }
    }
}

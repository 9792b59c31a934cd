//! Top-down binned SAH construction of a binary BVH (Wald 2007, "On fast construction of SAH-based
//! bounding volume hierarchies"): each node's primitives are sorted into bins by centroid along
//! each axis (up to [`BINS`], fewer for fewer primitives), the split between two bins of least
//! surface-area cost is taken, and the two halves are built in parallel while they are large.
//! Nodes of at most [`SMALL`] primitives try every split of their sorted centroids instead, and
//! nodes of at most [`TINY`] are halved along their widest axis. Where the leaves are blocks that a
//! ray tests at once (an object BVH's triangles, four to a block), a side's cost counts its
//! primitives in whole blocks, as Embree's builders do: one to four triangles cost one block test,
//! so the splits fill blocks rather than leave them three-quarters full.
//!
//! The tree has leaves of one primitive, as PLOC's has, or of up to three where the caller knows
//! that the leaf collapse would merge every subtree that small ([`build_binned_with_leaves`]): the
//! collapse is left to [`super::bvh4::Bvh4::from_bvh2`], which decides it with the same cost model
//! for every builder.
//!
//! Invariants:
//! - The node array of a tree over `n` primitives has exactly `2n - 1` slots, so each subtree's
//!   place in it is known before it is built: a node's children are the pair at the start of its
//!   descendants' range, followed by the left child's descendants and then the right's. A leaf of
//!   `m > 1` primitives leaves its `2m - 2` descendant slots as [`UNREACHED`] nodes, which no
//!   path from the root leads to. The layout is a function of the input alone, whatever the
//!   threads did first.
//! - Depth is bounded whatever the input: below [`SAH_DEPTH`] levels a node is split at its
//!   median, which halves it, so no tree is deeper than `SAH_DEPTH + 28` (at most 2^27
//!   primitives, [`super::bvh4::MAX_PRIMITIVES`]).

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use wide::{f32x8, i32x8};

/// Bins per axis.
const BINS: usize = 32;

/// Nodes of more primitives than this build their two halves in parallel.
const PARALLEL_SPLIT: usize = 4096;

/// Nodes of more primitives than this sort them into bins and move them on several threads, in
/// chunks of [`BINNING_CHUNK`].
const PARALLEL_BINNING: usize = 2 * BINNING_CHUNK;

/// The primitives of one task of a node binned on several threads. Small enough that the top
/// levels, where there are fewer nodes than threads, still have a task for every thread of a
/// many-core machine (a root of 100,000 primitives is 13 of them), large enough that a task's
/// work outweighs handing it out. A constant, not a share of the pool: the chunks decide the
/// order the primitives are moved in, so the tree is the same on any number of threads.
const BINNING_CHUNK: usize = 1 << 13;

/// Below this many levels, nodes are split at their median rather than by cost (see the module's
/// invariants).
const SAH_DEPTH: u32 = 64;

/// A primitive as the build moves it about: its box as the lower corner, with the input index in
/// the fourth lane, and the negated upper corner, with infinity in the fourth lane (32 bytes: two
/// to a cache line, where the partitions move them). As eight floats it is what [`Bin::add`] takes
/// the minimum with: one operation for both corners.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct PrimRef {
    lo: Vec4,
    neg_hi: Vec4,
}

impl PrimRef {
    fn new(b: &Aabb, id: u32) -> PrimRef {
        PrimRef { lo: b.min.extend(f32::from_bits(id)), neg_hi: (-b.max).extend(f32::INFINITY) }
    }

    #[inline(always)]
    fn lo(&self) -> Vec3A {
        Vec3A::from_vec4(self.lo)
    }

    #[inline(always)]
    fn hi(&self) -> Vec3A {
        -Vec3A::from_vec4(self.neg_hi)
    }

    #[inline(always)]
    fn id(&self) -> u32 {
        self.lo.w.to_bits()
    }

    /// Twice the centroid (the bins are laid over doubled centroids: one operation a primitive).
    /// `lo - (-hi)` is `lo + hi` bit for bit: IEEE subtraction is addition of the negation.
    #[inline(always)]
    fn centroid2(&self) -> Vec3A {
        Vec3A::from_vec4(self.lo - self.neg_hi)
    }

    /// The eight floats `[lo, id, -hi, inf]`.
    #[inline(always)]
    fn wide(&self) -> f32x8 {
        bytemuck::cast(*self)
    }
}

/// A box and the box of the doubled centroids inside it.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    geometry: Aabb,
    centroids: Aabb,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        geometry: Aabb { min: Vec3A::splat(f32::MAX), max: Vec3A::splat(f32::MIN) },
        centroids: Aabb { min: Vec3A::splat(f32::MAX), max: Vec3A::splat(f32::MIN) },
    };

    #[inline(always)]
    fn add(&mut self, p: &PrimRef) {
        self.geometry.min = self.geometry.min.min(p.lo());
        self.geometry.max = self.geometry.max.max(p.hi());
        let c = p.centroid2();
        self.centroids.min = self.centroids.min.min(c);
        self.centroids.max = self.centroids.max.max(c);
    }

    fn union(&self, o: &Bounds) -> Bounds {
        Bounds { geometry: self.geometry.union(&o.geometry), centroids: self.centroids.union(&o.centroids) }
    }

    fn of(refs: &[PrimRef]) -> Bounds {
        let mut b = Bounds::EMPTY;
        for p in refs {
            b.add(p);
        }
        b
    }
}

/// How a node's primitives are sorted into bins: bin `k` on axis `a` holds the centroids with
/// `(c[a] - origin[a]) * scale[a]` in `[k, k + 1)` (the last bin also those at the top).
#[derive(Clone, Copy, Debug)]
struct Binning {
    origin: Vec3A,
    scale: Vec3A,
    /// Bins in use: fewer for fewer primitives (as Embree: `4 + m / 20`, at most [`BINS`]), where
    /// more bins would cost more to sweep than their finer splits save.
    count: usize,
}

impl Binning {
    /// The binning of `m` centroids in `centroids`; axes without extent get scale 0 (one bin).
    fn of(centroids: &Aabb, m: usize) -> Binning {
        let count = (4 + m / 20).min(BINS);
        let extent = centroids.max - centroids.min;
        // Just under `count` so that the top centroid lands in the last bin, not past it.
        let k = count as f32 * (1.0 - 1e-6);
        let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), k / extent, Vec3A::ZERO);
        Binning { origin: centroids.min, scale, count }
    }

    /// Whether centroid `c` falls into a bin before bin `k` on `axis`: [`Binning::bins`] on one
    /// axis, compared before the conversion (for `v` in `[0, count - 1]`, `trunc(v) < k` exactly
    /// when `v < k`; `f32::max` also takes NaN to 0).
    #[inline(always)]
    fn left_of(&self, c: Vec3A, axis: usize, k: usize) -> bool {
        ((c[axis] - self.origin[axis]) * self.scale[axis]).max(0.0) < k as f32
    }

    /// The bins of a centroid on the three axes.
    #[inline(always)]
    fn bins(&self, c: Vec3A) -> [u32; 3] {
        // Clamped before the conversion (NaN to 0: `maxps` returns its second operand then), so
        // that the conversion needs no range checks.
        let top = Vec3A::splat(self.count as f32 - 1.0);
        let k = ((c - self.origin) * self.scale).max(Vec3A::ZERO).min(top);
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{__m128, _mm_cvttps_epi32};
            // SAFETY: SSE2 is part of x86-64.
            let v = unsafe { _mm_cvttps_epi32(__m128::from(k)) };
            let [x, y, z, _]: [u32; 4] = bytemuck::cast(v);
            [x, y, z]
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let k = k.as_uvec3();
            [k.x, k.y, k.z]
        }
    }
}

/// One bin of one axis: the box of its primitives and their number, as eight floats
/// `[min, -, -max, count]` with the count in the last lane's bits, an integer offset by
/// [`COUNT_BIAS`]. A primitive is added with one minimum (the negated upper corners' minimum is the
/// upper corners' maximum, and a primitive's last lane, infinity, leaves the count's lane as it
/// is: the offset count's bits are a positive normal float below infinity) and one integer
/// addition of one to the last lane (the other lanes' zeros leave the floats' bits as they are): a
/// load, two operations and a store for both corners and the count.
#[derive(Clone, Copy, Debug)]
struct Bin(f32x8);

/// The bits of an empty bin's count lane: the smallest normal float, so that a count's lane is
/// never a denormal, which a thread that treats denormal inputs as zero (an application may set
/// its threads so) would make the minimum return as zero.
const COUNT_BIAS: u32 = f32::MIN_POSITIVE.to_bits();

impl Bin {
    const EMPTY: Bin = Bin(f32x8::new([
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::INFINITY,
        f32::MIN_POSITIVE,
    ]));

    /// Adds the primitive whose [`PrimRef::wide`] is `p`.
    #[inline(always)]
    fn add(&mut self, p: f32x8) {
        let one = i32x8::new([0, 0, 0, 0, 0, 0, 0, 1]);
        let m: i32x8 = bytemuck::cast(self.0.fast_min(p));
        self.0 = bytemuck::cast(m + one);
    }

    #[inline(always)]
    fn count(&self) -> u32 {
        self.0.as_array()[7].to_bits() - COUNT_BIAS
    }

    /// The box of the primitives (empty, as [`Aabb::empty`], for none).
    #[inline(always)]
    fn aabb(&self) -> Aabb {
        unpack_box(self.0)
    }

    /// The bin of both bins' primitives (at most [`super::bvh4::MAX_PRIMITIVES`], far below the
    /// offset counts' limit, infinity's bits).
    #[inline(always)]
    fn merge(&self, o: &Bin) -> Bin {
        let mut v = self.0.fast_min(o.0).to_array();
        v[7] = f32::from_bits(COUNT_BIAS + self.count() + o.count());
        Bin(f32x8::new(v))
    }
}

/// The boxes of the doubled centroids on the two sides of a partition as it moves primitives, each
/// as eight floats `[min, -, -max, -]` (as [`Bin`]'s): a centroid is added to its side with one
/// minimum and one blend a side, without branches on the side.
struct SideBounds {
    left: f32x8,
    right: f32x8,
}

impl SideBounds {
    const EMPTY: SideBounds = SideBounds { left: f32x8::splat(f32::INFINITY), right: f32x8::splat(f32::INFINITY) };

    /// Adds centroid `c` to the left side if `left`, else to the right.
    #[inline(always)]
    fn add(&mut self, c: Vec3A, left: bool) {
        let [x, y, z] = c.to_array();
        let both = f32x8::new([x, y, z, 0.0, -x, -y, -z, 0.0]);
        let mask = f32x8::splat(f32::from_bits(0u32.wrapping_sub(u32::from(left))));
        self.left = mask.select(self.left.fast_min(both), self.left);
        self.right = mask.select(self.right, self.right.fast_min(both));
    }

    /// The two boxes, `[left, right]`.
    fn boxes(&self) -> [Aabb; 2] {
        [self.left, self.right].map(unpack_box)
    }
}

/// The box that eight floats `[min, -, -max, -]` hold (a [`Bin`]'s or a [`SideBounds`] side's).
#[inline(always)]
fn unpack_box(v: f32x8) -> Aabb {
    let v = v.as_array();
    Aabb { min: Vec3A::new(v[0], v[1], v[2]), max: -Vec3A::new(v[4], v[5], v[6]) }
}

/// Per axis, its bins; `N` bins at most (fewer primitives use fewer bins, [`Binning::count`], and a
/// smaller set is cheaper to clear and copy).
#[derive(Clone, Copy)]
struct Bins<const N: usize> {
    bins: [[Bin; N]; 3],
}

impl<const N: usize> Bins<N> {
    fn new() -> Bins<N> {
        Bins { bins: [[Bin::EMPTY; N]; 3] }
    }

    fn fill(binning: &Binning, refs: &[PrimRef]) -> Bins<N> {
        debug_assert!(binning.count <= N);
        if refs.len() < 64 {
            let mut bins = Bins::new();
            refs.iter().for_each(|p| bins.add(binning, p));
            return bins;
        }
        // Two sets of bins, for alternate primitives: neighbours in the input tend to fall into the
        // same bins, and each update would wait for the last one's store.
        let (mut even, mut odd) = (Bins::new(), Bins::new());
        let mut pairs = refs.chunks_exact(2);
        for pair in &mut pairs {
            even.add(binning, &pair[0]);
            odd.add(binning, &pair[1]);
        }
        pairs.remainder().iter().for_each(|p| even.add(binning, p));
        even.merge_bins(&odd, binning.count)
    }

    #[inline(always)]
    fn add(&mut self, binning: &Binning, p: &PrimRef) {
        let k = binning.bins(p.centroid2());
        let w = p.wide();
        for (a, k) in k.into_iter().enumerate() {
            self.bins[a][k as usize].add(w);
        }
    }

    fn merge_bins(mut self, o: &Bins<N>, count: usize) -> Bins<N> {
        for a in 0..3 {
            for k in 0..count {
                self.bins[a][k] = self.bins[a][k].merge(&o.bins[a][k]);
            }
        }
        self
    }

    /// The split of least cost `area(left) * blocks(left) + area(right) * blocks(right)` (blocks of
    /// `1 << block_shift` primitives, see [`blocks`]): its axis and its first bin on the right.
    /// `None` when every axis has all primitives in one bin.
    fn best_split(&self, bins: usize, block_shift: u32) -> Option<(usize, usize)> {
        let mut best: Option<(f32, usize, usize)> = None;
        for a in 0..3 {
            // Right-hand costs: `right[k]` for bins `k..`.
            let mut right = [0.0f32; N];
            let mut acc = Aabb::empty();
            let mut n = 0u32;
            for k in (1..bins).rev() {
                acc = acc.union(&self.bins[a][k].aabb());
                n += self.bins[a][k].count();
                right[k] = if n == 0 { f32::INFINITY } else { acc.half_area() * blocks(n, block_shift) };
            }
            let mut acc = Aabb::empty();
            let mut n = 0u32;
            for (k, &right) in right.iter().enumerate().take(bins).skip(1) {
                acc = acc.union(&self.bins[a][k - 1].aabb());
                n += self.bins[a][k - 1].count();
                if n == 0 || right.is_infinite() {
                    continue;
                }
                let cost = acc.half_area() * blocks(n, block_shift) + right;
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, a, k));
                }
            }
        }
        best.map(|(_, a, k)| (a, k))
    }
}

/// How many leaf blocks of `1 << block_shift` primitives `n` primitives take: the cost of testing
/// them, where a block's primitives are tested at once.
#[inline(always)]
fn blocks(n: u32, block_shift: u32) -> f32 {
    (n.saturating_add((1 << block_shift) - 1) >> block_shift) as f32
}

/// The slots of a leaf's unused descendant range (see the module's invariants): an inner node with
/// an empty box, never reached from the root.
const UNREACHED: Bvh2Node = Bvh2Node { aabb: Aabb::INVALID, prim_count: 0, first_index: 0, meta1: 0, meta2: 0 };

/// The binary BVH of `boxes` (one per primitive), leaves of one primitive each, built by binned SAH.
pub fn build_binned(boxes: &[Aabb]) -> Bvh2 {
    build_binned_with_leaves(boxes, 1)
}

/// [`build_binned`] with every subtree of at most `leaf_size` primitives (at most 3) made one leaf,
/// its primitives in the order the binary subtree's leaves would have had. For callers whose leaf
/// collapse merges every such subtree anyway ([`merged_leaf_size`]): the tree after the collapse is
/// the same, without building, writing and collapsing the small subtrees' nodes.
pub fn build_binned_with_leaves(boxes: &[Aabb], leaf_size: usize) -> Bvh2 {
    build_binned_summarised(boxes, leaf_size, 1, &|_: &Bvh2Node, _: &Finished| (0, 0))
}

/// The finished part of the node array below a node the build is finishing: its descendants'
/// range, every slot of it written.
pub struct Finished<'a> {
    nodes: &'a [MaybeUninit<Bvh2Node>],
    /// The index of `nodes[0]` in the whole array.
    base: usize,
}

impl Finished<'_> {
    /// Node `j` of the whole array, a descendant of the node being finished.
    #[inline(always)]
    pub fn node(&self, j: usize) -> Bvh2Node {
        let slot = j.checked_sub(self.base).and_then(|k| self.nodes.get(k));
        let Some(slot) = slot else { panic!("node {j} is not below the node being finished") };
        // SAFETY: every slot of a finished node's descendant range is written (`build`'s first
        // invariant).
        unsafe { slot.assume_init_read() }
    }
}

/// [`build_binned_with_leaves`] that also works out, for each node as it is finished (after its
/// subtree: bottom-up), `summary(node, descendants)` and keeps it in the node's `meta1` and
/// `meta2`: a bottom-up pass over the finished tree done while each node's children are still in
/// the cache. `block` is how many primitives the final tree's leaves test at once (a power of two;
/// 1 where each is tested on its own): the splits' costs count primitives in such blocks.
pub fn build_binned_summarised<S>(boxes: &[Aabb], leaf_size: usize, block: u32, summary: &S) -> Bvh2
where
    S: Fn(&Bvh2Node, &Finished) -> (u32, u32) + Sync,
{
    let leaf_size = leaf_size.clamp(1, TINY_LEAF);
    let block_shift = block.clamp(1, 1 << 16).ilog2();
    let n = boxes.len();
    if n == 0 {
        return Bvh2 { nodes: Vec::new(), primitive_indices: Vec::new(), max_depth: 1, ..Bvh2::default() };
    }
    let mut refs: Vec<PrimRef> = boxes.par_iter().enumerate().map(|(i, b)| PrimRef::new(b, i as u32)).collect();
    let bounds = if n > PARALLEL_BINNING {
        refs.par_chunks(BINNING_CHUNK).map(Bounds::of).reduce(|| Bounds::EMPTY, |a, b| a.union(&b))
    } else {
        Bounds::of(&refs)
    };
    let mut nodes: Vec<MaybeUninit<Bvh2Node>> = Vec::with_capacity(2 * n - 1);
    // SAFETY: `MaybeUninit` needs no initialisation.
    unsafe { nodes.set_len(2 * n - 1) };
    let (root, descendants) = nodes.split_at_mut(1);
    // Scratch that every partition writes before it is read: zeroed, not a copy of `refs`, so
    // that no thread spends a pass over all the primitives before the first split starts (fresh
    // zeroed pages cost nothing until the partitions, on all threads, first touch them).
    let mut spare: Vec<PrimRef> = bytemuck::zeroed_vec(n);
    let mut primitive_indices = vec![0u32; n];
    let at = Place { first: 0, base: 1 };
    let shape = Shape { leaf_size, block_shift, summary };
    let depth =
        build([&mut refs, &mut spare], &mut primitive_indices, at, &mut root[0], descendants, bounds, 0, &shape);
    // SAFETY: `build` wrote its node and every node of its descendants' range, which with the
    // root are all `2n - 1` (the module's first invariant: each call writes `me`, and its range
    // is exactly its children's pair and their own ranges, or [`UNREACHED`] slots).
    let nodes = unsafe {
        let mut nodes = std::mem::ManuallyDrop::new(nodes);
        Vec::from_raw_parts(nodes.as_mut_ptr() as *mut Bvh2Node, nodes.len(), nodes.capacity())
    };
    Bvh2 {
        nodes,
        primitive_indices,
        max_depth: (depth as usize + 1).max(obvhs::bvh2::DEFAULT_MAX_STACK_DEPTH),
        ..Bvh2::default()
    }
}

/// What every node of a build shares: subtrees of at most `leaf_size` primitives are one leaf,
/// splits count primitives in blocks of `1 << block_shift` ([`blocks`]), and each finished node
/// keeps its `summary`.
struct Shape<'s, S> {
    leaf_size: usize,
    block_shift: u32,
    summary: &'s S,
}

/// Where a subtree goes: its first slot, and the index of the first node of its descendants.
#[derive(Clone, Copy, Debug)]
struct Place {
    first: u32,
    base: u32,
}

/// Builds the subtree of `refs[0]` with its root in `me` and the rest in `descendants`
/// (`2 * m - 2` nodes, the first at index `at.base`), writing its primitives' input indices to
/// `ids` (its slots, from `at.first`); returns its depth. `refs[1]` is as long, scratch space that
/// partitions move the primitives into (the children then swap the two). Subtrees of at most
/// `shape.leaf_size` primitives are one leaf. `me` is written last, with its summary.
#[allow(clippy::too_many_arguments)]
fn build<S>(
    [refs, spare]: [&mut [PrimRef]; 2],
    ids: &mut [u32],
    at: Place,
    me: &mut MaybeUninit<Bvh2Node>,
    descendants: &mut [MaybeUninit<Bvh2Node>],
    bounds: Bounds,
    depth: u32,
    shape: &Shape<S>,
) -> u32
where
    S: Fn(&Bvh2Node, &Finished) -> (u32, u32) + Sync,
{
    let m = refs.len();
    let finish = |me: &mut MaybeUninit<Bvh2Node>, mut node: Bvh2Node, descendants: &[MaybeUninit<Bvh2Node>]| {
        (node.meta1, node.meta2) = (shape.summary)(&node, &Finished { nodes: descendants, base: at.base as usize });
        me.write(node);
    };
    if m <= shape.leaf_size {
        // The order the binary subtree's leaves would have: `split` halves three primitives
        // sorted along the widest axis, and leaves two as they are.
        if m == 3 {
            sort_along_widest_axis(refs, &bounds);
        }
        for (id, p) in ids.iter_mut().zip(refs.iter()) {
            *id = p.id();
        }
        for slot in descendants.iter_mut() {
            slot.write(UNREACHED);
        }
        finish(me, Bvh2Node::new(bounds.geometry, m as u32, at.first), descendants);
        return 1;
    }
    let (left_count, left, right, moved) = split(refs, spare, &bounds, depth, shape.block_shift);
    let (refs, spare) = if moved { (spare, refs) } else { (refs, spare) };
    let (pair, rest) = descendants.split_at_mut(2);
    let (lnode, rnode) = pair.split_at_mut(1);
    let (ldesc, rdesc) = rest.split_at_mut(2 * left_count - 2);
    let (lrefs, rrefs) = refs.split_at_mut(left_count);
    let (lspare, rspare) = spare.split_at_mut(left_count);
    let (lids, rids) = ids.split_at_mut(left_count);
    let lat = Place { first: at.first, base: at.base + 2 };
    let rat = Place { first: at.first + left_count as u32, base: lat.base + ldesc.len() as u32 };
    let (dl, dr) = if m > PARALLEL_SPLIT {
        rayon::join(
            || build([lrefs, lspare], lids, lat, &mut lnode[0], ldesc, left, depth + 1, shape),
            || build([rrefs, rspare], rids, rat, &mut rnode[0], rdesc, right, depth + 1, shape),
        )
    } else {
        (
            build([lrefs, lspare], lids, lat, &mut lnode[0], ldesc, left, depth + 1, shape),
            build([rrefs, rspare], rids, rat, &mut rnode[0], rdesc, right, depth + 1, shape),
        )
    };
    finish(me, Bvh2Node::new(bounds.geometry, 0, at.base), descendants);
    1 + dl.max(dr)
}

/// Sorts a few primitives by centroid along the widest axis of their centroids' box (insertion
/// sort: stable, ties keep their order).
fn sort_along_widest_axis(refs: &mut [PrimRef], bounds: &Bounds) {
    let extent = bounds.centroids.max - bounds.centroids.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    for i in 1..refs.len() {
        let mut j = i;
        while j > 0 && refs[j - 1].centroid2()[axis] > refs[j].centroid2()[axis] {
            refs.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// The largest leaf [`build_binned_with_leaves`] may make (a subtree of three is still one of
/// [`TINY`]'s, split by [`sort_along_widest_axis`]).
const TINY_LEAF: usize = 3;

/// The largest `m` such that `Bvh4::from_bvh2` with leaves of at most `max_leaf` primitives and
/// traversal cost `cost` merges every binary subtree of at most `m` primitives into one leaf: two
/// sibling leaves of `total` primitives merge when `area(parent) * (total - cost)` is at most the
/// children's `area * count`, which holds whatever the boxes when `total <= cost` (the left side
/// is then at most 0). A NaN box may refuse the merge where this says it happens; such a leaf is
/// no less correct, only merged where the cost model could not decide.
pub fn merged_leaf_size(max_leaf: u32, cost: f32) -> usize {
    (1..=TINY_LEAF).rev().find(|&m| m as u32 <= max_leaf && m as f32 <= cost).unwrap_or(1)
}

/// A split of a node's primitives: the left part's size, both parts' bounds, and whether the parts
/// were moved into the scratch buffer (else they are in place).
type Parts = (usize, Bounds, Bounds, bool);

/// Splits `refs` (2 or more) into a left and a right part, both non-empty: returns the left one's
/// size, both parts' bounds, and whether the parts are in `spare` (else in `refs`).
#[inline(never)]
fn split(refs: &mut [PrimRef], spare: &mut [PrimRef], bounds: &Bounds, depth: u32, block_shift: u32) -> Parts {
    let m = refs.len();
    if m == 2 {
        return (1, Bounds::of(&refs[..1]), Bounds::of(&refs[1..]), false);
    }
    if m <= TINY {
        // The leaf collapse merges any subtree of three and most of four (`Bvh4::from_bvh2`):
        // their shape hardly matters, and sorting along the widest axis does.
        sort_along_widest_axis(refs, bounds);
        let left = m / 2;
        return (left, Bounds::of(&refs[..left]), Bounds::of(&refs[left..]), false);
    }
    if m <= SMALL {
        let left = small_split(refs, block_shift);
        return (left, Bounds::of(&refs[..left]), Bounds::of(&refs[left..]), false);
    }
    if depth < SAH_DEPTH {
        let binning = Binning::of(&bounds.centroids, m);
        let found = if binning.count <= SMALL_BINS {
            binned_split::<SMALL_BINS>(refs, spare, &binning, block_shift)
        } else {
            binned_split::<BINS>(refs, spare, &binning, block_shift)
        };
        if let Some(found) = found {
            return found;
        }
    }
    // All centroids in one bin on every axis (or too deep): the median along the widest axis of the
    // centroids, ties broken by input index so that the result depends on the input alone.
    let extent = bounds.centroids.max - bounds.centroids.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let half = m / 2;
    refs.select_nth_unstable_by(half, |a, b| {
        a.centroid2()[axis].total_cmp(&b.centroid2()[axis]).then(a.id().cmp(&b.id()))
    });
    (half, Bounds::of(&refs[..half]), Bounds::of(&refs[half..]), false)
}

/// The bins of [`binned_split`] for fewer primitives (`Binning::count` at most this).
const SMALL_BINS: usize = 8;

/// [`split`] by binning into sets of `N` bins: the parts are in `spare`. `None` when every axis has
/// all primitives in one bin.
fn binned_split<const N: usize>(
    refs: &mut [PrimRef],
    spare: &mut [PrimRef],
    binning: &Binning,
    block_shift: u32,
) -> Option<Parts> {
    let m = refs.len();
    if m > PARALLEL_BINNING {
        return parallel_binned_split::<N>(refs, spare, binning, block_shift);
    }
    let bins = Bins::<N>::fill(binning, refs);
    let (axis, k) = bins.best_split(binning.count, block_shift)?;
    let (left_count, lc, rc) = partition(refs, spare, |c| binning.left_of(c, axis, k));
    // `best_split` only splits between two non-empty sides, counted by the same test.
    debug_assert!(left_count > 0 && left_count < m);
    if left_count == 0 || left_count == m {
        return None;
    }
    let (lb, rb) = bins.sides(binning.count, axis, k, [lc, rc]);
    Some((left_count, lb, rb, true))
}

/// [`binned_split`] of many primitives, in chunks of [`BINNING_CHUNK`] on the pool's threads:
/// each chunk is binned, and then moved to its places on both sides (the chunks' own bins say how
/// many of each go left, so each has its ranges of `spare` before any moves). The chunks are the
/// same whatever the number of threads, so the result is too.
fn parallel_binned_split<const N: usize>(
    refs: &mut [PrimRef],
    spare: &mut [PrimRef],
    binning: &Binning,
    block_shift: u32,
) -> Option<Parts> {
    let m = refs.len();
    let chunk_bins: Vec<Bins<N>> = refs.par_chunks(BINNING_CHUNK).map(|c| Bins::<N>::fill(binning, c)).collect();
    let bins = chunk_bins.iter().fold(Bins::<N>::new(), |a, b| a.merge_bins(b, binning.count));
    let (axis, k) = bins.best_split(binning.count, block_shift)?;
    let lefts: Vec<usize> =
        chunk_bins.iter().map(|b| b.bins[axis][..k].iter().map(|c| c.count() as usize).sum()).collect();
    let left_count: usize = lefts.iter().sum();
    if left_count == 0 || left_count == m {
        return None;
    }
    // Each chunk's ranges on the left and on the right, in chunk order.
    let (mut left_rest, mut right_rest) = spare.split_at_mut(left_count);
    let mut places = Vec::with_capacity(lefts.len());
    for (chunk, &l) in refs.chunks(BINNING_CHUNK).zip(&lefts) {
        let r = chunk.len().checked_sub(l)?;
        if l > left_rest.len() || r > right_rest.len() {
            return None;
        }
        let (lp, lr) = std::mem::take(&mut left_rest).split_at_mut(l);
        let (rp, rr) = std::mem::take(&mut right_rest).split_at_mut(r);
        (left_rest, right_rest) = (lr, rr);
        places.push((chunk, lp, rp));
    }
    let moved: Vec<Option<(Aabb, Aabb)>> = places
        .into_par_iter()
        .map(|(chunk, lp, rp)| {
            let (mut li, mut ri) = (0, 0);
            let mut sides = SideBounds::EMPTY;
            // Without branches on the side (as `partition`): the side picks the destination.
            for p in chunk {
                let c = p.centroid2();
                let go = binning.left_of(c, axis, k);
                let (out, i) = if go { (&mut *lp, li) } else { (&mut *rp, ri) };
                // The chunk's bins counted its sides with the same test, so the ranges fit; a
                // mismatch would leave the parts unfinished, and the caller falls back.
                *out.get_mut(i)? = *p;
                li += usize::from(go);
                ri += usize::from(!go);
                sides.add(c, go);
            }
            let [lc, rc] = sides.boxes();
            (li == lp.len() && ri == rp.len()).then_some((lc, rc))
        })
        .collect();
    let mut centroids = (Aabb::empty(), Aabb::empty());
    for sides in moved {
        let (lc, rc) = sides?;
        centroids = (centroids.0.union(&lc), centroids.1.union(&rc));
    }
    let (lb, rb) = bins.sides(binning.count, axis, k, [centroids.0, centroids.1]);
    Some((left_count, lb, rb, true))
}

impl<const N: usize> Bins<N> {
    /// The bounds of both sides of a split before bin `k` on `axis` (of `count` bins): their boxes
    /// are those of their bins, their centroids' boxes `[left, right]` are given.
    fn sides(&self, count: usize, axis: usize, k: usize, [lc, rc]: [Aabb; 2]) -> (Bounds, Bounds) {
        let side = |bins_of: &[Bin]| bins_of.iter().fold(Aabb::empty(), |a, b| a.union(&b.aabb()));
        let (lg, rg) = (side(&self.bins[axis][..k]), side(&self.bins[axis][k..count]));
        (Bounds { geometry: lg, centroids: lc }, Bounds { geometry: rg, centroids: rc })
    }
}

/// Nodes of at most this many primitives are split by sorting them along each axis and trying
/// every split of the sorted order (exact, and cheaper than bins for a few primitives).
const SMALL: usize = 8;

/// Nodes of at most this many primitives are split in half along the widest axis of their
/// centroids.
const TINY: usize = 4;

/// Splits `refs` (3 to [`SMALL`]) by sorted centroids: the split of least cost (sides counted in
/// blocks, [`blocks`]) over the three axes' orders. Reorders `refs` into the chosen order; returns
/// the left side's size.
fn small_split(refs: &mut [PrimRef], block_shift: u32) -> usize {
    let m = refs.len().min(SMALL);
    let mut items = [refs[0]; SMALL];
    items[..m].copy_from_slice(&refs[..m]);
    let centroids: [Vec3A; SMALL] = std::array::from_fn(|i| items[i].centroid2());
    let mut best = (f32::INFINITY, 0usize, 1usize);
    let mut orders = [[0u8; SMALL]; 3];
    for (axis, order) in orders.iter_mut().enumerate() {
        let keys: [f32; SMALL] = std::array::from_fn(|i| centroids[i][axis]);
        *order = stable_order(&keys, m);
        let mut right = [0.0f32; SMALL];
        let (mut lo, mut hi) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
        for i in (1..m).rev() {
            let p = &items[usize::from(order[i])];
            (lo, hi) = (lo.min(p.lo()), hi.max(p.hi()));
            right[i] = half_area(hi - lo) * blocks((m - i) as u32, block_shift);
        }
        let (mut lo, mut hi) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
        for i in 1..m {
            let p = &items[usize::from(order[i - 1])];
            (lo, hi) = (lo.min(p.lo()), hi.max(p.hi()));
            let cost = half_area(hi - lo) * blocks(i as u32, block_shift) + right[i];
            if cost < best.0 {
                best = (cost, axis, i);
            }
        }
    }
    let (_, axis, left) = best;
    for (r, &k) in refs.iter_mut().zip(&orders[axis][..m]) {
        *r = items[usize::from(k)];
    }
    left
}

/// The indices of `keys[..m]` (`m` at most [`SMALL`]) in ascending order of their keys, ties in
/// index order: an insertion sort's order, where no key is NaN. Without branches on the keys (an
/// insertion sort's comparisons are as good as random to the branch predictor): each key's place
/// is the number of keys below it and of equal keys before it, counted eight at a time.
fn stable_order(keys: &[f32; SMALL], m: usize) -> [u8; SMALL] {
    const _: () = assert!(SMALL == 8, "one i32x8 of keys");
    // Integers in the keys' order (`f32::total_cmp`'s), with -0 made +0 first: the two are equal to
    // an insertion sort's comparisons.
    let ordered = keys.map(|k| {
        let b = (k + 0.0).to_bits() as i32;
        b ^ (((b >> 31) as u32) >> 1) as i32
    });
    let all = wide::i32x8::new(ordered);
    let live = (1u32 << m.min(SMALL)) - 1;
    let mut order = [0u8; SMALL];
    for (i, &k) in ordered.iter().enumerate().take(m) {
        let k = wide::i32x8::splat(k);
        let below = all.simd_lt(k).to_bitmask() & live;
        let equal_before = all.simd_eq(k).to_bitmask() & ((1u32 << i) - 1);
        // Ranks are distinct (ties are told apart by index), so each lands once.
        order[(below.count_ones() + equal_before.count_ones()) as usize & (SMALL - 1)] = i as u8;
    }
    order
}

/// Half the surface area of a box of extent `d` (as [`Aabb::half_area`]).
#[inline(always)]
fn half_area(d: Vec3A) -> f32 {
    (d.x + d.y) * d.z + d.x * d.y
}

/// Moves `refs` into `out`, those whose doubled centroid `left` accepts to the front, keeping
/// their order, the others to the back, in reverse order: returns how many went to the front and
/// the bounds of both sides' doubled centroids. Without branches on `left` (its answers are as
/// good as random to the branch predictor): the side selects the cursor a primitive is written at
/// (a conditional move), and only that cursor moves.
fn partition(refs: &[PrimRef], out: &mut [PrimRef], left: impl Fn(Vec3A) -> bool) -> (usize, Aabb, Aabb) {
    debug_assert_eq!(refs.len(), out.len());
    let (mut front, mut back) = (0usize, out.len());
    let mut sides = SideBounds::EMPTY;
    for p in refs {
        let c = p.centroid2();
        let go = left(c);
        // `front <= back - 1` while primitives remain: each one moves exactly one cursor.
        out[if go { front } else { back - 1 }] = *p;
        front += usize::from(go);
        back -= usize::from(!go);
        sides.add(c, go);
    }
    let [left, right] = sides.boxes();
    (front, left, right)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = Vec3A::new(next(), next(), next()) * 100.0;
                let e = Vec3A::new(next(), next(), next());
                Aabb::new(c - e, c + e)
            })
            .collect()
    }

    /// Checks the tree's structure: every node written, children inside their parent, every
    /// primitive in exactly one leaf whose box holds it; returns the depth.
    fn check(bvh: &Bvh2, boxes: &[Aabb]) -> usize {
        check_with_leaves(bvh, boxes, 1)
    }

    /// [`check`] for trees with leaves of up to `largest` primitives.
    fn check_with_leaves(bvh: &Bvh2, boxes: &[Aabb], largest: u32) -> usize {
        assert_eq!(bvh.nodes.len(), 2 * boxes.len() - 1);
        let mut seen = vec![0u32; boxes.len()];
        let mut stack = vec![(0usize, 1usize)];
        let mut deepest = 0;
        while let Some((i, d)) = stack.pop() {
            deepest = deepest.max(d);
            let node = &bvh.nodes[i];
            if node.is_leaf() {
                assert!(node.prim_count <= largest);
                for k in 0..node.prim_count as usize {
                    let p = bvh.primitive_indices[node.first_index as usize + k] as usize;
                    seen[p] += 1;
                    assert!(node.aabb.min.cmple(boxes[p].min).all() && node.aabb.max.cmpge(boxes[p].max).all());
                }
                continue;
            }
            for c in [node.first_index as usize, node.first_index as usize + 1] {
                let child = &bvh.nodes[c];
                assert!(node.aabb.min.cmple(child.aabb.min).all() && node.aabb.max.cmpge(child.aabb.max).all());
                stack.push((c, d + 1));
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        deepest
    }

    #[test]
    fn every_primitive_lands_in_one_leaf_inside_its_ancestors() {
        for n in [1, 2, 3, 5, 17, 100, 5000, 70_000] {
            let boxes = random_boxes(n, n as u64);
            let bvh = build_binned(&boxes);
            check(&bvh, &boxes);
        }
    }

    /// Sides counted in blocks of four: eight unit cubes, five side by side and three apart, are
    /// split four and four (two full blocks), where counting each primitive splits off the three.
    #[test]
    fn block_costs_fill_blocks() {
        let cube = |x: f32| Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0));
        let boxes: Vec<Aabb> = [0.0, 1.0, 2.0, 3.0, 4.0, 10.0, 11.0, 12.0].map(cube).to_vec();
        let refs = |order: &[usize]| order.iter().map(|&i| PrimRef::new(&boxes[i], i as u32)).collect::<Vec<_>>();
        for order in [[0, 1, 2, 3, 4, 5, 6, 7], [7, 3, 5, 0, 6, 1, 4, 2]] {
            assert_eq!(small_split(&mut refs(&order), 0), 5);
            assert_eq!(small_split(&mut refs(&order), 2), 4);
        }
    }

    #[test]
    fn the_layout_depends_on_the_input_alone() {
        // More than `PARALLEL_BINNING` primitives: the top nodes are split chunk by chunk.
        let boxes = random_boxes(2 * PARALLEL_BINNING + 5000, 7);
        let a = build_binned(&boxes);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let b = pool.install(|| build_binned(&boxes));
        assert_eq!(a.primitive_indices, b.primitive_indices);
        assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| bytemuck::bytes_of(x) == bytemuck::bytes_of(y)));
    }

    #[test]
    fn coincident_and_degenerate_inputs_stay_shallow() {
        // All in one place: median splits only.
        let same = vec![Aabb::new(Vec3A::ONE, Vec3A::splat(2.0)); 10_000];
        assert!(check(&build_binned(&same), &same) <= 16);
        // Centroids at powers of two, where every cheapest split cuts off one primitive: the cost
        // splits stop at `SAH_DEPTH`, the median splits below halve.
        let spread: Vec<Aabb> = (0..3000)
            .map(|i| {
                let x = 1.001f32.powi(i * 20);
                Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x, 1.0, 1.0))
            })
            .collect();
        assert!(check(&build_binned(&spread), &spread) <= SAH_DEPTH as usize + 14);
        // Extreme magnitudes side by side (the centroid box's extent overflows to infinity): every
        // primitive still lands in one leaf.
        let extreme: Vec<Aabb> = (0..5000)
            .map(|i| {
                let x = [3e38f32, -3e38, 1e-30, 0.0, 1e20][i % 5] * if i % 2 == 0 { 1.0 } else { 0.5 };
                Aabb::new(Vec3A::new(x, i as f32, 0.0), Vec3A::new(x, i as f32 + 1.0, 1.0))
            })
            .collect();
        check(&build_binned(&extreme), &extreme);
    }

    /// Leaves of up to three primitives collapse into the same 4-wide tree as leaves of one: the
    /// same nodes and the same primitive order, on random and coincident inputs of
    /// sizes around the small-split thresholds and past the parallel ones.
    #[test]
    fn small_leaves_collapse_to_the_same_tree() {
        use crate::accel::bvh4::{BuildQuality, Bvh4};
        use crate::accel::object::OBJECT_LEAF_SIZE;
        let p = BuildQuality::High.params(OBJECT_LEAF_SIZE);
        let leaf = merged_leaf_size(p.max_prims_per_leaf, p.collapse_traversal_cost);
        assert_eq!(leaf, 3);
        let mut inputs: Vec<Vec<Aabb>> = [2, 3, 4, 5, 7, 9, 17, 33, 100, 5000, PARALLEL_BINNING + 3000]
            .map(|n| random_boxes(n, 3 * n as u64))
            .into();
        inputs.push(vec![Aabb::new(Vec3A::ONE, Vec3A::splat(2.0)); 1000]);
        for boxes in inputs {
            let mut ones = build_binned(&boxes);
            let mut threes = build_binned_with_leaves(&boxes, leaf);
            check_with_leaves(&threes, &boxes, 3);
            let a = Bvh4::from_bvh2(&mut ones, p.max_prims_per_leaf, p.collapse_traversal_cost);
            let b = Bvh4::from_bvh2(&mut threes, p.max_prims_per_leaf, p.collapse_traversal_cost);
            assert_eq!(a.prim_order, b.prim_order, "{} primitives", boxes.len());
            assert_eq!(a.depth, b.depth);
            assert!(a.nodes == b.nodes, "{} primitives", boxes.len());
        }
        // A leaf size the collapse would not merge is refused down to one that it would.
        assert_eq!(merged_leaf_size(OBJECT_LEAF_SIZE, 1.5), 1);
        assert_eq!(merged_leaf_size(2, 3.0), 2);
        assert_eq!(merged_leaf_size(1, 3.0), 1);
    }

    #[test]
    fn stable_order_sorts_as_an_insertion_sort_does() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut pick = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            [-1.5f32, -0.0, 0.0, 2.0, 7.25, 1e30, -1e-30, f32::INFINITY][(state % 8) as usize]
        };
        for round in 0..4000 {
            let m = 1 + round % SMALL;
            let keys: [f32; SMALL] = std::array::from_fn(|_| pick());
            // The insertion sort `small_split` sorted with before.
            let mut expected: [u8; SMALL] = std::array::from_fn(|i| i as u8);
            for i in 1..m {
                let k = expected[i];
                let mut j = i;
                while j > 0 && keys[usize::from(expected[j - 1])] > keys[usize::from(k)] {
                    expected[j] = expected[j - 1];
                    j -= 1;
                }
                expected[j] = k;
            }
            assert_eq!(stable_order(&keys, m)[..m], expected[..m], "{keys:?}, {m} keys");
        }
        // NaN keys have no place in an insertion sort's order, but every index still lands once.
        let keys = [f32::NAN, 1.0, -f32::NAN, 0.0, f32::NAN, -2.0, 3.0, f32::NAN];
        for m in 1..=SMALL {
            let mut order = stable_order(&keys, m)[..m].to_vec();
            order.sort_unstable();
            assert_eq!(order, (0..m as u8).collect::<Vec<_>>());
        }
    }

    #[test]
    fn separated_clusters_split_between_them() {
        // Two clusters far apart: the root's children are the clusters.
        let mut boxes = random_boxes(500, 1);
        boxes.extend(random_boxes(300, 2).iter().map(|b| Aabb::new(b.min + 1000.0, b.max + 1000.0)));
        let bvh = build_binned(&boxes);
        let root = &bvh.nodes[0];
        let sizes: Vec<f32> = (0..2).map(|k| bvh.nodes[root.first_index as usize + k].aabb.diagonal().x).collect();
        assert!(sizes.iter().all(|&s| s < 110.0), "children {sizes:?}");
    }

    /// Coordinates that exercise the packed forms: signed zeros (`maxps` and the negated `minps`
    /// must pick the same one), equal values, and large and tiny magnitudes.
    fn awkward_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let values = [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-30, 3e38, -3e38, 0.5, 7.25];
        let mut s = seed;
        let mut pick = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            values[(s >> 33) as usize % values.len()]
        };
        (0..n)
            .map(|_| {
                let (a, b) = (Vec3A::new(pick(), pick(), pick()), Vec3A::new(pick(), pick(), pick()));
                Aabb::new(a.min(b), a.max(b))
            })
            .collect()
    }

    fn same_bits(a: Vec3A, b: Vec3A) -> bool {
        a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)
    }

    #[test]
    fn a_bin_holds_the_box_and_count_of_its_primitives_bit_for_bit() {
        for seed in 0..20 {
            let boxes: Vec<Aabb> = if seed % 2 == 0 { awkward_boxes(200, seed) } else { random_boxes(200, seed) };
            let mut bins = [Bin::EMPTY; 2];
            // As an `Aabb` grows: `minps(acc, x)` and `maxps(acc, x)`.
            let mut expected = [Aabb::empty(); 2];
            for (i, b) in boxes.iter().enumerate() {
                let p = PrimRef::new(b, i as u32 * 7919);
                assert!(same_bits(p.hi(), b.max));
                assert!(same_bits(p.centroid2(), b.min + b.max));
                let k = usize::from(i % 3 == 0);
                bins[k].add(p.wide());
                expected[k] = Aabb { min: expected[k].min.min(b.min), max: expected[k].max.max(b.max) };
            }
            assert_eq!((bins[0].count(), bins[1].count()), (133, 67));
            let merged = bins[0].merge(&bins[1]);
            assert_eq!(merged.count(), 200);
            let pairs = [
                (bins[0].aabb(), expected[0]),
                (bins[1].aabb(), expected[1]),
                (merged.aabb(), expected[0].union(&expected[1])),
            ];
            for (got, want) in pairs {
                assert!(
                    same_bits(got.min, want.min) && same_bits(got.max, want.max),
                    "seed {seed}: {got:?} against {want:?}"
                );
            }
        }
        assert_eq!(Bin::EMPTY.count(), 0);
        let empty = Bin::EMPTY.aabb();
        assert!(empty.min.cmpgt(empty.max).all());
    }

    /// A thread that treats denormals as zero (an application's choice for its threads) still
    /// counts: the count lanes are normal floats. Run on a thread of its own with a pool of its own
    /// (new threads inherit the flags), so that no other test's threads get them.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(deprecated)] // `_mm_getcsr` and `_mm_setcsr`: there is no other way to set the flags
    fn bins_count_with_denormals_flushed_to_zero() {
        use std::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        const FTZ_DAZ: u32 = 0x8040;
        let boxes = random_boxes(PARALLEL_BINNING + 3000, 7);
        let flushed = std::thread::spawn({
            let boxes = boxes.clone();
            move || {
                // SAFETY: changes only this thread's flush-to-zero and denormals-are-zero flags
                // (and those of the pool it starts below); the thread ends with the test.
                unsafe { _mm_setcsr(_mm_getcsr() | FTZ_DAZ) };
                let mut bin = Bin::EMPTY;
                for (i, b) in boxes.iter().take(300).enumerate() {
                    bin.add(PrimRef::new(b, i as u32).wide());
                }
                assert_eq!((bin.count(), bin.merge(&bin).count()), (300, 600));
                let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
                pool.install(|| build_binned(&boxes))
            }
        })
        .join()
        .unwrap();
        let plain = build_binned(&boxes);
        check(&flushed, &boxes);
        // The same tree: the flags change only the unused fourth lanes of the nodes' boxes.
        assert_eq!(flushed.primitive_indices, plain.primitive_indices);
        let boxes_of = |bvh: &Bvh2| -> Vec<([f32; 3], [f32; 3], u32, u32)> {
            bvh.nodes
                .iter()
                .map(|n| (n.aabb.min.to_array(), n.aabb.max.to_array(), n.prim_count, n.first_index))
                .collect()
        };
        assert_eq!(boxes_of(&flushed), boxes_of(&plain));
    }

    #[test]
    fn side_bounds_match_the_boxes_of_each_side_bit_for_bit() {
        for seed in 0..20 {
            let boxes = if seed % 2 == 0 { awkward_boxes(300, seed) } else { random_boxes(300, seed) };
            let refs: Vec<PrimRef> = boxes.iter().enumerate().map(|(i, b)| PrimRef::new(b, i as u32)).collect();
            let left = |c: Vec3A| c.x + c.y < c.z;
            let mut out = vec![PrimRef::new(&Aabb::empty(), 0); refs.len()];
            let (count, lc, rc) = partition(&refs, &mut out, left);
            let mut expected = [Aabb::empty(), Aabb::empty()];
            for p in &refs {
                let c = p.centroid2();
                let side = &mut expected[usize::from(!left(c))];
                (side.min, side.max) = (side.min.min(c), side.max.max(c));
            }
            assert_eq!(count, refs.iter().filter(|p| left(p.centroid2())).count());
            for (got, want) in [lc, rc].iter().zip(&expected) {
                assert!(same_bits(got.min, want.min) && same_bits(got.max, want.max), "seed {seed}");
            }
            // The left side keeps its order at the front, the right side its order reversed at the back.
            let ids: Vec<u32> = out.iter().map(PrimRef::id).collect();
            let mut want: Vec<u32> = refs.iter().filter(|p| left(p.centroid2())).map(PrimRef::id).collect();
            want.extend(refs.iter().rev().filter(|p| !left(p.centroid2())).map(PrimRef::id));
            assert_eq!(ids, want);
        }
    }
}

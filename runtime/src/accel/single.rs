//! Single-ray traversal of the two-level BVH, and the brute-force reference.
//!
//! Object BVHs are traversed through their 8-wide form ([`super::bvh8`]), the top level through
//! its 4-wide nodes; one generic loop serves both (`WideNode`). An 8-wide node's boxes are tested
//! with one eight-lane slab test (wide's `f32x8`: one AVX register on `x86-64-v3`), a 4-wide
//! node's with one SSE test (glam's `Vec4`), the same operations; hit children are visited nearest first, and
//! popped entries farther than the current closest hit are skipped. This is the path for
//! incoherent rays and the fallback of packet traversal.
//!
//! Invariant: traversal state (`tmax`, the hit record) lives in `RayPre` and is shared between
//! the levels: `t` is the same number in world and object space because origin and direction are
//! transformed by the same affine map.

use super::bvh4::{leaf_range, Node4, EMPTY_CHILD, LEAF_BIT};
use super::bvh8::Node8;
use super::object::{Object, ObjectBvh, Parts, NO_TRIANGLE};
use super::stack::Stack;
use super::top::{InstanceData, TopLevel};
use super::{prefetch, safe_inv, FUSED_MARGIN, ROBUST};
use crate::geometry::triangle::{accept, intersect, PreTriangle, TriangleBlock, BLOCK_WIDTH};
use crate::ray::{Hit, HitCandidate, HitFilter, Ray, INVALID_ID};
use glam::{Vec3A, Vec4};
use wide::{f32x8, i32x8};

/// Traversal stack depth that fits on the machine stack; deeper BVHs use a heap stack.
pub(crate) const STACK: usize = 96;

/// A ray prepared for slab tests.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayPre {
    pub o: [f32; 3],
    pub d: [f32; 3],
    /// The inverse direction.
    id: [f32; 3],
    /// The inverse direction times [`ROBUST`], for the far planes (see [`slab4`]).
    fid: [f32; 3],
    neg: [bool; 3],
    /// The offsets of the fused slab test (see [`slab4`]): `-(o * id)` moved down by
    /// [`FUSED_MARGIN`] of itself, and `-(o * fid)` moved up by as much.
    near_c: [f32; 3],
    far_c: [f32; 3],
    /// Whether the slab tests may take the fused form and order distances as integers: every
    /// offset is finite and every inverse direction nonzero (so no distance is NaN), `tmin` is
    /// `+0.0` or above and `tmax` is not NaN (see [`slab8`]).
    fused: bool,
    pub tmin: f32,
    pub tmax: f32,
    /// The ray's time (where moving instances are).
    pub time: f32,
}

impl RayPre {
    #[inline(always)]
    pub fn new(o: Vec3A, d: Vec3A, tmin: f32, tmax: f32) -> Self {
        let id = [safe_inv(d.x), safe_inv(d.y), safe_inv(d.z)];
        let fid = id.map(|i| i * ROBUST);
        let o = o.to_array();
        // `-a` scaled away from zero (down) or towards it (up) by the margin: no `inf - inf`. A
        // zero offset is `+0.0`, so that no fused distance is `-0.0` ([`slab8`]).
        let down = |a: f32| -a * if a > 0.0 { 1.0 + FUSED_MARGIN } else { 1.0 - FUSED_MARGIN } + 0.0;
        let up = |a: f32| -a * if a > 0.0 { 1.0 - FUSED_MARGIN } else { 1.0 + FUSED_MARGIN } + 0.0;
        let near_c: [f32; 3] = std::array::from_fn(|k| down(o[k] * id[k]));
        let far_c: [f32; 3] = std::array::from_fn(|k| up(o[k] * fid[k]));
        RayPre {
            o,
            d: d.to_array(),
            id,
            fid,
            near_c,
            far_c,
            fused: near_c.iter().chain(&far_c).all(|c| c.is_finite())
                && id.iter().all(|&i| i != 0.0)
                && tmin >= 0.0
                && tmin.is_sign_positive()
                && !tmax.is_nan(),
            neg: [id[0] < 0.0, id[1] < 0.0, id[2] < 0.0],
            tmin,
            tmax,
            time: 0.0,
        }
    }

    /// The same ray at `time`.
    #[inline(always)]
    pub fn at_time(self, time: f32) -> Self {
        RayPre { time, ..self }
    }

    /// A world-space ray, at its time.
    #[inline(always)]
    pub fn of(ray: &Ray) -> Self {
        RayPre { time: ray.time, ..RayPre::new(ray.origin, ray.direction, ray.tmin, ray.tmax) }
    }

    /// This ray moved into the object space of `inst` (where `inst` is at the ray's time).
    #[inline(always)]
    pub fn in_object_space(&self, inst: &InstanceData) -> Self {
        if inst.identity {
            return *self;
        }
        let moving;
        let xf = if inst.motion.is_some() {
            moving = inst.object_from_world_at(self.time);
            &moving
        } else {
            &inst.object_from_world
        };
        let o = xf.transform_point3a(Vec3A::from(self.o));
        let d = xf.transform_vector3a(Vec3A::from(self.d));
        RayPre { time: self.time, ..RayPre::new(o, d, self.tmin, self.tmax) }
    }
}

/// A node that single-ray traversal reads: the 4-wide nodes of both levels and the 8-wide nodes of
/// object BVHs.
pub(crate) trait WideNode {
    /// Cache lines of one node (prefetched whole).
    const LINES: usize;
    /// Tests the child boxes: the hit mask and the entry distances (entries beyond the width are
    /// not meaningful).
    fn hits(&self, r: &RayPre) -> (u32, [f32; 8]);
    /// Child reference `k`.
    fn child(&self, k: usize) -> u32;
}

impl WideNode for Node4 {
    const LINES: usize = 2;

    #[inline(always)]
    fn hits(&self, r: &RayPre) -> (u32, [f32; 8]) {
        let (mask, t) = slab4([&self.min_x, &self.max_x, &self.min_y, &self.max_y, &self.min_z, &self.max_z], r);
        let mut all = [0.0; 8];
        t.write_to_slice(&mut all[..4]);
        (mask, all)
    }

    #[inline(always)]
    fn child(&self, k: usize) -> u32 {
        self.child[k]
    }
}

impl WideNode for Node8 {
    const LINES: usize = 4;

    #[inline(always)]
    fn hits(&self, r: &RayPre) -> (u32, [f32; 8]) {
        let (mask, t) = slab8([&self.min_x, &self.max_x, &self.min_y, &self.max_y, &self.min_z, &self.max_z], r);
        (mask, t.to_array())
    }

    #[inline(always)]
    fn child(&self, k: usize) -> u32 {
        self.child[k]
    }
}

/// Tests four boxes, given as `[min_x, max_x, min_y, max_y, min_z, max_z]` of four each: returns
/// the hit mask and the entry distances.
///
/// Robustness (Ize 2013): the far distances are scaled by [`ROBUST`] through the inverse direction
/// (`(f - o) * (inv * ROBUST)`) rather than after the slab minimum (`min(..) * ROBUST`): both are
/// the exact far distance times `ROBUST` times four rounding factors (subtraction, reciprocal and two
/// products; rounding is monotonic, so it commutes with `min`), so the bound, and with it
/// conservativeness, is the same, while one multiplication leaves the node-to-node dependency
/// chain (single-ray traversal is bound by that latency: measured on s1500k). Where the ray's
/// offsets are finite, each distance is one fused multiply-add ([`FUSED_MARGIN`]).
#[inline(always)]
fn slab4(b: [&[f32; 4]; 6], r: &RayPre) -> (u32, Vec4) {
    let (nx, fx) = if r.neg[0] { (b[1], b[0]) } else { (b[0], b[1]) };
    let (ny, fy) = if r.neg[1] { (b[3], b[2]) } else { (b[2], b[3]) };
    let (nz, fz) = if r.neg[2] { (b[5], b[4]) } else { (b[4], b[5]) };
    let s = Vec4::splat;
    let v = Vec4::from_array;
    let [tnx, tny, tnz, tfx, tfy, tfz] = if r.fused {
        [
            mul_add4(v(*nx), s(r.id[0]), s(r.near_c[0])),
            mul_add4(v(*ny), s(r.id[1]), s(r.near_c[1])),
            mul_add4(v(*nz), s(r.id[2]), s(r.near_c[2])),
            mul_add4(v(*fx), s(r.fid[0]), s(r.far_c[0])),
            mul_add4(v(*fy), s(r.fid[1]), s(r.far_c[1])),
            mul_add4(v(*fz), s(r.fid[2]), s(r.far_c[2])),
        ]
    } else {
        [
            (v(*nx) - s(r.o[0])) * s(r.id[0]),
            (v(*ny) - s(r.o[1])) * s(r.id[1]),
            (v(*nz) - s(r.o[2])) * s(r.id[2]),
            (v(*fx) - s(r.o[0])) * s(r.fid[0]),
            (v(*fy) - s(r.o[1])) * s(r.fid[1]),
            (v(*fz) - s(r.o[2])) * s(r.fid[2]),
        ]
    };
    let tnear = tnx.max(tny).max(tnz.max(Vec4::splat(r.tmin)));
    let tfar = tfx.min(tfy).min(tfz.min(Vec4::splat(r.tmax * ROBUST)));
    (tnear.cmple(tfar).bitmask(), tnear)
}

/// `a * b + c` as `f32x8::mul_add` computes it, lane by lane: fused where the build has fused
/// multiply-adds (`x86-64-v3`), else a product and a sum, each rounded (glam's `mul_add` would
/// then call the C library's exact `fmaf` for each lane, slowly, and differ from the 8-wide test).
#[inline(always)]
fn mul_add4(a: Vec4, b: Vec4, c: Vec4) -> Vec4 {
    #[cfg(target_feature = "fma")]
    return a.mul_add(b, c);
    #[cfg(not(target_feature = "fma"))]
    return a * b + c;
}

/// [`slab4`] of eight boxes at once (each coordinate eight floats, children 0-7), with the same
/// answers lane by lane: the same distances, and in the two-step form the same operations
/// (`f32x8`'s `fast_min` and `fast_max` are the `minps` and `maxps` that glam's `min` and `max`
/// are).
///
/// In the fused form the entry and exit distances are the maxima and minima of the floats' bits
/// as signed integers (`vpmaxsd`, `vpminsd`: a cycle each where `maxps` and `minps` take four on
/// Intel cores, and single-ray traversal is bound by the chain of each node's test). There no
/// distance is NaN or `-0.0` (a fused multiply-add gives `-0.0` only from a `-0.0` offset) and
/// `tmin` is `+0.0` or above ([`RayPre::fused`]), so the entry distance is the number `maxps`
/// gives, and the exit distance too where it is not negative; where it is negative the box is
/// missed either way. (A `tmax` of `-0.0`, after a hit at that distance, can let in boxes behind
/// the ray, which hold nothing nearer.)
#[inline(always)]
fn slab8(b: [&[[f32; 4]; 2]; 6], r: &RayPre) -> (u32, f32x8) {
    let row = |v: &[[f32; 4]; 2]| f32x8::new(bytemuck::cast(*v));
    let (nx, fx) = if r.neg[0] { (b[1], b[0]) } else { (b[0], b[1]) };
    let (ny, fy) = if r.neg[1] { (b[3], b[2]) } else { (b[2], b[3]) };
    let (nz, fz) = if r.neg[2] { (b[5], b[4]) } else { (b[4], b[5]) };
    let s = f32x8::splat;
    let [tnx, tny, tnz, tfx, tfy, tfz] = if r.fused {
        [
            row(nx).mul_add(s(r.id[0]), s(r.near_c[0])),
            row(ny).mul_add(s(r.id[1]), s(r.near_c[1])),
            row(nz).mul_add(s(r.id[2]), s(r.near_c[2])),
            row(fx).mul_add(s(r.fid[0]), s(r.far_c[0])),
            row(fy).mul_add(s(r.fid[1]), s(r.far_c[1])),
            row(fz).mul_add(s(r.fid[2]), s(r.far_c[2])),
        ]
    } else {
        [
            (row(nx) - s(r.o[0])) * s(r.id[0]),
            (row(ny) - s(r.o[1])) * s(r.id[1]),
            (row(nz) - s(r.o[2])) * s(r.id[2]),
            (row(fx) - s(r.o[0])) * s(r.fid[0]),
            (row(fy) - s(r.o[1])) * s(r.fid[1]),
            (row(fz) - s(r.o[2])) * s(r.fid[2]),
        ]
    };
    let (tmin, tmax) = (f32x8::splat(r.tmin), f32x8::splat(r.tmax * ROBUST));
    let (tnear, tfar) = if r.fused {
        let bits = |v: f32x8| -> i32x8 { bytemuck::cast(v) };
        let float = |v: i32x8| -> f32x8 { bytemuck::cast(v) };
        (
            float(bits(tnx).max(bits(tny)).max(bits(tnz).max(bits(tmin)))),
            float(bits(tfx).min(bits(tfy)).min(bits(tfz).min(bits(tmax)))),
        )
    } else {
        (tnx.fast_max(tny).fast_max(tnz.fast_max(tmin)), tfx.fast_min(tfy).fast_min(tfz.fast_min(tmax)))
    };
    (tnear.simd_le(tfar).to_bitmask(), tnear)
}

/// Traverses `bvh` from child reference `start` (0 for the root). `leaf(first, count, ray)` is called
/// for each leaf the ray reaches; it may shorten `ray.tmax`, and returns `true` to stop traversal
/// (then this function returns `true`). With `ORDERED`, hit children are visited nearest first
/// (closest hit); without, in child order, which saves the sort where any hit ends the traversal
/// (occlusion: the same nodes are visited either way). `prefetch_leaf(first)`
/// is called for hit leaf children (to prefetch their triangles); hit inner children are
/// prefetched here.
#[inline(always)]
pub(crate) fn traverse<const ORDERED: bool, N: WideNode, F: FnMut(u32, u32, &mut RayPre) -> bool, P: Fn(u32)>(
    nodes: &[N],
    start: u32,
    ray: &mut RayPre,
    prefetch_leaf: P,
    mut leaf: F,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    let mut stack: Stack<(u32, f32), STACK> = Stack::new();
    let mut cur = start;
    loop {
        // Descend towards the nearest hit child, pushing the others.
        while cur & LEAF_BIT == 0 {
            // Child references of inner nodes are valid node indices (bvh4 and bvh8 invariants).
            let node = &nodes[cur as usize];
            let (mask, t) = node.hits(ray);
            if mask == 0 {
                cur = EMPTY_CHILD;
                break;
            }
            let k0 = mask.trailing_zeros() as usize;
            let rest = mask & (mask - 1);
            if rest == 0 {
                cur = node.child(k0);
                continue;
            }
            // Sort the (2 to 8) hit children by entry distance, nearest last, and start loading
            // them all.
            let mut kids = [(0u32, 0f32); 8];
            let mut n = 0;
            let mut m = mask;
            while m != 0 {
                let k = m.trailing_zeros() as usize;
                m &= m - 1;
                let c = node.child(k);
                if c & LEAF_BIT == 0 {
                    prefetch(nodes.as_ptr().wrapping_add(c as usize), N::LINES);
                } else {
                    prefetch_leaf(leaf_range(c).0);
                }
                let mut j = n;
                while ORDERED && j > 0 && kids[j - 1].1 < t[k] {
                    kids[j] = kids[j - 1];
                    j -= 1;
                }
                kids[j] = (c, t[k]);
                n += 1;
            }
            for &kid in &kids[..n - 1] {
                stack.push(kid);
            }
            cur = kids[n - 1].0;
        }
        if cur != EMPTY_CHILD {
            let (first, count) = leaf_range(cur);
            if leaf(first, count, ray) {
                return true;
            }
        }
        // Pop the next entry that may still be nearer than the closest hit.
        loop {
            let Some((r, tn)) = stack.pop() else {
                return false;
            };
            if tn <= ray.tmax {
                cur = r;
                break;
            }
        }
    }
}

/// Closest-hit state of one ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HitState {
    pub u: f32,
    pub v: f32,
    pub instance: u32,
    pub primitive: u32,
}

impl HitState {
    pub const NONE: HitState = HitState { u: 0.0, v: 0.0, instance: INVALID_ID, primitive: INVALID_ID };
}

/// Closest hit of `ray` (in object space of `inst_id`) with object `obj`; updates `ray.tmax` and
/// `hit`. With `PARTS`, the object may be in parts ([`super::parts`]); without, it is whole.
#[inline(always)]
pub(crate) fn intersect_object<const PARTS: bool>(
    obj: &Object,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    hit: &mut HitState,
    filter: HitFilter,
    lane: u32,
) {
    let data = obj.data();
    if let Some(parts) = data.bvh.parts.as_deref().filter(|_| PARTS) {
        return intersect_parts(obj, &data.bvh, parts, inst_id, object_id, ray, hit, filter, lane);
    }
    intersect_tree(obj, &data.bvh, inst_id, object_id, ray, hit, filter, lane)
}

/// [`intersect_object`] with a whole tree, or one part.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn intersect_tree(
    obj: &Object,
    tree: &ObjectBvh,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    hit: &mut HitState,
    filter: HitFilter,
    lane: u32,
) {
    let blocks = &tree.blocks;
    match &tree.deformed {
        None => intersect_blocks(obj, tree, inst_id, object_id, ray, hit, filter, lane, |b, _| blocks[b]),
        Some(d) => {
            intersect_blocks(obj, tree, inst_id, object_id, ray, hit, filter, lane, |b, t| d.block_at(blocks, b, t))
        }
    }
}

/// [`intersect_object`] with a BVH in parts: the small tree's leaves are the parts' trees.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn intersect_parts(
    obj: &Object,
    small: &ObjectBvh,
    parts: &Parts,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    hit: &mut HitState,
    filter: HitFilter,
    lane: u32,
) {
    traverse::<true, _, _, _>(
        &small.wide.nodes,
        0,
        ray,
        |_| {},
        |p, _, ray| {
            intersect_tree(obj, obj.part(parts, p), inst_id, object_id, ray, hit, filter, lane);
            false
        },
    );
}

/// [`intersect_object`] with leaf block `b` at time `t` as `block(b, t)` makes it. A leaf's
/// triangles are tested at once; the hits are then taken in lane order, each while it is nearer
/// than the closest hit so far: the answer of testing them one by one.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn intersect_blocks(
    obj: &Object,
    tree: &ObjectBvh,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    hit: &mut HitState,
    filter: HitFilter,
    lane: u32,
    block: impl Fn(usize, f32) -> TriangleBlock,
) {
    let blocks = &tree.blocks;
    let order = &tree.bvh.prim_order;
    let pf = |b: u32| prefetch(blocks.as_ptr().wrapping_add(b as usize), 3);
    traverse::<true, _, _, _>(
        &tree.wide.nodes,
        0,
        ray,
        pf,
        #[inline(always)]
        |b, count, ray| {
            let (mask, t, u, v) = block(b as usize, ray.time).intersect(ray.o, ray.d, ray.tmin, ray.tmax);
            let mut bits = mask & ((1 << count) - 1);
            while bits != 0 {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (t, u, v) = (t[j], u[j], v[j]);
                // Accepted at the leaf's `tmax` (so not NaN); a nearer lane of the leaf may have come first.
                if t >= ray.tmax {
                    continue;
                }
                let primitive = order[BLOCK_WIDTH * b as usize + j];
                if !obj.solid_at(primitive, u, v) {
                    continue;
                }
                if let Some(f) = filter {
                    let c = HitCandidate { t, u, v, instance: inst_id, object: object_id, primitive, lane };
                    if !f(&c) {
                        continue;
                    }
                }
                ray.tmax = t;
                *hit = HitState { u, v, instance: inst_id, primitive };
            }
            false
        },
    );
}

/// Whether `ray` (in object space) hits object `obj` within its interval (`PARTS` as for
/// [`intersect_object`]).
#[inline(always)]
pub(crate) fn occluded_object<const PARTS: bool>(
    obj: &Object,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    filter: HitFilter,
    lane: u32,
) -> bool {
    let data = obj.data();
    if let Some(parts) = data.bvh.parts.as_deref().filter(|_| PARTS) {
        return occluded_parts(obj, &data.bvh, parts, inst_id, object_id, ray, filter, lane);
    }
    occluded_tree(obj, &data.bvh, inst_id, object_id, ray, filter, lane)
}

/// [`occluded_object`] with a whole tree, or one part.
#[inline(always)]
fn occluded_tree(
    obj: &Object,
    tree: &ObjectBvh,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    filter: HitFilter,
    lane: u32,
) -> bool {
    let blocks = &tree.blocks;
    match &tree.deformed {
        None => occluded_blocks(obj, tree, inst_id, object_id, ray, filter, lane, |b, _| blocks[b]),
        Some(d) => occluded_blocks(obj, tree, inst_id, object_id, ray, filter, lane, |b, t| d.block_at(blocks, b, t)),
    }
}

/// [`occluded_object`] with a BVH in parts.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn occluded_parts(
    obj: &Object,
    small: &ObjectBvh,
    parts: &Parts,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    filter: HitFilter,
    lane: u32,
) -> bool {
    traverse::<false, _, _, _>(
        &small.wide.nodes,
        0,
        ray,
        |_| {},
        |p, _, ray| occluded_tree(obj, obj.part(parts, p), inst_id, object_id, ray, filter, lane),
    )
}

/// [`occluded_object`] with leaf block `b` at time `t` as `block(b, t)` makes it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn occluded_blocks(
    obj: &Object,
    tree: &ObjectBvh,
    inst_id: u32,
    object_id: u32,
    ray: &mut RayPre,
    filter: HitFilter,
    lane: u32,
    block: impl Fn(usize, f32) -> TriangleBlock,
) -> bool {
    let blocks = &tree.blocks;
    let order = &tree.bvh.prim_order;
    let pf = |b: u32| prefetch(blocks.as_ptr().wrapping_add(b as usize), 3);
    traverse::<false, _, _, _>(
        &tree.wide.nodes,
        0,
        ray,
        pf,
        #[inline(always)]
        |b, count, ray| {
            let (mask, t, u, v) = block(b as usize, ray.time).intersect(ray.o, ray.d, ray.tmin, ray.tmax);
            let mut bits = mask & ((1 << count) - 1);
            while bits != 0 {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let primitive = order[BLOCK_WIDTH * b as usize + j];
                if !obj.solid_at(primitive, u[j], v[j]) {
                    continue;
                }
                match filter {
                    None => return true,
                    Some(f) => {
                        let c = HitCandidate {
                            t: t[j],
                            u: u[j],
                            v: v[j],
                            instance: inst_id,
                            object: object_id,
                            primitive,
                            lane,
                        };
                        if f(&c) {
                            return true;
                        }
                    }
                }
            }
            false
        },
    )
}

/// Closest hit of a world-space ray with the scene.
#[inline]
pub(crate) fn intersect_scene(top: &TopLevel, objects: &[Object], ray: &Ray, filter: HitFilter, lane: u32) -> Hit {
    match top.may_have_parts {
        true => intersect_scene_with::<true>(top, objects, ray, filter, lane),
        false => intersect_scene_with::<false>(top, objects, ray, filter, lane),
    }
}

/// [`intersect_scene`], whose objects may be in parts or not.
#[inline(never)]
fn intersect_scene_with<const PARTS: bool>(
    top: &TopLevel,
    objects: &[Object],
    ray: &Ray,
    filter: HitFilter,
    lane: u32,
) -> Hit {
    let mut r = RayPre::of(ray);
    let mut hit = HitState::NONE;
    if let Some(inst_id) = top.sole_instance() {
        // One instance: its object BVH's root test does the top level's culling.
        let inst = &top.instances[inst_id as usize];
        let mut o = r.in_object_space(inst);
        intersect_object::<PARTS>(&objects[inst.object as usize], inst_id, inst.object, &mut o, &mut hit, filter, lane);
        r.tmax = o.tmax;
    } else {
        traverse::<true, _, _, _>(
            &top.bvh.nodes,
            0,
            &mut r,
            |_| {},
            |first, count, r| {
                for s in first..first + count {
                    let inst_id = top.bvh.prim_order[s as usize];
                    let inst = &top.instances[inst_id as usize];
                    let mut o = r.in_object_space(inst);
                    intersect_object::<PARTS>(
                        &objects[inst.object as usize],
                        inst_id,
                        inst.object,
                        &mut o,
                        &mut hit,
                        filter,
                        lane,
                    );
                    r.tmax = o.tmax;
                }
                false
            },
        );
    }
    if hit.instance == INVALID_ID {
        Hit::MISS
    } else {
        Hit { t: r.tmax, u: hit.u, v: hit.v, instance: hit.instance, primitive: hit.primitive }
    }
}

/// Whether a world-space ray hits anything within its interval.
#[inline]
pub(crate) fn occluded_scene(top: &TopLevel, objects: &[Object], ray: &Ray, filter: HitFilter, lane: u32) -> bool {
    match top.may_have_parts {
        true => occluded_scene_with::<true>(top, objects, ray, filter, lane),
        false => occluded_scene_with::<false>(top, objects, ray, filter, lane),
    }
}

/// [`occluded_scene`], whose objects may be in parts or not.
#[inline(never)]
fn occluded_scene_with<const PARTS: bool>(
    top: &TopLevel,
    objects: &[Object],
    ray: &Ray,
    filter: HitFilter,
    lane: u32,
) -> bool {
    let mut r = RayPre::of(ray);
    if let Some(inst_id) = top.sole_instance() {
        let inst = &top.instances[inst_id as usize];
        let mut o = r.in_object_space(inst);
        return occluded_object::<PARTS>(&objects[inst.object as usize], inst_id, inst.object, &mut o, filter, lane);
    }
    traverse::<false, _, _, _>(
        &top.bvh.nodes,
        0,
        &mut r,
        |_| {},
        |first, count, r| {
            for s in first..first + count {
                let inst_id = top.bvh.prim_order[s as usize];
                let inst = &top.instances[inst_id as usize];
                let mut o = r.in_object_space(inst);
                if occluded_object::<PARTS>(&objects[inst.object as usize], inst_id, inst.object, &mut o, filter, lane)
                {
                    return true;
                }
            }
            false
        },
    )
}

/// The brute-force reference: tests every triangle of every instance, no BVH.
pub(crate) fn intersect_brute_force(top: &TopLevel, objects: &[Object], ray: &Ray, filter: HitFilter) -> Hit {
    let mut best = Hit::MISS;
    let mut tmax = ray.tmax;
    for (i, inst) in top.instances.iter().enumerate() {
        let Some(obj) = objects.get(inst.object as usize) else {
            continue;
        };
        let r = RayPre::of(ray).in_object_space(inst);
        for (tree, s) in live_slots(obj) {
            let (t, u, v) = intersect(r.o, r.d, &triangle_at(tree, s, ray.time));
            if accept(t, u, v, ray.tmin, tmax) {
                let primitive = tree.bvh.prim_order[s];
                if !obj.solid_at(primitive, u, v) {
                    continue;
                }
                if let Some(f) = filter {
                    let c = HitCandidate { t, u, v, instance: i as u32, object: inst.object, primitive, lane: 0 };
                    if !f(&c) {
                        continue;
                    }
                }
                tmax = t;
                best = Hit { t, u, v, instance: i as u32, primitive };
            }
        }
    }
    best
}

/// Leaf slot `s`'s triangle of `tree` at `time`.
fn triangle_at(tree: &ObjectBvh, s: usize, time: f32) -> PreTriangle {
    match &tree.deformed {
        None => tree.triangle(s),
        Some(d) => d.at(&tree.blocks, s, time),
    }
}

/// The leaf slots of `obj` that hold a triangle, each with the tree it is in (the whole tree, or
/// its part).
fn live_slots(obj: &Object) -> impl Iterator<Item = (&ObjectBvh, usize)> + '_ {
    let data = obj.data();
    let trees: Vec<&ObjectBvh> = match &data.bvh.parts {
        None => vec![&data.bvh],
        Some(parts) => (0..parts.parts.len() as u32).map(|p| obj.part(parts, p)).collect(),
    };
    trees.into_iter().flat_map(|tree| {
        let order = &tree.bvh.prim_order;
        (0..order.len()).filter(|&s| order[s] != NO_TRIANGLE).map(move |s| (tree, s))
    })
}

/// The brute-force occlusion reference.
pub(crate) fn occluded_brute_force(top: &TopLevel, objects: &[Object], ray: &Ray, filter: HitFilter) -> bool {
    for (i, inst) in top.instances.iter().enumerate() {
        let Some(obj) = objects.get(inst.object as usize) else {
            continue;
        };
        let r = RayPre::of(ray).in_object_space(inst);
        for (tree, s) in live_slots(obj) {
            let (t, u, v) = intersect(r.o, r.d, &triangle_at(tree, s, ray.time));
            if accept(t, u, v, ray.tmin, ray.tmax) && obj.solid_at(tree.bvh.prim_order[s], u, v) {
                let ok = filter.is_none_or(|f| {
                    f(&HitCandidate {
                        t,
                        u,
                        v,
                        instance: i as u32,
                        object: inst.object,
                        primitive: tree.bvh.prim_order[s],
                        lane: 0,
                    })
                });
                if ok {
                    return true;
                }
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Floats in [0, 1) from a xorshift generator seeded with `x`.
    fn unit_floats(mut x: u64) -> impl FnMut() -> f32 {
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// The slab test never culls a box that the ray touches (evaluated in `f64` from the same `f32`
    /// inputs), also for rays aimed exactly at box faces, edges and corners, and for boxes behind
    /// or beyond the interval. Checks the robustness argument of [`slab4`], and that an 8-wide
    /// node's test gives each half's 4-wide answer.
    #[test]
    fn node_test_is_conservative() {
        let mut next = unit_floats(0x9e37_79b9_7f4a_7c15);
        let (mut checked, mut culled, mut two_step) = (0u32, 0u32, 0u32);
        for i in 0..300_000 {
            let scale = [1e-3f32, 1.0, 1e3][i % 3];
            // Boxes and origin far from the coordinates' origin as well, where coordinates are
            // coarse.
            // At 1e9 and beyond, a ray with no direction along an axis has no finite fused
            // offset there (`o * id` overflows) and takes the two-step test.
            let offset = [0.0, 1e2, 1e4, 1e9][(i / 5) % 4] * scale;
            let mut n = Node4::default();
            for k in 0..4 {
                let lo: [f32; 3] = std::array::from_fn(|_| (next() * 2.0 - 1.0) * scale + offset);
                let ext: [f32; 3] = std::array::from_fn(|_| if next() < 0.1 { 0.0 } else { next() * scale });
                n.min_x[k] = lo[0];
                n.min_y[k] = lo[1];
                n.min_z[k] = lo[2];
                n.max_x[k] = lo[0] + ext[0];
                n.max_y[k] = lo[1] + ext[1];
                n.max_z[k] = lo[2] + ext[2];
                n.child[k] = k as u32;
            }
            let o: [f32; 3] = std::array::from_fn(|_| (next() * 6.0 - 3.0) * scale + offset);
            // Aim at a point of box 0's boundary (a corner, an edge or a face) or anywhere.
            let k0 = (i / 3) % 4;
            let (lo, hi) = ([n.min_x[k0], n.min_y[k0], n.min_z[k0]], [n.max_x[k0], n.max_y[k0], n.max_z[k0]]);
            let target: [f32; 3] = std::array::from_fn(|a| match (i / 12 + a) % 4 {
                0 => lo[a],
                1 => hi[a],
                2 => lo[a] + (hi[a] - lo[a]) * next(),
                _ => (next() * 6.0 - 3.0) * scale + offset,
            });
            let mut d: [f32; 3] = std::array::from_fn(|a| target[a] - o[a]);
            if i % 7 == 0 {
                d[i % 3] = 0.0;
            }
            let (tmin, tmax) = match i % 4 {
                0 => (0.0, f32::INFINITY),
                1 => (0.0, 1.0),
                2 => (0.5 * next(), 0.5 + next()),
                _ => (0.0, next()),
            };
            let r = RayPre::new(Vec3A::from(o), Vec3A::from(d), tmin, tmax);
            two_step += u32::from(!r.fused);
            let (mask, t) = n.hits(&r);
            // The 8-wide test is the 4-wide test on each half: here the same boxes in both halves,
            // the second half in reverse order.
            let mut wide = Node8::default();
            for k in 0..4 {
                for (h, j) in [(0, k), (1, 3 - k)] {
                    wide.min_x[h][j] = n.min_x[k];
                    wide.min_y[h][j] = n.min_y[k];
                    wide.min_z[h][j] = n.min_z[k];
                    wide.max_x[h][j] = n.max_x[k];
                    wide.max_y[h][j] = n.max_y[k];
                    wide.max_z[h][j] = n.max_z[k];
                }
            }
            let (mask8, t8) = wide.hits(&r);
            let reversed = (0..4).fold(0, |m, k| m | (mask >> k & 1) << (3 - k));
            assert_eq!(mask8, mask | reversed << 4, "case {i}");
            for k in (0..4).filter(|k| mask >> k & 1 != 0) {
                assert_eq!((t8[k], t8[7 - k]), (t[k], t[k]), "case {i}");
            }
            for k in 0..4 {
                let b = [[n.min_x[k], n.max_x[k]], [n.min_y[k], n.max_y[k]], [n.min_z[k], n.max_z[k]]];
                let (mut t0, mut t1) = (tmin as f64, tmax as f64);
                // A ray with no direction along an axis that lies exactly in the plane of a face
                // across it grazes the face: the clamped inverse direction (`safe_inv`) moves it
                // off the face, so a box stored as it is here may be culled (its far distance on
                // that axis is 0). Built trees store their boxes grown outward for such rays
                // (`Node4::set_child`); the agreement tests check those.
                let grazing = (0..3).any(|a| d[a] == 0.0 && (o[a] == b[a][0] || o[a] == b[a][1]));
                for a in 0..3 {
                    let (o, d) = (o[a] as f64, d[a] as f64);
                    let (l, h) = (b[a][0] as f64, b[a][1] as f64);
                    if d == 0.0 {
                        if o < l || o > h {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    let (ta, tb) = ((l - o) / d, (h - o) / d);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                // Touching in exact arithmetic (with a margin far below f32 rounding for the f64
                // evaluation's own rounding).
                if grazing {
                    continue;
                }
                if t0 <= t1 - 1e-12 * t1.abs() {
                    checked += 1;
                    assert!(mask >> k & 1 != 0, "case {i}: box {k} culled, t in [{t0}, {t1}]");
                } else {
                    culled += 1;
                }
            }
        }
        assert!(checked > 20_000 && culled > 20_000 && two_step > 1_000, "{checked} {culled} {two_step}");
    }

    /// The fused 8-wide test, which orders distances as integers, answers what `maxps` and
    /// `minps` answer over the same distances: the same boxes with the same entry distances.
    /// Coordinates include both zeros and values at the ray's origin, where products are `-0.0`;
    /// rays whose `tmin` is negative or `-0.0`, or whose `tmax` is NaN, take the other form.
    #[test]
    fn integer_ordering_answers_as_floats_do() {
        let mut next = unit_floats(0x2545_f491_4f6c_dd1d);
        let (mut entered, mut zeros) = (0u32, 0u32);
        for i in 0..100_000 {
            let mut pick = |k: u32| match (i as u32 + k) % 5 {
                0 => 0.0,
                1 => -0.0,
                _ => (next() * 4.0 - 2.0).round() * 0.5,
            };
            let o: [f32; 3] = std::array::from_fn(|k| pick(k as u32));
            let d: [f32; 3] = std::array::from_fn(|k| pick(k as u32 + 1));
            let mut n = Node8::default();
            for k in 0..8 {
                let (h, j) = (k / 4, k % 4);
                for (lo, hi) in
                    [(&mut n.min_x, &mut n.max_x), (&mut n.min_y, &mut n.max_y), (&mut n.min_z, &mut n.max_z)]
                {
                    let (a, b) = (pick(k as u32 + 2), pick(k as u32 + 3));
                    (lo[h][j], hi[h][j]) = (a.min(b), a.max(b));
                }
            }
            let tmax = [f32::INFINITY, 1.0, 0.5][i % 3];
            let r = RayPre::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
            assert!(r.fused, "case {i}");
            let (mask, t) = n.hits(&r);
            // The same distances, ordered as floats.
            let row = |v: &[[f32; 4]; 2]| f32x8::new(bytemuck::cast(*v));
            let (nx, fx) = if r.neg[0] { (&n.max_x, &n.min_x) } else { (&n.min_x, &n.max_x) };
            let (ny, fy) = if r.neg[1] { (&n.max_y, &n.min_y) } else { (&n.min_y, &n.max_y) };
            let (nz, fz) = if r.neg[2] { (&n.max_z, &n.min_z) } else { (&n.min_z, &n.max_z) };
            let s = f32x8::splat;
            let tn = [(nx, 0), (ny, 1), (nz, 2)].map(|(b, a)| row(b).mul_add(s(r.id[a]), s(r.near_c[a])));
            let tf = [(fx, 0), (fy, 1), (fz, 2)].map(|(b, a)| row(b).mul_add(s(r.fid[a]), s(r.far_c[a])));
            let near = tn[0].fast_max(tn[1]).fast_max(tn[2].fast_max(s(r.tmin)));
            let far = tf[0].fast_min(tf[1]).fast_min(tf[2].fast_min(s(r.tmax * ROBUST)));
            let float_mask = near.simd_le(far).to_bitmask();
            let (near, far) = (near.to_array(), far.to_array());
            assert_eq!(mask, float_mask, "case {i}: exits {far:?}");
            for k in (0..8).filter(|k| mask >> k & 1 != 0) {
                assert_eq!(t[k], near[k], "case {i}, box {k}");
                entered += 1;
            }
            zeros += far.iter().chain(&near).filter(|v| **v == 0.0).count() as u32;
        }
        assert!(entered > 100_000 && zeros > 100_000, "{entered} {zeros}");
        for (tmin, tmax) in [(-1.0, 1.0), (-0.0, 1.0), (f32::NAN, 1.0), (0.0, f32::NAN)] {
            let r = RayPre::new(Vec3A::ZERO, Vec3A::ONE, tmin, tmax);
            assert!(!r.fused, "tmin {tmin}, tmax {tmax}");
        }
        assert!(RayPre::new(Vec3A::ZERO, Vec3A::ONE, 0.0, f32::INFINITY).fused);
    }
}

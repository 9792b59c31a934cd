//! Packet traversal of the two-level BVH for coherent packets of 64 rays.
//!
//! The algorithm is ranged packet traversal (Wald et al. 2007; Overbeck et al. 2008) over 4-wide
//! nodes, in chunks of eight lanes (one AVX register per quantity on `x86-64-v3`, two SSE
//! registers without AVX). The kernels are compiled for the crate's target and once more for
//! AVX-512, which runs where the processor has it (`Kernels`, [`crate::cpu::kernel_isa`]):
//! 1. **Interval culling.** When every lane's direction has the same sign on each axis, the packet
//!    is bounded by intervals of origins and inverse directions; one interval-arithmetic slab test
//!    per node rejects the children that no lane can enter (4 children at once).
//! 2. **First and last active chunk.** For each surviving child, chunks are slab-tested from the
//!    front of the parent's range `[lo, hi]` until one hits, and from the back likewise; the child
//!    is visited with the narrowed range. Leaves get the exact mask of chunks that hit their box, and
//!    only those chunks are tested against the leaf's triangles.
//! 3. **Ordering.** Children are visited in the order of the entry distance of the first hitting
//!    lane.
//! 4. **Octant split.** A packet whose direction signs differ between lanes (shadow rays toward a
//!    light among the hits, reflections off a curved mirror) is split by the octant of its lanes'
//!    directions; each octant with more than [`SINGLE_RAY_THRESHOLD`] lanes is traced as its own
//!    packet (the other lanes are inactive in it), so interval culling stays valid.
//! 5. **Fallback to single rays.** Octants with few lanes, packets with few active lanes, lanes
//!    that become incoherent in an instance's space (a rotation), and occlusion packets whose
//!    unfinished lanes drop to [`SINGLE_RAY_THRESHOLD`] continue with [`super::single`] traversal
//!    per lane.
//!
//! Invariants:
//! - Lanes outside `active` are never reported: they are given the ray of an active lane with an
//!   empty interval (`tmin = +inf`, `tmax = -inf`), so they fail every test and do not widen the
//!   packet's bounds.
//! - The interval test is conservative *including rounding*: its bounds use the same IEEE
//!   operations as the per-lane test on the extreme values, and rounding is monotonic, so it never
//!   rejects a box that some lane's own test would enter.
//! - A lane's `tmax` only decreases; occluded lanes get `tmax = -inf` and take no further part.

use super::bvh4::{leaf_range, Bvh4, Node4, LEAF_BIT};
use super::object::{Object, ObjectBvh, Parts};
use super::single::{self, HitState, RayPre, STACK};
use super::stack::Stack;
use super::top::{InstanceData, TopLevel};
use super::{prefetch, ROBUST};
use crate::cpu::KernelIsa;
use crate::geometry::triangle::{intersect, intersect_shared, PreTriangle, SharedOrigin, BLOCK_WIDTH};
use crate::ray::{HitCandidate, HitFilter, HitPacket, RayPacket, INVALID_ID, PACKET_SIZE};
use glam::{Vec3A, Vec4};
use wide::{f32x8, i32x8};

/// Lanes per chunk.
const W: usize = 8;
/// Chunks of [`W`] lanes per packet.
pub const CHUNKS: usize = PACKET_SIZE / W;
/// Packets with at most this many active (unfinished) lanes are traced one ray at a time.
pub const SINGLE_RAY_THRESHOLD: u32 = 3;

/// One value of each lane of a chunk. Its arithmetic is IEEE lane by lane, as the single-ray
/// code's: a lane gets the same bits in either.
type Chunk = f32x8;
type Chunks = [Chunk; CHUNKS];
/// A packet row (`[f32; PACKET_SIZE]`) seen chunk by chunk.
type RowChunks = [[f32; W]; CHUNKS];

/// The chunks of the packet row `row`.
#[inline(always)]
fn row_chunks(row: &[f32; PACKET_SIZE]) -> &RowChunks {
    bytemuck::cast_ref(row)
}

/// [`row_chunks`], to write.
#[inline(always)]
fn row_chunks_mut(row: &mut [f32; PACKET_SIZE]) -> &mut RowChunks {
    bytemuck::cast_mut(row)
}

/// A row of ids seen chunk by chunk.
#[inline(always)]
fn id_chunks(row: &[u32; PACKET_SIZE]) -> &[[u32; W]; CHUNKS] {
    bytemuck::cast_ref(row)
}

#[inline(always)]
fn id_chunks_mut(row: &mut [u32; PACKET_SIZE]) -> &mut [[u32; W]; CHUNKS] {
    bytemuck::cast_mut(row)
}

/// Lane `j` of `v`.
#[inline(always)]
fn lane(v: &Chunk, j: usize) -> f32 {
    v.as_array()[j]
}

/// The smallest of the lanes, and the largest.
#[inline(always)]
fn min_lane(v: Chunk) -> f32 {
    v.to_array().into_iter().fold(f32::INFINITY, f32::min)
}

#[inline(always)]
fn max_lane(v: Chunk) -> f32 {
    v.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max)
}

/// The lane mask whose lane `j` is set where bit `j` of `bits` is.
#[inline(always)]
fn lane_mask(bits: u32) -> Chunk {
    let lane_bits = i32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);
    bytemuck::cast((i32x8::splat(bits as i32) & lane_bits).simd_eq(lane_bits))
}

/// The traversal's functions that are not inlined into their callers, compiled for one
/// instruction set: [`Built`] for the crate's target, [`Avx512`] once more with AVX-512 enabled
/// (the same code: 32 vector registers, mask registers and three-operand logic for its eight-lane
/// chunks, and the same IEEE results lane by lane). Each calls the others through its own set, so
/// that a packet traced by one set stays in it; what they inline (traversal, box and triangle
/// tests) is compiled with their instruction set.
///
/// # Safety
///
/// A method may run only on a processor with its set's instruction set: a value of a set exists
/// only there ([`Built`] everywhere this crate runs, [`Avx512`] where [`Avx512::on`] made it).
#[allow(clippy::too_many_arguments)]
trait Kernels: Copy {
    unsafe fn intersect_lanes(
        self,
        top: &TopLevel,
        objects: &[Object],
        p: &RayPacket,
        active: u64,
        out: &mut HitPacket,
        filter: HitFilter,
        split: bool,
    );
    unsafe fn occluded_lanes(
        self,
        top: &TopLevel,
        objects: &[Object],
        p: &RayPacket,
        active: u64,
        filter: HitFilter,
        split: bool,
    ) -> u64;
    unsafe fn intersect_object_with<const SHARED: bool>(self, v: &ObjectVisit, s: &mut State);
    unsafe fn intersect_parts<const SHARED: bool>(self, v: &ObjectVisit, parts: &Parts, s: &mut State);
    unsafe fn occluded_object_with<const SHARED: bool>(self, v: &ObjectVisit, s: &mut State) -> bool;
    unsafe fn occluded_parts<const SHARED: bool>(self, v: &ObjectVisit, parts: &Parts, s: &mut State) -> bool;
}

/// The kernels compiled for the crate's target.
#[derive(Clone, Copy)]
struct Built;

/// The kernels compiled with AVX-512: only made where the processor has it.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx512(());

#[cfg(target_arch = "x86_64")]
impl Avx512 {
    /// The AVX-512 kernels, where `isa` asks for them and the processor has them.
    fn on(isa: KernelIsa) -> Option<Avx512> {
        (isa == KernelIsa::Avx512 && crate::cpu::has_avx512()).then_some(Avx512(()))
    }
}

/// `Kernels` for `$set`, each method its own function (`#[inline(never)]`: one copy of each
/// traversal per set, as the two copies of the box tests are kept apart) compiled with `$attr`.
macro_rules! kernels {
    ($set:ty $(, #[$attr:meta])*) => {
        #[allow(clippy::too_many_arguments)]
        impl Kernels for $set {
            #[inline(never)]
            $(#[$attr])*
            unsafe fn intersect_lanes(
                self,
                top: &TopLevel,
                objects: &[Object],
                p: &RayPacket,
                active: u64,
                out: &mut HitPacket,
                filter: HitFilter,
                split: bool,
            ) {
                intersect_lanes_in(self, top, objects, p, active, out, filter, split)
            }

            #[inline(never)]
            $(#[$attr])*
            unsafe fn occluded_lanes(
                self,
                top: &TopLevel,
                objects: &[Object],
                p: &RayPacket,
                active: u64,
                filter: HitFilter,
                split: bool,
            ) -> u64 {
                occluded_lanes_in(self, top, objects, p, active, filter, split)
            }

            #[inline(never)]
            $(#[$attr])*
            unsafe fn intersect_object_with<const SHARED: bool>(self, v: &ObjectVisit, s: &mut State) {
                intersect_object_with_in::<Self, SHARED>(self, v, s)
            }

            #[inline(never)]
            $(#[$attr])*
            unsafe fn intersect_parts<const SHARED: bool>(self, v: &ObjectVisit, parts: &Parts, s: &mut State) {
                intersect_parts_in::<SHARED>(v, parts, s)
            }

            #[inline(never)]
            $(#[$attr])*
            unsafe fn occluded_object_with<const SHARED: bool>(self, v: &ObjectVisit, s: &mut State) -> bool {
                occluded_object_with_in::<Self, SHARED>(self, v, s)
            }

            #[inline(never)]
            $(#[$attr])*
            unsafe fn occluded_parts<const SHARED: bool>(
                self,
                v: &ObjectVisit,
                parts: &Parts,
                s: &mut State,
            ) -> bool {
                occluded_parts_in::<SHARED>(v, parts, s)
            }
        }
    };
}

kernels!(Built);
// The features `crate::cpu::has_avx512` checks.
#[cfg(target_arch = "x86_64")]
kernels!(
    Avx512,
    #[target_feature(
        enable = "avx512f,avx512bw,avx512cd,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt,f16c,movbe"
    )]
);

/// The packet's rays in one space (world, or an object's space), with interval bounds.
struct Geom {
    o: [Chunks; 3],
    d: [Chunks; 3],
    id: [Chunks; 3],
    neg: [bool; 3],
    o_lo: [f32; 3],
    o_hi: [f32; 3],
    id_lo: [f32; 3],
    id_hi: [f32; 3],
    /// Every lane in the range has the same origin (bit for bit).
    shared_origin: bool,
}

/// Mutable per-lane state shared by both levels.
struct State {
    tmin: Chunks,
    tmax: Chunks,
    tmin_lo: f32,
    tmax_hi: f32,
    u: Chunks,
    v: Chunks,
    instance: [u32; PACKET_SIZE],
    primitive: [u32; PACKET_SIZE],
    active: u64,
    done: u64,
    /// Occlusion only: set when few lanes remain and the rest should go single-ray.
    bail: bool,
}

#[inline(always)]
fn safe_inv(d: Chunk) -> Chunk {
    const TINY: f32 = 1e-30;
    let small = d.abs().simd_lt(Chunk::splat(TINY));
    Chunk::splat(1.0) / small.select(Chunk::splat(TINY).copysign(d), d)
}

impl Geom {
    fn zeroed() -> Self {
        Geom {
            o: [[Chunk::ZERO; CHUNKS]; 3],
            d: [[Chunk::ZERO; CHUNKS]; 3],
            id: [[Chunk::ZERO; CHUNKS]; 3],
            neg: [false; 3],
            o_lo: [0.0; 3],
            o_hi: [0.0; 3],
            id_lo: [0.0; 3],
            id_hi: [0.0; 3],
            shared_origin: false,
        }
    }

    /// Computes inverse directions and bounds over chunks `lo..=hi`; `false` if the direction signs
    /// differ between lanes (the packet is then incoherent and must go single-ray).
    fn finish(&mut self, lo: usize, hi: usize) -> bool {
        for a in 0..3 {
            let mut neg = 0u64;
            let mut olo = Chunk::splat(f32::INFINITY);
            let mut ohi = Chunk::splat(f32::NEG_INFINITY);
            let mut ilo = olo;
            let mut ihi = ohi;
            for c in lo..=hi {
                let id = safe_inv(self.d[a][c]);
                self.id[a][c] = id;
                neg |= (id.simd_lt(Chunk::ZERO).to_bitmask() as u64) << (W * (c - lo));
                olo = olo.fast_min(self.o[a][c]);
                ohi = ohi.fast_max(self.o[a][c]);
                ilo = ilo.fast_min(id);
                ihi = ihi.fast_max(id);
            }
            let all = if hi - lo + 1 >= CHUNKS { u64::MAX } else { (1u64 << (W * (hi - lo + 1))) - 1 };
            if neg != 0 && neg != all {
                return false;
            }
            self.neg[a] = neg != 0;
            self.o_lo[a] = min_lane(olo);
            self.o_hi[a] = max_lane(ohi);
            self.id_lo[a] = min_lane(ilo);
            self.id_hi[a] = max_lane(ihi);
        }
        self.shared_origin = (0..3).all(|a| self.o_lo[a].to_bits() == self.o_hi[a].to_bits());
        true
    }

    /// The world-space geometry of a packet's lanes `active` in its chunks `lo..=hi` (the chunks
    /// the traversal reads); their other lanes copy lane `fill`, chunks outside are zero.
    fn world(p: &RayPacket, active: u64, fill: usize, (lo, hi): (usize, usize)) -> Self {
        // Written in place, chunk by chunk: rows built apart and then moved in cost a copy of each
        // (a sixth of a primary packet's time outside the object traversal on s34k).
        let mut g = Geom::zeroed();
        let rows = [&p.ox.0, &p.oy.0, &p.oz.0, &p.dx.0, &p.dy.0, &p.dz.0];
        for c in lo..=hi {
            // A blend whatever the lanes: branches here made the compiler's code for this loop
            // vary from build to build.
            let lanes = lane_mask((active >> (W * c)) as u8 as u32);
            for (k, row) in rows.iter().enumerate() {
                let v = lanes.select(Chunk::new(row_chunks(row)[c]), Chunk::splat(row[fill]));
                if k < 3 {
                    g.o[k][c] = v;
                } else {
                    g.d[k - 3][c] = v;
                }
            }
        }
        g
    }

    /// This geometry moved into object space by `xf`, for chunks `lo..=hi`.
    fn transformed(&self, xf: &glam::Affine3A, lo: usize, hi: usize) -> Self {
        let mut g = Geom::zeroed();
        let m = xf.matrix3;
        let t = xf.translation;
        let (ax, ay, az) = (m.x_axis, m.y_axis, m.z_axis);
        for c in lo..=hi {
            let (x, y, z) = (self.o[0][c], self.o[1][c], self.o[2][c]);
            let k = Chunk::splat;
            g.o[0][c] = ((k(ax.x) * x + k(ay.x) * y) + k(az.x) * z) + k(t.x);
            g.o[1][c] = ((k(ax.y) * x + k(ay.y) * y) + k(az.y) * z) + k(t.y);
            g.o[2][c] = ((k(ax.z) * x + k(ay.z) * y) + k(az.z) * z) + k(t.z);
            let (x, y, z) = (self.d[0][c], self.d[1][c], self.d[2][c]);
            g.d[0][c] = (k(ax.x) * x + k(ay.x) * y) + k(az.x) * z;
            g.d[1][c] = (k(ax.y) * x + k(ay.y) * y) + k(az.y) * z;
            g.d[2][c] = (k(ax.z) * x + k(ay.z) * y) + k(az.z) * z;
        }
        g
    }

    #[inline(always)]
    fn lane_ray(&self, i: usize, tmin: f32, tmax: f32) -> RayPre {
        let (c, j) = (i / W, i % W);
        RayPre::new(
            Vec3A::new(lane(&self.o[0][c], j), lane(&self.o[1][c], j), lane(&self.o[2][c], j)),
            Vec3A::new(lane(&self.d[0][c], j), lane(&self.d[1][c], j), lane(&self.d[2][c], j)),
            tmin,
            tmax,
        )
    }
}

impl State {
    /// The state of the packet's lanes `active`, all in chunks `lo..=hi`; the others get an empty
    /// interval.
    fn new(p: &RayPacket, active: u64, (lo, hi): (usize, usize)) -> Self {
        let (empty_min, empty_max) = (Chunk::splat(f32::INFINITY), Chunk::splat(f32::NEG_INFINITY));
        let mut tmin = [empty_min; CHUNKS];
        let mut tmax = [empty_max; CHUNKS];
        for c in lo..=hi {
            // A blend, as `Geom::world`'s: a branch a lane cost more than the traversal of a
            // packet that meets a few large triangles.
            let lanes = lane_mask((active >> (W * c)) as u8 as u32);
            tmin[c] = lanes.select(Chunk::new(row_chunks(&p.tmin.0)[c]), empty_min);
            tmax[c] = lanes.select(Chunk::new(row_chunks(&p.tmax.0)[c]), empty_max);
        }
        let mut s = State {
            tmin,
            tmax,
            tmin_lo: 0.0,
            tmax_hi: 0.0,
            u: [Chunk::ZERO; CHUNKS],
            v: [Chunk::ZERO; CHUNKS],
            instance: [INVALID_ID; PACKET_SIZE],
            primitive: [INVALID_ID; PACKET_SIZE],
            active,
            done: 0,
            bail: false,
        };
        s.tmin_lo = min_lane(s.tmin.iter().fold(Chunk::splat(f32::INFINITY), |a, b| a.fast_min(*b)));
        s.update_tmax_hi();
        s
    }

    #[inline(always)]
    fn update_tmax_hi(&mut self) {
        self.tmax_hi = max_lane(self.tmax.iter().fold(Chunk::splat(f32::NEG_INFINITY), |a, b| a.fast_max(*b)));
    }

    #[inline(always)]
    fn lane_tmin(&self, i: usize) -> f32 {
        lane(&self.tmin[i / W], i % W)
    }

    #[inline(always)]
    fn lane_tmax(&self, i: usize) -> f32 {
        lane(&self.tmax[i / W], i % W)
    }

    #[inline(always)]
    fn set_lane_tmax(&mut self, i: usize, t: f32) {
        self.tmax[i / W].as_mut_array()[i % W] = t;
    }
}

/// Bit mask of the children of `n` that the packet's interval bounds may enter.
#[inline(always)]
fn interval_mask(n: &Node4, g: &Geom, s: &State) -> u32 {
    let mut near = Vec4::splat(s.tmin_lo);
    let mut far = Vec4::splat(s.tmax_hi);
    let planes = [(&n.min_x, &n.max_x), (&n.min_y, &n.max_y), (&n.min_z, &n.max_z)];
    for (a, (lo, hi)) in planes.into_iter().enumerate() {
        let (bn, bf, on, of) = if g.neg[a] { (hi, lo, g.o_lo[a], g.o_hi[a]) } else { (lo, hi, g.o_hi[a], g.o_lo[a]) };
        let (il, ih) = (Vec4::splat(g.id_lo[a]), Vec4::splat(g.id_hi[a]));
        let xn = Vec4::from_array(*bn) - Vec4::splat(on);
        let xf = Vec4::from_array(*bf) - Vec4::splat(of);
        near = near.max((xn * il).min(xn * ih));
        far = far.min((xf * il).max(xf * ih));
    }
    near.cmple(far * ROBUST).bitmask()
}

/// One child box, splatted, near and far planes chosen by the packet's direction signs. With
/// `SHARED` (every lane has the packet's one origin, `Geom::shared_origin`) the planes are stored
/// relative to that origin: the subtraction each chunk's test would repeat is done once per child,
/// with the same result.
struct BoxSplat<const SHARED: bool> {
    n: [Chunk; 3],
    f: [Chunk; 3],
}

impl<const SHARED: bool> BoxSplat<SHARED> {
    #[inline(always)]
    fn new(node: &Node4, k: usize, g: &Geom) -> Self {
        let lo = [node.min_x[k], node.min_y[k], node.min_z[k]];
        let hi = [node.max_x[k], node.max_y[k], node.max_z[k]];
        let mut b = BoxSplat { n: [Chunk::ZERO; 3], f: [Chunk::ZERO; 3] };
        for a in 0..3 {
            let (n, f) = if g.neg[a] { (hi[a], lo[a]) } else { (lo[a], hi[a]) };
            let (n, f) = if SHARED { (n - g.o_lo[a], f - g.o_lo[a]) } else { (n, f) };
            b.n[a] = Chunk::splat(n);
            b.f[a] = Chunk::splat(f);
        }
        b
    }

    /// Slab test of chunk `c`: the lanes that hit, and their entry distances (`+inf` in the other
    /// lanes). Same operations as the single-ray test.
    #[inline(always)]
    fn test(&self, g: &Geom, s: &State, c: usize) -> (u32, Chunk) {
        let rel = |plane: Chunk, a: usize| if SHARED { plane } else { plane - g.o[a][c] };
        let tnx = rel(self.n[0], 0) * g.id[0][c];
        let tny = rel(self.n[1], 1) * g.id[1][c];
        let tnz = rel(self.n[2], 2) * g.id[2][c];
        let tfx = rel(self.f[0], 0) * g.id[0][c];
        let tfy = rel(self.f[1], 1) * g.id[1][c];
        let tfz = rel(self.f[2], 2) * g.id[2][c];
        let tnear = tnx.fast_max(tny).fast_max(tnz.fast_max(s.tmin[c]));
        let tfar = tfx.fast_min(tfy).fast_min(tfz.fast_min(s.tmax[c]));
        let hit = tnear.simd_le(tfar * Chunk::splat(ROBUST));
        (hit.to_bitmask(), hit.select(tnear, Chunk::splat(f32::INFINITY)))
    }
}

#[derive(Clone, Copy, Default)]
struct Entry {
    r: u32,
    lo: u8,
    hi: u8,
    mask: u8,
}

/// Traverses `bvh` with the chunks `lo..=hi` of the packet. `leaf(first, count, chunk_mask, state)`
/// is called for each leaf entered, with the mask of chunks whose rays hit the leaf's box; it
/// returns `true` to end the traversal. Every child the packet will enter starts loading when it
/// is pushed: inner nodes here, leaves through `prefetch_leaf(first)` (their triangles).
///
/// `SHARED` must equal `g.shared_origin` (see [`BoxSplat`]).
#[inline(always)]
fn traverse<const SHARED: bool, F: FnMut(u32, u32, u8, &mut State) -> bool, P: Fn(u32)>(
    bvh: &Bvh4,
    g: &Geom,
    s: &mut State,
    lo: usize,
    hi: usize,
    prefetch_leaf: P,
    mut leaf: F,
) -> bool {
    if bvh.nodes.is_empty() {
        return false;
    }
    let mut stack: Stack<Entry, STACK> = Stack::new();
    stack.push(Entry { r: 0, lo: lo as u8, hi: hi as u8, mask: 0 });
    while let Some(e) = stack.pop() {
        if e.r & LEAF_BIT != 0 {
            let (first, count) = leaf_range(e.r);
            if leaf(first, count, e.mask, s) {
                return true;
            }
            continue;
        }
        let node = &bvh.nodes[e.r as usize];
        let mut m = interval_mask(node, g, s);
        let mut kids = [(Entry::default(), 0f32); 4];
        let mut n = 0;
        while m != 0 {
            let k = m.trailing_zeros() as usize;
            m &= m - 1;
            let b = BoxSplat::<SHARED>::new(node, k, g);
            let (elo, ehi) = (e.lo as usize, e.hi as usize);
            let mut first = None;
            for c in elo..=ehi {
                let (hm, tn) = b.test(g, s, c);
                if hm != 0 {
                    first = Some((c, min_lane(tn)));
                    break;
                }
            }
            let Some((f, t)) = first else { continue };
            let child = node.child[k];
            let mut entry = Entry { r: child, lo: f as u8, hi: f as u8, mask: 1 << f };
            if child & LEAF_BIT != 0 {
                prefetch_leaf(leaf_range(child).0);
                for c in f + 1..=ehi {
                    if b.test(g, s, c).0 != 0 {
                        entry.mask |= 1 << c;
                        entry.hi = c as u8;
                    }
                }
            } else {
                prefetch(bvh.nodes.as_ptr().wrapping_add(child as usize), 2);
                let mut l = ehi;
                while l > f && b.test(g, s, l).0 == 0 {
                    l -= 1;
                }
                entry.hi = l as u8;
            }
            let mut j = n;
            while j > 0 && kids[j - 1].1 < t {
                kids[j] = kids[j - 1];
                j -= 1;
            }
            kids[j] = (entry, t);
            n += 1;
        }
        for (entry, _) in &kids[..n] {
            stack.push(*entry);
        }
    }
    false
}

/// Tests the chunks in `mask` against one triangle: the hit mask and `(t, u, v)` per chunk is
/// handed to `on_hit`.
#[inline(always)]
fn leaf_triangle<H: FnMut(usize, u32, Chunk, Chunk, Chunk, &mut State)>(
    g: &Geom,
    s: &mut State,
    tri: &PreTriangle,
    mask: u8,
    mut on_hit: H,
) {
    let mut m = mask as u32;
    let shared = g.shared_origin.then(|| SharedOrigin::new(g.o_lo, tri));
    while m != 0 {
        let c = m.trailing_zeros() as usize;
        m &= m - 1;
        let d = [g.d[0][c], g.d[1][c], g.d[2][c]];
        let (t, u, v) = match &shared {
            Some(so) => intersect_shared(so, d, tri),
            None => intersect([g.o[0][c], g.o[1][c], g.o[2][c]], d, tri),
        };
        let hit = u.simd_ge(Chunk::ZERO)
            & v.simd_ge(Chunk::ZERO)
            & (u + v).simd_le(Chunk::splat(1.0))
            & t.simd_gt(s.tmin[c])
            & t.simd_lt(s.tmax[c]);
        let bits = hit.to_bitmask();
        if bits != 0 {
            on_hit(c, bits, t, u, v, s);
        }
    }
}

/// One object as a packet meets it: the object and its instance's and object's ids, the packet's
/// chunks `lo..=hi` with their rays in the object's space, and the hit filter.
#[derive(Clone, Copy)]
struct ObjectVisit<'a> {
    obj: &'a Object,
    inst_id: u32,
    object_id: u32,
    g: &'a Geom,
    lo: usize,
    hi: usize,
    filter: HitFilter<'a>,
}

impl ObjectVisit<'_> {
    /// The same visit with the chunks of `mask` (a part of the object that some reached).
    #[inline(always)]
    fn with_chunks(&self, mask: u8) -> Self {
        let (lo, hi) = mask_range(mask);
        ObjectVisit { lo, hi, ..*self }
    }
}

/// Tests the chunks `mask` against the triangles of leaf block `b` of `tree` (`count` of them):
/// `on_hit(c, bits, [t, u, v], primitive, s)` for each triangle's hits in chunk `c` that the
/// object's alpha mask and the filter accept (lanes `bits`). Returns whether there were any.
#[inline(always)]
fn leaf_hits(
    v: &ObjectVisit,
    tree: &ObjectBvh,
    s: &mut State,
    (b, count, mask): (u32, u32, u8),
    mut on_hit: impl FnMut(usize, u32, [Chunk; 3], u32, &mut State),
) -> bool {
    let mut any = false;
    let block = &tree.blocks[b as usize];
    for j in 0..count as usize {
        let primitive = tree.bvh.prim_order[BLOCK_WIDTH * b as usize + j];
        // Inlined, as the kernels' closures are (see `intersect_tree`).
        leaf_triangle(
            v.g,
            s,
            &block.triangle(j),
            mask,
            #[inline(always)]
            |c, bits, t, hu, hv, s| {
                let bits = accepted_lanes(v, primitive, c, bits, [t, hu, hv]);
                if bits != 0 {
                    on_hit(c, bits, [t, hu, hv], primitive, s);
                    any = true;
                }
            },
        );
    }
    any
}

/// The lanes of `bits` (chunk `c`'s hits `[t, u, v]` of triangle `primitive`) that the object's
/// alpha mask and the filter accept.
#[inline(always)]
fn accepted_lanes(visit: &ObjectVisit, primitive: u32, c: usize, mut bits: u32, [t, u, v]: [Chunk; 3]) -> u32 {
    let (obj, filter) = (visit.obj, visit.filter);
    if filter.is_none() && obj.alpha.is_none() {
        return bits;
    }
    let mut b = bits;
    while b != 0 {
        let j = b.trailing_zeros() as usize;
        b &= b - 1;
        if !obj.solid_at(primitive, lane(&u, j), lane(&v, j)) {
            bits &= !(1 << j);
            continue;
        }
        let Some(f) = filter else { continue };
        let cand = HitCandidate {
            t: lane(&t, j),
            u: lane(&u, j),
            v: lane(&v, j),
            instance: visit.inst_id,
            object: visit.object_id,
            primitive,
            lane: (W * c + j) as u32,
        };
        if !f(&cand) {
            bits &= !(1 << j);
        }
    }
    bits
}

/// Closest hit of the packet's chunks with one object.
#[inline(always)]
fn intersect_object<K: Kernels>(k: K, v: &ObjectVisit, s: &mut State) {
    // Two copies of the traversal, each its own function: one inlined into the other's body slowed
    // both (as `rtsl bench trace` measures primary packets).
    // SAFETY: a value of `K` exists only where the processor has its instruction set.
    unsafe {
        if v.g.shared_origin {
            k.intersect_object_with::<true>(v, s)
        } else {
            k.intersect_object_with::<false>(v, s)
        }
    }
}

/// [`intersect_object`] with the box tests of a shared origin or not.
#[inline(always)]
fn intersect_object_with_in<K: Kernels, const SHARED: bool>(k: K, v: &ObjectVisit, s: &mut State) {
    let data = v.obj.data();
    match &data.bvh.parts {
        None => intersect_tree::<SHARED>(v, &data.bvh, s),
        // SAFETY: as `intersect_object`'s.
        Some(parts) => unsafe { k.intersect_parts::<SHARED>(v, parts, s) },
    }
}

/// [`intersect_object_with_in`] with a BVH in parts: the small tree's leaves are the parts' trees,
/// each traversed with the chunks that reached its box.
#[inline(always)]
fn intersect_parts_in<const SHARED: bool>(v: &ObjectVisit, parts: &Parts, s: &mut State) {
    let small = &v.obj.data().bvh;
    traverse::<SHARED, _, _>(
        &small.bvh,
        v.g,
        s,
        v.lo,
        v.hi,
        |_| {},
        // Inlined, as the kernels' closures are (see `intersect_tree`).
        #[inline(always)]
        |p, _, mask, s| {
            intersect_tree::<SHARED>(&v.with_chunks(mask), v.obj.part(parts, p), s);
            false
        },
    );
}

/// [`intersect_object_with_in`] with a whole tree, or one part.
#[inline(always)]
fn intersect_tree<const SHARED: bool>(v: &ObjectVisit, tree: &ObjectBvh, s: &mut State) {
    let blocks = &tree.blocks;
    let pf = |b: u32| prefetch(blocks.as_ptr().wrapping_add(b as usize), 3);
    traverse::<SHARED, _, _>(
        &tree.bvh,
        v.g,
        s,
        v.lo,
        v.hi,
        pf,
        // A closure is compiled with the instruction set of the function that defines it, not of
        // the kernel that calls it: inlined, it takes the kernel's.
        #[inline(always)]
        |b, count, mask, s| {
            let any = leaf_hits(v, tree, s, (b, count, mask), |c, bits, [t, hu, hv], primitive, s| {
                let hm = lane_mask(bits);
                s.tmax[c] = hm.select(t, s.tmax[c]);
                s.u[c] = hm.select(hu, s.u[c]);
                s.v[c] = hm.select(hv, s.v[c]);
                let mut b = bits;
                while b != 0 {
                    let j = b.trailing_zeros() as usize;
                    b &= b - 1;
                    s.instance[W * c + j] = v.inst_id;
                    s.primitive[W * c + j] = primitive;
                }
            });
            if any {
                s.update_tmax_hi();
            }
            false
        },
    );
}

/// Occlusion of the packet's chunks with one object; returns `true` when traversal should stop
/// (every lane is done, or few remain and `s.bail` is set).
#[inline(always)]
fn occluded_object<K: Kernels>(k: K, v: &ObjectVisit, s: &mut State) -> bool {
    // As `intersect_object`: one function per copy of the traversal.
    // SAFETY: a value of `K` exists only where the processor has its instruction set.
    unsafe {
        if v.g.shared_origin {
            k.occluded_object_with::<true>(v, s)
        } else {
            k.occluded_object_with::<false>(v, s)
        }
    }
}

/// [`occluded_object`] with the box tests of a shared origin or not.
#[inline(always)]
fn occluded_object_with_in<K: Kernels, const SHARED: bool>(k: K, v: &ObjectVisit, s: &mut State) -> bool {
    let data = v.obj.data();
    match &data.bvh.parts {
        None => occluded_tree::<SHARED>(v, &data.bvh, s),
        // SAFETY: as `occluded_object`'s.
        Some(parts) => unsafe { k.occluded_parts::<SHARED>(v, parts, s) },
    }
}

/// [`occluded_object_with_in`] with a BVH in parts.
#[inline(always)]
fn occluded_parts_in<const SHARED: bool>(v: &ObjectVisit, parts: &Parts, s: &mut State) -> bool {
    let small = &v.obj.data().bvh;
    traverse::<SHARED, _, _>(
        &small.bvh,
        v.g,
        s,
        v.lo,
        v.hi,
        |_| {},
        // Inlined, as the kernels' closures are (see `intersect_tree`).
        #[inline(always)]
        |p, _, mask, s| occluded_tree::<SHARED>(&v.with_chunks(mask), v.obj.part(parts, p), s),
    )
}

/// [`occluded_object_with_in`] with a whole tree, or one part.
#[inline(always)]
fn occluded_tree<const SHARED: bool>(v: &ObjectVisit, tree: &ObjectBvh, s: &mut State) -> bool {
    let blocks = &tree.blocks;
    let pf = |b: u32| prefetch(blocks.as_ptr().wrapping_add(b as usize), 3);
    traverse::<SHARED, _, _>(
        &tree.bvh,
        v.g,
        s,
        v.lo,
        v.hi,
        pf,
        // As `intersect_tree`'s, inlined to take the kernel's instruction set.
        #[inline(always)]
        |b, count, mask, s| {
            let any = leaf_hits(v, tree, s, (b, count, mask), |c, bits, _, _, s| {
                s.tmax[c] = lane_mask(bits).select(Chunk::splat(f32::NEG_INFINITY), s.tmax[c]);
                s.done |= (bits as u64) << (W * c);
            });
            if any {
                let left = s.active & !s.done;
                if left == 0 {
                    return true;
                }
                if left.count_ones() <= SINGLE_RAY_THRESHOLD {
                    s.bail = true;
                    return true;
                }
                s.update_tmax_hi();
            }
            false
        },
    )
}

fn chunk_range(mask: u64) -> (usize, usize) {
    let lo = mask.trailing_zeros() as usize / W;
    let hi = (63 - mask.leading_zeros() as usize) / W;
    (lo, hi)
}

/// The chunk mask of chunks `lo..=hi`.
fn chunk_mask(lo: usize, hi: usize) -> u8 {
    ((1u32 << (hi + 1)) - (1u32 << lo)) as u8
}

fn mask_range(mask: u8) -> (usize, usize) {
    (mask.trailing_zeros() as usize, CHUNKS - 1 - mask.leading_zeros() as usize)
}

/// The lanes of `active` grouped by the octant of their direction (bit `a` set: negative along
/// axis `a`), with the sign test `finish` uses (`-0.0` counts as negative, as its inverse does).
fn octants(p: &RayPacket, active: u64) -> [u64; 8] {
    let mut by_octant = [0u64; 8];
    let mut m = active;
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        let octant = p.dx.0[i].is_sign_negative() as usize
            | (p.dy.0[i].is_sign_negative() as usize) << 1
            | (p.dz.0[i].is_sign_negative() as usize) << 2;
        by_octant[octant] |= 1 << i;
    }
    by_octant
}

/// Lanes of chunks in `mask` that are active and not done.
fn lanes_of(mask: u8, s: &State) -> u64 {
    let mut lanes = 0u64;
    for c in 0..CHUNKS {
        if mask >> c & 1 != 0 {
            lanes |= 0xFF << (W * c);
        }
    }
    lanes & s.active & !s.done
}

/// Lane `i` in the object space of `inst`: from the packet's object-space geometry `og` when there
/// is one (the instance stands still and its object does not deform), else from the world-space
/// geometry `g` moved by where the instance is at the lane's time, and at that time.
#[inline(always)]
fn lane_in_object(
    g: &Geom,
    og: Option<&Geom>,
    inst: &InstanceData,
    p: &RayPacket,
    i: usize,
    tmin: f32,
    tmax: f32,
) -> RayPre {
    match og {
        Some(og) => og.lane_ray(i, tmin, tmax),
        None => g.lane_ray(i, tmin, tmax).at_time(p.time.0[i]).in_object_space(inst),
    }
}

/// Closest hits of a packet (see the module documentation), with the kernels of `isa` (the built
/// ones where the processor lacks it).
pub(crate) fn intersect_packet_with(
    isa: KernelIsa,
    top: &TopLevel,
    objects: &[Object],
    p: &RayPacket,
    out: &mut HitPacket,
    filter: HitFilter,
) {
    #[cfg(target_arch = "x86_64")]
    if let Some(k) = Avx512::on(isa) {
        // SAFETY: `k` exists, so the processor has AVX-512.
        return unsafe { k.intersect_lanes(top, objects, p, p.active, out, filter, true) };
    }
    let _ = isa;
    // SAFETY: the built kernels run wherever this crate does.
    unsafe { Built.intersect_lanes(top, objects, p, p.active, out, filter, true) }
}

/// Closest hits of the packet's lanes `active`; an incoherent packet is split by octant when
/// `split` is set.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn intersect_lanes_in<K: Kernels>(
    k: K,
    top: &TopLevel,
    objects: &[Object],
    p: &RayPacket,
    active: u64,
    out: &mut HitPacket,
    filter: HitFilter,
    split: bool,
) {
    if active == 0 {
        return;
    }
    let single_all = |out: &mut HitPacket| {
        let mut m = active;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let h = single::intersect_scene(top, objects, &p.get(i), filter, i as u32);
            write_lane(out, i, h.t, h.u, h.v, h.instance, h.primitive);
        }
    };
    if active.count_ones() <= SINGLE_RAY_THRESHOLD {
        return single_all(out);
    }
    let fill = active.trailing_zeros() as usize;
    let (lo, hi) = chunk_range(active);
    let mut g = Geom::world(p, active, fill, (lo, hi));
    if !g.finish(lo, hi) {
        if !split {
            return single_all(out);
        }
        for lanes in octants(p, active) {
            // SAFETY: as `intersect_object`'s.
            unsafe { k.intersect_lanes(top, objects, p, lanes, out, filter, false) };
        }
        return;
    }
    let mut s = State::new(p, active, (lo, hi));
    // The packet's chunks `mask` against instance `inst_id`.
    let visit = |inst_id: u32, mask: u8, s: &mut State| {
        let inst: &InstanceData = &top.instances[inst_id as usize];
        let obj = &objects[inst.object as usize];
        let (clo, chi) = mask_range(mask);
        let deforms = obj.deforms();
        if inst.identity && !deforms {
            intersect_object(
                k,
                &ObjectVisit { obj, inst_id, object_id: inst.object, g: &g, lo: clo, hi: chi, filter },
                s,
            );
            return;
        }
        let og = match inst.motion {
            None if !deforms => {
                let mut og = g.transformed(&inst.object_from_world, clo, chi);
                if og.finish(clo, chi) {
                    intersect_object(
                        k,
                        &ObjectVisit { obj, inst_id, object_id: inst.object, g: &og, lo: clo, hi: chi, filter },
                        s,
                    );
                    return;
                }
                Some(og)
            }
            _ => None,
        };
        // Incoherent in this object's space, or moving or deforming (each lane at its own time):
        // one ray at a time.
        let mut m = lanes_of(mask, s);
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut r = lane_in_object(&g, og.as_ref(), inst, p, i, s.lane_tmin(i), s.lane_tmax(i));
            let (c, j) = (i / W, i % W);
            let mut h = HitState {
                u: lane(&s.u[c], j),
                v: lane(&s.v[c], j),
                instance: s.instance[i],
                primitive: s.primitive[i],
            };
            single::intersect_object::<true>(obj, inst_id, inst.object, &mut r, &mut h, filter, i as u32);
            s.set_lane_tmax(i, r.tmax);
            s.u[c].as_mut_array()[j] = h.u;
            s.v[c].as_mut_array()[j] = h.v;
            s.instance[i] = h.instance;
            s.primitive[i] = h.primitive;
        }
        s.update_tmax_hi();
    };
    if let Some(inst_id) = top.sole_instance() {
        // One instance: its object BVH's root test does the top level's culling.
        visit(inst_id, chunk_mask(lo, hi), &mut s);
    } else {
        traverse::<false, _, _>(
            &top.bvh,
            &g,
            &mut s,
            lo,
            hi,
            |_| {},
            |first, count, mask, s| {
                for slot in first..first + count {
                    visit(top.bvh.prim_order[slot as usize], mask, s);
                }
                false
            },
        );
    }
    write_hits(out, &s, active, (lo, hi));
}

/// The closest hits of lanes `active` (in chunks `lo..=hi`) from `s` into `out`, a chunk at a
/// time: a lane without a hit gets `write_lane`'s miss; the other lanes keep what `out` held.
#[inline(always)]
fn write_hits(out: &mut HitPacket, s: &State, active: u64, (lo, hi): (usize, usize)) {
    // Ids travel through the float blends as bits (`select` is a bitwise blend).
    let ids = |row: &[u32; PACKET_SIZE], c: usize| -> Chunk { bytemuck::cast(id_chunks(row)[c]) };
    let invalid = i32x8::splat(INVALID_ID as i32);
    for c in lo..=hi {
        let bits = (active >> (W * c)) as u8 as u32;
        if bits == 0 {
            continue;
        }
        let lanes = lane_mask(bits);
        let instance: Chunk = ids(&s.instance, c);
        let miss: Chunk = bytemuck::cast(bytemuck::cast::<Chunk, i32x8>(instance).simd_eq(invalid));
        let none = Chunk::ZERO;
        let t = miss.select(Chunk::splat(f32::INFINITY), s.tmax[c]);
        let u = miss.select(none, s.u[c]);
        let v = miss.select(none, s.v[c]);
        let primitive = miss.select(bytemuck::cast(invalid), ids(&s.primitive, c));
        for (row, value) in [(&mut out.t.0, t), (&mut out.u.0, u), (&mut out.v.0, v)] {
            let chunk = &mut row_chunks_mut(row)[c];
            *chunk = lanes.select(value, Chunk::new(*chunk)).to_array();
        }
        for (row, value) in [(&mut out.instance.0, instance), (&mut out.primitive.0, primitive)] {
            let chunk = &mut id_chunks_mut(row)[c];
            *chunk = bytemuck::cast(lanes.select(value, bytemuck::cast(*chunk)));
        }
    }
}

#[inline(always)]
fn write_lane(out: &mut HitPacket, i: usize, t: f32, u: f32, v: f32, inst: u32, prim: u32) {
    out.t.0[i] = t;
    out.u.0[i] = u;
    out.v.0[i] = v;
    out.instance.0[i] = inst;
    out.primitive.0[i] = prim;
}

/// Occlusion of a packet: the mask of active lanes that hit something, with the kernels of `isa`
/// (the built ones where the processor lacks it).
pub(crate) fn occluded_packet_with(
    isa: KernelIsa,
    top: &TopLevel,
    objects: &[Object],
    p: &RayPacket,
    filter: HitFilter,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if let Some(k) = Avx512::on(isa) {
        // SAFETY: `k` exists, so the processor has AVX-512.
        return unsafe { k.occluded_lanes(top, objects, p, p.active, filter, true) };
    }
    let _ = isa;
    // SAFETY: the built kernels run wherever this crate does.
    unsafe { Built.occluded_lanes(top, objects, p, p.active, filter, true) }
}

/// Occlusion of the packet's lanes `active`; an incoherent packet is split by octant when `split`
/// is set.
#[inline(always)]
fn occluded_lanes_in<K: Kernels>(
    k: K,
    top: &TopLevel,
    objects: &[Object],
    p: &RayPacket,
    active: u64,
    filter: HitFilter,
    split: bool,
) -> u64 {
    if active == 0 {
        return 0;
    }
    let single_lanes = |lanes: u64| {
        let mut hit = 0u64;
        let mut m = lanes;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            if single::occluded_scene(top, objects, &p.get(i), filter, i as u32) {
                hit |= 1 << i;
            }
        }
        hit
    };
    if active.count_ones() <= SINGLE_RAY_THRESHOLD {
        return single_lanes(active);
    }
    let fill = active.trailing_zeros() as usize;
    let (lo, hi) = chunk_range(active);
    let mut g = Geom::world(p, active, fill, (lo, hi));
    if !g.finish(lo, hi) {
        if !split {
            return single_lanes(active);
        }
        return octants(p, active)
            .into_iter()
            // SAFETY: as `intersect_object`'s.
            .map(|lanes| unsafe { k.occluded_lanes(top, objects, p, lanes, filter, false) })
            .fold(0, |a, b| a | b);
    }
    let mut s = State::new(p, active, (lo, hi));
    // The packet's chunks `mask` against instance `inst_id`: `true` ends the traversal (every lane
    // occluded, or few enough left to finish one by one).
    let visit = |inst_id: u32, mask: u8, s: &mut State| -> bool {
        let inst: &InstanceData = &top.instances[inst_id as usize];
        let obj = &objects[inst.object as usize];
        let (clo, chi) = mask_range(mask);
        let deforms = obj.deforms();
        if inst.identity && !deforms {
            return occluded_object(
                k,
                &ObjectVisit { obj, inst_id, object_id: inst.object, g: &g, lo: clo, hi: chi, filter },
                s,
            );
        }
        let og = match inst.motion {
            None if !deforms => {
                let mut og = g.transformed(&inst.object_from_world, clo, chi);
                if og.finish(clo, chi) {
                    return occluded_object(
                        k,
                        &ObjectVisit { obj, inst_id, object_id: inst.object, g: &og, lo: clo, hi: chi, filter },
                        s,
                    );
                }
                Some(og)
            }
            _ => None,
        };
        let mut m = lanes_of(mask, s);
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut r = lane_in_object(&g, og.as_ref(), inst, p, i, s.lane_tmin(i), s.lane_tmax(i));
            if single::occluded_object::<true>(obj, inst_id, inst.object, &mut r, filter, i as u32) {
                s.set_lane_tmax(i, f32::NEG_INFINITY);
                s.done |= 1 << i;
            }
        }
        let left = s.active & !s.done;
        if left == 0 {
            return true;
        }
        if left.count_ones() <= SINGLE_RAY_THRESHOLD {
            s.bail = true;
            return true;
        }
        s.update_tmax_hi();
        false
    };
    if let Some(inst_id) = top.sole_instance() {
        visit(inst_id, chunk_mask(lo, hi), &mut s);
    } else {
        traverse::<false, _, _>(
            &top.bvh,
            &g,
            &mut s,
            lo,
            hi,
            |_| {},
            |first, count, mask, s| {
                (first..first + count).any(|slot| visit(top.bvh.prim_order[slot as usize], mask, s))
            },
        );
    }
    let mut hit = s.done & active;
    if s.bail {
        hit |= single_lanes(active & !s.done);
    }
    hit
}

//! An object: a mesh plus its own BVH, built once and rebuilt only when the object's geometry
//! changes. Many instances share one object.
//!
//! Invariant: an object BVH's leaves are **blocks** of up to [`BLOCK_WIDTH`] triangles. The first-slot
//! field of a leaf reference holds the leaf's block `b` (see [`leaf_range`]): its triangles are leaf
//! slots `4 b .. 4 b + count`, lanes `0 .. count` of `blocks[b]`, mesh triangles
//! `bvh.prim_order[4 b + j]`; the block's other lanes hold zeros and the slots [`NO_TRIANGLE`].
//! Every block belongs to one leaf. For a deforming mesh, `deformed.close[b]` is the same block at
//! the deformation's close, and the BVH's boxes bound both ends (so every time between, a prepared
//! triangle being linear in its corners).
//!
//! An object BVH in parts ([`super::parts`], a distributed worker's large objects) holds a small
//! tree whose leaves name parts, and no blocks; each part is an object BVH as above.

use super::bvh4::{BuildQuality, Bvh4, LeafSlots, NO_PRIMITIVE};
use super::bvh8::Bvh8;
use super::parts::{cut, Bounds, Cut};
use crate::geometry::triangle::{PreTriangle, TriangleBlock, BLOCK_WIDTH};
use crate::geometry::{AlphaMask, Mesh};
use glam::Vec3A;
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, OnceLock};

/// Largest leaf the object BVHs are built with: a block, tested at once by single rays (see
/// `docs/tracer.md`).
pub const OBJECT_LEAF_SIZE: u32 = BLOCK_WIDTH as u32;

/// Objects of at most this many triangles are built twice at the default quality
/// ([`BuildQuality::High`]): also by PLOC ([`BuildQuality::Medium`]), keeping the tree of lower
/// SAH cost ([`Bvh4::sah_cost`], each triangle counted). The binned builder counts a side's
/// triangles in whole blocks, which suits single rays (a block is one test) and large meshes; but
/// packets test a leaf's triangles one at a time, and in a small object of large triangles (the
/// Cornell box's walls) filling blocks puts triangles far apart under one box that many packets
/// enter. Both builds of so few triangles take microseconds.
pub const SMALL_OBJECT_TRIANGLES: usize = 1024;

/// The leaf slots of a block's lanes that hold no triangle.
pub const NO_TRIANGLE: u32 = NO_PRIMITIVE;

/// An object's BVH with its triangles in blocks, in leaf order (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct ObjectBvh {
    /// The BVH over the triangles (read by packets), its leaves blocks.
    pub bvh: Bvh4,
    /// Its 8-wide form (read by single rays; same leaves).
    pub wide: Bvh8,
    /// Prepared triangles, [`BLOCK_WIDTH`] to a block, one block a leaf.
    pub blocks: Vec<TriangleBlock>,
    /// A deforming mesh's triangles at its close (`None`: the mesh stands still). In parts, the
    /// deformation's times with no triangles (each part holds its own).
    pub deformed: Option<DeformedTriangles>,
    /// A BVH in parts ([`super::parts`]): `bvh` and `wide` are its small tree, whose leaves name
    /// parts, and `blocks` is empty. `None` for a whole tree.
    pub parts: Option<Box<Parts>>,
}

/// The other end of a deforming object's triangles: a ray at time `t` meets the blend of
/// `blocks[b]` and `close[b]` by [`Deformation::blend`](crate::geometry::Deformation::blend).
#[derive(Clone, Debug, Default)]
pub struct DeformedTriangles {
    /// Prepared triangles at the close, in the blocks of the open ones.
    pub close: Vec<TriangleBlock>,
    pub open_time: f32,
    pub close_time: f32,
}

impl DeformedTriangles {
    /// Block `b` at `time`.
    #[inline(always)]
    pub fn block_at(&self, blocks: &[TriangleBlock], b: usize, time: f32) -> TriangleBlock {
        blocks[b].lerp(&self.close[b], crate::geometry::mesh::blend_between(self.open_time, self.close_time, time))
    }

    /// Leaf slot `s`'s triangle at `time` (the same values as its lane of [`Self::block_at`]).
    #[inline(always)]
    pub fn at(&self, blocks: &[TriangleBlock], s: usize, time: f32) -> PreTriangle {
        let (b, j) = (s / BLOCK_WIDTH, s % BLOCK_WIDTH);
        let w = crate::geometry::mesh::blend_between(self.open_time, self.close_time, time);
        blocks[b].triangle(j).lerp(&self.close[b].triangle(j), w)
    }
}

/// How many blocks ahead [`ObjectBvh::from_bvh4`] starts loading the triangles of a block.
const BLOCKS_AHEAD: usize = 4;

impl ObjectBvh {
    /// Builds the BVH of `mesh`.
    pub fn build(mesh: &Mesh, quality: BuildQuality) -> Self {
        let box_of = |corners: [glam::Vec3; 3]| {
            let [a, b, c] = corners.map(Vec3A::from);
            (a.min(b).min(c), a.max(b).max(c))
        };
        let boxes: Vec<Aabb> = match &mesh.deformation {
            None => (0..mesh.triangle_count())
                .into_par_iter()
                .with_min_len(4096)
                .map(|i| {
                    let (lo, hi) = box_of(mesh.corners(i));
                    Aabb::new(lo, hi)
                })
                .collect(),
            Some(d) => (0..mesh.triangle_count())
                .into_par_iter()
                .with_min_len(4096)
                .map(|i| {
                    let (lo, hi) = box_of(mesh.corners(i));
                    let (clo, chi) = box_of(mesh.triangles[i].map(|k| d.positions[k as usize]));
                    Aabb::new(lo.min(clo), hi.max(chi))
                })
                .collect(),
        };
        let slots = LeafSlots::Blocks(BLOCK_WIDTH as u32);
        let mut bvh = Bvh4::build_with(&boxes, quality, OBJECT_LEAF_SIZE, slots);
        if quality == BuildQuality::High && boxes.len() <= SMALL_OBJECT_TRIANGLES {
            let ploc = Bvh4::build_with(&boxes, BuildQuality::Medium, OBJECT_LEAF_SIZE, slots);
            if ploc.sah_cost() < bvh.sah_cost() {
                bvh = ploc;
            }
        }
        ObjectBvh::from_bvh4(mesh, bvh)
    }

    /// The object BVH of `mesh` around `bvh`, a 4-wide BVH over its triangles whose leaves are
    /// blocks (built here, or built elsewhere and checked: [`super::wire::decode_bvh4`]): its
    /// prepared triangles and its 8-wide form.
    pub fn from_bvh4(mesh: &Mesh, bvh: Bvh4) -> Self {
        let order = &bvh.prim_order;
        let blocks_of = |positions: &[glam::Vec3]| -> Vec<TriangleBlock> {
            let mut blocks = Vec::with_capacity(order.len() / BLOCK_WIDTH);
            order
                .par_chunks(BLOCK_WIDTH)
                .with_min_len(1024)
                .enumerate()
                .map(|(c, lanes)| {
                    // The leaves' triangles are scattered over the mesh: those of a block a few
                    // ahead start loading now, so that their misses overlap.
                    let ahead = order.get((c + BLOCKS_AHEAD) * BLOCK_WIDTH..(c + BLOCKS_AHEAD + 1) * BLOCK_WIDTH);
                    for t in ahead.unwrap_or(&[]).iter().filter_map(|&p| mesh.triangles.get(p as usize)) {
                        super::prefetch(t, 1);
                    }
                    // Each triangle goes from registers into its lane: gathered as `PreTriangle`s
                    // first, the block's rows were read back through stalled store forwarding.
                    let mut block = TriangleBlock::default();
                    for (j, &p) in lanes.iter().take_while(|&&p| p != NO_TRIANGLE).enumerate().take(BLOCK_WIDTH) {
                        let [a, b, c] = mesh.triangles[p as usize].map(|k| positions[k as usize]);
                        block.set(j, &PreTriangle::new(a, b, c));
                    }
                    block
                })
                .collect_into_vec(&mut blocks);
            blocks
        };
        let blocks = blocks_of(&mesh.positions);
        let deformed = mesh.deformation.as_ref().map(|d| DeformedTriangles {
            close: blocks_of(&d.positions),
            open_time: d.open,
            close_time: d.close,
        });
        let wide = Bvh8::from_bvh4(&bvh);
        ObjectBvh { bvh, wide, blocks, deformed, parts: None }
    }

    /// Leaf slot `s`'s triangle (at the deformation's open).
    #[inline(always)]
    pub fn triangle(&self, s: usize) -> PreTriangle {
        self.blocks[s / BLOCK_WIDTH].triangle(s % BLOCK_WIDTH)
    }

    /// Heap bytes of the BVH and the prepared triangles.
    pub fn memory_bytes(&self) -> usize {
        let blocks = self.blocks.len() + self.deformed.as_ref().map_or(0, |d| d.close.len());
        let parts = self.parts.as_ref().map_or(0, |p| p.memory_bytes());
        self.bvh.memory_bytes() + self.wide.memory_bytes() + blocks * size_of::<TriangleBlock>() + parts
    }
}

/// What an object traces: its mesh and the BVH built from it.
#[derive(Clone, Debug, Default)]
pub struct ObjectData {
    /// The geometry (shared, so that it can be handed out cheaply).
    pub mesh: Arc<Mesh>,
    /// Shared by the objects of other scenes with the same geometry ([`super::store::BvhStore`]).
    pub bvh: Arc<ObjectBvh>,
}

/// What a render thread that asks ahead traces in place of an object, or of a part of an
/// object's BVH, that is not here yet: nothing (its rays miss).
static MISSED: std::sync::LazyLock<ObjectData> = std::sync::LazyLock::new(ObjectData::default);
static MISSED_PART: std::sync::LazyLock<ObjectBvh> = std::sync::LazyLock::new(ObjectBvh::default);

/// Where the mesh of a demand-loaded object comes from (a distributed render's master).
pub trait MeshSource: Send + Sync + std::fmt::Debug {
    /// The mesh of the object the source knows as `key`; blocks until it is here. A source that
    /// cannot deliver returns an empty mesh and reports why through its own channel (the frame
    /// then fails): a traversal has no way to return an error.
    fn fetch(&self, key: u32) -> FetchedMesh;
    /// Part `part` of the object the source knows as `key`, delivered in parts
    /// ([`FetchedMesh::parts`]): its 4-wide BVH over `mesh`'s triangles, checked to hold `triangles`
    /// of them under `bounds`; blocks until it is here. `None` when it cannot be had (the source
    /// reports why, as for [`MeshSource::fetch`]).
    fn fetch_part(&self, _key: u32, _part: u32, _mesh: &Mesh, _triangles: u32, _bounds: Bounds) -> Option<Bvh4> {
        None
    }
    /// Asks for the mesh of `key` without waiting for it, for a render thread that renders
    /// [`super::ask_ahead::without_waiting`]: a later [`MeshSource::fetch`] of it takes the answer.
    /// Returns whether it asked (a source that cannot ask ahead returns `false`, and the thread
    /// waits for [`MeshSource::fetch`] as usual).
    fn ask_ahead(&self, _key: u32) -> bool {
        false
    }
    /// [`MeshSource::ask_ahead`] for part `part` of the object's BVH.
    fn ask_ahead_part(&self, _key: u32, _part: u32) -> bool {
        false
    }
    /// Told how long building the BVH of a mesh it delivered took (a worker reports it).
    fn built(&self, _took: std::time::Duration) {}
    /// The frame count the source's objects stamp themselves with when a ray reaches them (for
    /// least-recently-used eviction, [`Object::last_used`]).
    fn clock(&self) -> Arc<AtomicU32>;
}

/// A demand-loaded object's geometry as its source delivers it.
#[derive(Clone, Debug, Default)]
pub struct FetchedMesh {
    pub mesh: Arc<Mesh>,
    /// The 4-wide BVH over the mesh's triangles, where the source has it built (checked against
    /// the mesh); without it the object builds its own.
    pub bvh: Option<Bvh4>,
    /// Instead of `bvh`, a BVH in parts: the small tree and each part's triangle count and box
    /// (the parts come by [`MeshSource::fetch_part`] when rays reach them).
    pub parts: Option<(Bvh4, Vec<(u32, Bounds)>)>,
}

/// What is known of a demand-loaded object before its mesh is here: enough to place its
/// instances in the top-level BVH and to bind its attributes to shader parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshSummary {
    /// The root bounds of its BVH (as the master built it: the same top-level BVH follows).
    pub bounds: Option<(Vec3A, Vec3A)>,
    pub triangles: u32,
    /// Its per-vertex attributes' names and sizes.
    pub attributes: Vec<(String, u32)>,
    /// [`Mesh::digest`] of the mesh, with the shape of the master's tree over it where it has
    /// one: a worker that holds a mesh of this digest from an earlier scene takes it (and its
    /// tree, or small tree, whose parts it fetches from the master's tree of the new scene)
    /// rather than fetching it.
    pub digest: [u8; 32],
}

impl MeshSummary {
    /// The summary of `mesh`, whose BVH has root bounds `bounds`.
    pub fn of(mesh: &Mesh, bounds: Option<(Vec3A, Vec3A)>) -> MeshSummary {
        MeshSummary {
            bounds,
            triangles: mesh.triangle_count() as u32,
            attributes: mesh.attributes.iter().map(|a| (a.name.clone(), a.components as u32)).collect(),
            digest: mesh.digest(),
        }
    }

    /// The summary of `mesh` and `tree`, the master's BVH over it: its digest tells trees of
    /// other shapes apart (another build quality), so that a kept small tree never meets the
    /// parts of another cut.
    pub fn of_tree(mesh: &Mesh, tree: &Bvh4) -> MeshSummary {
        let mut summary = MeshSummary::of(mesh, tree.bounds);
        let mut hasher = blake3::Hasher::new();
        hasher.update(&summary.digest);
        hasher.update(&(tree.nodes.len() as u64).to_le_bytes());
        hasher.update(&(tree.depth as u64).to_le_bytes());
        hasher.update(&tree.sah_cost().to_bits().to_le_bytes());
        summary.digest = hasher.finalize().into();
        summary
    }
}

#[derive(Debug)]
struct Remote {
    summary: MeshSummary,
    key: u32,
    source: Arc<dyn MeshSource>,
    quality: BuildQuality,
    clock: Arc<AtomicU32>,
    /// The clock when a ray last reached the object.
    last_used: AtomicU32,
}

impl Clone for Remote {
    fn clone(&self) -> Self {
        Remote {
            summary: self.summary.clone(),
            key: self.key,
            source: self.source.clone(),
            quality: self.quality,
            clock: self.clock.clone(),
            last_used: AtomicU32::new(self.last_used.load(Ordering::Relaxed)),
        }
    }
}

impl Remote {
    #[inline(always)]
    fn touch(&self) {
        // Written once a frame at most: the line stays shared between the threads that read it.
        let now = self.clock.load(Ordering::Relaxed);
        if self.last_used.load(Ordering::Relaxed) != now {
            self.last_used.store(now, Ordering::Relaxed);
        }
    }
}

/// A retained object: its mesh and BVH, here from the start, or (demand loading) fetched from a
/// [`MeshSource`] the first time a ray reaches its bounds and kept until [`Object::evict`].
#[derive(Clone, Debug, Default)]
pub struct Object {
    data: OnceLock<ObjectData>,
    remote: Option<Remote>,
    /// Cut-outs: where the mask is uncovered the object has no surface.
    pub alpha: Option<Arc<AlphaMask>>,
}

impl Object {
    /// Builds an object from a mesh.
    pub fn new(mesh: Arc<Mesh>, quality: BuildQuality) -> Self {
        let bvh = Arc::new(ObjectBvh::build(&mesh, quality));
        Object::with_bvh(mesh, bvh)
    }

    /// An object of a mesh and the BVH built from it (or from a mesh of the same geometry).
    pub fn with_bvh(mesh: Arc<Mesh>, bvh: Arc<ObjectBvh>) -> Self {
        Object { data: OnceLock::from(ObjectData { mesh, bvh }), remote: None, alpha: None }
    }

    /// An object whose mesh `source` delivers when a ray first needs it (its BVH is then built at
    /// `quality`).
    pub fn remote(summary: MeshSummary, key: u32, source: Arc<dyn MeshSource>, quality: BuildQuality) -> Self {
        let clock = source.clock();
        let last_used = AtomicU32::new(clock.load(Ordering::Relaxed));
        let remote = Remote { summary, key, source, quality, clock, last_used };
        Object { data: OnceLock::new(), remote: Some(remote), alpha: None }
    }

    /// The mesh and BVH, fetched and built first if the object is remote and not yet here.
    #[inline(always)]
    pub fn data(&self) -> &ObjectData {
        if let Some(r) = &self.remote {
            r.touch();
        }
        match self.data.get() {
            Some(d) => d,
            None => self.load(),
        }
    }

    #[cold]
    #[inline(never)]
    fn load(&self) -> &ObjectData {
        if let Some(r) = &self.remote {
            if super::ask_ahead::asks_ahead() && r.source.ask_ahead(r.key) {
                super::ask_ahead::missed();
                return &MISSED;
            }
        }
        // One thread fetches; others that need the object meanwhile wait for it.
        self.data.get_or_init(|| match &self.remote {
            Some(r) => {
                let FetchedMesh { mesh, bvh, parts } = r.source.fetch(r.key);
                // Built on a thread of its own: on this one (a rayon worker), the build's parallel
                // loops could take a queued job that needs this very object, and wait for itself.
                let building = std::time::Instant::now();
                let build = || match (parts, bvh) {
                    (Some((small, parts)), _) => ObjectBvh::parted(&mesh, small, parts),
                    (None, Some(bvh)) => ObjectBvh::from_bvh4(&mesh, bvh),
                    (None, None) => ObjectBvh::build(&mesh, r.quality),
                };
                let bvh = std::thread::scope(|s| s.spawn(build).join()).unwrap_or_default();
                r.source.built(building.elapsed());
                ObjectData { mesh, bvh: Arc::new(bvh) }
            }
            None => ObjectData::default(),
        })
    }

    /// Part `p` of `parts`, the parts of this object's BVH, fetched and built first if it is not
    /// here yet (a part that cannot be had is empty: its rays miss, and the source has reported
    /// why).
    #[inline(always)]
    pub fn part<'a>(&'a self, parts: &'a Parts, p: u32) -> &'a ObjectBvh {
        // Part names are checked against the parts when the small tree arrives.
        let part = &parts.parts[p as usize];
        if let Some(r) = &self.remote {
            part.touch(r.clock.load(Ordering::Relaxed));
        }
        match part.bvh.get() {
            Some(bvh) => bvh,
            None => self.load_part(part, p),
        }
    }

    #[cold]
    #[inline(never)]
    fn load_part<'a>(&'a self, part: &'a Part, p: u32) -> &'a ObjectBvh {
        // As `load`: one thread fetches, others wait; built on a thread of its own.
        if let Some(r) = &self.remote {
            if super::ask_ahead::asks_ahead() && r.source.ask_ahead_part(r.key, p) {
                super::ask_ahead::missed();
                return &MISSED_PART;
            }
        }
        part.bvh.get_or_init(|| {
            let Some(r) = &self.remote else { return ObjectBvh::default() };
            let mesh = &self.data().mesh;
            let Some(bvh) = r.source.fetch_part(r.key, p, mesh, part.triangles, part.bounds) else {
                return ObjectBvh::default();
            };
            let building = std::time::Instant::now();
            let built = std::thread::scope(|s| s.spawn(|| ObjectBvh::from_bvh4(mesh, bvh)).join()).unwrap_or_default();
            r.source.built(building.elapsed());
            built
        })
    }

    /// Whether the object's mesh deforms over the shutter interval (fetched first if remote).
    #[inline(always)]
    pub fn deforms(&self) -> bool {
        self.data().bvh.deformed.is_some()
    }

    /// The digest of a demand-loaded object's mesh ([`MeshSummary::digest`]).
    pub fn digest(&self) -> Option<&[u8; 32]> {
        self.remote.as_ref().map(|r| &r.summary.digest)
    }

    /// Gives a demand-loaded object that has not fetched its mesh yet the mesh and BVH of its
    /// digest, kept from an earlier scene; `false` (and nothing changes) for any other object
    /// or another digest.
    pub fn preload(&self, digest: &[u8; 32], data: ObjectData) -> bool {
        self.digest() == Some(digest) && self.data.set(data).is_ok()
    }

    /// The mesh and BVH, if they are here (never fetches).
    pub fn resident_data(&self) -> Option<&ObjectData> {
        self.data.get()
    }

    /// Whether the mesh and BVH are here.
    pub fn is_resident(&self) -> bool {
        self.data.get().is_some()
    }

    /// How many parts of the object's BVH are here, when it is here in parts.
    pub fn resident_parts(&self) -> usize {
        self.data.get().and_then(|d| d.bvh.parts.as_ref()).map_or(0, |p| p.resident())
    }

    /// Whether the object's BVH is, or may come, in parts (it is demand-loaded, or was given a
    /// BVH in parts).
    pub fn may_be_in_parts(&self) -> bool {
        self.remote.is_some() || self.data.get().is_some_and(|d| d.bvh.parts.is_some())
    }

    /// Whether the object is demand-loaded.
    pub fn is_remote(&self) -> bool {
        self.remote.is_some()
    }

    /// What a demand-loaded object's source knows it as.
    pub fn remote_key(&self) -> Option<u32> {
        self.remote.as_ref().map(|r| r.key)
    }

    /// A demand-loaded object's [`MeshSource::clock`] when a ray last reached it.
    pub fn last_used(&self) -> Option<u32> {
        self.remote.as_ref().map(|r| r.last_used.load(Ordering::Relaxed))
    }

    /// Drops a demand-loaded object's mesh and BVH (fetched again when next needed); returns the
    /// bytes freed. An object built here stays.
    pub fn evict(&mut self) -> usize {
        if self.remote.is_none() {
            return 0;
        }
        self.data.take().map_or(0, |d| d.mesh.memory_bytes() + d.bvh.memory_bytes())
    }

    /// The parts of a demand-loaded object's BVH that are here: each part's number, the clock
    /// when a ray last reached it ([`Object::last_used`]) and its heap bytes.
    pub fn resident_parts_in_use(&self) -> Vec<(u32, u32, usize)> {
        let Some(parts) = self.data.get().and_then(|d| d.bvh.parts.as_ref()).filter(|_| self.remote.is_some()) else {
            return Vec::new();
        };
        let held = parts.parts.iter().enumerate();
        held.filter_map(|(p, part)| {
            Some((p as u32, part.last_used.load(Ordering::Relaxed), part.bvh.get()?.memory_bytes()))
        })
        .collect()
    }

    /// Drops part `p` of a demand-loaded object's BVH (fetched again when a ray next reaches
    /// it); returns the bytes freed.
    pub fn evict_part(&mut self, p: u32) -> usize {
        if self.remote.is_none() {
            return 0;
        }
        let Some(bvh) = self.data.get_mut().and_then(|d| Arc::get_mut(&mut d.bvh)) else { return 0 };
        let Some(part) = bvh.parts.as_deref_mut().and_then(|parts| parts.parts.get_mut(p as usize)) else { return 0 };
        part.bvh.take().map_or(0, |b| b.memory_bytes())
    }

    /// Makes a demand-loaded object's BVH in parts whole once every part is here
    /// ([`ObjectBvh::joined`]), so that rays no longer traverse it part by part; returns whether
    /// it did. Its parts then go together, with the object ([`Object::evict`]).
    pub fn join_parts(&mut self) -> bool {
        if self.remote.is_none() {
            return false;
        }
        let Some(data) = self.data.get_mut() else { return false };
        let Some(joined) = data.bvh.joined() else { return false };
        data.bvh = Arc::new(joined);
        true
    }

    /// The root bounds of the object's BVH, without fetching it.
    pub fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        match (&self.remote, self.data.get()) {
            (Some(r), _) => r.summary.bounds,
            (None, Some(d)) => d.bvh.bvh.bounds,
            (None, None) => None,
        }
    }

    /// Triangles, without fetching.
    pub fn triangle_count(&self) -> usize {
        match (&self.remote, self.data.get()) {
            (Some(r), _) => r.summary.triangles as usize,
            (None, Some(d)) => d.mesh.triangle_count(),
            (None, None) => 0,
        }
    }

    /// The per-vertex attributes' names and sizes, without fetching.
    pub fn attribute_names(&self) -> Vec<(String, usize)> {
        match (&self.remote, self.data.get()) {
            (Some(r), _) => r.summary.attributes.iter().map(|(n, c)| (n.clone(), *c as usize)).collect(),
            (None, Some(d)) => d.mesh.attributes.iter().map(|a| (a.name.clone(), a.components)).collect(),
            (None, None) => Vec::new(),
        }
    }

    /// Heap bytes of what is here.
    pub fn memory_bytes(&self) -> usize {
        let data = self.data.get().map_or(0, |d| d.mesh.memory_bytes() + d.bvh.memory_bytes());
        data + self.alpha.as_ref().map_or(0, |a| a.memory_bytes())
    }

    /// Whether a candidate hit of triangle `primitive` at barycentrics `(u, v)` is on the surface
    /// (not in a cut-out of the alpha mask).
    #[inline(always)]
    pub fn solid_at(&self, primitive: u32, u: f32, v: f32) -> bool {
        match &self.alpha {
            None => true,
            Some(mask) => mask.covers(&self.data().mesh, primitive, u, v),
        }
    }
}

/// The parts under an object's small tree (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct Parts {
    pub parts: Vec<Part>,
}

/// One part: what is known of it before it is here, and its BVH once it is.
#[derive(Debug, Default)]
pub struct Part {
    pub triangles: u32,
    /// Its box in the small tree.
    pub bounds: Bounds,
    pub bvh: OnceLock<ObjectBvh>,
    /// The demand-loading clock when a ray last reached it (for least-recently-used eviction).
    pub last_used: AtomicU32,
}

impl Clone for Part {
    fn clone(&self) -> Self {
        Part {
            triangles: self.triangles,
            bounds: self.bounds,
            bvh: self.bvh.clone(),
            last_used: AtomicU32::new(self.last_used.load(Ordering::Relaxed)),
        }
    }
}

impl Part {
    /// Stamps the part with the clock's `now`.
    #[inline(always)]
    pub fn touch(&self, now: u32) {
        // Written once a frame at most: the line stays shared between the threads that read it.
        if self.last_used.load(Ordering::Relaxed) != now {
            self.last_used.store(now, Ordering::Relaxed);
        }
    }
}

impl Parts {
    /// Heap bytes of the parts that are here.
    pub fn memory_bytes(&self) -> usize {
        let held: usize = self.parts.iter().filter_map(|p| p.bvh.get()).map(ObjectBvh::memory_bytes).sum();
        held + self.parts.len() * size_of::<Part>()
    }

    /// How many parts are here.
    pub fn resident(&self) -> usize {
        self.parts.iter().filter(|p| p.bvh.get().is_some()).count()
    }
}

impl ObjectBvh {
    /// The object BVH of `mesh` in parts: the small tree `small` (leaf `p` naming part `p`), each
    /// part's triangle count and box; the parts' BVHs are not here (see [`Object::part`]).
    pub fn parted(mesh: &Mesh, small: Bvh4, parts: Vec<(u32, Bounds)>) -> ObjectBvh {
        let wide = Bvh8::from_bvh4(&small);
        // The deformation's times, with no triangles: each part holds its own.
        let deformed = mesh.deformation.as_ref().map(|d| DeformedTriangles {
            close: Vec::new(),
            open_time: d.open,
            close_time: d.close,
        });
        let parts =
            parts.into_iter().map(|(triangles, bounds)| Part { triangles, bounds, ..Part::default() }).collect();
        ObjectBvh { bvh: small, wide, blocks: Vec::new(), deformed, parts: Some(Box::new(Parts { parts })) }
    }

    /// This BVH in parts made whole again, once every part is here: the tree it was cut from
    /// ([`super::parts::join`]), with the parts' prepared triangles in its leaf order and its
    /// 8-wide form. Rays then find the same hits (the parts' traversal is the whole tree's, see
    /// [`super::parts`]) without a traversal per part. `None` for a whole tree, or while a part is
    /// missing.
    pub fn joined(&self) -> Option<ObjectBvh> {
        let parts = self.parts.as_deref()?;
        let held: Vec<&ObjectBvh> = parts.parts.iter().map(|p| p.bvh.get()).collect::<Option<_>>()?;
        let trees: Vec<&Bvh4> = held.iter().map(|p| &p.bvh).collect();
        let (bvh, order) = super::parts::join(&self.bvh, &trees)?;
        let in_order = |blocks_of: &dyn Fn(&ObjectBvh) -> Option<&[TriangleBlock]>| -> Option<Vec<TriangleBlock>> {
            let mut blocks = Vec::with_capacity(bvh.prim_order.len() / BLOCK_WIDTH);
            for &p in &order {
                blocks.extend_from_slice(blocks_of(held[p as usize])?);
            }
            (blocks.len() * BLOCK_WIDTH == bvh.prim_order.len()).then_some(blocks)
        };
        let blocks = in_order(&|p| Some(&p.blocks))?;
        let deformed = match &self.deformed {
            None => None,
            Some(d) => Some(DeformedTriangles {
                close: in_order(&|p| p.deformed.as_ref().map(|d| d.close.as_slice()))?,
                open_time: d.open_time,
                close_time: d.close_time,
            }),
        };
        let wide = Bvh8::from_bvh4(&bvh);
        Some(ObjectBvh { bvh, wide, blocks, deformed, parts: None })
    }

    /// This (whole) BVH of `mesh` in parts of at most `part_triangles` triangles, every part here.
    pub fn in_parts(&self, mesh: &Mesh, part_triangles: u32) -> ObjectBvh {
        let Cut { small, parts } = cut(&self.bvh, part_triangles);
        let known = parts.iter().map(|p| (p.triangles, p.bounds())).collect();
        let mut parted = ObjectBvh::parted(mesh, small, known);
        let built: Vec<ObjectBvh> = parts.into_par_iter().map(|p| ObjectBvh::from_bvh4(mesh, p.bvh)).collect();
        if let Some(held) = parted.parts.as_deref_mut() {
            for (part, bvh) in held.parts.iter_mut().zip(built) {
                part.bvh = OnceLock::from(bvh);
            }
        }
        parted
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh4::{leaf_range, leaf_ref, EMPTY_CHILD, LEAF_BIT};
    use crate::geometry::Deformation;
    use glam::Vec3;

    /// The reference for [`LeafSlots::Blocks`]: `bvh` (leaf references holding first slots, leaves
    /// of at most [`BLOCK_WIDTH`] primitives) with its leaves made blocks afterwards: leaf `i` in
    /// slot order becomes block `i`, its slots `4 i ..`, the block's unused slots [`NO_TRIANGLE`].
    fn leaves_in_blocks(mut bvh: Bvh4) -> Bvh4 {
        // Each leaf's place in the node array, at its first slot: read in slot order, no sort.
        const NONE: u32 = u32::MAX;
        let mut leaf_at = vec![NONE; bvh.prim_order.len()];
        let mut leaves = 0;
        for (i, node) in bvh.nodes.iter().enumerate() {
            for (k, &r) in node.child.iter().enumerate() {
                if r & LEAF_BIT != 0 && r != EMPTY_CHILD {
                    leaf_at[leaf_range(r).0 as usize] = (4 * i + k) as u32;
                    leaves += 1;
                }
            }
        }
        let mut order = vec![NO_TRIANGLE; BLOCK_WIDTH * leaves];
        for (b, at) in leaf_at.into_iter().filter(|&at| at != NONE).enumerate() {
            let child = &mut bvh.nodes[at as usize / 4].child[at as usize % 4];
            let (first, count) = leaf_range(*child);
            assert!(count as usize <= BLOCK_WIDTH, "a leaf of {count} primitives does not fit a block");
            let slots = first as usize..(first + count) as usize;
            order[BLOCK_WIDTH * b..BLOCK_WIDTH * b + slots.len()].copy_from_slice(&bvh.prim_order[slots]);
            *child = leaf_ref(b as u32, count);
        }
        bvh.prim_order = order;
        bvh
    }

    /// `n` small triangles scattered over a box (a fixed sequence), each its own three vertices;
    /// with `moving`, each also somewhere else at the deformation's close.
    fn scattered(n: usize, moving: bool) -> Mesh {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut positions = Vec::new();
        for _ in 0..n {
            let at = Vec3::new(next(), next(), next()) * 50.0;
            for _ in 0..3 {
                positions.push(at + Vec3::new(next(), next(), next()));
            }
        }
        let triangles = (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let mut mesh = Mesh::from_triangles(positions, triangles).expect("a valid mesh");
        if moving {
            let close = mesh.positions.iter().map(|&p| p + Vec3::new(8.0, -3.0, 1.0) * next()).collect();
            mesh.deformation = Some(Deformation { positions: close, normals: None, open: 0.0, close: 1.0 });
        }
        mesh
    }

    /// A room of large quads (floor, ceiling, three walls) around two boxes: the Cornell box's
    /// kind of object, few triangles and most of them large.
    fn room() -> Mesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut quad = |corners: [Vec3; 4]| {
            let first = positions.len() as u32;
            positions.extend(corners);
            triangles.push([first, first + 1, first + 2]);
            triangles.push([first, first + 2, first + 3]);
        };
        let (w, h, d) = (556.0, 548.0, 559.0);
        quad([Vec3::ZERO, Vec3::new(w, 0.0, 0.0), Vec3::new(w, 0.0, d), Vec3::new(0.0, 0.0, d)]);
        quad([Vec3::new(0.0, h, 0.0), Vec3::new(0.0, h, d), Vec3::new(w, h, d), Vec3::new(w, h, 0.0)]);
        quad([Vec3::new(0.0, 0.0, d), Vec3::new(w, 0.0, d), Vec3::new(w, h, d), Vec3::new(0.0, h, d)]);
        quad([Vec3::ZERO, Vec3::new(0.0, 0.0, d), Vec3::new(0.0, h, d), Vec3::new(0.0, h, 0.0)]);
        quad([Vec3::new(w, 0.0, 0.0), Vec3::new(w, h, 0.0), Vec3::new(w, h, d), Vec3::new(w, 0.0, d)]);
        for (lo, hi) in [
            (Vec3::new(80.0, 0.0, 60.0), Vec3::new(240.0, 165.0, 220.0)),
            (Vec3::new(290.0, 0.0, 250.0), Vec3::new(450.0, 330.0, 410.0)),
        ] {
            let c = |x: bool, y: bool, z: bool| {
                Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
            };
            quad([c(false, true, false), c(true, true, false), c(true, true, true), c(false, true, true)]);
            quad([c(false, false, false), c(true, false, false), c(true, true, false), c(false, true, false)]);
            quad([c(false, false, true), c(false, true, true), c(true, true, true), c(true, false, true)]);
            quad([c(false, false, false), c(false, true, false), c(false, true, true), c(false, false, true)]);
            quad([c(true, false, false), c(true, false, true), c(true, true, true), c(true, true, false)]);
        }
        Mesh::from_triangles(positions, triangles).expect("a valid mesh")
    }

    /// At the default quality an object of at most `SMALL_OBJECT_TRIANGLES` triangles keeps the
    /// tree of lower SAH cost of its binned and its PLOC builds; a larger one keeps the binned
    /// build's.
    #[test]
    fn small_objects_keep_the_tree_of_lower_cost() {
        for mesh in [room(), scattered(300, false), scattered(SMALL_OBJECT_TRIANGLES + 1, false)] {
            let boxes: Vec<Aabb> = (0..mesh.triangle_count())
                .map(|i| {
                    let [a, b, c] = mesh.corners(i).map(Vec3A::from);
                    Aabb::new(a.min(b).min(c), a.max(b).max(c))
                })
                .collect();
            let slots = LeafSlots::Blocks(BLOCK_WIDTH as u32);
            let cost = |q| Bvh4::build_with(&boxes, q, OBJECT_LEAF_SIZE, slots).sah_cost();
            let (binned, ploc) = (cost(BuildQuality::High), cost(BuildQuality::Medium));
            let built = ObjectBvh::build(&mesh, BuildQuality::High).bvh.sah_cost();
            let n = mesh.triangle_count();
            let expected = if n <= SMALL_OBJECT_TRIANGLES { binned.min(ploc) } else { binned };
            assert_eq!(built, expected, "{n} triangles: binned {binned}, PLOC {ploc}");
        }
    }

    /// Every triangle lands in one block lane as the mesh gives it, at both ends of a deformation,
    /// and its leaf's box holds both ends; unused lanes are empty.
    #[test]
    fn blocks_hold_the_leaves_triangles_inside_the_leaves_boxes() {
        for moving in [false, true] {
            for n in [1, 6, 1000, 20_000] {
                let mesh = scattered(n, moving);
                let built = ObjectBvh::build(&mesh, BuildQuality::High);
                let close =
                    |s: usize| built.deformed.as_ref().map(|d| d.close[s / BLOCK_WIDTH].triangle(s % BLOCK_WIDTH));
                let mut seen = vec![0u32; n];
                for (s, &p) in built.bvh.prim_order.iter().enumerate() {
                    if p == NO_TRIANGLE {
                        assert_eq!(built.triangle(s), PreTriangle::default());
                        continue;
                    }
                    seen[p as usize] += 1;
                    let [a, b, c] = mesh.corners(p as usize);
                    assert_eq!(built.triangle(s), PreTriangle::new(a, b, c), "{n} triangles, slot {s}");
                    let ends =
                        mesh.deformation.as_ref().map(|d| mesh.triangles[p as usize].map(|k| d.positions[k as usize]));
                    assert_eq!(close(s), ends.map(|[a, b, c]| PreTriangle::new(a, b, c)));
                }
                assert!(seen.iter().all(|&k| k == 1), "{n} triangles: each in one lane");
                for node in &built.bvh.nodes {
                    for k in (0..4).filter(|&k| node.child[k] & LEAF_BIT != 0 && node.child[k] != EMPTY_CHILD) {
                        let lo = Vec3::new(node.min_x[k], node.min_y[k], node.min_z[k]);
                        let hi = Vec3::new(node.max_x[k], node.max_y[k], node.max_z[k]);
                        let (block, count) = leaf_range(node.child[k]);
                        for s in BLOCK_WIDTH * block as usize..BLOCK_WIDTH * block as usize + count as usize {
                            let p = built.bvh.prim_order[s] as usize;
                            let close =
                                mesh.deformation.as_ref().map(|d| mesh.triangles[p].map(|i| d.positions[i as usize]));
                            for q in mesh.corners(p).into_iter().chain(close.into_iter().flatten()) {
                                assert!(q.cmpge(lo).all() && q.cmple(hi).all(), "{n} triangles: {q} outside its leaf");
                            }
                        }
                    }
                }
            }
        }
    }

    /// The default quality's splits count triangles in blocks, so leaves fill their blocks: on
    /// scattered triangles more than four in five of the blocks' lanes hold one (with each
    /// triangle counted on its own, fewer than three in four do).
    #[test]
    fn default_builds_fill_their_blocks() {
        let n = 20_000;
        let tree = ObjectBvh::build(&scattered(n, false), BuildQuality::High);
        let fill = n as f64 / (BLOCK_WIDTH * tree.blocks.len()) as f64;
        assert!(fill > 0.8, "{fill}");
    }

    /// Leaves laid out in blocks as the collapse writes them are the blocks made afterwards from
    /// the packed layout (the same nodes and slots) of a build with the same split costs, for every
    /// quality, tiny inputs included.
    #[test]
    fn leaves_collapsed_into_blocks_are_the_packed_leaves_made_blocks() {
        let qualities = [BuildQuality::Fast, BuildQuality::Medium, BuildQuality::High, BuildQuality::Best];
        for n in [1, 3, 4, 5, 9, 700, 10_000] {
            let mesh = scattered(n, false);
            let boxes: Vec<Aabb> = (0..n)
                .map(|i| {
                    let [a, b, c] = mesh.corners(i).map(Vec3A::from);
                    Aabb::new(a.min(b).min(c), a.max(b).max(c))
                })
                .collect();
            for q in qualities {
                let block = BLOCK_WIDTH as u32;
                let packed =
                    leaves_in_blocks(Bvh4::build_costed(&boxes, q, OBJECT_LEAF_SIZE, LeafSlots::Packed, block));
                let blocks = Bvh4::build_with(&boxes, q, OBJECT_LEAF_SIZE, LeafSlots::Blocks(BLOCK_WIDTH as u32));
                assert_eq!(blocks.prim_order, packed.prim_order, "{n} boxes, {q:?}");
                assert!(blocks.nodes == packed.nodes, "{n} boxes, {q:?}");
                assert_eq!((blocks.depth, blocks.bounds), (packed.depth, packed.bounds));
            }
        }
    }
}

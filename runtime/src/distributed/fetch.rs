//! Demand loading on a worker: the render threads' requests for what rays reached and the worker
//! does not hold (the meshes of objects, textures, shadow maps and grids), passed to the thread
//! that talks to the master, and the master's answers passed back (the paper's section 5.4).
//!
//! A render thread that needs an object's mesh ([`MeshSource::fetch`], from the object's first
//! traversal) or a texture ([`TextureSource::fetch`], from its first lookup) queues a request and
//! waits; the worker's communication thread sends the queued requests as one `Fetch` message at
//! its next poll and hands each item of the `Data` answer to the threads waiting for it. Other
//! threads that reach the same object or texture meanwhile wait on the object (`Object::data`) or
//! the cache's slot, so each is fetched once.
//!
//! A fetch that fails (the answer is damaged, or never comes) leaves the object empty or the
//! texture missing and is recorded: the frame then ends with that failure, reported by the
//! master, never a wrong image passed off as right. A texture the master has no file for is no
//! failure: it is the warning a single process gives.

use crate::accel::bvh4::Bvh4;
use crate::accel::object::{FetchedMesh, MeshSource};
use crate::accel::parts::Bounds;
use crate::accel::wire::{decode_bvh4, decode_part, decode_small_tree};
use crate::api::decode_mesh;
use crate::geometry::Mesh;
use crate::scene::Scene;
use crate::texture::{decode_answer, Delivered, TextureAnswer, TexturePart, TextureSource};
use std::any::Any;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// How long a render thread waits for an answer before it gives up on the master.
const FETCH_TIMEOUT: Duration = Duration::from_secs(300);

/// An answer to what a render thread asked for ahead: on its way, or here.
#[derive(Debug)]
enum Early {
    Coming(Receiver<Vec<u8>>),
    Here(Vec<u8>),
}

/// What a render thread asks the master for.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) enum Want {
    /// The mesh of an object, by its id.
    Mesh(u32),
    /// A part of an object's BVH: the object's id, the part.
    Part(u32, u32),
    /// Part of what a texture name stands for.
    Texture(TexturePart, String),
}

/// The link between a worker's render threads and its communication thread.
#[derive(Default)]
pub struct FetchLink {
    /// Requests not yet sent: what, and where its bytes go.
    queued: Mutex<Vec<(Want, Sender<Vec<u8>>)>>,
    /// The first fetch of this frame that failed.
    failure: Mutex<Option<String>>,
    fetched_objects: AtomicU64,
    fetched_bytes: AtomicU64,
    fetched_parts: AtomicU64,
    fetched_part_bytes: AtomicU64,
    fetched_textures: AtomicU64,
    fetched_texture_levels: AtomicU64,
    fetched_texture_tiles: AtomicU64,
    fetched_texture_bytes: AtomicU64,
    /// Render threads' time waiting for the master's answers, and making fetched meshes ready
    /// (decoding them, building their BVHs), this frame (nanoseconds).
    waiting_ns: AtomicU64,
    building_ns: AtomicU64,
    /// Objects and parts of objects' BVHs evicted before this frame.
    evicted: AtomicU64,
    evicted_parts: AtomicU64,
    /// Objects of a new scene given the meshes the last scene fetched, before this frame.
    kept: AtomicU64,
    /// Textures, shadow maps and grids this frame took from what the caches before made of them
    /// (not fetched again; a texture's levels neither).
    kept_textures: AtomicU64,
    /// What caches made of the textures this link delivered, for the scenes after (a link
    /// serves a worker's scenes one after another).
    kept_made: Mutex<KeptMade>,
    /// Frames since the start: what objects stamp themselves with when a ray reaches them.
    clock: Arc<AtomicU32>,
    /// Wakes the communication thread when a request is queued (it may be waiting long).
    waker: Mutex<Option<Waker>>,
    /// Requests render threads made without waiting for them
    /// ([`crate::accel::ask_ahead::without_waiting`]) whose answers no thread has taken yet; a
    /// frame's go when the next starts (the master answers a frame's requests in that frame).
    asked_ahead: Mutex<HashMap<Want, Early>>,
    /// Units that render threads set aside this frame because they asked ahead.
    set_aside: AtomicU64,
    /// Render threads waiting for an answer now.
    threads_waiting: AtomicU32,
    /// Whether render threads wait for what a unit reaches instead of asking ahead (to compare).
    never_ahead: AtomicBool,
}

/// What a request queued on a [`FetchLink`] calls to wake the thread that sends it.
pub(super) type Waker = Box<dyn Fn() + Send + Sync>;

/// What a worker fetched in a frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct Fetched {
    /// The first fetch that failed.
    pub failure: Option<String>,
    pub objects: u64,
    pub object_bytes: u64,
    /// Parts of objects' BVHs, and their bytes.
    pub parts: u64,
    pub part_bytes: u64,
    /// Textures, shadow maps and grids (a texture's first answer), and the mip levels and tiles
    /// of levels fetched after it, with the bytes of all.
    pub textures: u64,
    pub texture_levels: u64,
    pub texture_tiles: u64,
    pub texture_bytes: u64,
    /// Objects and parts of objects' BVHs evicted before the frame.
    pub evicted: u64,
    pub evicted_parts: u64,
    /// Objects of a new scene given the meshes the last scene fetched, before the frame.
    pub kept: u64,
    /// Textures taken from the maps the scene before made.
    pub kept_textures: u64,
    /// Render threads' time waiting for answers, and making fetched meshes ready.
    pub waiting: Duration,
    pub building: Duration,
    /// Units set aside to be rendered again, having asked ahead for what they reached.
    pub set_aside: u64,
}

impl std::fmt::Debug for FetchLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FetchLink").field("clock", &self.clock).finish_non_exhaustive()
    }
}

impl FetchLink {
    pub fn new() -> Arc<FetchLink> {
        Arc::new(FetchLink::default())
    }

    /// The requests queued since the last call (communication thread).
    pub(super) fn take_requests(&self) -> Vec<(Want, Sender<Vec<u8>>)> {
        std::mem::take(&mut *self.queued.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// Whether requests are queued, not yet taken.
    pub(super) fn has_requests(&self) -> bool {
        !self.queued.lock().unwrap_or_else(PoisonError::into_inner).is_empty()
    }

    /// What this frame fetched; resets the counts for the next frame.
    pub(super) fn take_frame(&self) -> Fetched {
        let take = |n: &AtomicU64| n.swap(0, Ordering::Relaxed);
        Fetched {
            failure: self.failure.lock().unwrap_or_else(PoisonError::into_inner).take(),
            objects: take(&self.fetched_objects),
            object_bytes: take(&self.fetched_bytes),
            parts: take(&self.fetched_parts),
            part_bytes: take(&self.fetched_part_bytes),
            textures: take(&self.fetched_textures),
            texture_levels: take(&self.fetched_texture_levels),
            texture_tiles: take(&self.fetched_texture_tiles),
            texture_bytes: take(&self.fetched_texture_bytes),
            evicted: take(&self.evicted),
            evicted_parts: take(&self.evicted_parts),
            kept: take(&self.kept),
            kept_textures: take(&self.kept_textures),
            waiting: Duration::from_nanos(take(&self.waiting_ns)),
            building: Duration::from_nanos(take(&self.building_ns)),
            set_aside: take(&self.set_aside),
        }
    }

    fn add_time(counter: &AtomicU64, since: Instant) {
        counter.fetch_add(since.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }

    fn fail(&self, message: String) {
        self.failure.lock().unwrap_or_else(PoisonError::into_inner).get_or_insert(message);
    }

    /// Asks the master for `want` and waits for the answer's bytes (`None`: it never came). What
    /// was asked for ahead is not asked for again: its answer is awaited.
    fn request(&self, want: Want) -> Option<Vec<u8>> {
        let asked = Instant::now();
        self.threads_waiting.fetch_add(1, Ordering::Relaxed);
        let _waited = defer(|| {
            FetchLink::add_time(&self.waiting_ns, asked);
            self.threads_waiting.fetch_sub(1, Ordering::Relaxed);
        });
        let early = self.asked_ahead.lock().unwrap_or_else(PoisonError::into_inner).remove(&want);
        let early = match early {
            Some(Early::Here(bytes)) => Some(bytes),
            Some(Early::Coming(rx)) => rx.recv_timeout(FETCH_TIMEOUT).ok(),
            None => None,
        };
        if let Some(bytes) = early {
            return Some(bytes);
        }
        self.ask(want).recv_timeout(FETCH_TIMEOUT).ok()
    }

    /// Queues a request for `want` and wakes the communication thread; returns where the answer
    /// comes.
    fn ask(&self, want: Want) -> Receiver<Vec<u8>> {
        let (tx, rx) = channel();
        self.queued.lock().unwrap_or_else(PoisonError::into_inner).push((want, tx));
        if let Some(wake) = &*self.waker.lock().unwrap_or_else(PoisonError::into_inner) {
            wake();
        }
        rx
    }

    /// Asks for `want` without waiting, unless it is asked for already; returns whether the
    /// answer is still to come (`false`: it is here, or the request is gone, and a fetch takes
    /// it or asks again).
    fn ask_ahead_for(&self, want: Want) -> bool {
        let mut early = self.asked_ahead.lock().unwrap_or_else(PoisonError::into_inner);
        match early.get_mut(&want) {
            None => {
                let rx = self.ask(want.clone());
                early.insert(want, Early::Coming(rx));
                true
            }
            Some(Early::Here(_)) => false,
            Some(Early::Coming(rx)) => match rx.try_recv() {
                Ok(bytes) => {
                    early.insert(want, Early::Here(bytes));
                    false
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => true,
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    early.remove(&want);
                    false
                }
            },
        }
    }

    /// Whether render threads may render units asking ahead for what they reach
    /// ([`crate::accel::ask_ahead`]); they do unless turned off.
    pub(super) fn may_ask_ahead(&self) -> bool {
        !self.never_ahead.load(Ordering::Relaxed)
    }

    /// Turns asking ahead on or off.
    pub fn set_asking_ahead(&self, on: bool) {
        self.never_ahead.store(!on, Ordering::Relaxed);
    }

    /// Counts the texture answers that came from the master, as they come (whether or not a
    /// render thread takes them: one asked for ahead may go unread, its unit delivered by another
    /// worker).
    pub(super) fn count_texture_answers(&self, textures: &[(TexturePart, String, Vec<u8>)]) {
        for (part, _, bytes) in textures {
            let counter = match part {
                TexturePart::Level { .. } => &self.fetched_texture_levels,
                TexturePart::Tile { .. } => &self.fetched_texture_tiles,
                TexturePart::Whole(_) | TexturePart::Pyramid { .. } => &self.fetched_textures,
            };
            counter.fetch_add(1, Ordering::Relaxed);
            self.fetched_texture_bytes.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        }
    }

    /// The objects and parts of objects (object, part) asked for ahead whose answers no render
    /// thread took: the unit that asked went to another worker before it was rendered again.
    pub(super) fn unclaimed(&self) -> Vec<(u32, Option<u32>)> {
        let early = self.asked_ahead.lock().unwrap_or_else(PoisonError::into_inner);
        let mut keys: Vec<_> = early
            .keys()
            .filter_map(|w| match *w {
                Want::Mesh(object) => Some((object, None)),
                Want::Part(object, part) => Some((object, Some(part))),
                Want::Texture(..) => None,
            })
            .collect();
        keys.sort_unstable();
        keys
    }

    /// How many render threads wait for an answer now.
    pub(super) fn threads_waiting(&self) -> usize {
        self.threads_waiting.load(Ordering::Relaxed) as usize
    }

    /// Notes that a render thread set a unit aside, to render it again when what it asked for
    /// ahead has come.
    pub(super) fn note_set_aside(&self) {
        self.set_aside.fetch_add(1, Ordering::Relaxed);
    }

    /// Sets what wakes the communication thread when a request is queued (`None`: nothing; it
    /// polls).
    pub(super) fn set_waker(&self, waker: Option<Waker>) {
        *self.waker.lock().unwrap_or_else(PoisonError::into_inner) = waker;
    }

    /// The number of the frame under way: what the objects rays reach in it are stamped with
    /// ([`crate::accel::object::Object::last_used`]).
    pub(super) fn frame_number(&self) -> u32 {
        self.clock.load(Ordering::Relaxed)
    }

    /// A new scene starts: of what caches made of the textures delivered, what the scene that
    /// ended did not use is let go.
    pub(super) fn start_scene(&self) {
        let mut kept = self.kept_made.lock().unwrap_or_else(PoisonError::into_inner);
        let ended = kept.scene;
        kept.made.retain(|_, m| m.used == ended);
        kept.answered.clear();
        kept.scene += 1;
    }

    /// The digest of the texture from which a cache made what the link keeps of `part` of
    /// `name`, sent with a request for it: the master answers [`TextureAnswer::Unchanged`] when
    /// it would send the same texture. Only whole textures and pyramids are kept, not levels or tiles.
    pub(super) fn held_digest(&self, part: TexturePart, name: &str) -> Option<[u8; 32]> {
        if matches!(part, TexturePart::Level { .. } | TexturePart::Tile { .. }) {
            return None;
        }
        let kept = self.kept_made.lock().unwrap_or_else(PoisonError::into_inner);
        kept.made.get(&(part, name.to_string())).map(|m| m.digest)
    }

    /// Notes that `objects` of a new scene took the meshes the last scene fetched.
    pub(super) fn kept(&self, objects: u64) {
        self.kept.fetch_add(objects, Ordering::Relaxed);
    }

    /// Starts a frame: objects reached from now on are stamped with its number; `evicted`
    /// objects and parts were dropped before it.
    pub(super) fn start_frame(&self, (objects, parts): (u64, u64)) {
        self.clock.fetch_add(1, Ordering::Relaxed);
        self.asked_ahead.lock().unwrap_or_else(PoisonError::into_inner).clear();
        self.evicted.store(objects, Ordering::Relaxed);
        self.evicted_parts.store(parts, Ordering::Relaxed);
    }
}

/// The most bytes an object the master sends inflates to on a worker: a mesh and its BVH in one
/// message, which MPI counts in 32 bits even deflated.
pub const MAX_INFLATED_OBJECT: u64 = 1 << 32;

/// The BVH that comes with an object's mesh.
#[derive(Clone, Copy, Debug)]
pub(super) enum ObjectTree<'a> {
    /// None: the worker builds it.
    None,
    /// The whole tree ([`crate::accel::wire::encode_bvh4`]).
    Whole(&'a [u8]),
    /// The small tree of a BVH in parts ([`crate::accel::wire::encode_small_tree`]); the parts
    /// follow on request ([`encode_part`]).
    Parts(&'a [u8]),
}

/// An object as the master sends it: its mesh ([`crate::api::encode_mesh`]) and its BVH, the
/// mesh's length first, then a byte saying which tree follows (0: none, 1: whole, 2: parts), a
/// payload deflated or not ([`crate::deflate::pack`]; the master encodes each object once).
pub(super) fn encode_object(mesh: &[u8], tree: ObjectTree, deflated: bool) -> Vec<u8> {
    let (kind, bytes) = match tree {
        ObjectTree::None => (0u8, &[][..]),
        ObjectTree::Whole(bytes) => (1, bytes),
        ObjectTree::Parts(bytes) => (2, bytes),
    };
    crate::deflate::pack(&[&(mesh.len() as u64).to_le_bytes(), mesh, &[kind], bytes], deflated)
}

/// A part of an object's BVH as the master sends it ([`crate::accel::wire::encode_bvh4`] of the
/// part), a payload deflated or not.
pub(super) fn encode_part(bvh: &[u8], deflated: bool) -> Vec<u8> {
    crate::deflate::pack(&[bvh], deflated)
}

/// The bytes of an object [`encode_object`] wrote: at most [`MAX_INFLATED_OBJECT`].
fn unpack_object(bytes: &[u8]) -> Result<std::borrow::Cow<'_, [u8]>, String> {
    crate::deflate::unpack_at_most(bytes, MAX_INFLATED_OBJECT).map_err(|e| format!("the object {e}"))
}

/// The mesh's and the tree's bytes of an inflated object.
fn split_object(bytes: &[u8]) -> Result<(&[u8], ObjectTree<'_>), String> {
    let (length, rest) = bytes.split_first_chunk::<8>().ok_or("an object shorter than its header")?;
    let length = usize::try_from(u64::from_le_bytes(*length)).unwrap_or(usize::MAX);
    let (mesh, rest) = rest
        .split_at_checked(length)
        .ok_or_else(|| format!("an object of {} bytes with a mesh of {length}", bytes.len()))?;
    let tree = match rest.split_first() {
        Some((0, [])) => ObjectTree::None,
        Some((1, tree)) => ObjectTree::Whole(tree),
        Some((2, tree)) => ObjectTree::Parts(tree),
        _ => return Err("an object without a known kind of tree".into()),
    };
    Ok((mesh, tree))
}

/// Runs `f` when dropped: a time is counted however its scope is left.
fn defer<F: FnOnce()>(f: F) -> impl Drop {
    struct Defer<F: FnOnce()>(Option<F>);
    impl<F: FnOnce()> Drop for Defer<F> {
        fn drop(&mut self) {
            if let Some(f) = self.0.take() {
                f();
            }
        }
    }
    Defer(Some(f))
}

/// Drops the meshes of the demand-loaded objects of `scene`, and the parts of their BVHs, that
/// rays reached least recently until those held take at most `limit` bytes; returns how many
/// objects and parts were dropped. An object's parts go before the object (which takes them
/// all). What rays reached in the current frame goes last, and goes too if it alone exceeds the
/// limit (it is fetched again when next needed).
pub fn evict_least_recently_used(scene: &mut Scene, limit: usize) -> (u64, u64) {
    // (last used, a part (0) or the object (1), object, part, bytes)
    let mut held: Vec<(u32, u8, usize, u32, usize)> = Vec::new();
    for (i, o) in scene.objects().iter().enumerate().filter(|(_, o)| o.is_remote() && o.is_resident()) {
        let parts = o.resident_parts_in_use();
        let in_parts: usize = parts.iter().map(|p| p.2).sum();
        held.extend(parts.into_iter().map(|(p, used, bytes)| (used, 0, i, p, bytes)));
        held.push((o.last_used().unwrap_or(0), 1, i, 0, o.memory_bytes().saturating_sub(in_parts)));
    }
    let mut total: usize = held.iter().map(|h| h.4).sum();
    if total <= limit {
        return (0, 0);
    }
    held.sort_unstable();
    let (mut objects, mut parts) = (0, 0);
    let all = scene.objects_mut();
    for (_, kind, i, p, _) in held {
        if total <= limit {
            break;
        }
        let freed = match kind {
            0 => all[i].evict_part(p),
            _ => all[i].evict(),
        };
        if freed > 0 {
            total -= freed.min(total);
            *(if kind == 0 { &mut parts } else { &mut objects }) += 1;
        }
    }
    (objects, parts)
}

impl MeshSource for FetchLink {
    fn clock(&self) -> Arc<AtomicU32> {
        self.clock.clone()
    }

    fn built(&self, took: Duration) {
        self.building_ns.fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
    }

    fn fetch(&self, key: u32) -> FetchedMesh {
        let Some(bytes) = self.request(Want::Mesh(key)) else {
            self.fail(format!("the mesh of object {key} never came from the master"));
            return FetchedMesh::default();
        };
        self.fetched_objects.fetch_add(1, Ordering::Relaxed);
        self.fetched_bytes.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let decoding = Instant::now();
        let _decoded = defer(|| FetchLink::add_time(&self.building_ns, decoding));
        if bytes.is_empty() {
            self.fail(format!("the master has no mesh for object {key}"));
            return FetchedMesh::default();
        }
        let decoded = unpack_object(&bytes).and_then(|plain| {
            let (mesh, tree) = split_object(&plain)?;
            let mesh = decode_mesh(mesh).map_err(|e| e.to_string())?;
            let (bvh, parts) = match tree {
                // No BVH (the master had none built) is no failure: this side builds it.
                ObjectTree::None => (None, None),
                ObjectTree::Whole(bvh) => (Some(decode_bvh4(bvh, &mesh)?), None),
                ObjectTree::Parts(small) => (None, Some(decode_small_tree(small, &mesh)?)),
            };
            Ok(FetchedMesh { mesh: Arc::new(mesh), bvh, parts })
        });
        decoded.unwrap_or_else(|e| {
            self.fail(format!("the mesh of object {key}: {e}"));
            FetchedMesh::default()
        })
    }

    fn fetch_part(&self, key: u32, part: u32, mesh: &Mesh, triangles: u32, bounds: Bounds) -> Option<Bvh4> {
        self.part(key, part, mesh, triangles, bounds)
    }

    fn ask_ahead(&self, key: u32) -> bool {
        self.ask_ahead_for(Want::Mesh(key))
    }

    fn ask_ahead_part(&self, key: u32, part: u32) -> bool {
        self.ask_ahead_for(Want::Part(key, part))
    }
}

impl FetchLink {
    /// [`MeshSource::fetch_part`]: part `part` of object `key`'s BVH, checked against `mesh`.
    fn part(&self, key: u32, part: u32, mesh: &Mesh, triangles: u32, bounds: Bounds) -> Option<Bvh4> {
        let Some(bytes) = self.request(Want::Part(key, part)) else {
            self.fail(format!("part {part} of object {key} never came from the master"));
            return None;
        };
        self.fetched_parts.fetch_add(1, Ordering::Relaxed);
        self.fetched_part_bytes.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let decoding = Instant::now();
        let _decoded = defer(|| FetchLink::add_time(&self.building_ns, decoding));
        if bytes.is_empty() {
            self.fail(format!("the master has no part {part} of object {key}"));
            return None;
        }
        let decoded = crate::deflate::unpack_at_most(&bytes, MAX_INFLATED_OBJECT)
            .map_err(|e| format!("the part {e}"))
            .and_then(|plain| decode_part(&plain, mesh, triangles, bounds));
        decoded.inspect_err(|e| self.fail(format!("part {part} of object {key}: {e}"))).ok()
    }
}

impl TextureSource for FetchLink {
    fn fetch(&self, part: TexturePart, name: &str) -> TextureAnswer {
        let failed = |reason: String| {
            self.fail(format!("texture \"{name}\": {reason}"));
            TextureAnswer::Whole(Delivered::Missing { path: None, reason })
        };
        let Some(bytes) = self.request(Want::Texture(part, name.to_string())) else {
            return failed("it never came from the master".into());
        };
        let answer = decode_answer(&bytes).unwrap_or_else(failed);
        // The texture an answer stands for: a pyramid says; a whole answer is the texture.
        let digest = match (&answer, part) {
            (_, TexturePart::Level { .. } | TexturePart::Tile { .. })
            | (TextureAnswer::Whole(Delivered::Missing { .. }), _) => None,
            (TextureAnswer::Pyramid(header), _) => Some(header.digest),
            (TextureAnswer::Whole(_), _) => Some(blake3::hash(&bytes).into()),
            _ => None,
        };
        if let Some(digest) = digest {
            let mut kept = self.kept_made.lock().unwrap_or_else(PoisonError::into_inner);
            kept.answered.insert((part, name.to_string()), digest);
        }
        answer
    }

    fn failed(&self, message: String) {
        self.fail(message);
    }

    fn ask_ahead(&self, part: TexturePart, name: &str) -> bool {
        self.ask_ahead_for(Want::Texture(part, name.to_string()))
    }

    fn kept(&self, part: TexturePart, name: &str) -> Option<Arc<dyn Any + Send + Sync>> {
        let mut kept = self.kept_made.lock().unwrap_or_else(PoisonError::into_inner);
        let scene = kept.scene;
        let made = kept.made.get_mut(&(part, name.to_string()))?;
        made.used = scene;
        self.kept_textures.fetch_add(1, Ordering::Relaxed);
        Some(made.value.clone())
    }

    fn keep(&self, part: TexturePart, name: &str, value: Arc<dyn Any + Send + Sync>) {
        let mut kept = self.kept_made.lock().unwrap_or_else(PoisonError::into_inner);
        let key = (part, name.to_string());
        let Some(digest) = kept.answered.remove(&key) else { return };
        let used = kept.scene;
        kept.made.insert(key, Made { digest, value, used });
    }
}

/// What the caches of a link's scenes made of the textures, shadow maps and grids it delivered
/// (a texture's map with the levels it fetched since), by what was asked for, with the digest of
/// the texture it was made from (see [`FetchLink::held_digest`]).
#[derive(Default)]
struct KeptMade {
    made: HashMap<(TexturePart, String), Made>,
    /// The digests of the link's last answers, until a cache keeps what it made of them.
    answered: HashMap<(TexturePart, String), [u8; 32]>,
    /// Scenes started so far.
    scene: u64,
}

struct Made {
    digest: [u8; 32],
    value: Arc<dyn Any + Send + Sync>,
    /// The scene that last made or took it.
    used: u64,
}

/// A texture request as it goes to the master: the part, the name, and the digest of what the
/// worker holds of it ([`FetchLink::held_digest`]).
pub(super) type TextureRequest = (TexturePart, String, Option<[u8; 32]>);

/// What a worker asks the master for in one `Fetch`: objects' meshes, parts of objects' BVHs
/// (object, part), and textures.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Requests {
    pub objects: Vec<u32>,
    pub parts: Vec<(u32, u32)>,
    pub textures: Vec<TextureRequest>,
}

impl Requests {
    pub(super) fn is_empty(&self) -> bool {
        self.objects.is_empty() && self.parts.is_empty() && self.textures.is_empty()
    }

    /// The `Fetch` message of these requests in frame `frame`.
    pub(super) fn message(self, frame: u64) -> super::message::Message {
        let Requests { objects, parts, textures } = self;
        super::message::Message::Fetch { frame, objects, parts, textures }
    }
}

/// The communication thread's side: requests sent and not yet answered.
#[derive(Default)]
pub(super) struct Pending(HashMap<Want, Vec<Sender<Vec<u8>>>>);

impl Pending {
    /// Takes `link`'s queued requests; returns what to ask the master for (what is not already
    /// asked for).
    pub(super) fn take(&mut self, link: &FetchLink) -> Requests {
        let mut requests = Requests::default();
        for (want, tx) in link.take_requests() {
            let waiting = self.0.entry(want.clone()).or_default();
            if waiting.is_empty() {
                match want {
                    Want::Mesh(object) => requests.objects.push(object),
                    Want::Part(object, part) => requests.parts.push((object, part)),
                    Want::Texture(part, name) => {
                        let held = link.held_digest(part, &name);
                        requests.textures.push((part, name, held))
                    }
                }
            }
            waiting.push(tx);
        }
        requests
    }

    /// Whether requests sent are still unanswered.
    pub(super) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Hands the master's answer to the threads waiting for it.
    pub(super) fn answer(
        &mut self,
        meshes: Vec<(u32, Vec<u8>)>,
        parts: Vec<(u32, u32, Vec<u8>)>,
        textures: Vec<(TexturePart, String, Vec<u8>)>,
    ) {
        let answers = meshes
            .into_iter()
            .map(|(object, bytes)| (Want::Mesh(object), bytes))
            .chain(parts.into_iter().map(|(object, part, bytes)| (Want::Part(object, part), bytes)))
            .chain(textures.into_iter().map(|(part, name, bytes)| (Want::Texture(part, name), bytes)));
        for (want, bytes) in answers {
            for tx in self.0.remove(&want).unwrap_or_default() {
                // A thread that gave up waiting has dropped its receiver.
                let _ = tx.send(bytes.clone());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::object::{MeshSummary, Object, ObjectBvh};
    use crate::geometry::Mesh;

    /// Hands out the same small mesh for every object.
    #[derive(Debug, Default)]
    struct Local {
        clock: Arc<AtomicU32>,
        fetches: AtomicU64,
    }

    impl MeshSource for Local {
        fn fetch(&self, _key: u32) -> FetchedMesh {
            self.fetches.fetch_add(1, Ordering::Relaxed);
            let corners = vec![[0.0, 0.0, 0.0].into(), [1.0, 0.0, 0.0].into(), [0.0, 1.0, 0.0].into()];
            let mesh = Mesh::from_triangles(corners, vec![[0, 1, 2]]).expect("a triangle");
            FetchedMesh { mesh: Arc::new(mesh), bvh: None, parts: None }
        }
        fn clock(&self) -> Arc<AtomicU32> {
            self.clock.clone()
        }
    }

    /// A ribbon of `n` triangles.
    fn ribbon(n: u32) -> Mesh {
        let positions = (0..n + 2).map(|k| [k as f32, (k % 2) as f32, 0.0].into()).collect();
        Mesh::from_triangles(positions, (0..n).map(|k| [k, k + 1, k + 2]).collect()).expect("a ribbon")
    }

    /// What a render thread's fetch of an object gets when the master answers with `answer`.
    fn fetched_with(answer: Vec<u8>) -> (FetchedMesh, Fetched) {
        let link = FetchLink::new();
        let fetching = {
            let link = link.clone();
            std::thread::spawn(move || MeshSource::fetch(&*link, 7))
        };
        let mut pending = Pending::default();
        while !link.has_requests() {
            std::thread::yield_now();
        }
        assert_eq!(pending.take(&link), Requests { objects: vec![7], ..Requests::default() });
        pending.answer(vec![(7, answer)], vec![], vec![]);
        let fetched = fetching.join().expect("the render thread");
        (fetched, link.take_frame())
    }

    #[test]
    fn a_mesh_arrives_with_the_bvh_built_for_it_and_a_damaged_bvh_is_a_failure() {
        let mesh = ribbon(300);
        let built = ObjectBvh::build(&mesh, crate::accel::bvh4::BuildQuality::High).bvh;
        let mut bvh = Vec::new();
        crate::accel::wire::encode_bvh4(&built, &mut bvh);
        let encoded = crate::api::encode_mesh(&mesh);
        // Plain, and deflated (between machines): the same object arrives.
        for deflated in [false, true] {
            let (fetched, frame) = fetched_with(encode_object(&encoded, ObjectTree::Whole(&bvh), deflated));
            assert_eq!(frame.failure, None);
            assert_eq!(fetched.mesh.triangle_count(), 300);
            let arrived = fetched.bvh.expect("the master's BVH");
            assert_eq!((arrived.nodes, arrived.prim_order), (built.nodes.clone(), built.prim_order.clone()));
            assert_eq!(frame.object_bytes, encode_object(&encoded, ObjectTree::Whole(&bvh), deflated).len() as u64);
            // Without a BVH the mesh alone arrives (the object builds its own).
            let (fetched, frame) = fetched_with(encode_object(&encoded, ObjectTree::None, deflated));
            assert!(fetched.bvh.is_none() && frame.failure.is_none());
            assert_eq!(fetched.mesh.triangle_count(), 300);
            // A BVH for another mesh, or a cut object, fails the frame and leaves the object empty.
            let mut other = Vec::new();
            crate::accel::wire::encode_bvh4(
                &ObjectBvh::build(&ribbon(299), crate::accel::bvh4::BuildQuality::High).bvh,
                &mut other,
            );
            for damaged in [
                encode_object(&encoded, ObjectTree::Whole(&other), deflated),
                encode_object(&encoded, ObjectTree::Whole(&bvh), deflated)[..100].to_vec(),
            ] {
                let (fetched, frame) = fetched_with(damaged);
                assert_eq!(fetched.mesh.triangle_count(), 0);
                assert!(frame.failure.is_some_and(|f| f.contains("object 7")));
            }
        }
        let plain = encode_object(&encoded, ObjectTree::Whole(&bvh), false).len();
        let deflated = encode_object(&encoded, ObjectTree::Whole(&bvh), true).len();
        assert!(deflated < plain, "{deflated} deflated against {plain} plain");
    }

    #[test]
    fn the_least_recently_reached_objects_go_first() {
        let source = Arc::new(Local::default());
        let mut scene = Scene::new();
        let summary = MeshSummary { bounds: None, triangles: 1, attributes: Vec::new(), digest: [0; 32] };
        for key in 0..3 {
            scene.add_remote_object(summary.clone(), key, source.clone());
        }
        // Object 1 reached in frame 1, object 0 in frame 2, object 2 in frame 3.
        for (frame, object) in [(1, 1), (2, 0), (3, 2)] {
            source.clock.store(frame, Ordering::Relaxed);
            let _ = scene.objects()[object].data();
        }
        assert_eq!(source.fetches.load(Ordering::Relaxed), 3);
        let each = scene.objects()[0].memory_bytes();
        assert_eq!(evict_least_recently_used(&mut scene, 3 * each), (0, 0));
        assert_eq!(evict_least_recently_used(&mut scene, 2 * each), (1, 0));
        let resident: Vec<bool> = scene.objects().iter().map(Object::is_resident).collect();
        assert_eq!(resident, [true, false, true]);
        assert_eq!(evict_least_recently_used(&mut scene, each), (1, 0));
        let resident: Vec<bool> = scene.objects().iter().map(Object::is_resident).collect();
        assert_eq!(resident, [false, false, true]);
        // An evicted object comes back when next reached.
        let _ = scene.objects()[1].data();
        assert_eq!(source.fetches.load(Ordering::Relaxed), 4);
    }
}

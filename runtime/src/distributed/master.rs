//! The master: the rank that owns the scene and the output. It greets its workers, hands each
//! frame's tiles out on demand ([`Schedule`]), and assembles the image from the tiles they send.

use super::fetch::{encode_object, encode_part, ObjectTree};
use super::message::{
    build_fingerprint, greeting_version, FrameCounts, Job, LatticeUnit, Message, RenderedUnits, PROTOCOL_VERSION,
};
use super::schedule::{unit_tile, Delivery, Helping, Holdings, Schedule, TileUnit};
use super::transport::Transport;
use super::DistributedError;
use crate::accel::parts::{cut, PARTED_ABOVE, PART_TRIANGLES};
use crate::accel::wire::{encode_bvh4, encode_small_tree};
use crate::api::{encode_mesh, Context, Replicator, TextureDelivery};
use crate::render::progressive::{lattice_lanes, BatchReport, LatticeSamples, LatticeTracer, PixelLattice};
use crate::render::remote_displacement::DISPLACED_MESH_KEY;
use crate::render::{FrameReport, Framebuffer, LightPathCache, LightPaths, RenderedTile, TileRenderer, World};
use crate::texture::{
    encode_answer, DecodedTexture, Delivered, TextureAnswer, TextureKind, TexturePart, TextureServer, TILED_FROM_BYTES,
};
use std::collections::{HashMap, HashSet};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Units each worker has in flight per thread in its first frame, before the master knows how
/// long its units take: while it renders one, the next ones are on their way.
const TILES_IN_FLIGHT_PER_THREAD: usize = 16;
/// The fewest and the most units a worker has in flight per thread.
const FEWEST_TILES_IN_FLIGHT_PER_THREAD: usize = 2;
const MOST_TILES_IN_FLIGHT_PER_THREAD: usize = 256;
/// A worker's **lead**: the rendering time each of its threads has waiting behind the unit it
/// renders, which must outlast a round trip through the master. After its first frame a
/// worker's window is its lead over its threads' time per unit in the frame before, so that it
/// holds few expensive units and many cheap ones: a window counted in units must be large for
/// cheap units, and the same count of a frame's most expensive tiles keeps one worker busy while
/// the others idle. The lead doubles when the worker runs dry and eases back in each frame in
/// which it does not.
const FIRST_LEAD: Duration = Duration::from_millis(4);
const SHORTEST_LEAD: Duration = Duration::from_millis(2);
const LONGEST_LEAD: Duration = Duration::from_millis(32);

/// The most bytes of encoded objects the master keeps for fetches to come; past it, it starts
/// again from none (each object is encoded again when next fetched).
const ENCODED_OBJECTS_KEPT: usize = 1 << 30;

/// The largest texture file the master decodes before a worker asks for it.
const LARGEST_TEXTURE_DECODED_AHEAD: u64 = 256 << 20;

/// Once fewer than this share of a frame's tiles are left to hand out, the rest go out in
/// quarters ([`TileQuarters::AtTheEnd`]).
const QUARTERED_SHARE: usize = 8;

/// How long the frame's loop naps between polls while textures are decoded.
const DECODING_POLL: Duration = Duration::from_micros(50);

/// The side of the square regions of the image whose lattices a worker keeps from one piece of
/// a viewer's work to the next (see [`Master::trace_lattices`]).
const REGION_SIDE: u32 = 64;

/// A frame's work as the master hands it out: `units` units of `job`, for lattices each
/// described by its entry of `lattices`; `owners[u]`, where known, the worker that rendered unit
/// `u`'s part of the image last.
struct Work<'a> {
    job: Job,
    units: usize,
    lattices: &'a [LatticeUnit],
    owners: &'a [Option<usize>],
    /// `costs[u]`, where known for every unit: what unit `u`'s part of the image took last time.
    costs: &'a [u32],
    /// The frame's light paths, encoded (empty: none to send).
    light_paths: &'a [u8],
    /// Tiles taken while fewer than this many are left go out in quarters where `splittable`
    /// ([`Schedule::splitting`]; none for lattices).
    split_below: usize,
    splittable: &'a [bool],
}

/// Which of a frame's tiles the master hands out in quarters ([`Schedule::splitting`]), where a
/// tile's quarters render as the whole tile does ([`crate::render::TileRenderer::quarters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileQuarters {
    /// None.
    Never,
    /// The last eighth of a frame's tiles, when the workers have more than one render thread
    /// together (the default).
    AtTheEnd,
    /// Every tile (for tests).
    Always,
}

/// How a frame's units went on the workers.
struct FrameRun {
    /// Who rendered each unit (who delivered it first).
    given: Vec<Option<usize>>,
    /// Each worker's counts.
    counts: Vec<FrameCounts>,
    /// What each unit took its thread, in microseconds.
    costs: Vec<u32>,
    /// How the copies for helpers went.
    helping: Helping,
}

/// Texture requests of a worker (its rank) in the frame, as a `Fetch` carries them.
type TextureRequests = Vec<(TexturePart, String, Option<[u8; 32]>)>;

/// What the master's frame loop waits for: a worker's message, or a texture decoded away from it.
enum Event {
    Message(usize, Vec<u8>),
    Decoded(Box<DecodedTexture>),
}

/// Takes a unit's encoded pixels as they arrive, with the unit's index: an error is the sender's
/// protocol error.
type Accept<'a> = dyn FnMut(usize, &[u8]) -> Result<(), String> + 'a;

/// A worker as it introduced itself, and how its units went.
struct WorkerInfo {
    threads: u32,
    /// A thread's time in a unit over the worker's last frame (none before its first).
    unit_time: Option<Duration>,
    /// The rendering time its threads keep waiting ([`FIRST_LEAD`]).
    lead: Duration,
    /// Why it cannot render, if it cannot.
    failure: Option<String>,
}

impl WorkerInfo {
    fn new(threads: u32, failure: Option<String>) -> WorkerInfo {
        WorkerInfo { threads, unit_time: None, lead: FIRST_LEAD, failure }
    }

    /// How many units it should have in flight to outlast a round trip: the unit each thread
    /// renders and its lead's worth behind it.
    fn window(&self) -> usize {
        let per_thread = match self.unit_time {
            None => TILES_IN_FLIGHT_PER_THREAD,
            Some(unit) => {
                let behind = self.lead.as_nanos().div_ceil(unit.as_nanos().max(1));
                usize::try_from(behind).unwrap_or(usize::MAX).saturating_add(1)
            }
        };
        per_thread.clamp(FEWEST_TILES_IN_FLIGHT_PER_THREAD, MOST_TILES_IN_FLIGHT_PER_THREAD)
            * (self.threads as usize).max(1)
    }

    /// Ran dry while waiting for units: a round trip took longer than its lead.
    fn ran_dry(&mut self) {
        self.lead = (2 * self.lead).min(LONGEST_LEAD);
    }

    /// Its frame is over: `units` units took its threads `rendering` together, and it ran dry in
    /// it or not.
    fn frame_done(&mut self, units: usize, rendering: Duration, ran_dry: bool) {
        if units > 0 && !rendering.is_zero() {
            self.unit_time = Some(rendering / u32::try_from(units).unwrap_or(u32::MAX));
        }
        if !ran_dry {
            self.lead = (self.lead * 3 / 4).max(SHORTEST_LEAD);
        }
    }
}

/// The bytes a frame moved between the master and its workers, by kind (whole messages).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// The frame's update, as sent to every worker.
    pub updates: u64,
    /// Tile assignments and the rest of the frame messages.
    pub control: u64,
    /// Tile messages: pixels (and filter splats).
    pub pixels: u64,
    /// The workers' end-of-frame counters.
    pub counters: u64,
    /// Demand loading: the workers' requests and the meshes and textures sent in answer.
    pub fetches: u64,
    /// The frame's light paths (virtual lights, photon maps), traced here, as sent to every worker.
    pub light_paths: u64,
}

impl Traffic {
    pub fn total(&self) -> u64 {
        self.updates + self.control + self.pixels + self.counters + self.fetches + self.light_paths
    }
}

/// The master's side of a distributed run: rank 0 of `transport`, every other rank a worker.
/// Dropping it tells the workers to stop.
pub struct Master<T: Transport> {
    transport: T,
    workers: Vec<WorkerInfo>,
    frame: u64,
    /// Who rendered each tile of the last frame, so that each worker gets its own tiles again.
    last_owner: Vec<Option<usize>>,
    /// What each tile of the last frame took its thread, in microseconds, so that the most
    /// expensive go first ([`Schedule`]).
    last_cost: Vec<u32>,
    /// Who last traced lattices in each [`REGION_SIDE`] square of the image, row by row.
    region_owner: Vec<Option<usize>>,
    /// Whether the workers still wait for work (not yet told to quit).
    open: bool,
    /// Whether workers with nothing left to do at a frame's end get copies of the tiles others
    /// hold ([`Holdings`]).
    tile_copies: bool,
    tile_quarters: TileQuarters,
    traffic: Traffic,
    /// What the workers' contexts were last sent ([`Master::render_context`]).
    replicator: Replicator,
    demand: Demand,
    /// The workers' times in the last frame (their shares' times; the frame's own is set once
    /// the image is assembled).
    worker_time: WorkerTime,
    worker_times: Vec<WorkerShare>,
    /// Objects as last encoded for a fetch, each with the mesh it was encoded from, and their
    /// bytes together: an object fetched again (by another worker, in a later frame) is not
    /// encoded again while its mesh stands.
    encoded_objects: HashMap<u32, Encoded>,
    encoded_bytes: usize,
    /// Whether objects, their parts and textures travel deflated ([`Master::set_deflate`]).
    deflate: bool,
    /// Textures whose whole takes at least this many bytes travel in tiles of their large levels.
    texture_tiles_from: usize,
    /// Objects of more triangles than this travel in parts of at most `part_triangles`.
    parted_above: usize,
    part_triangles: u32,
    /// The textures the workers fetched, each decoded and mip-mapped once: on the thread pool,
    /// while the frame's loop answers other requests and takes tiles ([`Master::start_decoding`]).
    texture_server: TextureServer,
    /// Textures being decoded, and where they come back.
    decoding: HashSet<(String, bool)>,
    /// Textures the scene's shader parameters name, to decode before a worker asks for them, one
    /// at a time ([`Master::speculate`]); the names already considered; the one being decoded.
    to_decode: std::collections::VecDeque<String>,
    considered: HashSet<String>,
    speculating: Option<(String, bool)>,
    decoded_tx: Sender<DecodedTexture>,
    decoded_rx: Receiver<DecodedTexture>,
    /// The light paths of the viewer's pass being traced ([`Master::trace_lattices`]), and the
    /// paths the workers were last sent (they keep them for the pass's next pieces).
    light_paths: LightPathCache,
    sent_light_paths: LightPaths,
}

/// Where a worker's time went in the last frame, on average over the workers. A frame's time on
/// the master is each worker's `world + share + outside`; `share` is `rendering + waiting`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorkerTime {
    /// The frame on the master, from its start to the image assembled.
    pub frame: Duration,
    /// Bringing the worker's world to the frame's state: applying the update, building BVHs.
    pub world: Duration,
    /// From the world being ready to the worker reporting its part of the frame done.
    pub share: Duration,
    /// Of `share`, a render thread's time rendering units (the mean over its threads).
    pub rendering: Duration,
    /// Of `rendering`, the time it waited for meshes and textures fetched from the master, and
    /// the time it spent decoding fetched meshes and building their BVHs.
    pub fetching: Duration,
    pub loading: Duration,
    /// Of `rendering`, the time it was ready to run but off its core (its wall time in units less
    /// its CPU time and its waits for fetches): the cores were held by other threads or
    /// processes. Zero where the system does not tell a thread's CPU time.
    pub off_core: Duration,
    /// Of `share`, a render thread's time not rendering: waiting for units from the master, and
    /// the talking thread's turns on its core.
    pub waiting: Duration,
    /// Outside the worker's part of the frame: the master preparing it (tracing light paths,
    /// encoding the update), the frame's first message on its way, the other workers still
    /// rendering after this one reported, and the master assembling the image after the last
    /// tile.
    pub outside: Duration,
    /// Of `outside`, the time from the worker's report to the last worker's, as the master saw
    /// them arrive: the frame's imbalance.
    pub after_done: Duration,
    /// The copies of units handed to workers with nothing left to do at the frame's end.
    pub helping: Helping,
    /// Units the workers set aside to render again once what they asked ahead for came (summed
    /// over the workers).
    pub set_aside: u64,
}

/// One worker's times in a frame, its render threads' as their mean.
#[derive(Clone, Copy, Debug, Default)]
struct WorkerShare {
    world: Duration,
    share: Duration,
    /// From the frame's start on the master to the worker's report arriving there.
    done: Duration,
    rendering: Duration,
    fetching: Duration,
    loading: Duration,
    off_core: Duration,
    set_aside: u64,
}

impl WorkerShare {
    fn of(counts: &FrameCounts, threads: u32) -> WorkerShare {
        let per_thread = |ns: u64| Duration::from_nanos(ns) / threads.max(1);
        let rendering = per_thread(counts.rendering_ns);
        // Fetches made while the world was built are waited for outside any unit.
        let fetching = per_thread(counts.fetch_wait_ns).min(rendering);
        let off_core = match counts.rendering_cpu_ns {
            0 => Duration::ZERO,
            cpu => rendering.saturating_sub(per_thread(cpu) + fetching),
        };
        WorkerShare {
            world: Duration::from_nanos(counts.world_ns),
            share: Duration::from_nanos(counts.share_ns),
            done: Duration::ZERO,
            rendering,
            fetching,
            loading: per_thread(counts.fetch_build_ns).min(rendering),
            off_core,
            set_aside: counts.set_aside,
        }
    }
}

impl WorkerTime {
    /// The mean of the workers' times in a frame that took `frame` on the master.
    fn of(frame: Duration, workers: &[WorkerShare]) -> WorkerTime {
        let n = workers.len().max(1) as u32;
        let mean = |f: fn(&WorkerShare) -> Duration| workers.iter().map(f).sum::<Duration>() / n;
        let (world, share, rendering) = (mean(|w| w.world), mean(|w| w.share), mean(|w| w.rendering));
        WorkerTime {
            frame,
            world,
            share,
            rendering,
            fetching: mean(|w| w.fetching),
            loading: mean(|w| w.loading),
            off_core: mean(|w| w.off_core),
            waiting: share.saturating_sub(rendering),
            outside: frame.saturating_sub(world + share),
            after_done: workers
                .iter()
                .map(|w| w.done)
                .max()
                .map_or(Duration::ZERO, |last| workers.iter().map(|w| last - w.done).sum::<Duration>() / n),
            helping: Helping::default(),
            set_aside: workers.iter().map(|w| w.set_aside).sum(),
        }
    }
}

/// An object as the master encoded it for fetches: the mesh it was encoded from, the object's
/// bytes ([`encode_object`]) and, in parts, each part's ([`encode_part`]).
struct Encoded {
    mesh: Arc<crate::geometry::Mesh>,
    object: Arc<Vec<u8>>,
    parts: Vec<Vec<u8>>,
}

impl Encoded {
    fn bytes(&self) -> usize {
        self.object.len() + self.parts.iter().map(Vec::len).sum::<usize>()
    }
}

/// Demand loading over the workers in the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Demand {
    /// Objects the workers fetched, and the bytes of their meshes (with their BVHs, or their
    /// small trees).
    pub fetched_objects: u64,
    pub fetched_bytes: u64,
    /// Parts of large objects' BVHs the workers fetched, and their bytes; parts held after the
    /// frame by all workers together.
    pub fetched_parts: u64,
    pub fetched_part_bytes: u64,
    pub resident_parts: u64,
    /// Parts the workers evicted from their caches before the frame.
    pub evicted_parts: u64,
    /// Textures, shadow maps and grids the workers fetched, the mip levels and tiles of levels
    /// they fetched after a texture's first answer, and the bytes of all.
    pub fetched_textures: u64,
    pub fetched_texture_levels: u64,
    pub fetched_texture_tiles: u64,
    pub fetched_texture_bytes: u64,
    /// Objects the workers evicted from their caches before the frame.
    pub evicted_objects: u64,
    /// Objects held after the frame: by all workers together, and by the one that holds most.
    pub resident_objects: u64,
    pub most_resident_objects: u64,
    /// Objects the workers' rays reached in the frame, each counted by every worker that reached
    /// it: those held before the frame are the cache's hits, those fetched ([`Demand::fetched_objects`])
    /// its misses.
    pub reached_objects: u64,
    /// Objects of a new scene that took the meshes the workers had fetched for the scene before
    /// (a RIB file's next frame declaring its set again), each counted by every worker: not
    /// fetched again.
    pub kept_objects: u64,
    /// Textures of a new scene that took the maps the workers made for the scene before (the
    /// same name and texture), each counted by every worker: the levels they held not fetched
    /// again.
    pub kept_textures: u64,
}

impl Demand {
    /// The share of the objects the workers' rays reached that they already held (`None` when
    /// they reached none).
    pub fn hit_rate(&self) -> Option<f64> {
        let hits = self.reached_objects.saturating_sub(self.fetched_objects);
        (self.reached_objects > 0).then(|| hits as f64 / self.reached_objects as f64)
    }
}

impl<T: Transport> Master<T> {
    /// Waits for every worker's greeting and checks that each runs this very program and
    /// protocol. A worker whose scene failed to load is no error here: see
    /// [`Master::check_workers`].
    pub fn connect(transport: T) -> Result<Master<T>, DistributedError> {
        let n = transport.size();
        let deflate = !transport.shares_memory();
        let (decoded_tx, decoded_rx) = channel();
        let mut master = Master {
            transport,
            workers: Vec::new(),
            frame: 0,
            last_owner: Vec::new(),
            last_cost: Vec::new(),
            region_owner: Vec::new(),
            open: true,
            tile_copies: true,
            tile_quarters: TileQuarters::AtTheEnd,
            traffic: Traffic::default(),
            replicator: Replicator::demand_loading(),
            demand: Demand::default(),
            worker_time: WorkerTime::default(),
            worker_times: Vec::new(),
            encoded_objects: HashMap::new(),
            encoded_bytes: 0,
            deflate,
            texture_tiles_from: TILED_FROM_BYTES,
            parted_above: PARTED_ABOVE,
            part_triangles: PART_TRIANGLES,
            texture_server: TextureServer::new().with_deflate(deflate),
            decoding: HashSet::new(),
            to_decode: Default::default(),
            considered: HashSet::new(),
            speculating: None,
            decoded_tx,
            decoded_rx,
            light_paths: LightPathCache::default(),
            sent_light_paths: LightPaths::default(),
        };
        let build = build_fingerprint();
        let mut hellos: Vec<Option<WorkerInfo>> = (1..n).map(|_| None).collect();
        for _ in 1..n {
            let (rank, bytes) = master.transport.recv()?;
            let slot = rank.checked_sub(1).and_then(|w| hellos.get_mut(w)).filter(|h| h.is_none());
            let protocol_error = |message: String| DistributedError::Protocol { rank, message };
            let Some(slot) = slot else {
                return Err(protocol_error("greeted twice, or is no worker".into()));
            };
            match greeting_version(&bytes) {
                Some(PROTOCOL_VERSION) => {}
                Some(version) => {
                    return Err(DistributedError::Mismatch {
                        rank,
                        what: format!("protocol version {version}, where the master speaks {PROTOCOL_VERSION}"),
                    })
                }
                None => return Err(protocol_error("its first message is no greeting".into())),
            }
            match Message::decode(&bytes).map_err(protocol_error)? {
                Message::Hello { build: theirs, threads, failure, .. } => {
                    if theirs != build {
                        return Err(DistributedError::Mismatch {
                            rank,
                            what: "another build of the program (every rank must run the same executable)".into(),
                        });
                    }
                    *slot = Some(WorkerInfo::new(threads, failure));
                }
                _ => return Err(protocol_error("its first message is no greeting".into())),
            }
        }
        master.workers = hellos.into_iter().flatten().collect();
        Ok(master)
    }

    /// Sends the large levels of textures whose whole takes at least `bytes` to the workers in
    /// tiles (`texture/level_tiles.rs`; [`crate::texture::TILED_FROM_BYTES`] unless set).
    pub fn set_texture_tiles_from(&mut self, bytes: usize) {
        self.texture_tiles_from = bytes;
        self.texture_server = TextureServer::new().with_tiles_from(bytes).with_deflate(self.deflate);
    }

    /// Whether the master waits for its workers' messages polling without napping: for a master
    /// with a core of its own, each fetch's and tile's round trip then waits for no nap (by
    /// default it naps between polls, leaving the core to workers that share it).
    pub fn set_spinning(&mut self, spinning: bool) {
        self.transport.set_spinning(spinning);
    }

    /// Whether a worker with nothing left to do once a frame's tiles are all handed out gets
    /// copies of tiles other workers hold and have not started (by default it does; see
    /// [`Holdings`]).
    pub fn set_tile_copies(&mut self, on: bool) {
        self.tile_copies = on;
    }

    /// Which tiles go out in quarters (by default [`TileQuarters::AtTheEnd`]).
    pub fn set_tile_quarters(&mut self, quarters: TileQuarters) {
        self.tile_quarters = quarters;
    }

    /// Sends objects of more than `above` triangles in parts of at most `part_triangles`
    /// ([`crate::accel::parts`]; by default [`PARTED_ABOVE`] and [`PART_TRIANGLES`]). Takes effect
    /// for objects encoded from now on.
    pub fn set_parts(&mut self, above: usize, part_triangles: u32) {
        (self.parted_above, self.part_triangles) = (above, part_triangles.max(1));
        self.encoded_objects.clear();
        self.encoded_bytes = 0;
    }

    /// Sends objects, their BVHs' parts and textures deflated (`true`) or plain. By default they
    /// go plain when every rank shares the master's memory ([`Transport::shares_memory`]: MPI
    /// moves the bytes through it, faster than deflating and inflating them), deflated otherwise.
    /// Takes effect for objects encoded and textures served from now on.
    pub fn set_deflate(&mut self, on: bool) {
        self.deflate = on;
        self.encoded_objects.clear();
        self.encoded_bytes = 0;
        self.texture_server = TextureServer::new().with_tiles_from(self.texture_tiles_from).with_deflate(on);
    }

    /// How many workers render.
    pub fn workers(&self) -> usize {
        self.workers.len()
    }

    /// The threads of all the workers together.
    pub fn worker_threads(&self) -> usize {
        self.workers.iter().map(|w| w.threads as usize).sum()
    }

    /// What the last distributed frame moved.
    pub fn traffic(&self) -> Traffic {
        self.traffic
    }

    /// How many textures the master holds decoded for its workers: those they asked for, and
    /// those the scene names that it decoded before any asked.
    pub fn decoded_textures(&self) -> usize {
        self.texture_server.len()
    }

    /// What demand loading fetched and held in the last distributed frame.
    pub fn demand(&self) -> Demand {
        self.demand
    }

    /// Where the workers' time went in the last distributed frame.
    pub fn worker_time(&self) -> WorkerTime {
        self.worker_time
    }

    /// Sends workers whole meshes with the scene ([`Master::render_context`]) instead of letting
    /// them fetch each when a ray first needs it. For comparisons; call before the first frame.
    pub fn preload_meshes(&mut self) {
        self.replicator = Replicator::new();
    }

    /// The first worker that said it cannot render (its scene did not load), with its reason.
    pub fn check_workers(&self) -> Result<(), DistributedError> {
        match self.workers.iter().enumerate().find_map(|(w, info)| Some((w + 1, info.failure.clone()?))) {
            Some((rank, message)) => Err(DistributedError::Worker { rank, message }),
            None => Ok(()),
        }
    }

    /// Renders a frame of the application's context `rt` on workers serving a
    /// [`super::ReplicaScene`]: sends them what changed in `rt` since the last frame (all of it the
    /// first time: see [`Replicator`]), then renders `world`, which `rt` built as it stands now,
    /// as [`Master::render_frame`] does. An application renders distributed by calling this
    /// where it would call [`crate::render::render_frame`]; nothing else changes.
    ///
    /// A context other than the last frame's is another scene (a RIB file's next frame, a scene
    /// loaded again): the workers are told to start again from empty ([`Message::NewScene`]) and
    /// sent it whole.
    pub fn render_context(
        &mut self,
        rt: &Context,
        world: &World,
        progress: Option<&dyn Fn(usize, usize)>,
    ) -> Result<(Framebuffer, FrameReport), DistributedError> {
        if self.workers.is_empty() {
            return Ok(crate::render::render_frame(world, None));
        }
        let update = self.update(rt, world)?;
        self.render(world, &update, progress, Some(rt))
    }

    /// What the workers are sent of `rt` before a frame of `world`: what changed since the last
    /// frame, or, when `rt` is another context than the last frame's, all of it after telling
    /// them to start again from empty.
    fn update(&mut self, rt: &Context, world: &World) -> Result<Vec<u8>, DistributedError> {
        if !self.replicator.follows(rt) {
            self.new_scene()?;
        }
        Ok(self.replicator.update(rt, Some(world))?)
    }

    /// Tells the workers to drop their copies of the scene and everything kept of it, and forgets
    /// what they were sent and what their caches held: the next frame starts from empty, as the
    /// first did.
    fn new_scene(&mut self) -> Result<(), DistributedError> {
        self.replicator.restart();
        self.encoded_objects.clear();
        self.encoded_bytes = 0;
        self.last_owner.clear();
        self.last_cost.clear();
        self.region_owner.clear();
        self.light_paths = LightPathCache::default();
        self.sent_light_paths = LightPaths::default();
        self.to_decode.clear();
        self.considered.clear();
        let message = Message::NewScene.encode();
        for rank in 1..=self.workers.len() {
            self.transport.send(rank, message.clone())?;
        }
        Ok(())
    }

    /// Renders a frame of `world` on the workers, which first apply `update` to their copy of the
    /// scene, and assembles it: bit for bit the image [`crate::render::render_frame`] makes of
    /// `world`. `progress` is told how many tiles are done. With no worker, renders here.
    pub fn render_frame(
        &mut self,
        world: &World,
        update: &[u8],
        progress: Option<&dyn Fn(usize, usize)>,
    ) -> Result<(Framebuffer, FrameReport), DistributedError> {
        if self.workers.is_empty() {
            return Ok(crate::render::render_frame(world, None));
        }
        self.render(world, update, progress, None)
    }

    /// Traces `lattices` of pass `pass` on the workers, as
    /// [`crate::render::progressive::trace_lattices`] traces them here, after sending them what
    /// changed in `rt` since they were last sent it (see [`Master::render_context`]): the same
    /// samples bit for bit, in list order. The lanes where `wanted(x, y)` is false are not
    /// traced. With no worker, traces here. A viewer calls this for each piece of its work.
    pub fn trace_lattices(
        &mut self,
        rt: &Context,
        world: &World,
        lattices: &[PixelLattice],
        pass: u32,
        preview: bool,
        wanted: &(dyn Fn(u32, u32) -> bool + Sync),
    ) -> Result<(Vec<LatticeSamples>, BatchReport), DistributedError> {
        if self.workers.is_empty() {
            return Ok(crate::render::progressive::trace_lattices(world, lattices, pass, preview, wanted));
        }
        let start = Instant::now();
        let update = self.update(rt, world)?;
        let (w, h) = (world.options.width, world.options.height);
        let units: Vec<LatticeUnit> = lattices
            .iter()
            .map(|&lattice| LatticeUnit { lattice, lanes: lattice_lanes(lattice, w, h, wanted) })
            .collect();
        // Each worker keeps the regions of the image it traced before: their geometry is in its cache.
        let region = |l: &PixelLattice| {
            let cols = w.div_ceil(REGION_SIDE) as usize;
            (l.y0 / REGION_SIDE) as usize * cols + (l.x0 / REGION_SIDE) as usize
        };
        self.region_owner.resize(w.div_ceil(REGION_SIDE) as usize * h.div_ceil(REGION_SIDE) as usize, None);
        let owners: Vec<Option<usize>> =
            lattices.iter().map(|l| self.region_owner.get(region(l)).copied().flatten()).collect();
        let mut samples: Vec<Option<LatticeSamples>> = lattices.iter().map(|_| None).collect();
        // The pass's light paths, traced here once and sent with its first piece: a worker keeps
        // them for the pieces after (unless its world changed, when it traces the same ones).
        let tracer = LatticeTracer::new(world, pass, preview);
        tracer.reuse_light_paths(&self.light_paths);
        tracer.prepare_light_paths();
        tracer.keep_light_paths(&self.light_paths);
        let paths = tracer.light_paths();
        let mut light_paths = Vec::new();
        if !paths.same(&self.sent_light_paths) {
            paths.encode(&mut light_paths);
            self.sent_light_paths = paths;
        }
        let job = Job::Lattices { pass, preview };
        let work = Work {
            job,
            units: lattices.len(),
            lattices: &units,
            owners: &owners,
            costs: &[],
            light_paths: &light_paths,
            split_below: 0,
            splittable: &[],
        };
        let mut accept = |u: usize, bytes: &[u8]| -> Result<(), String> {
            samples[u] = Some(LatticeSamples::decode(world, units[u].lattice, units[u].lanes, bytes)?);
            Ok(())
        };
        let FrameRun { given, counts, .. } = self.run(world, &update, work, None, Some(rt), &mut accept)?;
        for (l, owner) in lattices.iter().zip(&given) {
            if let (Some(slot), Some(w)) = (self.region_owner.get_mut(region(l)), owner) {
                *slot = Some(*w);
            }
        }
        let samples: Vec<LatticeSamples> = samples.into_iter().flatten().collect();
        if samples.len() != lattices.len() {
            return Err(DistributedError::Protocol {
                rank: 0,
                message: format!("the workers traced {} of {} lattices", samples.len(), lattices.len()),
            });
        }
        let primary_rays = counts.iter().map(|c| c.rays[0]).sum();
        let total_rays = counts.iter().flat_map(|c| c.rays).sum();
        let elapsed = start.elapsed();
        self.worker_time = WorkerTime::of(elapsed, &self.worker_times);
        Ok((samples, BatchReport { primary_rays, total_rays, elapsed }))
    }

    /// [`Master::render_frame`], answering the workers' requests for meshes and textures from
    /// `source`, the application's context (with none, every request is answered with nothing).
    fn render(
        &mut self,
        world: &World,
        update: &[u8],
        progress: Option<&dyn Fn(usize, usize)>,
        source: Option<&Context>,
    ) -> Result<(Framebuffer, FrameReport), DistributedError> {
        let start = Instant::now();
        let renderer = TileRenderer::new(world);
        // Traced once here and sent to every worker, as the paper's master did.
        renderer.prepare_light_paths();
        let paths = renderer.light_paths();
        let mut light_paths = Vec::new();
        if !paths.is_empty() {
            paths.encode(&mut light_paths);
        }
        let tiles = renderer.tiles();
        // Tiles that are final as they arrive go straight into the image, which is then whole
        // when the last one is in; the others are kept for the frame's filter or pixel shader.
        let mut assembly = renderer.start_assembly();
        let mut rendered: Vec<Option<RenderedTile>> = Vec::new();
        if assembly.is_none() {
            rendered = tiles.iter().map(|_| None).collect();
        }
        // Quarters of tiles, counted as they arrive.
        let mut arrived = 0;
        let owners = std::mem::take(&mut self.last_owner);
        let costs = std::mem::take(&mut self.last_cost);
        let splittable: Vec<bool> = tiles.iter().map(|t| renderer.quarters(t).is_some()).collect();
        let split_below = match self.tile_quarters {
            TileQuarters::Never => 0,
            TileQuarters::AtTheEnd if self.worker_threads() > 1 => tiles.len() / QUARTERED_SHARE,
            TileQuarters::AtTheEnd => 0,
            TileQuarters::Always => tiles.len(),
        };
        let work = Work {
            job: Job::Tiles,
            units: tiles.len(),
            lattices: &[],
            owners: &owners,
            costs: &costs,
            light_paths: &light_paths,
            split_below,
            splittable: &splittable,
        };
        let mut accept = |u: usize, bytes: &[u8]| -> Result<(), String> {
            let unit = u32::try_from(u).ok().and_then(|u| TileUnit::of(u, tiles.len()));
            let tile = u32::try_from(u).ok().and_then(|u| unit_tile(&renderer, &tiles, u));
            let (Some(unit), Some(tile)) = (unit, tile) else {
                return Err(format!("unit {u} is no tile or quarter of this frame"));
            };
            match (&mut assembly, unit) {
                (Some(assembly), _) => assembly.add(tile, bytes)?,
                (None, TileUnit::Whole(t)) => rendered[t as usize] = Some(RenderedTile::decode(world, tile, bytes)?),
                // `unit_tile` gives quarters only of frames assembled as they arrive.
                (None, TileUnit::Quarter(..)) => return Err(format!("unit {u}: a quarter of a tile kept whole")),
            }
            arrived += unit.quarters();
            Ok(())
        };
        let FrameRun { given, counts, costs, helping } =
            self.run(world, update, work, progress, source, &mut accept)?;
        if arrived != 4 * tiles.len() {
            return Err(DistributedError::Protocol {
                rank: 0,
                message: format!(
                    "the workers finished frame {} with {:.2} of {} tiles",
                    self.frame,
                    arrived as f64 / 4.0,
                    tiles.len()
                ),
            });
        }
        (self.last_owner, self.last_cost) = per_tile(tiles.len(), &given, &costs);
        let (fb, mut report) = match assembly {
            Some(assembly) => assembly.finish(renderer, start),
            None => renderer.finish(rendered.into_iter().flatten().collect(), start),
        };
        for c in &counts {
            super::add_counts(&mut report, c);
        }
        report.threads = self.worker_threads();
        report.elapsed = start.elapsed();
        self.worker_time = WorkerTime { helping, ..WorkerTime::of(report.elapsed, &self.worker_times) };
        Ok((fb, report))
    }

    /// Runs a frame of `work` on the workers: sends each the frame's `update` and its first units,
    /// hands out the rest as units come back (each to `accept`, with its index), answers requests
    /// for meshes and textures from `source`, and gathers the workers' counts.
    fn run(
        &mut self,
        world: &World,
        update: &[u8],
        work: Work,
        progress: Option<&dyn Fn(usize, usize)>,
        source: Option<&Context>,
        accept: &mut Accept,
    ) -> Result<FrameRun, DistributedError> {
        self.frame += 1;
        let frame = self.frame;
        let started = Instant::now();
        let units = work.units;
        let described = |list: &[u32]| -> Vec<LatticeUnit> {
            match work.job {
                Job::Tiles => Vec::new(),
                Job::Lattices { .. } => list.iter().map(|&u| work.lattices[u as usize]).collect(),
            }
        };
        let mut schedule = Schedule::new(units, self.workers.len(), work.owners, work.costs)
            .splitting(work.split_below, |t| work.splittable.get(t as usize).copied().unwrap_or(false));
        // The units handed out are numbered past the tiles' where tiles may go out in quarters.
        let numbered = if work.split_below > 0 { TileUnit::count(units) } else { units };
        // Work handed out and held is counted in quarters of a tile.
        let quarters = |u: u32| TileUnit::of(u, units).map_or(4, TileUnit::quarters);
        // Units from the schedule for `worker`, up to `wanted` quarters; and the quarters they make.
        let take = |schedule: &mut Schedule, worker: usize, wanted: usize| {
            let (mut next, mut given) = (Vec::new(), 0);
            while given < wanted {
                let Some(u) = schedule.next(worker) else { break };
                given += quarters(u);
                next.push(u);
            }
            (next, given)
        };
        let mut holdings = Holdings::new(numbered, self.workers.len());
        // Tiles only: a helper's copy renders again what another worker may render too, and a
        // viewer's lattices report their rays, which would count twice.
        let helping = self.tile_copies && matches!(work.job, Job::Tiles);
        let mut costs = vec![0u32; numbered];
        let mut told_last = vec![false; self.workers.len()];
        let mut ran_dry = vec![false; self.workers.len()];
        // Units each worker sent, copies delivered second among them, in quarters of a tile.
        let mut sent = vec![0usize; self.workers.len()];
        let mut traffic = Traffic::default();
        let all_threads = self.worker_threads();
        let threads: Vec<usize> = self.workers.iter().map(|w| (w.threads as usize).max(1)).collect();
        for (w, info) in self.workers.iter().enumerate() {
            let target = in_flight_target(info, schedule.left(), all_threads);
            let (first, _) = take(&mut schedule, w, 4 * target);
            for &t in &first {
                holdings.hand(w, t);
            }
            told_last[w] = first.is_empty() || (!helping && schedule.left() == 0);
            let lattices = described(&first);
            let m = Message::Frame {
                frame,
                update: update.to_vec(),
                light_paths: work.light_paths.to_vec(),
                job: work.job,
                units: first,
                lattices,
                last: told_last[w],
            }
            .encode();
            traffic.updates += update.len() as u64;
            traffic.light_paths += work.light_paths.len() as u64;
            traffic.control += (m.len() - update.len() - work.light_paths.len()) as u64;
            self.transport.send(w + 1, m)?;
        }
        if let Some(rt) = source.filter(|_| !update.is_empty()) {
            self.consider_texture_names(rt);
        }
        self.speculate(source);
        let (mut received, mut done) = (0, vec![false; self.workers.len()]);
        // Texture requests waiting for their textures' decoding, by rank.
        let mut parked: Vec<(usize, TextureRequests)> = Vec::new();
        let mut counts = Vec::new();
        self.worker_times.clear();
        let mut failure = None;
        while done.contains(&false) {
            let (rank, bytes) = match self.next_event()? {
                Event::Message(rank, bytes) => (rank, bytes),
                Event::Decoded(texture) => {
                    self.decoding.remove(texture.key());
                    if self.speculating.as_ref() == Some(texture.key()) {
                        self.speculating = None;
                    }
                    self.texture_server.add(*texture);
                    // The requests that waited for it, and for nothing else now, are answered.
                    for (rank, textures) in std::mem::take(&mut parked) {
                        let (ready, waiting) = self.start_decoding(textures, source);
                        if !ready.is_empty() {
                            let textures = self.texture_answers(ready, source);
                            let m = Message::Data { frame, meshes: vec![], parts: vec![], textures }.encode();
                            traffic.fetches += m.len() as u64;
                            self.transport.send(rank, m)?;
                        }
                        if !waiting.is_empty() {
                            parked.push((rank, waiting));
                        }
                    }
                    self.speculate(source);
                    continue;
                }
            };
            let protocol_error = |message: String| DistributedError::Protocol { rank, message };
            let Some(w) = rank.checked_sub(1).filter(|&w| w < self.workers.len()) else {
                return Err(protocol_error("a message from no worker".into()));
            };
            // Finished tiles, by far the most bytes, are read where they lie in the message.
            if let Some(rendered) = RenderedUnits::decode(&bytes) {
                let RenderedUnits { frame: f, units: batch, starved } = rendered.map_err(protocol_error)?;
                if f != frame {
                    return Err(protocol_error(format!("a message out of place in frame {frame}")));
                }
                traffic.pixels += bytes.len() as u64;
                if starved {
                    self.workers[w].ran_dry();
                    ran_dry[w] = true;
                }
                sent[w] += batch.iter().map(|&(unit, ..)| quarters(unit)).sum::<usize>();
                // Per worker, the units another delivered first, for it to leave out.
                let mut dropped: Vec<(usize, Vec<u32>)> = Vec::new();
                for (unit, micros, pixels) in batch {
                    let u = unit as usize;
                    match holdings.deliver(w, unit) {
                        Delivery::NotGiven => {
                            return Err(protocol_error(format!("sent unit {unit}, which it was not given")))
                        }
                        Delivery::Again => continue,
                        Delivery::First { other } => {
                            if let Some(other) = other.filter(|&o| !done[o]) {
                                match dropped.iter_mut().find(|(o, _)| *o == other) {
                                    Some((_, units)) => units.push(unit),
                                    None => dropped.push((other, vec![unit])),
                                }
                            }
                        }
                    }
                    accept(u, pixels).map_err(protocol_error)?;
                    costs[u] = micros;
                    received += quarters(unit);
                    if let Some(p) = progress {
                        p(received / 4, units);
                    }
                }
                // The worker that sent, and each that may leave units out, get more: a worker
                // whose last units another delivered has nothing to send that would ask for more.
                dropped.push((w, Vec::new()));
                for (x, gone) in dropped {
                    let held = holdings.held_weight(x, quarters);
                    let target = in_flight_target(&self.workers[x], schedule.left(), all_threads);
                    let wanted = (4 * target).saturating_sub(held);
                    let top_up = !told_last[x] && (wanted > 0 || held == 0 || failure.is_some());
                    if !top_up && gone.is_empty() {
                        continue;
                    }
                    // Enough new units to bring the worker's units in flight back to its
                    // target; once every unit is handed out, copies of units others hold. After
                    // a failure nothing more is handed out: the frame ends as soon as every
                    // worker has sent what it holds.
                    let mut next: Vec<u32> = Vec::new();
                    if top_up {
                        let mut given = 0;
                        if failure.is_none() {
                            (next, given) = take(&mut schedule, x, wanted);
                            for &t in &next {
                                holdings.hand(x, t);
                            }
                            if helping && given < wanted {
                                next.extend(holdings.copies_for(x, wanted - given, quarters, |o| threads[o]));
                            }
                        }
                        told_last[x] = next.is_empty() || (!helping && (schedule.left() == 0 || given < wanted));
                    }
                    let lattices = described(&next);
                    let m = Message::Assign { frame, units: next, lattices, last: told_last[x], dropped: gone };
                    let m = m.encode();
                    traffic.control += m.len() as u64;
                    self.transport.send(x + 1, m)?;
                }
                self.transport.recycle(bytes);
                continue;
            }
            match Message::decode(&bytes).map_err(protocol_error)? {
                Message::Fetch { frame: f, objects, parts, textures } if f == frame => {
                    traffic.fetches += bytes.len() as u64;
                    let meshes: Vec<_> =
                        objects.into_iter().map(|id| (id, self.encoded_object(id, source, world))).collect();
                    let parts: Vec<_> = parts
                        .into_iter()
                        .map(|(id, part)| (id, part, self.encoded_part(id, part, source, world)))
                        .collect();
                    // Textures not decoded yet are answered once they are, in another message.
                    let (ready, waiting) = self.start_decoding(textures, source);
                    let textures = self.texture_answers(ready, source);
                    if !waiting.is_empty() {
                        parked.push((rank, waiting));
                    }
                    if !(meshes.is_empty() && parts.is_empty() && textures.is_empty()) {
                        let m = Message::Data { frame, meshes, parts, textures }.encode();
                        traffic.fetches += m.len() as u64;
                        self.transport.send(rank, m)?;
                    }
                }
                Message::FrameDone { frame: f, counts: c, failure: worker_failure } if f == frame && !done[w] => {
                    traffic.counters += bytes.len() as u64;
                    done[w] = true;
                    self.workers[w].frame_done(sent[w].div_ceil(4), Duration::from_nanos(c.rendering_ns), ran_dry[w]);
                    let share = WorkerShare { done: started.elapsed(), ..WorkerShare::of(&c, self.workers[w].threads) };
                    self.worker_times.push(share);
                    counts.push(c);
                    if let Some(message) = worker_failure {
                        failure.get_or_insert(DistributedError::Worker { rank, message });
                    }
                }
                _ => return Err(protocol_error(format!("a message out of place in frame {frame}"))),
            }
            self.transport.recycle(bytes);
        }
        if let Some(e) = failure {
            return Err(e);
        }
        self.traffic = traffic;
        self.demand = Demand {
            fetched_objects: counts.iter().map(|c| c.fetched_objects).sum(),
            fetched_bytes: counts.iter().map(|c| c.fetched_bytes).sum(),
            fetched_parts: counts.iter().map(|c| c.fetched_parts).sum(),
            fetched_part_bytes: counts.iter().map(|c| c.fetched_part_bytes).sum(),
            resident_parts: counts.iter().map(|c| c.resident_parts).sum(),
            evicted_parts: counts.iter().map(|c| c.evicted_parts).sum(),
            fetched_textures: counts.iter().map(|c| c.fetched_textures).sum(),
            fetched_texture_levels: counts.iter().map(|c| c.fetched_texture_levels).sum(),
            fetched_texture_tiles: counts.iter().map(|c| c.fetched_texture_tiles).sum(),
            fetched_texture_bytes: counts.iter().map(|c| c.fetched_texture_bytes).sum(),
            evicted_objects: counts.iter().map(|c| c.evicted_objects).sum(),
            resident_objects: counts.iter().map(|c| c.resident_objects).sum(),
            most_resident_objects: counts.iter().map(|c| c.resident_objects).max().unwrap_or(0),
            reached_objects: counts.iter().map(|c| c.reached_objects).sum(),
            kept_objects: counts.iter().map(|c| c.kept_objects).sum(),
            kept_textures: counts.iter().map(|c| c.kept_textures).sum(),
        };
        // Textures load where they are sampled: the workers' failures are the frame's.
        world.textures.add_warnings(counts.iter().flat_map(|c| &c.texture_warnings).map(|(name, path, reason)| {
            crate::texture::TextureWarning {
                name: name.clone(),
                path: (!path.is_empty()).then(|| path.into()),
                reason: reason.clone(),
            }
        }));
        let (given, helping) = holdings.delivered();
        let helping = Helping { quartered: schedule.split(), ..helping };
        Ok(FrameRun { given, counts, costs, helping })
    }

    /// The next worker message, or a texture decoded meanwhile.
    fn next_event(&self) -> Result<Event, DistributedError> {
        if self.decoding.is_empty() {
            let (rank, bytes) = self.transport.recv()?;
            return Ok(Event::Message(rank, bytes));
        }
        loop {
            if let Ok(texture) = self.decoded_rx.try_recv() {
                return Ok(Event::Decoded(Box::new(texture)));
            }
            if let Some((rank, bytes)) = self.transport.try_recv()? {
                return Ok(Event::Message(rank, bytes));
            }
            if self.transport.sending() {
                std::thread::yield_now();
            } else {
                std::thread::sleep(DECODING_POLL);
            }
        }
    }

    /// Splits `requests` into those that can be answered at once and those that wait for their
    /// textures' decoding, and starts decoding those on the thread pool, each texture once: a
    /// texture can take tens of milliseconds to decode and mip-map, which would hold up every
    /// other worker's tiles and fetches.
    fn start_decoding(
        &mut self,
        requests: TextureRequests,
        source: Option<&Context>,
    ) -> (TextureRequests, TextureRequests) {
        let Some(rt) = source else { return (requests, Vec::new()) };
        let generation = rt.textures().generation();
        let undecoded = self.texture_server.undecoded(generation, &requests);
        if undecoded.is_empty() {
            return (requests, Vec::new());
        }
        for key in &undecoded {
            if !self.decoding.contains(key) {
                let delivery = rt.texture_delivery(TextureKind::Texture, &key.0);
                self.decode(rt, key.clone(), delivery);
            }
        }
        requests.into_iter().partition(|(part, name, _)| match *part {
            TexturePart::Whole(_) => true,
            TexturePart::Pyramid { raw } | TexturePart::Level { raw, .. } | TexturePart::Tile { raw, .. } => {
                !undecoded.iter().any(|(n, r)| n == name && *r == raw)
            }
        })
    }

    /// Starts reading and decoding texture `key` (name, raw) of `rt` on the thread pool, from
    /// `delivery`, unless it is being decoded; returns whether it started.
    fn decode(&mut self, rt: &Context, key: (String, bool), delivery: TextureDelivery) -> bool {
        if !self.decoding.insert(key.clone()) {
            return false;
        }
        let (name, raw) = key;
        let decoder = self.texture_server.decoder(rt.textures().generation());
        let tx = self.decoded_tx.clone();
        rayon::spawn(move || {
            let decode = std::panic::AssertUnwindSafe(|| decoder.decode(name.clone(), raw, delivery.deliver()));
            let texture = std::panic::catch_unwind(decode).unwrap_or_else(|_| {
                let failed = Delivered::Missing { path: None, reason: "decoding it failed".into() };
                decoder.decode(name, raw, failed)
            });
            // The master is gone: nothing waits for it.
            let _ = tx.send(texture);
        });
        true
    }

    /// Queues for [`Master::speculate`] the textures `rt`'s shader parameters name that were not
    /// considered before: at a frame whose update is not empty (a frame with none changed no
    /// name).
    fn consider_texture_names(&mut self, rt: &Context) {
        for name in rt.texture_name_candidates() {
            if !self.considered.contains(name) {
                self.considered.insert(name.to_string());
                if rt.delivers_texture(name) {
                    self.to_decode.push_back(name.to_string());
                }
            }
        }
    }

    /// Decodes, one at a time, the textures the scene's shader parameters name that no worker
    /// has asked for yet: when one asks, its answer is ready and its fetch waits only for the
    /// round trip. Workers ask for a texture the first time a lookup reads it, often in the
    /// middle of a frame and all at once; decoding and mip-mapping one takes tens of
    /// milliseconds. Not past half the bytes the server keeps (what a worker asks for is served
    /// first).
    fn speculate(&mut self, source: Option<&Context>) {
        let Some(rt) = source else { return };
        if self.speculating.is_some() || self.texture_server.held_bytes() > crate::texture::MAX_SERVED_BYTES / 2 {
            return;
        }
        let generation = rt.textures().generation();
        while let Some(name) = self.to_decode.pop_front() {
            let request = (TexturePart::Pyramid { raw: false }, name, None);
            if self.texture_server.undecoded(generation, std::slice::from_ref(&request)).is_empty() {
                continue;
            }
            // A file that large may be no texture at all (a string parameter names any file).
            let delivery = rt.texture_delivery(TextureKind::Texture, &request.1);
            if delivery.file_bytes().is_some_and(|bytes| bytes > LARGEST_TEXTURE_DECODED_AHEAD) {
                continue;
            }
            let key = (request.1, false);
            if self.decode(rt, key.clone(), delivery) {
                self.speculating = Some(key);
                return;
            }
        }
    }

    /// The answers to texture requests, from `source` (none: every texture is missing).
    fn texture_answers(
        &mut self,
        requests: TextureRequests,
        source: Option<&Context>,
    ) -> Vec<(TexturePart, String, Vec<u8>)> {
        if requests.is_empty() {
            return Vec::new();
        }
        let answers: Vec<Vec<u8>> = match source {
            Some(rt) => {
                let generation = rt.textures().generation();
                let deliver = |kind, name: &str| rt.deliver_texture(kind, name);
                let answers = self.texture_server.answer_all(generation, &requests, deliver);
                answers.iter().map(|a| a.to_vec()).collect()
            }
            None => {
                let none = Delivered::Missing { path: None, reason: "the master serves no textures".into() };
                vec![encode_answer(&TextureAnswer::Whole(none), self.deflate); requests.len()]
            }
        };
        requests.into_iter().zip(answers).map(|((part, name, _), answer)| (part, name, answer)).collect()
    }

    /// Object `id` of `source` as a worker fetches it: its mesh and the BVH `world` holds for it,
    /// whole or its small tree ([`encode_object`]; empty when it has no mesh).
    fn encoded_object(&mut self, id: u32, source: Option<&Context>, world: &World) -> Vec<u8> {
        self.encoded(id, source, world).map(|e| e.object.as_ref().clone()).unwrap_or_default()
    }

    /// Part `part` of object `id`'s BVH as a worker fetches it ([`encode_part`]; empty when the
    /// object has no such part now).
    fn encoded_part(&mut self, id: u32, part: u32, source: Option<&Context>, world: &World) -> Vec<u8> {
        let encoded = self.encoded(id, source, world);
        encoded.and_then(|e| e.parts.get(part as usize)).cloned().unwrap_or_default()
    }

    /// Object `id` of `source` encoded for fetches, once for as long as its mesh stands: the BVH
    /// built here goes with the mesh (the worker need not build it again), a large object's cut
    /// into parts.
    fn encoded(&mut self, id: u32, source: Option<&Context>, world: &World) -> Option<&Encoded> {
        let rt = source?;
        let (mesh, bvh) = if id & DISPLACED_MESH_KEY != 0 {
            // A displaced mesh lives in the world's scene alone (`render/remote_displacement.rs`).
            let object = crate::scene::ObjectId(id & !DISPLACED_MESH_KEY);
            let mesh = world.scene.mesh(object)?;
            let built = world.scene.objects().get(object.0 as usize).and_then(|o| o.resident_data());
            (mesh, built.filter(|data| Arc::ptr_eq(&data.mesh, mesh)).map(|data| &data.bvh.bvh))
        } else {
            let object = crate::api::ObjectId(id);
            (rt.object_mesh(object)?, rt.object_bvh(object, world))
        };
        let fresh = self.encoded_objects.get(&id).is_some_and(|e| Arc::ptr_eq(&e.mesh, mesh));
        if !fresh {
            let encoded_mesh = encode_mesh(mesh);
            let (object_bytes, parts) = match bvh {
                Some(built) if mesh.triangle_count() > self.parted_above => {
                    let cut = cut(built, self.part_triangles);
                    let counts: Vec<u32> = cut.parts.iter().map(|p| p.triangles).collect();
                    let mut small = Vec::new();
                    encode_small_tree(&cut.small, &counts, &mut small);
                    let deflate = self.deflate;
                    let parts: Vec<Vec<u8>> = {
                        use rayon::prelude::*;
                        cut.parts
                            .par_iter()
                            .map(|p| {
                                let mut bytes = Vec::new();
                                encode_bvh4(&p.bvh, &mut bytes);
                                encode_part(&bytes, deflate)
                            })
                            .collect()
                    };
                    (encode_object(&encoded_mesh, ObjectTree::Parts(&small), self.deflate), parts)
                }
                Some(built) => {
                    let mut bvh = Vec::new();
                    encode_bvh4(built, &mut bvh);
                    (encode_object(&encoded_mesh, ObjectTree::Whole(&bvh), self.deflate), Vec::new())
                }
                None => (encode_object(&encoded_mesh, ObjectTree::None, self.deflate), Vec::new()),
            };
            let encoded = Encoded { mesh: mesh.clone(), object: Arc::new(object_bytes), parts };
            let size = encoded.bytes();
            if self.encoded_bytes + size > ENCODED_OBJECTS_KEPT {
                self.encoded_objects.clear();
                self.encoded_bytes = 0;
            }
            self.encoded_bytes += size;
            if let Some(old) = self.encoded_objects.insert(id, encoded) {
                self.encoded_bytes -= old.bytes();
            }
        }
        self.encoded_objects.get(&id)
    }

    /// Tells the workers to stop (as dropping the master does).
    pub fn shutdown(mut self) -> Result<(), DistributedError> {
        self.quit()
    }

    fn quit(&mut self) -> Result<(), DistributedError> {
        if !std::mem::replace(&mut self.open, false) {
            return Ok(());
        }
        let quit = Message::Quit.encode();
        let mut first_error = None;
        for rank in 1..self.transport.size() {
            if let Err(e) = self.transport.send(rank, quit.clone()) {
                first_error.get_or_insert(e);
            }
        }
        first_error.map_or(Ok(()), |e| Err(e.into()))
    }
}

impl<T: Transport> Drop for Master<T> {
    fn drop(&mut self) {
        // Workers wait for a word from the master whatever happened to it; an error here has no
        // one left to tell.
        let _ = self.quit();
    }
}

/// Who rendered each of a frame's `tiles` tiles and what it took, from the same by unit (`given`
/// and `costs`, numbered as [`TileUnit`]s are): a tile that went out in quarters was rendered by
/// the worker of its first quarter and took what its quarters took together.
fn per_tile(tiles: usize, given: &[Option<usize>], costs: &[u32]) -> (Vec<Option<usize>>, Vec<u32>) {
    (0..tiles)
        .map(|t| {
            let whole = (given.get(t).copied().flatten(), costs.get(t).copied().unwrap_or(0));
            let quarters = tiles + 4 * t..tiles + 4 * t + 4;
            match (whole.0, given.get(quarters.clone()), costs.get(quarters)) {
                (None, Some(owners), Some(costs)) => {
                    (owners.iter().flatten().next().copied(), costs.iter().fold(0u32, |a, &c| a.saturating_add(c)))
                }
                _ => whole,
            }
        })
        .unzip()
}

/// How many units a worker should have in flight: its window (enough to hide a round trip
/// through the master), but no more than its threads' share of the units not yet handed out, and
/// at least two a thread. Handing out shares of what is left (guided self-scheduling) keeps the
/// end of a frame balanced: no worker holds a long queue of expensive tiles while others idle.
fn in_flight_target(worker: &WorkerInfo, left: usize, all_threads: usize) -> usize {
    let threads = (worker.threads as usize).max(1);
    let share = (left * threads).div_ceil(all_threads.max(threads));
    worker.window().min(share.max(FEWEST_TILES_IN_FLIGHT_PER_THREAD * threads))
}

/// What a worker reports of its share of a frame.
pub(super) fn counts_of(report: &FrameReport) -> FrameCounts {
    use rtsl_compiler::interface::ShaderKind;
    let kind_index = |k: ShaderKind| ShaderKind::ALL.iter().position(|&x| x == k).unwrap_or(0) as u8;
    FrameCounts {
        rays: [report.primary_rays, report.shadow_rays, report.secondary_rays, report.transparency_rays],
        shaded_points: report.shaded_points,
        light_evaluations: report.light_evaluations,
        rays_cut: report.rays_cut,
        lights_dropped: report.lights_dropped,
        shading_ns: report.shading.as_nanos() as u64,
        kind_ns: report.by_kind.iter().map(|d| d.as_nanos() as u64).collect(),
        light_paths_ns: report.light_paths.as_nanos() as u64,
        gathering_ns: report.gathering.as_nanos() as u64,
        by_shader: report.by_shader.iter().map(|(n, k, d)| (n.clone(), kind_index(*k), d.as_nanos() as u64)).collect(),
        shader_messages: report.shader_messages.clone(),
        ..FrameCounts::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A worker in its first frame.
    fn fresh(threads: u32) -> WorkerInfo {
        WorkerInfo::new(threads, None)
    }

    /// A worker whose units took a microsecond each: its window is the most.
    fn cheap(threads: u32) -> WorkerInfo {
        WorkerInfo { unit_time: Some(Duration::from_micros(1)), ..fresh(threads) }
    }

    #[test]
    fn quartered_tiles_are_owned_by_their_first_quarter_and_cost_their_sum() {
        // Two tiles: 0 went whole to worker 1; 1 in quarters to workers 0, 2, 2, 1.
        let mut given = vec![Some(1), None, None, None, None, None, Some(0), Some(2), Some(2), Some(1)];
        let mut costs = vec![50, 0, 0, 0, 0, 0, 7, 8, 9, u32::MAX];
        assert_eq!(per_tile(2, &given, &costs), (vec![Some(1), Some(0)], vec![50, u32::MAX]));
        // A quarter nobody delivered (a failed frame) leaves the others'.
        given[6] = None;
        costs[9] = 1;
        assert_eq!(per_tile(2, &given, &costs), (vec![Some(1), Some(2)], vec![50, 25]));
        // Units numbered without quarters.
        assert_eq!(per_tile(2, &given[..2], &costs[..2]), (vec![Some(1), None], vec![50, 0]));
    }

    #[test]
    fn worker_time_splits_the_frame() {
        let ms = Duration::from_millis;
        let counts = |world: u64, share: u64, rendering: u64, fetch_wait: u64| FrameCounts {
            world_ns: world * 1_000_000,
            share_ns: share * 1_000_000,
            rendering_ns: rendering * 1_000_000,
            fetch_wait_ns: fetch_wait * 1_000_000,
            fetch_build_ns: 4_000_000,
            ..FrameCounts::default()
        };
        // A worker of one thread, and one of two whose threads rendered 120 ms between them.
        let shares = [WorkerShare::of(&counts(2, 80, 70, 10), 1), WorkerShare::of(&counts(4, 90, 120, 200), 2)];
        let time = WorkerTime::of(ms(100), &shares);
        assert_eq!((time.world, time.share, time.rendering), (ms(3), ms(85), ms(65)));
        // Fetch waits are per thread too, and never more than the rendering they are part of.
        assert_eq!((time.fetching, time.loading), (ms(35), ms(3)));
        assert_eq!((time.waiting, time.outside), (ms(20), ms(12)));
        assert_eq!(time.world + time.rendering + time.waiting + time.outside, time.frame);
        // Reports that arrived together: no worker waited for the other.
        assert_eq!(time.after_done, ms(0));
        // The first reported 30 ms before the second: a mean of 15 ms waiting for the last.
        let (first, second) = (WorkerShare { done: ms(60), ..shares[0] }, WorkerShare { done: ms(90), ..shares[1] });
        assert_eq!(WorkerTime::of(ms(100), &[first, second]).after_done, ms(15));
        // No CPU time reported: nothing off the core.
        assert_eq!(time.off_core, ms(0));
        // One thread: 70 ms in units, 10 of them waiting for fetches, 45 on its core: 15 off it.
        // Two threads: 60 ms each in units, 20 waiting, 30 on the core: 10 off it.
        let with_cpu = |c: FrameCounts, cpu: u64| FrameCounts { rendering_cpu_ns: cpu * 1_000_000, ..c };
        let shares = [
            WorkerShare::of(&with_cpu(counts(2, 80, 70, 10), 45), 1),
            WorkerShare::of(&with_cpu(counts(4, 90, 120, 40), 60), 2),
        ];
        assert_eq!(WorkerTime::of(ms(100), &shares).off_core, ms(12) + Duration::from_micros(500));
        // No worker reported: nothing is made up.
        assert_eq!(WorkerTime::of(ms(5), &[]).outside, ms(5));
    }

    #[test]
    fn a_worker_holds_at_most_its_share_of_what_is_left() {
        // Early in a frame the window bounds it.
        assert_eq!(in_flight_target(&fresh(1), 1200, 15), 16);
        // A grown window does not take more than the worker's share: 1200 over 15 threads.
        assert_eq!(in_flight_target(&cheap(1), 1200, 15), 80);
        // A worker of 4 threads among 16 takes a quarter of what is left.
        assert_eq!(in_flight_target(&cheap(4), 100, 16), 25);
        // Near the end, two units a thread, so that a round trip does not leave it idle.
        assert_eq!(in_flight_target(&cheap(1), 10, 15), 2);
        assert_eq!(in_flight_target(&cheap(3), 0, 15), 6);
        // No division by zero for a lone worker.
        assert_eq!(in_flight_target(&fresh(1), 1200, 0), 16);
    }

    #[test]
    fn a_window_holds_the_lead_in_rendering_time() {
        let ms = Duration::from_millis;
        // Units of a millisecond a thread: a frame of 100 of them over 2 threads took 100 ms of
        // the threads' time. The first lead, 4 ms, eases to 3 in a frame that never ran dry:
        // each thread holds the unit it renders and 3 behind it.
        let mut w = fresh(2);
        assert_eq!(w.window(), 32);
        w.frame_done(100, ms(100), false);
        assert_eq!((w.unit_time, w.lead), (Some(ms(1)), ms(3)));
        assert_eq!(w.window(), 8);
        // Running dry doubles the lead, up to the longest.
        w.ran_dry();
        assert_eq!(w.window(), 2 * (1 + 6));
        for _ in 0..10 {
            w.ran_dry();
        }
        assert_eq!(w.lead, LONGEST_LEAD);
        // Frames that do not run dry ease it back to the shortest.
        for _ in 0..20 {
            w.frame_done(100, ms(100), false);
        }
        assert_eq!(w.lead, SHORTEST_LEAD);
        assert_eq!(w.window(), 2 * (1 + 2));
        // Expensive units: never fewer than two a thread. Cheap ones: never more than the most.
        w.frame_done(10, ms(500), false);
        assert_eq!(w.window(), 2 * FEWEST_TILES_IN_FLIGHT_PER_THREAD);
        w.frame_done(100_000, ms(10), false);
        assert_eq!(w.window(), 2 * MOST_TILES_IN_FLIGHT_PER_THREAD);
        // A frame in which it rendered nothing keeps what it knew.
        w.frame_done(0, ms(0), true);
        assert_eq!(w.unit_time, Some(Duration::from_nanos(100)));
    }
}

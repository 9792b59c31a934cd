//! A worker: a rank that renders the tiles (or lattices) the master hands it, on the threads of its own pool,
//! from its own copy of the scene, brought to each frame's state before any of that frame's tiles.

use super::fetch::{FetchLink, Pending};
use super::message::{build_fingerprint, Job, LatticeUnit, Message, PROTOCOL_VERSION};
use super::schedule::unit_tile;
use super::transport::Transport;
use super::DistributedError;
use crate::accel::ask_ahead;
use crate::accel::object::ObjectData;
use crate::render::progressive::LatticeTracer;
use crate::render::{LightPaths, TileRenderer, World};
use crate::tiles::Tile;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

/// A worker's copy of the scene.
pub trait WorkerScene: Send {
    /// The world of the next frame, after applying the master's `update` for it (what an update
    /// holds is the application's business: a BART player sends the animation's time).
    fn world(&mut self, update: &[u8]) -> Result<World, String>;
    /// Takes back a frame's world once its tiles are rendered (to keep its BVHs for the next).
    fn finished(&mut self, world: World);
    /// Drops the scene and everything kept of it, for another scene that the next update brings
    /// whole (see [`Message::NewScene`]).
    fn start_again(&mut self);
    /// Where the scene's demand-loaded objects wait for their meshes, if it has any.
    fn fetch_link(&self) -> Option<Arc<FetchLink>> {
        None
    }
}

/// A worker's copy of the master's [`crate::api::Context`], which starts empty and is brought to
/// each frame's state by the updates [`super::Master::render_context`] sends: the worker loads
/// nothing itself, and fetches the mesh of an object from the master when a ray first reaches it,
/// and a texture, shadow map or grid when a shader first looks it up ([`FetchLink`]). A frame whose update is empty reuses the last frame's world.
pub struct ReplicaScene {
    context: crate::api::Context,
    world: Option<World>,
    link: Arc<FetchLink>,
    /// The most bytes of fetched meshes and their BVHs held between frames.
    cache_limit: usize,
    /// The programs the scenes' artifacts made, kept from one scene to the next.
    programs: Arc<crate::api::ShaderCache>,
    /// The meshes (with their BVHs) the last scene had fetched, by digest, for the first world
    /// of the next scene to take instead of fetching them again.
    kept: HashMap<[u8; 32], ObjectData>,
}

/// [`ReplicaScene`]'s cache limit unless told otherwise.
pub const DEFAULT_MESH_CACHE_BYTES: usize = 4 << 30;

impl Default for ReplicaScene {
    fn default() -> Self {
        Self::new()
    }
}

impl ReplicaScene {
    pub fn new() -> ReplicaScene {
        ReplicaScene::with_parts(Arc::new(crate::api::ShaderCache::new()), FetchLink::new())
    }

    /// A replica whose programs come from `programs` where they were made from the same
    /// artifacts, fetching through `link`.
    fn with_parts(programs: Arc<crate::api::ShaderCache>, link: Arc<FetchLink>) -> ReplicaScene {
        let mut context = crate::api::Context::new();
        context.set_mesh_source(link.clone());
        context.set_texture_source(link.clone());
        context.share_shader_cache(programs.clone());
        ReplicaScene {
            context,
            world: None,
            link,
            cache_limit: DEFAULT_MESH_CACHE_BYTES,
            programs,
            kept: HashMap::new(),
        }
    }

    /// A replica that holds at most `bytes` of fetched meshes and their BVHs between frames,
    /// dropping those that rays reached least recently first.
    pub fn with_cache_limit(bytes: usize) -> ReplicaScene {
        ReplicaScene { cache_limit: bytes, ..ReplicaScene::new() }
    }

    /// This replica with its render threads asking ahead for what a tile reaches and setting the
    /// tile aside (`on`, the default), or waiting for each object as they reach it.
    pub fn asking_ahead(self, on: bool) -> ReplicaScene {
        self.link.set_asking_ahead(on);
        self
    }
}

impl WorkerScene for ReplicaScene {
    fn world(&mut self, update: &[u8]) -> Result<World, String> {
        let changed = self.context.apply_update(update).map_err(|e| e.to_string())?;
        let mut world = match self.world.take() {
            Some(world) if !changed => world,
            Some(world) => {
                self.context.return_scene(world);
                self.context.build_world().map_err(|e| e.to_string())?
            }
            None => self.context.build_world().map_err(|e| e.to_string())?,
        };
        // A new scene's objects that the last scene held (a RIB file's next frame declares its
        // set again) are not fetched again; what this world does not take is let go.
        let kept = std::mem::take(&mut self.kept);
        if !kept.is_empty() {
            let mut taken = 0;
            for object in world.scene.objects() {
                let Some(digest) = object.digest() else { continue };
                if let Some(data) = kept.get(digest) {
                    taken += u64::from(object.preload(digest, data.clone()));
                }
            }
            self.link.kept(taken);
        }
        let evicted = super::fetch::evict_least_recently_used(&mut world.scene, self.cache_limit);
        // An object whose every part is here (seen whole from the worker's tiles) is traversed as
        // the one tree the master cut it from: the same hits, without a traversal per part.
        for object in world.scene.objects_mut() {
            object.join_parts();
        }
        self.link.start_frame(evicted);
        Ok(world)
    }

    fn finished(&mut self, world: World) {
        self.world = Some(world);
    }

    /// A fresh replica with the same cache limit: the world and the texture cache go with the
    /// old one. Its compiled programs stay, for the artifacts the next scene sends again (those
    /// the old scene did not use go); so do the meshes it fetched, for the next scene's first
    /// world to take where their digests match, and the fetch link with the texture maps made
    /// from its pyramids, for the next scene's caches to take where theirs match.
    fn start_again(&mut self) {
        self.programs.end_scene();
        self.link.start_scene();
        let kept = self.world.take().map(|w| kept_meshes(&w.scene, self.cache_limit)).unwrap_or_default();
        *self = ReplicaScene {
            cache_limit: self.cache_limit,
            kept,
            ..ReplicaScene::with_parts(self.programs.clone(), self.link.clone())
        };
    }

    fn fetch_link(&self) -> Option<Arc<FetchLink>> {
        Some(self.link.clone())
    }
}

/// The fetched meshes `scene` holds, with their BVHs, by digest: the most recently used first,
/// as many as fit in `limit` bytes.
fn kept_meshes(scene: &crate::scene::Scene, limit: usize) -> HashMap<[u8; 32], ObjectData> {
    let mut held: Vec<_> = scene
        .objects()
        .iter()
        .filter_map(|o| Some((o.last_used()?, o.digest()?, o.resident_data()?, o.memory_bytes())))
        .collect();
    held.sort_by_key(|h| std::cmp::Reverse(h.0));
    let mut kept = HashMap::new();
    let mut total = 0usize;
    for (_, digest, data, bytes) in held {
        if total.saturating_add(bytes) > limit {
            break;
        }
        total += bytes;
        kept.insert(*digest, data.clone());
    }
    kept
}

/// Serves the master on rank 0 of `transport` until it says to stop: greets it (with `scene`'s
/// failure if the scene could not be loaded), then renders each frame's tiles on `pool`. A frame
/// that fails here is reported to the master, and this rank renders nothing more until the master
/// starts a new scene ([`Message::NewScene`]), which it renders from empty.
pub fn serve<T: Transport + ?Sized>(
    transport: &T,
    scene: Result<&mut dyn WorkerScene, String>,
    pool: &rayon::ThreadPool,
) -> Result<(), DistributedError> {
    let (mut scene, mut failure) = match scene {
        Ok(s) => (Some(s), None),
        Err(e) => (None, Some(e)),
    };
    let hello = Message::Hello {
        protocol: PROTOCOL_VERSION,
        build: build_fingerprint(),
        threads: pool.current_num_threads() as u32,
        failure: failure.clone(),
    };
    transport.send(0, hello.encode())?;
    // The light paths the master last sent: a viewer's pass sends them with its first piece only.
    let mut kept_paths = LightPaths::default();
    loop {
        match receive(transport)? {
            Message::Quit => return Ok(()),
            Message::NewScene => {
                kept_paths = LightPaths::default();
                if let Some(s) = scene.as_deref_mut() {
                    s.start_again();
                    failure = None;
                }
            }
            Message::Frame { frame, update, light_paths, job, units, lattices, last } => {
                if !light_paths.is_empty() {
                    kept_paths = LightPaths::decode(&light_paths)
                        .map_err(|message| DistributedError::Protocol { rank: transport.rank(), message })?;
                }
                // A frame of tiles comes with its own paths (or has none); a piece of a pass uses its pass's.
                let paths = match job {
                    Job::Tiles if light_paths.is_empty() => LightPaths::default(),
                    _ => kept_paths.clone(),
                };
                let building = Instant::now();
                let mut early = Vec::new();
                let world = match (scene.as_deref_mut(), &failure) {
                    (Some(s), None) => build_world(transport, frame, pool, s, &update, &mut early)?,
                    (_, failure) => Err(failure.clone().unwrap_or_default()),
                };
                let result = match world {
                    Ok(world) => {
                        let link = scene.as_deref().and_then(|s| s.fetch_link());
                        let first = (units, lattices);
                        let share = Share { frame, job, first, last, early, built_in: building.elapsed() };
                        let rendered = render_share(transport, &world, share, pool, link.as_deref(), &paths);
                        if let Some(s) = scene.as_deref_mut() {
                            s.finished(world);
                        }
                        match rendered {
                            Ok(true) => return Ok(()),
                            Ok(false) => Ok(()),
                            Err(e @ DistributedError::Transport(_)) => return Err(e),
                            Err(e) => Err(e.to_string()),
                        }
                    }
                    Err(message) => Err(message),
                };
                if let Err(message) = result {
                    // The master reports it and ends the frame. This rank renders nothing more of
                    // this scene (its copy may be half updated): until a new scene, every frame
                    // it is sent ends at once with the same failure.
                    let done = Message::FrameDone { frame, counts: Default::default(), failure: Some(message.clone()) };
                    transport.send(0, done.encode())?;
                    failure = Some(message);
                }
            }
            // More tiles of the frame this rank gave up, or answers to what it fetched for it.
            Message::Assign { .. } | Message::Data { .. } if failure.is_some() => {}
            // Units of a frame this rank has finished, which another delivered first.
            Message::Assign { units, .. } if units.is_empty() => {}
            _ => return Err(out_of_place(transport)),
        }
    }
}

/// Builds the frame's world from `update` on the pool (building BVHs uses the worker's threads,
/// not every core) while this thread answers what building it fetches: an object's alpha mask
/// reads its texture, which a worker fetches from the master, and the master serves the frame's
/// fetches from the moment it sends the frame. The frame's assignments that come meanwhile (units
/// another worker delivered first) go to `early`, for the frame's share to take.
fn build_world<T: Transport + ?Sized>(
    transport: &T,
    frame: u64,
    pool: &rayon::ThreadPool,
    scene: &mut dyn WorkerScene,
    update: &[u8],
    early: &mut Vec<Message>,
) -> Result<Result<World, String>, DistributedError> {
    let Some(link) = scene.fetch_link() else { return Ok(pool.install(|| scene.world(update))) };
    std::thread::scope(|s| {
        let building = s.spawn(|| pool.install(|| scene.world(update)));
        let mut pending = Pending::default();
        let answered = (|| {
            while !building.is_finished() {
                let asked = pending.take(&link);
                if !asked.is_empty() {
                    transport.send(0, asked.message(frame).encode())?;
                }
                while let Some((rank, bytes)) = transport.try_recv()? {
                    match decode_given_back(transport, rank, bytes)? {
                        Message::Data { frame: f, meshes, parts, textures } if f == frame => {
                            link.count_texture_answers(&textures);
                            pending.answer(meshes, parts, textures)
                        }
                        m @ Message::Assign { frame: f, .. } if f == frame => early.push(m),
                        Message::Assign { frame: f, units, .. } if f < frame && units.is_empty() => {}
                        _ => return Err(out_of_place(transport)),
                    }
                }
                std::thread::sleep(POLL);
            }
            Ok(())
        })();
        // Whatever happened, no fetch of the build waits any longer: their senders go, so their
        // receivers give up at once (the build then reports what never came).
        drop(pending);
        while !building.is_finished() {
            drop(link.take_requests());
            std::thread::sleep(POLL);
        }
        let built = building.join().unwrap_or_else(|_| Err("building the frame's world panicked".into()));
        answered.map(|()| built)
    })
}

/// The next message from the master.
fn receive<T: Transport + ?Sized>(transport: &T) -> Result<Message, DistributedError> {
    let (rank, bytes) = transport.recv()?;
    decode_given_back(transport, rank, bytes)
}

/// [`decode_from`], the message's buffer given back to the transport once read.
fn decode_given_back<T: Transport + ?Sized>(
    transport: &T,
    rank: usize,
    bytes: Vec<u8>,
) -> Result<Message, DistributedError> {
    let message = decode_from(transport, rank, &bytes);
    transport.recycle(bytes);
    message
}

fn decode_from<T: Transport + ?Sized>(transport: &T, rank: usize, bytes: &[u8]) -> Result<Message, DistributedError> {
    let me = transport.rank();
    if rank != 0 {
        return Err(DistributedError::Protocol { rank: me, message: format!("a message from rank {rank}") });
    }
    Message::decode(bytes).map_err(|message| DistributedError::Protocol { rank: me, message })
}

fn out_of_place<T: Transport + ?Sized>(transport: &T) -> DistributedError {
    DistributedError::Protocol { rank: transport.rank(), message: "a message out of place from the master".into() }
}

/// A unit of work as the worker's renderers take it: its index in the frame, and for a lattice,
/// the lattice.
#[derive(Clone, Copy)]
struct QueuedUnit {
    index: u32,
    lattice: Option<LatticeUnit>,
    /// How many times a render thread set it aside for what it asked ahead for.
    set_aside: u8,
}

/// What renders a frame's units on this worker.
enum Units<'w> {
    Tiles { renderer: TileRenderer<'w>, tiles: Vec<Tile> },
    Lattices(LatticeTracer<'w>),
}

impl<'w> Units<'w> {
    fn new(world: &'w World, job: Job) -> Units<'w> {
        match job {
            Job::Tiles => {
                // The frame's light paths are traced by the first render thread that needs them,
                // not here: their rays may reach meshes this thread must fetch.
                let renderer = TileRenderer::new(world);
                let tiles = renderer.tiles();
                Units::Tiles { renderer, tiles }
            }
            Job::Lattices { pass, preview } => Units::Lattices(LatticeTracer::new(world, pass, preview)),
        }
    }

    /// The units the master handed out, checked against the frame: tiles it has, lattices inside
    /// its image.
    fn check(&self, world: &World, units: Vec<u32>, lattices: Vec<LatticeUnit>) -> Result<Vec<QueuedUnit>, String> {
        match self {
            Units::Tiles { renderer, tiles } => {
                if let Some(&bad) = units.iter().find(|&&u| unit_tile(renderer, tiles, u).is_none()) {
                    return Err(format!(
                        "the master handed out unit {bad}, no tile or quarter of one of a frame of {} tiles",
                        tiles.len()
                    ));
                }
                if !lattices.is_empty() {
                    return Err("the master handed out lattices in a frame of tiles".into());
                }
                Ok(units.into_iter().map(|index| QueuedUnit { index, lattice: None, set_aside: 0 }).collect())
            }
            Units::Lattices(_) => {
                if lattices.len() != units.len() {
                    return Err(format!("the master handed out {} lattices for {} units", lattices.len(), units.len()));
                }
                let (w, h) = (world.options.width, world.options.height);
                if let Some(bad) = lattices.iter().find(|l| !l.lattice.fits(w, h)) {
                    return Err(format!("the master handed out lattice {:?}, outside the {w}x{h} image", bad.lattice));
                }
                Ok(units
                    .into_iter()
                    .zip(lattices)
                    .map(|(index, l)| QueuedUnit { index, lattice: Some(l), set_aside: 0 })
                    .collect())
            }
        }
    }

    fn render(&self, unit: QueuedUnit, out: &mut Vec<u8>) {
        match (self, unit.lattice) {
            (Units::Tiles { renderer, tiles }, _) => {
                // `check` lets in only units that are tiles or quarters of this frame.
                if let Some(tile) = unit_tile(renderer, tiles, unit.index) {
                    renderer.render_tile(&tile).encode(out)
                }
            }
            (Units::Lattices(tracer), Some(l)) => tracer.trace(l.lattice, l.lanes).encode(out),
            // `check` gives every unit of a lattice job its lattice.
            (Units::Lattices(_), None) => {}
        }
    }

    fn report(&self, start: Instant) -> crate::render::FrameReport {
        match self {
            Units::Tiles { renderer, .. } => renderer.report(start),
            Units::Lattices(tracer) => tracer.frame_report(start),
        }
    }
}

/// Renders this worker's share of a frame: the units it was given first, then those it gets for
/// each one it sends back, until the master says no more will come; then reports its counts.
/// Returns whether the master said to stop meanwhile.
///
/// The pool's threads take units from a queue and render them for as long as the frame lasts,
/// each keeping its scratch warm; this thread (the only one that talks to the master) passes
/// finished units on and new units in. Handing the pool one tile at a time cost a thread wake-up
/// per tile, as much as rendering a tile of a simple scene.
///
/// Every wake-up of this thread takes a core from a renderer when the worker has one core a
/// thread, so it sleeps as long as nothing is urgent: while every render thread has a unit
/// waiting behind the one it renders and no fetch waits for an answer, finished units gather and
/// go out together at the next poll ([`BUSY_POLL`]). A render thread wakes it at once when it
/// leaves fewer units waiting than there are threads, or queues a fetch.
fn render_share<T: Transport + ?Sized>(
    transport: &T,
    world: &World,
    share: Share,
    pool: &rayon::ThreadPool,
    link: Option<&FetchLink>,
    paths: &LightPaths,
) -> Result<bool, DistributedError> {
    let Share { frame, job, first, mut last, early, built_in } = share;
    let mut pending = Pending::default();
    let start = Instant::now();
    let renderer = Units::new(world, job);
    // Before any render thread starts: without paths, the first that needs them traces them.
    match &renderer {
        Units::Tiles { renderer, .. } => renderer.use_light_paths(paths),
        Units::Lattices(tracer) => tracer.use_light_paths(paths),
    };
    let threads = pool.current_num_threads();
    let queue = UnitQueue::new(threads);
    let (rendering_ns, rendering_cpu_ns) = (AtomicU64::new(0), AtomicU64::new(0));
    let mut outstanding = 0usize;
    let give = |units: Vec<u32>, lattices: Vec<LatticeUnit>, outstanding: &mut usize| -> Result<(), DistributedError> {
        let new = renderer
            .check(world, units, lattices)
            .map_err(|message| DistributedError::Protocol { rank: transport.rank(), message })?;
        *outstanding += new.len();
        queue.push(new);
        Ok(())
    };
    let (wake_tx, wake_rx) = std::sync::mpsc::channel::<()>();
    // A render thread that queues a fetch wakes this thread, however long it means to wait.
    let _waker = link.map(|link| {
        let wake = wake_tx.clone();
        link.set_waker(Some(Box::new(move || {
            let _ = wake.send(());
        })));
        ClearWakerOnDrop(link)
    });
    let quit = pool.in_place_scope(|scope| -> Result<bool, DistributedError> {
        // However this thread leaves the scope, the renderers stop: the scope waits for them.
        let _close = CloseOnDrop(&queue);
        for _ in 0..threads {
            let (queue, renderer, wake_tx) = (&queue, &renderer, wake_tx.clone());
            let (rendering_ns, rendering_cpu_ns) = (&rendering_ns, &rendering_cpu_ns);
            scope.spawn(move |_| {
                while let Some((unit, others_wait)) = queue.pop() {
                    let mut pixels = Vec::new();
                    let (started, cpu_started) = (Instant::now(), thread_cpu_time());
                    // With other units to render meanwhile, a tile asks ahead for what it reaches
                    // and goes on; if it missed something, it is set aside and rendered again
                    // once the answers are here. Lattices never are: their reports count every
                    // ray they trace.
                    let ahead = others_wait
                        && unit.lattice.is_none()
                        && unit.set_aside < MAX_SET_ASIDE
                        && link.is_some_and(FetchLink::may_ask_ahead);
                    let set_aside = if ahead {
                        ask_ahead::without_waiting(|| renderer.render(unit, &mut pixels)).1
                    } else {
                        renderer.render(unit, &mut pixels);
                        false
                    };
                    let took = started.elapsed();
                    rendering_ns.fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
                    if let (Some(from), Some(to)) = (cpu_started, thread_cpu_time()) {
                        rendering_cpu_ns.fetch_add(to.saturating_sub(from).as_nanos() as u64, Ordering::Relaxed);
                    }
                    if set_aside {
                        if let Some(link) = link {
                            link.note_set_aside();
                        }
                        queue.put_back(QueuedUnit { set_aside: unit.set_aside + 1, ..unit });
                        continue;
                    }
                    let micros = u32::try_from(took.as_micros()).unwrap_or(u32::MAX);
                    if queue.finish(unit.index, micros, pixels) && wake_tx.send(()).is_err() {
                        break;
                    }
                }
            });
        }
        give(first.0, first.1, &mut outstanding)?;
        // More units, or units to leave out; returns whether they are the last.
        let assigned = |m: Message, outstanding: &mut usize| -> Result<bool, DistributedError> {
            let Message::Assign { units, lattices, last, dropped, .. } = m else { return Ok(false) };
            give(units, lattices, outstanding)?;
            *outstanding -= queue.leave_out(&dropped);
            Ok(last)
        };
        for m in early {
            last |= assigned(m, &mut outstanding)?;
        }
        let mut starved = false;
        let mut last_send = Instant::now();
        loop {
            let units = queue.take_finished();
            if !units.is_empty() {
                outstanding -= units.len();
                let starved = std::mem::take(&mut starved);
                transport.send(0, Message::Rendered { frame, units, starved }.encode())?;
                last_send = Instant::now();
            }
            while let Some((rank, bytes)) = transport.try_recv()? {
                match decode_given_back(transport, rank, bytes)? {
                    m @ Message::Assign { frame: f, .. } if f == frame => last |= assigned(m, &mut outstanding)?,
                    // Units of a frame before, which another worker delivered first.
                    Message::Assign { frame: f, units, .. } if f < frame && units.is_empty() => {}
                    Message::Data { frame: f, meshes, parts, textures } if f == frame => {
                        if let Some(link) = link {
                            link.count_texture_answers(&textures);
                        }
                        pending.answer(meshes, parts, textures)
                    }
                    Message::Quit => return Ok(true),
                    _ => return Err(out_of_place(transport)),
                }
            }
            if let Some(link) = link {
                let asked = pending.take(link);
                if !asked.is_empty() {
                    transport.send(0, asked.message(frame).encode())?;
                }
            }
            // Answers to what was asked ahead for come in the frame, even where another worker
            // delivered the unit that asked first.
            if last && outstanding == 0 && pending.is_empty() {
                return Ok(false);
            }
            // Every unit given is finished and sent back, and the master has not yet answered.
            starved |= !last && outstanding == 0;
            let busy = pending.is_empty() && !queue.running_low();
            let all_fetching = link.is_some_and(|l| l.threads_waiting() >= threads);
            if all_fetching || (!busy && last_send.elapsed() < SPIN_AFTER_SEND && transport.sending()) {
                // Every render thread waits for a fetch: a nap would add to their wait, and the
                // cores they leave idle have nothing else to do. Just after a send the master may
                // be waiting on this side to move it along (MPI's large messages) and its answer
                // is on its way. Either way the poll comes again at once, yielding in between.
                std::thread::yield_now();
            } else {
                // Drained first: wake-ups that came while this thread was awake are for what it
                // takes next, which the checks below see.
                while wake_rx.try_recv().is_ok() {}
                if queue.has_none_finished() && !link.is_some_and(FetchLink::has_requests) {
                    let _ = wake_rx.recv_timeout(if busy { BUSY_POLL } else { POLL });
                }
            }
        }
    })?;
    if quit {
        return Ok(true);
    }
    if let Some(link) = link {
        take_unclaimed(world, link);
    }
    let mut counts = super::master::counts_of(&renderer.report(start));
    counts.texture_warnings = world
        .textures
        .take_warnings()
        .into_iter()
        .map(|w| (w.name, w.path.map(|p| p.display().to_string()).unwrap_or_default(), w.reason))
        .collect();
    let mut failure = None;
    if let Some(link) = link {
        let fetched = link.take_frame();
        failure = fetched.failure;
        (counts.fetched_objects, counts.fetched_bytes) = (fetched.objects, fetched.object_bytes);
        (counts.fetched_parts, counts.fetched_part_bytes) = (fetched.parts, fetched.part_bytes);
        (counts.fetched_textures, counts.fetched_texture_levels, counts.fetched_texture_bytes) =
            (fetched.textures, fetched.texture_levels, fetched.texture_bytes);
        counts.fetched_texture_tiles = fetched.texture_tiles;
        (counts.evicted_objects, counts.evicted_parts) = (fetched.evicted, fetched.evicted_parts);
        counts.kept_objects = fetched.kept;
        counts.kept_textures = fetched.kept_textures;
        counts.fetch_wait_ns = fetched.waiting.as_nanos() as u64;
        counts.fetch_build_ns = fetched.building.as_nanos() as u64;
        counts.set_aside = fetched.set_aside;
        let remote = || world.scene.objects().iter().filter(|o| o.is_remote());
        counts.resident_objects = remote().filter(|o| o.is_resident()).count() as u64;
        counts.resident_parts = remote().map(|o| o.resident_parts() as u64).sum();
        let this_frame = Some(link.frame_number());
        counts.reached_objects = remote().filter(|o| o.last_used() == this_frame).count() as u64;
    }
    counts.world_ns = built_in.as_nanos() as u64;
    counts.rendering_ns = rendering_ns.into_inner();
    counts.rendering_cpu_ns = rendering_cpu_ns.into_inner();
    counts.share_ns = start.elapsed().as_nanos() as u64;
    transport.send(0, Message::FrameDone { frame, counts, failure }.encode())?;
    Ok(false)
}

/// The CPU time of the calling thread, where the system tells it (a unit's wall time less its CPU
/// time is time its thread waited: for a fetch, or for a core another thread or process held).
fn thread_cpu_time() -> Option<std::time::Duration> {
    #[cfg(unix)]
    {
        let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: `t` is a valid `timespec` for the call to write.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
        ok.then(|| std::time::Duration::new(t.tv_sec as u64, t.tv_nsec as u32))
    }
    #[cfg(not(unix))]
    None
}

/// A worker's share of a frame as the frame's message starts it: the frame, its job, the units
/// it was given first, whether they are the last, and how long bringing the world to the frame
/// took.
struct Share {
    frame: u64,
    job: Job,
    first: (Vec<u32>, Vec<LatticeUnit>),
    last: bool,
    /// The frame's assignments that came while the world was built.
    early: Vec<Message>,
    built_in: std::time::Duration,
}

/// Makes ready the objects and parts of objects whose answers came for units that asked ahead
/// and then went to other workers: they came, so they count as fetched, and rays of frames to
/// come are likely to reach them.
fn take_unclaimed(world: &World, link: &FetchLink) {
    let unclaimed = link.unclaimed();
    if unclaimed.is_empty() {
        return;
    }
    let objects = world.scene.objects();
    let by_key: HashMap<u32, &crate::accel::object::Object> =
        objects.iter().filter_map(|o| Some((o.remote_key()?, o))).collect();
    for (key, part) in unclaimed {
        let Some(object) = by_key.get(&key) else { continue };
        let data = object.data();
        if let (Some(p), Some(parts)) = (part, data.bvh.parts.as_deref()) {
            if (p as usize) < parts.parts.len() {
                object.part(parts, p);
            }
        }
    }
}

/// How many times a unit may be set aside for what it asked ahead for; after that it waits.
/// Each time it renders again with what it missed, and may reach more it does not hold (what
/// lay behind what it missed).
const MAX_SET_ASIDE: u8 = 2;
/// How long the worker's talking thread naps between polls when something is urgent (a renderer
/// runs low on units or waits for a fetch).
const POLL: std::time::Duration = std::time::Duration::from_micros(100);
/// How long it naps otherwise: a bound on how late finished units go out and the master's
/// messages are read when every renderer has work waiting.
const BUSY_POLL: std::time::Duration = std::time::Duration::from_millis(1);
/// How long after sending finished units the talking thread keeps polling instead of napping,
/// when something is urgent.
const SPIN_AFTER_SEND: std::time::Duration = std::time::Duration::from_micros(50);

/// Stops a fetch link waking a frame's talking thread once the frame is over.
struct ClearWakerOnDrop<'a>(&'a FetchLink);

impl Drop for ClearWakerOnDrop<'_> {
    fn drop(&mut self) {
        self.0.set_waker(None);
    }
}

/// The units a worker's renderers take, until it is closed, and the units they have finished.
struct UnitQueue {
    state: Mutex<QueueState>,
    ready: Condvar,
    /// The renderers: fewer units waiting than this is running low.
    threads: usize,
}

#[derive(Default)]
struct QueueState {
    waiting: VecDeque<QueuedUnit>,
    closed: bool,
    /// Finished units, with their render times in microseconds and their encoded pixels, not yet
    /// taken to be sent.
    finished: Vec<(u32, u32, Vec<u8>)>,
}

impl UnitQueue {
    fn new(threads: usize) -> UnitQueue {
        UnitQueue { state: Mutex::default(), ready: Condvar::new(), threads: threads.max(1) }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, QueueState> {
        self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Whether fewer units wait than there are renderers: some may soon have nothing to do.
    fn running_low(&self) -> bool {
        self.lock().waiting.len() < self.threads
    }

    fn push(&self, units: Vec<QueuedUnit>) {
        self.lock().waiting.extend(units);
        self.ready.notify_all();
    }

    /// Takes out the units of `dropped` that wait (none has started them); returns how many.
    fn leave_out(&self, dropped: &[u32]) -> usize {
        if dropped.is_empty() {
            return 0;
        }
        let mut state = self.lock();
        let before = state.waiting.len();
        state.waiting.retain(|u| !dropped.contains(&u.index));
        before - state.waiting.len()
    }

    /// The next unit and whether others wait behind it, waiting for one; `None` once the queue
    /// is closed.
    fn pop(&self) -> Option<(QueuedUnit, bool)> {
        let mut state = self.lock();
        loop {
            if state.closed {
                return None;
            }
            if let Some(t) = state.waiting.pop_front() {
                return Some((t, !state.waiting.is_empty()));
            }
            state = self.ready.wait(state).unwrap_or_else(std::sync::PoisonError::into_inner);
        }
    }

    /// Puts a unit set aside behind those waiting.
    fn put_back(&self, unit: QueuedUnit) {
        self.lock().waiting.push_back(unit);
        self.ready.notify_one();
    }

    /// Hands in a finished unit; returns whether the talking thread should wake for it now
    /// (the renderers are running low).
    fn finish(&self, unit: u32, micros: u32, pixels: Vec<u8>) -> bool {
        let mut state = self.lock();
        state.finished.push((unit, micros, pixels));
        state.waiting.len() < self.threads
    }

    /// The finished units not yet taken.
    fn take_finished(&self) -> Vec<(u32, u32, Vec<u8>)> {
        std::mem::take(&mut self.lock().finished)
    }

    /// Whether no finished unit waits to be taken: a wake-up drained before may have been for
    /// one.
    fn has_none_finished(&self) -> bool {
        self.lock().finished.is_empty()
    }

    fn close(&self) {
        let mut state = self.lock();
        state.waiting.clear();
        state.closed = true;
        drop(state);
        self.ready.notify_all();
    }
}

struct CloseOnDrop<'a>(&'a UnitQueue);

impl Drop for CloseOnDrop<'_> {
    fn drop(&mut self) {
        self.0.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A thread's CPU clock runs while it computes and stands while it sleeps.
    #[test]
    #[cfg(unix)]
    fn the_thread_cpu_clock_counts_computing_not_sleeping() {
        let Some(start) = thread_cpu_time() else { panic!("no thread CPU clock on a unix system") };
        std::thread::sleep(Duration::from_millis(60));
        let slept = thread_cpu_time().expect("a clock").saturating_sub(start);
        let busy_from = (Instant::now(), thread_cpu_time().expect("a clock"));
        let mut x = 1u64;
        while busy_from.0.elapsed() < Duration::from_millis(60) {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let busy = thread_cpu_time().expect("a clock").saturating_sub(busy_from.1);
        assert!(slept < Duration::from_millis(20), "asleep for 60 ms, the clock moved {slept:?}");
        // Even on a loaded machine a thread that spins for 60 ms gets some of it.
        assert!(busy > Duration::from_millis(5) && busy > 3 * slept, "busy {busy:?}, asleep {slept:?}");
    }
}

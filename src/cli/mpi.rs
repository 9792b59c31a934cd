//! `--mpi`: the subcommands that render over the ranks of an `mpirun` job. Rank 0 is the master
//! (it loads the scene, prints and writes what a single process would); every other rank starts
//! with an empty scene, is sent the master's, and serves it as a worker
//! (`rtsl_runtime::distributed`).

use rtsl_runtime::accel::parts::{PARTED_ABOVE, PART_TRIANGLES};
use rtsl_runtime::distributed::{
    serve, Demand, Master, ReplicaScene, TileQuarters, Traffic, Transport, WorkerTime, DEFAULT_MESH_CACHE_BYTES,
};
use rtsl_runtime::render::World;
use rtsl_runtime::texture::TILED_FROM_BYTES;

/// This process's rank of the `mpirun` job.
#[cfg(feature = "mpi")]
pub(crate) fn transport() -> anyhow::Result<Box<dyn Transport>> {
    crate::no_transparent_huge_pages();
    Ok(Box::new(rtsl_runtime::distributed::mpi::MpiTransport::init()?))
}

#[cfg(not(feature = "mpi"))]
pub(crate) fn transport() -> anyhow::Result<Box<dyn Transport>> {
    anyhow::bail!(
        "--mpi: this rtsl was built without MPI; build it with `cargo build --release --features mpi` \
         (which needs Open MPI: `apt-get install libopenmpi-dev openmpi-bin libclang-dev`) and run it under mpirun"
    )
}

/// The settings of a subcommand run with `--mpi` for how the workers fetch and keep the scene.
#[derive(clap::Args, Debug, Clone)]
pub struct WorkerArgs {
    /// With --mpi: the most megabytes of fetched meshes and their BVHs a worker keeps between
    /// frames; the meshes rays reached least recently go first, fetched again when next needed.
    #[arg(long, value_name = "MB", default_value_t = DEFAULT_MESH_CACHE_BYTES >> 20)]
    pub mesh_cache_mb: usize,
    /// With --mpi: objects of more triangles travel to the workers in parts, their BVHs fetched
    /// subtree by subtree as rays reach them (parts of at most 16384 triangles).
    #[arg(long, value_name = "TRIANGLES", default_value_t = PARTED_ABOVE)]
    pub parts_above: usize,
    /// With --mpi: textures of at least this many megabytes (as given, as they travel) travel to the
    /// workers in tiles of their large mip levels, fetched as lookups reach them; a worker reads
    /// such levels more slowly than whole ones.
    #[arg(long, value_name = "MB", default_value_t = TILED_FROM_BYTES >> 20)]
    pub tile_textures_from_mb: usize,
    /// With --mpi: give no worker copies of the tiles others hold once every tile is handed out
    /// (to compare; by default a worker with nothing left to do renders them too, and the first
    /// copy delivered is taken).
    #[arg(long)]
    pub no_tile_copies: bool,
    /// With --mpi: hand out every tile whole (to compare; by default the last eighth of a frame's
    /// tiles go out in quarters, so that no worker finishes long after the others on one
    /// expensive tile).
    #[arg(long)]
    pub no_tile_quarters: bool,
    /// With --mpi: the master polls for its workers' messages without napping between polls,
    /// for a master with a core of its own (by default it naps, leaving the core to workers).
    #[arg(long)]
    pub master_spins: bool,
    /// With --mpi: a worker's render threads wait for each mesh a tile reaches that the worker
    /// does not hold (to compare; by default a tile asks for all it reaches and is set aside,
    /// rendered again once they are here, while the thread renders other tiles).
    #[arg(long)]
    pub no_asking_ahead: bool,
    /// With --mpi: whether meshes, their BVHs and textures travel to the workers deflated:
    /// `auto` when some rank runs on another machine (ranks of one machine copy them through
    /// shared memory, faster than deflating and inflating them), or `always`, or `never`.
    #[arg(long, value_enum, default_value_t = Deflate::Auto)]
    pub deflate: Deflate,
}

/// When meshes, their BVHs and textures travel deflated (`--deflate`).
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Deflate {
    /// When some rank runs on another machine than the master.
    Auto,
    Always,
    Never,
}

impl WorkerArgs {
    /// Gives `master` these settings.
    pub(crate) fn apply<T: Transport>(&self, master: &mut Master<T>) {
        master.set_parts(self.parts_above, PART_TRIANGLES);
        master.set_texture_tiles_from(self.tile_textures_from_mb.saturating_mul(1 << 20));
        master.set_tile_copies(!self.no_tile_copies);
        master.set_tile_quarters(if self.no_tile_quarters { TileQuarters::Never } else { TileQuarters::AtTheEnd });
        master.set_spinning(self.master_spins);
        match self.deflate {
            Deflate::Auto => {}
            Deflate::Always => master.set_deflate(true),
            Deflate::Never => master.set_deflate(false),
        }
    }
}

/// Serves the master as a worker: a copy of the master's scene, sent to it frame by frame.
pub(crate) fn work(
    transport: &dyn Transport,
    pool: &rayon::ThreadPool,
    args: &WorkerArgs,
) -> anyhow::Result<std::process::ExitCode> {
    let limit = args.mesh_cache_mb.saturating_mul(1 << 20);
    serve(transport, Ok(&mut ReplicaScene::with_cache_limit(limit).asking_ahead(!args.no_asking_ahead)), pool)?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// "MPI traffic per frame: ..." of a frame's (or the mean frame's) traffic.
pub(crate) fn traffic_line(t: &Traffic) -> String {
    let kb = |b: u64| b as f64 / 1e3;
    format!(
        "MPI traffic per frame: {:.1} kB: pixels {:.1} kB, updates {:.2} kB, fetches (meshes, textures) {:.1} kB, light paths {:.1} kB, tile assignments {:.1} kB, counters {:.2} kB",
        kb(t.total()),
        kb(t.pixels),
        kb(t.updates),
        kb(t.fetches),
        kb(t.light_paths),
        kb(t.control),
        kb(t.counters)
    )
}

/// "worker time per frame of `frames`: ..." of the mean of `times` (one a frame): where a frame's
/// time went on the workers, on average over them.
pub(crate) fn worker_time_line(frames: &str, times: &[WorkerTime]) -> String {
    let n = times.len().max(1) as f64;
    let ms =
        |f: fn(&WorkerTime) -> std::time::Duration| times.iter().map(|t| f(t).as_secs_f64()).sum::<f64>() * 1e3 / n;
    let mean = |f: fn(&WorkerTime) -> u64| times.iter().map(|t| f(t) as f64).sum::<f64>() / n;
    format!(
        "worker time per frame of {frames} (mean over workers): world {:.2} ms, rendering {:.1} ms (of which off the core {:.1}, waiting for fetches {:.1}, decoding fetched meshes and building their BVHs {:.1}), waiting {:.1} ms (for tiles, a core), outside their share {:.1} ms (waiting for the last worker {:.1}; the master preparing the frame and assembling the image), of a {:.1} ms frame; tiles handed out in quarters {:.1} a frame; tiles copied to idle workers at the frame's end {:.1} a frame ({:.1} delivered first by the copy, {:.1} rendered twice); tiles set aside while what they reached was fetched {:.1} a frame",

        ms(|t| t.world),
        ms(|t| t.rendering),
        ms(|t| t.off_core),
        ms(|t| t.fetching),
        ms(|t| t.loading),
        ms(|t| t.waiting),
        ms(|t| t.outside),
        ms(|t| t.after_done),
        ms(|t| t.frame),
        mean(|t| t.helping.quartered),
        mean(|t| t.helping.copies),
        mean(|t| t.helping.helped),
        mean(|t| t.helping.twice),
        mean(|t| t.set_aside),
    )
}

/// A frame's line on its workers, for the per-frame lines: what they fetched, and what waiting
/// for it and decoding it cost them, against the time they rendered.
pub(crate) fn frame_workers_line(w: &WorkerTime, d: &Demand, workers: usize) -> String {
    let ms = |t: std::time::Duration| t.as_secs_f64() * 1e3;
    let each = |n: u64| n as f64 / workers.max(1) as f64;
    format!(
        "workers: rendering {:.1} ms (fetch waits {:.1}, decoding {:.1}, off the core {:.1}), waiting for the last {:.1} ms; fetched a worker: {:.1} objects {:.1} kB, {:.1} parts, {:.1} textures {:.1} levels {:.1} tiles {:.1} kB; {} tiles set aside",
        ms(w.rendering),
        ms(w.fetching),
        ms(w.loading),
        ms(w.off_core),
        ms(w.after_done),
        each(d.fetched_objects),
        each(d.fetched_bytes) / 1e3,
        each(d.fetched_parts),
        each(d.fetched_textures),
        each(d.fetched_texture_levels),
        each(d.fetched_texture_tiles),
        each(d.fetched_texture_bytes) / 1e3,
        w.set_aside,
    )
}

/// The objects of `world`'s scene and the bytes of their meshes as they travel (the master holds
/// them all).
pub(crate) fn scene_meshes(world: &World) -> (usize, usize) {
    let scene = &world.scene;
    let bytes = (0..scene.object_count() as u32)
        .filter_map(|i| scene.mesh(rtsl_runtime::scene::ObjectId(i)))
        .map(|m| rtsl_runtime::api::encode_mesh(m).len())
        .sum();
    (scene.object_count(), bytes)
}

/// What the workers fetched over one or more frames.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Fetched {
    objects: u64,
    object_bytes: u64,
    /// Parts of large objects' BVHs, and their bytes.
    parts: u64,
    part_bytes: u64,
    textures: u64,
    texture_levels: u64,
    texture_tiles: u64,
    texture_bytes: u64,
    /// Objects the workers' rays reached, each counted by every worker and frame that reached it.
    reached: u64,
}

impl From<&Demand> for Fetched {
    fn from(d: &Demand) -> Fetched {
        Fetched {
            objects: d.fetched_objects,
            object_bytes: d.fetched_bytes,
            parts: d.fetched_parts,
            part_bytes: d.fetched_part_bytes,
            textures: d.fetched_textures,
            texture_levels: d.fetched_texture_levels,
            texture_tiles: d.fetched_texture_tiles,
            texture_bytes: d.fetched_texture_bytes,
            reached: d.reached_objects,
        }
    }
}

impl std::ops::Add for Fetched {
    type Output = Fetched;
    fn add(self, o: Fetched) -> Fetched {
        Fetched {
            objects: self.objects + o.objects,
            object_bytes: self.object_bytes + o.object_bytes,
            parts: self.parts + o.parts,
            part_bytes: self.part_bytes + o.part_bytes,
            textures: self.textures + o.textures,
            texture_levels: self.texture_levels + o.texture_levels,
            texture_tiles: self.texture_tiles + o.texture_tiles,
            texture_bytes: self.texture_bytes + o.texture_bytes,
            reached: self.reached + o.reached,
        }
    }
}

/// "demand loading: ..." of what the workers fetched (over one or more frames) against the
/// scene's objects and mesh bytes, and what they hold (`held`, the last frame's).
pub(crate) fn demand_line(
    what: &str,
    fetched: Fetched,
    scene: (usize, usize),
    held: &Demand,
    workers: usize,
) -> String {
    let mb = |b: f64| b / 1e6;
    let geometry_bytes = (fetched.object_bytes + fetched.part_bytes) as f64;
    // Of the objects rays reached (per worker and frame), those a worker held already.
    let over_frames =
        Demand { fetched_objects: fetched.objects, reached_objects: fetched.reached, ..Demand::default() };
    let hit_rate = match over_frames.hit_rate() {
        None => "no object reached".to_string(),
        Some(rate) => format!("{:.1}% of the {} objects rays reached were held", 100.0 * rate, fetched.reached),
    };
    // A new scene's objects whose meshes the workers held from the scene before.
    let kept = match (held.kept_objects, held.kept_textures) {
        (0, 0) => String::new(),
        (objects, textures) => format!(
            "; taken from the scene before in the last frame: {objects} object(s), not fetched, and {textures} texture(s) with the levels they held"
        ),
    };
    format!(
        "demand loading, {what}: {} object(s) and {} BVH part(s), {:.2} MB fetched by {workers} worker(s) ({:.2} MB per worker) of the scene's {} object(s) and {:.2} MB of meshes; {} texture(s), {} mip level(s) and {} tile(s) of levels, {:.2} MB; cache hits: {hit_rate}; held now: at most {} object(s) per worker ({} object(s) and {} BVH part(s) evicted before the last frame){kept}",
        fetched.objects,
        fetched.parts,
        mb(geometry_bytes),
        mb(geometry_bytes / workers.max(1) as f64),
        scene.0,
        mb(scene.1 as f64),
        fetched.textures,
        fetched.texture_levels,
        fetched.texture_tiles,
        mb(fetched.texture_bytes as f64),
        held.most_resident_objects,
        held.evicted_objects,
        held.evicted_parts
    )
}

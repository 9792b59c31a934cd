//! The library side of `rtsl bench trace`: load a mesh, build its BVH, trace one primary ray per
//! pixel and one shadow ray per hit towards a point light, with packet and with single-ray
//! traversal, and report timings. Prints nothing; the CLI formats the [`BenchReport`].
//!
//! Invariants: every figure except the timings is independent of the thread count (tiles are
//! summed in tile order). The passes keep what Embree's side of the comparison keeps
//! (`shared/bench/embree/embree_bench.cpp`): each pixel's hit distance, and shadow rays made from
//! it as they are traced, by the same operations ([`ShadowView::ray`]), so that both tracers
//! trace the same rays and their harnesses move as much memory.

use glam::Vec3A;
use rtsl_runtime::accel::bvh4::BuildQuality;
use rtsl_runtime::camera::{packet_lane_offset, Camera, PACKET_SIDE};
use rtsl_runtime::mesh_io::{load_mesh, MeshIoError};
use rtsl_runtime::ray::{Hit, HitPacket, Ray, RayPacket, PACKET_SIZE};
use rtsl_runtime::scene::{scene_from_mesh, Scene};
use rtsl_runtime::tiles::{render_tiles, Tile};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// Tile side in pixels (a multiple of the packet side).
const TILE: u32 = 32;

/// What to benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// The OBJ or PLY mesh.
    pub mesh: PathBuf,
    /// Camera position.
    pub eye: Vec3A,
    /// Point looked at.
    pub look: Vec3A,
    /// Up vector.
    pub up: Vec3A,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
    /// Point light position.
    pub light: Vec3A,
    /// The scene's scale: shadow rays start and stop this times `1e-5` from their ends, as
    /// Embree's harness does with the scale its scene files give (300 for the benchmark scenes).
    pub scene_scale: f32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Worker threads (0: rayon's default).
    pub threads: usize,
    /// Timed repetitions of each pass (the median is reported).
    pub repeats: usize,
    /// BVH build quality.
    pub quality: BuildQuality,
    /// Which passes to time: primary packet, primary single, shadow packet, shadow single. Passes
    /// left out report 0 Mrays/s (the primary packet pass still runs once, untimed, for the shadow
    /// rays), and their results are not compared.
    pub passes: [bool; 4],
}

impl BenchOptions {
    /// The benchmark view of `shared/bench/README.md` for `mesh`.
    pub fn new(mesh: impl Into<PathBuf>) -> Self {
        BenchOptions {
            mesh: mesh.into(),
            eye: Vec3A::new(0.0, 130.0, -170.0),
            look: Vec3A::new(0.0, 0.0, -53.0),
            up: Vec3A::Y,
            fov_deg: 45.0,
            light: Vec3A::new(60.0, 220.0, 40.0),
            scene_scale: 300.0,
            width: 1024,
            height: 768,
            threads: 1,
            repeats: 5,
            quality: BuildQuality::High,
            passes: [true; 4],
        }
    }
}

/// Benchmark results.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchReport {
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Time to load the file, ms.
    pub load_ms: f64,
    /// BVH build time, ms (median of up to 3 builds, after the warm-up builds).
    pub build_ms: f64,
    /// Pages the kernel faulted in during each timed build (fresh memory: a build that reuses
    /// freed memory faults none), where the system counts them.
    pub build_page_faults: Option<Vec<u64>>,
    /// The untimed builds after the first that still faulted in fresh pages: each one's time (ms)
    /// and page faults.
    pub warmup_builds: Vec<(f64, u64)>,
    /// Mesh plus BVH memory, bytes.
    pub memory_bytes: usize,
    /// Primary rays traced (pixels).
    pub primary_rays: usize,
    /// Primary rays that hit.
    pub hits: usize,
    /// Sum of the hit distances.
    pub hit_distance_sum: f64,
    /// Shadow rays that found an occluder.
    pub occluded: usize,
    /// Pixels where packet and single-ray traversal disagree: one hits and the other misses, their
    /// hits lie at different distances, or one finds the shadow ray blocked and the other not.
    /// Hits at the same distance on different triangles (a shared edge) are ties that either
    /// traversal may report.
    pub mismatches: usize,
    /// Primary rays, packet traversal, million rays per second.
    pub primary_packet_mrays: f64,
    /// Primary rays, single-ray traversal.
    pub primary_single_mrays: f64,
    /// Shadow rays, packet traversal.
    pub shadow_packet_mrays: f64,
    /// Shadow rays, single-ray traversal.
    pub shadow_single_mrays: f64,
    /// Threads used.
    pub threads: usize,
}

/// A failure of the benchmark.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The mesh could not be loaded.
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    /// The thread pool could not be created.
    #[error("cannot start {threads} threads: {message}")]
    Threads {
        /// Threads asked for.
        threads: usize,
        /// The cause.
        message: String,
    },
    /// The image has no pixels.
    #[error("the image size must be at least 1x1")]
    EmptyImage,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the benchmark.
pub fn run_bench(opts: &BenchOptions) -> Result<BenchReport, BenchError> {
    if opts.width == 0 || opts.height == 0 {
        return Err(BenchError::EmptyImage);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .map_err(|e| BenchError::Threads { threads: opts.threads, message: e.to_string() })?;
    let t0 = Instant::now();
    let mesh = load_mesh(&opts.mesh)?;
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    let triangles = mesh.triangle_count();
    pool.install(|| {
        // Timed as a rebuild in a running program is: once the allocator holds the memory a build
        // needs. One untimed build starts the thread pool; on several threads the memory a build
        // freed is not always what the allocator hands the next one (each thread keeps its own
        // pages), so untimed builds go on while they still fault in fresh pages, up to
        // `MAX_WARMUP_BUILDS`. Each timed build comes after the last one's scene is dropped.
        let mut scene = scene_from_mesh(mesh.clone(), opts.quality);
        let mut warmup = Vec::new();
        let mut builds = Vec::new();
        let mut faults = Vec::new();
        while builds.len() < opts.repeats.clamp(1, 3) {
            let m = mesh.clone();
            drop(scene);
            let before = minor_page_faults();
            let t = Instant::now();
            scene = scene_from_mesh(m, opts.quality);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let fresh = before.zip(minor_page_faults()).map(|(b, a)| a.saturating_sub(b));
            if builds.is_empty() && fresh.is_some_and(|f| f > 0) && warmup.len() < MAX_WARMUP_BUILDS {
                warmup.push((ms, fresh.unwrap_or(0)));
                continue;
            }
            builds.push(ms);
            faults.push(fresh);
        }
        let mut report = trace_all(opts, &scene, triangles, load_ms, median(builds));
        report.build_page_faults = faults.into_iter().collect();
        report.warmup_builds = warmup;
        Ok(report)
    })
}

/// The most untimed builds that may precede the timed ones while they still fault in fresh pages
/// (see [`run_bench`]).
pub const MAX_WARMUP_BUILDS: usize = 4;

/// The page faults this process has taken that needed no disk (the kernel handing out and
/// zeroing fresh pages), where the system counts them.
fn minor_page_faults() -> Option<u64> {
    #[cfg(unix)]
    {
        let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
        // SAFETY: `getrusage` writes the struct it is given, which is large enough.
        let ok = unsafe { libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) } == 0;
        // SAFETY: zeroed is a valid `rusage`, and a successful call filled it in.
        ok.then(|| unsafe { usage.assume_init() }.ru_minflt as u64)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The hit distance of each pixel of one tile, row-major within the tile (infinity where the
/// primary ray missed): what Embree's harness keeps of a hit.
type TileDistances = Vec<f32>;

/// A hit's distance, infinity for a miss.
#[inline(always)]
fn distance(h: &Hit) -> f32 {
    if h.is_hit() {
        h.t
    } else {
        f32::INFINITY
    }
}

/// One output buffer per tile, reused by every repeat of a pass: the timed passes then measure
/// tracing, not the kernel handing out and zeroing fresh pages for each repeat's results (an
/// image's worth of hits is about 4,000 pages). Each buffer's lock and header have cache lines
/// of their own: neighbouring tiles go to different threads, and a push writes its buffer's
/// length once per ray, which would otherwise move the line between their cores every time.
struct TileBuffers<T>(Vec<OwnLines<Mutex<Vec<T>>>>);

/// A value alone on its cache lines (two, as Intel's adjacent-line prefetcher pairs them).
#[repr(align(128))]
struct OwnLines<T>(T);

impl<T: Clone + Send> TileBuffers<T> {
    fn new(tiles: usize) -> Self {
        TileBuffers((0..tiles).map(|_| OwnLines(Mutex::new(Vec::new()))).collect())
    }

    /// Runs `f` on every tile with that tile's buffer (emptied first).
    fn fill(&self, w: u32, h: u32, f: impl Fn(&Tile, &mut Vec<T>) + Sync) {
        render_tiles(w, h, TILE, |t| {
            // Each tile's lock is taken by one worker only; a poisoned one still holds a buffer.
            let mut out = self.0[t.index].0.lock().unwrap_or_else(|e| e.into_inner());
            out.clear();
            f(t, &mut out);
        });
    }

    fn into_vecs(self) -> Vec<Vec<T>> {
        self.0.into_iter().map(|m| m.0.into_inner().unwrap_or_else(|e| e.into_inner())).collect()
    }
}

/// The lane of each pixel of an 8x8 packet, row by row (the inverse of [`packet_lane_offset`]).
static LANES_BY_ROW: std::sync::LazyLock<[[u8; PACKET_SIDE as usize]; PACKET_SIDE as usize]> =
    std::sync::LazyLock::new(|| {
        let mut t = [[0u8; PACKET_SIDE as usize]; PACKET_SIDE as usize];
        for i in 0..PACKET_SIZE {
            let (dx, dy) = packet_lane_offset(i);
            t[dy as usize][dx as usize] = i as u8;
        }
        t
    });

fn primary_packets(scene: &Scene, cam: &Camera, tile: &Tile, out: &mut TileDistances) {
    out.resize((tile.width * tile.height) as usize, f32::INFINITY);
    let mut hp = HitPacket::default();
    for by in (0..tile.height).step_by(PACKET_SIDE as usize) {
        for bx in (0..tile.width).step_by(PACKET_SIDE as usize) {
            let p = cam.packet(tile.x0 + bx, tile.y0 + by);
            scene.intersect_packet(&p, &mut hp);
            if p.active == u64::MAX && bx + PACKET_SIDE <= tile.width && by + PACKET_SIDE <= tile.height {
                // A whole packet inside the tile: row by row.
                for (r, lanes) in LANES_BY_ROW.iter().enumerate() {
                    let at = ((by + r as u32) * tile.width + bx) as usize;
                    for (dst, &i) in out[at..at + lanes.len()].iter_mut().zip(lanes) {
                        *dst = distance(&hp.get(i as usize));
                    }
                }
                continue;
            }
            for i in 0..PACKET_SIZE {
                let (dx, dy) = packet_lane_offset(i);
                let (x, y) = (bx + dx, by + dy);
                if p.active >> i & 1 != 0 && x < tile.width && y < tile.height {
                    out[(y * tile.width + x) as usize] = distance(&hp.get(i));
                }
            }
        }
    }
}

fn primary_single(scene: &Scene, cam: &Camera, tile: &Tile, out: &mut TileDistances) {
    for y in 0..tile.height {
        for x in 0..tile.width {
            out.push(distance(&scene.intersect(&cam.ray(tile.x0 + x, tile.y0 + y))));
        }
    }
}

/// How the shadow passes make their rays: as Embree's harness does (`shadow_ray`), from the
/// primary hit at distance `t` along pixel `(x, y)`'s ray, towards the light, unit length, over
/// `(eps, distance - eps)`.
struct ShadowView<'a> {
    cam: &'a Camera,
    light: Vec3A,
    eps: f32,
}

impl ShadowView<'_> {
    #[inline(always)]
    fn ray(&self, x: u32, y: u32, t: f32) -> Ray {
        let o = self.cam.eye() + self.cam.ray(x, y).direction * t;
        let l = self.light - o;
        let dist = ((l.x * l.x + l.y * l.y) + l.z * l.z).sqrt();
        Ray::segment(o, l * (1.0 / dist), self.eps, dist - self.eps)
    }
}

fn shadow_packets(scene: &Scene, view: &ShadowView, tile: &Tile, dists: &TileDistances, out: &mut Vec<bool>) {
    out.resize(dists.len(), false);
    for by in (0..tile.height).step_by(PACKET_SIDE as usize) {
        for bx in (0..tile.width).step_by(PACKET_SIDE as usize) {
            let mut p = RayPacket::new();
            for i in 0..PACKET_SIZE {
                let (dx, dy) = packet_lane_offset(i);
                let (x, y) = (bx + dx, by + dy);
                if x < tile.width && y < tile.height {
                    let t = dists[(y * tile.width + x) as usize];
                    if t.is_finite() {
                        p.set(i, &view.ray(tile.x0 + x, tile.y0 + y, t));
                    }
                }
            }
            let occ = scene.occluded_packet(&p);
            for i in (0..PACKET_SIZE).filter(|i| p.active >> i & 1 != 0) {
                let (dx, dy) = packet_lane_offset(i);
                out[((by + dy) * tile.width + bx + dx) as usize] = occ >> i & 1 != 0;
            }
        }
    }
}

fn shadow_single(scene: &Scene, view: &ShadowView, tile: &Tile, dists: &TileDistances, out: &mut Vec<bool>) {
    out.extend(dists.iter().enumerate().map(|(k, &t)| {
        let (x, y) = (k as u32 % tile.width, k as u32 / tile.width);
        t.is_finite() && scene.occluded(&view.ray(tile.x0 + x, tile.y0 + y, t))
    }));
}

/// The median time of `repeats` runs of `f`.
fn timed(repeats: usize, mut f: impl FnMut()) -> f64 {
    let times = (0..repeats.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    median(times)
}

fn trace_all(opts: &BenchOptions, scene: &Scene, triangles: usize, load_ms: f64, build_ms: f64) -> BenchReport {
    let cam = Camera::look_at(opts.eye, opts.look, opts.up, opts.fov_deg, opts.width, opts.height);
    let (w, h) = (opts.width, opts.height);
    let list = rtsl_runtime::tiles::tiles(w, h, TILE);
    let [pp, ps, sp, ss] = opts.passes;
    let reps = |on: bool| if on { opts.repeats } else { 1 };
    let buffers = TileBuffers::new(list.len());
    let t_pp = timed(reps(pp), || buffers.fill(w, h, |t, out| primary_packets(scene, &cam, t, out)));
    let packet_distances = buffers.into_vecs();
    let (single_distances, t_ps) = if ps {
        let buffers = TileBuffers::new(list.len());
        let t = timed(opts.repeats, || buffers.fill(w, h, |t, out| primary_single(scene, &cam, t, out)));
        (buffers.into_vecs(), t)
    } else {
        (packet_distances.clone(), f64::INFINITY)
    };
    let view = ShadowView { cam: &cam, light: opts.light, eps: opts.scene_scale * 1e-5 };
    let shadow_pass = |on: bool, packets: bool| {
        if !on {
            return (None, f64::INFINITY);
        }
        let buffers = TileBuffers::new(list.len());
        let t = timed(opts.repeats, || {
            buffers.fill(w, h, |t, out| {
                if packets {
                    shadow_packets(scene, &view, t, &packet_distances[t.index], out)
                } else {
                    shadow_single(scene, &view, t, &packet_distances[t.index], out)
                }
            })
        });
        (Some(buffers.into_vecs()), t)
    };
    let (packet_occ, t_sp) = shadow_pass(sp, true);
    let (single_occ, t_ss) = shadow_pass(ss, false);
    let t_pp = if pp { t_pp } else { f64::INFINITY };

    let mut hits = 0;
    let mut sum = 0.0f64;
    let mut mismatches = 0;
    for (a, b) in packet_distances.iter().zip(&single_distances) {
        for (ta, tb) in a.iter().zip(b) {
            if ta.is_finite() {
                hits += 1;
                sum += *ta as f64;
            }
            mismatches += usize::from(ta.to_bits() != tb.to_bits());
        }
    }
    let mut occluded = 0;
    match (&packet_occ, &single_occ) {
        (Some(pa), Some(sa)) => {
            for (a, b) in pa.iter().zip(sa) {
                for (oa, ob) in a.iter().zip(b) {
                    occluded += *oa as usize;
                    mismatches += (oa != ob) as usize;
                }
            }
        }
        (Some(x), None) | (None, Some(x)) => occluded = x.iter().flatten().filter(|&&o| o).count(),
        (None, None) => {}
    }
    let primary = (w * h) as f64;
    let mr = |n: f64, t: f64| n / t / 1e6;
    BenchReport {
        triangles,
        load_ms,
        build_ms,
        build_page_faults: None,
        warmup_builds: Vec::new(),
        memory_bytes: scene.memory_bytes(),
        primary_rays: (w * h) as usize,
        hits,
        hit_distance_sum: sum,
        occluded,
        mismatches,
        primary_packet_mrays: mr(primary, t_pp),
        primary_single_mrays: mr(primary, t_ps),
        shadow_packet_mrays: mr(hits as f64, t_sp),
        shadow_single_mrays: mr(hits as f64, t_ss),
        threads: rayon::current_num_threads(),
    }
}

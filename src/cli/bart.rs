//! `rtsl bart`: plays a BART scene (an AFF file) at its own animation timing, writes the frames and
//! prints how long each took, split into the animation update, the scene update (the BVHs of what
//! changed and the top-level BVH over the instances) and rendering.

use anyhow::Context as _;
use rtsl_runtime::api::Context;
use rtsl_runtime::bart::{load_file, BartScene};
use rtsl_runtime::distributed::{Demand, Master, Traffic, Transport, WorkerTime};
use rtsl_runtime::render::render_frame;
use rtsl_runtime::{write_image, WriteOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Flags of `rtsl bart`.
#[derive(clap::Args, Debug, Clone)]
pub struct BartArgs {
    /// The scene: a BART AFF file (e.g. `robot/aff/Robot.aff`, `kitchen/aff/kitchen.aff`,
    /// `museum/aff/museum5.aff`).
    pub scene: PathBuf,
    /// Frames to render, spread evenly over the whole animation (frame k of N is the scene's frame
    /// floor(k * F / N) of its F frames); default and at most: all F.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Directory for the frames, `frame_0000.png` and on (created if needed); without it nothing
    /// is written.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Image size, `WxH` (default: the scene's `resolution`).
    #[arg(long, value_parser = super::bench::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Samples per pixel (as `rtsl render --samples`: a square number is spread on a grid, 4 is
    /// 2x2; at most 64 a side).
    #[arg(long, value_parser = super::render::parse_samples)]
    pub samples: Option<u32>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Print only the summary (and errors).
    #[arg(short, long)]
    pub quiet: bool,
    /// Render over the ranks of an `mpirun` job: rank 0 plays the animation and writes the frames,
    /// the others render tiles of a copy of the scene, sent what moved before each frame
    /// (docs/distributed.md).
    #[arg(long)]
    pub mpi: bool,
    #[command(flatten)]
    pub workers: super::mpi::WorkerArgs,
}

/// Loads the scene and applies the flags, as every rank does.
fn load(args: &BartArgs, pool: &rayon::ThreadPool) -> anyhow::Result<(Context, BartScene)> {
    let mut rt = Context::new();
    let mut scene = pool.install(|| load_file(&mut rt, &args.scene)).context("cannot load the BART scene")?;
    if let Some((w, h)) = args.size {
        rt.options.width = w;
        rt.options.height = h;
    }
    if let Some(n) = args.samples {
        rt.options.samples = super::render::samples_grid(n);
    }
    // Playback reports frame times and ray counts, not where shading time goes.
    rt.options.time_shaders = false;
    // The frames are written as colour alone.
    rt.options.depth_and_ids = false;
    // The camera depends on the image's shape: place everything again for the final size.
    let start = scene.animation.start;
    scene.set_time(&mut rt, start)?;
    Ok((rt, scene))
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// What one frame cost.
struct FrameTimes {
    animation: Duration,
    /// `build_world`: BVHs (in `accel`) plus the materials, lights and instances of the frame.
    build: Duration,
    render: Duration,
    /// Rays by kind: primary, shadow, secondary, transparency.
    rays_by_kind: [u64; 4],
    accel: rtsl_runtime::render::AccelUpdate,
    /// What the frame moved between the ranks, when it was rendered over MPI.
    traffic: Option<Traffic>,
    /// What the workers fetched for the frame, and how many workers there are.
    demand: Option<(Demand, usize)>,
    /// Where the workers' time went.
    worker_time: Option<WorkerTime>,
}

impl FrameTimes {
    fn rays(&self) -> u64 {
        self.rays_by_kind.iter().sum()
    }
}

pub fn run(args: &BartArgs) -> anyhow::Result<ExitCode> {
    let (threads, pool) = super::worker_pool(args.threads)?;

    let transport = if args.mpi { Some(super::mpi::transport()?) } else { None };
    if let Some(t) = transport.as_ref().filter(|t| t.rank() != 0) {
        return super::mpi::work(&**t, &pool, &args.workers);
    }
    let mut master = transport.map(Master::connect).transpose()?;
    if let Some(m) = master.as_mut() {
        args.workers.apply(m);
    }
    let started = Instant::now();
    let (mut rt, mut scene) = load(args, &pool)?;
    let loaded = started.elapsed();
    for w in &scene.warnings {
        eprintln!("{w}");
    }
    if let Some(m) = &master {
        m.check_workers()?;
    }
    let a = scene.animation;
    // Every object's BVH, once; frames rebuild only what moves.
    let build_started = Instant::now();
    let world = pool.install(|| rt.build_world())?;
    let first_build = build_started.elapsed();
    // The scene's meshes as they would travel, to set what workers fetch against.
    let meshes = master.as_ref().map(|_| super::mpi::scene_meshes(&world)).unwrap_or_default();
    rt.return_scene(world);

    let total = a.frames.max(1);
    let count = args.frames.unwrap_or(total).clamp(1, total);
    let s = &scene.summary;
    println!(
        "{}: {} triangles ({} in {} moving instances of {} animated nodes, {} morphing), {} objects of {} parts ({} mirrors, {} glass), {} lights, {} textures ({} missing){}",
        args.scene.display(),
        s.triangles,
        s.moving_triangles,
        s.moving_instances,
        s.animated_nodes,
        s.morphing_triangles,
        s.objects,
        s.parts,
        s.mirror_parts,
        s.glass_parts,
        s.lights,
        s.textures,
        s.missing_textures,
        if s.animated_camera { ", animated camera" } else { "" },
    );
    let fps = if a.end > a.start { a.frames as f64 / (a.end - a.start) as f64 } else { 0.0 };
    let threads = match &master {
        Some(m) => format!("{} worker rank(s), {} thread(s) in all", m.workers(), m.worker_threads()),
        None => format!("{threads} thread(s)"),
    };
    println!(
        "animation {} s to {} s, {} frames ({:.1} per second); rendering {count} of them at {}x{}, {}; loaded in {:.0} ms, first BVH build {:.0} ms",
        a.start,
        a.end,
        a.frames,
        fps,
        rt.options.width,
        rt.options.height,
        threads,
        ms(loaded),
        ms(first_build),
    );
    if let Some(dir) = &args.output {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }

    let mut times = Vec::with_capacity(count as usize);
    let mut warned = false;
    for k in 0..count {
        let frame = (u64::from(k) * u64::from(total) / u64::from(count)) as u32;
        let t = scene.frame_time(frame);
        let output = args.output.as_deref().map(|d| frame_path(d, k));
        let f = play_frame(&mut rt, &mut scene, &pool, master.as_mut(), t, output)?;
        if !warned {
            warned = true;
            for w in rt.take_warnings() {
                eprintln!("warning: {w}");
            }
        }
        let frame_total = f.animation + f.build + f.render;
        if !args.quiet {
            println!(
                "frame {k:4} (scene frame {frame:4}, t = {t:8.3} s): {:8.1} ms = update {:6.2} ms (animation {:5.2}, world {:6.2}: BVHs {:5.2} = {} object{} {:5.2} + top level {:5.2}) + render {:8.1} ms, {:6.2} M rays/s",
                ms(frame_total),
                ms(f.animation + f.build),
                ms(f.animation),
                ms(f.build),
                ms(f.accel.total()),
                f.accel.objects_rebuilt,
                if f.accel.objects_rebuilt == 1 { "" } else { "s" },
                ms(f.accel.object_bvhs),
                ms(f.accel.top_level),
                ms(f.render),
                f.rays() as f64 / f.render.as_secs_f64().max(1e-9) / 1e6,
            );
            if let (Some(w), Some((d, workers))) = (&f.worker_time, &f.demand) {
                println!("           {}", super::mpi::frame_workers_line(w, d, *workers));
            }
        }
        times.push(f);
    }
    summarize(&times, meshes);
    if let Some(m) = master {
        m.shutdown()?;
    }
    Ok(ExitCode::SUCCESS)
}

fn frame_path(dir: &Path, k: u32) -> PathBuf {
    dir.join(format!("frame_{k:04}.png"))
}

/// Moves the scene to time `t`, updates the BVHs, renders (on `pool`, or over the master's
/// workers, which move their scenes to `t` first), and writes the frame when asked.
fn play_frame(
    rt: &mut Context,
    scene: &mut BartScene,
    pool: &rayon::ThreadPool,
    master: Option<&mut Master<Box<dyn Transport>>>,
    t: f32,
    output: Option<PathBuf>,
) -> anyhow::Result<FrameTimes> {
    let start = Instant::now();
    scene.set_time(rt, t)?;
    let animation = start.elapsed();
    let start = Instant::now();
    let world = pool.install(|| rt.build_world())?;
    let build = start.elapsed();
    let start = Instant::now();
    let (fb, report, traffic, demand, worker_time) = match master {
        Some(m) if m.workers() > 0 => {
            let (fb, report) = m.render_context(rt, &world, None)?;
            (fb, report, Some(m.traffic()), Some((m.demand(), m.workers())), Some(m.worker_time()))
        }
        _ => {
            let (fb, report) = pool.install(|| render_frame(&world, None));
            (fb, report, None, None, None)
        }
    };
    let render = start.elapsed();
    for w in world.textures.take_warnings() {
        eprintln!("warning: {w}");
    }
    for m in &report.shader_messages {
        eprintln!("warning: {m}");
    }
    for w in report.warnings() {
        eprintln!("warning: {w}");
    }
    rt.return_scene(world);
    if let Some(path) = output {
        write_image(&path, fb.width as usize, fb.height as usize, &fb.rgba, &WriteOptions::default())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let rays_by_kind = [report.primary_rays, report.shadow_rays, report.secondary_rays, report.transparency_rays];
    Ok(FrameTimes { animation, build, render, rays_by_kind, accel: report.accel, traffic, demand, worker_time })
}

fn summarize(times: &[FrameTimes], meshes: (usize, usize)) {
    let n = times.len().max(1) as f64;
    let mean = |f: &dyn Fn(&FrameTimes) -> Duration| times.iter().map(|t| ms(f(t))).sum::<f64>() / n;
    let totals: Vec<f64> = times.iter().map(|t| ms(t.animation + t.build + t.render)).collect();
    let min = totals.iter().copied().fold(f64::INFINITY, f64::min);
    let max = totals.iter().copied().fold(0.0, f64::max);
    let median = {
        let mut sorted = totals.clone();
        sorted.sort_by(f64::total_cmp);
        match sorted.len() {
            0 => 0.0,
            len if len % 2 == 1 => sorted[len / 2],
            len => 0.5 * (sorted[len / 2 - 1] + sorted[len / 2]),
        }
    };
    let frame = totals.iter().sum::<f64>() / n;
    let accel = mean(&|t| t.accel.total());
    let rays: u64 = times.iter().map(FrameTimes::rays).sum();
    let render_s: f64 = times.iter().map(|t| t.render.as_secs_f64()).sum();
    // What a frame asks of the tracer, whatever the host's speed: over the tracer's best rate,
    // an upper bound on the frame rate however cheap the shading.
    let per_frame = |k: usize| (times.iter().map(|t| t.rays_by_kind[k]).sum::<u64>() as f64 / n).round();
    println!(
        "rays per frame: {:.0} on average ({} primary, {} shadow, {} secondary, {} transparency), at most {}",
        rays as f64 / n,
        per_frame(0),
        per_frame(1),
        per_frame(2),
        per_frame(3),
        times.iter().map(FrameTimes::rays).max().unwrap_or(0),
    );
    println!(
        "{} frames: {:.1} ms per frame on average (min {:.1}, median {:.1}, max {:.1}; {:.2} frames/s): update {:.2} ms (animation {:.2}, world {:.2} of which BVHs {:.2}, {:.2}% of a frame), render {:.1} ms; {:.2} M rays/s (image writing not counted)",
        times.len(),
        frame,
        min,
        median,
        max,
        1e3 / frame.max(1e-9),
        mean(&|t| t.animation + t.build),
        mean(&|t| t.animation),
        mean(&|t| t.build),
        accel,
        100.0 * accel / frame.max(1e-9),
        mean(&|t| t.render),
        rays as f64 / render_s.max(1e-9) / 1e6,
    );
    let traffic: Vec<Traffic> = times.iter().filter_map(|t| t.traffic).collect();
    if !traffic.is_empty() {
        let k = traffic.len() as u64;
        let mean = |f: fn(&Traffic) -> u64| traffic.iter().map(f).sum::<u64>() / k;
        let t = Traffic {
            updates: mean(|t| t.updates),
            control: mean(|t| t.control),
            pixels: mean(|t| t.pixels),
            counters: mean(|t| t.counters),
            fetches: mean(|t| t.fetches),
            light_paths: mean(|t| t.light_paths),
        };
        println!("{}", super::mpi::traffic_line(&t));
        // The first frame apart: it compiles the shaders and fetches what the view first reaches.
        let worker_times: Vec<WorkerTime> = times.iter().filter_map(|t| t.worker_time).collect();
        if let Some((first, later)) = worker_times.split_first() {
            println!("{}", super::mpi::worker_time_line("the first frame", std::slice::from_ref(first)));
            if !later.is_empty() {
                println!("{}", super::mpi::worker_time_line("the later frames", later));
            }
        }
    }
    let demands: Vec<_> = times.iter().filter_map(|t| t.demand).collect();
    if let Some(&(first, workers)) = demands.first() {
        println!("{}", super::mpi::demand_line("the first frame", (&first).into(), meshes, &first, workers));
        let rest = &demands[1..];
        let later = rest.iter().map(|(d, _)| super::mpi::Fetched::from(d)).fold(Default::default(), |a, b| a + b);
        let (d, workers) = demands.last().copied().unwrap_or((first, workers));
        println!(
            "{}",
            super::mpi::demand_line(&format!("the {} later frames", rest.len()), later, meshes, &d, workers)
        );
    }
}

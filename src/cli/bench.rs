//! `rtsl bench trace`: the command-line side of the tracer benchmark. Parses the flags into
//! [`rtsl::bench::BenchOptions`], runs [`rtsl::bench::run_bench`] and prints one `name: value`
//! line per figure.

use super::render::CameraSpec;
use anyhow::Context as _;
use rtsl::bench::native_plastic::NativePlastic;
use rtsl::bench::{run_bench, BenchOptions};
use rtsl_runtime::render::{FrameReport, Framebuffer};
use rtsl_runtime::BuildQuality;
use std::path::PathBuf;

/// Flags of `rtsl bench trace`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchTraceArgs {
    /// The mesh to trace (OBJ or PLY).
    #[arg(long)]
    pub mesh: PathBuf,
    /// Camera position, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,130,-170")]
    pub eye: [f32; 3],
    /// Point the camera looks at, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,-53")]
    pub look: [f32; 3],
    /// Camera up vector, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 45.0)]
    pub fov: f32,
    /// Point light position, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "60,220,40")]
    pub light: [f32; 3],
    /// The scene's scale: shadow rays start and stop this times 1e-5 from the hit and the light,
    /// as in Embree's side of the comparison (the benchmark scenes' files say 300).
    #[arg(long, value_parser = parse_scale, default_value_t = 300.0)]
    pub scene_scale: f32,
    /// Image size, `WxH`.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed repetitions of each pass; the median is printed.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// BVH build quality: fast, medium, high or best.
    #[arg(long, value_parser = parse_quality, default_value = "high")]
    pub quality: BuildQuality,
    /// Passes to time, comma-separated: pp (primary packets), ps (primary single rays), sp (shadow
    /// packets), ss (shadow single rays). Passes left out print 0.
    #[arg(long, value_parser = parse_passes, default_value = "pp,ps,sp,ss")]
    pub passes: [bool; 4],
}

pub(crate) fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers X,Y,Z, got `{s}`"));
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        let x: f32 = p.parse().map_err(|_| format!("`{p}` is not a number (in `{s}`)"))?;
        if !x.is_finite() {
            return Err(format!("`{p}` is not a finite number (in `{s}`)"));
        }
        *slot = x;
    }
    Ok(v)
}

pub(crate) fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) =
        s.split_once(['x', 'X']).ok_or_else(|| format!("expected an image size WxH such as 1024x768, got `{s}`"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width `{w}` is not a positive integer"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height `{h}` is not a positive integer"))?;
    if w == 0 || h == 0 {
        return Err(format!("image size `{s}` must be at least 1x1"));
    }
    rtsl_runtime::render::check_image_size(u64::from(w), u64::from(h))?;
    Ok((w, h))
}

fn parse_scale(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("scene scale `{s}` must be a finite number, 0 or more")),
    }
}

fn parse_passes(s: &str) -> Result<[bool; 4], String> {
    let mut on = [false; 4];
    for p in s.split(',').map(str::trim) {
        let i = ["pp", "ps", "sp", "ss"]
            .iter()
            .position(|&n| n == p)
            .ok_or_else(|| format!("unknown pass `{p}` (expected pp, ps, sp or ss)"))?;
        on[i] = true;
    }
    Ok(on)
}

fn parse_quality(s: &str) -> Result<BuildQuality, String> {
    match s {
        "fast" => Ok(BuildQuality::Fast),
        "medium" => Ok(BuildQuality::Medium),
        "high" => Ok(BuildQuality::High),
        "best" => Ok(BuildQuality::Best),
        _ => Err(format!("unknown build quality `{s}` (expected fast, medium, high or best)")),
    }
}

/// Runs `rtsl bench trace` and prints its report as `name: value` lines.
pub fn run_trace(args: &BenchTraceArgs) -> anyhow::Result<()> {
    let mut o = BenchOptions::new(&args.mesh);
    o.eye = args.eye.into();
    o.look = args.look.into();
    o.up = args.up.into();
    o.fov_deg = args.fov;
    o.light = args.light.into();
    o.scene_scale = args.scene_scale;
    (o.width, o.height) = args.size;
    super::thread_count(args.threads)?;
    o.threads = args.threads;
    o.repeats = args.repeats.max(1);
    o.quality = args.quality;
    o.passes = args.passes;
    let r = run_bench(&o).with_context(|| format!("benchmark of {} failed", args.mesh.display()))?;
    let per_tri = r.memory_bytes as f64 / r.triangles.max(1) as f64;
    println!("mesh: {}", args.mesh.display());
    println!("triangles: {}", r.triangles);
    println!("threads: {}", r.threads);
    println!("packet_kernels: {}", rtsl_runtime::cpu::kernel_isa().name());
    println!("load_ms: {:.1}", r.load_ms);
    println!("build_ms: {:.1}", r.build_ms);
    if let Some(faults) = &r.build_page_faults {
        let faults: Vec<String> = faults.iter().map(u64::to_string).collect();
        println!("build_page_faults: {}", faults.join(", "));
    }
    if !r.warmup_builds.is_empty() {
        let warmup: Vec<String> = r.warmup_builds.iter().map(|(ms, f)| format!("{ms:.1} ms/{f}")).collect();
        println!("warmup_builds: {}", warmup.join(", "));
    }
    println!("memory_bytes: {}", r.memory_bytes);
    println!("memory_bytes_per_triangle: {per_tri:.1}");
    println!("primary_rays: {}", r.primary_rays);
    println!("hits: {}", r.hits);
    println!("hit_distance_sum: {:.3}", r.hit_distance_sum);
    println!("shadow_rays: {}", r.hits);
    println!("occluded: {}", r.occluded);
    println!("packet_single_mismatches: {}", r.mismatches);
    println!("primary_packet_mrays: {:.2}", r.primary_packet_mrays);
    println!("primary_single_mrays: {:.2}", r.primary_single_mrays);
    println!("shadow_packet_mrays: {:.2}", r.shadow_packet_mrays);
    println!("shadow_single_mrays: {:.2}", r.shadow_single_mrays);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vectors_and_sizes() {
        assert_eq!(parse_vec3("1, 2,-3.5"), Ok([1.0, 2.0, -3.5]));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,x,2").unwrap_err().contains("`x`"));
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err());
        assert!(parse_size("0x480").is_err());
        assert_eq!(parse_passes("ss,pp"), Ok([true, false, false, true]));
        assert!(parse_passes("pp,xx").is_err());
        assert_eq!(parse_scale("550"), Ok(550.0));
        assert!(parse_scale("-1").is_err());
        assert!(parse_scale("inf").is_err());
    }
}

/// Flags of `rtsl bench render`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchRenderArgs {
    /// The scene (RIB, VRML or mesh; none: the default scene).
    pub scene: Option<PathBuf>,
    /// Of a VRML scene, the surface shader every shape gets instead of `material` (as `rtsl
    /// render --vrml-surface`).
    #[arg(long, value_name = "SHADER")]
    pub vrml_surface: Option<String>,
    /// Timed frames (after one untimed warm-up frame); the median is reported.
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Of a VRML scene, play its animation at this many frames per second of its time: each frame
    /// advances it (`VrmlScene::advance_to`) and rebuilds the world before rendering, and the
    /// update's time is reported apart.
    #[arg(long, value_name = "FPS")]
    pub animate: Option<f64>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Image size, `WxH` (overrides the scene's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Samples per pixel (overrides the scene's; as `rtsl render --samples`).
    #[arg(long, value_parser = super::render::parse_samples, default_value_t = 1)]
    pub samples: u32,
    /// Anti-aliasing mode (as `rtsl render --aa`).
    #[arg(long, value_parser = rtsl_runtime::render::Antialiasing::parse)]
    pub aa: Option<rtsl_runtime::render::Antialiasing>,
    /// Also render with every `plastic` replaced by hand-written Rust, alternating frame by frame,
    /// and print the JIT's cost as a ratio.
    #[arg(long)]
    pub native_plastic: bool,
    /// Also render with `RenderOptions::trace_ahead` off (each chunk's `trace` rays traced and
    /// shaded on their own, not a batch's together), alternating frame by frame, and print the
    /// ratio.
    #[arg(long)]
    pub compare_trace_ahead: bool,
    /// With `--gaze`: also render at uniform full quality (no relevance), alternating frame by
    /// frame, and print both frame rates and the image error inside the gaze radius and beyond its
    /// falloff against the uniform frame.
    #[arg(long, requires = "gaze")]
    pub compare_uniform: bool,
    /// Keep each pixel's depth and object id, as an application that reads them would (by
    /// default frames keep colour alone, as `rtsl render` does for an image of colour; over
    /// `--mpi` the tiles then carry 24 bytes a pixel instead of 16).
    #[arg(long)]
    pub depth_and_ids: bool,
    /// Directories searched for shaders by name (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
    /// Render over the ranks of an `mpirun` job: rank 0 times the frames, the others render tiles
    /// (`--threads` each; docs/distributed.md).
    #[arg(long)]
    pub mpi: bool,
    #[command(flatten)]
    pub workers: super::mpi::WorkerArgs,
    #[command(flatten)]
    pub rays: super::ray_params::RayParamArgs,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// The lines every `rtsl bench render` prints: the scene and its size, who rendered it, the
/// median of the timed frames' times `frames_ms` and their spread, and the rays of the last frame.
fn print_rate(
    args: &BenchRenderArgs,
    world: &rtsl_runtime::render::World,
    who: &str,
    frames_ms: &[f64],
    report: &FrameReport,
) {
    let ms = median(frames_ms.to_vec());
    println!("scene: {}", args.scene.as_ref().map_or("<default scene>".into(), |p| p.display().to_string()));
    println!("size: {}x{}, samples per pixel: {}, {who}", world.options.width, world.options.height, args.samples);
    println!("packet_kernels: {}", rtsl_runtime::cpu::kernel_isa().name());
    println!("frame_ms: {ms:.2}");
    // The spread tells a difference between two runs from the host's noise.
    let (fastest, slowest) = frames_ms.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
    if !frames_ms.is_empty() {
        println!("frame_ms_spread: {fastest:.2} to {slowest:.2} over {} frames", frames_ms.len());
    }
    println!("fps: {:.2}", 1e3 / ms.max(1e-9));
    println!(
        "rays_per_frame: {} (primary {}, shadow {}, secondary {}, transparency {})",
        report.total_rays(),
        report.primary_rays,
        report.shadow_rays,
        report.secondary_rays,
        report.transparency_rays
    );
    println!("mrays_per_second: {:.2}", report.total_rays() as f64 / ms.max(1e-9) / 1e3);
    // How full the shading batches run: their fixed costs are shared by the lanes of each.
    println!(
        "shaded_points: {}, light_batches: {} ({:.1} points a light batch)",
        report.shaded_points,
        report.light_evaluations,
        report.shaded_points as f64 / report.light_evaluations.max(1) as f64
    );
    print_tile_balance(report);
}

/// The last frame's tiles: how long the longest took, and how busy the hand-out of tiles in
/// their order keeps this run's threads and 16 and 64 (the frame's tiles replayed with their
/// times as measured here): where a frame's tail loses scaling, and where it does not.
fn print_tile_balance(report: &FrameReport) {
    if report.tile_times.is_empty() {
        return;
    }
    let ms: Vec<f64> = report.tile_times.iter().map(|d| d.as_secs_f64() * 1e3).collect();
    let longest = ms.iter().copied().fold(0.0f64, f64::max);
    let busy = |threads: usize| 100.0 * rtsl_runtime::tiles::hand_out_busy_share(&ms, threads);
    println!(
        "tiles: {}, longest {longest:.2} ms, of {:.1} ms in all; busy while tiles are handed out in order: {:.1}% over {} threads, {:.1}% over 16, {:.1}% over 64",
        ms.len(),
        ms.iter().sum::<f64>(),
        busy(report.threads),
        report.threads,
        busy(16),
        busy(64)
    );
}

/// Applies `rtsl bench render`'s image flags (size, samples per pixel, anti-aliasing) to `rt`.
fn apply_image_flags(args: &BenchRenderArgs, rt: &mut rtsl_runtime::api::Context) {
    if let Some((w, h)) = args.size {
        rt.options.width = w;
        rt.options.height = h;
    }
    rt.options.samples = super::render::samples_grid(args.samples);
    if let Some(aa) = args.aa {
        rt.options.antialiasing = aa;
    }
}

/// Runs `rtsl bench render`: frames per second and rays per second of a scene, and with
/// `--native-plastic` the JIT frame time over the hand-written one, measured in one run.
pub fn run_render(args: &BenchRenderArgs) -> anyhow::Result<()> {
    if let Some(fps) = args.animate {
        return run_render_animated(args, fps);
    }
    let load = || -> anyhow::Result<rtsl_runtime::api::Context> {
        let options = rtsl_runtime::LoadOptions { vrml_surface: args.vrml_surface.clone() };
        let (mut rt, _) = super::render::load_scene_frame(args.scene.as_deref(), &args.shader_path, &[], 0, &options)?;
        apply_image_flags(args, &mut rt);
        args.rays.apply(&mut rt)?;
        // Frames as `rtsl render` makes them for an image of colour: no depth or object ids.
        rt.options.depth_and_ids = args.depth_and_ids;
        // Timed frames read no shader clocks (a clock read on entering and leaving every batch is
        // a few percent of a frame of many small batches, which a frame rate compared with another
        // renderer's should not carry); one more frame after them times the shaders.
        rt.options.time_shaders = false;
        Ok(rt)
    };
    let (threads, pool) = super::worker_pool(args.threads)?;
    if args.mpi {
        anyhow::ensure!(
            !args.native_plastic && !args.compare_trace_ahead && !args.compare_uniform,
            "--native-plastic, --compare-trace-ahead and --compare-uniform change the world on rank 0 only: run them \
             without --mpi"
        );
        let transport = super::mpi::transport()?;
        if transport.rank() != 0 {
            super::mpi::work(&*transport, &pool, &args.workers)?;
            return Ok(());
        }
        let mut master = rtsl_runtime::distributed::Master::connect(transport)?;
        args.workers.apply(&mut master);
        let mut rt = load()?;
        master.check_workers()?;
        anyhow::ensure!(master.workers() > 0, "--mpi needs worker ranks: run it with mpirun -n 2 or more");
        let world = rt.build_world()?;
        let mut ms = Vec::new();
        let mut last = None;
        let mut first_demand = None;
        let mut worker_times = Vec::new();
        for frame in 0..=args.frames.max(1) {
            let (_, report) = master.render_context(&rt, &world, None)?;
            first_demand.get_or_insert(master.demand());
            if frame > 0 {
                ms.push(report.elapsed.as_secs_f64() * 1e3);
                worker_times.push(master.worker_time());
                last = Some(report);
            }
        }
        let threads = format!("worker ranks: {}, threads: {}", master.workers(), master.worker_threads());
        print_rate(args, &world, &threads, &ms, &last.unwrap_or_default());
        println!("{}", super::mpi::traffic_line(&master.traffic()));
        println!("{}", super::mpi::worker_time_line("the timed frames", &worker_times));
        let (first, d) = (first_demand.unwrap_or_default(), master.demand());
        let meshes = super::mpi::scene_meshes(&world);
        println!("{}", super::mpi::demand_line("the first frame", (&first).into(), meshes, &first, master.workers()));
        println!("{}", super::mpi::demand_line("the last frame", (&d).into(), meshes, &d, master.workers()));
        master.shutdown()?;
        return Ok(());
    }
    let mut rt = load()?;
    let mut world = rt.build_world()?;
    let frames = args.frames.max(1);
    let jit_world = world.materials.clone();
    let native_count = if args.native_plastic { world.use_native_surface("plastic", NativePlastic::shared) } else { 0 };
    let native_world = world.materials.clone();
    if args.native_plastic && native_count == 0 {
        anyhow::bail!("the scene has no plastic surface to compare");
    }
    let (mut jit_ms, mut native_ms, mut chunked_ms, mut uniform_ms) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut last = None;
    let relevance = world.options.ray_parameters.clone();
    let (mut adapted_image, mut uniform_image) = (None, None);
    #[derive(PartialEq)]
    enum Variant {
        Jit,
        Native,
        Chunked,
        Uniform,
    }
    for frame in 0..=frames {
        for variant in [Variant::Jit, Variant::Native, Variant::Chunked, Variant::Uniform] {
            if (variant == Variant::Native && !args.native_plastic)
                || (variant == Variant::Chunked && !args.compare_trace_ahead)
                || (variant == Variant::Uniform && !args.compare_uniform)
            {
                continue;
            }
            world.materials = if variant == Variant::Native { native_world.clone() } else { jit_world.clone() };
            world.options.trace_ahead = variant != Variant::Chunked;
            world.options.ray_parameters = relevance.clone();
            if variant == Variant::Uniform {
                world.options.ray_parameters.remove(rtsl_runtime::render::RELEVANCE);
            }
            let (image, report) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
            if frame > 0 {
                let ms = report.elapsed.as_secs_f64() * 1e3;
                match variant {
                    Variant::Native => native_ms.push(ms),
                    Variant::Chunked => chunked_ms.push(ms),
                    Variant::Uniform => {
                        uniform_ms.push(ms);
                        uniform_image = Some(image);
                    }
                    Variant::Jit => {
                        jit_ms.push(ms);
                        last = Some(report);
                        adapted_image = Some(image);
                    }
                }
            }
        }
    }
    let report = last.unwrap_or_default();
    print_rate(args, &world, &format!("threads: {threads}"), &jit_ms, &report);
    let ms = median(jit_ms);
    world.materials = jit_world;
    world.options.trace_ahead = true;
    world.options.ray_parameters = relevance;
    // The untimed frame that times the shaders, for the shares and the per-shader table.
    world.options.time_shaders = true;
    let (_, report) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
    println!("shading_share: {:.3}", report.shading_share());
    for kind in rtsl_compiler::interface::ShaderKind::ALL {
        let share = report.shader_share(kind);
        if share > 0.0 {
            println!("{}_shader_share: {share:.3}", kind.name());
        }
    }
    // Per shader, the last frame's thread time: where the shading time goes.
    print!("{}", report.shader_table());
    if args.native_plastic {
        let nms = median(native_ms);
        println!("native_plastic_frame_ms: {nms:.2} ({native_count} materials)");
        println!("jit_over_native: {:.3}", ms / nms.max(1e-9));
    }
    if args.compare_trace_ahead {
        let cms = median(chunked_ms);
        println!("chunk_by_chunk_trace_frame_ms: {cms:.2}");
        println!("trace_ahead_over_chunk_by_chunk: {:.3}", ms / cms.max(1e-9));
    }
    if let (Some(gaze), Some(adapted), Some(uniform)) = (&args.rays.gaze, &adapted_image, &uniform_image) {
        let ums = median(uniform_ms);
        println!("uniform_frame_ms: {ums:.2}");
        println!("uniform_fps: {:.2}", 1e3 / ums.max(1e-9));
        println!("relevance_speedup: {:.3}", ums / ms.max(1e-9));
        let (inside, outside) = gaze_errors(gaze, adapted, uniform);
        println!("rmse_inside_radius: {inside:.5}");
        println!("rmse_beyond_falloff: {outside:.5}");
    }
    Ok(())
}

/// The root-mean-square difference of the colours of two frames (over the channels), within the
/// gaze's radius and beyond its falloff.
fn gaze_errors(gaze: &super::ray_params::Gaze, a: &Framebuffer, b: &Framebuffer) -> (f64, f64) {
    let (mut inside, mut outside) = ((0.0f64, 0usize), (0.0f64, 0usize));
    for y in 0..a.height.min(b.height) {
        for x in 0..a.width.min(b.width) {
            let (p, q) = (a.pixel(x, y), b.pixel(x, y));
            let d: f64 = (0..3).map(|c| f64::from(p[c] - q[c]).powi(2)).sum::<f64>() / 3.0;
            let sum = if gaze.inside(x, y) {
                &mut inside
            } else if gaze.outside(x, y) {
                &mut outside
            } else {
                continue;
            };
            sum.0 += d;
            sum.1 += 1;
        }
    }
    let rms = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
    (rms(inside), rms(outside))
}

/// `rtsl bench render --animate FPS`: a VRML scene's animation played frame by frame, each frame's
/// update (the events run, instances moved, objects rebuilt, the world built again) timed apart
/// from its render.
fn run_render_animated(args: &BenchRenderArgs, fps: f64) -> anyhow::Result<()> {
    anyhow::ensure!(fps.is_finite() && fps > 0.0, "--animate takes frames per second above 0");
    anyhow::ensure!(
        !args.mpi && !args.native_plastic && !args.compare_trace_ahead,
        "--animate runs on its own (without --mpi, --native-plastic, --compare-trace-ahead)"
    );
    let options = rtsl_runtime::LoadOptions { vrml_surface: args.vrml_surface.clone() };
    let (mut rt, mut loaded) =
        super::render::load_scene_frame(args.scene.as_deref(), &args.shader_path, &[], 0, &options)?;
    let mut scene = loaded.vrml.take().context("--animate plays a VRML scene's animation")?;
    anyhow::ensure!(scene.is_animated(), "the scene has no animation (no TimeSensor routed anywhere)");
    apply_image_flags(args, &mut rt);
    let (threads, pool) = super::worker_pool(args.threads)?;
    let (mut update_ms, mut frame_ms) = (Vec::new(), Vec::new());
    let mut world = rt.build_world()?;
    let mut last = None;
    for frame in 0..=args.frames.max(1) {
        let start = std::time::Instant::now();
        scene.advance_to(frame as f64 / fps, &mut rt)?;
        rt.return_scene(world);
        world = rt.build_world()?;
        let update = start.elapsed().as_secs_f64() * 1e3;
        let (_, report) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
        if frame > 0 {
            update_ms.push(update);
            frame_ms.push(update + report.elapsed.as_secs_f64() * 1e3);
            last = Some(report);
        }
    }
    rtsl_runtime::rib::report::write_diagnostics(&scene.take_warnings(), &mut super::color::stderr())?;
    print_rate(args, &world, &format!("threads: {threads}"), &frame_ms, &last.unwrap_or_default());
    println!("update_ms: {:.2}", median(update_ms));
    Ok(())
}

/// Flags of `rtsl bench camera`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchCameraArgs {
    /// The scene (RIB or mesh; none: the default scene).
    pub scene: Option<PathBuf>,
    /// Timed frames per camera (after one untimed warm-up frame each); the median is reported.
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Image size, `WxH` (overrides the scene's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Camera shaders to compare with the built-in pinhole camera, each `NAME[:PARAM=VALUE]...`
    /// (`fisheye:fit=diagonal`: the full-frame fisheye, which makes a ray for every pixel).
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = CameraSpec::parse,
        default_value = "pinhole,fisheye,fisheye:fit=diagonal,thinlens,cylindrical,parabolic"
    )]
    pub cameras: Vec<CameraSpec>,
    /// Only make the rays, without tracing them, for profiling the cameras alone: only the
    /// `*_make_ns_per_pixel` lines are printed.
    #[arg(long)]
    pub make_only: bool,
}

/// Runs `rtsl bench camera`: Mrays/s of primary rays (made and traced, not shaded) from each camera
/// shader and from the built-in pinhole camera, frames interleaved camera by camera so that the
/// machine's drift touches all alike; each camera's speed is also printed as a ratio to the
/// built-in one.
pub fn run_camera(args: &BenchCameraArgs) -> anyhow::Result<()> {
    let (mut rt, _) = super::render::load_scene(args.scene.as_deref(), &[], &[])?;
    if let Some((w, h)) = args.size {
        rt.options.width = w;
        rt.options.height = h;
    }
    rt.options.samples = (1, 1);
    // Rays per second are all this reports: no shader clocks (the built-in camera has none).
    rt.options.time_shaders = false;
    // One world; only its camera shader changes from run to run.
    let mut cameras = vec![("builtin".to_string(), None)];
    for camera in &args.cameras {
        camera.bind(&mut rt)?;
        let world = rt.build_world()?;
        cameras.push((camera.label(), world.camera_shader.clone()));
        rt.return_scene(world);
    }
    rt.camera_shader(None, &[])?;
    let mut world = rt.build_world()?;
    let (threads, pool) = super::worker_pool(args.threads)?;
    let mut times = vec![Vec::new(); cameras.len()];
    let mut make_times = vec![Vec::new(); cameras.len()];
    let mut rays = vec![0u64; cameras.len()];
    for frame in 0..=args.frames.max(1) {
        for (k, (_, camera)) in cameras.iter().enumerate() {
            world.camera_shader = camera.clone();
            let start = std::time::Instant::now();
            let (n, _) =
                if args.make_only { (0, 0) } else { pool.install(|| rtsl_runtime::render::trace_primary_rays(&world)) };
            let traced = start.elapsed().as_secs_f64();
            let start = std::time::Instant::now();
            pool.install(|| rtsl_runtime::render::make_primary_rays(&world));
            if frame > 0 {
                times[k].push(traced);
                make_times[k].push(start.elapsed().as_secs_f64());
                rays[k] = n;
            }
        }
    }
    let (w, h) = (rt.options.width, rt.options.height);
    println!("scene: {}", args.scene.as_ref().map_or("<default scene>".into(), |p| p.display().to_string()));
    if args.make_only {
        println!("size: {w}x{h}, threads: {threads}, primary rays made (not traced)");
    } else {
        println!("size: {w}x{h}, threads: {threads}, primary rays made and traced (not shaded)");
    }
    let pixels = f64::from(w) * f64::from(h);
    // Ratios to the built-in camera are the median over frames of each frame's ratio: a frame's
    // cameras run back to back, so the ratio of the two is paired against the machine's drift
    // (the ratio of the two medians is not, and on a shared machine varied by 10% from run to run).
    let paired = |t: &[Vec<f64>], k: usize| median(t[0].iter().zip(&t[k]).map(|(b, c)| b / c.max(1e-12)).collect());
    for (k, (name, _)) in cameras.iter().enumerate().filter(|_| !args.make_only) {
        let mrays = rays[k] as f64 / median(times[k].clone()).max(1e-12) / 1e6;
        let ratio = paired(&times, k) * rays[k] as f64 / (rays[0] as f64).max(1.0);
        println!("{name}_mrays: {mrays:.2} ({} rays, {ratio:.3} of builtin)", rays[k]);
    }
    // Camera samples (one a pixel) per second: a camera that makes no ray for some samples (a
    // fisheye outside its image circle) still runs for them, so this is its throughput per sample.
    for (k, (name, _)) in cameras.iter().enumerate().filter(|_| !args.make_only) {
        let msamples = pixels / median(times[k].clone()).max(1e-12) / 1e6;
        println!("{name}_msamples: {msamples:.2} ({:.3} of builtin)", paired(&times, k));
    }
    // Making the rays alone (camera samples and the camera, no tracing): where a camera shader's
    // cost over the built-in camera lies.
    for (k, (name, _)) in cameras.iter().enumerate() {
        let t = median(make_times[k].clone());
        println!(
            "{name}_make_ns_per_pixel: {:.1} ({:.2}x builtin)",
            t * 1e9 / pixels.max(1.0),
            1.0 / paired(&make_times, k).max(1e-12)
        );
    }
    Ok(())
}

/// Flags of `rtsl bench aa`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchAaArgs {
    /// The scene (RIB or mesh; none: the default scene).
    pub scene: Option<PathBuf>,
    /// Image size, `WxH` (the reference takes many samples a pixel, so smaller than the scene's).
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    pub size: (u32, u32),
    /// Samples per pixel of the reference image (a jittered grid; a square number, as `rtsl render
    /// --samples`).
    #[arg(long, value_parser = super::render::parse_samples, default_value_t = 64)]
    pub reference: u32,
    /// The ray budget: samples per pixel of each fixed-rate mode (a square number, as `rtsl render
    /// --samples`).
    #[arg(long, value_parser = super::render::parse_samples, default_value_t = 4)]
    pub samples: u32,
    /// Thresholds of adaptive oversampling to try (it spends as many rays as its threshold asks).
    #[arg(long, value_delimiter = ',', default_value = "0.4,0.2,0.1,0.05,0.02")]
    pub thresholds: Vec<f32>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
}

/// Runs `rtsl bench aa`: renders a reference with many jittered samples a pixel, then the scene with
/// each anti-aliasing mode (regular and jittered grids and interleaved QMC sampling at the budget,
/// adaptive oversampling at several thresholds) and prints, per mode, the primary rays traced (all
/// rays too) and the root-mean-square error of the final RGB against the reference.
pub fn run_aa(args: &BenchAaArgs) -> anyhow::Result<()> {
    use rtsl_runtime::render::Antialiasing;
    let (mut rt, _) = super::render::load_scene(args.scene.as_deref(), &[], &[])?;
    (rt.options.width, rt.options.height) = args.size;
    let (threads, pool) = super::worker_pool(args.threads)?;
    let mut world = rt.build_world()?;
    let mut render = |aa: Antialiasing, samples: u32| {
        world.options.antialiasing = aa;
        world.options.samples = super::render::samples_grid(samples);
        let start = std::time::Instant::now();
        let (fb, report) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
        (fb, report, start.elapsed().as_secs_f64() * 1e3)
    };
    let (reference, _, _) = render(Antialiasing::Grid { jitter: true }, args.reference);
    let pixels = (args.size.0 as u64 * args.size.1 as u64).max(1);
    let rmse = |fb: &rtsl_runtime::render::Framebuffer| {
        let sum: f64 = fb
            .rgba
            .chunks(4)
            .zip(reference.rgba.chunks(4))
            .map(|(a, b)| (0..3).map(|c| f64::from(a[c] - b[c]).powi(2)).sum::<f64>())
            .sum();
        (sum / (3 * pixels) as f64).sqrt()
    };
    println!("scene: {}", args.scene.as_ref().map_or("<default scene>".into(), |p| p.display().to_string()));
    println!(
        "size: {}x{}, threads: {threads}, reference: {} jittered samples per pixel, budget: {} samples per pixel",
        args.size.0, args.size.1, args.reference, args.samples
    );
    let mut modes: Vec<(String, Antialiasing, u32)> = vec![
        ("regular".into(), Antialiasing::Grid { jitter: false }, args.samples),
        ("jittered".into(), Antialiasing::Grid { jitter: true }, args.samples),
        ("interleaved".into(), Antialiasing::Interleaved, args.samples),
        ("one_sample".into(), Antialiasing::Grid { jitter: false }, 1),
    ];
    for t in &args.thresholds {
        modes.push((format!("adaptive:{t}"), Antialiasing::Adaptive { threshold: *t }, 1));
    }
    for (name, aa, samples) in modes {
        let (fb, report, ms) = render(aa, samples);
        println!(
            "{name}: primary_rays_per_pixel {:.2}, rays {} (primary {}), rmse {:.5}, {ms:.0} ms",
            report.primary_rays as f64 / pixels as f64,
            report.total_rays(),
            report.primary_rays,
            rmse(&fb)
        );
    }
    Ok(())
}

/// Flags of `rtsl bench instances`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchInstancesArgs {
    /// Instance counts to time.
    #[arg(long, value_delimiter = ',', default_value = "1000,10000")]
    pub counts: Vec<usize>,
    /// Timed rebuilds per count; the median is reported.
    #[arg(long, default_value_t = 21)]
    pub repeats: usize,
}

/// Runs `rtsl bench instances`: the time to rebuild the top-level BVH (`Scene::commit`, what every
/// frame of a dynamic scene pays) over N instances of one small object, each placed by its own
/// rotation and translation on a jittered grid, for each N.
pub fn run_instances(args: &BenchInstancesArgs) -> anyhow::Result<()> {
    use rtsl_runtime::glam::{Affine3A, Quat, Vec3};
    let corners: Vec<Vec3> =
        (0..8).map(|k| Vec3::new((k & 1) as f32, (k >> 1 & 1) as f32, (k >> 2 & 1) as f32)).collect();
    let faces: [[u32; 4]; 6] = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let cube = rtsl_runtime::Mesh::from_polygons(corners, &faces)?;
    for &n in &args.counts {
        let mut scene = rtsl_runtime::Scene::new();
        let object = scene.add_object(cube.clone());
        let side = (n as f32).cbrt().ceil().max(1.0);
        for i in 0..n {
            // A deterministic scatter: a grid, jittered and turned by a hash of the index.
            let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let r = |b: u32| ((h >> b) & 0xFFFF) as f32 / 65536.0;
            let (x, y, z) =
                ((i as f32) % side, ((i as f32) / side).floor() % side, ((i as f32) / (side * side)).floor());
            let at = Vec3::new(x + r(0), y + r(16), z + r(32)) * 3.0;
            let turn = Quat::from_axis_angle(Vec3::new(r(8), r(24), 1.0).normalize(), r(40) * std::f32::consts::TAU);
            scene.add_instance(object, Affine3A::from_rotation_translation(turn, at))?;
        }
        scene.commit();
        let mut times = Vec::new();
        for _ in 0..args.repeats.max(1) {
            let start = std::time::Instant::now();
            scene.commit();
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        println!("instances_{n}_top_level_ms: {:.3}", median(times));
    }
    Ok(())
}

/// Flags of `rtsl bench reload`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchReloadArgs {
    /// Timed edits of `plastic.sl`; the median latency is reported.
    #[arg(long, default_value_t = 20)]
    pub edits: usize,
    /// Image size, `WxH`.
    #[arg(long, value_parser = parse_size, default_value = "640x480")]
    pub size: (u32, u32),
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// The scene, a RIB file whose surfaces use `plastic` (default: plastic spheres on a plastic floor).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// The reloader's debounce window in milliseconds (default: the library's).
    #[arg(long)]
    pub quiet_ms: Option<u64>,
}

/// The sum of a frame's pixels, to tell frames apart.
fn frame_sum(fb: &rtsl_runtime::render::Framebuffer) -> f64 {
    fb.rgba.iter().map(|&v| f64::from(v)).sum()
}

/// `rtsl bench reload`'s scene when none is given.
const RELOAD_SCENE: &str = r#"Format 320 240 1
Projection "perspective" "fov" 40
Translate 0 -0.5 6
WorldBegin
Attribute "light" "shadows" "on"
LightSource "ambientlight" 1 "intensity" 0.1
LightSource "pointlight" 2 "from" [2 4 -3] "intensity" 40
Color [0.8 0.8 0.8]
Surface "plastic"
Polygon "P" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]
Color [0.8 0.3 0.2]
AttributeBegin
Translate -1 1 0
Sphere 1 -1 1 360
AttributeEnd
Color [0.2 0.4 0.8]
AttributeBegin
Translate 1.2 0.8 0.5
Sphere 0.8 -0.8 0.8 360
AttributeEnd
WorldEnd
"#;

/// Runs `rtsl bench reload`: the latency of hot reload, from the moment an edit of `plastic.sl` is
/// written to the first finished frame that uses the new code, through the watcher, the background
/// compilation, the swap between frames and the frame (`ShaderReloader`). Prints each edit's latency
/// and its parts, and the medians.
pub fn run_reload(args: &BenchReloadArgs) -> anyhow::Result<()> {
    use rtsl_runtime::reload::{ShaderReloader, DEFAULT_QUIET};
    use std::time::{Duration, Instant};

    // The library (as built into the binary) written under a temporary directory, where its
    // plastic.sl is edited.
    let tmp = super::ScratchDir::new("bench-reload")?;
    rtsl_runtime::shading::library::write_to(&tmp.0).context("writing the shader library")?;
    let shader_dir = tmp.0.join("surface");
    let plastic = shader_dir.join("plastic.sl");
    let text = std::fs::read_to_string(&plastic).with_context(|| format!("reading {}", plastic.display()))?;
    let anchor = "Ci = Os * (";
    anyhow::ensure!(
        text.contains(anchor),
        "the library's plastic.sl no longer contains `{anchor}`, which the edits change"
    );

    // The default scene: plastic spheres on a plastic floor under a point light, made here so that
    // the benchmark needs no file of the source tree.
    let scene = match &args.scene {
        Some(scene) => scene.clone(),
        None => {
            let scene = tmp.0.join("reload.rib");
            std::fs::write(&scene, RELOAD_SCENE).with_context(|| format!("writing {}", scene.display()))?;
            scene
        }
    };
    let (mut rt, _) = super::render::load_scene(Some(&scene), std::slice::from_ref(&shader_dir), &[])?;
    (rt.options.width, rt.options.height) = args.size;
    let plastic_canon = plastic.canonicalize()?;
    anyhow::ensure!(
        rt.programs_by_id()
            .iter()
            .any(|(_, p)| p.path.as_ref().and_then(|p| p.canonicalize().ok()) == Some(plastic_canon.clone())),
        "{} does not use plastic from {}",
        scene.display(),
        shader_dir.display()
    );
    let (threads, pool) = super::worker_pool(args.threads)?;
    let frame = |rt: &mut rtsl_runtime::api::Context| -> anyhow::Result<(f64, Instant)> {
        let world = rt.build_world()?;
        let (fb, _) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
        rt.return_scene(world);
        Ok((frame_sum(&fb), Instant::now()))
    };
    let (mut previous, _) = frame(&mut rt)?;
    let quiet = args.quiet_ms.map_or(DEFAULT_QUIET, Duration::from_millis);
    let mut reloader = ShaderReloader::with_quiet(&rt, quiet)?;

    println!("scene: {}", scene.display());
    println!(
        "size: {}x{}, threads: {threads}, debounce: {:.0} ms, edits: {}",
        args.size.0,
        args.size.1,
        quiet.as_secs_f64() * 1e3,
        args.edits
    );
    let (mut total, mut detect, mut compile, mut apply, mut render) = (vec![], vec![], vec![], vec![], vec![]);
    for edit in 1..=args.edits {
        // Let the previous edit's trailing events and results settle, so they are not timed here.
        std::thread::sleep(Duration::from_millis(150));
        reloader.apply(&mut rt);
        // A different constant each time (consecutive edits always differ), so the code differs.
        let scale = 0.5 + (edit % 50) as f64 / 100.0;
        std::fs::write(&plastic, text.replace(anchor, &format!("Ci = Os * {scale:.2} * (")))
            .with_context(|| format!("writing {}", plastic.display()))?;
        let written = Instant::now();
        let reload = loop {
            let left = Duration::from_secs(10).saturating_sub(written.elapsed());
            anyhow::ensure!(!left.is_zero(), "edit {edit}: no reload within 10 s");
            let found = reloader.wait_apply(&mut rt, left).into_iter().find(|r| r.detected >= written);
            if let Some(r) = found {
                break r;
            }
        };
        let applied = Instant::now();
        let compile_time = reload.result.as_ref().map_err(|d| anyhow::anyhow!("edit {edit} did not compile:\n{d}"))?;
        let (sum, done) = frame(&mut rt)?;
        anyhow::ensure!(sum != previous, "edit {edit}: the frame after the reload does not use the new code");
        previous = sum;
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let parts = [
            ms(done - written),
            ms(reload.detected - written),
            ms(*compile_time),
            ms(applied - reload.detected) - ms(*compile_time),
            ms(done - applied),
        ];
        println!(
            "edit {edit}: {:.1} ms (detect {:.1}, compile {:.1}, hand-over {:.1}, frame {:.1})",
            parts[0], parts[1], parts[2], parts[3], parts[4]
        );
        for (v, p) in [&mut total, &mut detect, &mut compile, &mut apply, &mut render].into_iter().zip(parts) {
            v.push(p);
        }
    }
    drop(reloader);
    println!("latency_median_ms: {:.1}", median(total));
    println!("detect_median_ms: {:.1}", median(detect));
    println!("compile_median_ms: {:.1}", median(compile));
    println!("handover_median_ms: {:.1}", median(apply));
    println!("frame_median_ms: {:.1}", median(render));
    Ok(())
}

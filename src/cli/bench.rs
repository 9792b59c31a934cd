//! `rtsl bench trace`: the command-line side of the tracer benchmark. Parses the flags into
//! [`rtsl_runtime::BenchOptions`], runs [`rtsl_runtime::run_bench`] and prints one `name: value`
//! line per figure.

use anyhow::Context as _;
use rtsl_runtime::{run_bench, BenchOptions, BuildQuality};
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

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
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
    Ok((w, h))
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
    (o.width, o.height) = args.size;
    o.threads = args.threads;
    o.repeats = args.repeats.max(1);
    o.quality = args.quality;
    o.passes = args.passes;
    let r = run_bench(&o).with_context(|| format!("benchmark of {} failed", args.mesh.display()))?;
    let per_tri = r.memory_bytes as f64 / r.triangles.max(1) as f64;
    println!("mesh: {}", args.mesh.display());
    println!("triangles: {}", r.triangles);
    println!("threads: {}", r.threads);
    println!("load_ms: {:.1}", r.load_ms);
    println!("build_ms: {:.1}", r.build_ms);
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
    }
}

/// Flags of `rtsl bench render`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchRenderArgs {
    /// The scene (RIB or mesh; none: the default scene).
    pub scene: Option<PathBuf>,
    /// Timed frames (after one untimed warm-up frame); the median is reported.
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Image size, `WxH` (overrides the scene's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Samples per pixel (overrides the scene's).
    #[arg(long, default_value_t = 1)]
    pub samples: u32,
    /// Anti-aliasing mode (as `rtsl render --aa`).
    #[arg(long, value_parser = rtsl_runtime::render::Antialiasing::parse)]
    pub aa: Option<rtsl_runtime::render::Antialiasing>,
    /// Also render with every `plastic` replaced by hand-written Rust, alternating frame by frame,
    /// and print the JIT's cost as a ratio.
    #[arg(long)]
    pub native_plastic: bool,
    /// Directories searched for shaders by name.
    #[arg(short = 'S', long = "shader-path")]
    pub shader_path: Vec<PathBuf>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Runs `rtsl bench render`: frames per second and rays per second of a scene, and with
/// `--native-plastic` the JIT frame time over the hand-written one, measured in one run.
pub fn run_render(args: &BenchRenderArgs) -> anyhow::Result<()> {
    let (mut rt, _) = super::render::load_scene(args.scene.as_deref(), &args.shader_path, &[])?;
    if let Some((w, h)) = args.size {
        rt.options.width = w;
        rt.options.height = h;
    }
    rt.options.samples = super::render::samples_grid(args.samples);
    if let Some(aa) = args.aa {
        rt.options.antialiasing = aa;
    }
    let mut world = rt.build_world()?;
    let threads =
        if args.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { args.threads };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("starting the worker threads")?;
    let frames = args.frames.max(1);
    let jit_world = world.materials.clone();
    let native_count = if args.native_plastic { world.use_native_plastic() } else { 0 };
    let native_world = world.materials.clone();
    if args.native_plastic && native_count == 0 {
        anyhow::bail!("the scene has no plastic surface to compare");
    }
    let (mut jit_ms, mut native_ms) = (Vec::new(), Vec::new());
    let mut last = None;
    for frame in 0..=frames {
        for native in [false, true] {
            if native && !args.native_plastic {
                continue;
            }
            world.materials = if native { native_world.clone() } else { jit_world.clone() };
            let (_, report) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
            if frame > 0 {
                let ms = report.elapsed.as_secs_f64() * 1e3;
                if native {
                    native_ms.push(ms);
                } else {
                    jit_ms.push(ms);
                    last = Some(report);
                }
            }
        }
    }
    let report = last.unwrap_or_default();
    let ms = median(jit_ms);
    println!("scene: {}", args.scene.as_ref().map_or("<default scene>".into(), |p| p.display().to_string()));
    println!(
        "size: {}x{}, samples per pixel: {}, threads: {threads}",
        world.options.width, world.options.height, args.samples
    );
    println!("frame_ms: {ms:.2}");
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
    if args.native_plastic {
        let nms = median(native_ms);
        println!("native_plastic_frame_ms: {nms:.2} ({native_count} materials)");
        println!("jit_over_native: {:.3}", ms / nms.max(1e-9));
    }
    Ok(())
}

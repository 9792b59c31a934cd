//! `rtsl lightfield capture`: renders a two-plane light field of a scene with the engine itself (a
//! grid of cameras on the st plane, each seeing the uv square) and writes it as an image atlas for
//! the `twoplane` lightfield shader (docs/lightfields.md).

use super::bench::parse_vec3;
use anyhow::Context as _;
use rtsl_runtime::glam::Vec3A;
use rtsl_runtime::lightfield::{capture, LightfieldSpec};
use rtsl_runtime::render::MAX_PIXEL_SAMPLES;
use rtsl_runtime::{write_image, WriteOptions};
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `rtsl lightfield capture`.
#[derive(clap::Args, Debug, Clone)]
pub struct CaptureArgs {
    /// The scene to capture (RIB or mesh; none: the embedded default scene).
    pub scene: Option<PathBuf>,
    /// The atlas image to write (.png: 8-bit sRGB, or .exr).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Cameras along each side of the st square.
    #[arg(long, default_value_t = 8)]
    pub views: u32,
    /// Pixels along each side of a view.
    #[arg(long, default_value_t = 32)]
    pub view_size: u32,
    /// Samples per pixel of each view, on a square grid of this side (1 to 64, as `PixelSamples`).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_PIXEL_SAMPLES)))]
    pub samples: u32,
    /// Centre of the uv square, `X,Y,Z` (default: the centre of the scene's bounds).
    #[arg(long, value_parser = parse_vec3)]
    pub center: Option<[f32; 3]>,
    /// Half the side of the uv square (default: the radius of the scene's bounds).
    #[arg(long)]
    pub half_size: Option<f32>,
    /// Direction from the square towards the cameras, `X,Y,Z` (default: towards the scene's eye).
    #[arg(long, value_parser = parse_vec3)]
    pub toward: Option<[f32; 3]>,
    /// Distance from the uv plane to the st plane, in half sides.
    #[arg(long, default_value_t = 2.0)]
    pub distance: f32,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Directories searched for shaders by name (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
}

pub fn run_capture(args: &CaptureArgs) -> anyhow::Result<ExitCode> {
    if args.views < 2 || args.views > 64 || args.view_size == 0 || args.view_size > 1024 {
        anyhow::bail!("--views must be 2 to 64 and --view-size 1 to 1024");
    }
    if !(args.distance.is_finite() && args.distance > 0.0) {
        anyhow::bail!("--distance must be a positive number");
    }
    let sized = LightfieldSpec {
        views: args.views,
        view_size: args.view_size,
        ..LightfieldSpec::facing(Vec3A::ZERO, 1.0, Vec3A::Z, Vec3A::Y)
    };
    sized.atlas_side().map_err(|e| anyhow::anyhow!("--views {} --view-size {}: {e}", args.views, args.view_size))?;
    let (mut rt, _) = super::render::load_scene(args.scene.as_deref(), &args.shader_path, &[])?;
    let world = rt.build_world()?;
    let bounds = world.scene.bounds();
    let eye = world.camera.eye();
    let up = world.camera.world_from_camera.matrix3.y_axis;
    rt.return_scene(world);
    let (lo, hi) = bounds.context("the scene has no geometry to capture")?;
    let center = args.center.map(Vec3A::from).unwrap_or((lo + hi) * 0.5);
    let half = args.half_size.unwrap_or((hi - lo).length() * 0.5);
    if !(half.is_finite() && half > 0.0) {
        anyhow::bail!("--half-size must be a positive number");
    }
    let toward = args.toward.map(Vec3A::from).unwrap_or(eye - center);
    let mut spec = LightfieldSpec::facing(center, half, toward, up);
    spec.distance = args.distance;
    spec.views = args.views;
    spec.view_size = args.view_size;
    spec.samples = args.samples.max(1);
    let (_, pool) = super::worker_pool(args.threads)?;
    let start = std::time::Instant::now();
    let atlas = pool.install(|| capture(&mut rt, &spec, &mut |_, _| {}))?;
    let side = atlas.side as usize;
    write_image(&args.output, side, side, &atlas.rgba, &WriteOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let m = spec.world_from_object();
    let c = |v: Vec3A| format!("{} {} {}", v.x, v.y, v.z);
    println!(
        "{}: {}x{} views of {}x{} pixels in {:.2} s",
        args.output.display(),
        spec.views,
        spec.views,
        spec.view_size,
        spec.view_size,
        start.elapsed().as_secs_f64()
    );
    println!("# To show it, in RIB (the rectangle is the uv square):");
    println!(
        "ConcatTransform [{} 0 {} 0 {} 0 {} 1]",
        c(m.matrix3.x_axis),
        c(m.matrix3.y_axis),
        c(m.matrix3.z_axis),
        c(m.translation)
    );
    println!(
        "Surface \"twoplane\" \"lightfield\" \"{}\" \"nviews\" [{}] \"viewsize\" [{}] \"distance\" [{}]",
        args.output.display(),
        spec.views,
        spec.view_size,
        spec.distance
    );
    println!("Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]");
    Ok(ExitCode::SUCCESS)
}

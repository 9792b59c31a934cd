//! `rtsl render`: renders a RIB file, a mesh file, or (with no scene) the embedded default scene, and
//! writes the image, with a progress bar on a terminal and the frame's statistics at the end.

use anyhow::Context as _;
use rtsl_runtime::api::Context;
use rtsl_runtime::distributed::{Master, Transport};
use rtsl_runtime::image_io::{write_channels_as, ImageFormat, Quantize};
use rtsl_runtime::reload::{ShaderEvent, ShaderReloader, ShaderWatcher};
use rtsl_runtime::render::{
    render_frame, Antialiasing, DisplayMode, FrameReport, Framebuffer, World, MAX_PIXEL_SAMPLES,
};
use rtsl_runtime::shading::ParamValue;
use rtsl_runtime::{LoadedScene, Transfer, WriteOptions};
use std::collections::BTreeSet;
use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

/// Flags of `rtsl render`.
#[derive(clap::Args, Debug, Clone)]
pub struct RenderArgs {
    /// The scene: a RIB file, or a model (OBJ, PLY, glTF). Without one, the embedded default scene.
    pub scene: Option<PathBuf>,
    /// More RIB files, rendered after the first in turn (as `prman a.rib b.rib` does, e.g. one
    /// file a frame): their frames share compiled shaders, decoded textures and model files.
    #[arg(value_name = "MORE_RIB")]
    pub more_scenes: Vec<PathBuf>,
    /// The image to write (.png, .tif, .exr, .tga, .ppm), in place of the one a RIB's first
    /// `Display` names (its `+name` displays are written too). Of a file
    /// with several frames, `#f` in the name stands for the frame number (`#4f` padded to 4
    /// digits), as in `Display`.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Of a RIB file with several frames (`FrameBegin` blocks, or world blocks outside them), render
    /// only the one with this number (its `FrameBegin` number, or its place counting from 1).
    /// Without it, every frame is rendered in turn.
    #[arg(long)]
    pub frame: Option<i32>,
    /// Of a VRML scene, the library surface shader every shape gets instead of `material` (VRML's
    /// lighting model): e.g. `plastic`, `mirror`, `gimatte` (docs/vrml.md).
    #[arg(long, value_name = "SHADER")]
    pub vrml_surface: Option<String>,
    /// Of a VRML scene, the time its animation shows, in seconds from the load (with `--frame` or
    /// `--frames`, the time of frame 1).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0, value_parser = parse_time)]
    pub time: f64,
    /// Of a VRML scene, the frames to render, `A..B` (both included): frame N shows the time
    /// `--time + (N - 1) / --fps`, and `#f` in the image's name stands for N (`#4f` padded to 4
    /// digits). `--frame N` renders one.
    #[arg(long, value_name = "A..B", value_parser = parse_frame_range)]
    pub frames: Option<(i32, i32)>,
    /// Frames per second of a VRML animation's `--frame` and `--frames`.
    #[arg(long, default_value_t = 24.0, value_parser = parse_fps)]
    pub fps: f64,
    /// Image size, `WxH` (overrides the scene's `Format`).
    #[arg(long, value_parser = super::bench::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Samples per pixel (a square number is spread on a grid: 4 is 2x2; another number is one
    /// row; at most 64 a side, as `PixelSamples`; overrides `PixelSamples`).
    #[arg(long, value_parser = parse_samples)]
    pub samples: Option<u32>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Anti-aliasing: `regular` or `jittered` (the sample grid in every pixel), `interleaved`
    /// (quasi-Monte Carlo, Keller and Heidrich), or `adaptive[:THRESHOLD]` (one sample, more where
    /// neighbours differ; default threshold 0.05).
    #[arg(long, value_parser = Antialiasing::parse)]
    pub aa: Option<Antialiasing>,
    /// What adaptive anti-aliasing refines on, a comma-separated list of `color`, `object`,
    /// `shader` and `output:NAME` (an output variable of the surface shaders; default
    /// `color,object,shader`).
    #[arg(long, value_parser = rtsl_runtime::render::RefineOn::parse)]
    pub refine_on: Option<rtsl_runtime::render::RefineOn>,
    /// A camera shader by name (e.g. `fisheye`, `cylindrical`, `parabolic`, `thinlens`; see
    /// docs/cameras.md), with parameters after colons (`fisheye:fit=diagonal:fov=200`), replacing
    /// the scene's camera shader; the camera's placement stays.
    #[arg(long, value_parser = CameraSpec::parse)]
    pub camera: Option<CameraSpec>,
    /// Directories searched for `#include`d shader headers.
    #[arg(short = 'I', long = "include")]
    pub include: Vec<PathBuf>,
    /// Directories searched for shaders by name, before the standard library (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
    /// How 8-bit images (PNG, TGA, PPM) encode colour: `srgb` for display, or `linear` (the values
    /// as rendered). Without it, sRGB, except for RIB files (linear, as RenderMan writes, unless
    /// the file says `Option "image" "string transfer" "srgb"`) and scenes whose `Exposure`
    /// applies a gamma of their own. EXR is always linear.
    #[arg(long, value_parser = rtsl_runtime::Transfer::parse)]
    pub transfer: Option<Transfer>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
    /// Exit successfully even when part of the scene is missing from the image (a shader, texture,
    /// archive or model not found, a RIB request skipped); the warnings are printed either way.
    #[arg(long)]
    pub keep_going: bool,
    /// Keep running: re-render and rewrite the image whenever a shader source or header, the scene
    /// file, an archive, a model file or a texture changes.
    #[arg(long)]
    pub watch: bool,
    /// Render over the ranks of an `mpirun` job: rank 0 writes the image, the others render
    /// tiles (docs/distributed.md; needs a build with `--features mpi`).
    #[arg(long)]
    pub mpi: bool,
    #[command(flatten)]
    pub workers: super::mpi::WorkerArgs,
    #[command(flatten)]
    pub rays: super::ray_params::RayParamArgs,
}

/// A camera shader and parameter values, written `NAME[:PARAM=VALUE]...`: a value that reads as a
/// number is a float, any other a string (`fisheye:fit=diagonal:fov=200`).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSpec {
    pub name: String,
    pub params: Vec<(String, ParamValue)>,
}

impl CameraSpec {
    pub fn parse(spec: &str) -> Result<CameraSpec, String> {
        let mut parts = spec.split(':');
        let name = parts.next().unwrap_or_default().trim();
        if name.is_empty() {
            return Err(format!("`{spec}` names no camera shader"));
        }
        let params = parts
            .map(|p| {
                let (param, value) = p
                    .split_once('=')
                    .filter(|(n, _)| !n.trim().is_empty())
                    .ok_or_else(|| format!("`{p}` in `{spec}` is not PARAM=VALUE"))?;
                let value = value.trim();
                let value = value.parse::<f32>().map_or_else(|_| ParamValue::String(value.into()), ParamValue::Float);
                Ok((param.trim().to_string(), value))
            })
            .collect::<Result<_, String>>()?;
        Ok(CameraSpec { name: name.to_string(), params })
    }

    /// A name for reports: the spec with its separators as underscores (`fisheye_fit_diagonal`).
    pub fn label(&self) -> String {
        let mut label = self.name.clone();
        for (param, value) in &self.params {
            let value = match value {
                ParamValue::String(s) => s.clone(),
                ParamValue::Float(f) => f.to_string(),
                other => format!("{other:?}"),
            };
            label.extend(["_", param.as_str(), "_", value.as_str()]);
        }
        label.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
    }

    /// Makes this the context's camera shader.
    pub fn bind(&self, rt: &mut Context) -> anyhow::Result<()> {
        let id = rt.find_shader(&self.name)?;
        let params: Vec<(&str, ParamValue)> = self.params.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        rt.camera_shader(Some(id), &params).with_context(|| format!("camera shader `{}`", self.name))?;
        Ok(())
    }
}

/// Parses `--time`: a finite number of seconds.
pub(crate) fn parse_time(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(t) if t.is_finite() => Ok(t),
        _ => Err(format!("`{s}` is not a time in seconds")),
    }
}

fn parse_fps(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 => Ok(f),
        _ => Err(format!("`{s}` is not a frame rate above 0")),
    }
}

/// Parses `--frames A..B`: the first and last frame numbers, the first not after the last.
fn parse_frame_range(s: &str) -> Result<(i32, i32), String> {
    let (a, b) = s.split_once("..").ok_or_else(|| format!("`{s}` is not a range of frames A..B"))?;
    let number = |x: &str| x.trim().parse::<i32>().map_err(|_| format!("`{x}` in `{s}` is not a frame number"));
    let (a, b) = (number(a)?, number(b.trim_start_matches('='))?);
    if a > b {
        return Err(format!("`{s}`: the first frame comes after the last"));
    }
    Ok((a, b))
}

/// The time of a VRML scene's frame `number` (none: `--time` itself).
fn vrml_time(args: &RenderArgs, number: Option<i32>) -> f64 {
    args.time + number.map_or(0.0, |n| f64::from(n - 1) / args.fps)
}

/// Parses `--samples`: a count whose grid ([`samples_grid`]) has at most `MAX_PIXEL_SAMPLES` a
/// side, as RIB's `PixelSamples` has.
pub(crate) fn parse_samples(s: &str) -> Result<u32, String> {
    let n: u32 = s.trim().parse().map_err(|_| format!("`{s}` is not a count of samples"))?;
    let (sx, sy) = samples_grid(n);
    if n == 0 || sx > MAX_PIXEL_SAMPLES || sy > MAX_PIXEL_SAMPLES {
        let most = MAX_PIXEL_SAMPLES;
        return Err(format!(
            "{n} samples per pixel: at least 1, and a square number up to {} ({most}x{most}) or another number up to {most} (one row); RIB's PixelSamples takes at most {most} a side",
            most * most
        ));
    }
    Ok(n)
}

pub(crate) fn samples_grid(n: u32) -> (u32, u32) {
    let n = n.max(1);
    let side = (n as f64).sqrt().round() as u32;
    if u64::from(side) * u64::from(side) == u64::from(n) {
        (side, side)
    } else {
        (n, 1)
    }
}

/// Told how many of a frame's tiles are done, of how many.
type Progress<'a> = dyn Fn(usize, usize) + Sync + 'a;

/// Where `render` renders its frames: on this process's threads, or (`--mpi`, on rank 0) over the
/// worker ranks of an MPI job, which are sent each frame's scene.
struct Renderer {
    threads: usize,
    pool: rayon::ThreadPool,
    master: Option<Master<Box<dyn Transport>>>,
    /// The objects and mesh bytes of the scene last rendered over MPI, against which the summary
    /// sets what the workers fetched; measured once per scene ([`Renderer::next_scene`]).
    meshes: Option<(usize, usize)>,
    /// Whether the workers have been checked (after the first scene loads, so that a scene that
    /// fails to load is the first error).
    checked: bool,
}

impl Renderer {
    fn local(threads: usize, pool: rayon::ThreadPool) -> Renderer {
        Renderer { threads, pool, master: None, meshes: None, checked: true }
    }

    /// Rank 0's side of `--mpi`: greets the workers.
    fn over_mpi(
        transport: Box<dyn Transport>,
        threads: usize,
        pool: rayon::ThreadPool,
        settings: &super::mpi::WorkerArgs,
    ) -> anyhow::Result<Renderer> {
        let mut master = Master::connect(transport)?;
        settings.apply(&mut master);
        Ok(Renderer { threads, pool, master: Some(master), meshes: None, checked: false })
    }

    /// Checks, once, that the workers can render, and warns when there are none.
    fn check_workers(&mut self) -> anyhow::Result<()> {
        let Some(master) = self.master.as_ref().filter(|_| !self.checked) else { return Ok(()) };
        master.check_workers()?;
        if master.workers() == 0 {
            eprintln!(
                "warning: --mpi with no worker rank (run it with mpirun -n 2 or more): rendering on rank 0 alone"
            );
        }
        self.checked = true;
        Ok(())
    }

    /// Renders on the threads a frame's scene asks for (RIB `Option "limits" "threads"`), one a
    /// core where it asks for none; over MPI each rank keeps its own. For `rtsl render` without
    /// `--threads`, as `prman` lets its `-t` override the RIB.
    fn use_scene_threads(&mut self, wanted: Option<u32>) -> anyhow::Result<()> {
        use anyhow::Context as _;
        if self.master.is_some() {
            return Ok(());
        }
        let threads = super::thread_count(wanted.map_or(0, |n| (n as usize).min(super::MAX_THREADS)))?;
        if threads != self.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            self.pool = pool.context("starting the worker threads")?;
            self.threads = threads;
        }
        Ok(())
    }

    /// Another scene comes (a RIB file's next frame): its meshes are measured with its first frame.
    fn next_scene(&mut self) {
        self.meshes = None;
    }

    /// Renders a frame of `world`, which `rt` built; over MPI, the workers are first sent what
    /// changed in `rt` (all of it when `rt` is another context than the last frame's).
    fn render(
        &mut self,
        rt: &Context,
        world: &World,
        progress: &Progress<'_>,
    ) -> anyhow::Result<(Framebuffer, FrameReport)> {
        match self.master.as_mut().filter(|m| m.workers() > 0) {
            None => Ok(self.pool.install(|| render_frame(world, Some(progress)))),
            Some(master) => {
                let rendered = master.render_context(rt, world, Some(progress))?;
                self.meshes.get_or_insert_with(|| super::mpi::scene_meshes(world));
                Ok(rendered)
            }
        }
    }

    /// Prints a frame's summary: the image, its size and samples, who rendered it and the
    /// frame's report; over MPI, what travelled and what the workers fetched.
    fn summary(&self, rt: &Context, output: &Path, report: &FrameReport) {
        let Some(master) = &self.master else {
            return print_summary(rt, output, &format!("{} thread(s)", self.threads), report);
        };
        let ranks = format!("{} worker rank(s), {} thread(s) in all", master.workers(), master.worker_threads());
        print_summary(rt, output, &ranks, report);
        if master.workers() > 0 {
            println!("{}", super::mpi::traffic_line(&master.traffic()));
            let d = master.demand();
            let meshes = self.meshes.unwrap_or_default();
            println!("{}", super::mpi::demand_line("the frame", (&d).into(), meshes, &d, master.workers()));
        }
    }

    /// Tells the workers to stop.
    fn finish(self) -> anyhow::Result<()> {
        if let Some(master) = self.master {
            master.shutdown()?;
        }
        Ok(())
    }
}

/// The images a render writes, and how (a `--transfer` given, or the scene's).
struct Output {
    /// The first image (the scene's first display, or `-o`).
    first: Image,
    transfer: Option<Transfer>,
    /// More images of the frame (RIB `+name` displays).
    extra: Vec<Image>,
}

/// One image of a frame.
struct Image {
    path: PathBuf,
    /// The channels it holds.
    mode: DisplayMode,
    /// An output variable it holds instead of colour (a RIB arbitrary output variable).
    output: Option<String>,
    /// A shadow map (RIB `zfile` and `shadow` displays): depth and the camera's projection, as EXR
    /// whatever the name.
    depth_map: bool,
    /// The format its display driver asks for; `None`: the one its extension names.
    format: Option<ImageFormat>,
}

impl Image {
    fn file(path: PathBuf) -> Image {
        Image { path, mode: DisplayMode::Rgba, output: None, depth_map: false, format: None }
    }

    /// The format it is written in.
    fn format(&self) -> Option<ImageFormat> {
        self.format.or_else(|| ImageFormat::from_path(&self.path))
    }
}

impl Output {
    fn images(&self) -> impl Iterator<Item = &Image> {
        std::iter::once(&self.first).chain(&self.extra)
    }
}

/// Refuses, before rendering, an image that cannot be written: an unknown format, depth in a
/// format that stores no floats, a shadow map from a camera no matrix describes.
fn check_image(rt: &Context, image: &Image) -> anyhow::Result<()> {
    let path = &image.path;
    if image.depth_map {
        if rt.depth_map_projection().is_none() {
            anyhow::bail!(
                "{}: a shadow map needs the built-in perspective camera or Projection \"orthographic\", not a \
                 camera shader",
                path.display()
            );
        }
        return Ok(());
    }
    match image.format() {
        None => anyhow::bail!("{}: unsupported image format (known: .png .tga .ppm .tif .exr)", path.display()),
        Some(ImageFormat::Exr) => Ok(()),
        Some(ImageFormat::Tiff) if image.mode == DisplayMode::Z => Ok(()),
        Some(_) if image.mode.has_depth() => {
            anyhow::bail!("{}: depth needs a float image (.exr, or .tif for depth alone)", path.display())
        }
        Some(_) => Ok(()),
    }
}

/// What rendering and writing a frame reported.
struct Written {
    report: FrameReport,
    /// Textures that could not be read.
    missing_textures: usize,
    /// Every file the frame's textures were read from.
    texture_files: Vec<PathBuf>,
}

/// Renders the context's scene with `renderer` and writes `output`; prints warnings (those of
/// values a reloaded shader no longer takes only with `frame_warnings`: `--watch` prints them once
/// per reload, from the reload's events).
fn render_and_write(
    rt: &mut Context,
    renderer: &mut Renderer,
    output: &Output,
    quiet: bool,
    frame_warnings: bool,
) -> anyhow::Result<Written> {
    // Depth and object ids only where an image holds depth: the frame's tiles then travel
    // without them when the render is distributed.
    rt.options.depth_and_ids = output.images().any(|image| image.depth_map || image.mode.has_depth());
    let world = rt.build_world()?;
    for w in rt.take_warnings() {
        if frame_warnings {
            eprintln!("warning: {w}");
        }
    }
    let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} tiles, {elapsed}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let progress = |done: usize, total: usize| {
        if let Some(b) = &bar {
            b.set_length(total as u64);
            b.set_position(done as u64);
        }
    };
    let rendered = renderer.render(rt, &world, &progress);
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let (fb, report) = rendered?;
    let missing_textures = world.textures.take_warnings();
    for w in &missing_textures {
        eprintln!("warning: {w}");
    }
    for m in &report.shader_messages {
        eprintln!("warning: {m}");
    }
    for w in report.warnings() {
        eprintln!("warning: {w}");
    }
    let texture_files = world.textures.files();
    rt.return_scene(world);
    let transfer = output.transfer.unwrap_or_else(|| rt.options.transfer());
    let images: Vec<&Image> = output.images().collect();
    // Displays that name one EXR file are layers of it, written once with the first.
    let mut layered: Vec<&PathBuf> = Vec::new();
    for (i, image) in images.iter().enumerate() {
        let path = &image.path;
        if layered.contains(&path) {
            continue;
        }
        if image.depth_map {
            let (world_to_camera, world_to_ndc) =
                rt.depth_map_projection().context("a shadow map needs a camera a matrix describes")?;
            let (w, h) = (fb.width as usize, fb.height as usize);
            rtsl_runtime::texture::write_shadow_map(path, &fb.depth, w, h, world_to_camera, world_to_ndc)
                .with_context(|| format!("writing {}", path.display()))?;
            continue;
        }
        let format = image.format().with_context(|| format!("{}: unsupported image format", path.display()))?;
        let float = Quantize { one: 0.0, min: 0.0, max: 0.0, dither: 0.0 };
        let quantize = if image.mode.has_depth() { Some(float) } else { rt.options.quantize };
        let opts = WriteOptions { transfer, quantize, ..WriteOptions::default() };
        let (mut names, mut values) = display_channels(&fb, image.mode, image.output.as_deref());
        if format == ImageFormat::Exr {
            for other in &images[i + 1..] {
                if other.path != *path || other.depth_map {
                    continue;
                }
                let (more, more_values) = display_channels(&fb, other.mode, other.output.as_deref());
                let layer = other.output.as_deref().unwrap_or(other.mode.name());
                values = interleave(&values, names.len(), &more_values, more.len());
                names.extend(more.iter().map(|c| format!("{layer}.{c}")));
            }
            layered.push(path);
        }
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        write_channels_as(path, format, fb.width as usize, fb.height as usize, &names, &values, &opts)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(Written { report, missing_textures: missing_textures.len(), texture_files })
}

/// The channels of a display: `mode`'s, or an output variable's as RGB.
fn display_channels(
    fb: &rtsl_runtime::render::Framebuffer,
    mode: DisplayMode,
    variable: Option<&str>,
) -> (Vec<String>, Vec<f32>) {
    let (names, values) = match variable {
        Some(name) => {
            let values = fb.output(name).map_or_else(|| vec![0.0; 3 * fb.depth.len()], |v| v.as_flattened().to_vec());
            (&["R", "G", "B"][..], values)
        }
        None => fb.channels(mode),
    };
    (names.iter().map(|n| n.to_string()).collect(), values)
}

/// Two images' interleaved channels, `a` of `na` a pixel and `b` of `nb`, as one of `na + nb`.
fn interleave(a: &[f32], na: usize, b: &[f32], nb: usize) -> Vec<f32> {
    a.chunks_exact(na.max(1)).zip(b.chunks_exact(nb.max(1))).flat_map(|(x, y)| x.iter().chain(y).copied()).collect()
}

/// The exit status of a render that wrote its image with `omissions` parts of the scene missing
/// (requests skipped, files not found): a failure unless `keep_going`, so that a pipeline notices.
fn exit_status(omissions: usize, keep_going: bool) -> ExitCode {
    if omissions == 0 {
        return ExitCode::SUCCESS;
    }
    let parts = if omissions == 1 { "part" } else { "parts" };
    if keep_going {
        eprintln!("warning: {omissions} {parts} of the scene missing from the image (see the warnings above)");
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "error: {omissions} {parts} of the scene missing from the image (see the warnings above); \
             the image was written, and --keep-going accepts it"
        );
        ExitCode::FAILURE
    }
}

/// The files `--watch` watches besides shaders: the scene's own (the scene file, archives, model
/// files and, beside an OBJ file, the material libraries it may name) and the textures read.
fn scene_inputs(scene: &[PathBuf], textures: &[PathBuf]) -> (BTreeSet<PathBuf>, BTreeSet<PathBuf>) {
    let mut files: BTreeSet<PathBuf> = scene.iter().cloned().collect();
    for obj in scene.iter().filter(|f| f.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"))) {
        let dir = obj.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let Ok(entries) = std::fs::read_dir(dir) else { continue };
        files.extend(
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("mtl"))),
        );
    }
    let canonical = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
    (files.iter().map(canonical).collect(), textures.iter().map(canonical).collect())
}

/// How long `--watch` waits for more events of one save of a scene file or texture (editors and
/// exporters write in bursts).
const BURST: Duration = Duration::from_millis(100);

/// `--watch`: shaders are recompiled off the render thread as their sources or headers change
/// ([`ShaderReloader`]); the scene is loaded again when its file, an archive or a model file
/// changes, and textures are read again when theirs do. After each batch of changes the image is
/// rendered and rewritten, and each prints one line: the shader and its compile time, or the
/// scene, or the textures, and the frame time. A change that does not compile or load prints its
/// diagnostics, and the last good shader or scene stays. Runs until interrupted. A scene loaded
/// again takes the shaders and texture files that did not change from `caches`.
#[allow(clippy::too_many_arguments)]
fn watch(
    args: &RenderArgs,
    (frame_index, caches): (usize, &SharedCaches),
    rt: &mut Context,
    renderer: &mut Renderer,
    output: &Output,
    scene_files: &[PathBuf],
    texture_files: &[PathBuf],
) -> anyhow::Result<()> {
    let mut reloader = ShaderReloader::new(rt)?;
    let (mut scene, mut textures) = scene_inputs(scene_files, texture_files);
    let mut watcher = ShaderWatcher::for_files(scene.iter().chain(&textures).cloned())?;
    println!(
        "watching {} shader file(s), {} scene file(s) and {} texture(s); Ctrl-C to stop",
        reloader.watched_files(),
        scene.len(),
        textures.len()
    );
    loop {
        let reloads = reloader.wait_apply(rt, Duration::from_millis(250));
        let mut changed = watcher.poll();
        if !changed.is_empty() {
            changed.extend(watcher.wait(BURST, BURST));
        }
        if reloads.is_empty() && changed.is_empty() {
            anyhow::ensure!(reloader.is_running(), "the shader reload thread stopped");
            continue;
        }
        let mut done = Vec::new();
        let scene_changed: Vec<&PathBuf> = changed.iter().filter(|f| scene.contains(*f)).collect();
        if !scene_changed.is_empty() {
            match prepare(args, frame_index, caches) {
                // A half-typed edit is not a scene to show.
                Ok(prepared) if prepared.errors > 0 => {
                    eprintln!("error: the scene has syntax errors (above); the last good scene stays")
                }
                Ok(prepared) => {
                    *rt = prepared.rt;
                    reloader = ShaderReloader::new(rt)?;
                    scene = scene_inputs(&prepared.files, &[]).0;
                    watcher = ShaderWatcher::for_files(scene.iter().chain(&textures).cloned())?;
                    let names: Vec<String> = scene_changed.iter().map(|f| f.display().to_string()).collect();
                    done.push(format!("scene ({})", names.join(", ")));
                }
                Err(e) => eprintln!("error: {e:#}\nthe last good scene stays"),
            }
        } else if changed.iter().any(|f| textures.contains(f)) {
            rt.reload_textures();
            done.push(format!("{} texture(s)", changed.len()));
        }
        for e in rt.take_shader_events() {
            if let ShaderEvent::ParameterDropped { .. } = e {
                eprintln!("warning: {e}");
            }
        }
        for r in reloads.iter().filter(|r| r.result.is_err()) {
            eprintln!("{r}");
        }
        if scene_changed.is_empty() {
            for r in &reloads {
                if let Ok(compile) = &r.result {
                    done.push(format!("{}: compile {:.1} ms", r.name, compile.as_secs_f64() * 1e3));
                }
            }
        }
        if done.is_empty() {
            continue;
        }
        let written = render_and_write(rt, renderer, output, true, false)?;
        // What the scenes and edits before this one read and this one did not is let go.
        caches.end_frame();
        let frame_ms = written.report.elapsed.as_secs_f64() * 1e3;
        for what in done {
            println!("reloaded {what}, frame {frame_ms:.1} ms -> {}", output.first.path.display());
        }
        let (_, now) = scene_inputs(&[], &written.texture_files);
        if !now.is_subset(&textures) {
            textures.extend(now);
            watcher.add_files(textures.iter().cloned())?;
        }
    }
}

/// Makes a context with the search paths of the flags and the environment, and loads the scene (or
/// the default scene) into it, printing the loader's warnings; returns the context and what the
/// load reported besides (the output file the scene names, how much of it is missing).
pub(crate) fn load_scene(
    scene: Option<&Path>,
    shader_path: &[PathBuf],
    include: &[PathBuf],
) -> anyhow::Result<(Context, LoadedScene)> {
    load_scene_frame(scene, shader_path, include, 0, &rtsl_runtime::LoadOptions::default())
}

/// [`load_scene`] of the image at `frame_index` (counting from 0) of a scene with several.
pub(crate) fn load_scene_frame(
    scene: Option<&Path>,
    shader_path: &[PathBuf],
    include: &[PathBuf],
    frame_index: usize,
    options: &rtsl_runtime::LoadOptions,
) -> anyhow::Result<(Context, LoadedScene)> {
    load_scene_into(new_context(shader_path, include), scene, frame_index, options)
}

/// [`load_scene_frame`] into `rt`.
fn load_scene_into(
    mut rt: Context,
    scene: Option<&Path>,
    frame_index: usize,
    options: &rtsl_runtime::LoadOptions,
) -> anyhow::Result<(Context, LoadedScene)> {
    let loaded = match scene {
        None => {
            let rib = rtsl::default_scene::load(&mut rt)?;
            LoadedScene {
                display: rib.display,
                displays: rib.displays,
                warnings: rib.warnings,
                files: Vec::new(),
                frames: rib.frames,
                frame_number: rib.frame_number,
                vrml: None,
            }
        }
        Some(path) => rtsl_runtime::load_scene_with(&mut rt, path, frame_index, options)?,
    };
    rtsl_runtime::rib::report::write_diagnostics(&loaded.warnings, &mut super::color::stderr())?;
    Ok((rt, loaded))
}

/// What the contexts of one `rtsl render` share: compiled shaders, what they made of files
/// (decoded textures, parsed model files) and object BVHs: each frame of a RIB file, each reload
/// of a watched scene, is a context of its own.
struct SharedCaches {
    shaders: std::sync::Arc<rtsl_runtime::api::ShaderCache>,
    files: std::sync::Arc<rtsl_runtime::shared_files::SharedFiles>,
    bvhs: std::sync::Arc<rtsl_runtime::accel::store::BvhStore>,
}

impl SharedCaches {
    fn new() -> SharedCaches {
        SharedCaches { shaders: Default::default(), files: Default::default(), bvhs: Default::default() }
    }

    /// A frame was rendered: what the frames before it made and it did not use is let go.
    fn end_frame(&self) {
        self.files.end_frame();
        self.bvhs.end_frame();
    }

    /// A context with the search paths of the flags and the environment, sharing these caches.
    fn context(&self, args: &RenderArgs) -> Context {
        let mut rt = new_context(&args.shader_path, &args.include);
        rt.share_shader_cache(self.shaders.clone());
        rt.share_files(self.files.clone());
        rt.share_bvhs(self.bvhs.clone());
        rt
    }
}

/// A context with the search paths of the flags and the environment.
pub(crate) fn new_context(shader_path: &[PathBuf], include: &[PathBuf]) -> Context {
    let mut rt = Context::new();
    for dir in shader_path.iter().filter(|d| !d.as_os_str().is_empty() && !d.is_dir()) {
        eprintln!("warning: shader search directory {} does not exist", dir.display());
    }
    let mut search: Vec<PathBuf> = shader_path.to_vec();
    if let Ok(env) = std::env::var("RTSL_SHADER_PATH") {
        search.extend(std::env::split_paths(&env));
    }
    rt.set_shader_search_path(search);
    rt.set_include_paths(include.to_vec());
    rt
}

/// A scene loaded with the flags applied.
struct Prepared {
    rt: Context,
    output: Output,
    /// How many parts of the scene are missing (see [`LoadedScene::omissions`]).
    omissions: usize,
    /// How many requests of the scene could not be read (see [`LoadedScene::errors`]).
    errors: usize,
    /// The files it was read from.
    files: Vec<PathBuf>,
    /// A VRML scene's graph and events, advanced to the time asked for.
    vrml: Option<Box<rtsl_runtime::vrml::VrmlScene>>,
}

/// Refuses the flags that animate VRML scenes for other scenes.
fn check_animation_flags(args: &RenderArgs) -> anyhow::Result<()> {
    let vrml = args.scene.as_deref().is_some_and(rtsl_runtime::vrml::is_vrml_path);
    if !vrml && (args.frames.is_some() || args.time != 0.0) {
        anyhow::bail!("--time and --frames animate VRML scenes; a RIB file's frames are chosen with --frame");
    }
    Ok(())
}

/// The frames to render, as indices into the scene's frames: the one `--frame` names, or all.
fn frame_indices(args: &RenderArgs) -> anyhow::Result<Vec<usize>> {
    check_animation_flags(args)?;
    if args.scene.as_deref().is_some_and(rtsl_runtime::vrml::is_vrml_path) {
        // One load; the frames are times of its animation (`run_vrml`).
        return Ok(vec![0]);
    }
    let numbers = match &args.scene {
        Some(path) if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rib")) => {
            rtsl_runtime::rib::load::frame_numbers(path)?
        }
        _ => vec![1],
    };
    let Some(wanted) = args.frame else { return Ok((0..numbers.len()).collect()) };
    match numbers.iter().position(|&n| n == wanted) {
        Some(index) => Ok(vec![index]),
        None => {
            let known: Vec<String> = numbers.iter().map(i32::to_string).collect();
            anyhow::bail!("there is no frame {wanted}; the scene's frames are {}", known.join(", "))
        }
    }
}

/// Loads the image at `frame_index` of the scene and applies the flags to it.
fn prepare(args: &RenderArgs, frame_index: usize, caches: &SharedCaches) -> anyhow::Result<Prepared> {
    let options = rtsl_runtime::LoadOptions { vrml_surface: args.vrml_surface.clone() };
    let (rt, loaded) = load_scene_into(caches.context(args), args.scene.as_deref(), frame_index, &options)?;
    prepare_loaded(args, rt, loaded)
}

/// Applies the flags to a scene loaded (its warnings printed).
fn prepare_loaded(args: &RenderArgs, mut rt: Context, mut loaded: LoadedScene) -> anyhow::Result<Prepared> {
    let mut vrml = loaded.vrml.take();
    if let Some(scene) = vrml.as_mut() {
        scene.advance_to(vrml_time(args, args.frame.or(args.frames.map(|(first, _)| first))), &mut rt)?;
        print_animation_warnings(scene)?;
    }
    let expanded = |p: &PathBuf| {
        PathBuf::from(rtsl_runtime::rib::load::expand_display_name(&p.to_string_lossy(), loaded.frame_number))
    };
    let mut files = loaded.displays.iter().filter(|d| !d.window).map(|d| Image {
        path: d.name.clone(),
        mode: d.mode,
        depth_map: d.depth_map,
        output: d.output.clone(),
        format: d.format,
    });
    let mut to_default = false;
    let first = match args.output.as_ref().map(expanded) {
        Some(path) => {
            // `-o` names the scene's own image instead of its first display, not beside it; its
            // `+name` displays are written as well.
            if loaded.displays.first().is_some_and(|d| !d.window) {
                files.next();
            }
            Image::file(path)
        }
        None => files.next().unwrap_or_else(|| {
            to_default = true;
            Image::file(PathBuf::from("render.png"))
        }),
    };
    // A batch render never opens a window (it would wait for the window to close, in a script or
    // a farm as anywhere): one note for the frame's window displays, whatever else it writes.
    if let Some(window) = loaded.displays.iter().find(|d| d.window) {
        let rest = if to_default { "the image goes to render.png" } else { "it is left out" };
        eprintln!(
            "note: `Display \"{}\"` is a window, which rtsl render does not open (rtsl view does); {rest}",
            window.name.display()
        );
    }
    let extra: Vec<Image> = files.collect();
    if let Some((w, h)) = args.size {
        rt.options.width = w;
        rt.options.height = h;
    }
    if let Some(n) = args.samples {
        rt.options.samples = samples_grid(n);
    }
    if let Some(aa) = args.aa {
        rt.options.antialiasing = aa;
    }
    if let Some(on) = &args.refine_on {
        rt.options.refine_on = on.clone();
    }
    if let Some(camera) = &args.camera {
        camera.bind(&mut rt)?;
    }
    args.rays.apply(&mut rt)?;
    let output = Output { first, transfer: args.transfer, extra };
    // Refused before rendering, not after.
    for image in output.images() {
        check_image(&rt, image)?;
    }
    Ok(Prepared { rt, output, omissions: loaded.omissions(), errors: loaded.errors(), files: loaded.files, vrml })
}

/// Prints what running a VRML scene's animation found (routes' events dropped, lights that stay),
/// as the loader's warnings are printed.
fn print_animation_warnings(scene: &mut rtsl_runtime::vrml::VrmlScene) -> anyhow::Result<()> {
    rtsl_runtime::rib::report::write_diagnostics(&scene.take_warnings(), &mut super::color::stderr())?;
    Ok(())
}

/// `render` of a VRML scene's `--frames` (or `--frame`): loaded once, its animation advanced to
/// each frame's time, each image named with the frame's number. Over MPI the workers follow the
/// one context from frame to frame (they are sent what the animation changed).
fn run_vrml(args: &RenderArgs, renderer: &mut Renderer, caches: &SharedCaches) -> anyhow::Result<ExitCode> {
    let numbers: Vec<i32> = match (args.frames, args.frame) {
        (Some(_), Some(_)) => anyhow::bail!("--frame and --frames: choose one"),
        (Some((a, b)), None) => (a..=b).collect(),
        (None, Some(n)) => vec![n],
        (None, None) => unreachable!("run_vrml renders frames"),
    };
    let Prepared { mut rt, mut output, omissions, vrml, .. } = prepare(args, 0, caches)?;
    renderer.check_workers()?;
    let mut vrml = vrml.context("not a VRML scene")?;
    let pattern = args.output.clone().unwrap_or_else(|| PathBuf::from("render.png"));
    let mut missing = omissions;
    let mut written_paths = BTreeSet::new();
    for n in numbers {
        output.first.path = PathBuf::from(rtsl_runtime::rib::load::expand_display_name(&pattern.to_string_lossy(), n));
        if !written_paths.insert(output.first.path.clone()) {
            anyhow::bail!(
                "frame {n} would overwrite {} of an earlier frame: name the images with #f (as in `-o frame.#4f.png`)",
                output.first.path.display()
            );
        }
        vrml.advance_to(vrml_time(args, Some(n)), &mut rt)?;
        print_animation_warnings(&mut vrml)?;
        let written = render_and_write(&mut rt, renderer, &output, args.quiet, true)?;
        if !args.quiet {
            renderer.summary(&rt, &output.first.path, &written.report);
        }
        missing += written.missing_textures;
    }
    Ok(exit_status(missing, args.keep_going))
}

/// `rtsl render`. With `--mpi`, rank 0 loads each frame's scene, renders it over the other ranks
/// and writes its images as one process would; the other ranks start empty, are sent each
/// frame's scene (a RIB file's next frame is another scene: they start again from empty for it)
/// and render tiles (docs/distributed.md). With `--watch`, the frame is rendered again after each
/// reload (over MPI, reloaded shaders and scenes travel with the frame).
pub fn run(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    let (threads, pool) = super::worker_pool(args.threads)?;
    let mut renderer = if args.mpi {
        // A worker reads nothing of the scene, not even its list of frames.
        let transport = super::mpi::transport()?;
        if transport.rank() != 0 {
            return super::mpi::work(&*transport, &pool, &args.workers);
        }
        Renderer::over_mpi(transport, threads, pool, &args.workers)?
    } else {
        Renderer::local(threads, pool)
    };
    check_animation_flags(args)?;
    if args.watch && args.frames.is_some_and(|(a, b)| a != b) {
        anyhow::bail!("--watch renders one frame: choose it with --frame");
    }
    let ribs: Vec<&Path> = args.scene.iter().chain(&args.more_scenes).map(PathBuf::as_path).collect();
    if !args.more_scenes.is_empty() {
        if let Some(other) = ribs.iter().find(|p| !rtsl_runtime::is_rib_path(p)) {
            anyhow::bail!(
                "{}: several scenes are RIB files, rendered in turn; render other scenes one at a time",
                other.display()
            );
        }
        if args.watch || args.frame.is_some() {
            anyhow::bail!("--watch and --frame take one scene file");
        }
    }
    let vrml = args.scene.as_deref().is_some_and(rtsl_runtime::vrml::is_vrml_path);
    let caches = SharedCaches::new();
    let status = if vrml && (args.frames.is_some() || args.frame.is_some()) && !args.watch {
        run_vrml(args, &mut renderer, &caches)?
    } else if !ribs.is_empty() && rtsl_runtime::is_rib_path(ribs[0]) && !args.watch {
        run_rib_frames(args, &ribs, &mut renderer, &caches)?
    } else {
        let frames = frame_indices(args)?;
        if args.watch && frames.len() > 1 {
            anyhow::bail!("the scene has {} frames and --watch renders one: choose it with --frame", frames.len());
        }
        run_frames(args, &frames, &mut renderer, &caches)?
    };
    renderer.finish()?;
    Ok(status)
}

/// Renders the frames of RIB files in turn (or the one `--frame` names), each file as it is read,
/// in one reading of it: each frame is loaded into a context of its own as soon as its last request
/// is read, rendered and its images written before the file is read further. The contexts share
/// their compiled shaders, decoded textures and parsed model files, across the files too.
fn run_rib_frames(
    args: &RenderArgs,
    paths: &[&Path],
    renderer: &mut Renderer,
    caches: &SharedCaches,
) -> anyhow::Result<ExitCode> {
    let mut missing = 0;
    let mut written_paths = BTreeSet::new();
    for path in paths {
        let mut rendered = false;
        let images = rtsl_runtime::load_rib_frames(
            path,
            || caches.context(args),
            |_, number| args.frame.is_none_or(|wanted| wanted == number),
            |_, rt, loaded| -> anyhow::Result<ControlFlow<()>> {
                rtsl_runtime::rib::report::write_diagnostics(&loaded.warnings, &mut super::color::stderr())?;
                let number = loaded.frame_number;
                let Prepared { mut rt, output, omissions, .. } = prepare_loaded(args, rt, loaded)?;
                let frame = (&mut rt, &output, number);
                let written = render_frame_images(args, frame, renderer, caches, &mut written_paths)?;
                missing += omissions + written.missing_textures;
                rendered = true;
                // `--frame` names one frame: the rest of the file is not read.
                Ok(if args.frame.is_some() { ControlFlow::Break(()) } else { ControlFlow::Continue(()) })
            },
        )?;
        rtsl_runtime::rib::report::write_diagnostics(&images.warnings, &mut super::color::stderr())?;
        missing += images.warnings.iter().filter(|d| d.severity >= rtsl_runtime::rib::Severity::Omission).count();
        if let (Some(wanted), false) = (args.frame, rendered) {
            let known: Vec<String> = images.numbers.iter().map(i32::to_string).collect();
            anyhow::bail!("there is no frame {wanted}; the scene's frames are {}", known.join(", "))
        }
    }
    Ok(exit_status(missing, args.keep_going))
}

/// Renders a frame (its context, its images and its number) as a scene of its own, refusing
/// images that would overwrite an earlier frame's, writes its images and prints its summary; what
/// the frames before it read of files and this one did not is let go from `caches`.
fn render_frame_images(
    args: &RenderArgs,
    (rt, output, number): (&mut Context, &Output, i32),
    renderer: &mut Renderer,
    caches: &SharedCaches,
    written_paths: &mut BTreeSet<PathBuf>,
) -> anyhow::Result<Written> {
    renderer.check_workers()?;
    renderer.next_scene();
    if args.threads == 0 {
        renderer.use_scene_threads(rt.options.threads)?;
    }
    check_unwritten(output, number, written_paths)?;
    let written = render_and_write(rt, renderer, output, args.quiet, true)?;
    if !args.quiet {
        renderer.summary(rt, &output.first.path, &written.report);
    }
    caches.end_frame();
    Ok(written)
}

/// Refuses a frame whose images would overwrite an earlier frame's (a frame's displays may share
/// a file, as EXR layers; another frame's may not), and notes them as written.
fn check_unwritten(output: &Output, number: i32, written: &mut BTreeSet<PathBuf>) -> anyhow::Result<()> {
    let this_frame: BTreeSet<PathBuf> = output.images().map(|image| image.path.clone()).collect();
    for path in &this_frame {
        if !written.insert(path.clone()) {
            anyhow::bail!(
                "frame {number} would overwrite {} of an earlier frame: name the images with #f (as in \
                 `-o frame.#4f.png`) or choose one frame with --frame",
                path.display()
            );
        }
    }
    Ok(())
}

/// Renders the scene's frames at `frames` (indices into its frames) in turn, each loaded into a
/// context of its own just before it renders, and writes each frame's images; with `--watch`,
/// then watches the one frame.
fn run_frames(
    args: &RenderArgs,
    frames: &[usize],
    renderer: &mut Renderer,
    caches: &SharedCaches,
) -> anyhow::Result<ExitCode> {
    let mut missing = 0;
    let mut written_paths = BTreeSet::new();
    for &index in frames {
        let Prepared { mut rt, output, omissions, files, .. } = prepare(args, index, caches)?;
        let frame = (&mut rt, &output, index as i32 + 1);
        let written = render_frame_images(args, frame, renderer, caches, &mut written_paths)?;
        missing += omissions + written.missing_textures;
        if args.watch {
            // Watching is interactive: what is missing may be fixed by the next edit.
            let status = exit_status(missing, true);
            watch(args, (index, caches), &mut rt, renderer, &output, &files, &written.texture_files)?;
            return Ok(status);
        }
    }
    Ok(exit_status(missing, args.keep_going))
}

fn print_summary(rt: &Context, output: &Path, threads: &str, report: &FrameReport) {
    println!("{}: {}x{}, {} sample(s) per pixel, {threads}", output.display(), rt.options.width, rt.options.height, {
        let (sx, sy) = rt.options.pixel_samples();
        sx * sy
    },);
    println!("{report}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_specs_read_numbers_as_floats_and_anything_else_as_strings() {
        let spec = CameraSpec::parse("fisheye:fit=diagonal:fov=200").expect("a valid spec");
        assert_eq!(spec.name, "fisheye");
        assert_eq!(
            spec.params,
            vec![
                ("fit".to_string(), ParamValue::String("diagonal".into())),
                ("fov".to_string(), ParamValue::Float(200.0))
            ]
        );
        assert_eq!(spec.label(), "fisheye_fit_diagonal_fov_200");
        assert_eq!(CameraSpec::parse("thinlens").map(|s| s.params.len()), Ok(0));
        for bad in ["", ":fov=1", "fisheye:fov", "fisheye:=3"] {
            assert!(CameraSpec::parse(bad).is_err(), "`{bad}` is not a camera spec");
        }
    }
}

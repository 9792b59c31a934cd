//! Subcommands of the `rtsl` binary.

mod bart;
mod bench;
mod color;
mod compile;
mod info;
mod lightfield;
mod mpi;
mod preview;
mod ray_params;
mod render;
mod shade;
mod view;
mod volume;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(name = "rtsl", version, about = "A RenderMan-like shading language and interactive ray tracer")]
struct Cli {
    /// When diagnostics are coloured: `auto` (on a terminal, unless NO_COLOR is set), `always` or
    /// `never`.
    #[arg(long, global = true, value_enum, default_value_t = color::When::Auto)]
    color: color::When,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene (a RIB file or a mesh; with none, the embedded default scene) to an image.
    Render(render::RenderArgs),
    /// Run a shader of any type over a grid of points with no scene and write its results as images
    /// (like OSL's testshade).
    Shade(shade::ShadeArgs),
    /// Render a surface or displacement shader on a ball on a floor (a shader-ball preview).
    Preview(preview::PreviewArgs),
    /// Check shaders (files, or directories searched recursively for `.sl` files), and with `-o`
    /// write a compiled library: one artifact per shader and an `index.json`.
    Compile(compile::CompileArgs),
    /// Show the type, name and parameters of shaders (files, directories or names), like sloinfo.
    Info(info::InfoArgs),
    /// Play a BART animated scene (an AFF file) at its own timing: write the frames, print per-frame times.
    Bart(bart::BartArgs),
    /// Two-plane light fields: `capture` renders one of a scene for the `twoplane` shader.
    #[command(subcommand)]
    Lightfield(LightfieldCommand),
    /// Volume data sets for the `volumegrid` shader.
    #[command(subcommand)]
    Volume(VolumeCommand),
    /// Open a window showing the scene, rendered continuously: orbit, fly, pick and move objects;
    /// progressive or frameless rendering; shaders reload as they are edited.
    View(view::ViewArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand, Debug)]
enum LightfieldCommand {
    /// Render a light field of a scene (a grid of cameras on the st plane) to an image atlas.
    Capture(lightfield::CaptureArgs),
}

#[derive(Subcommand, Debug)]
enum VolumeCommand {
    /// Write a small synthetic 3-D grid (an RTSLGRID file, docs/volumes.md).
    Generate(volume::GenerateArgs),
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// Front-end throughput: lines per second from source to checked IR, on one thread.
    Frontend(compile::BenchFrontendArgs),
    /// Ray tracing throughput on a mesh: packet and single-ray traversal, primary and shadow rays.
    Trace(bench::BenchTraceArgs),
    /// Rendering speed of a scene: frames and rays per second, and the JIT's cost against
    /// hand-written Rust plastic.
    Render(bench::BenchRenderArgs),
    /// Shading speed (JIT vs interpreter vs hand-written Rust) and compile cost of a library.
    Shade(shade::BenchShadeArgs),
    /// Compiling a shader library to artifacts: one thread against every core.
    Library(compile::BenchLibraryArgs),
    /// Hot-reload latency: from an edit of `plastic.sl` written to the first frame of the Cornell
    /// box that uses the new code (watcher, background compile, swap, frame).
    Reload(bench::BenchReloadArgs),
    /// Primary rays per second from camera shaders against the built-in pinhole camera.
    Camera(bench::BenchCameraArgs),
    /// Top-level BVH rebuild time over 1,000 and 10,000 instances (what a dynamic frame pays).
    Instances(bench::BenchInstancesArgs),
    /// Anti-aliasing modes against a many-sample reference: rays traced and RMS error of each.
    Aa(bench::BenchAaArgs),
}

/// Runs the command line; the exit code says whether everything succeeded.
pub fn run() -> anyhow::Result<ExitCode> {
    let cli = Cli::parse();
    color::set(cli.color);
    match cli.command {
        Command::Render(args) => render::run(&args),
        Command::Shade(args) => shade::run(&args),
        Command::Preview(args) => preview::run(&args),
        Command::Compile(args) => compile::run(&args),
        Command::Info(args) => info::run(&args),
        Command::Bart(args) => bart::run(&args),
        Command::Lightfield(LightfieldCommand::Capture(args)) => lightfield::run_capture(&args),
        Command::Volume(VolumeCommand::Generate(args)) => volume::generate_cmd(&args),
        Command::View(args) => view::run(&args),
        Command::Bench(BenchCommand::Frontend(args)) => compile::bench_frontend(&args),
        Command::Bench(BenchCommand::Trace(args)) => bench::run_trace(&args).map(|()| ExitCode::SUCCESS),
        Command::Bench(BenchCommand::Render(args)) => bench::run_render(&args).map(|()| ExitCode::SUCCESS),
        Command::Bench(BenchCommand::Shade(args)) => shade::bench(&args),
        Command::Bench(BenchCommand::Library(args)) => compile::bench_library(&args),
        Command::Bench(BenchCommand::Reload(args)) => bench::run_reload(&args).map(|()| ExitCode::SUCCESS),
        Command::Bench(BenchCommand::Camera(args)) => bench::run_camera(&args).map(|()| ExitCode::SUCCESS),
        Command::Bench(BenchCommand::Instances(args)) => bench::run_instances(&args).map(|()| ExitCode::SUCCESS),
        Command::Bench(BenchCommand::Aa(args)) => bench::run_aa(&args).map(|()| ExitCode::SUCCESS),
    }
}

/// What separates the directories of one `-S` value, as in `RTSL_SHADER_PATH` and RenderMan's
/// search paths (`std::env::split_paths`'s separator).
pub(crate) const PATH_LIST_SEPARATOR: char = if cfg!(windows) { ';' } else { ':' };

/// The most worker threads `--threads` may ask for. Every worker keeps state of its own (statistics
/// slots, scratch buffers, a pool of batches), and rayon's idle workers spin before they sleep, so
/// thousands of them on a few cores make a frame take minutes; a count this high is a mistake.
pub(crate) const MAX_THREADS: usize = 256;

/// `--threads`, checked against [`MAX_THREADS`] (0: one per core).
pub(crate) fn thread_count(threads: usize) -> anyhow::Result<usize> {
    if threads > MAX_THREADS {
        anyhow::bail!("--threads {threads} is too many: at most {MAX_THREADS} (0 is one per core)");
    }
    Ok(if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get()).min(MAX_THREADS)
    } else {
        threads
    })
}

/// The rayon pool of `--threads` workers (0: one per core) and its size.
///
/// Rayon's global pool gets the same size (the first time): work begun outside the pool runs
/// there, such as the BVH of a mesh a distributed worker fetched, built on a thread of its own.
/// Left at one thread per core, every rank of an `mpirun` job with a rank per core would wake a
/// core's worth of threads for each such build, on cores its peers render on.
pub(crate) fn worker_pool(threads: usize) -> anyhow::Result<(usize, rayon::ThreadPool)> {
    use anyhow::Context as _;
    let threads = thread_count(threads)?;
    // Fails only when the global pool exists already (a second call), which then stays as it is.
    let _ = rayon::ThreadPoolBuilder::new().num_threads(threads).build_global();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("starting the worker threads")?;
    Ok((threads, pool))
}

/// A directory of its own under the system's temporary directory, removed when dropped.
pub(crate) struct ScratchDir(pub std::path::PathBuf);

impl ScratchDir {
    /// `rtsl-PURPOSE-PID` under the temporary directory, made now.
    pub(crate) fn new(purpose: &str) -> anyhow::Result<ScratchDir> {
        use anyhow::Context as _;
        let dir = std::env::temp_dir().join(format!("rtsl-{purpose}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(ScratchDir(dir))
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

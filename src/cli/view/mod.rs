//! `rtsl view`: the interactive viewer. A window (winit + softbuffer) shows the scene rendered
//! continuously by a render thread: progressive refinement while still, reduced-resolution
//! previews while moving, or frameless rendering; orbit and fly navigation, picking and moving
//! instances, hot reload with diagnostics in the overlay. `docs/viewer.md` is the user's guide.
//!
//! `renderer.rs` is the render thread, `window.rs` the window and input, `navigation.rs` the
//! camera's moves, `overlay.rs` the text, `script.rs` scripted input for tests.

mod navigation;
mod overlay;
mod renderer;
mod script;
mod window;

use anyhow::Context as _;
use rtsl_runtime::distributed::{Master, Transport};
use rtsl_runtime::render::Antialiasing;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

const AFTER_HELP: &str = "\
Mouse: left drag orbits about the pivot (a point ahead on the view axis); right drag looks around;
wheel dollies towards the pivot; left click selects the object under the cursor (click on nothing
to deselect); shift + left drag grabs the object under the cursor and moves it in the view plane.
Keys: W/S forward/back, A/D left/right, Q/E down/up (fly, held); X cycles anti-aliasing (jittered,
interleaved, adaptive, regular); C cycles the camera (built-in pinhole, fisheye, cylindrical,
parabolic, thinlens); F toggles frameless rendering; G makes quality follow the cursor (gaze);
V steps through a VRML scene's Viewpoints;
H toggles the overlay; R resets the view; Escape quits.
Scripted input (--events): steps separated by ';': drag:X0,Y0,X1,Y1  rdrag:...  shiftdrag:...
click:X,Y  move:X,Y  scroll:STEPS  key:NAME  hold:KEY,SECONDS  wait:FRAMES (one step per displayed frame).";

/// Flags of `rtsl view`.
#[derive(clap::Args, Debug, Clone)]
#[command(after_help = AFTER_HELP)]
pub struct ViewArgs {
    /// The scene: a RIB file, or a model (OBJ, PLY, glTF). Without one, the embedded default scene.
    pub scene: Option<PathBuf>,
    /// Window (and image) size, `WxH` (default: the scene's `Format`, at most 1280x960, else 640x480).
    #[arg(long, value_parser = super::bench::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Anti-aliasing to start with: `regular`, `jittered`, `interleaved` or `adaptive[:THRESHOLD]`.
    #[arg(long, value_parser = Antialiasing::parse)]
    pub aa: Option<Antialiasing>,
    /// Of a VRML scene, the library surface shader every shape gets instead of `material` (VRML's
    /// lighting model): e.g. `plastic`, `mirror`, `gimatte` (docs/vrml.md).
    #[arg(long, value_name = "SHADER")]
    pub vrml_surface: Option<String>,
    /// Of a VRML scene, hold its animation at this time (seconds from the load) instead of playing
    /// it at wall-clock time. With `--frames` and without it, the animation is held at 0 (a
    /// scripted run waits for the view to be still).
    #[arg(long, value_name = "SECONDS", value_parser = super::render::parse_time)]
    pub time: Option<f64>,
    /// Start in frameless mode.
    #[arg(long)]
    pub frameless: bool,
    /// Start with the overlay hidden (H toggles it).
    #[arg(long)]
    pub no_overlay: bool,
    /// Do not watch the shaders for changes.
    #[arg(long)]
    pub no_watch: bool,
    /// Save the window's contents as a PNG once `--frames` still frames are done, then exit.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// Exit once the scripted input has run and the view has been still for this many frames
    /// (full passes, or frameless sweeps); prints the frame rates.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Scripted input played through the input handlers, one step per displayed frame (see below).
    #[arg(long)]
    pub events: Option<String>,
    /// Directories searched for `#include`d shader headers.
    #[arg(short = 'I', long = "include")]
    pub include: Vec<PathBuf>,
    /// Directories searched for shaders by name, before the standard library (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
    /// Render over the ranks of an `mpirun` job: rank 0 opens the window and runs the viewer, the
    /// others trace its pixels (docs/distributed.md; needs a build with `--features mpi`).
    #[arg(long)]
    pub mpi: bool,
    #[command(flatten)]
    pub workers: super::mpi::WorkerArgs,
    #[command(flatten)]
    pub rays: super::ray_params::RayParamArgs,
}

/// What the render thread ends with: the session's frame rates, or nothing when it ended before
/// it rendered (an MPI worker rank, or a viewer whose window did not open).
type RenderOutcome = anyhow::Result<Option<renderer::Summary>>;

/// The render loop, handed to the render thread once the window's side is set up, with the
/// master of the MPI workers under `--mpi`.
type RenderJob = Box<dyn FnOnce(Option<Master<Box<dyn Transport>>>) -> renderer::Summary + Send>;

/// Starts the render thread. Under `--mpi` it starts MPI, and so is the only thread that may call
/// it (MPI_THREAD_FUNNELED): the window's thread never does. Returns the thread and, unless this
/// is a worker rank (whose thread serves the master until told to stop), where to send it the
/// render loop.
fn start_render_thread(
    args: &ViewArgs,
) -> anyhow::Result<(JoinHandle<RenderOutcome>, Option<mpsc::Sender<RenderJob>>)> {
    let (role_tx, role_rx) = mpsc::channel::<anyhow::Result<bool>>();
    let (jobs, job_rx) = mpsc::channel::<RenderJob>();
    let (mpi, workers, threads) = (args.mpi, args.workers.clone(), args.threads);
    let thread = std::thread::Builder::new()
        .name("rtsl-view-render".into())
        .spawn(move || -> RenderOutcome {
            let master = if mpi {
                let transport = match super::mpi::transport() {
                    Ok(t) => t,
                    Err(e) => {
                        let _ = role_tx.send(Err(e));
                        return Ok(None);
                    }
                };
                if transport.rank() != 0 {
                    let _ = role_tx.send(Ok(false));
                    let (_, pool) = super::worker_pool(threads)?;
                    super::mpi::work(&*transport, &pool, &workers)?;
                    return Ok(None);
                }
                let master = Master::connect(transport).map_err(anyhow::Error::from).and_then(|m| {
                    m.check_workers()?;
                    Ok(m)
                });
                match master {
                    Ok(m) if m.workers() == 0 => {
                        eprintln!("warning: --mpi with no worker rank (run it with mpirun -n 2 or more): rendering on rank 0 alone");
                        Some(m)
                    }
                    Ok(m) => Some(m),
                    Err(e) => {
                        let _ = role_tx.send(Err(e));
                        return Ok(None);
                    }
                }
            } else {
                None
            };
            let _ = role_tx.send(Ok(true));
            // No render loop comes when the window could not open; dropping the master then tells
            // the workers to stop.
            Ok(job_rx.recv().ok().map(|job| job(master)))
        })
        .context("starting the render thread")?;
    match role_rx.recv() {
        Ok(Ok(true)) => Ok((thread, Some(jobs))),
        Ok(Ok(false)) => Ok((thread, None)),
        Ok(Err(e)) => {
            let _ = thread.join();
            Err(e)
        }
        Err(_) => Err(finish(thread).err().unwrap_or_else(|| anyhow::anyhow!("the render thread ended at start-up"))),
    }
}

/// Waits for the render thread.
fn finish(thread: JoinHandle<RenderOutcome>) -> RenderOutcome {
    thread.join().map_err(|_| anyhow::anyhow!("the render thread panicked"))?
}

pub fn run(args: &ViewArgs) -> anyhow::Result<ExitCode> {
    let (thread, jobs) = start_render_thread(args)?;
    let Some(jobs) = jobs else {
        // A worker rank: it serves rank 0's viewer and opens no window.
        finish(thread)?;
        return Ok(ExitCode::SUCCESS);
    };
    // The render thread ends once the window closes, or at once if it never opened.
    let shown = show(args, jobs);
    let summary = finish(thread);
    let (w, h, screenshot) = shown?;
    if let Some(summary) = summary? {
        println!("{w}x{h}, {} thread(s): {summary}", summary.threads);
    }
    if let Some(path) = screenshot {
        println!("screenshot: {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Opens the window and runs the viewer until it closes, its render loop sent to the render
/// thread through `jobs`. Returns the window's size and the screenshot written, if any.
fn show(args: &ViewArgs, jobs: mpsc::Sender<RenderJob>) -> anyhow::Result<(u32, u32, Option<PathBuf>)> {
    let script = match &args.events {
        Some(s) => script::parse(s).map_err(|e| anyhow::anyhow!("--events: {e}"))?,
        None => Vec::new(),
    };
    let options = rtsl_runtime::LoadOptions { vrml_surface: args.vrml_surface.clone() };
    let (mut rt, mut loaded) =
        super::render::load_scene_frame(args.scene.as_deref(), &args.shader_path, &args.include, 0, &options)?;
    let mut playing = None;
    let mut viewpoints = Vec::new();
    anyhow::ensure!(
        args.time.is_none() || loaded.vrml.is_some(),
        "--time holds a VRML scene's animation; this is not one"
    );
    if let Some(mut scene) = loaded.vrml.take() {
        // The scene file's Viewpoints, in the order read (the first is where the view starts).
        let first_file = scene.viewpoints.iter().enumerate().filter(|(_, v)| v.node.doc == 0);
        viewpoints = first_file
            .map(|(index, v)| renderer::Viewpoint {
                index,
                name: v.made.description.clone(),
                eye: v.made.eye,
                forward: v.made.forward,
                up: v.made.up,
                fov_degrees: v.made.field_of_view.to_degrees(),
            })
            .collect();
        let held = args.time.or(args.frames.map(|_| 0.0));
        // The first image shows the animation's start.
        scene.advance_to(held.unwrap_or(0.0), &mut rt)?;
        if scene.is_animated() || scene.senses() || held.is_none() {
            playing = Some(renderer::Playing::new(scene, held));
        }
    }
    let (w, h) = match args.size {
        Some(size) => size,
        None if rt.options.width <= 1280 && rt.options.height <= 960 => (rt.options.width, rt.options.height),
        None => (640, 480),
    };
    anyhow::ensure!(w > 0 && h > 0, "the window size must not be 0");
    rt.options.width = w;
    rt.options.height = h;
    if let Some(aa) = args.aa {
        rt.options.antialiasing = aa;
    }
    args.rays.apply(&mut rt)?;
    let threads = super::thread_count(args.threads)?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("starting the worker threads")?;
    let mut renderer = renderer::Renderer::new(
        rt,
        !args.no_watch,
        args.frameless,
        threads,
        args.frames.unwrap_or(renderer::MAX_PASSES),
    )?;
    if let Some(playing) = playing {
        renderer.play(playing);
    }
    renderer.set_viewpoints(viewpoints);

    let event_loop = winit::event_loop::EventLoop::<window::FrameReady>::with_user_event()
        .build()
        .context("connecting to the display (is DISPLAY set? the viewer needs X11)")?;
    let proxy = event_loop.create_proxy();
    let (tx, rx) = mpsc::channel();
    let latest = Arc::new(Mutex::new(None));
    let slot = latest.clone();
    let job: RenderJob = Box::new(move |workers| {
        renderer.run(
            rx,
            slot,
            move || {
                // The window may be gone already at exit; nothing to tell then.
                let _ = proxy.send_event(window::FrameReady);
            },
            &pool,
            workers,
        )
    });
    jobs.send(job).map_err(|_| anyhow::anyhow!("the render thread ended before the window opened"))?;

    let title = format!(
        "rtsl view {}",
        args.scene.as_ref().map_or_else(|| "(default scene)".to_string(), |p| p.display().to_string())
    );
    let mut app = window::App::new(
        window::WindowOptions {
            title,
            width: w,
            height: h,
            screenshot: args.screenshot.clone(),
            frames: args.frames,
            script,
            overlay: !args.no_overlay,
        },
        tx,
        latest,
    );
    let looped = event_loop.run_app(&mut app);
    let error = app.error.take();
    let wrote = app.screenshot_written;
    // Dropping the app closes the command channel, which ends the render thread.
    drop(app);
    looped.context("running the window's event loop")?;
    if let Some(e) = error {
        return Err(e);
    }
    Ok((w, h, args.screenshot.clone().filter(|_| wrote)))
}

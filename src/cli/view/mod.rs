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
use rtsl_runtime::render::Antialiasing;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{mpsc, Arc, Mutex};

const AFTER_HELP: &str = "\
Mouse: left drag orbits about the pivot (a point ahead on the view axis); right drag looks around;
wheel dollies towards the pivot; left click selects the object under the cursor (click on nothing
to deselect); shift + left drag grabs the object under the cursor and moves it in the view plane.
Keys: W/S forward/back, A/D left/right, Q/E down/up (fly, held); X cycles anti-aliasing (jittered,
interleaved, adaptive, regular); C cycles the camera (built-in pinhole, fisheye, cylindrical,
parabolic, thinlens); F toggles frameless rendering; H toggles the overlay; R resets the
view; Escape quits.
Scripted input (--events): steps separated by ';': drag:X0,Y0,X1,Y1  rdrag:...  shiftdrag:...
click:X,Y  scroll:STEPS  key:NAME  hold:KEY,SECONDS  wait:FRAMES (one step per displayed frame).";

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
    /// Directories searched for shaders by name, before the standard library.
    #[arg(short = 'S', long = "shader-path")]
    pub shader_path: Vec<PathBuf>,
}

pub fn run(args: &ViewArgs) -> anyhow::Result<ExitCode> {
    let script = match &args.events {
        Some(s) => script::parse(s).map_err(|e| anyhow::anyhow!("--events: {e}"))?,
        None => Vec::new(),
    };
    let (mut rt, _) = super::render::load_scene(args.scene.as_deref(), &args.shader_path, &args.include)?;
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
    let threads = super::thread_count(args.threads)?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("starting the worker threads")?;
    let renderer = renderer::Renderer::new(
        rt,
        !args.no_watch,
        args.frameless,
        threads,
        args.frames.unwrap_or(renderer::MAX_PASSES),
    )?;

    let event_loop = winit::event_loop::EventLoop::<window::FrameReady>::with_user_event()
        .build()
        .context("connecting to the display (is DISPLAY set? the viewer needs X11)")?;
    let proxy = event_loop.create_proxy();
    let (tx, rx) = mpsc::channel();
    let latest = Arc::new(Mutex::new(None));
    let slot = latest.clone();
    let render_thread = std::thread::Builder::new()
        .name("rtsl-view-render".into())
        .spawn(move || {
            renderer.run(
                rx,
                slot,
                move || {
                    // The window may be gone already at exit; nothing to tell then.
                    let _ = proxy.send_event(window::FrameReady);
                },
                &pool,
            )
        })
        .context("starting the render thread")?;

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
    let summary = render_thread.join().map_err(|_| anyhow::anyhow!("the render thread panicked"))?;
    looped.context("running the window's event loop")?;
    if let Some(e) = error {
        return Err(e);
    }
    println!("{w}x{h}, {threads} thread(s): {summary}");
    if let (Some(path), true) = (&args.screenshot, wrote) {
        println!("screenshot: {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

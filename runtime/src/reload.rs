//! Hot reload: watching the files the loaded shaders came from (sources and every included header)
//! and recompiling the shaders they belong to, keeping the last good code when a change does not
//! compile.
//!
//! Two ways to use it:
//! - [`ShaderReloader`] (what a viewer wants): a background thread waits for (debounced) changes
//!   and compiles the affected shaders off the render thread; the application calls
//!   [`ShaderReloader::apply`] between frames, which swaps in what compiled and reports the rest,
//!   without blocking.
//! - [`ShaderWatcher`] with [`reload_changed`]: the same, synchronously on the caller's thread.
//!
//! Both report what happened as [`Reload`]s and as [`ShaderEvent`]s queued on the [`Context`]
//! ([`Context::take_shader_events`]).
//!
//! **Frames never see half a swap, and old code is freed only when no frame uses it.** A
//! [`Context`] holds programs as `Arc`s and a frame's `World` holds its own clones, taken when the
//! frame starts (`Context::build_world`): a frame runs one program per shader from start to end,
//! whatever is swapped meanwhile, and the old code lives until the last frame that uses it is
//! dropped (then `CompiledShader`'s drop frees its JIT memory; `rtsl_compiler::jit::
//! live_modules` counts what is alive).

pub use crate::api::ShaderEvent;
use crate::api::{Context, ShaderId};
use crate::shading::ShaderProgram;
use notify::{RecursiveMode, Watcher};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What reloading one shader did.
#[derive(Debug)]
pub struct Reload {
    pub shader: ShaderId,
    pub name: String,
    pub path: PathBuf,
    /// The new code is in place (compile time), or the diagnostics and the old code stays.
    pub result: Result<Duration, String>,
    /// When the change was seen (for [`ShaderReloader`], after debouncing; for [`reload_changed`],
    /// when it was called). Latency measurements start from it.
    pub detected: Instant,
}

impl Reload {
    /// The event this reload reports.
    pub fn event(&self) -> ShaderEvent {
        match &self.result {
            Ok(t) => ShaderEvent::Reloaded {
                shader: self.shader,
                name: self.name.clone(),
                path: self.path.clone(),
                compile_ms: t.as_secs_f64() * 1e3,
            },
            Err(d) => ShaderEvent::Failed {
                shader: self.shader,
                name: self.name.clone(),
                path: self.path.clone(),
                diagnostics: d.clone(),
            },
        }
    }
}

impl std::fmt::Display for Reload {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.event().fmt(f)
    }
}

/// Why watching could not start.
#[derive(Debug, thiserror::Error)]
#[error("cannot watch shader files: {0}")]
pub struct WatchError(#[from] notify::Error);

/// Watches the directories of a context's shader files.
pub struct ShaderWatcher {
    watcher: notify::RecommendedWatcher,
    events: Receiver<notify::Result<notify::Event>>,
    files: BTreeSet<PathBuf>,
    dirs: BTreeSet<PathBuf>,
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

impl ShaderWatcher {
    /// Starts watching every file the context's shaders were compiled from. (Directories are watched
    /// rather than files, so editors that save by replacing the file are seen too.)
    pub fn new(rt: &Context) -> Result<ShaderWatcher, WatchError> {
        ShaderWatcher::for_files(rt.shader_files())
    }

    /// Starts watching `files`.
    pub fn for_files(files: impl IntoIterator<Item = PathBuf>) -> Result<ShaderWatcher, WatchError> {
        let (tx, events) = channel();
        let watcher = notify::recommended_watcher(tx)?;
        let mut w = ShaderWatcher { watcher, events, files: BTreeSet::new(), dirs: BTreeSet::new() };
        w.add_files(files)?;
        Ok(w)
    }

    /// Watches `files` too (a reloaded shader may include new headers).
    pub fn add_files(&mut self, files: impl IntoIterator<Item = PathBuf>) -> Result<(), WatchError> {
        for f in files {
            let f = canonical(&f);
            if let Some(d) = f.parent() {
                if !self.dirs.contains(d) {
                    self.watcher.watch(d, RecursiveMode::NonRecursive)?;
                    self.dirs.insert(d.to_path_buf());
                }
            }
            self.files.insert(f);
        }
        Ok(())
    }

    /// The watched files.
    pub fn files(&self) -> &BTreeSet<PathBuf> {
        &self.files
    }

    /// Adds the watched files named by `event` to `changed`.
    fn collect(&self, event: notify::Event, changed: &mut BTreeSet<PathBuf>) {
        if matches!(event.kind, notify::EventKind::Access(_)) {
            return;
        }
        for p in event.paths {
            let p = canonical(&p);
            if self.files.contains(&p) {
                changed.insert(p);
            }
        }
    }

    /// Waits up to `timeout` for a change to a watched file, then keeps collecting until no event
    /// came for `quiet` (editors save in bursts); returns the changed files (empty on timeout).
    ///
    /// notify's debouncer crates are not used for this: they deliver on a timer tick of their own
    /// (a change waits for the next tick after the quiet time), while hot reload's latency is the
    /// quiet time alone, and the reloader already tolerates a save caught half-written.
    pub fn wait(&self, timeout: Duration, quiet: Duration) -> Vec<PathBuf> {
        let mut changed = BTreeSet::new();
        let deadline = Instant::now() + timeout;
        loop {
            let wait = if changed.is_empty() { deadline.saturating_duration_since(Instant::now()) } else { quiet };
            match self.events.recv_timeout(wait) {
                Ok(Ok(event)) => self.collect(event, &mut changed),
                Ok(Err(_)) => {}
                Err(RecvTimeoutError::Timeout) => {
                    if !changed.is_empty() || Instant::now() >= deadline {
                        break;
                    }
                }
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        changed.into_iter().collect()
    }

    /// The watched files changed since the last `wait` or `poll`, without waiting.
    pub fn poll(&self) -> Vec<PathBuf> {
        let mut changed = BTreeSet::new();
        while let Ok(event) = self.events.try_recv() {
            if let Ok(event) = event {
                self.collect(event, &mut changed);
            }
        }
        changed.into_iter().collect()
    }
}

/// Recompiles the shaders of `rt` that read any of `changed` and swaps in those that compile, on
/// the caller's thread. The reloads are also queued as [`ShaderEvent`]s on `rt`.
pub fn reload_changed(rt: &mut Context, changed: &[PathBuf]) -> Vec<Reload> {
    let detected = Instant::now();
    let changed: Vec<PathBuf> = changed.iter().map(|p| canonical(p)).collect();
    let mut out = Vec::new();
    for (id, program) in rt.programs_by_id() {
        let Some(path) = program.path.clone() else { continue };
        if !program.files.iter().any(|f| changed.contains(&canonical(f))) {
            continue;
        }
        let start = Instant::now();
        let result = ShaderProgram::from_file(&path, rt.include_paths()).map_err(|e| e.to_string());
        let compiled =
            Compiled { shader: id, name: program.name.clone(), path, result, compile: start.elapsed(), detected };
        out.push(compiled.swap_into(rt));
    }
    out
}

/// A compilation finished off the render thread, waiting for [`ShaderReloader::apply`].
struct Compiled {
    shader: ShaderId,
    name: String,
    path: PathBuf,
    result: Result<ShaderProgram, String>,
    compile: Duration,
    detected: Instant,
}

impl Compiled {
    /// Swaps the program in (when it compiled) and queues the events on `rt`.
    fn swap_into(self, rt: &mut Context) -> Reload {
        let (result, dropped) = match self.result {
            Ok(program) => match rt.swap_program(self.shader, program) {
                Ok(dropped) => (Ok(self.compile), dropped),
                Err(e) => (Err(e.to_string()), Vec::new()),
            },
            Err(d) => (Err(d), Vec::new()),
        };
        let reload = Reload { shader: self.shader, name: self.name, path: self.path, result, detected: self.detected };
        rt.push_shader_events(std::iter::once(reload.event()).chain(dropped));
        reload
    }
}

/// A shader the background thread recompiles when one of its files changes.
struct Tracked {
    shader: ShaderId,
    name: String,
    path: PathBuf,
    /// Canonical paths of the files its last compilation read.
    files: Vec<PathBuf>,
}

/// What the background thread needs to know of a context: its file-backed shaders and include
/// paths (taken when the reloader starts, and by [`ShaderReloader::track`]).
struct Snapshot {
    shaders: Vec<Tracked>,
    include_paths: Vec<PathBuf>,
}

impl Snapshot {
    fn of(rt: &Context) -> Snapshot {
        let shaders = rt
            .programs_by_id()
            .into_iter()
            .filter_map(|(shader, p)| {
                let path = p.path.clone()?;
                let files = p.files.iter().map(|f| canonical(f)).collect();
                Some(Tracked { shader, name: p.name.clone(), path, files })
            })
            .collect();
        Snapshot { shaders, include_paths: rt.include_paths().to_vec() }
    }

    fn files(&self) -> Vec<PathBuf> {
        self.shaders.iter().flat_map(|t| t.files.iter().cloned()).collect()
    }
}

/// The debounce window of [`ShaderReloader::new`]: a change is compiled once no further event came
/// for this long. Short, because the reloader drops a failed compilation whose files changed again
/// while it ran (a save caught half-written), so a burst of writes costs at most a redundant
/// compilation, never a spurious error.
pub const DEFAULT_QUIET: Duration = Duration::from_millis(10);

/// How long the background thread blocks before looking at its commands and its stop flag.
const POLL: Duration = Duration::from_millis(50);

/// Hot reload off the render thread: owns a [`ShaderWatcher`] and a background thread that waits
/// for changes, compiles the shaders that read a changed file (sources and headers), and hands the
/// results over a channel. The application calls [`ShaderReloader::apply`] between frames to swap
/// in what compiled; nothing touches the [`Context`] in between, so a frame in flight is never
/// affected.
///
/// Results arrive in the order the changes were seen, so a shader never goes back to an older
/// version. A compilation that failed while its files changed again is dropped (a newer one
/// follows). Dropping the reloader stops the thread and waits for it (at most one compilation);
/// programs compiled but not applied are freed then.
pub struct ShaderReloader {
    results: Receiver<Compiled>,
    commands: Sender<Snapshot>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    watched: usize,
}

impl ShaderReloader {
    /// Starts watching the files of `rt`'s shaders (as [`ShaderWatcher::new`]) with the default
    /// debounce window ([`DEFAULT_QUIET`]).
    pub fn new(rt: &Context) -> Result<ShaderReloader, WatchError> {
        ShaderReloader::with_quiet(rt, DEFAULT_QUIET)
    }

    /// As [`ShaderReloader::new`], compiling a change once no event came for `quiet`.
    pub fn with_quiet(rt: &Context, quiet: Duration) -> Result<ShaderReloader, WatchError> {
        let snapshot = Snapshot::of(rt);
        let watcher = ShaderWatcher::for_files(snapshot.files())?;
        let watched = watcher.files().len();
        let (results_tx, results) = channel();
        let (commands, commands_rx) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("rtsl-shader-reload".into())
            .spawn(move || background(watcher, snapshot, quiet, &flag, &commands_rx, &results_tx))
            .map_err(|e| WatchError(notify::Error::io(e)))?;
        Ok(ShaderReloader { results, commands, stop, thread: Some(thread), watched })
    }

    /// How many files were watched when the reloader started (sources and headers).
    pub fn watched_files(&self) -> usize {
        self.watched
    }

    /// Tracks `rt`'s shaders as they are now (call it after loading more shaders).
    pub fn track(&self, rt: &Context) {
        // The thread only stops when the reloader is dropped, so the send cannot fail before.
        let _ = self.commands.send(Snapshot::of(rt));
    }

    /// Whether the background thread still runs (it stops only if it panicked).
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Swaps in every compilation finished since the last call, without blocking: shaders that
    /// compiled replace the old code under their id ([`Context::replace_shader`]); the others keep
    /// the last good code. Call it between frames; the next frame uses the new code. The same
    /// reloads are queued as [`ShaderEvent`]s on `rt`, followed by the parameters each one drops.
    pub fn apply(&mut self, rt: &mut Context) -> Vec<Reload> {
        let mut out = Vec::new();
        while let Ok(c) = self.results.try_recv() {
            out.push(c.swap_into(rt));
        }
        out
    }

    /// As [`ShaderReloader::apply`], first waiting up to `timeout` for a compilation to finish
    /// (for applications that render only after a change, like `rtsl render --watch`).
    pub fn wait_apply(&mut self, rt: &mut Context, timeout: Duration) -> Vec<Reload> {
        match self.results.recv_timeout(timeout) {
            Ok(c) => {
                let mut out = vec![c.swap_into(rt)];
                out.extend(self.apply(rt));
                out
            }
            Err(_) => Vec::new(),
        }
    }
}

impl Drop for ShaderReloader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Compiles one shader, turning a panic of the compiler into an error so one bad edit cannot stop
/// hot reload.
fn compile(path: &Path, include_paths: &[PathBuf]) -> Result<ShaderProgram, String> {
    match std::panic::catch_unwind(|| ShaderProgram::from_file(path, include_paths)) {
        Ok(result) => result.map_err(|e| e.to_string()),
        Err(_) => Err(format!("{}: the compiler panicked (a bug); the last good version stays", path.display())),
    }
}

/// The background thread of a [`ShaderReloader`].
fn background(
    mut watcher: ShaderWatcher,
    mut snapshot: Snapshot,
    quiet: Duration,
    stop: &AtomicBool,
    commands: &Receiver<Snapshot>,
    results: &Sender<Compiled>,
) {
    let mut pending: BTreeSet<PathBuf> = BTreeSet::new();
    loop {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        loop {
            match commands.try_recv() {
                Ok(s) => {
                    // A directory that cannot be watched leaves its files unwatched; nothing else
                    // can be done from here.
                    let _ = watcher.add_files(s.files());
                    snapshot = s;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return,
            }
        }
        // With changes pending (seen while compiling), only wait out the rest of their burst.
        let timeout = if pending.is_empty() { POLL } else { quiet };
        pending.extend(watcher.wait(timeout, quiet));
        if pending.is_empty() {
            continue;
        }
        let detected = Instant::now();
        let changed = std::mem::take(&mut pending);
        for t in snapshot.shaders.iter_mut().filter(|t| t.files.iter().any(|f| changed.contains(f))) {
            if stop.load(Ordering::SeqCst) {
                return;
            }
            let start = Instant::now();
            let result = compile(&t.path, &snapshot.include_paths);
            let compile_time = start.elapsed();
            pending.extend(watcher.poll());
            if result.is_err() && t.files.iter().any(|f| pending.contains(f)) {
                // Changed again while compiling (a save caught half-written?): the next round
                // compiles the newer text.
                continue;
            }
            if let Ok(p) = &result {
                t.name = p.name.clone();
                t.files = p.files.iter().map(|f| canonical(f)).collect();
                let _ = watcher.add_files(t.files.iter().cloned());
            }
            let c = Compiled {
                shader: t.shader,
                name: t.name.clone(),
                path: t.path.clone(),
                result,
                compile: compile_time,
                detected,
            };
            if results.send(c).is_err() {
                return;
            }
        }
    }
}

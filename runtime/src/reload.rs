//! Hot reload: watching the files the loaded shaders came from (sources and every included header)
//! and recompiling the shaders they belong to, keeping the last good code when a change does not
//! compile.
//!
//! Swapping is safe at any time between frames: a [`crate::api::Context`] holds programs as `Arc`s
//! and a frame's `World` holds its own clones, so the old code lives until the last frame that uses
//! it is dropped (then `CompiledShader`'s drop frees it).

use crate::api::{Context, ShaderId};
use notify::{RecursiveMode, Watcher};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// What reloading one shader did.
#[derive(Debug)]
pub struct Reload {
    pub shader: ShaderId,
    pub name: String,
    pub path: PathBuf,
    /// The new code is in place (compile time), or the diagnostics and the old code stays.
    pub result: Result<Duration, String>,
}

impl std::fmt::Display for Reload {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.result {
            Ok(t) => write!(f, "reloaded {} ({}) in {:.1} ms", self.name, self.path.display(), t.as_secs_f64() * 1e3),
            Err(d) => {
                write!(f, "{} ({}) did not compile; the last good version stays:\n{d}", self.name, self.path.display())
            }
        }
    }
}

/// Why watching could not start.
#[derive(Debug, thiserror::Error)]
#[error("cannot watch shader files: {0}")]
pub struct WatchError(#[from] notify::Error);

/// Watches the directories of a context's shader files.
pub struct ShaderWatcher {
    _watcher: notify::RecommendedWatcher,
    events: Receiver<notify::Result<notify::Event>>,
    files: BTreeSet<PathBuf>,
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

impl ShaderWatcher {
    /// Starts watching every file the context's shaders were compiled from. (Directories are watched
    /// rather than files, so editors that save by replacing the file are seen too.)
    pub fn new(rt: &Context) -> Result<ShaderWatcher, WatchError> {
        let (tx, events) = channel();
        let mut watcher = notify::recommended_watcher(tx)?;
        let files: BTreeSet<PathBuf> = rt.shader_files().iter().map(|f| canonical(f)).collect();
        let dirs: BTreeSet<PathBuf> = files.iter().filter_map(|f| f.parent().map(Path::to_path_buf)).collect();
        for d in &dirs {
            watcher.watch(d, RecursiveMode::NonRecursive)?;
        }
        Ok(ShaderWatcher { _watcher: watcher, events, files })
    }

    /// The watched files.
    pub fn files(&self) -> &BTreeSet<PathBuf> {
        &self.files
    }

    /// Waits up to `timeout` for a change to a watched file, then keeps collecting until no event
    /// came for `quiet` (editors save in bursts); returns the changed files (empty on timeout).
    pub fn wait(&self, timeout: Duration, quiet: Duration) -> Vec<PathBuf> {
        let mut changed = BTreeSet::new();
        let deadline = Instant::now() + timeout;
        loop {
            let wait = if changed.is_empty() { deadline.saturating_duration_since(Instant::now()) } else { quiet };
            match self.events.recv_timeout(wait) {
                Ok(Ok(event)) => {
                    if matches!(event.kind, notify::EventKind::Access(_)) {
                        continue;
                    }
                    for p in event.paths {
                        let p = canonical(&p);
                        if self.files.contains(&p) {
                            changed.insert(p);
                        }
                    }
                }
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
}

/// Recompiles the shaders of `rt` that read any of `changed` and swaps in those that compile.
pub fn reload_changed(rt: &mut Context, changed: &[PathBuf]) -> Vec<Reload> {
    let changed: Vec<PathBuf> = changed.iter().map(|p| canonical(p)).collect();
    let mut out = Vec::new();
    for (id, program) in rt.programs_by_id() {
        let Some(path) = program.path.clone() else { continue };
        if !program.files.iter().any(|f| changed.contains(&canonical(f))) {
            continue;
        }
        let start = Instant::now();
        let result = match crate::shading::ShaderProgram::from_file(&path, rt.include_paths()) {
            Ok(new) => match rt.replace_shader(id, new) {
                Ok(()) => Ok(start.elapsed()),
                Err(e) => Err(e.to_string()),
            },
            Err(e) => Err(e.to_string()),
        };
        out.push(Reload { shader: id, name: program.name.clone(), path, result });
    }
    out
}

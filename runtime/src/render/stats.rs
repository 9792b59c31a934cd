//! What a frame counts: rays by kind, shaded points, light shader runs, and the time spent shading
//! with tracing excluded (per-thread timers around the outermost shading, minus the tracer calls
//! made meanwhile), split by the type of the shader that ran.
//!
//! The split is exclusive time: each thread keeps a stack of what runs (a shader's batch, or the
//! tracer), and the clock is charged to the top of the stack whenever it changes. A surface shader
//! that traces a reflection and shades the hit with a volume shader is charged for its own work
//! only; the tracer and the volume shader get theirs.

use crate::shading::Program;
use rtsl_compiler::interface::ShaderKind;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

/// The index of `kind` in [`ShaderKind::ALL`], the order of [`Stats::kind_ns`] and
/// `FrameReport::by_kind`.
pub(crate) fn kind_index(kind: ShaderKind) -> usize {
    ShaderKind::ALL.iter().position(|k| *k == kind).unwrap_or(0)
}

/// One thread's exclusive-time clock (see the module doc): `stack` holds indices into `entries`,
/// the programs that ran since the outermost shading began (`None`: the tracer).
struct KindClock {
    stack: Vec<usize>,
    since: Instant,
    entries: Vec<(Option<Program>, u64)>,
}

impl KindClock {
    fn charge(&mut self, now: Instant) {
        if let Some(&top) = self.stack.last() {
            self.entries[top].1 += now.saturating_duration_since(self.since).as_nanos() as u64;
        }
        self.since = now;
    }

    fn slot(&mut self, program: Option<&Program>) -> usize {
        let same = |e: &Option<Program>| match (e, program) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        match self.entries.iter().position(|(e, _)| same(e)) {
            Some(i) => i,
            None => {
                self.entries.push((program.cloned(), 0));
                self.entries.len() - 1
            }
        }
    }
}

thread_local! {
    static CLOCK: RefCell<KindClock> =
        RefCell::new(KindClock { stack: Vec::new(), since: Instant::now(), entries: Vec::new() });
}

/// Starts charging `program` (`None`: the tracer); returns the time it started.
fn enter(program: Option<&Program>) -> Instant {
    let now = Instant::now();
    CLOCK.with(|c| {
        let mut c = c.borrow_mut();
        c.charge(now);
        let slot = c.slot(program);
        c.stack.push(slot);
    });
    now
}

/// Stops charging what [`enter`] started; returns the time it stopped.
fn leave() -> Instant {
    let now = Instant::now();
    CLOCK.with(|c| {
        let mut c = c.borrow_mut();
        c.charge(now);
        c.stack.pop();
    });
    now
}

/// Charges the time until it is dropped to `program` (exclusive of what runs inside), when this
/// thread's frame times its shaders.
pub(crate) struct ShaderKindTimer {
    timed: bool,
}

impl ShaderKindTimer {
    pub(crate) fn enter(program: &Program) -> ShaderKindTimer {
        let timed = TIMING.with(|t| t.get());
        if timed {
            enter(Some(program));
        }
        ShaderKindTimer { timed }
    }
}

impl Drop for ShaderKindTimer {
    fn drop(&mut self) {
        if self.timed {
            leave();
        }
    }
}

/// A count of one frame, summed over threads. Each thread adds to a slot of its own, on a cache
/// line of its own: with one shared count, both threads of a frame added to the same line at every
/// packet and batch, and each addition would wait for the line to come back from the other core. A slot belongs to
/// one thread for good ([`OWN_SLOT`]), so that thread adds with a plain load and store: a locked
/// addition also waits for every store before it to drain (such as a light batch's row stores). Threads past the slots share
/// one more, by locked additions.
#[derive(Debug, Default)]
pub struct Counter {
    slots: [CounterSlot; COUNTER_SLOTS],
    shared: CounterSlot,
}

/// Threads past this many (since the process started) share one more slot.
const COUNTER_SLOTS: usize = 8;

/// Which slot of every [`Counter`] this thread owns: the order in which threads first counted
/// something. Never reused, so no two threads ever own the same slot.
static NEXT_SLOT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

thread_local! {
    static OWN_SLOT: usize = NEXT_SLOT.fetch_add(1, Ordering::Relaxed);
}

/// One thread's part of a [`Counter`], alone on its cache line (two lines: adjacent lines are
/// fetched in pairs).
#[derive(Debug, Default)]
#[repr(align(128))]
struct CounterSlot(AtomicU64);

impl Counter {
    pub(super) fn add(&self, n: usize) {
        let own = OWN_SLOT.try_with(|s| *s).unwrap_or(usize::MAX);
        match self.slots.get(own) {
            // Only this thread writes it: readers see the count before or after, never a torn one.
            Some(slot) => slot.0.store(slot.0.load(Ordering::Relaxed).wrapping_add(n as u64), Ordering::Relaxed),
            None => {
                self.shared.0.fetch_add(n as u64, Ordering::Relaxed);
            }
        }
    }

    /// The sum over threads (of what they added before, for example, the frame's tiles joined).
    pub fn load(&self) -> u64 {
        self.slots.iter().chain([&self.shared]).map(|s| s.0.load(Ordering::Relaxed)).sum()
    }
}

/// Counters of one frame, summed over threads.
#[derive(Debug, Default)]
pub struct Stats {
    pub primary_rays: Counter,
    pub shadow_rays: Counter,
    pub secondary_rays: Counter,
    pub transparency_rays: Counter,
    pub shaded_points: Counter,
    pub light_evaluations: Counter,
    /// Rays refused because their camera sample's tree had spent its budget
    /// ([`super::RAY_TREE_BUDGET`]).
    pub rays_cut: Counter,
    /// Lights left out at shading points that more than `MAX_LIGHTS` reached (each area-light
    /// sample counts as a light).
    pub lights_dropped: Counter,
    /// Time spent shading (surface and light shaders and the renderer's side of their calls),
    /// tracing excluded, summed over threads.
    pub shading_ns: AtomicU64,
    /// Of that, the time inside each type of shader's batches (in [`ShaderKind::ALL`] order):
    /// filling the batch, running it, reading it back and the host calls it makes, exclusive of
    /// tracing and of other shaders it runs.
    pub kind_ns: [AtomicU64; ShaderKind::ALL.len()],
    /// The same time per shader program, in nanoseconds.
    pub program_ns: Mutex<Vec<(Program, u64)>>,
    /// Global illumination: the time spent tracing the frame's light paths (virtual lights and
    /// caustic photons, the photon map's tree included; threads that need them meanwhile wait),
    /// and the threads' time gathering virtual lights (their shadow rays included).
    pub light_paths_ns: AtomicU64,
    pub gathering_ns: AtomicU64,
    /// Whether the shading times above are measured (`RenderOptions::time_shaders`; the frame
    /// sets it). Untimed, they stay zero and no clock is read.
    pub timed: bool,
}

thread_local! {
    /// Nanoseconds this thread spent in tracer calls made while shading, and how deeply shading
    /// is nested on this thread (trace() shades recursively; only the outermost level is timed).
    static TRACE_NS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    static SHADE_NESTING: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
    /// Whether the outermost shading on this thread is timed ([`Stats::timed`] of its frame): the
    /// shader and tracer clocks run only then.
    static TIMING: std::cell::Cell<bool> = const { std::cell::Cell::new(true) };
}

/// Runs a tracer query, counting its time as tracing rather than shading.
pub(super) fn tracing<R>(f: impl FnOnce() -> R) -> R {
    if !TIMING.with(|t| t.get()) {
        return f();
    }
    let start = enter(None);
    let r = f();
    let ns = leave().saturating_duration_since(start).as_nanos() as u64;
    TRACE_NS.with(|t| t.set(t.get() + ns));
    r
}

/// Times the outermost shading on this thread, tracing excluded.
pub(super) struct ShadingTimer<'a> {
    stats: &'a Stats,
    start: Option<(std::time::Instant, u64)>,
}

impl<'a> ShadingTimer<'a> {
    pub(super) fn start(stats: &'a Stats) -> ShadingTimer<'a> {
        let outer = SHADE_NESTING.with(|n| {
            n.set(n.get() + 1);
            n.get() == 1
        });
        if outer {
            TIMING.with(|t| t.set(stats.timed));
        }
        if outer && stats.timed {
            // What the clock gathered outside any frame's shading is not this frame's.
            CLOCK.with(|c| {
                let mut c = c.borrow_mut();
                c.stack.clear();
                c.entries.clear();
            });
        }
        let start = (outer && stats.timed).then(|| (std::time::Instant::now(), TRACE_NS.with(|t| t.get())));
        ShadingTimer { stats, start }
    }
}

impl Drop for ShadingTimer<'_> {
    fn drop(&mut self) {
        SHADE_NESTING.with(|n| n.set(n.get().saturating_sub(1)));
        if let Some((start, traced_before)) = self.start {
            let traced = TRACE_NS.with(|t| t.get()) - traced_before;
            let ns = (start.elapsed().as_nanos() as u64).saturating_sub(traced);
            self.stats.shading_ns.fetch_add(ns, Ordering::Relaxed);
            let entries = CLOCK.with(|c| std::mem::take(&mut c.borrow_mut().entries));
            let mut programs = self.stats.program_ns.lock().unwrap_or_else(PoisonError::into_inner);
            for (program, ns) in entries {
                let Some(program) = program.filter(|_| ns > 0) else { continue };
                self.stats.kind_ns[kind_index(program.kind)].fetch_add(ns, Ordering::Relaxed);
                match programs.iter_mut().find(|(p, _)| Arc::ptr_eq(p, &program)) {
                    Some((_, total)) => *total += ns,
                    None => programs.push((program, ns)),
                }
            }
        }
    }
}

impl Stats {
    pub(super) fn add(counter: &Counter, n: usize) {
        counter.add(n);
    }

    pub fn total_rays(&self) -> u64 {
        self.primary_rays.load() + self.shadow_rays.load() + self.secondary_rays.load() + self.transparency_rays.load()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// What threads add, in and out of the pool (more threads than slots among them), is all
    /// counted, and the slots stay on lines of their own.
    #[test]
    fn counters_sum_what_every_thread_adds() {
        assert!(std::mem::align_of::<CounterSlot>() >= 128);
        let stats = Stats::default();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(COUNTER_SLOTS + 3).build().unwrap();
        pool.install(|| {
            (0..10_000usize).into_par_iter().for_each(|i| {
                Stats::add(&stats.primary_rays, i % 7);
                Stats::add(&stats.shadow_rays, 1);
            })
        });
        Stats::add(&stats.secondary_rays, 5);
        // Threads of their own, more than there are slots, each adding many times: the slots they
        // own and the one they share lose nothing.
        std::thread::scope(|scope| {
            for _ in 0..2 * COUNTER_SLOTS {
                scope.spawn(|| (0..100_000).for_each(|_| Stats::add(&stats.transparency_rays, 3)));
            }
        });
        let want: usize = (0..10_000).map(|i| i % 7).sum();
        assert_eq!(stats.primary_rays.load(), want as u64);
        assert_eq!(stats.shadow_rays.load(), 10_000);
        assert_eq!(stats.transparency_rays.load(), 2 * COUNTER_SLOTS as u64 * 100_000 * 3);
        assert_eq!(stats.total_rays(), want as u64 + 10_000 + 5 + 2 * COUNTER_SLOTS as u64 * 300_000);
    }
}

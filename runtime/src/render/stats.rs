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
/// line of its own: with one shared count, the threads of a frame added to the same line at every
/// packet and batch, and each addition would wait for the line to come back from another core. A
/// slot belongs to one thread while it lives ([`OWN_SLOT`]), so that thread adds with a plain load
/// and store: a locked addition also waits for every store before it to drain (such as a light
/// batch's row stores). Threads past the slots share one more, by locked additions.
#[derive(Debug)]
pub struct Counter {
    /// [`slot_count`] slots, then the shared one.
    slots: Box<[CounterSlot]>,
}

impl Default for Counter {
    fn default() -> Counter {
        Counter { slots: (0..=slot_count()).map(|_| CounterSlot::default()).collect() }
    }
}

/// How many threads own slots of every [`Counter`] and of a frame's times at once: twice the
/// processor's threads and a few more (pools of more threads than cores, a distributed worker's
/// talking thread, the caller's own), so that every thread of a frame has one.
fn slot_count() -> usize {
    static COUNT: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *COUNT.get_or_init(|| {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        (2 * cores + 8).min(MOST_SLOTS)
    })
}

/// The most slots a counter has, however many threads the processor runs (each slot a cache line
/// pair in every counter of every frame).
const MOST_SLOTS: usize = 1024;

/// A thread's slot in every [`Counter`] and in a frame's times, which it gives back when it ends,
/// so that the threads alive at once, not all the threads a long run ever started, need slots.
struct SlotLease(usize);

/// Slots given back by threads that ended.
static FREE_SLOTS: Mutex<Vec<usize>> = Mutex::new(Vec::new());

/// The next slot no thread has owned.
static NEXT_SLOT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

impl SlotLease {
    fn take() -> SlotLease {
        let freed = FREE_SLOTS.lock().unwrap_or_else(PoisonError::into_inner).pop();
        SlotLease(freed.unwrap_or_else(|| NEXT_SLOT.fetch_add(1, Ordering::Relaxed)))
    }
}

impl Drop for SlotLease {
    /// The slot goes back through the lock, so the next thread to take it sees every addition this
    /// one made before it starts adding to the same count with plain stores.
    fn drop(&mut self) {
        if self.0 < slot_count() {
            FREE_SLOTS.lock().unwrap_or_else(PoisonError::into_inner).push(self.0);
        }
    }
}

thread_local! {
    /// Which slot of every [`Counter`] this thread owns: no two live threads own the same one.
    static OWN_SLOT: SlotLease = SlotLease::take();
}

/// This thread's slot, or `usize::MAX` (past every slot) while it ends.
#[inline]
fn own_slot() -> usize {
    OWN_SLOT.try_with(|s| s.0).unwrap_or(usize::MAX)
}

/// One thread's part of a [`Counter`], alone on its cache line (two lines: adjacent lines are
/// fetched in pairs).
#[derive(Debug, Default)]
#[repr(align(128))]
struct CounterSlot(AtomicU64);

impl Counter {
    pub(super) fn add(&self, n: usize) {
        let own = own_slot();
        match self.slots.get(own).filter(|_| own < self.slots.len() - 1) {
            // Only this thread writes it: readers see the count before or after, never a torn one.
            Some(slot) => slot.0.store(slot.0.load(Ordering::Relaxed).wrapping_add(n as u64), Ordering::Relaxed),
            None => {
                if let Some(shared) = self.slots.last() {
                    shared.0.fetch_add(n as u64, Ordering::Relaxed);
                }
            }
        }
    }

    /// The sum over threads (of what they added before, for example, the frame's tiles joined).
    pub fn load(&self) -> u64 {
        self.slots.iter().map(|s| s.0.load(Ordering::Relaxed)).fold(0, u64::wrapping_add)
    }
}

/// One thread's shading times in a frame ([`Stats::shading_ns`] and the others), kept apart from
/// other threads' for the same reason as a [`Counter`]'s slots: every outermost shading adds to
/// them, and a lock or a line that all threads share would make them wait for each other.
#[derive(Debug, Default)]
struct Times {
    shading_ns: u64,
    kind_ns: [u64; ShaderKind::ALL.len()],
    programs: Vec<(Program, u64)>,
}

/// A thread's [`Times`], on lines of its own; only its owner locks it while the frame renders.
#[derive(Debug, Default)]
#[repr(align(128))]
struct TimeSlot(Mutex<Times>);

/// Counters of one frame, summed over threads.
#[derive(Debug)]
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
    /// Per thread slot, then the shared one: time spent shading (surface and light shaders and the
    /// renderer's side of their calls), tracing excluded; of that, the time inside each type of
    /// shader's batches (filling the batch, running it, reading it back and the host calls it
    /// makes, exclusive of tracing and of other shaders it runs); and the same per shader program.
    times: Box<[TimeSlot]>,
    /// Global illumination: the time spent tracing the frame's light paths (virtual lights and
    /// caustic photons, the photon map's tree included; threads that need them meanwhile wait),
    /// and the threads' time gathering virtual lights (their shadow rays included), nanoseconds.
    pub light_paths_ns: Counter,
    pub gathering_ns: Counter,
    /// Whether the shading times above are measured (`RenderOptions::time_shaders`; the frame
    /// sets it). Untimed, they stay zero and no clock is read.
    pub timed: bool,
}

impl Default for Stats {
    fn default() -> Stats {
        Stats {
            primary_rays: Counter::default(),
            shadow_rays: Counter::default(),
            secondary_rays: Counter::default(),
            transparency_rays: Counter::default(),
            shaded_points: Counter::default(),
            light_evaluations: Counter::default(),
            rays_cut: Counter::default(),
            lights_dropped: Counter::default(),
            times: (0..=slot_count()).map(|_| TimeSlot::default()).collect(),
            light_paths_ns: Counter::default(),
            gathering_ns: Counter::default(),
            timed: false,
        }
    }
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
            let entries = CLOCK.with(|c| std::mem::take(&mut c.borrow_mut().entries));
            let Some(mut times) = self.stats.own_times() else { return };
            times.shading_ns += ns;
            for (program, ns) in entries {
                let Some(program) = program.filter(|_| ns > 0) else { continue };
                times.kind_ns[kind_index(program.kind)] += ns;
                add_program_time(&mut times.programs, program, ns);
            }
        }
    }
}

/// Adds `ns` to `program`'s entry in `programs`, or gives it one.
fn add_program_time(programs: &mut Vec<(Program, u64)>, program: Program, ns: u64) {
    match programs.iter_mut().find(|(p, _)| Arc::ptr_eq(p, &program)) {
        Some((_, total)) => *total += ns,
        None => programs.push((program, ns)),
    }
}

impl Stats {
    /// A frame's counters, all zero; its shaders timed where `timed` says.
    pub(super) fn with_timing(timed: bool) -> Stats {
        Stats { timed, ..Stats::default() }
    }

    pub(super) fn add(counter: &Counter, n: usize) {
        counter.add(n);
    }

    /// This thread's times: its slot's, or the shared slot past the last.
    fn own_times(&self) -> Option<std::sync::MutexGuard<'_, Times>> {
        let slot = self.times.get(own_slot().min(self.times.len().checked_sub(1)?))?;
        Some(slot.0.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// Calls `f` with each thread's times (see [`Stats::times`]).
    fn each_times(&self, mut f: impl FnMut(&Times)) {
        for slot in self.times.iter() {
            f(&slot.0.lock().unwrap_or_else(PoisonError::into_inner));
        }
    }

    /// The time spent shading, tracing excluded, summed over threads (nanoseconds).
    pub fn shading_ns(&self) -> u64 {
        let mut sum = 0u64;
        self.each_times(|t| sum = sum.wrapping_add(t.shading_ns));
        sum
    }

    /// The time inside each type of shader's batches, in [`ShaderKind::ALL`] order (nanoseconds).
    pub fn kind_ns(&self) -> [u64; ShaderKind::ALL.len()] {
        let mut sums = [0u64; ShaderKind::ALL.len()];
        self.each_times(|t| sums.iter_mut().zip(&t.kind_ns).for_each(|(s, n)| *s = s.wrapping_add(*n)));
        sums
    }

    /// The time inside each shader program's batches (nanoseconds), each program once.
    pub fn program_ns(&self) -> Vec<(Program, u64)> {
        let mut all = Vec::new();
        self.each_times(|t| t.programs.iter().for_each(|(p, ns)| add_program_time(&mut all, p.clone(), *ns)));
        all
    }

    pub fn total_rays(&self) -> u64 {
        self.primary_rays.load() + self.shadow_rays.load() + self.secondary_rays.load() + self.transparency_rays.load()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Held by the tests that start more threads than there are slots, or that count which slots
    /// threads get, so that one does not hold every slot while another counts.
    static MANY_THREADS: Mutex<()> = Mutex::new(());

    /// What threads add, in and out of the pool (more threads than slots among them), is all
    /// counted, and the slots stay on lines of their own.
    #[test]
    fn counters_sum_what_every_thread_adds() {
        let _alone = MANY_THREADS.lock().unwrap_or_else(PoisonError::into_inner);
        assert!(std::mem::align_of::<CounterSlot>() >= 128);
        let stats = Stats::default();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(slot_count() + 3).build().unwrap();
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
            for _ in 0..2 * slot_count() {
                scope.spawn(|| (0..100_000).for_each(|_| Stats::add(&stats.transparency_rays, 3)));
            }
        });
        let want: usize = (0..10_000).map(|i| i % 7).sum();
        assert_eq!(stats.primary_rays.load(), want as u64);
        assert_eq!(stats.shadow_rays.load(), 10_000);
        assert_eq!(stats.transparency_rays.load(), 2 * slot_count() as u64 * 100_000 * 3);
        assert_eq!(stats.total_rays(), want as u64 + 10_000 + 5 + 2 * slot_count() as u64 * 300_000);
    }

    /// A thread that ends gives its slot back: threads started one after another, many more than
    /// there are slots, take the same few slots again rather than each a new one (which would
    /// leave every thread after the first few sharing one line), and lose no count.
    #[test]
    fn threads_that_end_give_their_slots_back() {
        let _alone = MANY_THREADS.lock().unwrap_or_else(PoisonError::into_inner);
        let stats = Stats::default();
        let threads = 4 * slot_count();
        let mut owned = Vec::new();
        for _ in 0..threads {
            owned.push(std::thread::scope(|scope| {
                scope
                    .spawn(|| {
                        Stats::add(&stats.shaded_points, 2);
                        own_slot()
                    })
                    .join()
                    .unwrap()
            }));
        }
        assert_eq!(stats.shaded_points.load(), 2 * threads as u64);
        owned.sort_unstable();
        owned.dedup();
        assert!(owned.len() < threads / 2, "{} distinct slots for {threads} threads in turn", owned.len());
    }

    /// Shading times are kept per thread and summed when read: what every thread's timers add is
    /// in the frame's totals, by kind and by program.
    #[test]
    fn shading_times_sum_over_threads() {
        let _alone = MANY_THREADS.lock().unwrap_or_else(PoisonError::into_inner);
        let stats = Stats::default();
        let threads = slot_count() + 3;
        std::thread::scope(|scope| {
            for _ in 0..threads {
                scope.spawn(|| {
                    let mut t = stats.own_times().expect("a frame has time slots");
                    t.shading_ns += 5;
                    t.kind_ns[1] += 3;
                });
            }
        });
        assert_eq!(stats.shading_ns(), 5 * threads as u64);
        assert_eq!(stats.kind_ns()[1], 3 * threads as u64);
        assert_eq!(stats.kind_ns().iter().sum::<u64>(), 3 * threads as u64);
        assert!(stats.program_ns().is_empty());
    }
}

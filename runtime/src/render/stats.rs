//! What a frame counts: rays by kind, shaded points, light shader runs, and the time spent shading
//! with tracing excluded (per-thread timers around the outermost shading, minus the tracer calls
//! made meanwhile).

use std::sync::atomic::{AtomicU64, Ordering};

/// Counters of one frame, summed over threads.
#[derive(Debug, Default)]
pub struct Stats {
    pub primary_rays: AtomicU64,
    pub shadow_rays: AtomicU64,
    pub secondary_rays: AtomicU64,
    pub transparency_rays: AtomicU64,
    pub shaded_points: AtomicU64,
    pub light_evaluations: AtomicU64,
    /// Time spent shading (surface and light shaders and the renderer's side of their calls),
    /// tracing excluded, summed over threads.
    pub shading_ns: AtomicU64,
}

thread_local! {
    /// Nanoseconds this thread spent in tracer calls made while shading, and how deeply shading
    /// is nested on this thread (trace() shades recursively; only the outermost level is timed).
    static TRACE_NS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    static SHADE_NESTING: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// Runs a tracer query, counting its time as tracing rather than shading.
pub(super) fn tracing<R>(f: impl FnOnce() -> R) -> R {
    let start = std::time::Instant::now();
    let r = f();
    let ns = start.elapsed().as_nanos() as u64;
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
        let start = outer.then(|| (std::time::Instant::now(), TRACE_NS.with(|t| t.get())));
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
        }
    }
}

impl Stats {
    pub(super) fn add(counter: &AtomicU64, n: usize) {
        counter.fetch_add(n as u64, Ordering::Relaxed);
    }

    pub fn total_rays(&self) -> u64 {
        self.primary_rays.load(Ordering::Relaxed)
            + self.shadow_rays.load(Ordering::Relaxed)
            + self.secondary_rays.load(Ordering::Relaxed)
            + self.transparency_rays.load(Ordering::Relaxed)
    }
}

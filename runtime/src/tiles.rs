//! Demand-driven tiles over threads.
//!
//! The image is cut into square tiles. Worker threads of the current rayon pool take the next
//! tile from a shared atomic counter until none is left, so fast threads take more tiles.
//!
//! Invariant (determinism): a tile's result depends only on the tile, and results are returned in
//! tile order, so whatever the thread count, the assembled image (and any sum over tiles taken in
//! order) is bit-identical.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// A rectangle of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Position in the tile order.
    pub index: usize,
    /// Left column.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Tile {
    /// The four quarters of this tile, rows from the top, each with this tile's index; `None`
    /// unless its width and height are even.
    pub fn quarters(&self) -> Option<[Tile; 4]> {
        if self.width % 2 != 0 || self.height % 2 != 0 || self.width == 0 || self.height == 0 {
            return None;
        }
        let (w, h) = (self.width / 2, self.height / 2);
        let at = |qx: u32, qy: u32| Tile {
            index: self.index,
            x0: self.x0 + qx * w,
            y0: self.y0 + qy * h,
            width: w,
            height: h,
        };
        Some([at(0, 0), at(1, 0), at(0, 1), at(1, 1)])
    }
}

/// The tiles of a `width` x `height` image, `size` x `size` pixels each (smaller at the right and
/// bottom edges), in row-major order.
pub fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let size = size.max(1);
    let mut out = Vec::new();
    for y0 in (0..height).step_by(size as usize) {
        for x0 in (0..width).step_by(size as usize) {
            out.push(Tile { index: out.len(), x0, y0, width: size.min(width - x0), height: size.min(height - y0) });
        }
    }
    out
}

/// Runs `f` on every tile, demand-driven over the threads of the current rayon pool, and returns
/// the results in tile order.
pub fn render_tiles<T, F>(width: u32, height: u32, size: u32, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(&Tile) -> T + Sync,
{
    let list = tiles(width, height, size);
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, T)>> = Mutex::new(Vec::with_capacity(list.len()));
    let workers = rayon::current_num_threads().min(list.len()).max(1);
    rayon::scope(|s| {
        for _ in 0..workers {
            s.spawn(|_| {
                let mut mine = Vec::new();
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(tile) = list.get(i) else { break };
                    mine.push((i, f(tile)));
                }
                // A poisoned lock means another worker panicked; rayon re-raises that panic.
                if let Ok(mut r) = results.lock() {
                    r.extend(mine);
                }
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    results.sort_unstable_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, t)| t).collect()
}

/// The share of `threads` threads' time spent on tiles when tiles of these render `times` (any
/// unit), in tile order, are handed out as [`render_tiles`] hands them out: each to the first
/// thread free, in order. 1 when every thread finishes together; the rest is the frame's tail,
/// threads idle while the last tiles finish. A model of the hand-out alone, for times measured
/// on another thread count: it leaves out what changes with the threads (clocks, caches, memory).
pub fn hand_out_busy_share(times: &[f64], threads: usize) -> f64 {
    let threads = threads.max(1);
    let total: f64 = times.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return 1.0;
    }
    let mut free = vec![0.0f64; threads];
    for &t in times {
        // `threads` is a few hundred at most: a scan is as quick as a heap.
        let (first, _) =
            free.iter().enumerate().fold((0, f64::INFINITY), |a, (i, &f)| if f < a.1 { (i, f) } else { a });
        free[first] += t.max(0.0);
    }
    let makespan = free.iter().copied().fold(0.0f64, f64::max);
    total / (threads as f64 * makespan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hand_out_replay_counts_the_tail() {
        // Even tiles, a whole number per thread: nobody waits.
        assert_eq!(hand_out_busy_share(&[1.0; 64], 16), 1.0);
        // 17 tiles of 1 on 16 threads: one thread takes two, the others idle for one.
        assert!((hand_out_busy_share(&[1.0; 17], 16) - 17.0 / 32.0).abs() < 1e-12);
        // A long tile handed out last holds the frame: 15 threads wait 8 while it renders.
        let mut times = vec![1.0; 16];
        times.push(8.0);
        assert!((hand_out_busy_share(&times, 16) - 24.0 / (16.0 * 9.0)).abs() < 1e-12);
        // First, the same tile is hidden behind the others.
        times.rotate_right(1);
        assert!((hand_out_busy_share(&times, 2) - 1.0).abs() < 1e-12);
        // Fewer tiles than threads, and nothing to do.
        assert!((hand_out_busy_share(&[2.0, 2.0], 4) - 0.5).abs() < 1e-12);
        assert_eq!(hand_out_busy_share(&[], 8), 1.0);
        assert_eq!(hand_out_busy_share(&[1.0, 1.0], 0), 1.0);
    }

    #[test]
    fn tiles_cover_the_image() {
        let t = tiles(100, 37, 16);
        let area: u32 = t.iter().map(|t| t.width * t.height).sum();
        assert_eq!(area, 100 * 37);
    }

    #[test]
    fn quarters_cover_their_tile_once() {
        let tile = Tile { index: 7, x0: 32, y0: 16, width: 16, height: 10 };
        let quarters = tile.quarters().expect("even sides");
        let mut covered = vec![0; 16 * 10];
        for q in quarters {
            assert_eq!((q.index, q.width, q.height), (7, 8, 5));
            for y in q.y0..q.y0 + q.height {
                for x in q.x0..q.x0 + q.width {
                    covered[((y - 16) * 16 + x - 32) as usize] += 1;
                }
            }
        }
        assert!(covered.iter().all(|&n| n == 1), "{covered:?}");
        assert_eq!((quarters[1].x0, quarters[2].y0), (40, 21));
        for odd in [Tile { width: 15, ..tile }, Tile { height: 9, ..tile }, Tile { width: 0, ..tile }] {
            assert_eq!(odd.quarters(), None);
        }
    }

    #[test]
    fn results_in_tile_order_whatever_the_threads() {
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let r = pool.install(|| render_tiles(64, 64, 8, |t| t.index));
            assert_eq!(r, (0..64).collect::<Vec<_>>());
        }
    }
}

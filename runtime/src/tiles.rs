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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image() {
        let t = tiles(100, 37, 16);
        let area: u32 = t.iter().map(|t| t.width * t.height).sum();
        assert_eq!(area, 100 * 37);
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

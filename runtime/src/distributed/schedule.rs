//! Which worker renders which tile: demand-driven, and coherent in space and time (the paper's
//! section 2.3). Each worker has a list of tiles it prefers: the tiles it rendered last frame, or
//! on a first frame a contiguous block of the image. A worker asking for work gets its next
//! preferred tile; once its own are gone it takes from the end of the longest list left, so
//! workers that run fast help the slow ones without breaking their runs of neighbouring tiles.
//!
//! Where the tiles' costs in the last frame are known, each list runs from the most expensive
//! tile to the cheapest (longest processing time first): what a worker still holds, or another
//! takes from the end of its list, near the end of a frame is cheap, so no worker finishes long
//! after the others on a few expensive tiles handed out last.

use std::collections::VecDeque;

pub struct Schedule {
    /// Per worker, the tiles it prefers, in image order.
    preferred: Vec<VecDeque<u32>>,
    taken: Vec<bool>,
    left: usize,
}

impl Schedule {
    /// The schedule of `tiles` tiles over `workers` workers; `last_owner[t]` is the worker that
    /// rendered tile `t` last frame, if it is known and the tiles are the same, and `last_cost[t]`
    /// what it took then (in any unit; ignored unless there is one for every tile).
    pub fn new(tiles: usize, workers: usize, last_owner: &[Option<usize>], last_cost: &[u32]) -> Schedule {
        let workers = workers.max(1);
        let mut preferred = vec![VecDeque::new(); workers];
        for t in 0..tiles {
            let owner = match last_owner.get(t).copied().flatten() {
                Some(w) if w < workers && last_owner.len() == tiles => w,
                _ => t * workers / tiles.max(1),
            };
            preferred[owner].push_back(t as u32);
        }
        if last_cost.len() == tiles {
            for list in &mut preferred {
                list.make_contiguous().sort_by_key(|&t| std::cmp::Reverse(last_cost[t as usize]));
            }
        }
        Schedule { preferred, taken: vec![false; tiles], left: tiles }
    }

    /// Tiles not handed out yet.
    pub fn left(&self) -> usize {
        self.left
    }

    /// The next tile for `worker`, or `None` when every tile is handed out.
    pub fn next(&mut self, worker: usize) -> Option<u32> {
        while let Some(t) = self.preferred.get_mut(worker).and_then(VecDeque::pop_front) {
            if self.take(t) {
                return Some(t);
            }
        }
        loop {
            let longest = self.preferred.iter_mut().max_by_key(|q| q.len())?;
            let t = longest.pop_back()?;
            if self.take(t) {
                return Some(t);
            }
        }
    }

    fn take(&mut self, t: u32) -> bool {
        match self.taken.get_mut(t as usize) {
            Some(taken) if !*taken => {
                *taken = true;
                self.left -= 1;
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_tile_is_handed_out_once() {
        for (tiles, workers) in [(0, 3), (1, 3), (10, 3), (300, 7), (5, 1)] {
            let mut s = Schedule::new(tiles, workers, &[], &[]);
            let mut seen = vec![0; tiles];
            // Workers ask in an uneven order: worker 0 three times as often.
            let order = [0, 0, 0, 1, 2, 3, 4, 5, 6];
            let mut k = 0;
            while let Some(t) = s.next(order[k % order.len()] % workers) {
                seen[t as usize] += 1;
                k += 1;
            }
            assert!(seen.iter().all(|&n| n == 1), "{tiles} tiles over {workers} workers: {seen:?}");
            assert_eq!(s.left(), 0);
        }
    }

    #[test]
    fn workers_keep_last_frames_tiles_and_start_on_blocks() {
        let mut s = Schedule::new(8, 2, &[], &[]);
        assert_eq!((s.next(0), s.next(1), s.next(0), s.next(1)), (Some(0), Some(4), Some(1), Some(5)));
        let last = [1, 1, 0, 0, 1, 0, 0, 1].map(Some);
        let mut s = Schedule::new(8, 2, &last, &[]);
        let mine: Vec<_> = (0..4).filter_map(|_| s.next(1)).collect();
        assert_eq!(mine, [0, 1, 4, 7]);
        // Worker 1's own tiles are gone: it takes from the end of worker 0's.
        assert_eq!(s.next(1), Some(6));
        assert_eq!(s.next(0), Some(2));
    }

    #[test]
    fn the_most_expensive_tiles_go_first_and_the_cheapest_are_taken_from_others() {
        let last = [0, 0, 0, 0, 1, 1, 1, 1].map(Some);
        let cost = [5, 90, 20, 90, 1, 2, 3, 4];
        let mut s = Schedule::new(8, 2, &last, &cost);
        // Ties keep image order.
        assert_eq!((s.next(0), s.next(0), s.next(0)), (Some(1), Some(3), Some(2)));
        // Worker 1 runs through its own, then takes worker 0's cheapest.
        let mine: Vec<_> = (0..5).filter_map(|_| s.next(1)).collect();
        assert_eq!(mine, [7, 6, 5, 4, 0]);
        assert_eq!(s.next(0), None);
        // Costs for other tiles than these are ignored.
        let s = Schedule::new(8, 2, &last, &cost[..7]);
        assert_eq!(s.preferred[0], [0, 1, 2, 3]);
    }

    #[test]
    fn a_stale_owner_list_is_ignored() {
        let s = Schedule::new(4, 2, &[Some(1), Some(1)], &[]);
        assert_eq!(s.preferred[0], [0, 1]);
        let s = Schedule::new(4, 2, &[Some(5), Some(5), Some(5), Some(5)], &[]);
        assert_eq!(s.preferred[1], [2, 3]);
    }
}

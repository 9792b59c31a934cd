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

//!
//! Near a frame's end whole tiles are too coarse: one expensive tile started last keeps its
//! worker busy while the others have run dry. So the last tiles go out in **quarters**
//! ([`Schedule::splitting`]), units of their own that any worker may take.

use crate::render::TileRenderer;
use crate::tiles::Tile;
use std::collections::VecDeque;

/// The units of a frame of `tiles` tiles: tile `t` whole is unit `t`; handed out in quarters, its
/// quarter `q` (rows from the top) is unit `tiles + 4t + q`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileUnit {
    Whole(u32),
    Quarter(u32, u32),
}

impl TileUnit {
    /// What unit `unit` of a frame of `tiles` tiles is; `None` past its last quarter.
    pub fn of(unit: u32, tiles: usize) -> Option<TileUnit> {
        let (unit, tiles) = (unit as u64, tiles as u64);
        if unit < tiles {
            return Some(TileUnit::Whole(unit as u32));
        }
        let quarter = unit - tiles;
        (quarter < 4 * tiles).then_some(TileUnit::Quarter((quarter / 4) as u32, (quarter % 4) as u32))
    }

    /// How many units a frame of `tiles` tiles numbers, its quarters included.
    pub fn count(tiles: usize) -> usize {
        tiles.saturating_mul(5)
    }

    /// The share of its tile's pixels a unit covers, in quarters.
    pub fn quarters(self) -> usize {
        match self {
            TileUnit::Whole(_) => 4,
            TileUnit::Quarter(..) => 1,
        }
    }

    /// The tile.
    pub fn tile(self) -> u32 {
        match self {
            TileUnit::Whole(t) | TileUnit::Quarter(t, _) => t,
        }
    }
}

/// The pixels unit `unit` of a frame of `tiles` covers: a whole tile, or a quarter of one whose
/// quarters render as the whole tile does ([`TileRenderer::quarters`]); `None` for any other.
pub fn unit_tile(renderer: &TileRenderer, tiles: &[Tile], unit: u32) -> Option<Tile> {
    match TileUnit::of(unit, tiles.len())? {
        TileUnit::Whole(t) => tiles.get(t as usize).copied(),
        TileUnit::Quarter(t, q) => renderer.quarters(tiles.get(t as usize)?)?.get(q as usize).copied(),
    }
}

pub struct Schedule {
    /// Per worker, the tiles it prefers, in image order.
    preferred: Vec<VecDeque<u32>>,
    taken: Vec<bool>,
    left: usize,
    /// Tiles taken while fewer than this many are left go out in quarters, where `splittable`.
    split_below: usize,
    splittable: Vec<bool>,
    /// The quarters of split tiles not handed out yet, as units.
    pieces: VecDeque<u32>,
    split: u64,
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
        Schedule {
            preferred,
            taken: vec![false; tiles],
            left: tiles,
            split_below: 0,
            splittable: Vec::new(),
            pieces: VecDeque::new(),
            split: 0,
        }
    }

    /// This schedule handing out each tile `t` for which `splittable(t)` in quarters ([`TileUnit`])
    /// once fewer than `below` tiles are left to hand out (none: never; the number of tiles:
    /// every one). A split tile's quarters go out before any other tile, to whichever workers
    /// ask first.
    pub fn splitting(mut self, below: usize, splittable: impl Fn(u32) -> bool) -> Schedule {
        self.split_below = below;
        self.splittable = (0..self.taken.len() as u32).map(splittable).collect();
        self
    }

    /// The work not handed out yet, in tiles: a split tile's quarters left count as a tile.
    pub fn left(&self) -> usize {
        self.left + self.pieces.len().div_ceil(4)
    }

    /// How many tiles went out in quarters.
    pub fn split(&self) -> u64 {
        self.split
    }

    /// The next unit for `worker`, or `None` when every tile is handed out.
    pub fn next(&mut self, worker: usize) -> Option<u32> {
        if let Some(quarter) = self.pieces.pop_front() {
            return Some(quarter);
        }
        let t = self.next_tile(worker)?;
        if self.left >= self.split_below || !self.splittable.get(t as usize).copied().unwrap_or(false) {
            return Some(t);
        }
        let tiles = self.taken.len() as u64;
        // `TileUnit::count` of the frame fits a `u32` where its tiles' quarters are numbered.
        let first = u32::try_from(tiles + 4 * u64::from(t)).ok().filter(|f| f.checked_add(3).is_some());
        let Some(first) = first else { return Some(t) };
        self.pieces.extend(first + 1..first + 4);
        self.split += 1;
        Some(first)
    }

    /// The next whole tile for `worker`.
    fn next_tile(&mut self, worker: usize) -> Option<u32> {
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

/// Who holds which of a frame's units until one of them delivers it. Once every unit is handed
/// out, a worker with nothing left to do is given **copies** of units that others hold and have
/// not started (the last handed out, from the worker with the most waiting): the master cannot
/// take a unit back without a round trip, so it lets two workers race for it, takes whichever
/// delivers first and tells the other to leave it out. Near the end of a frame that turns a
/// worker's backlog into work for the idle, which last frame's costs and the shares of what is
/// left only estimate.
pub struct Holdings {
    /// Per unit: the worker it was handed to, the helper that holds a copy, and who delivered it.
    owner: Vec<Option<usize>>,
    helper: Vec<Option<usize>>,
    delivered: Vec<Option<usize>>,
    /// Per worker: the units it holds that no one has delivered, in the order they were handed
    /// out (the order it renders them in).
    held: Vec<VecDeque<u32>>,
    helping: Helping,
}

/// How a frame's copies for helpers went ([`Holdings`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Helping {
    /// Units copied to a helper.
    pub copies: u64,
    /// Of those, the units the helper delivered first.
    pub helped: u64,
    /// Units delivered a second time: rendered by both (the second started before the first
    /// copy arrived, or before the word to leave it out did).
    pub twice: u64,
    /// Tiles handed out in quarters ([`Schedule::splitting`]).
    pub quartered: u64,
}

/// A unit arriving from a worker.
#[derive(Debug, PartialEq, Eq)]
pub enum Delivery {
    /// The first copy: `other`, the other worker that holds it, if any, can leave it out.
    First { other: Option<usize> },
    /// Another worker delivered it first.
    Again,
    /// The worker never held it.
    NotGiven,
}

impl Holdings {
    pub fn new(units: usize, workers: usize) -> Holdings {
        Holdings {
            owner: vec![None; units],
            helper: vec![None; units],
            delivered: vec![None; units],
            held: vec![VecDeque::new(); workers],
            helping: Helping::default(),
        }
    }

    /// Unit `unit` is handed to `worker` (from the [`Schedule`]).
    pub fn hand(&mut self, worker: usize, unit: u32) {
        if let (Some(owner), Some(held)) = (self.owner.get_mut(unit as usize), self.held.get_mut(worker)) {
            *owner = Some(worker);
            held.push_back(unit);
        }
    }

    /// How many units `worker` holds that no one has delivered.
    pub fn held(&self, worker: usize) -> usize {
        self.held.get(worker).map_or(0, VecDeque::len)
    }

    /// The units `worker` holds that no one has delivered, each counted by `weight`.
    pub fn held_weight(&self, worker: usize, weight: impl Fn(u32) -> usize) -> usize {
        self.held.get(worker).map_or(0, |held| held.iter().map(|&u| weight(u)).sum())
    }

    /// Who delivered each unit first, and how the copies went.
    pub fn delivered(self) -> (Vec<Option<usize>>, Helping) {
        (self.delivered, self.helping)
    }

    /// `worker` sends `unit`.
    pub fn deliver(&mut self, worker: usize, unit: u32) -> Delivery {
        let u = unit as usize;
        let (Some(&owner), Some(&helper)) = (self.owner.get(u), self.helper.get(u)) else {
            return Delivery::NotGiven;
        };
        if owner != Some(worker) && helper != Some(worker) {
            return Delivery::NotGiven;
        }
        if self.delivered[u].is_some() {
            self.helping.twice += 1;
            return Delivery::Again;
        }
        self.delivered[u] = Some(worker);
        self.helping.helped += u64::from(helper == Some(worker));
        for holder in [owner, helper].into_iter().flatten() {
            if let Some(at) = self.held[holder].iter().position(|&h| h == unit) {
                self.held[holder].remove(at);
            }
        }
        let other = if owner == Some(worker) { helper } else { owner };
        Delivery::First { other }
    }

    /// Copies for `helper` of units that other workers hold and have not started, until their
    /// `weight`s add up to `wanted`: each the last handed out of the worker with the most such
    /// units waiting behind the ones its `threads(worker)` threads render. A unit is copied once.
    pub fn copies_for(
        &mut self,
        helper: usize,
        wanted: usize,
        weight: impl Fn(u32) -> usize,
        threads: impl Fn(usize) -> usize,
    ) -> Vec<u32> {
        let (mut copies, mut given) = (Vec::new(), 0);
        while given < wanted {
            let most = (0..self.held.len())
                .filter(|&w| w != helper)
                .map(|w| (self.copyable(w, threads(w)).count(), w))
                .filter(|&(n, _)| n > 0)
                .max_by_key(|&(n, w)| (n, std::cmp::Reverse(w)));
            let Some(unit) = most.and_then(|(_, from)| self.copyable(from, threads(from)).next()) else { break };
            self.helper[unit as usize] = Some(helper);
            self.held[helper].push_back(unit);
            self.helping.copies += 1;
            given += weight(unit).max(1);
            copies.push(unit);
        }
        copies
    }

    /// The units `worker` holds behind the `threads` it renders that no helper has a copy of,
    /// the last handed out first.
    fn copyable(&self, worker: usize, threads: usize) -> impl Iterator<Item = u32> + '_ {
        let held = &self.held[worker];
        let waiting = held.range(threads.min(held.len())..).rev().copied();
        waiting.filter(move |&u| self.helper[u as usize].is_none() && self.owner[u as usize] == Some(worker))
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
    fn idle_workers_get_copies_of_the_units_others_have_not_started() {
        let one_thread = |_| 1;
        let mut h = Holdings::new(10, 3);
        // Worker 0 holds 0..6 (renders 0, the rest wait), worker 1 holds 6 and 7, worker 2 none.
        for u in 0..6 {
            h.hand(0, u);
        }
        h.hand(1, 6);
        h.hand(1, 7);
        // Worker 2 gets the last handed out of the worker with most waiting, never a unit being
        // rendered: worker 0's 5, 4, 3, 2, 1 (on a tie, the first worker), then worker 1's 7.
        assert_eq!(h.copies_for(2, 3, |_| 1, one_thread), [5, 4, 3]);
        assert_eq!(h.copies_for(2, 3, |_| 1, one_thread), [2, 1, 7]);
        assert_eq!(h.copies_for(2, 3, |_| 1, one_thread), Vec::<u32>::new());
        assert_eq!((h.held(0), h.held(1), h.held(2)), (6, 2, 6));
        // A unit is copied once: worker 1 finds nothing left to copy.
        assert_eq!(h.copies_for(1, 5, |_| 1, one_thread), Vec::<u32>::new());
        // The helper delivers 5 first: worker 0 may leave it out; its copy, if it comes, is late.
        assert_eq!(h.deliver(2, 5), Delivery::First { other: Some(0) });
        assert_eq!(h.deliver(0, 5), Delivery::Again);
        assert_eq!((h.held(0), h.held(2)), (5, 5));
        // Worker 0 delivers its own 0 (no copy) and 4 before the helper.
        assert_eq!(h.deliver(0, 0), Delivery::First { other: None });
        assert_eq!(h.deliver(0, 4), Delivery::First { other: Some(2) });
        // Nobody else may deliver a unit: not the one that neither holds nor copied it.
        assert_eq!(h.deliver(1, 4), Delivery::NotGiven);
        assert_eq!(h.deliver(1, 3), Delivery::NotGiven);
        assert_eq!(h.deliver(0, 99), Delivery::NotGiven);
        let (delivered, helping) = h.delivered();
        assert_eq!(&delivered[..6], [Some(0), None, None, None, Some(0), Some(2)]);
        assert_eq!(helping, Helping { copies: 6, helped: 1, twice: 1, quartered: 0 });
    }

    #[test]
    fn a_worker_of_several_threads_keeps_as_many_units_as_it_renders() {
        let mut h = Holdings::new(6, 2);
        for u in 0..6 {
            h.hand(0, u);
        }
        // Four threads render 0..4; only 4 and 5 wait.
        assert_eq!(h.copies_for(1, 10, |_| 1, |w| if w == 0 { 4 } else { 1 }), [5, 4]);
    }

    #[test]
    fn copies_are_counted_in_quarters_of_a_tile() {
        // Three tiles: worker 0 renders tile 0 and holds tile 1 and the quarters of tile 2.
        let quarters = |u: u32| TileUnit::of(u, 3).map_or(4, TileUnit::quarters);
        let mut h = Holdings::new(TileUnit::count(3), 2);
        for u in [0, 1, 11, 12, 13, 14] {
            h.hand(0, u);
        }
        assert_eq!(h.held_weight(0, quarters), 12);
        // Half a tile's worth: two quarters, the last handed out first; then a tile's worth,
        // which takes the whole tile behind the quarters left.
        assert_eq!(h.copies_for(1, 2, quarters, |_| 1), [14, 13]);
        assert_eq!(h.copies_for(1, 4, quarters, |_| 1), [12, 11, 1]);
        assert_eq!(h.copies_for(1, 4, quarters, |_| 1), Vec::<u32>::new());
        assert_eq!(h.held_weight(1, quarters), 8);
    }

    #[test]
    fn the_last_tiles_go_out_in_quarters_to_whoever_asks() {
        // Ten tiles over two workers; tile 9 cannot be split. Fewer than four left: quarters.
        let mut s = Schedule::new(10, 2, &[], &[]).splitting(4, |t| t != 9);
        let whole: Vec<_> = [0, 1, 0, 1, 0, 1].iter().filter_map(|&w| s.next(w)).collect();
        assert_eq!(whole, [0, 5, 1, 6, 2, 7]);
        assert_eq!(s.left(), 4);
        // Worker 0's 3 leaves three tiles: it gets 3's first quarter, and the next asks, from
        // either worker, take the others before any other tile.
        assert_eq!(s.next(0), Some(10 + 4 * 3));
        assert_eq!(s.left(), 4);
        assert_eq!((s.next(1), s.next(0), s.next(1)), (Some(10 + 13), Some(10 + 14), Some(10 + 15)));
        assert_eq!(s.next(1), Some(10 + 4 * 8));
        let rest: Vec<_> = (0..8).map_while(|_| s.next(0)).collect();
        // Tile 9 goes whole.
        assert_eq!(rest, [43, 44, 45, 10 + 4 * 4, 27, 28, 29, 9]);
        assert_eq!((s.next(1), s.left(), s.split()), (None, 0, 3));
        // Every pixel once: each tile whole or in its four quarters.
        let units = [whole, vec![22, 23, 24, 25, 42], rest].concat();
        let mut covered = [0; 10];
        for u in units {
            let unit = TileUnit::of(u, 10).expect("a unit of the frame");
            covered[unit.tile() as usize] += unit.quarters();
        }
        assert_eq!(covered, [4; 10]);
    }

    #[test]
    fn units_number_tiles_then_their_quarters() {
        assert_eq!(TileUnit::of(2, 3), Some(TileUnit::Whole(2)));
        assert_eq!(TileUnit::of(3, 3), Some(TileUnit::Quarter(0, 0)));
        assert_eq!(TileUnit::of(3 + 4 * 2 + 3, 3), Some(TileUnit::Quarter(2, 3)));
        assert_eq!(TileUnit::of(15, 3), None);
        assert_eq!(TileUnit::of(u32::MAX, 3), None);
        assert_eq!(TileUnit::count(3), 15);
        // Without splitting, and with nothing splittable, tiles go whole.
        for mut s in [Schedule::new(4, 1, &[], &[]), Schedule::new(4, 1, &[], &[]).splitting(4, |_| false)] {
            assert_eq!((0..5).map_while(|_| s.next(0)).collect::<Vec<_>>(), [0, 1, 2, 3]);
        }
    }

    #[test]
    fn a_stale_owner_list_is_ignored() {
        let s = Schedule::new(4, 2, &[Some(1), Some(1)], &[]);
        assert_eq!(s.preferred[0], [0, 1]);
        let s = Schedule::new(4, 2, &[Some(5), Some(5), Some(5), Some(5)], &[]);
        assert_eq!(s.preferred[1], [2, 3]);
    }
}

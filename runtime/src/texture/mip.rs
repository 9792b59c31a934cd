//! The mip-map pyramid and filtered lookups over it.
//!
//! Level 0 is the image; each next level halves each dimension (rounding down, never below 1)
//! until 1x1. A level's texel is the area-weighted average of the texels of the level below that
//! it covers: for even sizes exactly the 2x2 box filter; for odd sizes the box is 2.x texels
//! wide and takes fractional parts of the texels on its edges, so every level keeps the image's
//! mean exactly (up to rounding).
//!
//! Lookups ([`MipMap::filter`]) turn the footprint into an ellipse in level-0 texels (the
//! covariance of the two derivative vectors, plus the blur), and place up to [`MAX_ANISOTROPY`]
//! equally weighted trilinear probes along its major axis: as many as the major axis is times
//! the minor one, less a quarter of slack, each as wide as its share of the major axis and at
//! least the minor axis (the mip level, trilinear between two levels). That is "EWA-lite": the
//! anisotropy of EWA at the cost of a handful of bilinear taps, with box rather than Gaussian
//! weights.
//!
//! [`MipMap::filter_lanes`] makes four lookups (a shader chunk's lanes) with the plan of their
//! probes worked out together in vector arithmetic, and, on textures whose levels wrap
//! periodically and are powers of two, their probes stepped through together too (probe `k` of
//! every lane at once); [`MipMap::filter`] is the same on one lane.

use super::image::{TexImage, TEXEL_PADDING};
use super::level_tiles::{tile_grid, TiledLevel, MAX_TILES_A_MAP};
use super::{Footprint, LookupOptions, Wrap};
use glam::{BVec4A, IVec4, Mat4, UVec4, Vec4};
use std::fmt;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

/// The most probes along a footprint's major axis; longer footprints are blurred across.
pub const MAX_ANISOTROPY: usize = 16;

/// How far past a whole number of probes a footprint's eccentricity may go before it takes
/// another: an ellipse 1.2 times as long as it is wide gets one probe as wide as the ellipse is
/// long (a quarter of a mip level blurrier across), not two. Nearly every footprint is slightly eccentric (a surface
/// seen a little off square), so without slack nearly every lookup took twice the probes it
/// needed.
const ANISOTROPY_SLACK: f32 = 0.25;

/// The locks a remote map fetches its tiles under ([`RemoteLevels::tile_locks`]).
const TILE_LOCKS: usize = 8;

/// A texture with its pre-filtered levels, immutable once built (so it is shared freely).
///
/// A map built here ([`MipMap::with_wrap`]) holds every level. A map a distributed worker
/// fetches ([`MipMap::remote`]) starts with its coarsest levels and gets each finer one the
/// first time a lookup reads it: computed from a finer level it holds, else fetched
/// (`texture/remote.rs`); a large level comes a tile at a time instead, each tile the first time
/// a lookup reads a texel of it (`texture/level_tiles.rs`). Either way a level or a tile, once
/// here, is the one the whole image would have made, bit for bit, and stays.
pub struct MipMap {
    /// Finest (the image itself) first; set once each.
    levels: Box<[OnceLock<TexImage>]>,
    /// A remote map's levels that come in tiles, where it does not hold them whole (`None` for
    /// the others); empty for a map built here.
    tiled: Box<[Option<TiledLevel>]>,
    /// Where the levels not yet here come from (a map built here has none missing).
    remote: Option<RemoteLevels>,
    /// The wrap modes of the file (s, t); a lookup may override them.
    wrap: [Wrap; 2],
    /// `worldToCamera` and `worldToNDC` from the file's header, if it had them.
    projection: Option<[[f32; 16]; 2]>,
    /// Every level's sizes fit an `i32` and its values 32-bit offsets, so periodic lookups go
    /// four lanes at once ([`MipMap::filter_lanes_periodic`]).
    periodic_lanes: bool,
    /// Every level is a power of two in both sizes: periodic taps are their coordinates' low bits.
    power_of_two_levels: bool,
    /// Each level's sizes, masks and row length, for [`LevelLanes`].
    shapes: Vec<LevelShape>,
    /// No level has an infinite or NaN value, so [`MipMap::filter_lanes_periodic`] may add taps
    /// of zero weight.
    finite: bool,
    /// Level 0's width, height and channels.
    size: [usize; 3],
}

/// A pyramid as [`MipMap::remote`] takes it: level 0's sizes, the map's properties, and its
/// coarsest levels.
pub(crate) struct RemotePyramid {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub wrap: [Wrap; 2],
    pub projection: Option<[[f32; 16]; 2]>,
    pub finite: bool,
    pub coarsest: Vec<TexImage>,
    /// The side of the tiles the finer levels come in where they are large (0: whole levels
    /// only); see `level_tiles.rs`.
    pub tile_side: usize,
}

/// Where a remote [`MipMap`] gets the levels it does not hold.
pub(crate) trait LevelFetch: Send + Sync {
    /// Level `level` of the map whose level 0 is `size` (width, height, channels), or the image
    /// itself; `None` when neither came (the source has recorded why).
    fn fetch_level(&self, level: usize, size: [usize; 3]) -> Option<FetchedLevel>;

    /// Tile `tile` of level `level` (a tile `tile_size` texels wide and high), or the image
    /// itself; `None` when neither came (the source has recorded why).
    fn fetch_tile(&self, level: usize, tile: usize, tile_size: [usize; 2], size: [usize; 3]) -> Option<FetchedLevel>;

    /// Records that something it delivered could not be used: the frame fails.
    fn failed(&self, message: String);

    /// Asks for level `level` without waiting ([`crate::accel::ask_ahead`]); returns whether
    /// it is still to come (`false`: fetch it now).
    fn ask_ahead_level(&self, _level: usize) -> bool {
        false
    }
}

/// What a [`LevelFetch`] delivers.
pub(crate) enum FetchedLevel {
    /// The level (or the tile) asked for.
    Level(TexImage),
    /// Level 0, the image, from which the map computes the rest.
    Image(TexImage),
}

/// What a remote map needs to fill in the levels it lacks.
#[derive(Clone)]
struct RemoteLevels {
    fetch: Arc<dyn LevelFetch>,
    /// Held while a level is filled in.
    busy: Arc<Mutex<()>>,
    /// Tile `k` is fetched holding lock `k % TILE_LOCKS`: threads that want other tiles fetch
    /// them meanwhile (a worker's requests go to the master together).
    tile_locks: Arc<[Mutex<()>]>,
    /// What a level whose fetch failed reads as: one texel of zeros. Lookups read it safely in
    /// place of a larger level: every tap is checked against the image it reads, not against the
    /// level's shape.
    stand_in: Arc<TexImage>,
}

impl Clone for MipMap {
    /// The levels held now; a remote map's copy fetches the others from the same place.
    fn clone(&self) -> MipMap {
        MipMap {
            levels: self.levels.iter().map(|l| l.get().cloned().map(OnceLock::from).unwrap_or_default()).collect(),
            tiled: self.tiled.clone(),
            remote: self.remote.clone(),
            shapes: self.shapes.clone(),
            ..*self
        }
    }
}

impl fmt::Debug for MipMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let held: Vec<usize> = (0..self.levels.len()).filter(|&i| self.levels[i].get().is_some()).collect();
        f.debug_struct("MipMap")
            .field("size", &self.size)
            .field("levels", &self.levels.len())
            .field("held", &held)
            .field("wrap", &self.wrap)
            .field("remote", &self.remote.is_some())
            .finish_non_exhaustive()
    }
}

/// The sizes of the levels of an image `width x height` (see the module doc), finest first.
pub fn level_sizes(width: usize, height: usize) -> Vec<[usize; 2]> {
    let mut sizes = vec![[width.max(1), height.max(1)]];
    while let Some(&[w, h]) = sizes.last().filter(|s| **s != [1, 1]) {
        sizes.push([(w / 2).max(1), (h / 2).max(1)]);
    }
    sizes
}

impl MipMap {
    /// Builds the pyramid of `image`, wrapping periodically unless a lookup says otherwise.
    pub fn new(image: TexImage) -> MipMap {
        MipMap::with_wrap(image, [Wrap::Periodic; 2])
    }

    /// Builds the pyramid with the file's own wrap modes (s, t).
    pub fn with_wrap(image: TexImage, wrap: [Wrap; 2]) -> MipMap {
        let mut levels = vec![image];
        loop {
            let last = levels.last().expect("level 0 exists");
            if last.width() == 1 && last.height() == 1 {
                break;
            }
            let next = downsample(last);
            levels.push(next);
        }
        let finite = levels.iter().all(|l| l.data().iter().all(|v| v.is_finite()));
        let size = [levels[0].width(), levels[0].height(), levels[0].channels()];
        MipMap::assemble(size, levels.into_iter().map(OnceLock::from).collect(), None, wrap, finite)
    }

    /// A map of which only the coarsest levels are here: `pyramid` describes the whole, and
    /// `fetch` delivers the finer levels (or the image) when lookups first read them. `None`
    /// when `pyramid` does not hold (a size of zero, no 1x1 level, a coarse level of another
    /// size or length).
    pub(crate) fn remote(pyramid: RemotePyramid, fetch: Arc<dyn LevelFetch>) -> Option<MipMap> {
        let RemotePyramid { width, height, channels, wrap, projection, finite, coarsest, tile_side } = pyramid;
        if width == 0 || height == 0 || channels == 0 || width.checked_mul(height)?.checked_mul(channels).is_none() {
            return None;
        }
        // The 1x1 level holds `channels` values as it came: the channel count, which sizes what
        // is made below, is then bounded by what was sent.
        if coarsest.is_empty() {
            return None;
        }
        let sizes = level_sizes(width, height);
        let first = sizes.len().checked_sub(coarsest.len())?;
        let mut levels: Vec<OnceLock<TexImage>> = sizes.iter().map(|_| OnceLock::new()).collect();
        for (k, level) in coarsest.into_iter().enumerate() {
            let [w, h] = sizes[first + k];
            if [level.width(), level.height(), level.channels()] != [w, h, channels] {
                return None;
            }
            levels[first + k] = OnceLock::from(level);
        }
        let stand_in = Arc::new(TexImage::new(1, 1, channels, vec![0.0; channels])?);
        // The large levels that did not come with the pyramid come in tiles, unless they would
        // take more than `MAX_TILES_A_MAP` slots: then a level at a time.
        let tiles: usize = sizes[..first].iter().filter_map(|&s| tile_grid(s, tile_side)).map(|[a, d]| a * d).sum();
        let tiled: Box<[Option<TiledLevel>]> = if tiles <= MAX_TILES_A_MAP && tile_side.is_power_of_two() {
            sizes.iter().enumerate().map(|(i, &s)| TiledLevel::new(s, tile_side).filter(|_| i < first)).collect()
        } else {
            Box::default()
        };
        let tile_locks = (0..TILE_LOCKS).map(|_| Mutex::new(())).collect();
        let remote = RemoteLevels { fetch, busy: Arc::new(Mutex::new(())), tile_locks, stand_in };
        let mut map = MipMap::assemble([width, height, channels], levels.into(), Some(remote), wrap, finite);
        if tiled.iter().any(Option::is_some) {
            map.tiled = tiled;
        }
        Some(map.with_projection(projection))
    }

    fn assemble(
        size: [usize; 3],
        levels: Box<[OnceLock<TexImage>]>,
        remote: Option<RemoteLevels>,
        wrap: [Wrap; 2],
        finite: bool,
    ) -> MipMap {
        let sizes = level_sizes(size[0], size[1]);
        // The periodic way's offsets are 32-bit: a level 0 of under 2^32 values (16 GiB) keeps
        // every offset and the four values after it in range.
        let periodic_lanes =
            size.iter().try_fold(1usize, |n, &k| n.checked_mul(k)).is_some_and(|n| n < (u32::MAX - 8) as usize)
                && sizes.iter().all(|&[w, h]| i32::try_from(w.max(h)).is_ok());
        let power_of_two_levels =
            periodic_lanes && sizes.iter().all(|&[w, h]| periodic_masks([w, h], [Wrap::Periodic; 2]).is_some());
        let shapes = sizes.iter().map(|&[w, h]| LevelShape::of(w, h, size[2])).collect();
        let tiled = Box::default();
        MipMap {
            levels,
            tiled,
            remote,
            wrap,
            projection: None,
            periodic_lanes,
            power_of_two_levels,
            shapes,
            finite,
            size,
        }
    }

    /// How many levels the pyramid has (each halving the last, down to 1x1).
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Level `i` (0 the image itself; past the last, the last), fetched or computed first when a
    /// remote map does not hold it yet.
    pub fn level(&self, i: usize) -> &TexImage {
        self.level_at(i.min(self.levels.len() - 1))
    }

    /// [`MipMap::level`] of a level that exists (lookups' own).
    #[inline(always)]
    fn level_at(&self, i: usize) -> &TexImage {
        match self.levels.get(i).and_then(OnceLock::get) {
            Some(level) => level,
            None => self.missing_level(i),
        }
    }

    /// Whether level `i` is here (always, for a map built here).
    pub fn holds_level(&self, i: usize) -> bool {
        self.levels.get(i).is_some_and(|l| l.get().is_some())
    }

    /// A remote map's level `i`, which it does not hold yet: computed from the nearest finer
    /// level it holds, else fetched; a level whose fetch failed reads as zeros (the frame fails,
    /// and the level is fetched again when next read).
    #[cold]
    #[inline(never)]
    fn missing_level(&self, i: usize) -> &TexImage {
        let i = i.min(self.levels.len() - 1);
        if let Some(level) = self.levels[i].get() {
            return level;
        }
        let Some(remote) = &self.remote else { unreachable!("a map built here holds every level") };
        // One thread at a time fills a map's levels: another thread that wanted the same one
        // finds it here when its turn comes.
        let _busy = remote.busy.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(level) = self.levels[i].get() {
            return level;
        }
        let finer = (0..i).rev().find(|&j| self.levels[j].get().is_some());
        if finer.is_none() && crate::accel::ask_ahead::asks_ahead() && remote.fetch.ask_ahead_level(i) {
            // A render thread asking ahead goes on without the level; nothing is kept of it.
            crate::accel::ask_ahead::missed();
            return &remote.stand_in;
        }
        let from = match finer {
            Some(j) => j,
            None => match remote.fetch.fetch_level(i, self.size) {
                Some(FetchedLevel::Level(level)) => {
                    let _ = self.levels[i].set(level);
                    i
                }
                Some(FetchedLevel::Image(image)) => {
                    let _ = self.levels[0].set(image);
                    0
                }
                None => return &remote.stand_in,
            },
        };
        for k in from..i {
            let Some(coarser) = self.levels[k].get().map(downsample) else { break };
            let _ = self.levels[k + 1].set(coarser);
        }
        match self.levels[i].get() {
            Some(level) => level,
            None => &remote.stand_in,
        }
    }

    /// How many tiles of level `i` a remote map holds and how many it is cut into, where that
    /// level comes in tiles.
    #[cfg(test)]
    pub(crate) fn tiles_held(&self, i: usize) -> Option<[usize; 2]> {
        let tiled = self.tiled.get(i)?.as_ref()?;
        Some([tiled.held(), tiled.count()])
    }

    /// Whether level `i` is to be read tile by tile: a remote map's level that comes in tiles,
    /// which it holds neither whole nor computes from a finer level it holds.
    #[inline(always)]
    fn reads_tiles(&self, i: usize) -> bool {
        self.tiled.get(i).is_some_and(Option::is_some) && !self.levels[..=i].iter().any(|l| l.get().is_some())
    }

    /// How a probe reads level `i`: tile by tile where [`MipMap::reads_tiles`], else whole
    /// (fetched or computed first where a remote map lacks it).
    fn level_read(&self, i: usize) -> LevelRead<'_> {
        match self.tiled.get(i) {
            Some(Some(tiled)) if self.reads_tiles(i) => LevelRead::Tiles(self, i, tiled),
            _ => LevelRead::Whole(self.level_at(i)),
        }
    }

    /// The four taps around (s, t) on level `i`, which comes in tiles, rows then columns, as
    /// [`bilinear_taps`] places them: each tap's weight and its texel's values, for the taps of
    /// weight other than 0 whose texels came.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn tile_taps<'a>(
        &'a self,
        i: usize,
        tiled: &'a TiledLevel,
        s: f32,
        t: f32,
        wrap: [Wrap; 2],
        weight: f32,
    ) -> impl Iterator<Item = (f32, &'a [f32])> + 'a {
        let [w, h] = tiled.size();
        let (rows, columns, taps) = bilinear_places(w, h, s, t, wrap, weight);
        taps.into_iter().enumerate().filter_map(move |(k, tap)| {
            let (Some(y), Some(x)) = (rows[k / 2], columns[k % 2]) else { return None };
            if tap == 0.0 {
                return None;
            }
            Some((tap, self.tile_texel(i, tiled, x, y)?))
        })
    }

    /// Adds `weight` times the bilinear interpolation at (s, t) of level `i`, which comes in
    /// tiles, to `out`: the values [`accumulate_taps`] gives on the whole level, tile by tile.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn accumulate_tile_taps<const N: usize>(
        &self,
        i: usize,
        tiled: &TiledLevel,
        s: f32,
        t: f32,
        wrap: [Wrap; 2],
        first: usize,
        weight: f32,
        out: &mut [f32],
    ) {
        let Some(out) = out.first_chunk_mut::<N>() else { return };
        let mut sum = *out;
        // Most probes' four taps lie in one tile: that tile found once, the same sums as below.
        let [w, h] = tiled.size();
        if let ([Some(y0), Some(y1)], [Some(x0), Some(x1)], taps) = bilinear_places(w, h, s, t, wrap, weight) {
            let (index, [dx, dy]) = tiled.tile_of(x0, y0);
            let channels = self.channels();
            let corner = [x0 - dx, y0 - dy];
            let one_tile = |tile: &&TexImage| holds(tile, corner, [x1, y1]) && first + N <= channels;
            if let Some(tile) = tiled.get(index).filter(one_tile) {
                let (rows, columns) = ([y0, y1].map(|y| y - (y0 - dy)), [x0, x1].map(|x| x - (x0 - dx)));
                let tw = tile.width();
                for (k, tap) in taps.into_iter().enumerate() {
                    if tap == 0.0 {
                        continue;
                    }
                    let offset = (rows[k / 2] * tw + columns[k % 2]) * channels + first;
                    let Some(texel) = tile.data().get(offset..).and_then(|t| t.first_chunk::<N>()) else { continue };
                    for (o, v) in sum.iter_mut().zip(texel) {
                        *o = tap.mul_add(*v, *o);
                    }
                }
                *out = sum;
                return;
            }
        }
        for (tap, texel) in self.tile_taps(i, tiled, s, t, wrap, weight) {
            let Some(texel) = texel.get(first..).and_then(|t| t.first_chunk::<N>()) else { continue };
            for (o, v) in sum.iter_mut().zip(texel) {
                *o = tap.mul_add(*v, *o);
            }
        }
        *out = sum;
    }

    /// [`MipMap::accumulate_tile_taps`] for any number of channels, as [`accumulate_bilinear`].
    #[allow(clippy::too_many_arguments)]
    fn accumulate_tiles(
        &self,
        i: usize,
        tiled: &TiledLevel,
        s: f32,
        t: f32,
        wrap: [Wrap; 2],
        first: usize,
        weight: f32,
        out: &mut [f32],
    ) {
        let n = out.len().min(self.channels().saturating_sub(first));
        match n {
            0 => {}
            1 => self.accumulate_tile_taps::<1>(i, tiled, s, t, wrap, first, weight, out),
            3 => self.accumulate_tile_taps::<3>(i, tiled, s, t, wrap, first, weight, out),
            4 => self.accumulate_tile_taps::<4>(i, tiled, s, t, wrap, first, weight, out),
            _ => {
                for (tap, texel) in self.tile_taps(i, tiled, s, t, wrap, weight) {
                    let Some(texel) = texel.get(first..first + n) else { continue };
                    for (o, v) in out.iter_mut().zip(texel) {
                        *o = tap.mul_add(*v, *o);
                    }
                }
            }
        }
    }

    /// The values of texel (x, y) of level `i`, which comes in tiles: from its tile, fetched first
    /// when not held; from the whole level where that came instead; `None` when neither came.
    #[inline(always)]
    fn tile_texel<'a>(&'a self, i: usize, tiled: &'a TiledLevel, x: usize, y: usize) -> Option<&'a [f32]> {
        let (index, [tx, ty]) = tiled.tile_of(x, y);
        let channels = self.channels();
        match tiled.get(index).or_else(|| self.missing_tile(i, tiled, index)) {
            Some(tile) => tile.data().get((ty * tile.width() + tx) * channels..)?.get(..channels),
            None => {
                let level = self.levels[i].get()?;
                level.data().get((y * level.width() + x) * channels..)?.get(..channels)
            }
        }
    }

    /// Tile `index` of level `i`, not held yet: fetched, unless what was fetched of the map
    /// already makes the image worth more; `None` when the level is held whole now (the image
    /// came instead: the level is computed from it) or nothing came (the source has recorded
    /// why; the tile reads as zeros, the frame fails, and the tile is fetched again when next
    /// read).
    #[cold]
    #[inline(never)]
    fn missing_tile<'a>(&'a self, i: usize, tiled: &'a TiledLevel, index: usize) -> Option<&'a TexImage> {
        let remote = self.remote.as_ref()?;
        let _busy = remote.tile_locks[index % remote.tile_locks.len()].lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(tile) = tiled.get(index) {
            return Some(tile);
        }
        if !self.reads_tiles(i) {
            // The image came meanwhile.
            self.level_at(i);
            return None;
        }
        match remote.fetch.fetch_tile(i, index, tiled.tile_size(index)?, self.size)? {
            FetchedLevel::Level(tile) => {
                if tiled.set(index, tile, self.channels()) {
                    tiled.get(index)
                } else {
                    let message = format!("tile {index} of mip level {i} is not the size it was cut to");
                    remote.fetch.failed(message);
                    None
                }
            }
            FetchedLevel::Image(image) => {
                let _ = self.levels[0].set(image);
                self.level_at(i);
                None
            }
        }
    }

    pub fn width(&self) -> usize {
        self.size[0]
    }

    pub fn height(&self) -> usize {
        self.size[1]
    }

    pub fn channels(&self) -> usize {
        self.size[2]
    }

    /// No level has an infinite or NaN value.
    pub fn is_finite(&self) -> bool {
        self.finite
    }

    /// The file's wrap modes (s, t).
    pub fn wrap(&self) -> [Wrap; 2] {
        self.wrap
    }

    /// The wrap modes a lookup uses: its own where it gives them, else the file's.
    fn wrap_for(&self, opts: &LookupOptions) -> [Wrap; 2] {
        [opts.swrap.unwrap_or(self.wrap[0]), opts.twrap.unwrap_or(self.wrap[1])]
    }

    /// Records the projection the file's header carried (`worldToCamera`, `worldToNDC`).
    pub fn with_projection(mut self, projection: Option<[[f32; 16]; 2]>) -> MipMap {
        self.projection = projection;
        self
    }

    /// The `worldToCamera` and `worldToNDC` matrices of the file, if it had them.
    pub fn projection(&self) -> Option<[[f32; 16]; 2]> {
        self.projection
    }

    /// Bilinear interpolation on one level: `out[c]` gets channel `first_channel + c`.
    /// Channels the texture lacks are 0. A `level` past the last means the last.
    pub fn bilinear(&self, level: usize, s: f32, t: f32, wrap: [Wrap; 2], first_channel: usize, out: &mut [f32]) {
        out.fill(0.0);
        let level = self.level(level);
        accumulate_bilinear(level, s, t, wrap, first_channel, 1.0, out);
    }

    /// The filtered value over a footprint (see the module doc): `out[c]` gets channel
    /// `first_channel + c`, channels the texture lacks get `opts.fill`.
    pub fn filter(
        &self,
        s: f32,
        t: f32,
        footprint: Footprint,
        first_channel: usize,
        out: &mut [f32],
        opts: &LookupOptions,
    ) {
        let wrap = self.wrap_for(opts);
        self.filter_wrapped(s, t, footprint, first_channel, out, opts, wrap);
    }

    /// [`MipMap::filter`] with the wrap modes decided by the caller.
    #[allow(clippy::too_many_arguments)] // the lookup's full description; a struct would only rename it
    pub(crate) fn filter_wrapped(
        &self,
        s: f32,
        t: f32,
        footprint: Footprint,
        first_channel: usize,
        out: &mut [f32],
        opts: &LookupOptions,
        wrap: [Wrap; 2],
    ) {
        self.filter_probing(s, t, footprint, first_channel, out, opts, wrap, Probing::Fastest);
    }

    /// [`MipMap::filter_wrapped`], its probes summed the way `probing` says.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn filter_probing(
        &self,
        s: f32,
        t: f32,
        footprint: Footprint,
        first_channel: usize,
        out: &mut [f32],
        opts: &LookupOptions,
        wrap: [Wrap; 2],
        probing: Probing,
    ) {
        let lanes = LookupLanes::splat(s, t, footprint, [opts.sblur, opts.tblur]);
        let plan = self.probe_plans(&lanes, opts).lane(0);
        self.filter_planned(s, t, plan, first_channel, out, opts.fill, wrap, probing);
    }

    /// Four filtered lookups at once, a shader chunk's lanes: for each active lane `l`,
    /// `out[4 * c + l]` gets channel `first[l] + c` (channels the texture lacks get `opts.fill`);
    /// inactive lanes' values stay as they are. Each lane has its own blur (`opts.sblur` and
    /// `opts.tblur` are not read). The same values as [`MipMap::filter`] lane by lane.
    ///
    /// Working out where a lookup's probes go is a chain of square roots, a division and a
    /// logarithm that a processor cannot overlap with the next lookup's; four lanes take that
    /// chain once.
    pub fn filter_lanes(
        &self,
        lanes: &LookupLanes,
        active: [bool; 4],
        first: [usize; 4],
        out: &mut [f32],
        opts: &LookupOptions,
    ) {
        let wrap = self.wrap_for(opts);
        let plans = self.probe_plans(lanes, opts);
        let values = (out.len() / 4).min(MAX_LANE_VALUES);
        let (s, t) = (lanes.s.to_array(), lanes.t.to_array());
        let mut left = active;
        if wrap == [Wrap::Periodic; 2] && self.periodic_lanes && self.finite && values <= 4 {
            // Compiled apart: what reading tiles adds would slow the common way down.
            left = if self.tiled.is_empty() {
                self.filter_lanes_periodic::<false>([s, t], active, first, &plans, out, values, opts.fill)
            } else {
                self.filter_lanes_periodic::<true>([s, t], active, first, &plans, out, values, opts.fill)
            };
        }
        if left.contains(&true) {
            self.filter_lanes_one_by_one([s, t], left, first, &plans, out, values, opts.fill, wrap);
        }
    }

    /// [`MipMap::filter_lanes`] of the lanes `left`, one after the other. Out of line: the common
    /// way needs none of its buffer.
    #[allow(clippy::too_many_arguments)] // filter_lanes' own arguments, worked out once there
    #[inline(never)]
    fn filter_lanes_one_by_one(
        &self,
        [s, t]: [[f32; 4]; 2],
        left: [bool; 4],
        first: [usize; 4],
        plans: &ProbePlans,
        out: &mut [f32],
        values: usize,
        fill: f32,
        wrap: [Wrap; 2],
    ) {
        let mut lane_out = [0.0f32; MAX_LANE_VALUES];
        for lane in (0..4).filter(|&l| left[l]) {
            let lane_out = &mut lane_out[..values];
            self.filter_planned(
                s[lane],
                t[lane],
                plans.lane(lane),
                first[lane],
                lane_out,
                fill,
                wrap,
                Probing::Fastest,
            );
            for (c, v) in lane_out.iter().enumerate() {
                out[4 * c + lane] = *v;
            }
        }
    }

    /// [`MipMap::filter_lanes`] for textures whose levels wrap periodically (most textures; all of
    /// BART's) and whose texels are all finite, at most four values a lane: the same values, bit
    /// for bit, as [`PeriodicProbes`] (power-of-two levels) and the general way (others) sum them
    /// lane by lane, written straight into `out`. Returns the active lanes it left to the caller: those with a probe
    /// beyond 2^22 texels, where its integer conversions ([`floor_small`]) do not hold.
    ///
    /// The four lanes step through their probes together, in vector arithmetic: probe `k` of every
    /// lane, on its first level and then its second. Lookup by lookup, each lane's setup (its
    /// levels, its probes' places, their floors and tap weights) would stand in a chain of its own,
    /// and take more instructions than its taps.
    ///
    /// Where the lanes differ, the work is padded: a lane past its last probe, or with one level,
    /// adds taps of zero weight. That changes no bit: a sum starts at +0 and never becomes -0, and
    /// zero times a finite texel is a zero, so adding it leaves the sum as it was (which is why
    /// the texels must be finite: zero times infinity is NaN). A lane past its last probe steps
    /// on its last probe again, so that its padding reads where its probes read.
    ///
    /// A remote map's level that comes in tiles is read this way through the one tile a lane's
    /// probes read on it, where they read one that is here ([`MipMap::tile_views`]); the lanes
    /// that read such a level otherwise are left to the caller too.
    #[allow(clippy::too_many_arguments)] // filter_lanes' own arguments, worked out once there
    #[inline(always)]
    fn filter_lanes_periodic<const TILED: bool>(
        &self,
        [s, t]: [[f32; 4]; 2],
        active: [bool; 4],
        first: [usize; 4],
        plans: &ProbePlans,
        out: &mut [f32],
        values: usize,
        fill: f32,
    ) -> [bool; 4] {
        let channels = self.channels();
        // Each lane's values; lanes summed: active ones with values, at finite coordinates (a NaN or
        // infinite coordinate has no texel: the fill value rather than NaN). In vector arithmetic:
        // lane by lane these tests were a tenth of a lookup's setup.
        let counts: [usize; 4] = std::array::from_fn(|l| values.min(channels.saturating_sub(first[l])));
        let finite = Vec4::from_array(s).is_finite_mask() & Vec4::from_array(t).is_finite_mask();
        let asking = BVec4A::from_array(active);
        let summing = asking & finite & BVec4A::from_array(counts.map(|n| n > 0));
        let unsummed = (asking & !summing).bitmask();
        for l in (0..4).filter(|&l| unsummed >> l & 1 != 0) {
            for c in 0..values {
                out[4 * c + l] = fill;
            }
        }
        if !summing.any() {
            return [false; 4];
        }
        let mut summed: [bool; 4] = std::array::from_fn(|l| summing.test(l));
        let mut lanes = LaneProbes::of(self, plans, summed);
        // Lanes that read a level in tiles but not through one tile that is here.
        let mut untiled = [false; 4];
        let views = if !TILED {
            None
        } else {
            let (views, through) = self.tile_views([s, t], &lanes, summed);
            untiled = std::array::from_fn(|l| summed[l] && !through[l]);
            if untiled.contains(&true) {
                summed = through;
                if !summed.contains(&true) {
                    return untiled;
                }
                for l in (0..4).filter(|&l| untiled[l]) {
                    lanes.leave_out(l, self.levels.len() - 1);
                }
            }
            Some(views)
        };
        let plan = LanePlan::of(self, &lanes, summed, first, views.as_ref());
        let mut sums = [Vec4::ZERO; 4];
        let mut far = BVec4A::FALSE;
        let (s, t) = (Vec4::from_array(s), Vec4::from_array(t));
        let probes = plan.probes;
        let last = (probes - Vec4::ONE).max(Vec4::ZERO);
        let steps = probes.max_element() as usize;
        let levels = if plan.two { 2 } else { 1 };
        for k in 0..steps {
            let k = Vec4::splat(k as f32);
            let live = k.cmplt(probes);
            // The probe's centre, as `filter_planned` places it.
            let along = (if TILED { k.min(last) } else { k } + Vec4::splat(0.5)) * plan.weight - Vec4::splat(0.5);
            let (s, t) = (s + plan.axis[0] * along, t + plan.axis[1] * along);
            for level in &plan.levels[..levels] {
                match level.add_probe(s, t, live, &mut sums) {
                    Some(beyond) => far |= beyond,
                    // An offset past its level (which the masks rule out): every lane the long way.
                    None => return std::array::from_fn(|l| summed[l] || untiled[l]),
                }
            }
        }
        let far = far.bitmask();
        // A lane's values in a row each: channel `c` of every lane.
        let rows = Mat4::from_cols(sums[0], sums[1], sums[2], sums[3]).transpose();
        let written = BVec4A::from_array(std::array::from_fn(|l| summed[l] && far >> l & 1 == 0));
        for c in 0..values.min(4) {
            let Some(chunk) = out.get_mut(4 * c..4 * c + 4) else { break };
            let has = BVec4A::from_array(counts.map(|n| c < n));
            let value = Vec4::select(has, rows.col(c), Vec4::splat(fill));
            Vec4::select(written, value, Vec4::from_slice(chunk)).write_to_slice(chunk);
        }
        std::array::from_fn(|l| summed[l] && far >> l & 1 != 0 || untiled[l])
    }

    /// For each `summed` lane of `lanes` and each level it reads that comes in tiles
    /// ([`MipMap::reads_tiles`]), the tile its probes read there, where they read one tile that is
    /// here: the box of their taps, shifted by whole periods, lies in it. The
    /// second answer is the summed lanes that have such a tile for each such level (or read none);
    /// the others go tap by tap, which fetches what they read.
    ///
    /// The probes' texel coordinates are worked out here by the arithmetic that places them in
    /// [`MipMap::filter_lanes_periodic`], operation for operation (so to the bit), and they are
    /// monotonic in the probe's number (each operation is), so the first and the last probe
    /// bound the taps.
    #[inline(never)]
    fn tile_views(&self, [s, t]: [[f32; 4]; 2], lanes: &LaneProbes, summed: [bool; 4]) -> (LaneTiles<'_>, [bool; 4]) {
        let mut views: LaneTiles<'_> = [[None; 4]; 2];
        let mut through = summed;
        let (s, t) = (Vec4::from_array(s), Vec4::from_array(t));
        // Each lane's first and last probe, as `filter_lanes_periodic` places them.
        let last = (lanes.probes - Vec4::ONE).max(Vec4::ZERO);
        let along = [Vec4::ZERO, last].map(|k| (k + Vec4::splat(0.5)) * lanes.weight - Vec4::splat(0.5));
        let ends = along.map(|a| [s + lanes.axis[0] * a, t + lanes.axis[1] * a]);
        for (slot, (views, levels)) in views.iter_mut().zip(lanes.levels).enumerate() {
            let asked: [bool; 4] = std::array::from_fn(|l| summed[l] && (slot == 0 || lanes.two.test(l)));
            let Some(lane) = asked.iter().position(|&a| a) else { continue };
            // Mostly, the lanes read one level (and one tile of it, found once below).
            let one_level = (0..4).all(|l| !asked[l] || levels[l] == levels[lane]).then_some(levels[lane]);
            let reading: [bool; 4] = match one_level {
                Some(level) if !self.reads_tiles(level) => continue,
                Some(_) => asked,
                None => std::array::from_fn(|l| asked[l] && self.reads_tiles(levels[l])),
            };
            if !reading.contains(&true) {
                continue;
            }
            let shapes = levels.map(|l| &self.shapes[l.min(self.shapes.len() - 1)]);
            // Each lane's probes' texel coordinates along each axis, the lesser end then the
            // greater: its taps read from the floor of the one to one past the floor of the other.
            let ends = [0, 1].map(|axis| {
                let size = Vec4::from_array(shapes.map(|shape| shape.size[axis]));
                let [a, b] = ends.map(|e| e[axis] * size - Vec4::splat(0.5));
                (a.min(b), a.max(b))
            });
            let limit = 4_194_304.0;
            if let Some(one_level) = one_level {
                let lanes_read = BVec4A::from_array(reading);
                let spans = ends.map(|(lesser, greater)| {
                    let first = Vec4::select(lanes_read, lesser, Vec4::INFINITY).min_element();
                    let last = Vec4::select(lanes_read, greater, Vec4::NEG_INFINITY).max_element();
                    (first.abs() < limit && last.abs() < limit).then(|| (first.floor() as i32, last.floor() as i32 + 1))
                });
                if let Some(view) = self.tile_view(one_level, spans) {
                    for l in (0..4).filter(|&l| reading[l]) {
                        views[l] = Some(view);
                    }
                    #[cfg(test)]
                    LANES_THROUGH_TILES.with(|c| c.set(c.get() + reading.iter().filter(|&&r| r).count()));
                    continue;
                }
            }
            let near =
                ends.map(|(a, b)| (a.abs().cmplt(Vec4::splat(limit)) & b.abs().cmplt(Vec4::splat(limit))).bitmask());
            let spans = ends.map(|(a, b)| (floor_small(a).1.to_array(), (floor_small(b).1 + IVec4::ONE).to_array()));
            for l in (0..4).filter(|&l| reading[l]) {
                let span = |axis: usize| (near[axis] >> l & 1 != 0).then(|| (spans[axis].0[l], spans[axis].1[l]));
                match self.tile_view(levels[l], [span(0), span(1)]) {
                    Some(found) => {
                        #[cfg(test)]
                        LANES_THROUGH_TILES.with(|c| c.set(c.get() + 1));
                        views[l] = Some(found);
                    }
                    None => through[l] = false,
                }
            }
        }
        // A lane of one level reads it again as its second, weighted zero.
        for l in (0..4).filter(|&l| !lanes.two.test(l)) {
            views[1][l] = views[0][l];
        }
        (views, through)
    }

    /// The tile of level `level` (one that comes in tiles) that holds the texels `spans` (first
    /// and last, columns then rows, before they are wrapped periodically), where one does and is
    /// here.
    #[inline(always)]
    fn tile_view(&self, level: usize, [columns, rows]: [Option<(i32, i32)>; 2]) -> Option<TileView<'_>> {
        let tiled = self.tiled.get(level)?.as_ref()?;
        let [w, h] = tiled.size();
        let [x0, x1] = columns.and_then(|(first, last)| texel_span(first, last, w))?;
        let [y0, y1] = rows.and_then(|(first, last)| texel_span(first, last, h))?;
        let (index, [dx, dy]) = tiled.tile_of(x0, y0);
        let origin = [x0 - dx, y0 - dy];
        let tile = tiled.get(index).filter(|tile| holds(tile, origin, [x1, y1]))?;
        Some(TileView { tile, origin })
    }

    /// Where the probes of four lookups go (see the module doc).
    #[inline(always)]
    fn probe_plans(&self, lanes: &LookupLanes, opts: &LookupOptions) -> ProbePlans {
        let ellipses = Ellipses::of(lanes, opts, self.width() as f32, self.height() as f32);
        // Clamp the eccentricity: beyond MAX_ANISOTROPY probes, widen the filter instead.
        let major = ellipses.major;
        let minor = ellipses.minor.max(major / MAX_ANISOTROPY as f32);
        let positive = minor.cmpgt(Vec4::ZERO);
        let probes = Vec4::select(
            positive,
            (major / minor - Vec4::splat(ANISOTROPY_SLACK)).ceil().clamp(Vec4::ONE, Vec4::splat(MAX_ANISOTROPY as f32)),
            Vec4::ONE,
        );
        // Each probe filters its share of the major axis, and at least the minor one: where the
        // slack spared a probe, the others widen a little rather than alias.
        let width = minor.max(major / probes);
        let lod = Vec4::select(positive, log2(width), Vec4::splat(f32::NEG_INFINITY));
        ProbePlans { probes, lod, major, direction: ellipses.direction }
    }

    /// One lookup's probes, planned, summed into `out` (channel `first_channel + c` into
    /// `out[c]`, `fill` where the texture has no such channel).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn filter_planned(
        &self,
        s: f32,
        t: f32,
        plan: ProbePlan,
        first_channel: usize,
        out: &mut [f32],
        fill: f32,
        wrap: [Wrap; 2],
        probing: Probing,
    ) {
        // A NaN or infinite coordinate has no texel: answer the fill value rather than NaN.
        if !(s.is_finite() && t.is_finite()) {
            out.fill(fill);
            return;
        }
        out.fill(0.0);
        let (w, h) = (self.width() as f32, self.height() as f32);
        let ProbePlan { probes, lod, major, direction } = plan;
        let weight = 1.0 / probes as f32;
        // Probe centres split the major axis into equal parts (no division per probe: each
        // would be on the probe's path to its texels).
        let axis = [direction[0] * major / w, direction[1] * major / h];
        let probe = |k: usize| {
            let along = (k as f32 + 0.5) * weight - 0.5;
            (s + axis[0] * along, t + axis[1] * along)
        };
        // Every probe blends the same levels with the same weights: that is worked out once, and
        // the probe loop is unrolled for the common channel counts.
        let n = out.len().min(self.channels().saturating_sub(first_channel));
        let plan = self.trilinear(lod, weight, wrap);
        match n {
            1 => plan.accumulate_probes::<1>(probes, probe, wrap, first_channel, out, probing),
            3 => plan.accumulate_probes::<3>(probes, probe, wrap, first_channel, out, probing),
            4 => plan.accumulate_probes::<4>(probes, probe, wrap, first_channel, out, probing),
            _ => {
                for k in 0..probes {
                    let (ps, pt) = probe(k);
                    plan.accumulate(ps, pt, wrap, first_channel, out);
                }
            }
        }
        fill_missing(self.channels(), first_channel, fill, out);
    }

    /// The levels a trilinear probe at `lod` blends, and their weights (a probe's `weight` split
    /// between them), the same for every probe of a lookup.
    fn trilinear(&self, lod: f32, weight: f32, wrap: [Wrap; 2]) -> Trilinear<'_> {
        let ([a, b], weights, two) = self.blended_levels(lod, weight);
        if !self.tiled.is_empty() && (self.reads_tiles(a) || two && self.reads_tiles(b)) {
            let first = self.level_read(a);
            let levels = [first, if two { self.level_read(b) } else { first }];
            return Trilinear::Tiles { levels, weights, two };
        }
        if two {
            Trilinear::Two(LevelPair::new([self.level_at(a), self.level_at(b)], weights, wrap))
        } else {
            Trilinear::One(self.level_at(a), weights[0])
        }
    }

    /// The levels a probe at `lod` reads and their weights (its `weight` split between them), and
    /// whether it blends two; with one, the first level and weight.
    #[inline(always)]
    fn blended_levels(&self, lod: f32, weight: f32) -> ([usize; 2], [f32; 2], bool) {
        let top = self.levels.len() - 1;
        // NaN (a degenerate footprint) also means the finest level.
        if lod.is_nan() || lod <= 0.0 {
            return ([0, 0], [weight, 0.0], false);
        }
        let below = floor(lod) as usize;
        if below >= top {
            return ([top, top], [weight, 0.0], false);
        }
        let frac = lod - below as f32;
        ([below, below + 1], [weight * (1.0 - frac), weight * frac], true)
    }
}

/// How a lookup sums its probes. The ways give the same values, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Probing {
    /// [`PeriodicProbes`] where the wrap modes and sizes allow it.
    Fastest,
    /// Tap by tap, every wrap mode alike (for tests: the reference of the others).
    #[cfg_attr(not(test), allow(dead_code))]
    General,
}

/// Where a filtered lookup's probes read: one level, or two adjacent levels blended, with weights.
enum Trilinear<'a> {
    One(&'a TexImage, f32),
    Two(LevelPair<'a>),
    /// A remote map's levels of which one at least is read tile by tile: the first level, and the
    /// second where `two`, one after the other (the values [`Trilinear::Two`] gives).
    Tiles {
        levels: [LevelRead<'a>; 2],
        weights: [f32; 2],
        two: bool,
    },
}

/// How a probe reads a level of a remote map ([`MipMap::level_read`]): whole, or level `.1` of
/// map `.0` tile by tile.
#[derive(Clone, Copy)]
enum LevelRead<'a> {
    Whole(&'a TexImage),
    Tiles(&'a MipMap, usize, &'a TiledLevel),
}

impl Trilinear<'_> {
    /// Adds one probe at (s, t) to `out`, for any number of channels.
    fn accumulate(&self, s: f32, t: f32, wrap: [Wrap; 2], first: usize, out: &mut [f32]) {
        match self {
            Trilinear::One(img, weight) => accumulate_bilinear(img, s, t, wrap, first, *weight, out),
            Trilinear::Two(pair) => accumulate_bilinear_pair(pair.levels, s, t, wrap, first, pair.weights, out),
            Trilinear::Tiles { levels, weights, two } => {
                for (level, &weight) in levels.iter().zip(weights).take(1 + usize::from(*two)) {
                    match *level {
                        LevelRead::Whole(img) => accumulate_bilinear(img, s, t, wrap, first, weight, out),
                        LevelRead::Tiles(map, i, tiled) => {
                            map.accumulate_tiles(i, tiled, s, t, wrap, first, weight, out)
                        }
                    }
                }
            }
        }
    }

    /// Adds the `probes` probes at `probe(k)` to `out`, for `N` channels from `first`, in order:
    /// the same values as [`Trilinear::accumulate`] for each probe, unrolled.
    #[inline(always)]
    fn accumulate_probes<const N: usize>(
        &self,
        probes: usize,
        probe: impl Fn(usize) -> (f32, f32),
        wrap: [Wrap; 2],
        first: usize,
        out: &mut [f32],
        probing: Probing,
    ) {
        let fast = if probing == Probing::Fastest { PeriodicProbes::of(self, wrap) } else { None };
        if let (Some(fast), Some(out)) = (fast, out.first_chunk_mut::<N>()) {
            let mut sum = Vec4::ZERO;
            for (lane, o) in out.iter().enumerate() {
                sum[lane] = *o;
            }
            let mut one_probe = |(s, t): (f32, f32), sum: Vec4| match fast.accumulate::<N>(s, t, first, sum) {
                Some(sum) => sum,
                // Coordinates too far out for the fast way: the general one, from where the sums
                // are.
                None => {
                    out.copy_from_slice(&sum.to_array()[..N]);
                    self.accumulate(s, t, wrap, first, out);
                    Vec4::from_array(std::array::from_fn(|lane| out.get(lane).copied().unwrap_or(0.0)))
                }
            };
            if probes == 1 {
                sum = one_probe(probe(0), sum);
            } else {
                // Four probes at a time (the last group padded with its last probe, not summed).
                for group in (0..probes).step_by(4) {
                    let count = (probes - group).min(4);
                    let at: [(f32, f32); 4] = std::array::from_fn(|j| probe(group + j.min(count - 1)));
                    let (s, t) = (Vec4::from_array(at.map(|p| p.0)), Vec4::from_array(at.map(|p| p.1)));
                    sum = match fast.accumulate_four::<N>(s, t, count, first, sum) {
                        Some(sum) => sum,
                        None => at[..count].iter().fold(sum, |sum, &p| one_probe(p, sum)),
                    };
                }
            }
            out.copy_from_slice(&sum.to_array()[..N]);
            return;
        }
        match self {
            Trilinear::One(img, weight) => {
                for k in 0..probes {
                    let (s, t) = probe(k);
                    accumulate_taps::<N>(img, s, t, wrap, first, *weight, out);
                }
            }
            Trilinear::Two(pair) => {
                for k in 0..probes {
                    let (s, t) = probe(k);
                    accumulate_pair_taps::<N>(pair, s, t, wrap, first, out);
                }
            }
            Trilinear::Tiles { levels, weights, two } => {
                let levels = &levels[..1 + usize::from(*two)];
                for k in 0..probes {
                    let (s, t) = probe(k);
                    for (level, &weight) in levels.iter().zip(weights) {
                        match *level {
                            LevelRead::Whole(img) => accumulate_taps::<N>(img, s, t, wrap, first, weight, out),
                            LevelRead::Tiles(map, i, tiled) => {
                                map.accumulate_tile_taps::<N>(i, tiled, s, t, wrap, first, weight, out)
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Four lookups' probe plans as lanes, for [`MipMap::filter_lanes_periodic`]: each lane's number
/// of probes (0 for a lane it does not sum), probe weight and axis, and its levels.
struct LanePlan<'a> {
    probes: Vec4,
    weight: Vec4,
    /// The major axis in texture coordinates, s then t.
    axis: [Vec4; 2],
    /// Each lane's first level, then its second (the first again, weighted zero, where a lane
    /// reads one).
    levels: [LevelLanes<'a>; 2],
    /// Whether any lane reads two levels.
    two: bool,
}

impl<'a> LanePlan<'a> {
    /// The plan of `lanes`, their levels read whole or, where `views` has one, through a tile.
    #[inline(always)]
    fn of(
        map: &'a MipMap,
        lanes: &LaneProbes,
        summed: [bool; 4],
        first: [usize; 4],
        views: Option<&LaneTiles<'a>>,
    ) -> LanePlan<'a> {
        let first = std::array::from_fn(|l| if summed[l] { first[l] } else { 0 });
        let view = |slot: usize| views.map_or([None; 4], |v| v[slot]);
        LanePlan {
            probes: lanes.probes,
            weight: lanes.weight,
            axis: lanes.axis,
            levels: [
                LevelLanes::of(map, lanes.levels[0], lanes.weights[0], first, view(0)),
                LevelLanes::of(map, lanes.levels[1], lanes.weights[1], first, view(1)),
            ],
            two: lanes.two.any(),
        }
    }
}

/// Where four lookups' probes go, lane by lane: each lane's number of probes (0 for a lane not
/// summed), probe weight and axis, its two levels (the first again where it reads one) and their
/// weights.
struct LaneProbes {
    probes: Vec4,
    weight: Vec4,
    /// The major axis in texture coordinates, s then t.
    axis: [Vec4; 2],
    levels: [[usize; 4]; 2],
    weights: [Vec4; 2],
    /// The lanes that read two levels.
    two: BVec4A,
}

impl LaneProbes {
    #[inline(always)]
    fn of(map: &MipMap, plans: &ProbePlans, summed: [bool; 4]) -> LaneProbes {
        let (w, h) = (map.width() as f32, map.height() as f32);
        let summing = BVec4A::from_array(summed);
        let probes = Vec4::select(summing, plans.probes.min(Vec4::splat(MAX_ANISOTROPY as f32)), Vec4::ZERO);
        let weight = Vec4::ONE / plans.probes;
        let axis =
            [plans.direction[0] * plans.major / Vec4::splat(w), plans.direction[1] * plans.major / Vec4::splat(h)];
        // `blended_levels`, lane by lane: the finest level where the level of detail is not
        // positive (or NaN), the coarsest at or past it, else the two around it.
        let top = Vec4::splat((map.levels.len() - 1) as f32);
        let lod = plans.lod;
        let positive = lod.cmpgt(Vec4::ZERO);
        // A lane not summed reads the coarsest level (it takes no taps): a remote map holds that
        // one, and fetches nothing for it.
        let below = Vec4::select(summing, Vec4::select(positive, lod.min(top).floor(), Vec4::ZERO), top);
        let two = positive & below.cmplt(top) & summing;
        let frac = lod - below;
        let weights =
            [Vec4::select(two, weight * (Vec4::ONE - frac), weight), Vec4::select(two, weight * frac, Vec4::ZERO)];
        // Whole numbers from 0 to the top level: one truncation gives them.
        let first_level = floor_small(below).1.to_array().map(|b| b.max(0) as usize);
        let second_level = std::array::from_fn(|l| first_level[l] + usize::from(two.test(l)));
        LaneProbes { probes, weight, axis, levels: [first_level, second_level], weights, two }
    }

    /// Lane `l` as [`LaneProbes::of`] makes a lane not summed: no probes, on the coarsest level
    /// (`top`).
    fn leave_out(&mut self, l: usize, top: usize) {
        self.probes[l] = 0.0;
        self.levels = self.levels.map(|mut levels| {
            levels[l] = top;
            levels
        });
        self.two.set(l, false);
    }
}

#[cfg(test)]
thread_local! {
    /// How many lanes' levels [`MipMap::tile_views`] found a tile for on this thread: tests'
    /// evidence that lookups read tiles the four-lane way.
    pub(crate) static LANES_THROUGH_TILES: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// For each of a [`LanePlan`]'s two levels, the tile each lane reads it through (`None`: whole).
type LaneTiles<'a> = [[Option<TileView<'a>>; 4]; 2];

/// A tile of a level, and where it lies in the level (its top left texel).
#[derive(Clone, Copy)]
struct TileView<'a> {
    tile: &'a TexImage,
    origin: [usize; 2],
}

impl TileView<'_> {
    /// Values in a row of the tile.
    fn row(&self, channels: usize) -> u32 {
        (self.tile.width() * channels) as u32
    }

    /// What a texel's offset in the level, counted in rows of the tile, exceeds its offset in the
    /// tile by (modulo 2^32, as offsets are computed).
    fn bias(&self, channels: usize) -> u32 {
        let [x, y] = self.origin.map(|v| v as u32);
        y.wrapping_mul(self.row(channels)).wrapping_add(x.wrapping_mul(channels as u32))
    }
}

/// Whether a tile whose first texel is `corner` of its level holds texel `at` of the level (in
/// its apron, perhaps).
#[inline(always)]
fn holds(tile: &TexImage, corner: [usize; 2], at: [usize; 2]) -> bool {
    let inside = |k: usize, n: usize| at[k].checked_sub(corner[k]).is_some_and(|d| d < n);
    inside(0, tile.width()) && inside(1, tile.height())
}

/// The texels `first..=last` along an axis of `n` texels shifted by a whole period into `0..n`;
/// `None` where they do not fit there unwrapped.
#[inline(always)]
fn texel_span(first: i32, last: i32, n: usize) -> Option<[usize; 2]> {
    let (first, last) = (i64::from(first), i64::from(last));
    let n = i64::try_from(n).ok()?;
    // Most coordinates are in the first period: no division.
    let shift = if first >= 0 && last < n { 0 } else { first.div_euclid(n) * n };
    let span = [first - shift, last - shift];
    (span[1] < n).then(|| span.map(|v| v as usize))
}

/// A level for each of four lookups (their levels may differ), for their probes' taps.
struct LevelLanes<'a> {
    /// Each lane's level's values, padded ([`TexImage::padded_data`]).
    data: [&'a [f32]; 4],
    /// Each lane's level's number of values: the furthest offset a four-value load may start at.
    limit: UVec4,
    /// Widths, then heights, as floats.
    size: [Vec4; 2],
    /// Widths less one, then heights less one: a tap's texel index is its coordinate's low bits
    /// where every level is a power of two (`pow2`), else its Euclidean remainder by the size.
    mask: [IVec4; 2],
    pow2: bool,
    /// Values in a row of each lane's level.
    row: UVec4,
    /// Values in a texel (every level's, the map's channels).
    texel: UVec4,
    /// Each lane's first channel.
    first: UVec4,
    /// The weight of each lane's probes on this level.
    weight: Vec4,
}

impl<'a> LevelLanes<'a> {
    #[inline(always)]
    fn of(
        map: &'a MipMap,
        levels: [usize; 4],
        weight: Vec4,
        first: [usize; 4],
        views: [Option<TileView<'a>>; 4],
    ) -> LevelLanes<'a> {
        let channels = map.channels();
        // A lane read through a tile: its rows are the tile's, and its offsets, counted so,
        // less where the tile starts are the tile's own.
        let first: [u32; 4] =
            std::array::from_fn(|l| (first[l] as u32).wrapping_sub(views[l].map_or(0, |v| v.bias(channels))));
        let data: [&[f32]; 4] = std::array::from_fn(|l| match views[l] {
            Some(view) => view.tile.padded_data(),
            None => map.level_at(levels[l]).padded_data(),
        });
        let shapes = levels.map(|l| &map.shapes[l.min(map.shapes.len() - 1)]);
        let row: [u32; 4] = std::array::from_fn(|l| views[l].map_or(shapes[l].row, |v| v.row(channels)));
        // `periodic_lanes` keeps every count and offset of these under 2^32.
        let limit = data.map(|d| (d.len() - TEXEL_PADDING) as u32);
        LevelLanes {
            data,
            limit: UVec4::from_array(limit),
            size: [0, 1].map(|k| Vec4::from_array(shapes.map(|s| s.size[k]))),
            mask: [0, 1].map(|k| IVec4::from_array(shapes.map(|s| s.mask[k]))),
            pow2: map.power_of_two_levels,
            row: UVec4::from_array(row),
            texel: UVec4::splat(channels as u32),
            first: UVec4::from_array(first),
            weight,
        }
    }

    /// The periodic texel indices along `axis` (0 columns, 1 rows) of the taps at `corner` and
    /// `corner + 1` (corners under 2^22 in magnitude): those of [`wrap_pair`], lane by lane.
    #[inline(always)]
    fn wrap(&self, corner: IVec4, axis: usize) -> [UVec4; 2] {
        if self.pow2 {
            let mask = self.mask[axis];
            return [(corner & mask).as_uvec4(), ((corner + IVec4::ONE) & mask).as_uvec4()];
        }
        // `corner.rem_euclid(n)`, by the floor of a float quotient, which is the true one here:
        // corner and size are exact as floats, the quotient of an integer corner `c` by `n` is
        // an integer or at least `1 / n` from one, and rounding moves it by at most half a
        // float's spacing, under `2^-2 / n` for `|c| < 2^22`, so it never reaches an integer it
        // is not. Wrapping arithmetic: a lane beyond 2^22 texels computes garbage here, which the
        // caller does not use.
        let n = self.mask[axis] + IVec4::ONE;
        let quotient = (corner.as_vec4() / n.as_vec4()).floor().as_ivec4();
        let first = corner.wrapping_sub(quotient.wrapping_mul(n));
        let next = first.wrapping_add(IVec4::ONE);
        let second = IVec4::select(next.cmpeq(n), IVec4::ZERO, next);
        [first.as_uvec4(), second.as_uvec4()]
    }

    /// Adds each `live` lane's probe at (s, t) on this level to its sum (and zeros to the other
    /// lanes' sums): the taps and weights of [`PeriodicProbes::accumulate`], lane by lane.
    /// Returns the live lanes whose probe is beyond 2^22 texels (their sums are not to be used),
    /// or `None` if an offset would pass its level's end, which the masks rule out.
    #[inline(always)]
    fn add_probe(&self, s: Vec4, t: Vec4, live: BVec4A, sums: &mut [Vec4; 4]) -> Option<BVec4A> {
        let (x, y) = (s * self.size[0] - Vec4::splat(0.5), t * self.size[1] - Vec4::splat(0.5));
        let limit = Vec4::splat(4_194_304.0);
        let far = live & !(x.abs().cmplt(limit) & y.abs().cmplt(limit));
        let ((x_floor, column), (y_floor, row)) = (floor_small(x), floor_small(y));
        let (fx, fy) = (x - x_floor, y - y_floor);
        let (gx, gy) = (Vec4::ONE - fx, Vec4::ONE - fy);
        let ([x0, x1], [y0, y1]) = (self.wrap(column, 0), self.wrap(row, 1));
        let weight = Vec4::select(live, self.weight, Vec4::ZERO);
        // Row-major, as everywhere.
        let taps = [weight * gx * gy, weight * fx * gy, weight * gx * fy, weight * fx * fy].map(|v| v.to_array());
        let rows = [y0, y1].map(|y| y.wrapping_mul(self.row));
        let columns = [x0, x1].map(|x| x.wrapping_mul(self.texel).wrapping_add(self.first));
        let offsets = [
            rows[0].wrapping_add(columns[0]),
            rows[0].wrapping_add(columns[1]),
            rows[1].wrapping_add(columns[0]),
            rows[1].wrapping_add(columns[1]),
        ];
        let furthest = offsets[0].max(offsets[1]).max(offsets[2]).max(offsets[3]);
        if !furthest.cmple(self.limit).all() {
            return None;
        }
        let offsets = offsets.map(|v| v.to_array());
        for (l, sum) in sums.iter_mut().enumerate() {
            let data = self.data[l];
            for (tap, offset) in taps.iter().zip(&offsets) {
                *sum = Vec4::splat(tap[l]).mul_add(four_values(data, offset[l] as usize), *sum);
            }
        }
        Some(far)
    }
}

/// The four values of `data` from `offset`, which the caller has checked: `offset + 4` is at most
/// `data.len()`.
#[inline(always)]
fn four_values(data: &[f32], offset: usize) -> Vec4 {
    debug_assert!(offset + 4 <= data.len());
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: the caller checked that the 16 bytes read are inside `data`; `_mm_loadu_ps`
        // needs no alignment, and SSE2 is part of x86-64.
        Vec4::from(unsafe { std::arch::x86_64::_mm_loadu_ps(data.as_ptr().add(offset)) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::from_slice(&data[offset..offset + 4])
    }
}

/// The probes of a lookup whose levels wrap periodically in both axes and are powers of two in
/// size: the same sums, in the same order, as the general way ([`accumulate_taps`] and
/// [`accumulate_pair_taps`]), with less work per tap. Most of a filtered lookup's time is its
/// probes, and most textures (all of BART's) are such.
struct PeriodicProbes<'a> {
    /// The levels blended; one level is given twice, with `two` false.
    levels: [&'a TexImage; 2],
    two: bool,
    weights: [f32; 2],
    /// The levels' widths and heights as floats (the first level's, then the second's).
    size: Vec4,
    /// Each of those sizes less one: a tap's texel index is its coordinate's low bits.
    masks: IVec4,
}

impl<'a> PeriodicProbes<'a> {
    #[inline(always)]
    fn of(plan: &Trilinear<'a>, wrap: [Wrap; 2]) -> Option<PeriodicProbes<'a>> {
        match *plan {
            Trilinear::One(img, weight) => {
                let masks = periodic_masks([img.width(), img.height()], wrap)?;
                let (w, h) = (img.width() as f32, img.height() as f32);
                Some(PeriodicProbes {
                    levels: [img; 2],
                    two: false,
                    weights: [weight; 2],
                    size: Vec4::new(w, h, w, h),
                    masks: IVec4::new(masks[0], masks[1], masks[0], masks[1]),
                })
            }
            Trilinear::Two(ref pair) => Some(PeriodicProbes {
                levels: pair.levels,
                two: true,
                weights: pair.weights,
                size: pair.size,
                masks: pair.masks?,
            }),
            Trilinear::Tiles { .. } => None,
        }
    }

    /// `sum` (lanes up to `N`) plus the probe at (s, t), or `None` for coordinates of more than
    /// 2^22 texels, where the exact integer conversion below does not hold.
    #[inline(always)]
    fn accumulate<const N: usize>(&self, s: f32, t: f32, first: usize, sum: Vec4) -> Option<Vec4> {
        let p = Vec4::new(s, t, s, t) * self.size - Vec4::splat(0.5);
        // NaN fails this too.
        if !p.abs().cmplt(Vec4::splat(4_194_304.0)).all() {
            return None;
        }
        let floor = p.floor();
        let f = p - floor;
        let g = Vec4::ONE - f;
        let corner = small_integers(floor);
        let lo = (corner & self.masks).to_array();
        let hi = ((corner + IVec4::ONE) & self.masks).to_array();
        // `weight * wx[column] * wy[row]` for the taps in row-major order, as everywhere.
        let taps = |weight: f32, gx: f32, fx: f32, gy: f32, fy: f32| {
            Vec4::splat(weight) * Vec4::new(gx, fx, gx, fx) * Vec4::new(gy, gy, fy, fy)
        };
        let first_level = taps(self.weights[0], g.x, f.x, g.y, f.y);
        let mut sum = level_taps::<N>(self.levels[0], [lo[0], hi[0], lo[1], hi[1]], first_level, first, sum);
        if self.two {
            let second_level = taps(self.weights[1], g.z, f.z, g.w, f.w);
            sum = level_taps::<N>(self.levels[1], [lo[2], hi[2], lo[3], hi[3]], second_level, first, sum);
        }
        Some(sum)
    }

    /// `sum` plus the first `count` (1 to 4) of the probes at (s, t), lane by lane: the same
    /// values as [`PeriodicProbes::accumulate`] probe after probe, with each level's coordinates,
    /// floors, wrapped taps and tap weights worked out for the four probes together. `None`, with
    /// nothing added, where a probe is beyond the fast way's limit.
    #[inline(always)]
    fn accumulate_four<const N: usize>(&self, s: Vec4, t: Vec4, count: usize, first: usize, sum: Vec4) -> Option<Vec4> {
        let [w0, h0, w1, h1] = self.size.to_array();
        let [mw0, mh0, mw1, mh1] = self.masks.to_array();
        let first_level = FourProbes::of(s, t, [w0, h0], [mw0, mh0], self.weights[0]);
        let second_level = self.two.then(|| FourProbes::of(s, t, [w1, h1], [mw1, mh1], self.weights[1]));
        if first_level.far || second_level.as_ref().is_some_and(|l| l.far) {
            return None;
        }
        let mut sum = sum;
        for k in 0..count.min(4) {
            sum = level_taps::<N>(self.levels[0], first_level.corners[k], first_level.taps[k], first, sum);
            if let Some(level) = &second_level {
                sum = level_taps::<N>(self.levels[1], level.corners[k], level.taps[k], first, sum);
            }
        }
        Some(sum)
    }
}

/// Four probes' taps on one level (`size` its width and height, `masks` each less one): per probe
/// the wrapped columns and rows `[x0, x1, y0, y1]` and the four tap weights in row-major order,
/// by the arithmetic of [`PeriodicProbes::accumulate`] lane by lane. `far` where a probe is
/// beyond 2^22 texels (or NaN), and then the rest is not to be used.
struct FourProbes {
    corners: [[i32; 4]; 4],
    taps: [Vec4; 4],
    far: bool,
}

impl FourProbes {
    #[inline(always)]
    fn of(s: Vec4, t: Vec4, size: [f32; 2], masks: [i32; 2], weight: f32) -> FourProbes {
        let (x, y) = (s * size[0] - Vec4::splat(0.5), t * size[1] - Vec4::splat(0.5));
        let limit = Vec4::splat(4_194_304.0);
        let far = !(x.abs().cmplt(limit) & y.abs().cmplt(limit)).all();
        let ((x_floor, column), (y_floor, row)) = (floor_small(x), floor_small(y));
        let (fx, fy) = (x - x_floor, y - y_floor);
        let (gx, gy) = (Vec4::ONE - fx, Vec4::ONE - fy);
        let wrap = |v: IVec4, mask: i32| (v & IVec4::splat(mask)).to_array();
        let (x0, x1) = (wrap(column, masks[0]), wrap(column + IVec4::ONE, masks[0]));
        let (y0, y1) = (wrap(row, masks[1]), wrap(row + IVec4::ONE, masks[1]));
        let weight = Vec4::splat(weight);
        // The taps of all four probes, a tap a column; transposed, a probe a column.
        let taps = Mat4::from_cols(weight * gx * gy, weight * fx * gy, weight * gx * fy, weight * fx * fy).transpose();
        FourProbes {
            corners: std::array::from_fn(|k| [x0[k], x1[k], y0[k], y1[k]]),
            taps: std::array::from_fn(|k| taps.col(k)),
            far,
        }
    }
}

/// `v.floor()` and [`small_integers`] of it, for lanes under 2^22 in magnitude (others give
/// values not to be used): truncated by one conversion and stepped down where that rounded up,
/// the integers kept from the conversion. The same values (a floor of -0 is +0 here, which no
/// texel coordinate `s * size - 0.5` is).
#[inline(always)]
fn floor_small(v: Vec4) -> (Vec4, IVec4) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_add_epi32, _mm_and_ps, _mm_castps_si128, _mm_cmplt_ps, _mm_cvtepi32_ps, _mm_cvttps_epi32, _mm_set1_ps,
            _mm_storeu_si128, _mm_sub_ps,
        };
        let x = v.into();
        let mut lanes = [0i32; 4];
        // SAFETY: SSE2 is part of x86-64, so these instructions exist; `lanes` is 16 writable
        // bytes, and the store needs no alignment.
        let floor = unsafe {
            let truncated = _mm_cvttps_epi32(x);
            let back = _mm_cvtepi32_ps(truncated);
            // All ones where the truncation rounded up (negative non-integers).
            let above = _mm_cmplt_ps(x, back);
            _mm_storeu_si128(lanes.as_mut_ptr().cast(), _mm_add_epi32(truncated, _mm_castps_si128(above)));
            _mm_sub_ps(back, _mm_and_ps(above, _mm_set1_ps(1.0)))
        };
        (Vec4::from(floor), IVec4::from_array(lanes))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let floor = v.floor();
        (floor, small_integers(floor))
    }
}

/// The integers of `v`, whose lanes are integers under 2^22 in magnitude: added to 1.5 * 2^23,
/// each is the low bits of the sum's mantissa, exactly (no rounding, no saturating conversion).
#[inline(always)]
fn small_integers(v: Vec4) -> IVec4 {
    const MAGIC: f32 = 12_582_912.0;
    let bits = (v + Vec4::splat(MAGIC)).to_array().map(|x| x.to_bits() as i32);
    IVec4::from_array(bits) - IVec4::splat(MAGIC.to_bits() as i32)
}

/// `sum` plus one level's four taps: columns `x0, x1` and rows `y0, y1` (wrapped already), their
/// weights `taps` in row-major order. Channel `c` of a texel is lane `c`; the lanes past `N` read
/// whatever follows the texel and are not used. Zero-weight taps are skipped, as everywhere, so an
/// infinite texel beside a texel centre does not make it NaN.
#[inline(always)]
fn level_taps<const N: usize>(img: &TexImage, [x0, x1, y0, y1]: [i32; 4], taps: Vec4, first: usize, sum: Vec4) -> Vec4 {
    let (w, ch, data) = (img.width(), img.channels(), img.data());
    // `(y * w + x) * ch + first`, with the rows' and the columns' parts worked out once.
    let (rows, columns) = ([y0, y1].map(|y| y as usize * (w * ch)), [x0, x1].map(|x| x as usize * ch + first));
    let texel = |x: usize, y: usize| {
        let offset = rows[y] + columns[x];
        match data.get(offset..offset + 4) {
            Some(four) => Vec4::from_slice(four),
            None => Vec4::from_array(std::array::from_fn(|c| {
                if c < N {
                    data.get(offset + c).copied().unwrap_or(0.0)
                } else {
                    0.0
                }
            })),
        }
    };
    let texels = [(0, 0), (1, 0), (0, 1), (1, 1)];
    let weights = taps.to_array();
    let mut sum = sum;
    if taps.cmpeq(Vec4::ZERO).any() {
        for ((x, y), tap) in texels.into_iter().zip(weights) {
            if tap != 0.0 {
                sum = Vec4::splat(tap).mul_add(texel(x, y), sum);
            }
        }
    } else {
        for ((x, y), tap) in texels.into_iter().zip(weights) {
            sum = Vec4::splat(tap).mul_add(texel(x, y), sum);
        }
    }
    sum
}

/// A level's sizes as floats, each less one (its periodic mask where it is a power of two), and
/// its row length in values, for [`LevelLanes`].
#[derive(Clone, Debug)]
struct LevelShape {
    size: [f32; 2],
    mask: [i32; 2],
    row: u32,
}

impl LevelShape {
    fn of(w: usize, h: usize, ch: usize) -> LevelShape {
        LevelShape {
            size: [w as f32, h as f32],
            mask: [w, h].map(|n| n.min(i32::MAX as usize) as i32 - 1),
            row: (w * ch).min(u32::MAX as usize) as u32,
        }
    }
}

/// Two levels a trilinear probe blends, their weights, and their sizes as floats (level 0's
/// width and height, then level 1's).
struct LevelPair<'a> {
    levels: [&'a TexImage; 2],
    weights: [f32; 2],
    size: Vec4,
    /// When both axes wrap periodically and every size is a power of two (so are most textures,
    /// and all of BART's), each size less one, in the order of `size`: a tap's texel index is its
    /// coordinate's low bits.
    masks: Option<IVec4>,
}

impl<'a> LevelPair<'a> {
    fn new(levels: [&'a TexImage; 2], weights: [f32; 2], wrap: [Wrap; 2]) -> LevelPair<'a> {
        let [a, b] = levels;
        let sizes = [a.width(), a.height(), b.width(), b.height()];
        let size = Vec4::from_array(sizes.map(|n| n as f32));
        LevelPair { levels, weights, size, masks: periodic_masks(sizes, wrap).map(IVec4::from_array) }
    }
}

/// Each size less one, when both axes wrap periodically and every size (widths at even places,
/// heights at odd ones) is a power of two that an `i32` holds.
#[inline(always)]
fn periodic_masks<const K: usize>(sizes: [usize; K], wrap: [Wrap; 2]) -> Option<[i32; K]> {
    // Not `is_power_of_two`: without the `popcnt` instruction (x86-64's baseline) that counts bits
    // the long way, a few dozen instructions a size.
    let fits = |n: usize| n != 0 && n & (n - 1) == 0 && i32::try_from(n).is_ok();
    (wrap == [Wrap::Periodic; 2] && sizes.iter().all(|&n| fits(n))).then(|| sizes.map(|n| n as i32 - 1))
}

/// The most values a lane of [`MipMap::filter_lanes`] gets (the shading ABI's limit).
const MAX_LANE_VALUES: usize = 64;

/// Four lookups (a shader chunk's lanes): coordinates, their screen-space derivatives and blur,
/// a lane each.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookupLanes {
    pub s: Vec4,
    pub t: Vec4,
    pub dsdx: Vec4,
    pub dtdx: Vec4,
    pub dsdy: Vec4,
    pub dtdy: Vec4,
    /// Added filter widths in s and t, in texture coordinates.
    pub sblur: Vec4,
    pub tblur: Vec4,
}

impl LookupLanes {
    /// One lookup in every lane.
    pub fn splat(s: f32, t: f32, footprint: Footprint, [sblur, tblur]: [f32; 2]) -> LookupLanes {
        LookupLanes {
            s: Vec4::splat(s),
            t: Vec4::splat(t),
            dsdx: Vec4::splat(footprint.dsdx),
            dtdx: Vec4::splat(footprint.dtdx),
            dsdy: Vec4::splat(footprint.dsdy),
            dtdy: Vec4::splat(footprint.dtdy),
            sblur: Vec4::splat(sblur),
            tblur: Vec4::splat(tblur),
        }
    }
}

/// Where a lookup's probes go: how many, along which axis (its full length, in level-0 texels,
/// and unit direction in texel space, s then t), and the level of detail each probe reads.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ProbePlan {
    probes: usize,
    lod: f32,
    major: f32,
    direction: [f32; 2],
}

/// Four lookups' [`ProbePlan`]s, a lane each (the number of probes as a float).
#[derive(Clone, Copy, Debug, PartialEq)]
struct ProbePlans {
    probes: Vec4,
    lod: Vec4,
    major: Vec4,
    direction: [Vec4; 2],
}

impl ProbePlans {
    fn lane(&self, l: usize) -> ProbePlan {
        ProbePlan {
            probes: self.probes[l] as usize,
            lod: self.lod[l],
            major: self.major[l],
            direction: [self.direction[0][l], self.direction[1][l]],
        }
    }
}

/// Four footprints as ellipses in level-0 texels: axis lengths (full widths) and the unit
/// direction of the major axis (in texel space, s then t), a lane each.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ellipses {
    major: Vec4,
    minor: Vec4,
    direction: [Vec4; 2],
}

impl Ellipses {
    fn of(lanes: &LookupLanes, opts: &LookupOptions, w: f32, h: f32) -> Ellipses {
        // Anything wider than a few times the texture reads the top level anyway: axes are capped
        // there. Components are clamped to a billion texels, far past any cap, which keeps every
        // product below finite (infinities would make NaN of the direction); NaN is no footprint.
        let cap = Vec4::splat(4.0 * w.max(h));
        let tame = |v: Vec4| Vec4::select(v.is_nan_mask(), Vec4::ZERO, v.clamp(Vec4::splat(-1e9), Vec4::splat(1e9)));
        let (sw, tw) = (Vec4::splat(opts.swidth * w), Vec4::splat(opts.twidth * h));
        let (x0, x1) = (tame(lanes.dsdx * sw), tame(lanes.dtdx * tw));
        let (y0, y1) = (tame(lanes.dsdy * sw), tame(lanes.dtdy * tw));
        let (bs, bt) = (tame(lanes.sblur * w), tame(lanes.tblur * h));
        // The covariance x x^T + y y^T has eigenvalues |x|^2 and |y|^2 when x and y are
        // orthogonal; blur adds in quadrature, like convolving with a second filter.
        let (bs2, bt2) = (bs * bs, bt * bt);
        let (a0, c0) = (x0 * x0 + y0 * y0, x1 * x1 + y1 * y1);
        let (a, b, c) = (a0 + bs2, x0 * x1 + y0 * y1, c0 + bt2);
        let half_difference = 0.5 * (a - c);
        let l1 = 0.5 * (a + c) + (half_difference * half_difference + b * b).sqrt();
        // The smaller eigenvalue as the determinant over the larger: `mean - spread` would lose
        // the digits of a thin ellipse. The determinant is a sum of positive terms (Lagrange's
        // identity for the footprint's part), so it keeps them.
        let cross = x0 * y1 - x1 * y0;
        let determinant = cross * cross + a0 * bt2 + c0 * bs2 + bs2 * bt2;
        let l2 = Vec4::select(l1.cmpgt(Vec4::ZERO), (determinant / l1).min(l1), Vec4::ZERO);
        // The major axis: an eigenvector of l1, from the covariance's row that keeps its digits
        // (l1 - c and l1 - a are the differences of nearly equal numbers on the other side).
        let s_major = a.cmpge(c);
        let dx = Vec4::select(s_major, l1 - c, b);
        let dy = Vec4::select(s_major, b, l1 - a);
        let length = (dx * dx + dy * dy).sqrt();
        // A circle (or no footprint) has no major axis: s, or t where it is the longer.
        let axis = length.cmpgt(Vec4::ZERO);
        let (on_s, on_t) = (Vec4::select(s_major, Vec4::ONE, Vec4::ZERO), Vec4::select(s_major, Vec4::ZERO, Vec4::ONE));
        let direction = [Vec4::select(axis, dx / length, on_s), Vec4::select(axis, dy / length, on_t)];
        let axis_length = |v: Vec4| v.sqrt().min(cap);
        Ellipses { major: axis_length(l1), minor: axis_length(l2), direction }
    }
}

/// `log2` of four positive floats, to within a few units in the last place; values below the
/// smallest normal float (no level is that fine) give -127.
#[inline(always)]
fn log2(v: Vec4) -> Vec4 {
    // v = m 2^e with m in [sqrt(1/2), sqrt(2)); log2(m) = 2 atanh(z) / ln 2 with
    // z = (m - 1) / (m + 1), |z| < 0.172, whose odd series to z^9 leaves under 1e-9.
    // The exponent and mantissa in integer vector arithmetic. (The sign bit shifts in as ones
    // for negative `v`, whose result the last line replaces.)
    let bits = IVec4::from_array(v.to_array().map(|x| x.to_bits() as i32));
    let mantissa = bits & IVec4::splat(0x007F_FFFF);
    // Mantissas past sqrt(2) (0x3504F3 in the fraction's bits) take the next exponent.
    let past = mantissa.cmpgt(IVec4::splat(0x0035_04F3));
    let exponent = (bits >> 23_i32) - IVec4::splat(127) + IVec4::select(past, IVec4::ONE, IVec4::ZERO);
    let scaled = mantissa | IVec4::select(past, IVec4::splat(0x3F00_0000), IVec4::splat(0x3F80_0000));
    let exponent = exponent.as_vec4();
    let m = Vec4::from_array(scaled.to_array().map(|b| f32::from_bits(b as u32)));
    let z = (m - Vec4::ONE) / (m + Vec4::ONE);
    let z2 = z * z;
    let series = z * (Vec4::ONE + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0)))));
    let log = exponent + series * (2.0 / std::f32::consts::LN_2);
    Vec4::select(v.cmpge(Vec4::splat(f32::MIN_POSITIVE)), log, Vec4::splat(-127.0))
}

/// Maps an integer texel index to one inside `0..n`, or `None` for black outside.
#[inline(always)]
fn wrap_index(i: i64, n: usize, mode: Wrap) -> Option<usize> {
    let n = n as i64;
    // Most taps are inside: skip the 64-bit division of the periodic case.
    if (0..n).contains(&i) {
        return Some(i as usize);
    }
    match mode {
        Wrap::Periodic => Some(i.rem_euclid(n) as usize),
        Wrap::Clamp => Some(i.clamp(0, n - 1) as usize),
        Wrap::Black => (0..n).contains(&i).then_some(i as usize),
    }
}

/// [`wrap_index`] of `i` and of `i + 1` (saturating), with at most one division: a tiled texture
/// (periodic, coordinates past 1) wraps every tap, and a 64-bit division per tap was most of the
/// time of its lookups.
#[inline(always)]
fn wrap_pair(i: i64, n: usize, mode: Wrap) -> [Option<usize>; 2] {
    let len = n as i64;
    if i >= 0 && i < len - 1 {
        return [Some(i as usize), Some(i as usize + 1)];
    }
    match mode {
        Wrap::Periodic if i < i64::MAX && len > 0 => {
            // Most textures are a power of two wide: a mask is their remainder (two's complement
            // makes it the Euclidean one for negative taps too).
            let first = if len & (len - 1) == 0 {
                i & (len - 1)
            } else {
                match (i32::try_from(i), i32::try_from(len)) {
                    (Ok(i), Ok(len)) => i64::from(i.rem_euclid(len)),
                    _ => i.rem_euclid(len),
                }
            };
            let second = if first + 1 == len { 0 } else { first + 1 };
            [Some(first as usize), Some(second as usize)]
        }
        _ => [wrap_index(i, n, mode), wrap_index(i.saturating_add(1), n, mode)],
    }
}

/// Adds `weight` times the bilinear interpolation at (s, t) to `out`. Texel centres sit at
/// `(i + 0.5) / w`, so the four texels around `s * w - 0.5` are blended.
///
/// Each channel gets `tap * value` added tap by tap (rows, then columns), skipping taps of zero
/// weight, so a texel centre reads its texel exactly even next to an infinite one.
fn accumulate_bilinear(img: &TexImage, s: f32, t: f32, wrap: [Wrap; 2], first: usize, weight: f32, out: &mut [f32]) {
    // The channels both the texture and `out` have; the rest stay as they are.
    let n = out.len().min(img.channels().saturating_sub(first));
    match n {
        0 => {}
        1 => accumulate_taps::<1>(img, s, t, wrap, first, weight, out),
        3 => accumulate_taps::<3>(img, s, t, wrap, first, weight, out),
        4 => accumulate_taps::<4>(img, s, t, wrap, first, weight, out),
        _ => accumulate_taps_dyn(img, s, t, wrap, first, weight, &mut out[..n]),
    }
}

/// The two bilinear lookups of a trilinear probe: `levels[0]` weighted by `weights[0]`, then
/// `levels[1]` by `weights[1]`, added to `out`. The same values, in the same order, as two
/// [`accumulate_bilinear`] calls; the two levels' texel coordinates, their floors and the tap
/// weights are worked out together, four lanes at a time (this runs for every probe of every
/// filtered lookup, and done level by level its scalar setup was most of a lookup's time).
fn accumulate_bilinear_pair(
    levels: [&TexImage; 2],
    s: f32,
    t: f32,
    wrap: [Wrap; 2],
    first: usize,
    weights: [f32; 2],
    out: &mut [f32],
) {
    // Levels of one pyramid have the same channels.
    let n = out.len().min(levels[0].channels().saturating_sub(first));
    let pair = LevelPair::new(levels, weights, wrap);
    match n {
        0 => {}
        1 => accumulate_pair_taps::<1>(&pair, s, t, wrap, first, out),
        3 => accumulate_pair_taps::<3>(&pair, s, t, wrap, first, out),
        4 => accumulate_pair_taps::<4>(&pair, s, t, wrap, first, out),
        _ => one_level_after_the_other(levels, s, t, wrap, first, weights, out),
    }
}

/// [`accumulate_bilinear_pair`] the plain way: what it must equal, and what it falls back on.
fn one_level_after_the_other(
    levels: [&TexImage; 2],
    s: f32,
    t: f32,
    wrap: [Wrap; 2],
    first: usize,
    weights: [f32; 2],
    out: &mut [f32],
) {
    for (img, weight) in levels.into_iter().zip(weights) {
        accumulate_bilinear(img, s, t, wrap, first, weight, out);
    }
}

/// [`accumulate_bilinear_pair`] for `N` channels.
#[inline(always)]
fn accumulate_pair_taps<const N: usize>(
    pair: &LevelPair,
    s: f32,
    t: f32,
    wrap: [Wrap; 2],
    first: usize,
    out: &mut [f32],
) {
    let LevelPair { levels, weights, size, .. } = *pair;
    // Texel coordinates of both levels, x then y: `bilinear_taps`' arithmetic, lane by lane.
    let p = Vec4::new(s, t, s, t) * size - Vec4::splat(0.5);
    // Beyond 2^23 a float is an integer already, and far beyond it no i32 holds its floor: such
    // coordinates (and NaN) take the level-by-level way, which handles them.
    if !p.abs().cmplt(Vec4::splat(8_388_608.0)).all() {
        return one_level_after_the_other(levels, s, t, wrap, first, weights, out);
    }
    let floor = p.floor();
    let f = p - floor;
    let g = Vec4::ONE - f;
    let Some(out) = out.first_chunk_mut::<N>() else { return };
    let corner = floor.as_ivec4().to_array();
    let mut sum = *out;
    for (k, (img, weight)) in levels.into_iter().zip(weights).enumerate() {
        let (w, ch, data) = (img.width(), img.channels(), img.data());
        let columns = wrap_pair(i64::from(corner[2 * k]), w, wrap[0]);
        let rows = wrap_pair(i64::from(corner[2 * k + 1]), img.height(), wrap[1]);
        let (fx, fy, gx, gy) = (f[2 * k], f[2 * k + 1], g[2 * k], g[2 * k + 1]);
        // `weight * wx[column] * wy[row]` for the taps in row-major order.
        let taps = (Vec4::splat(weight) * Vec4::new(gx, fx, gx, fx) * Vec4::new(gy, gy, fy, fy)).to_array();
        for (tap, weight) in taps.into_iter().enumerate() {
            let (Some(iy), Some(ix)) = (rows[tap / 2], columns[tap % 2]) else { continue };
            if weight == 0.0 {
                continue;
            }
            let Some(texel) = data.get((iy * w + ix) * ch + first..).and_then(|d| d.first_chunk::<N>()) else {
                continue;
            };
            for (o, v) in sum.iter_mut().zip(texel) {
                *o = weight.mul_add(*v, *o);
            }
        }
    }
    *out = sum;
}

/// The four taps around (s, t), rows then columns: each texel's offset in the image's data and
/// its weight. A tap outside a black border gets weight 0 (and offset 0), which callers skip.
#[inline(always)]
fn bilinear_taps(img: &TexImage, s: f32, t: f32, wrap: [Wrap; 2], weight: f32) -> ([usize; 4], [f32; 4]) {
    let (w, ch) = (img.width(), img.channels());
    let (rows, columns, weights) = bilinear_places(w, img.height(), s, t, wrap, weight);
    let mut offsets = [0; 4];
    let mut taps = [0.0; 4];
    for (k, (offset, tap)) in offsets.iter_mut().zip(&mut taps).enumerate() {
        if let (Some(iy), Some(ix)) = (rows[k / 2], columns[k % 2]) {
            *offset = (iy * w + ix) * ch;
            *tap = weights[k];
        }
    }
    (offsets, taps)
}

/// The rows and columns of the four taps around (s, t) on a level of `w x h` texels (`None`
/// outside a black border), and the taps' weights, rows then columns (0 for a tap outside).
#[inline(always)]
fn bilinear_places(
    w: usize,
    h: usize,
    s: f32,
    t: f32,
    wrap: [Wrap; 2],
    weight: f32,
) -> ([Option<usize>; 2], [Option<usize>; 2], [f32; 4]) {
    let x = s * w as f32 - 0.5;
    let y = t * h as f32 - 0.5;
    let (x0, y0) = (floor(x), floor(y));
    let (fx, fy) = (x - x0, y - y0);
    let (wx, wy) = ([1.0 - fx, fx], [1.0 - fy, fy]);
    // Saturating casts: NaN becomes 0, huge values the ends of i64; wrapping keeps them in range.
    let (x0, y0) = (x0 as i64, y0 as i64);
    let columns = wrap_pair(x0, w, wrap[0]);
    let rows = wrap_pair(y0, h, wrap[1]);
    let mut taps = [0.0; 4];
    for (k, tap) in taps.iter_mut().enumerate() {
        let (row, column) = (k / 2, k % 2);
        if rows[row].is_some() && columns[column].is_some() {
            *tap = weight * wx[column] * wy[row];
        }
    }
    (rows, columns, taps)
}

/// [`accumulate_bilinear`] for `N` channels, unrolled.
#[inline(always)]
fn accumulate_taps<const N: usize>(
    img: &TexImage,
    s: f32,
    t: f32,
    wrap: [Wrap; 2],
    first: usize,
    weight: f32,
    out: &mut [f32],
) {
    let Some(out) = out.first_chunk_mut::<N>() else { return };
    let data = img.data();
    let (offsets, taps) = bilinear_taps(img, s, t, wrap, weight);
    // Summed in registers: through `out` each tap would wait for the last one's store.
    let mut sum = *out;
    for (offset, tap) in offsets.into_iter().zip(taps) {
        if tap == 0.0 {
            continue;
        }
        let Some(texel) = data.get(offset + first..).and_then(|d| d.first_chunk::<N>()) else { continue };
        for (o, v) in sum.iter_mut().zip(texel) {
            *o = tap.mul_add(*v, *o);
        }
    }
    *out = sum;
}

/// [`accumulate_bilinear`] for any number of channels (`out` holds exactly those to read).
fn accumulate_taps_dyn(img: &TexImage, s: f32, t: f32, wrap: [Wrap; 2], first: usize, weight: f32, out: &mut [f32]) {
    let data = img.data();
    let (offsets, taps) = bilinear_taps(img, s, t, wrap, weight);
    for (offset, tap) in offsets.into_iter().zip(taps) {
        if tap == 0.0 {
            continue;
        }
        let Some(texel) = data.get(offset + first..offset + first + out.len()) else { continue };
        for (o, v) in out.iter_mut().zip(texel) {
            *o = tap.mul_add(*v, *o);
        }
    }
}

/// `x.floor()` without the libm call that x86-64's baseline (no SSE4.1 `roundss`) makes of it;
/// equal to it for every input (floats of magnitude 2^23 and more are already integers).
#[inline(always)]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let truncated = x as i32 as f32;
        // -0.5 truncates to -0: the floor is -1. Zero and -0 stay as they are.
        if truncated > x {
            truncated - 1.0
        } else if truncated == 0.0 {
            0.0f32.copysign(x)
        } else {
            truncated
        }
    } else {
        x.floor()
    }
}

fn fill_missing(channels: usize, first: usize, fill: f32, out: &mut [f32]) {
    for (c, o) in out.iter_mut().enumerate() {
        if first + c >= channels {
            *o = fill;
        }
    }
}

/// For each of `dst` output texels, the source texels it covers and their weights (summing to
/// 1): a box `src / dst` texels wide.
fn box_weights(src: usize, dst: usize) -> Vec<Vec<(usize, f32)>> {
    let ratio = src as f64 / dst as f64;
    (0..dst)
        .map(|i| {
            let (lo, hi) = (i as f64 * ratio, (i + 1) as f64 * ratio);
            (lo.floor() as usize..(hi.ceil() as usize).min(src))
                .filter_map(|j| {
                    let overlap = hi.min(j as f64 + 1.0) - lo.max(j as f64);
                    (overlap > 0.0).then_some((j, (overlap / ratio) as f32))
                })
                .collect()
        })
        .collect()
}

/// The next coarser level (see the module doc), filtering rows then columns.
fn downsample(img: &TexImage) -> TexImage {
    let (w, h, ch) = (img.width(), img.height(), img.channels());
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let (xs, ys) = (box_weights(w, nw), box_weights(h, nh));
    let mut rows = vec![0.0f32; nw * h * ch];
    for y in 0..h {
        for (x, taps) in xs.iter().enumerate() {
            let dst = &mut rows[(y * nw + x) * ch..][..ch];
            for &(sx, wt) in taps {
                for (d, v) in dst.iter_mut().zip(img.texel(sx, y)) {
                    *d += wt * v;
                }
            }
        }
    }
    let mut out = vec![0.0f32; nw * nh * ch];
    for (y, taps) in ys.iter().enumerate() {
        for &(sy, wt) in taps {
            let src = &rows[sy * nw * ch..][..nw * ch];
            for (d, v) in out[y * nw * ch..][..nw * ch].iter_mut().zip(src) {
                *d += wt * v;
            }
        }
    }
    TexImage::new(nw, nh, ch, out).expect("sizes are at least 1 and the buffer matches")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pair of wrapped taps is the two taps wrapped one at a time, for every mode, inside and
    /// outside the image, near the 32-bit limits and at the saturated ends.
    #[test]
    fn wrapping_a_pair_of_taps_equals_wrapping_each() {
        let mut taps: Vec<i64> = (-40..40).collect();
        for edge in [i64::from(i32::MAX), i64::from(i32::MIN), i64::MAX, i64::MIN, 1 << 40, -(1 << 40)] {
            taps.extend([edge.saturating_sub(1), edge, edge.saturating_add(1)]);
        }
        for n in [1, 2, 3, 7, 16] {
            for mode in [Wrap::Periodic, Wrap::Clamp, Wrap::Black] {
                for &i in &taps {
                    let each = [wrap_index(i, n, mode), wrap_index(i.saturating_add(1), n, mode)];
                    assert_eq!(wrap_pair(i, n, mode), each, "tap {i}, {n} texels, {mode:?}");
                }
            }
        }
    }

    /// The bilinear blend as first written: every tap wrapped on its own, each channel looked up
    /// by index, zero-weight and missing taps skipped.
    fn bilinear_tap_by_tap(img: &TexImage, s: f32, t: f32, wrap: [Wrap; 2], first: usize, out: &mut [f32]) {
        let x = s * img.width() as f32 - 0.5;
        let y = t * img.height() as f32 - 0.5;
        let (fx, fy) = (x - x.floor(), y - y.floor());
        let (x0, y0) = (x.floor() as i64, y.floor() as i64);
        for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
            for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
                let tap = 1.0 * wx * wy;
                let (Some(ix), Some(iy)) =
                    (wrap_index(x0 + dx, img.width(), wrap[0]), wrap_index(y0 + dy, img.height(), wrap[1]))
                else {
                    continue;
                };
                if tap == 0.0 {
                    continue;
                }
                for (c, o) in out.iter_mut().enumerate() {
                    if let Some(v) = img.texel(ix, iy).get(first + c) {
                        *o = tap.mul_add(*v, *o);
                    }
                }
            }
        }
    }

    /// Every channel count, first channel and result width (the unrolled widths and the rest)
    /// blends exactly as tap by tap, in every wrap mode, inside and outside the image.
    #[test]
    fn bilinear_blends_any_channels_exactly_as_tap_by_tap() {
        let modes = [Wrap::Periodic, Wrap::Clamp, Wrap::Black];
        let coords = [-1.3f32, -0.01, 0.0, 0.124, 0.5, 0.77, 0.999, 1.0, 2.6];
        for channels in 1..=5 {
            for (w, h) in [(4, 4), (5, 3), (1, 2)] {
                let img = image(w, h, channels, |x, y, c| (x * 7 + y * 13 + c * 29) as f32 * 0.37 - 1.0);
                for first in 0..=channels {
                    for width in 1..=5 {
                        for (&s, &t) in coords.iter().zip(coords.iter().rev()) {
                            for wrap in [[modes[0], modes[1]], [modes[1], modes[2]], [modes[2], modes[0]]] {
                                let (mut fast, mut slow) = (vec![0.5; width], vec![0.5; width]);
                                accumulate_bilinear(&img, s, t, wrap, first, 1.0, &mut fast);
                                bilinear_tap_by_tap(&img, s, t, wrap, first, &mut slow);
                                let case = format!("{channels} channels, {w}x{h}, first {first}, {width} wide, at ({s}, {t}), {wrap:?}");
                                assert_eq!(fast, slow, "{case}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// A trilinear probe's paired lookup is the two levels' lookups one after the other, bit for
    /// bit: every channel count, first channel and result width, every wrap mode, even and odd
    /// levels, coordinates inside, outside, on texel centres and edges, far away and not finite.
    #[test]
    fn paired_levels_blend_exactly_as_one_level_after_the_other() {
        let modes = [Wrap::Periodic, Wrap::Clamp, Wrap::Black];
        let mut coords = vec![-1.3f32, -0.01, 0.0, 0.124, 0.125, 0.5, 0.77, 0.999, 1.0, 2.6, -7.9e5, 3.1e6];
        coords.extend([1e9, -1e12, f32::MAX, f32::INFINITY, f32::NAN]);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..40 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            coords.push((state >> 40) as f32 / (1u64 << 22) as f32 - 2.0);
        }
        for channels in 1..=5 {
            for (w, h) in [(8, 8), (5, 3), (1, 2), (16, 4)] {
                let m = MipMap::new(image(w, h, channels, |x, y, c| (x * 7 + y * 13 + c * 29) as f32 * 0.37 - 1.0));
                let levels = [m.level(0), m.level(1)];
                for first in 0..=channels {
                    for width in [1, 3, 4, 5] {
                        for (i, &s) in coords.iter().enumerate() {
                            let t = coords[(i * 7 + 3) % coords.len()];
                            let wrap = [modes[i % 3], modes[(i / 3 + channels) % 3]];
                            let weights = [0.3 + 0.01 * i as f32, 0.25];
                            let (mut paired, mut each) = (vec![0.5; width], vec![0.5; width]);
                            accumulate_bilinear_pair(levels, s, t, wrap, first, weights, &mut paired);
                            one_level_after_the_other(levels, s, t, wrap, first, weights, &mut each);
                            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                            let case = format!(
                                "{channels} channels, {w}x{h}, first {first}, {width} wide, at ({s}, {t}), {wrap:?}"
                            );
                            assert_eq!(bits(&paired), bits(&each), "{case}");
                        }
                    }
                }
            }
        }
    }

    /// Filtered lookups sum their probes the fast way, where the texture wraps periodically and
    /// its levels are powers of two, exactly as tap by tap: every channel count, first channel and
    /// result width, magnified and minified, isotropic and anisotropic footprints, coordinates
    /// inside, outside, near the fast way's limit of 2^22 texels and beyond it, and zero-weight
    /// taps beside infinite texels.
    #[test]
    fn periodic_probes_sum_exactly_as_tap_by_tap() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || unit_random(&mut state);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for channels in 1..=5 {
            for (w, h) in [(16, 16), (32, 4), (1, 8), (8, 1), (12, 8)] {
                let mut m = MipMap::new(image(w, h, channels, |x, y, c| (x * 7 + y * 13 + c * 29) as f32 * 0.37 - 1.0));
                if channels == 2 {
                    // An infinite texel: texel centres beside it must still read exactly.
                    let mut data = m.level(0).data().to_vec();
                    data[channels] = f32::INFINITY;
                    m = MipMap::new(TexImage::new(w, h, channels, data).unwrap());
                }
                for case in 0..300 {
                    let far = [0.0, 1.0, -3.0, 4_194_303.0 / w as f32, 4_194_305.0 / w as f32, -9.0e6, 2.5e7];
                    let mut s = next() * 3.0 - 1.0 + far[case % far.len()];
                    let mut t = next() * 3.0 - 1.0;
                    if case % 11 == 0 {
                        // On texel centres: zero-weight taps.
                        s = (((s * w as f32) as i64) as f32 + 0.5) / w as f32;
                        t = (((t * h as f32) as i64) as f32 + 0.5) / h as f32;
                    }
                    let scale = (next() * 10.0 - 6.0).exp2();
                    let angle = next() * std::f32::consts::TAU;
                    let ratio = 1.0 + 20.0 * next() * next();
                    let footprint = Footprint {
                        dsdx: scale * angle.cos(),
                        dtdx: scale * angle.sin(),
                        dsdy: -scale / ratio * angle.sin(),
                        dtdy: scale / ratio * angle.cos(),
                    };
                    let first = case % (channels + 1);
                    let width = [1, 3, 4, 5][case % 4];
                    let opts = LookupOptions::default();
                    let wrap = [Wrap::Periodic; 2];
                    let (mut fast, mut general) = (vec![0.5; width], vec![0.5; width]);
                    m.filter_probing(s, t, footprint, first, &mut fast, &opts, wrap, Probing::Fastest);
                    m.filter_probing(s, t, footprint, first, &mut general, &opts, wrap, Probing::General);
                    let case = format!(
                        "{channels} channels, {w}x{h}, first {first}, {width} wide, at ({s}, {t}), {footprint:?}"
                    );
                    assert_eq!(bits(&fast), bits(&general), "{case}");
                }
            }
        }
    }

    /// Four lanes at once give each lane the values of a lookup of its own, bit for bit, with
    /// inactive lanes untouched: lanes with different footprints (so different numbers of probes
    /// and levels), blur, first channels and coordinates (one not finite, some past 2^22 texels),
    /// on power-of-two textures (the periodic way) of 1, 3 and 4 channels, one that is not, and
    /// one with an infinite texel, 1 to 5 values a lane, with the texture's wrap modes and with
    /// clamping.
    /// Four lanes' periodic tap indices, for levels of any size, are those of `wrap_pair`: for
    /// corners on either side of zero, at the sizes' multiples and up to 2^22.
    #[test]
    fn lanes_wrap_taps_as_one_lane_does() {
        for n in [1usize, 2, 3, 7, 12, 1044, 65_537] {
            let map = MipMap::new(image(n, 1, 1, |x, _, _| x as f32));
            assert_eq!(map.power_of_two_levels, n.is_power_of_two());
            let level = LevelLanes::of(&map, [0; 4], Vec4::ONE, [0; 4], [None; 4]);
            let mut corners: Vec<i64> = (-3 * n as i64 - 2..3 * n as i64 + 2).collect();
            for big in [4_194_303i64, 4_194_304 - n as i64, 3_000_017, 1 << 21] {
                corners.extend([big, -big, big - 1, 1 - big]);
            }
            for four in corners.chunks(4) {
                let lanes: [i64; 4] = std::array::from_fn(|l| four[l % four.len()]);
                let [first, second] = level.wrap(IVec4::from_array(lanes.map(|c| c as i32)), 0);
                for (l, &corner) in lanes.iter().enumerate() {
                    let want = wrap_pair(corner, n, Wrap::Periodic).map(|i| i.map(|i| i as u32));
                    assert_eq!([Some(first.to_array()[l]), Some(second.to_array()[l])], want, "{n} texels, {corner}");
                }
            }
        }
    }

    #[test]
    fn lanes_filter_as_lookups_one_at_a_time() {
        /// A lane's s, t, footprint, blur and first channel.
        type Lane = (f32, f32, Footprint, f32, usize);
        let mut maps = [(32, 16, 3), (16, 16, 4), (8, 32, 1), (12, 8, 3), (21, 7, 4), (16, 8, 2)]
            .map(|(w, h, ch)| MipMap::new(image(w, h, ch, |x, y, c| ((x * 5 + y * 11 + c * 3) % 17) as f32 / 17.0)));
        // An infinite texel: the periodic way adds zero-weight taps, which only finite texels
        // allow, so this one goes lane by lane.
        let mut data = maps[5].level(0).data().to_vec();
        data[2 * (16 * 3 + 5)] = f32::INFINITY;
        maps[5] = MipMap::new(TexImage::new(16, 8, 2, data).unwrap());
        assert!(maps.iter().map(|m| m.finite).eq([true, true, true, true, true, false]));
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || unit_random(&mut state);
        for round in 0..800 {
            let m = &maps[round % maps.len()];
            let values = 1 + round / maps.len() % 5;
            let mut lane = |_| {
                let scale = (next() * 12.0 - 8.0).exp2();
                let fp = Footprint {
                    dsdx: scale * (next() - 0.5),
                    dtdx: scale * (next() - 0.5),
                    dsdy: scale * (next() - 0.5),
                    dtdy: scale * (next() - 0.5),
                };
                let blur = if next() < 0.3 { next() * 0.1 } else { 0.0 };
                let far = if next() < 0.1 { 4_194_300.0 / 8.0 } else { 0.0 };
                (next() * 4.0 - 2.0 + far, next() * 4.0 - 2.0, fp, blur, (next() * 5.0) as usize)
            };
            let mut lanes: [Lane; 4] = std::array::from_fn(&mut lane);
            if round % 7 == 0 {
                lanes[round % 4].0 = f32::NAN;
            }
            let active = std::array::from_fn(|l| (round + l) % 5 != 0);
            let wrap = if round % 9 == 0 { Some(Wrap::Clamp) } else { None };
            let opts = LookupOptions { fill: 0.25, swidth: 1.5, swrap: wrap, twrap: wrap, ..LookupOptions::default() };
            let row = |f: &dyn Fn(&Lane) -> f32| Vec4::from_array(std::array::from_fn(|l| f(&lanes[l])));
            let query = LookupLanes {
                s: row(&|l| l.0),
                t: row(&|l| l.1),
                dsdx: row(&|l| l.2.dsdx),
                dtdx: row(&|l| l.2.dtdx),
                dsdy: row(&|l| l.2.dsdy),
                dtdy: row(&|l| l.2.dtdy),
                sblur: row(&|l| l.3),
                tblur: row(&|l| l.3),
            };
            let mut out = vec![-1.0f32; 4 * values];
            m.filter_lanes(&query, active, lanes.map(|l| l.4), &mut out, &opts);
            for (l, &(s, t, fp, blur, first)) in lanes.iter().enumerate() {
                let mut alone = vec![0.0; values];
                m.filter(s, t, fp, first, &mut alone, &LookupOptions { sblur: blur, tblur: blur, ..opts });
                for (c, v) in alone.iter().enumerate() {
                    let want = if active[l] { v.to_bits() } else { (-1.0f32).to_bits() };
                    assert_eq!(out[4 * c + l].to_bits(), want, "round {round}, lane {l}, channel {c}");
                }
            }
        }
    }

    /// The footprint's ellipse, worked out in f32 four lanes at a time, against the same
    /// eigen-decomposition in f64: thin, round, rotated, blurred, tiny and huge footprints.
    #[test]
    fn ellipses_match_the_eigenvalues_in_double_precision() {
        let (w, h) = (64.0f32, 32.0f32);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || f64::from(unit_random(&mut state));
        for round in 0..2000 {
            let scale = (next() * 16.0 - 12.0).exp2();
            let (angle, ratio) = (next() * std::f64::consts::TAU, (next() * 12.0).exp2());
            let (blur_s, blur_t) = if round % 3 == 0 { (next() * 0.02, next() * 0.02) } else { (0.0, 0.0) };
            let (sin, cos) = angle.sin_cos();
            let fp = [scale * cos, scale * sin, -scale / ratio * sin, scale / ratio * cos].map(|v| v as f32);
            let footprint = Footprint { dsdx: fp[0], dtdx: fp[1], dsdy: fp[2], dtdy: fp[3] };
            let lanes = LookupLanes::splat(0.5, 0.5, footprint, [blur_s as f32, blur_t as f32]);
            let e = Ellipses::of(&lanes, &LookupOptions::default(), w, h);
            // The reference, in f64 from the same f32 inputs.
            let (x0, x1) = (fp[0] as f64 * w as f64, fp[1] as f64 * h as f64);
            let (y0, y1) = (fp[2] as f64 * w as f64, fp[3] as f64 * h as f64);
            let (bs, bt) = ((blur_s as f32) as f64 * w as f64, (blur_t as f32) as f64 * h as f64);
            let (a, b, c) = (x0 * x0 + y0 * y0 + bs * bs, x0 * x1 + y0 * y1, x1 * x1 + y1 * y1 + bt * bt);
            let spread = (0.25 * (a - c) * (a - c) + b * b).sqrt();
            let l1 = 0.5 * (a + c) + spread;
            let l2 = (a * c - b * b) / l1;
            let cap = 4.0 * 64.0;
            let (major, minor) = (l1.sqrt().min(cap), l2.max(0.0).sqrt().min(cap));
            let case = format!("round {round}: {footprint:?}, blur {blur_s} {blur_t}");
            let close = |got: f32, want: f64| (got as f64 - want).abs() <= 1e-5 * want + 1e-30;
            assert!(close(e.major.x, major), "major {} vs {major}: {case}", e.major.x);
            assert!(close(e.minor.x, minor), "minor {} vs {minor}: {case}", e.minor.x);
            // The direction is a unit eigenvector of l1 (up to sign), where the ellipse is not
            // nearly round.
            if l1 > 1.01 * l2 {
                let (dx, dy) = (e.direction[0].x as f64, e.direction[1].x as f64);
                assert!(((dx * dx + dy * dy) - 1.0).abs() < 1e-5, "unit: {case}");
                let residual = ((a - l1) * dx + b * dy).abs() + (b * dx + (c - l1) * dy).abs();
                assert!(residual <= 1e-4 * l1, "eigenvector residual {residual} of {l1}: {case}");
            }
        }
    }

    #[test]
    fn the_vector_logarithm_is_within_a_few_ulps_of_the_library_one() {
        let mut values = vec![f32::MIN_POSITIVE, 1.0, 2.0, 0.5, std::f32::consts::SQRT_2, 1.4142134, 1.4142137, 3.0e38];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..100_000 {
            values.push((unit_random(&mut state) * 200.0 - 100.0).exp2());
        }
        for chunk in values.chunks(4) {
            let v = Vec4::from_array(std::array::from_fn(|l| chunk.get(l).copied().unwrap_or(1.0)));
            for (got, x) in log2(v).to_array().into_iter().zip(v.to_array()) {
                let want = (x as f64).log2();
                assert!(
                    (got as f64 - want).abs() <= 4.0 * f32::EPSILON as f64 * want.abs().max(1.0),
                    "log2({x:e}): {got} vs {want}"
                );
            }
        }
        let below = log2(Vec4::new(0.0, 1e-40, -1.0, f32::MIN_POSITIVE / 2.0)).to_array();
        assert_eq!(below, [-127.0; 4], "nothing below the smallest normal float");
    }

    /// The vector split into exponent and mantissa gives the bits the split lane by lane (as first
    /// written) gives, for every kind of float.
    #[test]
    fn the_vector_logarithm_splits_its_argument_as_lane_by_lane() {
        fn lane_by_lane(v: Vec4) -> Vec4 {
            let split = v.to_array().map(|x| {
                let bits = x.to_bits();
                let (exponent, mantissa) = ((bits >> 23) as i32 - 127, bits & 0x007F_FFFF);
                if mantissa > 0x0035_04F3 {
                    (exponent + 1, f32::from_bits(mantissa | 0x3F00_0000))
                } else {
                    (exponent, f32::from_bits(mantissa | 0x3F80_0000))
                }
            });
            let exponent = Vec4::from_array(split.map(|(e, _)| e as f32));
            let m = Vec4::from_array(split.map(|(_, m)| m));
            let z = (m - Vec4::ONE) / (m + Vec4::ONE);
            let z2 = z * z;
            let series = z * (Vec4::ONE + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0)))));
            let log = exponent + series * (2.0 / std::f32::consts::LN_2);
            Vec4::select(v.cmpge(Vec4::splat(f32::MIN_POSITIVE)), log, Vec4::splat(-127.0))
        }
        let mut state = 0x5151_F00D_2024_0001u64;
        let mut values = vec![0.0, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, f32::MAX, f32::MIN_POSITIVE];
        // Around sqrt(2), where the mantissa takes the next exponent, and its reciprocal.
        values.extend([
            1.4142134f32,
            std::f32::consts::SQRT_2,
            1.4142137,
            std::f32::consts::FRAC_1_SQRT_2,
            1e-40,
            -2.5,
        ]);
        for _ in 0..200_000 {
            // Every bit pattern is as likely: signs, subnormals, NaNs and infinities included.
            unit_random(&mut state);
            values.push(f32::from_bits((state >> 32) as u32));
        }
        for chunk in values.chunks(4) {
            let v = Vec4::from_array(std::array::from_fn(|l| chunk.get(l).copied().unwrap_or(1.0)));
            let (got, want) = (log2(v).to_array().map(f32::to_bits), lane_by_lane(v).to_array().map(f32::to_bits));
            assert_eq!(got, want, "log2 of {v}");
        }
    }

    #[test]
    fn the_inline_floor_equals_the_library_floor_bit_for_bit() {
        let mut special = vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 8_388_607.5, -8_388_607.5, 8_388_608.0, -8_388_609.0];
        special.extend([f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-45, -1e-45, f32::MAX, f32::MIN]);
        special.extend([f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 2.0f32.powi(31), -(2.0f32.powi(31))]);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..200_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            special.push(f32::from_bits(state as u32));
            special.push((state >> 40) as f32 / 1024.0 - 8192.0);
        }
        for x in special {
            let (a, b) = (floor(x), x.floor());
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "floor({x:e}): {a:e} vs {b:e}");
        }
    }

    /// `floor_small` against `floor` and `small_integers` of it: integers, halves, tiny values on
    /// both sides of zero and random values up to 2^22 (zero itself positive: no texel coordinate
    /// is -0).
    #[test]
    fn the_vector_floor_and_its_integers_equal_the_library_ones() {
        let mut values = vec![0.0, 0.5, -0.5, 1.0, -1.0, 1e-45, -1e-45, 4_194_303.5, -4_194_303.5, -4_194_304.0];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..100_000 {
            let r = unit_random(&mut state);
            values.push((r - 0.5) * 8_388_607.0 * unit_random(&mut state).powi(8));
        }
        for four in values.chunks_exact(4) {
            let v = Vec4::from_slice(four);
            let (floor, integers) = floor_small(v);
            assert_eq!(floor.to_array().map(f32::to_bits), v.floor().to_array().map(f32::to_bits), "{v}");
            assert_eq!(integers, small_integers(v.floor()), "{v}");
        }
    }

    /// The next number in [0, 1) of a xorshift generator (24 bits): the same cases every run.
    fn unit_random(state: &mut u64) -> f32 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    fn image(w: usize, h: usize, ch: usize, f: impl Fn(usize, usize, usize) -> f32) -> TexImage {
        let data =
            (0..h).flat_map(|y| (0..w).flat_map(move |x| (0..ch).map(move |c| (x, y, c)))).map(|(x, y, c)| f(x, y, c));
        TexImage::new(w, h, ch, data.collect()).unwrap()
    }

    fn checker(n: usize) -> MipMap {
        MipMap::new(image(n, n, 1, |x, y, _| ((x + y) % 2) as f32))
    }

    fn mean(img: &TexImage) -> f32 {
        img.data().iter().sum::<f32>() / img.data().len() as f32
    }

    fn lookup(m: &MipMap, s: f32, t: f32, fp: Footprint, opts: &LookupOptions) -> f32 {
        let mut out = [0.0];
        m.filter(s, t, fp, 0, &mut out, opts);
        out[0]
    }

    #[test]
    fn level_sizes_halve_down_to_one_including_odd_and_oblong() {
        let sizes = |w, h| -> Vec<(usize, usize)> {
            {
                let m = MipMap::new(image(w, h, 1, |_, _, _| 0.0));
                (0..m.level_count()).map(|i| (m.level(i).width(), m.level(i).height())).collect()
            }
        };
        assert_eq!(sizes(8, 8), [(8, 8), (4, 4), (2, 2), (1, 1)]);
        assert_eq!(sizes(5, 3), [(5, 3), (2, 1), (1, 1)]);
        assert_eq!(sizes(8, 2), [(8, 2), (4, 1), (2, 1), (1, 1)]);
        assert_eq!(sizes(1, 1), [(1, 1)]);
    }

    #[test]
    fn levels_average_exactly() {
        // Even: each texel of level 1 is the mean of its 2x2 block.
        let m = MipMap::new(image(4, 4, 2, |x, y, c| (x + 4 * y + 100 * c) as f32));
        let l1 = m.level(1);
        assert_eq!(l1.texel(0, 0), &[(0.0 + 1.0 + 4.0 + 5.0) / 4.0, 102.5]);
        assert_eq!(l1.texel(1, 1), &[(10.0 + 11.0 + 14.0 + 15.0) / 4.0, 112.5]);
        // Odd sizes keep the mean at every level.
        let m = MipMap::new(image(7, 5, 1, |x, y, _| (x * x + 3 * y) as f32));
        let want = mean(m.level(0));
        for l in (0..m.level_count()).map(|i| m.level(i)) {
            assert!((mean(l) - want).abs() < 1e-4, "{} vs {want}", mean(l));
        }
    }

    #[test]
    fn bilinear_is_exact_at_texel_centres_and_interpolates_between() {
        let m = MipMap::new(image(4, 2, 1, |x, y, _| (x + 10 * y) as f32));
        let mut out = [0.0];
        for y in 0..2 {
            for x in 0..4 {
                let (s, t) = ((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 2.0);
                m.bilinear(0, s, t, [Wrap::Clamp; 2], 0, &mut out);
                assert_eq!(out[0], (x + 10 * y) as f32);
                // A point-sampled filter is the same thing.
                assert_eq!(lookup(&m, s, t, Footprint::POINT, &LookupOptions::default()), (x + 10 * y) as f32);
            }
        }
        m.bilinear(0, 0.25, 0.5, [Wrap::Clamp; 2], 0, &mut out);
        assert!((out[0] - 5.5).abs() < 1e-5, "the mean of texels 0, 1, 10, 11: {}", out[0]);
    }

    #[test]
    fn t_runs_down_the_image() {
        // Top row 1, bottom row 0.
        let m = MipMap::new(image(2, 2, 1, |_, y, _| if y == 0 { 1.0 } else { 0.0 }));
        let opts = LookupOptions { twrap: Some(Wrap::Clamp), ..LookupOptions::default() };
        assert_eq!(lookup(&m, 0.5, 0.1, Footprint::POINT, &opts), 1.0);
        assert_eq!(lookup(&m, 0.5, 0.9, Footprint::POINT, &opts), 0.0);
    }

    #[test]
    fn wrap_modes() {
        // Left column 1, right column 0; sample just left of s = 0.
        let m = MipMap::new(image(2, 1, 1, |x, _, _| if x == 0 { 1.0 } else { 0.0 }));
        let at = |wrap| {
            let opts = LookupOptions { swrap: Some(wrap), ..LookupOptions::default() };
            lookup(&m, -0.25, 0.5, Footprint::POINT, &opts)
        };
        assert_eq!(at(Wrap::Clamp), 1.0, "the left edge extends");
        assert_eq!(at(Wrap::Periodic), 0.0, "s = -0.25 is s = 0.75, the right texel");
        assert_eq!(at(Wrap::Black), 0.0);
        // Half way over the edge: black blends with the edge texel.
        let opts = LookupOptions { swrap: Some(Wrap::Black), ..LookupOptions::default() };
        assert!((lookup(&m, 0.0, 0.5, Footprint::POINT, &opts) - 0.5).abs() < 1e-6);
        // The file's own modes apply when the lookup does not say.
        let clamped = MipMap::with_wrap(m.level(0).clone(), [Wrap::Clamp, Wrap::Clamp]);
        assert_eq!(lookup(&clamped, -0.25, 0.5, Footprint::POINT, &LookupOptions::default()), 1.0);
        // Far away and non-finite coordinates stay in range.
        assert!(lookup(&m, 1e30, -1e30, Footprint::POINT, &LookupOptions::default()).is_finite());
        let fill = LookupOptions { fill: 0.5, ..LookupOptions::default() };
        assert_eq!(lookup(&m, f32::NAN, 0.5, Footprint::POINT, &fill), 0.5, "no texel: the fill value");
        assert_eq!(lookup(&m, 0.5, f32::INFINITY, Footprint::POINT, &fill), 0.5);
        let nan_footprint = Footprint { dsdx: f32::NAN, dtdx: 0.0, dsdy: 0.0, dtdy: 1.0 };
        assert!(lookup(&m, 0.5, 0.5, nan_footprint, &LookupOptions::default()).is_finite());
        let huge = Footprint { dsdx: f32::INFINITY, dtdx: 0.0, dsdy: 0.0, dtdy: f32::MAX };
        assert!((lookup(&m, 0.5, 0.5, huge, &LookupOptions::default()) - 0.5).abs() < 1e-6, "the whole texture");
    }

    #[test]
    fn a_checkerboard_under_a_large_footprint_is_grey() {
        let m = checker(64);
        let opts = LookupOptions::default();
        // The footprint covers the whole texture.
        let v = lookup(&m, 0.3, 0.7, Footprint { dsdx: 1.0, dtdx: 0.0, dsdy: 0.0, dtdy: 1.0 }, &opts);
        assert!((v - 0.5).abs() < 1e-4, "{v}");
        // A few texels wide, rotated 45 degrees: already close to grey.
        let fp = Footprint { dsdx: 6.0 / 64.0, dtdx: 6.0 / 64.0, dsdy: -6.0 / 64.0, dtdy: 6.0 / 64.0 };
        let v = lookup(&m, 0.41, 0.37, fp, &opts);
        assert!((v - 0.5).abs() < 0.05, "{v}");
        // A point sample sees black or white.
        let v = lookup(&m, 0.5 / 64.0, 0.5 / 64.0, Footprint::POINT, &opts);
        assert_eq!(v, 0.0);
    }

    #[test]
    fn anisotropic_footprints_average_along_their_length_only() {
        // Vertical stripes, one texel each: a footprint long in s averages to grey, one long in
        // t (and one texel wide in s) keeps the stripe.
        let m = MipMap::new(image(64, 64, 1, |x, _, _| (x % 2) as f32));
        let opts = LookupOptions::default();
        let across =
            lookup(&m, 0.5 / 64.0, 0.5, Footprint { dsdx: 16.0 / 64.0, dtdx: 0.0, dsdy: 0.0, dtdy: 0.5 / 64.0 }, &opts);
        assert!((across - 0.5).abs() < 0.05, "{across}");
        let along =
            lookup(&m, 1.5 / 64.0, 0.5, Footprint { dsdx: 0.0, dtdx: 16.0 / 64.0, dsdy: 0.5 / 64.0, dtdy: 0.0 }, &opts);
        assert!(along > 0.9, "stays on the white stripe: {along}");
    }

    #[test]
    fn probes_follow_the_eccentricity_with_a_quarter_of_slack_each_as_wide_as_its_share() {
        let m = MipMap::new(image(256, 256, 1, |x, y, _| ((x + y) % 2) as f32));
        let opts = LookupOptions::default();
        // A footprint `aspect` times as long in s as it is wide in t, 4 texels wide.
        let plan = |aspect: f32| {
            let fp = Footprint { dsdx: 4.0 * aspect / 256.0, dtdx: 0.0, dsdy: 0.0, dtdy: 4.0 / 256.0 };
            m.probe_plans(&LookupLanes::splat(0.5, 0.5, fp, [0.0, 0.0]), &opts).lane(0)
        };
        for (aspect, probes, width) in [
            (1.0, 1, 4.0),
            // Slightly eccentric: one probe, as wide as the footprint is long.
            (1.2, 1, 4.8),
            (1.3, 2, 4.0),
            // Two probes, each as wide as half the length.
            (2.2, 2, 4.4),
            (2.3, 3, 4.0),
            (7.9, 8, 4.0),
            // Past the most probes, each widens to its share of the length.
            (32.0, MAX_ANISOTROPY, 8.0),
        ] {
            let p = plan(aspect);
            assert_eq!(p.probes, probes, "aspect {aspect}");
            assert!((p.lod - f32::log2(width)).abs() < 1e-4, "aspect {aspect}: lod {} for width {width}", p.lod);
        }
    }

    #[test]
    fn width_and_blur_widen_the_filter() {
        let m = checker(32);
        let tiny = Footprint { dsdx: 0.01 / 32.0, dtdx: 0.0, dsdy: 0.0, dtdy: 0.01 / 32.0 };
        let at = |opts: &LookupOptions| lookup(&m, 0.5 / 32.0, 0.5 / 32.0, tiny, opts);
        assert_eq!(at(&LookupOptions::default()), 0.0);
        let blurred = at(&LookupOptions { sblur: 0.5, tblur: 0.5, ..LookupOptions::default() });
        assert!((blurred - 0.5).abs() < 0.02, "{blurred}");
        let wide = at(&LookupOptions { swidth: 3200.0, twidth: 3200.0, ..LookupOptions::default() });
        assert!((wide - 0.5).abs() < 0.02, "{wide}");
        // Blur in s only, over a texture striped in t: nothing to average.
        let stripes = MipMap::new(image(32, 32, 1, |_, y, _| (y % 2) as f32));
        let v = lookup(&stripes, 0.5, 0.5 / 32.0, tiny, &LookupOptions { sblur: 0.5, ..LookupOptions::default() });
        assert!(v < 0.05, "{v}");
    }

    #[test]
    fn channels_beyond_the_texture_get_the_fill_value() {
        let m = MipMap::new(image(1, 1, 2, |_, _, c| c as f32 + 1.0));
        let mut out = [0.0; 3];
        m.filter(0.5, 0.5, Footprint::POINT, 1, &mut out, &LookupOptions { fill: 7.0, ..LookupOptions::default() });
        assert_eq!(out, [2.0, 7.0, 7.0]);
    }
}

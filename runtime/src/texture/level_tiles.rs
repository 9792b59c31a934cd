//! Mip levels in tiles: what a distributed worker fetches of a large level, a square of texels at
//! a time, the first time a lookup reads it (`remote.rs`, `mip.rs`).
//!
//! A level is cut into tiles of `side` texels square (a power of two), row after row from the
//! top-left corner; the tiles of the last column and row are as narrow and as short as what is
//! left. Whether a level is cut at all, and into how many tiles, follows from its size and the
//! side alone ([`tile_grid`]), so the master and a worker agree on every tile's place from the
//! side the master names.
//!
//! A tile also holds an apron of [`APRON`] texels: the columns right of it and the rows below it,
//! where the level goes on. A lookup reads a box of texels from its probes' first tap to their
//! last; whichever tile holds the box's first texel holds all of a box up to `APRON + 1` texels
//! on a side, and the lookup reads that one tile (`MipMap::tile_views`) rather than texel by
//! texel across two or four: every bilinear probe (two columns by two rows), and the short runs
//! of probes of a slanted footprint.

use std::sync::OnceLock;

use super::image::TexImage;

/// The side of the tiles a master cuts large levels into, in texels: 64 x 64 texels are 12 KiB
/// of an 8-bit RGB level, 48 KiB of floats.
pub(crate) const TILE_SIDE: usize = 64;

/// The texels a tile holds past its right and bottom edges, where the level goes on: 4 makes a
/// tile 68 x 68 texels, 13% more than its own 64 x 64.
pub(crate) const APRON: usize = 4;

/// The most tiles the levels of one map are cut into, together. A worker sets aside a slot for
/// every tile of a map it is told of; a map that would have more (a level 0 of more than 2^32
/// texels at the master's side) is fetched a level at a time.
pub const MAX_TILES_A_MAP: usize = 1 << 20;

/// The tiles across and down of a level of `[width, height]` texels cut into tiles of `side`, or
/// `None` when it is not cut: a side of 0 (no tiles), or a level of at most four tiles' texels,
/// which travels whole.
pub(crate) fn tile_grid([width, height]: [usize; 2], side: usize) -> Option<[usize; 2]> {
    let texels = width.checked_mul(height)?;
    let tile = side.checked_mul(side)?;
    if side == 0 || texels <= tile.saturating_mul(4) {
        return None;
    }
    Some([width.div_ceil(side), height.div_ceil(side)])
}

/// Whether `side` is one a worker takes: a power of two from 16 to 4096 texels, or 0 for none.
pub(crate) fn valid_side(side: usize) -> bool {
    side == 0 || (side.is_power_of_two() && (16..=4096).contains(&side))
}

/// The first texel (column, row) of tile `index` of a level of `size` cut into tiles of `side`,
/// and the tile's width and height; `None` past the last tile or for a level not cut.
pub(crate) fn tile_rect(size: [usize; 2], side: usize, index: usize) -> Option<([usize; 2], [usize; 2])> {
    let [across, down] = tile_grid(size, side)?;
    if index >= across * down {
        return None;
    }
    let corner = [index % across * side, index / across * side];
    Some((corner, [side.min(size[0] - corner[0]), side.min(size[1] - corner[1])]))
}

/// The texels tile `index` holds: its first texel (its place in the level, as [`tile_rect`]'s),
/// and its width and height with its apron.
pub(crate) fn held_rect(size: [usize; 2], side: usize, index: usize) -> Option<([usize; 2], [usize; 2])> {
    let (corner, tile) = tile_rect(size, side, index)?;
    Some((corner, [0, 1].map(|k| (tile[k] + APRON).min(size[k] - corner[k]))))
}

/// Tile `index` of `level` cut into tiles of `side`, with its apron, as an image of its own.
pub(crate) fn cut_tile(level: &TexImage, side: usize, index: usize) -> Option<TexImage> {
    let ([x, y], [w, h]) = held_rect([level.width(), level.height()], side, index)?;
    let channels = level.channels();
    let row = level.width() * channels;
    let mut values = Vec::with_capacity(w * h * channels);
    for r in y..y + h {
        values.extend_from_slice(&level.data()[r * row + x * channels..][..w * channels]);
    }
    TexImage::new(w, h, channels, values)
}

/// A level of a remote map, held tile by tile as lookups read them.
pub(crate) struct TiledLevel {
    size: [usize; 2],
    /// The tiles' side is `1 << shift` texels.
    shift: u32,
    across: usize,
    /// Row after row; each set once, with the tile's texels.
    tiles: Box<[OnceLock<TexImage>]>,
}

impl TiledLevel {
    /// A level of `size` texels in tiles of `side` (a power of two), none held yet; `None` when
    /// such a level is not cut.
    pub(crate) fn new(size: [usize; 2], side: usize) -> Option<TiledLevel> {
        let [across, down] = tile_grid(size, side).filter(|_| side.is_power_of_two())?;
        let tiles = (0..across * down).map(|_| OnceLock::new()).collect();
        Some(TiledLevel { size, shift: side.trailing_zeros(), across, tiles })
    }

    /// How many tiles the level is cut into.
    #[cfg(test)]
    pub(crate) fn count(&self) -> usize {
        self.tiles.len()
    }

    /// How many of them are held.
    #[cfg(test)]
    pub(crate) fn held(&self) -> usize {
        self.tiles.iter().filter(|t| t.get().is_some()).count()
    }

    /// The level's width and height.
    pub(crate) fn size(&self) -> [usize; 2] {
        self.size
    }

    /// The tile holding texel (x, y) of the level (inside it), and the texel's place in the tile.
    #[inline(always)]
    pub(crate) fn tile_of(&self, x: usize, y: usize) -> (usize, [usize; 2]) {
        let (tx, ty) = (x >> self.shift, y >> self.shift);
        (ty * self.across + tx, [x - (tx << self.shift), y - (ty << self.shift)])
    }

    /// Tile `index`, when held.
    #[inline(always)]
    pub(crate) fn get(&self, index: usize) -> Option<&TexImage> {
        self.tiles.get(index)?.get()
    }

    /// The width and height tile `index` has, its apron included.
    pub(crate) fn tile_size(&self, index: usize) -> Option<[usize; 2]> {
        held_rect(self.size, 1 << self.shift, index).map(|(_, size)| size)
    }

    /// Holds `tile` as tile `index`, when it is that tile's size with `channels` channels and the
    /// tile is not held already. Whether it is held now.
    pub(crate) fn set(&self, index: usize, tile: TexImage, channels: usize) -> bool {
        let Some([w, h]) = self.tile_size(index) else { return false };
        if [tile.width(), tile.height(), tile.channels()] == [w, h, channels] {
            let _ = self.tiles[index].set(tile);
        }
        self.tiles[index].get().is_some()
    }
}

impl Clone for TiledLevel {
    /// The tiles held now.
    fn clone(&self) -> TiledLevel {
        TiledLevel {
            tiles: self.tiles.iter().map(|t| t.get().cloned().map(OnceLock::from).unwrap_or_default()).collect(),
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_of_more_than_four_tiles_are_cut_into_tiles_that_cover_them_once() {
        assert_eq!(tile_grid([128, 128], 64), None, "four tiles travel whole");
        assert_eq!(tile_grid([256, 64], 64), None);
        assert_eq!(tile_grid([129, 128], 64), Some([3, 2]));
        assert_eq!(tile_grid([1000, 1], 16), None);
        assert_eq!(tile_grid([2000, 1], 16), Some([125, 1]));
        assert_eq!(tile_grid([512, 512], 0), None);
        assert_eq!(tile_grid([usize::MAX, 2], 64), None);
        let (w, h, ch) = (300, 170, 3);
        let values: Vec<f32> = (0..w * h * ch).map(|i| i as f32).collect();
        let level = TexImage::new(w, h, ch, values).unwrap();
        let tiled = TiledLevel::new([w, h], 64).unwrap();
        assert_eq!(tiled.count(), 5 * 3);
        let mut covered = vec![0u8; w * h];
        for index in 0..tiled.count() {
            let ([x0, y0], [tw, th]) = tile_rect([w, h], 64, index).unwrap();
            let tile = cut_tile(&level, 64, index).unwrap();
            // The apron: columns and rows more, except along the level's right and bottom edges.
            let held = [(tw + APRON).min(w - x0), (th + APRON).min(h - y0)];
            assert_eq!([tile.width(), tile.height()], held);
            assert_eq!(held_rect([w, h], 64, index), Some(([x0, y0], held)));
            assert_eq!(tiled.tile_size(index), Some(held));
            for (y, x) in (0..held[1]).flat_map(|y| (0..held[0]).map(move |x| (y, x))) {
                assert_eq!(tile.texel(x, y), level.texel(x0 + x, y0 + y));
                if x < tw && y < th {
                    covered[(y0 + y) * w + x0 + x] += 1;
                    assert_eq!(tiled.tile_of(x0 + x, y0 + y), (index, [x, y]));
                }
            }
            assert!(tiled.set(index, tile, ch));
        }
        assert!(covered.iter().all(|&c| c == 1));
        assert_eq!(tile_rect([w, h], 64, tiled.count()), None);
        assert_eq!(tiled.clone().held(), tiled.count());
    }

    #[test]
    fn a_tile_of_another_size_is_not_held() {
        let tiled = TiledLevel::new([200, 100], 64).unwrap();
        let tile = |w, h, ch| TexImage::new(w, h, ch, vec![0.5; w * h * ch]).unwrap();
        let side = 64 + APRON;
        assert!(!tiled.set(3, tile(side, side, 3), 3), "the last tile of the first row is 8 texels wide");
        assert!(!tiled.set(0, tile(64, 64, 3), 3), "a tile holds its apron");
        assert!(!tiled.set(0, tile(side, side, 4), 3));
        assert!(!tiled.set(99, tile(side, side, 3), 3));
        assert!(tiled.set(3, tile(8, side, 3), 3));
        assert!(tiled.set(7, tile(8, 36, 3), 3));
        assert_eq!(tiled.held(), 2);
        assert!(!valid_side(100) && !valid_side(8) && valid_side(64) && valid_side(0));
    }
}

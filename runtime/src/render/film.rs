//! Filtered reconstruction: every sample is splatted through the frame's [`PixelFilter`] onto the
//! pixels whose centres lie within the filter's support around it, and a pixel's value is
//! `sum(w c) / sum(w)` over those samples (colour and alpha alike).
//!
//! A tile's samples reach past the tile, so each tile splats into its own [`TileFilm`], the tile
//! grown by the filter's reach (an apron), and the tile films are added into the frame's [`Film`]
//! one after the other in tile order. Every float sum is then taken in the same order whatever the
//! thread count, and the image is bit-identical.

use super::filter::PixelFilter;
use crate::tiles::Tile;

/// Weighted colour and alpha, then the sum of the weights.
type Sums = [f32; 5];

/// A pixel whose weights sum to less than this share of the filter's peak takes its box value
/// instead (its own samples' mean): with negative lobes, or a support narrower than the sample
/// spacing, the sum can come near zero and the quotient would blow up noise.
const MIN_WEIGHT_SHARE: f32 = 1e-3;

/// A rectangle of pixels, `x0..x1` by `y0..y1` (empty when either end is not past the start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
}

impl Rect {
    fn width(&self) -> usize {
        self.x1.saturating_sub(self.x0) as usize
    }

    fn height(&self) -> usize {
        self.y1.saturating_sub(self.y0) as usize
    }

    /// The pixels `lo..=hi` along one axis (from [`reach`]) clipped to `start..end`.
    fn clip(lo: i64, hi: i64, start: u32, end: u32) -> std::ops::Range<u32> {
        let lo = lo.max(i64::from(start));
        let hi = hi.min(i64::from(end) - 1);
        if lo > hi {
            0..0
        } else {
            lo as u32..hi as u32 + 1
        }
    }
}

/// The pixels along one axis whose centres `c = i + 0.5` lie within `radius` of a sample at `p`,
/// as `(first, last)`: `p - radius <= c <= p + radius`, the filter's closed support, so that a
/// sample exactly `radius` away counts on either side alike.
fn reach(p: f32, radius: f32) -> (i64, i64) {
    ((p - radius - 0.5).ceil() as i64, (p + radius - 0.5).floor() as i64)
}

/// The splats of one tile's samples: the tile grown by the filter's reach, clipped to the pixels
/// rendered (the image, or its crop window).
pub struct TileFilm {
    filter: PixelFilter,
    rect: Rect,
    sums: Vec<Sums>,
}

impl TileFilm {
    /// An empty film for `tile`'s samples; `pixels` is `(x0, x1, y0, y1)`, the pixels rendered
    /// ([`super::RenderOptions::pixel_range`]).
    pub fn new(filter: PixelFilter, tile: &Tile, pixels: (u32, u32, u32, u32)) -> TileFilm {
        let (rx, ry) = filter.radius();
        // A sample in the tile reaches at most ceil(radius) pixels past it (see `reach`).
        let (ax, ay) = (rx.ceil() as u32, ry.ceil() as u32);
        let (px0, px1, py0, py1) = pixels;
        let rect = Rect {
            x0: tile.x0.saturating_sub(ax).max(px0),
            x1: (tile.x0 + tile.width).saturating_add(ax).min(px1),
            y0: tile.y0.saturating_sub(ay).max(py0),
            y1: (tile.y0 + tile.height).saturating_add(ay).min(py1),
        };
        TileFilm { filter, rect, sums: vec![[0.0; 5]; rect.width() * rect.height()] }
    }

    /// The film's sums, a row of its pixels after another: red, green, blue, alpha and weight.
    pub fn sums(&self) -> &[[f32; 5]] {
        &self.sums
    }

    /// [`TileFilm::sums`], to fill in sums made elsewhere (a film of the same filter, tile and
    /// pixels has as many).
    pub fn sums_mut(&mut self) -> &mut [[f32; 5]] {
        &mut self.sums
    }

    /// Adds a sample of colour and alpha `rgba` at raster position `(x, y)` to every pixel of the
    /// film its filter reaches.
    pub fn splat(&mut self, (x, y): (f32, f32), rgba: [f32; 4]) {
        let (rx, ry) = self.filter.radius();
        let (ylo, yhi) = reach(y, ry);
        let (xlo, xhi) = reach(x, rx);
        let r = self.rect;
        let width = r.width();
        for py in Rect::clip(ylo, yhi, r.y0, r.y1) {
            let dy = py as f32 + 0.5 - y;
            let row = (py - r.y0) as usize * width;
            for px in Rect::clip(xlo, xhi, r.x0, r.x1) {
                let w = self.filter.weight(px as f32 + 0.5 - x, dy);
                if w == 0.0 {
                    continue;
                }
                let s = &mut self.sums[row + (px - r.x0) as usize];
                for (acc, v) in s.iter_mut().zip(rgba) {
                    *acc += w * v;
                }
                s[4] += w;
            }
        }
    }
}

/// The splats of a whole frame, added from its tile films.
pub struct Film {
    width: u32,
    /// The peak of the filter, which [`MIN_WEIGHT_SHARE`] is a share of.
    peak: f32,
    sums: Vec<Sums>,
}

impl Film {
    pub fn new(filter: &PixelFilter, width: u32, height: u32) -> Film {
        Film { width, peak: filter.weight(0.0, 0.0), sums: vec![[0.0; 5]; width as usize * height as usize] }
    }

    /// Adds a tile's splats. Callers add the tiles in tile order, so that each pixel's sums are
    /// taken in one order whatever the threads.
    pub fn add(&mut self, tile: &TileFilm) {
        let r = tile.rect;
        let width = r.width();
        if width == 0 {
            return;
        }
        for (y, row) in (r.y0..r.y1).zip(tile.sums.chunks_exact(width)) {
            let start = y as usize * self.width as usize + r.x0 as usize;
            for (acc, s) in self.sums[start..start + width].iter_mut().zip(row) {
                for (a, v) in acc.iter_mut().zip(s) {
                    *a += v;
                }
            }
        }
    }

    /// The filtered colour and alpha of pixel `(x, y)`, or `None` where the weights that reached it
    /// sum to too little (outside the pixels rendered, nothing reached it).
    pub fn resolve(&self, x: u32, y: u32) -> Option<[f32; 4]> {
        if x >= self.width {
            return None;
        }
        let s = self.sums.get(y as usize * self.width as usize + x as usize)?;
        (s[4] > MIN_WEIGHT_SHARE * self.peak).then(|| [s[0] / s[4], s[1] / s[4], s[2] / s[4], s[3] / s[4]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::filter::FilterKind;
    use crate::tiles::tiles;

    fn filter(kind: FilterKind, width: f32) -> PixelFilter {
        PixelFilter::new(kind, width, width).expect("valid widths")
    }

    /// Splats `samples` (raster position, value) through `f` over a `w` x `h` image cut into
    /// `size` tiles, each sample going to the tile of the pixel it lies in, tiles added in order.
    fn film_of(f: PixelFilter, w: u32, h: u32, size: u32, samples: &[((f32, f32), f32)]) -> Film {
        let mut film = Film::new(&f, w, h);
        for tile in tiles(w, h, size) {
            let mut t = TileFilm::new(f, &tile, (0, w, 0, h));
            for &((x, y), v) in samples {
                let inside = (tile.x0..tile.x0 + tile.width).contains(&(x as u32))
                    && (tile.y0..tile.y0 + tile.height).contains(&(y as u32));
                if inside {
                    t.splat((x, y), [v, v, v, 1.0]);
                }
            }
            film.add(&t);
        }
        film
    }

    #[test]
    fn a_unit_box_keeps_each_sample_on_its_own_pixel() {
        // Samples near the pixels' left and top edges and near the right and bottom ones.
        let samples: Vec<_> = (0..6)
            .flat_map(|y| (0..6).map(move |x| (x, y)))
            .flat_map(|(x, y)| {
                let v = (x + 10 * y) as f32;
                [((x as f32 + 0.001, y as f32 + 0.001), v), ((x as f32 + 0.999, y as f32 + 0.999), v)]
            })
            .collect();
        let film = film_of(PixelFilter::default(), 6, 6, 4, &samples);
        for y in 0..6 {
            for x in 0..6 {
                let v = (x + 10 * y) as f32;
                assert_eq!(film.resolve(x, y), Some([v, v, v, 1.0]), "({x}, {y})");
            }
        }
    }

    #[test]
    fn a_sample_on_the_edge_of_the_support_counts_on_both_sides() {
        // Half a pixel from two centres under a box one pixel wide.
        let film = film_of(PixelFilter::default(), 2, 1, 16, &[((1.0, 0.5), 1.0), ((0.25, 0.5), 0.0)]);
        assert_eq!(film.resolve(0, 0), Some([0.5, 0.5, 0.5, 1.0]));
        assert_eq!(film.resolve(1, 0), Some([1.0; 4]));
    }

    #[test]
    fn splats_cross_tile_borders() {
        // One sample at the corner where four 4x4 tiles meet reaches all four tiles' pixels.
        let film = film_of(filter(FilterKind::Gaussian, 2.0), 8, 8, 4, &[((4.0, 4.0), 1.0)]);
        for (x, y) in [(3, 3), (4, 3), (3, 4), (4, 4)] {
            assert_eq!(film.resolve(x, y), Some([1.0; 4]), "({x}, {y})");
        }
        assert_eq!(film.resolve(2, 4), None, "1.5 pixels away, past the support");
        assert_eq!(film.resolve(8, 0), None, "outside the image");
    }

    #[test]
    fn weights_normalise_and_tiny_sums_give_way() {
        // Two samples half a pixel either side of pixel (1, 0)'s centre, under a triangle 2 wide.
        let f = filter(FilterKind::Triangle, 2.0);
        let film = film_of(f, 3, 1, 16, &[((1.0, 0.5), 1.0), ((2.25, 0.5), 0.0)]);
        // Weights 0.5 and 0.25: (0.5 * 1 + 0.25 * 0) / 0.75.
        let p = film.resolve(1, 0).expect("weighted");
        assert!((p[0] - 2.0 / 3.0).abs() < 1e-6 && (p[3] - 1.0).abs() < 1e-6, "{p:?}");
        // Pixel 0's centre is 0.5 from the first sample only.
        assert_eq!(film.resolve(0, 0), Some([1.0; 4]));
        // A sample at the edge of a triangle's support weighs (next to) nothing.
        let edge = film_of(f, 3, 1, 16, &[((1.5 + 0.99995, 0.5), 1.0)]);
        assert_eq!(edge.resolve(1, 0), None);
    }

    #[test]
    fn a_crop_keeps_splats_inside_it() {
        let f = filter(FilterKind::Gaussian, 4.0);
        let tile = Tile { index: 0, x0: 0, y0: 0, width: 8, height: 8 };
        let mut t = TileFilm::new(f, &tile, (2, 5, 0, 8));
        t.splat((2.5, 4.5), [1.0; 4]);
        let mut film = Film::new(&f, 8, 8);
        film.add(&t);
        assert!(film.resolve(1, 4).is_none() && film.resolve(5, 4).is_none());
        assert!(film.resolve(2, 4).is_some() && film.resolve(4, 4).is_some());
    }
}

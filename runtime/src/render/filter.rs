//! Pixel reconstruction filters (RIB `PixelFilter "name" xwidth ywidth`, RISpec 3.2 section 4.3 and
//! appendix E): the weight a sample gets in a pixel, from the sample's offset to the pixel centre.
//!
//! The formulas are RISpec's where it gives one (box, triangle, catmull-rom, gaussian, sinc) and
//! PRMan's usual ones otherwise (blackman-harris, mitchell with B = C = 1/3, separable-catmull-rom,
//! disk). As in RISpec, catmull-rom, separable-catmull-rom and sinc are functions of the offset in
//! pixels (their lobes are 2 and 1 pixels wide): the widths only cut them off, so `4 4` shows the
//! whole of catmull-rom; the other filters stretch to fill their widths. The weight is zero outside
//! the support, `|dx| <= xwidth / 2`, `|dy| <= ywidth / 2`.
//!
//! The renderer's default is box 1x1, the plain average of each pixel's own samples (RenderMan's
//! is gaussian 2x2): images stay bit-identical to those made before filters existed, and one sample
//! per pixel stays as sharp as it can be. [`render_frame`](super::render_frame) takes its old path
//! for exactly that filter and splats samples through any other (`film.rs`).

use std::f32::consts::PI;

/// A filter's shape (the `name` of `PixelFilter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FilterKind {
    Box,
    Triangle,
    CatmullRom,
    Gaussian,
    Sinc,
    BlackmanHarris,
    Mitchell,
    SeparableCatmullRom,
    Disk,
}

impl FilterKind {
    /// Every kind, in the order of [`FilterKind::name`]'s list.
    pub const ALL: [FilterKind; 9] = [
        FilterKind::Box,
        FilterKind::Triangle,
        FilterKind::CatmullRom,
        FilterKind::Gaussian,
        FilterKind::Sinc,
        FilterKind::BlackmanHarris,
        FilterKind::Mitchell,
        FilterKind::SeparableCatmullRom,
        FilterKind::Disk,
    ];

    /// The RIB name.
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Box => "box",
            FilterKind::Triangle => "triangle",
            FilterKind::CatmullRom => "catmull-rom",
            FilterKind::Gaussian => "gaussian",
            FilterKind::Sinc => "sinc",
            FilterKind::BlackmanHarris => "blackman-harris",
            FilterKind::Mitchell => "mitchell",
            FilterKind::SeparableCatmullRom => "separable-catmull-rom",
            FilterKind::Disk => "disk",
        }
    }

    /// The kind named `name` (a RIB name), if there is one.
    pub fn parse(name: &str) -> Option<FilterKind> {
        FilterKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The names, comma separated (for messages).
    pub fn names() -> String {
        FilterKind::ALL.map(FilterKind::name).join(", ")
    }
}

/// A pixel filter: its shape and its total support in pixels along x and y (both finite and
/// positive; [`PixelFilter::new`] checks).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PixelFilter {
    kind: FilterKind,
    xwidth: f32,
    ywidth: f32,
}

impl Default for PixelFilter {
    /// Box 1x1: each pixel is the average of its own samples (see the module's notes).
    fn default() -> Self {
        PixelFilter { kind: FilterKind::Box, xwidth: 1.0, ywidth: 1.0 }
    }
}

impl PixelFilter {
    /// A filter of `kind`, `xwidth` by `ywidth` pixels; an error unless both widths are positive
    /// and at most [`PixelFilter::MAX_WIDTH`].
    pub fn new(kind: FilterKind, xwidth: f32, ywidth: f32) -> Result<PixelFilter, String> {
        let valid = |w: f32| w > 0.0 && w <= Self::MAX_WIDTH;
        if !(valid(xwidth) && valid(ywidth)) {
            return Err(format!(
                "filter widths {xwidth} {ywidth} are not both positive and at most {} pixels",
                Self::MAX_WIDTH
            ));
        }
        Ok(PixelFilter { kind, xwidth, ywidth })
    }

    /// The widest support accepted, in pixels. Each tile splats into its own buffer grown by the
    /// filter's reach, so a huge width would take memory in proportion to the tile count times the
    /// image; RenderMan's filters are a few pixels wide.
    pub const MAX_WIDTH: f32 = 16.0;

    /// The filter named `name` (RIB's names, see [`FilterKind::name`]), `xwidth` by `ywidth`.
    pub fn named(name: &str, xwidth: f32, ywidth: f32) -> Result<PixelFilter, String> {
        let kind = FilterKind::parse(name)
            .ok_or_else(|| format!("unknown pixel filter \"{name}\" (known: {})", FilterKind::names()))?;
        PixelFilter::new(kind, xwidth, ywidth)
    }

    pub fn kind(&self) -> FilterKind {
        self.kind
    }

    /// The support's total width and height in pixels.
    pub fn widths(&self) -> (f32, f32) {
        (self.xwidth, self.ywidth)
    }

    /// Half the support along x and y: a sample reaches the pixels whose centres are that close.
    pub fn radius(&self) -> (f32, f32) {
        (0.5 * self.xwidth, 0.5 * self.ywidth)
    }

    /// Whether this is the default box 1x1, which the frame renders as a plain per-pixel average.
    pub fn is_unit_box(&self) -> bool {
        *self == PixelFilter::default()
    }

    /// The weight of a sample `(dx, dy)` pixels from a pixel's centre (zero outside the support).
    pub fn weight(&self, dx: f32, dy: f32) -> f32 {
        let (rx, ry) = self.radius();
        if dx.abs() > rx || dy.abs() > ry {
            return 0.0;
        }
        let (w, h) = (self.xwidth, self.ywidth);
        match self.kind {
            FilterKind::Box => 1.0,
            FilterKind::Triangle => (1.0 - dx.abs() / rx) * (1.0 - dy.abs() / ry),
            // RISpec's radial Catmull-Rom is twice the one-dimensional cubic of the distance.
            FilterKind::CatmullRom => 2.0 * catmull_rom((dx * dx + dy * dy).sqrt()),
            FilterKind::Gaussian => {
                let (x, y) = (dx * 2.0 / w, dy * 2.0 / h);
                (-2.0 * (x * x + y * y)).exp()
            }
            FilterKind::Sinc => windowed_sinc(dx, w) * windowed_sinc(dy, h),
            FilterKind::BlackmanHarris => blackman_harris(dx / w) * blackman_harris(dy / h),
            // Mitchell's cubic spans [-2, 2]: the support is mapped onto it.
            FilterKind::Mitchell => mitchell(4.0 * dx / w) * mitchell(4.0 * dy / h),
            FilterKind::SeparableCatmullRom => catmull_rom(dx) * catmull_rom(dy),
            FilterKind::Disk => {
                if (dx / rx).powi(2) + (dy / ry).powi(2) <= 1.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// The one-dimensional Catmull-Rom cubic, `x` in pixels: 1 at 0, negative lobes between 1 and 2.
fn catmull_rom(x: f32) -> f32 {
    let x = x.abs();
    let x2 = x * x;
    if x >= 2.0 {
        0.0
    } else if x < 1.0 {
        1.5 * x * x2 - 2.5 * x2 + 1.0
    } else {
        -0.5 * x * x2 + 2.5 * x2 - 4.0 * x + 2.0
    }
}

/// RISpec's sinc along one axis, `x` in pixels, under its cosine window of the filter's `width`.
fn windowed_sinc(x: f32, width: f32) -> f32 {
    if x == 0.0 {
        return 1.0;
    }
    let px = PI * x;
    (0.5 * px / width).cos() * px.sin() / px
}

/// The four-term Blackman-Harris window centred on 0, `t` the offset as a fraction of the width
/// (it falls to zero at `t = ±1/2`).
fn blackman_harris(t: f32) -> f32 {
    const A: [f32; 4] = [0.35875, 0.48829, 0.14128, 0.01168];
    let a = 2.0 * PI * t;
    A[0] + A[1] * a.cos() + A[2] * (2.0 * a).cos() + A[3] * (3.0 * a).cos()
}

/// Mitchell and Netravali's cubic with B = C = 1/3, `x` in [-2, 2].
fn mitchell(x: f32) -> f32 {
    const B: f32 = 1.0 / 3.0;
    const C: f32 = 1.0 / 3.0;
    let x = x.abs();
    let (x2, x3) = (x * x, x * x * x);
    let v = if x >= 2.0 {
        0.0
    } else if x >= 1.0 {
        (-B - 6.0 * C) * x3 + (6.0 * B + 30.0 * C) * x2 + (-12.0 * B - 48.0 * C) * x + (8.0 * B + 24.0 * C)
    } else {
        (12.0 - 9.0 * B - 6.0 * C) * x3 + (-18.0 + 12.0 * B + 6.0 * C) * x2 + (6.0 - 2.0 * B)
    };
    v / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kind at its usual PRMan widths.
    fn filters() -> Vec<PixelFilter> {
        let width = |k: FilterKind| match k {
            FilterKind::Box => 1.0,
            FilterKind::Triangle | FilterKind::Gaussian => 2.0,
            FilterKind::BlackmanHarris | FilterKind::Disk => 3.0,
            _ => 4.0,
        };
        FilterKind::ALL.into_iter().map(|k| PixelFilter::new(k, width(k), width(k)).expect("valid widths")).collect()
    }

    /// Offsets across and beyond the support of `f`, on a grid that includes 0.
    fn offsets(f: &PixelFilter) -> Vec<(f32, f32)> {
        let (rx, ry) = f.radius();
        let steps = 24;
        let mut out = Vec::new();
        for i in -steps..=steps {
            for j in -steps..=steps {
                out.push((1.5 * rx * i as f32 / steps as f32, 1.5 * ry * j as f32 / steps as f32));
            }
        }
        out
    }

    #[test]
    fn every_name_parses_back_and_unknown_names_do_not() {
        for k in FilterKind::ALL {
            assert_eq!(FilterKind::parse(k.name()), Some(k));
        }
        assert_eq!(FilterKind::parse("Gaussian"), None, "RIB names are case sensitive");
        let err = PixelFilter::named("nonsense", 2.0, 2.0).expect_err("unknown");
        assert!(err.contains("nonsense") && err.contains("catmull-rom"), "{err}");
    }

    #[test]
    fn widths_must_be_finite_and_positive() {
        for (x, y) in [(0.0, 1.0), (1.0, -2.0), (f32::NAN, 1.0), (1.0, f32::INFINITY), (1e6, 2.0)] {
            assert!(PixelFilter::new(FilterKind::Box, x, y).is_err(), "{x} {y}");
        }
        assert!(PixelFilter::new(FilterKind::Box, 0.5, 3.0).is_ok());
        assert!(PixelFilter::new(FilterKind::Gaussian, PixelFilter::MAX_WIDTH, 1.0).is_ok());
    }

    #[test]
    fn the_default_is_the_unit_box_and_only_it_is() {
        assert!(PixelFilter::default().is_unit_box());
        assert_eq!(PixelFilter::default().weight(0.49, -0.49), 1.0);
        assert!(!PixelFilter::new(FilterKind::Box, 2.0, 1.0).expect("valid").is_unit_box());
        assert!(!PixelFilter::new(FilterKind::Gaussian, 1.0, 1.0).expect("valid").is_unit_box());
    }

    #[test]
    fn the_weight_is_largest_at_the_centre() {
        for f in filters() {
            let peak = f.weight(0.0, 0.0);
            assert!(peak > 0.0, "{f:?}");
            for (dx, dy) in offsets(&f) {
                assert!(f.weight(dx, dy) <= peak + 1e-6, "{f:?} at ({dx}, {dy})");
            }
        }
    }

    #[test]
    fn filters_are_symmetric() {
        for f in filters() {
            for (dx, dy) in offsets(&f) {
                let w = f.weight(dx, dy);
                for (x, y) in [(-dx, dy), (dx, -dy), (-dx, -dy)] {
                    assert!((f.weight(x, y) - w).abs() <= 1e-6, "{f:?} at ({dx}, {dy}) vs ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn the_weight_is_zero_outside_the_support() {
        for f in filters() {
            let (rx, ry) = f.radius();
            for (dx, dy) in offsets(&f).into_iter().filter(|(x, y)| x.abs() > rx || y.abs() > ry) {
                assert_eq!(f.weight(dx, dy), 0.0, "{f:?} at ({dx}, {dy})");
            }
        }
        // A non-square support: 1 pixel wide, 3 tall.
        let g = PixelFilter::new(FilterKind::Gaussian, 1.0, 3.0).expect("valid");
        assert_eq!(g.weight(0.6, 0.0), 0.0);
        assert!(g.weight(0.0, 1.4) > 0.0);
    }

    #[test]
    fn the_gaussian_is_rispecs() {
        // RISpec: x *= 2 / xwidth, y *= 2 / ywidth, exp(-2 (x^2 + y^2)).
        let f = PixelFilter::new(FilterKind::Gaussian, 2.0, 4.0).expect("valid");
        let (dx, dy) = (0.3f32, -1.1f32);
        let (x, y) = (dx * 2.0 / 2.0, dy * 2.0 / 4.0);
        let expected = (-2.0 * (x * x + y * y)).exp();
        assert!((f.weight(dx, dy) - expected).abs() < 1e-7, "{} vs {expected}", f.weight(dx, dy));
        assert!((f.weight(0.0, 0.0) - 1.0).abs() < 1e-7);
        // exp(-2) at the edge of the support, where RenderMan cuts it off.
        assert!((f.weight(1.0, 0.0) - (-2.0f32).exp()).abs() < 1e-6);
    }

    #[test]
    fn negative_lobes_where_the_kernels_have_them() {
        let at = |k: FilterKind, x: f32| PixelFilter::new(k, 4.0, 4.0).expect("valid").weight(x, 0.0);
        assert!(at(FilterKind::CatmullRom, 1.5) < 0.0);
        assert!(at(FilterKind::SeparableCatmullRom, 1.5) < 0.0);
        assert!(at(FilterKind::Sinc, 1.5) < 0.0);
        assert!(at(FilterKind::Mitchell, 1.5) < 0.0);
        // The interpolating kernels vanish at the next pixel centre.
        assert!(at(FilterKind::CatmullRom, 1.0).abs() < 1e-6);
        assert!(at(FilterKind::SeparableCatmullRom, 1.0).abs() < 1e-6);
        assert!(at(FilterKind::Sinc, 1.0).abs() < 1e-6);
        assert!(at(FilterKind::Gaussian, 1.5) > 0.0 && at(FilterKind::BlackmanHarris, 1.5) >= 0.0);
    }

    #[test]
    fn triangle_and_blackman_harris_fall_to_zero_at_the_edge() {
        let t = PixelFilter::new(FilterKind::Triangle, 2.0, 2.0).expect("valid");
        assert!((t.weight(0.5, 0.0) - 0.5).abs() < 1e-6);
        assert!(t.weight(1.0, 0.0).abs() < 1e-6);
        let b = PixelFilter::new(FilterKind::BlackmanHarris, 3.0, 3.0).expect("valid");
        assert!(b.weight(1.5, 0.0).abs() < 1e-3 * b.weight(0.0, 0.0));
    }

    #[test]
    fn the_disk_is_round() {
        let d = PixelFilter::new(FilterKind::Disk, 2.0, 2.0).expect("valid");
        assert_eq!(d.weight(0.6, 0.6), 1.0);
        assert_eq!(d.weight(0.75, 0.75), 0.0, "a corner of the square support");
    }
}

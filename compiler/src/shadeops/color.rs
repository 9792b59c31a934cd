//! Colour spaces (RISpec 3.2 section 15.3): `ctransform` and the space-cast `color "space" (a, b, c)`.
//!
//! The renderer's own colour space is linear RGB with the Rec. 709 / sRGB primaries and the D65 white
//! point; `"rgb"` is the identity. The other spaces, named case-insensitively:
//! - `"hsv"` (hue, saturation, value) and `"hsl"` (hue, saturation, lightness), with RenderMan's
//!   convention that hue is a fraction of a full turn in [0,1) (red 0, green 1/3, blue 2/3), not
//!   degrees. Converting *to* RGB wraps any hue into [0,1) (`1.25` is `0.25`; a non-finite hue is 0).
//!   Greys (and black) have hue 0 and saturation 0.
//! - `"xyz"` (or `"XYZ"`): CIE 1931 XYZ, the linear map fixed by the sRGB primaries' chromaticities
//!   (0.64, 0.33), (0.30, 0.60), (0.15, 0.06) and D65 (0.3127, 0.3290) with white `(1,1,1)` at `Y = 1`
//!   (the IEC 61966-2-1 matrix, derived in `f64` here so that white maps exactly onto D65).
//! - `"xyY"`: the chromaticity `x = X/(X+Y+Z)`, `y = Y/(X+Y+Z)` and the luminance `Y`.
//! - `"YIQ"`: NTSC's luma and chroma, `Y = 0.299 R + 0.587 G + 0.114 B`,
//!   `I = 0.5959 R - 0.2746 G - 0.3213 B`, `Q = 0.2115 R - 0.5227 G + 0.3112 B` (greys have `I = Q = 0`);
//!   the inverse is the exact inverse of that matrix.
//!
//! Unknown names give `None`; the caller (the checker for constant names, the interpreter otherwise)
//! decides what to report. The conversions are computed in `f64` and rounded to `f32` once; nothing
//! panics, and NaN components propagate except where a function documents otherwise.
//!
//! They are written here rather than taken from a colour crate (`palette`): RenderMan's hue as a
//! fraction of a turn, YIQ, and these rules for greys, NaN and rounding are RSL's, and the JIT
//! calls these same functions so that it and the interpreter agree bit for bit.

use super::V3;

/// A colour space `ctransform` and colour space-casts understand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    Rgb,
    Hsv,
    Hsl,
    Xyz,
    XyY,
    Yiq,
}

impl Space {
    /// The space a name selects (case-insensitive: `"rgb"`, `"hsv"`, `"hsl"`, `"xyz"`/`"XYZ"`,
    /// `"xyY"`, `"YIQ"`), or `None` for an unknown name.
    pub fn from_name(name: &str) -> Option<Space> {
        const NAMES: [(&str, Space); 6] = [
            ("rgb", Space::Rgb),
            ("hsv", Space::Hsv),
            ("hsl", Space::Hsl),
            ("xyz", Space::Xyz),
            ("xyy", Space::XyY),
            ("yiq", Space::Yiq),
        ];
        NAMES.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, s)| *s)
    }

    /// Converts a colour in this space to RGB.
    pub fn to_rgb(self, c: V3) -> V3 {
        let c = c.map(f64::from);
        let rgb = match self {
            Space::Rgb => c,
            Space::Hsv => {
                let chroma = c[2] * c[1];
                hue_to_rgb(c[0], chroma, c[2] - chroma)
            }
            Space::Hsl => {
                let chroma = (1.0 - (2.0 * c[2] - 1.0).abs()) * c[1];
                hue_to_rgb(c[0], chroma, c[2] - 0.5 * chroma)
            }
            Space::Xyz => apply(&XYZ_TO_RGB, c),
            Space::XyY => apply(&XYZ_TO_RGB, xyy_to_xyz(c)),
            Space::Yiq => apply(&YIQ_TO_RGB, c),
        };
        rgb.map(|x| x as f32)
    }

    /// Converts an RGB colour to this space.
    pub fn from_rgb(self, c: V3) -> V3 {
        let c = c.map(f64::from);
        let out = match self {
            Space::Rgb => c,
            Space::Hsv => {
                let (max, min) = max_min(c);
                let chroma = max - min;
                let s = if max != 0.0 { chroma / max } else { 0.0 };
                [rgb_hue(c, max, chroma), s, max]
            }
            Space::Hsl => {
                let (max, min) = max_min(c);
                let chroma = max - min;
                let l = 0.5 * (max + min);
                let denom = 1.0 - (2.0 * l - 1.0).abs();
                let s = if denom != 0.0 { chroma / denom } else { 0.0 };
                [rgb_hue(c, max, chroma), s, l]
            }
            Space::Xyz => apply(&RGB_TO_XYZ, c),
            Space::XyY => xyz_to_xyy(apply(&RGB_TO_XYZ, c)),
            Space::Yiq => apply(&RGB_TO_YIQ, c),
        };
        out.map(|x| x as f32)
    }
}

/// The colour `c`, given in the space named `space`, converted to RGB (RSL's space-cast
/// `color "space" (a, b, c)`). `None` for an unknown space name. See the module documentation for the
/// spaces; hue is a fraction of a turn and wraps into [0,1).
pub fn to_rgb(space: &str, c: V3) -> Option<V3> {
    Space::from_name(space).map(|s| s.to_rgb(c))
}

/// The RGB colour `c` converted to the space named `space` (RSL's one-space `ctransform(to, c)`).
/// `None` for an unknown space name. Hue comes back in [0,1); greys get hue 0 and saturation 0; a
/// colour whose largest component is 0 has HSV saturation 0, and one whose HSL denominator
/// `1 - |2L - 1|` is 0 has HSL saturation 0 (so those do not round-trip unless they are grey). All other
/// colours, including ones outside `[0, 1]`, round-trip through every space up to rounding. For `"xyY"`,
/// when `X + Y + Z` is 0 the chromaticity is D65's (0.3127, 0.3290).
pub fn from_rgb(space: &str, c: V3) -> Option<V3> {
    Space::from_name(space).map(|s| s.from_rgb(c))
}

/// RSL's `ctransform(from, to, c)`: `c`, given in the space `from`, converted to the space `to` (through
/// RGB). `None` when either name is unknown. When both names select the same space `c` is returned
/// unchanged (no hue wrapping).
pub fn ctransform(from: &str, to: &str, c: V3) -> Option<V3> {
    let (from, to) = (Space::from_name(from)?, Space::from_name(to)?);
    Some(if from == to { c } else { to.from_rgb(from.to_rgb(c)) })
}

type M3 = [[f64; 3]; 3];

fn apply(m: &M3, c: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * c[0] + m[0][1] * c[1] + m[0][2] * c[2],
        m[1][0] * c[0] + m[1][1] * c[1] + m[1][2] * c[2],
        m[2][0] * c[0] + m[2][1] * c[1] + m[2][2] * c[2],
    ]
}

const fn det3(m: &M3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// The inverse of a (known invertible) 3x3 matrix, by cofactors.
const fn inverse3(m: &M3) -> M3 {
    let d = det3(m);
    [
        [
            (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / d,
            (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / d,
            (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / d,
        ],
        [
            (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / d,
            (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / d,
            (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / d,
        ],
        [
            (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / d,
            (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / d,
            (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / d,
        ],
    ]
}

/// D65's chromaticity.
const WHITE_XY: [f64; 2] = [0.3127, 0.3290];

/// RGB to XYZ from the primaries' chromaticities and the white point: the columns are the primaries'
/// XYZ at `Y = 1`, scaled so that `(1,1,1)` maps to the white point at `Y = 1`.
const fn rgb_to_xyz_matrix() -> M3 {
    const PRIMARIES: [[f64; 2]; 3] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]];
    let mut p = [[0.0; 3]; 3];
    let mut k = 0;
    while k < 3 {
        let [x, y] = PRIMARIES[k];
        p[0][k] = x / y;
        p[1][k] = 1.0;
        p[2][k] = (1.0 - x - y) / y;
        k += 1;
    }
    let [wx, wy] = WHITE_XY;
    let w = [wx / wy, 1.0, (1.0 - wx - wy) / wy];
    let pi = inverse3(&p);
    let mut out = p;
    let mut c = 0;
    while c < 3 {
        let s = pi[c][0] * w[0] + pi[c][1] * w[1] + pi[c][2] * w[2];
        let mut r = 0;
        while r < 3 {
            out[r][c] = p[r][c] * s;
            r += 1;
        }
        c += 1;
    }
    out
}

const RGB_TO_XYZ: M3 = rgb_to_xyz_matrix();
const XYZ_TO_RGB: M3 = inverse3(&RGB_TO_XYZ);
const RGB_TO_YIQ: M3 = [[0.299, 0.587, 0.114], [0.5959, -0.2746, -0.3213], [0.2115, -0.5227, 0.3112]];
const YIQ_TO_RGB: M3 = inverse3(&RGB_TO_YIQ);

fn xyz_to_xyy(c: [f64; 3]) -> [f64; 3] {
    let sum = c[0] + c[1] + c[2];
    if sum == 0.0 {
        [WHITE_XY[0], WHITE_XY[1], c[1]]
    } else {
        [c[0] / sum, c[1] / sum, c[1]]
    }
}

/// xyY to XYZ; `y == 0` gives black (the chromaticity has no finite XYZ).
fn xyy_to_xyz(c: [f64; 3]) -> [f64; 3] {
    let [x, y, lum] = c;
    if y == 0.0 {
        [0.0; 3]
    } else {
        [x * lum / y, lum, (1.0 - x - y) * lum / y]
    }
}

/// The largest and smallest component (NaN components are skipped unless all are NaN).
fn max_min(c: [f64; 3]) -> (f64, f64) {
    (c[0].max(c[1]).max(c[2]), c[0].min(c[1]).min(c[2]))
}

/// The hue in [0,1) of an RGB colour given its largest component and its chroma (0 for greys).
fn rgb_hue(c: [f64; 3], max: f64, chroma: f64) -> f64 {
    if !(chroma.is_finite() && chroma > 0.0) {
        return 0.0;
    }
    let [r, g, b] = c;
    let h6 = if r == max {
        (g - b) / chroma
    } else if g == max {
        (b - r) / chroma + 2.0
    } else {
        (r - g) / chroma + 4.0
    };
    let h = h6 / 6.0;
    let h = h - h.floor();
    // Compared as the `f32` it becomes: a hue just below 1 rounds to 1, which is 0 on the circle.
    if h as f32 >= 1.0 || !h.is_finite() {
        0.0
    } else {
        h
    }
}

/// RGB from a hue (a fraction of a turn, wrapped into [0,1); non-finite is 0), a chroma and the amount
/// `m` added to every component (the smallest component).
fn hue_to_rgb(h: f64, chroma: f64, m: f64) -> [f64; 3] {
    let h = if h.is_finite() { h - h.floor() } else { 0.0 };
    let h6 = h * 6.0;
    // `h < 1` but `h * 6` can round up to 6.
    let sector = (h6.floor() as i32).clamp(0, 5);
    let x = chroma * (1.0 - ((h6 - 2.0 * (f64::from(sector) / 2.0).floor()) - 1.0).abs());
    let (r, g, b) = match sector {
        0 => (chroma, x, 0.0),
        1 => (x, chroma, 0.0),
        2 => (0.0, chroma, x),
        3 => (0.0, x, chroma),
        4 => (x, 0.0, chroma),
        _ => (chroma, 0.0, x),
    };
    [r + m, g + m, b + m]
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPACES: [&str; 6] = ["rgb", "hsv", "hsl", "xyz", "xyY", "YIQ"];

    /// A small deterministic generator (xorshift32) in [lo, hi).
    struct Rng(u32);
    impl Rng {
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            lo + (hi - lo) * ((self.0 >> 8) as f32 / (1u32 << 24) as f32)
        }
    }

    fn close(a: V3, b: V3, tol: f32) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    /// Hues compare on the circle.
    fn close_hue(a: V3, b: V3, tol: f32) -> bool {
        let dh = (a[0] - b[0]).abs();
        dh.min(1.0 - dh) <= tol && close([0.0, a[1], a[2]], [0.0, b[1], b[2]], tol)
    }

    #[test]
    fn names() {
        assert_eq!(Space::from_name("XYZ"), Some(Space::Xyz));
        assert_eq!(Space::from_name("xyz"), Some(Space::Xyz));
        assert_eq!(Space::from_name("xyY"), Some(Space::XyY));
        assert_eq!(Space::from_name("YIQ"), Some(Space::Yiq));
        assert_eq!(Space::from_name("HSV"), Some(Space::Hsv));
        assert_eq!(Space::from_name("cmyk"), None);
        assert_eq!(Space::from_name(""), None);
        assert_eq!(to_rgb("lab", [0.0; 3]), None);
        assert_eq!(from_rgb("lab", [0.0; 3]), None);
        assert_eq!(ctransform("rgb", "lab", [0.0; 3]), None);
        assert_eq!(ctransform("lab", "rgb", [0.0; 3]), None);
    }

    #[test]
    fn rgb_round_trips_through_every_space() {
        let mut rng = Rng(0xC0FFEE);
        for space in SPACES {
            for _ in 0..2000 {
                let c = [rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
                let there = from_rgb(space, c).unwrap();
                let back = to_rgb(space, there).unwrap();
                assert!(close(back, c, 1e-5), "{space}: {c:?} -> {there:?} -> {back:?}");
                assert!(close(ctransform(space, "rgb", there).unwrap(), c, 1e-5));
            }
        }
        // Out-of-range colours round-trip too (except the documented degenerate cases).
        for c in [[2.0, -0.5, 0.25], [-1.0, -2.0, -3.0], [5.0, 5.0, 4.0]] {
            for space in SPACES {
                let back = to_rgb(space, from_rgb(space, c).unwrap()).unwrap();
                assert!(close(back, c, 1e-5), "{space}: {c:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn each_space_round_trips_through_rgb() {
        let mut rng = Rng(17);
        for _ in 0..2000 {
            let hsv = [rng.range(0.0, 1.0), rng.range(0.05, 1.0), rng.range(0.05, 1.0)];
            let back = from_rgb("hsv", to_rgb("hsv", hsv).unwrap()).unwrap();
            assert!(close_hue(back, hsv, 1e-5), "{hsv:?} -> {back:?}");
            let hsl = [rng.range(0.0, 1.0), rng.range(0.05, 1.0), rng.range(0.05, 0.95)];
            let back = from_rgb("hsl", to_rgb("hsl", hsl).unwrap()).unwrap();
            assert!(close_hue(back, hsl, 1e-5), "{hsl:?} -> {back:?}");
            let xyz = [rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
            let back = from_rgb("XYZ", to_rgb("XYZ", xyz).unwrap()).unwrap();
            assert!(close(back, xyz, 1e-5), "{xyz:?} -> {back:?}");
            let xyy = [rng.range(0.1, 0.6), rng.range(0.1, 0.6), rng.range(0.01, 1.0)];
            let back = from_rgb("xyY", to_rgb("xyY", xyy).unwrap()).unwrap();
            assert!(close(back, xyy, 1e-5), "{xyy:?} -> {back:?}");
            let yiq = [rng.range(0.0, 1.0), rng.range(-0.5, 0.5), rng.range(-0.5, 0.5)];
            let back = from_rgb("YIQ", to_rgb("YIQ", yiq).unwrap()).unwrap();
            assert!(close(back, yiq, 1e-5), "{yiq:?} -> {back:?}");
            // Between two non-RGB spaces.
            let via = ctransform("hsv", "hsl", hsv).unwrap();
            assert!(close_hue(ctransform("hsl", "hsv", via).unwrap(), hsv, 1e-5));
        }
    }

    #[test]
    fn known_values() {
        assert_eq!(from_rgb("hsv", [1.0, 0.0, 0.0]), Some([0.0, 1.0, 1.0]));
        assert!(close(from_rgb("hsv", [0.0, 1.0, 0.0]).unwrap(), [1.0 / 3.0, 1.0, 1.0], 1e-7));
        assert!(close(from_rgb("hsv", [0.0, 0.0, 0.5]).unwrap(), [2.0 / 3.0, 1.0, 0.5], 1e-7));
        assert!(close(from_rgb("hsv", [1.0, 0.0, 1.0]).unwrap(), [5.0 / 6.0, 1.0, 1.0], 1e-7));
        assert_eq!(from_rgb("hsl", [1.0, 0.0, 0.0]), Some([0.0, 1.0, 0.5]));
        assert!(close(to_rgb("hsv", [1.0 / 6.0, 1.0, 1.0]).unwrap(), [1.0, 1.0, 0.0], 1e-6));
        assert!(close(to_rgb("hsl", [0.5, 1.0, 0.5]).unwrap(), [0.0, 1.0, 1.0], 1e-6));
        assert!(close(to_rgb("hsl", [0.0, 0.5, 0.25]).unwrap(), [0.375, 0.125, 0.125], 1e-6));
        // Greys: hue 0, saturation 0.
        for g in [0.0, 0.2, 1.0, 3.0] {
            let grey = [g, g, g];
            assert_eq!(from_rgb("hsv", grey), Some([0.0, 0.0, g]));
            assert_eq!(from_rgb("hsl", grey), Some([0.0, 0.0, g]));
            let yiq = from_rgb("YIQ", grey).unwrap();
            assert!((yiq[0] - g).abs() < 1e-6 && yiq[1].abs() < 1e-6 && yiq[2].abs() < 1e-6);
        }
        // White is D65 at Y = 1.
        let white = from_rgb("xyY", [1.0, 1.0, 1.0]).unwrap();
        assert!(close(white, [0.3127, 0.3290, 1.0], 1e-6), "{white:?}");
        let xyz = from_rgb("XYZ", [1.0, 1.0, 1.0]).unwrap();
        assert!(close(xyz, [0.95046, 1.0, 1.08906], 1e-4), "{xyz:?}");
        // The published sRGB matrix, to its four places.
        let red = from_rgb("xyz", [1.0, 0.0, 0.0]).unwrap();
        assert!(close(red, [0.4124, 0.2126, 0.0193], 1e-4), "{red:?}");
        // Each primary's chromaticity is its own.
        assert!(close(from_rgb("xyY", [0.0, 2.0, 0.0]).unwrap(), [0.30, 0.60, 2.0 * 0.7152], 1e-4));
        // Black: D65 chromaticity, and back to black.
        assert_eq!(from_rgb("xyY", [0.0; 3]), Some([0.3127, 0.3290, 0.0]));
        assert_eq!(to_rgb("xyY", [0.3, 0.0, 1.0]), Some([0.0; 3]));
        assert_eq!(to_rgb("xyY", [0.3127, 0.3290, 0.0]), Some([0.0; 3]));
    }

    #[test]
    fn hue_wraps() {
        let base = to_rgb("hsv", [0.25, 0.8, 0.6]).unwrap();
        for h in [1.25, -0.75, 5.25] {
            assert!(close(to_rgb("hsv", [h, 0.8, 0.6]).unwrap(), base, 1e-6), "{h}");
        }
        let base = to_rgb("hsl", [0.9, 0.8, 0.6]).unwrap();
        assert!(close(to_rgb("hsl", [-0.1, 0.8, 0.6]).unwrap(), base, 1e-6));
        // Hue 1 is hue 0; a hue just below 1 stays in the last sector.
        assert!(close(to_rgb("hsv", [1.0, 1.0, 1.0]).unwrap(), [1.0, 0.0, 0.0], 1e-6));
        let c = to_rgb("hsv", [0.99999994, 1.0, 1.0]).unwrap();
        assert!(close(c, [1.0, 0.0, 0.0], 1e-5), "{c:?}");
        // Non-finite hue is 0; hues from RGB are always in [0, 1).
        assert_eq!(to_rgb("hsv", [f32::INFINITY, 1.0, 1.0]), Some([1.0, 0.0, 0.0]));
        assert_eq!(to_rgb("hsv", [f32::NAN, 1.0, 1.0]), Some([1.0, 0.0, 0.0]));
        let h = from_rgb("hsv", [1.0, 0.0, 1e-8]).unwrap()[0];
        assert!((0.0..1.0).contains(&h), "{h}");
        assert_eq!(from_rgb("hsv", [f32::NAN, 0.5, 0.2]).unwrap()[0], 0.0);
    }

    #[test]
    fn same_space_is_identity() {
        let c = [1.5, 0.3, 0.2];
        assert_eq!(ctransform("hsv", "HSV", c), Some(c));
        assert_eq!(ctransform("rgb", "rgb", c), Some(c));
        let hsl = ctransform("rgb", "hsl", c).unwrap();
        assert_eq!(Some(hsl), from_rgb("hsl", c));
    }
}

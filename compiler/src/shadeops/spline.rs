//! The `spline` built-in (RISpec 3.2 section 15.1): a cubic spline through control values, for floats
//! and for triples (colours, points, vectors, normals, component-wise).
//!
//! Semantics, as RISpec 3.2 describes them and as OSL implements the same built-in:
//! - `x` is clamped to `[0, 1]` (NaN reads as 0).
//! - Every basis needs at least 4 knots. With `n` knots there are `nsegs = (n - 4) / step + 1`
//!   segments (integer division), where `step` is 1 for catmull-rom, b-spline, linear and constant, 3
//!   for bezier and 2 for hermite. Segment `i` covers `x` in `[i/nsegs, (i+1)/nsegs)` (the last one
//!   includes 1) and uses the four knots starting at `i * step`; knots beyond the last full segment are
//!   ignored (e.g. a bezier with 5 knots uses the first 4). RISpec asks for `3k+1` knots for bezier
//!   and `2k+2` for hermite; other counts are not an error here.
//! - catmull-rom (the default) interpolates the interior knots: `x = 0` gives the second knot and
//!   `x = 1` the next-to-last; the first and last knots only shape the ends.
//! - b-spline approximates (uniform cubic B-spline): it passes through no knot in general.
//! - bezier interpolates the first and last knot of each 4-knot group (`x = 0` gives the first knot,
//!   `x = 1` the last used knot); the middle two are control points.
//! - hermite reads the knots as `p0 t0 p1 t1 p2 t2 ...` (values and tangents alternately): `x = 0`
//!   gives `p0`, `x = 1` the last value, and each segment is the cubic Hermite curve from `p_i` with
//!   tangent `t_i` to `p_{i+1}` with tangent `t_{i+1}`.
//! - linear interpolates the interior knots piecewise linearly (segment `i` goes from knot `i+1` to
//!   knot `i+2`); RISpec: "the first and last knot are unused, but are nevertheless required".
//! - constant (an extension also in OSL) is a step function: segment `i` holds knot `i+1` (so the
//!   first knot and the last two are unused; with 4 knots it is always the second).
//!
//! Basis names are case-insensitive; `""` and any unknown name mean catmull-rom.

use super::V3;

/// A spline basis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Basis {
    CatmullRom,
    BSpline,
    Bezier,
    Hermite,
    Linear,
    Constant,
}

impl Basis {
    /// The basis a name selects, or `None` for an unknown name. Case-insensitive; `""` is catmull-rom,
    /// and both `"b-spline"` and RISpec's `"bspline"` are accepted.
    pub fn from_name(name: &str) -> Option<Basis> {
        const NAMES: [(&str, Basis); 7] = [
            ("", Basis::CatmullRom),
            ("catmull-rom", Basis::CatmullRom),
            ("bspline", Basis::BSpline),
            ("b-spline", Basis::BSpline),
            ("bezier", Basis::Bezier),
            ("hermite", Basis::Hermite),
            ("linear", Basis::Linear),
        ];
        if name.eq_ignore_ascii_case("constant") {
            return Some(Basis::Constant);
        }
        NAMES.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, b)| *b)
    }

    /// The basis a name selects, catmull-rom for unknown names (RSL's default basis).
    pub fn parse(name: &str) -> Basis {
        Basis::from_name(name).unwrap_or(Basis::CatmullRom)
    }

    /// How many knots one segment advances by.
    pub fn step(self) -> usize {
        match self {
            Basis::Bezier => 3,
            Basis::Hermite => 2,
            _ => 1,
        }
    }

    /// The basis matrix: the value of a segment at local `t` is
    /// `sum_k (((M[0][k] t + M[1][k]) t + M[2][k]) t + M[3][k]) * P[k]` over its four knots `P`.
    fn matrix(self) -> [[f32; 4]; 4] {
        match self {
            Basis::CatmullRom => {
                [[-0.5, 1.5, -1.5, 0.5], [1.0, -2.5, 2.0, -0.5], [-0.5, 0.0, 0.5, 0.0], [0.0, 1.0, 0.0, 0.0]]
            }
            Basis::BSpline => {
                const S: f32 = 1.0 / 6.0;
                [
                    [-S, 3.0 * S, -3.0 * S, S],
                    [3.0 * S, -6.0 * S, 3.0 * S, 0.0],
                    [-3.0 * S, 0.0, 3.0 * S, 0.0],
                    [S, 4.0 * S, S, 0.0],
                ]
            }
            Basis::Bezier => {
                [[-1.0, 3.0, -3.0, 1.0], [3.0, -6.0, 3.0, 0.0], [-3.0, 3.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
            }
            Basis::Hermite => {
                [[2.0, 1.0, -2.0, 1.0], [-3.0, -2.0, 3.0, -1.0], [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
            }
            Basis::Linear => [[0.0; 4], [0.0; 4], [0.0, -1.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
            Basis::Constant => [[0.0; 4], [0.0; 4], [0.0; 4], [0.0, 1.0, 0.0, 0.0]],
        }
    }

    /// Where `x` falls for `n` knots: the first knot of its segment and the four knot weights, or
    /// `None` when there are fewer than 4 knots.
    pub fn weights(self, x: f32, n: usize) -> Option<(usize, [f32; 4])> {
        if n < 4 {
            return None;
        }
        let nsegs = (n - 4) / self.step() + 1;
        let x = if x > 0.0 { x.min(1.0) } else { 0.0 };
        let xs = x * nsegs as f32;
        let seg = (xs as usize).min(nsegs - 1);
        if self == Basis::Constant {
            return Some((seg, [0.0, 1.0, 0.0, 0.0]));
        }
        let t = xs - seg as f32;
        let m = self.matrix();
        let w = std::array::from_fn(|k| ((m[0][k] * t + m[1][k]) * t + m[2][k]) * t + m[3][k]);
        Some((seg * self.step(), w))
    }
}

impl Basis {
    /// [`Basis::weights`] of four lanes' `x` (`None` for fewer than 4 knots): each lane's first knot
    /// and its four weights as rows (`w[k][l]`: knot `k` of lane `l`), by the same operations in
    /// each lane.
    pub fn weights4(self, x: [f32; 4], n: usize) -> Option<([usize; 4], [[f32; 4]; 4])> {
        use glam::Vec4;
        if n < 4 {
            return None;
        }
        let nsegs = (n - 4) / self.step() + 1;
        // Lanes with a segment count past what a float counts exactly: lane by lane.
        if nsegs > 1 << 24 {
            let each: [(usize, [f32; 4]); 4] = std::array::from_fn(|l| self.weights(x[l], n).unwrap_or_default());
            return Some((each.map(|e| e.0), std::array::from_fn(|k| std::array::from_fn(|l| each[l].1[k]))));
        }
        let x = Vec4::from_array(x);
        // `if x > 0 { x.min(1) } else { 0 }`: NaN reads as 0.
        let x = Vec4::select(x.cmpgt(Vec4::ZERO), x.min(Vec4::ONE), Vec4::ZERO);
        let xs = x * Vec4::splat(nsegs as f32);
        // `xs` lies in [0, nsegs]: its truncation is `xs as usize`.
        let seg = xs.as_ivec4().to_array().map(|s| (s as usize).min(nsegs - 1));
        if self == Basis::Constant {
            return Some((seg, [[0.0; 4], [1.0; 4], [0.0; 4], [0.0; 4]]));
        }
        let t = xs - Vec4::from_array(seg.map(|s| s as f32));
        let m = self.matrix();
        let w = std::array::from_fn(|k| {
            let c = |r: usize| Vec4::splat(m[r][k]);
            (((c(0) * t + c(1)) * t + c(2)) * t + c(3)).to_array()
        });
        Some((seg.map(|s| s * self.step()), w))
    }
}

/// RSL's `spline(basis, x, knots...)` for floats (the `spline(x, ...)` form passes `""`). See the
/// module documentation for the segment rules. Fewer than 4 knots: the first knot, or 0 for none.
/// Unknown basis names mean catmull-rom. NaN `x` reads as 0; NaN knots propagate.
pub fn spline(basis: &str, x: f32, knots: &[f32]) -> f32 {
    match Basis::parse(basis).weights(x, knots.len()) {
        Some((s, w)) => w[0] * knots[s] + w[1] * knots[s + 1] + w[2] * knots[s + 2] + w[3] * knots[s + 3],
        None => knots.first().copied().unwrap_or(0.0),
    }
}

/// [`spline`] for triples (colours, points, vectors, normals), component-wise, with the same rules:
/// fewer than 4 knots gives the first knot, or `(0,0,0)` for none.
pub fn spline3(basis: &str, x: f32, knots: &[V3]) -> V3 {
    match Basis::parse(basis).weights(x, knots.len()) {
        Some((s, w)) => std::array::from_fn(|c| {
            w[0] * knots[s][c] + w[1] * knots[s + 1][c] + w[2] * knots[s + 2][c] + w[3] * knots[s + 3][c]
        }),
        None => knots.first().copied().unwrap_or([0.0; 3]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four lanes at once give each lane's one-lane weights and segment, bit for bit.
    #[test]
    fn four_lane_weights_are_the_one_lane_ones() {
        let xs = [0.0, -0.0, 1.0, 0.999_999_94, 1e-8, -3.0, 7.0, 0.5, 0.25, 1.0 / 3.0, f32::NAN, f32::INFINITY];
        let mut h = 0x1234_5678u32;
        for basis in BASES.map(Basis::parse) {
            for n in [0, 3, 4, 5, 7, 8, 10, 13, 50, 1001] {
                for i in 0..400 {
                    let x: [f32; 4] = std::array::from_fn(|l| {
                        h ^= h << 13;
                        h ^= h >> 17;
                        h ^= h << 5;
                        if (i + l) % 2 == 0 {
                            xs[h as usize % xs.len()]
                        } else {
                            (h >> 8) as f32 / 16_777_216.0
                        }
                    });
                    let four = basis.weights4(x, n);
                    for l in 0..4 {
                        let one = basis.weights(x[l], n);
                        match (one, four) {
                            (None, None) => {}
                            (Some((s, w)), Some((segs, rows))) => {
                                assert_eq!(s, segs[l], "{basis:?} n {n} x {}", x[l]);
                                for k in 0..4 {
                                    assert_eq!(w[k].to_bits(), rows[k][l].to_bits(), "{basis:?} n {n} x {}", x[l]);
                                }
                            }
                            _ => panic!("{basis:?} n {n}: one lane {one:?}, four lanes {four:?}"),
                        }
                    }
                }
            }
        }
    }

    const BASES: [&str; 6] = ["catmull-rom", "bspline", "bezier", "hermite", "linear", "constant"];

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-5 * b.abs().max(1.0)
    }

    #[test]
    fn names() {
        assert_eq!(Basis::from_name("Catmull-Rom"), Some(Basis::CatmullRom));
        assert_eq!(Basis::from_name(""), Some(Basis::CatmullRom));
        assert_eq!(Basis::from_name("b-spline"), Some(Basis::BSpline));
        assert_eq!(Basis::from_name("BSPLINE"), Some(Basis::BSpline));
        assert_eq!(Basis::from_name("Bezier"), Some(Basis::Bezier));
        assert_eq!(Basis::from_name("HERMITE"), Some(Basis::Hermite));
        assert_eq!(Basis::from_name("Linear"), Some(Basis::Linear));
        assert_eq!(Basis::from_name("constant"), Some(Basis::Constant));
        assert_eq!(Basis::from_name("cubic"), None);
        assert_eq!(Basis::parse("cubic"), Basis::CatmullRom);
        let k = [0.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(spline("nonsense", 0.3, &k), spline("catmull-rom", 0.3, &k));
        assert_eq!(spline("", 0.3, &k), spline("catmull-rom", 0.3, &k));
    }

    #[test]
    fn catmull_rom_interpolates_interior_knots() {
        let k = [5.0, 1.0, 4.0, -2.0, 3.0, 7.0];
        // 6 knots: 3 segments; the interior knots 1..=4 are hit at x = 0, 1/3, 2/3, 1.
        for (i, want) in [1.0, 4.0, -2.0, 3.0].iter().enumerate() {
            assert!(close(spline("catmull-rom", i as f32 / 3.0, &k), *want), "knot {i}");
        }
        assert_eq!(spline("catmull-rom", 0.0, &k), 1.0);
        assert_eq!(spline("catmull-rom", 1.0, &k), 3.0);
        // The tangent at a knot is half the difference of its neighbours: a 4-knot line stays a line.
        let line = [-1.0, 0.0, 1.0, 2.0];
        for i in 0..=10 {
            let x = i as f32 / 10.0;
            assert!(close(spline("catmull-rom", x, &line), x));
        }
        // Midpoint of one segment: (-P0 + 9 P1 + 9 P2 - P3) / 16.
        assert!(close(spline("", 0.5, &[1.0, 2.0, 4.0, 8.0]), (-1.0 + 18.0 + 36.0 - 8.0) / 16.0));
    }

    #[test]
    fn linear_and_constant() {
        assert_eq!(spline("linear", 0.5, &[0.0, 0.0, 1.0, 1.0]), 0.5);
        assert_eq!(spline("linear", 0.25, &[9.0, 0.0, 1.0, 9.0]), 0.25);
        // 5 knots, 2 segments: 10 -> 20 -> 40, the outer knots unused.
        let k = [-100.0, 10.0, 20.0, 40.0, 100.0];
        assert_eq!(spline("linear", 0.0, &k), 10.0);
        assert_eq!(spline("linear", 0.25, &k), 15.0);
        assert_eq!(spline("linear", 0.5, &k), 20.0);
        assert_eq!(spline("linear", 0.75, &k), 30.0);
        assert_eq!(spline("linear", 1.0, &k), 40.0);
        assert_eq!(spline("constant", 0.0, &k), 10.0);
        assert_eq!(spline("constant", 0.49, &k), 10.0);
        assert_eq!(spline("constant", 0.5, &k), 20.0);
        assert_eq!(spline("constant", 1.0, &k), 20.0);
        assert_eq!(spline("constant", 0.7, &[1.0, 2.0, 3.0, 4.0]), 2.0);
    }

    #[test]
    fn bezier_endpoints_and_segments() {
        let k = [1.0, 5.0, -3.0, 2.0, 8.0, 0.0, 6.0];
        // 7 knots: 2 segments, interpolating knots 0, 3 and 6.
        assert_eq!(spline("bezier", 0.0, &k), 1.0);
        assert!(close(spline("bezier", 0.5, &k), 2.0));
        assert!(close(spline("bezier", 1.0, &k), 6.0));
        // Midpoint of a cubic Bezier: (P0 + 3 P1 + 3 P2 + P3) / 8.
        assert!(close(spline("bezier", 0.25, &k), (1.0 + 15.0 - 9.0 + 2.0) / 8.0));
        // 5 knots: one segment, the fifth knot ignored.
        assert!(close(spline("bezier", 1.0, &[1.0, 5.0, -3.0, 2.0, 100.0]), 2.0));
    }

    #[test]
    fn hermite_values_and_tangents() {
        // p0 = 1, t0 = 0, p1 = 3, t1 = 0, p2 = 2, t2 = 1: 2 segments.
        let k = [1.0, 0.0, 3.0, 0.0, 2.0, 1.0];
        assert_eq!(spline("hermite", 0.0, &k), 1.0);
        assert!(close(spline("hermite", 0.5, &k), 3.0));
        assert!(close(spline("hermite", 1.0, &k), 2.0));
        // Zero tangents: smoothstep between the values.
        assert!(close(spline("hermite", 0.25, &k), 2.0));
        // A line with matching tangents stays a line: p = 2t over one segment.
        let line = [0.0, 2.0, 2.0, 2.0];
        for i in 0..=8 {
            let x = i as f32 / 8.0;
            assert!(close(spline("hermite", x, &line), 2.0 * x));
        }
    }

    #[test]
    fn b_spline_reproduces_lines_and_averages() {
        // A uniform cubic B-spline through collinear knots is the line, shifted by one knot.
        let k = [0.0, 1.0, 2.0, 3.0, 4.0];
        assert!(close(spline("bspline", 0.0, &k), 1.0));
        assert!(close(spline("b-spline", 0.5, &k), 2.0));
        assert!(close(spline("bspline", 1.0, &k), 3.0));
        // At a segment start the value is (P0 + 4 P1 + P2) / 6.
        assert!(close(spline("bspline", 0.0, &[6.0, 0.0, 0.0, 0.0]), 1.0));
    }

    #[test]
    fn continuous_across_segment_boundaries() {
        let k: Vec<f32> = (0..13).map(|i| ((i * 7919) % 13) as f32 - 6.0).collect();
        for basis in BASES.iter().filter(|b| **b != "constant") {
            let nsegs = (k.len() - 4) / Basis::parse(basis).step() + 1;
            for i in 1..nsegs {
                let x = i as f32 / nsegs as f32;
                let (a, b) = (spline(basis, x - 1e-4, &k), spline(basis, x + 1e-4, &k));
                assert!((a - b).abs() < 0.05, "{basis} jumps at segment {i}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn x_is_clamped_and_short_lists_are_safe() {
        let k = [0.0, 1.0, 2.0, 5.0];
        for basis in BASES {
            assert_eq!(spline(basis, -3.0, &k), spline(basis, 0.0, &k), "{basis}");
            assert_eq!(spline(basis, 7.0, &k), spline(basis, 1.0, &k), "{basis}");
            assert_eq!(spline(basis, f32::NAN, &k), spline(basis, 0.0, &k), "{basis}");
            assert_eq!(spline(basis, f32::INFINITY, &k), spline(basis, 1.0, &k), "{basis}");
            assert_eq!(spline(basis, 0.5, &[]), 0.0);
            assert_eq!(spline(basis, 0.5, &[3.0]), 3.0);
            assert_eq!(spline(basis, 0.5, &[3.0, 4.0, 5.0]), 3.0);
            assert_eq!(spline3(basis, 0.5, &[]), [0.0; 3]);
            assert_eq!(spline3(basis, 0.5, &[[1.0, 2.0, 3.0]]), [1.0, 2.0, 3.0]);
        }
        // Long lists, every x: no index out of range.
        let long: Vec<f32> = (0..50).map(|i| i as f32).collect();
        for basis in BASES {
            for n in 0..long.len() {
                for i in 0..=64 {
                    let _ = spline(basis, i as f32 / 64.0, &long[..n]);
                }
            }
        }
    }

    #[test]
    fn spline3_is_component_wise() {
        let k3 = [[0.0, 1.0, 2.0], [1.0, 3.0, 0.0], [4.0, -1.0, 2.0], [2.0, 2.0, 2.0], [3.0, 0.0, 5.0]];
        for basis in BASES {
            for i in 0..=10 {
                let x = i as f32 / 10.0;
                let v = spline3(basis, x, &k3);
                for c in 0..3 {
                    let k: Vec<f32> = k3.iter().map(|p| p[c]).collect();
                    assert_eq!(v[c], spline(basis, x, &k), "{basis} {x} {c}");
                }
            }
        }
    }
}

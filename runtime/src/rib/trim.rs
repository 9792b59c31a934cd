//! Trim curves (RISpec 3.2 section 5.4, `TrimCurve`): loops of rational B-spline curves in the
//! `(u, v)` parameter space of the `NuPatch`es that follow, sampled into polygons that
//! `nurbs.rs` cuts the patches' tessellations with.
//!
//! Each curve has its own order (2 to [`MAX_NURBS_ORDER`]), knots, range and homogeneous control
//! points `(u w, v w, w)` (weights positive); the curves of a loop are joined in order and the
//! loop is closed. A point is inside when it is inside an odd number of loops (RISpec's odd
//! winding rule; which way a loop runs is not used), and [`TrimSense`] says which side is removed.
//!
//! Invariants: a curve is sampled at one segment per 2.8125 degrees its control polygon turns (128
//! a full turn), 8 to 64 a curved span, one a straight span (order 2), at most
//! [`MAX_TRIM_SEGMENTS`] for a whole `TrimCurve` (fewer a span past that); every loop kept has at
//! least 3 points. Malformed data is an `Err` with a message, never a panic.

use glam::{DVec2, DVec3};

use super::request::TrimCurve;
use super::spline::{segments_for_turn, turning, Knots, MAX_NURBS_ORDER};

/// The most line segments the loops of one `TrimCurve` are sampled into.
pub const MAX_TRIM_SEGMENTS: usize = 1 << 14;

/// Degrees a trim curve's control polygon may turn per segment (128 segments a full turn).
const TRIM_DEGREES_PER_SEGMENT: f64 = 360.0 / 128.0;

/// Segments a curved span of a trim curve is sampled into: at least this many, and at most 64.
const MIN_TRIM_SPAN_SEGMENTS: u32 = 8;

/// Which side of the trim loops is removed: `Attribute "trimcurve" "sense"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TrimSense {
    /// `"inside"` (the default): what lies inside an odd number of loops is removed.
    #[default]
    Inside,
    /// `"outside"`: what lies inside an odd number of loops is kept, the rest removed.
    Outside,
}

/// A `TrimCurve`'s loops, sampled to closed polygons in the `(u, v)` parameter space of the
/// patches they trim.
#[derive(Clone, Debug, PartialEq)]
pub struct Trim {
    /// Each loop's polygon (its last point joins its first), at least 3 points.
    loops: Vec<Vec<DVec2>>,
}

impl Trim {
    /// The loops' polygons.
    pub fn loops(&self) -> &[Vec<DVec2>] {
        &self.loops
    }

    /// Every edge of every loop.
    pub(super) fn segments(&self) -> Vec<(DVec2, DVec2)> {
        self.loops.iter().flat_map(|l| (0..l.len()).map(move |k| (l[k], l[(k + 1) % l.len()]))).collect()
    }

    /// Each loop's bounding box, lower and upper corners.
    pub(super) fn extents(&self) -> Vec<(DVec2, DVec2)> {
        self.loops
            .iter()
            .map(|l| l.iter().fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p))))
            .collect()
    }
}

/// One checked trim curve: knots, the range used, homogeneous control points `(u w, v w, w)`.
struct TrimSpline {
    knots: Knots,
    range: (f64, f64),
    points: Vec<DVec3>,
}

impl TrimSpline {
    /// The point at `t` on span `span`.
    fn at(&self, span: usize, t: f64) -> DVec2 {
        let (n, _) = self.knots.basis(span, t);
        let first = span - self.knots.degree();
        let h: DVec3 = (0..self.knots.order).map(|j| self.points[first + j] * n[j]).sum();
        DVec2::new(h.x / h.z, h.y / h.z)
    }

    /// Each span in the range with the segments it is sampled into.
    fn plan(&self) -> Vec<(usize, f64, f64, usize)> {
        let plane = |h: DVec3| DVec3::new(h.x / h.z, h.y / h.z, 0.0);
        self.knots
            .spans(self.range)
            .into_iter()
            .map(|(span, a, b)| {
                let segments = if self.knots.order == 2 {
                    1
                } else {
                    let first = span - self.knots.degree();
                    let turn = turning(self.points[first..=span].iter().map(|&h| plane(h)), 0.0);
                    segments_for_turn(turn, TRIM_DEGREES_PER_SEGMENT, MIN_TRIM_SPAN_SEGMENTS, 64)
                };
                (span, a, b, segments as usize)
            })
            .collect()
    }
}

/// The loops of a `TrimCurve`, sampled to polygons; `None` for one without loops (which removes
/// the trim).
pub fn trim_from_request(t: &TrimCurve) -> Result<Option<Trim>, String> {
    if t.ncurves.is_empty() {
        return Ok(None);
    }
    let ncurves: Vec<usize> = t
        .ncurves
        .iter()
        .map(|&n| usize::try_from(n).ok().filter(|&n| n >= 1))
        .collect::<Option<_>>()
        .ok_or("every loop needs at least one curve")?;
    let total = ncurves.iter().try_fold(0usize, |a, &n| a.checked_add(n)).ok_or("too many curves")?;
    let lengths =
        [("orders", t.order.len()), ("range starts", t.min.len()), ("range ends", t.max.len()), ("sizes", t.n.len())];
    for (what, len) in lengths {
        if len != total {
            return Err(format!("the loops have {total} curves in all, but {len} curve {what} are given"));
        }
    }
    let mut curves = Vec::with_capacity(total);
    let (mut knot_at, mut point_at) = (0usize, 0usize);
    for c in 0..total {
        let what = format!("trim curve {c}");
        let n = usize::try_from(t.n[c]).map_err(|_| format!("{what}: {} control points", t.n[c]))?;
        let order = usize::try_from(t.order[c])
            .ok()
            .filter(|k| (2..=MAX_NURBS_ORDER).contains(k))
            .ok_or_else(|| format!("{what}: order {} is not 2 to {MAX_NURBS_ORDER}", t.order[c]))?;
        let knot_end = knot_at.saturating_add(n).saturating_add(order);
        let knots = t.knot.get(knot_at..knot_end).ok_or_else(|| {
            format!("{what}: the curves up to it need {knot_end} knots, but {} are given", t.knot.len())
        })?;
        let knots = Knots::new(t.n[c], t.order[c], knots, &what)?;
        let range = knots.range(t.min[c], t.max[c], &what)?;
        let point_end = point_at.saturating_add(n);
        let mut points = Vec::with_capacity(n);
        for k in point_at..point_end {
            let (Some(&u), Some(&v), Some(&w)) = (t.u.get(k), t.v.get(k), t.w.get(k)) else {
                return Err(format!(
                    "{what}: the curves up to it have {point_end} control points, but u, v and w have {}, {} and {}",
                    t.u.len(),
                    t.v.len(),
                    t.w.len()
                ));
            };
            let h = DVec3::new(f64::from(u), f64::from(v), f64::from(w));
            if !h.is_finite() || h.z <= 0.0 {
                return Err(format!(
                    "{what}: control point {} is not finite or its weight is not positive",
                    k - point_at
                ));
            }
            points.push(h);
        }
        curves.push(TrimSpline { knots, range, points });
        (knot_at, point_at) = (knot_end, point_end);
    }
    if knot_at != t.knot.len() {
        return Err(format!("the curves take {knot_at} knots, but {} are given", t.knot.len()));
    }
    if [t.u.len(), t.v.len(), t.w.len()] != [point_at; 3] {
        return Err(format!(
            "the curves have {point_at} control points, but u, v and w have {}, {} and {}",
            t.u.len(),
            t.v.len(),
            t.w.len()
        ));
    }

    // Segments per span, scaled down if they would pass the limit.
    let mut plans: Vec<Vec<(usize, f64, f64, usize)>> = curves.iter().map(TrimSpline::plan).collect();
    let spans: usize = plans.iter().map(Vec::len).sum();
    if spans > MAX_TRIM_SEGMENTS {
        return Err(format!("the trim curves have {spans} spans; at most {MAX_TRIM_SEGMENTS} can be sampled"));
    }
    let wanted: usize = plans.iter().flatten().map(|s| s.3).sum();
    if wanted > MAX_TRIM_SEGMENTS {
        for s in plans.iter_mut().flatten() {
            s.3 = (s.3 * MAX_TRIM_SEGMENTS / wanted).max(1);
        }
    }

    // Each loop's curves one after the other, their joints not repeated.
    let mut loops = Vec::with_capacity(ncurves.len());
    let mut next = curves.iter().zip(&plans);
    for &count in &ncurves {
        let mut polygon: Vec<DVec2> = Vec::new();
        let mut push = |p: DVec2| {
            if polygon.last() != Some(&p) {
                polygon.push(p);
            }
        };
        for (curve, plan) in next.by_ref().take(count) {
            for &(span, a, b, segments) in plan {
                for k in 0..segments {
                    push(curve.at(span, a + (b - a) * k as f64 / segments as f64));
                }
            }
            if let Some(&(span, _, _, _)) = plan.last() {
                push(curve.at(span, curve.range.1));
            }
        }
        if polygon.len() > 1 && polygon.first() == polygon.last() {
            polygon.pop();
        }
        if polygon.len() >= 3 {
            loops.push(polygon);
        }
    }
    Ok(Some(Trim { loops }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::{parse_str, Request, RequestKind as K};

    fn request(text: &str) -> Request {
        let parse = parse_str(text, "t.rib");
        assert!(!parse.has_errors(), "{text}: {:?}", parse.diagnostics);
        parse.requests.into_iter().next().expect("a request")
    }

    fn numbers(values: impl IntoIterator<Item = f64>) -> String {
        values.into_iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(" ")
    }

    #[test]
    fn bad_trim_curves_are_errors() {
        let good = "[1] [2] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 1]";
        let K::TrimCurve(t) = request(&format!("TrimCurve {good}")).kind else { panic!() };
        assert!(
            trim_from_request(&t).expect("valid").is_some_and(|t| t.loops().is_empty()),
            "two points enclose nothing"
        );
        let K::TrimCurve(empty) = request("TrimCurve [] [] [] [] [] [] [] [] []").kind else { panic!() };
        assert_eq!(trim_from_request(&empty), Ok(None));
        for (text, expected) in [
            ("[0] [2] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 1]", "every loop needs at least one curve"),
            ("[1] [2 2] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 1]", "1 curves in all, but 2 curve orders"),
            ("[1] [2] [0 0 1 1] [0] [1 2] [2] [0 1] [0 0] [1 1]", "but 2 curve range ends"),
            ("[1] [2] [0 0 1] [0] [1] [2] [0 1] [0 0] [1 1]", "need 4 knots, but 3 are given"),
            ("[1] [2] [0 0 1 1 5] [0] [1] [2] [0 1] [0 0] [1 1]", "take 4 knots, but 5 are given"),
            ("[1] [2] [0 1 0 1] [0] [1] [2] [0 1] [0 0] [1 1]", "trim curve 0: the knots decrease"),
            ("[1] [20] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 1]", "order 20 is not 2 to 16"),
            ("[1] [2] [0 0 1 1] [1] [0] [2] [0 1] [0 0] [1 1]", "the parameter range 1 to 0 is empty"),
            ("[1] [2] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 0]", "control point 1 is not finite or its weight"),
            ("[1] [2] [0 0 1 1] [0] [1] [2] [0 1 2] [0 0] [1 1]", "u, v and w have 3, 2 and 2"),
            ("[1] [2] [0 0 1 1] [0] [1] [2] [0] [0 0] [1 1]", "u, v and w have 1, 2 and 2"),
            ("[1] [2] [0 0 1 1] [0] [1] [-2] [0 1] [0 0] [1 1]", "-2 control points"),
        ] {
            let K::TrimCurve(t) = request(&format!("TrimCurve {text}")).kind else { panic!() };
            match trim_from_request(&t) {
                Err(e) => assert!(e.contains(expected), "{text}: {e}"),
                Ok(trim) => panic!("{text}: {trim:?}"),
            }
        }
        // More spans than can be sampled.
        let n = MAX_TRIM_SEGMENTS + 2;
        let knots: Vec<String> = (0..n + 2).map(|k| k.to_string()).collect();
        let coordinates = numbers((0..n).map(|k| k as f64));
        let text = format!(
            "TrimCurve [1] [2] [{}] [1] [{}] [{n}] [{coordinates}] [{coordinates}] [{}]",
            knots.join(" "),
            n,
            numbers((0..n).map(|_| 1.0))
        );
        let K::TrimCurve(t) = request(&text).kind else { panic!() };
        let e = trim_from_request(&t).expect_err("too many spans");
        assert!(e.contains(&format!("at most {MAX_TRIM_SEGMENTS} can be sampled")), "{e}");
    }
}

//! B-spline knot vectors and basis functions, for NURBS patches (`nurbs.rs`) and their trim curves
//! (`trim.rs`): the Cox-de Boor recurrence as The NURBS Book's algorithms A2.2 and A2.3 give it,
//! in `f64`.
//!
//! Invariants: a [`Knots`] has an order from 2 to [`MAX_NURBS_ORDER`], at least as many control
//! points as its order, `n + order` finite, non-decreasing knots, and a non-empty range from knot
//! `order - 1` to knot `n`; checking a knot vector never panics.

use glam::DVec3;

/// The highest order (degree + 1) of a `NuPatch` direction or of a trim curve.
pub const MAX_NURBS_ORDER: usize = 16;

/// `x / y`, or 0 where `y` is 0 (a repeated knot).
pub(super) fn ratio(x: f64, y: f64) -> f64 {
    if y != 0.0 {
        x / y
    } else {
        0.0
    }
}

/// The basis functions that do not vanish on a span, or their derivatives.
pub(super) type Basis = [f64; MAX_NURBS_ORDER];

/// A checked knot vector.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Knots {
    /// Control points.
    pub(super) n: usize,
    /// Order (degree + 1), 2 to [`MAX_NURBS_ORDER`].
    pub(super) order: usize,
    /// `n + order` non-decreasing knots.
    pub(super) knots: Vec<f64>,
}

impl Knots {
    pub(super) fn new(n: i32, order: i32, knots: &[f32], what: &str) -> Result<Knots, String> {
        let order = usize::try_from(order)
            .ok()
            .filter(|k| (2..=MAX_NURBS_ORDER).contains(k))
            .ok_or_else(|| format!("{what}: order {order} is not 2 to {MAX_NURBS_ORDER}"))?;
        let n = usize::try_from(n)
            .ok()
            .filter(|&n| n >= order)
            .ok_or_else(|| format!("{what}: {n} control points, fewer than the order ({order})"))?;
        let needed = n.saturating_add(order);
        if knots.len() != needed {
            return Err(format!(
                "{what}: {} knots given, where {n} control points of order {order} need {needed}",
                knots.len()
            ));
        }
        if let Some(k) = knots.iter().position(|k| !k.is_finite()) {
            return Err(format!("{what}: knot {k} is not finite"));
        }
        if let Some(k) = knots.windows(2).position(|w| w[1] < w[0]) {
            return Err(format!("{what}: the knots decrease (knot {} is {} after {})", k + 1, knots[k + 1], knots[k]));
        }
        let knots: Vec<f64> = knots.iter().map(|&k| f64::from(k)).collect();
        if knots[order - 1] >= knots[n] {
            return Err(format!("{what}: knots {} to {n} are all {}, so the spline is empty", order - 1, knots[n]));
        }
        Ok(Knots { n, order, knots })
    }

    pub(super) fn degree(&self) -> usize {
        self.order - 1
    }

    /// `[min, max]` checked against where the spline is defined (a range past it by rounding is
    /// cut to it).
    pub(super) fn range(&self, min: f32, max: f32, what: &str) -> Result<(f64, f64), String> {
        let (lo, hi) = (self.knots[self.degree()], self.knots[self.n]);
        let slack = 1e-5 * (hi - lo).max(lo.abs()).max(hi.abs());
        let (min, max) = (f64::from(min), f64::from(max));
        if min.is_nan() || max.is_nan() || min >= max {
            return Err(format!("{what}: the parameter range {min} to {max} is empty"));
        }
        if !(min >= lo - slack && max <= hi + slack) {
            return Err(format!("{what}: the parameter range {min} to {max} is not within the knots' {lo} to {hi}"));
        }
        Ok((min.max(lo), max.min(hi)))
    }

    /// The spans (between distinct knots) that meet `[min, max]`: the index `i` of each
    /// (`knots[i] < knots[i + 1]`) and the part of it in the range.
    pub(super) fn spans(&self, (min, max): (f64, f64)) -> Vec<(usize, f64, f64)> {
        (self.degree()..self.n)
            .filter_map(|i| {
                let (a, b) = (self.knots[i].max(min), self.knots[i + 1].min(max));
                (a < b).then_some((i, a, b))
            })
            .collect()
    }

    /// The span `t` lies in (the first or last one when `t` is outside the spline's range).
    pub(super) fn span_of(&self, t: f64) -> usize {
        let p = self.degree();
        let below = self.knots[p..self.n].partition_point(|&k| k <= t);
        let mut i = (p + below.saturating_sub(1)).clamp(p, self.n - 1);
        while i > p && self.knots[i] >= self.knots[i + 1] {
            i -= 1;
        }
        while i + 1 < self.n && self.knots[i] >= self.knots[i + 1] {
            i += 1;
        }
        i
    }

    /// The basis functions that do not vanish on span `i` at `t` (`N[i - p + j]` at `j`, for `j`
    /// from 0 to the degree `p`), and their derivatives (from the degree `p - 1` functions).
    pub(super) fn basis(&self, i: usize, t: f64) -> (Basis, Basis) {
        let p = self.degree();
        let k = &self.knots;
        let mut n = [0.0; MAX_NURBS_ORDER];
        let mut lower = [0.0; MAX_NURBS_ORDER];
        let mut left = [0.0; MAX_NURBS_ORDER];
        let mut right = [0.0; MAX_NURBS_ORDER];
        n[0] = 1.0;
        for d in 1..=p {
            left[d] = t - k[i + 1 - d];
            right[d] = k[i + d] - t;
            if d == p {
                lower = n;
            }
            let mut saved = 0.0;
            for r in 0..d {
                let term = ratio(n[r], right[r + 1] + left[d - r]);
                n[r] = saved + right[r + 1] * term;
                saved = left[d - r] * term;
            }
            n[d] = saved;
        }
        let mut dn = [0.0; MAX_NURBS_ORDER];
        for j in 0..=p {
            let rising = if j > 0 { ratio(lower[j - 1], k[i + j] - k[i + j - p]) } else { 0.0 };
            let falling = if j < p { ratio(lower[j], k[i + j + 1] - k[i + j + 1 - p]) } else { 0.0 };
            dn[j] = p as f64 * (rising - falling);
        }
        (n, dn)
    }
}

/// How much a polyline turns, in degrees (legs no longer than `tiny` are skipped).
pub(super) fn turning(points: impl Iterator<Item = DVec3>, tiny: f64) -> f64 {
    let (mut last, mut leg, mut total) = (None::<DVec3>, None::<DVec3>, 0.0);
    for p in points {
        if let Some(q) = last {
            let next = p - q;
            if next.length() > tiny {
                if let Some(previous) = leg {
                    total += previous.cross(next).length().atan2(previous.dot(next)).to_degrees();
                }
                leg = Some(next);
            }
        }
        last = Some(p);
    }
    total
}

/// Segments for a turn of `degrees` at `per_segment` each: at least `min`, at most `max`.
pub(super) fn segments_for_turn(degrees: f64, per_segment: f64, min: u32, max: u32) -> u32 {
    let n = (degrees / per_segment).ceil();
    if n.is_finite() {
        (n.min(f64::from(max)) as u32).max(min)
    } else {
        min
    }
}

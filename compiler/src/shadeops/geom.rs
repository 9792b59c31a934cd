//! Geometric and scalar-shaping built-ins (RISpec 3.2 sections 15.1 and 15.2): `faceforward`,
//! `reflect`, `refract`, `fresnel`, `ptlined`, `rotate` (of a point), `length`, `normalize`,
//! `distance`, the `.` and `^` operators, and `step`, `smoothstep`, `filterstep`, `mix`, `clamp`, `mod`,
//! `sign` for one float (triples apply these per component).
//!
//! Directions follow RenderMan's conventions: `I` points from the eye towards the surface, `N` is the
//! surface normal, and the functions that take both assume (but do not require) unit vectors, as RSL
//! does. Nothing panics: degenerate inputs (zero vectors, equal points, zero widths) have the
//! documented results, and NaN arguments propagate into a NaN result unless a function says otherwise.

use super::{matrix, V3};

/// The dot product (RSL's `.` operator).
pub fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The cross product (RSL's `^` operator).
pub fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn mul(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// RSL's `length(v)`: the Euclidean length `sqrt(v . v)`.
pub fn length(v: V3) -> f32 {
    dot(v, v).sqrt()
}

/// RSL's `normalize(v)`: `v / length(v)`. A vector of length 0 (including one so short that its
/// squared length underflows to 0) is returned unchanged, so the zero vector stays zero. A vector with
/// an infinite component gives zero or NaN components, as the division does.
pub fn normalize(v: V3) -> V3 {
    let len = length(v);
    if len == 0.0 {
        v
    } else {
        mul(v, 1.0 / len)
    }
}

/// RSL's `distance(p1, p2)`: `length(p1 - p2)`.
pub fn distance(a: V3, b: V3) -> f32 {
    length(sub(a, b))
}

/// RSL's `faceforward(N, I, Nref)`: `N` flipped if needed so that it faces against `I`, judged by
/// `Nref`. RISpec writes it as `sign(-I . Nref) * N`; here `-N` is returned when `I . Nref > 0` and
/// `N` otherwise, so a zero (or NaN) `I . Nref` keeps `N` where a literal `sign` would give the zero
/// vector (OSL does the same). RSL's two-argument `faceforward(N, I)` is this with `Nref = Ng`: the
/// interpreter passes the geometric normal.
pub fn faceforward(n: V3, i: V3, nref: V3) -> V3 {
    if dot(i, nref) > 0.0 {
        [-n[0], -n[1], -n[2]]
    } else {
        n
    }
}

/// RSL's `reflect(I, N)`: `I - 2 (I . N) N`, the mirror direction of `I` about a unit normal `N`. `N`
/// is not normalised (RISpec's definition); either orientation of `N` gives the same result.
pub fn reflect(i: V3, n: V3) -> V3 {
    sub(i, mul(n, 2.0 * dot(i, n)))
}

/// RSL's `refract(I, N, eta)`, RISpec's formula: with `c = I . N` and `k = 1 - eta^2 (1 - c^2)`, the
/// result is `eta I - (eta c + sqrt(k)) N`, or the zero vector when `k < 0` (total internal
/// reflection) or `k` is NaN. `I` and `N` should be unit vectors with `N` facing against `I`
/// (`I . N <= 0`); `eta` is the ratio of the index of refraction on `I`'s side to the one on the far
/// side (so `1 / 1.5` entering glass from air). At normal incidence the direction is unchanged.
pub fn refract(i: V3, n: V3, eta: f32) -> V3 {
    let c = dot(i, n);
    let k = 1.0 - eta * eta * (1.0 - c * c);
    if k >= 0.0 {
        sub(mul(i, eta), mul(n, eta * c + k.sqrt()))
    } else {
        [0.0; 3]
    }
}

/// RSL's `fresnel(I, N, eta, Kr, Kt [, R, T])`, returned as `(Kr, Kt, R, T)`.
///
/// `eta` is the ratio of the index of refraction on the incident side to the one on the far side
/// (RISpec). `I` and `N` are normalised here, and `N` is flipped when it faces the same way as `I`
/// (as `faceforward` would), so the coefficients depend only on the angle between the two lines.
/// `Kr` is the unpolarised Fresnel reflectance for a dielectric, the mean of the s- and p-polarised
/// reflectances `rs = (eta cos_i - cos_t) / (eta cos_i + cos_t)` and
/// `rp = (cos_i - eta cos_t) / (cos_i + eta cos_t)` squared, with `cos_t` from Snell's law; `Kt` is
/// `1 - Kr` (energy is conserved; no absorption). `R` is `reflect(I, N)` and `T` is
/// `refract(I, N, eta)`, both of the normalised vectors, so both are unit length.
///
/// Edge cases: total internal reflection gives `Kr = 1, Kt = 0, T = 0`; grazing incidence (including
/// a zero `I` or `N`) gives `Kr = 1`; an `eta` that is not positive and finite gives `Kr = 1, Kt = 0,
/// T = 0`; NaN directions give `Kr = 1, Kt = 0`, a NaN `R` and a zero `T`.
pub fn fresnel(i: V3, n: V3, eta: f32) -> (f32, f32, V3, V3) {
    let i = normalize(i);
    let mut n = normalize(n);
    let mut cos_i = -dot(i, n);
    if cos_i < 0.0 {
        n = [-n[0], -n[1], -n[2]];
        cos_i = -cos_i;
    }
    let r = reflect(i, n);
    if !(eta.is_finite() && eta > 0.0) {
        return (1.0, 0.0, r, [0.0; 3]);
    }
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t.is_nan() || sin2_t >= 1.0 {
        return (1.0, 0.0, r, [0.0; 3]);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let kr = 0.5 * (rs * rs + rp * rp);
    let kr = if kr.is_nan() { 1.0 } else { kr.clamp(0.0, 1.0) };
    (kr, 1.0 - kr, r, refract(i, n, eta))
}

/// RSL's `ptlined(P, A, B)`: the distance from `P` to the closest point of the segment from `A` to
/// `B`. A degenerate segment (`A == B`) gives the distance from `P` to `A`.
pub fn ptlined(p: V3, a: V3, b: V3) -> f32 {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    if len2.is_nan() || len2 <= 0.0 {
        return distance(p, a);
    }
    let t = clamp(dot(sub(p, a), ab) / len2, 0.0, 1.0);
    distance(p, add(a, mul(ab, t)))
}

/// RSL's `rotate(Q, angle, P1, P2)`: `Q` rotated by `angle` radians about the axis through `P1` and
/// `P2`, in the sense of [`matrix::rotation`] about the direction `P2 - P1` (a positive angle about +z
/// takes +x towards +y). When `P1 == P2` (or the axis is not finite) `Q` is returned unchanged.
pub fn rotate_point(q: V3, angle: f32, p1: V3, p2: V3) -> V3 {
    let axis = sub(p2, p1);
    let len = length(axis);
    if !(len.is_finite() && len > 0.0) {
        return q;
    }
    let m = matrix::rotation(angle, axis);
    add(p1, matrix::transform_vector(&m, sub(q, p1)))
}

/// RSL's `step(min, value)`: 0 if `value < min`, else 1. NaN in either argument gives 1 (the
/// comparison is false).
pub fn step(edge: f32, x: f32) -> f32 {
    if x < edge {
        0.0
    } else {
        1.0
    }
}

/// RSL's `smoothstep(min, max, value)`: 0 if `value < min`, 1 if `value >= max`, and in between the
/// Hermite curve `t^2 (3 - 2t)` with `t = (value - min) / (max - min)`. The tests run in that order,
/// so `min >= max` is a step at `min` (0 below it, 1 from it on) and never divides by zero. A NaN
/// argument gives NaN unless one of the two comparisons has already decided (`smoothstep(0, NaN, -1)`
/// is 0).
pub fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if x < a {
        0.0
    } else if x >= b {
        1.0
    } else {
        let t = (x - a) / (b - a);
        t * t * (3.0 - 2.0 * t)
    }
}

/// RSL's `filterstep(edge, value)`, with the filter width given: `step(edge, value)` box-filtered
/// over `[value - width/2, value + width/2]`, i.e. the fraction of that interval at or above `edge`:
/// `clamp((value - edge) / width + 0.5, 0, 1)` (written so that `value == edge` gives exactly 0.5). A width that is not positive (or is NaN) gives the
/// plain [`step`]; an infinite width gives 0.5. RSL's one-value form takes the width from the
/// derivatives of `value`, times its `"width"` parameter (the caller computes it); only the box
/// filter is implemented (RISpec's `"filter"` names others, which implementations may ignore).
pub fn filterstep(edge: f32, x: f32, width: f32) -> f32 {
    if width.is_nan() || width <= 0.0 {
        return step(edge, x);
    }
    if width.is_infinite() {
        return 0.5;
    }
    clamp((x - edge) / width + 0.5, 0.0, 1.0)
}

/// RSL's two-value `filterstep(edge, s1, s2)`: `step(edge, s)` box-filtered over the interval between
/// `s1` and `s2` (in either order), i.e. the fraction of it at or above `edge`, the interval first
/// widened about its middle by `scale` (the `"width"` parameter; RISpec: the amount to overfilter).
/// An empty interval (`s1 == s2`, or NaN) gives `step(edge, s1)`; an infinite one is treated like
/// [`filterstep`] with an infinite width (0.5).
pub fn filterstep_interval(edge: f32, s1: f32, s2: f32, scale: f32) -> f32 {
    let (mut lo, mut hi) = if s1 <= s2 { (s1, s2) } else { (s2, s1) };
    if scale != 1.0 {
        let (middle, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5 * scale);
        (lo, hi) = (middle - half, middle + half);
    }
    let width = hi - lo;
    if width.is_nan() || width <= 0.0 {
        return step(edge, s1);
    }
    if width.is_infinite() {
        return 0.5;
    }
    clamp((hi - edge) / width, 0.0, 1.0)
}

/// RSL's `mix(x, y, a)`: `x (1 - a) + y a` (so `a = 0` gives `x` and `a = 1` gives `y` exactly for
/// finite values). `a` is not clamped.
pub fn mix(x: f32, y: f32, a: f32) -> f32 {
    x * (1.0 - a) + y * a
}

/// RSL's `clamp(x, lo, hi)`: `lo` where `x` is below `lo`, `hi` where it is above `hi`, else `x`
/// (RISpec's words), and `lo` for a NaN `x` (clamp scrubs NaN). Where `lo > hi`, a value below `lo`
/// gives `lo` and any other `hi`: a ray march that steps by `clamp(step, smallest, end - d)` then
/// moves on past its end instead of stepping by 0 for ever. Evaluated as `y = x > lo ? x : lo;
/// y < hi ? y : (x >= lo ? hi : lo)`, which the JIT and the derivatives follow comparison for
/// comparison.
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    let y = if x > lo { x } else { lo };
    if y < hi {
        y
    } else if x >= lo {
        hi
    } else {
        lo
    }
}

/// RSL's `mod(a, b)`: `a - b * floor(a / b)`, which has the sign of `b` (unlike C's `fmod`). `b == 0`
/// gives 0 (as OSL's `mod` does) rather than NaN. Evaluated exactly as written, so rounding can give
/// `b` itself for a tiny negative `a` (`mod(-1e-9, 1) == 1`). An infinite `a` or `b` gives NaN.
pub fn mod_(a: f32, b: f32) -> f32 {
    if b == 0.0 {
        0.0
    } else {
        a - b * (a / b).floor()
    }
}

/// RSL's `sign(x)`: -1 for negative `x`, 1 for positive, 0 for zero (either sign) and for NaN.
pub fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Whether a light from direction `l` is within 90 degrees of `n` (the `illuminance(P, N, PI/2)`
/// of RISpec's `diffuse`, `specular` and `phong`): the cosine of the angle is not negative. (Both
/// back ends use this one test; comparing `acos` of the cosine with PI/2 costs a libm call per light
/// and differs only for cosines within an ulp of 0.)
pub fn in_hemisphere(l: V3, n: V3) -> bool {
    dot(normalize(l), normalize(n)) >= 0.0
}

/// Whether `incident()` (or, with `opposite`, `opposite()`) asks about the volume inside the
/// surface: a ray arriving through the back of the geometric normal `ng` (along `i`) comes from
/// inside, so its incident volume is the interior and the opposite one the exterior. Both back
/// ends use this one test.
pub fn asks_interior(i: V3, ng: V3, opposite: bool) -> bool {
    (dot(i, ng) > 0.0) != opposite
}

/// How far apart (in s and t) `bump` samples its height map to difference it.
pub const BUMP_STEP: f32 = 1.0 / 1024.0;

/// `bump(name, N, dPds, dPdt)`: the normal of the surface displaced by the height map along the
/// unit normal (Blinn's bump mapping), from the heights at (s, t), (s + step, t) and (s, t + step):
/// `N + h_s (n x dPdt) + h_t (dPds x n)`, with `n` the unit `N` and `h_s`, `h_t` the forward
/// differences over [`BUMP_STEP`]. Not normalised (like `calculatenormal`).
pub fn bump(n: V3, dpds: V3, dpdt: V3, h: f32, h_s: f32, h_t: f32) -> V3 {
    let unit = normalize(n);
    let (hs, ht) = ((h_s - h) / BUMP_STEP, (h_t - h) / BUMP_STEP);
    let a = cross(unit, dpdt);
    let b = cross(dpds, unit);
    [n[0] + hs * a[0] + ht * b[0], n[1] + hs * a[1] + ht * b[1], n[2] + hs * a[2] + ht * b[2]]
}

/// The exponent of the specular highlight of `roughness`: `1 / (roughness / 8)`, as PRMan, BMRT
/// and Aqsis compute it (RISpec 3.2's printed `specular` has `1 / roughness`, but the renderers'
/// `plastic` highlights are those of `8 / roughness`; Aqsis notes it emulates BMRT's
/// `prmanspecular`). A roughness at or below zero is taken as 1e-4 (a very sharp highlight).
pub fn specular_exponent(roughness: f32) -> f32 {
    8.0 / if roughness > 0.0 { roughness } else { 1e-4 }
}

/// RenderMan's specular weight of one light (`specularbrdf`): [`specular_weight`] of the inputs
/// normalised.
pub fn specular_brdf(l: V3, n: V3, v: V3, roughness: f32) -> f32 {
    specular_weight(normalize(l), normalize(n), normalize(v), roughness)
}

/// The per-light term of `specular` for unit `l`, `n` and `v`: `pow(max(0, N . H),
/// specular_exponent(roughness))` with the half vector `H = normalize(L + V)`. (Both back ends
/// compute it with these operations: at the exponents of sharp highlights, normalising a unit
/// vector again would move the result by more than they may differ.)
pub fn specular_weight(l: V3, n: V3, v: V3, roughness: f32) -> f32 {
    let h = normalize([l[0] + v[0], l[1] + v[1], l[2] + v[2]]);
    super::transcendental::pow(dot(n, h).max(0.0), specular_exponent(roughness))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: V3, b: V3, tol: f32) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    /// A small deterministic generator (xorshift32) of unit vectors.
    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            (self.0 >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        }
        fn unit(&mut self) -> V3 {
            loop {
                let v = [self.next(), self.next(), self.next()];
                let l = length(v);
                if l > 0.1 && l <= 1.0 {
                    return normalize(v);
                }
            }
        }
    }

    #[test]
    fn vectors() {
        assert_eq!(length([3.0, 4.0, 0.0]), 5.0);
        assert_eq!(normalize([0.0, 0.0, 0.0]), [0.0, 0.0, 0.0]);
        assert_eq!(normalize([0.0, 0.0, -2.0]), [0.0, 0.0, -1.0]);
        assert_eq!(normalize([1e-30, 0.0, 0.0]), [1e-30, 0.0, 0.0]);
        assert_eq!(distance([1.0, 1.0, 1.0], [1.0, 4.0, 5.0]), 5.0);
        assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(dot([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]), 32.0);
    }

    #[test]
    fn faceforward_flips_against_i() {
        let n = [0.0, 0.0, 1.0];
        assert_eq!(faceforward(n, [0.0, 0.0, -1.0], n), n);
        assert_eq!(faceforward(n, [0.0, 0.0, 1.0], n), [0.0, 0.0, -1.0]);
        assert_eq!(faceforward(n, [1.0, 0.0, 0.0], n), n);
        assert_eq!(faceforward(n, [f32::NAN; 3], n), n);
        // Nref decides, not N.
        assert_eq!(faceforward(n, [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]), n);
    }

    #[test]
    fn reflect_is_an_involution() {
        let mut rng = Rng(42);
        for _ in 0..200 {
            let (i, n) = (rng.unit(), rng.unit());
            let r = reflect(i, n);
            assert!(close(reflect(r, n), i, 1e-5));
            assert!((length(r) - 1.0).abs() < 1e-5);
            // The angle to the normal is preserved, the normal component flips.
            assert!((dot(r, n) + dot(i, n)).abs() < 1e-5);
        }
        assert_eq!(reflect([1.0, -1.0, 0.0], [0.0, 1.0, 0.0]), [1.0, 1.0, 0.0]);
    }

    #[test]
    fn refract_follows_snell() {
        let n = [0.0, 0.0, 1.0];
        let i = [0.0, 0.0, -1.0];
        assert!(close(refract(i, n, 1.0 / 1.5), i, 1e-6));
        assert!(close(refract(i, n, 1.5), i, 1e-6));
        let mut rng = Rng(5);
        for _ in 0..200 {
            let mut i = rng.unit();
            if dot(i, n) > 0.0 {
                i[2] = -i[2];
            }
            let eta = 1.0 / 1.5;
            let t = refract(i, n, eta);
            // Unit length, same side as I, and sin_t = eta sin_i.
            assert!((length(t) - 1.0).abs() < 1e-5);
            assert!(dot(t, n) <= 0.0);
            let (sin_i, sin_t) = (length(cross(i, n)), length(cross(t, n)));
            assert!((sin_t - eta * sin_i).abs() < 1e-5);
        }
        // Total internal reflection: glass to air beyond the critical angle.
        let grazing = normalize([1.0, 0.0, -0.2]);
        assert_eq!(refract(grazing, n, 1.5), [0.0; 3]);
        assert_eq!(refract(grazing, n, f32::NAN), [0.0; 3]);
    }

    #[test]
    fn fresnel_coefficients() {
        let n = [0.0, 0.0, 1.0];
        let i = [0.0, 0.0, -1.0];
        for eta in [1.5, 1.0 / 1.5] {
            let (kr, kt, r, t) = fresnel(i, n, eta);
            assert!((kr - 0.04).abs() < 1e-6, "{kr}");
            assert_eq!(kr + kt, 1.0);
            assert!(close(r, [0.0, 0.0, 1.0], 1e-6));
            assert!(close(t, i, 1e-6));
        }
        // Same answer with N facing the other way, and for unnormalised inputs.
        let a = fresnel(normalize([1.0, 0.0, -1.0]), n, 0.8);
        let b = fresnel([3.0, 0.0, -3.0], [0.0, 0.0, -2.0], 0.8);
        assert!((a.0 - b.0).abs() < 1e-6 && close(a.2, b.2, 1e-6) && close(a.3, b.3, 1e-6));
        // Monotonic in angle from normal incidence to grazing, where Kr -> 1.
        let mut last = 0.0;
        for k in 0..=20 {
            let th = k as f32 / 20.0 * std::f32::consts::FRAC_PI_2 * 0.999;
            let (kr, kt, _, _) = fresnel([th.sin(), 0.0, -th.cos()], n, 1.0 / 1.5);
            assert!(kr >= last - 1e-6 && (kr + kt - 1.0).abs() < 1e-6);
            last = kr;
        }
        assert!(last > 0.9);
        // Brewster's angle: rp vanishes, so Kr = rs^2 / 2.
        let th = (1.5f32).atan();
        let (kr, _, _, _) = fresnel([th.sin(), 0.0, -th.cos()], n, 1.0 / 1.5);
        let ct = (1.0 - (th.sin() / 1.5).powi(2)).sqrt();
        let rs = (th.cos() / 1.5 - ct) / (th.cos() / 1.5 + ct);
        assert!((kr - 0.5 * rs * rs).abs() < 1e-5);
        // Total internal reflection.
        let (kr, kt, _, t) = fresnel(normalize([1.0, 0.0, -0.2]), n, 1.5);
        assert_eq!((kr, kt, t), (1.0, 0.0, [0.0; 3]));
        // Degenerate inputs.
        assert_eq!(fresnel([0.0; 3], n, 1.5).0, 1.0);
        assert_eq!(fresnel(i, [0.0; 3], 0.5).0, 1.0);
        assert_eq!(fresnel(i, n, 0.0).0, 1.0);
        assert_eq!(fresnel(i, n, f32::NAN).1, 0.0);
        let (kr, kt, _, t) = fresnel([f32::NAN; 3], n, 1.5);
        assert_eq!((kr, kt, t), (1.0, 0.0, [0.0; 3]));
    }

    #[test]
    fn ptlined_and_rotate_point() {
        let (a, b) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        assert_eq!(ptlined([1.0, 3.0, 0.0], a, b), 3.0);
        assert_eq!(ptlined([-3.0, 4.0, 0.0], a, b), 5.0);
        assert_eq!(ptlined([5.0, 4.0, 0.0], a, b), 5.0);
        assert_eq!(ptlined([3.0, 4.0, 0.0], a, a), 5.0);
        let q = rotate_point([2.0, 1.0, 5.0], std::f32::consts::FRAC_PI_2, [1.0, 1.0, 0.0], [1.0, 1.0, 3.0]);
        assert!(close(q, [1.0, 2.0, 5.0], 1e-6), "{q:?}");
        assert_eq!(rotate_point([2.0, 1.0, 5.0], 1.0, [1.0; 3], [1.0; 3]), [2.0, 1.0, 5.0]);
    }

    #[test]
    fn steps() {
        assert_eq!(step(0.5, 0.4), 0.0);
        assert_eq!(step(0.5, 0.5), 1.0);
        assert_eq!(smoothstep(0.0, 1.0, -1.0), 0.0);
        assert_eq!(smoothstep(0.0, 1.0, 0.5), 0.5);
        assert_eq!(smoothstep(0.0, 1.0, 1.0), 1.0);
        assert!((smoothstep(2.0, 4.0, 2.5) - 0.15625).abs() < 1e-7);
        assert_eq!(smoothstep(1.0, 1.0, 0.9), 0.0);
        assert_eq!(smoothstep(1.0, 1.0, 1.0), 1.0);
        assert_eq!(smoothstep(2.0, 1.0, 1.5), 0.0);
        assert_eq!(smoothstep(2.0, 1.0, 2.0), 1.0);
        assert!(smoothstep(0.0, 1.0, f32::NAN).is_nan());
        assert_eq!(filterstep(0.5, 0.5, 0.2), 0.5);
        assert!((filterstep(0.5, 0.45, 0.2) - 0.25).abs() < 1e-6);
        assert_eq!(filterstep(0.5, 0.0, 0.2), 0.0);
        assert_eq!(filterstep(0.5, 1.0, 0.2), 1.0);
        assert_eq!(filterstep(0.5, 0.4, 0.0), 0.0);
        assert_eq!(filterstep(0.5, 0.6, -1.0), 1.0);
        assert_eq!(filterstep(0.5, 0.6, f32::NAN), 1.0);
        assert_eq!(filterstep(0.5, 0.6, f32::INFINITY), 0.5);
        // Tends to step as the width goes to 0.
        for x in [0.3f32, 0.49, 0.499, 0.51, 0.7] {
            let mut w = 1.0;
            let mut v = 0.0;
            while w > 1e-6 {
                v = filterstep(0.5, x, w);
                w *= 0.5;
            }
            assert_eq!(v, step(0.5, x), "{x}");
        }
        assert!((filterstep_interval(0.5, 0.4, 0.6, 1.0) - 0.5).abs() < 1e-6);
        assert!((filterstep_interval(0.5, 0.6, 0.4, 1.0) - 0.5).abs() < 1e-6);
        assert!((filterstep_interval(0.5, 0.4, 0.8, 1.0) - 0.75).abs() < 1e-6);
        assert_eq!(filterstep_interval(0.5, 0.0, 1.0, 1.0), 0.5);
        assert_eq!(filterstep_interval(0.25, 0.0, 1.0, 1.0), 0.75);
        assert_eq!(filterstep_interval(0.5, 0.45, 0.45, 1.0), 0.0);
        assert_eq!(filterstep_interval(0.5, f32::NEG_INFINITY, f32::INFINITY, 1.0), 0.5);
        // Widened twice about its middle: [0.2, 1.0], of which 0.5 to 1.0 is past the edge.
        assert!((filterstep_interval(0.5, 0.4, 0.8, 2.0) - 0.625).abs() < 1e-6);
    }

    #[test]
    fn mix_clamp_mod_sign() {
        assert_eq!(mix(2.0, 4.0, 0.0), 2.0);
        assert_eq!(mix(2.0, 4.0, 1.0), 4.0);
        assert_eq!(mix(2.0, 4.0, 0.25), 2.5);
        assert_eq!(mix(2.0, 4.0, 2.0), 6.0);
        assert_eq!(clamp(5.0, 0.0, 1.0), 1.0);
        assert_eq!(clamp(-5.0, 0.0, 1.0), 0.0);
        assert_eq!(clamp(0.5, 0.0, 1.0), 0.5);
        assert_eq!(clamp(f32::NAN, 0.0, 1.0), 0.0);
        assert_eq!(clamp(0.5, 1.0, 0.0), 1.0, "below lo (lo > hi): lo");
        assert_eq!(clamp(1.5, 1.0, 0.0), 0.0, "not below lo (lo > hi): hi");
        assert_eq!(clamp(1.0, 1.0, 0.0), 0.0, "at lo (lo > hi): hi");
        assert_eq!(clamp(f32::NAN, 1.0, 0.0), 1.0, "NaN: lo");
        assert_eq!(clamp(-1.0, 0.5, 0.5), 0.5);
        assert_eq!(clamp(2.0, 0.5, 0.5), 0.5);
        assert_eq!(mod_(5.5, 2.0), 1.5);
        assert_eq!(mod_(-0.5, 2.0), 1.5);
        assert_eq!(mod_(0.5, -2.0), -1.5);
        assert_eq!(mod_(3.0, 0.0), 0.0);
        assert!(mod_(f32::INFINITY, 2.0).is_nan());
        assert_eq!(sign(-3.0), -1.0);
        assert_eq!(sign(3.0), 1.0);
        assert_eq!(sign(0.0), 0.0);
        assert_eq!(sign(-0.0), 0.0);
        assert_eq!(sign(f32::NAN), 0.0);
    }
}

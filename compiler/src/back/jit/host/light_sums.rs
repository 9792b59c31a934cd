//! `ambient()`, `diffuse()` and `specular()` over a chunk's four lanes at once: the lights come
//! as rows ([`LightLanes`]), and each light's direction is normalised, tested against the
//! hemisphere and weighed for all lanes together in `Vec4`s, instead of lane by lane.
//!
//! Bit for bit the scalar `sum_lights` (and so the interpreter's): every lane computes the same
//! IEEE operations in the same order (`sqrtps` and `divps` are exactly rounded like their scalar
//! forms, and `max(x, 0)` gives 0 for a NaN `x` as `f32::max` does); a light a lane does not have
//! (past its count, ambient, facing away, or an inactive lane) leaves its sum alone.
//!
//! Written with explicit `Vec4`s: the same code over `[f32; 4]` arrays came out as scalar
//! square roots and store-forwarding stalls, slower than a plain lane-by-lane loop.

use super::{LightLanes, CONE_ROWS, MAX_LIGHTS};
use crate::shadeops::transcendental;
#[cfg(test)]
use crate::shadeops::V3;
use glam::{BVec4A, Vec4};

/// Four lanes of a triple, as rows x, y, z.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Lanes3(pub [Vec4; 3]);

impl Lanes3 {
    /// Rows `k..k + 3` of a helper's SoA arguments (`input[4 * row + lane]`).
    pub(super) fn of_rows(input: &[f32], k: usize) -> Lanes3 {
        let row = |r: usize| input.get(4 * r..4 * r + 4).map_or(Vec4::ZERO, Vec4::from_slice);
        Lanes3([row(k), row(k + 1), row(k + 2)])
    }

    #[cfg(test)]
    pub(super) fn lane(&self, l: usize) -> V3 {
        [self.0[0][l], self.0[1][l], self.0[2][l]]
    }

    #[inline(always)]
    fn dot(&self, o: &Lanes3) -> Vec4 {
        let (a, b) = (&self.0, &o.0);
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    /// `geom::normalize` in each lane: unchanged where the length is 0, else times `1 / length`.
    #[inline(always)]
    pub(super) fn normalized(&self) -> Lanes3 {
        let len = self.dot(self).sqrt();
        let (zero, inv) = (len.cmpeq(Vec4::ZERO), Vec4::ONE / len);
        Lanes3(self.0.map(|row| Vec4::select(zero, row, row * inv)))
    }

    #[inline(always)]
    fn add(&self, o: &Lanes3) -> Lanes3 {
        Lanes3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

/// The `i`-th light of each lane (whatever the buffer holds where a lane has none) and the lanes
/// that have one that is not ambient.
struct LightRow {
    l: Lanes3,
    cl: Lanes3,
    nondiffuse: Vec4,
    nonspecular: Vec4,
    has: BVec4A,
}

/// Rows of a light: loaded as they lie.
#[inline(always)]
fn rows3(rows: &[[f32; 4]; 3]) -> Lanes3 {
    Lanes3(rows.map(Vec4::from_array))
}

/// Which lanes ask (`mask`) and how many lights each has (`counts`), for the tests of each light
/// row in vector lanes.
struct Asking {
    /// Each asking lane's count (at most [`MAX_LIGHTS`], so exact as a float); 0 elsewhere.
    counts: Vec4,
    /// The most lights any asking lane has.
    most: usize,
}

impl Asking {
    #[inline(always)]
    fn of(counts: [u32; 4], mask: [bool; 4]) -> Asking {
        // Clamped as floats: a count past MAX_LIGHTS converts to a float past it too.
        let counts = Vec4::from_array(counts.map(|c| c as f32)).min(Vec4::splat(MAX_LIGHTS as f32));
        let counts = Vec4::select(BVec4A::from_array(mask), counts, Vec4::ZERO);
        Asking { counts, most: counts.max_element() as usize }
    }

    /// The lanes that are asking and have an `i`-th light (`i` below [`MAX_LIGHTS`]).
    #[inline(always)]
    fn with(&self, i: usize) -> BVec4A {
        self.counts.cmpgt(Vec4::splat(i as f32))
    }
}

/// The lanes whose light in `lights` is ambient.
#[inline(always)]
fn ambient_lanes(lights: &LightLanes) -> BVec4A {
    // A nonzero integer converts to a nonzero float (in one instruction for the four lanes).
    Vec4::from_array(lights.ambient.map(|a| a as i32 as f32)).cmpne(Vec4::ZERO)
}

impl LightRow {
    #[inline(always)]
    fn of(lights: &LightLanes, asking: &Asking, i: usize) -> LightRow {
        LightRow {
            l: rows3(&lights.l),
            cl: rows3(&lights.cl),
            nondiffuse: Vec4::from_array(lights.nondiffuse),
            nonspecular: Vec4::from_array(lights.nonspecular),
            has: asking.with(i) & !ambient_lanes(lights),
        }
    }
}

/// `ambient()` of four lanes: the sum of each lane's ambient lights' colours, in order.
pub(super) fn ambient(buffer: &[LightLanes], counts: [u32; 4], mask: [bool; 4]) -> Lanes3 {
    let mut sum = Lanes3::default();
    let asking = Asking::of(counts, mask);
    for (i, lights) in buffer.iter().take(asking.most).enumerate() {
        let counted = asking.with(i) & ambient_lanes(lights);
        for (s, cl) in sum.0.iter_mut().zip(&lights.cl) {
            *s = Vec4::select(counted, *s + Vec4::from_array(*cl), *s);
        }
    }
    sum
}

/// [`light_in_cone`](super::light_in_cone) of four lanes: lane `j` is `light_in_cone(l_j, axis_j, cos_j)`, by the same
/// operations in each lane.
#[inline(always)]
fn in_cone(l: &Lanes3, axis: &Lanes3, cos: Vec4) -> BVec4A {
    let every = cos.cmple(Vec4::splat(-1.0));
    let c = cos - Vec4::splat(1e-3);
    let (la, lengths) = (l.dot(axis), l.dot(l) * axis.dot(axis));
    let unsure = la.is_nan_mask() | c.is_nan_mask() | !lengths.is_finite_mask();
    let (zero, c_nonpositive, c_negative) = (lengths.cmpeq(Vec4::ZERO), c.cmple(Vec4::ZERO), c.cmplt(Vec4::ZERO));
    let (la2, bound) = (la * la, c * c * lengths);
    let front = la.cmpge(Vec4::ZERO);
    let facing = (front & (c_nonpositive | la2.cmpge(bound))) | (!front & c_negative & la2.cmple(bound));
    let decided = (zero & c_nonpositive) | (!zero & facing);
    every | unsure | decided
}

/// Whether any lane's pending light (bit `k` of `pending[l]`: lane `l`'s light `k` in `buffer`)
/// lies within the lane's cone (`cone` as `HostTable::lights` takes it: axis rows, then the
/// cosines), as [`light_in_cone`](super::light_in_cone) decides: four lanes per light at once.
pub(super) fn pending_in_cone(buffer: &[LightLanes], pending: [u32; 4], cone: &[f32; 4 * CONE_ROWS]) -> bool {
    let row = |r: usize| Vec4::from_slice(&cone[4 * r..4 * r + 4]);
    let (axis, cos) = (Lanes3([row(0), row(1), row(2)]), row(3));
    let mut lights = pending[0] | pending[1] | pending[2] | pending[3];
    while lights != 0 {
        let k = lights.trailing_zeros() as usize;
        lights &= lights - 1;
        let Some(light) = buffer.get(k) else { continue };
        let lanes = BVec4A::new(
            pending[0] >> k & 1 != 0,
            pending[1] >> k & 1 != 0,
            pending[2] >> k & 1 != 0,
            pending[3] >> k & 1 != 0,
        );
        if (lanes & in_cone(&rows3(&light.l), &axis, cos)).any() {
            return true;
        }
    }
    false
}

/// The lights of each lane that face `n` (its normalised normal, normalised once more for the
/// hemisphere test as `sum_lights` does), summed with `weight(light, unit L, counted)`.
#[inline(always)]
fn sum_lights(
    buffer: &[LightLanes],
    counts: [u32; 4],
    mask: [bool; 4],
    n: &Lanes3,
    mut weight: impl FnMut(&LightRow, &Lanes3, BVec4A) -> Vec4,
) -> Lanes3 {
    let mut sum = Lanes3::default();
    let unit_n = n.normalized();
    let asking = Asking::of(counts, mask);
    for (i, lights) in buffer.iter().take(asking.most).enumerate() {
        let row = LightRow::of(lights, &asking, i);
        // Most often an ambient light, in every lane's list (and the same row of each).
        if !row.has.any() {
            continue;
        }
        let unit_l = row.l.normalized();
        let counted = row.has & unit_l.dot(&unit_n).cmpge(Vec4::ZERO);
        if !counted.any() {
            continue;
        }
        let w = weight(&row, &unit_l, counted);
        for (s, cl) in sum.0.iter_mut().zip(&row.cl.0) {
            *s = Vec4::select(counted, *s + *cl * w, *s);
        }
    }
    sum
}

/// `diffuse(N)` of four lanes: `n` is each lane's normalised `N`.
pub(super) fn diffuse(buffer: &[LightLanes], counts: [u32; 4], mask: [bool; 4], n: &Lanes3) -> Lanes3 {
    sum_lights(buffer, counts, mask, n, |row, unit_l, _| unit_l.dot(n).max(Vec4::ZERO) * (Vec4::ONE - row.nondiffuse))
}

/// `specular(N, V, roughness)` of four lanes: `n` and `view` normalised.
pub(super) fn specular(
    buffer: &[LightLanes],
    counts: [u32; 4],
    mask: [bool; 4],
    n: &Lanes3,
    view: &Lanes3,
    roughness: Vec4,
) -> Lanes3 {
    // `geom::specular_exponent` of each lane.
    let exponent = Vec4::splat(8.0) / Vec4::select(roughness.cmpgt(Vec4::ZERO), roughness, Vec4::splat(1e-4));
    sum_lights(buffer, counts, mask, n, |row, unit_l, counted| {
        let h = unit_l.add(view).normalized();
        highlight(n.dot(&h).max(Vec4::ZERO), exponent, counted, row.nonspecular)
    })
}

/// `pow(base, exponent) * (1 - nonspecular)` in the lanes `counted`, 0 in the others.
#[inline(always)]
fn highlight(base: Vec4, exponent: Vec4, counted: BVec4A, nonspecular: Vec4) -> Vec4 {
    // `base` is a `max(_, 0)`: positive, or +0 (never -0 or NaN), and `pow(+0, y)` is +0 for
    // every positive `y`, so those lanes (a light behind the highlight's lobe) need no power. The
    // lanes that need none ask for `1^1`, which `pow4` answers on its fast path.
    let zero = base.cmpeq(Vec4::ZERO) & exponent.cmpgt(Vec4::ZERO);
    let wanted = counted & !zero;
    if !wanted.any() {
        return Vec4::ZERO * (Vec4::ONE - nonspecular);
    }
    let (base, exponent) = (Vec4::select(wanted, base, Vec4::ONE), Vec4::select(wanted, exponent, Vec4::ONE));
    let powers = Vec4::from_array(transcendental::pow4(base.to_array(), exponent.to_array()));
    Vec4::select(wanted, powers, Vec4::ZERO) * (Vec4::ONE - nonspecular)
}

/// `phong(N, V, size)` of four lanes: `n` and `view` normalised; each light weighs
/// `pow(max(R . L, 0), size)`, `R` the reflection of `-view` about `n` (`geom::reflect`'s
/// operations).
pub(super) fn phong(
    buffer: &[LightLanes],
    counts: [u32; 4],
    mask: [bool; 4],
    n: &Lanes3,
    view: &Lanes3,
    size: Vec4,
) -> Lanes3 {
    let incident = Lanes3(view.0.map(|row| -row));
    let twice = Vec4::splat(2.0) * incident.dot(n);
    let r = Lanes3(std::array::from_fn(|k| incident.0[k] - n.0[k] * twice));
    sum_lights(buffer, counts, mask, n, |row, unit_l, counted| {
        highlight(r.dot(unit_l).max(Vec4::ZERO), size, counted, row.nonspecular)
    })
}

#[cfg(test)]
mod tests {
    use super::super::{geom, light_in_cone, specular_brdf, sum_lights as scalar_sum_lights, HostLight, MAX_LIGHTS};
    use super::*;

    /// A small deterministic generator (xorshift), so that failures reproduce.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        /// Mostly ordinary values, sometimes the ones that take special paths.
        fn value(&mut self) -> f32 {
            match self.next() % 16 {
                0 => 0.0,
                1 => -0.0,
                2 => f32::NAN,
                3 => f32::INFINITY,
                4 => 1e-30,
                _ => (self.next() % 2001) as f32 / 1000.0 - 1.0,
            }
        }
        fn triple(&mut self) -> V3 {
            [self.value(), self.value(), self.value()]
        }
    }

    /// Equal bits, or both NaN: which NaN an operation on two of them returns depends on operand
    /// order, which the optimiser may swap in either form (a release build does).
    fn same_bits(a: V3, b: V3) -> bool {
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    }

    /// The four-lane cone test decides as `light_in_cone` lane by lane, on random and special
    /// directions (zero too), axes and cosines (every light, none, NaN, a bound of 0 after the
    /// slack), and any pattern of pending lights.
    #[test]
    fn four_lane_cone_test_is_the_lane_by_lane_one() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        for case in 0..20000 {
            let mut buffer = vec![LightLanes::default(); 3];
            for x in buffer.iter_mut() {
                for l in 0..4 {
                    let l_dir = if rng.next() % 8 == 0 { [0.0; 3] } else { rng.triple() };
                    x.set_lane(l, &HostLight { l: l_dir, ..HostLight::default() });
                }
            }
            let pending: [u32; 4] = std::array::from_fn(|_| (rng.next() % 16) as u32);
            let cone: [f32; 4 * CONE_ROWS] = std::array::from_fn(|i| match (i, rng.next() % 8) {
                (12.., 0) => -2.0,
                (12.., 1) => 2.0,
                (12.., 2) => 0.0,
                // The slack cancels: a cosine bound of exactly 0.
                (12.., 3) => 1e-3,
                _ => rng.value(),
            });
            let want = (0..4).any(|l| {
                let axis = [cone[l], cone[4 + l], cone[8 + l]];
                (0..32)
                    .filter(|k| pending[l] >> k & 1 != 0)
                    .any(|k| buffer.get(k).is_some_and(|x| light_in_cone(x.lane_l(l), axis, cone[12 + l])))
            });
            assert_eq!(pending_in_cone(&buffer, pending, &cone), want, "case {case}: {pending:?} {cone:?} {buffer:?}");
        }
    }

    #[test]
    fn four_lane_sums_are_the_lane_by_lane_ones_bit_for_bit() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for case in 0..4000 {
            let counts: [u32; 4] = std::array::from_fn(|_| (rng.next() % 6) as u32);
            let mask: [bool; 4] = std::array::from_fn(|_| rng.next() % 5 != 0);
            let mut buffer = vec![LightLanes::default(); MAX_LIGHTS];
            for x in buffer.iter_mut().take(6) {
                for l in 0..4 {
                    let light = HostLight {
                        l: rng.triple(),
                        cl: rng.triple(),
                        ambient: u32::from(rng.next() % 6 == 0),
                        nondiffuse: if rng.next() % 4 == 0 { rng.value() } else { 0.0 },
                        nonspecular: if rng.next() % 4 == 0 { rng.value() } else { 0.0 },
                        ..HostLight::default()
                    };
                    x.set_lane(l, &light);
                }
            }
            let raw_n = Lanes3(std::array::from_fn(|_| Vec4::from_array(std::array::from_fn(|_| rng.value()))));
            let raw_v = Lanes3(std::array::from_fn(|_| Vec4::from_array(std::array::from_fn(|_| rng.value()))));
            let roughness = Vec4::from_array(std::array::from_fn(|_| rng.value()));
            let (n, view) = (raw_n.normalized(), raw_v.normalized());
            let diffuse = diffuse(&buffer, counts, mask, &n);
            let specular = specular(&buffer, counts, mask, &n, &view, roughness);
            let ambient = ambient(&buffer, counts, mask);
            let size = Vec4::from_array(std::array::from_fn(|_| if rng.next() % 2 == 0 { rng.value() } else { 20.0 }));
            let phong = phong(&buffer, counts, mask, &n, &view, size);
            for l in (0..4).filter(|&l| mask[l]) {
                let lights = || (0..counts[l] as usize).map(|i| buffer[i].lane(l));
                let (ln, lv) = (geom::normalize(raw_n.lane(l)), geom::normalize(raw_v.lane(l)));
                assert_eq!(n.lane(l).map(f32::to_bits), ln.map(f32::to_bits), "case {case}: normalize");
                let want_d = scalar_sum_lights(lights(), ln, |x, unit_l| {
                    (unit_l[0] * ln[0] + unit_l[1] * ln[1] + unit_l[2] * ln[2]).max(0.0) * (1.0 - x.nondiffuse)
                });
                let want_s = scalar_sum_lights(lights(), ln, |x, unit_l| {
                    specular_brdf(unit_l, ln, lv, roughness[l]) * (1.0 - x.nonspecular)
                });
                // `h_phong` as it was lane by lane.
                let r = geom::reflect(lv.map(|x| -x), ln);
                let want_p = scalar_sum_lights(lights(), ln, |x, unit_l| {
                    transcendental::pow(geom::dot(r, unit_l).max(0.0), size[l]) * (1.0 - x.nonspecular)
                });
                assert!(
                    same_bits(phong.lane(l), want_p),
                    "case {case} lane {l}: phong {:?} != {want_p:?}",
                    phong.lane(l)
                );
                // `h_ambient`'s sum as it was lane by lane.
                let want_a = lights()
                    .filter(|x| x.ambient != 0)
                    .fold([0.0f32; 3], |acc, x| [acc[0] + x.cl[0], acc[1] + x.cl[1], acc[2] + x.cl[2]]);
                assert!(
                    same_bits(ambient.lane(l), want_a),
                    "case {case} lane {l}: ambient {:?} != {want_a:?}",
                    ambient.lane(l)
                );
                assert!(
                    same_bits(diffuse.lane(l), want_d),
                    "case {case} lane {l}: diffuse {:?} != {want_d:?}",
                    diffuse.lane(l)
                );
                assert!(
                    same_bits(specular.lane(l), want_s),
                    "case {case} lane {l}: specular {:?} != {want_s:?}",
                    specular.lane(l)
                );
            }
        }
    }
}

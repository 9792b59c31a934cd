//! Lane vectors: the arithmetic that hit geometry does for several hits at once, four lanes wide
//! (glam's `Vec4`) or eight (wide's `f32x8`, one AVX register where the target has AVX, as
//! `x86-64-v3` in `.cargo/config.toml` does). Every operation is the IEEE operation lane by lane,
//! so a lane gets the same bits at either width.

use glam::{BVec4A, Mat3A, Vec2, Vec3, Vec3A, Vec4};
use std::ops::{Add, BitAnd, Div, Mul, Neg, Not, Sub};
use wide::f32x8;

/// A vector of `LANES` floats, a hit a lane.
pub(super) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// A mask with a lane per lane of the vector.
    type Mask: Copy + BitAnd<Output = Self::Mask> + Not<Output = Self::Mask>;
    const LANES: usize;
    fn splat(v: f32) -> Self;
    /// Lane `j` is `f(j)`.
    fn from_fn(f: impl Fn(usize) -> f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn cmplt(self, o: Self) -> Self::Mask;
    fn cmpgt(self, o: Self) -> Self::Mask;
    fn is_finite_mask(self) -> Self::Mask;
    /// `a` where `mask` is set, else `b`.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    /// `self * a + b`, rounded once where the target has FMA (as glam and wide both do), else twice.
    /// (Only FMA targets use it outside the tests: see [`Lanes3::cross`].)
    #[cfg_attr(not(target_feature = "fma"), allow(dead_code))]
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// The mask whose lane `j` is `f(j)`.
    fn mask_from_fn(f: impl Fn(usize) -> bool) -> Self::Mask;
    /// Bit `j` set where lane `j` of `mask` is.
    fn bitmask(mask: Self::Mask) -> u32;
    /// Writes the lanes to `out[..LANES]` (if `out` is that long).
    fn write_to(self, out: &mut [f32]);
    /// Element `index(j)` of `data` in lane `j` (zero where there is none).
    fn gather3(data: &[Vec3], index: impl Fn(usize) -> usize) -> Lanes3<Self>;
    /// Element `index(j)` of `data` in lane `j`, its `x` and its `y` (zeros where there is none).
    fn gather2(data: &[Vec2], index: impl Fn(usize) -> usize) -> [Self; 2];
    /// Elements `at..at + LANES` of `row` (zeros where `row` is shorter).
    fn load(row: &[f32], at: usize) -> Self;
}

impl Lanes for Vec4 {
    type Mask = BVec4A;
    const LANES: usize = 4;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        Vec4::splat(v)
    }

    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> f32) -> Self {
        Vec4::new(f(0), f(1), f(2), f(3))
    }

    #[inline(always)]
    fn load(row: &[f32], at: usize) -> Self {
        row.get(at..at.saturating_add(4)).map_or(Vec4::ZERO, Vec4::from_slice)
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        Vec4::sqrt(self)
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Vec4::abs(self)
    }

    #[inline(always)]
    fn cmplt(self, o: Self) -> BVec4A {
        Vec4::cmplt(self, o)
    }

    #[inline(always)]
    fn cmpgt(self, o: Self) -> BVec4A {
        Vec4::cmpgt(self, o)
    }

    #[inline(always)]
    fn is_finite_mask(self) -> BVec4A {
        Vec4::is_finite_mask(self)
    }

    #[inline(always)]
    fn select(mask: BVec4A, a: Self, b: Self) -> Self {
        Vec4::select(mask, a, b)
    }

    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        Vec4::mul_add(self, a, b)
    }

    #[inline(always)]
    fn mask_from_fn(f: impl Fn(usize) -> bool) -> BVec4A {
        BVec4A::new(f(0), f(1), f(2), f(3))
    }

    #[inline(always)]
    fn bitmask(mask: BVec4A) -> u32 {
        mask.bitmask()
    }

    #[inline(always)]
    fn write_to(self, out: &mut [f32]) {
        if let Some(out) = out.get_mut(..4) {
            self.write_to_slice(out);
        }
    }

    #[inline(always)]
    fn gather3(data: &[Vec3], index: impl Fn(usize) -> usize) -> Lanes3<Self> {
        Lanes3::gather(data, index)
    }

    #[inline(always)]
    fn gather2(data: &[Vec2], index: impl Fn(usize) -> usize) -> [Self; 2] {
        let at = [index(0), index(1), index(2), index(3)];
        #[cfg(target_arch = "x86_64")]
        {
            // Eight bytes an element, shuffled into rows in registers: element by element, each
            // would take a bounds check and two loads and inserts (for the texture coordinates of
            // a triangle's corners, on every hit).
            if at[0].max(at[1]).max(at[2]).max(at[3]) < data.len() {
                use std::arch::x86_64::{_mm_castpd_ps, _mm_load_sd, _mm_movelh_ps, _mm_shuffle_ps};
                // SAFETY: every `i < data.len()`, checked above, so the 8 bytes of element `i` lie
                // inside `data`; `Vec2` is two `f32`s (`repr(C)`), and `_mm_load_sd` needs no
                // alignment. The rest only shuffles registers (SSE2 is part of x86-64).
                return unsafe {
                    let load = |i: usize| _mm_castpd_ps(_mm_load_sd(data.as_ptr().add(i).cast::<f64>()));
                    let (low, high) =
                        (_mm_movelh_ps(load(at[0]), load(at[1])), _mm_movelh_ps(load(at[2]), load(at[3])));
                    [
                        _mm_shuffle_ps::<0b10_00_10_00>(low, high).into(),
                        _mm_shuffle_ps::<0b11_01_11_01>(low, high).into(),
                    ]
                };
            }
        }
        let at = |j: usize| data.get(at[j]).copied().unwrap_or_default();
        let (a, b, c, d) = (at(0), at(1), at(2), at(3));
        [Vec4::new(a.x, b.x, c.x, d.x), Vec4::new(a.y, b.y, c.y, d.y)]
    }
}

/// Lanes `0..4` from `lo`, `4..8` from `hi`.
#[inline(always)]
fn halves(lo: Vec4, hi: Vec4) -> f32x8 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::__m128;
        // Two 16-byte registers as one 32-byte one: `vinsertf128` where the target has AVX.
        bytemuck::cast::<[__m128; 2], f32x8>([lo.into(), hi.into()])
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let (lo, hi) = (lo.to_array(), hi.to_array());
        f32x8::new([lo[0], lo[1], lo[2], lo[3], hi[0], hi[1], hi[2], hi[3]])
    }
}

impl Lanes for f32x8 {
    type Mask = f32x8;
    const LANES: usize = 8;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        f32x8::splat(v)
    }

    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> f32) -> Self {
        halves(Vec4::from_fn(&f), Vec4::from_fn(|j| f(j + 4)))
    }

    #[inline(always)]
    fn load(row: &[f32], at: usize) -> Self {
        let eight: Option<[f32; 8]> = row.get(at..at.saturating_add(8)).and_then(|r| r.try_into().ok());
        eight.map_or(f32x8::splat(0.0), f32x8::from)
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }

    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }

    #[inline(always)]
    fn cmplt(self, o: Self) -> f32x8 {
        self.simd_lt(o)
    }

    #[inline(always)]
    fn cmpgt(self, o: Self) -> f32x8 {
        self.simd_gt(o)
    }

    #[inline(always)]
    fn is_finite_mask(self) -> f32x8 {
        self.is_finite()
    }

    #[inline(always)]
    fn select(mask: f32x8, a: Self, b: Self) -> Self {
        mask.select(a, b)
    }

    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f32x8::mul_add(self, a, b)
    }

    #[inline(always)]
    fn mask_from_fn(f: impl Fn(usize) -> bool) -> f32x8 {
        let lane = |j: usize| if f(j) { f32::from_bits(u32::MAX) } else { 0.0 };
        <f32x8 as Lanes>::from_fn(lane)
    }

    #[inline(always)]
    fn bitmask(mask: f32x8) -> u32 {
        mask.to_bitmask()
    }

    #[inline(always)]
    fn write_to(self, out: &mut [f32]) {
        if let Some(out) = out.get_mut(..8) {
            out.copy_from_slice(&self.to_array());
        }
    }

    #[inline(always)]
    fn gather3(data: &[Vec3], index: impl Fn(usize) -> usize) -> Lanes3<Self> {
        let (lo, hi) = (Lanes3::gather(data, &index), Lanes3::gather(data, |j| index(j + 4)));
        Lanes3 { x: halves(lo.x, hi.x), y: halves(lo.y, hi.y), z: halves(lo.z, hi.z) }
    }

    #[inline(always)]
    fn gather2(data: &[Vec2], index: impl Fn(usize) -> usize) -> [Self; 2] {
        let (lo, hi) = (Vec4::gather2(data, &index), Vec4::gather2(data, |j| index(j + 4)));
        [halves(lo[0], hi[0]), halves(lo[1], hi[1])]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eight lanes give each lane the bits four give it, for the operations hit geometry uses,
    /// on ordinary, tiny, huge, zero, infinite and NaN values.
    #[test]
    fn eight_lanes_compute_what_four_do() {
        let values = [1.5f32, -2.25, 1e-30, -3e30, 0.0, -0.0, f32::INFINITY, f32::NAN, 7.0, 1.0 / 3.0, -1e-40, 2.0];
        let pick = |seed: usize| move |j: usize| values[(seed * 7 + j * 5) % values.len()];
        for seed in 0..values.len() {
            let (a, b, c) = (pick(seed), pick(seed + 1), pick(seed + 3));
            let lanes8 = |f: &dyn Fn(usize) -> f32| <f32x8 as Lanes>::from_fn(f);
            let (a8, b8, c8) = (lanes8(&a), lanes8(&b), lanes8(&c));
            let four = |off: usize| {
                let (a4, b4, c4) =
                    (Vec4::from_fn(|j| a(j + off)), Vec4::from_fn(|j| b(j + off)), Vec4::from_fn(|j| c(j + off)));
                let m = a4.cmplt(b4) & !c4.cmpgt(a4) & a4.is_finite_mask();
                [
                    a4 + b4,
                    a4 - b4,
                    a4 * b4,
                    a4 / b4,
                    -a4,
                    a4.sqrt(),
                    a4.abs(),
                    a4.mul_add(b4, c4),
                    Vec4::select(m, a4, c4),
                ]
                .map(|v| v.to_array())
            };
            let m8 = Lanes::cmplt(a8, b8) & !Lanes::cmpgt(c8, a8) & Lanes::is_finite_mask(a8);
            let eight = [
                a8 + b8,
                a8 - b8,
                a8 * b8,
                a8 / b8,
                -a8,
                Lanes::sqrt(a8),
                Lanes::abs(a8),
                Lanes::mul_add(a8, b8, c8),
                <f32x8 as Lanes>::select(m8, a8, c8),
            ];
            let (lo, hi) = (four(0), four(4));
            for (k, v) in eight.iter().enumerate() {
                let v = v.to_array();
                for j in 0..8 {
                    let want = if j < 4 { lo[k][j] } else { hi[k][j - 4] };
                    assert_eq!(v[j].to_bits(), want.to_bits(), "seed {seed}, operation {k}, lane {j}");
                }
            }
            let mask = <f32x8 as Lanes>::mask_from_fn(|j| a(j) > 1.0);
            let want = (0..8).filter(|&j| a(j) > 1.0).fold(0, |m, j| m | 1 << j);
            assert_eq!(<f32x8 as Lanes>::bitmask(mask), want);
        }
    }

    /// A load reads the row's elements from its start, at either width, and zeros past the row.
    #[test]
    fn loads_read_a_rows_elements_or_zeros_past_it() {
        let row: Vec<f32> = (0..12).map(|k| k as f32 * 1.5).collect();
        assert_eq!(<Vec4 as Lanes>::load(&row, 3).to_array(), [4.5, 6.0, 7.5, 9.0]);
        assert_eq!(<f32x8 as Lanes>::load(&row, 4).to_array(), std::array::from_fn(|j| (4 + j) as f32 * 1.5));
        assert_eq!(<Vec4 as Lanes>::load(&row, 10), Vec4::ZERO);
        assert_eq!(<f32x8 as Lanes>::load(&row, 5).to_array(), [0.0; 8]);
    }

    /// Gathering texture coordinates four or eight lanes at a time gives each lane its element's
    /// bits, and zeros for an index past the data (every lane then goes the slow way).
    #[test]
    fn gathered_pairs_are_the_elements() {
        let data: Vec<Vec2> = (0..37).map(|i| Vec2::new(i as f32 * 1.5 - 3.0, -(i as f32) / 7.0)).collect();
        for seed in 0..60usize {
            let index = |j: usize| (seed * 11 + j * 13) % if seed % 5 == 0 { 40 } else { 37 };
            let want = |j: usize| data.get(index(j)).copied().unwrap_or_default();
            let [x, y] = Vec4::gather2(&data, index);
            let [x8, y8] = <f32x8 as Lanes>::gather2(&data, index);
            for j in 0..8 {
                if j < 4 {
                    assert_eq!(
                        [x[j].to_bits(), y[j].to_bits()],
                        [want(j).x.to_bits(), want(j).y.to_bits()],
                        "seed {seed}"
                    );
                }
                let (x8, y8) = (x8.to_array()[j], y8.to_array()[j]);
                assert_eq!([x8.to_bits(), y8.to_bits()], [want(j).x.to_bits(), want(j).y.to_bits()], "seed {seed}");
            }
        }
        let [x, _] = Vec4::gather2(&[], |j| j);
        assert_eq!(x, Vec4::ZERO);
    }
}

/// A 3-vector for each of several lanes (four: `Vec4`; eight: see [`Lanes`]), a vector per
/// component. The operations are `Vec3A`'s, in the same order, so that each lane gets the bits a
/// `Vec3A` would.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Lanes3<V = Vec4> {
    pub(super) x: V,
    pub(super) y: V,
    pub(super) z: V,
}

impl Lanes3 {
    /// Element `index(j)` of `data` in lane `j` (zero where there is none). Loaded straight from
    /// `data`: gathered through an array of vectors, the transposition read the array back with
    /// loads across its stores, which stall.
    #[inline(always)]
    pub(super) fn gather(data: &[Vec3], index: impl Fn(usize) -> usize) -> Lanes3 {
        let at = [index(0), index(1), index(2), index(3)];
        #[cfg(target_arch = "x86_64")]
        {
            // Sixteen bytes from each element: its three values and the first of the next one,
            // which the transposition drops. Element by element, each would take a bounds
            // check and three loads and inserts.
            if at[0].max(at[1]).max(at[2]).max(at[3]) < data.len().saturating_sub(1) {
                let load = |i: usize| {
                    // SAFETY: `i + 1 < data.len()`, checked above, so the 16 bytes from element `i`
                    // (12 of its own, 4 of the next) lie inside `data`; `Vec3` is three `f32`s
                    // (`repr(C)`), and `_mm_loadu_ps` needs no alignment.
                    unsafe { std::arch::x86_64::_mm_loadu_ps(data.as_ptr().add(i).cast::<f32>()) }
                };
                return Lanes3::transposed([load(at[0]), load(at[1]), load(at[2]), load(at[3])]);
            }
        }
        let at = |j: usize| data.get(at[j]).copied().unwrap_or(Vec3::ZERO);
        let (a, b, c, d) = (at(0), at(1), at(2), at(3));
        Lanes3 { x: Vec4::new(a.x, b.x, c.x, d.x), y: Vec4::new(a.y, b.y, c.y, d.y), z: Vec4::new(a.z, b.z, c.z, d.z) }
    }

    /// The first three values of each of four vectors, a vector a lane, transposed in registers
    /// (`_MM_TRANSPOSE4_PS`, less the fourth row).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn transposed([a, b, c, d]: [std::arch::x86_64::__m128; 4]) -> Lanes3 {
        use std::arch::x86_64::{_mm_movehl_ps, _mm_movelh_ps, _mm_unpackhi_ps, _mm_unpacklo_ps};
        // SAFETY: SSE is part of x86-64, and these only shuffle registers.
        let [x, y, z] = unsafe {
            let (ab_low, cd_low) = (_mm_unpacklo_ps(a, b), _mm_unpacklo_ps(c, d));
            let (ab_high, cd_high) = (_mm_unpackhi_ps(a, b), _mm_unpackhi_ps(c, d));
            [_mm_movelh_ps(ab_low, cd_low), _mm_movehl_ps(cd_low, ab_low), _mm_movelh_ps(ab_high, cd_high)]
        };
        Lanes3 { x: x.into(), y: y.into(), z: z.into() }
    }

    #[inline(always)]
    pub(super) fn lane(&self, j: usize) -> Vec3A {
        Vec3A::new(self.x[j], self.y[j], self.z[j])
    }

    /// Four consecutive vectors, a vector a lane.
    #[inline(always)]
    pub(super) fn of_four(four: &[Vec3A; 4]) -> Lanes3 {
        Lanes3::of([&four[0], &four[1], &four[2], &four[3]], |v| *v)
    }

    /// The vectors `f(items[j])`, one a lane: transposed in registers. (Built as an array of
    /// vectors and read back a component at a time, the reads would straddle the array's
    /// stores, which stalls them: store forwarding fails.)
    #[inline(always)]
    pub(super) fn of<T>(items: [&T; 4], f: impl Fn(&T) -> Vec3A) -> Lanes3 {
        let [a, b, c, d] = [f(items[0]), f(items[1]), f(items[2]), f(items[3])];
        #[cfg(target_arch = "x86_64")]
        {
            Lanes3::transposed([a.into(), b.into(), c.into(), d.into()])
        }
        #[cfg(not(target_arch = "x86_64"))]
        Lanes3 { x: Vec4::new(a.x, b.x, c.x, d.x), y: Vec4::new(a.y, b.y, c.y, d.y), z: Vec4::new(a.z, b.z, c.z, d.z) }
    }
}

impl<V: Lanes> Lanes3<V> {
    /// Elements `at..at + V::LANES` of three rows, a row a component.
    #[inline(always)]
    pub(super) fn load(rows: [&[f32]; 3], at: usize) -> Self {
        Lanes3 { x: V::load(rows[0], at), y: V::load(rows[1], at), z: V::load(rows[2], at) }
    }

    pub(super) fn zero() -> Self {
        Lanes3 { x: V::splat(0.0), y: V::splat(0.0), z: V::splat(0.0) }
    }

    pub(super) fn splat(v: Vec3A) -> Self {
        Lanes3 { x: V::splat(v.x), y: V::splat(v.y), z: V::splat(v.z) }
    }

    pub(super) fn add(self, o: Self) -> Self {
        Lanes3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }

    pub(super) fn sub(self, o: Self) -> Self {
        Lanes3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }

    pub(super) fn scale(self, s: V) -> Self {
        Lanes3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    /// `Vec3A::dot`: `(x + y) + z`.
    pub(super) fn dot(self, o: Self) -> V {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// `Vec3A::cross`, whose second product is fused into the subtraction where the target has
    /// FMA (`x86-64-v3`, `.cargo/config.toml`).
    pub(super) fn cross(self, o: Self) -> Self {
        #[cfg(target_feature = "fma")]
        let minus_product = |a: V, b: V, from: V| (-a).mul_add(b, from);
        #[cfg(not(target_feature = "fma"))]
        let minus_product = |a: V, b: V, from: V| from - a * b;
        Lanes3 {
            x: minus_product(self.z, o.y, self.y * o.z),
            y: minus_product(self.x, o.z, self.z * o.x),
            z: minus_product(self.y, o.x, self.x * o.y),
        }
    }

    /// `m * v` as `Mat3A * Vec3A` sums it: column by column.
    pub(super) fn transformed(self, m: &Mat3A) -> Self {
        let row = |a: f32, b: f32, c: f32| V::splat(a) * self.x + V::splat(b) * self.y + V::splat(c) * self.z;
        Lanes3 {
            x: row(m.x_axis.x, m.y_axis.x, m.z_axis.x),
            y: row(m.x_axis.y, m.y_axis.y, m.z_axis.y),
            z: row(m.x_axis.z, m.y_axis.z, m.z_axis.z),
        }
    }

    pub(super) fn select(mask: V::Mask, a: Self, b: Self) -> Self {
        Lanes3 { x: V::select(mask, a.x, b.x), y: V::select(mask, a.y, b.y), z: V::select(mask, a.z, b.z) }
    }

    /// `Vec3A::normalize_or`, per lane.
    pub(super) fn normalize_or(self, fallback: Self) -> Self {
        let rcp = V::splat(1.0) / self.dot(self).sqrt();
        Lanes3::select(rcp.is_finite_mask() & rcp.cmpgt(V::splat(0.0)), self.scale(rcp), fallback)
    }
}

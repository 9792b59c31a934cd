//! Matrix built-ins (RISpec 3.2 section 15.4) and the matrix arithmetic the language's operators use.
//!
//! Conventions (the module's, RenderMan's): points are row vectors, transformed as `p * M`; a matrix
//! is 16 floats in row-major order with the translation in elements 12, 13 and 14; angles are in
//! radians. So `mul(a, b)` is the transform that applies `a` first and then `b`. Nothing here panics:
//! singular matrices, zero axes and out-of-range indices all have a documented result, and NaN or
//! infinite elements propagate through the arithmetic like any other IEEE value. Determinants and
//! inverses are computed in `f64` and rounded to `f32` once.

use super::{M4, V3};

/// The identity matrix.
pub const IDENTITY: M4 = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// The identity matrix (RSL's `matrix 1`).
pub fn identity() -> M4 {
    IDENTITY
}

/// The matrix product `a * b`. With row vectors, `p * (a * b)` applies `a` first and then `b`, so this
/// is RSL's `a * b` operator and the concatenation "a, then b".
pub fn mul(a: &M4, b: &M4) -> M4 {
    let mut r = [0.0f32; 16];
    for row in 0..4 {
        for col in 0..4 {
            r[row * 4 + col] = a[row * 4] * b[col]
                + a[row * 4 + 1] * b[4 + col]
                + a[row * 4 + 2] * b[8 + col]
                + a[row * 4 + 3] * b[12 + col];
        }
    }
    r
}

/// The transpose.
pub fn transpose(m: &M4) -> M4 {
    let mut r = [0.0f32; 16];
    for row in 0..4 {
        for col in 0..4 {
            r[col * 4 + row] = m[row * 4 + col];
        }
    }
    r
}

/// `m` in `f64` for glam. glam's matrices are column-major, so this is `m` transposed; the
/// determinant does not change under transposition, and the inverse of the transpose is the
/// transpose of the inverse, so reading the result back row-major undoes it.
fn transposed_f64(m: &M4) -> glam::DMat4 {
    glam::DMat4::from_cols_array(&m.map(f64::from))
}

/// The determinant (RSL's `determinant`), computed in `f64` and rounded once. NaN elements give NaN.
pub fn determinant(m: &M4) -> f32 {
    transposed_f64(m).determinant() as f32
}

/// The inverse, or `None` when `m` is singular: when any element is not finite, when
/// `|det| <= 1e-12 * (the product of the rows' Euclidean lengths)` (a relative test: that product is
/// the largest determinant rows of those lengths can have, Hadamard's bound), or when an element of the
/// inverse does not fit in an `f32`. glam's inverse does not test for singularity itself.
pub fn inverse(m: &M4) -> Option<M4> {
    if m.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let t = transposed_f64(m);
    let det = t.determinant();
    // The rows of `m` are the columns of `t`.
    let bound: f64 = (0..4).map(|c| t.col(c).length()).product();
    if !(det.is_finite() && det.abs() > 1e-12 * bound) {
        return None;
    }
    let r: M4 = t.inverse().to_cols_array().map(|x| x as f32);
    r.iter().all(|x| x.is_finite()).then_some(r)
}

/// RSL's matrix division `a / b`, which is `a * inverse(b)`. When `b` is singular (see [`inverse`])
/// the result is `a` unchanged.
pub fn div(a: &M4, b: &M4) -> M4 {
    match inverse(b) {
        Some(inv) => mul(a, &inv),
        None => *a,
    }
}

/// The matrix that translates by `t`: the identity with `t` in elements 12, 13, 14.
pub fn translation(t: V3) -> M4 {
    let mut r = IDENTITY;
    r[12] = t[0];
    r[13] = t[1];
    r[14] = t[2];
    r
}

/// The matrix that scales by `s` along the axes.
pub fn scaling(s: V3) -> M4 {
    let mut r = IDENTITY;
    r[0] = s[0];
    r[5] = s[1];
    r[10] = s[2];
    r
}

/// The matrix that rotates by `angle` radians about `axis` through the origin, in the sense of
/// `RiRotate`: a positive angle about +z takes +x towards +y (`(1,0,0) * rotation(pi/2, z) = (0,1,0)`).
/// The axis need not be unit length. A zero-length or non-finite axis gives the identity.
pub fn rotation(angle: f32, axis: V3) -> M4 {
    let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    if !(len.is_finite() && len > 0.0) {
        return IDENTITY;
    }
    let [x, y, z] = [axis[0] / len, axis[1] / len, axis[2] / len];
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    // The transpose of the column-vector Rodrigues matrix, since points are row vectors here.
    [
        t * x * x + c,
        t * x * y + s * z,
        t * x * z - s * y,
        0.0,
        t * x * y - s * z,
        t * y * y + c,
        t * y * z + s * x,
        0.0,
        t * x * z + s * y,
        t * y * z - s * x,
        t * z * z + c,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
    ]
}

/// RSL's `translate(m, t)`. RISpec 3.2 says these functions concatenate simple transformations onto
/// the given matrix like `RiTranslate` does onto the current transformation, and `RiTranslate` makes
/// the new transform apply to points *before* the existing one. So the result is
/// `translation(t) * m`: `p * result = (p + t) * m`.
pub fn translate(m: &M4, t: V3) -> M4 {
    mul(&translation(t), m)
}

/// RSL's `rotate(m, angle, axis)`: `rotation(angle, axis) * m` (the rotation applies first, as with
/// `RiRotate`; see [`translate`]). The angle is in radians, unlike `RiRotate`'s degrees. A zero axis
/// leaves `m` unchanged.
pub fn rotate(m: &M4, angle: f32, axis: V3) -> M4 {
    mul(&rotation(angle, axis), m)
}

/// RSL's `scale(m, s)`: `scaling(s) * m` (the scale applies first, as with `RiScale`; see
/// [`translate`]).
pub fn scale(m: &M4, s: V3) -> M4 {
    mul(&scaling(s), m)
}

/// Transforms a point: `(p, 1) * m` followed by the homogeneous divide. When the resulting `w` is 0
/// (or not finite) the un-divided `xyz` is returned; when it is exactly 1 no division happens.
pub fn transform_point(m: &M4, p: V3) -> V3 {
    let x = p[0] * m[0] + p[1] * m[4] + p[2] * m[8] + m[12];
    let y = p[0] * m[1] + p[1] * m[5] + p[2] * m[9] + m[13];
    let z = p[0] * m[2] + p[1] * m[6] + p[2] * m[10] + m[14];
    let w = p[0] * m[3] + p[1] * m[7] + p[2] * m[11] + m[15];
    if w == 1.0 || w == 0.0 || !w.is_finite() {
        [x, y, z]
    } else {
        [x / w, y / w, z / w]
    }
}

/// Transforms a vector: `v` times the upper-left 3x3 of `m` (no translation, no divide).
pub fn transform_vector(m: &M4, v: V3) -> V3 {
    [
        v[0] * m[0] + v[1] * m[4] + v[2] * m[8],
        v[0] * m[1] + v[1] * m[5] + v[2] * m[9],
        v[0] * m[2] + v[1] * m[6] + v[2] * m[10],
    ]
}

/// Transforms a normal: `n` times the transpose of the inverse of `m`'s upper-left 3x3 (the part
/// [`transform_vector`] applies), so that a normal stays perpendicular to every transformed tangent
/// vector, for any matrix. For affine matrices (last column `0 0 0 1`) this equals the upper-left 3x3
/// of the 4x4 inverse's transpose; for projective ones, which have no single tangent map, the 3x3 is
/// the choice that keeps `transform_normal` and `transform_vector` consistent. The result is not
/// renormalised (as in RSL's `ntransform`). When the 3x3 is singular (the test of [`inverse`]: not
/// finite, or `|det| <= 1e-12 * (the product of its rows' lengths)`) `n` is returned unchanged.
pub fn transform_normal(m: &M4, n: V3) -> V3 {
    let a: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| f64::from(m[r * 4 + c])));
    // The cofactor matrix of `a` is `det * inverse(a)^T`, so `n * cof / det` is the row vector
    // `n * inverse(a)^T`.
    let cof = [
        [
            a[1][1] * a[2][2] - a[1][2] * a[2][1],
            a[1][2] * a[2][0] - a[1][0] * a[2][2],
            a[1][0] * a[2][1] - a[1][1] * a[2][0],
        ],
        [
            a[0][2] * a[2][1] - a[0][1] * a[2][2],
            a[0][0] * a[2][2] - a[0][2] * a[2][0],
            a[0][1] * a[2][0] - a[0][0] * a[2][1],
        ],
        [
            a[0][1] * a[1][2] - a[0][2] * a[1][1],
            a[0][2] * a[1][0] - a[0][0] * a[1][2],
            a[0][0] * a[1][1] - a[0][1] * a[1][0],
        ],
    ];
    let det = a[0][0] * cof[0][0] + a[0][1] * cof[0][1] + a[0][2] * cof[0][2];
    let bound: f64 = a.iter().map(|row| row.iter().map(|x| x * x).sum::<f64>().sqrt()).product();
    if !(det.is_finite() && bound.is_finite() && det.abs() > 1e-12 * bound) {
        return n;
    }
    let n = n.map(f64::from);
    let r: V3 = std::array::from_fn(|c| ((n[0] * cof[0][c] + n[1] * cof[1][c] + n[2] * cof[2][c]) / det) as f32);
    if r.iter().all(|x| x.is_finite()) {
        r
    } else {
        n.map(|x| x as f32)
    }
}

/// An index into a row or column: truncated toward zero and clamped to 0..=3 (NaN is 0).
fn index(i: f32) -> usize {
    (i as i32).clamp(0, 3) as usize
}

/// RSL's `comp(m, row, col)`: the element at `row`, `col`. The indices are floats, as in RSL; each is
/// truncated toward zero and clamped to 0..=3 (NaN reads as 0), so no index is out of range.
pub fn comp(m: &M4, row: f32, col: f32) -> f32 {
    m[index(row) * 4 + index(col)]
}

/// RSL's `setcomp(m, row, col, value)`: sets the element at `row`, `col`, with the indices treated
/// as in [`comp`].
pub fn set_comp(m: &mut M4, row: f32, col: f32, value: f32) {
    m[index(row) * 4 + index(col)] = value;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift32) for test inputs.
    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            (self.0 >> 8) as f32 / (1u32 << 24) as f32
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.next()
        }
        fn v3(&mut self) -> V3 {
            [self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0)]
        }
        /// A well-conditioned matrix: rotation, positive scale, translation and a small perspective.
        fn matrix(&mut self) -> M4 {
            let s = [self.range(0.5, 2.0), self.range(0.5, 2.0), self.range(0.5, 2.0)];
            let mut m = translate(&rotate(&scaling(s), self.range(-3.0, 3.0), self.v3()), self.v3());
            m[3] = self.range(-0.1, 0.1);
            m[7] = self.range(-0.1, 0.1);
            m
        }
    }

    fn close(a: &[f32], b: &[f32], tol: f32) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    fn dot(a: V3, b: V3) -> f32 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    #[test]
    fn inverse_times_m_is_identity() {
        let mut rng = Rng(0x1234_5678);
        for _ in 0..500 {
            let m = rng.matrix();
            let inv = inverse(&m).expect("well-conditioned");
            assert!(close(&mul(&inv, &m), &IDENTITY, 1e-5), "{m:?}");
            assert!(close(&mul(&m, &inv), &IDENTITY, 1e-5), "{m:?}");
            assert!(close(&div(&m, &m), &IDENTITY, 1e-5));
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_have_no_inverse() {
        assert_eq!(inverse(&[0.0; 16]), None);
        let mut m = scaling([1.0, 0.0, 1.0]);
        assert_eq!(inverse(&m), None);
        // Dependent rows.
        m = [1.0, 2.0, 3.0, 4.0, 2.0, 4.0, 6.0, 8.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(inverse(&m), None);
        assert_eq!(determinant(&m), 0.0);
        // Tiny but well-conditioned: the test is relative.
        assert!(inverse(&scaling([1e-6, 1e-6, 1e-6])).is_some());
        m = IDENTITY;
        m[5] = f32::NAN;
        assert_eq!(inverse(&m), None);
        m[5] = f32::INFINITY;
        assert_eq!(inverse(&m), None);
        let a = translation([1.0, 2.0, 3.0]);
        assert_eq!(div(&a, &[0.0; 16]), a);
    }

    #[test]
    fn determinant_of_a_scale() {
        assert_eq!(determinant(&scale(&identity(), [2.0, 3.0, 4.0])), 24.0);
        assert_eq!(determinant(&IDENTITY), 1.0);
        assert!((determinant(&rotation(0.7, [1.0, 2.0, 3.0])) - 1.0).abs() < 1e-6);
        let mut rng = Rng(99);
        for _ in 0..100 {
            let (a, b) = (rng.matrix(), rng.matrix());
            let d = determinant(&mul(&a, &b));
            assert!((d - determinant(&a) * determinant(&b)).abs() <= 1e-4 * d.abs().max(1.0));
            assert!((determinant(&transpose(&a)) - determinant(&a)).abs() <= 1e-5);
        }
    }

    #[test]
    fn rotate_by_90_degrees_about_z_maps_x_to_y() {
        let m = rotate(&identity(), std::f32::consts::FRAC_PI_2, [0.0, 0.0, 1.0]);
        assert!(close(&transform_point(&m, [1.0, 0.0, 0.0]), &[0.0, 1.0, 0.0], 1e-6));
        assert!(close(&transform_vector(&m, [0.0, 1.0, 0.0]), &[-1.0, 0.0, 0.0], 1e-6));
        // About x: y goes to z; about y: z goes to x (right-handed sense of the rotation formula).
        let mx = rotation(std::f32::consts::FRAC_PI_2, [2.0, 0.0, 0.0]);
        assert!(close(&transform_vector(&mx, [0.0, 1.0, 0.0]), &[0.0, 0.0, 1.0], 1e-6));
        let my = rotation(std::f32::consts::FRAC_PI_2, [0.0, 1.0, 0.0]);
        assert!(close(&transform_vector(&my, [0.0, 0.0, 1.0]), &[1.0, 0.0, 0.0], 1e-6));
        assert_eq!(rotation(1.0, [0.0; 3]), IDENTITY);
        assert_eq!(rotation(1.0, [f32::NAN, 0.0, 0.0]), IDENTITY);
    }

    #[test]
    fn translate_rotate_scale_apply_before_m() {
        let m = translation([10.0, 0.0, 0.0]);
        // translate(m, t): p is translated by t first, then by m.
        let t = translate(&scale(&m, [2.0, 2.0, 2.0]), [1.0, 0.0, 0.0]);
        // (p + (1,0,0)) * 2 + (10,0,0)
        assert!(close(&transform_point(&t, [1.0, 1.0, 1.0]), &[14.0, 2.0, 2.0], 1e-6));
        let r = rotate(&m, std::f32::consts::FRAC_PI_2, [0.0, 0.0, 1.0]);
        assert!(close(&transform_point(&r, [1.0, 0.0, 0.0]), &[10.0, 1.0, 0.0], 1e-6));
        // Vectors ignore translation.
        assert_eq!(transform_vector(&m, [1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]);
    }

    #[test]
    fn transform_point_divides_by_w() {
        let mut m = IDENTITY;
        m[15] = 2.0;
        assert_eq!(transform_point(&m, [2.0, 4.0, 6.0]), [1.0, 2.0, 3.0]);
        m[15] = 0.0;
        assert_eq!(transform_point(&m, [2.0, 4.0, 6.0]), [2.0, 4.0, 6.0]);
        m[15] = f32::NAN;
        assert_eq!(transform_point(&m, [2.0, 4.0, 6.0]), [2.0, 4.0, 6.0]);
    }

    #[test]
    fn normals_stay_perpendicular_to_transformed_tangents() {
        let mut rng = Rng(7);
        for _ in 0..300 {
            let m = rng.matrix();
            let (a, b) = (rng.v3(), rng.v3());
            // n is perpendicular to both tangents a and b.
            let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
            let tn = transform_normal(&m, n);
            for t in [a, b] {
                let tt = transform_vector(&m, t);
                let scale = dot(tn, tn).sqrt() * dot(tt, tt).sqrt();
                assert!(dot(tn, tt).abs() <= 1e-5 * scale.max(1e-3), "{m:?}");
            }
        }
        // A non-uniform scale: the normal of the plane x = y transforms against the scale.
        let s = scaling([2.0, 1.0, 1.0]);
        assert!(close(&transform_normal(&s, [1.0, -1.0, 0.0]), &[0.5, -1.0, 0.0], 1e-6));
        // Singular: unchanged.
        assert_eq!(transform_normal(&[0.0; 16], [0.0, 0.0, 1.0]), [0.0, 0.0, 1.0]);
        assert_eq!(transform_normal(&scaling([1.0, 0.0, 1.0]), [0.0, 0.0, 1.0]), [0.0, 0.0, 1.0]);
        let mut nan = IDENTITY;
        nan[0] = f32::NAN;
        assert_eq!(transform_normal(&nan, [0.0, 0.0, 1.0]), [0.0, 0.0, 1.0]);
        // Affine: agrees with the inverse transpose of the whole matrix.
        let m = translate(&rotate(&scaling([1.0, 2.0, 3.0]), 0.5, [1.0, 1.0, 0.0]), [4.0, 5.0, 6.0]);
        let inv_t = transpose(&inverse(&m).unwrap());
        assert!(close(&transform_normal(&m, [0.3, -0.2, 0.9]), &transform_vector(&inv_t, [0.3, -0.2, 0.9]), 1e-5));
    }

    #[test]
    fn mul_and_transpose() {
        let a = translation([1.0, 2.0, 3.0]);
        let b = scaling([2.0, 2.0, 2.0]);
        // a then b: (p + t) * 2.
        assert_eq!(transform_point(&mul(&a, &b), [0.0, 0.0, 0.0]), [2.0, 4.0, 6.0]);
        assert_eq!(mul(&IDENTITY, &a), a);
        assert_eq!(transpose(&transpose(&a)), a);
        assert_eq!(transpose(&a)[3], 1.0);
    }

    #[test]
    fn comp_clamps_indices() {
        let mut m: M4 = std::array::from_fn(|i| i as f32);
        assert_eq!(comp(&m, 3.0, 2.0), 14.0);
        assert_eq!(comp(&m, 1.9, 0.0), 4.0);
        assert_eq!(comp(&m, -5.0, 99.0), 3.0);
        assert_eq!(comp(&m, f32::NAN, f32::INFINITY), 3.0);
        set_comp(&mut m, 7.0, -1.0, 100.0);
        assert_eq!(m[12], 100.0);
        set_comp(&mut m, 0.0, 1.0, -1.0);
        assert_eq!(m[1], -1.0);
    }
}

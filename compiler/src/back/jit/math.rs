//! Float math for either shape (scalar `f32` or `f32x4`), and the per-chunk helpers.
//!
//! Invariants:
//! - Every inline formula evaluates exactly the operations of the interpreter's scalar code
//!   (`crate::shadeops::geom`, `crate::interp`) in the same order and with the same comparisons, so
//!   results agree bit for bit (no fused multiply-add, no approximate reciprocal or square root).
//!   `min`/`max` follow `f32::min`/`f32::max`: a NaN operand yields the other operand.
//! - Transcendental functions (`sin cos tan asin acos atan exp log pow`) and the noise family are
//!   **helpers**: `extern "C" fn(in: *const f32, out: *mut f32)` over one chunk, reading `4 * ins`
//!   floats (input `k` lane `l` at `in[4k + l]`) and writing `4 * outs`. They compute what the
//!   interpreter computes per lane, bit for bit: the transcendental functions are the four-lane forms
//!   of `shadeops::transcendental` (polynomial kernels, accuracy documented there), whose lanes equal
//!   its scalar functions that the interpreter calls. One call per chunk, never per lane; a uniform
//!   argument is splatted and lane 0 of the result taken.

use super::mask::{choose, konst};
use crate::shadeops::{geom, matrix, noise, transcendental as tm, M4};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{InstBuilder, Value};
use cranelift_frontend::FunctionBuilder;

type B<'a, 'b> = &'a mut FunctionBuilder<'b>;

/// `f32::min`: `a < b ? a : b`, except that a NaN `b` gives `a`.
pub(super) fn min(b: B<'_, '_>, x: Value, y: Value) -> Value {
    let lt = b.ins().fcmp(FloatCC::LessThan, x, y);
    let nan = b.ins().fcmp(FloatCC::Unordered, y, y);
    let c = b.ins().bor(lt, nan);
    choose(b, c, x, y)
}

pub(super) fn max(b: B<'_, '_>, x: Value, y: Value) -> Value {
    let gt = b.ins().fcmp(FloatCC::GreaterThan, x, y);
    let nan = b.ins().fcmp(FloatCC::Unordered, y, y);
    let c = b.ins().bor(gt, nan);
    choose(b, c, x, y)
}

/// `geom::clamp`: `y = x > lo ? x : lo; y < hi ? y : (x >= lo ? hi : lo)`.
pub(super) fn clamp(b: B<'_, '_>, x: Value, lo: Value, hi: Value) -> Value {
    let c = b.ins().fcmp(FloatCC::GreaterThan, x, lo);
    let y = choose(b, c, x, lo);
    let inside = b.ins().fcmp(FloatCC::GreaterThanOrEqual, x, lo);
    let bound = choose(b, inside, hi, lo);
    let c = b.ins().fcmp(FloatCC::LessThan, y, hi);
    choose(b, c, y, bound)
}

/// `geom::sign`.
pub(super) fn sign(b: B<'_, '_>, x: Value) -> Value {
    let zero = konst(b, 0.0, x);
    let one = konst(b, 1.0, x);
    let minus = konst(b, -1.0, x);
    let neg = b.ins().fcmp(FloatCC::LessThan, x, zero);
    let r = choose(b, neg, minus, zero);
    let pos = b.ins().fcmp(FloatCC::GreaterThan, x, zero);
    choose(b, pos, one, r)
}

/// `f32::round`: half away from zero, exactly (`x - trunc(x)` is exact; `trunc` keeps the sign of
/// zero as `f32::round` does).
pub(super) fn round(b: B<'_, '_>, x: Value) -> Value {
    let t = b.ins().trunc(x);
    let d = b.ins().fsub(x, t);
    let ad = b.ins().fabs(d);
    let half = konst(b, 0.5, x);
    let big = b.ins().fcmp(FloatCC::GreaterThanOrEqual, ad, half);
    let one = konst(b, 1.0, x);
    let minus = konst(b, -1.0, x);
    let zero = konst(b, 0.0, x);
    let neg = b.ins().fcmp(FloatCC::LessThan, x, zero);
    let s = choose(b, neg, minus, one);
    let away = b.ins().fadd(t, s);
    choose(b, big, away, t)
}

/// `sqrt` of the language: 0 for `x <= 0` and NaN.
pub(super) fn sqrt(b: B<'_, '_>, x: Value) -> Value {
    let zero = konst(b, 0.0, x);
    let pos = b.ins().fcmp(FloatCC::GreaterThan, x, zero);
    let r = b.ins().sqrt(x);
    choose(b, pos, r, zero)
}

pub(super) fn inversesqrt(b: B<'_, '_>, x: Value) -> Value {
    let zero = konst(b, 0.0, x);
    let one = konst(b, 1.0, x);
    let pos = b.ins().fcmp(FloatCC::GreaterThan, x, zero);
    let r = b.ins().sqrt(x);
    let r = b.ins().fdiv(one, r);
    choose(b, pos, r, zero)
}

/// `geom::step(edge, x)`: `x < edge ? 0 : 1`.
pub(super) fn step(b: B<'_, '_>, edge: Value, x: Value) -> Value {
    let zero = konst(b, 0.0, x);
    let one = konst(b, 1.0, x);
    let lt = b.ins().fcmp(FloatCC::LessThan, x, edge);
    choose(b, lt, zero, one)
}

/// `tm::sincos4` of a chunk, operation for operation (Cody-Waite reduction by pi/4, Cephes'
/// polynomials, sign fix-ups), and whether every lane is within the kernels' range (an `i8`): the
/// lanes outside it (beyond `TRIG_MAX`, or NaN) are wrong here and left to the caller.
pub(super) fn sincos4(b: B<'_, '_>, x: Value) -> (Value, Value, Value) {
    use cranelift_codegen::ir::condcodes::IntCC;
    use cranelift_codegen::ir::{types, MemFlagsData};
    use tm::{COS_POLY, DP1, DP2, DP3, FOPI, SIN_POLY, TRIG_MAX};
    let f = |b: &mut FunctionBuilder<'_>, c: f32| super::mask::fconst(b, c, true);
    let i = |b: &mut FunctionBuilder<'_>, c: i32| {
        let c = b.ins().iconst(types::I32, i64::from(c));
        b.ins().splat(types::I32X4, c)
    };
    let ax = b.ins().fabs(x);
    let in_range = {
        let max = f(b, TRIG_MAX);
        let m = b.ins().fcmp(FloatCC::LessThanOrEqual, ax, max);
        b.ins().vall_true(m)
    };
    // j = (trunc(|x| * 4/pi) + 1) & !1; the conversion matters only on lanes within range (the
    // others take the fallback), where SSE's truncating one (one instruction) and the saturating
    // one (seven on x86-64) agree.
    let fopi = f(b, FOPI);
    let t = b.ins().fmul(ax, fopi);
    let j = if cfg!(target_arch = "x86_64") {
        b.ins().x86_cvtt2dq(types::I32X4, t)
    } else {
        b.ins().fcvt_to_sint_sat(types::I32X4, t)
    };
    let one = i(b, 1);
    let j = b.ins().iadd(j, one);
    let not_one = i(b, !1);
    let j = b.ins().band(j, not_one);
    let y = b.ins().fcvt_from_sint(types::F32X4, j);
    let mut z = ax;
    for dp in [DP1, DP2, DP3] {
        let dp = f(b, dp);
        let yd = b.ins().fmul(y, dp);
        z = b.ins().fsub(z, yd);
    }
    let zz = b.ins().fmul(z, z);
    // sin: ((a * zz + b) * zz - c) * zz * z + z
    let [sa, sb, sc] = SIN_POLY.map(|c| f(b, c));
    let p = b.ins().fmul(sa, zz);
    let p = b.ins().fadd(p, sb);
    let p = b.ins().fmul(p, zz);
    let p = b.ins().fsub(p, sc);
    let p = b.ins().fmul(p, zz);
    let p = b.ins().fmul(p, z);
    let s = b.ins().fadd(p, z);
    // cos: ((a * zz - b) * zz + c) * zz * zz - 0.5 * zz + 1
    let [ca, cb, cc] = COS_POLY.map(|c| f(b, c));
    let q = b.ins().fmul(ca, zz);
    let q = b.ins().fsub(q, cb);
    let q = b.ins().fmul(q, zz);
    let q = b.ins().fadd(q, cc);
    let q = b.ins().fmul(q, zz);
    let q = b.ins().fmul(q, zz);
    let half = f(b, 0.5);
    let h = b.ins().fmul(half, zz);
    let q = b.ins().fsub(q, h);
    let one_f = f(b, 1.0);
    let c = b.ins().fadd(q, one_f);
    // j mod 8: sin is (0) sin, (2) cos, (4) -sin, (6) -cos, negated again for a negative x;
    // cos is (0) cos, (2) -sin, (4) -cos, (6) sin.
    let two = i(b, 2);
    let j2 = b.ins().band(j, two);
    let swapped = b.ins().icmp(IntCC::Equal, j2, two);
    let swapped = super::mask::mask_as_f32(b, swapped);
    let sin_v = b.ins().bitselect(swapped, c, s);
    let cos_v = b.ins().bitselect(swapped, s, c);
    let four = i(b, 4);
    let j4 = b.ins().band(j, four);
    let flip = b.ins().ishl_imm_u(j4, 29);
    let sign_bit = i(b, i32::MIN);
    let little = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
    let xbits = b.ins().bitcast(types::I32X4, little, x);
    let sign = b.ins().band(xbits, sign_bit);
    let sin_sign = b.ins().bxor(sign, flip);
    let sin_sign = b.ins().bitcast(types::F32X4, little, sin_sign);
    let sin_v = b.ins().bxor(sin_v, sin_sign);
    let j_1 = b.ins().ushr_imm_u(j, 1);
    let j_2 = b.ins().ushr_imm_u(j, 2);
    let odd = b.ins().bxor(j_1, j_2);
    let odd = b.ins().band(odd, one);
    let cos_sign = b.ins().ishl_imm_u(odd, 31);
    let cos_sign = b.ins().bitcast(types::F32X4, little, cos_sign);
    let cos_v = b.ins().bxor(cos_v, cos_sign);
    (sin_v, cos_v, in_range)
}

/// `geom::smoothstep(a, b, x)`.
pub(super) fn smoothstep(b: B<'_, '_>, lo: Value, hi: Value, x: Value) -> Value {
    let zero = konst(b, 0.0, x);
    let one = konst(b, 1.0, x);
    let two = konst(b, 2.0, x);
    let three = konst(b, 3.0, x);
    let num = b.ins().fsub(x, lo);
    let den = b.ins().fsub(hi, lo);
    let t = b.ins().fdiv(num, den);
    let tt = b.ins().fmul(t, t);
    let t2 = b.ins().fmul(two, t);
    let k = b.ins().fsub(three, t2);
    let curve = b.ins().fmul(tt, k);
    let ge = b.ins().fcmp(FloatCC::GreaterThanOrEqual, x, hi);
    let r = choose(b, ge, one, curve);
    let lt = b.ins().fcmp(FloatCC::LessThan, x, lo);
    choose(b, lt, zero, r)
}

/// `geom::mix(x, y, a)`: `x * (1 - a) + y * a`.
pub(super) fn mix(b: B<'_, '_>, x: Value, y: Value, a: Value) -> Value {
    let one = konst(b, 1.0, a);
    let ia = b.ins().fsub(one, a);
    let p = b.ins().fmul(x, ia);
    let q = b.ins().fmul(y, a);
    b.ins().fadd(p, q)
}

/// `geom::mod_(a, m)`: `m == 0 ? 0 : a - m * floor(a / m)`.
pub(super) fn modulo(b: B<'_, '_>, a: Value, m: Value) -> Value {
    let zero = konst(b, 0.0, a);
    let q = b.ins().fdiv(a, m);
    let f = b.ins().floor(q);
    let p = b.ins().fmul(m, f);
    let r = b.ins().fsub(a, p);
    let z = b.ins().fcmp(FloatCC::Equal, m, zero);
    choose(b, z, zero, r)
}

/// A per-chunk helper: its symbol, its function and its arity in `f32x4` values.
pub(super) struct Helper {
    pub name: &'static str,
    f: unsafe extern "C" fn(*const f32, *mut f32),
    pub ins: usize,
    pub outs: usize,
}

impl Helper {
    pub fn ptr(&self) -> *const u8 {
        self.f as *const u8
    }
}

/// Runs `f` on each of the four lanes.
///
/// # Safety
/// `input` points to `4 * I` readable floats and `out` to `4 * O` writable ones.
unsafe fn lanes<const I: usize, const O: usize>(input: *const f32, out: *mut f32, f: impl Fn([f32; I]) -> [f32; O]) {
    // SAFETY: the caller's contract.
    let (input, out) =
        unsafe { (std::slice::from_raw_parts(input, 4 * I), std::slice::from_raw_parts_mut(out, 4 * O)) };
    for l in 0..4 {
        let r = f(std::array::from_fn(|k| input[4 * k + l]));
        for (k, v) in r.iter().enumerate() {
            out[4 * k + l] = *v;
        }
    }
}

macro_rules! helpers {
    ($($fname:ident $sym:literal $i:literal -> $o:literal |$args:pat_param| $body:expr;)*) => {
        $(
            /// # Safety
            /// See [`lanes`].
            unsafe extern "C" fn $fname(input: *const f32, out: *mut f32) {
                // SAFETY: generated code passes stack buffers of the declared sizes.
                unsafe { lanes::<$i, $o>(input, out, |$args| $body) }
            }
        )*
        pub(super) static HELPERS: &[Helper] = &[
            $(Helper { name: $sym, f: $fname, ins: $i, outs: $o },)*
        ];
    };
}

helpers! {
    h_cell1 "rtsl_cellnoise1" 1 -> 1 |[x]| [noise::cellnoise1(x)];
    h_cell2 "rtsl_cellnoise2" 2 -> 1 |[x, y]| [noise::cellnoise2(x, y)];
    h_cell3 "rtsl_cellnoise3" 3 -> 1 |[x, y, z]| [noise::cellnoise3([x, y, z])];
    h_cell4 "rtsl_cellnoise4" 4 -> 1 |[x, y, z, t]| [noise::cellnoise4([x, y, z], t)];
    h_vcell1 "rtsl_vcellnoise1" 1 -> 3 |[x]| noise::vcellnoise1(x);
    h_vcell2 "rtsl_vcellnoise2" 2 -> 3 |[x, y]| noise::vcellnoise2(x, y);
    h_vcell3 "rtsl_vcellnoise3" 3 -> 3 |[x, y, z]| noise::vcellnoise3([x, y, z]);
    h_vcell4 "rtsl_vcellnoise4" 4 -> 3 |[x, y, z, t]| noise::vcellnoise4([x, y, z], t);
    h_pnoise1 "rtsl_pnoise1" 2 -> 1 |[x, px]| [noise::pnoise1(x, px)];
    h_pnoise2 "rtsl_pnoise2" 4 -> 1 |[x, y, px, py]| [noise::pnoise2(x, y, px, py)];
    h_pnoise3 "rtsl_pnoise3" 6 -> 1 |x| [noise::pnoise3([x[0], x[1], x[2]], [x[3], x[4], x[5]])];
    h_pnoise4 "rtsl_pnoise4" 8 -> 1 |x| [noise::pnoise4([x[0], x[1], x[2]], x[3], [x[4], x[5], x[6]], x[7])];
    h_vpnoise1 "rtsl_vpnoise1" 2 -> 3 |[x, px]| noise::vpnoise1(x, px);
    h_vpnoise2 "rtsl_vpnoise2" 4 -> 3 |[x, y, px, py]| noise::vpnoise2(x, y, px, py);
    h_vpnoise3 "rtsl_vpnoise3" 6 -> 3 |x| noise::vpnoise3([x[0], x[1], x[2]], [x[3], x[4], x[5]]);
    h_vpnoise4 "rtsl_vpnoise4" 8 -> 3 |x| noise::vpnoise4([x[0], x[1], x[2]], x[3], [x[4], x[5], x[6]], x[7]);
    h_filterstep "rtsl_filterstep" 3 -> 1 |[edge, x, w]| [geom::filterstep(edge, x, w)];
    h_filterstep2 "rtsl_filterstep_interval" 4 -> 1 |[edge, s1, s2, k]| [geom::filterstep_interval(edge, s1, s2, k)];
    h_random "rtsl_random" 3 -> 1 |[lo, hi, k]| [noise::random(random_seed(lo, hi, k))];
    h_vrandom "rtsl_vrandom" 3 -> 3 |[lo, hi, k]| noise::vrandom(random_seed(lo, hi, k));
    h_mmul "rtsl_mmul" 32 -> 16 |x| matrix::mul(&m4(&x, 0), &m4(&x, 16));
    h_mdiv "rtsl_mdiv" 32 -> 16 |x| matrix::div(&m4(&x, 0), &m4(&x, 16));
    h_det "rtsl_determinant" 16 -> 1 |x| [matrix::determinant(&m4(&x, 0))];
    h_xp "rtsl_xform_point" 19 -> 3 |x| matrix::transform_point(&m4(&x, 0), [x[16], x[17], x[18]]);
    h_xv "rtsl_xform_vector" 19 -> 3 |x| matrix::transform_vector(&m4(&x, 0), [x[16], x[17], x[18]]);
    h_xn "rtsl_xform_normal" 19 -> 3 |x| matrix::transform_normal(&m4(&x, 0), [x[16], x[17], x[18]]);
    h_translate "rtsl_translate" 19 -> 16 |x| matrix::translate(&m4(&x, 0), [x[16], x[17], x[18]]);
    h_scale "rtsl_scale" 19 -> 16 |x| matrix::scale(&m4(&x, 0), [x[16], x[17], x[18]]);
    h_rotate "rtsl_rotate" 20 -> 16 |x| matrix::rotate(&m4(&x, 0), x[16], [x[17], x[18], x[19]]);
    h_mcomp "rtsl_mcomp" 18 -> 1 |x| [matrix::comp(&m4(&x, 0), x[16], x[17])];
    h_msetcomp "rtsl_msetcomp" 19 -> 16 |x| { let mut m = m4(&x, 0); matrix::set_comp(&mut m, x[16], x[17], x[18]); m };
    h_rotpt "rtsl_rotate_point" 10 -> 3 |x| geom::rotate_point([x[0], x[1], x[2]], x[3], [x[4], x[5], x[6]], [x[7], x[8], x[9]]);
    h_refract "rtsl_refract" 7 -> 3 |x| geom::refract([x[0], x[1], x[2]], [x[3], x[4], x[5]], x[6]);
    h_fresnel "rtsl_fresnel" 7 -> 8 |x| { let (kr, kt, r, t) = geom::fresnel([x[0], x[1], x[2]], [x[3], x[4], x[5]], x[6]); [kr, kt, r[0], r[1], r[2], t[0], t[1], t[2]] };
    h_ptlined "rtsl_ptlined" 9 -> 1 |[px, py, pz, ax, ay, az, bx, by, bz]| [geom::ptlined([px, py, pz], [ax, ay, az], [bx, by, bz])];
    h_specularbrdf "rtsl_specularbrdf" 10 -> 1 |x| [geom::specular_brdf([x[0], x[1], x[2]], [x[3], x[4], x[5]], [x[6], x[7], x[8]], x[9])];
}

/// The interpreter's seed of a lane's `k`-th `random()`: `seed * 0x9E3779B97F4A7C15 + k`, where the
/// lane's 64-bit seed arrives as two `u32`s and `k` as a `u32`, all in the bits of `f32`s.
fn random_seed(lo: f32, hi: f32, k: f32) -> u64 {
    let seed = u64::from(lo.to_bits()) | (u64::from(hi.to_bits()) << 32);
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(u64::from(k.to_bits()))
}

fn m4(x: &[f32], at: usize) -> M4 {
    std::array::from_fn(|i| x[at + i])
}

/// Runs `f` on the whole chunk at once: argument `k` of lane `l` at `[k][l]`, the same for results.
///
/// # Safety
/// As [`lanes`].
unsafe fn chunk<const I: usize, const O: usize>(
    input: *const f32,
    out: *mut f32,
    f: impl Fn([[f32; 4]; I]) -> [[f32; 4]; O],
) {
    // SAFETY: the caller's contract.
    let (input, out) =
        unsafe { (std::slice::from_raw_parts(input, 4 * I), std::slice::from_raw_parts_mut(out, 4 * O)) };
    let r = f(std::array::from_fn(|k| std::array::from_fn(|l| input[4 * k + l])));
    for (k, v) in r.iter().enumerate() {
        out[4 * k..4 * k + 4].copy_from_slice(v);
    }
}

macro_rules! chunk_helpers {
    ($($fname:ident $sym:literal $i:literal -> $o:literal $body:expr;)*) => {
        $(
            /// # Safety
            /// See [`lanes`].
            unsafe extern "C" fn $fname(input: *const f32, out: *mut f32) {
                // SAFETY: generated code passes stack buffers of the declared sizes.
                unsafe { chunk::<$i, $o>(input, out, $body) }
            }
        )*
        static CHUNK_HELPERS: &[Helper] = &[
            $(Helper { name: $sym, f: $fname, ins: $i, outs: $o },)*
        ];
    };
}

// Helpers written four lanes at a time (`noise::x4`, `transcendental`).
chunk_helpers! {
    h_sin "rtsl_sin" 1 -> 1 |[x]| [tm::sin4(x)];
    h_cos "rtsl_cos" 1 -> 1 |[x]| [tm::cos4(x)];
    h_sincos "rtsl_sincos" 1 -> 2 |[x]| {
        let (sin, cos) = tm::sincos4(x);
        [sin, cos]
    };
    h_tan "rtsl_tan" 1 -> 1 |[x]| [tm::tan4(x)];
    h_asin "rtsl_asin" 1 -> 1 |[x]| [tm::asin4(x)];
    h_acos "rtsl_acos" 1 -> 1 |[x]| [tm::acos4(x)];
    h_atan "rtsl_atan" 1 -> 1 |[x]| [tm::atan4(x)];
    h_atan2 "rtsl_atan2" 2 -> 1 |[y, x]| [tm::atan24(y, x)];
    h_exp "rtsl_exp" 1 -> 1 |[x]| [tm::exp4(x)];
    h_log "rtsl_log" 1 -> 1 |[x]| [tm::ln4(x)];
    h_logb "rtsl_logb" 2 -> 1 |[x, base]| {
        let (a, b) = (tm::ln4(x), tm::ln4(base));
        [std::array::from_fn(|l| a[l] / b[l])]
    };
    h_pow "rtsl_pow" 2 -> 1 |[x, y]| [tm::pow4(x, y)];
    h_noise1 "rtsl_noise1" 1 -> 1 |p| [noise::x4::noise::<1>(p)];
    h_noise2 "rtsl_noise2" 2 -> 1 |p| [noise::x4::noise::<2>(p)];
    h_noise3 "rtsl_noise3" 3 -> 1 |p| [noise::x4::noise::<3>(p)];
    h_noise4 "rtsl_noise4" 4 -> 1 |p| [noise::x4::noise::<4>(p)];
    h_lucille_turb "rtsl_lucille_turb" 3 -> 1 |p| [noise::x4::lucille_turb(p)];
    h_vnoise1 "rtsl_vnoise1" 1 -> 3 noise::x4::vnoise::<1>;
    h_vnoise2 "rtsl_vnoise2" 2 -> 3 noise::x4::vnoise::<2>;
    h_vnoise3 "rtsl_vnoise3" 3 -> 3 noise::x4::vnoise::<3>;
    h_vnoise4 "rtsl_vnoise4" 4 -> 3 noise::x4::vnoise::<4>;
    // `illuminate`'s cone: 1 where the angle between the two vectors is within the third argument.
    h_cone "rtsl_cone" 7 -> 1 |x| {
        let angles = tm::acos4(cosines_between(&x).to_array());
        [std::array::from_fn(|l| if angles[l] > x[6][l] { 0.0 } else { 1.0 })]
    };
}

/// [`super::host::cosine_between`] of four lanes' vectors (rows 0-2 and 3-5 of `x`), by the same
/// operations in each lane: `geom::normalize` (left alone at length 0, else times one over the
/// length), the dot product in component order, and the clamp to `[-1, 1]` (NaN stays NaN).
fn cosines_between(x: &[[f32; 4]; 7]) -> glam::Vec4 {
    use glam::Vec4;
    let row = |k: usize| Vec4::from_array(x[k]);
    let normalized = |v: [Vec4; 3]| {
        let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (zero, inverse) = (length.cmpeq(Vec4::ZERO), Vec4::ONE / length);
        v.map(|c| Vec4::select(zero, c, c * inverse))
    };
    let (a, b) = (normalized([row(0), row(1), row(2)]), normalized([row(3), row(4), row(5)]));
    let c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let c = Vec4::select(c.cmplt(Vec4::splat(-1.0)), Vec4::splat(-1.0), c);
    Vec4::select(c.cmpgt(Vec4::ONE), Vec4::ONE, c)
}

/// Every per-chunk helper.
pub(super) fn helpers() -> impl Iterator<Item = &'static Helper> {
    HELPERS.iter().chain(CHUNK_HELPERS)
}

pub(super) fn helper(name: &str) -> Option<&'static Helper> {
    helpers().find(|h| h.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cone helper's four-lane cosines are the interpreter's, lane by lane, bit for bit: zero,
    /// tiny, huge, infinite and NaN components included. (Any NaN for a NaN: which of two NaN
    /// operands a product or sum returns depends on their order, which the optimiser may swap, and
    /// does in a build for plain x86-64.)
    #[test]
    fn four_lane_cone_cosines_are_the_one_lane_ones() {
        let specials = [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-25, 3e19, -2e38, f32::INFINITY, f32::NAN, 0.5, -7.25];
        let mut h = 0x853c_49e6_748f_ea9bu64;
        for n in 0..100_000u32 {
            let x: [[f32; 4]; 7] = std::array::from_fn(|_| {
                std::array::from_fn(|_| {
                    h ^= h << 13;
                    h ^= h >> 7;
                    h ^= h << 17;
                    if n % 3 == 0 {
                        specials[(h >> 40) as usize % specials.len()]
                    } else {
                        ((h >> 40) as f32 - 8_388_608.0) / 1_048_576.0
                    }
                })
            });
            let c = cosines_between(&x);
            for l in 0..4 {
                let (a, b) = ([x[0][l], x[1][l], x[2][l]], [x[3][l], x[4][l], x[5][l]]);
                let want = super::super::host::cosine_between(a, b);
                if !(c[l].is_nan() && want.is_nan()) {
                    assert_eq!(c[l].to_bits(), want.to_bits(), "{a:?} {b:?}");
                }
            }
        }
    }
}

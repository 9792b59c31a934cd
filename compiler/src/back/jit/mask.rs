//! Masks and the uniform/varying value shapes.
//!
//! Invariants:
//! - A **varying** float is an `f32x4` (one chunk of four lanes); a **uniform** float is an `f32`.
//! - A **varying** bool (a lane mask) is an `i32x4` whose lanes are all ones (-1) or all zeros; a
//!   **uniform** bool is an `i8` that is exactly 0 or 1 (what scalar `fcmp` produces), so `band`,
//!   `bor` and `icmp_imm eq 0` (not) keep it canonical. `bnot` is never applied to a uniform bool.
//! - Masked assignment is `bitselect(mask, new, old)` (one `blendvps` where the host has it): lanes
//!   outside the mask keep the old bits exactly (no arithmetic on them), which is what lets stores
//!   write inactive lanes back unchanged.

use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::FunctionBuilder;

pub(super) fn is_vec(b: &FunctionBuilder<'_>, v: Value) -> bool {
    b.func.dfg.value_type(v).is_vector()
}

/// A float constant shaped like `like` (scalar or `f32x4`).
pub(super) fn konst(b: &mut FunctionBuilder<'_>, x: f32, like: Value) -> Value {
    let vary = is_vec(b, like);
    fconst(b, x, vary)
}

pub(super) fn fconst(b: &mut FunctionBuilder<'_>, x: f32, vary: bool) -> Value {
    let c = b.ins().f32const(x);
    if vary {
        b.ins().splat(types::F32X4, c)
    } else {
        c
    }
}

/// A float made varying (splatted) when `vary` and it is a scalar.
pub(super) fn widen(b: &mut FunctionBuilder<'_>, v: Value, vary: bool) -> Value {
    if vary && !is_vec(b, v) {
        let ty = b.func.dfg.value_type(v);
        if ty == types::I8 {
            return to_mask(b, v);
        }
        b.ins().splat(types::F32X4, v)
    } else {
        v
    }
}

/// A bool as a lane mask: uniform `i8` 0/1 becomes all-zeros/all-ones `i32x4`.
pub(super) fn to_mask(b: &mut FunctionBuilder<'_>, c: Value) -> Value {
    if is_vec(b, c) {
        return c;
    }
    let wide = b.ins().bmask(types::I32, c);
    b.ins().splat(types::I32X4, wide)
}

pub(super) fn mask_as_f32(b: &mut FunctionBuilder<'_>, m: Value) -> Value {
    b.ins().bitcast(types::F32X4, MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little), m)
}

/// `cond ? a : x` for matching shapes: a uniform `i8` condition selects scalars or vectors; a mask
/// selects lanes (`bitselect`).
pub(super) fn choose(b: &mut FunctionBuilder<'_>, cond: Value, a: Value, x: Value) -> Value {
    let vary = is_vec(b, cond) || is_vec(b, a) || is_vec(b, x);
    let a = widen(b, a, vary);
    let x = widen(b, x, vary);
    if is_vec(b, cond) {
        select_lanes(b, cond, a, x)
    } else if vary {
        // A uniform condition between vectors (a space cast's lookup succeeded, a uniform
        // ternary): as a lane mask it is one blend, and the mask, loop-invariant, leaves the chunk
        // loop; a scalar `select` of vectors re-tests the condition with branches in every chunk.
        let mask = widen(b, cond, true);
        select_lanes(b, mask, a, x)
    } else {
        b.ins().select(cond, a, x)
    }
}

/// Lanes of `new` where `mask` is set, `old` elsewhere (bit-exact).
pub(super) fn merge(b: &mut FunctionBuilder<'_>, mask: Value, new: Value, old: Value) -> Value {
    let new = widen(b, new, true);
    select_lanes(b, mask, new, old)
}

/// Lanes of `a` where the lane mask `m` (an `i32x4`) is set, `x` elsewhere. On x86-64 with SSE4.1
/// this is one `blendvps`, which reads only each lane's sign bit (exact for canonical masks, see
/// the invariants above) where the generic `bitselect` takes three instructions (and, and-not,
/// or). Masked assignment is in every varying store, so this is a measurable share of a shader.
fn select_lanes(b: &mut FunctionBuilder<'_>, m: Value, a: Value, x: Value) -> Value {
    let ty = b.func.dfg.value_type(a);
    // Against zero bits (`c ? a : 0`, `c ? 0 : x`: a square root's or a division's guard, a 0/1
    // step) the masked choice is one `and` (or and-not) with the mask, no blend and no zero
    // constant; the same bits, for canonical masks.
    if ty == types::F32X4 || ty == types::I32X4 {
        let (x_zero, a_zero) = (is_zero_vector(b, x), is_zero_vector(b, a));
        if x_zero || a_zero {
            let m = if ty == types::I32X4 { m } else { mask_as_f32(b, m) };
            return if x_zero { b.ins().band(a, m) } else { b.ins().band_not(x, m) };
        }
    }
    if blendv_available() && (ty == types::F32X4 || ty == types::I32X4) {
        let flags = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
        let as_int = |b: &mut FunctionBuilder<'_>, v: Value| {
            if b.func.dfg.value_type(v) == types::I32X4 {
                v
            } else {
                b.ins().bitcast(types::I32X4, flags, v)
            }
        };
        let (m, a, x) = (as_int(b, m), as_int(b, a), as_int(b, x));
        let r = b.ins().blendv(m, a, x);
        return if ty == types::I32X4 { r } else { b.ins().bitcast(ty, flags, r) };
    }
    let m = mask_as_f32(b, m);
    b.ins().bitselect(m, a, x)
}

/// Whether `v` is a vector constant of zero bits (see `invariants::vector_constant`).
fn is_zero_vector(b: &FunctionBuilder<'_>, v: Value) -> bool {
    let dfg = &b.func.dfg;
    let v = dfg.resolve_aliases(v);
    match dfg.value_def(v) {
        cranelift_codegen::ir::ValueDef::Result(def, _) => {
            super::invariants::vector_constant(b.func, def, dfg.value_type(v)) == Some(0)
        }
        _ => false,
    }
}

/// Whether Cranelift lowers `blendv` on this host: x86-64 with SSE4.1 (`cranelift_native`, which
/// builds the JIT's ISA, enables SSE4.1 exactly when the CPU has it).
fn blendv_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static AVAILABLE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *AVAILABLE.get_or_init(|| std::arch::is_x86_feature_detected!("sse4.1"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

pub(super) fn any(b: &mut FunctionBuilder<'_>, m: Value) -> Value {
    b.ins().vany_true(m)
}

pub(super) fn zero_mask(b: &mut FunctionBuilder<'_>) -> Value {
    let z = b.ins().iconst(types::I32, 0);
    b.ins().splat(types::I32X4, z)
}

/// Logical and/or/not of bools of either shape (a uniform operand is widened when the other is a
/// mask).
pub(super) fn and(b: &mut FunctionBuilder<'_>, x: Value, y: Value) -> Value {
    let vary = is_vec(b, x) || is_vec(b, y);
    let (x, y) = (widen(b, x, vary), widen(b, y, vary));
    b.ins().band(x, y)
}

pub(super) fn or(b: &mut FunctionBuilder<'_>, x: Value, y: Value) -> Value {
    let vary = is_vec(b, x) || is_vec(b, y);
    let (x, y) = (widen(b, x, vary), widen(b, y, vary));
    b.ins().bor(x, y)
}

pub(super) fn not(b: &mut FunctionBuilder<'_>, x: Value) -> Value {
    if is_vec(b, x) {
        b.ins().bnot(x)
    } else {
        b.ins().icmp_imm_u(cranelift_codegen::ir::condcodes::IntCC::Equal, x, 0)
    }
}

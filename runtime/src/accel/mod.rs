//! Acceleration structures and their traversal: a two-level BVH.
//!
//! - [`ask_ahead`]: rendering that asks for demand-loaded objects it does not hold and goes on
//!   without them, instead of waiting (a distributed worker renders such a unit again later).
//! - [`binned`]: the default builder of binary BVHs, top-down binned SAH.
//! - [`bvh4`]: the 4-wide node layout shared by both levels, collapsed from a binary BVH (binned
//!   SAH, or obvhs's PLOC for the fastest qualities).
//! - [`bvh8`]: the 8-wide form of an object's BVH that single rays traverse (same leaves).
//! - [`object`]: an object's own BVH over its triangles (built once per geometry change).
//! - [`parts`]: an object's BVH cut into a small tree and parts, as a distributed worker fetches
//!   a large object.
//! - [`store`]: object BVHs shared by scenes, by the geometry they were built from (the frames
//!   of an animation whose set does not move build its BVHs once).
//! - [`top`]: the top-level BVH over instances (rebuilt every frame from the instance list).
//! - [`wire`]: an object's BVH as it travels between processes, checked on arrival.
//! - [`single`]: single-ray traversal (SSE node tests, 8-wide in objects), for incoherent rays.
//! - [`packet`]: packet traversal for coherent packets of 64 rays (interval-arithmetic culling,
//!   ranged first/last-active-chunk traversal, per-lane masks), falling back to [`single`].
//!
//! Invariants: both traversals and the brute-force reference in [`single`] intersect triangles with
//! the same formula ([`crate::geometry::triangle::intersect`]) and use conservative box tests
//! (Ize's robust slab test, with the far distance scaled by `1 + 2 gamma(3)`), so they find the same
//! closest primitive (up to ties at equal `t`) and the same occlusion answers.

pub mod ask_ahead;
pub mod binned;
pub mod bvh4;
pub mod bvh8;
pub mod object;
pub mod packet;
pub mod parts;
pub mod single;
mod stack;
pub mod store;
pub mod top;
pub mod wire;

/// Scales the far distance of slab tests so that rounding never culls a box the ray touches
/// (`1 + 2 gamma(3)`, Ize 2013, "Robust BVH Ray Traversal").
pub(crate) const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// The fused slab test's margin, relative to `o * id`: a plane's distance is taken as
/// `plane * id + c` in one fused multiply-add (one rounding, and one operation fewer on the
/// node-to-node dependency chain than `(plane - o) * id`), where `c` is `-(o * id)` made smaller
/// for near planes and larger for far planes by this share of itself. The two roundings of `c`
/// (`o * id` and the scaling) move it by less than `2^-23` of `o * id`, so a near distance is
/// never above, and a far one never below, the same plane's `(plane - o) * id` before its final
/// rounding: the fused test culls no box that the two-step one would keep ([`ROBUST`]'s bound
/// holds as it is). Without a fused multiply-add instruction the sum's extra rounding is within
/// the same margin and factor.
pub(crate) const FUSED_MARGIN: f32 = 4.0 * f32::EPSILON;

/// The inverse of a direction component, never infinite: components closer to zero than `1e-30`
/// are replaced by `+-1e-30` (keeping the sign), so slab tests never compute `0 * inf`.
#[inline(always)]
pub(crate) fn safe_inv(d: f32) -> f32 {
    const TINY: f32 = 1e-30;
    let d = if d.abs() < TINY {
        if d.is_sign_negative() {
            -TINY
        } else {
            TINY
        }
    } else {
        d
    };
    1.0 / d
}

/// Starts loading the `lines` cache lines at `p` (a hint: no effect on results, none on targets
/// without a prefetch instruction). Traversal of large scenes is bound by cache misses; children
/// that a ray will visit later are prefetched when their parent is tested.
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    for l in 0..lines {
        // SAFETY: prefetching never faults and has no architectural effect, even for addresses
        // outside any allocation; `wrapping_add` keeps the pointer arithmetic defined.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((p as *const i8).wrapping_add(64 * l))
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, lines);
}

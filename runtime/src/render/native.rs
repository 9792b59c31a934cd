//! Surfaces shaded by Rust code instead of a compiled shader ([`NativeSurface`]): the renderer
//! computes the same lights (light shaders over the batch, traced shadows) as for a JIT surface and
//! composites the same way; only the surface's own code differs. `rtsl bench render
//! --native-plastic` uses one, the library's `plastic` written in Rust, to measure what
//! programmability costs.

use glam::Vec3A;

/// A surface shaded by Rust code: `Ci` and `Oi` at one point from `n` (the shading normal), `i`
/// (the incident vector, from the eye to the point), the surface colour and opacity, and the
/// lights that reach the point. The lights are those in the hemisphere around `n` faced against
/// `i` ([`faced_against`]), each as an `illuminance` loop sees it.
pub trait NativeSurface: Send + Sync + std::fmt::Debug {
    fn shade(&self, n: Vec3A, i: Vec3A, cs: Vec3A, os: Vec3A, lights: &[LightSeen]) -> (Vec3A, Vec3A);
}

/// `n` flipped to face against `i`, as `faceforward(N, I)` with `N` its own reference: the side
/// whose lights a native surface gets.
pub fn faced_against(n: Vec3A, i: Vec3A) -> Vec3A {
    if i.dot(n) < 0.0 {
        n
    } else {
        -n
    }
}

/// One light as the surface sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSeen {
    /// From the point towards the light, unnormalised (`L` inside an `illuminance` loop).
    pub l: Vec3A,
    /// The light's colour at the point, its shadow applied (`Cl`).
    pub cl: Vec3A,
    /// An ambient light (no position, no direction): `l` is meaningless.
    pub ambient: bool,
}

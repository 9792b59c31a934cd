//! Hand-written Rust surface shading, the baseline that measures what programmability costs: the
//! library's `plastic` written directly in Rust over the same hits, the same light shaders and the
//! same traced shadows as the JIT path (only the surface shader's own code differs). Used by
//! `rtsl bench render --native-plastic`, never by default.

use glam::Vec3A;

/// A surface shaded by Rust code instead of a compiled shader.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NativeSurface {
    /// RISpec's `plastic`, operation for operation (see `stdlib_shaders/surface/plastic.sl`).
    Plastic { ks: f32, kd: f32, ka: f32, roughness: f32, specular_color: Vec3A },
}

/// `n` flipped to face against `i`, as `faceforward(N, I)` with `N` its own reference: the side
/// whose lights the hand-written surfaces sum.
pub(crate) fn faced_against(n: Vec3A, i: Vec3A) -> Vec3A {
    if i.dot(n) < 0.0 {
        n
    } else {
        -n
    }
}

/// One light as the surface sees it.
pub(crate) struct LightSeen {
    pub l: Vec3A,
    pub cl: Vec3A,
    pub ambient: bool,
}

impl NativeSurface {
    /// `Ci` and `Oi` at one point: `n` the shading normal, `i` the incident vector.
    pub(crate) fn shade(&self, n: Vec3A, i: Vec3A, cs: Vec3A, os: Vec3A, lights: &[LightSeen]) -> (Vec3A, Vec3A) {
        match *self {
            NativeSurface::Plastic { ks, kd, ka, roughness, specular_color } => {
                let nf = faced_against(n.normalize_or_zero(), i);
                let v = -i.normalize_or_zero();
                let (mut ambient, mut diffuse, mut specular) = (Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO);
                let r = if roughness > 0.0 { roughness } else { 1e-4 };
                for light in lights {
                    if light.ambient {
                        ambient += light.cl;
                        continue;
                    }
                    let ln = light.l.normalize_or_zero();
                    // illuminance(P, Nf, PI/2): lights in the hemisphere around Nf.
                    if ln.dot(nf) <= 0.0 {
                        continue;
                    }
                    diffuse += light.cl * ln.dot(nf);
                    let h = (ln + v).normalize_or_zero();
                    specular += light.cl * nf.dot(h).max(0.0).powf(1.0 / r);
                }
                let ci = os * (cs * (ka * ambient + kd * diffuse) + specular_color * ks * specular);
                (ci, os)
            }
        }
    }
}

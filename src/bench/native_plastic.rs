//! The library's `plastic` written in Rust (`rtsl bench render --native-plastic`): the baseline
//! that measures what the JIT's programmability costs, operation for operation as
//! `stdlib_shaders/surface/plastic.sl` computes it.

use rtsl_runtime::glam::Vec3A;
use rtsl_runtime::render::native::{faced_against, LightSeen, NativeSurface};
use rtsl_runtime::shading::ShaderInstance;
use std::sync::Arc;

/// RISpec's `plastic` with one instance's parameter values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NativePlastic {
    pub ks: f32,
    pub kd: f32,
    pub ka: f32,
    pub roughness: f32,
    pub specular_color: Vec3A,
}

impl NativePlastic {
    /// The parameter values of a `plastic` instance (RISpec's defaults where unset).
    pub fn of(surface: &ShaderInstance) -> NativePlastic {
        let float = |name: &str, default: f32| surface.float_param(name).unwrap_or(default);
        NativePlastic {
            ks: float("Ks", 0.5),
            kd: float("Kd", 0.5),
            ka: float("Ka", 1.0),
            roughness: float("roughness", 0.1),
            specular_color: Vec3A::from(surface.triple_param("specularcolor").unwrap_or([1.0; 3])),
        }
    }

    /// [`NativePlastic::of`] as the renderer takes it.
    pub fn shared(surface: &ShaderInstance) -> Arc<dyn NativeSurface> {
        Arc::new(NativePlastic::of(surface))
    }
}

impl NativeSurface for NativePlastic {
    fn shade(&self, n: Vec3A, i: Vec3A, cs: Vec3A, os: Vec3A, lights: &[LightSeen]) -> (Vec3A, Vec3A) {
        let nf = faced_against(n.normalize_or_zero(), i);
        let v = -i.normalize_or_zero();
        let (mut ambient, mut diffuse, mut specular) = (Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO);
        let r = if self.roughness > 0.0 { self.roughness } else { 1e-4 };
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
            specular += light.cl * nf.dot(h).max(0.0).powf(8.0 / r);
        }
        let ci = os * (cs * (self.ka * ambient + self.kd * diffuse) + self.specular_color * self.ks * specular);
        (ci, os)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtsl_runtime::api::Context;
    use rtsl_runtime::render::render_frame;
    use std::path::Path;

    /// The Rust plastic shades as the library's compiled `plastic` does: same lights, same
    /// shadows, same compositing, so the images agree to float rounding (the JIT's `pow` and
    /// `normalize` are not Rust's to the last bit).
    #[test]
    fn rust_plastic_matches_the_compiled_plastic() {
        let rib = r#"
            Format 48 36 1
            Projection "perspective" "fov" 40
            Translate 0 0 5
            WorldBegin
            Attribute "light" "shadows" "on"
            LightSource "ambientlight" 1 "intensity" 0.1
            LightSource "distantlight" 2 "from" [1 2 -3] "to" [0 0 0] "intensity" 0.9
            LightSource "pointlight" 3 "from" [-2 1 -2] "intensity" 6 "lightcolor" [1 0.8 0.6]
            Color [0.8 0.3 0.2]
            Surface "plastic" "Ks" 0.7 "roughness" 0.05 "specularcolor" [0.9 0.9 1]
            Sphere 1 -1 1 360
            Color [0.5 0.6 0.7]
            Surface "plastic" "Kd" 0.8
            Polygon "P" [-3 -1 -2  3 -1 -2  3 -1 3  -3 -1 3]
            WorldEnd
        "#;
        let mut rt = Context::new();
        rtsl_runtime::rib::load::load_str(&mut rt, rib, Path::new("plastic.rib")).expect("the scene loads");
        let mut world = rt.build_world().expect("a world");
        let (compiled, _) = render_frame(&world, None);
        assert_eq!(world.use_native_surface("plastic", NativePlastic::shared), 2);
        let (native, _) = render_frame(&world, None);
        let lit = compiled.rgba.iter().filter(|&&v| v > 0.05).count();
        assert!(lit > compiled.rgba.len() / 4, "the scene is lit: {lit} values");
        let worst = compiled.rgba.iter().zip(&native.rgba).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 2e-3, "largest difference {worst}");
    }
}

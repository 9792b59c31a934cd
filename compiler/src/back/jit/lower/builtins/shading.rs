//! The shading models: `ambient()`, `diffuse()`, `specular()` and `phong()`, summed over the
//! renderer's lights by host helpers, and `specularbrdf()`.

use super::Call;
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::unsupported;
use crate::builtins::Builtin;

impl<'m> Lower<'m, '_> {
    /// The shading models: `ambient`, `diffuse`, `specular` and `phong` over the renderer's lights
    /// (host helpers), and `specularbrdf` (a chunk helper).
    pub(super) fn shading(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let bi = call.bi;
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Specularbrdf => {
                // A colour whose three components are the one weight.
                let all = self.concat(vals);
                let w = self.call_helper("rtsl_specularbrdf", &all.c, all.vary)?;
                Val { vary: all.vary, c: vec![w[0], w[0], w[0]] }
            }
            Bi::Ambient => {
                let p = self.global_val("P")?;
                self.call_helper_on("rtsl_h_ambient", &[p], true)?
            }
            Bi::Diffuse => {
                let p = self.global_val("P")?;
                self.call_helper_on("rtsl_h_diffuse", &[p, v(0)], true)?
            }
            Bi::Specular | Bi::Phong => {
                let p = self.global_val("P")?;
                let name = if bi == Bi::Specular { "rtsl_h_specular" } else { "rtsl_h_phong" };
                self.call_helper_on(name, &[p, v(0), v(1), v(2)], true)?
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

//! What the renderer answers beyond textures and messages, through host helpers: the rays it
//! traces (`trace`, `transmission`, `visibility`, `occlusion`, `indirectdiffuse`), the image's
//! pixels (`pixelvalue`) and its state (`depth`, `raydepth`, `shadername`).

use super::{param_arg, Call};
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::mask::choose;
use crate::back::jit::unsupported;
use crate::builtins::Builtin;
use crate::ir::BaseType;
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::InstBuilder;

impl<'m> Lower<'m, '_> {
    /// Rays and the renderer's state: `trace`, `transmission`, `visibility`, `occlusion`,
    /// `indirectdiffuse`, `pixelvalue`, `depth`, `raydepth` and `shadername`.
    pub(super) fn renderer(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, e, f, fixed) = (call.bi, call.args, call.e, call.f, call.fixed);
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Depth => self.call_helper_on("rtsl_h_depth", &[v(0)], true)?,
            Bi::Raydepth => {
                call.vary = false;
                self.call_helper_on("rtsl_h_raydepth", &[], false)?
            }
            Bi::Shadername => {
                let (kind, has) = if vals.is_empty() { (self.const_string(""), 0.0) } else { (v(0), 1.0) };
                let has = Val { vary: false, c: vec![self.fconst(has, false)] };
                if kind.vary {
                    return unsupported("varying strings");
                }
                call.vary = false;
                self.call_helper_on("rtsl_h_shadername", &[kind, has], false)?
            }
            Bi::Trace => {
                let r = self.call_helper_on("rtsl_h_trace", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    Val { vary: true, c: vec![r.c[3]] }
                } else {
                    Val { vary: true, c: r.c[..3].to_vec() }
                }
            }
            Bi::Transmission => self.call_helper_on("rtsl_h_transmission", &[v(0), v(1)], true)?,
            Bi::Pixelvalue => {
                let c = self.call_helper_on("rtsl_h_pixelvalue", &[v(0), v(1), v(2)], true)?;
                if e.ty.base == BaseType::Float {
                    Val { vary: true, c: vec![c.c[0]] }
                } else {
                    c
                }
            }
            Bi::Visibility => {
                let t = self.call_helper_on("rtsl_h_transmission", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    let zero = self.fconst(0.0, true);
                    let mut any_pos = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[0], zero);
                    for k in 1..3 {
                        let c = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[k], zero);
                        any_pos = self.b.ins().bor(any_pos, c);
                    }
                    let one = self.fconst(1.0, true);
                    Val { vary: true, c: vec![choose(&mut self.b, any_pos, one, zero)] }
                } else {
                    t
                }
            }
            Bi::Occlusion | Bi::Indirectdiffuse => {
                let samples = if fixed == 3 {
                    v(2)
                } else {
                    match param_arg(f, args, fixed, "samples")? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            vals[i].clone()
                        }
                        None => Val { vary: false, c: vec![self.fconst(16.0, false)] },
                    }
                };
                let name = if bi == Bi::Occlusion { "rtsl_h_occlusion" } else { "rtsl_h_indirectdiffuse" };
                // Aqsis's occlusion: an occlusion map's name, then P and N.
                let at = usize::from(fixed == 4);
                self.call_helper_on(name, &[v(at), v(at + 1), samples], true)?
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

//! Textures: `texture` (its footprint from the coordinates' derivatives, as the interpreter
//! computes it), `environment`, `shadow` (the interpreter's query: region, then options),
//! `texture3d`, `bump` and `photonmap` (a uniform map name) through host helpers; `bake3d` and
//! `texture3d` on point clouds report that rtsl does not support them and return their
//! documented value.

use super::{param_arg, Call};
use crate::back::jit::layout::components;
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::mask::widen;
use crate::back::jit::unsupported;
use crate::builtins::Builtin;
use crate::ir::{BaseType, BinaryOp, Type};
use cranelift_codegen::ir::InstBuilder;

impl<'m> Lower<'m, '_> {
    /// Texture lookups: `texture` (with its footprint from derivatives), `environment`, `shadow`,
    /// `texture3d`, `bump`; and the point-cloud built-ins, reported as unsupported.
    pub(super) fn texture(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, e, f, fixed) = (call.bi, call.args, call.e, call.f, call.fixed);
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Texture | Bi::Environment | Bi::Shadow => {
                if vals[0].vary {
                    return unsupported("varying texture names");
                }
                let opt = |s: &mut Self, name: &str, default: f32| -> R<Val> {
                    match param_arg(f, args, fixed, name)? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            Ok(vals[i].clone())
                        }
                        None => Ok(Val { vary: false, c: vec![s.fconst(default, false)] }),
                    }
                };
                // The option `name` where the call gives it, else `fallback` (another option's value).
                let opt_or = |name: &str, fallback: Val| -> R<Val> {
                    Ok(match param_arg(f, args, fixed, name)? {
                        Some(a) => vals[args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0)].clone(),
                        None => fallback,
                    })
                };
                let n = if e.ty.base == BaseType::Float { 1 } else { 3 };
                match bi {
                    Bi::Texture => {
                        let (s_, t_) = match fixed {
                            1 => (self.global_val("s")?, self.global_val("t")?),
                            3 => (v(1), v(2)),
                            _ => {
                                // The centre of the four corners: (a + b + c + d) / 4.
                                let sum = |s: &mut Self, ks: [usize; 4]| -> R<Val> {
                                    let mut acc = vals[ks[0]].clone();
                                    for k in &ks[1..] {
                                        acc = s.binary(BinaryOp::Add, Type::FLOAT, &acc, &vals[*k])?;
                                    }
                                    let four = Val { vary: false, c: vec![s.fconst(4.0, false)] };
                                    s.binary(BinaryOp::Div, Type::FLOAT, &acc, &four)
                                };
                                (sum(self, [1, 3, 5, 7])?, sum(self, [2, 4, 6, 8])?)
                            }
                        };
                        let first = opt(self, "channel", 0.0)?;
                        let fill = opt(self, "fill", 0.0)?;
                        let nv = Val { vary: false, c: vec![self.fconst(n as f32, false)] };
                        // The footprint (the interpreter's `footprint`).
                        let width = opt(self, "width", 1.0)?;
                        let sw = opt_or("swidth", width.clone())?;
                        let tw = opt_or("twidth", width)?;
                        // "sblur" and "tblur" (RISpec), each "blur" where not given.
                        let blur = opt(self, "blur", 0.0)?;
                        let sblur = opt_or("sblur", blur.clone())?;
                        let tblur = opt_or("tblur", blur)?;
                        let d = self.texture_derivs(fixed, vals)?;
                        let fp: Vec<Val> = d
                            .iter()
                            .enumerate()
                            .map(|(k, x)| {
                                let w = if k % 2 == 0 { &sw } else { &tw };
                                let wv = widen(&mut self.b, w.c[0], true);
                                let c = vec![self.b.ins().fmul(x.c[0], wv)];
                                Val { vary: true, c }
                            })
                            .collect();
                        let mut parts = vec![v(0), s_, t_, first, fill, nv];
                        parts.extend(fp);
                        parts.push(sblur);
                        parts.push(tblur);
                        let r = self.call_helper_on("rtsl_h_texture", &parts, true)?;
                        Val { vary: true, c: r.c[..n].to_vec() }
                    }
                    Bi::Environment => {
                        // The interpreter's `environment_query`: the direction and its changes
                        // over a pixel step, then the options, each one float.
                        let first = |x: Val| Val { vary: x.vary, c: x.c[..1].to_vec() };
                        let [dir, ddx, ddy] = self.environment_directions(vals, fixed)?;
                        let blur = first(opt(self, "blur", 0.0)?);
                        let width = first(opt(self, "width", 1.0)?);
                        let mut inputs = vec![v(0), dir, ddx, ddy];
                        for (name, fallback) in
                            [("sblur", &blur), ("tblur", &blur), ("swidth", &width), ("twidth", &width)]
                        {
                            inputs.push(first(opt_or(name, fallback.clone())?));
                        }
                        inputs.push(first(opt(self, "fill", 0.0)?));
                        inputs.push(first(opt(self, "channel", 0.0)?));
                        inputs.push(Val { vary: false, c: vec![self.fconst(n as f32, false)] });
                        let r = self.call_helper_on("rtsl_h_environment", &inputs, true)?;
                        Val { vary: true, c: r.c[..n].to_vec() }
                    }
                    _ => {
                        // The interpreter's `shadow_query`: the region, then the options, each
                        // one float ("sblur" over "blur", "swidth" over "width").
                        let given = |name: &str| -> R<bool> { Ok(param_arg(f, args, fixed, name)?.is_some()) };
                        let first = |x: Val| Val { vary: x.vary, c: x.c[..1].to_vec() };
                        let blur = first(opt(self, "blur", 0.0)?);
                        let width = first(opt(self, "width", 1.0)?);
                        let mut inputs = vec![v(0)];
                        inputs.extend(self.shadow_region(vals, fixed)?);
                        inputs.push(first(opt(self, "samples", 16.0)?));
                        for (name, fallback) in
                            [("sblur", &blur), ("tblur", &blur), ("swidth", &width), ("twidth", &width)]
                        {
                            let x = if given(name)? { first(opt(self, name, 0.0)?) } else { fallback.clone() };
                            inputs.push(x);
                        }
                        // Not given: NaN, for the renderer's default (`ShadowQuery::bias`).
                        inputs.push(first(opt(self, "bias", f32::NAN)?));
                        let r = self.call_helper_on("rtsl_h_shadow", &inputs, true)?;
                        Val { vary: true, c: vec![r.c[0]; n] }
                    }
                }
            }
            Bi::Bump => {
                let (s, t) = (self.global_val("s")?, self.global_val("t")?);
                self.call_helper_on("rtsl_h_bump", &[v(0), s, t, v(1), v(2), v(3)], true)?
            }
            // Point clouds: reported once per call site when a lane runs the
            // call, which returns its documented value (the built-in table) and writes nothing.
            Bi::Photonmap => {
                let n = if fixed == 3 { v(2) } else { Val { vary: false, c: vec![self.fconst(0.0, false); 3] } };
                let estimator = match param_arg(f, args, fixed, "estimator")? {
                    Some(a) => {
                        let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                        vals[i].clone()
                    }
                    None => Val { vary: false, c: vec![self.fconst(50.0, false)] },
                };
                if vals[0].vary {
                    return unsupported("varying photon map names");
                }
                self.call_helper_on("rtsl_h_photonmap", &[v(0), v(1), n, estimator], true)?
            }
            Bi::Bake3d | Bi::Bake | Bi::Texture3d if bi != Bi::Texture3d || fixed != 2 => {
                self.report_unsupported(bi, e.span)?;
                let n = components(e.ty).unwrap_or(1);
                Val { vary: false, c: vec![self.fconst(0.0, false); n] }
            }
            Bi::Texture3d => {
                if vals[0].vary {
                    return unsupported("varying texture names");
                }
                let fill = match param_arg(f, args, fixed, "fill")? {
                    Some(a) => {
                        let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                        vals[i].clone()
                    }
                    None => Val { vary: false, c: vec![self.fconst(0.0, false)] },
                };
                let n = if e.ty.base == BaseType::Float { 1 } else { 3 };
                let r = self.call_helper_on("rtsl_h_texture3d", &[v(0), v(1), fill], true)?;
                Val { vary: true, c: r.c[..n].to_vec() }
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

//! Geometry of triples: `xcomp` to `setcomp` on points, vectors and colours, `length`,
//! `distance`, `normalize`, `ptlined`, `faceforward`, `reflect` (inline, in the interpreter's
//! order), `refract` and `fresnel` (chunk helpers).

use super::Call;
use crate::back::jit::lower::{Idx, Lower, Val, R};
use crate::back::jit::mask::{choose, is_vec, konst, widen};
use crate::back::jit::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::globals::Global;
use crate::ir::{BinaryOp, PlaceBase, Type};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{InstBuilder, Value};

impl<'m> Lower<'m, '_> {
    /// Triples: components, lengths and distances, `normalize`, `ptlined`, `faceforward`,
    /// `reflect`, `refract` and `fresnel`.
    pub(super) fn geometry(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args) = (call.bi, call.args);
        let (vals, refs) = (&call.vals, &call.refs);
        let v = |i: usize| vals[i].clone();
        let void = Val { vary: false, c: Vec::new() };
        let r = match bi {
            Bi::Xcomp | Bi::Ycomp | Bi::Zcomp => {
                let k = [Bi::Xcomp, Bi::Ycomp, Bi::Zcomp].iter().position(|x| *x == bi).unwrap_or(0);
                Val { vary: vals[0].vary, c: vec![vals[0].c[k]] }
            }
            Bi::SetXcomp | Bi::SetYcomp | Bi::SetZcomp => {
                let k = [Bi::SetXcomp, Bi::SetYcomp, Bi::SetZcomp].iter().position(|x| *x == bi).unwrap_or(0);
                let mut t = v(0);
                let x = v(1);
                let vary = t.vary || x.vary;
                t.c[k] = x.c[0];
                let t = self.concat(&[Val { vary, c: t.c }]);
                self.write_ref(refs, &t)?;
                void
            }
            Bi::Comp | Bi::SetComp if vals[0].c.len() != 3 => {
                return unsupported("matrices");
            }
            Bi::Comp => {
                let idx = self.arg_index(args, 1, &vals[1], 3);
                self.select_elem(&v(0), 1, idx)?
            }
            Bi::SetComp => {
                let idx = self.arg_index(args, 1, &vals[1], 3);
                let t = v(0);
                let x = v(2);
                let vary = t.vary || x.vary || matches!(idx, Idx::Dyn(i) if is_vec(&self.b, i));
                let mut c = Vec::new();
                for j in 0..3 {
                    c.push(match self.idx_cond(idx, j) {
                        None => t.c[j],
                        Some(None) => x.c[0],
                        Some(Some(cond)) => choose(&mut self.b, cond, x.c[0], t.c[j]),
                    });
                }
                let t = self.concat(&[Val { vary, c }]);
                self.write_ref(refs, &t)?;
                void
            }
            Bi::Length => {
                let a = v(0);
                let d = self.dot(&a.c, &a.c);
                Val { vary: a.vary, c: vec![self.b.ins().sqrt(d)] }
            }
            Bi::Distance => {
                let d = self.binary(BinaryOp::Sub, Type::POINT, &v(0), &v(1))?;
                let s = self.dot(&d.c, &d.c);
                Val { vary: d.vary, c: vec![self.b.ins().sqrt(s)] }
            }
            Bi::Normalize => {
                let a = v(0);
                let d = self.dot(&a.c, &a.c);
                let len = self.b.ins().sqrt(d);
                let zero = konst(&mut self.b, 0.0, len);
                let one = konst(&mut self.b, 1.0, len);
                let is0 = self.b.ins().fcmp(FloatCC::Equal, len, zero);
                let inv = self.b.ins().fdiv(one, len);
                let c =
                    a.c.iter()
                        .map(|x| {
                            let s = self.b.ins().fmul(*x, inv);
                            choose(&mut self.b, is0, *x, s)
                        })
                        .collect();
                Val { vary: a.vary, c }
            }
            Bi::Ptlined => {
                let all = self.concat(vals);
                let c = self.call_helper("rtsl_ptlined", &all.c, all.vary)?;
                Val { vary: all.vary, c }
            }
            Bi::Faceforward => {
                let nref = if vals.len() == 3 {
                    v(2)
                } else {
                    let g = Global::lookup("Ng").ok_or_else(|| JitError::Codegen("Ng".into()))?;
                    let s = self.store_of(PlaceBase::Global(g))?;
                    self.read_store(&s)
                };
                let (n, i) = (v(0), v(1));
                let vary = n.vary || i.vary || nref.vary;
                let iw: Vec<Value> = i.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let rw: Vec<Value> = nref.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let d = self.dot(&iw, &rw);
                let zero = konst(&mut self.b, 0.0, d);
                let flip = self.b.ins().fcmp(FloatCC::GreaterThan, d, zero);
                let c =
                    n.c.iter()
                        .map(|x| {
                            let neg = self.b.ins().fneg(*x);
                            choose(&mut self.b, flip, neg, *x)
                        })
                        .collect();
                Val { vary, c }
            }
            Bi::Reflect => {
                let (i, n) = (v(0), v(1));
                let vary = i.vary || n.vary;
                let iw: Vec<Value> = i.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let nw: Vec<Value> = n.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                let d = self.dot(&iw, &nw);
                let two = konst(&mut self.b, 2.0, d);
                let s = self.b.ins().fmul(two, d);
                let c = iw
                    .iter()
                    .zip(&nw)
                    .map(|(p, q)| {
                        let m = self.b.ins().fmul(*q, s);
                        self.b.ins().fsub(*p, m)
                    })
                    .collect();
                Val { vary, c }
            }
            Bi::Refract => self.call_helper_on("rtsl_refract", &[v(0), v(1), v(2)], false)?,
            Bi::Fresnel => {
                let r = self.call_helper_on("rtsl_fresnel", &[v(0), v(1), v(2)], false)?;
                let part = |a: usize, b: usize| Val { vary: r.vary, c: r.c[a..b].to_vec() };
                for (k, (a, b)) in [(3, (0, 1)), (4, (1, 2)), (5, (2, 5)), (6, (5, 8))] {
                    if let Some(Some(t)) = refs.get(k) {
                        self.write_targets(t, &part(a, b))?;
                    }
                }
                void
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

//! Matrices and coordinate spaces: the renderer's space matrices (looked up once per pair of
//! constant names in the prologue), space casts, points and vectors transformed inline in
//! `shadeops::matrix`'s order, and the matrix built-ins (`comp`/`setcomp` on matrices, `rotate`,
//! `translate`, `scale`, `determinant`, `transform` and its kin, `ctransform`).

use super::Call;
use crate::back::jit::lower::{constant_bits, Lower, Val, R};
use crate::back::jit::mask::{and, choose, is_vec, konst, widen};
use crate::back::jit::unsupported;
use crate::builtins::Builtin;
use crate::ir::{BaseType, ExprId};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, Value};
use cranelift_frontend::Variable;

impl<'m> Lower<'m, '_> {
    /// Matrices and spaces: matrix components, `rotate`, `translate`, `scale`, `determinant`,
    /// `transform`, `vtransform`, `ntransform`, `mtransform` and `ctransform`.
    pub(super) fn transform(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, e) = (call.bi, call.e);
        let (vals, refs) = (&call.vals, &call.refs);
        let v = |i: usize| vals[i].clone();
        let void = Val { vary: false, c: Vec::new() };
        let r = match bi {
            Bi::Comp => {
                let r = self.call_helper_on("rtsl_mcomp", &[v(0), v(1), v(2)], false)?;
                Val { vary: r.vary, c: r.c }
            }
            Bi::SetComp => {
                let m = self.call_helper_on("rtsl_msetcomp", &[v(0), v(1), v(2), v(3)], false)?;
                self.write_ref(refs, &m)?;
                void
            }
            Bi::Rotate if e.ty.base == BaseType::Matrix => {
                self.call_helper_on("rtsl_rotate", &[v(0), v(1), v(2)], false)?
            }
            Bi::Rotate => self.call_helper_on("rtsl_rotate_point", &[v(0), v(1), v(2), v(3)], false)?,
            Bi::Translate => self.call_helper_on("rtsl_translate", &[v(0), v(1)], false)?,
            Bi::Scale => self.call_helper_on("rtsl_scale", &[v(0), v(1)], false)?,
            Bi::Determinant => self.call_helper_on("rtsl_determinant", &[v(0)], false)?,
            Bi::Transform | Bi::Vtransform | Bi::Ntransform => {
                let name = match bi {
                    Bi::Transform => "rtsl_xform_point",
                    Bi::Vtransform => "rtsl_xform_vector",
                    _ => "rtsl_xform_normal",
                };
                let p = v(vals.len() - 1);
                let (m, ok) = match vals.len() {
                    2 if call.is_matrix_arg(0) => {
                        let t = self.b.ins().iconst(types::I8, 1);
                        (v(0), t)
                    }
                    2 => {
                        let cur = self.const_string("current");
                        self.space_matrix(&cur, &v(0))?
                    }
                    _ if call.is_matrix_arg(1) => {
                        let cur = self.const_string("current");
                        let (to_current, ok) = self.space_matrix(&v(0), &cur)?;
                        // Into "current", then through the matrix (as the interpreter).
                        let m = self.call_helper_on("rtsl_mmul", &[to_current, v(1)], false)?;
                        (m, ok)
                    }
                    _ => self.space_matrix(&v(0), &v(1))?,
                };
                self.apply_if(name, ok, &m, &p, &p)?
            }
            Bi::Mtransform => {
                let m = v(vals.len() - 1);
                let (space, ok) = if vals.len() == 3 {
                    self.space_matrix(&v(0), &v(1))?
                } else {
                    let cur = self.const_string("current");
                    self.space_matrix(&cur, &v(0))?
                };
                self.apply_if("rtsl_mmul", ok, &m, &space, &m)?
            }
            Bi::Ctransform => {
                let c = v(vals.len() - 1);
                let three = vals.len() == 3;
                let b = if three { v(1) } else { v(0) };
                let flag = self.fconst(if three { 1.0 } else { 0.0 }, false);
                let flag = Val { vary: false, c: vec![flag] };
                self.call_helper_on("rtsl_h_ctransform", &[v(0), b, c, flag], false)?
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }

    /// The matrix from space `from` to `to` (uniform) and whether the renderer knows it.
    pub(in crate::back::jit::lower) fn space_matrix(&mut self, from: &Val, to: &Val) -> R<(Val, Value)> {
        if from.vary || to.vary {
            return unsupported("varying space names");
        }
        let names = constant_bits(&self.b, from.c[0]).zip(constant_bits(&self.b, to.c[0]));
        if let (Some(names), Some(known)) = (names, &self.prologue_matrices) {
            if let Some((_, m)) = known.iter().find(|(k, _)| *k == names) {
                return Ok(m.clone());
            }
        }
        let out = self.call_helper("rtsl_h_matrix", &[from.c[0], to.c[0]], false)?;
        let zero = self.b.ins().f32const(0.0);
        let ok = self.b.ins().fcmp(FloatCC::NotEqual, out[16], zero);
        let m = (Val { vary: false, c: out[..16].to_vec() }, ok);
        if let (Some(names), Some(known)) = (names, &mut self.prologue_matrices) {
            known.push((names, m.clone()));
        }
        Ok(m)
    }

    /// The prologue's matrix for the space name `space`, in the shader body itself.
    pub(in crate::back::jit::lower) fn batch_matrix(&self, space: ExprId) -> Option<(Val, Value)> {
        if self.frames.len() == 1 {
            self.batch_matrices.get(&space.0).cloned()
        } else {
            None
        }
    }

    /// `v` cast from `space` to "current"; `matrix` is that transform when already known.
    pub(in crate::back::jit::lower) fn space_cast(
        &mut self,
        ty: BaseType,
        space: &Val,
        v: Val,
        matrix: Option<(Val, Value)>,
    ) -> R<Val> {
        if ty == BaseType::Color {
            if space.vary {
                return unsupported("varying space names");
            }
            let all = self.concat(&[space.clone(), v]);
            let c = self.call_helper("rtsl_h_to_rgb", &all.c, all.vary)?;
            return Ok(Val { vary: all.vary, c });
        }
        let (m, ok) = match matrix {
            Some(m) => m,
            None => {
                let current = self.const_string("current");
                self.space_matrix(space, &current)?
            }
        };
        match ty {
            // mul(v, m): the value first.
            BaseType::Matrix => self.apply_if("rtsl_mmul", ok, &v, &m, &v),
            BaseType::Point => self.apply_if("rtsl_xform_point", ok, &m, &v, &v),
            BaseType::Vector => self.apply_if("rtsl_xform_vector", ok, &m, &v, &v),
            BaseType::Normal => self.apply_if("rtsl_xform_normal", ok, &m, &v, &v),
            _ => unsupported(format!("a space cast of {ty}")),
        }
    }

    /// `helper(a, b)` where `ok`, else `fallback` (of the result's size).
    pub(in crate::back::jit::lower) fn apply_if(
        &mut self,
        helper: &'static str,
        ok: Value,
        a: &Val,
        b: &Val,
        fallback: &Val,
    ) -> R<Val> {
        if let Some(point) = match helper {
            "rtsl_xform_point" => Some(true),
            "rtsl_xform_vector" => Some(false),
            _ => None,
        } {
            let vary = a.vary || b.vary || fallback.vary;
            if vary && !is_vec(&self.b, ok) {
                // A uniform lookup result: one branch around the transform, not a blend per
                // component in every chunk.
                let ty = types::F32X4;
                let (found, join) = (self.b.create_block(), self.b.create_block());
                let params: Vec<Value> = fallback.c.iter().map(|_| self.b.append_block_param(join, ty)).collect();
                let kept: Vec<cranelift_codegen::ir::BlockArg> =
                    fallback.c.iter().map(|x| widen(&mut self.b, *x, true).into()).collect();
                self.b.ins().brif(ok, found, &[], join, &kept);
                self.b.switch_to_block(found);
                self.b.seal_block(found);
                let r = self.transform_inline(a, b, point);
                let made: Vec<cranelift_codegen::ir::BlockArg> =
                    r.c.iter().map(|x| widen(&mut self.b, *x, true).into()).collect();
                self.b.ins().jump(join, &made);
                self.b.switch_to_block(join);
                self.b.seal_block(join);
                return Ok(Val { vary: true, c: params });
            }
            let r = self.transform_inline(a, b, point);
            let c = r.c.iter().zip(&fallback.c).map(|(x, y)| choose(&mut self.b, ok, *x, *y)).collect();
            return Ok(Val { vary: r.vary || fallback.vary, c });
        }
        let all = self.concat(&[a.clone(), b.clone()]);
        let r = self.call_helper(helper, &all.c, all.vary)?;
        let c = r.iter().zip(&fallback.c).map(|(x, y)| choose(&mut self.b, ok, *x, *y)).collect();
        Ok(Val { vary: all.vary || fallback.vary, c })
    }

    /// `p` times the 4x4 matrix `m` in the code itself, by the operations of
    /// `shadeops::matrix::transform_point` (or `transform_vector`, without translation and divide)
    /// in their order, so the same bits: a helper call would move 19 values a lane through memory
    /// for 12 multiply-adds, and space casts sit in the inner loops of most shaders.
    fn transform_inline(&mut self, m: &Val, p: &Val, point: bool) -> Val {
        let vary = m.vary || p.vary;
        // The matrix's own (scalar) entries when it is uniform.
        let uniform_m = (!m.vary).then(|| m.c.clone());
        let m: Vec<Value> = m.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
        let p: Vec<Value> = p.c.iter().map(|x| widen(&mut self.b, *x, vary)).collect();
        let mut out: Vec<Value> = (0..3).map(|j| self.transform_column(&m, &p, j, point)).collect();
        if !point {
            return Val { vary, c: out };
        }
        match uniform_m {
            // A uniform affine matrix (last column 0 0 0 1) makes w 1, or NaN where p is not
            // finite: no division either way, so that case skips the w column and the divisions
            // (space casts to "camera" or "shader" space are mostly of this kind).
            Some(um) => {
                let ty = self.b.func.dfg.value_type(out[0]);
                let vars: Vec<Variable> = out
                    .iter()
                    .map(|x| {
                        let v = self.b.declare_var(ty);
                        self.b.def_var(v, *x);
                        v
                    })
                    .collect();
                let mut affine = None;
                for (k, want) in [(3, 0.0), (7, 0.0), (11, 0.0), (15, 1.0)] {
                    let c = self.b.ins().f32const(want);
                    let eq = self.b.ins().fcmp(FloatCC::Equal, um[k], c);
                    affine = Some(match affine {
                        Some(a) => self.b.ins().band(a, eq),
                        None => eq,
                    });
                }
                let affine = affine.expect("four entries");
                let (divide_b, join) = (self.b.create_block(), self.b.create_block());
                self.b.ins().brif(affine, join, &[], divide_b, &[]);
                self.b.switch_to_block(divide_b);
                let divided = self.divide_by_w(&m, &p, &out);
                for (v, x) in vars.iter().zip(divided) {
                    self.b.def_var(*v, x);
                }
                self.b.ins().jump(join, &[]);
                self.b.switch_to_block(join);
                out = vars.iter().map(|v| self.b.use_var(*v)).collect();
            }
            None => out = self.divide_by_w(&m, &p, &out),
        }
        Val { vary, c: out }
    }

    /// Column `j` of `p` (with a 1 appended for a point) times `m`, in `transform_point`'s order.
    fn transform_column(&mut self, m: &[Value], p: &[Value], j: usize, point: bool) -> Value {
        let mut sum = self.b.ins().fmul(p[0], m[j]);
        for (k, pk) in p.iter().enumerate().skip(1) {
            let term = self.b.ins().fmul(*pk, m[4 * k + j]);
            sum = self.b.ins().fadd(sum, term);
        }
        if point {
            sum = self.b.ins().fadd(sum, m[12 + j]);
        }
        sum
    }

    /// `xyz` divided by the point's w (`transform_column` 3) unless w is 1, 0 or not finite.
    fn divide_by_w(&mut self, m: &[Value], p: &[Value], xyz: &[Value]) -> Vec<Value> {
        let w = self.transform_column(m, p, 3, true);
        let one = konst(&mut self.b, 1.0, w);
        let zero = konst(&mut self.b, 0.0, w);
        let inf = konst(&mut self.b, f32::INFINITY, w);
        let not_one = self.b.ins().fcmp(FloatCC::NotEqual, w, one);
        let not_zero = self.b.ins().fcmp(FloatCC::NotEqual, w, zero);
        let abs = self.b.ins().fabs(w);
        let finite = self.b.ins().fcmp(FloatCC::LessThan, abs, inf);
        let divide = and(&mut self.b, not_one, not_zero);
        let divide = and(&mut self.b, divide, finite);
        xyz.iter()
            .map(|x| {
                let q = self.b.ins().fdiv(*x, w);
                choose(&mut self.b, divide, q, *x)
            })
            .collect()
    }
}

//! Math built-ins: the scalar and component-wise functions (`abs` to `smoothstep`), `filterstep`
//! over the filter width from derivatives, and `spline` (segment and weights from a host helper,
//! the knots selected and summed inline).

use super::{param_arg, Call};
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::mask::{choose, konst, widen};
use crate::back::jit::{math, unsupported};
use crate::builtins::Builtin;
use crate::ir::{Arg, BaseType, BinaryOp, Type};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{InstBuilder, Value};

impl<'m> Lower<'m, '_> {
    /// Scalar and component-wise math: `abs` to `smoothstep` (instructions, or the chunk helpers
    /// of `math.rs` for the transcendental functions), and `filterstep`.
    pub(super) fn math(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, f, fixed) = (call.bi, call.args, call.f, call.fixed);
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Abs => self.map1(&v(0), |b, x| b.ins().fabs(x)),
            Bi::Sign => self.map1(&v(0), math::sign),
            Bi::Floor => self.map1(&v(0), |b, x| b.ins().floor(x)),
            Bi::Ceil => self.map1(&v(0), |b, x| b.ins().ceil(x)),
            Bi::Round => self.map1(&v(0), math::round),
            Bi::Sqrt => self.map1(&v(0), math::sqrt),
            Bi::InverseSqrt => self.map1(&v(0), math::inversesqrt),
            Bi::Exp => self.map_helper("rtsl_exp", &v(0))?,
            Bi::Log if vals.len() == 2 => self.map2_helper("rtsl_logb", &v(0), &v(1))?,
            Bi::Log => self.map_helper("rtsl_log", &v(0))?,
            Bi::Pow => self.map2_helper("rtsl_pow", &v(0), &v(1))?,
            Bi::Sin => self.sin_cos(&v(0), 0)?,
            Bi::Cos => self.sin_cos(&v(0), 1)?,
            Bi::Tan => self.map_helper("rtsl_tan", &v(0))?,
            Bi::Asin => self.map_helper("rtsl_asin", &v(0))?,
            Bi::Acos => self.map_helper("rtsl_acos", &v(0))?,
            Bi::Atan if vals.len() == 2 => self.map2_helper("rtsl_atan2", &v(0), &v(1))?,
            Bi::Atan => self.map_helper("rtsl_atan", &v(0))?,
            Bi::Radians | Bi::Degrees => {
                let k = if bi == Bi::Radians { 1.0f32.to_radians() } else { 1.0f32.to_degrees() };
                let a = v(0);
                let kc = self.fconst(k, a.vary);
                Val { vary: a.vary, c: a.c.iter().map(|x| self.b.ins().fmul(*x, kc)).collect() }
            }
            Bi::Mod => self.mapn(&[&v(0), &v(1)], |b, a| math::modulo(b, a[0], a[1])),
            Bi::Min | Bi::Max => {
                let mut acc = v(0);
                for x in &vals[1..] {
                    acc = if bi == Bi::Min {
                        self.mapn(&[&acc, x], |b, a| math::min(b, a[0], a[1]))
                    } else {
                        self.mapn(&[&acc, x], |b, a| math::max(b, a[0], a[1]))
                    };
                }
                acc
            }
            Bi::Clamp => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::clamp(b, a[0], a[1], a[2])),
            Bi::Mix => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::mix(b, a[0], a[1], a[2])),
            Bi::Step => self.mapn(&[&v(0), &v(1)], |b, a| math::step(b, a[0], a[1])),
            Bi::Smoothstep => self.mapn(&[&v(0), &v(1), &v(2)], |b, a| math::smoothstep(b, a[0], a[1], a[2])),
            Bi::Filterstep => {
                // The "width" parameter (RISpec: also "swidth") multiplies the width filtered.
                let mut scale = None;
                for name in ["width", "swidth"] {
                    if let (None, Some(a)) = (&scale, param_arg(f, args, fixed, name)?) {
                        let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                        scale = Some(vals[i].clone());
                    }
                }
                if fixed == 3 {
                    let scale = match scale {
                        Some(scale) => scale,
                        None => Val { vary: false, c: vec![self.fconst(1.0, false)] },
                    };
                    self.call_helper_on("rtsl_filterstep_interval", &[v(0), v(1), v(2), scale], false)?
                } else {
                    let mut width = self.filter_width(1)?;
                    if let Some(scale) = scale {
                        width = self.binary(BinaryOp::Mul, Type::FLOAT, &width, &scale)?;
                    }
                    self.call_helper_on("rtsl_filterstep", &[v(0), v(1), width], false)?
                }
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }

    /// `spline([basis,] x, knots... | knots[])`: the host helper finds each lane's segment and its
    /// four weights (`shadeops::spline::Basis::weights`, the interpreter's code); the knots are
    /// selected per lane and summed here in the interpreter's order
    /// (`w0 k[s] + w1 k[s+1] + w2 k[s+2] + w3 k[s+3]`). Fewer than 4 knots give the first one.
    pub(super) fn spline(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        let (args, vals, e) = (call.args, &call.vals, call.e);
        let f = self.func();
        let has_basis = match &args[0] {
            Arg::Value(x) => f.expr(*x).ty.base == BaseType::String,
            Arg::Ref(p) => p.ty.base == BaseType::String,
        };
        let (basis, rest) = if has_basis { (vals[0].clone(), 1) } else { (self.const_string(""), 0) };
        if basis.vary {
            return unsupported("varying strings");
        }
        let x = vals[rest].clone();
        let comps = if e.ty.base == BaseType::Float { 1 } else { 3 };
        let knots = self.concat(&vals[rest + 1..]);
        let n = knots.c.len() / comps;
        if n < 4 {
            return Ok(match n {
                0 => Val { vary: false, c: vec![self.fconst(0.0, false); comps] },
                _ => Val { vary: knots.vary, c: knots.c[..comps].to_vec() },
            });
        }
        let nv = self.fconst(n as f32, false);
        let w = self.call_helper("rtsl_h_spline", &[basis.c[0], x.c[0], nv], x.vary)?;
        let vary = x.vary || knots.vary;
        let w: Vec<Value> = w.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let k: Vec<Value> = knots.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        // Segment starts 1..=n-4 (0 is the default of every select).
        let mut at = Vec::with_capacity(n - 3);
        for s in 1..=n - 4 {
            let sc = konst(&mut self.b, s as f32, w[0]);
            at.push(self.b.ins().fcmp(FloatCC::Equal, w[0], sc));
        }
        let mut c = Vec::with_capacity(comps);
        for j in 0..comps {
            let mut sum: Option<Value> = None;
            for i in 0..4 {
                let mut pick = k[i * comps + j];
                for (s, eq) in at.iter().enumerate() {
                    pick = choose(&mut self.b, *eq, k[(s + 1 + i) * comps + j], pick);
                }
                let term = self.b.ins().fmul(w[1 + i], pick);
                sum = Some(match sum {
                    None => term,
                    Some(acc) => self.b.ins().fadd(acc, term),
                });
            }
            c.push(sum.expect("four terms"));
        }
        Ok(Val { vary, c })
    }
}

//! Expressions: constants, variables, operators (in the interpreter's order), conversions,
//! selects and short-circuit logic under masks; and calls of user functions, inlined with the
//! interpreter's copy-in/copy-out semantics (in uniform mode where the call allows it).

use super::deriv::Dual;
use super::stmt::{divergent_return, may_write};
use super::{Idx, Lower, Val, R};
use crate::back::jit::layout::components;
use crate::back::jit::mask::{and, choose, fconst, is_vec, konst, not, or, to_mask, widen};
use crate::back::jit::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{self, Arg, BaseType, BinaryOp, Constant, ExprId, ExprKind, FuncId, PlaceBase, Type, UnaryOp};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::{FunctionBuilder, Variable};

impl<'m> Lower<'m, '_> {
    pub(super) fn fconst(&mut self, x: f32, vary: bool) -> Value {
        fconst(&mut self.b, x, vary)
    }

    pub(super) fn expr(&mut self, id: ExprId) -> R<Val> {
        // The prologue's values, in the shader body itself (inlined functions have ids of their own).
        if self.frames.len() == 1 {
            if let Some(v) = self.batch_consts.get(&id.0) {
                return Ok(v.clone());
            }
        }
        if !self.cache.is_empty() {
            if let Some(v) = self.cache.get(&(self.frames.len(), id.0)) {
                return Ok(v.clone());
            }
        }
        let f = self.func();
        let e = f.expr(id);
        let marked = self.info.expr(self.frame().fid, id);
        match &e.kind {
            ExprKind::Assign { .. } | ExprKind::Call { .. } if marked => return Ok(self.dual(id)?.v),
            ExprKind::CallBuiltin { builtin, overload, args }
                if ir::deriv::is_deriv_builtin(*builtin) || matches!(builtin, Builtin::Texture | Builtin::Shadow | Builtin::Environment) =>
            {
                return Ok(self.builtin_dual(*builtin, *overload, args, e, false)?.v)
            }
            _ => {}
        }
        match &e.kind {
            ExprKind::Const(Constant::Float(x)) => Ok(Val { vary: false, c: vec![self.b.ins().f32const(*x)] }),
            ExprKind::Const(Constant::String(x)) => {
                let h = self.string_handle(x);
                Ok(Val { vary: false, c: vec![self.b.ins().f32const(f32::from_bits(h))] })
            }
            ExprKind::Var(v) => {
                let s = self.store_of(PlaceBase::Var(*v))?;
                Ok(self.read_store(&s))
            }
            ExprKind::Global(g) => {
                let s = self.store_of(PlaceBase::Global(*g))?;
                Ok(self.read_store(&s))
            }
            ExprKind::Index { base, index } => {
                let bt = f.expr(*base).ty;
                let bv = self.expr(*base)?;
                let comps = if bt.is_array() { components(bt.element()).unwrap_or(1) } else { 1 };
                let n = bv.c.len() / comps;
                let idx = self.index(*index, n)?;
                self.select_elem(&bv, comps, idx)
            }
            ExprKind::Unary { op: UnaryOp::Neg, arg } => {
                let a = self.expr(*arg)?;
                if !(e.ty.base.is_numeric() || e.ty.base == BaseType::Matrix) {
                    return unsupported(format!("negation of {}", e.ty));
                }
                Ok(Val { vary: a.vary, c: a.c.iter().map(|x| self.b.ins().fneg(*x)).collect() })
            }
            ExprKind::Unary { op: UnaryOp::Not, arg } => {
                let a = self.expr(*arg)?;
                Ok(Val { vary: a.vary, c: vec![not(&mut self.b, a.c[0])] })
            }
            ExprKind::Binary { op: op @ (BinaryOp::And | BinaryOp::Or), lhs, rhs } => {
                self.logic(*op, *lhs, *rhs, e.varying)
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let lt = f.expr(*lhs).ty;
                let a = self.expr(*lhs)?;
                let b = self.expr(*rhs)?;
                self.binary(*op, lt, &a, &b)
            }
            ExprKind::Convert { arg } => {
                let from = f.expr(*arg).ty;
                let a = self.expr(*arg)?;
                self.convert(a, from, e.ty)
            }
            ExprKind::Construct { args } => {
                let mut vals = Vec::new();
                for a in args {
                    vals.push(self.expr(*a)?);
                }
                Ok(self.concat(&vals))
            }
            ExprKind::SpaceCast { space, arg } => {
                let sp = self.expr(*space)?;
                let v = self.expr(*arg)?;
                let m = self.batch_matrix(*space);
                self.space_cast(e.ty.base, &sp, v, m)
            }
            ExprKind::Select { cond, a, b } => self.select(e, *cond, *a, *b),
            ExprKind::CallBuiltin { builtin, overload, args } => self.builtin(*builtin, *overload, args, e),
            ExprKind::Call { func, args } => Ok(self.call(*func, args, e)?.v),
            ExprKind::Assign { place, op, value } => {
                let v = self.expr(*value)?;
                let t = self.place_targets(place)?;
                let stored = match op {
                    Some(op) => {
                        let cur = self.read_targets(&t)?;
                        self.binary(*op, place.ty, &cur, &v)?
                    }
                    None => v,
                };
                self.write_targets(&t, &stored)?;
                Ok(stored)
            }
            ExprKind::ArrayLiteral { elements } => {
                let mut vals = Vec::new();
                for el in elements {
                    vals.push(self.expr(*el)?);
                }
                Ok(self.concat(&vals))
            }
        }
    }

    /// Components of several values in order, all varying if any is.
    pub(super) fn concat(&mut self, vals: &[Val]) -> Val {
        let vary = vals.iter().any(|v| v.vary);
        let c = vals.iter().flat_map(|v| v.c.iter().copied()).collect::<Vec<_>>();
        Val { vary, c: c.into_iter().map(|x| widen(&mut self.b, x, vary)).collect() }
    }

    pub(super) fn select_elem(&mut self, bv: &Val, comps: usize, idx: Idx) -> R<Val> {
        let n = bv.c.len() / comps.max(1);
        match idx {
            Idx::Const(k) => Ok(Val { vary: bv.vary, c: bv.c[k * comps..(k + 1) * comps].to_vec() }),
            Idx::Dyn(i) => {
                let vary = bv.vary || is_vec(&self.b, i);
                let mut c: Vec<Value> = bv.c[..comps].iter().map(|x| widen(&mut self.b, *x, vary)).collect();
                for k in 1..n {
                    let kc = konst(&mut self.b, k as f32, i);
                    let eq = self.b.ins().fcmp(FloatCC::Equal, i, kc);
                    for (j, cj) in c.iter_mut().enumerate() {
                        *cj = choose(&mut self.b, eq, bv.c[k * comps + j], *cj);
                    }
                }
                Ok(Val { vary, c })
            }
        }
    }

    fn logic(&mut self, op: BinaryOp, lhs: ExprId, rhs: ExprId, vary_flag: bool) -> R<Val> {
        let l = self.expr(lhs)?;
        if l.vary || (vary_flag && !self.frame().uniform) {
            let lm = to_mask(&mut self.b, l.c[0]);
            let save = self.exec();
            let m = if op == BinaryOp::And { self.b.ins().band(save, lm) } else { self.b.ins().band_not(save, lm) };
            self.set_exec(m);
            self.div += 1;
            self.vdepth += 1;
            let r = self.expr(rhs);
            self.div -= 1;
            self.vdepth -= 1;
            self.set_exec(save);
            let r = r?;
            let rm = to_mask(&mut self.b, r.c[0]);
            let res = if op == BinaryOp::And { self.b.ins().band(lm, rm) } else { self.b.ins().bor(lm, rm) };
            return Ok(Val { vary: true, c: vec![res] });
        }
        let res = self.b.declare_var(types::I8);
        self.b.def_var(res, l.c[0]);
        let (rb, join) = (self.b.create_block(), self.b.create_block());
        if op == BinaryOp::And {
            self.b.ins().brif(l.c[0], rb, &[], join, &[]);
        } else {
            self.b.ins().brif(l.c[0], join, &[], rb, &[]);
        }
        self.b.switch_to_block(rb);
        let r = self.expr(rhs)?;
        if r.vary {
            return unsupported("a varying operand of a uniform && or ||");
        }
        self.b.def_var(res, r.c[0]);
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(Val { vary: false, c: vec![self.b.use_var(res)] })
    }

    fn select(&mut self, e: &ir::Expr, cond: ExprId, a: ExprId, b: ExprId) -> R<Val> {
        let f = self.func();
        let c = self.expr(cond)?;
        let n = match e.ty.base {
            BaseType::Bool => 1,
            _ => components(e.ty).ok_or_else(|| JitError::Unsupported(format!("a select of {}", e.ty)))?,
        } * e.ty.array_len().unwrap_or(1) as usize;
        if c.vary || (f.expr(cond).varying && !self.frame().uniform) {
            let cm = to_mask(&mut self.b, c.c[0]);
            let save = self.exec();
            self.div += 1;
            self.vdepth += 1;
            let m = self.b.ins().band(save, cm);
            self.set_exec(m);
            let av = self.expr(a);
            let m = self.b.ins().band_not(save, cm);
            self.set_exec(m);
            let bv = av.and_then(|av| Ok((av, self.expr(b)?)));
            self.div -= 1;
            self.vdepth -= 1;
            self.set_exec(save);
            let (av, bv) = bv?;
            let c = av.c.iter().zip(&bv.c).map(|(x, y)| choose(&mut self.b, cm, *x, *y)).collect();
            return Ok(Val { vary: true, c });
        }
        let vary = e.varying && !self.frame().uniform;
        let ty = match (e.ty.base, vary) {
            (BaseType::Bool, false) => types::I8,
            (BaseType::Bool, true) => types::I32X4,
            (_, false) => types::F32,
            (_, true) => types::F32X4,
        };
        let vars: Vec<Variable> = (0..n).map(|_| self.b.declare_var(ty)).collect();
        let (tb, eb, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().brif(c.c[0], tb, &[], eb, &[]);
        for (blk, side) in [(tb, a), (eb, b)] {
            self.b.switch_to_block(blk);
            let v = self.expr(side)?;
            if v.vary && !vary {
                return unsupported("a varying side of a uniform select");
            }
            for (var, x) in vars.iter().zip(&v.c) {
                let x = widen(&mut self.b, *x, vary);
                self.b.def_var(*var, x);
            }
            self.b.ins().jump(join, &[]);
        }
        self.b.switch_to_block(join);
        Ok(Val { vary, c: vars.iter().map(|v| self.b.use_var(*v)).collect() })
    }

    pub(super) fn convert(&mut self, a: Val, from: Type, to: Type) -> R<Val> {
        if from.is_array() {
            return if from.base == to.base || (from.base.is_triple() && to.base.is_triple()) {
                Ok(a)
            } else {
                unsupported("an array conversion")
            };
        }
        match (from.base, to.base) {
            (x, y) if x == y => Ok(a),
            (x, y) if x.is_triple() && y.is_triple() => Ok(a),
            (BaseType::Float, y) if y.is_triple() => Ok(Val { vary: a.vary, c: vec![a.c[0]; 3] }),
            (BaseType::Float, BaseType::Matrix) => {
                let zero = self.fconst(0.0, a.vary);
                let c = (0..16).map(|k| if k % 5 == 0 { a.c[0] } else { zero }).collect();
                Ok(Val { vary: a.vary, c })
            }
            (x, BaseType::Float) if x.is_triple() => Ok(Val { vary: a.vary, c: vec![a.c[0]] }),
            (BaseType::Bool, BaseType::Float) => {
                let one = self.fconst(1.0, a.vary);
                let zero = self.fconst(0.0, a.vary);
                Ok(Val { vary: a.vary, c: vec![choose(&mut self.b, a.c[0], one, zero)] })
            }
            _ => unsupported(format!("a conversion from {from} to {to}")),
        }
    }

    /// Component-wise binary operators on operands of one type (`lt`), as `interp::binary`.
    pub(super) fn binary(&mut self, op: BinaryOp, lt: Type, a: &Val, b: &Val) -> R<Val> {
        use BinaryOp::*;
        let vary = a.vary || b.vary;
        if lt.base == BaseType::String {
            // Handles are interned per batch: equal handles are equal strings.
            let ty = if vary { types::I32X4 } else { types::I32 };
            let (x, y) = (widen(&mut self.b, a.c[0], vary), widen(&mut self.b, b.c[0], vary));
            let flags = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
            let x = self.b.ins().bitcast(ty, flags, x);
            let y = self.b.ins().bitcast(ty, flags, y);
            let cc = match op {
                Eq => IntCC::Equal,
                Ne => IntCC::NotEqual,
                _ => return unsupported(format!("{op:?} on strings")),
            };
            return Ok(Val { vary, c: vec![self.b.ins().icmp(cc, x, y)] });
        }
        if lt.base == BaseType::Matrix && matches!(op, Mul | Div) {
            let all = self.concat(&[a.clone(), b.clone()]);
            let name = if op == Mul { "rtsl_mmul" } else { "rtsl_mdiv" };
            let c = self.call_helper(name, &all.c, all.vary)?;
            return Ok(Val { vary: all.vary, c });
        }
        let x: Vec<Value> = a.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let y: Vec<Value> = b.c.iter().map(|v| widen(&mut self.b, *v, vary)).collect();
        let ins = |s: &mut Self, f: fn(&mut FunctionBuilder<'_>, Value, Value) -> Value| -> Vec<Value> {
            x.iter().zip(&y).map(|(p, q)| f(&mut s.b, *p, *q)).collect()
        };
        let c = match op {
            Add => ins(self, |b, p, q| b.ins().fadd(p, q)),
            Sub => ins(self, |b, p, q| b.ins().fsub(p, q)),
            Mul => ins(self, |b, p, q| b.ins().fmul(p, q)),
            Div => ins(self, |b, p, q| b.ins().fdiv(p, q)),
            Dot => vec![self.dot(&x, &y)],
            Cross => {
                let m = |s: &mut Self, i: usize, j: usize| {
                    let p = s.b.ins().fmul(x[i], y[j]);
                    let q = s.b.ins().fmul(x[j], y[i]);
                    s.b.ins().fsub(p, q)
                };
                vec![m(self, 1, 2), m(self, 2, 0), m(self, 0, 1)]
            }
            Lt | Gt | Le | Ge => {
                let cc = match op {
                    Lt => FloatCC::LessThan,
                    Gt => FloatCC::GreaterThan,
                    Le => FloatCC::LessThanOrEqual,
                    _ => FloatCC::GreaterThanOrEqual,
                };
                vec![self.b.ins().fcmp(cc, x[0], y[0])]
            }
            Eq | Ne if lt.base == BaseType::Bool => {
                let d = self.b.ins().bxor(x[0], y[0]);
                vec![if op == Ne { d } else { not(&mut self.b, d) }]
            }
            Eq | Ne => {
                let cc = if op == Eq { FloatCC::Equal } else { FloatCC::NotEqual };
                let mut acc = self.b.ins().fcmp(cc, x[0], y[0]);
                for k in 1..x.len() {
                    let c = self.b.ins().fcmp(cc, x[k], y[k]);
                    acc = if op == Eq { and(&mut self.b, acc, c) } else { or(&mut self.b, acc, c) };
                }
                vec![acc]
            }
            And | Or => return unsupported("logic outside its expression"),
        };
        Ok(Val { vary, c })
    }

    pub(super) fn dot(&mut self, x: &[Value], y: &[Value]) -> Value {
        let p0 = self.b.ins().fmul(x[0], y[0]);
        let p1 = self.b.ins().fmul(x[1], y[1]);
        let p2 = self.b.ins().fmul(x[2], y[2]);
        let s = self.b.ins().fadd(p0, p1);
        self.b.ins().fadd(s, p2)
    }

    // ---- Calls ----

    /// Inlines a call; the result is a dual when the callee's result is differentiated.
    pub(super) fn call(&mut self, fid: FuncId, args: &'m [Arg], e: &ir::Expr) -> R<Dual> {
        let callee = self.m.function(fid);
        let mut inputs = Vec::with_capacity(args.len());
        let mut dargs = Vec::with_capacity(args.len());
        let mut places = Vec::with_capacity(args.len());
        for (k, a) in args.iter().enumerate() {
            let marked = callee.params.get(k).is_some_and(|p| self.info.var(fid, *p));
            match a {
                Arg::Value(x) => {
                    let d = if marked { self.dual(*x)? } else { Dual { v: self.expr(*x)?, d: None } };
                    inputs.push((d.v, None));
                    dargs.push(d.d);
                    places.push(None);
                }
                Arg::Ref(p) => {
                    let t = self.place_targets(p)?;
                    let v = self.read_targets(&t)?;
                    let vary = self.store_of(p.base)?.vary;
                    let d = match self.tangent_stores(p.base) {
                        Some(ds) if marked => {
                            let x = self.read_targets_in(&ds[0], &t)?;
                            let y = self.read_targets_in(&ds[1], &t)?;
                            Some([x.c, y.c])
                        }
                        _ => None,
                    };
                    inputs.push((v, Some(vary)));
                    dargs.push(d);
                    places.push(Some(t));
                }
            }
        }
        // After a divergent return the lanes still running may update uniform locals (the lanes
        // that left never read them again), but not uniform output or captured parameters, which
        // every calling lane reads back.
        // Uniform mode: a callee that reads no varying state, called with uniform arguments (values
        // and output places alike), computes the same value in every lane, whatever the checker
        // inferred for its locals in general (it infers once per function, for every call site).
        // Its locals become uniform storage and its control flow uniform, so a uniform result can
        // flow into uniform storage (e.g. `uniform float n = halvings(1 / cellsize, 1)`).
        let uniform = !callee.reads_varying && inputs.iter().all(|(v, _)| !v.vary);
        let fdiv = !uniform && self.fn_divergent(fid);
        let mut frame = self.new_frame(fid, callee, &inputs, &dargs, uniform)?;
        if fdiv {
            for (k, (_, by_ref)) in inputs.iter().enumerate() {
                if by_ref.is_some() {
                    if let Some(s) = frame.vars[callee.params[k].0 as usize].as_mut() {
                        s.div = u32::MAX;
                    }
                }
            }
        }
        if callee.return_type.base != BaseType::Void {
            let comps = components(callee.return_type)
                .ok_or_else(|| JitError::Unsupported(format!("a function returning {}", callee.return_type)))?;
            if callee.return_type.is_array() {
                return unsupported("a function returning an array");
            }
            // A function that may return under a varying condition returns into varying storage.
            let vary = (e.varying && !uniform) || fdiv;
            frame.ret = Some(self.zero_store(vary, comps, comps));
            if vary && self.info.ret[fid.0 as usize] {
                frame.dret = Some([self.zero_store(true, comps, comps), self.zero_store(true, comps, comps)]);
            }
        }
        let save = self.exec();
        let rb = frame.ret_block;
        self.frames.push(frame);
        let r = self.block(&callee.body);
        let frame = self.frames.pop().expect("frame");
        r?;
        self.b.ins().jump(rb, &[]);
        self.b.switch_to_block(rb);
        self.set_exec(save);
        for (k, t) in places.iter().enumerate() {
            let Some(t) = t else { continue };
            let pv = callee.params[k];
            // A parameter the callee never writes holds what was copied in: nothing to copy back
            // (and a uniform capture read under varying control flow could not take it).
            if !may_write(callee, pv.0 as usize) {
                continue;
            }
            let s = frame.vars[pv.0 as usize].clone().ok_or_else(|| JitError::Codegen("parameter".into()))?;
            let v = self.read_store(&s);
            let d = frame.dvars[pv.0 as usize].clone().map(|[x, y]| [self.read_store(&x).c, self.read_store(&y).c]);
            self.write_targets_d(t, &Dual { v, d })?;
        }
        let v = match &frame.ret {
            Some(s) => self.read_store(s),
            None => Val { vary: false, c: Vec::new() },
        };
        let d = frame.dret.clone().map(|[x, y]| [self.read_store(&x).c, self.read_store(&y).c]);
        Ok(Dual { v, d })
    }

    fn fn_divergent(&mut self, fid: FuncId) -> bool {
        if let Some(d) = self.fn_div.get(&fid.0) {
            return *d;
        }
        let f = self.m.function(fid);
        let d = divergent_return(f, &f.body, 0);
        self.fn_div.insert(fid.0, d);
        d
    }
}

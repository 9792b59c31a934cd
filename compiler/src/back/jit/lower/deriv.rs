//! Forward-mode differentiation in the JIT: duals, tangent storage and the derivative built-ins.
//!
//! Mirrors `interp/deriv.rs` operation for operation (so the two agree bit for bit where the
//! interpreter's scalar formulas are evaluated in the same order):
//! - a [`Dual`] is a value and its two tangents (d/dx, d/dy), each one `f32x4` per component
//!   (tangents are always varying: uniform values have zero derivatives); `None` means zero and
//!   costs nothing where tangents only move (loads, stores, conversions, selects), while every
//!   rule with arithmetic evaluates on materialised zeros exactly as the interpreter does (so
//!   `0 * inf` is NaN in both);
//! - the values `ir::deriv` marks are lowered by `dual`; the others by `expr`, with zero tangents;
//! - a built-in whose result or derivative is needed evaluates its arguments as duals first
//!   (`builtin_dual`), leaves their values in `Lower::cache` for the ordinary lowering of the call
//!   (which then does not evaluate them again) and applies its rule to the tangents;
//! - the renderer's derivatives are loaded once per chunk for the globals that keep tangents, plus
//!   `u` and `v` whenever the module differentiates (`Du`/`Dv` need them).

use super::{Lower, Store, Val, R};
use crate::back::jit::layout::components;
use crate::back::jit::mask::{choose, fconst, to_mask, widen};
use crate::back::jit::{math, unsupported, JitError};
use crate::builtins::Builtin;
use crate::globals::Global;
use crate::ir::{self, Arg, BaseType, BinaryOp, ExprId, ExprKind, PlaceBase, Type, UnaryOp};
use crate::shadeops::deriv::MIN_JACOBIAN;
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, Value};

/// A value and its screen-space tangents (`None`: zero).
#[derive(Clone, Debug)]
pub(crate) struct Dual {
    pub(super) v: Val,
    pub(super) d: Option<[Vec<Value>; 2]>,
}

type T2 = [Vec<Value>; 2];

impl<'m> Lower<'m, '_> {
    // ---- Storage ----

    pub(super) fn tangent_stores(&self, base: PlaceBase) -> Option<[Store; 2]> {
        match base {
            PlaceBase::Var(v) => self.frame().dvars.get(v.0 as usize).cloned().flatten(),
            PlaceBase::Global(g) => self.dglobals[g.0 as usize].clone(),
        }
    }

    /// The tangents of a dual, zeros materialised.
    pub(super) fn tangents(&mut self, d: &Dual) -> T2 {
        match &d.d {
            Some(t) => t.clone(),
            None => {
                let z = fconst(&mut self.b, 0.0, true);
                [vec![z; d.v.c.len()], vec![z; d.v.c.len()]]
            }
        }
    }

    /// Writes a dual's tangents into tangent storage under `exec`.
    pub(super) fn write_tangents(&mut self, ds: &[Store; 2], v: &Dual) -> R<()> {
        let [x, y] = self.tangents(v);
        self.write_store(&ds[0], &Val { vary: true, c: x })?;
        self.write_store(&ds[1], &Val { vary: true, c: y })
    }

    /// Loads the renderer's derivatives of the globals that keep tangents (zeros for a null
    /// `derivs`): slot `s`'s d/dx at `derivs[2s * stride ..]`, d/dy at `derivs[(2s + 1) * stride ..]`.
    pub(super) fn load_global_derivs(&mut self) -> R<()> {
        let wanted: Vec<_> = self.layout.globals.iter().filter(|g| g.derivs).cloned().collect();
        if wanted.is_empty() {
            return Ok(());
        }
        let mut pairs = Vec::new();
        for gs in &wanted {
            let pair = [
                self.new_store(true, gs.components, gs.components),
                self.new_store(true, gs.components, gs.components),
            ];
            self.dglobals[gs.global.0 as usize] = Some(pair.clone());
            pairs.push((gs.offset, pair));
        }
        let (load_b, zero_b, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        let null = self.derivs_null.expect("entry");
        self.b.ins().brif(null, zero_b, &[], load_b, &[]);
        self.b.switch_to_block(zero_b);
        let z = fconst(&mut self.b, 0.0, true);
        for (_, pair) in &pairs {
            for s in pair {
                for v in &s.vars {
                    self.b.def_var(*v, z);
                }
            }
        }
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(load_b);
        let (base, sb) = (self.derivs_base.expect("chunk"), self.stride_bytes.expect("chunk"));
        for (offset, pair) in &pairs {
            for (dir, s) in pair.iter().enumerate() {
                for (k, v) in s.vars.iter().enumerate() {
                    let off = self.b.ins().imul_imm_s(sb, (2 * (offset + k) + dir) as i64);
                    let a = self.b.ins().iadd(base, off);
                    let x = self.b.ins().load(types::F32X4, super::mem(), a, 0);
                    self.b.def_var(*v, x);
                }
            }
        }
        self.b.ins().jump(join, &[]);
        self.b.switch_to_block(join);
        Ok(())
    }

    // ---- f32x4 arithmetic on tangents ----

    fn w(&mut self, x: Value) -> Value {
        widen(&mut self.b, x, true)
    }

    fn add(&mut self, x: Value, y: Value) -> Value {
        let (x, y) = (self.w(x), self.w(y));
        self.b.ins().fadd(x, y)
    }

    fn sub(&mut self, x: Value, y: Value) -> Value {
        let (x, y) = (self.w(x), self.w(y));
        self.b.ins().fsub(x, y)
    }

    fn mul(&mut self, x: Value, y: Value) -> Value {
        let (x, y) = (self.w(x), self.w(y));
        self.b.ins().fmul(x, y)
    }

    fn div(&mut self, x: Value, y: Value) -> Value {
        let (x, y) = (self.w(x), self.w(y));
        self.b.ins().fdiv(x, y)
    }

    fn k(&mut self, x: f32) -> Value {
        fconst(&mut self.b, x, true)
    }

    /// `(x0 y0 + x1 y1) + x2 y2`, the interpreter's `dot`.
    fn dot3(&mut self, x: &[Value], y: &[Value]) -> Value {
        let p0 = self.mul(x[0], y[0]);
        let p1 = self.mul(x[1], y[1]);
        let p2 = self.mul(x[2], y[2]);
        let s = self.add(p0, p1);
        self.add(s, p2)
    }

    fn cross3(&mut self, x: &[Value], y: &[Value]) -> Vec<Value> {
        let mut m = |i: usize, j: usize| {
            let p = self.mul(x[i], y[j]);
            let q = self.mul(x[j], y[i]);
            self.sub(p, q)
        };
        vec![m(1, 2), m(2, 0), m(0, 1)]
    }

    /// The tangent of `a op b` in one direction (the interpreter's `binary_tangent`).
    fn binary_tangent(&mut self, op: BinaryOp, a: &Val, da: &[Value], b: &Val, db: &[Value]) -> Vec<Value> {
        use BinaryOp::*;
        let n = a.c.len().min(b.c.len());
        match op {
            Add => (0..n).map(|i| self.add(da[i], db[i])).collect(),
            Sub => (0..n).map(|i| self.sub(da[i], db[i])).collect(),
            Mul => (0..n)
                .map(|i| {
                    let l = self.mul(da[i], b.c[i]);
                    let r = self.mul(a.c[i], db[i]);
                    self.add(l, r)
                })
                .collect(),
            Div => (0..n)
                .map(|i| {
                    let l = self.mul(da[i], b.c[i]);
                    let r = self.mul(a.c[i], db[i]);
                    let num = self.sub(l, r);
                    let bb = self.mul(b.c[i], b.c[i]);
                    self.div(num, bb)
                })
                .collect(),
            Dot => {
                let l = self.dot3(da, &b.c);
                let r = self.dot3(&a.c, db);
                vec![self.add(l, r)]
            }
            Cross => {
                let l = self.cross3(da, &b.c);
                let r = self.cross3(&a.c, db);
                (0..3).map(|i| self.add(l[i], r[i])).collect()
            }
            _ => Vec::new(),
        }
    }

    fn binary_dual(&mut self, op: BinaryOp, lt: Type, a: &Dual, b: &Dual) -> R<Dual> {
        let v = self.binary(op, lt, &a.v, &b.v)?;
        // Zero tangents still go through the rule, as in the interpreter (IEEE: 0 * inf is NaN).
        if !lt.base.is_numeric() || lt.is_array() {
            return Ok(Dual { v, d: None });
        }
        let [ax, ay] = self.tangents(a);
        let [bx, by] = self.tangents(b);
        let dx = self.binary_tangent(op, &a.v, &ax, &b.v, &bx);
        let dy = self.binary_tangent(op, &a.v, &ay, &b.v, &by);
        Ok(Dual { v, d: Some([dx, dy]) })
    }

    // ---- Expressions ----

    /// Lowers an expression as a dual (unmarked expressions: zero tangents).
    pub(super) fn dual(&mut self, id: ExprId) -> R<Dual> {
        let f = self.func();
        if !self.info.expr(self.frame().fid, id) {
            return Ok(Dual { v: self.expr(id)?, d: None });
        }
        let e = f.expr(id);
        match &e.kind {
            ExprKind::Var(_) | ExprKind::Global(_) => {
                let base = match e.kind {
                    ExprKind::Var(v) => PlaceBase::Var(v),
                    ExprKind::Global(g) => PlaceBase::Global(g),
                    _ => unreachable!("matched above"),
                };
                let v = self.expr(id)?;
                let d = self.tangent_stores(base).map(|[x, y]| [self.read_store(&x).c, self.read_store(&y).c]);
                Ok(Dual { v, d })
            }
            ExprKind::Index { base, index } => {
                let bt = f.expr(*base).ty;
                let bd = self.dual(*base)?;
                let comps = if bt.is_array() { components(bt.element()).unwrap_or(1) } else { 1 };
                let n = bd.v.c.len() / comps;
                let idx = self.index(*index, n)?;
                let v = self.select_elem(&bd.v, comps, idx)?;
                let d = match bd.d {
                    Some([x, y]) => {
                        let x = self.select_elem(&Val { vary: true, c: x }, comps, idx)?.c;
                        let y = self.select_elem(&Val { vary: true, c: y }, comps, idx)?.c;
                        Some([x, y])
                    }
                    None => None,
                };
                Ok(Dual { v, d })
            }
            ExprKind::Unary { op: UnaryOp::Neg, arg } => {
                let a = self.dual(*arg)?;
                let v = Val { vary: a.v.vary, c: a.v.c.iter().map(|x| self.b.ins().fneg(*x)).collect() };
                let d = a.d.map(|[x, y]| {
                    [
                        x.iter().map(|t| self.b.ins().fneg(*t)).collect(),
                        y.iter().map(|t| self.b.ins().fneg(*t)).collect(),
                    ]
                });
                Ok(Dual { v, d })
            }
            ExprKind::Binary { op, lhs, rhs }
                if matches!(
                    op,
                    BinaryOp::Add | BinaryOp::Sub | BinaryOp::Mul | BinaryOp::Div | BinaryOp::Dot | BinaryOp::Cross
                ) =>
            {
                let lt = f.expr(*lhs).ty;
                let a = self.dual(*lhs)?;
                let b = self.dual(*rhs)?;
                self.binary_dual(*op, lt, &a, &b)
            }
            ExprKind::Convert { arg } => {
                let from = f.expr(*arg).ty;
                let a = self.dual(*arg)?;
                let v = self.convert(a.v, from, e.ty)?;
                let d = match a.d {
                    Some([x, y]) if e.ty.base != BaseType::Matrix && from.base != BaseType::Bool => {
                        let x = self.convert(Val { vary: true, c: x }, from, e.ty)?.c;
                        let y = self.convert(Val { vary: true, c: y }, from, e.ty)?.c;
                        Some([x, y])
                    }
                    _ => None,
                };
                Ok(Dual { v, d })
            }
            ExprKind::Construct { args } if e.ty.base != BaseType::Matrix => {
                let mut ds = Vec::new();
                for a in args {
                    ds.push(self.dual(*a)?);
                }
                let vals: Vec<Val> = ds.iter().map(|d| d.v.clone()).collect();
                let v = self.concat(&vals);
                let d = if ds.iter().all(|d| d.d.is_none()) {
                    None
                } else {
                    let mut x = Vec::new();
                    let mut y = Vec::new();
                    for d in &ds {
                        let [a, b] = self.tangents(d);
                        x.extend(a);
                        y.extend(b);
                    }
                    Some([x, y])
                };
                Ok(Dual { v, d })
            }
            ExprKind::SpaceCast { space, arg } if e.ty.base.is_pointlike() => {
                let sp = self.expr(*space)?;
                let a = self.dual(*arg)?;
                let cached = self.batch_matrix(*space);
                let v = self.space_cast(e.ty.base, &sp, a.v.clone(), cached.clone())?;
                let [x, y] = self.tangents(&a);
                let (m, ok) = match cached {
                    Some(m) => m,
                    None => {
                        let current = self.const_string("current");
                        self.space_matrix(&sp, &current)?
                    }
                };
                let h = if e.ty.base == BaseType::Normal { "rtsl_xform_normal" } else { "rtsl_xform_vector" };
                let (x, y) = (Val { vary: true, c: x }, Val { vary: true, c: y });
                let x = self.apply_if(h, ok, &m, &x, &x)?.c;
                let y = self.apply_if(h, ok, &m, &y, &y)?.c;
                let d = Some([x, y]);
                Ok(Dual { v, d })
            }
            ExprKind::Select { cond, a, b } => self.select_dual(e, *cond, *a, *b),
            ExprKind::CallBuiltin { builtin, overload, args } => self.builtin_dual(*builtin, *overload, args, e, true),
            ExprKind::Call { func, args } => self.call(*func, args, e),
            ExprKind::Assign { place, op, value } => {
                let vd = self.dual(*value)?;
                let t = self.place_targets(place)?;
                let stored = match op {
                    Some(op) => {
                        let cur = self.read_targets(&t)?;
                        let d = match self.tangent_stores(place.base) {
                            Some([x, y]) => Some([self.read_targets_in(&x, &t)?.c, self.read_targets_in(&y, &t)?.c]),
                            None => None,
                        };
                        self.binary_dual(*op, place.ty, &Dual { v: cur, d }, &vd)?
                    }
                    None => vd,
                };
                self.write_targets_d(&t, &stored)?;
                Ok(stored)
            }
            ExprKind::ArrayLiteral { elements } => {
                let mut ds = Vec::new();
                for el in elements {
                    ds.push(self.dual(*el)?);
                }
                let vals: Vec<Val> = ds.iter().map(|d| d.v.clone()).collect();
                let v = self.concat(&vals);
                let d = if ds.iter().all(|d| d.d.is_none()) {
                    None
                } else {
                    let (mut x, mut y) = (Vec::new(), Vec::new());
                    for d in &ds {
                        let [a, b] = self.tangents(d);
                        x.extend(a);
                        y.extend(b);
                    }
                    Some([x, y])
                };
                Ok(Dual { v, d })
            }
            _ => Ok(Dual { v: self.expr(id)?, d: None }),
        }
    }

    /// `cond ? a : b` as a dual: `select`'s lowering with the tangents carried along.
    fn select_dual(&mut self, e: &ir::Expr, cond: ExprId, a: ExprId, b: ExprId) -> R<Dual> {
        let f = self.func();
        let c = self.expr(cond)?;
        if c.vary || (f.expr(cond).varying && !self.frame().uniform) {
            let cm = to_mask(&mut self.b, c.c[0]);
            let save = self.exec();
            self.div += 1;
            self.vdepth += 1;
            let m = self.b.ins().band(save, cm);
            self.set_exec(m);
            let ad = self.dual(a);
            let m = self.b.ins().band_not(save, cm);
            self.set_exec(m);
            let bd = ad.and_then(|ad| Ok((ad, self.dual(b)?)));
            self.div -= 1;
            self.vdepth -= 1;
            self.set_exec(save);
            let (ad, bd) = bd?;
            let v = Val {
                vary: true,
                c: ad.v.c.iter().zip(&bd.v.c).map(|(x, y)| choose(&mut self.b, cm, *x, *y)).collect(),
            };
            let d = if ad.d.is_none() && bd.d.is_none() {
                None
            } else {
                let [ax, ay] = self.tangents(&ad);
                let [bx, by] = self.tangents(&bd);
                let x = ax.iter().zip(&bx).map(|(p, q)| choose(&mut self.b, cm, *p, *q)).collect();
                let y = ay.iter().zip(&by).map(|(p, q)| choose(&mut self.b, cm, *p, *q)).collect();
                Some([x, y])
            };
            return Ok(Dual { v, d });
        }
        // A uniform condition: branch, with the value and both tangents in variables.
        let vary = e.varying && !self.frame().uniform;
        let n = components(e.ty).unwrap_or(1) * e.ty.array_len().unwrap_or(1) as usize;
        let ty = if vary { types::F32X4 } else { types::F32 };
        let vars: Vec<_> = (0..n).map(|_| self.b.declare_var(ty)).collect();
        let dvars: Vec<_> = (0..2 * n).map(|_| self.b.declare_var(types::F32X4)).collect();
        let (tb, eb, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().brif(c.c[0], tb, &[], eb, &[]);
        for (blk, side) in [(tb, a), (eb, b)] {
            self.b.switch_to_block(blk);
            let d = self.dual(side)?;
            if d.v.vary && !vary {
                return unsupported("a varying side of a uniform select");
            }
            for (var, x) in vars.iter().zip(&d.v.c) {
                let x = widen(&mut self.b, *x, vary);
                self.b.def_var(*var, x);
            }
            let [x, y] = self.tangents(&d);
            for (var, t) in dvars.iter().zip(x.iter().chain(&y)) {
                self.b.def_var(*var, *t);
            }
            self.b.ins().jump(join, &[]);
        }
        self.b.switch_to_block(join);
        let v = Val { vary, c: vars.iter().map(|v| self.b.use_var(*v)).collect() };
        let t: Vec<Value> = dvars.iter().map(|v| self.b.use_var(*v)).collect();
        Ok(Dual { v, d: Some([t[..n].to_vec(), t[n..].to_vec()]) })
    }

    // ---- Built-ins ----

    /// A built-in call with its arguments evaluated as duals: the derivative built-ins, and the
    /// others (through `builtin`) with their tangent rule applied when `want`.
    pub(super) fn builtin_dual(
        &mut self,
        bi: Builtin,
        overload: u16,
        args: &'m [Arg],
        e: &ir::Expr,
        want: bool,
    ) -> R<Dual> {
        let depth = self.frames.len();
        let mut duals = Vec::with_capacity(args.len());
        let mut keys = Vec::new();
        for a in args {
            match a {
                Arg::Value(x) => {
                    let d = self.dual(*x)?;
                    self.cache.insert((depth, x.0), d.v.clone());
                    keys.push((depth, x.0));
                    duals.push(Some(d));
                }
                Arg::Ref(_) => duals.push(None),
            }
        }
        let saved = std::mem::replace(&mut self.arg_duals, duals);
        let r = match bi {
            Builtin::Du | Builtin::Dv | Builtin::Deriv | Builtin::Area | Builtin::Calculatenormal => self.deriv_op(bi),
            _ => self.builtin(bi, overload, args, e),
        };
        let duals = std::mem::replace(&mut self.arg_duals, saved);
        let differenced = match &r {
            Ok(v) if want && crate::ir::deriv::has_difference_rule(bi) => {
                Some(self.difference_rule(bi, overload, args, e, &duals, v, depth))
            }
            _ => None,
        };
        for k in keys {
            self.cache.remove(&k);
        }
        let v = r?;
        if !want {
            return Ok(Dual { v, d: None });
        }
        let d = match differenced {
            Some(d) => d?,
            None => self.builtin_rule(bi, args, &duals, &v)?,
        };
        Ok(Dual { v, d })
    }

    /// The interpreter's `difference_tangents`: the built-in lowered again with its arguments
    /// (left in `cache` by `builtin_dual`) moved by plus and minus half their tangents, per
    /// direction. `None` (zero) when no argument has tangents.
    #[allow(clippy::too_many_arguments)]
    fn difference_rule(
        &mut self,
        bi: Builtin,
        overload: u16,
        args: &'m [Arg],
        e: &ir::Expr,
        duals: &[Option<Dual>],
        r: &Val,
        depth: usize,
    ) -> R<Option<T2>> {
        if !duals.iter().flatten().any(|d| d.d.is_some()) {
            return Ok(None);
        }
        let mut out: T2 = [Vec::new(), Vec::new()];
        for (dir, o) in out.iter_mut().enumerate() {
            // Lanes where no argument moves along this direction have a zero derivative, as in the
            // interpreter, even where the function itself is NaN (pow of a negative base).
            let zero = self.k(0.0);
            let mut moving = None;
            for t in duals.iter().flatten().filter_map(|d| d.d.as_ref()) {
                for c in &t[dir] {
                    let c = widen(&mut self.b, *c, true);
                    let zero = widen(&mut self.b, zero, true);
                    let m = self.b.ins().fcmp(FloatCC::NotEqual, c, zero);
                    moving = Some(match moving {
                        Some(acc) => self.b.ins().bor(acc, m),
                        None => m,
                    });
                }
            }
            let mut ends = Vec::with_capacity(2);
            for h in [0.5f32, -0.5] {
                for (a, d) in args.iter().zip(duals) {
                    let (Arg::Value(x), Some(d)) = (a, d) else { continue };
                    let Some(t) = &d.d else { continue };
                    let mut c = Vec::with_capacity(d.v.c.len());
                    for (v, t) in d.v.c.iter().zip(&t[dir]) {
                        let k = self.k(h);
                        let step = self.mul(*t, k);
                        c.push(self.add(*v, step));
                    }
                    self.cache.insert((depth, x.0), Val { vary: true, c });
                }
                // The moved lookup filters by the arguments' tangents, as the interpreter's does.
                let saved = std::mem::replace(&mut self.arg_duals, duals.to_vec());
                let end = self.builtin(bi, overload, args, e);
                self.arg_duals = saved;
                ends.push(end?);
            }
            *o = (0..r.c.len())
                .map(|i| {
                    let diff = self.sub(ends[0].c[i], ends[1].c[i]);
                    match moving {
                        Some(m) => choose(&mut self.b, m, diff, zero),
                        None => zero,
                    }
                })
                .collect();
        }
        for (a, d) in args.iter().zip(duals) {
            if let (Arg::Value(x), Some(d)) = (a, d) {
                self.cache.insert((depth, x.0), d.v.clone());
            }
        }
        Ok(Some(out))
    }

    /// The screen derivatives of `u` and `v`: `[u_x, u_y, v_x, v_y]`.
    fn uv(&mut self) -> [Value; 4] {
        let mut out = [self.k(0.0); 4];
        for (i, name) in ["u", "v"].iter().enumerate() {
            if let Some(g) = Global::lookup(name) {
                if let Some([x, y]) = self.dglobals[g.0 as usize].clone() {
                    out[2 * i] = self.b.use_var(x.vars[0]);
                    out[2 * i + 1] = self.b.use_var(y.vars[0]);
                }
            }
        }
        out
    }

    /// `shadeops::deriv::du_dv` per component.
    fn du_dv(&mut self, d: &Dual) -> (Vec<Value>, Vec<Value>) {
        let [fx, fy] = self.tangents(d);
        let [ux, uy, vx, vy] = self.uv();
        let a = self.mul(ux, vy);
        let b = self.mul(uy, vx);
        let j = self.sub(a, b);
        let aj = self.b.ins().fabs(j);
        let lim = self.k(MIN_JACOBIAN);
        let ok = self.b.ins().fcmp(FloatCC::GreaterThan, aj, lim);
        let zero = self.k(0.0);
        let (mut du, mut dv) = (Vec::new(), Vec::new());
        for (x, y) in fx.iter().zip(&fy) {
            let p = self.mul(*x, vy);
            let q = self.mul(*y, vx);
            let n = self.sub(p, q);
            let r = self.div(n, j);
            du.push(choose(&mut self.b, ok, r, zero));
            let p = self.mul(*y, ux);
            let q = self.mul(*x, uy);
            let n = self.sub(p, q);
            let r = self.div(n, j);
            dv.push(choose(&mut self.b, ok, r, zero));
        }
        (du, dv)
    }

    fn arg_dual(&self, k: usize) -> R<Dual> {
        self.arg_duals.get(k).cloned().flatten().ok_or_else(|| JitError::Codegen("a derivative argument".into()))
    }

    fn ratio(&mut self, num: Value, den: Value) -> Value {
        let zero = self.k(0.0);
        let den = self.w(den);
        let is0 = self.b.ins().fcmp(FloatCC::Equal, den, zero);
        let q = self.div(num, den);
        choose(&mut self.b, is0, zero, q)
    }

    /// `Du`, `Dv`, `Deriv`, `area`, `calculatenormal` (the interpreter's `deriv_builtin`).
    fn deriv_op(&mut self, bi: Builtin) -> R<Val> {
        let a = self.arg_dual(0)?;
        let (pu, pv) = self.du_dv(&a);
        let c = match bi {
            Builtin::Du => pu,
            Builtin::Dv => pv,
            Builtin::Deriv => {
                let den = self.arg_dual(1)?;
                let (du, dv) = self.du_dv(&den);
                (0..pu.len())
                    .map(|i| {
                        let x = self.ratio(pu[i], du[0]);
                        let y = self.ratio(pv[i], dv[0]);
                        self.add(x, y)
                    })
                    .collect()
            }
            Builtin::Area => {
                let du = self.global_val("du")?.c[0];
                let dv = self.global_val("dv")?.c[0];
                let x: Vec<Value> = pu.iter().map(|p| self.mul(*p, du)).collect();
                let y: Vec<Value> = pv.iter().map(|p| self.mul(*p, dv)).collect();
                let c = self.cross3(&x, &y);
                let l = self.dot3(&c, &c);
                vec![self.b.ins().sqrt(l)]
            }
            _ => {
                let n = self.cross3(&pu, &pv);
                let dpdu = self.global_val("dPdu")?.c;
                let dpdv = self.global_val("dPdv")?.c;
                let ng = self.global_val("Ng")?.c;
                let g = self.cross3(&dpdu, &dpdv);
                let o = self.dot3(&g, &ng);
                let zero = self.k(0.0);
                let flip = self.b.ins().fcmp(FloatCC::LessThan, o, zero);
                n.iter()
                    .map(|x| {
                        let m = self.b.ins().fneg(*x);
                        choose(&mut self.b, flip, m, *x)
                    })
                    .collect()
            }
        };
        Ok(Val { vary: true, c })
    }

    /// `filterstep`'s width from the derivatives of argument `k`: `|Du(x) du| + |Dv(x) dv|`.
    pub(super) fn filter_width(&mut self, k: usize) -> R<Val> {
        let x = self.arg_dual(k)?;
        let (xu, xv) = self.du_dv(&x);
        let du = self.global_val("du")?.c[0];
        let dv = self.global_val("dv")?.c[0];
        let a = self.mul(xu[0], du);
        let a = self.b.ins().fabs(a);
        let b = self.mul(xv[0], dv);
        let b = self.b.ins().fabs(b);
        Ok(Val { vary: true, c: vec![self.add(a, b)] })
    }

    /// A `texture` call's coordinate derivatives `[ds/dx, dt/dx, ds/dy, dt/dy]` (before the width
    /// options): the interpreter's `footprint`.
    pub(super) fn texture_derivs(&mut self, fixed: usize, vals: &[Val]) -> R<[Val; 4]> {
        let one = |c: Value| Val { vary: true, c: vec![c] };
        match fixed {
            1 => {
                let mut out = Vec::new();
                for name in ["s", "t"] {
                    let d = match Global::lookup(name).and_then(|g| self.dglobals[g.0 as usize].clone()) {
                        Some([x, y]) => [self.b.use_var(x.vars[0]), self.b.use_var(y.vars[0])],
                        None => [self.k(0.0), self.k(0.0)],
                    };
                    out.push(d);
                }
                Ok([one(out[0][0]), one(out[1][0]), one(out[0][1]), one(out[1][1])])
            }
            3 => {
                let s = self.arg_dual(1)?;
                let t = self.arg_dual(2)?;
                let [sx, sy] = self.tangents(&s);
                let [tx, ty] = self.tangents(&t);
                Ok([one(sx[0]), one(tx[0]), one(sy[0]), one(ty[0])])
            }
            _ => {
                let mut d = |a: usize, b: usize| -> Value {
                    let x = vals.get(a).map(|v| v.c[0]).unwrap_or_else(|| self.k(0.0));
                    let y = vals.get(b).map(|v| v.c[0]).unwrap_or_else(|| self.k(0.0));
                    self.sub(x, y)
                };
                Ok([one(d(3, 1)), one(d(4, 2)), one(d(5, 1)), one(d(6, 2))])
            }
        }
    }

    /// The direction of an `environment()` call and its changes over a pixel step in x and y
    /// (the interpreter's `environment_query`): the four-direction form's mean and the
    /// differences `D2 - D1` and `D3 - D1`, else the direction and its tangents.
    pub(super) fn environment_directions(&mut self, vals: &[Val], fixed: usize) -> R<[Val; 3]> {
        let varying = |c: Vec<Value>| Val { vary: true, c };
        let component = |v: &Val, i: usize| {
            v.c.get(i).or(v.c.first()).copied().ok_or_else(|| JitError::Codegen("an environment direction".into()))
        };
        if fixed == 5 {
            let quarter = self.k(0.25);
            let (mut mean, mut dx, mut dy) = (Vec::with_capacity(3), Vec::with_capacity(3), Vec::with_capacity(3));
            for i in 0..3 {
                let d: Vec<Value> = vals[1..5].iter().map(|v| component(v, i)).collect::<R<_>>()?;
                let sum = self.add(d[0], d[1]);
                let sum = self.add(sum, d[2]);
                let sum = self.add(sum, d[3]);
                mean.push(self.mul(sum, quarter));
                dx.push(self.sub(d[1], d[0]));
                dy.push(self.sub(d[2], d[0]));
            }
            return Ok([varying(mean), varying(dx), varying(dy)]);
        }
        let d = self.arg_dual(1)?;
        let [dx, dy] = self.tangents(&d);
        Ok([d.v.clone(), varying(dx), varying(dy)])
    }

    /// The point and region of a `shadow()` call (the interpreter's `shadow_query`): the centre
    /// and the four points of the four-point form, else the point and its pixel footprint
    /// `P ± dPdx/2 ± dPdy/2`, computed with the interpreter's operations in its order.
    pub(super) fn shadow_region(&mut self, vals: &[Val], fixed: usize) -> R<Vec<Val>> {
        let varying = |c: Vec<Value>| Val { vary: true, c };
        let component = |v: &Val, i: usize| v.c.get(i).or(v.c.first()).copied();
        let mut out = Vec::with_capacity(5);
        if fixed == 5 {
            let quarter = self.k(0.25);
            let mut centre = Vec::with_capacity(3);
            for i in 0..3 {
                let mut sum = component(&vals[1], i).ok_or_else(|| JitError::Codegen("a shadow corner".into()))?;
                for corner in &vals[2..5] {
                    let c = component(corner, i).ok_or_else(|| JitError::Codegen("a shadow corner".into()))?;
                    sum = self.add(sum, c);
                }
                centre.push(self.mul(sum, quarter));
            }
            out.push(varying(centre));
            out.extend(vals[1..5].iter().cloned());
            return Ok(out);
        }
        let p = self.arg_dual(1)?;
        let [dx, dy] = self.tangents(&p);
        let half = self.k(0.5);
        let (mut hx, mut hy) = (Vec::with_capacity(3), Vec::with_capacity(3));
        for i in 0..3 {
            hx.push(self.mul(dx[i], half));
            hy.push(self.mul(dy[i], half));
        }
        out.push(p.v.clone());
        for (right, down) in [(false, false), (true, false), (false, true), (true, true)] {
            let mut c = Vec::with_capacity(3);
            for i in 0..3 {
                let pi = component(&p.v, i).ok_or_else(|| JitError::Codegen("a shadow point".into()))?;
                let x = if right { self.add(pi, hx[i]) } else { self.sub(pi, hx[i]) };
                c.push(if down { self.add(x, hy[i]) } else { self.sub(x, hy[i]) });
            }
            out.push(varying(c));
        }
        Ok(out)
    }

    /// The tangents of a built-in's result (the interpreter's `builtin_tangent`).
    fn builtin_rule(&mut self, bi: Builtin, args: &[Arg], duals: &[Option<Dual>], r: &Val) -> R<Option<T2>> {
        let val = |k: usize| duals[k].as_ref().map(|d| d.v.clone()).unwrap_or(Val { vary: false, c: Vec::new() });
        let mut t: Vec<T2> = Vec::new();
        for d in duals {
            t.push(match d {
                Some(d) => self.tangents(d),
                None => [Vec::new(), Vec::new()],
            });
        }
        let mut out: [Vec<Value>; 2] = [Vec::new(), Vec::new()];
        for (dir, o) in out.iter_mut().enumerate() {
            let td = |k: usize| t[k][dir].clone();
            *o = match bi {
                Builtin::Xcomp => vec![td(0)[0]],
                Builtin::Ycomp => vec![td(0)[1]],
                Builtin::Zcomp => vec![td(0)[2]],
                Builtin::Comp if duals.len() == 2 && val(0).c.len() == 3 => {
                    let i = val(1);
                    let idx = self.arg_index(args, 1, &i, 3);
                    self.select_elem(&Val { vary: true, c: td(0) }, 1, idx)?.c
                }
                Builtin::Abs => {
                    let x = val(0).c;
                    (0..x.len())
                        .map(|i| {
                            let s = math::sign(&mut self.b, x[i]);
                            self.mul(td(0)[i], s)
                        })
                        .collect()
                }
                Builtin::Sqrt => (0..r.c.len())
                    .map(|i| {
                        let h = self.k(0.5);
                        let a = self.mul(td(0)[i], h);
                        let q = self.div(a, r.c[i]);
                        let zero = self.k(0.0);
                        let rv = self.w(r.c[i]);
                        let pos = self.b.ins().fcmp(FloatCC::GreaterThan, rv, zero);
                        choose(&mut self.b, pos, q, zero)
                    })
                    .collect(),
                Builtin::Sin | Builtin::Cos => {
                    let x = val(0).c;
                    let t0 = td(0);
                    let mut c = Vec::new();
                    for (xi, ti) in x.iter().zip(&t0) {
                        let xi = self.w(*xi);
                        let h = if bi == Builtin::Sin { "rtsl_cos" } else { "rtsl_sin" };
                        let g = self.call_helper(h, &[xi], true)?[0];
                        let p = self.mul(*ti, g);
                        c.push(if bi == Builtin::Sin { p } else { self.b.ins().fneg(p) });
                    }
                    c
                }
                Builtin::Exp => (0..r.c.len()).map(|i| self.mul(td(0)[i], r.c[i])).collect(),
                Builtin::Min | Builtin::Max if duals.len() >= 2 => {
                    let n = val(0).c.len();
                    let mut acc: Vec<Value> = val(0).c.iter().map(|x| widen(&mut self.b, *x, true)).collect();
                    let mut dacc = td(0);
                    for k in 1..duals.len() {
                        let xk = val(k).c;
                        for i in 0..n {
                            let y = self.w(xk[i]);
                            let cc = if bi == Builtin::Min { FloatCC::LessThan } else { FloatCC::GreaterThan };
                            let c1 = self.b.ins().fcmp(cc, acc[i], y);
                            let nan = self.b.ins().fcmp(FloatCC::Unordered, y, y);
                            let keep = self.b.ins().bor(c1, nan);
                            dacc[i] = choose(&mut self.b, keep, dacc[i], td(k)[i]);
                            acc[i] = if bi == Builtin::Min {
                                math::min(&mut self.b, acc[i], y)
                            } else {
                                math::max(&mut self.b, acc[i], y)
                            };
                        }
                    }
                    dacc
                }
                Builtin::Clamp => {
                    let (x, lo, hi) = (val(0).c, val(1).c, val(2).c);
                    (0..x.len())
                        .map(|i| {
                            let (xi, li, hv) = (self.w(x[i]), self.w(lo[i]), self.w(hi[i]));
                            let c1 = self.b.ins().fcmp(FloatCC::GreaterThan, xi, li);
                            let dy = choose(&mut self.b, c1, td(0)[i], td(1)[i]);
                            let y = choose(&mut self.b, c1, xi, li);
                            let c2 = self.b.ins().fcmp(FloatCC::LessThan, y, hv);
                            let inside = self.b.ins().fcmp(FloatCC::GreaterThanOrEqual, xi, li);
                            let dbound = choose(&mut self.b, inside, td(2)[i], td(1)[i]);
                            choose(&mut self.b, c2, dy, dbound)
                        })
                        .collect()
                }
                Builtin::Mix => {
                    let (x, y, a) = (val(0).c, val(1).c, val(2).c);
                    (0..x.len())
                        .map(|i| {
                            let ai = if a.len() == 1 { a[0] } else { a[i] };
                            let dai = if a.len() == 1 { td(2)[0] } else { td(2)[i] };
                            let one = self.k(1.0);
                            let om = self.sub(one, ai);
                            let p = self.mul(td(0)[i], om);
                            let q = self.mul(x[i], dai);
                            let l = self.sub(p, q);
                            let p = self.mul(td(1)[i], ai);
                            let q = self.mul(y[i], dai);
                            let rr = self.add(p, q);
                            self.add(l, rr)
                        })
                        .collect()
                }
                Builtin::Length => {
                    let d = self.dot3(&val(0).c, &td(0));
                    let q = self.div(d, r.c[0]);
                    let zero = self.k(0.0);
                    let rv = self.w(r.c[0]);
                    let pos = self.b.ins().fcmp(FloatCC::GreaterThan, rv, zero);
                    vec![choose(&mut self.b, pos, q, zero)]
                }
                Builtin::Normalize => {
                    let p = val(0).c;
                    let pp = self.dot3(&p, &p);
                    let len = self.b.ins().sqrt(pp);
                    let zero = self.k(0.0);
                    let is0 = self.b.ins().fcmp(FloatCC::Equal, len, zero);
                    let dp = td(0);
                    let kk = self.dot3(&r.c, &dp);
                    (0..3)
                        .map(|i| {
                            let m = self.mul(r.c[i], kk);
                            let s = self.sub(dp[i], m);
                            let q = self.div(s, len);
                            choose(&mut self.b, is0, dp[i], q)
                        })
                        .collect()
                }
                _ => return Ok(None),
            };
        }
        Ok(Some(out))
    }
}

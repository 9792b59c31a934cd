//! Storage: the Cranelift variables behind variables, globals and parameters (`Store`), the
//! batch's slots they load from and store to, places and the positions they cover (`Targets`),
//! array and component indices with their bounds checks, and the sites runtime checks report.

use super::deriv::Dual;
use super::{const_index, mem, Idx, Lower, Store, Targets, Val, R, RUNTIME_INDEX, RUNTIME_UNSUPPORTED};
use crate::back::jit::layout::components;
use crate::back::jit::mask::{and, any, choose, fconst, is_vec, konst, merge, to_mask, widen};
use crate::back::jit::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{Constant, ExprId, ExprKind, Place, PlaceBase, Type};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Value};

impl<'m> Lower<'m, '_> {
    // ---- Stores and slots ----

    pub(super) fn new_store(&mut self, vary: bool, n: usize, comps: usize) -> Store {
        let ty = if vary { types::F32X4 } else { types::F32 };
        let vars = (0..n).map(|_| self.b.declare_var(ty)).collect();
        Store { vary, vars, comps, div: self.div, fresh: false }
    }

    pub(super) fn zero_store(&mut self, vary: bool, n: usize, comps: usize) -> Store {
        let s = self.new_store(vary, n, comps);
        let z = fconst(&mut self.b, 0.0, vary);
        for v in &s.vars {
            self.b.def_var(*v, z);
        }
        s
    }

    pub(super) fn read_store(&mut self, s: &Store) -> Val {
        Val { vary: s.vary, c: s.vars.iter().map(|v| self.b.use_var(*v)).collect() }
    }

    /// A value the IR holds uniform that the JIT computed per lane (a built-in of uniform
    /// arguments lowered through a per-lane host call, as `depth(point(0, 0, 1))`), as a uniform
    /// value: the checker proved the running lanes equal, so the first running lane's is it.
    fn uniform_from_running(&mut self, v: &Val) -> Val {
        if !v.vary {
            return v.clone();
        }
        let e = self.exec();
        let c = v.c.iter().map(|&x| self.first_running_lane(x, e)).collect();
        Val { vary: false, c }
    }

    /// Initialises storage (no mask: the storage is fresh or being loaded).
    pub(super) fn init_store(&mut self, s: &Store, v: &Val) -> R<()> {
        let v = &if v.vary && !s.vary { self.uniform_from_running(v) } else { v.clone() };
        if v.c.len() != s.vars.len() {
            return unsupported("a value of unexpected size");
        }
        for (var, x) in s.vars.iter().zip(&v.c) {
            let x = widen(&mut self.b, *x, s.vary);
            self.b.def_var(*var, x);
        }
        Ok(())
    }

    /// Writes a whole value into storage: masked by `exec` when varying.
    pub(super) fn write_store(&mut self, s: &Store, v: &Val) -> R<()> {
        if !s.vary {
            if self.div != s.div {
                return unsupported("a uniform variable assigned under varying control flow");
            }
            return self.init_store(s, v);
        }
        let e = self.exec();
        for (var, x) in s.vars.iter().zip(&v.c) {
            let old = self.b.use_var(*var);
            let new = merge(&mut self.b, e, *x, old);
            self.b.def_var(*var, new);
        }
        Ok(())
    }

    pub(super) fn store_of(&self, base: PlaceBase) -> R<Store> {
        match base {
            PlaceBase::Var(v) => self.frame().vars[v.0 as usize].clone(),
            PlaceBase::Global(g) => self.globals[g.0 as usize].clone(),
        }
        .ok_or_else(|| JitError::Unsupported("a string or matrix variable".into()))
    }

    fn addr(&mut self, slot: usize) -> Value {
        let (base, sb) = (self.chunk_base.expect("chunk"), self.stride_bytes.expect("chunk"));
        if slot == 0 {
            return base;
        }
        let off = self.b.ins().imul_imm_s(sb, slot as i64);
        self.b.ins().iadd(base, off)
    }

    pub(super) fn load_slot(&mut self, vary: bool, offset: usize) -> Value {
        self.load_slot_with(vary, offset, mem())
    }

    pub(super) fn load_slot_with(&mut self, vary: bool, offset: usize, flags: MemFlagsData) -> Value {
        if vary {
            let a = self.addr(offset);
            self.b.ins().load(types::F32X4, flags, a, 0)
        } else {
            let u = self.uniform.expect("chunk");
            self.b.ins().load(types::F32, flags, u, (offset * 4) as i32)
        }
    }

    pub(super) fn store_slot(&mut self, vary: bool, offset: usize, v: Value) {
        if vary {
            let a = self.addr(offset);
            self.b.ins().store(mem(), v, a, 0);
        } else {
            let u = self.uniform.expect("chunk");
            self.b.ins().store(mem(), v, u, (offset * 4) as i32);
        }
    }

    // ---- Places ----

    pub(super) fn place_targets(&mut self, p: &Place) -> R<Targets> {
        let store = self.store_of(p.base)?;
        let base_ty = match p.base {
            PlaceBase::Var(v) => self.func().var(v).ty,
            PlaceBase::Global(g) => Type::scalar(g.def().ty),
        };
        let total = store.vars.len();
        let comps = store.comps;
        let mut list = Vec::new();
        match (p.index, p.component) {
            (None, _) => list.extend((0..total).map(|k| (k, k, None))),
            (Some(i), comp) if base_ty.is_array() => {
                let n = total / comps;
                let idx = self.index(i, n)?;
                let cidx = match comp {
                    Some(c) => Some(self.index(c, comps)?),
                    None => None,
                };
                for e in 0..n {
                    let Some(ce) = self.idx_cond(idx, e) else { continue };
                    for j in 0..comps {
                        match cidx {
                            None => list.push((e * comps + j, j, ce)),
                            Some(ci) => {
                                let Some(cj) = self.idx_cond(ci, j) else { continue };
                                let cond = match (ce, cj) {
                                    (Some(a), Some(b)) => Some(and(&mut self.b, a, b)),
                                    (a, b) => a.or(b),
                                };
                                list.push((e * comps + j, 0, cond));
                            }
                        }
                    }
                }
            }
            (Some(i), _) => {
                let idx = self.index(i, total)?;
                for k in 0..total {
                    if let Some(c) = self.idx_cond(idx, k) {
                        list.push((k, 0, c));
                    }
                }
            }
        }
        let out = components(p.ty).unwrap_or(1) * p.ty.array_len().unwrap_or(1) as usize;
        Ok(Targets { base: p.base, list, comps: out })
    }

    pub(super) fn read_targets(&mut self, t: &Targets) -> R<Val> {
        let store = self.store_of(t.base)?;
        self.read_targets_in(&store, t)
    }

    pub(super) fn read_targets_in(&mut self, store: &Store, t: &Targets) -> R<Val> {
        let mut c = Vec::with_capacity(t.comps);
        let mut vary = store.vary;
        for j in 0..t.comps {
            let mut acc: Option<Value> = None;
            for (flat, vj, cond) in &t.list {
                if *vj != j {
                    continue;
                }
                let x = self.b.use_var(store.vars[*flat]);
                acc = Some(match (acc, cond) {
                    (None, _) | (_, None) => x,
                    (Some(a), Some(cnd)) => {
                        vary |= is_vec(&self.b, *cnd);
                        choose(&mut self.b, *cnd, x, a)
                    }
                });
            }
            c.push(acc.ok_or_else(|| JitError::Codegen("empty place".into()))?);
        }
        let c = c.into_iter().map(|x| widen(&mut self.b, x, vary)).collect();
        Ok(Val { vary, c })
    }

    /// Writes a place; its tangents (when it keeps them) become zero.
    pub(super) fn write_targets(&mut self, t: &Targets, v: &Val) -> R<()> {
        self.write_targets_d(t, &Dual { v: v.clone(), d: None })
    }

    /// Writes a place and, when it keeps tangents, the value's tangents (under the same masks).
    pub(super) fn write_targets_d(&mut self, t: &Targets, v: &Dual) -> R<()> {
        let store = self.store_of(t.base)?;
        self.write_targets_in(&store, t, &v.v)?;
        if let Some(ds) = self.tangent_stores(t.base) {
            let [dx, dy] = self.tangents(v);
            self.write_targets_in(&ds[0], t, &Val { vary: true, c: dx })?;
            self.write_targets_in(&ds[1], t, &Val { vary: true, c: dy })?;
        }
        Ok(())
    }

    fn write_targets_in(&mut self, store: &Store, t: &Targets, v: &Val) -> R<()> {
        let store = store.clone();
        let uniform_value;
        let v = if !store.vary && v.vary {
            uniform_value = self.uniform_from_running(v);
            &uniform_value
        } else {
            v
        };
        if !store.vary {
            if t.list.iter().any(|(_, _, c)| c.is_some_and(|c| is_vec(&self.b, c))) {
                return unsupported("a varying value stored in uniform storage");
            }
            if self.div != store.div {
                return unsupported("a uniform variable assigned under varying control flow");
            }
        }
        let e = if store.vary { Some(self.exec()) } else { None };
        // In the shader body outside varying control flow every lane of the chunk's mask runs, and
        // a fresh global's other lanes are blended back at the chunk's end (a body's local's are
        // never read into anything that is stored): no merge.
        let whole = store.fresh && self.div == 0 && self.frames.len() == 1;
        for (flat, j, cond) in &t.list {
            let var = store.vars[*flat];
            let old = self.b.use_var(var);
            let x = v.c[*j];
            let new = match (e, cond) {
                (Some(e), Some(c)) => {
                    let cm = to_mask(&mut self.b, *c);
                    let m = self.b.ins().band(e, cm);
                    merge(&mut self.b, m, x, old)
                }
                (Some(_), None) if whole => widen(&mut self.b, x, true),
                (Some(e), None) => merge(&mut self.b, e, x, old),
                (None, Some(c)) => self.b.ins().select(*c, x, old),
                (None, None) => x,
            };
            self.b.def_var(var, new);
        }
        Ok(())
    }

    // ---- Indices and runtime checks ----

    pub(super) fn index(&mut self, e: ExprId, n: usize) -> R<Idx> {
        if let ExprKind::Const(Constant::Float(x)) = self.func().expr(e).kind {
            return Ok(Idx::Const(const_index(x, n)));
        }
        let v = self.expr(e)?;
        let span = self.func().expr(e).span;
        self.check_index(v.c[0], n, span)?;
        Ok(self.dyn_index(v.c[0], n))
    }

    /// The interpreter's `index_of` per lane: non-finite or negative gives 0, else `min(trunc, n-1)`.
    pub(super) fn dyn_index(&mut self, i: Value, n: usize) -> Idx {
        let b = &mut self.b;
        let zero = konst(b, 0.0, i);
        let inf = konst(b, f32::INFINITY, i);
        let ge = b.ins().fcmp(FloatCC::GreaterThanOrEqual, i, zero);
        let lt = b.ins().fcmp(FloatCC::LessThan, i, inf);
        let ok = b.ins().band(ge, lt);
        let t = b.ins().trunc(i);
        let hi = konst(b, (n.max(1) - 1) as f32, i);
        let small = b.ins().fcmp(FloatCC::LessThan, t, hi);
        let t = choose(b, small, t, hi);
        Idx::Dyn(choose(b, ok, t, zero))
    }

    pub(super) fn idx_cond(&mut self, idx: Idx, k: usize) -> Option<Option<Value>> {
        match idx {
            Idx::Const(c) => (c == k).then_some(None),
            Idx::Dyn(v) => {
                let kc = konst(&mut self.b, k as f32, v);
                Some(Some(self.b.ins().fcmp(FloatCC::Equal, v, kc)))
            }
        }
    }

    /// Reports (once per site, through the renderer) a running lane whose index is outside
    /// `0..n`; the index is then clamped as the interpreter does.
    fn check_index(&mut self, i: Value, n: usize, span: crate::source::Span) -> R<()> {
        let site = self.site(span);
        let b = &mut self.b;
        let zero = konst(b, 0.0, i);
        let end = konst(b, n as f32, i);
        let ge = b.ins().fcmp(FloatCC::GreaterThanOrEqual, i, zero);
        let lt = b.ins().fcmp(FloatCC::LessThan, i, end);
        let ok = b.ins().band(ge, lt);
        let bad = if is_vec(b, i) {
            let m = to_mask(b, ok);
            let e = self.exec();
            let bad = self.b.ins().band_not(e, m);
            any(&mut self.b, bad)
        } else {
            let e = self.exec();
            let running = any(&mut self.b, e);
            let not_ok = self.b.ins().bxor_imm_u(ok, 1);
            self.b.ins().band(running, not_ok)
        };
        let (report, go) = (self.b.create_block(), self.b.create_block());
        self.b.ins().brif(bad, report, &[], go, &[]);
        self.b.switch_to_block(report);
        self.runtime_error(RUNTIME_INDEX, site)?;
        self.b.ins().jump(go, &[]);
        self.b.switch_to_block(go);
        Ok(())
    }

    /// The site of a runtime check at `span`. Inlined copies of a function share their sites, so
    /// that a check is reported once per place in the source, as the interpreter reports it.
    pub(super) fn site(&mut self, span: crate::source::Span) -> usize {
        if let Some(&i) = self.site_ids.get(&span) {
            return i;
        }
        let text = self.location_text(span);
        self.sites.push(text);
        self.site_ids.insert(span, self.sites.len() - 1);
        self.sites.len() - 1
    }

    fn location_text(&self, span: crate::source::Span) -> String {
        match self.sources {
            Some(src) => src.location(span).to_string(),
            None => format!("byte {} of file {}", span.start, span.file.0),
        }
    }

    /// Reports (once per site, see `RuntimeErrors`) that a running lane called a built-in rtsl
    /// accepts but cannot honour.
    pub(super) fn report_unsupported(&mut self, bi: Builtin, span: crate::source::Span) -> R<()> {
        let site = self.site(span);
        self.sites[site] = format!("`{}` at {}", bi.name(), self.location_text(span));
        let e = self.exec();
        let running = any(&mut self.b, e);
        let (report, go) = (self.b.create_block(), self.b.create_block());
        self.b.ins().brif(running, report, &[], go, &[]);
        self.b.switch_to_block(report);
        self.runtime_error(RUNTIME_UNSUPPORTED, site)?;
        self.b.ins().jump(go, &[]);
        self.b.switch_to_block(go);
        Ok(())
    }

    /// Calls the runtime-error helper for `kind` at `site` (lane 0; the helper records it once).
    pub(super) fn runtime_error(&mut self, kind: u32, site: usize) -> R<()> {
        let k = self.b.ins().f32const(kind as f32);
        let s = self.b.ins().f32const(site as f32);
        self.call_helper("rtsl_h_runtime_error", &[k, s], false)?;
        Ok(())
    }
}

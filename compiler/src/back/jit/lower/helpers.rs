//! Calls of the `extern "C"` helpers: the per-chunk math helpers (`math.rs`) and the host helpers
//! (`host.rs`), through stack slots of four lanes per value, directly or through a
//! register-preserving trampoline; `sin`/`cos` inline with the helper as the cold fallback; and
//! component-wise maps of helpers and instructions over values.

use super::{Lower, Val, R};
use crate::back::jit::mask::{self, is_vec, widen};
use crate::back::jit::{host, math, JitError};
use cranelift_codegen::ir::{types, AbiParam, FuncRef, InstBuilder, StackSlotData, StackSlotKind, Value};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::FunctionBuilder;
use cranelift_module::{Linkage, Module as _};

impl<'m> Lower<'m, '_> {
    fn helper_ref(&mut self, name: &'static str, params: usize) -> R<FuncRef> {
        if let Some(r) = self.helpers.get(name) {
            return Ok(*r);
        }
        let mut sig = self.jit.make_signature();
        for _ in 0..params {
            sig.params.push(AbiParam::new(self.ptr));
        }
        let id =
            self.jit.declare_function(name, Linkage::Import, &sig).map_err(|e| JitError::Codegen(e.to_string()))?;
        let r = self.jit.declare_func_in_func(id, self.b.func);
        self.helpers.insert(name, r);
        Ok(r)
    }

    /// Calls a per-chunk helper on `inputs` (scalars are splatted); results are uniform again when
    /// every input was.
    ///
    /// Host helpers (`host::HOST_HELPERS`) also receive the batch record and a mask: the lanes of
    /// `exec` when `vary`, else lane 0 alone (the result is uniform).
    pub(super) fn call_helper(&mut self, name: &'static str, inputs: &[Value], vary: bool) -> R<Vec<Value>> {
        self.call_helper_as(name, inputs, vary, false)
    }

    /// [`Lower::call_helper`] for a call on a cold path: on x86-64 through a trampoline that
    /// preserves every register (`CallConv::PreserveAll`), so that the values live across the call
    /// stay in their registers instead of being spilled (at their definitions, which the hot path
    /// then pays too). A per-chunk (not host) helper.
    fn call_helper_keeping_registers(&mut self, name: &'static str, inputs: &[Value]) -> R<Vec<Value>> {
        self.call_helper_as(name, inputs, true, cfg!(target_arch = "x86_64"))
    }

    /// The reference to the register-preserving trampoline of per-chunk helper `name`.
    fn trampoline_ref(&mut self, name: &'static str) -> R<FuncRef> {
        let key: &'static str = match name {
            "rtsl_sincos" => "rtsl_sincos_keep",
            _ => return Err(JitError::Codegen(format!("no register-preserving trampoline for {name}"))),
        };
        if let Some(r) = self.helpers.get(key) {
            return Ok(*r);
        }
        let mut sig = self.jit.make_signature();
        sig.call_conv = CallConv::PreserveAll;
        sig.params.extend([AbiParam::new(self.ptr), AbiParam::new(self.ptr)]);
        let id = self.jit.declare_function(key, Linkage::Local, &sig).map_err(|e| JitError::Codegen(e.to_string()))?;
        self.trampolines.push((id, name));
        let r = self.jit.declare_func_in_func(id, self.b.func);
        self.helpers.insert(key, r);
        Ok(r)
    }

    fn call_helper_as(&mut self, name: &'static str, inputs: &[Value], vary: bool, keep: bool) -> R<Vec<Value>> {
        let (hname, ins, outs, is_host) = match (math::helper(name), host::host_helper(name)) {
            (Some(h), _) => (h.name, h.ins, h.outs, false),
            (None, Some(h)) => (h.name, h.ins, h.outs, true),
            _ => return Err(JitError::Codegen(format!("no helper {name}"))),
        };
        let ins = if ins == host::VARIADIC { inputs.len() } else { ins };
        if ins != inputs.len() {
            return Err(JitError::Codegen(format!("{name} takes {ins} inputs, not {}", inputs.len())));
        }
        let fr = if keep && !is_host {
            self.trampoline_ref(hname)?
        } else {
            self.helper_ref(hname, if is_host { 4 } else { 2 })?
        };
        let slot = |n: usize| StackSlotData::new(StackSlotKind::ExplicitSlot, 16 * n.max(1) as u32, 4);
        let sin = self.b.create_sized_stack_slot(slot(ins));
        let sout = self.b.create_sized_stack_slot(slot(outs));
        for (k, x) in inputs.iter().enumerate() {
            let x = if is_vec(&self.b, *x) && self.b.func.dfg.value_type(*x) == types::I32X4 {
                mask::mask_as_f32(&mut self.b, *x)
            } else {
                widen(&mut self.b, *x, true)
            };
            self.b.ins().stack_store(self.ptr, x, sin, (16 * k) as i32);
        }
        let pin = self.b.ins().stack_addr(self.ptr, sin, 0);
        let pout = self.b.ins().stack_addr(self.ptr, sout, 0);
        if is_host {
            let smask = self.b.create_sized_stack_slot(slot(1));
            let m = if vary {
                self.exec()
            } else {
                let z = self.b.ins().iconst(types::I32, 0);
                let z = self.b.ins().splat(types::I32X4, z);
                let on = self.b.ins().iconst(types::I32, -1);
                self.b.ins().insertlane(z, on, 0)
            };
            self.b.ins().stack_store(self.ptr, m, smask, 0);
            let pmask = self.b.ins().stack_addr(self.ptr, smask, 0);
            let batch = self.batch.expect("batch");
            self.host_calls += 1;
            self.b.ins().call(fr, &[batch, pmask, pin, pout]);
        } else {
            self.b.ins().call(fr, &[pin, pout]);
        }
        let mut out = Vec::with_capacity(outs);
        for j in 0..outs {
            let v = self.b.ins().stack_load(self.ptr, types::F32X4, sout, (16 * j) as i32);
            out.push(if vary { v } else { self.b.ins().extractlane(v, 0) });
        }
        Ok(out)
    }

    /// `name` on the components of `parts`, in order (scalars are splatted); the result is varying
    /// when `vary` or any part is.
    pub(super) fn call_helper_on(&mut self, name: &'static str, parts: &[Val], vary: bool) -> R<Val> {
        let all = self.concat(parts);
        let c = self.call_helper(name, &all.c, vary || all.vary)?;
        Ok(Val { vary: vary || all.vary, c })
    }

    /// A one-input helper applied to each component.
    pub(super) fn map_helper(&mut self, name: &'static str, v: &Val) -> R<Val> {
        let mut c = Vec::new();
        for x in &v.c {
            c.push(self.call_helper(name, &[*x], v.vary)?[0]);
        }
        Ok(Val { vary: v.vary, c })
    }

    pub(super) fn map2_helper(&mut self, name: &'static str, a: &Val, b: &Val) -> R<Val> {
        let vary = a.vary || b.vary;
        let mut c = Vec::new();
        for (x, y) in a.c.iter().zip(&b.c) {
            c.push(self.call_helper(name, &[*x, *y], vary)?[0]);
        }
        Ok(Val { vary, c })
    }

    pub(super) fn map1(&mut self, v: &Val, f: fn(&mut FunctionBuilder<'_>, Value) -> Value) -> Val {
        Val { vary: v.vary, c: v.c.iter().map(|x| f(&mut self.b, *x)).collect() }
    }

    /// Component-wise over operands widened to one shape; a one-component operand is broadcast.
    pub(super) fn mapn(&mut self, vals: &[&Val], f: impl Fn(&mut FunctionBuilder<'_>, &[Value]) -> Value) -> Val {
        let vary = vals.iter().any(|v| v.vary);
        let n = vals.iter().map(|v| v.c.len()).max().unwrap_or(0);
        let mut c = Vec::with_capacity(n);
        for k in 0..n {
            let args: Vec<Value> = vals
                .iter()
                .map(|v| {
                    let x = if v.c.len() == 1 { v.c[0] } else { v.c[k] };
                    widen(&mut self.b, x, vary)
                })
                .collect();
            c.push(f(&mut self.b, &args));
        }
        Val { vary, c }
    }

    /// `sin` (`which` 0) or `cos` (1) of each component. Both come from one `rtsl_sincos` call,
    /// whose results are kept for the rest of the block: `sin(a)` and `cos(a)` of the same value
    /// (a rotation, a point on a circle) then cost one call and one range reduction.
    pub(super) fn sin_cos(&mut self, v: &Val, which: usize) -> R<Val> {
        let mut c = Vec::with_capacity(v.c.len());
        for &x in &v.c {
            let block = self.b.current_block();
            let cached = self.sincos_results.get(&x).filter(|(b, _)| *b == block).map(|(_, r)| *r);
            let results = match cached {
                Some(r) => r,
                None => {
                    let r = if v.vary && self.b.func.dfg.value_type(x) == types::F32X4 {
                        self.sincos_inline(x)?
                    } else {
                        let r = self.call_helper("rtsl_sincos", &[x], v.vary)?;
                        [r[0], r[1]]
                    };
                    // The inline form may end in a new block (after its fallback).
                    let block = self.b.current_block();
                    self.sincos_results.insert(x, (block, r));
                    r
                }
            };
            c.push(results[which]);
        }
        Ok(Val { vary: v.vary, c })
    }

    /// `sin` and `cos` of four lanes in the chunk's own code ([`math::sincos4`]: the same bits as
    /// the helper and the interpreter). A chunk with a lane beyond `TRIG_MAX` (or NaN) calls the
    /// helper instead, which computes those lanes the slow way. Inline because the call cost more
    /// than the arithmetic. The fallback goes through a register-preserving trampoline: with an
    /// ordinary call every vector live across it was spilled where it was defined, on the hot path.
    fn sincos_inline(&mut self, x: Value) -> R<[Value; 2]> {
        let (sin_v, cos_v, in_range) = math::sincos4(&mut self.b, x);
        // Lanes out of range: the helper, for the whole chunk (its in-range lanes are these bits).
        let (slow, join) = (self.b.create_block(), self.b.create_block());
        let (sin_p, cos_p) =
            (self.b.append_block_param(join, types::F32X4), self.b.append_block_param(join, types::F32X4));
        self.b.ins().brif(in_range, join, &[sin_v.into(), cos_v.into()], slow, &[]);
        self.b.set_cold_block(slow);
        self.b.switch_to_block(slow);
        self.b.seal_block(slow);
        let r = self.call_helper_keeping_registers("rtsl_sincos", &[x])?;
        self.b.ins().jump(join, &[r[0].into(), r[1].into()]);
        self.b.switch_to_block(join);
        self.b.seal_block(join);
        Ok([sin_p, cos_p])
    }
}

//! Noise and random numbers: `noise`, `cellnoise` and `pnoise` (one chunk helper per dimension and
//! result shape, the interpreter's scalar code per lane) and `random()` (each lane's seed and the
//! number of calls it ran in the chunk).

use super::Call;
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{Arg, BaseType};
use cranelift_codegen::ir::InstBuilder;

impl<'m> Lower<'m, '_> {
    /// Lane `x` (an `f32x4`) holds in the first lane that `exec` runs (lane 0 when none runs).
    pub(in crate::back::jit::lower) fn first_running_lane(&mut self, x: cranelift_codegen::ir::Value, exec: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        use cranelift_codegen::ir::{condcodes::IntCC, types};
        let running = self.b.ins().vhigh_bits(types::I32, exec);
        // Bit 4 set: no running lane reads as lane 4, which the selects below leave at lane 3;
        // nothing reads the value then.
        let running = self.b.ins().bor_imm_u(running, 0x10);
        let first = self.b.ins().ctz(running);
        let mut value = self.b.ins().extractlane(x, 3);
        for lane in (0..3u8).rev() {
            let here = self.b.ins().extractlane(x, lane);
            let is = self.b.ins().icmp_imm_u(IntCC::Equal, first, i64::from(lane));
            value = self.b.ins().select(is, here, value);
        }
        value
    }

    /// `noise`, `cellnoise` and `pnoise` through the chunk helpers of their dimension and shape,
    /// and `random()` from each lane's seed and call count.
    pub(super) fn noise(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, e, f) = (call.bi, call.args, call.e, call.f);
        let vals = &call.vals;
        let r = match bi {
            Bi::Noise | Bi::Cellnoise => {
                let first_triple = args.first().is_some_and(|a| match a {
                    Arg::Value(x) => f.expr(*x).ty.base.is_triple(),
                    Arg::Ref(p) => p.ty.base.is_triple(),
                });
                let dims = if first_triple { 2 + vals.len() } else { vals.len() };
                let triple = e.ty.base != BaseType::Float;
                let name: &'static str = match (bi == Bi::Noise, triple, dims) {
                    (true, false, 1) => "rtsl_noise1",
                    (true, false, 2) => "rtsl_noise2",
                    (true, false, 3) => "rtsl_noise3",
                    (true, false, _) => "rtsl_noise4",
                    (true, true, 1) => "rtsl_vnoise1",
                    (true, true, 2) => "rtsl_vnoise2",
                    (true, true, 3) => "rtsl_vnoise3",
                    (true, true, _) => "rtsl_vnoise4",
                    (false, false, 1) => "rtsl_cellnoise1",
                    (false, false, 2) => "rtsl_cellnoise2",
                    (false, false, 3) => "rtsl_cellnoise3",
                    (false, false, _) => "rtsl_cellnoise4",
                    (false, true, 1) => "rtsl_vcellnoise1",
                    (false, true, 2) => "rtsl_vcellnoise2",
                    (false, true, 3) => "rtsl_vcellnoise3",
                    (false, true, _) => "rtsl_vcellnoise4",
                };
                let all = self.concat(vals);
                let c = self.call_helper(name, &all.c, all.vary)?;
                Val { vary: all.vary, c }
            }
            Bi::Turb => {
                let n = self.call_helper_on("rtsl_lucille_turb", &[vals[0].clone()], false)?;
                let comps = if e.ty.base == BaseType::Float { 1 } else { 3 };
                Val { vary: n.vary, c: vec![n.c[0]; comps] }
            }
            Bi::Pnoise => {
                let first_triple = vals[0].c.len() == 3;
                let name: &'static str = match (e.ty.base != BaseType::Float, first_triple, vals.len()) {
                    (false, false, 4) => "rtsl_pnoise2",
                    (false, false, _) => "rtsl_pnoise1",
                    (false, true, 4) => "rtsl_pnoise4",
                    (false, true, _) => "rtsl_pnoise3",
                    (true, false, 4) => "rtsl_vpnoise2",
                    (true, false, _) => "rtsl_vpnoise1",
                    (true, true, 4) => "rtsl_vpnoise4",
                    (true, true, _) => "rtsl_vpnoise3",
                };
                self.call_helper_on(name, vals, false)?
            }
            Bi::Random => {
                let slot = self.layout.seed.ok_or_else(|| JitError::Codegen("no seed slots".into()))?;
                let lo = self.load_slot(true, slot);
                let hi = self.load_slot(true, slot + 1);
                let calls = self.b.use_var(self.random_calls);
                let name = if e.ty.base == BaseType::Float { "rtsl_random" } else { "rtsl_vrandom" };
                let c = self.call_helper(name, &[lo, hi, calls], true)?;
                // Running lanes count the call (exec is -1 there).
                let exec = self.exec();
                let next = self.b.ins().isub(calls, exec);
                self.b.def_var(self.random_calls, next);
                if e.varying {
                    Val { vary: true, c }
                } else {
                    // In uniform context (assigned to a uniform variable) one number serves the
                    // chunk, as one serves a grid in RenderMan: the first running lane's.
                    let c = c.into_iter().map(|x| self.first_running_lane(x, exec)).collect();
                    Val { vary: false, c }
                }
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

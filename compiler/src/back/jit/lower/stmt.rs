//! Statements: blocks, `if` and loops under masks (uniform conditions branch, varying ones run
//! each side under its lanes), `break`/`continue`/`return` through their accumulators, the light
//! statements' bodies; and the analyses deciding where lanes can part ways.

use super::{LoopCx, Lower, R, RUNTIME_LOOP_BUDGET};
use crate::back::jit::mask::{self, any, to_mask};
use crate::back::jit::JitError;
use crate::ir::{self, Arg, BinaryOp, ExprKind, Function, Place, PlaceBase, StmtKind, Type};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, Block, InstBuilder, Value};

impl<'m> Lower<'m, '_> {
    /// Lowers a block; returns early after a statement that leaves it.
    pub(super) fn block(&mut self, blk: &'m ir::Block) -> R<()> {
        for s in &blk.stmts {
            if self.stmt(s)? {
                break;
            }
        }
        Ok(())
    }

    /// After a jump: continue in a fresh, unreachable block.
    fn jump_away(&mut self, target: Block) {
        self.b.ins().jump(target, &[]);
        let dead = self.b.create_block();
        self.b.switch_to_block(dead);
    }

    /// Lowers one statement; true when it leaves the block (break, continue, return).
    pub(super) fn stmt(&mut self, s: &'m ir::Stmt) -> R<bool> {
        let f = self.func();
        match &s.kind {
            StmtKind::Expr(e) => {
                self.expr(*e)?;
            }
            StmtKind::If { cond, then, otherwise } => {
                let c = self.expr(*cond)?;
                if !c.vary {
                    let (tb, eb, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
                    self.b.ins().brif(c.c[0], tb, &[], eb, &[]);
                    self.b.switch_to_block(tb);
                    self.block(then)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(eb);
                    self.block(otherwise)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(join);
                } else {
                    let cm = to_mask(&mut self.b, c.c[0]);
                    let save = self.exec();
                    self.vdepth += 1;
                    self.div += 1;
                    let tm = self.b.ins().band(save, cm);
                    let t = self.masked_block(tm, then)?;
                    let em = self.b.ins().band_not(save, cm);
                    let e = if otherwise.stmts.is_empty() { em } else { self.masked_block(em, otherwise)? };
                    let all = self.b.ins().bor(t, e);
                    self.set_exec(all);
                    self.vdepth -= 1;
                    self.div -= 1;
                }
            }
            StmtKind::Loop { cond, body, step } => {
                let uniform = self.frame().uniform;
                let vary_cond = !uniform && cond.is_some_and(|c| f.expr(c).varying);
                let divergent = !uniform && (vary_cond || divergent_exit(f, body, step));
                if vary_cond {
                    self.vdepth += 1;
                }
                if divergent {
                    self.div += 1;
                }
                let exit_acc = self.b.declare_var(types::I32X4);
                let cont_acc = self.b.declare_var(types::I32X4);
                let z = mask::zero_mask(&mut self.b);
                self.b.def_var(exit_acc, z);
                self.b.def_var(cont_acc, z);
                let iterations = self.loop_count;
                let site = self.site(s.span);
                let (header, body_b, cont_b, exit_b) =
                    (self.b.create_block(), self.b.create_block(), self.b.create_block(), self.b.create_block());
                self.b.ins().jump(header, &[]);
                self.b.switch_to_block(header);
                // The iteration budget, shared by every loop of the invocation: past it, the running
                // lanes leave this loop (as by `break`), every later loop header stops too, and the
                // renderer is told once per loop where.
                let count = self.b.use_var(iterations);
                let count = self.b.ins().iadd_imm_u(count, 1);
                self.b.def_var(iterations, count);
                let over = self.b.ins().icmp_imm_u(IntCC::UnsignedGreaterThan, count, i64::from(self.loop_budget));
                let (stop_b, go_b) = (self.b.create_block(), self.b.create_block());
                self.b.ins().brif(over, stop_b, &[], go_b, &[]);
                self.b.switch_to_block(stop_b);
                self.runtime_error(RUNTIME_LOOP_BUDGET, site)?;
                let e = self.exec();
                let acc = self.b.use_var(exit_acc);
                let acc = self.b.ins().bor(acc, e);
                self.b.def_var(exit_acc, acc);
                self.b.ins().jump(exit_b, &[]);
                self.b.switch_to_block(go_b);
                if let Some(c) = cond {
                    let cv = self.expr(*c)?;
                    let cm = to_mask(&mut self.b, cv.c[0]);
                    let e = self.exec();
                    let leaving = self.b.ins().band_not(e, cm);
                    let acc = self.b.use_var(exit_acc);
                    let acc = self.b.ins().bor(acc, leaving);
                    self.b.def_var(exit_acc, acc);
                    let stay = self.b.ins().band(e, cm);
                    self.set_exec(stay);
                }
                let e = self.exec();
                let live = any(&mut self.b, e);
                self.b.ins().brif(live, body_b, &[], exit_b, &[]);
                self.b.switch_to_block(body_b);
                let z = mask::zero_mask(&mut self.b);
                self.b.def_var(cont_acc, z);
                let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: cont_b, depth: self.vdepth };
                self.frames.last_mut().expect("frame").loops.push(lp);
                self.block(body)?;
                self.b.ins().jump(cont_b, &[]);
                self.b.switch_to_block(cont_b);
                let e = self.exec();
                let ca = self.b.use_var(cont_acc);
                let e = self.b.ins().bor(e, ca);
                self.set_exec(e);
                self.block(step)?;
                self.b.ins().jump(header, &[]);
                self.frames.last_mut().expect("frame").loops.pop();
                self.b.switch_to_block(exit_b);
                let acc = self.b.use_var(exit_acc);
                self.set_exec(acc);
                if vary_cond {
                    self.vdepth -= 1;
                }
                if divergent {
                    self.div -= 1;
                }
            }
            StmtKind::Break(n) | StmtKind::Continue(n) => {
                let loops = &self.frame().loops;
                let lp = *loops
                    .get(loops.len().wrapping_sub(*n as usize))
                    .ok_or_else(|| JitError::Codegen("break outside a loop".into()))?;
                let is_break = matches!(s.kind, StmtKind::Break(_));
                let (acc, target) = if is_break { (lp.exit_acc, lp.exit) } else { (lp.cont_acc, lp.cont) };
                let e = self.exec();
                let a = self.b.use_var(acc);
                let a = self.b.ins().bor(a, e);
                self.b.def_var(acc, a);
                let z = mask::zero_mask(&mut self.b);
                self.set_exec(z);
                if self.vdepth == lp.depth {
                    self.jump_away(target);
                }
                return Ok(true);
            }
            StmtKind::Return(v) => {
                if let Some(v) = v {
                    let val = self.dual(*v)?;
                    let ret = self.frame().ret.clone().ok_or_else(|| JitError::Codegen("return value".into()))?;
                    self.write_store(&ret, &val.v)?;
                    if let Some(ds) = self.frame().dret.clone() {
                        self.write_tangents(&ds, &val)?;
                    }
                }
                let z = mask::zero_mask(&mut self.b);
                self.set_exec(z);
                let (depth, rb) = (self.frame().depth, self.frame().ret_block);
                if self.vdepth == depth {
                    self.jump_away(rb);
                }
                return Ok(true);
            }
            StmtKind::Illuminance { category, position, cone, body } => {
                self.illuminance(*category, *position, *cone, body)?;
            }
            StmtKind::Illuminate { position, cone, body } => {
                let from = self.expr(*position)?;
                let cone = match cone {
                    Some((a, b)) => Some((self.expr(*a)?, self.expr(*b)?)),
                    None => None,
                };
                let ps = self.global_val("Ps")?;
                let l = self.binary(BinaryOp::Sub, Type::POINT, &ps, &from)?;
                match cone {
                    None => {
                        self.set_global("L", &l)?;
                        self.block(body)?
                    }
                    Some((axis, angle)) => {
                        let all = self.concat(&[l.clone(), axis, angle]);
                        let ok = self.call_helper("rtsl_cone", &all.c, true)?[0];
                        let zero = self.fconst(0.0, true);
                        let ok = self.b.ins().fcmp(FloatCC::NotEqual, ok, zero);
                        let save = self.exec();
                        self.vdepth += 1;
                        self.div += 1;
                        let run = self.b.ins().band(save, ok);
                        // L is set only where the body runs.
                        self.set_exec(run);
                        self.set_global("L", &l)?;
                        let after = self.masked_block(run, body)?;
                        let skipped = self.b.ins().band_not(save, ok);
                        let e = self.b.ins().bor(after, skipped);
                        self.set_exec(e);
                        self.vdepth -= 1;
                        self.div -= 1;
                    }
                }
            }
            StmtKind::Solar { cone, body } => {
                if let Some((a, b)) = cone {
                    let axis = self.expr(*a)?;
                    self.expr(*b)?;
                    self.set_global("L", &axis)?;
                }
                self.block(body)?;
            }
            StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                let cone = [*category, *position, *direction, *angle, *samples];
                self.gather(cone, params, body, otherwise)?;
            }
        }
        Ok(false)
    }

    /// Runs `blk` under `m` (skipped when no lane is set); returns `exec` after it.
    pub(super) fn masked_block(&mut self, m: Value, blk: &'m ir::Block) -> R<Value> {
        self.set_exec(m);
        let (run, after) = (self.b.create_block(), self.b.create_block());
        let live = any(&mut self.b, m);
        self.b.ins().brif(live, run, &[], after, &[]);
        self.b.switch_to_block(run);
        self.block(blk)?;
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        Ok(self.exec())
    }
}

/// Whether variable `var` of `f` is assigned anywhere in `f` (directly or as an output argument).
pub(super) fn assigned(f: &Function, var: usize) -> bool {
    let hit = |p: &Place| p.base == PlaceBase::Var(ir::VarId(var as u32));
    f.exprs.iter().any(|e| match &e.kind {
        ExprKind::Assign { place, .. } => hit(place),
        ExprKind::Call { args, .. } | ExprKind::CallBuiltin { args, .. } => {
            args.iter().any(|a| matches!(a, Arg::Ref(p) if hit(p)))
        }
        _ => false,
    })
}

/// Whether `f` may write its variable `var`: by assignment, as an output argument, or as a
/// `gather` output.
pub(super) fn may_write(f: &Function, var: usize) -> bool {
    fn gathers_into(blk: &ir::Block, var: usize) -> bool {
        blk.stmts.iter().any(|s| match &s.kind {
            StmtKind::Gather { params, body, otherwise, .. } => {
                params.iter().any(|(_, a)| matches!(a, Arg::Ref(p) if p.base == PlaceBase::Var(ir::VarId(var as u32))))
                    || gathers_into(body, var)
                    || gathers_into(otherwise, var)
            }
            StmtKind::If { then, otherwise, .. } => gathers_into(then, var) || gathers_into(otherwise, var),
            StmtKind::Loop { body, step, .. } => gathers_into(body, var) || gathers_into(step, var),
            StmtKind::Illuminance { body, .. } | StmtKind::Illuminate { body, .. } | StmtKind::Solar { body, .. } => {
                gathers_into(body, var)
            }
            _ => false,
        })
    }
    assigned(f, var) || gathers_into(&f.body, var)
}

/// Whether a `return` in `blk` can run under a varying condition (`vdepth > 0`).
pub(super) fn divergent_return(f: &Function, blk: &ir::Block, vdepth: u32) -> bool {
    blk.stmts.iter().any(|s| match &s.kind {
        StmtKind::Return(_) => vdepth > 0,
        StmtKind::If { cond, then, otherwise } => {
            let d = vdepth + u32::from(f.expr(*cond).varying);
            divergent_return(f, then, d) || divergent_return(f, otherwise, d)
        }
        StmtKind::Loop { cond, body, step } => {
            let d = vdepth + u32::from(cond.is_some_and(|c| f.expr(c).varying));
            divergent_return(f, body, d) || divergent_return(f, step, d)
        }
        _ => false,
    })
}

/// Whether a loop's body or step can leave the loop (or an outer one) or continue it under a
/// varying condition, so that its lanes part ways.
fn divergent_exit(f: &Function, body: &ir::Block, step: &ir::Block) -> bool {
    fn walk(f: &Function, blk: &ir::Block, vdepth: u32, nest: u32) -> bool {
        blk.stmts.iter().any(|s| match &s.kind {
            StmtKind::Break(n) | StmtKind::Continue(n) => *n > nest && vdepth > 0,
            StmtKind::If { cond, then, otherwise } => {
                let d = vdepth + u32::from(f.expr(*cond).varying);
                walk(f, then, d, nest) || walk(f, otherwise, d, nest)
            }
            StmtKind::Loop { cond, body, step } => {
                let d = vdepth + u32::from(cond.is_some_and(|c| f.expr(c).varying));
                walk(f, body, d, nest + 1) || walk(f, step, d, nest + 1)
            }
            _ => false,
        })
    }
    walk(f, body, 0, 0) || walk(f, step, 0, 0)
}

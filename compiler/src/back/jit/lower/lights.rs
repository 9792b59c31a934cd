//! Light loops: `illuminance` (one `lights` query per chunk, the body once per light under the
//! lanes that have it) and `gather` (one sample ray per round under the lanes still sampling), and
//! the globals (`L`, `Cl`, `Ol`) they set and restore.

use super::deriv::Dual;
use super::{LoopCx, Lower, Val, R};
use crate::back::jit::mask::{self, any, choose, widen};
use crate::back::jit::JitError;
use crate::globals::Global;
use crate::ir::{self, Arg, Constant, ExprId, ExprKind, Place, PlaceBase, Type};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Value};

impl<'m> Lower<'m, '_> {
    pub(super) fn global_val(&mut self, name: &str) -> R<Val> {
        let g = Global::lookup(name).ok_or_else(|| JitError::Codegen(name.into()))?;
        let st = self.store_of(PlaceBase::Global(g))?;
        Ok(self.read_store(&st))
    }

    /// Writes a global under `exec` (nothing when the shader's layout does not hold it).
    pub(super) fn set_global(&mut self, name: &str, v: &Val) -> R<()> {
        let Some(g) = Global::lookup(name) else { return Ok(()) };
        if let Some(ds) = self.dglobals[g.0 as usize].clone() {
            self.write_tangents(&ds, &Dual { v: v.clone(), d: None })?;
        }
        match self.globals[g.0 as usize].clone() {
            Some(st) => self.write_store(&st, v),
            None => Ok(()),
        }
    }

    /// `illuminance`: one `lights` call per chunk, then the body once per light index `k` under the
    /// lanes whose `k`-th non-ambient light exists and passes the cone. Lanes without it wait in
    /// `skip`; `break`/`continue` use the loop accumulators (never jumping: other lanes may be
    /// waiting). `L`, `Cl`, `Ol` are restored afterwards for the lanes that ran the statement.
    pub(super) fn illuminance(
        &mut self,
        category: Option<ExprId>,
        position: ExprId,
        cone: Option<(ExprId, ExprId)>,
        body: &'m ir::Block,
    ) -> R<()> {
        let cat = match category {
            Some(c) => self.expr(c)?,
            None => self.const_string(""),
        };
        if cat.vary {
            return self.per_string(&cat, |s, one| s.illuminance_of(one, position, cone, body));
        }
        self.illuminance_of(cat, position, cone, body)
    }

    /// [`Self::illuminance`] for a uniform category.
    fn illuminance_of(
        &mut self,
        cat: Val,
        position: ExprId,
        cone: Option<(ExprId, ExprId)>,
        body: &'m ir::Block,
    ) -> R<()> {
        let p = self.expr(position)?;
        let (axis, angle, has) = match cone {
            Some((a, b)) => (self.expr(a)?, self.expr(b)?, 1.0),
            None => {
                let z = self.fconst(0.0, false);
                (Val { vary: false, c: vec![z; 3] }, Val { vary: false, c: vec![z] }, 0.0)
            }
        };
        let has = Val { vary: false, c: vec![self.fconst(has, false)] };
        let saved: Vec<(&str, Option<Val>)> =
            ["L", "Cl", "Ol"].into_iter().map(|n| (n, self.global_val(n).ok())).collect();
        let entry = self.exec();
        // The cone goes with the query too: the renderer need not trace the shadows of lights
        // outside it.
        let nesting = Val { vary: false, c: vec![self.fconst(self.light_loops.len() as f32, false)] };
        let all = self.concat(&[cat, p, axis.clone(), angle.clone(), has.clone(), nesting]);
        let out = self.call_helper("rtsl_h_lights", &all.c, true)?;
        let set = self.b.ins().extractlane(out[0], 0);
        let count = self.b.ins().extractlane(out[1], 0);

        self.vdepth += 1;
        self.div += 1;
        let k = self.b.declare_var(types::F32);
        let z = self.b.ins().f32const(0.0);
        self.b.def_var(k, z);
        let exit_acc = self.b.declare_var(types::I32X4);
        let cont_acc = self.b.declare_var(types::I32X4);
        let skip = self.b.declare_var(types::I32X4);
        let zm = mask::zero_mask(&mut self.b);
        self.b.def_var(exit_acc, zm);
        self.b.def_var(cont_acc, zm);
        self.b.def_var(skip, zm);
        let (header, body_b, cont_b, leave, exit_b) = (
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
            self.b.create_block(),
        );
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let kv = self.b.use_var(k);
        let more = self.b.ins().fcmp(FloatCC::LessThan, kv, count);
        let e = self.exec();
        let live = any(&mut self.b, e);
        let go = self.b.ins().band(more, live);
        self.b.ins().brif(go, body_b, &[], leave, &[]);

        self.b.switch_to_block(body_b);
        let kv = self.b.use_var(k);
        let inputs = self.concat(&[Val { vary: false, c: vec![set, kv] }, axis.clone(), angle.clone(), has.clone()]);
        let r = self.call_helper("rtsl_h_light", &inputs.c, true)?;
        let lm = self.b.ins().bitcast(
            types::I32X4,
            MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little),
            r[0],
        );
        let e = self.exec();
        let run = self.b.ins().band(e, lm);
        let skipped = self.b.ins().band_not(e, lm);
        self.b.def_var(skip, skipped);
        self.b.def_var(cont_acc, zm);
        self.set_exec(run);
        for (name, at) in [("L", 1), ("Cl", 4), ("Ol", 7)] {
            let v = Val { vary: true, c: r[at..at + 3].to_vec() };
            self.set_global(name, &v)?;
        }
        let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: cont_b, depth: u32::MAX };
        self.frames.last_mut().expect("frame").loops.push(lp);
        let (run_b, after) = (self.b.create_block(), self.b.create_block());
        let live = any(&mut self.b, run);
        self.b.ins().brif(live, run_b, &[], after, &[]);
        self.b.switch_to_block(run_b);
        self.light_loops.push((set, k));
        let r = self.block(body);
        self.light_loops.pop();
        self.frames.last_mut().expect("frame").loops.pop();
        r?;
        self.b.ins().jump(after, &[]);
        self.b.switch_to_block(after);
        self.b.ins().jump(cont_b, &[]);
        self.b.switch_to_block(cont_b);
        let e = self.exec();
        let ca = self.b.use_var(cont_acc);
        let sk = self.b.use_var(skip);
        let e = self.b.ins().bor(e, ca);
        let e = self.b.ins().bor(e, sk);
        self.set_exec(e);
        self.next_iteration(k, header);

        self.b.switch_to_block(leave);
        let e = self.exec();
        let acc = self.b.use_var(exit_acc);
        let acc = self.b.ins().bor(acc, e);
        self.b.def_var(exit_acc, acc);
        self.b.ins().jump(exit_b, &[]);
        self.b.switch_to_block(exit_b);
        self.vdepth -= 1;
        self.div -= 1;
        let after = self.b.use_var(exit_acc);
        self.set_exec(entry);
        for (name, v) in saved {
            if let Some(v) = v {
                self.set_global(name, &v)?;
            }
        }
        self.set_exec(after);
        Ok(())
    }

    /// `gather` (`shadeops::gather`): the arguments and options once, then per sample `k` one
    /// `rtsl_h_gather` call for the chunk's lanes with `k` below their sample count, the outputs
    /// written (`ray:` under those lanes, `surface:` under the hits), `body` under the hits and
    /// `otherwise` under the misses. Lanes whose samples are done leave through the exit
    /// accumulator; `break`/`continue` use the loop accumulators as in `illuminance`.
    pub(super) fn gather(
        &mut self,
        [category, position, direction, angle, samples]: [ExprId; 5],
        params: &'m [(ExprId, Arg)],
        body: &'m ir::Block,
        otherwise: &'m ir::Block,
    ) -> R<()> {
        use crate::shadeops::gather::{self as g, Output};
        let f = self.func();
        let cat = self.expr(category)?;
        let p = self.expr(position)?;
        let axis = self.expr(direction)?;
        let ang = self.expr(angle)?;
        let count = self.expr(samples)?;
        let mut maxdist = Val { vary: false, c: vec![self.fconst(f32::INFINITY, false)] };
        let mut bias = Val { vary: false, c: vec![self.fconst(0.0, false)] };
        let mut distribution = self.const_string("");
        let mut outputs: Vec<(Output, &'m Place, Option<Value>)> = Vec::new();
        for (name, arg) in params {
            let ExprKind::Const(Constant::String(name)) = &f.expr(*name).kind else {
                // A name known only when the shader runs: each option and output applies under
                // the lanes whose name is its own, as the interpreter decides per point.
                let name = self.expr(*name)?;
                match arg {
                    Arg::Value(x) => {
                        let ty = f.expr(*x).ty;
                        let v = self.expr(*x)?;
                        if ty == Type::FLOAT {
                            let is = self.names_equal(&name, &["maxdist"])?;
                            maxdist = self.choose_val(is, &v, &maxdist);
                            let is = self.names_equal(&name, &["bias"])?;
                            bias = self.choose_val(is, &v, &bias);
                        } else if ty == Type::STRING {
                            let is = self.names_equal(&name, &["distribution"])?;
                            distribution = self.choose_val(is, &v, &distribution);
                        }
                    }
                    Arg::Ref(place) => {
                        for o in Output::ALL.into_iter().filter(|o| o.fits(place.ty)) {
                            let is = self.names_equal(&name, o.names())?;
                            outputs.push((o, place, Some(is)));
                        }
                    }
                }
                continue;
            };
            match arg {
                Arg::Value(x) => {
                    let ty = f.expr(*x).ty;
                    let v = self.expr(*x)?;
                    match g::Options::float_slot(name) {
                        Some(0) if ty == Type::FLOAT => maxdist = v,
                        Some(_) if ty == Type::FLOAT => bias = v,
                        None if name == "distribution" && ty == Type::STRING => distribution = v,
                        _ => {}
                    }
                }
                Arg::Ref(place) => {
                    if let Some(o) = Output::parse(name).filter(|o| o.fits(place.ty)) {
                        outputs.push((o, place, None));
                    }
                }
            }
        }
        let run = GatherRun { p, axis, ang, count, maxdist, bias, outputs };
        match (cat.vary, distribution.vary) {
            (false, false) => self.gather_of(cat, distribution, &run, body, otherwise),
            (true, false) => self.per_string(&cat, |s, c| s.gather_of(c, distribution.clone(), &run, body, otherwise)),
            (_, true) => self.per_string(&distribution, |s, d| {
                if cat.vary {
                    s.per_string(&cat, |s, c| s.gather_of(c, d.clone(), &run, body, otherwise))
                } else {
                    s.gather_of(cat.clone(), d, &run, body, otherwise)
                }
            }),
        }
    }

    /// [`Self::gather`] for a uniform category and distribution.
    fn gather_of(
        &mut self,
        cat: Val,
        distribution: Val,
        run: &GatherRun<'m>,
        body: &'m ir::Block,
        otherwise: &'m ir::Block,
    ) -> R<()> {
        use crate::shadeops::gather as g;
        let GatherRun { p, axis, ang, count, maxdist, bias, outputs } = run;
        // The sample count, `gather::sample_count` per lane: NaN and negatives give 0.
        let n = {
            let x = widen(&mut self.b, count.c[0], true);
            let zero = self.fconst(0.0, true);
            let top = self.fconst(g::MAX_SAMPLES, true);
            let pos = self.b.ins().fcmp(FloatCC::GreaterThan, x, zero);
            let x = choose(&mut self.b, pos, x, zero);
            let below = self.b.ins().fcmp(FloatCC::LessThan, x, top);
            let x = choose(&mut self.b, below, x, top);
            self.b.ins().ceil(x)
        };

        self.vdepth += 1;
        self.div += 1;
        let k = self.b.declare_var(types::F32);
        let z = self.b.ins().f32const(0.0);
        self.b.def_var(k, z);
        let exit_acc = self.b.declare_var(types::I32X4);
        let cont_acc = self.b.declare_var(types::I32X4);
        let zm = mask::zero_mask(&mut self.b);
        self.b.def_var(exit_acc, zm);
        self.b.def_var(cont_acc, zm);
        let (header, body_b, leave, exit_b) =
            (self.b.create_block(), self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(header);
        let kv = self.b.use_var(k);
        let kv = self.b.ins().splat(types::F32X4, kv);
        let more = self.b.ins().fcmp(FloatCC::LessThan, kv, n);
        let e = self.exec();
        let go = self.b.ins().band(e, more);
        let done = self.b.ins().band_not(e, more);
        let acc = self.b.use_var(exit_acc);
        let acc = self.b.ins().bor(acc, done);
        self.b.def_var(exit_acc, acc);
        self.set_exec(go);
        let live = any(&mut self.b, go);
        self.b.ins().brif(live, body_b, &[], leave, &[]);

        self.b.switch_to_block(body_b);
        let kv = self.b.use_var(k);
        let kval = Val { vary: false, c: vec![kv] };
        let nval = Val { vary: true, c: vec![n] };
        let inputs = self.concat(&[
            cat,
            p.clone(),
            axis.clone(),
            ang.clone(),
            kval,
            nval,
            maxdist.clone(),
            bias.clone(),
            distribution,
        ]);
        let rec = self.call_helper("rtsl_h_gather", &inputs.c, true)?;
        let e = self.exec();
        let miss = self.fconst(g::MISS, true);
        let hit = self.fconst(g::HIT, true);
        let ran = self.b.ins().fcmp(FloatCC::NotEqual, rec[0], miss);
        let ran = self.b.ins().band(e, ran);
        let surf = self.b.ins().fcmp(FloatCC::Equal, rec[0], hit);
        let surf = self.b.ins().band(e, surf);
        for (o, place, named) in outputs {
            let under = if o.on_miss() { e } else { surf };
            let under = match named {
                Some(is) => mask::and(&mut self.b, under, *is),
                None => under,
            };
            self.set_exec(under);
            let t = self.place_targets(place)?;
            let row = o.row();
            self.write_targets(&t, &Val { vary: true, c: rec[row..row + o.components()].to_vec() })?;
        }
        self.b.def_var(cont_acc, zm);
        let lp = LoopCx { exit_acc, cont_acc, exit: exit_b, cont: header, depth: u32::MAX };
        self.frames.last_mut().expect("frame").loops.push(lp);
        let after_hit = self.masked_block(ran, body);
        let missed = self.b.ins().band_not(e, ran);
        let after = after_hit.and_then(|h| Ok((h, self.masked_block(missed, otherwise)?)));
        self.frames.last_mut().expect("frame").loops.pop();
        let (after_hit, after_miss) = after?;
        let ca = self.b.use_var(cont_acc);
        let next = self.b.ins().bor(after_hit, after_miss);
        let next = self.b.ins().bor(next, ca);
        self.set_exec(next);
        self.next_iteration(k, header);

        self.b.switch_to_block(leave);
        self.b.ins().jump(exit_b, &[]);
        self.b.switch_to_block(exit_b);
        self.vdepth -= 1;
        self.div -= 1;
        let after = self.b.use_var(exit_acc);
        self.set_exec(after);
        Ok(())
    }
}

/// What a `gather` computes once, before it splits on a varying category or distribution.
struct GatherRun<'m> {
    p: Val,
    axis: Val,
    ang: Val,
    count: Val,
    maxdist: Val,
    bias: Val,
    /// Each output, its place, and for a computed name the lanes whose name is the output's.
    outputs: Vec<(crate::shadeops::gather::Output, &'m Place, Option<Value>)>,
}

impl<'m> Lower<'m, '_> {
    /// Runs `run` once per distinct string among the running lanes of the varying `names`, under
    /// the lanes holding it and with it as a uniform value (a light category, a gather
    /// distribution), as `split_strings` does for built-ins. The lanes running afterwards are
    /// those each round left running.
    fn per_string(&mut self, names: &Val, mut run: impl FnMut(&mut Self, Val) -> R<()>) -> R<()> {
        let save = self.exec();
        self.div += 1;
        self.vdepth += 1;
        let pending = self.b.declare_var(types::I32X4);
        self.b.def_var(pending, save);
        let out = self.b.declare_var(types::I32X4);
        let zm = mask::zero_mask(&mut self.b);
        self.b.def_var(out, zm);
        let (header, body, done) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let p = self.b.use_var(pending);
        let live = any(&mut self.b, p);
        self.b.ins().brif(live, body, &[], done, &[]);

        self.b.switch_to_block(body);
        let (m, one) = self.first_pending_string(names, p);
        self.set_exec(m);
        run(self, one)?;
        let left = self.exec();
        let acc = self.b.use_var(out);
        let acc = self.b.ins().bor(acc, left);
        self.b.def_var(out, acc);
        let rest = self.b.ins().band_not(p, m);
        self.b.def_var(pending, rest);
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(done);
        self.div -= 1;
        self.vdepth -= 1;
        let after = self.b.use_var(out);
        self.set_exec(after);
        Ok(())
    }

    /// Whether the string `name` is one of `names` (a uniform bool or a lane mask).
    fn names_equal(&mut self, name: &Val, names: &[&str]) -> R<Value> {
        let mut is = None;
        for n in names {
            let c = self.const_string(n);
            let eq = self.binary(ir::BinaryOp::Eq, Type::STRING, name, &c)?.c[0];
            is = Some(match is {
                Some(x) => mask::or(&mut self.b, x, eq),
                None => eq,
            });
        }
        is.ok_or_else(|| JitError::Codegen("no names to compare".into()))
    }

    /// `is ? a : b` for one-component values.
    fn choose_val(&mut self, is: Value, a: &Val, b: &Val) -> Val {
        let c = choose(&mut self.b, is, a.c[0], b.c[0]);
        Val { vary: mask::is_vec(&self.b, c), c: vec![c] }
    }
}

impl Lower<'_, '_> {
    /// Ends an iteration of a light or gather loop: its counter `k` (a float variable) one up,
    /// then back to the loop's `header`.
    fn next_iteration(&mut self, k: cranelift_frontend::Variable, header: cranelift_codegen::ir::Block) {
        let kv = self.b.use_var(k);
        let one = self.b.ins().f32const(1.0);
        let k1 = self.b.ins().fadd(kv, one);
        self.b.def_var(k, k1);
        self.b.ins().jump(header, &[]);
    }
}

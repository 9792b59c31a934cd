//! Strings: the constants' handles (interned at compile time, `""` first), the split of a built-in
//! call over the distinct strings of a varying string argument, and `concat`, `match`, `format` and
//! `printf`, whose host helpers read each running lane's strings.

use super::Call;
use crate::back::jit::layout::components;
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::mask::{any, merge};
use crate::back::jit::{host, unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{self, Arg, BaseType, ExprId};
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData};
use cranelift_frontend::Variable;

impl<'m> Lower<'m, '_> {
    pub(in crate::back::jit::lower) fn string_handle(&mut self, s: &str) -> u32 {
        match self.strings.iter().position(|x| x == s) {
            Some(h) => h as u32,
            None => {
                self.strings.push(s.to_string());
                (self.strings.len() - 1) as u32
            }
        }
    }

    pub(in crate::back::jit::lower) fn const_string(&mut self, s: &str) -> Val {
        let h = self.string_handle(s);
        Val { vary: false, c: vec![self.b.ins().f32const(f32::from_bits(h))] }
    }

    /// A built-in whose string arguments differ between lanes (a texture name, a space, a light
    /// category per lane) runs once per distinct string: the first string argument that is
    /// varying is evaluated once, then each round takes the string of the first pending lane, runs
    /// the call under the lanes holding that string (with it as a uniform argument: the call may
    /// split again on another string argument), and merges the result under those lanes. `None`
    /// when no string argument varies; string arguments are then left evaluated in `cache`.
    /// `concat`, `match`, `format` and `printf` need no split: their helpers read every lane's
    /// strings.
    pub(super) fn split_strings(
        &mut self,
        bi: Builtin,
        overload: u16,
        args: &'m [Arg],
        e: &ir::Expr,
    ) -> R<Option<Val>> {
        use Builtin as Bi;
        if matches!(bi, Bi::Concat | Bi::Match | Bi::Format | Bi::Printf) {
            return Ok(None);
        }
        let f = self.func();
        let depth = self.frames.len();
        let strings: Vec<ExprId> = args
            .iter()
            .filter_map(|a| match a {
                Arg::Value(x) if f.expr(*x).ty.base == BaseType::String => Some(*x),
                _ => None,
            })
            .collect();
        let mut split = None;
        for x in &strings {
            let v = match self.cache.get(&(depth, x.0)) {
                Some(v) => v.clone(),
                None => {
                    let v = self.expr(*x)?;
                    self.cache.insert((depth, x.0), v.clone());
                    self.split_keys.push((depth, x.0));
                    v
                }
            };
            if v.vary && split.is_none() {
                split = Some((*x, v));
            }
        }
        let Some((x, names)) = split else { return Ok(None) };
        let comps = match e.ty.base {
            BaseType::Void => 0,
            _ => components(e.ty).ok_or_else(|| JitError::Unsupported(format!("a built-in returning {}", e.ty)))?,
        };
        let save = self.exec();
        self.div += 1;
        self.vdepth += 1;
        let pending = self.b.declare_var(types::I32X4);
        self.b.def_var(pending, save);
        let acc: Vec<Variable> = (0..comps).map(|_| self.b.declare_var(types::F32X4)).collect();
        let zero = self.fconst(0.0, true);
        for a in &acc {
            self.b.def_var(*a, zero);
        }
        let (header, body, done) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let p = self.b.use_var(pending);
        let live = any(&mut self.b, p);
        self.b.ins().brif(live, body, &[], done, &[]);

        self.b.switch_to_block(body);
        let (m, one) = self.first_pending_string(&names, p);
        self.set_exec(m);
        self.cache.insert((depth, x.0), one);
        let r = self.builtin(bi, overload, args, e);
        self.cache.insert((depth, x.0), names);
        let r = r?;
        for (a, c) in acc.iter().zip(&r.c) {
            let old = self.b.use_var(*a);
            let new = merge(&mut self.b, m, *c, old);
            self.b.def_var(*a, new);
        }
        let rest = self.b.ins().band_not(p, m);
        self.b.def_var(pending, rest);
        self.b.ins().jump(header, &[]);

        self.b.switch_to_block(done);
        self.div -= 1;
        self.vdepth -= 1;
        self.set_exec(save);
        let c = acc.iter().map(|a| self.b.use_var(*a)).collect();
        Ok(Some(Val { vary: true, c }))
    }

    /// Of the varying strings `names`, the string of the first lane in `pending` (as a uniform
    /// value) and the pending lanes that hold it (a mask): one round of a split over strings.
    pub(in crate::back::jit::lower) fn first_pending_string(&mut self, names: &Val, pending: cranelift_codegen::ir::Value) -> (cranelift_codegen::ir::Value, Val) {
        let flags = MemFlagsData::new().with_endianness(cranelift_codegen::ir::Endianness::Little);
        let handles = self.b.ins().bitcast(types::I32X4, flags, names.c[0]);
        let mut h = self.b.ins().extractlane(handles, 3);
        for l in (0..3u8).rev() {
            let on = self.b.ins().extractlane(pending, l);
            let hl = self.b.ins().extractlane(handles, l);
            h = self.b.ins().select(on, hl, h);
        }
        let hs = self.b.ins().splat(types::I32X4, h);
        let same = self.b.ins().icmp(IntCC::Equal, handles, hs);
        let m = self.b.ins().band(pending, same);
        let one = self.b.ins().bitcast(types::F32, flags, h);
        (m, Val { vary: false, c: vec![one] })
    }

    /// The string built-ins, whose host helpers read every running lane's strings: `concat`,
    /// `match`, `format` and `printf`.
    pub(super) fn strings(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, f) = (call.bi, call.args, call.f);
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Concat if vals.len() < 2 => v(0),
            Bi::Concat => {
                // Each lane's strings at once (a varying call interns a result per lane), so that
                // only the whole is cut and counted, as in the interpreter.
                let site = self.site(call.e.span) as f32;
                let mut parts = vec![self.fconst(site, false), self.fconst((2 + vals.len()) as f32, false)];
                parts.extend(vals.iter().map(|x| x.c[0]));
                let vary = vals.iter().any(|x| x.vary);
                Val { vary, c: self.call_helper("rtsl_h_concat", &parts, vary)? }
            }
            Bi::Match => self.call_helper_on("rtsl_h_match", &[v(0), v(1)], false)?,
            Bi::Format | Bi::Printf => {
                let printf = bi == Bi::Printf;
                let mut kinds = Vec::new();
                for a in &args[1..] {
                    let ty = match a {
                        Arg::Value(x) => f.expr(*x).ty,
                        Arg::Ref(p) => p.ty,
                    };
                    if ty.is_array() {
                        return unsupported("an array argument of format or printf");
                    }
                    kinds.push(match ty.base {
                        BaseType::Float => host::FMT_FLOAT,
                        b if b.is_triple() => host::FMT_TRIPLE,
                        BaseType::Matrix => host::FMT_MATRIX,
                        BaseType::String => host::FMT_STRING,
                        BaseType::Bool => host::FMT_BOOL,
                        _ => return unsupported(format!("a {ty} argument of format or printf")),
                    });
                }
                let data: usize = vals[1..].iter().map(|x| x.c.len()).sum();
                let mut header = vec![v(0).c[0]];
                header.push(self.fconst((3 + kinds.len() + data + 1) as f32, false));
                header.push(self.fconst(kinds.len() as f32, false));
                for k in &kinds {
                    header.push(self.fconst(*k as f32, false));
                }
                let mut inputs = header;
                for x in &vals[1..] {
                    inputs.extend(x.c.iter().copied());
                }
                let site = self.site(call.e.span) as f32;
                inputs.push(self.fconst(site, false));
                if printf {
                    self.call_helper("rtsl_h_printf", &inputs, true)?;
                    Val { vary: false, c: Vec::new() }
                } else {
                    // A varying call formats and interns each running lane's text.
                    let vary = vals.iter().any(|x| x.vary);
                    call.vary = vary;
                    let c = self.call_helper("rtsl_h_format", &inputs, vary)?;
                    Val { vary, c }
                }
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

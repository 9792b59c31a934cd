//! What the renderer answers beyond textures and messages, through host helpers: the rays it
//! traces (`trace`, `transmission`, `visibility`, `occlusion`, `indirectdiffuse`), the image's
//! pixels (`pixelvalue`) and its state (`depth`, `raydepth`, `shadername`).

use super::{param_arg, Call};
use crate::back::jit::batch::OFF_PIXELS;
use crate::back::jit::host::{PixelChannel, PixelView};
use crate::back::jit::lower::{mem, readonly, Lower, Val, R};
use crate::back::jit::mask::{choose, widen};
use crate::back::jit::{facts, unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{Arg, BaseType, Constant, ExprKind};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, InstBuilder, Value};
use std::mem::offset_of;

impl<'m> Lower<'m, '_> {
    /// Rays and the renderer's state: `trace`, `transmission`, `visibility`, `occlusion`,
    /// `indirectdiffuse`, `pixelvalue`, `depth`, `raydepth` and `shadername`.
    pub(super) fn renderer(&mut self, call: &mut Call<'m, '_>) -> R<Val> {
        use Builtin as Bi;
        let (bi, args, e, f, fixed) = (call.bi, call.args, call.e, call.f, call.fixed);
        let vals = &call.vals;
        let v = |i: usize| vals[i].clone();
        let r = match bi {
            Bi::Depth => self.call_helper_on("rtsl_h_depth", &[v(0)], true)?,
            Bi::Raydepth => {
                call.vary = false;
                self.call_helper_on("rtsl_h_raydepth", &[], false)?
            }
            Bi::Shadername => {
                let (kind, has) = if vals.is_empty() { (self.const_string(""), 0.0) } else { (v(0), 1.0) };
                let has = Val { vary: false, c: vec![self.fconst(has, false)] };
                if kind.vary {
                    return unsupported("varying strings");
                }
                call.vary = false;
                self.call_helper_on("rtsl_h_shadername", &[kind, has], false)?
            }
            Bi::Trace => {
                let r = self.call_helper_on("rtsl_h_trace", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    Val { vary: true, c: vec![r.c[3]] }
                } else {
                    Val { vary: true, c: r.c[..3].to_vec() }
                }
            }
            Bi::Transmission => self.call_helper_on("rtsl_h_transmission", &[v(0), v(1)], true)?,
            Bi::Pixelvalue => {
                let float = e.ty.base == BaseType::Float;
                let literal = match args.first() {
                    Some(Arg::Value(x)) => match &f.expr(*x).kind {
                        ExprKind::Const(Constant::String(name)) => Some(name.as_str()),
                        _ => None,
                    },
                    _ => None,
                };
                // One of the image's channels, else the output variable of that name, the k-th
                // of those the shader names (`CompiledShader::pixel_outputs`).
                let read = literal.and_then(|name| match PixelChannel::of(name) {
                    Some(channel) => Some(PixelRead::Channel(channel)),
                    None => facts::pixel_outputs(self.m).iter().position(|n| n == name).map(PixelRead::Output),
                });
                let c = match read {
                    Some(read) => self.pixel_value(read, [v(0), v(1), v(2)], if float { 1 } else { 3 })?,
                    None => self.call_helper_on("rtsl_h_pixelvalue", &[v(0), v(1), v(2)], true)?,
                };
                if float {
                    Val { vary: true, c: vec![c.c[0]] }
                } else {
                    c
                }
            }
            Bi::Visibility => {
                let t = self.call_helper_on("rtsl_h_transmission", &[v(0), v(1)], true)?;
                if e.ty.base == BaseType::Float {
                    let zero = self.fconst(0.0, true);
                    let mut any_pos = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[0], zero);
                    for k in 1..3 {
                        let c = self.b.ins().fcmp(FloatCC::GreaterThan, t.c[k], zero);
                        any_pos = self.b.ins().bor(any_pos, c);
                    }
                    let one = self.fconst(1.0, true);
                    Val { vary: true, c: vec![choose(&mut self.b, any_pos, one, zero)] }
                } else {
                    t
                }
            }
            Bi::Occlusion | Bi::Indirectdiffuse => {
                let samples = if fixed == 3 {
                    v(2)
                } else {
                    match param_arg(f, args, fixed, "samples")? {
                        Some(a) => {
                            let i = args.iter().position(|x| std::ptr::eq(x, a)).unwrap_or(0);
                            vals[i].clone()
                        }
                        None => Val { vary: false, c: vec![self.fconst(16.0, false)] },
                    }
                };
                let name = if bi == Bi::Occlusion { "rtsl_h_occlusion" } else { "rtsl_h_indirectdiffuse" };
                // Aqsis's occlusion: an occlusion map's name, then P and N.
                let at = usize::from(fixed == 4);
                self.call_helper_on(name, &[v(at), v(at + 1), samples], true)?
            }
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        Ok(r)
    }
}

impl Lower<'_, '_> {
    /// `pixelvalue(name, x, y)` of a channel named by a literal: read from the image the batch
    /// record points to ([`PixelView`]), four lanes in the chunk's own code, or where the record
    /// has no image (or, for an output variable, no array of it), through the helper (a renderer
    /// without one, a test host). The values of
    /// the runtime's `PixelImage::value` and so of the interpreter: the nearest pixel inside the
    /// image, zero in every component for a coordinate that is not finite. `wanted` components
    /// are read (1 or 3); the others are zero.
    fn pixel_value(&mut self, read: PixelRead, args: [Val; 3], wanted: usize) -> R<Val> {
        let batch = self.batch.expect("batch");
        let ptr = self.ptr;
        let view = self.b.ins().load(ptr, mem(), batch, OFF_PIXELS);
        let (inline_b, helper_b, join) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        let results: Vec<Value> = (0..3).map(|_| self.b.append_block_param(join, types::F32X4)).collect();
        let none = self.b.ins().icmp_imm_u(IntCC::Equal, view, 0);
        let array = match read {
            PixelRead::Channel(channel) => {
                self.b.ins().brif(none, helper_b, &[], inline_b, &[]);
                PixelArray::Channel(channel)
            }
            PixelRead::Output(k) => {
                // The view's `k`-th output array, where it has one (else the helper answers).
                let (count_b, table_b) = (self.b.create_block(), self.b.create_block());
                self.b.ins().brif(none, helper_b, &[], count_b, &[]);
                self.b.switch_to_block(count_b);
                self.b.seal_block(count_b);
                let count = self.b.ins().load(types::I32, readonly(), view, offset_of!(PixelView, output_count) as i32);
                let held = self.b.ins().icmp_imm_u(IntCC::UnsignedGreaterThan, count, k as i64);
                self.b.ins().brif(held, table_b, &[], helper_b, &[]);
                self.b.switch_to_block(table_b);
                self.b.seal_block(table_b);
                let table = self.b.ins().load(ptr, readonly(), view, offset_of!(PixelView, outputs) as i32);
                let at = i32::try_from(k * ptr.bytes() as usize).map_err(|_| JitError::Unsupported("pixel outputs".into()))?;
                let base = self.b.ins().load(ptr, readonly(), table, at);
                let missing = self.b.ins().icmp_imm_u(IntCC::Equal, base, 0);
                self.b.ins().brif(missing, helper_b, &[], inline_b, &[]);
                PixelArray::Output(base)
            }
        };

        self.b.switch_to_block(helper_b);
        self.b.seal_block(helper_b);
        let called = self.call_helper_on("rtsl_h_pixelvalue", &args, true)?;
        let called: Vec<_> = called.c.iter().map(|&c| widen(&mut self.b, c, true).into()).collect();
        self.b.ins().jump(join, &called);

        self.b.switch_to_block(inline_b);
        self.b.seal_block(inline_b);
        let x = widen(&mut self.b, args[1].c[0], true);
        let y = widen(&mut self.b, args[2].c[0], true);
        let read = self.pixel_lanes(view, array, [x, y], wanted);
        let read: Vec<_> = read.iter().map(|&c| c.into()).collect();
        self.b.ins().jump(join, &read);

        self.b.switch_to_block(join);
        self.b.seal_block(join);
        Ok(Val { vary: true, c: results })
    }

    /// Channel `channel` of the pixels at four lanes' raster `x`, `y` of the image `view`: its
    /// first `wanted` components, zero past them and in lanes whose coordinates are not finite.
    /// Every index is clamped into the image, which holds `width * height` pixels in every array
    /// (`PixelView::new`), so every load is inside it whatever the coordinates.
    fn pixel_lanes(&mut self, view: Value, array: PixelArray, [x, y]: [Value; 2], wanted: usize) -> [Value; 3] {
        let b = &mut self.b;
        let field = |b: &mut cranelift_frontend::FunctionBuilder<'_>, ty, offset: usize| {
            b.ins().load(ty, readonly(), view, offset as i32)
        };
        let width = field(b, types::I32, offset_of!(PixelView, width));
        let height = field(b, types::I32, offset_of!(PixelView, height));
        // Finite lanes: `v - v` is zero for a finite `v` and NaN otherwise.
        let fzero = b.ins().f32const(0.0);
        let fzero = b.ins().splat(types::F32X4, fzero);
        let finite = |b: &mut cranelift_frontend::FunctionBuilder<'_>, v: Value| {
            let d = b.ins().fsub(v, v);
            b.ins().fcmp(FloatCC::Equal, d, fzero)
        };
        let (fx, fy) = (finite(b, x), finite(b, y));
        let finite = b.ins().band(fx, fy);
        // `floor`, then into `0..=extent - 1` (a saturating conversion: huge values and NaN stay
        // representable, and NaN lanes are zeroed below): `PixelImage::value`'s pixel.
        let izero = b.ins().iconst(types::I32, 0);
        let izero = b.ins().splat(types::I32X4, izero);
        let clamped = |b: &mut cranelift_frontend::FunctionBuilder<'_>, v: Value, extent: Value| {
            let f = b.ins().floor(v);
            let i = b.ins().fcvt_to_sint_sat(types::I32X4, f);
            let top = b.ins().iadd_imm_s(extent, -1);
            let top = b.ins().splat(types::I32X4, top);
            let i = b.ins().smax(i, izero);
            b.ins().smin(i, top)
        };
        let (px, py) = (clamped(b, x, width), clamped(b, y, height));
        let row = b.ins().splat(types::I32X4, width);
        let index = b.ins().imul(py, row);
        let index = b.ins().iadd(index, px);
        let ptr = self.ptr;
        // The array, its entry size and the offsets of the components in an entry.
        let (base, size, offsets): (Value, i64, &[i32]) = match array {
            PixelArray::Output(base) => (base, 12, &[0, 4, 8]),
            PixelArray::Channel(channel) => {
                let (field_at, size, offsets): (usize, i64, &[i32]) = match channel {
                    PixelChannel::Ci => (offset_of!(PixelView, rgba), 16, &[0, 4, 8]),
                    PixelChannel::Alpha => (offset_of!(PixelView, rgba), 16, &[12]),
                    PixelChannel::Z => (offset_of!(PixelView, depth), 4, &[0]),
                    PixelChannel::ObjectId => (offset_of!(PixelView, object_id), 4, &[0]),
                    PixelChannel::ShaderId => (offset_of!(PixelView, shader_id), 4, &[0]),
                    PixelChannel::N => (offset_of!(PixelView, normal), 12, &[0, 4, 8]),
                };
                (field(b, ptr, field_at), size, offsets)
            }
        };
        let ids = matches!(array, PixelArray::Channel(PixelChannel::ObjectId | PixelChannel::ShaderId));
        let entries: Vec<Value> = (0..4)
            .map(|lane| {
                let i = b.ins().extractlane(index, lane);
                let i = b.ins().uextend(ptr, i);
                let at = b.ins().imul_imm_s(i, size);
                b.ins().iadd(base, at)
            })
            .collect();
        let mut out = [fzero; 3];
        for (k, &offset) in offsets.iter().enumerate().take(wanted) {
            let mut lanes = fzero;
            for (lane, &entry) in entries.iter().enumerate() {
                let v = if ids {
                    // -1 for none (`u32::MAX`), else the id as a float, rounded as `as f32` rounds.
                    let id = b.ins().load(types::I32, readonly(), entry, offset);
                    let none = b.ins().icmp_imm_s(IntCC::Equal, id, -1);
                    let as_float = b.ins().fcvt_from_uint(types::F32, id);
                    let minus_one = b.ins().f32const(-1.0);
                    b.ins().select(none, minus_one, as_float)
                } else {
                    b.ins().load(types::F32, readonly(), entry, offset)
                };
                lanes = b.ins().insertlane(lanes, v, lane as u8);
            }
            out[k] = choose(b, finite, lanes, fzero);
        }
        out
    }
}

/// What a `pixelvalue` of a literal name reads: one of the image's channels, or the `k`-th output
/// variable of those the shader names (`CompiledShader::pixel_outputs`).
#[derive(Clone, Copy, Debug)]
enum PixelRead {
    Channel(PixelChannel),
    Output(usize),
}

/// Where [`Lower::pixel_lanes`] reads: a channel's array of the view, or an output's array
/// (its address, checked non-null).
#[derive(Clone, Copy, Debug)]
enum PixelArray {
    Channel(PixelChannel),
    Output(Value),
}

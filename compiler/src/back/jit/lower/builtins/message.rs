//! Message passing: `surface()`, `displacement()`, `atmosphere()`, `lightsource()` (each lane's
//! current light inside `illuminance`), `incident()` and `opposite()`, `attribute()`, `option()`,
//! `rendererinfo()`, `rayinfo()` and `textureinfo()`: a host helper answers, and the destination is
//! written where it knows the name.

use crate::back::jit::layout::components;
use crate::back::jit::lower::{Lower, Val, R};
use crate::back::jit::mask::to_mask;
use crate::back::jit::{host, unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{self, Arg};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::InstBuilder;

impl<'m> Lower<'m, '_> {
    /// Message passing: `f(name, output dest)` (`textureinfo(tex, name, dest)`): 1 and the value
    /// written where the renderer knows the name with the destination's shape, else 0.
    pub(super) fn message(&mut self, bi: Builtin, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        let (name_arg, dest_arg) = if bi == Builtin::Textureinfo { (1, 2) } else { (0, 1) };
        let mut name = None;
        for (k, a) in args.iter().enumerate() {
            let v = self.arg_val(a)?;
            if k == name_arg {
                name = Some(v);
            }
        }
        let name = name.ok_or_else(|| JitError::Codegen("message name".into()))?;
        let Some(Arg::Ref(place)) = args.get(dest_arg) else { return unsupported("a message without a destination") };
        let class = host::msg_class(place.ty.base)
            .ok_or_else(|| JitError::Unsupported(format!("a message into {}", place.ty)))?;
        let len = place.ty.array_len().unwrap_or(0);
        let floats = components(place.ty).unwrap_or(1) * len.max(1) as usize;
        if floats > host::MESSAGE_FLOATS || name.vary {
            return unsupported("a message of this shape");
        }
        let vary = e.varying;
        let cl = self.fconst(class as f32, false);
        let ln = self.fconst(len as f32, false);
        // Inside an illuminance loop, `lightsource()` asks about each lane's current light.
        let out = match self.light_loops.last() {
            Some(&(set, k)) if bi == Builtin::Lightsource => {
                let k = self.b.use_var(k);
                self.call_helper("rtsl_h_light_message", &[set, k, name.c[0], cl, ln], true)?
            }
            // `incident()` and `opposite()` ask about the volume on one side of each lane's surface.
            _ if matches!(bi, Builtin::Incident | Builtin::Opposite) => {
                let which = self.fconst(bi as u32 as f32, false);
                let mut inputs = vec![which, name.c[0], cl, ln];
                for g in ["I", "Ng"] {
                    inputs.extend(self.global_val(g)?.c);
                }
                self.call_helper("rtsl_h_volume_message", &inputs, true)?
            }
            _ => {
                let which = self.fconst(bi as u32 as f32, false);
                self.call_helper("rtsl_h_message", &[which, name.c[0], cl, ln], vary)?
            }
        };
        let vary = vary || (bi == Builtin::Lightsource && !self.light_loops.is_empty());
        let found = out[0];
        let value = Val { vary, c: out[1..1 + floats].to_vec() };
        let t = self.place_targets(place)?;
        let zero = self.fconst(0.0, vary);
        let ok = self.b.ins().fcmp(FloatCC::NotEqual, found, zero);
        if vary {
            let save = self.exec();
            let okm = to_mask(&mut self.b, ok);
            let m = self.b.ins().band(save, okm);
            self.set_exec(m);
            self.div += 1;
            let r = self.write_targets(&t, &value);
            self.div -= 1;
            self.set_exec(save);
            r?;
        } else {
            let (wb, join) = (self.b.create_block(), self.b.create_block());
            self.b.ins().brif(ok, wb, &[], join, &[]);
            self.b.switch_to_block(wb);
            self.write_targets(&t, &value)?;
            self.b.ins().jump(join, &[]);
            self.b.switch_to_block(join);
        }
        Ok(Val { vary, c: vec![found] })
    }
}

//! Built-in calls: `builtin` lowers a call (once per distinct string when a string argument
//! varies, see `strings.rs`), and two dispatchers send each built-in to the function of its family:
//! `builtin_once` for the component-wise ones, whose arguments must have components, and
//! `builtin_ext` for the rest (matrices, spaces, the renderer's services, strings).
//!
//! - `math.rs`: scalar and component-wise math, `filterstep` and `spline`;
//! - `noise.rs`: `noise`, `cellnoise`, `pnoise` and `random`;
//! - `geometry.rs`: triple components, lengths and distances, `normalize`, `faceforward`,
//!   `reflect`, `refract`, `fresnel`;
//! - `transform.rs`: matrices, space lookups and casts, `transform` and its kin;
//! - `shading.rs`: the shading models (`ambient`, `diffuse`, `specular`, `phong`, `specularbrdf`);
//! - `texture.rs`: `texture`, `environment`, `shadow`, `texture3d`, `bump`, and the point-cloud
//!   built-ins;
//! - `renderer.rs`: rays (`trace`, `transmission`, `visibility`, `occlusion`,
//!   `indirectdiffuse`), `pixelvalue`, `depth`, `raydepth`, `shadername`;
//! - `strings.rs`: string constants, the split over varying strings, `concat`, `match`, `format`,
//!   `printf`;
//! - `message.rs`: message passing (`surface()`, `lightsource()`, `attribute()`,
//!   `textureinfo()`...).

use super::{const_index, Idx, Lower, Targets, Val, R};
use crate::back::jit::layout::components;
use crate::back::jit::{unsupported, JitError};
use crate::builtins::Builtin;
use crate::ir::{self, Arg, BaseType, Constant, ExprKind, Function};

mod geometry;
mod math;
mod message;
mod noise;
mod renderer;
mod shading;
mod strings;
mod texture;
mod transform;

/// A built-in call being lowered, its arguments evaluated left to right: what the function of its
/// family reads.
struct Call<'m, 'e> {
    bi: Builtin,
    args: &'m [Arg],
    e: &'e ir::Expr,
    /// The function the call is in.
    f: &'m Function,
    /// How many arguments come before the parameter list (see [`fixed_args`]).
    fixed: usize,
    /// The arguments' values (an output argument's value when the call starts).
    vals: Vec<Val>,
    /// The places of the output arguments.
    refs: Vec<Option<Targets>>,
    /// For `builtin_ext`: whether the result is varying (the IR says so, or an argument is), when
    /// a uniform result is widened. A family sets it to its result's own shape where that is
    /// uniform whatever the call (`raydepth`) or follows the operands alone (`format`).
    vary: bool,
}

impl Call<'_, '_> {
    fn is_matrix_arg(&self, k: usize) -> bool {
        is_matrix_arg(self.f, self.args, k)
    }
}

/// Whether argument `k` of a call in `f` is a matrix.
fn is_matrix_arg(f: &Function, args: &[Arg], k: usize) -> bool {
    match args.get(k) {
        Some(Arg::Value(x)) => f.expr(*x).ty.base == BaseType::Matrix,
        Some(Arg::Ref(p)) => p.ty.base == BaseType::Matrix,
        None => false,
    }
}

/// How many arguments of a call come before its parameter list (`"name", value` pairs): all of
/// them when the built-in's last parameter repeats.
fn fixed_args(bi: Builtin, overload: u16, args: &[Arg]) -> usize {
    let sig = &crate::builtins::signatures(bi)[overload as usize];
    if sig.repeat_last {
        args.len()
    } else {
        sig.params.len().min(args.len())
    }
}

impl<'m> Lower<'m, '_> {
    /// Lowers a built-in call; the argument values `split_strings` left in `cache` for it are
    /// dropped afterwards.
    pub(super) fn builtin(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        let mark = self.split_keys.len();
        let r = self.builtin_once(bi, overload, args, e);
        for k in self.split_keys.split_off(mark) {
            self.cache.remove(&k);
        }
        r
    }

    /// A built-in call, once per distinct string of a varying string argument (`split_strings`)
    /// or else once: by a family of `builtin_ext`, or a component-wise one, whose arguments must
    /// all have components.
    fn builtin_once(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Val> {
        use Builtin as Bi;
        if let Some(r) = self.split_strings(bi, overload, args, e)? {
            return Ok(r);
        }
        if let Some(r) = self.builtin_ext(bi, overload, args, e)? {
            return Ok(r);
        }
        let f = self.func();
        let family: fn(&mut Self, &mut Call<'m, '_>) -> R<Val> = match bi {
            Bi::Abs
            | Bi::Sign
            | Bi::Floor
            | Bi::Ceil
            | Bi::Round
            | Bi::Sqrt
            | Bi::InverseSqrt
            | Bi::Exp
            | Bi::Log
            | Bi::Pow
            | Bi::Sin
            | Bi::Cos
            | Bi::Tan
            | Bi::Asin
            | Bi::Acos
            | Bi::Atan
            | Bi::Radians
            | Bi::Degrees
            | Bi::Mod
            | Bi::Min
            | Bi::Max
            | Bi::Clamp
            | Bi::Mix
            | Bi::Step
            | Bi::Smoothstep => Self::math,
            Bi::Noise | Bi::Cellnoise => Self::noise,
            Bi::Xcomp
            | Bi::Ycomp
            | Bi::Zcomp
            | Bi::SetXcomp
            | Bi::SetYcomp
            | Bi::SetZcomp
            | Bi::Length
            | Bi::Normalize
            | Bi::Distance
            | Bi::Ptlined
            | Bi::Faceforward
            | Bi::Reflect
            | Bi::Comp
            | Bi::SetComp => Self::geometry,
            Bi::Specularbrdf => Self::shading,
            _ => return unsupported(format!("the built-in {}", bi.name())),
        };
        let mut vals = Vec::with_capacity(args.len());
        let mut refs = Vec::with_capacity(args.len());
        for a in args {
            match a {
                Arg::Value(x) => {
                    if components(f.expr(*x).ty).is_none() {
                        return unsupported(format!("{} with a {} argument", bi.name(), f.expr(*x).ty));
                    }
                    vals.push(self.expr(*x)?);
                    refs.push(None);
                }
                Arg::Ref(p) => {
                    if components(p.ty).is_none() {
                        return unsupported(format!("{} with a {} argument", bi.name(), p.ty));
                    }
                    let t = self.place_targets(p)?;
                    vals.push(self.read_targets(&t)?);
                    refs.push(Some(t));
                }
            }
        }
        let fixed = fixed_args(bi, overload, args);
        let mut call = Call { bi, args, e, f, fixed, vals, refs, vary: false };
        family(self, &mut call)
    }

    /// The built-ins beyond the component-wise ones (matrices, spaces, the renderer's services,
    /// strings, messages); `None` for the others.
    fn builtin_ext(&mut self, bi: Builtin, overload: u16, args: &'m [Arg], e: &ir::Expr) -> R<Option<Val>> {
        use Builtin as Bi;
        let f = self.func();
        let fixed = fixed_args(bi, overload, args);
        let family: fn(&mut Self, &mut Call<'m, '_>) -> R<Val> = match bi {
            Bi::Comp | Bi::SetComp if is_matrix_arg(f, args, 0) => Self::transform,
            Bi::Rotate if e.ty.base == BaseType::Matrix || args.len() == 4 => Self::transform,
            Bi::Determinant
            | Bi::Translate
            | Bi::Scale
            | Bi::Transform
            | Bi::Vtransform
            | Bi::Ntransform
            | Bi::Mtransform
            | Bi::Ctransform => Self::transform,
            Bi::Refract | Bi::Fresnel => Self::geometry,
            Bi::Ambient | Bi::Diffuse | Bi::Specular | Bi::Phong => Self::shading,
            Bi::Texture
            | Bi::Environment
            | Bi::Shadow
            | Bi::Texture3d
            | Bi::Bump
            | Bi::Bake3d
            | Bi::Bake
            | Bi::Photonmap => {
                Self::texture
            }
            Bi::Depth
            | Bi::Raydepth
            | Bi::Shadername
            | Bi::Pixelvalue
            | Bi::Trace
            | Bi::Transmission
            | Bi::Visibility
            | Bi::Occlusion
            | Bi::Indirectdiffuse => Self::renderer,
            Bi::Spline => Self::spline,
            Bi::Filterstep => Self::math,
            Bi::Pnoise | Bi::Random | Bi::Turb => Self::noise,
            Bi::Concat | Bi::Format | Bi::Printf | Bi::Match => Self::strings,
            // Message passing evaluates the name, then reads nothing else before the call.
            Bi::Atmosphere
            | Bi::Displacement
            | Bi::Lightsource
            | Bi::Surface
            | Bi::Incident
            | Bi::Opposite
            | Bi::Attribute
            | Bi::Option
            | Bi::Rendererinfo
            | Bi::Rayinfo
            | Bi::Textureinfo => return self.message(bi, args, e).map(Some),
            _ => return Ok(None),
        };
        // Fixed arguments, left to right (parameter lists: the whole list, in order).
        let mut vals = Vec::with_capacity(args.len());
        let mut refs = Vec::with_capacity(args.len());
        for a in args {
            match a {
                Arg::Value(x) => {
                    vals.push(self.expr(*x)?);
                    refs.push(None);
                }
                Arg::Ref(p) => {
                    let t = self.place_targets(p)?;
                    vals.push(self.read_targets(&t)?);
                    refs.push(Some(t));
                }
            }
        }
        // In uniform mode the IR's flag describes the callee's general case, not this call: only
        // the built-in's own variation (`random`, ...) and the actual operands count.
        let ir_varying =
            if self.frame().uniform { bi.flags() & crate::builtins::flags::VARYING != 0 } else { e.varying };
        let vary = ir_varying || vals.iter().any(|x| x.vary);
        let mut call = Call { bi, args, e, f, fixed, vals, refs, vary };
        let r = family(self, &mut call)?;
        if call.vary && !r.vary {
            return Ok(Some(self.concat(&[Val { vary: true, c: r.c }])));
        }
        Ok(Some(r))
    }

    fn arg_val(&mut self, a: &Arg) -> R<Val> {
        match a {
            Arg::Value(x) => self.expr(*x),
            Arg::Ref(p) => {
                let t = self.place_targets(p)?;
                self.read_targets(&t)
            }
        }
    }

    pub(super) fn arg_index(&mut self, args: &[Arg], k: usize, v: &Val, n: usize) -> Idx {
        if let Some(Arg::Value(x)) = args.get(k) {
            if let ExprKind::Const(Constant::Float(c)) = self.func().expr(*x).kind {
                return Idx::Const(const_index(c, n));
            }
        }
        self.dyn_index(v.c[0], n)
    }

    fn write_ref(&mut self, refs: &[Option<Targets>], v: &Val) -> R<()> {
        match refs.first() {
            Some(Some(t)) => self.write_targets(t, v),
            _ => Err(JitError::Codegen("output argument".into())),
        }
    }
}

/// The `"name", value` pairs after the fixed arguments: the value of `name` (names must be constants).
fn param_arg<'m>(f: &'m Function, args: &'m [Arg], fixed: usize, name: &str) -> R<Option<&'m Arg>> {
    let rest = args.get(fixed..).unwrap_or(&[]);
    for pair in rest.chunks(2) {
        let [Arg::Value(n), v] = pair else { continue };
        match &f.expr(*n).kind {
            ExprKind::Const(Constant::String(s)) if s == name => return Ok(Some(v)),
            ExprKind::Const(Constant::String(_)) => {}
            _ => return unsupported("a parameter list with computed names"),
        }
    }
    Ok(None)
}

//! Which values need derivatives: the compile-time half of forward-mode differentiation.
//!
//! A ray tracer has no grids, so `Du`, `Dv`, `Deriv`, `area`, `calculatenormal` and `filterstep`
//! (without an explicit width) differentiate their arguments with respect to the screen: back ends
//! carry the values that feed them as dual numbers `(value, d/dx, d/dy)`, starting from the
//! derivatives of the varying input globals the renderer supplies (`docs/packet-abi.md`,
//! "Derivatives"). This pass finds those values, so everything else costs nothing extra.
//!
//! It is a backward dataflow analysis to a fixed point over the whole module, with one fact per
//! expression, per variable (per function, for every call site together), per function result and
//! per global:
//! - **Roots**: the differentiated arguments of the derivative built-ins (see [`is_root_arg`]).
//! - An expression that needs a dual needs its differentiable operands as duals (arithmetic,
//!   conversions, constructors, space casts, both sides of a select, array elements, the value
//!   arguments of a built-in, the base of an index; never conditions, indices or strings).
//! - A variable read where a dual is needed needs tangent storage; then every value assigned to it
//!   (assignments, argument copy-in of a parameter, shader parameter defaults) is a dual too, and an
//!   output argument links the caller's place and the callee's parameter both ways.
//! - A call whose result is needed as a dual needs the callee's `return` values as duals.
//!
//! Invariant: if a value's derivative can reach a derivative built-in, it is marked (the back ends
//! rely on it: an unmarked value is treated as having zero derivatives, so over-marking costs time
//! but never changes results, and under-marking would be a bug).

use super::{Arg, Block, Constant, ExprKind, FuncId, Function, Module, PlaceBase, StmtKind};
use crate::builtins::Builtin;
use crate::globals::GLOBALS;

/// The result of [`analyse`].
#[derive(Clone, Debug, Default)]
pub struct DerivInfo {
    /// Per function, per expression: computed as a dual.
    pub exprs: Vec<Vec<bool>>,
    /// Per function, per variable: has tangent storage.
    pub vars: Vec<Vec<bool>>,
    /// Per function: its result is needed as a dual.
    pub ret: Vec<bool>,
    /// Per global: tangents are kept (loaded from the renderer's derivatives, updated on writes).
    pub globals: Vec<bool>,
    /// The module calls a derivative built-in at all.
    pub any: bool,
    /// The module calls `calculatenormal` (which reads `dPdu`, `dPdv` and `Ng` for orientation).
    pub normals: bool,
    /// The module calls `texture` (whose coordinates' derivatives are its filter footprint).
    pub textures: bool,
}

impl DerivInfo {
    pub fn expr(&self, f: FuncId, e: super::ExprId) -> bool {
        self.exprs.get(f.0 as usize).and_then(|v| v.get(e.0 as usize)).copied().unwrap_or(false)
    }

    pub fn var(&self, f: FuncId, v: super::VarId) -> bool {
        self.vars.get(f.0 as usize).and_then(|x| x.get(v.0 as usize)).copied().unwrap_or(false)
    }

    pub fn global(&self, g: crate::globals::Global) -> bool {
        self.globals.get(g.0 as usize).copied().unwrap_or(false)
    }

    fn place(&self, f: usize, base: PlaceBase) -> bool {
        match base {
            PlaceBase::Var(v) => self.vars[f][v.0 as usize],
            PlaceBase::Global(g) => self.globals[g.0 as usize],
        }
    }
}

/// Whether argument `k` (of `n`) of a call to `b` is differentiated by the built-in itself.
pub fn is_root_arg(b: Builtin, k: usize, n: usize) -> bool {
    match b {
        Builtin::Du | Builtin::Dv | Builtin::Area | Builtin::Calculatenormal => k == 0,
        Builtin::Deriv => k < 2,
        // `filterstep(edge, x, ...)`: the width comes from the derivatives of `x` unless a second
        // value or a "width" parameter gives it (a conservative mark when it does).
        Builtin::Filterstep => k == 1 && n >= 2,
        // `texture(name, s, t, ...)`: the footprint (numeric arguments only; the four-corner form
        // takes its footprint from the corners, so this over-marks it harmlessly).
        Builtin::Texture => k == 1 || k == 2,
        // `shadow(name, P, ...)`: the kernel covers P's pixel footprint (the four-point form takes
        // its region from the points, so this over-marks it harmlessly, as for `texture`).
        Builtin::Shadow => k == 1,
        // `environment(name, D, ...)`: the footprint of the direction (over-marking the
        // four-direction form likewise).
        Builtin::Environment => k == 1,
        _ => false,
    }
}

/// Whether a `texture` or `environment` call's parameter list sets its filter width to a literal 0 in both
/// directions (`"width", 0`, or `"swidth", 0` and `"twidth", 0`): its footprint is then zero
/// whatever the coordinates' derivatives, so they need not be computed.
fn zero_width(func: &Function, args: &[Arg]) -> bool {
    let literal = |k: usize, want: &str| matches!(args.get(k), Some(Arg::Value(x)) if matches!(&func.expr(*x).kind, ExprKind::Const(Constant::String(s)) if s == want));
    let zero_after = |name: &str| {
        (1..args.len()).any(|k| {
            literal(k, name)
                && matches!(args.get(k + 1), Some(Arg::Value(v)) if matches!(func.expr(*v).kind, ExprKind::Const(Constant::Float(x)) if x == 0.0))
        })
    };
    let named = |name: &str| (1..args.len()).any(|k| literal(k, name));
    (zero_after("width") && !named("swidth") && !named("twidth")) || (zero_after("swidth") && zero_after("twidth"))
}

/// Whether the back ends differentiate a built-in by a central difference: evaluated again with
/// every argument moved half its tangent forwards and half backwards, the result's tangent is the
/// difference of the two. For smooth built-ins without a closed-form rule and without side
/// effects, chiefly `noise` and the space transforms that bump mapping feeds to `calculatenormal`
/// (RenderMan's grids difference neighbouring points the same way). Piecewise-constant built-ins
/// (`floor`, `step`, `cellnoise`, ...) keep zero derivatives.
pub fn has_difference_rule(b: Builtin) -> bool {
    matches!(
        b,
        Builtin::Noise
            | Builtin::Pnoise
            | Builtin::Turb
            | Builtin::Transform
            | Builtin::Vtransform
            | Builtin::Ntransform
            | Builtin::Smoothstep
            | Builtin::Spline
            | Builtin::Distance
            | Builtin::Reflect
            | Builtin::Rotate
            | Builtin::Ptlined
            | Builtin::Radians
            | Builtin::Degrees
            | Builtin::Pow
            | Builtin::Log
            | Builtin::Tan
            | Builtin::Asin
            | Builtin::Acos
            | Builtin::Atan
            | Builtin::InverseSqrt
            // Linear between its wraps: `filterwidth(mod(x, p))` (rmannotes' `repeat`) is the
            // width of `x`, as on a RenderMan grid; a footprint across a wrap differences it.
            | Builtin::Mod
            // Bump and displacement maps (RISpec's `bumpy`): the height read at the moved
            // coordinates, each lookup filtered by the coordinates' own footprint.
            | Builtin::Texture
    )
}

/// Whether a built-in needs derivatives at all.
pub fn is_deriv_builtin(b: Builtin) -> bool {
    matches!(
        b,
        Builtin::Du | Builtin::Dv | Builtin::Deriv | Builtin::Area | Builtin::Calculatenormal | Builtin::Filterstep
    )
}

struct Pass<'m> {
    m: &'m Module,
    info: DerivInfo,
    changed: bool,
}

impl Pass<'_> {
    fn mark_expr(&mut self, f: usize, e: super::ExprId) {
        let slot = &mut self.info.exprs[f][e.0 as usize];
        if !*slot {
            *slot = true;
            self.changed = true;
        }
    }

    fn mark_place(&mut self, f: usize, base: PlaceBase) {
        let slot = match base {
            PlaceBase::Var(v) => &mut self.info.vars[f][v.0 as usize],
            PlaceBase::Global(g) => &mut self.info.globals[g.0 as usize],
        };
        if !*slot {
            *slot = true;
            self.changed = true;
        }
    }

    fn mark_ret(&mut self, f: FuncId) {
        let slot = &mut self.info.ret[f.0 as usize];
        if !*slot {
            *slot = true;
            self.changed = true;
        }
    }

    fn returns(&mut self, f: usize, blk: &Block) {
        for s in &blk.stmts {
            match &s.kind {
                StmtKind::Return(Some(e)) => self.mark_expr(f, *e),
                StmtKind::If { then, otherwise, .. } => {
                    self.returns(f, then);
                    self.returns(f, otherwise);
                }
                StmtKind::Loop { body, step, .. } => {
                    self.returns(f, body);
                    self.returns(f, step);
                }
                StmtKind::Illuminance { body, .. }
                | StmtKind::Illuminate { body, .. }
                | StmtKind::Solar { body, .. } => self.returns(f, body),
                StmtKind::Gather { body, otherwise, .. } => {
                    self.returns(f, body);
                    self.returns(f, otherwise);
                }
                _ => {}
            }
        }
    }

    /// One sweep over every function; sets `changed` when a fact was added.
    fn sweep(&mut self) {
        let m = self.m;
        for (fi, func) in m.functions.iter().enumerate() {
            for (ei, e) in func.exprs.iter().enumerate() {
                let marked = self.info.exprs[fi][ei];
                match &e.kind {
                    ExprKind::CallBuiltin { builtin, args, .. } => {
                        // `texture(name)`: the footprint is that of the globals s and t.
                        let coords = args.get(1).is_some_and(|a| match a {
                            Arg::Value(x) => func.expr(*x).ty.base.is_numeric(),
                            Arg::Ref(_) => false,
                        });
                        // A lookup whose filter width is a literal 0 needs no footprint.
                        let pointwise =
                            matches!(builtin, Builtin::Texture | Builtin::Environment) && zero_width(func, args);
                        if *builtin == Builtin::Texture && !coords && !pointwise {
                            for name in ["s", "t"] {
                                if let Some(g) = crate::globals::Global::lookup(name) {
                                    self.mark_place(fi, PlaceBase::Global(g));
                                }
                            }
                        }
                        for (k, a) in args.iter().enumerate() {
                            let Arg::Value(x) = a else { continue };
                            let numeric = func.expr(*x).ty.base.is_numeric();
                            if numeric
                                && ((is_root_arg(*builtin, k, args.len()) && !pointwise)
                                    || (marked && !is_deriv_builtin(*builtin)))
                            {
                                self.mark_expr(fi, *x);
                            }
                        }
                    }
                    ExprKind::Call { func: callee, args } => {
                        if marked {
                            self.mark_ret(*callee);
                        }
                        let cf = m.function(*callee);
                        let ci = callee.0 as usize;
                        for (k, a) in args.iter().enumerate() {
                            let Some(p) = cf.params.get(k) else { continue };
                            let pm = self.info.vars[ci][p.0 as usize];
                            match a {
                                Arg::Value(x) if pm => self.mark_expr(fi, *x),
                                Arg::Value(_) => {}
                                Arg::Ref(place) => {
                                    if pm {
                                        self.mark_place(fi, place.base);
                                    } else if self.info.place(fi, place.base) {
                                        let slot = &mut self.info.vars[ci][p.0 as usize];
                                        *slot = true;
                                        self.changed = true;
                                    }
                                }
                            }
                        }
                    }
                    ExprKind::Assign { place, value, .. } => {
                        if self.info.place(fi, place.base) {
                            self.mark_expr(fi, super::ExprId(ei as u32));
                        }
                        if self.info.exprs[fi][ei] {
                            self.mark_expr(fi, *value);
                            self.mark_place(fi, place.base);
                        }
                    }
                    _ if !marked => {}
                    ExprKind::Var(v) => self.mark_place(fi, PlaceBase::Var(*v)),
                    ExprKind::Global(g) => self.mark_place(fi, PlaceBase::Global(*g)),
                    ExprKind::Index { base, .. } => self.mark_expr(fi, *base),
                    ExprKind::Unary { op: super::UnaryOp::Neg, arg } | ExprKind::Convert { arg } => {
                        self.mark_expr(fi, *arg)
                    }
                    ExprKind::SpaceCast { arg, .. } => self.mark_expr(fi, *arg),
                    ExprKind::Binary { op, lhs, rhs } => {
                        use super::BinaryOp::*;
                        if matches!(op, Add | Sub | Mul | Div | Cross | Dot) {
                            self.mark_expr(fi, *lhs);
                            self.mark_expr(fi, *rhs);
                        }
                    }
                    ExprKind::Construct { args: xs } | ExprKind::ArrayLiteral { elements: xs } => {
                        for x in xs {
                            self.mark_expr(fi, *x);
                        }
                    }
                    ExprKind::Select { a, b, .. } => {
                        self.mark_expr(fi, *a);
                        self.mark_expr(fi, *b);
                    }
                    _ => {}
                }
            }
            if self.info.ret[fi] {
                self.returns(fi, &func.body);
            }
        }
        // Shader parameters: a marked parameter's default is a dual.
        if let Some(shader) = &m.shader {
            let fi = shader.body.0 as usize;
            for p in &shader.params {
                if self.info.vars[fi][p.var.0 as usize] {
                    self.mark_expr(fi, p.default);
                }
            }
        }
    }
}

/// Finds the values of `m` that need derivatives (see the module docs).
pub fn analyse(m: &Module) -> DerivInfo {
    let mut info = DerivInfo {
        exprs: m.functions.iter().map(|f| vec![false; f.exprs.len()]).collect(),
        vars: m.functions.iter().map(|f| vec![false; f.vars.len()]).collect(),
        ret: vec![false; m.functions.len()],
        globals: vec![false; GLOBALS.len()],
        any: false,
        normals: false,
        textures: false,
    };
    for f in &m.functions {
        for e in &f.exprs {
            if let ExprKind::CallBuiltin { builtin, .. } = &e.kind {
                info.any |= is_deriv_builtin(*builtin);
                info.normals |= *builtin == Builtin::Calculatenormal;
                info.textures |= matches!(builtin, Builtin::Texture | Builtin::Shadow | Builtin::Environment);
            }
        }
    }
    if !info.any && !info.textures {
        return info;
    }
    let mut pass = Pass { m, info, changed: true };
    while pass.changed {
        pass.changed = false;
        pass.sweep();
    }
    pass.info
}

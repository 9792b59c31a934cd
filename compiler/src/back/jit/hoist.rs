//! Uniform hoisting: the leading statements of a shader body that compute the same thing for
//! every chunk of a batch run once per batch, in a prologue before the chunk loop.
//!
//! A typical camera or light shader starts with uniform set-up (`option("FieldOfView", f)`,
//! `tan(radians(f) / 2)`, a space's matrix, a string); run per chunk of four lanes, it costs as
//! much as the per-lane work. [`uniform_prefix`] finds the longest run of leading statements that
//! is safe to hoist; `lower.rs` lowers them once, then starts each chunk with a fresh frame holding
//! copies of what they wrote, so each chunk sees exactly the state it would have computed itself.
//!
//! Safe means: every expression is uniform (in the IR and in the batch layout), control flow is
//! only a uniform `if`, writes go only to uniform local variables (or shader parameters), and calls
//! are only to built-ins that depend on nothing but their arguments and the batch's uniform
//! context (no varying state, derivatives, lights, rays, textures or side effects; of the queries
//! that answer through an output argument, `option` and `rendererinfo`, which answer the same for
//! every lane). User functions are not hoisted. Every uniform parameter's default must be safe too,
//! since the prologue evaluates them.

use super::layout::Layout;
use crate::builtins::{flags, Builtin};
use crate::ir::{self, Arg, ExprId, ExprKind, Function, Place, PlaceBase, Shader, StmtKind, VarId, VarKind};

/// What the prologue runs: the first `len` statements of the body, which write `writes`.
#[derive(Debug, Default)]
pub(super) struct Prefix {
    pub len: usize,
    /// Variables the prologue sets (hoisted writes and uniform parameters), each once.
    pub writes: Vec<VarId>,
}

/// The hoistable leading statements of `shader`'s body (none when nothing can be hoisted).
pub(super) fn uniform_prefix(m: &ir::Module, shader: &Shader, layout: &Layout) -> Prefix {
    let f = m.function(shader.body);
    let mut check = Check { f, layout, writes: Vec::new() };
    for (i, p) in shader.params.iter().enumerate() {
        let uniform = layout.params.get(i).is_some_and(|s| !s.varying) && !f.var(p.var).varying;
        if uniform && !check.expr(p.default) {
            return Prefix::default();
        }
    }
    let mut len = 0;
    for s in &f.body.stmts {
        let before = check.writes.len();
        if !check.stmt(s) {
            check.writes.truncate(before);
            break;
        }
        len += 1;
    }
    if len == 0 {
        return Prefix::default();
    }
    let mut writes = check.writes;
    for (i, p) in shader.params.iter().enumerate() {
        if layout.params.get(i).is_some_and(|s| !s.varying) && !f.var(p.var).varying {
            writes.push(p.var);
        }
    }
    writes.sort_by_key(|v| v.0);
    writes.dedup();
    Prefix { len, writes }
}

struct Check<'a> {
    f: &'a Function,
    layout: &'a Layout,
    writes: Vec<VarId>,
}

impl Check<'_> {
    fn stmt(&mut self, s: &ir::Stmt) -> bool {
        match &s.kind {
            StmtKind::Expr(e) => self.expr(*e),
            StmtKind::If { cond, then, otherwise } => {
                self.expr(*cond) && then.stmts.iter().chain(&otherwise.stmts).all(|s| self.stmt(s))
            }
            _ => false,
        }
    }

    fn exprs(&mut self, es: &[ExprId]) -> bool {
        es.iter().all(|e| self.expr(*e))
    }

    fn expr(&mut self, id: ExprId) -> bool {
        let e = self.f.expr(id);
        if e.varying {
            return false;
        }
        match &e.kind {
            ExprKind::Const(_) => true,
            ExprKind::Var(v) => self.uniform_var(*v),
            ExprKind::Global(g) => self.layout.globals.iter().any(|s| s.global == *g && !s.varying),
            ExprKind::Index { base, index } => self.expr(*base) && self.expr(*index),
            ExprKind::Unary { arg, .. } | ExprKind::Convert { arg } => self.expr(*arg),
            ExprKind::Binary { lhs, rhs, .. } => self.expr(*lhs) && self.expr(*rhs),
            ExprKind::Construct { args } => self.exprs(args),
            ExprKind::ArrayLiteral { elements } => self.exprs(elements),
            ExprKind::SpaceCast { space, arg } => self.expr(*space) && self.expr(*arg),
            ExprKind::Select { cond, a, b } => self.expr(*cond) && self.expr(*a) && self.expr(*b),
            ExprKind::CallBuiltin { builtin, args, .. } => {
                hoistable(*builtin)
                    && args.iter().all(|a| match a {
                        Arg::Value(v) => self.expr(*v),
                        Arg::Ref(p) => self.place(p),
                    })
            }
            ExprKind::Call { .. } => false,
            ExprKind::Assign { place, value, .. } => self.place(place) && self.expr(*value),
        }
    }

    /// A variable whose storage is uniform in the IR and, for a parameter, in the batch.
    fn uniform_var(&self, v: VarId) -> bool {
        let var = self.f.var(v);
        !var.varying
            && match var.kind {
                VarKind::Local => true,
                VarKind::ShaderParam { index, .. } => {
                    self.layout.params.get(index as usize).is_some_and(|s| !s.varying)
                }
                VarKind::Param { .. } | VarKind::Capture => false,
            }
    }

    fn place(&mut self, p: &Place) -> bool {
        let PlaceBase::Var(v) = p.base else { return false };
        if !self.uniform_var(v) {
            return false;
        }
        let indices_ok = p.index.is_none_or(|i| self.expr(i)) && p.component.is_none_or(|c| self.expr(c));
        if indices_ok {
            self.writes.push(v);
        }
        indices_ok
    }
}

/// Built-ins whose uniform calls give every chunk of a batch the same result and do nothing else.
fn hoistable(b: Builtin) -> bool {
    let f = b.flags();
    let per_lane = flags::VARYING | flags::DERIVS | flags::LIGHTS | flags::RAYS | flags::TEXTURE | flags::UNSUPPORTED;
    if f & per_lane != 0 {
        return false;
    }
    if f & flags::SIDE_EFFECTS != 0 {
        // Queries that write only their output argument, the same for every lane of a batch.
        return matches!(b, Builtin::Option | Builtin::Rendererinfo);
    }
    true
}

//! Uniform hoisting: the leading statements of a shader body that compute the same thing for
//! every chunk of a batch run once per batch, in a prologue before the chunk loop.
//!
//! A typical camera or light shader starts with uniform set-up (`option("FieldOfView", f)`,
//! `tan(radians(f) / 2)`, a space's matrix, a string); run per chunk of four lanes, it costs as
//! much as the per-lane work. [`uniform_prefix`] finds the longest run of leading statements that
//! is safe to hoist; `lower/mod.rs` lowers them once, then starts each chunk with a fresh frame
//! holding copies of what they wrote, so each chunk sees exactly the state it would have computed
//! itself.
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

/// What the prologue does: binds the uniform parameters, runs the first `len` statements of the
/// body, and evaluates the batch constants `consts`.
#[derive(Debug, Default)]
pub(super) struct Prefix {
    pub len: usize,
    /// Variables the prologue sets (uniform parameters and hoisted writes), each once: every chunk
    /// starts with copies of them.
    pub writes: Vec<VarId>,
    pub consts: Vec<ExprId>,
    /// Space names of the body's point, vector, normal and matrix casts that read nothing the body
    /// writes (`point "camera" (...)` with varying coordinates): the prologue looks up their
    /// matrices once.
    pub spaces: Vec<ExprId>,
}

impl Prefix {
    /// Whether there is anything to do once per batch.
    pub fn any(&self) -> bool {
        self.len > 0 || !self.consts.is_empty() || !self.spaces.is_empty()
    }
}

/// What of `shader`'s body can run once per batch (nothing when a uniform parameter's default is
/// not safe to evaluate there).
pub(super) fn uniform_prefix(m: &ir::Module, shader: &Shader, layout: &Layout) -> Prefix {
    let f = m.function(shader.body);
    let mut check = Check { f, layout, writes: Vec::new() };
    let uniform_params: Vec<VarId> = shader
        .params
        .iter()
        .enumerate()
        .filter(|(i, p)| layout.params.get(*i).is_some_and(|s| !s.varying) && !f.var(p.var).varying)
        .map(|(_, p)| p.var)
        .collect();
    for p in &shader.params {
        if uniform_params.contains(&p.var) && !check.expr(p.default) {
            return Prefix::default();
        }
    }
    check.writes.clear();
    let mut len = 0;
    for s in &f.body.stmts {
        let before = check.writes.len();
        if !check.stmt(s) {
            check.writes.truncate(before);
            break;
        }
        len += 1;
    }
    let (consts, spaces) = batch_constants(m, shader, layout, len, &check.writes);
    if len == 0 && consts.is_empty() && spaces.is_empty() {
        return Prefix::default();
    }
    let mut writes = check.writes;
    writes.extend(uniform_params);
    writes.sort_by_key(|v| v.0);
    writes.dedup();
    Prefix { len, writes, consts, spaces }
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

    fn expr(&mut self, id: ExprId) -> bool {
        let e = self.f.expr(id);
        if e.varying {
            return false;
        }
        match &e.kind {
            ExprKind::Const(_) => true,
            ExprKind::Var(v) => self.uniform_var(*v),
            ExprKind::Global(g) => self.layout.globals.iter().any(|s| s.global == *g && !s.varying),
            ExprKind::CallBuiltin { builtin, args, .. } => {
                hoistable(*builtin)
                    && args.iter().all(|a| match a {
                        Arg::Value(v) => self.expr(*v),
                        Arg::Ref(p) => self.place(p),
                    })
            }
            ExprKind::Call { .. } => false,
            ExprKind::Assign { place, value, .. } => self.place(place) && self.expr(*value),
            other => operands(other).into_iter().all(|c| self.expr(c)),
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

/// The value operands of an expression (the values of calls' arguments, not the places of their
/// output arguments), in evaluation order.
fn operands(kind: &ExprKind) -> Vec<ExprId> {
    match kind {
        ExprKind::Const(_) | ExprKind::Var(_) | ExprKind::Global(_) => Vec::new(),
        ExprKind::Index { base, index } => vec![*base, *index],
        ExprKind::Unary { arg, .. } | ExprKind::Convert { arg } => vec![*arg],
        ExprKind::Binary { lhs, rhs, .. } => vec![*lhs, *rhs],
        ExprKind::Construct { args } => args.clone(),
        ExprKind::ArrayLiteral { elements } => elements.clone(),
        ExprKind::SpaceCast { space, arg } => vec![*space, *arg],
        ExprKind::Select { cond, a, b } => vec![*cond, *a, *b],
        ExprKind::CallBuiltin { args, .. } | ExprKind::Call { args, .. } => args
            .iter()
            .filter_map(|a| match a {
                Arg::Value(v) => Some(*v),
                Arg::Ref(_) => None,
            })
            .collect(),
        ExprKind::Assign { value, .. } => vec![*value],
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

/// Uniform expressions anywhere in the body after the hoisted prefix (its first `prefix_len`
/// statements) that compute the same value for every chunk and involve a call (a helper, a space's
/// matrix): the prologue evaluates them once, after the prefix, and the chunks use that value
/// (`E = point "camera" (0, 0, 0)`, `radians(fov)`, a thin lens's `cos(phi)` of a uniform lens
/// sample). They may read only constants, shader parameters, uniform globals and the uniform
/// locals the prefix wrote (`prefix_writes`), none of which the rest of the body writes, and call
/// only built-ins without side effects (they are evaluated whether or not the chunk reaches them,
/// which is harmless for such pure computations). Maximal ones only: a listed expression's parts
/// are not.
fn batch_constants(
    m: &ir::Module,
    shader: &Shader,
    layout: &Layout,
    prefix_len: usize,
    prefix_writes: &[VarId],
) -> (Vec<ExprId>, Vec<ExprId>) {
    let f = m.function(shader.body);
    let (prefix, rest) = f.body.stmts.split_at(prefix_len.min(f.body.stmts.len()));
    // The prologue has run the prefix when the constants are evaluated: only writes after it count.
    let mut in_prefix = vec![false; f.exprs.len()];
    for s in prefix {
        mark_prefix_stmt(f, s, &mut in_prefix);
    }
    let mut written = Vec::new();
    for (i, e) in f.exprs.iter().enumerate() {
        if in_prefix[i] {
            continue;
        }
        match &e.kind {
            ExprKind::Assign { place, .. } => written.push(place.base),
            ExprKind::CallBuiltin { args, .. } | ExprKind::Call { args, .. } => {
                written.extend(args.iter().filter_map(|a| match a {
                    Arg::Ref(p) => Some(p.base),
                    Arg::Value(_) => None,
                }))
            }
            _ => {}
        }
    }
    gather_refs(&f.body, &mut written);
    let settled = prefix_writes.iter().copied().filter(|v| f.var(*v).kind == VarKind::Local).collect();
    let pure = Pure { f, layout, written, settled };
    let mut found = Vec::new();
    pure.stmts(rest, &mut found);
    let spaces = f
        .exprs
        .iter()
        .filter_map(|e| match e.kind {
            ExprKind::SpaceCast { space, .. } if e.ty.base != ir::BaseType::Color && pure.pure(space) => Some(space),
            _ => None,
        })
        .collect();
    (found, spaces)
}

fn gather_refs(b: &ir::Block, out: &mut Vec<PlaceBase>) {
    for s in &b.stmts {
        match &s.kind {
            StmtKind::If { then, otherwise, .. } => {
                gather_refs(then, out);
                gather_refs(otherwise, out);
            }
            StmtKind::Loop { body, step, .. } => {
                gather_refs(body, out);
                gather_refs(step, out);
            }
            StmtKind::Illuminance { body, .. } | StmtKind::Illuminate { body, .. } | StmtKind::Solar { body, .. } => {
                gather_refs(body, out)
            }
            StmtKind::Gather { params, body, otherwise, .. } => {
                out.extend(params.iter().filter_map(|(_, a)| match a {
                    Arg::Ref(p) => Some(p.base),
                    Arg::Value(_) => None,
                }));
                gather_refs(body, out);
                gather_refs(otherwise, out);
            }
            _ => {}
        }
    }
}

/// Marks the expressions of a hoisted statement (an expression or a uniform `if` of them), the
/// indices of the places it assigns included.
fn mark_prefix_stmt(f: &Function, s: &ir::Stmt, marks: &mut [bool]) {
    match &s.kind {
        StmtKind::Expr(e) => mark_expr(f, *e, marks),
        StmtKind::If { cond, then, otherwise } => {
            mark_expr(f, *cond, marks);
            for s in then.stmts.iter().chain(&otherwise.stmts) {
                mark_prefix_stmt(f, s, marks);
            }
        }
        _ => {}
    }
}

fn mark_expr(f: &Function, id: ExprId, marks: &mut [bool]) {
    if let Some(m) = marks.get_mut(id.0 as usize) {
        *m = true;
    }
    let kind = &f.expr(id).kind;
    let places: Vec<&Place> = match kind {
        ExprKind::Assign { place, .. } => vec![place],
        ExprKind::CallBuiltin { args, .. } | ExprKind::Call { args, .. } => args
            .iter()
            .filter_map(|a| match a {
                Arg::Ref(p) => Some(p),
                Arg::Value(_) => None,
            })
            .collect(),
        _ => Vec::new(),
    };
    let indices = places.into_iter().flat_map(|p| p.index.into_iter().chain(p.component));
    for c in operands(kind).into_iter().chain(indices) {
        mark_expr(f, c, marks);
    }
}

struct Pure<'a> {
    f: &'a Function,
    layout: &'a Layout,
    /// What the body writes after the hoisted prefix.
    written: Vec<PlaceBase>,
    /// Uniform locals the hoisted prefix writes: the prologue has their values.
    settled: Vec<VarId>,
}

impl Pure<'_> {
    fn block(&self, b: &ir::Block, found: &mut Vec<ExprId>) {
        self.stmts(&b.stmts, found);
    }

    fn stmts(&self, stmts: &[ir::Stmt], found: &mut Vec<ExprId>) {
        for s in stmts {
            match &s.kind {
                StmtKind::Expr(e) => self.visit(*e, found),
                StmtKind::If { cond, then, otherwise } => {
                    self.visit(*cond, found);
                    self.block(then, found);
                    self.block(otherwise, found);
                }
                StmtKind::Loop { cond, body, step } => {
                    if let Some(c) = cond {
                        self.visit(*c, found);
                    }
                    self.block(body, found);
                    self.block(step, found);
                }
                StmtKind::Return(Some(e)) => self.visit(*e, found),
                StmtKind::Illuminance { body, .. }
                | StmtKind::Illuminate { body, .. }
                | StmtKind::Solar { body, .. } => self.block(body, found),
                StmtKind::Gather { body, otherwise, .. } => {
                    self.block(body, found);
                    self.block(otherwise, found);
                }
                _ => {}
            }
        }
    }

    /// Lists `id` if it qualifies, else looks inside it.
    fn visit(&self, id: ExprId, found: &mut Vec<ExprId>) {
        if self.pure(id) && self.calls(id) {
            if !found.contains(&id) {
                found.push(id);
            }
            return;
        }
        for c in operands(&self.f.expr(id).kind) {
            self.visit(c, found);
        }
    }

    /// Uniform, free of effects, and reading only what no statement of the body writes.
    fn pure(&self, id: ExprId) -> bool {
        let e = self.f.expr(id);
        if e.varying {
            return false;
        }
        match &e.kind {
            ExprKind::Const(_) => true,
            ExprKind::Var(v) => {
                let var = self.f.var(*v);
                let storage = match var.kind {
                    VarKind::ShaderParam { index, .. } => {
                        self.layout.params.get(index as usize).is_some_and(|s| !s.varying)
                    }
                    VarKind::Local => self.settled.contains(v),
                    VarKind::Param { .. } | VarKind::Capture => false,
                };
                !var.varying && storage && !self.written.contains(&PlaceBase::Var(*v))
            }
            ExprKind::Global(g) => {
                self.layout.globals.iter().any(|s| s.global == *g && !s.varying && !s.written)
                    && !self.written.contains(&PlaceBase::Global(*g))
            }
            ExprKind::CallBuiltin { builtin, args, .. } => {
                hoistable(*builtin)
                    && builtin.flags() & flags::SIDE_EFFECTS == 0
                    && args.iter().all(|a| matches!(a, Arg::Value(v) if self.pure(*v)))
            }
            ExprKind::Call { .. } | ExprKind::Assign { .. } => false,
            other => operands(other).into_iter().all(|c| self.pure(c)),
        }
    }

    /// Whether evaluating `id` calls out (worth doing once): a built-in or a space cast.
    fn calls(&self, id: ExprId) -> bool {
        match &self.f.expr(id).kind {
            ExprKind::CallBuiltin { .. } | ExprKind::SpaceCast { .. } => true,
            ExprKind::Call { .. } | ExprKind::Assign { .. } => false,
            other => operands(other).into_iter().any(|c| self.calls(c)),
        }
    }
}

//! Uniform/varying inference over the IR.
//!
//! A value is varying if it depends on varying data: varying globals, varying built-ins (`random`,
//! lighting, texture lookups), varying variables, or an assignment made under varying control flow
//! (a branch or loop whose condition is varying, code after a divergent `break`/`return`, the body
//! of a light loop). Variables without a declared storage class become varying when any varying
//! value reaches them; the analysis iterates to a fixed point.
//!
//! A variable declared `uniform` that is assigned under varying control flow is kept per lane
//! ([`Level::PerLane`]): its storage is varying, but its values are still uniform ones in the
//! language's terms, so they may flow on into other `uniform` variables (which are then kept per
//! lane too). Only varying data ([`Level::Varying`]) reaching a `uniform` variable is an error.
//!
//! Functions are analysed twice. First with their (undeclared) parameters uniform, which tells
//! whether the function reads varying state by itself ([`ir::Function::reads_varying`]) and is where
//! errors are reported; then with those parameters varying, which gives the annotations back ends use
//! (a function is compiled once, for varying arguments).

use crate::builtins::{flags, Builtin};
use crate::diagnostic::{Code, Diagnostic, Diagnostics};
use crate::front::parse::ast::ShaderKind;
use crate::ir::{self, Arg, ExprId, ExprKind, FuncId, Function, PlaceBase, Shader, StmtKind, VarId, VarKind};
use crate::source::Span;

/// Infers storage for every function and the shader, reporting varying values that reach uniform
/// variables.
/// `needed[i]` says whether function `i` is kept in the module (reachable from the shader): only
/// those get pass B's annotations; every function gets pass A and its errors.
pub fn infer(functions: &mut [Function], shader: Option<&Shader>, needed: &[bool], diags: &mut Diagnostics) {
    let body = shader.map(|s| s.body);
    let kind = shader.map(|s| s.kind);
    let writes = written_params(functions);
    // Pass A, callees before callers (there is no recursion), so each function is analysed once with
    // the final `reads_varying` of everything it calls.
    let mut reads: Vec<Level> = vec![Level::Uniform; functions.len()];
    let mut violations: Vec<Vec<Violation>> = vec![Vec::new(); functions.len()];
    for i in callees_first(functions) {
        if Some(FuncId(i as u32)) == body {
            continue;
        }
        let mut a = Analysis::new(&functions[i], &reads, &writes, kind, false, true);
        a.run(&functions[i]);
        let r = a.reads_varying(&functions[i]);
        violations[i] = a.violations;
        reads[i] = r;
    }
    for (i, f) in functions.iter_mut().enumerate() {
        f.reads_varying = reads[i] != Level::Uniform;
    }
    // The shader body: one pass, with errors.
    if let (Some(shader), Some(body)) = (shader, body) {
        let f = &functions[body.0 as usize];
        let mut a = Analysis::new(f, &reads, &writes, kind, false, true);
        a.defaults = shader.params.iter().map(|p| (p.var, p.default, p.varying)).collect();
        a.run(f);
        violations[body.0 as usize] = a.violations;
        let (exprs, vars) = (a.expr_varying, a.var_varying);
        let f = &mut functions[body.0 as usize];
        apply(f, &exprs, &vars);
    }
    for (i, list) in violations.iter().enumerate() {
        report(&functions[i], list, diags);
    }
    // Pass B: annotations for user functions, parameters varying.
    for (i, f) in functions.iter_mut().enumerate() {
        if Some(FuncId(i as u32)) == body || !needed.get(i).copied().unwrap_or(true) {
            continue;
        }
        let mut a = Analysis::new(f, &reads, &writes, kind, true, false);
        a.run(f);
        let (exprs, vars) = (a.expr_varying, a.var_varying);
        apply(f, &exprs, &vars);
    }
}

fn apply(f: &mut Function, exprs: &[Level], vars: &[bool]) {
    for (e, v) in f.exprs.iter_mut().zip(exprs) {
        e.varying = *v != Level::Uniform;
    }
    for (var, v) in f.vars.iter_mut().zip(vars) {
        var.varying = *v;
    }
}

#[derive(Clone, Debug)]
struct Violation {
    var: VarId,
    span: Span,
    /// A shader parameter's default value (E0136) rather than an assignment (E0110).
    default: bool,
}

fn report(f: &Function, list: &[Violation], diags: &mut Diagnostics) {
    let mut seen: Vec<VarId> = Vec::new();
    for v in list {
        if seen.contains(&v.var) {
            continue;
        }
        seen.push(v.var);
        let var = f.var(v.var);
        let d = if v.default {
            Diagnostic::new(
                Code::DefaultNotUniform,
                v.span,
                format!("the default of uniform parameter `{}` depends on varying data", var.name),
            )
            .with_label("varying value")
            .with_secondary(var.span, "parameter declared here")
            .with_note("declare the parameter `varying`, or use a constant default")
        } else {
            let what = match var.kind {
                VarKind::ShaderParam { .. } => "shader parameter",
                VarKind::Param { .. } => "parameter",
                _ => "variable",
            };
            let note = match var.kind {
                VarKind::ShaderParam { .. } => format!(
                    "shader parameters are uniform unless declared `varying`: `varying {} {}`",
                    var.ty, var.name
                ),
                _ => format!(
                    "declare it `varying`, or leave out `uniform` to let the compiler decide: `varying {} {}`",
                    var.ty, var.name
                ),
            };
            Diagnostic::new(
                Code::VaryingToUniform,
                v.span,
                format!("a varying value is assigned to the uniform {what} `{}`", var.name),
            )
            .with_label("varying value assigned here")
            .with_secondary(var.span, "declared uniform here")
            .with_note(note)
        };
        diags.push(d);
    }
}

/// How much a value may differ from lane to lane, in increasing order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
enum Level {
    /// One value for the whole batch.
    #[default]
    Uniform,
    /// Uniform in the language's terms but kept per lane: read from a variable declared `uniform`
    /// that was assigned under varying control flow, so lanes that did not run the assignment
    /// still hold the old value.
    PerLane,
    /// Depends on varying data.
    Varying,
}

struct Analysis<'a> {
    reads: &'a [Level],
    /// For each function, which of its parameters (by position) it may write.
    writes: &'a [Vec<bool>],
    expr_varying: Vec<Level>,
    /// Variables kept per lane (their storage).
    var_varying: Vec<bool>,
    /// Variables that hold varying data (never one declared `uniform`: that is an error instead).
    var_data: Vec<bool>,
    /// Variables whose storage is fixed: declared `uniform` (violations are errors) or `varying`.
    fixed: Vec<bool>,
    violations: Vec<Violation>,
    /// Variables read during the current pass. A variable that turns varying after it was read
    /// makes the pass stale (the read saw the old value), and only then is another pass needed: a
    /// pass in which every variable turned varying before its first read is already the fixpoint.
    read: Vec<bool>,
    changed: bool,
    /// The level of the values `return` gives (returning under varying control counts).
    ret_varying: Level,
    /// Shader parameters: variable, default value, declared varying.
    defaults: Vec<(VarId, ExprId, bool)>,
    /// The module's shader type, which decides whether some globals are varying.
    kind: Option<ShaderKind>,
    /// Walking the value assigned to a uniform variable, where `random()` is uniform.
    random_uniform: bool,
}

/// How a statement left control flow: some lanes may have left the loop, or the function.
#[derive(Clone, Copy, Default)]
struct Exits {
    /// How many enclosing loops a divergent `break n`/`continue n` reaches (0: none).
    loop_exit: u32,
    func_exit: bool,
}

impl<'a> Analysis<'a> {
    /// `params_varying`: undeclared parameters start varying. `strict`: declared-uniform locals and
    /// parameters stay uniform and record violations (otherwise they are promoted silently).
    fn new(
        f: &Function,
        reads: &'a [Level],
        writes: &'a [Vec<bool>],
        kind: Option<ShaderKind>,
        params_varying: bool,
        strict: bool,
    ) -> Analysis<'a> {
        let mut var_varying = Vec::with_capacity(f.vars.len());
        let mut fixed = Vec::with_capacity(f.vars.len());
        for v in &f.vars {
            let (vary, fix) = match (v.kind, v.declared) {
                (_, Some(true)) => (true, true),
                (VarKind::ShaderParam { .. }, _) => (false, true),
                (_, Some(false)) => (false, strict),
                (VarKind::Param { .. }, None) => (params_varying, false),
                (VarKind::Capture, None) => (true, false),
                (VarKind::Local, None) => (false, false),
            };
            var_varying.push(vary);
            fixed.push(fix);
        }
        Analysis {
            reads,
            writes,
            expr_varying: vec![Level::Uniform; f.exprs.len()],
            var_data: var_varying.clone(),
            var_varying,
            fixed,
            violations: Vec::new(),
            read: vec![false; f.vars.len()],
            changed: false,
            ret_varying: Level::Uniform,
            defaults: Vec::new(),
            kind,
            random_uniform: false,
        }
    }

    fn run(&mut self, f: &Function) {
        loop {
            self.changed = false;
            self.read.fill(false);
            self.violations.clear();
            self.ret_varying = Level::Uniform;
            for (var, default, varying) in self.defaults.clone() {
                if self.expr(f, default) != Level::Uniform && !varying {
                    self.violations.push(Violation { var, span: f.expr(default).span, default: true });
                }
            }
            self.block(f, &f.body, Level::Uniform);
            if !self.changed {
                break;
            }
        }
    }

    /// Whether the function's results depend on varying state (with uniform parameters), and how.
    fn reads_varying(&self, f: &Function) -> Level {
        let outputs = f.vars.iter().enumerate().filter(|(_, v)| {
            matches!(v.kind, VarKind::Param { output: true } | VarKind::Capture) && v.declared != Some(true)
        });
        outputs.fold(self.ret_varying, |level, (i, _)| level.max(self.var_level(i)))
    }

    /// Whether a variable is declared `uniform` (in the strict pass; kept per lane or not).
    fn declared_uniform(&self, var: VarId) -> bool {
        let i = var.0 as usize;
        self.fixed[i] && !self.var_data[i]
    }

    fn var_level(&self, i: usize) -> Level {
        if self.var_data[i] {
            Level::Varying
        } else if self.var_varying[i] {
            Level::PerLane
        } else {
            Level::Uniform
        }
    }

    /// Records that a variable receives a value of level `value` under control flow of level `ctl`.
    /// A variable declared `uniform` may not receive varying data (E0110), but a uniform value
    /// assigned under varying control is accepted: the variable is then kept per lane, as RenderMan
    /// shaders with `uniform` loop counters and divergent `break`s (filtered fBm) expect, and so is
    /// a value read from such a variable. Any other variable takes the higher of the two levels.
    fn mark(&mut self, var: VarId, value: Level, ctl: Level, span: Span) {
        let i = var.0 as usize;
        let declared_uniform = self.declared_uniform(var);
        if declared_uniform && value == Level::Varying {
            self.violations.push(Violation { var, span, default: false });
            return;
        }
        let level = value.max(ctl);
        if level == Level::Uniform {
            return;
        }
        let data = level == Level::Varying && !declared_uniform;
        if self.var_varying[i] && (self.var_data[i] || !data) {
            return;
        }
        self.var_varying[i] = true;
        self.var_data[i] |= data;
        self.changed |= self.read[i];
    }

    fn block(&mut self, f: &Function, block: &ir::Block, ctl: Level) -> Exits {
        let mut ctl = ctl;
        let mut exits = Exits::default();
        for s in &block.stmts {
            let e = self.stmt(f, s, ctl);
            if e.loop_exit > 0 || e.func_exit {
                // Later statements run only in lanes that did not leave: divergent from here on if
                // the exit was taken under varying control (`stmt` reports only divergent exits).
                ctl = Level::Varying;
            }
            exits.loop_exit = exits.loop_exit.max(e.loop_exit);
            exits.func_exit |= e.func_exit;
        }
        exits
    }

    /// Returns the divergent exits the statement may take.
    fn stmt(&mut self, f: &Function, s: &ir::Stmt, ctl: Level) -> Exits {
        match &s.kind {
            StmtKind::Expr(e) => {
                self.expr_ctl(f, *e, ctl);
                Exits::default()
            }
            StmtKind::If { cond, then, otherwise } => {
                let c = self.expr_ctl(f, *cond, ctl);
                let a = self.block(f, then, ctl.max(c));
                let b = self.block(f, otherwise, ctl.max(c));
                Exits { loop_exit: a.loop_exit.max(b.loop_exit), func_exit: a.func_exit || b.func_exit }
            }
            StmtKind::Loop { cond, body, step } => {
                let c = cond.map_or(Level::Uniform, |c| self.expr_ctl(f, c, ctl));
                let inner = ctl.max(c);
                let e = self.block(f, body, inner);
                // Values of one iteration reach the next through variables read before they turn
                // varying, which the fixpoint catches (`read`). Lanes that left in one iteration
                // make the whole next iteration divergent: only that needs a second walk here.
                let diverged = inner == Level::Uniform && (e.loop_exit > 0 || e.func_exit);
                let inner = if diverged { Level::Varying } else { inner };
                let e2 = if diverged { self.block(f, body, inner) } else { Exits::default() };
                self.block(f, step, inner);
                if let Some(c) = cond {
                    self.expr_ctl(f, *c, inner);
                }
                // A `break 2` inside leaves this loop and the next one out: the rest of the outer
                // loop's body, and its next iteration, are divergent too.
                let outer = e.loop_exit.max(e2.loop_exit).saturating_sub(1);
                Exits { loop_exit: outer, func_exit: e.func_exit || e2.func_exit }
            }
            StmtKind::Break(n) | StmtKind::Continue(n) => {
                let divergent = ctl != Level::Uniform;
                Exits { loop_exit: if divergent { (*n).max(1) } else { 0 }, func_exit: false }
            }
            StmtKind::Return(value) => {
                let v = value.map_or(Level::Uniform, |v| self.expr_ctl(f, v, ctl));
                self.ret_varying = self.ret_varying.max(v).max(ctl);
                Exits { loop_exit: 0, func_exit: ctl != Level::Uniform }
            }
            StmtKind::Illuminance { category, position, cone, body } => {
                if let Some(c) = category {
                    self.expr_ctl(f, *c, ctl);
                }
                self.expr_ctl(f, *position, ctl);
                if let Some((a, b)) = cone {
                    self.expr_ctl(f, *a, ctl);
                    self.expr_ctl(f, *b, ctl);
                }
                let e = self.block(f, body, Level::Varying);
                Exits { loop_exit: e.loop_exit.saturating_sub(1), func_exit: e.func_exit }
            }
            StmtKind::Illuminate { position, cone, body } => {
                self.expr_ctl(f, *position, ctl);
                if let Some((a, b)) = cone {
                    self.expr_ctl(f, *a, ctl);
                    self.expr_ctl(f, *b, ctl);
                }
                self.block(f, body, Level::Varying)
            }
            StmtKind::Solar { cone, body } => {
                if let Some((a, b)) = cone {
                    self.expr_ctl(f, *a, ctl);
                    self.expr_ctl(f, *b, ctl);
                }
                self.block(f, body, Level::Varying)
            }
            StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                for e in [category, position, direction, angle, samples] {
                    self.expr_ctl(f, *e, ctl);
                }
                for (name, arg) in params {
                    self.expr_ctl(f, *name, ctl);
                    match arg {
                        Arg::Value(v) => {
                            self.expr_ctl(f, *v, ctl);
                        }
                        Arg::Ref(p) => {
                            if let PlaceBase::Var(v) = p.base {
                                self.mark(v, Level::Varying, Level::Uniform, s.span);
                            }
                        }
                    }
                }
                let a = self.block(f, body, Level::Varying);
                let b = self.block(f, otherwise, Level::Varying);
                Exits {
                    loop_exit: a.loop_exit.max(b.loop_exit).saturating_sub(1),
                    func_exit: a.func_exit || b.func_exit,
                }
            }
        }
    }

    /// Evaluates an expression under the given control flow and returns whether it is varying.
    fn expr_ctl(&mut self, f: &Function, id: ExprId, ctl: Level) -> Level {
        self.walk(f, id, ctl)
    }

    fn expr(&mut self, f: &Function, id: ExprId) -> Level {
        self.walk(f, id, Level::Uniform)
    }

    fn place_written(&mut self, f: &Function, place: &ir::Place, value: Level, ctl: Level, span: Span) {
        let mut index = Level::Uniform;
        for i in [place.index, place.component].into_iter().flatten() {
            index = index.max(self.walk(f, i, ctl));
        }
        if let PlaceBase::Var(v) = place.base {
            self.mark(v, value.max(index), ctl, span);
        }
    }

    fn read_var(&mut self, var: VarId) -> Level {
        let i = var.0 as usize;
        self.read[i] = true;
        self.var_level(i)
    }

    fn walk(&mut self, f: &Function, id: ExprId, ctl: Level) -> Level {
        let e = f.expr(id);
        let level = match &e.kind {
            ExprKind::Const(_) => Level::Uniform,
            ExprKind::Var(v) => self.read_var(*v),
            ExprKind::Global(g) => varying_if(g.def().varying_in(self.kind)),
            ExprKind::Index { base, index } => {
                let a = self.walk(f, *base, ctl);
                a.max(self.walk(f, *index, ctl))
            }
            ExprKind::Unary { arg, .. } | ExprKind::Convert { arg } => self.walk(f, *arg, ctl),
            ExprKind::Binary { lhs, rhs, .. } => {
                let a = self.walk(f, *lhs, ctl);
                a.max(self.walk(f, *rhs, ctl))
            }
            ExprKind::Construct { args } | ExprKind::ArrayLiteral { elements: args } => {
                args.iter().fold(Level::Uniform, |v, a| v.max(self.walk(f, *a, ctl)))
            }
            ExprKind::SpaceCast { space, arg } => {
                let a = self.walk(f, *space, ctl);
                a.max(self.walk(f, *arg, ctl))
            }
            ExprKind::Select { cond, a, b } => {
                let c = self.walk(f, *cond, ctl);
                let x = self.walk(f, *a, ctl.max(c));
                let y = self.walk(f, *b, ctl.max(c));
                c.max(x).max(y)
            }
            ExprKind::CallBuiltin { builtin, args, .. } => {
                let fl = builtin.flags();
                // `incident()`/`opposite()` answer from the volume on each lane's side of its
                // surface, so even whether they find the name varies.
                let mut v = varying_if(
                    (fl & flags::VARYING != 0 && !(*builtin == Builtin::Random && self.random_uniform))
                        || matches!(builtin, Builtin::Incident | Builtin::Opposite),
                );
                // `rayinfo()` answers from each lane's ray (the ray parameters of its pixel and of
                // the objects on its path), unless its destination is declared uniform: that takes
                // one lane's answer, as a uniform `random()` does.
                if *builtin == Builtin::Rayinfo {
                    let per_lane = args.iter().any(|a| match a {
                        Arg::Ref(p) => !matches!(p.base, PlaceBase::Var(var) if self.declared_uniform(var)),
                        Arg::Value(_) => false,
                    });
                    v = v.max(varying_if(per_lane));
                }
                for a in args {
                    if let Arg::Value(x) = a {
                        v = v.max(self.walk(f, *x, ctl));
                    }
                }
                // Parameters of other shaders may vary; options, attributes and renderer facts do
                // not. A destination declared uniform takes one lane's answer, as for `rayinfo()`.
                let to_uniform = args
                    .iter()
                    .any(|a| matches!(a, Arg::Ref(p) if matches!(p.base, PlaceBase::Var(var) if self.declared_uniform(var))));
                let from_shader = !to_uniform
                    && matches!(
                    builtin,
                    Builtin::Surface
                        | Builtin::Displacement
                        | Builtin::Lightsource
                        | Builtin::Atmosphere
                        | Builtin::Incident
                        | Builtin::Opposite
                );
                let out = v.max(varying_if(fl & flags::MESSAGE != 0 && from_shader));
                for a in args {
                    if let Arg::Ref(p) = a {
                        self.place_written(f, p, out, ctl, e.span);
                    }
                }
                v
            }
            ExprKind::Call { func, args } => {
                let mut v = self.reads.get(func.0 as usize).copied().unwrap_or(Level::Varying);
                for a in args {
                    match a {
                        Arg::Value(x) => v = v.max(self.walk(f, *x, ctl)),
                        Arg::Ref(p) => {
                            if let PlaceBase::Var(var) = p.base {
                                // Captured variables and in-out arguments carry values in.
                                v = v.max(self.read_var(var));
                            }
                        }
                    }
                }
                let written = self.writes.get(func.0 as usize);
                for (i, a) in args.iter().enumerate() {
                    if let Arg::Ref(p) = a {
                        if written.is_none_or(|w| w.get(i).copied().unwrap_or(true)) {
                            self.place_written(f, p, v, ctl, e.span);
                        }
                    }
                }
                v
            }
            ExprKind::Assign { place, op, value } => {
                // `random()` assigned to a variable declared uniform is one number for the batch,
                // as in RenderMan (a uniform `random()`), not a varying value.
                let to_uniform = matches!(place.base, PlaceBase::Var(var) if self.declared_uniform(var));
                let outer = std::mem::replace(&mut self.random_uniform, to_uniform);
                let mut v = self.walk(f, *value, ctl);
                self.random_uniform = outer;
                if op.is_some() {
                    if let PlaceBase::Var(var) = place.base {
                        v = v.max(self.read_var(var));
                    } else {
                        v = Level::Varying;
                    }
                }
                self.place_written(f, place, v, ctl, e.span);
                v.max(ctl)
            }
        };
        self.expr_varying[id.0 as usize] = level;
        level
    }
}

fn varying_if(varying: bool) -> Level {
    if varying {
        Level::Varying
    } else {
        Level::Uniform
    }
}

/// For each function, which parameters (by position) it may write: directly, or by passing them on
/// to a built-in's output or to a function that writes that parameter.
fn written_params(functions: &[Function]) -> Vec<Vec<bool>> {
    let mut writes: Vec<Vec<bool>> = functions.iter().map(|f| vec![false; f.params.len()]).collect();
    loop {
        let mut changed = false;
        for (i, f) in functions.iter().enumerate() {
            let mut vars = vec![false; f.vars.len()];
            for e in &f.exprs {
                match &e.kind {
                    ExprKind::Assign { place, .. } => {
                        if let PlaceBase::Var(v) = place.base {
                            vars[v.0 as usize] = true;
                        }
                    }
                    ExprKind::CallBuiltin { args, .. } => {
                        for a in args {
                            if let Arg::Ref(ir::Place { base: PlaceBase::Var(v), .. }) = a {
                                vars[v.0 as usize] = true;
                            }
                        }
                    }
                    ExprKind::Call { func, args } => {
                        for (k, a) in args.iter().enumerate() {
                            if let Arg::Ref(ir::Place { base: PlaceBase::Var(v), .. }) = a {
                                if writes.get(func.0 as usize).is_none_or(|w| w.get(k).copied().unwrap_or(true)) {
                                    vars[v.0 as usize] = true;
                                }
                            }
                        }
                    }
                    _ => {}
                }
            }
            for s in all_gather_outputs(&f.body) {
                vars[s.0 as usize] = true;
            }
            for (k, p) in f.params.iter().enumerate() {
                if vars[p.0 as usize] && !writes[i][k] {
                    writes[i][k] = true;
                    changed = true;
                }
            }
        }
        if !changed {
            return writes;
        }
    }
}

fn all_gather_outputs(block: &ir::Block) -> Vec<VarId> {
    let mut out = Vec::new();
    for s in &block.stmts {
        match &s.kind {
            StmtKind::Gather { params, body, otherwise, .. } => {
                for (_, a) in params {
                    if let Arg::Ref(ir::Place { base: PlaceBase::Var(v), .. }) = a {
                        out.push(*v);
                    }
                }
                out.extend(all_gather_outputs(body));
                out.extend(all_gather_outputs(otherwise));
            }
            StmtKind::If { then, otherwise, .. } => {
                out.extend(all_gather_outputs(then));
                out.extend(all_gather_outputs(otherwise));
            }
            StmtKind::Loop { body, step, .. } => {
                out.extend(all_gather_outputs(body));
                out.extend(all_gather_outputs(step));
            }
            StmtKind::Illuminance { body, .. } | StmtKind::Illuminate { body, .. } | StmtKind::Solar { body, .. } => {
                out.extend(all_gather_outputs(body));
            }
            _ => {}
        }
    }
    out
}

/// Function indices ordered so that every function comes after the functions it calls.
fn callees_first(functions: &[Function]) -> Vec<usize> {
    let n = functions.len();
    let callees: Vec<Vec<usize>> = functions
        .iter()
        .map(|f| {
            f.exprs
                .iter()
                .filter_map(|e| match e.kind {
                    ExprKind::Call { func, .. } if (func.0 as usize) < n => Some(func.0 as usize),
                    _ => None,
                })
                .collect()
        })
        .collect();
    let mut order = Vec::with_capacity(n);
    let mut state = vec![0u8; n]; // 0 new, 1 in progress, 2 done
    for start in 0..n {
        if state[start] != 0 {
            continue;
        }
        let mut stack = vec![(start, 0usize)];
        state[start] = 1;
        while let Some((node, next)) = stack.pop() {
            if let Some(&c) = callees[node].get(next) {
                stack.push((node, next + 1));
                if state[c] == 0 {
                    state[c] = 1;
                    stack.push((c, 0));
                }
            } else {
                state[node] = 2;
                order.push(node);
            }
        }
    }
    order
}

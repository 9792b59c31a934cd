//! The IR validator: checks the invariants `ir` documents, so back ends can rely on them.
//!
//! What it checks, in order:
//! 1. handles: every `ExprId`, `VarId` and `FuncId` is in range, the shader's body and its
//!    parameters' variables and defaults included; a shader parameter's variable says which
//!    parameter it is (`VarKind::ShaderParam`), and only those do; function parameters are
//!    parameters (`VarKind::Param` or `Capture`);
//! 2. sizes: array lengths are between 1 and [`ir::MAX_ARRAY_LEN`], unsized only for function
//!    parameters; the shader's size once calls are inlined is within [`ir::INLINE_BUDGET`] (also
//!    with its arrays counted by their floats) and its variables within [`ir::STORAGE_BUDGET`];
//! 3. trees: every expression is used exactly once (by an expression, a statement, or a shader
//!    parameter's default), so back ends may evaluate each where it appears;
//! 4. types: operands of every operator, conversion, constructor, select, assignment, call and
//!    statement have the types the IR's documentation promises; an index applies to an array or a
//!    triple, a component to an element of an array of triples;
//! 5. calls: overload indices exist; arguments match the signature's arity, and exactly the output
//!    (and captured) parameters receive places; there is no recursion;
//! 6. control flow: `break n`/`continue n` stay within their loops; `return` values match the
//!    function's type;
//! 7. storage: a uniform variable is never assigned a varying value.
//!
//! What it does not check yet: that assignments to uniform variables happen under uniform control
//! flow (the checker's inference guarantees it, and a later pass will verify it).
//!
//! A failure is a compiler bug, never a user error: valid source always lowers to valid IR. The
//! validator itself indexes nothing it has not checked, so any decoded IR gets an answer.

use crate::builtins::{self, Builtin};
use crate::ir::{
    self, Arg, ArrayLen, BaseType, BinaryOp, Block, ExprId, ExprKind, FuncId, Function, Module, Place, PlaceBase,
    StmtKind, Type, UnaryOp, VarKind,
};

/// Checks a module; returns every violation found.
pub fn validate(m: &Module) -> Result<(), Vec<String>> {
    let mut v = Validator { m, errors: Vec::new() };
    v.shader();
    for (i, f) in m.functions.iter().enumerate() {
        v.function(i, f);
    }
    v.recursion();
    if v.errors.is_empty() {
        // Sizes are computed over an acyclic call graph with every handle in range.
        v.budgets();
    }
    if v.errors.is_empty() {
        Ok(())
    } else {
        Err(v.errors)
    }
}

struct Validator<'a> {
    m: &'a Module,
    errors: Vec<String>,
}

struct FnState<'a> {
    index: usize,
    f: &'a Function,
    uses: Vec<u32>,
}

impl<'a> Validator<'a> {
    fn err(&mut self, st: &FnState<'_>, msg: String) {
        self.errors.push(format!("fn{} {}: {msg}", st.index, st.f.name));
    }

    /// The shader's body and parameters refer to real storage, consistently.
    fn shader(&mut self) {
        let Some(s) = &self.m.shader else { return };
        let Some(body) = self.m.functions.get(s.body.0 as usize) else {
            self.errors.push(format!("the shader's body fn{} out of range", s.body.0));
            return;
        };
        for (i, p) in s.params.iter().enumerate() {
            match body.vars.get(p.var.0 as usize) {
                None => self.errors.push(format!("shader parameter {}: variable {} out of range", p.name, p.var.0)),
                Some(var) => {
                    if var.ty != p.ty {
                        self.errors
                            .push(format!("shader parameter {} is {} but its variable is {}", p.name, p.ty, var.ty));
                    }
                    if var.kind != (VarKind::ShaderParam { index: i as u32, output: p.output }) {
                        self.errors.push(format!("shader parameter {}: its variable is {:?}", p.name, var.kind));
                    }
                }
            }
            if p.default.0 as usize >= body.exprs.len() {
                self.errors.push(format!("shader parameter {}: default {} out of range", p.name, p.default.0));
            }
        }
    }

    /// Checks an array length wherever a type appears.
    fn ty(&mut self, st: &FnState<'_>, ty: Type, unsized_ok: bool, what: &str) {
        match ty.array {
            Some(ArrayLen::Fixed(n)) if n == 0 || n > ir::MAX_ARRAY_LEN => {
                self.err(st, format!("{what} has array length {n}"));
            }
            Some(ArrayLen::Unsized) if !unsized_ok => self.err(st, format!("{what} is an unsized array")),
            _ => {}
        }
    }

    fn budgets(&mut self) {
        if let Err(why) = ir::within_budgets(self.m) {
            self.errors.push(why);
        }
    }

    fn function(&mut self, index: usize, f: &'a Function) {
        let mut st = FnState { index, f, uses: vec![0; f.exprs.len()] };
        for p in &f.params {
            match f.vars.get(p.0 as usize) {
                None => self.err(&st, format!("parameter {} out of range", p.0)),
                Some(var) if !matches!(var.kind, VarKind::Param { .. } | VarKind::Capture) => {
                    self.err(&st, format!("parameter %{} is a {:?}", var.name, var.kind));
                }
                Some(_) => {}
            }
        }
        let shader = self.m.shader.as_ref().filter(|s| s.body.0 as usize == index);
        for (i, var) in f.vars.iter().enumerate() {
            self.ty(
                &st,
                var.ty,
                matches!(var.kind, VarKind::Param { .. } | VarKind::Capture),
                &format!("%{}", var.name),
            );
            if let VarKind::ShaderParam { index: k, .. } = var.kind {
                if shader.and_then(|s| s.params.get(k as usize)).is_none_or(|p| p.var.0 as usize != i) {
                    self.err(&st, format!("%{} claims to be shader parameter {k}", var.name));
                }
            }
        }
        self.ty(&st, f.return_type, false, "the return type");
        for (i, e) in f.exprs.iter().enumerate() {
            self.ty(&st, e.ty, true, &format!("e{i}"));
        }
        if let Some(s) = shader {
            for p in &s.params {
                self.expr(&mut st, p.default);
                if self.in_range(&st, p.default) && f.expr(p.default).ty != p.ty {
                    self.err(&st, format!("default of {} has type {} not {}", p.name, f.expr(p.default).ty, p.ty));
                }
            }
        }
        self.block(&mut st, &f.body, 0);
        for (i, n) in st.uses.iter().enumerate() {
            if *n != 1 {
                self.err(&st, format!("expression e{i} is used {n} times (expressions form trees)"));
            }
        }
    }

    fn in_range(&self, st: &FnState<'_>, id: ExprId) -> bool {
        (id.0 as usize) < st.f.exprs.len()
    }

    fn block(&mut self, st: &mut FnState<'a>, b: &Block, loops: u32) {
        for s in &b.stmts {
            match &s.kind {
                StmtKind::Expr(e) => {
                    self.expr(st, *e);
                }
                StmtKind::If { cond, then, otherwise } => {
                    self.expect(st, *cond, Type::BOOL, "if condition");
                    self.block(st, then, loops);
                    self.block(st, otherwise, loops);
                }
                StmtKind::Loop { cond, body, step } => {
                    if let Some(c) = cond {
                        self.expect(st, *c, Type::BOOL, "loop condition");
                    }
                    self.block(st, body, loops + 1);
                    self.block(st, step, loops + 1);
                }
                StmtKind::Break(n) | StmtKind::Continue(n) => {
                    if *n == 0 || *n > loops {
                        self.err(st, format!("break/continue {n} with {loops} enclosing loops"));
                    }
                }
                StmtKind::Return(v) => {
                    let ret = st.f.return_type;
                    match v {
                        Some(e) => self.expect(st, *e, ret, "returned value"),
                        None if ret.base != BaseType::Void => self.err(st, "return without a value".into()),
                        None => {}
                    }
                }
                StmtKind::Illuminance { category, position, cone, body } => {
                    if let Some(c) = category {
                        self.expect(st, *c, Type::STRING, "category");
                    }
                    self.expect(st, *position, Type::POINT, "position");
                    self.cone(st, cone);
                    self.block(st, body, loops + 1);
                }
                StmtKind::Illuminate { position, cone, body } => {
                    self.expect(st, *position, Type::POINT, "position");
                    self.cone(st, cone);
                    self.block(st, body, loops);
                }
                StmtKind::Solar { cone, body } => {
                    self.cone(st, cone);
                    self.block(st, body, loops);
                }
                StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                    self.expect(st, *category, Type::STRING, "category");
                    self.expect(st, *position, Type::POINT, "position");
                    self.expect(st, *direction, Type::VECTOR, "direction");
                    self.expect(st, *angle, Type::FLOAT, "angle");
                    self.expect(st, *samples, Type::FLOAT, "samples");
                    for (name, a) in params {
                        self.expect(st, *name, Type::STRING, "gather parameter name");
                        self.arg(st, a);
                    }
                    self.block(st, body, loops + 1);
                    self.block(st, otherwise, loops + 1);
                }
            }
        }
    }

    fn cone(&mut self, st: &mut FnState<'a>, cone: &Option<(ExprId, ExprId)>) {
        if let Some((axis, angle)) = cone {
            self.expect(st, *axis, Type::VECTOR, "cone axis");
            self.expect(st, *angle, Type::FLOAT, "cone angle");
        }
    }

    fn expect(&mut self, st: &mut FnState<'a>, id: ExprId, ty: Type, what: &str) {
        if let Some(t) = self.expr(st, id) {
            if t != ty {
                self.err(st, format!("{what} e{} has type {t}, expected {ty}", id.0));
            }
        }
    }

    fn arg(&mut self, st: &mut FnState<'a>, a: &Arg) -> Option<Type> {
        match a {
            Arg::Value(e) => self.expr(st, *e),
            Arg::Ref(p) => self.place(st, p),
        }
    }

    fn place(&mut self, st: &mut FnState<'a>, p: &Place) -> Option<Type> {
        let base_ty = match p.base {
            PlaceBase::Var(v) => match st.f.vars.get(v.0 as usize) {
                Some(var) => var.ty,
                None => {
                    self.err(st, format!("variable {} out of range", v.0));
                    return None;
                }
            },
            PlaceBase::Global(g) => Type::scalar(g.def().ty),
        };
        for i in [p.index, p.component].into_iter().flatten() {
            self.expect(st, i, Type::FLOAT, "index");
        }
        let expected = match (p.index.is_some(), p.component.is_some()) {
            (false, false) => base_ty,
            (true, false) if base_ty.is_array() => base_ty.element(),
            (true, false) if base_ty.base.is_triple() => Type::FLOAT,
            (true, true) if base_ty.is_array() && base_ty.base.is_triple() => Type::FLOAT,
            _ => {
                self.err(st, format!("place indexes {base_ty} with {:?}, {:?}", p.index, p.component));
                return None;
            }
        };
        if expected != p.ty {
            self.err(st, format!("place has type {} but its base gives {expected}", p.ty));
        }
        Some(p.ty)
    }

    /// Visits an expression (counting the use) and returns its type.
    fn expr(&mut self, st: &mut FnState<'a>, id: ExprId) -> Option<Type> {
        if !self.in_range(st, id) {
            self.err(st, format!("expression {} out of range", id.0));
            return None;
        }
        st.uses[id.0 as usize] += 1;
        if st.uses[id.0 as usize] > 1 {
            return Some(st.f.expr(id).ty);
        }
        let e = st.f.expr(id);
        let ty = e.ty;
        match &e.kind {
            ExprKind::Const(c) => {
                let want = match c {
                    crate::ir::Constant::Float(_) => Type::FLOAT,
                    crate::ir::Constant::String(_) => Type::STRING,
                };
                if ty != want {
                    self.err(st, format!("constant e{} typed {ty}", id.0));
                }
            }
            ExprKind::Var(v) => match st.f.vars.get(v.0 as usize) {
                Some(var) if var.ty == ty => {
                    if e.varying != var.varying && !e.varying {
                        self.err(st, format!("e{} reads varying %{} but is marked uniform", id.0, var.name));
                    }
                }
                Some(var) => self.err(st, format!("e{} reads %{}: {} as {ty}", id.0, var.name, var.ty)),
                None => self.err(st, format!("variable {} out of range", v.0)),
            },
            ExprKind::Global(g) => {
                if Type::scalar(g.def().ty) != ty {
                    self.err(st, format!("global ${} typed {ty}", g.def().name));
                }
            }
            ExprKind::Index { base, index } => {
                let bt = self.expr(st, *base);
                self.expect(st, *index, Type::FLOAT, "index");
                if let Some(bt) = bt {
                    let want = if bt.is_array() { bt.element() } else { Type::FLOAT };
                    if (!bt.is_array() && !bt.base.is_triple()) || want != ty {
                        self.err(st, format!("index of {bt} typed {ty}"));
                    }
                }
            }
            ExprKind::Unary { op, arg } => {
                let at = self.expr(st, *arg);
                let ok = match op {
                    UnaryOp::Neg => at == Some(ty) && (ty.base.is_numeric() || ty.base == BaseType::Matrix),
                    UnaryOp::Not => at == Some(Type::BOOL) && ty == Type::BOOL,
                };
                if !ok {
                    self.err(st, format!("unary {op:?} on {at:?} typed {ty}"));
                }
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let (lt, rt) = (self.expr(st, *lhs), self.expr(st, *rhs));
                if let (Some(lt), Some(rt)) = (lt, rt) {
                    if !binary_ok(*op, lt, rt, ty) {
                        self.err(st, format!("binary {op:?} on {lt} and {rt} typed {ty}"));
                    }
                }
            }
            ExprKind::Convert { arg } => {
                if let Some(at) = self.expr(st, *arg) {
                    if at.array != ty.array || !convertible(at.base, ty.base) {
                        self.err(st, format!("conversion from {at} to {ty}"));
                    }
                }
            }
            ExprKind::Construct { args } => {
                let n = args.len();
                if !((n == 3 && ty.base.is_triple()) || (n == 16 && ty.base == BaseType::Matrix)) || ty.is_array() {
                    self.err(st, format!("constructor of {ty} from {n} values"));
                }
                for a in args {
                    self.expect(st, *a, Type::FLOAT, "component");
                }
            }
            ExprKind::SpaceCast { space, arg } => {
                self.expect(st, *space, Type::STRING, "space name");
                self.expect(st, *arg, ty, "space-cast operand");
            }
            ExprKind::Select { cond, a, b } => {
                self.expect(st, *cond, Type::BOOL, "select condition");
                self.expect(st, *a, ty, "select operand");
                self.expect(st, *b, ty, "select operand");
            }
            ExprKind::CallBuiltin { builtin, overload, args } => self.call_builtin(st, *builtin, *overload, args, ty),
            ExprKind::Call { func, args } => self.call(st, *func, args, ty),
            ExprKind::Assign { place, op, value } => {
                let pt = self.place(st, place);
                self.expect(st, *value, ty, "assigned value");
                if pt != Some(ty) {
                    self.err(st, format!("assignment typed {ty} to a place of {pt:?}"));
                }
                if op.is_some() && !(ty.base.is_numeric() || ty.base == BaseType::Matrix) {
                    self.err(st, format!("compound assignment on {ty}"));
                }
                if let (PlaceBase::Var(v), Some(value)) = (place.base, st.f.exprs.get(value.0 as usize)) {
                    let value_varying = value.varying;
                    if let Some(var) = st.f.vars.get(v.0 as usize) {
                        if !var.varying && value_varying {
                            self.err(st, format!("uniform %{} assigned a varying value", var.name));
                        }
                    }
                }
            }
            ExprKind::ArrayLiteral { elements } => {
                if ty.array_len() != Some(elements.len() as u32) {
                    self.err(st, format!("array literal of {} elements typed {ty}", elements.len()));
                }
                for el in elements {
                    self.expect(st, *el, ty.element(), "array element");
                }
            }
        }
        Some(ty)
    }

    fn call_builtin(&mut self, st: &mut FnState<'a>, b: Builtin, overload: u16, args: &[Arg], ty: Type) {
        let Some(sig) = builtins::signatures(b).get(overload as usize) else {
            self.err(st, format!("{} has no overload {overload}", b.name()));
            return;
        };
        if Type::scalar(sig.ret) != ty {
            self.err(st, format!("{}.{overload} returns {} but is typed {ty}", b.name(), sig.ret));
        }
        let fixed = if sig.repeat_last { args.len() } else { sig.params.len().min(args.len()) };
        if args.len() < sig.min_args() || (args.len() > fixed && !sig.param_list) {
            self.err(st, format!("{}.{overload} called with {} arguments", b.name(), args.len()));
        }
        for (i, a) in args.iter().enumerate() {
            let at = self.arg(st, a);
            if i >= fixed {
                continue;
            }
            let Some(p) = sig.param(i) else { continue };
            if p.output != matches!(a, Arg::Ref(_)) {
                self.err(st, format!("{}.{overload} argument {i}: output mismatch", b.name()));
            }
            if let (Some(want), Some(at)) = (p.ty, at) {
                let base_ok = at.base == want || (p.output && at.base.is_pointlike() && want.is_pointlike());
                if !base_ok || at.is_array() != p.array {
                    self.err(st, format!("{}.{overload} argument {i} is {at}, expected {want}", b.name()));
                }
            }
        }
    }

    fn call(&mut self, st: &mut FnState<'a>, func: FuncId, args: &[Arg], ty: Type) {
        let Some(callee) = self.m.functions.get(func.0 as usize) else {
            self.err(st, format!("function {} out of range", func.0));
            return;
        };
        if callee.return_type != ty {
            self.err(st, format!("call of {} typed {ty}, returns {}", callee.name, callee.return_type));
        }
        if callee.params.len() != args.len() {
            self.err(
                st,
                format!("call of {} with {} arguments for {} parameters", callee.name, args.len(), callee.params.len()),
            );
        }
        for (a, p) in args.iter().zip(&callee.params) {
            let at = self.arg(st, a);
            let Some(param) = callee.vars.get(p.0 as usize) else { continue };
            let by_ref = matches!(param.kind, VarKind::Param { output: true } | VarKind::Capture);
            if by_ref != matches!(a, Arg::Ref(_)) {
                self.err(
                    st,
                    format!(
                        "call of {}: parameter %{} passed {}",
                        callee.name,
                        param.name,
                        if by_ref { "by value" } else { "by reference" }
                    ),
                );
            }
            if let Some(at) = at {
                let same = at.base == param.ty.base || (at.base.is_pointlike() && param.ty.base.is_pointlike());
                let arrays = match (at.array, param.ty.array) {
                    (None, None) => true,
                    (Some(_), Some(crate::ir::ArrayLen::Unsized)) => true,
                    (a, b) => a == b,
                };
                if !same || !arrays {
                    self.err(st, format!("call of {}: %{} is {} but gets {at}", callee.name, param.name, param.ty));
                }
            }
        }
    }

    fn recursion(&mut self) {
        let n = self.m.functions.len();
        let mut edges = vec![Vec::new(); n];
        for (i, f) in self.m.functions.iter().enumerate() {
            for e in &f.exprs {
                if let ExprKind::Call { func, .. } = e.kind {
                    if (func.0 as usize) < n {
                        edges[i].push(func.0 as usize);
                    }
                }
            }
        }
        // Kahn's algorithm: a cycle leaves nodes with callers.
        let mut indegree = vec![0usize; n];
        for list in &edges {
            for &c in list {
                indegree[c] += 1;
            }
        }
        let mut ready: Vec<usize> = (0..n).filter(|&i| indegree[i] == 0).collect();
        let mut seen = 0;
        while let Some(i) = ready.pop() {
            seen += 1;
            for &c in &edges[i] {
                indegree[c] -= 1;
                if indegree[c] == 0 {
                    ready.push(c);
                }
            }
        }
        if seen != n {
            self.errors.push("the call graph has a cycle (recursion)".into());
        }
    }
}

fn convertible(from: BaseType, to: BaseType) -> bool {
    use BaseType::*;
    from == to
        || (from.is_triple() && to.is_triple())
        || (from == Float && (to.is_triple() || to == Matrix))
        || (from == Bool && to == Float)
        || (from.is_triple() && to == Float)
}

fn binary_ok(op: BinaryOp, l: Type, r: Type, ty: Type) -> bool {
    use BinaryOp::*;
    if l.is_array() || r.is_array() || l != r {
        return false;
    }
    match op {
        Add | Sub | Mul | Div => {
            (l.base.is_numeric() || l.base == BaseType::Matrix)
                && (ty == l || (op == Sub && l == Type::POINT && ty == Type::VECTOR))
        }
        Cross => l.base.is_triple() && ty == l,
        Dot => l.base.is_triple() && ty == Type::FLOAT,
        Lt | Gt | Le | Ge => l == Type::FLOAT && ty == Type::BOOL,
        Eq | Ne => ty == Type::BOOL && l.base != BaseType::Void,
        And | Or => l == Type::BOOL && ty == Type::BOOL,
    }
}

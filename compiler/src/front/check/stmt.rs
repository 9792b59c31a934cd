//! Statements: declarations, control flow, light loops, nested functions.

use super::{Binding, Checker, WithLabel};
use crate::diagnostic::{Code, Diagnostic};
use crate::front::parse::ast::{self, ShaderKind};
use crate::globals::Global;
use crate::ir::{self, Arg, BaseType, Block, Constant, ExprId, ExprKind, StmtKind, Type, VarKind};
use crate::source::Span;

impl Checker<'_> {
    /// Lowers a block. `new_scope` is false for a function's outermost block, which shares the scope
    /// of the parameters.
    pub(super) fn block(&mut self, block: &ast::Block, new_scope: bool) -> Block {
        if new_scope {
            self.push_scope();
        }
        let mut out = Block::default();
        self.stmts_into(block.stmts, &mut out);
        if new_scope {
            self.pop_scope();
        }
        out
    }

    fn stmts_into(&mut self, stmts: &[ast::Stmt], out: &mut Block) {
        let mut ended: Option<Span> = None;
        let mut warned = false;
        for s in stmts {
            if let (Some(end), false) = (ended, warned) {
                if !matches!(s.kind, ast::StmtKind::Empty | ast::StmtKind::Function(_)) {
                    warned = true;
                    self.diags.push(
                        Diagnostic::new(Code::UnreachableCode, s.span, "unreachable statement")
                            .with_label("this is never run")
                            .with_secondary(end, "any code after this is unreachable"),
                    );
                }
            }
            if matches!(s.kind, ast::StmtKind::Return(_) | ast::StmtKind::Break(..) | ast::StmtKind::Continue(..)) {
                ended.get_or_insert(s.span);
            }
            self.stmt(s, out);
        }
    }

    /// Lowers a statement that forms its own scope (a loop or branch body).
    fn scoped(&mut self, s: &ast::Stmt) -> Block {
        self.push_scope();
        let mut out = Block::default();
        match &s.kind {
            ast::StmtKind::Block(b) => self.stmts_into(b.stmts, &mut out),
            _ => self.stmt(s, &mut out),
        }
        self.pop_scope();
        out
    }

    fn push(&mut self, out: &mut Block, kind: StmtKind, span: Span) {
        out.stmts.push(ir::Stmt { kind, span });
    }

    fn stmt(&mut self, s: &ast::Stmt, out: &mut Block) {
        if !self.enter(s.span) {
            return;
        }
        self.stmt_inner(s, out);
        self.depth -= 1;
    }

    fn stmt_inner(&mut self, s: &ast::Stmt, out: &mut Block) {
        use ast::StmtKind as S;
        match &s.kind {
            S::Decl(d) => self.var_decl(d, out),
            S::Expr(e) => {
                if let Some(id) = self.expr(e, None) {
                    self.push(out, StmtKind::Expr(id), s.span);
                }
            }
            S::Block(b) => {
                let inner = self.block(b, true);
                out.stmts.extend(inner.stmts);
            }
            S::If { cond, then, otherwise } => {
                let c = self.condition(cond);
                let t = self.scoped(then);
                let o = otherwise.as_ref().map(|o| self.scoped(o)).unwrap_or_default();
                if let Some(cond) = c {
                    self.push(out, StmtKind::If { cond, then: t, otherwise: o }, s.span);
                }
            }
            S::While { cond, body } => {
                let c = self.condition(cond);
                self.b().loop_depth += 1;
                let body = self.scoped(body);
                self.b().loop_depth -= 1;
                if let Some(cond) = c {
                    self.push(out, StmtKind::Loop { cond: Some(cond), body, step: Block::default() }, s.span);
                }
            }
            S::For { init, cond, step, body } => {
                self.push_scope();
                if let Some(init) = init {
                    self.stmt(init, out);
                }
                let c = cond.as_ref().map(|c| self.condition(c));
                let step_block = match step {
                    Some(e) => {
                        let mut b = Block::default();
                        if let Some(id) = self.expr(e, None) {
                            self.push(&mut b, StmtKind::Expr(id), e.span);
                        }
                        b
                    }
                    None => Block::default(),
                };
                self.b().loop_depth += 1;
                let body = self.scoped(body);
                self.b().loop_depth -= 1;
                self.pop_scope();
                match c {
                    Some(None) => {}
                    Some(Some(cond)) => {
                        self.push(out, StmtKind::Loop { cond: Some(cond), body, step: step_block }, s.span)
                    }
                    None => self.push(out, StmtKind::Loop { cond: None, body, step: step_block }, s.span),
                }
            }
            S::Break(n, level_span) | S::Continue(n, level_span) => {
                let is_break = matches!(s.kind, S::Break(..));
                let word = if is_break { "break" } else { "continue" };
                let depth = self.cur().loop_depth;
                if *n == 0 || *n > depth {
                    let span = level_span.unwrap_or(s.span);
                    let msg = if depth == 0 {
                        format!("`{word}` outside a loop")
                    } else {
                        format!("`{word} {n}` leaves {n} loops, but only {depth} enclose it")
                    };
                    self.error(Code::BreakLevel, span, msg).with_label("too many levels");
                } else {
                    let kind = if is_break { StmtKind::Break(*n) } else { StmtKind::Continue(*n) };
                    self.push(out, kind, s.span);
                }
            }
            S::Return(value) => self.return_stmt(value.as_ref(), s.span, out),
            S::Illuminance { args, body } => self.illuminance(args, body, s.span, out),
            S::Illuminate { args, body } | S::Solar { args, body } => {
                let solar = matches!(s.kind, S::Solar { .. });
                self.illuminate(solar, args, body, s.span, out)
            }
            S::Gather { args, body, otherwise } => self.gather(args, body, otherwise.as_deref(), s.span, out),
            S::Function(f) => {
                if let Some(index) = self.declare_function(f) {
                    self.b().scopes.last_mut().expect("scope").funcs.entry(f.name.sym).or_default().push(index);
                    self.lower_function(f, index);
                }
            }
            S::Empty | S::Error => {}
        }
    }

    fn return_stmt(&mut self, value: Option<&ast::Expr>, span: Span, out: &mut Block) {
        if self.cur().is_shader {
            self.error(Code::ReturnMismatch, span, "`return` in a shader body")
                .with_label("only functions return")
                .notes
                .push("a shader ends when its body ends; set its outputs (e.g. `Ci`) instead".into());
            return;
        }
        let ret = self.cur().func.return_type;
        match (value, ret.base) {
            (None, BaseType::Void) => self.push(out, StmtKind::Return(None), span),
            (Some(e), BaseType::Void) => {
                self.error(Code::ReturnMismatch, e.span, "a `void` function cannot return a value")
                    .with_label("remove this value");
            }
            (None, _) => {
                self.error(Code::ReturnMismatch, span, format!("this function must return a `{ret}`"))
                    .with_label("value missing");
            }
            (Some(e), _) => {
                let value = self
                    .expr(e, Some(ret.base))
                    .and_then(|id| self.coerce(id, ret, e.span, Code::ReturnMismatch, "returned value"));
                // After an error the statement still counts as a return (no IR is produced then),
                // so that "missing return" is not reported on top.
                self.push(out, StmtKind::Return(value), span);
            }
        }
    }

    pub(super) fn var_decl(&mut self, d: &ast::VarDecl, out: &mut Block) {
        let base: BaseType = d.ty.name.into();
        let declared = d.ty.storage.map(|s| s == ast::Storage::Varying);
        if base == BaseType::String && declared == Some(true) {
            self.error(Code::VaryingString, d.ty.span, "strings are always uniform")
                .with_label("`varying` string")
                .notes
                .push("remove `varying`".into());
        }
        if base == BaseType::Void {
            self.error(Code::AssignTypeMismatch, d.ty.span, "a variable cannot have type `void`");
            return;
        }
        for decl in d.vars {
            let Some(array) = self.array_len(&decl.array, false) else {
                // Declare it anyway (as a one-element array) so later uses do not cascade.
                let ty = Type { base, array: Some(ir::ArrayLen::Fixed(1)) };
                let _ = self.declare_var(decl.name, ty, VarKind::Local, declared);
                continue;
            };
            let ty = Type { base, array };
            if d.is_extern {
                self.extern_decl(decl, ty);
                continue;
            }
            // The initialiser is checked before the name is in scope (`float x = x;` reads an outer x).
            let init = match &decl.init {
                Some(e) => match self.initializer(e, ty) {
                    Some(id) => Some(id),
                    None => {
                        // Declare anyway so later uses do not report an undefined name.
                        let _ = self.declare_var(decl.name, ty, VarKind::Local, declared);
                        continue;
                    }
                },
                None => None,
            };
            let Some(var) = self.declare_var(decl.name, ty, VarKind::Local, declared) else { continue };
            if let Some(value) = init {
                let place = ir::Place { base: ir::PlaceBase::Var(var), index: None, component: None, ty };
                let span = decl.name.span.to(self.cur().func.expr(value).span);
                let assign = self.add_expr(ExprKind::Assign { place, op: None, value }, ty, span);
                self.push(out, StmtKind::Expr(assign), span);
            }
        }
    }

    /// `extern type name;`: a variable of an enclosing function, or a shader global.
    fn extern_decl(&mut self, decl: &ast::Declarator, ty: Type) {
        let text = self.name(decl.name.sym).to_string();
        let level = self.builders.len() - 1;
        // An enclosing scope of this function (`extern` in a light loop's block is redundant but
        // legal), then the enclosing functions.
        let found = self.lookup_outer(level, decl.name.sym);
        match found {
            Some((owner, Binding::Var(var))) => {
                let outer_ty = self.builders[owner].func.var(var).ty;
                if outer_ty.base != ty.base && !(outer_ty.base.is_pointlike() && ty.base.is_pointlike()) {
                    self.error(
                        Code::AssignTypeMismatch,
                        decl.name.span,
                        format!("`extern {ty} {text}` does not match its declaration as `{outer_ty}`"),
                    )
                    .with_label("type differs");
                    return;
                }
                let local = self.access_outer(level, owner, var);
                self.b().scopes.last_mut().expect("scope").vars.insert(decl.name.sym, Binding::Var(local));
            }
            Some((_, Binding::Global(g))) => {
                self.b().scopes.last_mut().expect("scope").vars.insert(decl.name.sym, Binding::Global(g));
            }
            None => match Global::lookup(&text) {
                Some(g) if self.kind.is_none_or(|k| g.def().access(k) != crate::globals::Access::None) => {
                    self.b().scopes.last_mut().expect("scope").vars.insert(decl.name.sym, Binding::Global(g));
                }
                // A global of another shader type: an error only where the shader calls this
                // function (a header's helpers serve several types).
                Some(_) if self.current_function().is_some() => {
                    let kind = self.kind.map(|k| k.name()).unwrap_or("");
                    let owner = self.current_function();
                    self.context_error(
                        owner,
                        Code::UndefinedVariable,
                        decl.name.span,
                        format!("`{text}` is not available in {kind} shaders"),
                    )
                    .label = Some("not a global of this shader type".into());
                    let _ = self.declare_var(decl.name, ty, VarKind::Local, None);
                }
                _ => {
                    let mut d = Diagnostic::new(
                        Code::ExternNotFound,
                        decl.name.span,
                        format!("`extern {text}` names no variable of an enclosing function or shader global"),
                    )
                    .with_label("not found");
                    if level == 0 {
                        d = d.with_note(
                            "`extern` reaches variables of enclosing functions; this function is not nested",
                        );
                    }
                    self.diags.push(d);
                    // Declare it locally so that its uses do not cascade into more errors.
                    let _ = self.declare_var(decl.name, ty, VarKind::Local, None);
                }
            },
        }
    }

    /// Checks an initialiser (or default value) against the declared type.
    pub(super) fn initializer(&mut self, e: &ast::Expr, ty: Type) -> Option<ExprId> {
        if let ast::ExprKind::ArrayLiteral(elements) = &e.kind {
            let Some(len) = ty.array_len() else {
                self.error(Code::ArrayMismatch, e.span, format!("`{{...}}` initialises arrays, but this is a `{ty}`"))
                    .with_label("not an array");
                return None;
            };
            if elements.len() != len as usize {
                self.error(
                    Code::ArrayMismatch,
                    e.span,
                    format!(
                        "array of length {len} initialised with {} value{}",
                        elements.len(),
                        if elements.len() == 1 { "" } else { "s" }
                    ),
                )
                .with_label(&format!("expected {len} values"));
                return None;
            }
            let mut ids = Vec::with_capacity(elements.len());
            for el in elements.iter() {
                let id = self.expr(el, Some(ty.base))?;
                ids.push(self.coerce(id, ty.element(), el.span, Code::ArrayMismatch, "array element")?);
            }
            return Some(self.add_expr(ExprKind::ArrayLiteral { elements: ids }, ty, e.span));
        }
        let id = self.expr(e, Some(ty.base))?;
        self.coerce(id, ty, e.span, Code::AssignTypeMismatch, "initial value")
    }

    /// A condition: a relation, or a float compared with zero.
    pub(super) fn condition(&mut self, e: &ast::Expr) -> Option<ExprId> {
        let id = self.expr(e, None)?;
        self.as_condition(id, e.span)
    }

    pub(super) fn as_condition(&mut self, id: ExprId, span: Span) -> Option<ExprId> {
        let ty = self.cur().func.expr(id).ty;
        match ty {
            Type { base: BaseType::Bool, array: None } => Some(id),
            Type { base: BaseType::Float, array: None } => {
                let zero = self.add_expr(ExprKind::Const(Constant::Float(0.0)), Type::FLOAT, span);
                Some(self.add_expr(ExprKind::Binary { op: ir::BinaryOp::Ne, lhs: id, rhs: zero }, Type::BOOL, span))
            }
            other => {
                self.error(
                    Code::BadCondition,
                    span,
                    format!("a condition must be a relation or a float, not a `{other}`"),
                )
                .with_label("not a condition")
                .notes
                .push("compare it, e.g. `x != 0` or `s == \"name\"`".into());
                None
            }
        }
    }

    fn expect_arg(&mut self, e: &ast::Expr, ty: Type, what: &str) -> Option<ExprId> {
        let id = self.expr(e, Some(ty.base))?;
        self.coerce(id, ty, e.span, Code::NoMatchingOverload, what)
    }

    fn light_loop_body(&mut self, body: &ast::Stmt) -> Block {
        self.b().loop_depth += 1;
        self.b().light_loop_depth += 1;
        let b = self.scoped(body);
        self.b().light_loop_depth -= 1;
        self.b().loop_depth -= 1;
        b
    }

    fn illuminance(&mut self, args: &[ast::Expr], body: &ast::Stmt, span: Span, out: &mut Block) {
        self.b().uses_light_loop.get_or_insert(span);
        if args.is_empty() || args.len() > 4 {
            self.error(Code::NoMatchingOverload, span, "`illuminance` takes ([category,] position [, axis, angle])")
                .with_label(&format!("{} arguments given", args.len()));
            let _ = self.light_loop_body(body);
            return;
        }
        // The first argument is a category when it is a string.
        let first = self.expr(&args[0], Some(BaseType::Point));
        let first_is_string = first.is_some_and(|id| self.cur().func.expr(id).ty == Type::STRING);
        let (category, position, rest) = if first_is_string {
            let position = args.get(1).and_then(|a| self.expect_arg(a, Type::POINT, "position"));
            (first, position, args.get(2..).unwrap_or(&[]))
        } else {
            let position =
                first.and_then(|id| self.coerce(id, Type::POINT, args[0].span, Code::NoMatchingOverload, "position"));
            (None, position, &args[1..])
        };
        if (first_is_string && args.len() < 2) || (!rest.is_empty() && rest.len() != 2) {
            self.error(Code::NoMatchingOverload, span, "`illuminance` takes ([category,] position [, axis, angle])")
                .with_label(&format!("{} arguments given", args.len()));
            let _ = self.light_loop_body(body);
            return;
        }
        let cone = if rest.len() == 2 {
            let axis = self.expect_arg(&rest[0], Type::VECTOR, "axis");
            let angle = self.expect_arg(&rest[1], Type::FLOAT, "angle");
            match (axis, angle) {
                (Some(a), Some(b)) => Some(Some((a, b))),
                _ => None,
            }
        } else {
            Some(None)
        };
        let body = self.light_loop_body(body);
        if let (Some(position), Some(cone), true) = (position, cone, first.is_some()) {
            self.push(out, StmtKind::Illuminance { category, position, cone, body }, span);
        }
    }

    fn illuminate(&mut self, solar: bool, args: &[ast::Expr], body: &ast::Stmt, span: Span, out: &mut Block) {
        let word = if solar { "solar" } else { "illuminate" };
        if self.kind.is_some_and(|k| k != ShaderKind::Light) {
            let kind = self.kind.map(|k| k.name()).unwrap_or("");
            self.error(
                Code::IlluminateContext,
                span,
                format!("`{word}` is only available in light shaders, not in {kind} shaders"),
            )
            .with_label("here")
            .notes
            .push(if kind == "surface" {
                "surface shaders gather light with `illuminance`".to_string()
            } else {
                "emit light from a light shader".to_string()
            });
            // Check the rest anyway, for its own errors and so its variables count as used.
            for a in args {
                let _ = self.expr(a, None);
            }
            let _ = self.scoped(body);
            return;
        }
        let ok_count = if solar { args.is_empty() || args.len() == 2 } else { args.len() == 1 || args.len() == 3 };
        if !ok_count {
            let form = if solar {
                "`solar` takes () or (axis, angle)"
            } else {
                "`illuminate` takes (position [, axis, angle])"
            };
            self.error(Code::NoMatchingOverload, span, form).with_label(&format!("{} arguments given", args.len()));
            return;
        }
        let (position, cone_args) = if solar { (None, args) } else { (Some(&args[0]), &args[1..]) };
        let position = match position {
            Some(p) => match self.expect_arg(p, Type::POINT, "position") {
                Some(id) => Some(id),
                None => return,
            },
            None => None,
        };
        let cone = if cone_args.len() == 2 {
            let axis = self.expect_arg(&cone_args[0], Type::VECTOR, "axis");
            let angle = self.expect_arg(&cone_args[1], Type::FLOAT, "angle");
            match (axis, angle) {
                (Some(a), Some(b)) => Some((a, b)),
                _ => return,
            }
        } else {
            None
        };
        self.b().light_loop_depth += 1;
        let body = self.scoped(body);
        self.b().light_loop_depth -= 1;
        let kind = match position {
            Some(position) => StmtKind::Illuminate { position, cone, body },
            None => StmtKind::Solar { cone, body },
        };
        self.push(out, kind, span);
    }

    fn gather(
        &mut self,
        args: &[ast::Expr],
        body: &ast::Stmt,
        otherwise: Option<&ast::Stmt>,
        span: Span,
        out: &mut Block,
    ) {
        self.b().uses_light_loop.get_or_insert(span);
        if args.len() < 5 || (args.len() - 5) % 2 != 0 {
            self.error(
                Code::NoMatchingOverload,
                span,
                "`gather` takes (category, position, direction, angle, samples, \"name\", value...)",
            )
            .with_label(&format!("{} arguments given", args.len()));
            return;
        }
        let category = self.expect_arg(&args[0], Type::STRING, "category");
        let position = self.expect_arg(&args[1], Type::POINT, "position");
        let direction = self.expect_arg(&args[2], Type::VECTOR, "direction");
        let angle = self.expect_arg(&args[3], Type::FLOAT, "angle");
        let samples = self.expect_arg(&args[4], Type::FLOAT, "samples");
        let mut params = Vec::new();
        let mut ok = true;
        for pair in args[5..].chunks(2) {
            let output = matches!(&pair[0].kind, ast::ExprKind::String(s) if self.name(*s).contains(':'));
            let Some(name) = self.expect_arg(&pair[0], Type::STRING, "parameter name") else {
                ok = false;
                continue;
            };
            let value = if output {
                self.place(&pair[1], true).map(Arg::Ref)
            } else {
                self.expr(&pair[1], None).map(Arg::Value)
            };
            match value {
                Some(v) => params.push((name, v)),
                None => ok = false,
            }
        }
        self.b().loop_depth += 1;
        self.b().light_loop_depth += 1;
        let body = self.scoped(body);
        let otherwise = otherwise.map(|o| self.scoped(o)).unwrap_or_default();
        self.b().light_loop_depth -= 1;
        self.b().loop_depth -= 1;
        if let (Some(category), Some(position), Some(direction), Some(angle), Some(samples), true) =
            (category, position, direction, angle, samples, ok)
        {
            self.push(
                out,
                StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise },
                span,
            );
        }
    }
}

//! Expressions: names, operators, typecasts, assignments.

use super::{Binding, Checker, WithLabel};
use crate::diagnostic::{Code, Diagnostic};
use crate::front::parse::ast::{self, AssignOp, ShaderKind};
use crate::globals::{Access, Global};
use crate::ir::types::COLOR_SPACES;
use crate::ir::{self, BaseType, Constant, ExprId, ExprKind, Place, PlaceBase, Type};
use crate::source::Span;
use crate::symbol::Symbol;

impl Checker<'_> {
    /// Checks and lowers an expression. `expected` is the type the context wants, if it knows: it
    /// picks the result type of context-typed built-ins (`noise`, `texture`) and of untyped triples.
    /// Returns `None` after reporting an error.
    pub(super) fn expr(&mut self, e: &ast::Expr, expected: Option<BaseType>) -> Option<ExprId> {
        if !self.enter(e.span) {
            return None;
        }
        let result = self.expr_inner(e, expected);
        self.depth -= 1;
        result
    }

    fn expr_inner(&mut self, e: &ast::Expr, expected: Option<BaseType>) -> Option<ExprId> {
        use ast::ExprKind as K;
        match &e.kind {
            K::Number(v) => Some(self.add_expr(ExprKind::Const(Constant::Float(*v as f32)), Type::FLOAT, e.span)),
            K::String(s) => {
                let text = self.name(*s).to_string();
                Some(self.add_expr(ExprKind::Const(Constant::String(text)), Type::STRING, e.span))
            }
            K::Ident(sym) => self.name_expr(*sym, e.span),
            K::Index(base, index) => self.index_expr(base, index, e.span),
            K::Call { name, args } => self.call(name, args, e.span, expected),
            K::Tuple(items) => self.tuple(items, e.span, expected),
            K::ArrayLiteral(_) => {
                self.error(Code::ArrayMismatch, e.span, "`{...}` may only initialise an array declaration")
                    .with_label("array initialiser here");
                None
            }
            K::Cast { ty, space, expr } => self.cast((*ty).into(), *space, expr, e.span),
            K::Unary(op, arg) => self.unary(*op, arg, e.span, expected),
            K::Binary(op, l, r) => self.binary(*op, l, r, e.span, expected),
            K::Ternary(c, a, b) => self.ternary(c, a, b, e.span, expected),
            K::Assign(op, target, value) => self.assign(*op, target, value, e.span),
            K::IncDec { increment, prefix, target } => self.inc_dec(*increment, *prefix, target, e.span),
            K::Error => None,
        }
    }

    fn name_expr(&mut self, sym: Symbol, span: Span) -> Option<ExprId> {
        match self.lookup_var(sym) {
            Some(Binding::Var(v)) => {
                self.b().used[v.0 as usize] = true;
                let ty = self.cur().func.var(v).ty;
                Some(self.add_expr(ExprKind::Var(v), ty, span))
            }
            Some(Binding::Global(g)) => self.global_read(g, span),
            None => {
                let text = self.name(sym).to_string();
                if let Some(g) = Global::lookup(&text) {
                    return self.global_read(g, span);
                }
                if text == "PI" {
                    // RISpec 3.2 predefines `float PI = 3.14159...` (headers that `#define PI` still win).
                    return Some(self.add_expr(
                        ExprKind::Const(Constant::Float(std::f32::consts::PI)),
                        Type::FLOAT,
                        span,
                    ));
                }
                self.undefined_name(&text, span);
                None
            }
        }
    }

    fn global_read(&mut self, g: Global, span: Span) -> Option<ExprId> {
        let def = g.def();
        if let Some(kind) = self.kind {
            if def.access(kind) == Access::None && self.vendor_global(kind, def.name, Access::Read, span) {
                return Some(self.add_expr(ExprKind::Global(g), Type::scalar(def.ty), span));
            }
            if def.access(kind) == Access::None {
                let owner = self.current_function();
                self.context_error(
                    owner,
                    Code::UndefinedVariable,
                    span,
                    format!("`{}` is not available in {} shaders", def.name, kind.name()),
                )
                .with_label("not a global of this shader type");
                return None;
            }
            let in_light_loop_context =
                matches!(kind, ShaderKind::Surface | ShaderKind::Volume | ShaderKind::Lightfield);
            if def.light_loop_only()
                && in_light_loop_context
                && self.cur().is_shader
                && self.cur().light_loop_depth == 0
            {
                self.error(
                    Code::LightGlobalOutsideLoop,
                    span,
                    format!("`{}` is only defined inside `illuminance`", def.name),
                )
                .with_label("used outside a light loop")
                .notes
                .push(format!("`{}` holds the values of the light being visited by `illuminance`", def.name));
                return None;
            }
        }
        Some(self.add_expr(ExprKind::Global(g), Type::scalar(def.ty), span))
    }

    /// Whether `name` is another renderer's global for `kind` giving `wanted` access
    /// ([`crate::globals::VENDOR_GLOBALS`]): then warning W0012 says whose and what rtsl gives.
    pub(super) fn vendor_global(&mut self, kind: ShaderKind, name: &str, wanted: Access, span: Span) -> bool {
        let Some((access, renderer, meaning)) = crate::globals::vendor_access(kind, name) else { return false };
        if wanted == Access::Write && access != Access::Write {
            return false;
        }
        let what = if wanted == Access::Write { "writing" } else { "reading" };
        self.diags.push(
            Diagnostic::new(
                Code::VendorExtension,
                span,
                format!("{what} `{name}` in {} shaders is {renderer}'s extension", kind.name()),
            )
            .with_label(format!("accepted, as {renderer} accepts it"))
            .with_note(format!("rtsl gives {meaning}")),
        );
        true
    }

    pub(super) fn undefined_name(&mut self, text: &str, span: Span) {
        if self.incomplete {
            // The parser dropped statements, perhaps the declaration: do not guess.
            return;
        }
        let mut candidates: Vec<String> = Vec::new();
        for b in &self.builders {
            for s in &b.scopes {
                for sym in s.vars.keys() {
                    candidates.push(self.name(*sym).to_string());
                }
            }
        }
        for g in crate::globals::GLOBALS {
            if self.kind.is_none_or(|k| g.access(k) != Access::None) {
                candidates.push(g.name.to_string());
            }
        }
        let mut d = Diagnostic::new(Code::UndefinedVariable, span, format!("undefined variable `{text}`"))
            .with_label("not found in this scope");
        if let Some(best) = closest(text, candidates.iter().map(String::as_str)) {
            d = d.with_note(format!("did you mean `{best}`?"));
        }
        self.diags.push(d);
    }

    fn index_expr(&mut self, base: &ast::Expr, index: &ast::Expr, span: Span) -> Option<ExprId> {
        let b = self.expr(base, None)?;
        let i = self.expr(index, Some(BaseType::Float))?;
        let bty = self.expr_ty(b);
        let ity = self.expr_ty(i);
        if ity != Type::FLOAT {
            self.error(Code::BadIndex, index.span, format!("an index must be a float, not a `{ity}`"))
                .with_label("not a number");
            return None;
        }
        let ty = if bty.is_array() {
            bty.element()
        } else if bty.base.is_triple() {
            Type::FLOAT
        } else {
            self.error(Code::BadIndex, base.span, format!("a `{bty}` cannot be indexed"))
                .with_label("not an array or triple")
                .notes
                .push("only arrays (and the components of triples) can be indexed".into());
            return None;
        };
        Some(self.add_expr(ExprKind::Index { base: b, index: i }, ty, span))
    }

    fn tuple(&mut self, items: &[ast::Expr], span: Span, expected: Option<BaseType>) -> Option<ExprId> {
        let ty = match (items.len(), expected) {
            (3, Some(t)) if t.is_triple() => t,
            (3, _) => BaseType::Point,
            (16, _) => BaseType::Matrix,
            (n, _) => {
                self.error(
                    Code::BadConstructor,
                    span,
                    format!("a parenthesised list must have 3 values (a triple) or 16 (a matrix), not {n}"),
                )
                .with_label("wrong number of values");
                return None;
            }
        };
        self.construct(ty, items, span)
    }

    fn construct(&mut self, ty: BaseType, items: &[ast::Expr], span: Span) -> Option<ExprId> {
        let mut args = Vec::with_capacity(items.len());
        let mut ok = true;
        for item in items {
            let Some(id) = self.expr(item, Some(BaseType::Float)) else {
                ok = false;
                continue;
            };
            match self.coerce_strict_float(id, item.span) {
                Some(id) => args.push(id),
                None => ok = false,
            }
        }
        ok.then(|| self.add_expr(ExprKind::Construct { args }, Type::scalar(ty), span))
    }

    /// A component of a triple or matrix: must be a float (relations convert).
    fn coerce_strict_float(&mut self, id: ExprId, span: Span) -> Option<ExprId> {
        let ty = self.expr_ty(id);
        match ty {
            Type { base: BaseType::Float, array: None } => Some(id),
            Type { base: BaseType::Bool, array: None } => Some(self.convert_node(id, BaseType::Float)),
            _ => {
                self.error(Code::BadConstructor, span, format!("each component must be a float, not a `{ty}`"))
                    .with_label("not a float");
                None
            }
        }
    }

    fn cast(&mut self, to: BaseType, space: Option<(Symbol, Span)>, operand: &ast::Expr, span: Span) -> Option<ExprId> {
        // `color (r, g, b)` and `matrix (16 values)` construct directly.
        let value = match &operand.kind {
            ast::ExprKind::Tuple(items) if to.is_triple() && items.len() == 3 => {
                self.construct(to, items, operand.span)?
            }
            ast::ExprKind::Tuple(items) if to == BaseType::Matrix && items.len() == 16 => {
                self.construct(to, items, operand.span)?
            }
            ast::ExprKind::Tuple(items) => {
                self.error(
                    Code::BadConstructor,
                    operand.span,
                    format!(
                        "a `{to}` is built from {} values, not {}",
                        if to == BaseType::Matrix { 16 } else { 3 },
                        items.len()
                    ),
                )
                .with_label("wrong number of values");
                return None;
            }
            _ => {
                let id = self.expr(operand, Some(to))?;
                let from = self.expr_ty(id);
                let ok = !from.is_array()
                    && match (from.base, to) {
                        (a, b) if a == b => true,
                        (BaseType::Float | BaseType::Bool, b) => b.is_numeric() || b == BaseType::Matrix,
                        (a, b) if a.is_triple() && (b.is_triple() || b == BaseType::Float) => true,
                        _ => false,
                    };
                if !ok {
                    self.error(Code::BadTypecast, span, format!("cannot typecast a `{from}` to `{to}`"))
                        .with_label("invalid typecast");
                    return None;
                }
                self.convert_node(id, to)
            }
        };
        let Some((space_sym, space_span)) = space else {
            return Some(value);
        };
        let space_text = self.name(space_sym).to_string();
        if !(to.is_triple() || to == BaseType::Matrix) {
            self.error(Code::BadTypecast, space_span, format!("a `{to}` has no coordinate or colour space"))
                .with_label("space not allowed here");
            return None;
        }
        if to == BaseType::Color && !COLOR_SPACES.contains(&space_text.as_str()) {
            let mut d =
                Diagnostic::new(Code::UnknownColorSpace, space_span, format!("unknown colour space \"{space_text}\""))
                    .with_label("not a colour space")
                    .with_note(format!("colour spaces are: {}", COLOR_SPACES.join(", ")));
            if let Some(best) = closest(&space_text, COLOR_SPACES.iter().copied()) {
                d = d.with_note(format!("did you mean \"{best}\"?"));
            }
            self.diags.push(d);
            return None;
        }
        if to == BaseType::Color && space_text == "rgb" {
            return Some(value);
        }
        let space_id = self.add_expr(ExprKind::Const(Constant::String(space_text)), Type::STRING, space_span);
        Some(self.add_expr(ExprKind::SpaceCast { space: space_id, arg: value }, Type::scalar(to), span))
    }

    fn unary(&mut self, op: ast::UnaryOp, arg: &ast::Expr, span: Span, expected: Option<BaseType>) -> Option<ExprId> {
        match op {
            ast::UnaryOp::Neg => {
                let id = self.expr(arg, expected)?;
                let ty = self.expr_ty(id);
                let id = if ty == Type::BOOL { self.convert_node(id, BaseType::Float) } else { id };
                let ty = self.expr_ty(id);
                if ty.is_array() || !(ty.base.is_numeric() || ty.base == BaseType::Matrix) {
                    self.error(Code::UnaryOperandType, span, format!("cannot negate a `{ty}`"))
                        .with_label("not a number");
                    return None;
                }
                Some(self.add_expr(ExprKind::Unary { op: ir::UnaryOp::Neg, arg: id }, ty, span))
            }
            ast::UnaryOp::Not => {
                let id = self.expr(arg, None)?;
                let ty = self.expr_ty(id);
                if !matches!(ty, Type { base: BaseType::Bool | BaseType::Float, array: None }) {
                    self.error(Code::UnaryOperandType, span, format!("`!` needs a relation, not a `{ty}`"))
                        .with_label("not a condition");
                    return None;
                }
                let b = self.as_condition(id, arg.span)?;
                Some(self.add_expr(ExprKind::Unary { op: ir::UnaryOp::Not, arg: b }, Type::BOOL, span))
            }
        }
    }

    /// Lowers both operands; an untyped triple `(a, b, c)` takes the type of the other side.
    fn operands(&mut self, l: &ast::Expr, r: &ast::Expr, expected: Option<BaseType>) -> Option<(ExprId, ExprId)> {
        let l_tuple = matches!(l.kind, ast::ExprKind::Tuple(_));
        let r_tuple = matches!(r.kind, ast::ExprKind::Tuple(_));
        if l_tuple && !r_tuple {
            let rid = self.expr(r, expected);
            let hint = rid.map(|id| self.expr_ty(id).base).filter(|b| b.is_triple()).or(expected);
            let lid = self.expr(l, hint);
            return Some((lid?, rid?));
        }
        let lid = self.expr(l, expected);
        let hint =
            if r_tuple { lid.map(|id| self.expr_ty(id).base).filter(|b| b.is_triple()).or(expected) } else { expected };
        let rid = self.expr(r, hint);
        Some((lid?, rid?))
    }

    fn binary(
        &mut self,
        op: ast::BinaryOp,
        l: &ast::Expr,
        r: &ast::Expr,
        span: Span,
        expected: Option<BaseType>,
    ) -> Option<ExprId> {
        use ast::BinaryOp as B;
        let operand_expected = match op {
            B::Add | B::Sub | B::Mul | B::Div | B::Cross => expected,
            _ => None,
        };
        let (lid, rid) = self.operands(l, r, operand_expected)?;
        self.binary_ids(op, lid, rid, span)
    }

    /// Types a binary operation on lowered operands.
    pub(super) fn binary_ids(&mut self, op: ast::BinaryOp, lid: ExprId, rid: ExprId, span: Span) -> Option<ExprId> {
        use ast::BinaryOp as B;
        let (lt, rt) = (self.expr_ty(lid), self.expr_ty(rid));
        let bad = |this: &mut Self| {
            this.error(
                Code::BinaryOperandTypes,
                span,
                format!("operator `{}` cannot be applied to `{lt}` and `{rt}`", op.spelling()),
            )
            .with_label(&format!("`{lt}` {} `{rt}`", op.spelling()));
            None
        };
        if lt.is_array() || rt.is_array() || lt.base == BaseType::Void || rt.base == BaseType::Void {
            if lt.base == BaseType::Void || rt.base == BaseType::Void {
                self.error(Code::VoidValue, span, "a `void` function's result used as an operand")
                    .with_label("no value");
                return None;
            }
            return bad(self);
        }
        let (lb, rb) = (lt.base, rt.base);
        let ir_op = match op {
            B::Add => ir::BinaryOp::Add,
            B::Sub => ir::BinaryOp::Sub,
            B::Mul => ir::BinaryOp::Mul,
            B::Div => ir::BinaryOp::Div,
            B::Cross => ir::BinaryOp::Cross,
            B::Dot => ir::BinaryOp::Dot,
            B::Lt => ir::BinaryOp::Lt,
            B::Gt => ir::BinaryOp::Gt,
            B::Le => ir::BinaryOp::Le,
            B::Ge => ir::BinaryOp::Ge,
            B::Eq => ir::BinaryOp::Eq,
            B::Ne => ir::BinaryOp::Ne,
            B::And => ir::BinaryOp::And,
            B::Or => ir::BinaryOp::Or,
        };
        match op {
            B::And | B::Or => {
                let ok = |b: BaseType| matches!(b, BaseType::Bool | BaseType::Float);
                if !ok(lb) || !ok(rb) {
                    return bad(self);
                }
                let l = self.as_condition(lid, span)?;
                let r = self.as_condition(rid, span)?;
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: l, rhs: r }, Type::BOOL, span))
            }
            B::Lt | B::Gt | B::Le | B::Ge => {
                let ok = |b: BaseType| matches!(b, BaseType::Bool | BaseType::Float);
                if !ok(lb) || !ok(rb) {
                    return bad(self);
                }
                let l = self.convert_node(lid, BaseType::Float);
                let r = self.convert_node(rid, BaseType::Float);
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: l, rhs: r }, Type::BOOL, span))
            }
            B::Eq | B::Ne => {
                let common = if lb == rb {
                    lb
                } else if let Some(c) = arithmetic_type(lb, rb) {
                    c
                } else {
                    return bad(self);
                };
                let l = self.convert_node(lid, common);
                let r = self.convert_node(rid, common);
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: l, rhs: r }, Type::BOOL, span))
            }
            B::Dot => {
                if !(lb.is_triple() && rb.is_triple()) || (lb == BaseType::Color) != (rb == BaseType::Color) {
                    return bad(self);
                }
                let r = self.convert_node(rid, lb);
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: lid, rhs: r }, Type::FLOAT, span))
            }
            B::Cross => {
                if !(lb.is_triple() && rb.is_triple()) || (lb == BaseType::Color) != (rb == BaseType::Color) {
                    return bad(self);
                }
                let result = if lb == BaseType::Color { BaseType::Color } else { BaseType::Vector };
                let l = self.convert_node(lid, result);
                let r = self.convert_node(rid, result);
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: l, rhs: r }, Type::scalar(result), span))
            }
            B::Add | B::Sub | B::Mul | B::Div => {
                let lb = if lb == BaseType::Bool { BaseType::Float } else { lb };
                let rb = if rb == BaseType::Bool { BaseType::Float } else { rb };
                let Some(common) = arithmetic_type(lb, rb) else {
                    return bad(self);
                };
                if common == BaseType::String {
                    return bad(self);
                }
                // RSL: point - point is a vector; point + vector is a point.
                let result = match (op, lb, rb) {
                    (B::Sub, BaseType::Point, BaseType::Point) => BaseType::Vector,
                    _ => common,
                };
                let l = self.convert_node(lid, common);
                let r = self.convert_node(rid, common);
                Some(self.add_expr(ExprKind::Binary { op: ir_op, lhs: l, rhs: r }, Type::scalar(result), span))
            }
        }
    }

    fn ternary(
        &mut self,
        c: &ast::Expr,
        a: &ast::Expr,
        b: &ast::Expr,
        span: Span,
        expected: Option<BaseType>,
    ) -> Option<ExprId> {
        let cond = self.condition(c);
        let (aid, bid) = self.operands(a, b, expected)?;
        let cond = cond?;
        let (at, bt) = (self.expr_ty(aid), self.expr_ty(bid));
        let common = if at == bt {
            at
        } else if !at.is_array() && !bt.is_array() {
            match arithmetic_type(at.base, bt.base) {
                Some(c) => Type::scalar(c),
                None => {
                    self.error(
                        Code::BinaryOperandTypes,
                        span,
                        format!("the two results of `?:` have different types: `{at}` and `{bt}`"),
                    )
                    .with_label("types differ");
                    return None;
                }
            }
        } else {
            self.error(
                Code::BinaryOperandTypes,
                span,
                format!("the two results of `?:` have different types: `{at}` and `{bt}`"),
            )
            .with_label("types differ");
            return None;
        };
        let a = self.convert_node(aid, common.base);
        let b = self.convert_node(bid, common.base);
        Some(self.add_expr(ExprKind::Select { cond, a, b }, common, span))
    }

    /// An assignable place: a variable, a writable global, an array element or a component.
    /// `mark_read` also counts it as read (compound assignment).
    pub(super) fn place_of(&mut self, e: &ast::Expr, mark_read: bool, output_arg: bool) -> Option<Place> {
        let code = if output_arg { Code::OutputArgument } else { Code::NotAssignable };
        match &e.kind {
            ast::ExprKind::Ident(sym) => {
                let binding = match self.lookup_var(*sym) {
                    Some(b) => Some(b),
                    None => Global::lookup(self.name(*sym)).map(Binding::Global),
                };
                match binding {
                    Some(Binding::Var(v)) => {
                        if mark_read {
                            self.b().used[v.0 as usize] = true;
                        }
                        let ty = self.cur().func.var(v).ty;
                        Some(Place { base: PlaceBase::Var(v), index: None, component: None, ty })
                    }
                    Some(Binding::Global(g)) => {
                        let def = g.def();
                        let access = self.kind.map(|k| def.access(k)).unwrap_or(Access::Write);
                        match access {
                            Access::Write => Some(Place {
                                base: PlaceBase::Global(g),
                                index: None,
                                component: None,
                                ty: Type::scalar(def.ty),
                            }),
                            Access::Read | Access::None
                                if self.kind.is_some_and(|k| self.vendor_global(k, def.name, Access::Write, e.span)) =>
                            {
                                Some(Place {
                                    base: PlaceBase::Global(g),
                                    index: None,
                                    component: None,
                                    ty: Type::scalar(def.ty),
                                })
                            }
                            Access::Read => {
                                let kind = self.kind.map(|k| k.name()).unwrap_or("");
                                self.error(code, e.span, format!("`{}` is read-only in {kind} shaders", def.name))
                                    .with_label("cannot be written")
                                    .notes
                                    .push(format!("`{}` is the {}", def.name, def.doc));
                                None
                            }
                            Access::None => {
                                let kind = self.kind.map(|k| k.name()).unwrap_or("");
                                let owner = self.current_function();
                                self.context_error(
                                    owner,
                                    Code::UndefinedVariable,
                                    e.span,
                                    format!("`{}` is not available in {kind} shaders", def.name),
                                )
                                .with_label("not a global of this shader type");
                                None
                            }
                        }
                    }
                    None => {
                        let text = self.name(*sym).to_string();
                        self.undefined_name(&text, e.span);
                        None
                    }
                }
            }
            ast::ExprKind::Index(base, index) => {
                let mut place = self.place_of(base, mark_read, output_arg)?;
                let i = self.expr(index, Some(BaseType::Float))?;
                let ity = self.expr_ty(i);
                if ity != Type::FLOAT {
                    self.error(Code::BadIndex, index.span, format!("an index must be a float, not a `{ity}`"))
                        .with_label("not a number");
                    return None;
                }
                if place.index.is_none() && place.ty.is_array() {
                    place.index = Some(i);
                    place.ty = place.ty.element();
                } else if place.component.is_none() && place.ty.base.is_triple() && !place.ty.is_array() {
                    if place.index.is_none() {
                        place.index = Some(i);
                    } else {
                        place.component = Some(i);
                    }
                    place.ty = Type::FLOAT;
                } else {
                    let ty = place.ty;
                    self.error(Code::BadIndex, base.span, format!("a `{ty}` cannot be indexed"))
                        .with_label("not an array or triple");
                    return None;
                }
                Some(place)
            }
            _ => {
                let what =
                    if output_arg { "an `output` argument must be a variable" } else { "this cannot be assigned to" };
                self.error(code, e.span, what).with_label("not a variable").notes.push(if output_arg {
                    "the function writes its result through this argument, so pass a variable".to_string()
                } else {
                    "only variables, array elements and writable globals can be assigned".to_string()
                });
                None
            }
        }
    }

    /// An output argument or gather output.
    pub(super) fn place(&mut self, e: &ast::Expr, output_arg: bool) -> Option<Place> {
        self.place_of(e, false, output_arg)
    }

    fn assign(&mut self, op: AssignOp, target: &ast::Expr, value: &ast::Expr, span: Span) -> Option<ExprId> {
        let place = self.place_of(target, op != AssignOp::Assign, false);
        let expected = place.as_ref().map(|p| p.ty.base);
        let v = self.expr(value, expected);
        let (place, v) = (place?, v?);
        let op = op.binary().map(|b| match b {
            ast::BinaryOp::Add => ir::BinaryOp::Add,
            ast::BinaryOp::Sub => ir::BinaryOp::Sub,
            ast::BinaryOp::Mul => ir::BinaryOp::Mul,
            _ => ir::BinaryOp::Div,
        });
        if op.is_some() && (place.ty.is_array() || !(place.ty.base.is_numeric() || place.ty.base == BaseType::Matrix)) {
            let ty = place.ty;
            self.error(
                Code::BinaryOperandTypes,
                span,
                format!("compound assignment needs a number, triple or matrix, not a `{ty}`"),
            )
            .with_label("cannot be updated arithmetically");
            return None;
        }
        let value = self.coerce(v, place.ty, value.span, Code::AssignTypeMismatch, "assigned value")?;
        let ty = place.ty;
        Some(self.add_expr(ExprKind::Assign { place, op, value }, ty, span))
    }

    fn inc_dec(&mut self, increment: bool, prefix: bool, target: &ast::Expr, span: Span) -> Option<ExprId> {
        let place = self.place_of(target, true, false)?;
        if place.ty != Type::FLOAT {
            let ty = place.ty;
            self.error(Code::UnaryOperandType, span, format!("`++`/`--` need a float variable, not a `{ty}`"))
                .with_label("not a float");
            return None;
        }
        let one = self.add_expr(ExprKind::Const(Constant::Float(1.0)), Type::FLOAT, span);
        let op = if increment { ir::BinaryOp::Add } else { ir::BinaryOp::Sub };
        let assign = self.add_expr(ExprKind::Assign { place, op: Some(op), value: one }, Type::FLOAT, span);
        if prefix {
            return Some(assign);
        }
        // The postfix form's value is the value before the update.
        let one = self.add_expr(ExprKind::Const(Constant::Float(1.0)), Type::FLOAT, span);
        let back = if increment { ir::BinaryOp::Sub } else { ir::BinaryOp::Add };
        Some(self.add_expr(ExprKind::Binary { op: back, lhs: assign, rhs: one }, Type::FLOAT, span))
    }
}

/// The common type of an arithmetic operation on `a` and `b`, if they mix.
pub(super) fn arithmetic_type(a: BaseType, b: BaseType) -> Option<BaseType> {
    use BaseType::*;
    if a == b {
        return Some(a);
    }
    match (a, b) {
        (Float | Bool, Float | Bool) => Some(Float),
        (Float | Bool, t) | (t, Float | Bool) if t.is_triple() || t == Matrix => Some(t),
        (x, y) if x.is_pointlike() && y.is_pointlike() => Some(if x == Point || y == Point { Point } else { Vector }),
        _ => None,
    }
}

/// The candidate closest to `name` by edit distance, if close enough to be a likely typo.
pub(super) fn closest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<String> {
    let limit = (name.len() / 3).max(1);
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        if c == name {
            continue;
        }
        let d = edit_distance(&name.to_lowercase(), &c.to_lowercase());
        if d <= limit && best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c.to_string())
}

fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        cur[0] = i;
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            cur[j] = (prev[j] + 1).min(cur[j - 1] + 1).min(prev[j - 1] + cost);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

//! Implicit conversions, as RSL allows them.
//!
//! - float to any triple (all components) or matrix (the diagonal): always;
//! - among point, vector and normal: always (they share a representation);
//! - a relation to float (0 or 1): always;
//! - colour to point-like or back: with warning W0009 (RSL asks for a typecast);
//! - a triple to float: with warning W0003 (the first component is kept);
//! - arrays: only to arrays of the same element type and length (or to an unsized parameter).
//!
//! Everything else is an error with the code the caller chooses.

use super::{Checker, WithLabel};
use crate::diagnostic::{Code, Diagnostic};
use crate::ir::{ArrayLen, BaseType, ExprId, ExprKind, Type};
use crate::source::Span;

/// How a value of one type reaches another, and at what cost (for overload resolution).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Conversion {
    Exact,
    /// Between point, vector and normal.
    Pointlike,
    /// Float to triple or matrix, or relation to float.
    Promote,
    /// Colour to/from point-like: allowed with a warning.
    ColorPointlike,
    /// Triple to float: allowed with a warning.
    Narrow,
}

impl Conversion {
    pub(super) fn cost(self) -> u32 {
        match self {
            Conversion::Exact => 0,
            Conversion::Pointlike => 1,
            Conversion::Promote => 2,
            Conversion::ColorPointlike => 8,
            Conversion::Narrow => 8,
        }
    }
}

/// How `from` converts to `to` implicitly, if it does (ignoring arrays).
pub(super) fn conversion(from: BaseType, to: BaseType) -> Option<Conversion> {
    use BaseType::*;
    if from == to {
        return Some(Conversion::Exact);
    }
    match (from, to) {
        (a, b) if a.is_pointlike() && b.is_pointlike() => Some(Conversion::Pointlike),
        (Float, b) if b.is_triple() || b == Matrix => Some(Conversion::Promote),
        (Bool, Float) => Some(Conversion::Promote),
        (Color, b) if b.is_pointlike() => Some(Conversion::ColorPointlike),
        (a, Color) if a.is_pointlike() => Some(Conversion::ColorPointlike),
        (a, Float) if a.is_triple() => Some(Conversion::Narrow),
        _ => None,
    }
}

/// Whether an argument of type `from` may be passed where `to` is expected, counting arrays.
pub(super) fn array_compatible(from: Type, to: Type) -> bool {
    match (from.array, to.array) {
        (None, None) => true,
        (Some(_), Some(ArrayLen::Unsized)) => true,
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

impl Checker<'_> {
    pub(super) fn add_expr(&mut self, kind: ExprKind, ty: Type, span: Span) -> ExprId {
        let f = &mut self.b().func;
        let id = ExprId(f.exprs.len() as u32);
        f.exprs.push(crate::ir::Expr { kind, ty, varying: false, span });
        id
    }

    pub(super) fn expr_ty(&self, id: ExprId) -> Type {
        self.cur().func.expr(id).ty
    }

    /// Wraps `id` in a conversion node to `to` (no checks).
    pub(super) fn convert_node(&mut self, id: ExprId, to: BaseType) -> ExprId {
        let e = self.cur().func.expr(id);
        if e.ty.base == to {
            return id;
        }
        let span = e.span;
        let ty = Type { base: to, array: e.ty.array };
        self.add_expr(ExprKind::Convert { arg: id }, ty, span)
    }

    /// Converts `id` to `to` as an assignment or argument would, reporting problems with `code`.
    pub(super) fn coerce(&mut self, id: ExprId, to: Type, span: Span, code: Code, what: &str) -> Option<ExprId> {
        let from = self.expr_ty(id);
        if from.base == BaseType::Void {
            self.error(Code::VoidValue, span, format!("a `void` function's result used as the {what}"))
                .with_label("this has no value");
            return None;
        }
        if from.is_array() || to.is_array() {
            if from.base == to.base && array_compatible(from, to) {
                return Some(id);
            }
            let code = if from.is_array() && to.is_array() { Code::ArrayMismatch } else { code };
            self.error(code, span, format!("the {what} must be a `{to}`, not a `{from}`"))
                .with_label(&format!("this is a `{from}`"));
            return None;
        }
        match conversion(from.base, to.base) {
            Some(Conversion::Exact) => Some(id),
            Some(Conversion::Pointlike | Conversion::Promote) => Some(self.convert_node(id, to.base)),
            Some(Conversion::ColorPointlike) => {
                self.diags.push(
                    Diagnostic::new(
                        Code::ImplicitColorConversion,
                        span,
                        format!("implicit conversion from `{from}` to `{to}`"),
                    )
                    .with_label("converted here")
                    .with_note(format!("write a typecast to make it explicit: `{} (...)`", to.base)),
                );
                Some(self.convert_node(id, to.base))
            }
            Some(Conversion::Narrow) => {
                self.diags.push(
                    Diagnostic::new(
                        Code::ImplicitNarrowing,
                        span,
                        format!("implicit narrowing from `{from}` to `float` keeps only the first component"),
                    )
                    .with_label("narrowed here")
                    .with_note("use `comp(x, 0)`, `xcomp(x)` or an average to say which value you mean"),
                );
                Some(self.convert_node(id, to.base))
            }
            None => {
                self.error(code, span, format!("the {what} must be a `{to}`, not a `{from}`"))
                    .with_label(&format!("this is a `{from}`"));
                None
            }
        }
    }
}

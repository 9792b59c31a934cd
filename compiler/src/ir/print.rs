//! The IR's text form, for golden tests and bug reports (`rtsl compile --emit-ir`).
//!
//! One block per function: its signature, its variables (id, name, type, storage, kind), then its
//! statements as an indented tree. Expressions print inline: `%name.id` is a variable, `$P` a shader
//! global, `noise.2(...)` a built-in with its overload index, `@f(...)` a user function, `&x` an
//! output argument, `convert<vector>(...)` an implicit conversion. A `'` after an expression marks it
//! varying.

use super::{Arg, Block, Constant, ExprId, ExprKind, Function, Module, Place, PlaceBase, StmtKind, UnaryOp, VarKind};
use std::fmt::Write as _;

/// Prints a whole module.
pub fn module(m: &Module) -> String {
    let mut out = String::new();
    if let Some(s) = &m.shader {
        let _ = writeln!(out, "shader {} {} = fn{}", s.kind.name(), s.name, s.body.0);
        for p in &s.params {
            let body = m.function(s.body);
            let _ = writeln!(
                out,
                "  param {}{} {} {} = {}",
                if p.output { "output " } else { "" },
                if p.varying { "varying" } else { "uniform" },
                p.ty,
                p.name,
                expr(m, body, p.default)
            );
        }
    }
    for (i, f) in m.functions.iter().enumerate() {
        out.push('\n');
        function(&mut out, m, i, f);
    }
    out
}

fn function(out: &mut String, m: &Module, index: usize, f: &Function) {
    let params: Vec<String> = f.params.iter().map(|p| var_name(f, *p)).collect();
    let _ = writeln!(
        out,
        "fn{index} {}({}) -> {}{}",
        f.name,
        params.join(", "),
        f.return_type,
        if f.reads_varying { " reads-varying" } else { "" }
    );
    for (i, v) in f.vars.iter().enumerate() {
        let kind = match v.kind {
            VarKind::Local => "local".to_string(),
            VarKind::Param { output } => format!("param{}", if output { " output" } else { "" }),
            VarKind::ShaderParam { index, output } => {
                format!("shader-param {index}{}", if output { " output" } else { "" })
            }
            VarKind::Capture => "capture".to_string(),
        };
        let declared = match v.declared {
            Some(true) => " (declared varying)",
            Some(false) => " (declared uniform)",
            None => "",
        };
        let _ = writeln!(
            out,
            "  var %{}.{i}: {} {} {kind}{declared}",
            v.name,
            if v.varying { "varying" } else { "uniform" },
            v.ty
        );
    }
    block(out, m, f, &f.body, 1);
}

fn indent(out: &mut String, depth: usize) {
    for _ in 0..depth {
        out.push_str("  ");
    }
}

fn block(out: &mut String, m: &Module, f: &Function, b: &Block, depth: usize) {
    indent(out, depth);
    out.push_str("{\n");
    for s in &b.stmts {
        indent(out, depth + 1);
        match &s.kind {
            StmtKind::Expr(e) => {
                let _ = writeln!(out, "{};", expr(m, f, *e));
            }
            StmtKind::If { cond, then, otherwise } => {
                let _ = writeln!(out, "if {}", expr(m, f, *cond));
                block(out, m, f, then, depth + 1);
                if !otherwise.stmts.is_empty() {
                    indent(out, depth + 1);
                    out.push_str("else\n");
                    block(out, m, f, otherwise, depth + 1);
                }
            }
            StmtKind::Loop { cond, body, step } => {
                let c = cond.map(|c| expr(m, f, c)).unwrap_or_else(|| "true".into());
                let _ = writeln!(out, "loop while {c}");
                block(out, m, f, body, depth + 1);
                if !step.stmts.is_empty() {
                    indent(out, depth + 1);
                    out.push_str("step\n");
                    block(out, m, f, step, depth + 1);
                }
            }
            StmtKind::Break(n) => {
                let _ = writeln!(out, "break {n};");
            }
            StmtKind::Continue(n) => {
                let _ = writeln!(out, "continue {n};");
            }
            StmtKind::Return(v) => {
                let v = v.map(|v| format!(" {}", expr(m, f, v))).unwrap_or_default();
                let _ = writeln!(out, "return{v};");
            }
            StmtKind::Illuminance { category, position, cone, body } => {
                let mut args = Vec::new();
                args.extend(category.map(|c| expr(m, f, c)));
                args.push(expr(m, f, *position));
                if let Some((a, b)) = cone {
                    args.push(expr(m, f, *a));
                    args.push(expr(m, f, *b));
                }
                let _ = writeln!(out, "illuminance({})", args.join(", "));
                block(out, m, f, body, depth + 1);
            }
            StmtKind::Illuminate { position, cone, body } => {
                let mut args = vec![expr(m, f, *position)];
                if let Some((a, b)) = cone {
                    args.push(expr(m, f, *a));
                    args.push(expr(m, f, *b));
                }
                let _ = writeln!(out, "illuminate({})", args.join(", "));
                block(out, m, f, body, depth + 1);
            }
            StmtKind::Solar { cone, body } => {
                let args = cone.map(|(a, b)| format!("{}, {}", expr(m, f, a), expr(m, f, b))).unwrap_or_default();
                let _ = writeln!(out, "solar({args})");
                block(out, m, f, body, depth + 1);
            }
            StmtKind::Gather { category, position, direction, angle, samples, params, body, otherwise } => {
                let mut args: Vec<String> =
                    [category, position, direction, angle, samples].iter().map(|e| expr(m, f, **e)).collect();
                for (name, a) in params {
                    args.push(expr(m, f, *name));
                    args.push(arg(m, f, a));
                }
                let _ = writeln!(out, "gather({})", args.join(", "));
                block(out, m, f, body, depth + 1);
                if !otherwise.stmts.is_empty() {
                    indent(out, depth + 1);
                    out.push_str("else\n");
                    block(out, m, f, otherwise, depth + 1);
                }
            }
        }
    }
    indent(out, depth);
    out.push_str("}\n");
}

fn var_name(f: &Function, v: super::VarId) -> String {
    format!("%{}.{}", f.var(v).name, v.0)
}

fn place(m: &Module, f: &Function, p: &Place) -> String {
    let mut s = match p.base {
        PlaceBase::Var(v) => var_name(f, v),
        PlaceBase::Global(g) => format!("${}", g.def().name),
    };
    for i in [p.index, p.component].into_iter().flatten() {
        let _ = write!(s, "[{}]", expr(m, f, i));
    }
    s
}

fn arg(m: &Module, f: &Function, a: &Arg) -> String {
    match a {
        Arg::Value(e) => expr(m, f, *e),
        Arg::Ref(p) => format!("&{}", place(m, f, p)),
    }
}

fn list(m: &Module, f: &Function, ids: &[ExprId]) -> String {
    ids.iter().map(|e| expr(m, f, *e)).collect::<Vec<_>>().join(", ")
}

/// One expression, inline.
pub fn expr(m: &Module, f: &Function, id: ExprId) -> String {
    let e = f.expr(id);
    let text = match &e.kind {
        ExprKind::Const(Constant::Float(v)) => format!("{v:?}"),
        ExprKind::Const(Constant::String(s)) => format!("\"{}\"", crate::front::lex::escape(s)),
        ExprKind::Var(v) => var_name(f, *v),
        ExprKind::Global(g) => format!("${}", g.def().name),
        ExprKind::Index { base, index } => format!("{}[{}]", expr(m, f, *base), expr(m, f, *index)),
        ExprKind::Unary { op: UnaryOp::Neg, arg } => format!("(-{})", expr(m, f, *arg)),
        ExprKind::Unary { op: UnaryOp::Not, arg } => format!("(!{})", expr(m, f, *arg)),
        ExprKind::Binary { op, lhs, rhs } => format!("({} {} {})", expr(m, f, *lhs), binary(*op), expr(m, f, *rhs)),
        ExprKind::Convert { arg } => format!("convert<{}>({})", e.ty, expr(m, f, *arg)),
        ExprKind::Construct { args } => format!("{}({})", e.ty, list(m, f, args)),
        ExprKind::SpaceCast { space, arg } => {
            format!("spacecast<{}>({}, {})", e.ty, expr(m, f, *space), expr(m, f, *arg))
        }
        ExprKind::Select { cond, a, b } => format!("({} ? {} : {})", expr(m, f, *cond), expr(m, f, *a), expr(m, f, *b)),
        ExprKind::CallBuiltin { builtin, overload, args } => {
            let args: Vec<String> = args.iter().map(|a| arg(m, f, a)).collect();
            format!("{}.{}({})", builtin.name(), overload, args.join(", "))
        }
        ExprKind::Call { func, args } => {
            let args: Vec<String> = args.iter().map(|a| arg(m, f, a)).collect();
            format!("@{}({})", m.function(*func).name, args.join(", "))
        }
        ExprKind::Assign { place: p, op, value } => {
            let op = op.map(|o| format!("{}=", binary(o))).unwrap_or_else(|| "=".into());
            format!("({} {op} {})", place(m, f, p), expr(m, f, *value))
        }
        ExprKind::ArrayLiteral { elements } => format!("{{{}}}", list(m, f, elements)),
    };
    if e.varying {
        format!("{text}'")
    } else {
        text
    }
}

fn binary(op: super::BinaryOp) -> &'static str {
    use super::BinaryOp::*;
    match op {
        Add => "+",
        Sub => "-",
        Mul => "*",
        Div => "/",
        Cross => "^",
        Dot => ".",
        Lt => "<",
        Gt => ">",
        Le => "<=",
        Ge => ">=",
        Eq => "==",
        Ne => "!=",
        And => "&&",
        Or => "||",
    }
}

//! A shader's interface: its type, name and parameters with their default values, as `rtsl info`
//! shows them and as the runtime binds them.
//!
//! Defaults are evaluated at compile time when they are constant (numbers, triples, matrices,
//! strings, arrays of those, arithmetic on them, `radians()` and the like). A default that names a
//! coordinate system (`point "shader" (0,0,0)`) keeps the space name: it is transformed when the shader
//! is bound. Other defaults (those calling renderer services) are shown as source text.

use crate::builtins::Builtin;
/// The base types of parameters, as an interface states them.
pub use crate::ir::BaseType;
/// The shader types, as an interface states them.
pub use crate::ir::ShaderKind;
use crate::ir::{self, Constant, ExprId, ExprKind, Function, Module, Type};
use crate::source::SourceMap;
use serde::Serialize;

/// A constant value.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    Float(f32),
    Triple(Triple),
    Matrix(MatrixValue),
    String(String),
    Array(Vec<Value>),
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Triple {
    pub value: [f32; 3],
    /// The space the value was written in, if not the current one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub space: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MatrixValue {
    pub value: [f32; 16],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub space: Option<String>,
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Float(v) => write!(f, "{}", fmt_float(*v)),
            Value::Triple(t) => {
                if let Some(s) = &t.space {
                    write!(f, "\"{s}\" ")?;
                }
                write!(f, "[{} {} {}]", fmt_float(t.value[0]), fmt_float(t.value[1]), fmt_float(t.value[2]))
            }
            Value::Matrix(m) => {
                if let Some(s) = &m.space {
                    write!(f, "\"{s}\" ")?;
                }
                let parts: Vec<String> = m.value.iter().map(|v| fmt_float(*v)).collect();
                write!(f, "[{}]", parts.join(" "))
            }
            Value::String(s) => write!(f, "\"{}\"", crate::front::lex::escape(s)),
            Value::Array(items) => {
                let parts: Vec<String> = items.iter().map(|v| v.to_string()).collect();
                write!(f, "{{{}}}", parts.join(", "))
            }
        }
    }
}

fn fmt_float(v: f32) -> String {
    if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{}", v as i64)
    } else {
        format!("{v}")
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct ParamInfo {
    pub name: String,
    /// `uniform` or `varying`.
    pub storage: &'static str,
    #[serde(rename = "type")]
    pub base: BaseType,
    /// The array length, for array parameters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub array_length: Option<u32>,
    pub output: bool,
    /// The default, when it is a constant.
    pub default: Option<Value>,
    /// The default as written in the source.
    pub default_source: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct ShaderInterface {
    #[serde(rename = "type")]
    pub kind: ShaderKind,
    pub name: String,
    pub parameters: Vec<ParamInfo>,
}

impl ShaderInterface {
    pub fn from_module(module: &Module, sources: &SourceMap) -> Option<ShaderInterface> {
        let shader = module.shader.as_ref()?;
        let body = module.function(shader.body);
        let parameters = shader
            .params
            .iter()
            .map(|p| {
                let span = body.expr(p.default).span;
                ParamInfo {
                    name: p.name.clone(),
                    storage: if p.varying { "varying" } else { "uniform" },
                    base: p.ty.base,
                    array_length: p.ty.array_len(),
                    output: p.output,
                    default: eval(body, p.default),
                    default_source: sources.text(span).to_string(),
                }
            })
            .collect();
        Some(ShaderInterface { kind: shader.kind, name: shader.name.clone(), parameters })
    }
}

/// Evaluates a constant expression of a function, if it is one.
pub fn eval(f: &Function, id: ExprId) -> Option<Value> {
    let e = f.expr(id);
    match &e.kind {
        ExprKind::Const(Constant::Float(v)) => Some(Value::Float(*v)),
        ExprKind::Const(Constant::String(s)) => Some(Value::String(s.clone())),
        ExprKind::Construct { args } => {
            let vals: Option<Vec<f32>> = args.iter().map(|a| as_float(&eval(f, *a)?)).collect();
            let vals = vals?;
            if e.ty.base == BaseType::Matrix {
                let mut m = [0.0; 16];
                m.copy_from_slice(vals.get(..16)?);
                Some(Value::Matrix(MatrixValue { value: m, space: None }))
            } else {
                Some(Value::Triple(Triple { value: [vals[0], vals[1], vals[2]], space: None }))
            }
        }
        ExprKind::Convert { arg } => convert(eval(f, *arg)?, e.ty),
        ExprKind::SpaceCast { space, arg } => {
            let Some(Value::String(space)) = eval(f, *space) else { return None };
            match eval(f, *arg)? {
                Value::Triple(mut t) => {
                    t.space = Some(space);
                    Some(Value::Triple(t))
                }
                Value::Matrix(mut m) => {
                    m.space = Some(space);
                    Some(Value::Matrix(m))
                }
                _ => None,
            }
        }
        ExprKind::Unary { op: ir::UnaryOp::Neg, arg } => map(eval(f, *arg)?, |v| -v),
        ExprKind::Binary { op, lhs, rhs } => {
            let (a, b) = (eval(f, *lhs)?, eval(f, *rhs)?);
            let op: fn(f32, f32) -> f32 = match op {
                ir::BinaryOp::Add => |a, b| a + b,
                ir::BinaryOp::Sub => |a, b| a - b,
                ir::BinaryOp::Mul if e.ty.base != BaseType::Matrix => |a, b| a * b,
                ir::BinaryOp::Div if e.ty.base != BaseType::Matrix => |a, b| a / b,
                _ => return None,
            };
            zip(a, b, op)
        }
        ExprKind::ArrayLiteral { elements } => {
            let vals: Option<Vec<Value>> = elements.iter().map(|a| eval(f, *a)).collect();
            Some(Value::Array(vals?))
        }
        ExprKind::CallBuiltin { builtin, args, .. } => {
            let ir::Arg::Value(a) = args.first()? else { return None };
            let x = eval(f, *a)?;
            let g: fn(f32) -> f32 = match builtin {
                Builtin::Radians => f32::to_radians,
                Builtin::Degrees => f32::to_degrees,
                Builtin::Sqrt => f32::sqrt,
                Builtin::Cos => f32::cos,
                Builtin::Sin => f32::sin,
                Builtin::Abs => f32::abs,
                _ => return None,
            };
            if args.len() != 1 {
                return None;
            }
            map(x, g)
        }
        _ => None,
    }
}

fn as_float(v: &Value) -> Option<f32> {
    match v {
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

fn convert(v: Value, to: Type) -> Option<Value> {
    match (v, to.base) {
        (Value::Float(x), b) if b.is_triple() => Some(Value::Triple(Triple { value: [x; 3], space: None })),
        (Value::Float(x), BaseType::Matrix) => {
            let mut m = [0.0; 16];
            for i in 0..4 {
                m[i * 5] = x;
            }
            Some(Value::Matrix(MatrixValue { value: m, space: None }))
        }
        (Value::Triple(t), b) if b.is_triple() => Some(Value::Triple(t)),
        (Value::Triple(t), BaseType::Float) => Some(Value::Float(t.value[0])),
        (v @ Value::Float(_), BaseType::Float) => Some(v),
        _ => None,
    }
}

fn map(v: Value, g: fn(f32) -> f32) -> Option<Value> {
    match v {
        Value::Float(x) => Some(Value::Float(g(x))),
        Value::Triple(t) => Some(Value::Triple(Triple { value: t.value.map(g), space: t.space })),
        Value::Matrix(m) => Some(Value::Matrix(MatrixValue { value: m.value.map(g), space: m.space })),
        _ => None,
    }
}

fn zip(a: Value, b: Value, g: fn(f32, f32) -> f32) -> Option<Value> {
    match (a, b) {
        (Value::Float(x), Value::Float(y)) => Some(Value::Float(g(x, y))),
        (Value::Triple(x), Value::Triple(y)) if x.space.is_none() && y.space.is_none() => Some(Value::Triple(Triple {
            value: [g(x.value[0], y.value[0]), g(x.value[1], y.value[1]), g(x.value[2], y.value[2])],
            space: None,
        })),
        _ => None,
    }
}

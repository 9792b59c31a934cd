//! Values of the reference interpreter: one lane's worth of a typed IR value.

use crate::ir::{BaseType, Type};
use crate::shadeops::{M4, V3};
use std::rc::Rc;

/// A value of one lane.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Float(f32),
    Triple(V3),
    Matrix(M4),
    String(Rc<str>),
    Bool(bool),
    Array(Vec<Value>),
    Void,
}

impl Value {
    /// The zero value of a type (what an uninitialised variable holds).
    pub fn zero(ty: Type) -> Value {
        let scalar = match ty.base {
            BaseType::Float => Value::Float(0.0),
            BaseType::Color | BaseType::Point | BaseType::Vector | BaseType::Normal => Value::Triple([0.0; 3]),
            BaseType::Matrix => Value::Matrix(crate::shadeops::matrix::identity()),
            BaseType::String => Value::String(Rc::from("")),
            BaseType::Bool => Value::Bool(false),
            BaseType::Void => Value::Void,
        };
        match ty.array_len() {
            Some(n) => Value::Array(vec![scalar; n as usize]),
            None => scalar,
        }
    }

    pub fn f(&self) -> f32 {
        match self {
            Value::Float(v) => *v,
            Value::Bool(b) => f32::from(u8::from(*b)),
            Value::Triple(t) => t[0],
            _ => 0.0,
        }
    }

    pub fn v3(&self) -> V3 {
        match self {
            Value::Triple(t) => *t,
            Value::Float(v) => [*v; 3],
            _ => [0.0; 3],
        }
    }

    pub fn m4(&self) -> M4 {
        match self {
            Value::Matrix(m) => *m,
            Value::Float(v) => {
                let mut m = [0.0; 16];
                for i in 0..4 {
                    m[i * 5] = *v;
                }
                m
            }
            _ => crate::shadeops::matrix::identity(),
        }
    }

    pub fn b(&self) -> bool {
        match self {
            Value::Bool(b) => *b,
            Value::Float(v) => *v != 0.0,
            _ => false,
        }
    }

    pub fn s(&self) -> &str {
        match self {
            Value::String(s) => s,
            _ => "",
        }
    }

    pub fn elements(&self) -> &[Value] {
        match self {
            Value::Array(v) => v,
            _ => &[],
        }
    }
}

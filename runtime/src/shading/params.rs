//! Shader parameter values and their binding to a program's parameters, with type checks.
//!
//! Conventions (RenderMan's): point, vector and normal values are given in the space that is
//! current when they are bound and are stored in world space ("current" in rtsl); colours and floats
//! are stored as given. A single float given for a colour or a point is copied to the three
//! components, as RenderMan's typecasts do. Anything else that does not match the declared type is
//! a [`ParamError`], never a silently wrong value. Output parameters may be bound too: the value is
//! their starting value.

use super::program::ShaderProgram;
use glam::{Affine3A, Mat4, Vec3, Vec3A};
use rtsl_compiler::interface::BaseType;

/// A value given for a shader parameter.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ParamValue {
    Float(f32),
    /// A float array (or the components of several floats).
    Floats(Vec<f32>),
    Color([f32; 3]),
    Point([f32; 3]),
    Vector([f32; 3]),
    Normal([f32; 3]),
    /// An array of colours, points, vectors or normals: the element type is the parameter's.
    Triples(Vec<[f32; 3]>),
    /// Row-major, RenderMan's convention (points are row vectors).
    Matrix([f32; 16]),
    String(String),
}

// Conversions for the API's `impl Into<ParamValue>` arguments and the `params!` macro. How a
// triple is stored is decided by the parameter's declaration when it is bound (a point is moved
// to world space, a vector is only turned, a colour is kept), never by the variant chosen here,
// so one variant per Rust type is enough: glam vectors are points, bare arrays colours.

impl From<f32> for ParamValue {
    fn from(x: f32) -> Self {
        ParamValue::Float(x)
    }
}

impl From<[f32; 3]> for ParamValue {
    fn from(c: [f32; 3]) -> Self {
        ParamValue::Color(c)
    }
}

impl From<Vec3> for ParamValue {
    fn from(p: Vec3) -> Self {
        ParamValue::Point(p.to_array())
    }
}

impl From<Vec3A> for ParamValue {
    fn from(p: Vec3A) -> Self {
        ParamValue::Point(p.to_array())
    }
}

impl From<Vec<f32>> for ParamValue {
    fn from(v: Vec<f32>) -> Self {
        ParamValue::Floats(v)
    }
}

impl From<&[f32]> for ParamValue {
    fn from(v: &[f32]) -> Self {
        ParamValue::Floats(v.to_vec())
    }
}

impl From<Vec<[f32; 3]>> for ParamValue {
    fn from(v: Vec<[f32; 3]>) -> Self {
        ParamValue::Triples(v)
    }
}

impl From<Vec<Vec3>> for ParamValue {
    fn from(v: Vec<Vec3>) -> Self {
        ParamValue::Triples(v.iter().map(Vec3::to_array).collect())
    }
}

/// Row-major as RenderMan writes it: glam's column-major array of a column-vector matrix is the
/// same sixteen numbers.
impl From<Mat4> for ParamValue {
    fn from(m: Mat4) -> Self {
        ParamValue::Matrix(m.to_cols_array())
    }
}

impl From<Affine3A> for ParamValue {
    fn from(m: Affine3A) -> Self {
        ParamValue::Matrix(Mat4::from(m).to_cols_array())
    }
}

impl From<&str> for ParamValue {
    fn from(s: &str) -> Self {
        ParamValue::String(s.to_string())
    }
}

impl From<String> for ParamValue {
    fn from(s: String) -> Self {
        ParamValue::String(s)
    }
}

impl From<&String> for ParamValue {
    fn from(s: &String) -> Self {
        ParamValue::String(s.clone())
    }
}

/// A list of shader parameter values, `&[(&str, ParamValue)]`, for the calls that bind a shader
/// with its values ([`crate::api::Context::light_source`], [`crate::api::Context::parameters`],
/// [`crate::api::Context::pixel_shader`], ...): each value is anything with a
/// `From` conversion to [`ParamValue`] (`f32`, `[f32; 3]`, glam vectors and matrices, strings,
/// `Vec<f32>`), checked against the shader's declaration when bound.
///
/// ```
/// use rtsl_runtime::glam::Vec3;
/// use rtsl_runtime::params;
/// use rtsl_runtime::shading::ParamValue;
///
/// let values = params!["intensity" => 20.0, "lightcolor" => [1.0, 0.9, 0.8], "from" => Vec3::Y];
/// assert_eq!(values[0], ("intensity", ParamValue::Float(20.0)));
/// assert_eq!(values[2].1, ParamValue::Point([0.0, 1.0, 0.0]));
/// ```
#[macro_export]
macro_rules! params {
    ($($name:expr => $value:expr),* $(,)?) => {
        &[$(($name, $crate::shading::ParamValue::from($value))),*]
    };
}

impl ParamValue {
    fn describe(&self) -> String {
        match self {
            ParamValue::Float(_) => "float".into(),
            ParamValue::Floats(v) => format!("float[{}]", v.len()),
            ParamValue::Color(_) => "color".into(),
            ParamValue::Point(_) => "point".into(),
            ParamValue::Vector(_) => "vector".into(),
            ParamValue::Normal(_) => "normal".into(),
            ParamValue::Triples(v) => format!("triple[{}]", v.len()),
            ParamValue::Matrix(_) => "matrix".into(),
            ParamValue::String(_) => "string".into(),
        }
    }
}

/// Why a parameter could not be bound.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("shader {shader} has no parameter {name}")]
    NoSuchParameter { shader: String, name: String },
    #[error("parameter {name} of shader {shader} is {expected}, but a {given} was given")]
    TypeMismatch { shader: String, name: String, expected: String, given: String },
}

/// A parameter value ready to copy into batches: its index in the program's layout and its floats
/// (or string).
#[derive(Clone, Debug, PartialEq)]
pub struct BoundParam {
    pub index: usize,
    pub name: String,
    pub floats: Vec<f32>,
    pub string: Option<String>,
}

/// Checks `value` against parameter `name` of `program` and converts it to the stored form;
/// `world_from_current` places point-like values.
pub fn bind_param(
    program: &ShaderProgram,
    name: &str,
    value: &ParamValue,
    world_from_current: &Affine3A,
) -> Result<BoundParam, ParamError> {
    let shader = program.name.clone();
    let (index, _) = program
        .layout()
        .param(name)
        .ok_or_else(|| ParamError::NoSuchParameter { shader: shader.clone(), name: name.to_string() })?;
    let info = &program.interface.parameters[index];
    let len = info.array_length.map_or(1, |n| n as usize);
    let expected = match info.array_length {
        Some(n) => format!("{}[{n}]", info.base.name()),
        None => info.base.name().to_string(),
    };
    let mismatch = || ParamError::TypeMismatch {
        shader: shader.clone(),
        name: name.to_string(),
        expected: expected.clone(),
        given: value.describe(),
    };
    let bound = |floats: Vec<f32>| BoundParam { index, name: name.to_string(), floats, string: None };
    match (info.base, value) {
        (BaseType::String, ParamValue::String(s)) if len == 1 => {
            Ok(BoundParam { index, name: name.to_string(), floats: Vec::new(), string: Some(s.clone()) })
        }
        (BaseType::Float, ParamValue::Float(x)) if len == 1 => Ok(bound(vec![*x])),
        (BaseType::Float, ParamValue::Floats(v)) if v.len() == len => Ok(bound(v.clone())),
        (b, v) if b.is_triple() => {
            let triples: Vec<[f32; 3]> = match v {
                ParamValue::Float(x) => vec![[*x; 3]],
                ParamValue::Floats(f) if f.len() == 3 * len => f.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
                ParamValue::Color(c) | ParamValue::Point(c) | ParamValue::Vector(c) | ParamValue::Normal(c) => {
                    vec![*c]
                }
                ParamValue::Triples(t) => t.clone(),
                _ => return Err(mismatch()),
            };
            if triples.len() != len {
                return Err(mismatch());
            }
            let normal_xf = world_from_current.matrix3.inverse().transpose();
            let mut floats = Vec::with_capacity(3 * len);
            for t in triples {
                let x = Vec3A::from(t);
                let w = match b {
                    BaseType::Point => world_from_current.transform_point3a(x),
                    BaseType::Vector => world_from_current.transform_vector3a(x),
                    BaseType::Normal => normal_xf * x,
                    _ => x,
                };
                floats.extend_from_slice(&w.to_array());
            }
            Ok(bound(floats))
        }
        // Matrices are taken as given (world space); RenderMan leaves their space to the shader.
        (BaseType::Matrix, ParamValue::Matrix(m)) if len == 1 => Ok(bound(m.to_vec())),
        _ => Err(mismatch()),
    }
}

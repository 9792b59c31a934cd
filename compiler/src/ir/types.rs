//! The types of the language.
//!
//! A value's type is a [`BaseType`] plus an optional fixed array length. Whether a value is uniform or
//! varying is not part of its type: it is a separate fact the checker infers (see `ir` docs).

use std::fmt;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseType {
    Float,
    Color,
    Point,
    Vector,
    Normal,
    Matrix,
    String,
    Void,
    /// The result of a relation or `&&`/`||`; usable as a condition, converts to float 0 or 1.
    Bool,
}

impl BaseType {
    pub fn name(self) -> &'static str {
        match self {
            BaseType::Float => "float",
            BaseType::Color => "color",
            BaseType::Point => "point",
            BaseType::Vector => "vector",
            BaseType::Normal => "normal",
            BaseType::Matrix => "matrix",
            BaseType::String => "string",
            BaseType::Void => "void",
            BaseType::Bool => "bool",
        }
    }

    /// Three floats: color, point, vector, normal.
    pub fn is_triple(self) -> bool {
        matches!(self, BaseType::Color | BaseType::Point | BaseType::Vector | BaseType::Normal)
    }

    /// Point, vector or normal: the spatial triples, which convert into each other freely.
    pub fn is_pointlike(self) -> bool {
        matches!(self, BaseType::Point | BaseType::Vector | BaseType::Normal)
    }

    /// Float or a triple: the types arithmetic works on component by component.
    pub fn is_numeric(self) -> bool {
        self == BaseType::Float || self.is_triple()
    }

    /// How many floats a value of this type holds (strings and void hold none).
    pub fn components(self) -> usize {
        match self {
            BaseType::Float | BaseType::Bool => 1,
            BaseType::Color | BaseType::Point | BaseType::Vector | BaseType::Normal => 3,
            BaseType::Matrix => 16,
            BaseType::String | BaseType::Void => 0,
        }
    }
}

impl fmt::Display for BaseType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The length of an array type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum ArrayLen {
    Fixed(u32),
    /// `float a[]`: a function parameter that takes arrays of any length.
    Unsized,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Type {
    pub base: BaseType,
    pub array: Option<ArrayLen>,
}

impl Type {
    pub const FLOAT: Type = Type::scalar(BaseType::Float);
    pub const COLOR: Type = Type::scalar(BaseType::Color);
    pub const POINT: Type = Type::scalar(BaseType::Point);
    pub const VECTOR: Type = Type::scalar(BaseType::Vector);
    pub const NORMAL: Type = Type::scalar(BaseType::Normal);
    pub const MATRIX: Type = Type::scalar(BaseType::Matrix);
    pub const STRING: Type = Type::scalar(BaseType::String);
    pub const VOID: Type = Type::scalar(BaseType::Void);
    pub const BOOL: Type = Type::scalar(BaseType::Bool);

    pub const fn scalar(base: BaseType) -> Type {
        Type { base, array: None }
    }

    pub const fn array(base: BaseType, len: u32) -> Type {
        Type { base, array: Some(ArrayLen::Fixed(len)) }
    }

    pub fn is_array(self) -> bool {
        self.array.is_some()
    }

    pub fn element(self) -> Type {
        Type::scalar(self.base)
    }

    pub fn array_len(self) -> Option<u32> {
        match self.array {
            Some(ArrayLen::Fixed(n)) => Some(n),
            _ => None,
        }
    }
}

impl fmt::Display for Type {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.array {
            None => write!(f, "{}", self.base),
            Some(ArrayLen::Fixed(n)) => write!(f, "{}[{}]", self.base, n),
            Some(ArrayLen::Unsized) => write!(f, "{}[]", self.base),
        }
    }
}

impl From<crate::front::parse::ast::TypeName> for BaseType {
    fn from(t: crate::front::parse::ast::TypeName) -> BaseType {
        use crate::front::parse::ast::TypeName as T;
        match t {
            T::Float => BaseType::Float,
            T::Color => BaseType::Color,
            T::Point => BaseType::Point,
            T::Vector => BaseType::Vector,
            T::Normal => BaseType::Normal,
            T::Matrix => BaseType::Matrix,
            T::String => BaseType::String,
            T::Void => BaseType::Void,
        }
    }
}

/// The colour spaces a `color "space" (...)` typecast or `ctransform` may name.
pub const COLOR_SPACES: &[&str] = &["rgb", "hsv", "hsl", "xyz", "XYZ", "xyY", "YIQ"];

//! Parameter declarations: storage class, type and array length, as written in `Declare`
//! requests and inline (`"uniform float Kd"`), and the table of names RenderMan predeclares.
//!
//! Invariant: a [`Decl`] always has at least one component per value (`array_len`, when present,
//! is at least 1), so value counts can be checked by divisibility.

use std::collections::HashMap;
use std::fmt;

/// How a parameter's values are spread over a primitive (RISpec 3.2, section 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Class {
    /// One value for the whole primitive.
    Constant,
    /// One value per face (per patch, per polygon).
    Uniform,
    /// One value per corner of each face's parameter space, interpolated linearly.
    Varying,
    /// One value per control vertex, interpolated like `P`.
    Vertex,
    /// One value per face corner.
    FaceVarying,
    /// No declaration was found: the values are kept as written (numbers as floats, or strings),
    /// for a shader's interface to type them (PRMan reads undeclared shader parameters' types from
    /// the shader). Geometry ignores such parameters.
    Implicit,
}

/// A parameter's value type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Ty {
    /// `float`
    Float,
    /// `integer` (or `int`)
    Integer,
    /// `color` (three components: RIB's default colour space)
    Color,
    /// `point`
    Point,
    /// `vector`
    Vector,
    /// `normal`
    Normal,
    /// `hpoint` (homogeneous: four components)
    HPoint,
    /// `string`
    String,
    /// `matrix` (sixteen components)
    Matrix,
}

impl Ty {
    /// Numbers (or strings) per value.
    pub fn components(self) -> usize {
        match self {
            Ty::Float | Ty::Integer | Ty::String => 1,
            Ty::Color | Ty::Point | Ty::Vector | Ty::Normal => 3,
            Ty::HPoint => 4,
            Ty::Matrix => 16,
        }
    }

    fn keyword(self) -> &'static str {
        match self {
            Ty::Float => "float",
            Ty::Integer => "integer",
            Ty::Color => "color",
            Ty::Point => "point",
            Ty::Vector => "vector",
            Ty::Normal => "normal",
            Ty::HPoint => "hpoint",
            Ty::String => "string",
            Ty::Matrix => "matrix",
        }
    }
}

impl Class {
    fn keyword(self) -> &'static str {
        match self {
            Class::Constant => "constant",
            Class::Uniform => "uniform",
            Class::Varying => "varying",
            Class::Vertex => "vertex",
            Class::FaceVarying => "facevarying",
            Class::Implicit => "undeclared",
        }
    }
}

/// A declaration: class, type and optional array length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Decl {
    /// Storage class.
    pub class: Class,
    /// Value type.
    pub ty: Ty,
    /// `Some(n)` for `type[n]`.
    pub array_len: Option<usize>,
}

impl Decl {
    /// A declaration without an array length.
    pub const fn new(class: Class, ty: Ty) -> Self {
        Decl { class, ty, array_len: None }
    }

    /// Numbers (or strings) per value: the type's components times the array length.
    pub fn components(&self) -> usize {
        self.ty.components() * self.array_len.unwrap_or(1)
    }
}

impl fmt::Display for Decl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.class.keyword(), self.ty.keyword())?;
        if let Some(n) = self.array_len {
            write!(f, "[{n}]")?;
        }
        Ok(())
    }
}

/// The longest array a declaration may ask for (guards against absurd allocations downstream).
const MAX_ARRAY_LEN: usize = 1 << 20;

/// Parses a `Declare` type string (`"uniform float"`, `"varying color"`, `"float[2]"`).
/// The class defaults to `uniform`, as in RISpec.
pub fn parse_declaration(text: &str) -> Result<Decl, String> {
    let words = words(text);
    let (decl, rest) = parse_words(&words)?;
    match rest {
        [] => Ok(decl),
        [extra, ..] => Err(format!("unexpected `{extra}` after the type in declaration `{text}`")),
    }
}

/// Parses an inline declaration (`"uniform float Kd"`, `"float[2] st"`) into the declaration and
/// the parameter's name.
pub fn parse_inline(text: &str) -> Result<(Decl, String), String> {
    let words = words(text);
    let (decl, rest) = parse_words(&words)?;
    match rest {
        [name] if is_identifier(name) => Ok((decl, name.to_string())),
        [] => Err(format!("inline declaration `{text}` has no parameter name")),
        _ => Err(format!("inline declaration `{text}` should be `[class] type[[n]] name`")),
    }
}

/// Whether `name` is written with an inline declaration (more than a bare name).
pub fn is_inline(name: &str) -> bool {
    name.contains(|c: char| c.is_whitespace() || c == '[')
}

fn is_identifier(word: &str) -> bool {
    !word.is_empty() && word.chars().all(|c| c.is_alphanumeric() || c == '_' || c == ':' || c == '.')
}

/// Splits on whitespace, with `[` and `]` as words of their own.
fn words(text: &str) -> Vec<&str> {
    let mut out = Vec::new();
    for word in text.split_whitespace() {
        let mut rest = word;
        while let Some(i) = rest.find(['[', ']']) {
            if i > 0 {
                out.push(&rest[..i]);
            }
            out.push(&rest[i..i + 1]);
            rest = &rest[i + 1..];
        }
        if !rest.is_empty() {
            out.push(rest);
        }
    }
    out
}

fn parse_words<'a, 'w>(words: &'a [&'w str]) -> Result<(Decl, &'a [&'w str]), String> {
    let mut rest = words;
    let class = match rest.first().and_then(|w| class_keyword(w)) {
        Some(class) => {
            rest = &rest[1..];
            class
        }
        None => Class::Uniform,
    };
    let ty = match rest.first() {
        Some(w) => match type_keyword(w) {
            Some(ty) => ty,
            None => {
                return Err(format!(
                "unknown type `{w}` (expected float, integer, color, point, vector, normal, hpoint, string or matrix)"
            ))
            }
        },
        None => return Err("declaration has no type".to_string()),
    };
    rest = &rest[1..];
    let mut array_len = None;
    if rest.first() == Some(&"[") {
        let n = match rest {
            [_, n, "]", ..] => n.parse::<usize>().ok().filter(|n| (1..=MAX_ARRAY_LEN).contains(n)),
            _ => None,
        };
        match n {
            Some(n) => array_len = Some(n),
            None => {
                return Err(format!("bad array length in declaration (expected `[n]` with 1 <= n <= {MAX_ARRAY_LEN})"))
            }
        }
        rest = &rest[3..];
    }
    Ok((Decl { class, ty, array_len }, rest))
}

fn class_keyword(word: &str) -> Option<Class> {
    Some(match word {
        "constant" => Class::Constant,
        "uniform" => Class::Uniform,
        "varying" => Class::Varying,
        "vertex" => Class::Vertex,
        // PRMan's `facevertex` is a value per face corner, as `facevarying`, interpolated with the
        // surface's own basis where the two differ: on polygons they are the same; subdivision
        // meshes refine both linearly here.
        "facevarying" | "facevertex" => Class::FaceVarying,
        _ => return None,
    })
}

fn type_keyword(word: &str) -> Option<Ty> {
    Some(match word {
        "float" => Ty::Float,
        "integer" | "int" => Ty::Integer,
        "color" => Ty::Color,
        "point" => Ty::Point,
        "vector" => Ty::Vector,
        "normal" => Ty::Normal,
        "hpoint" => Ty::HPoint,
        "string" => Ty::String,
        // PRMan's `mpoint`: a point given as the 4x4 matrix of a coordinate system (a Blobby
        // leaf's reference frame, as `vertex mpoint Pref`), 16 floats a value.
        "matrix" | "mpoint" => Ty::Matrix,
        _ => return None,
    })
}

/// Names RenderMan predeclares: RISpec 3.2 table 5.1 (standard geometric primitive variables),
/// the standard shaders' and `Projection`'s parameters (`ri.h`'s `RI_*` tokens), and the
/// common `Option`/`Attribute`/`Display` parameters that RIB files use without declaring.
const PREDECLARED: &[(&str, Class, Ty, Option<usize>)] = &[
    // Geometric primitive variables (table 5.1).
    ("P", Class::Vertex, Ty::Point, None),
    ("Pz", Class::Vertex, Ty::Float, None),
    ("Pw", Class::Vertex, Ty::HPoint, None),
    ("N", Class::Varying, Ty::Normal, None),
    ("Np", Class::Uniform, Ty::Normal, None),
    ("Cs", Class::Varying, Ty::Color, None),
    ("Os", Class::Varying, Ty::Color, None),
    ("s", Class::Varying, Ty::Float, None),
    ("t", Class::Varying, Ty::Float, None),
    ("st", Class::Varying, Ty::Float, Some(2)),
    ("width", Class::Varying, Ty::Float, None),
    ("constantwidth", Class::Constant, Ty::Float, None),
    // Standard shader parameters (ri.h).
    ("Ka", Class::Uniform, Ty::Float, None),
    ("Kd", Class::Uniform, Ty::Float, None),
    ("Ks", Class::Uniform, Ty::Float, None),
    ("Kr", Class::Uniform, Ty::Float, None),
    ("Km", Class::Uniform, Ty::Float, None),
    ("roughness", Class::Uniform, Ty::Float, None),
    ("specularcolor", Class::Uniform, Ty::Color, None),
    ("texturename", Class::Uniform, Ty::String, None),
    ("amplitude", Class::Uniform, Ty::Float, None),
    ("intensity", Class::Uniform, Ty::Float, None),
    ("lightcolor", Class::Uniform, Ty::Color, None),
    ("from", Class::Uniform, Ty::Point, None),
    ("to", Class::Uniform, Ty::Point, None),
    ("coneangle", Class::Uniform, Ty::Float, None),
    ("conedeltaangle", Class::Uniform, Ty::Float, None),
    ("beamdistribution", Class::Uniform, Ty::Float, None),
    ("mindistance", Class::Uniform, Ty::Float, None),
    ("maxdistance", Class::Uniform, Ty::Float, None),
    ("background", Class::Uniform, Ty::Color, None),
    ("distance", Class::Uniform, Ty::Float, None),
    ("fov", Class::Uniform, Ty::Float, None),
    // Display, Option and Attribute parameters in common use.
    ("origin", Class::Uniform, Ty::Integer, Some(2)),
    ("shader", Class::Uniform, Ty::String, None),
    ("texture", Class::Uniform, Ty::String, None),
    ("archive", Class::Uniform, Ty::String, None),
    ("procedural", Class::Uniform, Ty::String, None),
    ("resource", Class::Uniform, Ty::String, None),
    ("display", Class::Uniform, Ty::String, None),
    ("name", Class::Uniform, Ty::String, None),
    ("sphere", Class::Uniform, Ty::Float, None),
    ("coordinatesystem", Class::Uniform, Ty::String, None),
    ("bucketsize", Class::Uniform, Ty::Integer, Some(2)),
    ("gridsize", Class::Uniform, Ty::Integer, None),
    ("texturememory", Class::Uniform, Ty::Integer, None),
    ("othreshold", Class::Uniform, Ty::Color, None),
    ("zthreshold", Class::Uniform, Ty::Color, None),
];

/// The declarations in force: `Declare`d names over the predeclared ones. RenderMan's `Declare`
/// is global (not scoped by `AttributeBegin`), so one table serves a whole RIB stream, archives
/// included.
#[derive(Clone, Debug)]
pub struct DeclTable {
    declared: HashMap<String, Decl>,
}

impl Default for DeclTable {
    fn default() -> Self {
        Self::new()
    }
}

impl DeclTable {
    /// A table holding only the predeclared names.
    pub fn new() -> Self {
        let declared = PREDECLARED
            .iter()
            .map(|&(name, class, ty, array_len)| (name.to_string(), Decl { class, ty, array_len }))
            .collect();
        DeclTable { declared }
    }

    /// Declares (or redeclares) `name`.
    pub fn declare(&mut self, name: &str, decl: Decl) {
        self.declared.insert(name.to_string(), decl);
    }

    /// The declaration of `name`, if any.
    pub fn get(&self, name: &str) -> Option<Decl> {
        self.declared.get(name).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn declarations() {
        assert_eq!(parse_declaration("varying color").unwrap(), Decl::new(Class::Varying, Ty::Color));
        assert_eq!(parse_declaration("float").unwrap(), Decl::new(Class::Uniform, Ty::Float));
        let d = parse_declaration("facevarying float[2]").unwrap();
        assert_eq!((d.class, d.ty, d.array_len, d.components()), (Class::FaceVarying, Ty::Float, Some(2), 2));
        assert_eq!(parse_declaration("facevertex float").unwrap().class, Class::FaceVarying);
        assert_eq!(parse_declaration("uniform float [ 3 ]").unwrap().array_len, Some(3));
        assert!(parse_declaration("uniform flaot").unwrap_err().contains("unknown type `flaot`"));
        assert!(parse_declaration("float[0]").is_err());
        assert!(parse_declaration("float[2").is_err());
        assert!(parse_declaration("").is_err());
        assert!(parse_declaration("float x").is_err());
    }

    #[test]
    fn inline_declarations() {
        let (d, name) = parse_inline("constant string texname").unwrap();
        assert_eq!((d, name.as_str()), (Decl::new(Class::Constant, Ty::String), "texname"));
        let (d, name) = parse_inline("float[2] foo").unwrap();
        assert_eq!((d.array_len, name.as_str()), (Some(2), "foo"));
        let (d, _) = parse_inline("hpoint Pw").unwrap();
        assert_eq!(d.components(), 4);
        assert!(parse_inline("uniform float").is_err());
        assert!(parse_inline("uniform float a b").is_err());
        assert!(is_inline("float Kd") && is_inline("st[2]") && !is_inline("Kd"));
    }

    #[test]
    fn table_lookup_and_redeclaration() {
        let mut table = DeclTable::new();
        assert_eq!(table.get("P"), Some(Decl::new(Class::Vertex, Ty::Point)));
        assert_eq!(table.get("st").unwrap().components(), 2);
        assert_eq!(table.get("foo"), None);
        table.declare("Kd", Decl::new(Class::Varying, Ty::Float));
        assert_eq!(table.get("Kd").unwrap().class, Class::Varying);
        assert_eq!(Decl::new(Class::Vertex, Ty::Point).to_string(), "vertex point");
    }
}

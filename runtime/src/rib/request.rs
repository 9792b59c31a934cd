//! The typed requests a RIB stream holds, with their parameter lists.
//!
//! Invariants: every [`Param`]'s value count is a non-zero multiple of its declaration's
//! components ([`Decl::components`]), and its value variant matches the declared type (integers
//! as [`ParamValue::Ints`], strings as [`ParamValue::Strings`], every other type as
//! [`ParamValue::Floats`]). `ReadArchive` never appears: the parser expands it inline.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use super::decl::{Decl, Ty};
use crate::geometry::quadric::Quadric;

/// Where something is in a RIB file.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Location {
    /// The file as it was named (the `parse_str` name, or an archive path joined to its
    /// includer's directory).
    pub file: Arc<Path>,
    /// 1-based line; 0 when the location is the file as a whole (e.g. it could not be read).
    pub line: u32,
    /// 1-based column in characters; 0 with line 0.
    pub column: u32,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.file.display())
        } else {
            write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
        }
    }
}

/// A parameter's values.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// Every numeric type but `integer`, flattened (a colour is three floats).
    Floats(Vec<f32>),
    /// `integer` values.
    Ints(Vec<i32>),
    /// `string` values.
    Strings(Vec<String>),
}

impl ParamValue {
    /// Number of numbers or strings.
    pub fn len(&self) -> usize {
        match self {
            ParamValue::Floats(v) => v.len(),
            ParamValue::Ints(v) => v.len(),
            ParamValue::Strings(v) => v.len(),
        }
    }

    /// Whether there are no values (never true of a parsed parameter).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One `"name" value` pair of a parameter list, typed.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    /// The bare name (an inline declaration's type words removed).
    pub name: String,
    /// Its declaration (inline, `Declare`d or predeclared).
    pub decl: Decl,
    /// Its values.
    pub value: ParamValue,
    /// Where the name was written.
    pub loc: Location,
}

impl Param {
    /// The values as floats, if the type is a float type.
    pub fn floats(&self) -> Option<&[f32]> {
        match &self.value {
            ParamValue::Floats(v) => Some(v),
            _ => None,
        }
    }

    /// The values as integers, if the type is `integer`.
    pub fn ints(&self) -> Option<&[i32]> {
        match &self.value {
            ParamValue::Ints(v) => Some(v),
            _ => None,
        }
    }

    /// The values as strings, if the type is `string`.
    pub fn strings(&self) -> Option<&[String]> {
        match &self.value {
            ParamValue::Strings(v) => Some(v),
            _ => None,
        }
    }

    /// Number of values (numbers divided by the declaration's components).
    pub fn value_count(&self) -> usize {
        self.value.len() / self.decl.components()
    }

    /// Whether the values are of type `ty`.
    pub fn is(&self, ty: Ty) -> bool {
        self.decl.ty == ty
    }
}

/// The first parameter called `name`.
pub fn find_param<'a>(params: &'a [Param], name: &str) -> Option<&'a Param> {
    params.iter().find(|p| p.name == name)
}

/// A shader (or other named, parameterised) statement: `Surface "plastic" "Kd" 0.5`.
#[derive(Clone, Debug, PartialEq)]
pub struct Shader {
    /// The shader's name.
    pub name: String,
    /// Its parameter list.
    pub params: Vec<Param>,
}

/// A light or object handle: RIB 3.2's sequence numbers, or the later string handles.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Handle {
    /// `LightSource "spot" 1`, `ObjectBegin 1`.
    Number(i32),
    /// `LightSource "spot" "key"`, `ObjectBegin "tree"`.
    Name(String),
}

/// `Orientation`'s argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Orientation {
    /// `"outside"`: normals point out of the current coordinate system's handedness.
    Outside,
    /// `"inside"`
    Inside,
    /// `"lh"`
    LeftHanded,
    /// `"rh"`
    RightHanded,
}

/// The patch type of `Patch` and `PatchMesh`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchType {
    /// Four control points per patch.
    Bilinear,
    /// Sixteen control points per patch, under the current `Basis`.
    Bicubic,
}

/// `PatchMesh`'s wrap mode in one direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// The mesh closes on itself.
    Periodic,
    /// The mesh is open.
    NonPeriodic,
}

/// How `Curves` interpolate their control points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveType {
    /// Polylines through the points.
    Linear,
    /// Piecewise cubic curves under the current `Basis` (its v basis and step).
    Cubic,
}

/// A spline basis, for `Basis`.
#[derive(Clone, Debug, PartialEq)]
pub enum Basis {
    /// A standard basis by name (`"bezier"`, `"b-spline"`, `"catmull-rom"`, `"hermite"`,
    /// `"power"`).
    Named(String),
    /// An explicit 4x4 basis matrix (row major, as written).
    Matrix([f32; 16]),
}

/// One parametric direction of a `NuPatch`, as written.
#[derive(Clone, Debug, PartialEq)]
pub struct NuDirection {
    /// Control points along the direction (`nu` or `nv`).
    pub n: i32,
    /// The order: the degree plus one.
    pub order: i32,
    /// The knot vector (`n + order` values, non-decreasing).
    pub knots: Vec<f32>,
    /// Where the rendered part of the parameter range starts.
    pub min: f32,
    /// Where it ends.
    pub max: f32,
}

/// `TrimCurve`'s arrays, as written: loops of rational B-spline curves in the `(u, v)` parameter
/// space of the `NuPatch`es that follow, each curve's data concatenated after the previous one's.
#[derive(Clone, Debug, PartialEq)]
pub struct TrimCurve {
    /// Curves per loop (the number of loops is its length).
    pub ncurves: Vec<i32>,
    /// Each curve's order.
    pub order: Vec<i32>,
    /// Each curve's knot vector (`n + order` values), one after the other.
    pub knot: Vec<f32>,
    /// Each curve's parameter range start.
    pub min: Vec<f32>,
    /// Each curve's parameter range end.
    pub max: Vec<f32>,
    /// Each curve's number of control points.
    pub n: Vec<i32>,
    /// The control points' homogeneous `u` (already multiplied by `w`).
    pub u: Vec<f32>,
    /// Their homogeneous `v`.
    pub v: Vec<f32>,
    /// Their weights.
    pub w: Vec<f32>,
}

/// A parsed request and where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// What it asks for.
    pub kind: RequestKind,
    /// Where its name was written.
    pub loc: Location,
}

/// Every request the reader understands. Angles are in degrees, as written.
#[derive(Clone, Debug, PartialEq)]
pub enum RequestKind {
    /// `version 3.03` (a header that RIB writers emit).
    Version(f32),
    // --- Options: camera and image.
    /// `Format xres yres pixelaspect`
    Format {
        /// Width in pixels.
        xres: i32,
        /// Height in pixels.
        yres: i32,
        /// Pixel aspect ratio (negative: the renderer chooses).
        pixel_aspect: f32,
    },
    /// `FrameAspectRatio ratio`
    FrameAspectRatio(f32),
    /// `ScreenWindow left right bottom top`
    ScreenWindow([f32; 4]),
    /// `CropWindow xmin xmax ymin ymax`
    CropWindow([f32; 4]),
    /// `Projection "name" params` (`"perspective"`, `"orthographic"`).
    Projection(Shader),
    /// `ClippingPlane x y z nx ny nz`: a point on the plane and its normal, in the current space.
    ClippingPlane([f32; 6]),
    /// `Clipping near far`
    Clipping {
        /// Near plane distance.
        near: f32,
        /// Far plane distance.
        far: f32,
    },
    /// `DepthOfField fstop focallength focaldistance`
    DepthOfField([f32; 3]),
    /// `Shutter open close`
    Shutter([f32; 2]),
    /// `Detail [xmin xmax ymin ymax zmin zmax]`: the bound in object space that `DetailRange`
    /// measures.
    Detail([f32; 6]),
    /// `DetailRange minvisible lowertransition uppertransition maxvisible`
    DetailRange([f32; 4]),
    /// `RelativeDetail scale`
    RelativeDetail(f32),
    /// `Quantize "type" one min max ditheramplitude`
    Quantize {
        /// `"rgba"` or `"z"`.
        ty: String,
        one: f32,
        min: f32,
        max: f32,
        dither: f32,
    },
    /// `Display "name" "type" "mode" params`
    Display {
        /// Output name (file name).
        name: String,
        /// Display driver (`"file"`, `"framebuffer"`, `"tiff"`...).
        driver: String,
        /// Channels (`"rgb"`, `"rgba"`...).
        mode: String,
        /// Driver parameters.
        params: Vec<Param>,
    },
    /// `PixelSamples xsamples ysamples`
    PixelSamples {
        /// Samples along x.
        x: f32,
        /// Samples along y.
        y: f32,
    },
    /// `PixelFilter "name" xwidth ywidth`
    PixelFilter {
        /// Filter name (`"box"`, `"gaussian"`...).
        filter: String,
        /// Width in x.
        xwidth: f32,
        /// Width in y.
        ywidth: f32,
    },
    /// `Exposure gain gamma`
    Exposure {
        /// Gain.
        gain: f32,
        /// Gamma.
        gamma: f32,
    },
    /// `ShadingRate size`: the micropolygon area truly displaced objects are diced to (surfaces
    /// are otherwise shaded per hit).
    ShadingRate(f32),
    /// `Option "name" params`
    Option(Shader),
    /// `Imager "name" params`
    Imager(Shader),
    /// OpenRT's `Camera "name" params`: a camera shader.
    Camera(Shader),
    /// OpenRT's `Pixel "name" params`: a pixel shader.
    Pixel(Shader),
    // --- Structure.
    /// `FrameBegin n` (the number is optional here).
    FrameBegin(Option<i32>),
    /// `FrameEnd`
    FrameEnd,
    /// `WorldBegin`
    WorldBegin,
    /// `WorldEnd`
    WorldEnd,
    /// `AttributeBegin`
    AttributeBegin,
    /// `AttributeEnd`
    AttributeEnd,
    /// `TransformBegin`
    TransformBegin,
    /// `TransformEnd`
    TransformEnd,
    /// `ObjectBegin handle`
    ObjectBegin(Handle),
    /// `ObjectEnd`
    ObjectEnd,
    /// `ObjectInstance handle`
    ObjectInstance(Handle),
    // --- Transformations.
    /// `Identity`
    Identity,
    /// `Transform [16 numbers]` (row major, RenderMan's row-vector convention, as written).
    Transform([f32; 16]),
    /// `ConcatTransform [16 numbers]`
    ConcatTransform([f32; 16]),
    /// `Perspective fov`
    Perspective(f32),
    /// `Translate dx dy dz`
    Translate([f32; 3]),
    /// `Rotate angle dx dy dz`
    Rotate {
        /// Angle in degrees.
        angle: f32,
        /// Axis.
        axis: [f32; 3],
    },
    /// `Scale sx sy sz`
    Scale([f32; 3]),
    /// `Skew angle dx1 dy1 dz1 dx2 dy2 dz2`
    Skew([f32; 7]),
    /// `CoordinateSystem "name"`
    CoordinateSystem(String),
    /// `ScopedCoordinateSystem "name"`: `CoordinateSystem` until the attribute block ends.
    ScopedCoordinateSystem(String),
    /// `Resource "name" "type" params`: PRMan's named resources (`"attributes"`: a saved
    /// attribute state).
    Resource {
        /// The resource's name.
        name: String,
        /// Its type.
        ty: String,
        /// `"operation"`, `"subset"`.
        params: Vec<Param>,
    },
    /// `ResourceBegin`: resources saved from here are forgotten at the matching `ResourceEnd`.
    ResourceBegin,
    /// `ResourceEnd`
    ResourceEnd,
    /// `CoordSysTransform "name"`
    CoordSysTransform(String),
    // --- Attributes and shaders.
    /// `Surface "name" params`
    Surface(Shader),
    /// `Displacement "name" params`
    Displacement(Shader),
    /// `Atmosphere "name" params`
    Atmosphere(Shader),
    /// `Interior "name" params`
    Interior(Shader),
    /// `Exterior "name" params`
    Exterior(Shader),
    /// `LightSource "name" handle params`
    LightSource {
        /// The light shader.
        shader: Shader,
        /// Its handle, for `Illuminate` (absent in some hand-written files).
        handle: Option<Handle>,
    },
    /// `AreaLightSource "name" handle params`
    AreaLightSource {
        /// The light shader.
        shader: Shader,
        /// Its handle.
        handle: Option<Handle>,
    },
    /// `Illuminate handle onoff`
    Illuminate {
        /// Which light.
        light: Handle,
        /// On (true) or off.
        on: bool,
    },
    /// `Color [r g b]` or `Color r g b`
    Color([f32; 3]),
    /// `Opacity [r g b]`
    Opacity([f32; 3]),
    /// `Attribute "name" params`
    Attribute(Shader),
    /// `Declare "name" "class type"`
    Declare {
        /// The declared name.
        name: String,
        /// Its declaration.
        decl: Decl,
    },
    /// `Sides 1|2`
    Sides(i32),
    /// `Orientation "outside"|"inside"|"lh"|"rh"`
    Orientation(Orientation),
    /// `ReverseOrientation`
    ReverseOrientation,
    /// `Matte onoff`
    Matte(bool),
    /// `ShadingInterpolation "constant"|"smooth"` (accepted; a ray tracer shades per hit).
    ShadingInterpolation(String),
    /// `GeometricRepresentation "primitive"|"points"|"lines"` (accepted; surfaces are drawn whole,
    /// and the reader warns about any other representation).
    GeometricRepresentation(String),
    /// `Hider "type" params`
    Hider(Shader),
    /// `TextureCoordinates s1 t1 s2 t2 s3 t3 s4 t4`: the default `(s, t)` at the `(u, v)` corners
    /// `(0, 0) (1, 0) (0, 1) (1, 1)` of patches and quadrics.
    TextureCoordinates([f32; 8]),
    /// `Bound [xmin xmax ymin ymax zmin zmax]`
    Bound([f32; 6]),
    /// `MotionBegin [times]`: the requests up to `MotionEnd` are samples of one request at these
    /// times.
    MotionBegin(Vec<f32>),
    /// `MotionEnd`
    MotionEnd,
    /// `SolidBegin "operation"` (CSG: `"primitive"`, `"union"`, `"intersection"`, `"difference"`).
    SolidBegin(String),
    /// `SolidEnd`
    SolidEnd,
    /// `ReadArchive "mesh.obj"` (or `.ply`, `.gltf`, `.glb`): a mesh file to add under the current attributes (an
    /// rtsl extension; other archives are RIB, expanded in place).
    MeshArchive(std::path::PathBuf),
    /// `Basis ustep vstep` with each basis a name or a matrix.
    Basis {
        /// The u basis.
        u: Basis,
        /// Its step.
        ustep: i32,
        /// The v basis.
        v: Basis,
        /// Its step.
        vstep: i32,
    },
    // --- Geometry.
    /// `Polygon params` (a convex polygon; `P` gives the vertices).
    Polygon(Vec<Param>),
    /// `GeneralPolygon [nvertices per loop] params` (first loop outer, the rest holes).
    GeneralPolygon {
        /// Vertices per loop.
        nvertices: Vec<i32>,
        /// Vertex data.
        params: Vec<Param>,
    },
    /// `PointsPolygons [nvertices] [vertices] params`
    PointsPolygons {
        /// Vertices per polygon.
        nvertices: Vec<i32>,
        /// Vertex indices, polygon after polygon.
        vertices: Vec<i32>,
        /// Vertex data.
        params: Vec<Param>,
    },
    /// `PointsGeneralPolygons [nloops] [nvertices] [vertices] params`
    PointsGeneralPolygons {
        /// Loops per polygon.
        nloops: Vec<i32>,
        /// Vertices per loop.
        nvertices: Vec<i32>,
        /// Vertex indices, loop after loop.
        vertices: Vec<i32>,
        /// Vertex data.
        params: Vec<Param>,
    },
    /// `SubdivisionMesh scheme [nvertices] [vertices] [tags] [nargs] [intargs] [floatargs] params`
    /// (RISpec 3.2, section 5.5); the four tag arrays may be left out together.
    SubdivisionMesh {
        /// The subdivision scheme (`"catmull-clark"`, `"bilinear"`...), as written.
        scheme: String,
        /// Vertices per face.
        nvertices: Vec<i32>,
        /// Vertex indices, face after face.
        vertices: Vec<i32>,
        /// Tag names (`"crease"`, `"corner"`, `"hole"`, `"interpolateboundary"`...).
        tags: Vec<String>,
        /// Two counts per tag: its integer arguments, then its float arguments.
        nargs: Vec<i32>,
        /// The tags' integer arguments, tag after tag.
        intargs: Vec<i32>,
        /// The tags' float arguments, tag after tag.
        floatargs: Vec<f32>,
        /// Vertex data.
        params: Vec<Param>,
    },
    /// `Patch "bilinear"|"bicubic" params`
    Patch {
        /// Patch type.
        ty: PatchType,
        /// Control points and other data.
        params: Vec<Param>,
    },
    /// `PatchMesh type nu uwrap nv vwrap params`
    PatchMesh {
        /// Patch type.
        ty: PatchType,
        /// Control points along u.
        nu: i32,
        /// Wrap along u.
        uwrap: Wrap,
        /// Control points along v.
        nv: i32,
        /// Wrap along v.
        vwrap: Wrap,
        /// Control points and other data.
        params: Vec<Param>,
    },
    /// `NuPatch nu uorder uknot umin umax nv vorder vknot vmin vmax params`: a non-uniform rational
    /// B-spline patch (`P` or `Pw` gives the `nu` x `nv` control points, u varying fastest).
    NuPatch {
        /// The u direction.
        u: NuDirection,
        /// The v direction.
        v: NuDirection,
        /// Control points and other data.
        params: Vec<Param>,
    },
    /// `TrimCurve ncurves order knot min max n u v w`: the trim loops of the `NuPatch`es that follow
    /// in the attribute block.
    TrimCurve(TrimCurve),
    /// `Geometry "name" params`: a primitive the renderer provides (`"teapot"`).
    Geometry {
        /// Its name.
        name: String,
        /// Further data.
        params: Vec<Param>,
    },
    /// `Points params` (RISpec 3.2, section 5.6): one particle per `P` value.
    Points(Vec<Param>),
    /// `Curves type [nvertices] wrap params` (RISpec 3.2, section 5.7): ribbons through control
    /// points, one curve per `nvertices` entry.
    Curves {
        /// Linear or cubic.
        ty: CurveType,
        /// Control points per curve.
        nvertices: Vec<i32>,
        /// Whether each curve closes on itself.
        wrap: Wrap,
        /// Control points, widths and other data.
        params: Vec<Param>,
    },
    /// `Blobby nleaf [code] [floats] [strings] params` (RISpec 3.2, section 5.6): an implicit
    /// surface, the isosurface of primitive fields combined by a program.
    Blobby {
        /// The leaves (primitive fields) the code has, as the request counts them.
        nleaf: i32,
        /// The program: opcodes and their operands.
        code: Vec<i32>,
        /// The leaves' numbers (matrices, ends, radii).
        floats: Vec<f32>,
        /// The leaves' names.
        strings: Vec<String>,
        /// Primitive variables (one `vertex` or `varying` value per leaf).
        params: Vec<Param>,
    },
    /// `Sphere`, `Cylinder`, `Cone`, `Disk`, `Torus`, `Paraboloid`, `Hyperboloid`.
    Quadric {
        /// The shape and its parameters.
        quadric: Quadric,
        /// Further data (`Cs`, shader parameters...).
        params: Vec<Param>,
    },
    /// `MakeShadow "picture" "texture" params`: a depth map into a shadow map.
    MakeShadow {
        /// The depth map (a `zfile` or `shadow` display).
        picture: String,
        /// The shadow map to write.
        shadow: String,
    },
    /// `MakeTexture "picture" "texture" swrap twrap "filter" swidth twidth params`
    MakeTexture {
        /// Source image.
        picture: String,
        /// Texture file to write.
        texture: String,
        /// Wrap mode in s (`"periodic"`, `"black"`, `"clamp"`).
        swrap: String,
        /// Wrap mode in t.
        twrap: String,
        /// Filter name.
        filter: String,
        /// Filter width in s.
        swidth: f32,
        /// Filter width in t.
        twidth: f32,
        /// Further parameters.
        params: Vec<Param>,
    },
    /// `MakeCubeFaceEnvironment px nx py ny pz nz texture fov filter swidth twidth params`
    MakeCubeFaceEnvironment {
        /// The face images along +x, -x, +y, -y, +z, -z.
        faces: [String; 6],
        /// The environment map to write.
        texture: String,
        /// Each face's field of view, in degrees.
        fov: f32,
        /// Filter name.
        filter: String,
        /// Filter width in s.
        swidth: f32,
        /// Filter width in t.
        twidth: f32,
        /// Further parameters.
        params: Vec<Param>,
    },
    // --- Conditional RIB. The reader evaluates these as it reads, keeping only the requests of
    // the branches taken; they appear in a request list only inside an inline archive, whose
    // conditions are evaluated where it is read.
    /// `IfBegin "expression"`
    IfBegin(String),
    /// `ElseIf "expression"`
    ElseIf(String),
    /// `Else`
    Else,
    /// `IfEnd`
    IfEnd,
}

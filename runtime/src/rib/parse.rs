//! The parser: tokens grouped into requests (a name and the arguments up to the next name), each
//! then read by its request's signature into a [`RequestKind`].
//!
//! Recovery rests on RIB's shape: request names are the only bare words, so the next name is
//! always a safe place to resume. An error inside a request drops that request (and reports only
//! its first error); an error in one parameter drops only that parameter.

use std::collections::HashMap;
use std::iter::Peekable;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::cond::{self, CondError, Value, CONDITION_BUDGET, MAX_IF_DEPTH};
use super::decl::{self, Class, Decl, DeclTable, Ty};
use super::lex::{tokens, Token, TokenKind, Tokens};
use super::request::{
    Basis, CurveType, Handle, Location, NuDirection, Orientation, Param, ParamValue, PatchType, Request,
    RequestKind as K, Shader, TrimCurve, Wrap,
};
use super::{base_dir, RibDiagnostic, RibParse, RibSink, MAX_ARCHIVE_DEPTH};
use crate::geometry::quadric::Quadric;
use glam::Vec3;

type Result<T> = std::result::Result<T, RibDiagnostic>;

/// RenderMan requests (RISpec 3.2 and the common later ones) that only tune how a renderer works or
/// quantises, which rtsl does its own way: skipping them changes nothing in the picture, so they
/// get a warning, not an omission.
const IGNORED_REQUESTS: &[&str] = &["ErrorHandler", "GeometricApproximation", "PixelVariance"];

/// RenderMan requests (RISpec 3.2 and the common later ones) that this reader skips: what they
/// ask for is missing from the picture, which their warning says (rather than the "unknown
/// request" one a typo gets).
const UNSUPPORTED_REQUESTS: &[&str] = &["Shader"];

/// One argument of a request, as written.
#[derive(Clone, Debug)]
enum ArgValue {
    Number(f64),
    Str(String),
    /// `[ numbers ]`; also `[]`.
    Numbers(Vec<f64>),
    /// `[ strings ]`
    Strings(Vec<String>),
}

impl ArgValue {
    fn describe(&self) -> &'static str {
        match self {
            ArgValue::Number(_) => "a number",
            ArgValue::Str(_) => "a string",
            ArgValue::Numbers(_) => "an array of numbers",
            ArgValue::Strings(_) => "an array of strings",
        }
    }
}

#[derive(Clone, Debug)]
struct Arg {
    value: ArgValue,
    loc: Location,
}

/// The reading state of one RIB stream, shared by the files it includes.
pub(super) struct Parser<'s> {
    /// Canonical paths of the files being read, outermost first (for cycle detection).
    pub(super) include_stack: Vec<PathBuf>,
    /// Archive nesting depth of the file being read (the top file is 0).
    depth: usize,
    decls: DeclTable,
    /// The requests read, unless `sink` takes them; and the requests of the inline archives
    /// being defined.
    requests: Vec<Request>,
    /// Where the requests go as they are read (outside inline archive definitions), so that a
    /// stream need not be held whole.
    sink: Option<&'s mut dyn RibSink>,
    /// Whether the sink asked for no more requests.
    stopped: bool,
    diagnostics: Vec<RibDiagnostic>,
    /// Canonical paths of the archives read, in order.
    archives: Vec<PathBuf>,
    /// Inline archives (`ArchiveBegin "name"` ... `ArchiveEnd`) by name, with their weights.
    inline_archives: HashMap<String, (Arc<[Request]>, usize)>,
    /// Inline archives being defined: name, index of their first request, weight so far, where.
    open_archives: Vec<(String, usize, usize, Location)>,
    /// `ArchiveBegin`s refused (too deep, or malformed) whose `ArchiveEnd` has not come yet, each
    /// as the number of archives open when it came: their `ArchiveEnd`s close nothing.
    refused_archives: Vec<usize>,
    /// The weight (arguments and array elements) of the requests read so far, expansions included.
    weight: usize,
    /// What inline-archive expansions may still add to `weight`.
    expansion_left: usize,
    /// `Option "searchpath" "archive"`: where relative `ReadArchive` paths are looked up first.
    archive_path: Vec<PathBuf>,
    /// The open `IfBegin` blocks, outermost first.
    branches: Vec<Branch>,
    /// `IfBegin` blocks opened past [`MAX_IF_DEPTH`]: skipped whole, counted but not kept.
    branches_too_deep: usize,
    /// How many of `branches` belong to the files and inline archives around the one being read:
    /// an `ElseIf`, `Else` or `IfEnd` cannot reach them.
    branches_floor: usize,
    /// What conditions read: the frame number, options and attributes.
    vars: CondVars,
    /// What is left of [`CONDITION_BUDGET`].
    condition_work: usize,
    /// `ColorSamples`: the colours written from here on, `None` for RGB.
    colors: Option<ColorSamples>,
    /// The colour samples around each open `FrameBegin` block (an option set in a frame holds for
    /// that frame).
    frame_colors: Vec<Option<ColorSamples>>,
}

/// `ColorSamples n nRGB RGBn`: colours are written with `n` samples each, which `nRGB` (`n` rows
/// of 3) turns into RGB as the stream is read: a colour `c` is `c nRGB`. (`RGBn` turns RGB into
/// samples, which nothing in rtsl needs: shaders compute in RGB.)
#[derive(Clone, Debug)]
struct ColorSamples {
    n: usize,
    to_rgb: Vec<f32>,
}

impl ColorSamples {
    /// The RGB colours of `values`, `n` samples each (a whole number of colours).
    fn to_rgb(&self, values: &[f32]) -> Vec<f32> {
        values
            .chunks_exact(self.n)
            .flat_map(|c| {
                let mut rgb = [0.0f32; 3];
                for (i, sample) in c.iter().enumerate() {
                    for (j, out) in rgb.iter_mut().enumerate() {
                        *out += sample * self.to_rgb[3 * i + j];
                    }
                }
                rgb
            })
            .collect()
    }
}

/// An open `IfBegin` block.
struct Branch {
    /// Whether the requests read now are kept.
    active: bool,
    /// Whether a branch of the block was (or is being) taken, or the whole block is skipped.
    done: bool,
    /// Whether `Else` was read.
    had_else: bool,
    /// Where the block began.
    loc: Location,
}

/// The state conditional expressions read, kept as the requests are read in stream order: the
/// frame being read (numbered as [`super::load::Frames`] numbers them), and the `Option` and
/// `Attribute` parameters in force, options scoped by frames and attributes by attribute blocks
/// (frames and world blocks included), as RenderMan scopes them.
#[derive(Default)]
struct CondVars {
    frame: f64,
    images: usize,
    in_frame: bool,
    in_world: bool,
    options: Vec<HashMap<String, Value>>,
    attributes: Vec<HashMap<String, Value>>,
}

impl CondVars {
    fn track(&mut self, kind: &K) {
        fn set(layers: &mut Vec<HashMap<String, Value>>, shader: &Shader) {
            if layers.is_empty() {
                layers.push(HashMap::new());
            }
            let Some(top) = layers.last_mut() else { return };
            for p in &shader.params {
                let value = match &p.value {
                    ParamValue::Floats(v) => v.first().map(|&x| Value::Num(f64::from(x))),
                    ParamValue::Ints(v) => v.first().map(|&x| Value::Num(f64::from(x))),
                    ParamValue::Strings(v) => v.first().map(|x| Value::Str(x.clone())),
                };
                if let Some(value) = value {
                    top.insert(format!("{}:{}", shader.name, p.name), value);
                }
            }
        }
        match kind {
            K::FrameBegin(number) if !self.in_frame => {
                self.in_frame = true;
                self.images += 1;
                self.frame = number.map_or(self.images as f64, f64::from);
                self.options.push(HashMap::new());
                self.attributes.push(HashMap::new());
            }
            K::FrameEnd if self.in_frame => {
                self.in_frame = false;
                self.options.pop();
                self.attributes.pop();
            }
            K::WorldBegin => {
                if !self.in_frame && !self.in_world {
                    self.images += 1;
                    self.frame = self.images as f64;
                }
                self.in_world = true;
                self.attributes.push(HashMap::new());
            }
            K::WorldEnd => {
                self.in_world = false;
                self.attributes.pop();
            }
            K::AttributeBegin => self.attributes.push(HashMap::new()),
            K::AttributeEnd => {
                self.attributes.pop();
            }
            K::Option(o) => set(&mut self.options, o),
            K::Attribute(a) => set(&mut self.attributes, a),
            _ => {}
        }
    }

    /// The value of `$name`.
    fn lookup(&self, name: &str) -> Option<Value> {
        let find = |layers: &[HashMap<String, Value>], key: &str| layers.iter().rev().find_map(|l| l.get(key)).cloned();
        if name == "Frame" {
            Some(Value::Num(self.frame))
        } else if let Some(key) = name.strip_prefix("Option:") {
            find(&self.options, key)
        } else if let Some(key) = name.strip_prefix("Attribute:") {
            find(&self.attributes, key)
        } else {
            find(&self.options, name).or_else(|| find(&self.attributes, name))
        }
    }
}

/// How much reading inline archives may copy into one stream, weighed as [`REQUEST_WEIGHT`] a
/// request plus one per argument and array element: an archive read twice by an archive read
/// twice, and so on, doubles at every level.
pub const INLINE_ARCHIVE_BUDGET: usize = 1 << 24;

/// A request's own weight in [`INLINE_ARCHIVE_BUDGET`], beyond its values: what holding it costs
/// counted in values.
const REQUEST_WEIGHT: usize = 16;

fn location(file: &Arc<Path>, token: &Token) -> Location {
    Location { file: file.clone(), line: token.line, column: token.column }
}

fn error(loc: &Location, message: impl Into<String>) -> RibDiagnostic {
    RibDiagnostic::error(loc, message)
}

fn is_name(token: &Token) -> bool {
    matches!(token.kind, TokenKind::Name(_))
}

impl<'s> Parser<'s> {
    pub(super) fn new() -> Self {
        Parser {
            include_stack: Vec::new(),
            depth: 0,
            decls: DeclTable::new(),
            requests: Vec::new(),
            sink: None,
            stopped: false,
            diagnostics: Vec::new(),
            archives: Vec::new(),
            inline_archives: HashMap::new(),
            open_archives: Vec::new(),
            refused_archives: Vec::new(),
            weight: 0,
            expansion_left: INLINE_ARCHIVE_BUDGET,
            archive_path: Vec::new(),
            branches: Vec::new(),
            branches_too_deep: 0,
            branches_floor: 0,
            vars: CondVars::default(),
            condition_work: CONDITION_BUDGET,
            colors: None,
            frame_colors: Vec::new(),
        }
    }

    /// A parser that hands each request to `sink` as it is read (its [`Parser::finish`] then holds
    /// no requests).
    pub(super) fn with_sink(sink: &'s mut dyn RibSink) -> Self {
        Parser { sink: Some(sink), ..Parser::new() }
    }

    /// Reports a diagnostic: to the sink, when it takes them, else into the result.
    fn diagnose(&mut self, d: RibDiagnostic) {
        match &mut self.sink {
            Some(sink) if sink.takes_diagnostics() => sink.diagnostic(d),
            _ => self.diagnostics.push(d),
        }
    }

    pub(super) fn finish(self) -> RibParse {
        RibParse { requests: self.requests, diagnostics: self.diagnostics, archives: self.archives }
    }

    /// Reads one file's bytes (ASCII or binary RIB, gzip-compressed or not), appending its
    /// requests.
    pub(super) fn parse_file_text(&mut self, bytes: &[u8], file: Arc<Path>) {
        let inflated;
        let bytes = if bytes.starts_with(&GZIP_MAGIC) {
            match inflate(bytes) {
                Ok(text) => {
                    inflated = text;
                    &inflated[..]
                }
                Err(message) => {
                    let loc = Location { file, line: 1, column: 1 };
                    self.diagnose(error(&loc, message));
                    return;
                }
            }
        } else {
            bytes
        };
        let archives_open_before = self.open_archives.len();
        let refused_before = self.refused_archives.len();
        let floor = std::mem::replace(&mut self.branches_floor, self.branches.len());
        let too_deep = std::mem::take(&mut self.branches_too_deep);
        // One request's tokens at a time (`lex::tokens`).
        let mut tokens = tokens(bytes).peekable();
        while let Some(token) = tokens.next() {
            if self.stopped {
                return;
            }
            let loc = location(&file, &token);
            let TokenKind::Name(name) = token.kind else {
                let message = match token.kind {
                    TokenKind::Error(message) => message,
                    TokenKind::Number(_) => "expected a request name, found a number".into(),
                    TokenKind::Str(_) => "expected a request name, found a string".into(),
                    TokenKind::OpenBracket => "expected a request name, found `[`".into(),
                    _ => "expected a request name, found `]`".into(),
                };
                self.diagnose(error(&loc, message));
                while tokens.next_if(|t| !is_name(t)).is_some() {}
                continue;
            };
            match collect_args(&mut tokens, &file) {
                Ok(args) => self.request(&name, loc, &args),
                Err(diagnostic) => self.diagnose(diagnostic),
            }
        }
        // An inline archive still open at the end of its file ends there.
        while self.open_archives.len() > archives_open_before {
            if let Some((name, _, _, loc)) = self.open_archives.last() {
                let message = format!("`ArchiveBegin \"{name}\"` has no `ArchiveEnd`; the archive ends with the file");
                self.diagnose(RibDiagnostic::warning(loc, message));
            }
            self.end_archive();
        }
        self.refused_archives.truncate(refused_before);
        self.close_branches("the file");
        self.branches_floor = floor;
        self.branches_too_deep = too_deep;
    }

    fn request(&mut self, name: &str, loc: Location, args: &[Arg]) {
        // In a branch not taken only the conditionals are read, to find where it ends.
        if self.skipping() && !matches!(name, "IfBegin" | "ElseIf" | "Else" | "IfEnd") {
            return;
        }
        let result = match name {
            "ReadArchive" => self.read_archive(&loc, args),
            "Procedural" => self.procedural(&loc, args),
            "System" => {
                let message = "`System` runs a program the scene names, which rtsl does not do; what it would \
                               make is missing";
                self.diagnose(RibDiagnostic::omission(&loc, message));
                Ok(())
            }
            "ArchiveBegin" => {
                let begun = self.begin_archive(&loc, args);
                if begun.is_err() {
                    self.refused_archives.push(self.open_archives.len());
                }
                begun
            }
            "ColorSamples" => self.color_samples(&loc, args),
            // The end of a refused block, whose requests were read where they stand.
            "ArchiveEnd" if self.refused_archives.last() == Some(&self.open_archives.len()) => {
                self.refused_archives.pop();
                Ok(())
            }
            "ArchiveEnd" if self.open_archives.is_empty() => Err(error(&loc, "`ArchiveEnd` without `ArchiveBegin`")),
            "ArchiveEnd" => {
                self.end_archive();
                Ok(())
            }
            _ => {
                self.build_request(name, loc, args);
                return;
            }
        };
        if let Err(diagnostic) = result {
            self.diagnose(diagnostic);
        }
    }

    fn build_request(&mut self, name: &str, loc: Location, args: &[Arg]) {
        self.weight = self.weight.saturating_add(args_weight(args));
        let mut args = Args { request: name, loc: &loc, items: args, pos: 0 };
        let kind = match self.build(name, &mut args) {
            Ok(Some(kind)) => args.finish().map(|()| Some(kind)),
            other => other,
        };
        match kind {
            Ok(Some(kind)) => {
                if let K::Declare { name, decl } = &kind {
                    self.decls.declare(name, *decl);
                }
                match kind {
                    K::FrameBegin(_) => self.frame_colors.push(self.colors.clone()),
                    K::FrameEnd => {
                        if let Some(outer) = self.frame_colors.pop() {
                            self.colors = outer;
                        }
                    }
                    _ => {}
                }
                if let K::Option(option) = &kind {
                    self.archive_search_path(option);
                }
                self.push(Request { kind, loc });
            }
            Ok(None) if IGNORED_REQUESTS.contains(&name) => {
                let message = format!("`{name}` has no effect in rtsl and is ignored");
                self.diagnose(RibDiagnostic::warning(&loc, message));
            }
            Ok(None) => {
                let message = if UNSUPPORTED_REQUESTS.contains(&name) {
                    format!("`{name}` is not supported yet and is skipped")
                } else {
                    format!("unknown request `{name}` skipped")
                };
                self.diagnose(RibDiagnostic::omission(&loc, message));
            }
            Err(diagnostic) => self.diagnose(diagnostic),
        }
    }

    /// Reads the arguments of request `name`; `Ok(None)` for a request this reader does not know.
    fn build(&mut self, name: &str, a: &mut Args) -> Result<Option<K>> {
        let kind = match name {
            "version" => K::Version(a.float("version number")?),
            "Format" => K::Format {
                xres: a.int("xresolution")?,
                yres: a.int("yresolution")?,
                pixel_aspect: a.float("pixel aspect ratio")?,
            },
            "FrameAspectRatio" => K::FrameAspectRatio(a.float("frame aspect ratio")?),
            "ScreenWindow" => K::ScreenWindow(a.floats("left right bottom top")?),
            "CropWindow" => K::CropWindow(a.floats("xmin xmax ymin ymax")?),
            "Projection" => K::Projection(self.shader(a)?),
            "Clipping" => K::Clipping { near: a.float("near distance")?, far: a.float("far distance")? },
            "ClippingPlane" => K::ClippingPlane(a.floats("x y z nx ny nz")?),
            "DepthOfField" => K::DepthOfField(a.floats("fstop focallength focaldistance")?),
            "Shutter" => K::Shutter(a.floats("open and close times")?),
            "Display" => K::Display {
                name: a.string("output name")?,
                driver: a.string("display type")?,
                mode: a.string("display mode")?,
                params: self.params(a),
            },
            "PixelSamples" => K::PixelSamples { x: a.float("x samples")?, y: a.float("y samples")? },
            "PixelFilter" => K::PixelFilter {
                filter: a.string("filter name")?,
                xwidth: a.float("x width")?,
                ywidth: a.float("y width")?,
            },
            "Exposure" => K::Exposure { gain: a.float("gain")?, gamma: a.float("gamma")? },
            "Quantize" => K::Quantize {
                ty: a.string("type")?,
                one: a.float("one")?,
                min: a.float("min")?,
                max: a.float("max")?,
                dither: a.float("dither amplitude")?,
            },
            "ShadingRate" => K::ShadingRate(a.float("shading rate")?),
            "Detail" => K::Detail(a.floats("xmin xmax ymin ymax zmin zmax")?),
            "DetailRange" => K::DetailRange(a.floats("minvisible lowertransition uppertransition maxvisible")?),
            "RelativeDetail" => K::RelativeDetail(a.float("relative detail")?),
            "Option" => K::Option(self.shader(a)?),
            "Attribute" => K::Attribute(self.shader(a)?),
            "Imager" => K::Imager(self.shader(a)?),
            "Camera" => K::Camera(self.shader(a)?),
            "Pixel" => K::Pixel(self.shader(a)?),
            "Surface" => K::Surface(self.shader(a)?),
            "Displacement" => K::Displacement(self.shader(a)?),
            "Atmosphere" => K::Atmosphere(self.shader(a)?),
            "Interior" => K::Interior(self.shader(a)?),
            "Exterior" => K::Exterior(self.shader(a)?),
            "FrameBegin" => K::FrameBegin(if a.is_done() { None } else { Some(a.int("frame number")?) }),
            "FrameEnd" => K::FrameEnd,
            "WorldBegin" => K::WorldBegin,
            "WorldEnd" => K::WorldEnd,
            "AttributeBegin" => K::AttributeBegin,
            "AttributeEnd" => K::AttributeEnd,
            "TransformBegin" => K::TransformBegin,
            "TransformEnd" => K::TransformEnd,
            "ObjectBegin" => K::ObjectBegin(a.handle("object handle")?),
            "ObjectEnd" => K::ObjectEnd,
            "ObjectInstance" => K::ObjectInstance(a.handle("object handle")?),
            "Identity" => K::Identity,
            "Transform" => K::Transform(a.floats("4x4 matrix")?),
            "ConcatTransform" => K::ConcatTransform(a.floats("4x4 matrix")?),
            "Perspective" => K::Perspective(a.float("field of view")?),
            "Translate" => K::Translate(a.floats("dx dy dz")?),
            "Rotate" => K::Rotate { angle: a.float("angle")?, axis: a.floats("axis dx dy dz")? },
            "Scale" => K::Scale(a.floats("sx sy sz")?),
            "Skew" => K::Skew(a.floats("angle dx1 dy1 dz1 dx2 dy2 dz2")?),
            "CoordinateSystem" => K::CoordinateSystem(a.string("coordinate system name")?),
            "CoordSysTransform" => K::CoordSysTransform(a.string("coordinate system name")?),
            "ScopedCoordinateSystem" => K::ScopedCoordinateSystem(a.string("coordinate system name")?),
            "Resource" => {
                K::Resource { name: a.string("resource name")?, ty: a.string("resource type")?, params: self.params(a) }
            }
            "ResourceBegin" => K::ResourceBegin,
            "ResourceEnd" => K::ResourceEnd,
            "LightSource" => {
                let (shader, handle) = self.light(a)?;
                K::LightSource { shader, handle }
            }
            "AreaLightSource" => {
                let (shader, handle) = self.light(a)?;
                K::AreaLightSource { shader, handle }
            }
            "Illuminate" => K::Illuminate { light: a.handle("light handle")?, on: a.int("on/off flag")? != 0 },
            "Color" => K::Color(self.color(a)?),
            "Opacity" => K::Opacity(self.color(a)?),
            "Declare" => {
                let name = a.string("declared name")?;
                let (text, loc) = a.string_at("declaration")?;
                let decl = decl::parse_declaration(&text).map_err(|m| error(&loc, m))?;
                K::Declare { name, decl }
            }
            "Sides" => K::Sides(a.int("number of sides")?),
            "Orientation" => {
                let (text, loc) = a.string_at("orientation")?;
                K::Orientation(match text.as_str() {
                    "outside" => Orientation::Outside,
                    "inside" => Orientation::Inside,
                    "lh" => Orientation::LeftHanded,
                    "rh" => Orientation::RightHanded,
                    other => {
                        return Err(error(
                            &loc,
                            format!(
                                "unknown orientation \"{other}\" (expected \"outside\", \"inside\", \"lh\" or \"rh\")"
                            ),
                        ))
                    }
                })
            }
            "ReverseOrientation" => K::ReverseOrientation,
            "Matte" => K::Matte(a.int("on/off flag")? != 0),
            "ShadingInterpolation" => K::ShadingInterpolation(a.string("interpolation type")?),
            "GeometricRepresentation" => {
                let (representation, loc) = a.string_at("representation")?;
                if representation != "primitive" {
                    let message = format!(
                        "GeometricRepresentation \"{representation}\" is not supported: surfaces are drawn whole"
                    );
                    self.diagnose(RibDiagnostic::warning(&loc, message));
                }
                K::GeometricRepresentation(representation)
            }
            "Hider" => K::Hider(self.shader(a)?),
            "TextureCoordinates" => K::TextureCoordinates(a.floats("s1 t1 s2 t2 s3 t3 s4 t4")?),
            "Bound" => K::Bound(a.floats("xmin xmax ymin ymax zmin zmax")?),
            "MotionBegin" => K::MotionBegin(a.numbers("sample times")?),
            "MotionEnd" => K::MotionEnd,
            "SolidBegin" => K::SolidBegin(a.string("operation")?),
            "SolidEnd" => K::SolidEnd,
            "Basis" => K::Basis { u: a.basis()?, ustep: a.int("u step")?, v: a.basis()?, vstep: a.int("v step")? },
            "Polygon" => K::Polygon(self.params(a)),
            "GeneralPolygon" => K::GeneralPolygon { nvertices: a.ints("vertices per loop")?, params: self.params(a) },
            "PointsPolygons" => K::PointsPolygons {
                nvertices: a.ints("vertices per polygon")?,
                vertices: a.ints("vertex indices")?,
                params: self.params(a),
            },
            "PointsGeneralPolygons" => K::PointsGeneralPolygons {
                nloops: a.ints("loops per polygon")?,
                nvertices: a.ints("vertices per loop")?,
                vertices: a.ints("vertex indices")?,
                params: self.params(a),
            },
            "SubdivisionMesh" => {
                let scheme = a.string("subdivision scheme")?;
                let nvertices = a.ints("vertices per face")?;
                let vertices = a.ints("vertex indices")?;
                // The tag arrays come together or not at all: a string here is a parameter name.
                let (tags, nargs, intargs, floatargs) = match a.peek() {
                    Some(ArgValue::Strings(_) | ArgValue::Numbers(_)) => (
                        a.strings("tags")?,
                        a.ints("tag argument counts")?,
                        a.ints("tag integer arguments")?,
                        a.numbers("tag float arguments")?,
                    ),
                    _ => Default::default(),
                };
                K::SubdivisionMesh {
                    scheme,
                    nvertices,
                    vertices,
                    tags,
                    nargs,
                    intargs,
                    floatargs,
                    params: self.params(a),
                }
            }
            "HierarchicalSubdivisionMesh" => {
                // PRMan's form: three argument counts a tag (integers, floats, strings) and the
                // string arguments after the floats. The tags read are the same as
                // `SubdivisionMesh`'s, which take no strings; a tag's strings (`"creasemethod"`
                // `["chaikin"]`) are counted and left, and the tag is warned of as unsupported.
                let scheme = a.string("subdivision scheme")?;
                let nvertices = a.ints("vertices per face")?;
                let vertices = a.ints("vertex indices")?;
                let tags = a.strings("tags")?;
                let (counts, loc) = (a.ints("tag argument counts")?, a.loc.clone());
                let intargs = a.ints("tag integer arguments")?;
                let floatargs = a.numbers("tag float arguments")?;
                let stringargs = a.strings("tag string arguments")?;
                if counts.len() != 3 * tags.len() {
                    return Err(error(
                        &loc,
                        format!(
                            "`HierarchicalSubdivisionMesh` has {} tags, which take {} argument counts (three a tag), but {} are given",
                            tags.len(),
                            3 * tags.len(),
                            counts.len()
                        ),
                    ));
                }
                let strings: i64 = counts.chunks(3).map(|c| i64::from(c[2])).sum();
                if counts.chunks(3).any(|c| c[2] < 0) || strings != stringargs.len() as i64 {
                    return Err(error(
                        &loc,
                        format!(
                            "the tags' argument counts take {strings} string arguments, but {} are given",
                            stringargs.len()
                        ),
                    ));
                }
                K::SubdivisionMesh {
                    scheme,
                    nvertices,
                    vertices,
                    tags,
                    nargs: counts.chunks(3).flat_map(|c| [c[0], c[1]]).collect(),
                    intargs,
                    floatargs,
                    params: self.params(a),
                }
            }
            "Patch" => K::Patch { ty: a.patch_type()?, params: self.params(a) },
            "PatchMesh" => K::PatchMesh {
                ty: a.patch_type()?,
                nu: a.int("nu")?,
                uwrap: a.wrap()?,
                nv: a.int("nv")?,
                vwrap: a.wrap()?,
                params: self.params(a),
            },
            "NuPatch" => K::NuPatch { u: a.nu_direction("u")?, v: a.nu_direction("v")?, params: self.params(a) },
            "TrimCurve" => {
                // RIB leaves out C's `nloops` (the length of `ncurves`); a file that writes it is read too.
                let nloops = match (a.peek(), a.remaining()) {
                    (Some(ArgValue::Number(_)), 10) => Some(a.int("number of loops")?),
                    _ => None,
                };
                let (ncurves, loc) = (a.ints("curves per loop")?, a.loc.clone());
                if let Some(nloops) = nloops.filter(|&n| usize::try_from(n).ok() != Some(ncurves.len())) {
                    return Err(error(
                        &loc,
                        format!("`TrimCurve` has {nloops} loops but {} curve counts", ncurves.len()),
                    ));
                }
                K::TrimCurve(TrimCurve {
                    ncurves,
                    order: a.ints("curve orders")?,
                    knot: a.numbers("knot vectors")?,
                    min: a.numbers("parameter range starts")?,
                    max: a.numbers("parameter range ends")?,
                    n: a.ints("control points per curve")?,
                    u: a.numbers("control point u")?,
                    v: a.numbers("control point v")?,
                    w: a.numbers("control point w")?,
                })
            }
            "Points" => K::Points(self.params(a)),
            "Curves" => K::Curves {
                ty: a.curve_type()?,
                nvertices: a.ints("vertices per curve")?,
                wrap: a.wrap()?,
                params: self.params(a),
            },
            "Blobby" => K::Blobby {
                nleaf: a.int("number of leaves")?,
                code: a.ints("code")?,
                floats: a.numbers("float operands")?,
                // The strings come as an array; a bare string is a parameter name (a file that
                // leaves out an empty string array is read too).
                strings: match a.peek() {
                    Some(ArgValue::Strings(_) | ArgValue::Numbers(_)) => a.strings("string operands")?,
                    _ => Vec::new(),
                },
                params: self.params(a),
            },
            "Geometry" => K::Geometry { name: a.string("geometry name")?, params: self.params(a) },
            "Sphere" => {
                let [radius, zmin, zmax, thetamax] = a.floats("radius zmin zmax thetamax")?;
                self.quadric(a, Quadric::Sphere { radius, zmin, zmax, thetamax })
            }
            "Cylinder" => {
                let [radius, zmin, zmax, thetamax] = a.floats("radius zmin zmax thetamax")?;
                self.quadric(a, Quadric::Cylinder { radius, zmin, zmax, thetamax })
            }
            "Cone" => {
                let [height, radius, thetamax] = a.floats("height radius thetamax")?;
                self.quadric(a, Quadric::Cone { height, radius, thetamax })
            }
            "Disk" => {
                let [height, radius, thetamax] = a.floats("height radius thetamax")?;
                self.quadric(a, Quadric::Disk { height, radius, thetamax })
            }
            "Torus" => {
                let [major_radius, minor_radius, phimin, phimax, thetamax] =
                    a.floats("majorradius minorradius phimin phimax thetamax")?;
                self.quadric(a, Quadric::Torus { major_radius, minor_radius, phimin, phimax, thetamax })
            }
            "Paraboloid" => {
                let [rmax, zmin, zmax, thetamax] = a.floats("rmax zmin zmax thetamax")?;
                self.quadric(a, Quadric::Paraboloid { rmax, zmin, zmax, thetamax })
            }
            "Hyperboloid" => {
                let [x1, y1, z1, x2, y2, z2, thetamax] = a.floats("x1 y1 z1 x2 y2 z2 thetamax")?;
                let (point1, point2) = (Vec3::new(x1, y1, z1), Vec3::new(x2, y2, z2));
                self.quadric(a, Quadric::Hyperboloid { point1, point2, thetamax })
            }
            "MakeShadow" => {
                let picture = a.string("picture file")?;
                let shadow = a.string("shadow file")?;
                // Its parameters tune a renderer's own map format; a shadow map here is the depth
                // map itself.
                let _ = self.params(a);
                K::MakeShadow { picture, shadow }
            }
            // A latitude-longitude environment map is a texture that wraps around in s and stops at
            // the poles in t.
            "MakeLatLongEnvironment" => K::MakeTexture {
                picture: a.string("picture file")?,
                texture: a.string("texture file")?,
                swrap: "periodic".into(),
                twrap: "clamp".into(),
                filter: a.string("filter name")?,
                swidth: a.float("s filter width")?,
                twidth: a.float("t filter width")?,
                params: self.params(a),
            },
            "MakeCubeFaceEnvironment" => K::MakeCubeFaceEnvironment {
                faces: [
                    a.string("+x face")?,
                    a.string("-x face")?,
                    a.string("+y face")?,
                    a.string("-y face")?,
                    a.string("+z face")?,
                    a.string("-z face")?,
                ],
                texture: a.string("texture file")?,
                fov: a.float("field of view")?,
                filter: a.string("filter name")?,
                swidth: a.float("s filter width")?,
                twidth: a.float("t filter width")?,
                params: self.params(a),
            },
            // RISpec 3.2's bump maps have no reader in its shading language: the map is made as a
            // texture, which a displacement shader reads with `texture()`.
            "MakeBump" => {
                let kind = K::MakeTexture {
                    picture: a.string("picture file")?,
                    texture: a.string("bump file")?,
                    swrap: a.string("s wrap mode")?,
                    twrap: a.string("t wrap mode")?,
                    filter: a.string("filter name")?,
                    swidth: a.float("s filter width")?,
                    twidth: a.float("t filter width")?,
                    params: self.params(a),
                };
                let message = "`MakeBump` is obsolete (RISpec 3.2's shading language reads no bump map): the \
                               map is made as a texture, which a displacement shader reads with `texture()`";
                self.diagnose(RibDiagnostic::warning(a.loc, message));
                kind
            }
            "MakeTexture" => K::MakeTexture {
                picture: a.string("picture file")?,
                texture: a.string("texture file")?,
                swrap: a.string("s wrap mode")?,
                twrap: a.string("t wrap mode")?,
                filter: a.string("filter name")?,
                swidth: a.float("s filter width")?,
                twidth: a.float("t filter width")?,
                params: self.params(a),
            },
            "IfBegin" => K::IfBegin(a.string("condition")?),
            "ElseIf" => K::ElseIf(a.string("condition")?),
            "Else" => K::Else,
            "IfEnd" => K::IfEnd,
            _ => return Ok(None),
        };
        Ok(Some(kind))
    }

    /// Adds a request read (or copied from an inline archive): kept as it is inside an inline
    /// archive being defined; otherwise conditionals are evaluated, and other requests kept unless
    /// they are in a branch not taken.
    fn push(&mut self, r: Request) {
        if !self.open_archives.is_empty() {
            self.requests.push(r);
            return;
        }
        match &r.kind {
            K::IfBegin(expr) => self.if_begin(expr, &r.loc),
            K::ElseIf(expr) => self.else_if(expr, &r.loc),
            K::Else => self.else_branch(&r.loc),
            K::IfEnd => self.if_end(&r.loc),
            _ if self.skipping() || self.stopped => {}
            kind => {
                self.vars.track(kind);
                match &mut self.sink {
                    Some(sink) => self.stopped = sink.request(r).is_break(),
                    None => self.requests.push(r),
                }
            }
        }
    }

    /// Whether requests read now are in a branch not taken.
    fn skipping(&self) -> bool {
        self.branches_too_deep > 0 || self.branches.last().is_some_and(|b| !b.active)
    }

    /// The value of a condition; one that cannot be evaluated is false, with a diagnostic.
    fn condition(&mut self, expr: &str, loc: &Location) -> bool {
        let vars = &self.vars;
        match cond::evaluate(expr, &|name| vars.lookup(name), &mut self.condition_work) {
            Ok(value) => value,
            Err(e @ CondError::Undefined(_)) => {
                self.diagnose(RibDiagnostic::warning(loc, format!("condition \"{expr}\": {e}; it is false")));
                false
            }
            Err(e) => {
                self.diagnose(error(loc, format!("condition \"{expr}\": {e}; it is false")));
                false
            }
        }
    }

    fn if_begin(&mut self, expr: &str, loc: &Location) {
        if self.skipping() {
            if self.branches_too_deep > 0 {
                self.branches_too_deep += 1;
            } else {
                self.branches.push(Branch { active: false, done: true, had_else: false, loc: loc.clone() });
            }
            return;
        }
        if self.branches.len() >= MAX_IF_DEPTH {
            let message = format!("`IfBegin` blocks nest deeper than {MAX_IF_DEPTH}; this block is skipped");
            self.diagnose(error(loc, message));
            self.branches_too_deep = 1;
            return;
        }
        let active = self.condition(expr, loc);
        self.branches.push(Branch { active, done: active, had_else: false, loc: loc.clone() });
    }

    /// The innermost open block of the file being read, or an error at `loc` naming `request`.
    fn open_branch(&mut self, request: &str, loc: &Location) -> Option<usize> {
        if self.branches.len() > self.branches_floor {
            Some(self.branches.len() - 1)
        } else {
            self.diagnose(error(loc, format!("`{request}` without `IfBegin`")));
            None
        }
    }

    fn else_if(&mut self, expr: &str, loc: &Location) {
        if self.branches_too_deep > 0 {
            return;
        }
        let Some(i) = self.open_branch("ElseIf", loc) else { return };
        if self.branches[i].had_else {
            self.diagnose(error(loc, "`ElseIf` after `Else`; its branch is skipped"));
            self.branches[i].active = false;
        } else if self.branches[i].done {
            self.branches[i].active = false;
        } else {
            let active = self.condition(expr, loc);
            self.branches[i].active = active;
            self.branches[i].done = active;
        }
    }

    fn else_branch(&mut self, loc: &Location) {
        if self.branches_too_deep > 0 {
            return;
        }
        let Some(i) = self.open_branch("Else", loc) else { return };
        let branch = &mut self.branches[i];
        if branch.had_else {
            self.diagnose(error(loc, "a second `Else` in one `IfBegin` block; its branch is skipped"));
            self.branches[i].active = false;
            return;
        }
        branch.had_else = true;
        branch.active = !branch.done;
        branch.done = true;
    }

    fn if_end(&mut self, loc: &Location) {
        if self.branches_too_deep > 0 {
            self.branches_too_deep -= 1;
        } else if self.open_branch("IfEnd", loc).is_some() {
            self.branches.pop();
        }
    }

    /// Ends the blocks still open at the end of a file or inline archive (`what`), with a
    /// warning at each `IfBegin`.
    fn close_branches(&mut self, what: &str) {
        self.branches_too_deep = 0;
        while self.branches.len() > self.branches_floor {
            if let Some(b) = self.branches.pop() {
                let message = format!("`IfBegin` has no `IfEnd`; the block ends with {what}");
                self.diagnose(RibDiagnostic::warning(&b.loc, message));
            }
        }
    }

    fn quadric(&mut self, a: &mut Args, quadric: Quadric) -> K {
        K::Quadric { quadric, params: self.params(a) }
    }

    fn shader(&mut self, a: &mut Args) -> Result<Shader> {
        let name = a.string("name")?;
        Ok(Shader { name, params: self.params(a) })
    }

    /// `LightSource "name" [handle] params`: the handle is a number, or a string that leaves an
    /// even number of arguments (parameter lists come in pairs).
    fn light(&mut self, a: &mut Args) -> Result<(Shader, Option<Handle>)> {
        let name = a.string("shader name")?;
        let handle = match a.peek() {
            Some(ArgValue::Number(_) | ArgValue::Numbers(_)) => Some(a.handle("light handle")?),
            Some(ArgValue::Str(_)) if a.remaining() % 2 == 1 => Some(a.handle("light handle")?),
            _ => None,
        };
        Ok((Shader { name, params: self.params(a) }, handle))
    }

    /// `ColorSamples n [nRGB] [RGBn]`: how many numbers a colour is written with from here on,
    /// and how they become RGB. Three samples with identity matrices is RGB again.
    fn color_samples(&mut self, loc: &Location, args: &[Arg]) -> Result<()> {
        let mut a = Args { request: "ColorSamples", loc, items: args, pos: 0 };
        let n = a.int("number of samples")?;
        let to_rgb = a.numbers("nRGB matrix")?;
        let from_rgb = a.numbers("RGBn matrix")?;
        a.finish()?;
        let n = usize::try_from(n).ok().filter(|&n| n >= 1).ok_or_else(|| {
            error(loc, format!("`ColorSamples` needs at least 1 sample, not {n}; colours stay as they were"))
        })?;
        for (what, matrix) in [("nRGB", &to_rgb), ("RGBn", &from_rgb)] {
            if matrix.len() != 3 * n {
                let message = format!(
                    "`ColorSamples {n}` needs a {what} matrix of {} numbers, not {}; colours stay as they were",
                    3 * n,
                    matrix.len()
                );
                return Err(error(loc, message));
            }
        }
        if !to_rgb.iter().all(|x| x.is_finite()) {
            return Err(error(loc, "`ColorSamples`'s nRGB matrix is not finite; colours stay as they were"));
        }
        let identity = n == 3 && to_rgb.iter().enumerate().all(|(i, &x)| x == if i % 4 == 0 { 1.0 } else { 0.0 });
        self.colors = (!identity).then_some(ColorSamples { n, to_rgb });
        Ok(())
    }

    /// A `Color` or `Opacity` argument: as many numbers as `ColorSamples` says, as RGB.
    fn color(&self, a: &mut Args) -> Result<[f32; 3]> {
        let Some(samples) = &self.colors else { return a.floats("r g b") };
        let values = a.float_list(samples.n, "one number a colour sample")?;
        let rgb = samples.to_rgb(&values);
        Ok([rgb[0], rgb[1], rgb[2]])
    }

    /// The rest of the arguments as a parameter list.
    fn params(&mut self, a: &mut Args) -> Vec<Param> {
        let mut params = Vec::new();
        while let Some(name_arg) = a.items.get(a.pos) {
            let ArgValue::Str(written) = &name_arg.value else {
                self.diagnose(error(
                    &name_arg.loc,
                    format!(
                        "expected a parameter name (a string) in `{}`'s parameter list, found {}",
                        a.request,
                        name_arg.value.describe()
                    ),
                ));
                a.pos = a.items.len();
                break;
            };
            let Some(value_arg) = a.items.get(a.pos + 1) else {
                self.diagnose(error(&name_arg.loc, format!("parameter \"{written}\" has no value")));
                a.pos = a.items.len();
                break;
            };
            a.pos += 2;
            if let Some(param) = self.param(written, &name_arg.loc, value_arg) {
                params.push(param);
            }
        }
        params
    }

    fn param(&mut self, written: &str, loc: &Location, value: &Arg) -> Option<Param> {
        let (decl, name) = if decl::is_inline(written) {
            match decl::parse_inline(written) {
                Ok(found) => found,
                Err(message) => {
                    self.diagnose(error(loc, message));
                    return None;
                }
            }
        } else if let Some(decl) = self.decls.get(written) {
            (decl, written.to_string())
        } else {
            // Typed later by the shader it is given to (a warning there if it has no such parameter).
            let ty = match &value.value {
                ArgValue::Str(_) | ArgValue::Strings(_) => Ty::String,
                _ => Ty::Float,
            };
            (Decl { class: Class::Implicit, ty, array_len: None }, written.to_string())
        };
        let converted = match (&self.colors, decl.ty) {
            (Some(samples), Ty::Color) => colors_to_rgb(samples, &decl, &value.value),
            _ => convert_value(&decl, &value.value),
        };
        match converted {
            Ok(value) => Some(Param { name, decl, value, loc: loc.clone() }),
            Err(message) => {
                self.diagnose(error(&value.loc, format!("parameter \"{name}\" ({decl}): {message}")));
                None
            }
        }
    }

    /// `Option "searchpath" "archive" "dirs"`: `:`-separated, `&` for the previous path, relative
    /// directories against the directory of the file that sets it.
    fn archive_search_path(&mut self, option: &Shader) {
        if option.name != "searchpath" {
            return;
        }
        for p in option.params.iter().filter(|p| p.name == "archive") {
            let Some(spec) = p.strings().and_then(|s| s.first()) else { continue };
            let base = base_dir(&p.loc.file);
            let mut path = Vec::new();
            for part in spec.split(':').filter(|part| !part.is_empty()) {
                if part == "&" {
                    path.extend(self.archive_path.iter().cloned());
                } else {
                    path.push(base.join(part));
                }
            }
            self.archive_path = path;
        }
    }

    /// `ArchiveBegin "name" params`: the requests up to the matching `ArchiveEnd` are kept under
    /// `name` for `ReadArchive "name"`, not rendered where they stand.
    fn begin_archive(&mut self, loc: &Location, args: &[Arg]) -> Result<()> {
        let mut a = Args { request: "ArchiveBegin", loc, items: args, pos: 0 };
        let name = a.string("archive name")?;
        // Its parameters are hints for a RIB writer; nothing here reads them.
        let _ = self.params(&mut a);
        if self.open_archives.len() >= MAX_ARCHIVE_DEPTH {
            return Err(error(loc, format!("inline archives nest deeper than {MAX_ARCHIVE_DEPTH}")));
        }
        self.open_archives.push((name, self.requests.len(), self.weight, loc.clone()));
        Ok(())
    }

    fn end_archive(&mut self) {
        if let Some((name, start, weight_before, _)) = self.open_archives.pop() {
            let requests: Arc<[Request]> = self.requests.drain(start..).collect();
            self.inline_archives.insert(name, (requests, self.weight.saturating_sub(weight_before)));
        }
    }

    /// Where a relative archive path is found: the `archive` search path, the current directory
    /// (RenderMan's default), then the directory of the file that reads it (so that a scene and
    /// its archives render from any directory). The first that exists wins; `None` if none does.
    fn find_archive(&self, name: &str, including_file: &Path) -> Option<PathBuf> {
        let path = Path::new(name);
        if path.is_absolute() {
            return Some(path.to_path_buf());
        }
        let cwd = Path::new(".");
        let fallback = base_dir(including_file);
        let found = self
            .archive_path
            .iter()
            .map(PathBuf::as_path)
            .chain([cwd, fallback.as_path()])
            .map(|dir| dir.join(path))
            .find(|p| p.is_file());
        found
    }

    /// Expands `ReadArchive "name"` in place: an inline archive of that name, or a file.
    fn read_archive(&mut self, loc: &Location, args: &[Arg]) -> Result<()> {
        let mut a = Args { request: "ReadArchive", loc, items: args, pos: 0 };
        let name = a.string("archive file name")?;
        a.finish()?;
        self.expand_archive(loc, name)
    }

    /// `Procedural "DelayedReadArchive" ["file"] [bound]` reads the archive where it stands (a ray
    /// tracer cannot wait for a bound to be reached); `RunProgram` and `DynamicLoad`, which run
    /// code a scene file names, are refused.
    fn procedural(&mut self, loc: &Location, args: &[Arg]) -> Result<()> {
        let mut a = Args { request: "Procedural", loc, items: args, pos: 0 };
        let kind = a.string("procedural name")?;
        let data = a.strings("procedural arguments")?;
        let _bound: [f32; 6] = a.floats("bound")?;
        a.finish()?;
        match kind.as_str() {
            "DelayedReadArchive" => match data.first() {
                Some(file) => self.expand_archive(loc, file.clone()),
                None => Err(error(loc, "`Procedural \"DelayedReadArchive\"` names no archive")),
            },
            "RunProgram" | "DynamicLoad" => {
                let message = format!(
                    "`Procedural \"{kind}\"` runs code the scene names, which rtsl does not do; what it would make \
                     is missing"
                );
                self.diagnose(RibDiagnostic::omission(loc, message));
                Ok(())
            }
            other => Err(error(
                loc,
                format!("unknown procedural \"{other}\" (RISpec's are DelayedReadArchive, RunProgram and DynamicLoad)"),
            )),
        }
    }

    /// Reads the inline archive or the file `name` into the requests.
    fn expand_archive(&mut self, loc: &Location, name: String) -> Result<()> {
        if let Some((requests, weight)) = self.inline_archives.get(&name).cloned() {
            if weight > self.expansion_left {
                return Err(error(
                    loc,
                    format!("inline archives expand past their budget of {INLINE_ARCHIVE_BUDGET} (at \"{name}\")"),
                ));
            }
            self.expansion_left -= weight;
            self.weight = self.weight.saturating_add(weight);
            let floor = std::mem::replace(&mut self.branches_floor, self.branches.len());
            let too_deep = std::mem::take(&mut self.branches_too_deep);
            for r in requests.iter() {
                if self.stopped {
                    break;
                }
                self.push(r.clone());
            }
            self.close_branches(&format!("the inline archive \"{name}\""));
            self.branches_floor = floor;
            self.branches_too_deep = too_deep;
            return Ok(());
        }
        if self.depth >= MAX_ARCHIVE_DEPTH {
            return Err(error(loc, format!("archives nest deeper than {MAX_ARCHIVE_DEPTH} (at \"{name}\")")));
        }
        // An archive found nowhere is reported at the including file's directory.
        let path = self.find_archive(&name, &loc.file).unwrap_or_else(|| base_dir(&loc.file).join(&name));
        // A mesh file named as an archive is geometry for the engine to load, not RIB to read.
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("obj" | "ply" | "gltf" | "glb")) {
            self.push(Request { kind: crate::rib::RequestKind::MeshArchive(path), loc: loc.clone() });
            return Ok(());
        }
        let unreadable = |e: std::io::Error| error(loc, format!("cannot read archive \"{}\": {e}", path.display()));
        let canonical = std::fs::canonicalize(&path).map_err(unreadable)?;
        if self.include_stack.contains(&canonical) {
            return Err(error(loc, format!("archive \"{}\" includes itself (a ReadArchive cycle)", path.display())));
        }
        let bytes = std::fs::read(&canonical).map_err(unreadable)?;
        if let Some(sink) = &mut self.sink {
            sink.archive(&canonical);
        }
        self.archives.push(canonical.clone());
        self.include_stack.push(canonical);
        self.depth += 1;
        self.parse_file_text(&bytes, Arc::from(path.as_path()));
        self.depth -= 1;
        self.include_stack.pop();
        Ok(())
    }
}

/// The first bytes of a gzip stream.
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// The most bytes a gzip-compressed RIB file may inflate to.
pub const MAX_INFLATED_RIB: u64 = 1 << 30;

/// Inflates a gzip-compressed RIB stream, refusing one that inflates past [`MAX_INFLATED_RIB`].
fn inflate(bytes: &[u8]) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let mut text = Vec::new();
    let mut decoder = flate2::read::MultiGzDecoder::new(bytes).take(MAX_INFLATED_RIB + 1);
    decoder.read_to_end(&mut text).map_err(|e| format!("cannot decompress gzip RIB: {e}"))?;
    if text.len() as u64 > MAX_INFLATED_RIB {
        return Err(format!("gzip RIB inflates to more than {MAX_INFLATED_RIB} bytes"));
    }
    Ok(text)
}

/// A request's weight as read: [`REQUEST_WEIGHT`] and its arguments, arrays counted by their
/// elements.
fn args_weight(args: &[Arg]) -> usize {
    args.iter()
        .map(|a| match &a.value {
            ArgValue::Numbers(v) => v.len() + 1,
            ArgValue::Strings(v) => v.len() + 1,
            _ => 1,
        })
        .sum::<usize>()
        + REQUEST_WEIGHT
}

/// Collects the arguments after a request name, up to the next name. On error the rest of the
/// request is skipped and the first error returned.
fn collect_args(tokens: &mut Peekable<Tokens>, file: &Arc<Path>) -> Result<Vec<Arg>> {
    let mut args = Vec::new();
    let mut first_error = None;
    while let Some(token) = tokens.next_if(|t| !is_name(t)) {
        let loc = location(file, &token);
        let arg = match token.kind {
            TokenKind::Number(x) => Ok(ArgValue::Number(x)),
            TokenKind::Str(s) => Ok(ArgValue::Str(s)),
            TokenKind::OpenBracket => collect_array(tokens, file, &loc),
            TokenKind::CloseBracket => Err(error(&loc, "`]` without a matching `[`")),
            TokenKind::Error(message) => Err(error(&loc, message)),
            TokenKind::Name(_) => unreachable!("the loop stops at names"),
        };
        match arg {
            Ok(value) => args.push(Arg { value, loc }),
            Err(diagnostic) => {
                first_error.get_or_insert(diagnostic);
            }
        }
    }
    match first_error {
        None => Ok(args),
        Some(diagnostic) => Err(diagnostic),
    }
}

/// The elements of an array whose `[` was just read: all numbers or all strings.
fn collect_array(tokens: &mut Peekable<Tokens>, file: &Arc<Path>, open: &Location) -> Result<ArgValue> {
    let mut numbers = Vec::new();
    let mut strings = Vec::new();
    loop {
        let Some(token) = tokens.next_if(|t| !is_name(t)) else {
            return Err(error(open, "`[` is never closed"));
        };
        // The element's place, made into a location only for an error.
        let (line, column) = (token.line, token.column);
        let at = || Location { file: file.clone(), line, column };
        match token.kind {
            TokenKind::CloseBracket => break,
            TokenKind::Number(x) => numbers.push(x),
            TokenKind::Str(s) => strings.push(s),
            TokenKind::OpenBracket => return Err(error(&at(), "arrays do not nest in RIB")),
            TokenKind::Error(message) => return Err(error(&at(), message)),
            TokenKind::Name(_) => unreachable!("the loop stops at names"),
        }
        if !numbers.is_empty() && !strings.is_empty() {
            return Err(error(&at(), "an array mixes numbers and strings"));
        }
    }
    Ok(if strings.is_empty() { ArgValue::Numbers(numbers) } else { ArgValue::Strings(strings) })
}

fn to_int(x: f64) -> std::result::Result<i32, String> {
    if x.fract() == 0.0 && x >= f64::from(i32::MIN) && x <= f64::from(i32::MAX) {
        Ok(x as i32)
    } else {
        Err(format!("{x} is not an integer"))
    }
}

/// A colour parameter's values written with `samples.n` numbers a colour, as RGB.
fn colors_to_rgb(samples: &ColorSamples, decl: &Decl, value: &ArgValue) -> std::result::Result<ParamValue, String> {
    let values: Vec<f32> = match value {
        ArgValue::Number(x) => vec![*x as f32],
        ArgValue::Numbers(v) => v.iter().map(|&x| x as f32).collect(),
        other => return Err(format!("expected numbers, found {}", other.describe())),
    };
    let per_value = samples.n * decl.array_len.unwrap_or(1);
    if values.is_empty() {
        Err("no values given".to_string())
    } else if values.len() % per_value != 0 {
        Err(format!(
            "{} numbers given, which is not a multiple of {per_value} (numbers per value: `ColorSamples` {} a colour)",
            values.len(),
            samples.n
        ))
    } else {
        Ok(ParamValue::Floats(samples.to_rgb(&values)))
    }
}

/// Types a parameter's value by its declaration and checks the count.
fn convert_value(decl: &Decl, value: &ArgValue) -> std::result::Result<ParamValue, String> {
    use ArgValue as A;
    let value = match (decl.ty, value) {
        (Ty::String, A::Str(s)) => ParamValue::Strings(vec![s.clone()]),
        (Ty::String, A::Strings(v)) => ParamValue::Strings(v.clone()),
        (Ty::String, _) => return Err(format!("expected strings, found {}", value.describe())),
        (Ty::Integer, A::Number(x)) => ParamValue::Ints(vec![to_int(*x)?]),
        (Ty::Integer, A::Numbers(v)) => {
            ParamValue::Ints(v.iter().map(|&x| to_int(x)).collect::<std::result::Result<_, _>>()?)
        }
        (Ty::Integer, _) => return Err(format!("expected integers, found {}", value.describe())),
        (_, A::Number(x)) => ParamValue::Floats(vec![*x as f32]),
        (_, A::Numbers(v)) => ParamValue::Floats(v.iter().map(|&x| x as f32).collect()),
        (_, _) => return Err(format!("expected numbers, found {}", value.describe())),
    };
    let per_value = decl.components();
    if value.is_empty() {
        Err("no values given".to_string())
    } else if value.len() % per_value != 0 {
        Err(format!("{} numbers given, which is not a multiple of {per_value} (numbers per value)", value.len()))
    } else {
        Ok(value)
    }
}

/// A cursor over a request's arguments, reading them by the request's signature.
struct Args<'a> {
    request: &'a str,
    loc: &'a Location,
    items: &'a [Arg],
    pos: usize,
}

impl<'a> Args<'a> {
    fn is_done(&self) -> bool {
        self.pos >= self.items.len()
    }

    fn remaining(&self) -> usize {
        self.items.len().saturating_sub(self.pos)
    }

    fn peek(&self) -> Option<&'a ArgValue> {
        self.items.get(self.pos).map(|a| &a.value)
    }

    fn next(&mut self, what: &str) -> Result<&'a Arg> {
        let items = self.items;
        let arg =
            items.get(self.pos).ok_or_else(|| error(self.loc, format!("`{}` is missing its {what}", self.request)))?;
        self.pos += 1;
        Ok(arg)
    }

    /// `N` numbers, written singly or in arrays (`Translate 1 2 3` or `Translate [1 2 3]`).
    fn floats<const N: usize>(&mut self, what: &str) -> Result<[f32; N]> {
        let mut out = [0.0; N];
        let mut n = 0;
        while n < N {
            let Some(arg) = self.items.get(self.pos) else {
                let message = format!("`{}` needs {N} numbers ({what}) but has {n}", self.request);
                return Err(error(self.loc, message));
            };
            match &arg.value {
                ArgValue::Number(x) => {
                    out[n] = *x as f32;
                    n += 1;
                }
                ArgValue::Numbers(xs) if n + xs.len() <= N => {
                    for &x in xs {
                        out[n] = x as f32;
                        n += 1;
                    }
                }
                ArgValue::Numbers(xs) => {
                    let message =
                        format!("`{}` needs {N} numbers ({what}) but this array has {}", self.request, xs.len());
                    return Err(error(&arg.loc, message));
                }
                other => {
                    let message = format!("`{}` expects numbers ({what}), found {}", self.request, other.describe());
                    return Err(error(&arg.loc, message));
                }
            }
            self.pos += 1;
        }
        Ok(out)
    }

    /// `n` numbers, written singly or in arrays, as [`Args::floats`] reads a fixed count.
    fn float_list(&mut self, n: usize, what: &str) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(n.min(self.remaining().max(1) * 16));
        while out.len() < n {
            let Some(arg) = self.items.get(self.pos) else {
                let message = format!("`{}` needs {n} numbers ({what}) but has {}", self.request, out.len());
                return Err(error(self.loc, message));
            };
            match &arg.value {
                ArgValue::Number(x) => out.push(*x as f32),
                ArgValue::Numbers(xs) if out.len() + xs.len() <= n => out.extend(xs.iter().map(|&x| x as f32)),
                ArgValue::Numbers(xs) => {
                    let message =
                        format!("`{}` needs {n} numbers ({what}) but this array has {}", self.request, xs.len());
                    return Err(error(&arg.loc, message));
                }
                other => {
                    let message = format!("`{}` expects numbers ({what}), found {}", self.request, other.describe());
                    return Err(error(&arg.loc, message));
                }
            }
            self.pos += 1;
        }
        Ok(out)
    }

    /// An array of numbers (a single number is accepted as a one-element array).
    fn numbers(&mut self, what: &str) -> Result<Vec<f32>> {
        let arg = self.next(what)?;
        match &arg.value {
            ArgValue::Number(x) => Ok(vec![*x as f32]),
            ArgValue::Numbers(xs) => Ok(xs.iter().map(|&x| x as f32).collect()),
            other => {
                Err(error(&arg.loc, format!("`{}` expects numbers ({what}), found {}", self.request, other.describe())))
            }
        }
    }

    fn float(&mut self, what: &str) -> Result<f32> {
        let [x] = self.floats::<1>(what)?;
        Ok(x)
    }

    fn int(&mut self, what: &str) -> Result<i32> {
        let arg = self.next(what)?;
        let x = match &arg.value {
            ArgValue::Number(x) => *x,
            ArgValue::Numbers(xs) if xs.len() == 1 => xs[0],
            other => {
                return Err(error(
                    &arg.loc,
                    format!("`{}` expects an integer ({what}), found {}", self.request, other.describe()),
                ))
            }
        };
        to_int(x).map_err(|m| error(&arg.loc, format!("`{}` expects an integer ({what}): {m}", self.request)))
    }

    /// An array of integers (a single number is accepted as a one-element array).
    fn ints(&mut self, what: &str) -> Result<Vec<i32>> {
        let arg = self.next(what)?;
        let numbers = match &arg.value {
            ArgValue::Number(x) => std::slice::from_ref(x),
            ArgValue::Numbers(xs) => xs.as_slice(),
            other => {
                let message =
                    format!("`{}` expects an array of integers ({what}), found {}", self.request, other.describe());
                return Err(error(&arg.loc, message));
            }
        };
        numbers
            .iter()
            .map(|&x| to_int(x))
            .collect::<std::result::Result<_, _>>()
            .map_err(|m| error(&arg.loc, format!("`{}` expects integers ({what}): {m}", self.request)))
    }

    /// An array of strings (a single string, and the empty array `[]`, are accepted too).
    fn strings(&mut self, what: &str) -> Result<Vec<String>> {
        let arg = self.next(what)?;
        match &arg.value {
            ArgValue::Str(s) => Ok(vec![s.clone()]),
            ArgValue::Strings(v) => Ok(v.clone()),
            ArgValue::Numbers(xs) if xs.is_empty() => Ok(Vec::new()),
            other => Err(error(
                &arg.loc,
                format!("`{}` expects an array of strings ({what}), found {}", self.request, other.describe()),
            )),
        }
    }

    /// A string and where it was written (a one-element string array is accepted too).
    fn string_at(&mut self, what: &str) -> Result<(String, Location)> {
        let arg = self.next(what)?;
        match &arg.value {
            ArgValue::Str(s) => Ok((s.clone(), arg.loc.clone())),
            ArgValue::Strings(v) if v.len() == 1 => Ok((v[0].clone(), arg.loc.clone())),
            other => Err(error(
                &arg.loc,
                format!("`{}` expects a string ({what}), found {}", self.request, other.describe()),
            )),
        }
    }

    fn string(&mut self, what: &str) -> Result<String> {
        self.string_at(what).map(|(s, _)| s)
    }

    fn handle(&mut self, what: &str) -> Result<Handle> {
        match self.peek() {
            Some(ArgValue::Str(_) | ArgValue::Strings(_)) => Ok(Handle::Name(self.string(what)?)),
            _ => Ok(Handle::Number(self.int(what)?)),
        }
    }

    fn patch_type(&mut self) -> Result<PatchType> {
        let (text, loc) = self.string_at("patch type")?;
        match text.as_str() {
            "bilinear" => Ok(PatchType::Bilinear),
            "bicubic" => Ok(PatchType::Bicubic),
            other => Err(error(&loc, format!("unknown patch type \"{other}\" (expected \"bilinear\" or \"bicubic\")"))),
        }
    }

    fn curve_type(&mut self) -> Result<CurveType> {
        let (text, loc) = self.string_at("curve type")?;
        match text.as_str() {
            "linear" => Ok(CurveType::Linear),
            "cubic" => Ok(CurveType::Cubic),
            other => Err(error(&loc, format!("unknown curve type \"{other}\" (expected \"linear\" or \"cubic\")"))),
        }
    }

    fn wrap(&mut self) -> Result<Wrap> {
        let (text, loc) = self.string_at("wrap mode")?;
        match text.as_str() {
            "periodic" => Ok(Wrap::Periodic),
            // `nowrap` is the older name (`RI_NOWRAP` in ri.h), which the RenderMan Companion's
            // RIB files use.
            "nonperiodic" | "nowrap" => Ok(Wrap::NonPeriodic),
            other => {
                Err(error(&loc, format!("unknown wrap mode \"{other}\" (expected \"periodic\" or \"nonperiodic\")")))
            }
        }
    }

    fn basis(&mut self) -> Result<Basis> {
        match self.peek() {
            Some(ArgValue::Str(_) | ArgValue::Strings(_)) => Ok(Basis::Named(self.string("basis name")?)),
            _ => Ok(Basis::Matrix(self.floats("basis matrix")?)),
        }
    }

    /// One direction of a `NuPatch`: `n order [knots] min max`.
    fn nu_direction(&mut self, axis: &str) -> Result<NuDirection> {
        Ok(NuDirection {
            n: self.int(&format!("n{axis} (control points along {axis})"))?,
            order: self.int(&format!("{axis} order"))?,
            knots: self.numbers(&format!("{axis} knot vector"))?,
            min: self.float(&format!("{axis}min"))?,
            max: self.float(&format!("{axis}max"))?,
        })
    }

    /// Checks that every argument was used.
    fn finish(&self) -> Result<()> {
        match self.items.get(self.pos) {
            None => Ok(()),
            Some(extra) => Err(error(
                &extra.loc,
                format!("unexpected extra argument to `{}`: {}", self.request, extra.value.describe()),
            )),
        }
    }
}

//! The AFF reader: BART's "animated file format" (Lext, Assarsson and Möller, "BART: A Benchmark
//! for Animated Ray Tracing", 2001), which is Eric Haines' NFF plus keyframe animation, transform
//! hierarchies, meshes, textures and includes, parsed into an [`AffScene`].
//!
//! Commands (the first word of a statement; statements may span lines):
//!
//! | command | meaning |
//! |---|---|
//! | `v` + `from`, `at`, `up`, `angle`, `hither`, `resolution` lines | the viewpoint |
//! | `b r g b` | background colour |
//! | `l x y z [r g b]` | a point light (white without a colour) |
//! | `f r g b Kd Ks shine T ior` | NFF material: diffuse `Kd * rgb`, white specular `Ks` |
//! | `fm ar ag ab dr dg db sr sg sb shine T ior` | BART material: ambient, diffuse, specular colours |
//! | `am r g b` | ambient light |
//! | `c bx by bz br ax ay az ar` | a cone or cylinder (open) from base to apex |
//! | `s x y z r` | a sphere |
//! | `p n` + n vertices / `pp n` + n vertices with normals | a polygon / polygonal patch |
//! | `tt tex` + 3 × `x y z u v` | a textured triangle |
//! | `ttp tex` + 3 × `x y z nx ny nz u v` | a textured triangle patch |
//! | `tpa n` + n × (time, 3 × `x y z nx ny nz`) | an animated triangle (linear between its keys) |
//! | `m` + `vertices n`, `normals n`, `texturecoords n [tex]`, `triangles n` blocks | a mesh; each triangle is 3 vertex indices, then 3 normal and 3 texture-coordinate indices when those blocks exist |
//! | `i level file` | include (relative to the including file); the detail level is read and ignored |
//! | `a start end frames` | the animation's time span and frame count |
//! | `k name { transl n ... rot n ... scale n ... visibility n ... }` | keyframes: `time x y z T C B`, rotations `time ax ay az degrees T C B`, visibility `time 0/1` |
//! | `x name { ... }` | a node animated by the keyframes of that name |
//! | `xs sx sy sz ax ay az degrees tx ty tz { ... }` | a static node: scale, then rotate, then translate |
//! | `}` | ends the innermost node |
//!
//! `%` and `#` at the start of a word comment out the rest of the line (the files use both, also
//! after the numbers of a statement). The material and texture state is global, as in NFF: an
//! `fm` inside a node or an included file stays current after it.
//!
//! Errors: malformed statements stop the parse with an [`AffError`] naming the file, line and
//! column; what cannot be honoured (an unknown command, a missing include, a node animated by
//! keyframes that do not exist) is a warning with its location, given once per kind, and the parse
//! goes on. Nothing here panics on bad input, and counts in the file never size an allocation
//! beyond what the file can hold.

use super::animation::{AxisAngle, Key, Keyframes, RotationTrack, Tcb, VectorTrack, VisibilityTrack};
use glam::{Affine3A, Vec2, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where something is in the files: file, 1-based line and column (in bytes).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    pub file: Arc<Path>,
    pub line: u32,
    pub column: u32,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
    }
}

/// A malformed AFF file.
#[derive(Debug, thiserror::Error)]
pub enum AffError {
    #[error("{at}: {message}")]
    Syntax { at: Location, message: String },
    // The I/O error is the source (printed after this by an error chain), not part of the message.
    #[error("cannot read {}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
}

/// The viewpoint (`v`).
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    pub from: Vec3,
    pub at: Vec3,
    pub up: Vec3,
    /// The field of view in degrees (taken as vertical, as OpenGL's `gluPerspective`).
    pub angle: f32,
    pub hither: f32,
    pub resolution: Option<(u32, u32)>,
}

impl Default for Viewpoint {
    fn default() -> Self {
        Viewpoint {
            from: Vec3::new(0.0, 0.0, 1.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            angle: 45.0,
            hither: 1e-3,
            resolution: None,
        }
    }
}

/// A point light (`l`), in the space of its node.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    pub position: Vec3,
    pub color: Vec3,
    pub node: usize,
    pub at: Location,
}

/// A material (`f` or `fm`), NFF's terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub ambient: Vec3,
    pub diffuse: Vec3,
    pub specular: Vec3,
    /// Phong exponent of the highlight.
    pub shine: f32,
    /// Transmittance: the share of light passing through.
    pub transmittance: f32,
    pub index_of_refraction: f32,
}

impl Material {
    /// What surfaces get before any `f` or `fm`: light grey, matte.
    pub const DEFAULT: Material = Material {
        ambient: Vec3::ZERO,
        diffuse: Vec3::splat(0.8),
        specular: Vec3::ZERO,
        shine: 0.0,
        transmittance: 0.0,
        index_of_refraction: 1.0,
    };

    fn bits(&self) -> [u32; 12] {
        let v = [
            self.ambient.to_array(),
            self.diffuse.to_array(),
            self.specular.to_array(),
            [self.shine, self.transmittance, self.index_of_refraction],
        ];
        let mut out = [0u32; 12];
        for (o, x) in out.iter_mut().zip(v.iter().flatten()) {
            *o = x.to_bits();
        }
        out
    }
}

/// How a node is placed in its parent.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeTransform {
    /// `xs`, or the root (identity).
    Static(Affine3A),
    /// `x NAME`: the keyframes named `NAME`, evaluated per frame.
    Animated(String),
}

/// A node of the transform hierarchy; node 0 is the root. Parents come before their children.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub parent: Option<usize>,
    pub transform: NodeTransform,
    pub at: Location,
}

/// A texture named by a primitive, with the directory of the file that named it.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    pub name: String,
    pub dir: Arc<Path>,
    pub at: Location,
}

/// One key of an animated triangle (`tpa`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleKey {
    pub time: f32,
    pub positions: [Vec3; 3],
    pub normals: [Vec3; 3],
}

/// A triangle mesh in a node's space: optional per-vertex normals and texture coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Triangles {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
}

/// What a shape is.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// Polygons (`p`, `pp`), textured triangles (`tt`, `ttp`) and meshes (`m`).
    Triangles(Triangles),
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// An open truncated cone from `base` to `apex`.
    Cone {
        base: Vec3,
        base_radius: f32,
        apex: Vec3,
        apex_radius: f32,
    },
    /// A triangle whose corners move (`tpa`), keys sorted by time.
    AnimatedTriangle(Vec<TriangleKey>),
}

/// A primitive with its node, material and texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    pub node: usize,
    pub material: usize,
    pub texture: Option<TextureRef>,
    pub geometry: Geometry,
    pub at: Location,
}

/// The `a` line: the animation runs from `start` to `end` (seconds) in `frames` frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnimationParams {
    pub start: f32,
    pub end: f32,
    pub frames: u32,
}

/// A parsed AFF scene.
#[derive(Clone, Debug)]
pub struct AffScene {
    pub viewpoint: Option<Viewpoint>,
    pub background: Option<Vec3>,
    pub ambient: Option<Vec3>,
    pub lights: Vec<Light>,
    /// Distinct materials; `materials[0]` is [`Material::DEFAULT`].
    pub materials: Vec<Material>,
    pub nodes: Vec<Node>,
    pub shapes: Vec<Shape>,
    pub keyframes: Vec<Keyframes>,
    pub animation: Option<AnimationParams>,
    /// What was skipped, each with its location (one per kind of problem).
    pub warnings: Vec<String>,
    /// Every file read (the scene and its includes), each once.
    pub files: Vec<PathBuf>,
}

impl AffScene {
    /// The keyframes named `name`, if any.
    pub fn keyframes(&self, name: &str) -> Option<&Keyframes> {
        self.keyframes.iter().find(|k| k.name == name)
    }

    /// Triangles given as triangles or polygons (`p`, `pp`, `tt`, `ttp`, `m`, `tpa`), before
    /// spheres and cones are tessellated.
    pub fn triangle_count(&self) -> usize {
        self.shapes
            .iter()
            .map(|s| match &s.geometry {
                Geometry::Triangles(t) => t.triangles.len(),
                Geometry::AnimatedTriangle(_) => 1,
                Geometry::Sphere { .. } | Geometry::Cone { .. } => 0,
            })
            .sum()
    }
}

/// Parses the AFF file at `path` and the files it includes.
pub fn parse_file(path: &Path) -> Result<AffScene, AffError> {
    let bytes = std::fs::read(path).map_err(|source| AffError::Read { path: path.to_path_buf(), source })?;
    let mut parser = Parser::new();
    parser.files.insert(path.to_path_buf());
    parser.parse_text(&bytes, path, 0)?;
    Ok(parser.finish())
}

/// Parses AFF text; `name` names it in messages and its directory resolves includes.
pub fn parse_str(text: &str, name: &Path) -> Result<AffScene, AffError> {
    let mut parser = Parser::new();
    parser.parse_text(text.as_bytes(), name, 0)?;
    Ok(parser.finish())
}

/// Includes nested deeper than this are refused (a file that includes itself).
const MAX_INCLUDE_DEPTH: usize = 32;

/// The most elements a count in the file may announce (a mesh of 50 million triangles is far beyond
/// BART's; a garbage count is an error rather than an allocation).
const MAX_COUNT: usize = 50_000_000;

/// The viewpoint's resolution is clamped to this many pixels a side as it is read (so that it fits
/// the options' `u32`s); the renderer's image-size limit then refuses what is still too large.
const MAX_RESOLUTION: usize = 1 << 16;

#[derive(Clone, Copy, Debug)]
struct Tok<'a> {
    text: &'a [u8],
    line: u32,
    column: u32,
    /// The first word on its line.
    line_start: bool,
}

impl Tok<'_> {
    fn is(&self, word: &str) -> bool {
        self.text == word.as_bytes()
    }

    fn show(&self) -> String {
        String::from_utf8_lossy(self.text).into_owned()
    }

    fn number(&self) -> Option<f32> {
        let v: f32 = std::str::from_utf8(self.text).ok()?.parse().ok()?;
        v.is_finite().then_some(v)
    }
}

/// Words separated by white space, with `%` and `#` comments skipped. Works on bytes: the files
/// hold Latin-1 text in comments.
struct Lexer<'a> {
    text: &'a [u8],
    pos: usize,
    line: u32,
    column: u32,
    last_line: u32,
    peeked: Option<Option<Tok<'a>>>,
    file: Arc<Path>,
}

impl<'a> Lexer<'a> {
    fn new(text: &'a [u8], file: Arc<Path>) -> Self {
        Lexer { text, pos: 0, line: 1, column: 1, last_line: 0, peeked: None, file }
    }

    fn scan(&mut self) -> Option<Tok<'a>> {
        loop {
            while let Some(&b) = self.text.get(self.pos) {
                if b > b' ' {
                    break;
                }
                self.pos += 1;
                if b == b'\n' {
                    self.line += 1;
                    self.column = 1;
                } else {
                    self.column += 1;
                }
            }
            let &first = self.text.get(self.pos)?;
            if first == b'%' || first == b'#' {
                while self.text.get(self.pos).is_some_and(|&b| b != b'\n') {
                    self.pos += 1;
                }
                continue;
            }
            let (start, line, column) = (self.pos, self.line, self.column);
            while self.text.get(self.pos).is_some_and(|&b| b > b' ') {
                self.pos += 1;
                self.column += 1;
            }
            let line_start = line != self.last_line;
            self.last_line = line;
            return Some(Tok { text: &self.text[start..self.pos], line, column, line_start });
        }
    }

    fn bump(&mut self) -> Option<Tok<'a>> {
        match self.peeked.take() {
            Some(t) => t,
            None => self.scan(),
        }
    }

    fn peek(&mut self) -> Option<Tok<'a>> {
        if self.peeked.is_none() {
            self.peeked = Some(self.scan());
        }
        self.peeked.flatten()
    }

    fn location(&self, t: &Tok) -> Location {
        Location { file: self.file.clone(), line: t.line, column: t.column }
    }

    /// Where the file ends (for "expected ..., found the end of the file").
    fn end_location(&self) -> Location {
        Location { file: self.file.clone(), line: self.line, column: self.column }
    }

    fn error(&self, t: &Tok, message: String) -> AffError {
        AffError::Syntax { at: self.location(t), message }
    }

    /// The next word, or an error naming what was expected.
    fn word(&mut self, what: &str) -> Result<Tok<'a>, AffError> {
        self.bump().ok_or_else(|| AffError::Syntax {
            at: self.end_location(),
            message: format!("expected {what}, found the end of the file"),
        })
    }

    fn number(&mut self, what: &str) -> Result<f32, AffError> {
        let t = self.word(what)?;
        t.number().ok_or_else(|| self.error(&t, format!("expected {what} (a number), found `{}`", t.show())))
    }

    fn vec3(&mut self, what: &str) -> Result<Vec3, AffError> {
        Ok(Vec3::new(self.number(what)?, self.number(what)?, self.number(what)?))
    }

    fn count(&mut self, what: &str) -> Result<usize, AffError> {
        let t = self.word(what)?;
        let n = std::str::from_utf8(t.text).ok().and_then(|s| s.parse::<usize>().ok());
        match n {
            Some(n) if n <= MAX_COUNT => Ok(n),
            Some(n) => Err(self.error(&t, format!("{what} {n} is more than this reader accepts ({MAX_COUNT})"))),
            None => Err(self.error(&t, format!("expected {what} (a whole number), found `{}`", t.show()))),
        }
    }

    fn index(&mut self, what: &str, limit: usize) -> Result<u32, AffError> {
        let t = self.word(what)?;
        match std::str::from_utf8(t.text).ok().and_then(|s| s.parse::<u32>().ok()) {
            Some(i) if (i as usize) < limit => Ok(i),
            Some(i) => Err(self.error(&t, format!("{what} {i} is out of range (there are {limit})"))),
            None => Err(self.error(&t, format!("expected {what} (a whole number), found `{}`", t.show()))),
        }
    }

    fn expect(&mut self, word: &str, context: &str) -> Result<(), AffError> {
        let t = self.word(&format!("`{word}` {context}"))?;
        if t.is(word) {
            Ok(())
        } else {
            Err(self.error(&t, format!("expected `{word}` {context}, found `{}`", t.show())))
        }
    }

    /// A number that continues the current line (for optional trailing values).
    fn number_on_this_line(&mut self) -> Option<f32> {
        let t = self.peek()?;
        if t.line_start {
            return None;
        }
        let v = t.number()?;
        self.bump();
        Some(v)
    }

    /// A word on the current line that is not a number (a texture name after a count).
    fn name_on_this_line(&mut self) -> Option<Tok<'a>> {
        let t = self.peek()?;
        if t.line_start || t.number().is_some() {
            return None;
        }
        self.bump();
        Some(t)
    }
}

/// Capacity for `n` announced elements: never more than a bound, so a garbage count in a short
/// file cannot reserve gigabytes before the parse fails.
fn capacity(n: usize) -> usize {
    n.min(1 << 16)
}

struct Parser {
    scene: AffScene,
    material_ids: HashMap<[u32; 12], usize>,
    material: usize,
    /// Open nodes, innermost last, with where each was opened.
    open: Vec<(usize, Location)>,
    warned: HashSet<String>,
    files: HashSet<PathBuf>,
    cache: HashMap<PathBuf, Arc<[u8]>>,
}

impl Parser {
    fn new() -> Parser {
        let root_at = Location { file: Arc::from(Path::new("<root>")), line: 0, column: 0 };
        let scene = AffScene {
            viewpoint: None,
            background: None,
            ambient: None,
            lights: Vec::new(),
            materials: vec![Material::DEFAULT],
            nodes: vec![Node { parent: None, transform: NodeTransform::Static(Affine3A::IDENTITY), at: root_at }],
            shapes: Vec::new(),
            keyframes: Vec::new(),
            animation: None,
            warnings: Vec::new(),
            files: Vec::new(),
        };
        let mut material_ids = HashMap::new();
        material_ids.insert(Material::DEFAULT.bits(), 0);
        Parser {
            scene,
            material_ids,
            material: 0,
            open: Vec::new(),
            warned: HashSet::new(),
            files: HashSet::new(),
            cache: HashMap::new(),
        }
    }

    fn finish(mut self) -> AffScene {
        let mut files: Vec<PathBuf> = self.files.into_iter().collect();
        files.sort();
        self.scene.files = files;
        self.scene
    }

    /// A warning, given once per `kind` of problem.
    fn warn(&mut self, kind: &str, at: &Location, message: String) {
        if self.warned.insert(kind.to_string()) {
            self.scene.warnings.push(format!("{at}: warning: {message}"));
        }
    }

    fn node(&self) -> usize {
        self.open.last().map_or(0, |(n, _)| *n)
    }

    fn set_material(&mut self, m: Material) {
        let next = self.scene.materials.len();
        let id = *self.material_ids.entry(m.bits()).or_insert(next);
        if id == next {
            self.scene.materials.push(m);
        }
        self.material = id;
    }

    fn shape(&mut self, lx: &Lexer, t: &Tok, texture: Option<TextureRef>, geometry: Geometry) {
        let at = lx.location(t);
        self.scene.shapes.push(Shape { node: self.node(), material: self.material, texture, geometry, at });
    }

    fn parse_text(&mut self, bytes: &[u8], file: &Path, depth: usize) -> Result<(), AffError> {
        let file: Arc<Path> = Arc::from(file);
        let dir: Arc<Path> = Arc::from(file.parent().unwrap_or(Path::new("")));
        let mut lx = Lexer::new(bytes, file);
        let open_at_start = self.open.len();
        while let Some(t) = lx.bump() {
            self.statement(&mut lx, t, &dir, depth, open_at_start)?;
        }
        if self.open.len() > open_at_start {
            let (_, at) = &self.open[open_at_start];
            return Err(AffError::Syntax {
                at: at.clone(),
                message: "this node is not closed by a `}` before the end of its file".to_string(),
            });
        }
        Ok(())
    }

    fn statement<'a>(
        &mut self,
        lx: &mut Lexer<'a>,
        t: Tok<'a>,
        dir: &Arc<Path>,
        depth: usize,
        open_at_start: usize,
    ) -> Result<(), AffError> {
        let word = std::str::from_utf8(t.text).unwrap_or("");
        match word {
            "v" => self.viewpoint(lx),
            "b" => {
                self.scene.background = Some(lx.vec3("a background colour component")?);
                Ok(())
            }
            "am" => {
                self.scene.ambient = Some(lx.vec3("an ambient light colour component")?);
                Ok(())
            }
            "l" => {
                let position = lx.vec3("a light position coordinate")?;
                let color = match lx.number_on_this_line() {
                    Some(r) => {
                        Vec3::new(r, lx.number("a light colour component")?, lx.number("a light colour component")?)
                    }
                    None => Vec3::ONE,
                };
                let at = lx.location(&t);
                self.scene.lights.push(Light { position, color, node: self.node(), at });
                Ok(())
            }
            "f" => {
                let what = "a value of `f` (r g b Kd Ks shine T ior)";
                let rgb = lx.vec3(what)?;
                let kd = lx.number(what)?;
                let ks = lx.number(what)?;
                let shine = lx.number(what)?;
                let transmittance = lx.number(what)?;
                let index_of_refraction = lx.number(what)?;
                self.set_material(Material {
                    ambient: Vec3::ZERO,
                    diffuse: rgb * kd,
                    specular: Vec3::splat(ks),
                    shine,
                    transmittance,
                    index_of_refraction,
                });
                Ok(())
            }
            "fm" => {
                let what = "a value of `fm` (ambient rgb, diffuse rgb, specular rgb, shine, T, ior)";
                let ambient = lx.vec3(what)?;
                let diffuse = lx.vec3(what)?;
                let specular = lx.vec3(what)?;
                let shine = lx.number(what)?;
                let transmittance = lx.number(what)?;
                let index_of_refraction = lx.number(what)?;
                self.set_material(Material { ambient, diffuse, specular, shine, transmittance, index_of_refraction });
                Ok(())
            }
            "c" => {
                let what = "a value of the cone `c` (base x y z radius, apex x y z radius)";
                let base = lx.vec3(what)?;
                let base_radius = lx.number(what)?;
                let apex = lx.vec3(what)?;
                let apex_radius = lx.number(what)?;
                self.shape(lx, &t, None, Geometry::Cone { base, base_radius, apex, apex_radius });
                Ok(())
            }
            "s" => {
                let what = "a value of the sphere `s` (x y z radius)";
                let center = lx.vec3(what)?;
                let radius = lx.number(what)?;
                self.shape(lx, &t, None, Geometry::Sphere { center, radius });
                Ok(())
            }
            "p" | "pp" => self.polygon(lx, t, word == "pp"),
            "tt" | "ttp" => self.textured_triangle(lx, t, dir, word == "ttp"),
            "tpa" => self.animated_triangle(lx, t),
            "m" => self.mesh(lx, t, dir),
            "i" => self.include(lx, t, dir, depth),
            "a" => {
                let what = "a value of `a` (start time, end time, frames)";
                let start = lx.number(what)?;
                let end = lx.number(what)?;
                let frames = lx.count("the frame count of `a`")?;
                self.scene.animation =
                    Some(AnimationParams { start, end, frames: frames.min(u32::MAX as usize) as u32 });
                Ok(())
            }
            "k" => self.keyframes(lx),
            "x" => {
                let name = lx.word("the name of the keyframes animating this `x` node")?;
                lx.expect("{", "after `x NAME`")?;
                self.open_node(lx, &t, NodeTransform::Animated(name.show()));
                Ok(())
            }
            "xs" => {
                let what = "a value of `xs` (scale xyz, rotation axis xyz and degrees, translation xyz)";
                let scale = lx.vec3(what)?;
                let axis = lx.vec3(what)?;
                let degrees = lx.number(what)?;
                let translation = lx.vec3(what)?;
                lx.expect("{", "after the values of `xs`")?;
                let rotation = AxisAngle { axis, degrees }.to_quat();
                let m = Affine3A::from_scale_rotation_translation(scale, rotation, translation);
                self.open_node(lx, &t, NodeTransform::Static(m));
                Ok(())
            }
            "}" => {
                if self.open.len() <= open_at_start {
                    return Err(lx.error(&t, "`}` without an open `x` or `xs` node in this file".to_string()));
                }
                self.open.pop();
                Ok(())
            }
            _ => {
                let at = lx.location(&t);
                self.warn(
                    &format!("command {word}"),
                    &at,
                    format!("unknown command `{}`: skipped with its values", t.show()),
                );
                // Skip the statement's values: everything up to the next line that starts with a
                // word (a command, known or not, which is then read or reported in turn).
                while let Some(n) = lx.peek() {
                    if n.line_start && n.number().is_none() {
                        break;
                    }
                    lx.bump();
                }
                Ok(())
            }
        }
    }

    fn open_node(&mut self, lx: &Lexer, t: &Tok, transform: NodeTransform) {
        let at = lx.location(t);
        self.scene.nodes.push(Node { parent: Some(self.node()), transform, at: at.clone() });
        self.open.push((self.scene.nodes.len() - 1, at));
    }

    fn viewpoint(&mut self, lx: &mut Lexer) -> Result<(), AffError> {
        let mut v = self.scene.viewpoint.clone().unwrap_or_default();
        while let Some(t) = lx.peek() {
            let what = |field: &str| format!("a value of the viewpoint's `{field}`");
            if t.is("from") {
                lx.bump();
                v.from = lx.vec3(&what("from"))?;
            } else if t.is("at") {
                lx.bump();
                v.at = lx.vec3(&what("at"))?;
            } else if t.is("up") {
                lx.bump();
                v.up = lx.vec3(&what("up"))?;
            } else if t.is("angle") {
                lx.bump();
                v.angle = lx.number(&what("angle"))?;
            } else if t.is("hither") {
                lx.bump();
                v.hither = lx.number(&what("hither"))?;
            } else if t.is("resolution") {
                lx.bump();
                let w = lx.count("the viewpoint's resolution width")?;
                let h = lx.count("the viewpoint's resolution height")?;
                v.resolution = Some((w.min(MAX_RESOLUTION) as u32, h.min(MAX_RESOLUTION) as u32));
            } else {
                break;
            }
        }
        self.scene.viewpoint = Some(v);
        Ok(())
    }

    fn polygon<'a>(&mut self, lx: &mut Lexer<'a>, t: Tok<'a>, with_normals: bool) -> Result<(), AffError> {
        let n = lx.count("the vertex count of the polygon")?;
        let mut positions = Vec::with_capacity(capacity(n));
        let mut normals = Vec::with_capacity(if with_normals { capacity(n) } else { 0 });
        for _ in 0..n {
            positions.push(lx.vec3("a polygon vertex coordinate")?);
            if with_normals {
                normals.push(lx.vec3("a polygon vertex normal component")?);
            }
        }
        if n < 3 {
            let at = lx.location(&t);
            self.warn("degenerate polygon", &at, format!("a polygon of {n} vertices has no area: skipped"));
            return Ok(());
        }
        let mut triangles = Vec::with_capacity(n - 2);
        let fan: Vec<u32> = (0..n as u32).collect();
        // At least 3 vertices, so the fan cannot fail.
        let _ = crate::geometry::mesh::triangulate_into(0, &fan, &mut triangles);
        let tris = Triangles { positions, normals: with_normals.then_some(normals), uvs: None, triangles };
        self.shape(lx, &t, None, Geometry::Triangles(tris));
        Ok(())
    }

    fn texture_ref(&self, lx: &Lexer, t: &Tok, dir: &Arc<Path>) -> TextureRef {
        TextureRef { name: t.show(), dir: dir.clone(), at: lx.location(t) }
    }

    fn textured_triangle<'a>(
        &mut self,
        lx: &mut Lexer<'a>,
        t: Tok<'a>,
        dir: &Arc<Path>,
        with_normals: bool,
    ) -> Result<(), AffError> {
        let name = lx.word("the texture file name of the textured triangle")?;
        let texture = self.texture_ref(lx, &name, dir);
        let mut tris = Triangles { triangles: vec![[0, 1, 2]], ..Default::default() };
        let (mut normals, mut uvs) = (Vec::new(), Vec::new());
        for _ in 0..3 {
            tris.positions.push(lx.vec3("a textured triangle vertex coordinate")?);
            if with_normals {
                normals.push(lx.vec3("a textured triangle vertex normal component")?);
            }
            uvs.push(Vec2::new(lx.number("a texture coordinate")?, lx.number("a texture coordinate")?));
        }
        tris.normals = with_normals.then_some(normals);
        tris.uvs = Some(uvs);
        self.shape(lx, &t, Some(texture), Geometry::Triangles(tris));
        Ok(())
    }

    fn animated_triangle<'a>(&mut self, lx: &mut Lexer<'a>, t: Tok<'a>) -> Result<(), AffError> {
        let n = lx.count("the key count of the animated triangle `tpa`")?;
        let mut keys = Vec::with_capacity(capacity(n));
        for _ in 0..n {
            let time = lx.number("the time of an animated triangle key")?;
            let mut positions = [Vec3::ZERO; 3];
            let mut normals = [Vec3::ZERO; 3];
            for k in 0..3 {
                positions[k] = lx.vec3("an animated triangle vertex coordinate")?;
                normals[k] = lx.vec3("an animated triangle vertex normal component")?;
            }
            keys.push(TriangleKey { time, positions, normals });
        }
        if keys.is_empty() {
            let at = lx.location(&t);
            self.warn("empty tpa", &at, "an animated triangle with no keys: skipped".to_string());
            return Ok(());
        }
        keys.sort_by(|a, b| a.time.total_cmp(&b.time));
        self.shape(lx, &t, None, Geometry::AnimatedTriangle(keys));
        Ok(())
    }

    fn mesh<'a>(&mut self, lx: &mut Lexer<'a>, t: Tok<'a>, dir: &Arc<Path>) -> Result<(), AffError> {
        let mut vertices: Vec<Vec3> = Vec::new();
        let mut normals: Option<Vec<Vec3>> = None;
        let mut uvs: Option<Vec<Vec2>> = None;
        let mut texture = None;
        loop {
            let block = lx.word("a mesh block (`vertices`, `normals`, `texturecoords` or `triangles`)")?;
            if block.is("vertices") {
                let n = lx.count("the vertex count")?;
                vertices = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    vertices.push(lx.vec3("a mesh vertex coordinate")?);
                }
            } else if block.is("normals") {
                let n = lx.count("the normal count")?;
                let mut ns = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    ns.push(lx.vec3("a mesh normal component")?);
                }
                normals = Some(ns);
            } else if block.is("texturecoords") {
                let n = lx.count("the texture coordinate count")?;
                if let Some(name) = lx.name_on_this_line() {
                    texture = Some(self.texture_ref(lx, &name, dir));
                }
                let mut ts = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    ts.push(Vec2::new(lx.number("a texture coordinate")?, lx.number("a texture coordinate")?));
                }
                uvs = Some(ts);
            } else if block.is("triangles") {
                let n = lx.count("the triangle count")?;
                let tris = read_mesh_triangles(lx, n, &vertices, normals.as_deref(), uvs.as_deref())?;
                self.shape(lx, &t, texture, Geometry::Triangles(tris));
                return Ok(());
            } else {
                return Err(lx.error(
                    &block,
                    format!(
                        "expected a mesh block (`vertices`, `normals`, `texturecoords` or `triangles`), found `{}`",
                        block.show()
                    ),
                ));
            }
        }
    }

    fn include<'a>(&mut self, lx: &mut Lexer<'a>, t: Tok<'a>, dir: &Arc<Path>, depth: usize) -> Result<(), AffError> {
        let mut name = lx.word("the detail level and file name of the include")?;
        if name.number().is_some() {
            // The detail level: every level is read.
            name = lx.word("the file name of the include")?;
        }
        let path = dir.join(name.show());
        if depth + 1 > MAX_INCLUDE_DEPTH {
            return Err(
                lx.error(&t, format!("includes nest deeper than {MAX_INCLUDE_DEPTH} (does a file include itself?)"))
            );
        }
        let bytes = match self.cache.get(&path) {
            Some(b) => b.clone(),
            None => match std::fs::read(&path) {
                Ok(b) => {
                    let b: Arc<[u8]> = Arc::from(b);
                    self.cache.insert(path.clone(), b.clone());
                    b
                }
                Err(e) => {
                    let at = lx.location(&name);
                    self.warn(
                        &format!("include {}", path.display()),
                        &at,
                        format!("cannot read the included file {}: {e}; skipped", path.display()),
                    );
                    return Ok(());
                }
            },
        };
        self.files.insert(path.clone());
        self.parse_text(&bytes, &path, depth + 1)
    }

    fn keyframes(&mut self, lx: &mut Lexer) -> Result<(), AffError> {
        let name = lx.word("the name of the keyframes `k`")?;
        lx.expect("{", "after `k NAME`")?;
        let mut k = Keyframes { name: name.show(), ..Default::default() };
        let tcb = |lx: &mut Lexer| -> Result<Tcb, AffError> {
            let what = "a key's tension, continuity or bias";
            Ok(Tcb { tension: lx.number(what)?, continuity: lx.number(what)?, bias: lx.number(what)? })
        };
        loop {
            let t = lx.word("a track (`transl`, `rot`, `scale`, `visibility`) or `}` of the keyframes")?;
            if t.is("}") {
                break;
            }
            let track = t.show();
            let what_count = format!("the key count of the `{track}` track");
            if t.is("transl") || t.is("scale") {
                let n = lx.count(&what_count)?;
                let mut keys = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    let time = lx.number("a key's time")?;
                    let value = lx.vec3("a key's value")?;
                    keys.push(Key { time, value, tcb: tcb(lx)? });
                }
                let track = VectorTrack::new(keys);
                if t.is("transl") {
                    k.translation = track;
                } else {
                    k.scale = track;
                }
            } else if t.is("rot") {
                let n = lx.count(&what_count)?;
                let mut keys = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    let time = lx.number("a key's time")?;
                    let axis = lx.vec3("a rotation key's axis component")?;
                    let degrees = lx.number("a rotation key's angle")?;
                    keys.push(Key { time, value: AxisAngle { axis, degrees }, tcb: tcb(lx)? });
                }
                k.rotation = RotationTrack::new(keys);
            } else if t.is("visibility") {
                let n = lx.count(&what_count)?;
                let mut keys = Vec::with_capacity(capacity(n));
                for _ in 0..n {
                    let time = lx.number("a key's time")?;
                    let on = lx.number("a visibility key's value (0 or 1)")? > 0.0;
                    keys.push(Key { time, value: on, tcb: Tcb::default() });
                }
                k.visibility = VisibilityTrack::new(keys);
            } else {
                return Err(lx.error(
                    &t,
                    format!(
                        "expected a track (`transl`, `rot`, `scale`, `visibility`) or `}}` in keyframes `{}`, found `{}`",
                        k.name, track
                    ),
                ));
            }
        }
        if let Some(old) = self.scene.keyframes.iter_mut().find(|o| o.name == k.name) {
            // A file included twice defines its keyframes twice, alike: only a change is news.
            if *old != k {
                let at = lx.location(&name);
                let kind = format!("keyframes {} redefined", k.name);
                let message =
                    format!("keyframes `{}` are defined again, differently; the later definition is used", k.name);
                *old = k;
                self.warn(&kind, &at, message);
            }
        } else {
            self.scene.keyframes.push(k);
        }
        Ok(())
    }
}

/// The `triangles` block of a mesh: vertex indices, then normal and texture-coordinate indices when
/// the mesh has those blocks. Corners that combine the same three indices share one vertex.
fn read_mesh_triangles(
    lx: &mut Lexer,
    n: usize,
    vertices: &[Vec3],
    normals: Option<&[Vec3]>,
    uvs: Option<&[Vec2]>,
) -> Result<Triangles, AffError> {
    let mut out =
        Triangles { normals: normals.map(|_| Vec::new()), uvs: uvs.map(|_| Vec::new()), ..Default::default() };
    let mut ids: HashMap<(u32, u32, u32), u32> = HashMap::new();
    out.triangles.reserve(capacity(n));
    for _ in 0..n {
        let mut v = [0u32; 3];
        for x in &mut v {
            *x = lx.index("a triangle's vertex index", vertices.len())?;
        }
        let mut ni = [0u32; 3];
        if let Some(ns) = normals {
            for x in &mut ni {
                *x = lx.index("a triangle's normal index", ns.len())?;
            }
        }
        let mut ti = [0u32; 3];
        if let Some(ts) = uvs {
            for x in &mut ti {
                *x = lx.index("a triangle's texture coordinate index", ts.len())?;
            }
        }
        let mut tri = [0u32; 3];
        for k in 0..3 {
            let next = out.positions.len() as u32;
            let id = *ids.entry((v[k], ni[k], ti[k])).or_insert(next);
            if id == next {
                // The indices were checked against the block lengths above.
                out.positions.push(vertices[v[k] as usize]);
                if let (Some(dst), Some(ns)) = (out.normals.as_mut(), normals) {
                    dst.push(ns[ni[k] as usize]);
                }
                if let (Some(dst), Some(ts)) = (out.uvs.as_mut(), uvs) {
                    dst.push(ts[ti[k] as usize]);
                }
            }
            tri[k] = id;
        }
        out.triangles.push(tri);
    }
    Ok(out)
}

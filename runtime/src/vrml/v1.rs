//! VRML 1.0 scenes (`#VRML V1.0 ascii`) read into a [`Context`].
//!
//! VRML 1.0 is Open Inventor's format: a node's children sit in its braces beside its fields, and
//! the nodes before a shape set its state (the matrix, the material, the coordinates, the
//! normals, the bindings) for every shape after them until the `Separator` around them ends. So
//! this reader is its own: [`parse`] reads the file into an arena of nodes (`DEF`/`USE` sharing
//! one), and [`build_str_with`] walks it from the top with that traversal state, pushed at each
//! `Separator` and popped after it. Shapes become objects of the `material` shader, as VRML 97's
//! do (`super::build`), their meshes made by the same code (`super::mesh`).
//!
//! The bounds are VRML 97's ([`super::MAX_VRML_NESTING`], [`super::MAX_VRML_NODES`],
//! [`super::VRML_TRAVERSAL_BUDGET`], [`crate::scene_file::MAX_MODEL_TRIANGLES`]); a syntax error
//! is a [`VrmlError`] with file, line and column, a node or field not read is one warning per type
//! or field.

use super::lex::{Lexer, Tok, Token};
use super::mesh::{self, FaceSet, Indexed};
use super::parse::NodeId;
use super::{
    linear, location, relative_path, Loc, NodeRef, Placed, Viewpoint, VrmlError, VrmlOptions, VrmlScene,
    MAX_VRML_NESTING, MAX_VRML_NODES, VRML_EAR_CLIP_BUDGET, VRML_TRAVERSAL_BUDGET,
};
use crate::api::{Context, LightId, ShaderId};
use crate::geometry::Mesh;
use crate::rib::{RibDiagnostic, Severity};
use crate::scene_file::{SceneFileError, MAX_MODEL_TRIANGLES};
use crate::shading::ParamValue;
use glam::{Affine3A, Mat4, Quat, Vec2, Vec3, Vec3A};
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::Path;
use std::sync::Arc;

/// A field's value as written: numbers, strings, or words (enums, `TRUE`, a bit mask's flags).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Numbers(Vec<f64>),
    Strings(Vec<String>),
    Words(Vec<String>),
}

/// A node of a VRML 1.0 file.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub type_name: String,
    pub loc: Loc,
    pub fields: Vec<(String, Loc, Value)>,
    pub children: Vec<NodeId>,
}

impl Node {
    fn field(&self, name: &str) -> Option<&(String, Loc, Value)> {
        self.fields.iter().rev().find(|f| f.0 == name)
    }
}

/// A parsed VRML 1.0 file: its nodes and the top-level ones.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Document {
    pub nodes: Vec<Node>,
    pub roots: Vec<NodeId>,
    pub warnings: Vec<(Loc, String)>,
}

type ParseResult<T> = std::result::Result<T, (Loc, String)>;

/// Parses VRML 1.0 text (the header line is a comment to the grammar).
pub fn parse(text: &str) -> ParseResult<Document> {
    // A bit mask `(SIDES | TOP)` as a list of words, the text keeping its columns.
    let mut in_string = false;
    let mut escaped = false;
    let text: String = text
        .chars()
        .map(|c| {
            if in_string {
                match (escaped, c) {
                    (false, '\\') => escaped = true,
                    (false, '"') => in_string = false,
                    _ => escaped = false,
                }
                return c;
            }
            match c {
                '"' => {
                    in_string = true;
                    c
                }
                '(' => '[',
                ')' => ']',
                '|' => ' ',
                _ => c,
            }
        })
        .collect();
    let mut p =
        Parser { lexer: Lexer::new(&text), ahead: VecDeque::new(), doc: Document::default(), defs: HashMap::new() };
    while p.peek(0)?.is_some() {
        if let Some(n) = p.node_statement(0)? {
            p.doc.roots.push(n);
        }
    }
    Ok(p.doc)
}

struct Parser<'a> {
    lexer: Lexer<'a>,
    ahead: VecDeque<Token>,
    doc: Document,
    defs: HashMap<String, NodeId>,
}

impl Parser<'_> {
    fn peek(&mut self, k: usize) -> ParseResult<Option<&Token>> {
        while self.ahead.len() <= k {
            match self.lexer.next_token().map_err(|e| (e.loc, e.message))? {
                Some(t) => self.ahead.push_back(t),
                None => return Ok(None),
            }
        }
        Ok(self.ahead.get(k))
    }

    fn next(&mut self, what: &str) -> ParseResult<Token> {
        self.peek(0)?;
        self.ahead.pop_front().ok_or_else(|| (self.lexer.loc(), format!("the file ends where {what} was expected")))
    }

    fn ident(&mut self, what: &str) -> ParseResult<(String, Loc)> {
        let t = self.next(what)?;
        match t.tok {
            Tok::Ident(s) => Ok((s, t.loc)),
            _ => Err((t.loc, format!("expected {what}"))),
        }
    }

    /// `DEF name Type { ... }`, `USE name` or `Type { ... }`; `None` for a `USE` of an unknown name.
    fn node_statement(&mut self, depth: usize) -> ParseResult<Option<NodeId>> {
        let (word, loc) = self.ident("a node")?;
        match word.as_str() {
            "DEF" => {
                let (name, _) = self.ident("a name after DEF")?;
                let id = self.node(depth)?;
                self.defs.insert(name, id);
                Ok(Some(id))
            }
            "USE" => {
                let (name, at) = self.ident("a name after USE")?;
                match self.defs.get(&name) {
                    Some(&id) => Ok(Some(id)),
                    None => {
                        self.doc.warnings.push((at, format!("USE {name}: no node is DEFined by that name here")));
                        Ok(None)
                    }
                }
            }
            _ => {
                self.ahead.push_front(Token { tok: Tok::Ident(word), loc });
                self.node(depth).map(Some)
            }
        }
    }

    fn node(&mut self, depth: usize) -> ParseResult<NodeId> {
        let (type_name, loc) = self.ident("a node type")?;
        if depth >= MAX_VRML_NESTING {
            return Err((loc, format!("nodes nest deeper than {MAX_VRML_NESTING} levels")));
        }
        let t = self.next("`{` after the node type")?;
        if t.tok != Tok::LBrace {
            return Err((t.loc, "expected `{` after the node type".into()));
        }
        let mut node = Node { type_name, loc, fields: Vec::new(), children: Vec::new() };
        loop {
            let t = self.next("a field, a node or `}`")?;
            let (word, at) = match t.tok {
                Tok::RBrace => break,
                Tok::Ident(w) => (w, t.loc),
                _ => return Err((t.loc, "expected a field name, a node or `}`".into())),
            };
            // A child: `DEF`, `USE`, or a type followed by its braces.
            let child =
                matches!(word.as_str(), "DEF" | "USE") || matches!(self.peek(0)?, Some(Token { tok: Tok::LBrace, .. }));
            if child {
                self.ahead.push_front(Token { tok: Tok::Ident(word), loc: at });
                if let Some(c) = self.node_statement(depth + 1)? {
                    node.children.push(c);
                }
            } else {
                let value = self.value()?;
                node.fields.push((word, at, value));
            }
        }
        if self.doc.nodes.len() >= MAX_VRML_NODES {
            return Err((loc, format!("more than {MAX_VRML_NODES} nodes")));
        }
        self.doc.nodes.push(node);
        Ok(NodeId(self.doc.nodes.len() as u32 - 1))
    }

    /// A field's value: numbers, a string, words, or a bracketed list of one of those.
    fn value(&mut self) -> ParseResult<Value> {
        let t = self.next("a field value")?;
        match t.tok {
            Tok::Number(x, _) => {
                let mut v = vec![x];
                while let Some(Token { tok: Tok::Number(x, _), .. }) = self.peek(0)? {
                    v.push(*x);
                    self.ahead.pop_front();
                }
                Ok(Value::Numbers(v))
            }
            Tok::Str(s) => Ok(Value::Strings(vec![s])),
            Tok::Ident(w) => Ok(Value::Words(vec![w])),
            Tok::LBracket => {
                let mut numbers = Vec::new();
                let mut strings = Vec::new();
                let mut words = Vec::new();
                loop {
                    let t = self.next("`]`")?;
                    match t.tok {
                        Tok::RBracket => break,
                        Tok::Number(x, _) => numbers.push(x),
                        Tok::Str(s) => strings.push(s),
                        Tok::Ident(w) => words.push(w),
                        _ => return Err((t.loc, "expected a value or `]`".into())),
                    }
                }
                Ok(if !strings.is_empty() {
                    Value::Strings(strings)
                } else if !words.is_empty() {
                    Value::Words(words)
                } else {
                    Value::Numbers(numbers)
                })
            }
            _ => Err((t.loc, "expected a field value".into())),
        }
    }
}

/// How values are bound to a shape's parts (MaterialBinding, NormalBinding).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Binding {
    /// DEFAULT and OVERALL: one value (normals: made from the faces).
    Overall,
    PerFace,
    PerFaceIndexed,
    PerVertex,
    PerVertexIndexed,
}

/// One Material's values.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Material {
    diffuse: Vec3,
    specular: Vec3,
    emissive: Vec3,
    ambient: Vec3,
    shininess: f32,
    transparency: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            diffuse: Vec3::splat(0.8),
            specular: Vec3::ZERO,
            emissive: Vec3::ZERO,
            ambient: Vec3::splat(0.2),
            shininess: 0.2,
            transparency: 0.0,
        }
    }
}

/// The traversal state: what the nodes so far set for the shapes after them.
#[derive(Clone, Debug)]
struct State {
    matrix: Affine3A,
    materials: Arc<Vec<Material>>,
    material_binding: Binding,
    normals: Arc<Vec<Vec3>>,
    /// None: DEFAULT (per vertex, indexed, for a face set).
    normal_binding: Option<Binding>,
    coords: Arc<Vec<Vec3>>,
    tex_coords: Arc<Vec<Vec2>>,
    /// The texture's name and whether it repeats along s and t.
    texture: Option<(String, bool, bool)>,
    ccw: bool,
    crease_angle: f32,
    /// The lights that light what follows (indices into the builder's `own_lights`): a light
    /// lights what comes after it in its Separator.
    lights: Arc<Vec<usize>>,
}

impl Default for State {
    fn default() -> Self {
        State {
            matrix: Affine3A::IDENTITY,
            materials: Arc::new(vec![Material::default()]),
            material_binding: Binding::Overall,
            normals: Arc::default(),
            normal_binding: None,
            coords: Arc::default(),
            tex_coords: Arc::default(),
            texture: None,
            ccw: true,
            crease_angle: 0.5,
            lights: Arc::default(),
        }
    }
}

type Result<T> = std::result::Result<T, SceneFileError>;

/// Reads VRML 1.0 text into `rt`; `path` names it in messages, and texture file names are
/// resolved against its folder.
pub fn build_str_with(rt: &mut Context, text: &str, path: &Path, options: &VrmlOptions) -> Result<VrmlScene> {
    let scene = VrmlScene { bounds: (Vec3A::INFINITY, Vec3A::NEG_INFINITY), ..VrmlScene::default() };
    let mut top = Inlined {
        scene,
        world: Affine3A::IDENTITY,
        path: Vec::new(),
        depth: 0,
        visits: 0,
        ear_clip_budget: VRML_EAR_CLIP_BUDGET,
    };
    build_into(rt, text, path, options.surface.as_deref(), &mut top)?;
    Ok(top.scene)
}

/// Where a VRML 1.0 file is read into: a scene (its own, or the VRML 97 scene that inlines it)
/// under a matrix, and what is left of the walk's budgets.
pub struct Inlined {
    pub scene: VrmlScene,
    /// The matrix of the Transforms above the file.
    pub world: Affine3A,
    /// The VRML 97 nodes above it (its Inline among them): its shapes move with their Transforms.
    pub path: Vec<NodeRef>,
    pub depth: usize,
    pub visits: usize,
    pub ear_clip_budget: usize,
}

/// Reads VRML 1.0 text into `rt` and `into`: at the top (an empty path), with the camera and
/// headlight of a scene on its own; inlined, without them (the including file binds those).
pub fn build_into(rt: &mut Context, text: &str, path: &Path, surface: Option<&str>, into: &mut Inlined) -> Result<()> {
    let file: Arc<Path> = Arc::from(path);
    let doc = parse(text).map_err(|(loc, message)| SceneFileError::from(VrmlError::at(&file, loc, message)))?;
    let top = into.path.is_empty();
    into.scene.documents.push((path.to_path_buf(), super::parse::Document::default()));
    let mut b = Builder {
        rt,
        doc: &doc,
        doc_index: into.scene.documents.len() - 1,
        file: file.clone(),
        scene: std::mem::take(&mut into.scene),
        warned: HashSet::new(),
        shaders: HashMap::new(),
        surface: surface.map(str::to_string),
        visits: into.visits,
        ear_clip_budget: into.ear_clip_budget,
        camera_bound: !top,
        lights: 0,
        own_lights: Vec::new(),
        light_sets: Vec::new(),
        light_set_numbers: HashMap::new(),
        scoped: doc
            .nodes
            .iter()
            .any(|n| matches!(n.type_name.as_str(), "PointLight" | "SpotLight" | "DirectionalLight")),
        world: into.world,
        path: into.path.clone(),
    };
    for (loc, message) in &doc.warnings {
        b.scene.warnings.push(RibDiagnostic::warning(&location(&file, *loc), message.clone()));
    }
    let mut state = State::default();
    let mut result = Ok(());
    for &root in &doc.roots {
        result = b.visit(root, &mut state, into.depth);
        if result.is_err() {
            break;
        }
    }
    if result.is_ok() {
        result = b.scope_lights();
    }
    if result.is_ok() && top {
        result = b.finish();
    }
    (into.visits, into.ear_clip_budget) = (b.visits, b.ear_clip_budget);
    into.scene = b.scene;
    result
}

struct Builder<'a> {
    rt: &'a mut Context,
    doc: &'a Document,
    /// This file's entry in the scene's documents.
    doc_index: usize,
    /// The matrix above the file, and the VRML 97 nodes above it.
    world: Affine3A,
    path: Vec<NodeRef>,
    file: Arc<Path>,
    scene: VrmlScene,
    warned: HashSet<String>,
    shaders: HashMap<String, ShaderId>,
    surface: Option<String>,
    visits: usize,
    ear_clip_budget: usize,
    camera_bound: bool,
    lights: usize,
    /// The lights this file made, in the order made.
    own_lights: Vec<LightId>,
    /// Each set of lights that lights a shape (indices into `own_lights`), its place its number,
    /// and each set's number.
    light_sets: Vec<Vec<usize>>,
    light_set_numbers: HashMap<Vec<usize>, usize>,
    /// Whether the file has lights: its shapes then say which of them light them.
    scoped: bool,
}

/// The VRML 1.0 node types and their fields: read, or skipped with a warning saying so.
const NODE_TYPES: &[(&str, &[&str])] = &[
    ("AsciiText", &["string", "spacing", "justification", "width"]),
    ("Cone", &["parts", "bottomRadius", "height"]),
    ("Coordinate3", &["point"]),
    ("Cube", &["width", "height", "depth"]),
    ("Cylinder", &["parts", "radius", "height"]),
    ("DirectionalLight", &["on", "intensity", "color", "direction"]),
    ("FontStyle", &["size", "family", "style"]),
    ("Group", &[]),
    ("IndexedFaceSet", &["coordIndex", "materialIndex", "normalIndex", "textureCoordIndex"]),
    ("IndexedLineSet", &["coordIndex", "materialIndex", "normalIndex", "textureCoordIndex"]),
    ("Info", &["string"]),
    ("LOD", &["range", "center"]),
    ("Material", &["ambientColor", "diffuseColor", "specularColor", "emissiveColor", "shininess", "transparency"]),
    ("MaterialBinding", &["value"]),
    ("MatrixTransform", &["matrix"]),
    ("Normal", &["vector"]),
    ("NormalBinding", &["value"]),
    ("OrthographicCamera", &["position", "orientation", "focalDistance", "height"]),
    ("PerspectiveCamera", &["position", "orientation", "focalDistance", "heightAngle"]),
    ("PointLight", &["on", "intensity", "color", "location"]),
    ("PointSet", &["startIndex", "numPoints"]),
    ("Rotation", &["rotation"]),
    ("Scale", &["scaleFactor"]),
    ("Separator", &["renderCulling"]),
    ("ShapeHints", &["vertexOrdering", "shapeType", "faceType", "creaseAngle"]),
    ("Sphere", &["radius"]),
    ("SpotLight", &["on", "intensity", "color", "location", "direction", "dropOffRate", "cutOffAngle"]),
    ("Switch", &["whichChild"]),
    ("Texture2", &["filename", "image", "wrapS", "wrapT"]),
    ("Texture2Transform", &["translation", "rotation", "scaleFactor", "center"]),
    ("TextureCoordinate2", &["point"]),
    ("Transform", &["translation", "rotation", "scaleFactor", "scaleOrientation", "center"]),
    ("TransformSeparator", &[]),
    ("Translation", &["translation"]),
    ("WWWAnchor", &["name", "description", "map"]),
    ("WWWInline", &["name", "bboxSize", "bboxCenter"]),
];

impl Builder<'_> {
    fn warn_once(&mut self, key: String, loc: Loc, severity: Severity, message: impl Into<String>) {
        if self.warned.insert(key) {
            let loc = location(&self.file, loc);
            self.scene.warnings.push(RibDiagnostic { severity, loc, message: message.into() });
        }
    }

    fn error(&self, loc: Loc, message: impl Into<String>) -> SceneFileError {
        VrmlError::at(&self.file, loc, message).into()
    }

    fn shader(&mut self, name: &str) -> Result<ShaderId> {
        if let Some(&id) = self.shaders.get(name) {
            return Ok(id);
        }
        let id = self.rt.find_shader(name)?;
        self.shaders.insert(name.to_string(), id);
        Ok(id)
    }

    // ---- Field values ----

    fn numbers(&mut self, n: NodeId, name: &str) -> Option<Vec<f32>> {
        let node = &self.doc.nodes[n.0 as usize];
        let (_, loc, value) = node.field(name)?;
        match value {
            Value::Numbers(v) if v.iter().all(|x| x.is_finite()) => Some(v.iter().map(|&x| x as f32).collect()),
            _ => {
                let (loc, type_name) = (*loc, node.type_name.clone());
                self.warn_once(
                    format!("value:{type_name}.{name}"),
                    loc,
                    Severity::Warning,
                    format!("{type_name}.{name} expects numbers; the value is ignored"),
                );
                None
            }
        }
    }

    fn float(&mut self, n: NodeId, name: &str, default: f32) -> f32 {
        self.numbers(n, name).and_then(|v| v.first().copied()).unwrap_or(default)
    }

    fn vec3(&mut self, n: NodeId, name: &str, default: Vec3) -> Vec3 {
        match self.numbers(n, name) {
            Some(v) if v.len() >= 3 => Vec3::new(v[0], v[1], v[2]),
            _ => default,
        }
    }

    fn vec3s(&mut self, n: NodeId, name: &str) -> Option<Vec<Vec3>> {
        let v = self.numbers(n, name)?;
        Some(v.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
    }

    fn rotation(&mut self, n: NodeId, name: &str) -> Quat {
        match self.numbers(n, name) {
            Some(v) if v.len() >= 4 => super::events::quat_of([v[0], v[1], v[2], v[3]]),
            _ => Quat::IDENTITY,
        }
    }

    fn ints(&mut self, n: NodeId, name: &str) -> Vec<i32> {
        self.numbers(n, name)
            .unwrap_or_default()
            .into_iter()
            .map(|x| if x.fract() == 0.0 && x.abs() < i32::MAX as f32 { x as i32 } else { i32::MAX })
            .collect()
    }

    fn word(&self, n: NodeId, name: &str) -> Option<String> {
        match self.doc.nodes[n.0 as usize].field(name) {
            Some((_, _, Value::Words(w))) => w.first().cloned(),
            _ => None,
        }
    }

    fn words(&self, n: NodeId, name: &str) -> Vec<String> {
        match self.doc.nodes[n.0 as usize].field(name) {
            Some((_, _, Value::Words(w))) => w.clone(),
            _ => Vec::new(),
        }
    }

    fn boolean(&self, n: NodeId, name: &str, default: bool) -> bool {
        match self.word(n, name).as_deref() {
            Some("TRUE") => true,
            Some("FALSE") => false,
            _ => match self.doc.nodes[n.0 as usize].field(name) {
                Some((_, _, Value::Numbers(v))) if v.len() == 1 => v[0] != 0.0,
                _ => default,
            },
        }
    }

    /// Whether a `parts` bit mask has `part` (`ALL` has every part; no field, every part).
    fn has_part(&self, n: NodeId, part: &str) -> bool {
        let parts = self.words(n, "parts");
        parts.is_empty() || parts.iter().any(|p| p == part || p == "ALL")
    }

    // ---- The walk ----

    fn visit(&mut self, n: NodeId, state: &mut State, depth: usize) -> Result<()> {
        self.visits += 1;
        let node = &self.doc.nodes[n.0 as usize];
        let loc = node.loc;
        if self.visits > VRML_TRAVERSAL_BUDGET {
            return Err(self.error(
                loc,
                format!("the scene graph has more than {VRML_TRAVERSAL_BUDGET} nodes once every USE is followed"),
            ));
        }
        if depth >= MAX_VRML_NESTING {
            return Err(self.error(loc, format!("nodes nest deeper than {MAX_VRML_NESTING} levels")));
        }
        let type_name = node.type_name.clone();
        let children = node.children.clone();
        // Fields the type does not have (`fields` declares an extension node's own).
        if let Some((_, known)) = NODE_TYPES.iter().find(|(t, _)| *t == type_name) {
            let unknown: Vec<(String, Loc)> = node
                .fields
                .iter()
                .filter(|(f, _, _)| !known.contains(&f.as_str()) && f != "fields")
                .map(|(f, at, _)| (f.clone(), *at))
                .collect();
            for (field, at) in unknown {
                self.warn_once(
                    format!("field:{type_name}.{field}"),
                    at,
                    Severity::Warning,
                    format!("{type_name} has no field `{field}`; it is ignored"),
                );
            }
        }
        match type_name.as_str() {
            "Separator" => {
                let mut inner = state.clone();
                for c in children {
                    self.visit(c, &mut inner, depth + 1)?;
                }
            }
            "TransformSeparator" => {
                let matrix = state.matrix;
                for c in children {
                    self.visit(c, state, depth + 1)?;
                }
                state.matrix = matrix;
            }
            "Group" | "WWWAnchor" => {
                for c in children {
                    self.visit(c, state, depth + 1)?;
                }
            }
            "Switch" => {
                let which = self.float(n, "whichChild", -1.0);
                if which == -3.0 {
                    for c in children {
                        self.visit(c, state, depth + 1)?;
                    }
                } else if which >= 0.0 {
                    if let Some(&c) = children.get(which as usize) {
                        self.visit(c, state, depth + 1)?;
                    }
                }
            }
            "LOD" => {
                if children.len() > 1 {
                    self.warn_once("LOD".into(), loc, Severity::Warning, "LOD draws its first child at every distance");
                }
                if let Some(&c) = children.first() {
                    self.visit(c, state, depth + 1)?;
                }
            }
            "Transform" => {
                let t = self.vec3(n, "translation", Vec3::ZERO);
                let r = self.rotation(n, "rotation");
                let s = self.vec3(n, "scaleFactor", Vec3::ONE);
                let so = self.rotation(n, "scaleOrientation");
                let c = self.vec3(n, "center", Vec3::ZERO);
                state.matrix = state.matrix
                    * Affine3A::from_translation(t + c)
                    * Affine3A::from_quat(r)
                    * Affine3A::from_quat(so)
                    * Affine3A::from_scale(s)
                    * Affine3A::from_quat(so.inverse())
                    * Affine3A::from_translation(-c);
            }
            "MatrixTransform" => match self.numbers(n, "matrix") {
                // Row vectors: the file's rows are the columns of the matrix that maps column vectors.
                Some(m) if m.len() == 16 => {
                    let m = Mat4::from_cols_slice(&m);
                    let affine = Affine3A::from_mat4(m);
                    if affine.is_finite() {
                        state.matrix *= affine;
                    }
                }
                _ => self.warn_once(
                    format!("matrix:{}:{}", loc.line, loc.column),
                    loc,
                    Severity::Warning,
                    "MatrixTransform needs 16 numbers; it is ignored",
                ),
            },
            "Translation" => state.matrix *= Affine3A::from_translation(self.vec3(n, "translation", Vec3::ZERO)),
            "Rotation" => state.matrix *= Affine3A::from_quat(self.rotation(n, "rotation")),
            "Scale" => state.matrix *= Affine3A::from_scale(self.vec3(n, "scaleFactor", Vec3::ONE)),
            "Material" => state.materials = Arc::new(self.material(n)),
            "MaterialBinding" => state.material_binding = self.binding(n),
            "NormalBinding" => {
                state.normal_binding = match self.word(n, "value").as_deref() {
                    None | Some("DEFAULT") => None,
                    _ => Some(self.binding(n)),
                }
            }
            "Coordinate3" => state.coords = Arc::new(self.vec3s(n, "point").unwrap_or_default()),
            "Normal" => state.normals = Arc::new(self.vec3s(n, "vector").unwrap_or_default()),
            "TextureCoordinate2" => {
                let v = self.numbers(n, "point").unwrap_or_default();
                state.tex_coords = Arc::new(v.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect());
            }
            "Texture2" => {
                let repeat = |b: &Self, f: &str| b.word(n, f).as_deref() != Some("CLAMP");
                state.texture = self.texture(n).map(|t| (t, repeat(self, "wrapS"), repeat(self, "wrapT")));
            }
            "ShapeHints" => {
                if let Some(order) = self.word(n, "vertexOrdering") {
                    state.ccw = order != "CLOCKWISE";
                }
                state.crease_angle = self.float(n, "creaseAngle", state.crease_angle);
            }
            "IndexedFaceSet" => {
                let made = self.face_set(n, state);
                self.place(n, made, state)?;
            }
            "Cube" => {
                let size =
                    Vec3::new(self.float(n, "width", 2.0), self.float(n, "height", 2.0), self.float(n, "depth", 2.0))
                        .max(Vec3::ZERO);
                self.place(n, Some(mesh::box_mesh(size)), state)?;
            }
            "Sphere" => {
                let radius = self.float(n, "radius", 1.0).max(0.0);
                self.place(n, Some(mesh::sphere(radius)), state)?;
            }
            "Cylinder" => {
                let radius = self.float(n, "radius", 1.0).max(0.0);
                let height = self.float(n, "height", 2.0).max(0.0);
                let (side, top, bottom) =
                    (self.has_part(n, "SIDES"), self.has_part(n, "TOP"), self.has_part(n, "BOTTOM"));
                self.place(n, Some(mesh::cylinder(radius, height, side, top, bottom)), state)?;
            }
            "Cone" => {
                let radius = self.float(n, "bottomRadius", 1.0).max(0.0);
                let height = self.float(n, "height", 2.0).max(0.0);
                let (side, bottom) = (self.has_part(n, "SIDES"), self.has_part(n, "BOTTOM"));
                self.place(n, Some(mesh::cone(radius, height, side, bottom)), state)?;
            }
            "PointLight" | "SpotLight" | "DirectionalLight" => self.light(n, &type_name, state)?,
            "PerspectiveCamera" | "OrthographicCamera" => self.camera(n, &type_name, state),
            "Info" | "FontStyle" => {}
            "Texture2Transform" => self.warn_once(
                "node:Texture2Transform".into(),
                loc,
                Severity::Warning,
                "Texture2Transform is not applied; textures keep their coordinates",
            ),
            "IndexedLineSet" | "PointSet" | "AsciiText" | "WWWInline" => self.warn_once(
                format!("node:{type_name}"),
                loc,
                Severity::Omission,
                format!("{type_name} is not drawn; it is skipped"),
            ),
            other => {
                let known = NODE_TYPES.iter().any(|(t, _)| *t == other);
                self.warn_once(
                    format!("node:{other}"),
                    loc,
                    Severity::Omission,
                    if known {
                        format!("{other} is not read; it is skipped")
                    } else {
                        format!("unknown node type {other}; it is skipped with its children")
                    },
                );
            }
        }
        Ok(())
    }

    fn binding(&mut self, n: NodeId) -> Binding {
        match self.word(n, "value").as_deref() {
            Some("PER_FACE" | "PER_PART") => Binding::PerFace,
            Some("PER_FACE_INDEXED" | "PER_PART_INDEXED") => Binding::PerFaceIndexed,
            Some("PER_VERTEX") => Binding::PerVertex,
            Some("PER_VERTEX_INDEXED") => Binding::PerVertexIndexed,
            _ => Binding::Overall,
        }
    }

    /// A Material's values, one per entry of its longest field (shorter fields repeat their last).
    fn material(&mut self, n: NodeId) -> Vec<Material> {
        let d = Material::default();
        let colors = |b: &mut Self, name: &str, default: Vec3| {
            b.vec3s(n, name).filter(|v| !v.is_empty()).unwrap_or(vec![default])
        };
        let floats = |b: &mut Self, name: &str, default: f32| {
            b.numbers(n, name).filter(|v| !v.is_empty()).unwrap_or(vec![default])
        };
        let diffuse = colors(self, "diffuseColor", d.diffuse);
        let specular = colors(self, "specularColor", d.specular);
        let emissive = colors(self, "emissiveColor", d.emissive);
        let ambient = colors(self, "ambientColor", d.ambient);
        let shininess = floats(self, "shininess", d.shininess);
        let transparency = floats(self, "transparency", d.transparency);
        let count = diffuse.len().max(specular.len()).max(emissive.len()).max(shininess.len()).max(transparency.len());
        let at = |v: &[Vec3], i: usize| v[i.min(v.len() - 1)];
        let at1 = |v: &[f32], i: usize| v[i.min(v.len() - 1)];
        (0..count)
            .map(|i| Material {
                diffuse: at(&diffuse, i),
                specular: at(&specular, i),
                emissive: at(&emissive, i),
                ambient: at(&ambient, i),
                shininess: at1(&shininess, i).clamp(0.0, 1.0),
                transparency: at1(&transparency, i).clamp(0.0, 1.0),
            })
            .collect()
    }

    /// A Texture2's file, if it is a relative path to one that exists.
    fn texture(&mut self, n: NodeId) -> Option<String> {
        let loc = self.doc.nodes[n.0 as usize].loc;
        let name = match self.doc.nodes[n.0 as usize].field("filename") {
            Some((_, _, Value::Strings(s))) => s.first().cloned()?,
            _ => {
                if self.doc.nodes[n.0 as usize].field("image").is_some() {
                    self.warn_once(
                        "texture2:image".into(),
                        loc,
                        Severity::Omission,
                        "Texture2's image field is not read; the shape is drawn untextured",
                    );
                }
                return None;
            }
        };
        let dir = self.file.parent().map(Path::to_path_buf).unwrap_or_default();
        match relative_path(&name) {
            Ok(rel) if dir.join(&rel).is_file() => Some(dir.join(rel).display().to_string()),
            Ok(rel) => {
                let message =
                    format!("Texture2 \"{name}\": {} not found; shapes are drawn untextured", dir.join(rel).display());
                self.warn_once(format!("texture:{name}"), loc, Severity::Omission, message);
                None
            }
            Err(why) => {
                self.warn_once(
                    format!("texture:{name}"),
                    loc,
                    Severity::Omission,
                    format!("Texture2 \"{name}\" {why}; shapes are drawn untextured"),
                );
                None
            }
        }
    }

    /// The mesh of an IndexedFaceSet with the state's coordinates, normals, materials (as
    /// colours) and texture coordinates.
    fn face_set(&mut self, n: NodeId, state: &State) -> Option<Mesh> {
        let coord_index = self.ints(n, "coordIndex");
        let material_index = self.ints(n, "materialIndex");
        let normal_index = self.ints(n, "normalIndex");
        let tex_index = self.ints(n, "textureCoordIndex");
        // PER_VERTEX takes values in the order of the corners: an index counting them.
        let running: Vec<i32> = {
            let mut k = 0;
            coord_index
                .iter()
                .map(|&i| {
                    if i < 0 {
                        -1
                    } else {
                        k += 1;
                        k - 1
                    }
                })
                .collect()
        };
        // Whether values go per vertex, and their index (empty: in order, or by the coordinates).
        let indexed = |binding: Binding, index: &[i32]| -> Option<(bool, Vec<i32>)> {
            match binding {
                Binding::Overall => None,
                Binding::PerFace => Some((false, Vec::new())),
                Binding::PerFaceIndexed => Some((false, index.to_vec())),
                Binding::PerVertex => Some((true, running.clone())),
                Binding::PerVertexIndexed => Some((true, index.to_vec())),
            }
        };
        let colors: Vec<Vec3> = state.materials.iter().map(|m| Vec3::from(linear(m.diffuse))).collect();
        let color_binding =
            if state.materials.len() > 1 { indexed(state.material_binding, &material_index) } else { None };
        // A face set's DEFAULT normal binding is PER_VERTEX_INDEXED.
        let normal_binding = match state.normal_binding {
            _ if state.normals.is_empty() => None,
            None => indexed(Binding::PerVertexIndexed, &normal_index),
            Some(binding) => indexed(binding, &normal_index),
        };
        let tex =
            (!state.tex_coords.is_empty() && state.texture.is_some()).then(|| (&state.tex_coords[..], &tex_index[..]));
        let made = mesh::face_set(
            &FaceSet {
                points: &state.coords,
                coord_index: &coord_index,
                ccw: state.ccw,
                crease_angle: state.crease_angle,
                normals: normal_binding.as_ref().map(|(per_vertex, index)| Indexed {
                    values: &state.normals,
                    index,
                    per_vertex: *per_vertex,
                }),
                colors: color_binding.as_ref().map(|(per_vertex, index)| Indexed {
                    values: &colors,
                    index,
                    per_vertex: *per_vertex,
                }),
                tex_coords: tex,
                default_tex_coords: state.texture.is_some(),
            },
            &mut self.ear_clip_budget,
        );
        if !made.problems.is_empty() {
            let loc = self.doc.nodes[n.0 as usize].loc;
            let message = format!("IndexedFaceSet: {}", made.problems.join("; "));
            self.warn_once(format!("faces:{}:{}", loc.line, loc.column), loc, Severity::Warning, message);
        }
        Some(made.mesh)
    }

    /// Places a shape's mesh with the state's matrix, material and texture.
    fn place(&mut self, n: NodeId, mesh: Option<Mesh>, state: &State) -> Result<()> {
        let loc = self.doc.nodes[n.0 as usize].loc;
        let Some(mut mesh) = mesh.filter(|m| m.triangle_count() > 0) else { return Ok(()) };
        let total = self.scene.triangles.saturating_add(mesh.triangle_count());
        if total > MAX_MODEL_TRIANGLES {
            return Err(
                self.error(loc, format!("{total} triangles: a VRML scene may hold at most {MAX_MODEL_TRIANGLES}"))
            );
        }
        if let Err(e) = mesh.validate() {
            let type_name = self.doc.nodes[n.0 as usize].type_name.clone();
            self.warn_once(
                format!("mesh:{}:{}", loc.line, loc.column),
                loc,
                Severity::Omission,
                format!("{type_name}: {e}; it is skipped"),
            );
            return Ok(());
        }
        let world = self.world * state.matrix;
        let det = world.matrix3.determinant();
        if !(world.is_finite() && det != 0.0 && det.is_finite() && world.inverse().is_finite()) {
            self.warn_once(
                format!("singular:{}:{}", loc.line, loc.column),
                loc,
                Severity::Warning,
                "the transforms before this shape scale it to nothing; it is not drawn",
            );
            return Ok(());
        }
        self.scene.triangles = total;
        if let Some(uvs) = mesh.uvs.as_mut() {
            for uv in uvs {
                uv.y = 1.0 - uv.y;
            }
        }
        let material = state.materials.first().copied().unwrap_or_default();
        let coloured = !mesh.attributes.is_empty();
        let swapped = self.surface.clone();
        let shader = self.shader(swapped.as_deref().unwrap_or("material"))?;
        let declared: Option<HashSet<String>> = match &swapped {
            Some(_) => Some(self.rt.program(shader)?.interface.parameters.iter().map(|p| p.name.clone()).collect()),
            None => None,
        };
        let diffuse = if coloured || state.texture.is_some() { [1.0; 3] } else { linear(material.diffuse) };
        let mut params: Vec<(&str, ParamValue)> = vec![
            ("diffusecolor", ParamValue::Color(diffuse)),
            ("specularcolor", ParamValue::Color(linear(material.specular))),
            ("emissivecolor", ParamValue::Color(linear(material.emissive))),
            ("shininess", ParamValue::Float(material.shininess)),
            // VRML 1.0's ambient colour against VRML 97's ambient intensity (of the diffuse colour).
            ("ambientintensity", ParamValue::Float(ambient_intensity(material))),
            ("transparency", ParamValue::Float(material.transparency)),
        ];
        if self.scoped {
            params.push(("lightcategory", ParamValue::String(format!("-{}", self.light_set(&state.lights)))));
        }
        if let Some((t, s, tt)) = &state.texture {
            params.push(("texturename", ParamValue::String(t.clone())));
            params.push(("repeats", ParamValue::Float(if *s { 1.0 } else { 0.0 })));
            params.push(("repeatt", ParamValue::Float(if *tt { 1.0 } else { 0.0 })));
        }
        let (lo, hi) =
            mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        self.rt.push_attributes();
        self.rt.load_identity();
        let made = (|| -> Result<crate::api::ObjectId> {
            self.rt.bind_shader(shader)?;
            if let Some(declared) = &declared {
                self.rt.color(diffuse[0], diffuse[1], diffuse[2]);
                let o = 1.0 - material.transparency;
                self.rt.opacity(o, o, o);
                params.retain(|(n, _)| declared.contains(*n));
            }
            self.rt.parameters(&params)?;
            if material.transparency > 0.0 {
                self.rt.shadows_from_shader(true);
            }
            let id = self.rt.begin_object()?;
            self.rt.mesh(&mesh)?;
            self.rt.end_object()?;
            Ok(id)
        })();
        self.rt.pop_attributes()?;
        let id = made?;
        let instance = super::place_instance(self.rt, &mut self.scene, id, world, (lo, hi))?;
        let node = NodeRef { doc: self.doc_index, node: n };
        let path = self.path.clone();
        self.scene.shapes.push(Placed { made: instance, node, path, world, local: state.matrix });
        self.scene.shape_objects.push(id);
        Ok(())
    }

    fn light(&mut self, n: NodeId, kind: &str, state: &mut State) -> Result<()> {
        let on = self.boolean(n, "on", true);
        let intensity = self.float(n, "intensity", 1.0).max(0.0);
        let color = linear(self.vec3(n, "color", Vec3::ONE));
        let world = self.world * state.matrix;
        let mut params = vec![("intensity", ParamValue::Float(intensity)), ("lightcolor", ParamValue::Color(color))];
        let shader = match kind {
            "DirectionalLight" => {
                let direction = self.vec3(n, "direction", Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                params.push(("from", ParamValue::Point([0.0; 3])));
                params.push(("to", ParamValue::Point(direction.to_array())));
                "distantlight"
            }
            _ => {
                let location = self.vec3(n, "location", Vec3::new(0.0, 0.0, 1.0));
                params.push(("from", ParamValue::Point(location.to_array())));
                if kind == "SpotLight" {
                    let direction = self.vec3(n, "direction", Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                    let cut_off = self
                        .float(n, "cutOffAngle", std::f32::consts::FRAC_PI_4)
                        .clamp(0.0, std::f32::consts::FRAC_PI_2);
                    params.push(("to", ParamValue::Point((location + direction).to_array())));
                    params.push(("cutoffangle", ParamValue::Float(cut_off)));
                    // dropOffRate 0 (the default) is an even beam to the cut-off.
                    let drop = self.float(n, "dropOffRate", 0.0).clamp(0.0, 1.0);
                    params.push(("beamwidth", ParamValue::Float(cut_off * (1.0 - drop))));
                    "vrmlspotlight"
                } else {
                    "vrmlpointlight"
                }
            }
        };
        let id = self.shader(shader)?;
        // The light's own space is where it stands, so that a Transform above the file that
        // moves carries it (`Context::set_light_transform`).
        self.rt.push_matrix();
        self.rt.load_matrix(world);
        let light = self.rt.light_source(id, &params);
        self.rt.pop_matrix()?;
        let light = light?;
        if !on {
            self.rt.set_light(light, false, true)?;
        }
        self.lights += 1;
        Arc::make_mut(&mut state.lights).push(self.own_lights.len());
        self.own_lights.push(light);
        let (node, path) = (NodeRef { doc: self.doc_index, node: n }, self.path.clone());
        self.scene.lights.push(Placed { made: light, node, path, world, local: state.matrix });
        Ok(())
    }

    fn camera(&mut self, n: NodeId, kind: &str, state: &State) {
        let position = self.vec3(n, "position", Vec3::new(0.0, 0.0, 1.0));
        let orientation = self.rotation(n, "orientation");
        let world = self.world * state.matrix;
        let eye = world.transform_point3a(Vec3A::from(position));
        let forward = world.transform_vector3a(Vec3A::from(orientation * Vec3::NEG_Z)).normalize_or(Vec3A::NEG_Z);
        let up = world.transform_vector3a(Vec3A::from(orientation * Vec3::Y)).normalize_or(Vec3A::Y);
        let loc = self.doc.nodes[n.0 as usize].loc;
        let mut fov = self.float(n, "heightAngle", std::f32::consts::FRAC_PI_4);
        if kind == "OrthographicCamera" {
            self.warn_once(
                "ortho".into(),
                loc,
                Severity::Warning,
                "OrthographicCamera is drawn as a perspective camera of 45 degrees from its position",
            );
            fov = std::f32::consts::FRAC_PI_4;
        }
        if !(fov > 0.0 && fov < std::f32::consts::PI) {
            fov = std::f32::consts::FRAC_PI_4;
        }
        if !self.camera_bound {
            self.camera_bound = true;
            self.scene.bound_viewpoint = Some(self.scene.viewpoints.len());
            self.rt.camera_look_at(eye, eye + forward, up, fov.to_degrees());
        }
        let view = Viewpoint { description: String::new(), eye, forward, up, field_of_view: fov };
        let (node, path) = (NodeRef { doc: self.doc_index, node: n }, self.path.clone());
        self.scene.viewpoints.push(Placed { made: view, node, path, world, local: state.matrix });
    }

    /// The category of the shapes lit by the lights `set` of this file (and by lights of no
    /// category: the including VRML 97 file's, the headlight).
    fn light_set(&mut self, set: &[usize]) -> String {
        let k = match self.light_set_numbers.get(set) {
            Some(&k) => k,
            None => {
                self.light_sets.push(set.to_vec());
                self.light_set_numbers.insert(set.to_vec(), self.light_sets.len() - 1);
                self.light_sets.len() - 1
            }
        };
        format!("vrml1:{}:{k}", self.doc_index)
    }

    /// Scopes the file's lights, once every shape is made: each is put in the category of every
    /// set of lights it is not in, which the shapes lit by that set leave out (their `material`
    /// shader's `lightcategory` is `-` that category). Past [`super::VRML_LIGHT_SCOPE_BUDGET`]
    /// categories the lights light the whole scene (a warning).
    fn scope_lights(&mut self) -> Result<()> {
        if self.own_lights.len().saturating_mul(self.light_sets.len()) > super::VRML_LIGHT_SCOPE_BUDGET {
            self.warn_once(
                "light-scope".into(),
                Loc::default(),
                Severity::Warning,
                format!(
                    "{} lights in {} scopes pass the scoping budget ({}); each lights the whole scene",
                    self.own_lights.len(),
                    self.light_sets.len(),
                    super::VRML_LIGHT_SCOPE_BUDGET
                ),
            );
            return Ok(());
        }
        for (k, &light) in self.own_lights.iter().enumerate() {
            let unlit: Vec<String> = (0..self.light_sets.len())
                // A set is in increasing order: lights join the state in the order they are made.
                .filter(|&s| self.light_sets[s].binary_search(&k).is_err())
                .map(|s| format!("vrml1:{}:{s}", self.doc_index))
                .collect();
            if !unlit.is_empty() {
                self.rt.set_light_parameters(light, &[("__category", ParamValue::String(unlit.join(",")))])?;
            }
        }
        Ok(())
    }

    /// A camera framing the scene when the file has none, and a headlight when it has no light
    /// (VRML 1.0 browsers light a scene with a headlight).
    fn finish(&mut self) -> Result<()> {
        if !self.camera_bound {
            crate::scene_file::frame_camera(self.rt, self.scene.bounds);
        }
        if self.lights == 0 {
            let id = self.shader("distantlight")?;
            let light = super::add_headlight(self.rt, id)?;
            self.scene.headlight = Some((light, self.rt.camera().world_from_camera));
            let ambient = self.shader("ambientlight")?;
            self.rt.light_source(ambient, &[("intensity", ParamValue::Float(0.3))])?;
        }
        Ok(())
    }
}

/// VRML 1.0's ambient colour as VRML 97's ambient intensity: its brightness over the diffuse
/// colour's (an ambient colour equal to the diffuse one is intensity 1).
fn ambient_intensity(m: Material) -> f32 {
    let diffuse = m.diffuse.max_element();
    if diffuse <= 1e-6 {
        return 0.0;
    }
    (m.ambient.max_element() / diffuse).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> (Context, VrmlScene) {
        let mut rt = Context::new();
        let scene =
            build_str_with(&mut rt, &format!("#VRML V1.0 ascii\n{text}"), Path::new("v1.wrl"), &VrmlOptions::default())
                .unwrap_or_else(|e| panic!("{e}"));
        (rt, scene)
    }

    #[test]
    fn separators_keep_their_state_inside() {
        let (_, scene) = load(
            "Separator {
               Separator { Translation { translation 10 0 0 } Cube { } }
               Cube { width 4 }
               DEF S Separator { Transform { scaleFactor 2 2 2 } Sphere { radius 0.5 } }
               Translation { translation 0 5 0 }
               USE S
             }",
        );
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_eq!(scene.shapes.len(), 4);
        let x = |i: usize| scene.shapes[i].world.translation;
        assert_eq!(x(0), Vec3A::new(10.0, 0.0, 0.0));
        assert_eq!(x(1), Vec3A::ZERO, "the inner Separator's translation ends with it");
        assert_eq!(x(3), Vec3A::new(0.0, 5.0, 0.0));
        assert_eq!(scene.shapes[3].world.matrix3.x_axis.x, 2.0);
        let (lo, hi) = scene.bounds;
        assert!(lo.x < -1.99 && hi.x > 10.99 && hi.y > 5.99, "{lo} {hi}");
    }

    #[test]
    fn a_light_lights_what_follows_it_in_its_separator() {
        // Four cubes in a row, left to right: one before the light in its Separator, one after
        // it there, one after that Separator, one after a light that comes last but for it in a
        // Separator of its own.
        let (mut rt, scene) = load(
            "PerspectiveCamera { position 0 0 12 heightAngle 0.9 }
             Separator {
               Translation { translation -4.5 0 0 } Cube { }
               PointLight { location 1.5 0 4 }
               Translation { translation 3 0 0 } Cube { }
             }
             Translation { translation 1.5 0 0 } Cube { }
             Separator { Translation { translation 3 0 0 } Cube { } }
             DirectionalLight { direction 0 0 -1 }",
        );
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_eq!((scene.shapes.len(), scene.lights.len()), (4, 2));
        rt.options.width = 80;
        rt.options.height = 20;
        let (fb, _) = rt.render_frame().expect("renders");
        let at = |x: f32| {
            let p = rt.camera().world_from_camera.inverse().transform_point3a(Vec3A::new(x, 0.0, 1.0));
            let tan = (rt.camera().fov_degrees.to_radians() * 0.5).tan();
            // The image is wider than high: the field of view spans its height.
            let px = 40.0 + p.x / p.z / tan * 10.0;
            let c = fb.pixel(px.round() as u32, 10);
            c[0] + c[1] + c[2]
        };
        let lit = at(-1.5);
        assert!(lit > 0.3, "the cube after the light: {lit}");
        for x in [-4.5, 1.5, 4.5] {
            assert!(at(x) < 0.02, "the cube at {x} is not lit: {} against {lit}", at(x));
        }
        // The same file without the Separators: the point light lights the three after it.
        let (mut rt, _) = load(
            "PerspectiveCamera { position 0 0 12 heightAngle 0.9 }
             Translation { translation -4.5 0 0 } Cube { }
             PointLight { location 1.5 0 4 }
             Translation { translation 3 0 0 } Cube { }
             Translation { translation 3 0 0 } Cube { }",
        );
        rt.options.width = 80;
        rt.options.height = 20;
        let (fb, _) = rt.render_frame().expect("renders");
        let c = fb.pixel(40 + (1.5f32 / 12.0 / (0.45f32).tan() * 10.0).round() as u32, 10);
        assert!(c[0] + c[1] + c[2] > 0.3, "{c:?}");
    }

    #[test]
    fn a_matrix_transform_is_read_in_row_vector_order() {
        let (_, scene) = load("MatrixTransform { matrix 2 0 0 0  0 2 0 0  0 0 2 0  1 2 3 1 } Cube { }");
        let w = scene.shapes[0].world;
        assert_eq!(w.translation, Vec3A::new(1.0, 2.0, 3.0));
        assert_eq!(w.matrix3.x_axis.x, 2.0);
    }

    #[test]
    fn materials_bind_per_face_and_normals_per_vertex() {
        let (rt, scene) = load(
            "Material { diffuseColor [1 0 0, 0 1 0] }
             MaterialBinding { value PER_FACE_INDEXED }
             NormalBinding { value PER_VERTEX_INDEXED }
             ShapeHints { vertexOrdering CLOCKWISE creaseAngle 0 }
             Coordinate3 { point [0 0 0, 1 0 0, 1 1 0, 0 1 0] }
             Normal { vector [0 0 1] }
             IndexedFaceSet { coordIndex [0 1 2 -1 0 2 3 -1] materialIndex [1 0] normalIndex [0 0 0 -1 0 0 0 -1] }
             Cylinder { parts (SIDES | TOP) }
             IndexedLineSet { coordIndex [0 1] }",
        );
        assert_eq!(scene.shapes.len(), 2);
        let mesh = rt.object_mesh(scene.shape_objects[0]).expect("a mesh");
        assert!(!mesh.attributes.is_empty(), "the faces' colours");
        assert!(mesh.normals.as_ref().is_some_and(|n| n.iter().all(|n| n.z.abs() > 0.99)));
        // Sides and top: no bottom cap.
        let cylinder = rt.object_mesh(scene.shape_objects[1]).expect("a mesh");
        assert!(cylinder.positions.iter().all(|p| p.y > -0.99 || p.x * p.x + p.z * p.z > 0.98));
        let shown: Vec<String> = scene.warnings.iter().map(ToString::to_string).collect();
        assert_eq!(shown.len(), 1, "{shown:?}");
        assert!(shown[0].starts_with("v1.wrl:10:14: warning: IndexedLineSet is not drawn"), "{shown:?}");
    }

    #[test]
    fn a_vrml97_file_inlines_a_vrml1_file_and_moves_it() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        std::fs::write(
            dir.path().join("old.wrl"),
            "#VRML V1.0 ascii\nSeparator { PointLight { location 0 1 0 } Translation { translation 0 2 0 } Cube { } }",
        )
        .expect("written");
        let main = dir.path().join("main.wrl");
        std::fs::write(
            &main,
            "#VRML V2.0 utf8
             DEF T Transform { translation 5 0 0 children Inline { url \"old.wrl\" } }
             DEF P PositionInterpolator { key [0 1] keyValue [0 0 0, 0 0 10] }
             DEF C TimeSensor { loop TRUE }
             ROUTE C.fraction_changed TO P.set_fraction
             ROUTE P.value_changed TO T.set_translation",
        )
        .expect("written");
        let mut rt = Context::new();
        let mut scene = crate::vrml::load_file(&mut rt, &main).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_eq!(scene.files().len(), 2);
        assert_eq!(scene.shapes.len(), 1);
        assert_eq!(scene.shapes[0].world.translation, Vec3A::new(5.0, 2.0, 0.0));
        // The Transform above the Inline moves the VRML 1.0 shape, its own translation kept.
        scene.advance_to(0.5, &mut rt).expect("runs");
        let m = rt.instance_transform(scene.shapes[0].made).expect("placed");
        assert_eq!(m.translation, Vec3A::new(0.0, 2.0, 5.0));
        // Its light too.
        let light = rt.light_transform(scene.lights[0].made).expect("a light");
        assert_eq!(light.translation, Vec3A::new(0.0, 0.0, 5.0));
        rt.options.width = 8;
        rt.options.height = 8;
        rt.render_frame().expect("renders");
    }

    #[test]
    fn bad_files_are_errors_with_their_place() {
        let err = |text: &str| {
            let mut rt = Context::new();
            build_str_with(&mut rt, text, Path::new("v1.wrl"), &VrmlOptions::default())
                .expect_err("an error")
                .to_string()
        };
        assert!(err("#VRML V1.0 ascii\nSeparator { Cube { }").starts_with("v1.wrl:2:"), "{}", err("Separator {"));
        assert!(err("#VRML V1.0 ascii\nSeparator { width [ 1 { ] }").contains("v1.wrl:2:23"));
        let deep = "Separator { ".repeat(200);
        assert!(err(&deep).contains("nest deeper"));
        // Unknown nodes are skipped with their children, warned once.
        let (_, scene) = load("Frob { a 1 Cube { } } Frob { }\nCube { wdth 3 } Cube { wdth 4 }");
        assert_eq!(scene.shapes.len(), 2);
        let shown: Vec<String> = scene.warnings.iter().map(ToString::to_string).collect();
        assert_eq!(shown.len(), 2, "{shown:?}");
        assert!(shown[0].starts_with("v1.wrl:2:1: warning: unknown node type Frob"), "{shown:?}");
        assert!(shown[1].starts_with("v1.wrl:3:8: warning: Cube has no field `wdth`"), "{shown:?}");
    }
}

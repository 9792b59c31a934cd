//! The scene graph of a VRML 97 file walked into a [`Context`]: Shapes become objects (one per
//! geometry and appearance, instanced wherever the graph reaches them), lights become light
//! shaders, the first Viewpoint the camera, the first Background the image's background.
//!
//! The walk is depth-first from the file's top-level nodes, in file order, with the world matrix
//! of the Transforms above; grouping nodes (`Group`, `Transform`, `Switch`'s choice, `LOD`'s first
//! level, `Billboard`, `Anchor`, `Collision`, `Inline`) lead further. `docs/vrml.md` lists how each
//! node maps onto rtsl.

use super::linear;
use super::mesh::{self, FaceSet, Indexed};
use super::nodes::{knows_field, node_type, Support};
use super::parse::{Document, Value};
pub use super::relative_path;
use super::{
    check_header, location, read_text, Loc, NodeRef, Placed, Viewpoint, VrmlError, VrmlOptions, VrmlScene,
    MAX_INLINE_DEPTH, MAX_PROTO_DEPTH, MAX_VRML_NESTING, VRML_EAR_CLIP_BUDGET, VRML_LIGHT_SCOPE_BUDGET,
    VRML_TRAVERSAL_BUDGET,
};
use crate::api::{Context, ObjectId, ShaderId};
use crate::geometry::Mesh;
use crate::rib::{RibDiagnostic, Severity};
use crate::scene_file::{SceneFileError, MAX_MODEL_TRIANGLES};
use crate::shading::ParamValue;
use crate::texture::srgb_to_linear;
use glam::{Affine3A, Quat, Vec2, Vec3, Vec3A};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Reads the VRML file at `path` (and its Inline files) into `rt`.
pub fn build(rt: &mut Context, path: &Path) -> Result<VrmlScene> {
    build_with(rt, path, &VrmlOptions::default())
}

/// [`build`] with [`VrmlOptions`].
pub fn build_with(rt: &mut Context, path: &Path, options: &VrmlOptions) -> Result<VrmlScene> {
    let text = read_text(path)?;
    build_str_with(rt, &text, path, options)
}

/// Reads VRML text into `rt`; `path` names it in messages, and Inline URLs are resolved against
/// its folder.
pub fn build_str(rt: &mut Context, text: &str, path: &Path) -> Result<VrmlScene> {
    build_str_with(rt, text, path, &VrmlOptions::default())
}

/// [`build_str`] with [`VrmlOptions`].
pub fn build_str_with(rt: &mut Context, text: &str, path: &Path, options: &VrmlOptions) -> Result<VrmlScene> {
    let scene = VrmlScene { bounds: (Vec3A::INFINITY, Vec3A::NEG_INFINITY), ..VrmlScene::default() };
    let kept = Kept { surface: options.surface.clone(), ..Kept::default() };
    let mut b = Builder::new(rt, scene, kept);
    let doc = b.add_document(path, text)?;
    let main_canonical = b.canonical[doc].clone();
    b.inlines.extend(main_canonical);
    let roots = b.doc(doc).roots.clone();
    let mut trail = Vec::new();
    for root in roots {
        b.visit(NodeRef { doc, node: root }, Affine3A::IDENTITY, &mut trail, 0)?;
    }
    b.finish()?;
    let mut events = super::events::Events::new(&b.scene.documents, &b.files);
    b.scene.warnings.append(&mut events.warnings);
    b.scene.events = events;
    b.scene.kept = Kept {
        surface: b.surface.clone(),
        files: b.files.clone(),
        shaders: b.shaders.clone(),
        textures: b.textures.clone(),
        pixel_textures: b.pixel_textures,
    };
    let mut scene = b.scene;
    // Billboards and LODs were placed for the camera as the walk found it; the Viewpoint bound
    // after them may have moved it.
    scene.follow_camera(rt)?;
    scene.apply(rt)?;
    Ok(scene)
}

/// What the walk made that a later rebuild of an object (as animation changes its fields) uses
/// again: the files' names, the shaders found and the textures made.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Kept {
    surface: Option<String>,
    files: Vec<Arc<Path>>,
    shaders: HashMap<String, ShaderId>,
    textures: HashMap<NodeRef, Option<Texture>>,
    pixel_textures: usize,
}

/// The world-from-local matrix of what lies under `path` (its Transforms' fields as they stand).
pub(super) fn world_of(rt: &mut Context, scene: &mut VrmlScene, path: &[NodeRef]) -> Affine3A {
    with_builder(rt, scene, |b| {
        let mut world = Affine3A::IDENTITY;
        for &r in path {
            match b.type_of(r) {
                "Transform" => world *= b.transform(r),
                "Billboard" => world *= b.billboard(r, world),
                _ => {}
            }
        }
        Ok(world)
    })
    .unwrap_or(Affine3A::IDENTITY)
}

/// The level LOD `r` (reached along `path`) shows for the camera as it stands.
pub(super) fn lod_level_of(rt: &mut Context, scene: &mut VrmlScene, r: NodeRef, path: &[NodeRef]) -> usize {
    let world = world_of(rt, scene, path);
    with_builder(rt, scene, |b| {
        let levels = b.nodes(r, "level").len();
        Ok(b.lod_level(r, world, levels))
    })
    .unwrap_or(0)
}

/// Builds object `id` again from `geometry` and `appearance` as their fields stand (animation
/// changed a Material, a Coordinate...). Warnings about the new values are not repeated.
pub(super) fn remake_object(
    rt: &mut Context,
    scene: &mut VrmlScene,
    geometry: NodeRef,
    appearance: Option<NodeRef>,
    id: ObjectId,
) -> Result<()> {
    let lights = scene.object_lights.get(&id).cloned();
    with_builder(rt, scene, |b| b.make_object(geometry, appearance, Some(id), lights.as_deref()).map(|_| ()))
}

/// Places light `k` of `scene.lights` by `world` again, with its node's fields as they stand (an
/// animated Transform above it moved, or events changed its fields). A VRML 1.0 light (its fields
/// do not change) only moves.
pub(super) fn relight(rt: &mut Context, scene: &mut VrmlScene, k: usize, world: Affine3A) -> Result<()> {
    let Some(placed) = scene.lights.get_mut(k) else { return Ok(()) };
    placed.world = world;
    let (id, r) = (placed.made, placed.node);
    rt.set_light_transform(id, world)?;
    let type_name =
        scene.documents.get(r.doc).and_then(|(_, d)| d.nodes.get(r.node.0 as usize)).map(|n| n.type_name.clone());
    let Some(kind) = type_name.filter(|t| matches!(t.as_str(), "PointLight" | "SpotLight" | "DirectionalLight")) else {
        return Ok(());
    };
    let ambient = scene.ambient_lights.contains(&id);
    with_builder(rt, scene, |b| {
        let values = b.light_values(r, &kind, world)?;
        if ambient {
            b.rt.set_light_parameters(id, &values.ambient.0)?;
            b.rt.set_light(id, values.on && values.ambient.1 > 0.0, true)?;
        } else {
            b.rt.set_light_parameters(id, &values.params)?;
            b.rt.set_light(id, values.on, true)?;
        }
        Ok(())
    })
}

/// Places viewpoint `k` of `scene.viewpoints` by `world` again, with its node's fields as they
/// stand; the camera follows it when it is the bound one. A VRML 1.0 camera only moves.
pub(super) fn replace_viewpoint(rt: &mut Context, scene: &mut VrmlScene, k: usize, world: Affine3A) -> Result<()> {
    let Some(placed) = scene.viewpoints.get(k) else { return Ok(()) };
    let r = placed.node;
    let is_97 = scene.documents.get(r.doc).and_then(|(_, d)| d.nodes.get(r.node.0 as usize)).is_some();
    let view = if is_97 {
        with_builder(rt, scene, |b| Ok(b.viewpoint_values(r, world)))?
    } else {
        // The view as placed, carried from where it was to `world`.
        let placed = &scene.viewpoints[k];
        let to = world * placed.world.inverse();
        if !to.is_finite() {
            return Ok(());
        }
        let v = &placed.made;
        Viewpoint {
            eye: to.transform_point3a(v.eye),
            forward: to.transform_vector3a(v.forward).normalize_or(v.forward),
            up: to.transform_vector3a(v.up).normalize_or(v.up),
            ..v.clone()
        }
    };
    if scene.bound_viewpoint == Some(k) {
        view.look(rt);
    }
    let placed = &mut scene.viewpoints[k];
    placed.world = world;
    placed.made = view;
    Ok(())
}

/// Runs `f` with a builder over `scene` as the walk left it.
fn with_builder<T>(rt: &mut Context, scene: &mut VrmlScene, f: impl FnOnce(&mut Builder) -> Result<T>) -> Result<T> {
    let kept = std::mem::take(&mut scene.kept);
    let mut b = Builder::new(rt, std::mem::take(scene), kept);
    let (warnings, triangles) = (b.scene.warnings.len(), b.scene.triangles);
    let result = f(&mut b);
    b.scene.warnings.truncate(warnings);
    b.scene.triangles = triangles;
    b.scene.kept = Kept {
        surface: b.surface.take(),
        files: std::mem::take(&mut b.files),
        shaders: std::mem::take(&mut b.shaders),
        textures: std::mem::take(&mut b.textures),
        pixel_textures: b.pixel_textures,
    };
    *scene = std::mem::take(&mut b.scene);
    result
}

/// A texture an appearance names: its name for the shader, whether its colour replaces the
/// diffuse colour (RGB) or modulates it (intensity), and whether it has alpha.
#[derive(Clone, Debug, PartialEq)]
struct Texture {
    name: String,
    rgb: bool,
    alpha: bool,
    repeat: (bool, bool),
}

struct Builder<'a> {
    rt: &'a mut Context,
    scene: VrmlScene,
    /// Each document's file as messages name it.
    files: Vec<Arc<Path>>,
    /// Each document's canonical path, when it has one (an Inline of the same file is read once).
    canonical: Vec<Option<PathBuf>>,
    /// The files being walked, outermost first (cycles are errors).
    inlines: Vec<PathBuf>,
    warned: HashSet<String>,
    visits: usize,
    /// Each geometry node's mesh (its own coordinates, rtsl texture coordinates), or none.
    meshes: HashMap<NodeRef, Option<Arc<Mesh>>>,
    /// Each geometry-and-appearance pair's object, for each set of scoped DirectionalLights
    /// lighting it, and its own bounds, or none (nothing to draw).
    objects: HashMap<(NodeRef, Option<NodeRef>, usize), Option<Made>>,
    shaders: HashMap<String, ShaderId>,
    /// The surface shader that replaces `material` ([`VrmlOptions::surface`]).
    surface: Option<String>,
    /// Each texture node's texture, or none (missing, or not read).
    textures: HashMap<NodeRef, Option<Texture>>,
    camera_bound: bool,
    /// NavigationInfo's headlight, once the first was read.
    headlight: Option<bool>,
    background_bound: bool,
    fog_bound: bool,
    pixel_textures: usize,
    /// What is left of [`VRML_EAR_CLIP_BUDGET`].
    ear_clip_budget: usize,
    /// The Inline files that are VRML 1.0 (read by `super::v1` each time they are inlined).
    v1_files: HashSet<PathBuf>,
    /// How many routed Switches above the node being walked do not choose it (its shapes are
    /// placed hidden).
    unchosen: usize,
    /// DirectionalLights light their group's nodes only (see `scope_directional_lights`): the
    /// placements (the light and the path to its group) whose group is being walked,
    dir_scope: Vec<usize>,
    /// each placement's number,
    dir_placements: HashMap<(NodeRef, Vec<NodeRef>), usize>,
    /// the lights made for each,
    dir_lights: Vec<Vec<crate::api::LightId>>,
    /// each set of placements that lights a shape (its place its number) and each set's number,
    dir_sets: Vec<Vec<usize>>,
    dir_set_numbers: HashMap<Vec<usize>, usize>,
    /// and the objects made before the first scoped DirectionalLight was met, with their set.
    unscoped_objects: Vec<(NodeRef, Option<NodeRef>, ObjectId, usize)>,
}

type Result<T> = std::result::Result<T, SceneFileError>;

/// An object and the bounds of its mesh in its own space.
type Made = (ObjectId, (Vec3, Vec3));

/// A VRML 97 light's shader and values in its own space, whether it is on, and its ambient part's
/// values and `ambientIntensity`.
struct LightValues {
    shader: ShaderId,
    params: Vec<(&'static str, ParamValue)>,
    on: bool,
    ambient: (Vec<(&'static str, ParamValue)>, f32),
}

impl<'a> Builder<'a> {
    fn new(rt: &'a mut Context, scene: VrmlScene, kept: Kept) -> Builder<'a> {
        let canonical = vec![None; kept.files.len()];
        Builder {
            surface: kept.surface,
            rt,
            scene,
            files: kept.files,
            canonical,
            inlines: Vec::new(),
            warned: HashSet::new(),
            visits: 0,
            meshes: HashMap::new(),
            objects: HashMap::new(),
            shaders: kept.shaders,
            textures: kept.textures,
            camera_bound: false,
            headlight: None,
            background_bound: false,
            fog_bound: false,
            pixel_textures: kept.pixel_textures,
            ear_clip_budget: VRML_EAR_CLIP_BUDGET,
            v1_files: HashSet::new(),
            unchosen: 0,
            dir_scope: Vec::new(),
            dir_placements: HashMap::new(),
            dir_lights: Vec::new(),
            dir_sets: Vec::new(),
            dir_set_numbers: HashMap::new(),
            unscoped_objects: Vec::new(),
        }
    }

    fn doc(&self, doc: usize) -> &Document {
        &self.scene.documents[doc].1
    }

    fn type_of(&self, r: NodeRef) -> &str {
        &self.doc(r.doc).node(r.node).type_name
    }

    fn loc_of(&self, r: NodeRef) -> Loc {
        self.doc(r.doc).node(r.node).loc
    }

    fn error(&self, doc: usize, loc: Loc, message: impl Into<String>) -> SceneFileError {
        VrmlError::at(&self.files[doc], loc, message).into()
    }

    /// Parses `text` as the document of `path` and adds it.
    fn add_document(&mut self, path: &Path, text: &str) -> Result<usize> {
        let file: Arc<Path> = Arc::from(path);
        if let Some(w) = check_header(&file, text)? {
            self.scene.warnings.push(w);
        }
        let doc =
            super::parse::parse(text).map_err(|e| SceneFileError::from(VrmlError::at(&file, e.loc, e.message)))?;
        for (loc, message) in &doc.warnings {
            self.scene.warnings.push(RibDiagnostic::warning(&location(&file, *loc), message.clone()));
        }
        self.files.push(file);
        self.canonical.push(std::fs::canonicalize(path).ok());
        self.scene.documents.push((path.to_path_buf(), doc));
        Ok(self.scene.documents.len() - 1)
    }

    /// A warning, once per `key`.
    fn warn_once(&mut self, key: String, doc: usize, loc: Loc, severity: Severity, message: impl Into<String>) {
        if self.warned.insert(key) {
            let loc = location(&self.files[doc], loc);
            self.scene.warnings.push(RibDiagnostic { severity, loc, message: message.into() });
        }
    }

    fn shader(&mut self, name: &str) -> Result<ShaderId> {
        if let Some(&id) = self.shaders.get(name) {
            return Ok(id);
        }
        let id = self.rt.find_shader(name)?;
        self.shaders.insert(name.to_string(), id);
        Ok(id)
    }

    /// What node `r` stands for: itself, or the first node of a PROTO instance's body. `None` for
    /// an empty PROTO and an EXTERNPROTO's instance (warned once).
    fn resolve(&mut self, r: NodeRef) -> Option<NodeRef> {
        let mut r = r;
        for _ in 0..=MAX_PROTO_DEPTH + 1 {
            let node = self.doc(r.doc).node(r.node);
            if let Some(at) = node.extern_proto {
                let name = node.type_name.clone();
                let loc = node.loc;
                self.warn_once(
                    format!("extern:{name}"),
                    r.doc,
                    loc,
                    Severity::Omission,
                    format!(
                        "{name} is an EXTERNPROTO (declared at {}:{}), which is not read; its instances are skipped",
                        at.line, at.column
                    ),
                );
                return None;
            }
            match &node.expansion {
                Some(body) => r = NodeRef { doc: r.doc, node: *body.first()? },
                None => return Some(r),
            }
        }
        None
    }

    /// Warns once about each field of `r` its (standard) type does not have.
    fn check_fields(&mut self, r: NodeRef) {
        let node = self.doc(r.doc).node(r.node);
        let Some((_, known)) = node_type(&node.type_name) else { return };
        if node.type_name == "Script" {
            return;
        }
        let unknown: Vec<(String, Loc)> =
            node.fields.iter().filter(|f| !knows_field(known, &f.name)).map(|f| (f.name.clone(), f.loc)).collect();
        let type_name = node.type_name.clone();
        for (name, loc) in unknown {
            self.warn_once(
                format!("field:{type_name}.{name}"),
                r.doc,
                loc,
                Severity::Warning,
                format!("{type_name} has no field `{name}`; it is ignored"),
            );
        }
    }

    // ---- Field values ----

    /// Field `name` of `r` converted by `convert`; `None` when absent or empty, and when the value
    /// does not convert (a warning, once per node type and field, naming `expects`).
    fn get<T>(&mut self, r: NodeRef, name: &str, expects: &str, convert: impl Fn(&Value) -> Option<T>) -> Option<T> {
        let node = self.doc(r.doc).node(r.node);
        let field = node.field(name)?;
        if matches!(field.value, Value::Empty) {
            return None;
        }
        let loc = field.loc;
        match convert(&field.value) {
            Some(v) => Some(v),
            None => {
                let type_name = node.type_name.clone();
                self.warn_once(
                    format!("value:{type_name}.{name}"),
                    r.doc,
                    loc,
                    Severity::Warning,
                    format!("{type_name}.{name} expects {expects}; the value is ignored"),
                );
                None
            }
        }
    }

    fn numbers(&mut self, r: NodeRef, name: &str, count: usize, expects: &str) -> Option<Vec<f32>> {
        self.get(r, name, expects, |v| match v {
            Value::Numbers(n) if n.len() == count || (count == 0 && !n.is_empty()) => {
                let f: Vec<f32> = n.iter().map(|&x| x as f32).collect();
                f.iter().all(|x| x.is_finite()).then_some(f)
            }
            _ => None,
        })
    }

    fn float(&mut self, r: NodeRef, name: &str, default: f32) -> f32 {
        self.numbers(r, name, 1, "one number").map_or(default, |v| v[0])
    }

    fn int(&mut self, r: NodeRef, name: &str, default: i32) -> i32 {
        self.get(r, name, "an integer", |v| match v {
            Value::Numbers(n) if n.len() == 1 && n[0].fract() == 0.0 && n[0].abs() <= i32::MAX as f64 => {
                Some(n[0] as i32)
            }
            _ => None,
        })
        .unwrap_or(default)
    }

    fn boolean(&mut self, r: NodeRef, name: &str, default: bool) -> bool {
        self.get(r, name, "TRUE or FALSE", |v| match v {
            Value::Bools(b) if b.len() == 1 => Some(b[0]),
            _ => None,
        })
        .unwrap_or(default)
    }

    fn vec3(&mut self, r: NodeRef, name: &str, default: Vec3) -> Vec3 {
        self.numbers(r, name, 3, "three numbers").map_or(default, |v| Vec3::new(v[0], v[1], v[2]))
    }

    fn vec2(&mut self, r: NodeRef, name: &str, default: Vec2) -> Vec2 {
        self.numbers(r, name, 2, "two numbers").map_or(default, |v| Vec2::new(v[0], v[1]))
    }

    /// An `SFRotation` (axis and angle) as a quaternion.
    fn rotation(&mut self, r: NodeRef, name: &str) -> Quat {
        self.numbers(r, name, 4, "an axis and an angle (four numbers)").map_or(Quat::IDENTITY, |v| rotation(&v))
    }

    fn vec3s(&mut self, r: NodeRef, name: &str) -> Vec<Vec3> {
        self.get(r, name, "triples of numbers", |v| match v {
            Value::Numbers(n) if n.len() % 3 == 0 => {
                let out: Vec<Vec3> =
                    n.chunks_exact(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect();
                out.iter().all(|p| p.is_finite()).then_some(out)
            }
            _ => None,
        })
        .unwrap_or_default()
    }

    fn vec2s(&mut self, r: NodeRef, name: &str) -> Vec<Vec2> {
        self.get(r, name, "pairs of numbers", |v| match v {
            Value::Numbers(n) if n.len() % 2 == 0 => {
                let out: Vec<Vec2> = n.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect();
                out.iter().all(|p| p.is_finite()).then_some(out)
            }
            _ => None,
        })
        .unwrap_or_default()
    }

    fn floats(&mut self, r: NodeRef, name: &str) -> Vec<f32> {
        self.numbers(r, name, 0, "numbers").unwrap_or_default()
    }

    fn rotations(&mut self, r: NodeRef, name: &str) -> Vec<Quat> {
        self.get(r, name, "rotations (four numbers each)", |v| match v {
            Value::Numbers(n) if n.len() % 4 == 0 => {
                let f: Vec<f32> = n.iter().map(|&x| x as f32).collect();
                f.iter().all(|x| x.is_finite()).then(|| f.chunks_exact(4).map(rotation).collect())
            }
            _ => None,
        })
        .unwrap_or_default()
    }

    fn ints(&mut self, r: NodeRef, name: &str) -> Vec<i32> {
        self.get(r, name, "integers", |v| match v {
            Value::Numbers(n) => n
                .iter()
                .map(|&x| (x.fract() == 0.0 && x >= i32::MIN as f64 && x <= i32::MAX as f64).then_some(x as i32))
                .collect(),
            _ => None,
        })
        .unwrap_or_default()
    }

    fn strings(&mut self, r: NodeRef, name: &str) -> Vec<String> {
        self.get(r, name, "strings", |v| match v {
            Value::Strings(s) => Some(s.clone()),
            _ => None,
        })
        .unwrap_or_default()
    }

    /// An `SFNode` field (what it stands for, PROTO instances resolved).
    fn node(&mut self, r: NodeRef, name: &str) -> Option<NodeRef> {
        let found = self.get(r, name, "a node", |v| match v {
            Value::Node(n) => Some(*n),
            Value::Nodes(v) if v.len() <= 1 => Some(v.first().copied()),
            _ => None,
        })??;
        self.resolve(NodeRef { doc: r.doc, node: found })
    }

    /// An `MFNode` field, as written (PROTO instances not resolved).
    fn nodes(&mut self, r: NodeRef, name: &str) -> Vec<NodeRef> {
        let found = self
            .get(r, name, "nodes", |v| match v {
                Value::Nodes(v) => Some(v.clone()),
                Value::Node(n) => Some(n.iter().copied().collect()),
                _ => None,
            })
            .unwrap_or_default();
        found.into_iter().map(|node| NodeRef { doc: r.doc, node }).collect()
    }

    // ---- The walk ----

    fn visit(&mut self, r: NodeRef, world: Affine3A, trail: &mut Vec<NodeRef>, depth: usize) -> Result<()> {
        self.visits += 1;
        if self.visits > VRML_TRAVERSAL_BUDGET {
            let loc = self.loc_of(r);
            return Err(self.error(
                r.doc,
                loc,
                format!("the scene graph has more than {VRML_TRAVERSAL_BUDGET} nodes once every USE is followed"),
            ));
        }
        if depth >= MAX_VRML_NESTING {
            let loc = self.loc_of(r);
            return Err(self.error(r.doc, loc, format!("nodes nest deeper than {MAX_VRML_NESTING} levels")));
        }
        // A PROTO instance is its body's first node, reached through the instance.
        if self.doc(r.doc).node(r.node).expansion.is_some() || self.doc(r.doc).node(r.node).extern_proto.is_some() {
            let Some(target) = self.resolve(r) else { return Ok(()) };
            trail.push(r);
            let result = self.visit(target, world, trail, depth + 1);
            trail.pop();
            return result;
        }
        let type_name = self.type_of(r).to_string();
        let loc = self.loc_of(r);
        let Some((support, _)) = node_type(&type_name) else {
            self.warn_once(
                format!("node:{type_name}"),
                r.doc,
                loc,
                Severity::Omission,
                format!("unknown node type {type_name}; it is skipped"),
            );
            return Ok(());
        };
        self.check_fields(r);
        let children = |b: &mut Self, fields: &[&str], world: Affine3A, trail: &mut Vec<NodeRef>| -> Result<()> {
            trail.push(r);
            let kids: Vec<NodeRef> = fields.iter().flat_map(|field| b.nodes(r, field)).collect();
            let scope = b.enter_scope(&kids, trail);
            for child in kids {
                b.visit(child, world, trail, depth + 1)?;
            }
            b.dir_scope.truncate(scope);
            trail.pop();
            Ok(())
        };
        match type_name.as_str() {
            "Group" | "Anchor" | "Collision" => children(self, &["children"], world, trail),
            "Billboard" => {
                // Turned to the camera as it stands now; the animation pass turns it again as the
                // camera moves (a Viewpoint bound later, the viewer's navigation).
                self.scene.view_nodes.push(r);
                let turned = world * self.billboard(r, world);
                children(self, &["children"], turned, trail)
            }
            "Transform" => {
                let m = world * self.transform(r);
                children(self, &["children"], m, trail)
            }
            "Switch" => {
                let which = self.int(r, "whichChoice", -1);
                let choices = self.nodes(r, "choice");
                // A Switch that a ROUTE can change has every choice placed, those not chosen
                // hidden (their instances deleted) until it chooses them.
                if self.is_routed_switch(r) {
                    trail.push(r);
                    for (k, choice) in choices.into_iter().enumerate() {
                        let unchosen = usize::try_from(which).ok() != Some(k);
                        self.unchosen += usize::from(unchosen);
                        let result = self.visit(choice, world, trail, depth + 1);
                        self.unchosen -= usize::from(unchosen);
                        if result.is_err() {
                            trail.pop();
                            return result;
                        }
                    }
                    trail.pop();
                    return Ok(());
                }
                if let Some(&chosen) = usize::try_from(which).ok().and_then(|i| choices.get(i)) {
                    trail.push(r);
                    let result = self.visit(chosen, world, trail, depth + 1);
                    trail.pop();
                    result?;
                }
                Ok(())
            }
            "LOD" => {
                // Every level is placed, those not chosen for the camera as it stands hidden; the
                // animation pass chooses again as the camera moves.
                self.scene.view_nodes.push(r);
                let levels = self.nodes(r, "level");
                let chosen = self.lod_level(r, world, levels.len());
                self.scene.lod_levels.insert(r, chosen);
                trail.push(r);
                for (k, level) in levels.into_iter().enumerate() {
                    let unchosen = k != chosen;
                    self.unchosen += usize::from(unchosen);
                    let result = self.visit(level, world, trail, depth + 1);
                    self.unchosen -= usize::from(unchosen);
                    if result.is_err() {
                        trail.pop();
                        return result;
                    }
                }
                trail.pop();
                Ok(())
            }
            "Inline" => self.inline(r, world, trail, depth),
            "Shape" => self.shape(r, world, trail),
            "PointLight" | "SpotLight" | "DirectionalLight" => self.light(r, &type_name, world, trail),
            "Viewpoint" => {
                self.viewpoint(r, world, trail);
                Ok(())
            }
            "ProximitySensor" | "VisibilitySensor" => {
                // Sensed against the camera at each timestamp, in the space of the Transforms
                // above them.
                self.scene.sensors.push(Placed {
                    made: (),
                    node: r,
                    path: trail.to_vec(),
                    world,
                    local: Affine3A::IDENTITY,
                });
                Ok(())
            }
            "NavigationInfo" => {
                if self.headlight.is_none() && r.doc == 0 {
                    self.headlight = Some(self.boolean(r, "headlight", true));
                }
                Ok(())
            }
            "Background" => self.background(r, world),
            "Fog" => self.fog(r, world),
            _ => {
                match support {
                    Support::Read => self.warn_once(
                        format!("child:{type_name}"),
                        r.doc,
                        loc,
                        Severity::Warning,
                        format!(
                            "{type_name} is not a child node (it belongs in a field of another node); it is skipped"
                        ),
                    ),
                    Support::Omitted => self.warn_once(
                        format!("node:{type_name}"),
                        r.doc,
                        loc,
                        Severity::Omission,
                        format!("{type_name} is not drawn; it is skipped"),
                    ),
                    Support::Static => self.warn_once(
                        format!("node:{type_name}"),
                        r.doc,
                        loc,
                        Severity::Warning,
                        format!("{type_name} is skipped: scripts and sound are not run"),
                    ),
                    Support::Silent | Support::Runs => {}
                }
                Ok(())
            }
        }
    }

    /// Whether a ROUTE of `r`'s file sends `whichChoice` to the Switch `r`.
    fn is_routed_switch(&self, r: NodeRef) -> bool {
        let doc = self.doc(r.doc);
        doc.routes.iter().any(|route| {
            !route.in_proto
                && doc.defs.get(&route.to.0) == Some(&r.node)
                && matches!(route.to.1.as_str(), "whichChoice" | "set_whichChoice")
        })
    }

    /// A Transform's matrix: `T C R SR S -SR -C` (ISO/IEC 14772-1, 6.52).
    fn transform(&mut self, r: NodeRef) -> Affine3A {
        let t = self.vec3(r, "translation", Vec3::ZERO);
        let c = self.vec3(r, "center", Vec3::ZERO);
        let rot = self.rotation(r, "rotation");
        let s = self.vec3(r, "scale", Vec3::ONE);
        let so = self.rotation(r, "scaleOrientation");
        Affine3A::from_translation(t + c)
            * Affine3A::from_quat(rot)
            * Affine3A::from_quat(so)
            * Affine3A::from_scale(s)
            * Affine3A::from_quat(so.inverse())
            * Affine3A::from_translation(-c)
    }

    fn inline(&mut self, r: NodeRef, world: Affine3A, trail: &mut Vec<NodeRef>, depth: usize) -> Result<()> {
        let urls = self.strings(r, "url");
        let loc = self.doc(r.doc).node(r.node).field("url").map_or(self.loc_of(r), |f| f.loc);
        let dir = self.scene.documents[r.doc].0.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut refused = None;
        let mut chosen = None;
        for url in &urls {
            match relative_path(url) {
                Ok(rel) => {
                    chosen = Some((url.clone(), dir.join(rel)));
                    break;
                }
                Err(why) => refused = refused.or(Some(format!("Inline URL \"{url}\" {why}"))),
            }
        }
        let Some((url, path)) = chosen else {
            return match refused {
                Some(message) => Err(self.error(r.doc, loc, message)),
                None => Ok(()),
            };
        };
        let Ok(canonical) = std::fs::canonicalize(&path) else {
            self.warn_once(
                format!("inline:{}", path.display()),
                r.doc,
                loc,
                Severity::Omission,
                format!("Inline \"{url}\": {} not found; it is skipped", path.display()),
            );
            return Ok(());
        };
        if self.inlines.contains(&canonical) {
            return Err(self.error(r.doc, loc, format!("Inline \"{url}\" includes a file that includes it (a cycle)")));
        }
        if self.inlines.len() > MAX_INLINE_DEPTH {
            return Err(self.error(r.doc, loc, format!("Inline files nest deeper than {MAX_INLINE_DEPTH} levels")));
        }
        let known = self.canonical.iter().position(|c| c.as_ref() == Some(&canonical));
        let doc = match known {
            Some(doc) if !self.v1_files.contains(&canonical) => doc,
            _ => {
                let text = read_text(&path)?;
                if super::is_vrml1(&text) {
                    // A VRML 1.0 file: built by its own reader under this Inline's matrix.
                    self.v1_files.insert(canonical.clone());
                    self.inlines.push(canonical);
                    trail.push(r);
                    let scene = std::mem::take(&mut self.scene);
                    let mut inlined = super::v1::Inlined {
                        scene,
                        world,
                        path: trail.clone(),
                        depth: depth + 1,
                        visits: self.visits,
                        ear_clip_budget: self.ear_clip_budget,
                    };
                    let before = inlined.scene.shapes.len();
                    let result = super::v1::build_into(self.rt, &text, &path, self.surface.as_deref(), &mut inlined);
                    self.scene = inlined.scene;
                    if self.unchosen > 0 {
                        for i in before..self.scene.shapes.len() {
                            self.rt.delete_instance(self.scene.shapes[i].made)?;
                            self.scene.hidden_shapes.insert(i);
                        }
                    }
                    (self.visits, self.ear_clip_budget) = (inlined.visits, inlined.ear_clip_budget);
                    self.files.push(Arc::from(path.as_path()));
                    self.canonical.push(None);
                    trail.pop();
                    self.inlines.pop();
                    return result;
                }
                self.add_document(&path, &text)?
            }
        };
        self.inlines.push(canonical);
        trail.push(r);
        let roots: Vec<NodeRef> = self.doc(doc).roots.iter().map(|&node| NodeRef { doc, node }).collect();
        let scope = self.enter_scope(&roots, trail);
        let mut result = Ok(());
        for root in roots {
            result = self.visit(root, world, trail, depth + 1);
            if result.is_err() {
                break;
            }
        }
        self.dir_scope.truncate(scope);
        trail.pop();
        self.inlines.pop();
        result
    }

    /// Puts the DirectionalLights among a group's `kids` (`trail` ending with the group) in
    /// scope for the walk of them; returns the scope's length before, to cut it back to after.
    /// The scene file's top-level ones light everything and are not scoped.
    fn enter_scope(&mut self, kids: &[NodeRef], trail: &[NodeRef]) -> usize {
        let before = self.dir_scope.len();
        if trail.is_empty() {
            return before;
        }
        for &c in kids {
            let node = self.doc(c.doc).node(c.node);
            if node.type_name != "DirectionalLight" || node.expansion.is_some() || node.extern_proto.is_some() {
                continue;
            }
            let next = self.dir_placements.len();
            let k = *self.dir_placements.entry((c, trail.to_vec())).or_insert(next);
            if k == next {
                self.dir_lights.push(Vec::new());
            }
            self.dir_scope.push(k);
        }
        before
    }

    /// The number of the set of scoped DirectionalLights lighting what is walked now.
    fn light_set(&mut self) -> usize {
        let mut set = self.dir_scope.clone();
        set.sort_unstable();
        set.dedup();
        if let Some(&k) = self.dir_set_numbers.get(&set) {
            return k;
        }
        self.dir_sets.push(set.clone());
        self.dir_set_numbers.insert(set, self.dir_sets.len() - 1);
        self.dir_sets.len() - 1
    }

    fn viewpoint(&mut self, r: NodeRef, world: Affine3A, trail: &[NodeRef]) {
        let view = self.viewpoint_values(r, world);
        // The first Viewpoint of the scene file is bound; Inline files bind none.
        if !self.camera_bound && r.doc == 0 {
            self.camera_bound = true;
            self.scene.bound_viewpoint = Some(self.scene.viewpoints.len());
            view.look(self.rt);
        }
        self.scene.viewpoints.push(Placed {
            made: view,
            node: r,
            path: trail.to_vec(),
            world,
            local: Affine3A::IDENTITY,
        });
    }

    /// A Viewpoint's view in the world, placed by `world`.
    fn viewpoint_values(&mut self, r: NodeRef, world: Affine3A) -> Viewpoint {
        let position = self.vec3(r, "position", Vec3::new(0.0, 0.0, 10.0));
        let orientation = self.rotation(r, "orientation");
        let field_of_view = self.float(r, "fieldOfView", std::f32::consts::FRAC_PI_4);
        let description = self.strings(r, "description").into_iter().next().unwrap_or_default();
        let eye = world.transform_point3a(Vec3A::from(position));
        let forward = world.transform_vector3a(Vec3A::from(orientation * Vec3::NEG_Z)).normalize_or(Vec3A::NEG_Z);
        let up = world.transform_vector3a(Vec3A::from(orientation * Vec3::Y)).normalize_or(Vec3A::Y);
        let field_of_view = if field_of_view > 0.0 && field_of_view < std::f32::consts::PI {
            field_of_view
        } else {
            std::f32::consts::FRAC_PI_4
        };
        Viewpoint { description, eye, forward, up, field_of_view }
    }

    /// A Billboard's rotation (ISO/IEC 14772-1, 6.6) in its parent's frame `world`, toward the
    /// camera as it stands: about `axisOfRotation` so that the local +z axis points at the viewer
    /// as nearly as the axis allows, or, for a zero axis, with +z at the viewer and +y along the
    /// camera's up. Identity where the viewer is on the axis (or the frame is degenerate).
    fn billboard(&mut self, r: NodeRef, world: Affine3A) -> Affine3A {
        let axis = self.vec3(r, "axisOfRotation", Vec3::Y);
        let camera = *self.rt.camera();
        let local_from_world = world.inverse();
        if !local_from_world.is_finite() {
            return Affine3A::IDENTITY;
        }
        let eye = Vec3::from(local_from_world.transform_point3a(camera.eye()));
        let turn = if axis.length_squared() < 1e-12 {
            let up = Vec3::from(local_from_world.transform_vector3a(camera.world_from_camera.matrix3.y_axis));
            let z = eye.normalize_or_zero();
            let x = up.cross(z).normalize_or_zero();
            if z == Vec3::ZERO || x == Vec3::ZERO {
                return Affine3A::IDENTITY;
            }
            Quat::from_mat3(&glam::Mat3::from_cols(x, z.cross(x), z))
        } else {
            let a = axis.normalize();
            let to_eye = eye - a * a.dot(eye);
            let z = Vec3::Z - a * a.z;
            if to_eye.length_squared() < 1e-12 || z.length_squared() < 1e-12 {
                return Affine3A::IDENTITY;
            }
            let (to_eye, z) = (to_eye.normalize(), z.normalize());
            Quat::from_axis_angle(a, z.cross(to_eye).dot(a).atan2(z.dot(to_eye)))
        };
        Affine3A::from_quat(turn)
    }

    /// The level an LOD shows (6.26) for the camera as it stands: the first whose `range` entry
    /// is beyond the viewer's distance from `center` in the LOD's frame `world`, the last past
    /// them all; the first without ranges.
    fn lod_level(&mut self, r: NodeRef, world: Affine3A, levels: usize) -> usize {
        let ranges = self.floats(r, "range");
        let center = self.vec3(r, "center", Vec3::ZERO);
        let eye = Vec3::from(world.inverse().transform_point3a(self.rt.camera().eye()));
        let distance = eye.distance(center);
        let k = if ranges.is_empty() || !distance.is_finite() {
            0
        } else {
            ranges.iter().position(|&x| distance < x).unwrap_or(ranges.len())
        };
        k.min(levels.saturating_sub(1))
    }

    /// The first Background of the scene file: one sky colour alone is the `background` imager's
    /// colour; gradients or panorama images become an environment map (`vrml::background`) that
    /// the `envbackground` imager shows along each camera ray.
    fn background(&mut self, r: NodeRef, world: Affine3A) -> Result<()> {
        if self.background_bound || r.doc != 0 {
            return Ok(());
        }
        self.background_bound = true;
        let sky: Vec<[f32; 3]> = self.vec3s(r, "skyColor").into_iter().map(linear).collect();
        let ground: Vec<[f32; 3]> = self.vec3s(r, "groundColor").into_iter().map(linear).collect();
        let dir = self.scene.documents[r.doc].0.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut faces = Vec::new();
        for (field, axis, right, up) in super::background::FACES {
            let urls = self.strings(r, field);
            if urls.is_empty() {
                continue;
            }
            let loc = self.doc(r.doc).node(r.node).field(field).map_or(self.loc_of(r), |f| f.loc);
            let found =
                urls.iter().find_map(|u| relative_path(u).ok().map(|rel| dir.join(rel)).filter(|p| p.is_file()));
            let loaded = found.as_deref().map(|path| crate::texture::load_texture_image(path, false));
            match loaded {
                Some(Ok(image)) => faces.push(super::background::Face { image: image.image, axis, right, up }),
                Some(Err(e)) => self.warn_once(
                    format!("background:{field}"),
                    r.doc,
                    loc,
                    Severity::Omission,
                    format!("Background {field}: {e}; that face of the panorama is not drawn"),
                ),
                None => self.warn_once(
                    format!("background:{field}"),
                    r.doc,
                    loc,
                    Severity::Omission,
                    format!(
                        "Background {field}: no URL names a file inside the scene's folder ({}); that face of the panorama is not drawn",
                        urls.join(", ")
                    ),
                ),
            }
        }
        let color = sky.first().copied().unwrap_or([0.0; 3]);
        if sky.len() <= 1 && ground.len() <= 1 && faces.is_empty() {
            let id = self.shader("background")?;
            self.rt.pixel_shader(Some(id), &[("background", ParamValue::Color(color))])?;
            return Ok(());
        }
        let backdrop = super::background::Backdrop {
            sky,
            sky_angles: self.floats(r, "skyAngle"),
            ground,
            ground_angles: self.floats(r, "groundAngle"),
            faces,
            rotation: world.to_scale_rotation_translation().1,
        };
        let (w, h, texels) = backdrop.map();
        let name = format!("{}#background", self.files[r.doc].display());
        self.rt.tex_image_2d(&name, w, h, 3, &texels)?;
        let id = self.shader("envbackground")?;
        self.rt.pixel_shader(
            Some(id),
            &[("envname", ParamValue::String(name)), ("background", ParamValue::Color(color))],
        )?;
        Ok(())
    }

    /// The first Fog of the scene file, through the `vrmlfog` atmosphere: VRML's LINEAR or
    /// EXPONENTIAL blend by the distance from the eye, its `visibilityRange` scaled by the
    /// Transforms above it (6.19).
    fn fog(&mut self, r: NodeRef, world: Affine3A) -> Result<()> {
        if self.fog_bound || r.doc != 0 {
            return Ok(());
        }
        self.fog_bound = true;
        let scale = world.matrix3.determinant().abs().cbrt();
        let range = self.float(r, "visibilityRange", 0.0) * if scale.is_finite() { scale } else { 1.0 };
        if range <= 0.0 || !range.is_finite() {
            return Ok(());
        }
        let color = linear(self.vec3(r, "color", Vec3::ONE));
        let kind = self.strings(r, "fogType").into_iter().next().unwrap_or_else(|| "LINEAR".into());
        let id = self.shader("vrmlfog")?;
        self.rt.atmosphere(
            Some(id),
            &[
                ("fogcolor", ParamValue::Color(color)),
                ("visibilityrange", ParamValue::Float(range)),
                ("exponential", ParamValue::Float(if kind == "EXPONENTIAL" { 1.0 } else { 0.0 })),
            ],
        )?;
        Ok(())
    }

    fn light(&mut self, r: NodeRef, kind: &str, world: Affine3A, trail: &[NodeRef]) -> Result<()> {
        let values = self.light_values(r, kind, world)?;
        // VRML's ambient term of a light is an ambient light of its own (without attenuation),
        // made when the file gives one or a ROUTE may.
        let with_ambient = values.ambient.1 > 0.0 || self.is_routed(r, &["ambientIntensity", "set_ambientIntensity"]);
        let mut made = Vec::new();
        self.rt.push_matrix();
        self.rt.load_matrix(world);
        let result = (|| -> Result<()> {
            made.push((self.rt.light_source(values.shader, &values.params)?, values.on));
            if with_ambient {
                let id = self.shader("ambientlight")?;
                let light = self.rt.light_source(id, &values.ambient.0)?;
                made.push((light, values.on && values.ambient.1 > 0.0));
            }
            Ok(())
        })();
        self.rt.pop_matrix()?;
        result?;
        if let (Some(&k), Some((main, _))) = (self.dir_placements.get(&(r, trail.to_vec())), made.first()) {
            self.dir_lights[k].push(*main);
        }
        for (k, (id, on)) in made.into_iter().enumerate() {
            if !on {
                self.rt.set_light(id, false, true)?;
            }
            if k == 1 {
                self.scene.ambient_lights.push(id);
            }
            self.scene.lights.push(Placed {
                made: id,
                node: r,
                path: trail.to_vec(),
                world,
                local: Affine3A::IDENTITY,
            });
        }
        Ok(())
    }

    /// Whether a ROUTE of `r`'s file sends one of `events` to `r`.
    fn is_routed(&self, r: NodeRef, events: &[&str]) -> bool {
        let doc = self.doc(r.doc);
        doc.routes.iter().any(|route| {
            !route.in_proto && doc.defs.get(&route.to.0) == Some(&r.node) && events.contains(&route.to.1.as_str())
        })
    }

    /// A VRML 97 light's shader and values in its own space, placed by `world` (the light's
    /// attenuation and radius are in that space's units, so they are rescaled by its scale).
    fn light_values(&mut self, r: NodeRef, kind: &str, world: Affine3A) -> Result<LightValues> {
        let on = self.boolean(r, "on", true);
        let intensity = self.float(r, "intensity", 1.0).max(0.0);
        let ambient = self.float(r, "ambientIntensity", 0.0).max(0.0);
        let color = linear(self.vec3(r, "color", Vec3::ONE));
        let mut params = vec![("intensity", ParamValue::Float(intensity)), ("lightcolor", ParamValue::Color(color))];
        let scale = world.matrix3.determinant().abs().cbrt().max(1e-12);
        let shader = match kind {
            "DirectionalLight" => {
                let direction = self.vec3(r, "direction", Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                params.push(("from", ParamValue::Point([0.0; 3])));
                params.push(("to", ParamValue::Point(direction.to_array())));
                "distantlight"
            }
            _ => {
                let location = self.vec3(r, "location", Vec3::ZERO);
                let attenuation = self.numbers(r, "attenuation", 3, "three numbers").unwrap_or(vec![1.0, 0.0, 0.0]);
                let radius = self.float(r, "radius", 100.0).max(0.0);
                params.push(("from", ParamValue::Point(location.to_array())));
                params.push(("constantattenuation", ParamValue::Float(attenuation[0].max(0.0))));
                params.push(("linearattenuation", ParamValue::Float(attenuation[1].max(0.0) / scale)));
                params.push(("quadraticattenuation", ParamValue::Float(attenuation[2].max(0.0) / (scale * scale))));
                params.push(("radius", ParamValue::Float(radius * scale)));
                if kind == "SpotLight" {
                    let direction = self.vec3(r, "direction", Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                    let half = std::f32::consts::FRAC_PI_2;
                    params.push(("to", ParamValue::Point((location + direction).to_array())));
                    params.push(("beamwidth", ParamValue::Float(self.float(r, "beamWidth", half).clamp(0.0, half))));
                    let cut_off = self.float(r, "cutOffAngle", std::f32::consts::FRAC_PI_4).clamp(0.0, half);
                    params.push(("cutoffangle", ParamValue::Float(cut_off)));
                    "vrmlspotlight"
                } else {
                    "vrmlpointlight"
                }
            }
        };
        let ambient_params =
            vec![("intensity", ParamValue::Float(intensity * ambient)), ("lightcolor", ParamValue::Color(color))];
        Ok(LightValues { shader: self.shader(shader)?, params, on, ambient: (ambient_params, ambient) })
    }

    // ---- Shapes ----

    fn shape(&mut self, r: NodeRef, world: Affine3A, trail: &[NodeRef]) -> Result<()> {
        let Some(geometry) = self.node(r, "geometry") else { return Ok(()) };
        let appearance = self.node(r, "appearance");
        // One object per set of scoped DirectionalLights lighting it too.
        let set = self.light_set();
        let key = (geometry, appearance, set);
        let object = match self.objects.get(&key) {
            Some(done) => *done,
            None => {
                let lights = (!self.dir_placements.is_empty()).then(|| format!("-vrml97dir:{set}"));
                let made = self.make_object(geometry, appearance, None, lights.as_deref())?;
                self.objects.insert(key, made);
                if let Some((id, _)) = made {
                    self.scene.objects.push((geometry, appearance, id));
                    match lights {
                        Some(lights) => {
                            self.scene.object_lights.insert(id, lights);
                        }
                        None => self.unscoped_objects.push((geometry, appearance, id, set)),
                    }
                }
                made
            }
        };
        let Some((id, (lo, hi))) = object else { return Ok(()) };
        // A matrix without an inverse (a scale of 0, which files use to hide shapes) places nothing
        // the tracer can take.
        let det = world.matrix3.determinant();
        if !(world.is_finite() && det != 0.0 && det.is_finite() && world.inverse().is_finite()) {
            let loc = self.loc_of(r);
            self.warn_once(
                format!("singular:{}:{}:{}", r.doc, loc.line, loc.column),
                r.doc,
                loc,
                Severity::Warning,
                "this Shape's Transforms scale it to nothing (or to infinity); it is not drawn",
            );
            return Ok(());
        }
        let instance = super::place_instance(self.rt, &mut self.scene, id, world, (lo, hi))?;
        self.scene.shapes.push(Placed {
            made: instance,
            node: r,
            path: trail.to_vec(),
            world,
            local: Affine3A::IDENTITY,
        });
        self.scene.shape_objects.push(id);
        if self.unchosen > 0 {
            self.rt.delete_instance(instance)?;
            self.scene.hidden_shapes.insert(self.scene.shapes.len() - 1);
        }
        Ok(())
    }

    /// The object of `geometry` drawn with `appearance`, with its own bounds; `None` when there is
    /// nothing to draw. With `into`, that object is built again (left empty when there is nothing
    /// to draw).
    fn make_object(
        &mut self,
        geometry: NodeRef,
        appearance: Option<NodeRef>,
        into: Option<ObjectId>,
        lights: Option<&str>,
    ) -> Result<Option<Made>> {
        let Some(mesh) = self.geometry(geometry)? else {
            if let Some(id) = into {
                self.rt.redefine_object(id)?;
                self.rt.end_object()?;
            }
            return Ok(None);
        };
        if let Some(a) = appearance {
            self.check_fields(a);
        }
        let material = appearance.and_then(|a| self.node(a, "material"));
        let texture = match appearance.and_then(|a| self.node(a, "texture")) {
            Some(t) => self.texture(t)?,
            None => None,
        };
        let transform = appearance.and_then(|a| self.node(a, "textureTransform"));
        // The mesh as this appearance draws it: texture coordinates transformed, colours dropped
        // where an RGB texture replaces them.
        let mut mesh = mesh;
        let drop_colours = texture.as_ref().is_some_and(|t| t.rgb) && !mesh.attributes.is_empty();
        if transform.is_some() || drop_colours {
            let mut m = (*mesh).clone();
            if let (Some(t), Some(uvs)) = (transform, m.uvs.as_mut()) {
                let f = self.texture_transform(t);
                for uv in uvs.iter_mut() {
                    let vrml = f(Vec2::new(uv.x, 1.0 - uv.y));
                    *uv = Vec2::new(vrml.x, 1.0 - vrml.y);
                }
            }
            if drop_colours {
                m.attributes.clear();
            }
            mesh = Arc::new(m);
        }
        let (lo, hi) =
            mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));

        let swapped = self.surface.clone();
        let shader = self.shader(swapped.as_deref().unwrap_or("material"))?;
        // A swapped-in shader takes the VRML parameters it declares; RenderMan shaders read the
        // diffuse colour and the opacity as Cs and Os.
        let declared: Option<HashSet<String>> = match &swapped {
            Some(_) => {
                let program = self.rt.program(shader)?;
                Some(program.interface.parameters.iter().map(|p| p.name.clone()).collect())
            }
            None => None,
        };
        self.rt.push_attributes();
        self.rt.load_identity();
        let result = (|| -> Result<ObjectId> {
            self.rt.bind_shader(shader)?;
            let mut params: Vec<(&str, ParamValue)> = Vec::new();
            let mut transparency = 0.0;
            match material {
                Some(m) => {
                    self.check_fields(m);
                    let diffuse = linear(self.vec3(m, "diffuseColor", Vec3::splat(0.8)));
                    params.push(("diffusecolor", ParamValue::Color(diffuse)));
                    params
                        .push(("specularcolor", ParamValue::Color(linear(self.vec3(m, "specularColor", Vec3::ZERO)))));
                    params
                        .push(("emissivecolor", ParamValue::Color(linear(self.vec3(m, "emissiveColor", Vec3::ZERO)))));
                    params.push(("shininess", ParamValue::Float(self.float(m, "shininess", 0.2).clamp(0.0, 1.0))));
                    params.push((
                        "ambientintensity",
                        ParamValue::Float(self.float(m, "ambientIntensity", 0.2).clamp(0.0, 1.0)),
                    ));
                    transparency = self.float(m, "transparency", 0.0).clamp(0.0, 1.0);
                    params.push(("transparency", ParamValue::Float(transparency)));
                }
                // No Material: unlit, the colour of the texture, the colours or white.
                None => {
                    params.push(("diffusecolor", ParamValue::Color([1.0; 3])));
                    params.push(("lit", ParamValue::Float(0.0)));
                }
            }
            if let Some(t) = &texture {
                // An RGB texture replaces the diffuse colour; an intensity texture modulates it.
                if t.rgb {
                    params.retain(|(n, _)| *n != "diffusecolor");
                    params.push(("diffusecolor", ParamValue::Color([1.0; 3])));
                }
                params.push(("texturename", ParamValue::String(t.name.clone())));
                params.push(("repeats", ParamValue::Float(if t.repeat.0 { 1.0 } else { 0.0 })));
                params.push(("repeatt", ParamValue::Float(if t.repeat.1 { 1.0 } else { 0.0 })));
                if t.alpha {
                    self.rt.alpha_mask(Some(&t.name));
                }
            }
            if let Some(lights) = lights {
                params.push(("lightcategory", ParamValue::String(lights.to_string())));
            }
            if let Some(declared) = &declared {
                if let Some((_, ParamValue::Color([r, g, b]))) = params.iter().find(|(n, _)| *n == "diffusecolor") {
                    self.rt.color(*r, *g, *b);
                }
                let opacity = 1.0 - transparency;
                self.rt.opacity(opacity, opacity, opacity);
                params.retain(|(n, _)| declared.contains(*n));
            }
            self.rt.parameters(&params)?;
            if transparency > 0.0 {
                self.rt.shadows_from_shader(true);
            }
            let id = match into {
                Some(id) => {
                    self.rt.redefine_object(id)?;
                    id
                }
                None => self.rt.begin_object()?,
            };
            self.rt.mesh(&mesh)?;
            self.rt.end_object()?;
            Ok(id)
        })();
        self.rt.pop_attributes()?;
        Ok(Some((result?, (lo, hi))))
    }

    /// TextureTransform as a function of VRML texture coordinates: `-C S R C T` (6.53).
    fn texture_transform(&mut self, t: NodeRef) -> impl Fn(Vec2) -> Vec2 {
        self.check_fields(t);
        let center = self.vec2(t, "center", Vec2::ZERO);
        let angle = self.float(t, "rotation", 0.0);
        let scale = self.vec2(t, "scale", Vec2::ONE);
        let translation = self.vec2(t, "translation", Vec2::ZERO);
        let (sin, cos) = angle.sin_cos();
        move |p: Vec2| {
            let p = p + translation + center;
            let p = Vec2::new(cos * p.x - sin * p.y, sin * p.x + cos * p.y);
            p * scale - center
        }
    }

    /// The texture of a texture node, made once.
    fn texture(&mut self, t: NodeRef) -> Result<Option<Texture>> {
        if let Some(done) = self.textures.get(&t) {
            return Ok(done.clone());
        }
        self.check_fields(t);
        let repeat = (self.boolean(t, "repeatS", true), self.boolean(t, "repeatT", true));
        let loc = self.loc_of(t);
        let made = match self.type_of(t) {
            "ImageTexture" => self.image_texture(t, repeat)?,
            "PixelTexture" => self.pixel_texture(t, repeat)?,
            other => {
                let other = other.to_string();
                self.warn_once(
                    format!("texture:{other}"),
                    t.doc,
                    loc,
                    Severity::Omission,
                    format!("{other} is not read as a texture; the shape is drawn untextured"),
                );
                None
            }
        };
        self.textures.insert(t, made.clone());
        Ok(made)
    }

    fn image_texture(&mut self, t: NodeRef, repeat: (bool, bool)) -> Result<Option<Texture>> {
        let urls = self.strings(t, "url");
        let loc = self.doc(t.doc).node(t.node).field("url").map_or(self.loc_of(t), |f| f.loc);
        let dir = self.scene.documents[t.doc].0.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut why = None;
        let mut found = None;
        for url in &urls {
            match relative_path(url) {
                Ok(rel) if dir.join(&rel).is_file() => {
                    found = Some(dir.join(rel));
                    break;
                }
                Ok(rel) => why = why.or(Some(format!("\"{url}\": {} not found", dir.join(rel).display()))),
                Err(e) => why = why.or(Some(format!("\"{url}\" {e}"))),
            }
        }
        let Some(path) = found else {
            if let Some(why) = why {
                self.warn_once(
                    format!("texture:{}:{}:{}", t.doc, loc.line, loc.column),
                    t.doc,
                    loc,
                    Severity::Omission,
                    format!("ImageTexture {why}; the shape is drawn untextured"),
                );
            }
            return Ok(None);
        };
        let name = path.display().to_string();
        // The channels, from the file's header: colour or intensity, alpha or not.
        let channels = image::ImageReader::open(&path)
            .ok()
            .and_then(|r| r.with_guessed_format().ok())
            .and_then(|r| r.into_decoder().ok())
            .map(|d| image::ImageDecoder::color_type(&d).channel_count());
        let Some(channels) = channels else {
            self.warn_once(
                format!("texture:{name}"),
                t.doc,
                loc,
                Severity::Omission,
                format!("ImageTexture {name}: not an image this reader decodes; the shape is drawn untextured"),
            );
            return Ok(None);
        };
        if channels >= 3 {
            return Ok(Some(Texture { name, rgb: true, alpha: channels == 4, repeat }));
        }
        // An intensity texture, as grey RGB (a colour lookup of a one-channel texture reads only
        // its first channel).
        match crate::texture::load_texture_image(&path, false) {
            Ok(loaded) => {
                let image = loaded.image;
                let (w, h, c) = (image.width(), image.height(), image.channels());
                let mut texels = Vec::with_capacity(w * h * (c + 2));
                for px in image.data().chunks_exact(c.max(1)) {
                    texels.extend_from_slice(&[px[0], px[0], px[0]]);
                    if c == 2 {
                        texels.push(px[1]);
                    }
                }
                let memory = format!("{name}#grey");
                self.rt.tex_image_2d(&memory, w, h, if c == 2 { 4 } else { 3 }, &texels)?;
                Ok(Some(Texture { name: memory, rgb: false, alpha: c == 2, repeat }))
            }
            Err(e) => {
                self.warn_once(
                    format!("texture:{name}"),
                    t.doc,
                    loc,
                    Severity::Omission,
                    format!("ImageTexture {name}: {e}; the shape is drawn untextured"),
                );
                Ok(None)
            }
        }
    }

    fn pixel_texture(&mut self, t: NodeRef, repeat: (bool, bool)) -> Result<Option<Texture>> {
        let loc = self.loc_of(t);
        let values = self.get(t, "image", "an SFImage (width, height, components, pixels)", |v| match v {
            Value::Numbers(n) => Some(n.clone()),
            _ => None,
        });
        let Some(values) = values else { return Ok(None) };
        let header = |i: usize| values.get(i).copied().filter(|x| x.fract() == 0.0 && *x >= 0.0).map(|x| x as usize);
        let (Some(w), Some(h), Some(c)) = (header(0), header(1), header(2)) else {
            self.warn_once(
                format!("pixeltexture:{}:{}", loc.line, loc.column),
                t.doc,
                loc,
                Severity::Omission,
                "PixelTexture's image has no width, height and components",
            );
            return Ok(None);
        };
        let count = w.checked_mul(h);
        if w == 0 || h == 0 || !(1..=4).contains(&c) || count != Some(values.len() - 3) {
            if w > 0 && h > 0 {
                self.warn_once(
                    format!("pixeltexture:{}:{}", loc.line, loc.column),
                    t.doc,
                    loc,
                    Severity::Omission,
                    format!("PixelTexture's image of {w}x{h} pixels of {c} components has {} pixels", values.len() - 3),
                );
            }
            return Ok(None);
        }
        // Pixels are packed integers, rows from the bottom up; texels rows from the top down.
        let out_channels = if c <= 2 { c + 2 } else { c };
        let mut texels = vec![0.0f32; w * h * out_channels];
        for (k, &v) in values[3..].iter().enumerate() {
            let v = v as i64 as u32;
            let bytes: Vec<f32> = (0..c).rev().map(|i| ((v >> (8 * i)) & 0xff) as f32 / 255.0).collect();
            let (x, y) = (k % w, h - 1 - k / w);
            let at = (y * w + x) * out_channels;
            let texel = &mut texels[at..at + out_channels];
            let colour = |b: f32| srgb_to_linear(b);
            match c {
                1 | 2 => {
                    texel[..3].fill(colour(bytes[0]));
                    if c == 2 {
                        texel[3] = bytes[1];
                    }
                }
                _ => {
                    for i in 0..3 {
                        texel[i] = colour(bytes[i]);
                    }
                    if c == 4 {
                        texel[3] = bytes[3];
                    }
                }
            }
        }
        self.pixel_textures += 1;
        let name = format!("{}#PixelTexture{}", self.files[t.doc].display(), self.pixel_textures);
        self.rt.tex_image_2d(&name, w, h, out_channels, &texels)?;
        Ok(Some(Texture { name, rgb: c >= 3, alpha: c == 2 || c == 4, repeat }))
    }

    /// The mesh of a geometry node, made once (`None`: nothing to draw).
    fn geometry(&mut self, g: NodeRef) -> Result<Option<Arc<Mesh>>> {
        if let Some(done) = self.meshes.get(&g) {
            return Ok(done.clone());
        }
        self.check_fields(g);
        let type_name = self.type_of(g).to_string();
        let loc = self.loc_of(g);
        let made = match type_name.as_str() {
            "Box" => {
                let size = self.vec3(g, "size", Vec3::splat(2.0)).max(Vec3::ZERO);
                Some(mesh::box_mesh(size))
            }
            "Sphere" => Some(mesh::sphere(self.float(g, "radius", 1.0).max(0.0))),
            "Cylinder" => {
                let radius = self.float(g, "radius", 1.0).max(0.0);
                let height = self.float(g, "height", 2.0).max(0.0);
                let (side, top, bottom) =
                    (self.boolean(g, "side", true), self.boolean(g, "top", true), self.boolean(g, "bottom", true));
                Some(mesh::cylinder(radius, height, side, top, bottom))
            }
            "Cone" => {
                let radius = self.float(g, "bottomRadius", 1.0).max(0.0);
                let height = self.float(g, "height", 2.0).max(0.0);
                let (side, bottom) = (self.boolean(g, "side", true), self.boolean(g, "bottom", true));
                Some(mesh::cone(radius, height, side, bottom))
            }
            "IndexedFaceSet" => Some(self.face_set(g)?),
            "ElevationGrid" => self.elevation_grid(g)?,
            "Extrusion" => self.extrusion(g)?,
            other => {
                let (severity, message) = match node_type(other) {
                    Some((Support::Omitted, _)) => (Severity::Omission, format!("{other} is not drawn; it is skipped")),
                    Some(_) => (Severity::Omission, format!("{other} is not a geometry node; the Shape is skipped")),
                    None => (Severity::Omission, format!("unknown node type {other}; it is skipped")),
                };
                self.warn_once(format!("node:{other}"), g.doc, loc, severity, message);
                None
            }
        };
        let made = match made {
            Some(m) if m.triangle_count() > 0 => {
                self.count_triangles(g, m.triangle_count())?;
                if let Err(e) = m.validate() {
                    self.warn_once(
                        format!("mesh:{}:{}:{}", g.doc, loc.line, loc.column),
                        g.doc,
                        loc,
                        Severity::Omission,
                        format!("{type_name}: {e}; it is skipped"),
                    );
                    None
                } else {
                    Some(Arc::new(to_rtsl_uvs(m)))
                }
            }
            _ => None,
        };
        self.meshes.insert(g, made.clone());
        Ok(made)
    }

    /// Counts `count` more triangles against [`MAX_MODEL_TRIANGLES`].
    fn count_triangles(&mut self, g: NodeRef, count: usize) -> Result<()> {
        let total = self.scene.triangles.saturating_add(count);
        if total > MAX_MODEL_TRIANGLES {
            let loc = self.loc_of(g);
            return Err(self.error(
                g.doc,
                loc,
                format!("{total} triangles: a VRML scene may hold at most {MAX_MODEL_TRIANGLES}"),
            ));
        }
        self.scene.triangles = total;
        Ok(())
    }

    /// Warns about a geometry node's problems, once each.
    fn problems(&mut self, g: NodeRef, problems: Vec<String>) {
        let loc = self.loc_of(g);
        let type_name = self.type_of(g).to_string();
        for p in problems {
            self.warn_once(
                format!("problem:{}:{}:{}:{p}", g.doc, loc.line, loc.column),
                g.doc,
                loc,
                Severity::Warning,
                format!("{type_name}: {p}"),
            );
        }
    }

    /// Point lists of a coordinate-like node (`Coordinate.point`, `Color.color`, ...).
    fn points3(&mut self, owner: NodeRef, field: &str, inner: &str) -> Option<Vec<Vec3>> {
        let n = self.node(owner, field)?;
        self.check_fields(n);
        Some(self.vec3s(n, inner))
    }

    fn face_set(&mut self, g: NodeRef) -> Result<Mesh> {
        let points = self.points3(g, "coord", "point").unwrap_or_default();
        let coord_index = self.ints(g, "coordIndex");
        let normals = self.points3(g, "normal", "vector");
        let normal_index = self.ints(g, "normalIndex");
        let colors =
            self.points3(g, "color", "color").map(|c| c.into_iter().map(|c| Vec3::from(linear(c))).collect::<Vec<_>>());
        let color_index = self.ints(g, "colorIndex");
        let tex = self.node(g, "texCoord").map(|t| {
            self.check_fields(t);
            self.vec2s(t, "point")
        });
        let tex_index = self.ints(g, "texCoordIndex");
        let ccw = self.boolean(g, "ccw", true);
        let crease_angle = self.float(g, "creaseAngle", 0.0);
        let normal_per_vertex = self.boolean(g, "normalPerVertex", true);
        let color_per_vertex = self.boolean(g, "colorPerVertex", true);
        let made = mesh::face_set(
            &FaceSet {
                points: &points,
                coord_index: &coord_index,
                ccw,
                crease_angle,
                normals: normals.as_deref().map(|values| Indexed {
                    values,
                    index: &normal_index,
                    per_vertex: normal_per_vertex,
                }),
                colors: colors.as_deref().map(|values| Indexed {
                    values,
                    index: &color_index,
                    per_vertex: color_per_vertex,
                }),
                tex_coords: tex.as_deref().map(|values| (values, &tex_index[..])),
                default_tex_coords: true,
            },
            &mut self.ear_clip_budget,
        );
        self.problems(g, made.problems);
        Ok(made.mesh)
    }

    fn elevation_grid(&mut self, g: NodeRef) -> Result<Option<Mesh>> {
        let nx = usize::try_from(self.int(g, "xDimension", 0)).unwrap_or(0);
        let nz = usize::try_from(self.int(g, "zDimension", 0)).unwrap_or(0);
        let height = self.floats(g, "height");
        if nx < 2 || nz < 2 {
            return Ok(None);
        }
        if nx.checked_mul(nz).is_none_or(|n| n > height.len()) {
            self.problems(
                g,
                vec![format!("{nx}x{nz} points need as many heights; there are {}; it is skipped", height.len())],
            );
            return Ok(None);
        }
        let colors =
            self.points3(g, "color", "color").map(|c| c.into_iter().map(|c| Vec3::from(linear(c))).collect::<Vec<_>>());
        let normals = self.points3(g, "normal", "vector");
        let tex = self.node(g, "texCoord").map(|t| self.vec2s(t, "point"));
        let grid = mesh::Grid {
            x_dimension: nx,
            z_dimension: nz,
            x_spacing: self.float(g, "xSpacing", 1.0),
            z_spacing: self.float(g, "zSpacing", 1.0),
            height: &height,
            ccw: self.boolean(g, "ccw", true),
            crease_angle: self.float(g, "creaseAngle", 0.0),
            colors: colors.as_deref().map(|c| (c, self.boolean(g, "colorPerVertex", true))),
            normals: normals.as_deref().map(|n| (n, self.boolean(g, "normalPerVertex", true))),
            tex_coords: tex.as_deref(),
        };
        let made = mesh::elevation_grid(&grid, &mut self.ear_clip_budget);
        self.problems(g, made.problems);
        Ok(Some(made.mesh))
    }

    fn extrusion(&mut self, g: NodeRef) -> Result<Option<Mesh>> {
        let spine = self.get(g, "spine", "triples of numbers", |v| match v {
            Value::Numbers(n) if n.len() % 3 == 0 => Some(n.clone()),
            _ => None,
        });
        let spine: Vec<Vec3> = match spine {
            Some(n) => n.chunks_exact(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect(),
            None => vec![Vec3::ZERO, Vec3::Y],
        };
        let section = {
            let s = self.vec2s(g, "crossSection");
            if s.is_empty() && self.doc(g.doc).node(g.node).field("crossSection").is_none() {
                vec![
                    Vec2::new(1.0, 1.0),
                    Vec2::new(1.0, -1.0),
                    Vec2::new(-1.0, -1.0),
                    Vec2::new(-1.0, 1.0),
                    Vec2::new(1.0, 1.0),
                ]
            } else {
                s
            }
        };
        if !spine.iter().all(|p| p.is_finite()) {
            self.problems(g, vec!["its spine has a number that is not finite; it is skipped".into()]);
            return Ok(None);
        }
        let most = mesh::extrusion_triangles(spine.len(), section.len());
        if most > MAX_MODEL_TRIANGLES.saturating_sub(self.scene.triangles) {
            return self.count_triangles(g, most).map(|_| None);
        }
        let scale = self.vec2s(g, "scale");
        let orientation = self.rotations(g, "orientation");
        let e = mesh::Extrusion {
            spine: &spine,
            cross_section: &section,
            scale: if scale.is_empty() { &[Vec2::ONE] } else { &scale },
            orientation: &orientation,
            begin_cap: self.boolean(g, "beginCap", true),
            end_cap: self.boolean(g, "endCap", true),
            ccw: self.boolean(g, "ccw", true),
            crease_angle: self.float(g, "creaseAngle", 0.0),
        };
        let made = mesh::extrusion(&e, &mut self.ear_clip_budget);
        self.problems(g, made.problems);
        Ok(Some(made.mesh))
    }

    /// A DirectionalLight lights only its group's nodes (6.16): each set of the scoped ones (all
    /// but the scene file's top-level ones) that lights a shape is a light category; a light is
    /// put in the categories of the sets it is not in, which the shapes of those sets leave out
    /// (the `material` shader's `lightcategory`). Objects made before the first scoped light was
    /// met are made again with their category. Past [`VRML_LIGHT_SCOPE_BUDGET`] categories the
    /// lights light the whole scene (a warning).
    fn scope_directional_lights(&mut self) -> Result<()> {
        if self.dir_placements.is_empty() {
            return Ok(());
        }
        for (geometry, appearance, id, set) in std::mem::take(&mut self.unscoped_objects) {
            let lights = format!("-vrml97dir:{set}");
            self.make_object(geometry, appearance, Some(id), Some(&lights))?;
            self.scene.object_lights.insert(id, lights);
        }
        let cost = self.dir_lights.iter().map(Vec::len).sum::<usize>().saturating_mul(self.dir_sets.len());
        if cost > VRML_LIGHT_SCOPE_BUDGET {
            let loc = self.doc(0).roots.first().map_or(Loc::default(), |&n| self.doc(0).node(n).loc);
            self.warn_once(
                "light-scope".into(),
                0,
                loc,
                Severity::Warning,
                format!(
                    "{} DirectionalLights in {} scopes pass the scoping budget ({VRML_LIGHT_SCOPE_BUDGET}); each lights the whole scene",
                    self.dir_lights.len(),
                    self.dir_sets.len()
                ),
            );
            return Ok(());
        }
        for k in 0..self.dir_lights.len() {
            let unlit: Vec<String> = (0..self.dir_sets.len())
                .filter(|&s| self.dir_sets[s].binary_search(&k).is_err())
                .map(|s| format!("vrml97dir:{s}"))
                .collect();
            if unlit.is_empty() {
                continue;
            }
            let category = ParamValue::String(unlit.join(","));
            for &light in &self.dir_lights[k] {
                self.rt.set_light_parameters(light, &[("__category", category.clone())])?;
            }
        }
        Ok(())
    }

    /// After the walk: a camera framing the scene when no Viewpoint was bound, and the headlight.
    fn finish(&mut self) -> Result<()> {
        self.scope_directional_lights()?;
        if !self.camera_bound {
            crate::scene_file::frame_camera(self.rt, self.scene.bounds);
        }
        if self.headlight.unwrap_or(true) {
            // VRML's headlight: a directional light of intensity 1 along the view, at the camera
            // the scene starts with.
            let id = self.shader("distantlight")?;
            let light = super::add_headlight(self.rt, id)?;
            self.scene.headlight = Some((light, self.rt.camera().world_from_camera));
        }
        Ok(())
    }
}

/// An `SFRotation`'s axis and angle as a quaternion (a zero axis is no rotation).
fn rotation(v: &[f32]) -> Quat {
    let axis = Vec3::new(v[0], v[1], v[2]);
    if axis.length_squared() < 1e-20 || !v[3].is_finite() {
        return Quat::IDENTITY;
    }
    Quat::from_axis_angle(axis.normalize(), v[3])
}

/// The mesh with its texture coordinates turned from VRML's (`t` up) into rtsl's (`t` down).
fn to_rtsl_uvs(mut m: Mesh) -> Mesh {
    if let Some(uvs) = m.uvs.as_mut() {
        for uv in uvs {
            uv.y = 1.0 - uv.y;
        }
    }
    m
}

#[cfg(test)]
mod tests;

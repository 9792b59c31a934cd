//! VRML 97 scenes (ISO/IEC 14772-1, `#VRML V2.0 utf8`): read into a [`Context`], and animated
//! through it; VRML 1.0 scenes ([`v1`]) too.
//!
//! The reader is ours: no maintained Rust crate reads VRML 97 (crates.io has none that parses the
//! whole grammar: PROTO, IS, EXTERNPROTO, ROUTE), and the grammar is small. [`lex`] splits the
//! text into tokens, [`parse`] builds a [`parse::Document`] (an arena of nodes with their file
//! locations, `DEF`/`USE` sharing one node, PROTO instances expanded in place), and [`build`]
//! walks the scene graph from the file's top-level nodes and makes objects, instances, lights,
//! the camera and the background through the [`Context`] API. [`events`] runs the ROUTEs,
//! TimeSensors and interpolators on the documents, [`sensors`] runs the sensors of the user (the
//! pointer, the camera), and [`animate`] shows what they change ([`VrmlScene::advance_to`]). [`load_file`] reads a VRML 1.0 file with [`v1`], chosen by its
//! header. `docs/vrml.md` says what is read and how VRML maps onto rtsl.
//!
//! Invariants:
//! - bad input never panics, hangs or exhausts memory: a syntax error is a [`VrmlError`] with file,
//!   line and column and nothing is loaded; node nesting ([`MAX_VRML_NESTING`]), PROTO expansion
//!   ([`MAX_PROTO_DEPTH`], [`MAX_VRML_NODES`]), Inline nesting ([`MAX_INLINE_DEPTH`]), the walk over
//!   a graph that `USE` makes exponential ([`VRML_TRAVERSAL_BUDGET`]), the triangles made
//!   ([`crate::scene_file::MAX_MODEL_TRIANGLES`]) and gzip inflation ([`MAX_INFLATED_VRML`]) are
//!   bounded, a bound passed is an error naming it; ear clipping is bounded by
//!   [`VRML_EAR_CLIP_BUDGET`], past which faces are fanned with a warning;
//! - a node or field the reader does not support is skipped with one warning per node type or field
//!   name, at its first place (`file:line:column`); a value of the wrong type is a warning and the
//!   field keeps its default;
//! - the scene graph stays addressable for animation: [`VrmlScene`] keeps the parsed documents
//!   (`DEF` names, every node's fields), and each placed shape, light and viewpoint records the
//!   nodes it was reached through ([`Placed::path`]), so that a changed Transform moves the
//!   instances under it ([`Context::set_instance_transform`]); an eventOut sends at most once per
//!   timestamp and a timestamp's cascade is bounded ([`events::VRML_EVENT_BUDGET`]);
//! - a geometry node reached again (`USE`, or a group used twice) with the same appearance is one
//!   object, instanced again, never a copy;
//! - Inline URLs are relative paths inside the including file's folder; absolute ones, ones that
//!   climb out with `..`, URLs with a scheme and cycles are errors.

pub mod animate;
pub mod background;
pub mod build;
pub mod events;
pub mod lex;
pub mod mesh;
pub mod nodes;
pub mod parse;
pub mod sensors;
pub mod v1;

use crate::api::{Context, InstanceId, LightId, ObjectId};
use crate::rib::{Location, RibDiagnostic};
use glam::{Affine3A, Vec3A};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use build::{build, build_str, build_str_with, build_with};
pub use parse::{Document, NodeId};

/// How deep nodes may nest: in a file, in a PROTO's expansion, and along the walk of the scene
/// graph across Inline files.
pub const MAX_VRML_NESTING: usize = 128;

/// How deep PROTO instances may nest inside PROTO bodies (a PROTO that instantiates one that
/// instantiates one ...).
pub const MAX_PROTO_DEPTH: usize = 32;

/// How many nodes one file may make, each PROTO instance's copy of its body counted.
pub const MAX_VRML_NODES: usize = 1 << 20;

/// How deep Inline files may include each other.
pub const MAX_INLINE_DEPTH: usize = 16;

/// How many nodes the walk of the scene graph may visit, all files together: a group `USE`d twice
/// in a group `USE`d twice ... is visited once per path, so a short file could ask for any amount.
pub const VRML_TRAVERSAL_BUDGET: usize = 1 << 20;

/// How much ear clipping one scene may do, all faces together, a face of `n` vertices costing
/// `n * n` (ear clipping is quadratic in the vertices); faces past it are fanned instead.
pub const VRML_EAR_CLIP_BUDGET: usize = 1 << 28;

/// How many light categories scoped lights may be given, all lights together (a light's count is
/// the sets of lights that light a shape and not it): a DirectionalLight in VRML 97, any light in
/// VRML 1.0, lights only part of the scene, and a file with many lights in many groups would
/// otherwise ask for a product of the two. Past it, the lights light the whole scene.
pub const VRML_LIGHT_SCOPE_BUDGET: usize = 1 << 18;

/// The most bytes a gzip-compressed VRML file may inflate to.
pub const MAX_INFLATED_VRML: u64 = 1 << 30;

/// A line and column (1-based, columns in characters) in a VRML file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Loc {
    pub line: u32,
    pub column: u32,
}

/// A VRML file that could not be read: where, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{loc}: {message}")]
pub struct VrmlError {
    pub loc: Location,
    pub message: String,
}

impl VrmlError {
    pub fn at(file: &Arc<Path>, loc: Loc, message: impl Into<String>) -> VrmlError {
        VrmlError { loc: location(file, loc), message: message.into() }
    }

    /// An error about a file as a whole.
    pub fn file(file: &Path, message: impl Into<String>) -> VrmlError {
        VrmlError { loc: Location { file: Arc::from(file), line: 0, column: 0 }, message: message.into() }
    }
}

impl From<VrmlError> for crate::scene_file::SceneFileError {
    fn from(e: VrmlError) -> Self {
        crate::scene_file::SceneFileError::Vrml { loc: e.loc, message: e.message }
    }
}

fn location(file: &Arc<Path>, loc: Loc) -> Location {
    Location { file: file.clone(), line: loc.line, column: loc.column }
}

/// Places an instance of object `id` at `world` and grows the scene's bounds by its box `lo..hi`
/// (in the object's space) carried there.
pub(crate) fn place_instance(
    rt: &mut Context,
    scene: &mut VrmlScene,
    id: ObjectId,
    world: Affine3A,
    (lo, hi): (glam::Vec3, glam::Vec3),
) -> std::result::Result<InstanceId, crate::api::ApiError> {
    rt.push_matrix();
    rt.load_matrix(world);
    let instance = rt.instantiate_object(id);
    rt.pop_matrix()?;
    let instance = instance?;
    for k in 0..8 {
        let corner = glam::Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let w = world.transform_point3a(Vec3A::from(corner));
        scene.bounds.0 = scene.bounds.0.min(w);
        scene.bounds.1 = scene.bounds.1.max(w);
    }
    Ok(instance)
}

/// Adds a headlight: `distantlight` (shader `id`) shining along the view of the camera the scene
/// starts with, from the eye, casting no shadows (they would hide behind what casts them).
pub(crate) fn add_headlight(
    rt: &mut Context,
    id: crate::api::ShaderId,
) -> std::result::Result<LightId, crate::api::ApiError> {
    use crate::shading::ParamValue;
    let camera = rt.camera().world_from_camera;
    let (eye, forward) = (camera.translation, camera.matrix3 * Vec3A::Z);
    rt.push_matrix();
    rt.load_identity();
    let light = rt.light_source(
        id,
        &[("from", ParamValue::Point(eye.to_array())), ("to", ParamValue::Point((eye + forward).to_array()))],
    );
    rt.pop_matrix()?;
    let light = light?;
    rt.set_light(light, true, false)?;
    Ok(light)
}

/// A node of one of the scene's files: `docs[doc]`'s node `node`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeRef {
    pub doc: usize,
    pub node: NodeId,
}

/// Something placed in the world, with the nodes it was reached through.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed<T> {
    /// What was made of it (an instance, a light, a viewpoint's world transform).
    pub made: T,
    /// The node itself (a Shape, a light, a Viewpoint).
    pub node: NodeRef,
    /// The grouping nodes from a file's top to it (Transforms, Groups, Inlines, ...): a Transform's
    /// change moves what lies under it.
    pub path: Vec<NodeRef>,
    /// The world-from-local matrix it was placed with: the Transforms along `path` multiplied,
    /// then `local`.
    pub world: Affine3A,
    /// The matrix below `path`'s Transforms: a VRML 1.0 file's own transforms (identity for a
    /// VRML 97 node).
    pub local: Affine3A,
}

/// A Viewpoint as read.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    pub description: String,
    /// The world position of the eye.
    pub eye: Vec3A,
    /// World directions the view looks along and up.
    pub forward: Vec3A,
    pub up: Vec3A,
    /// VRML's `fieldOfView` (radians): the smaller of the view's two angles.
    pub field_of_view: f32,
}

impl Viewpoint {
    /// Puts `rt`'s camera at this view.
    pub fn look(&self, rt: &mut Context) {
        rt.camera_look_at(self.eye, self.eye + self.forward, self.up, self.field_of_view.to_degrees());
    }
}

/// What a VRML load made and kept.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VrmlScene {
    /// The files read: `[0]` the scene file, then each Inline file once.
    pub documents: Vec<(PathBuf, Document)>,
    /// Each Shape placed (one instance per path that reaches it).
    pub shapes: Vec<Placed<InstanceId>>,
    /// The object of each geometry-and-appearance pair, made once.
    pub objects: Vec<(NodeRef, Option<NodeRef>, ObjectId)>,
    pub lights: Vec<Placed<LightId>>,
    /// Every Viewpoint reached, in the order reached; the first of the scene file is the camera.
    pub viewpoints: Vec<Placed<Viewpoint>>,
    /// The bounds of what was placed, in world space (empty: +inf, -inf).
    pub bounds: (Vec3A, Vec3A),
    /// Triangles made (each object's once, however often it is instanced).
    pub triangles: usize,
    /// Warnings: what was skipped or approximated, each once, with its place.
    pub warnings: Vec<RibDiagnostic>,
    /// The object of each of `shapes`, in its order.
    pub shape_objects: Vec<ObjectId>,
    /// The routes and the sensors' state ([`animate`] runs them).
    pub events: events::Events,
    /// The shapes (indices into `shapes`) whose Transforms now scale them to nothing: their
    /// instances are deleted until a Transform makes them visible again.
    pub hidden_shapes: std::collections::BTreeSet<usize>,
    /// What rebuilding an object as animation changes it needs.
    pub(crate) kept: build::Kept,
    /// The lights of `lights` made for a VRML 97 light's `ambientIntensity` (each after its light).
    pub ambient_lights: Vec<LightId>,
    /// The Viewpoint of `viewpoints` that is the camera, if one is.
    pub bound_viewpoint: Option<usize>,
    /// Every ProximitySensor and VisibilitySensor reached, with its path.
    pub sensors: Vec<Placed<()>>,
    /// The light category (`material`'s `lightcategory`) each object is made with, where scoped
    /// lights leave some out.
    pub(crate) object_lights: std::collections::HashMap<ObjectId, String>,
    /// The pointing-device, proximity and visibility sensors' state between events.
    pub(crate) sensing: sensors::Sensing,
    /// Every Billboard and LOD reached: they follow the camera, so the animation pass places what
    /// is under them again when it moves.
    pub view_nodes: Vec<NodeRef>,
    /// The level each LOD shows, as the camera last stood.
    pub(crate) lod_levels: std::collections::HashMap<NodeRef, usize>,
    /// The camera the view nodes and the headlight were last placed for.
    pub(crate) placed_for_camera: Option<glam::Affine3A>,
    /// The headlight and the camera it was made for: it turns with the camera (`follow_camera`).
    pub(crate) headlight: Option<(LightId, glam::Affine3A)>,
}

impl VrmlScene {
    /// The files read, scene file first.
    pub fn files(&self) -> Vec<PathBuf> {
        self.documents.iter().map(|(p, _)| p.clone()).collect()
    }
}

/// Reads the VRML 97 file at `path` (plain or gzip-compressed, told apart by content) and its
/// Inline files into `rt`.
pub fn load_file(rt: &mut Context, path: impl AsRef<Path>) -> Result<VrmlScene, crate::scene_file::SceneFileError> {
    build(rt, path.as_ref())
}

/// How a VRML scene is built, beyond the file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VrmlOptions {
    /// The surface shader every shape gets instead of `material` (the paper's browser swapped
    /// VRML's lighting model for shaders that add shadows, reflections or global illumination).
    /// It gets the VRML parameters it declares (`diffusecolor`, `texturename`...), the diffuse
    /// colour as `Cs` and one minus the transparency as `Os`.
    pub surface: Option<String>,
}

/// [`load_file`] with [`VrmlOptions`].
pub fn load_file_with(
    rt: &mut Context,
    path: impl AsRef<Path>,
    options: &VrmlOptions,
) -> Result<VrmlScene, crate::scene_file::SceneFileError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    if is_vrml1(&text) {
        return v1::build_str_with(rt, &text, path, options);
    }
    build_str_with(rt, &text, path, options)
}

/// Whether the text is a VRML 1.0 file (its header line says so).
pub fn is_vrml1(text: &str) -> bool {
    text.trim_start_matches('\u{feff}').starts_with("#VRML V1.0")
}

/// The text of a VRML file: its bytes, inflated when gzip-compressed, decoded as UTF-8 (invalid
/// sequences replaced).
pub fn read_text(path: &Path) -> Result<String, VrmlError> {
    let bytes = std::fs::read(path).map_err(|e| VrmlError::file(path, format!("cannot read VRML file: {e}")))?;
    decode_bytes(path, bytes)
}

/// [`read_text`] of bytes already read.
pub fn decode_bytes(path: &Path, bytes: Vec<u8>) -> Result<String, VrmlError> {
    let bytes = if bytes.starts_with(&[0x1f, 0x8b]) {
        use std::io::Read;
        let mut text = Vec::new();
        let mut decoder = flate2::read::MultiGzDecoder::new(&bytes[..]).take(MAX_INFLATED_VRML + 1);
        decoder
            .read_to_end(&mut text)
            .map_err(|e| VrmlError::file(path, format!("cannot decompress gzip VRML: {e}")))?;
        if text.len() as u64 > MAX_INFLATED_VRML {
            return Err(VrmlError::file(path, format!("gzip VRML inflates to more than {MAX_INFLATED_VRML} bytes")));
        }
        text
    } else {
        bytes
    };
    Ok(match String::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
    })
}

/// Checks the header line: VRML 97 reads; VRML 1.0 and X3D are errors; anything else is read as
/// VRML 97 with a warning (returned).
pub fn check_header(file: &Arc<Path>, text: &str) -> Result<Option<RibDiagnostic>, VrmlError> {
    let first = text.trim_start_matches('\u{feff}').lines().next().unwrap_or("");
    if first.starts_with("#VRML V2.0") {
        return Ok(None);
    }
    let at = Loc { line: 1, column: 1 };
    if first.starts_with("#VRML V1.0") {
        return Err(VrmlError::at(file, at, "a VRML 1.0 file is read by `vrml::v1` (`vrml::load_file` chooses it)"));
    }
    if first.starts_with("#X3D") {
        return Err(VrmlError::at(file, at, "X3D files are not read (only VRML 97, `#VRML V2.0 utf8`)"));
    }
    Ok(Some(RibDiagnostic::warning(
        &location(file, at),
        "no `#VRML V2.0 utf8` header line; the file is read as VRML 97",
    )))
}

/// How VRML's colours (display values, as browsers light them) become linear rtsl colours.
pub(crate) fn linear(c: glam::Vec3) -> [f32; 3] {
    c.to_array().map(|v| crate::texture::srgb_to_linear(v.clamp(0.0, 1.0)))
}

/// A URL as a path relative to the including file's folder, or why it is refused: one with a
/// scheme, an absolute path, or one that climbs out of the folder with `..`. A fragment (`#...`)
/// is dropped, `%XX` escapes decoded.
pub fn relative_path(url: &str) -> std::result::Result<PathBuf, &'static str> {
    let url = url.split('#').next().unwrap_or("").replace('\\', "/");
    let url = url.as_str();
    if url.is_empty() {
        return Err("is empty");
    }
    // A scheme: letters, digits, `+`, `-`, `.` before a colon (a drive letter too).
    if let Some((scheme, _)) = url.split_once(':') {
        if !scheme.is_empty() && scheme.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')) {
            return Err("has a scheme; only relative file paths are read");
        }
    }
    use crate::scene_file::{decode_relative_path, PathRefusal};
    match decode_relative_path(url) {
        Ok(path) => Ok(path),
        Err(PathRefusal::MalformedEscape) => Err("has a malformed %-escape"),
        Err(PathRefusal::NotUtf8) => Err("does not decode to UTF-8"),
        Err(PathRefusal::LeavesFolder) => Err("climbs out of the including file's folder with `..`"),
        Err(PathRefusal::Absolute) => Err("is an absolute path; only paths relative to the including file are read"),
    }
}

/// Whether `path` names a VRML file by its extension: `.wrl`, `.wrz`, `.wrl.gz` (any case).
pub fn is_vrml_path(path: &Path) -> bool {
    let name = path.file_name().and_then(|n| n.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    name.ends_with(".wrl") || name.ends_with(".wrz") || name.ends_with(".wrl.gz")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_and_extensions() {
        let f: Arc<Path> = Arc::from(Path::new("a.wrl"));
        assert_eq!(check_header(&f, "#VRML V2.0 utf8\nGroup {}"), Ok(None));
        assert!(check_header(&f, "#VRML V1.0 ascii\n").unwrap_err().message.contains("VRML 1.0"));
        assert!(check_header(&f, "#X3D V3.0 utf8\n").is_err());
        assert!(check_header(&f, "Group {}").expect("read").is_some());
        for (p, yes) in [("a.wrl", true), ("A.WRZ", true), ("x/a.wrl.gz", true), ("a.gz", false), ("a.obj", false)] {
            assert_eq!(is_vrml_path(Path::new(p)), yes, "{p}");
        }
    }

    #[test]
    fn gzip_files_inflate() {
        use std::io::Write;
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(b"#VRML V2.0 utf8\nGroup {}\n").expect("written");
        let bytes = gz.finish().expect("finished");
        assert_eq!(decode_bytes(Path::new("a.wrz"), bytes).expect("inflates"), "#VRML V2.0 utf8\nGroup {}\n");
        let e = decode_bytes(Path::new("a.wrz"), vec![0x1f, 0x8b, 0, 1, 2]).unwrap_err();
        assert!(e.to_string().starts_with("a.wrz: cannot decompress"), "{e}");
    }
}

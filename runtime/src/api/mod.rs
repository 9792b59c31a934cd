//! The application API, modelled on OpenRT (OpenGL's names for geometry and matrices) and the
//! Stanford real-time shading API (`shader_file`, `compile_shader`, `bind_shader`, `parameter`).
//!
//! ```
//! use rtsl_runtime::api::{params, Context, Primitive};
//! use rtsl_runtime::glam::Vec3;
//!
//! let mut rt = Context::new();
//! rt.options.width = 64;
//! rt.options.height = 48;
//! let plastic = rt.find_shader("plastic")?;
//! let light = rt.find_shader("pointlight")?;
//! rt.camera_look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::ZERO, Vec3::Y, 40.0);
//! let quad = rt.begin_object()?;
//! rt.bind_shader(plastic)?;
//! rt.parameter("Kd", 0.8)?;
//! rt.begin(Primitive::Quads)?;
//! for (x, z) in [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
//!     rt.vertex(x, 0.0, z)?;
//! }
//! rt.end()?;
//! rt.end_object()?;
//! rt.instantiate_object(quad)?;
//! rt.light_source(light, params!["intensity" => 10.0, "from" => [0.0, 2.0, 1.0]])?;
//! let (image, report) = rt.render_frame()?;
//! assert!(image.pixel(32, 24)[0] > 0.0, "the lit quad fills the middle of the frame");
//! # Ok::<(), rtsl_runtime::api::ApiError>(())
//! ```
//!
//! `docs/api.md` is the guide: every call in tables, and how values, frames and hot reload work.
//!
//! Semantics:
//! - **State** is OpenGL's: a current matrix with a stack, a current colour and opacity, a current
//!   surface shader binding. Geometry inside `begin_object`/`end_object` is stored in the object's own
//!   space: the current matrix relative to the one at `begin_object`. `instantiate_object` places the
//!   object with the current matrix.
//! - **Scopes of `parameter`**: [`Context::parameter`] sets a value of the bound surface shader for
//!   the object being built (object scope) or, outside objects, for the shader binding that later
//!   objects get; [`Context::primitive_parameter`] for the primitive between `begin` and `end`;
//!   [`Context::vertex_parameter`] for the following vertices (sticky, like `glColor`). Primitive
//!   and vertex values are interpolated at the hit and must name varying parameters.
//! - **Frames** (OpenRT): shader and object references are resolved when [`Context::render_frame`]
//!   runs, so a shader recompiled under the same id, or an object whose geometry was replaced, is
//!   seen by the next frame. Only what changed is rebuilt: an object's BVH when its geometry
//!   changes, the top-level BVH every frame.
//! - **Errors**: misuse (unbalanced begin/end, unknown ids, a parameter the bound shader does not
//!   have or of the wrong type) returns an [`ApiError`]; nothing panics.

use crate::accel::object::{MeshSource, MeshSummary};
use crate::geometry::alpha::DEFAULT_CUTOFF as ALPHA_CUTOFF;
use crate::geometry::{AlphaMask, Attribute, MeshError};
use crate::render::{
    render_frame, AreaLight, CameraSetup, InstanceParts, InstanceShading, LightSource, Material, RenderOptions, World,
};
use crate::scene::{ObjectId as SceneObject, Scene, SceneError};
use crate::shading::library::{self, LibraryShader};
use crate::shading::{LightKind, ParamError, Program, ShaderError, ShaderInstance, ShaderProgram};
use crate::texture::{TexImage, TextureCache, Wrap};
use glam::{Affine3A, Quat, Vec2, Vec3, Vec3A};
use rtsl_compiler::interface::ShaderKind;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod events;
mod frames;
mod objects;
mod ray_params;
mod replica;
mod shader_cache;
mod shaders;
mod state;
pub use events::ShaderEvent;
pub use replica::{decode_mesh, encode_mesh, ReplicaError, Replicator, TextureDelivery};
pub use shader_cache::ShaderCache;
pub use state::{AttributeParts, InheritedAppearance, SavedAttributes};
// The types `Context`'s calls take and return, so that one `use rtsl_runtime::api::{...}` serves an
// application (vector types: `rtsl_runtime::glam`).
pub use crate::geometry::{Deformation, Mesh, Quadric, Tessellation};
pub use crate::image_io::WriteOptions;
pub use crate::params;
pub use crate::render::{FrameReport, Framebuffer};
pub use crate::shading::ParamValue;

/// `docs/api.md`, compiled by `cargo test` so that the guide's example cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../../../docs/api.md")]
pub struct ApiGuide;

/// A compiled shader known to a [`Context`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct ShaderId(pub u32);

/// A retained object of a [`Context`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct ObjectId(pub u32);

/// An instance of an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct InstanceId(pub u32);

/// A light source.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LightId(pub u32);

/// What `begin` starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Primitive {
    Triangles,
    Quads,
    /// One convex or concave simple polygon.
    Polygon,
    TriangleStrip,
    TriangleFan,
}

/// Misuse of the API.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    #[error("{0} without a matching {1}")]
    Unbalanced(&'static str, &'static str),
    #[error("{0} is not allowed inside {1}")]
    Nested(&'static str, &'static str),
    #[error("{0} needs an object being built (call begin_object first)")]
    NoObject(&'static str),
    #[error("no shader with id {0}")]
    UnknownShader(u32),
    #[error("no object with id {0}")]
    UnknownObject(u32),
    #[error("no instance with id {0}")]
    UnknownInstance(u32),
    #[error("no light with id {0}")]
    UnknownLight(u32),
    #[error("shader {name} is a {got} shader, not a {expected} shader")]
    WrongKind { name: String, expected: &'static str, got: &'static str },
    #[error("no surface shader is bound, so parameter {0} has nothing to apply to")]
    NoShaderBound(String),
    #[error("parameter {name} of shader {shader} is uniform; only varying parameters take primitive or vertex values")]
    NotVarying { shader: String, name: String },
    #[error("{0} vertices do not make whole {1}")]
    IncompletePrimitive(usize, &'static str),
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error(transparent)]
    Shader(#[from] ShaderError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{0}")]
    ImageSize(String),
    #[error("the matrix stack is empty")]
    MatrixStackEmpty,
    #[error("texture {name}: {width}x{height} texels of {channels} channels need {} floats, {given} given", width * height * channels)]
    BadTexture { name: String, width: usize, height: usize, channels: usize, given: usize },
    #[error("texture {name}: {message}")]
    BadTextureFile { name: String, message: String },
    #[error("object {0} is demand-loaded and the context has no mesh source")]
    NoMeshSource(u32),
    #[error("the master's displaced meshes: {0}")]
    RemoteDisplacement(String),
    #[error("more than {} instances: the scene's top-level BVH holds no more", crate::accel::bvh4::MAX_PRIMITIVES)]
    TooManyInstances,
    #[error(
        "a mesh deforming from time {open} to {close} in an object that deforms from {was_open} to {was_close}: \
         one object deforms over one interval"
    )]
    DeformationTimes { open: f32, close: f32, was_open: f32, was_close: f32 },
    #[error(transparent)]
    RayParameter(#[from] crate::render::RayParameterError),
    #[error(transparent)]
    Solid(#[from] crate::csg::SolidError),
}

fn kind_name(k: ShaderKind) -> &'static str {
    match k {
        ShaderKind::Surface => "surface",
        ShaderKind::Light => "light",
        ShaderKind::Displacement => "displacement",
        ShaderKind::Volume => "volume",
        ShaderKind::Imager => "pixel",
        ShaderKind::Camera => "camera",
        ShaderKind::Lightfield => "lightfield",
    }
}

/// A surface shader binding: a shader and its object-scope values (kept as given, resolved at frame
/// time against whatever program the id names then).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct Binding {
    shader: ShaderId,
    params: Vec<(String, ParamValue, Affine3A)>,
    world_from_shader: Affine3A,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct Appearance {
    color: [f32; 3],
    opacity: [f32; 3],
    surface: Option<Binding>,
    /// The volume shader of the inside of objects built from now on (RIB `Interior`).
    interior: Option<Binding>,
    /// The displacement shader of objects built from now on (RIB `Displacement`).
    displacement: Option<Binding>,
    shadow_by_shader: bool,
    /// How light paths meet objects built from now on (RIB `Attribute "photon" "shadingmodel"`).
    photon: crate::render::world::PhotonModel,
    /// The texture whose alpha cuts objects built from now on, and the cut-off
    /// ([`Context::alpha_mask`]).
    alpha_mask: Option<(String, f32)>,
    /// The ray parameter values of objects built from now on ([`Context::ray_attribute`]).
    ray_values: Vec<(String, crate::render::RayValue)>,
    /// Whether objects built from now on are one-sided (RIB `Sides 1`): rays do not see the back
    /// of their triangles.
    #[serde(default)]
    one_sided: bool,
    /// The kinds of rays that see objects built from now on (RIB `Attribute "visibility"`).
    #[serde(default)]
    visibility: crate::render::Visibility,
    /// Whether objects built from now on are holdouts (RIB `Matte 1`).
    #[serde(default)]
    matte: bool,
    /// The name of objects built from now on (RIB `Attribute "identifier" "name"`).
    #[serde(default)]
    identifier: Option<String>,
    /// The bounces rays may take beyond objects built from now on (RIB `Attribute "trace"
    /// "maxdiffusedepth"` and `"maxspeculardepth"`).
    #[serde(default)]
    trace_depths: crate::render::TraceDepths,
    /// How far along rays spawned by objects built from now on start (RIB `Attribute "trace"
    /// "bias"`).
    #[serde(default)]
    trace_bias: f32,
    /// Whether displacement shaders move objects built from now on, where said (RIB `Attribute
    /// "trace" "displacements"`, BMRT's `"render" "truedisplacement"`); unsaid, they do where
    /// `displacement_bound` is above 0.
    #[serde(default)]
    true_displacement: Option<bool>,
    /// How far displacement may move objects built from now on (RIB `Attribute
    /// "displacementbound" "sphere"`).
    #[serde(default)]
    displacement_bound: f32,
    /// The micropolygon area in pixels that displaced objects built from now on are diced to
    /// (RIB `ShadingRate`).
    #[serde(default = "unit_shading_rate")]
    shading_rate: f32,
}

fn unit_shading_rate() -> f32 {
    1.0
}

impl Default for Appearance {
    fn default() -> Self {
        Appearance {
            color: [1.0; 3],
            opacity: [1.0; 3],
            surface: None,
            interior: None,
            displacement: None,
            shadow_by_shader: false,
            photon: crate::render::world::PhotonModel::Matte,
            alpha_mask: None,
            ray_values: Vec::new(),
            one_sided: false,
            visibility: crate::render::Visibility::ALL,
            matte: false,
            identifier: None,
            trace_depths: crate::render::TraceDepths::UNBOUNDED,
            trace_bias: 0.0,
            true_displacement: None,
            displacement_bound: 0.0,
            shading_rate: 1.0,
        }
    }
}

struct ObjectRecord {
    mesh: Option<Arc<Mesh>>,
    /// A demand-loaded object's summary, its mesh left with the context it replicates
    /// ([`Context::apply_update`]); `mesh` is then `None`.
    remote: Option<MeshSummary>,
    appearance: Appearance,
    /// The parts of an object built in parts ([`Context::end_part`]); `None`: one appearance.
    parts: Option<ObjectParts>,
    scene_object: Option<SceneObject>,
    /// The geometry changed since the scene last saw it.
    dirty: bool,
    deleted: bool,
    /// Changes whenever the mesh, appearance, parts or deletion do ([`Context::next_object_version`]):
    /// what was built or sent of the record is still right while its version is the same, which
    /// costs a comparison of two numbers a frame instead of one of appearances and their shader
    /// parameters.
    version: u64,
}

impl ObjectRecord {
    /// An object with no geometry yet, which the next frame's scene takes in.
    fn empty() -> ObjectRecord {
        ObjectRecord {
            mesh: None,
            remote: None,
            appearance: Appearance::default(),
            parts: None,
            scene_object: None,
            dirty: true,
            deleted: false,
            version: 0,
        }
    }

    fn has_geometry(&self) -> bool {
        self.mesh.is_some() || self.remote.is_some()
    }
}

/// An object's parts: each part's appearance, and each triangle's part.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct ObjectParts {
    appearances: Vec<Appearance>,
    of_triangle: Arc<[u32]>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct InstanceRecord {
    object: ObjectId,
    transform: Affine3A,
    /// Where the instance is when the shutter closes, if it moves.
    close_transform: Option<Affine3A>,
    deleted: bool,
    /// The instance's own appearance, which shades it in place of its object's
    /// ([`Context::instantiate_object_inheriting`]); `None`: the object's.
    #[serde(default)]
    appearance: Option<Appearance>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct LightRecord {
    shader: ShaderId,
    params: Vec<(String, ParamValue, Affine3A)>,
    world_from_shader: Affine3A,
    shadows: bool,
    /// World-space emitting triangles of an area light (empty for other lights).
    area_triangles: Vec<[Vec3A; 3]>,
    area_samples: u32,
    on: bool,
}

/// Geometry being built for one object: triangles with their vertex attributes.
#[derive(Default)]
struct MeshBuilder {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    has_normals: bool,
    has_uvs: bool,
    attributes: Vec<Attribute>,
    triangles: Vec<[u32; 3]>,
    /// The parts ended so far ([`Context::end_part`]): where each ends (a triangle count) and its
    /// appearance.
    parts: Vec<(usize, Appearance)>,
    /// Once a deforming mesh is added: where the vertices are at the deformation's close
    /// (positions and normals, up to the vertices added since, which stand still), and its times.
    deformation: Option<Deformation>,
}

impl MeshBuilder {
    /// Makes the triangles added since the last part a part of `appearance` (none: no part).
    fn close_part(&mut self, appearance: &Appearance) {
        let start = self.parts.last().map_or(0, |(end, _)| *end);
        if self.triangles.len() > start {
            self.parts.push((self.triangles.len(), appearance.clone()));
        }
    }

    /// Brings the deformation up to the vertices added so far (those standing still: at the
    /// close where they are at the open).
    fn catch_up_deformation(&mut self) {
        if let Some(d) = &mut self.deformation {
            d.positions.extend_from_slice(&self.positions[d.positions.len()..]);
            let normals = d.normals.get_or_insert_with(Vec::new);
            normals.extend_from_slice(&self.normals[normals.len()..]);
        }
    }

    /// Makes the object deform from `open` to `close` (an error when it already deforms over
    /// another interval).
    fn deform(&mut self, open: f32, close: f32) -> Result<&mut Deformation, ApiError> {
        self.catch_up_deformation();
        let d = self.deformation.get_or_insert_with(|| Deformation {
            positions: self.positions.clone(),
            normals: Some(self.normals.clone()),
            open,
            close,
        });
        if (d.open, d.close) != (open, close) {
            return Err(ApiError::DeformationTimes { open, close, was_open: d.open, was_close: d.close });
        }
        Ok(d)
    }

    /// The deformation of the finished object: every vertex's, normals only where the object has
    /// normals.
    fn finish_deformation(&mut self) -> Option<Deformation> {
        self.catch_up_deformation();
        let mut d = self.deformation.take()?;
        if !self.has_normals {
            d.normals = None;
        }
        Some(d)
    }
}

struct OpenPrimitive {
    kind: Primitive,
    first_vertex: u32,
}

/// The rendering context: scene state, shaders, and frames.
pub struct Context {
    programs: Vec<Option<Program>>,
    /// Programs compiled by other contexts too (`share_shader_cache`).
    shader_cache: Option<Arc<ShaderCache>>,
    shader_search_path: Vec<PathBuf>,
    include_paths: Vec<PathBuf>,
    matrix: Affine3A,
    stack: Vec<(Affine3A, Option<Affine3A>)>,
    /// The current matrix at the shutter's close, where it differs from `matrix` (motion blur).
    close_matrix: Option<Affine3A>,
    appearance: Appearance,
    appearance_stack: Vec<Appearance>,
    objects: Vec<ObjectRecord>,
    building: Option<(ObjectId, Affine3A, MeshBuilder)>,
    primitive: Option<OpenPrimitive>,
    current_normal: Vec3,
    current_uv: Vec2,
    vertex_values: Vec<(String, Vec<f32>)>,
    primitive_values: Vec<(String, Vec<f32>)>,
    instances: Vec<InstanceRecord>,
    /// Solids over the instances ([`Context::add_solid`]).
    solids: Vec<crate::csg::Solid<InstanceId>>,
    lights: Vec<LightRecord>,
    pixel: Option<Binding>,
    camera_shader: Option<Binding>,
    atmosphere: Option<Binding>,
    camera: CameraSetup,
    pub options: RenderOptions,
    spaces: std::collections::HashMap<String, Affine3A>,
    scene: Option<Scene>,
    texture_search_path: Vec<PathBuf>,
    textures: Arc<TextureCache>,
    memory_textures: Vec<(String, TexImage)>,
    memory_grids: Vec<(String, crate::texture::grid::Grid)>,
    /// Counts the changes to `memory_textures` and `memory_grids` (a [`Replicator`] sends them
    /// again when it moves).
    memory_changes: u64,
    warnings: Vec<String>,
    /// Hot-reload events not yet taken ([`Context::take_shader_events`]).
    events: Vec<ShaderEvent>,
    /// Each object's materials as the last frame built them (by object index).
    built_materials: Vec<Option<BuiltMaterials>>,
    /// The meshes true displacement made for the last frame, with the scene objects holding
    /// them (`render/true_displacement.rs`).
    displaced: crate::render::true_displacement::DisplacedMeshes,
    /// A demand-loading replica's displaced meshes, as its master displaced them.
    remote_displaced: crate::render::remote_displacement::RemoteDisplacements,
    /// The last [`ObjectRecord::version`] given.
    object_versions: u64,
    /// Where demand-loaded objects' meshes come from ([`Context::set_mesh_source`]).
    mesh_source: Option<Arc<dyn MeshSource>>,
    /// Where textures come from instead of files ([`Context::set_texture_source`]).
    texture_source: Option<Arc<dyn crate::texture::TextureSource>>,
    /// Texture files other contexts decoded too ([`Context::share_files`]).
    shared_files: Option<Arc<crate::shared_files::SharedFiles>>,
    /// Object BVHs other contexts built too ([`Context::share_bvhs`]).
    bvh_store: Option<Arc<crate::accel::store::BvhStore>>,
    /// The ray parameter names shaders asked for and nothing set, shared with the worlds built,
    /// so that each is reported once across frames.
    ray_parameter_misses: Arc<crate::render::ray_params::RayParameterMisses>,
    /// Tells this context from every other made in the process: a [`Replicator`] follows one
    /// context, and starts its replicas again from empty when given another.
    identity: u64,
}

/// An object's materials as a frame built them, and what they were built from: reused by the next
/// frame while its appearances and the programs their bindings name are the same. Building the
/// shader instances of every material again each frame would be most of the serial world update
/// of an animation with many materials.
struct BuiltMaterials {
    /// The [`ObjectRecord::version`] built from, and its appearances.
    version: u64,
    appearances: Vec<Appearance>,
    /// The program of each binding of `appearances` (surface, interior, displacement), kept so
    /// that comparing addresses cannot mistake a new program for a freed one.
    programs: Vec<Program>,
    materials: Vec<Material>,
    warnings: Vec<String>,
}

impl Default for Context {
    fn default() -> Self {
        Self::new()
    }
}

/// The `identity` of the next [`Context`] made.
fn next_context_identity() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
    NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

/// Where shader `name` is found as a file: in each directory of `search` (in order), then in the
/// folders (`surface/`, `light/`, ...) of the library directory `RTSL_STDLIB` names, the compiled
/// artifact `NAME.rtso` (written by `rtsl compile -o`; it is checked against its sources when
/// loaded) or else the source `NAME.sl`. A name found twice resolves to the first. Without a file,
/// [`locate_shader`] looks in the library embedded in the binary.
pub fn find_shader_file(name: &str, search: &[impl AsRef<Path>]) -> Option<PathBuf> {
    let files = [format!("{name}.{}", rtsl_compiler::artifact::EXTENSION), format!("{name}.sl")];
    let library: Vec<PathBuf> =
        library::override_dir().map(|dir| library::FOLDERS.iter().map(|f| dir.join(f)).collect()).unwrap_or_default();
    search
        .iter()
        .map(AsRef::as_ref)
        .chain(library.iter().map(PathBuf::as_path))
        .flat_map(|d| files.iter().map(move |f| d.join(f)))
        .find(|p| p.is_file())
}

/// Where a shader comes from: a file, or the library embedded in the binary.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ShaderLocation {
    File(PathBuf),
    Library(LibraryShader),
}

impl std::fmt::Display for ShaderLocation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ShaderLocation::File(path) => write!(f, "{}", path.display()),
            ShaderLocation::Library(shader) => write!(f, "{} (built in)", shader.path),
        }
    }
}

/// Where shader `name` is loaded from: a file ([`find_shader_file`]), else the embedded library.
pub fn locate_shader(name: &str, search: &[impl AsRef<Path>]) -> Option<ShaderLocation> {
    find_shader_file(name, search)
        .map(ShaderLocation::File)
        .or_else(|| library::find(name).map(ShaderLocation::Library))
}

impl Context {
    pub fn new() -> Context {
        Context {
            programs: Vec::new(),
            shader_cache: None,
            shader_search_path: Vec::new(),
            include_paths: Vec::new(),
            matrix: Affine3A::IDENTITY,
            stack: Vec::new(),
            close_matrix: None,
            appearance: Appearance::default(),
            appearance_stack: Vec::new(),
            objects: Vec::new(),
            building: None,
            primitive: None,
            current_normal: Vec3::ZERO,
            current_uv: Vec2::ZERO,
            vertex_values: Vec::new(),
            primitive_values: Vec::new(),
            instances: Vec::new(),
            solids: Vec::new(),
            lights: Vec::new(),
            pixel: None,
            camera_shader: None,
            atmosphere: None,
            camera: CameraSetup::default(),
            options: RenderOptions::default(),
            spaces: Default::default(),
            scene: Some(Scene::new()),
            texture_search_path: Vec::new(),
            textures: Arc::new(TextureCache::new()),
            memory_textures: Vec::new(),
            memory_grids: Vec::new(),
            memory_changes: 0,
            mesh_source: None,
            texture_source: None,
            shared_files: None,
            bvh_store: None,
            ray_parameter_misses: Default::default(),
            identity: next_context_identity(),
            warnings: crate::cpu::build_note_once().map(str::to_string).into_iter().collect(),
            events: Vec::new(),
            built_materials: Vec::new(),
            displaced: Default::default(),
            remote_displaced: Default::default(),
            object_versions: 0,
        }
    }
}

impl Context {
    /// A version no object record of this context had: for a record whose mesh, appearance,
    /// parts or deletion change.
    fn next_object_version(&mut self) -> u64 {
        self.object_versions += 1;
        self.object_versions
    }
}

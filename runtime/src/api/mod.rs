//! The application API, modelled on OpenRT (OpenGL's names for geometry and matrices) and the
//! Stanford real-time shading API (`shader_file`, `compile_shader`, `bind_shader`, `parameter`).
//!
//! ```no_run
//! use rtsl_runtime::api::{Context, Primitive};
//! use rtsl_runtime::shading::ParamValue;
//! use glam::Vec3A;
//!
//! let mut rt = Context::new();
//! let plastic = rt.find_shader("plastic")?;
//! let light = rt.find_shader("pointlight")?;
//! rt.camera_look_at(Vec3A::new(0.0, 1.0, 4.0), Vec3A::ZERO, Vec3A::Y, 40.0);
//! let quad = rt.begin_object()?;
//! rt.bind_shader(plastic)?;
//! rt.parameter("Kd", ParamValue::Float(0.8))?;
//! rt.begin(Primitive::Quads)?;
//! for (x, z) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
//!     rt.vertex(x, 0.0, z)?;
//! }
//! rt.end()?;
//! rt.end_object()?;
//! rt.instantiate_object(quad)?;
//! rt.light_source(light, &[("intensity", ParamValue::Float(10.0))])?;
//! let (image, report) = rt.render_frame()?;
//! # Ok::<(), rtsl_runtime::api::ApiError>(())
//! ```
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
use crate::geometry::{AlphaMask, Attribute, Mesh, MeshError};
use crate::render::{
    render_frame, AreaLight, CameraSetup, FrameReport, Framebuffer, InstanceParts, InstanceShading, LightSource,
    Material, RenderOptions, World,
};
use crate::scene::{ObjectId as SceneObject, Scene, SceneError};
use crate::shading::{LightKind, ParamError, ParamValue, Program, ShaderError, ShaderInstance, ShaderProgram};
use crate::texture::{TexImage, TextureCache, Wrap};
use glam::{Affine3A, Quat, Vec2, Vec3, Vec3A};
use rtsl_compiler::front::parse::ast::ShaderKind;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod events;
mod replica;
pub use events::ShaderEvent;
pub use replica::{decode_mesh, encode_mesh, ReplicaError, Replicator};

/// A compiled shader known to a [`Context`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct ShaderId(pub u32);

/// A retained object of a [`Context`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct ObjectId(pub u32);

/// An instance of an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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
    /// The texture whose alpha cuts objects built from now on, and the cut-off
    /// ([`Context::alpha_mask`]).
    alpha_mask: Option<(String, f32)>,
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
            alpha_mask: None,
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
}

impl ObjectRecord {
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
}

impl MeshBuilder {
    /// Makes the triangles added since the last part a part of `appearance` (none: no part).
    fn close_part(&mut self, appearance: &Appearance) {
        let start = self.parts.last().map_or(0, |(end, _)| *end);
        if self.triangles.len() > start {
            self.parts.push((self.triangles.len(), appearance.clone()));
        }
    }
}

struct OpenPrimitive {
    kind: Primitive,
    first_vertex: u32,
}

/// The rendering context: scene state, shaders, and frames.
pub struct Context {
    programs: Vec<Option<Program>>,
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
    /// Where demand-loaded objects' meshes come from ([`Context::set_mesh_source`]).
    mesh_source: Option<Arc<dyn MeshSource>>,
}

/// An object's materials as a frame built them, and what they were built from: reused by the next
/// frame while its appearances and the programs their bindings name are the same. Building the
/// shader instances of every material again each frame would be most of the serial world update
/// of an animation with many materials.
struct BuiltMaterials {
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

/// Where shader `name` is found: in each directory of `search` (in order), then in the standard
/// library's folders (`surface/`, `light/`, ...), the compiled artifact `NAME.rtso` (written by
/// `rtsl compile -o`; it is checked against its sources when loaded) or else the source `NAME.sl`.
/// A name found twice resolves to the first.
pub fn find_shader_file(name: &str, search: &[PathBuf]) -> Option<PathBuf> {
    let files = [format!("{name}.{}", rtsl_compiler::artifact::EXTENSION), format!("{name}.sl")];
    let std = stdlib_dir();
    let std_dirs =
        ["surface", "light", "displacement", "volume", "imager", "camera", "pixel", "lightfield"].map(|d| std.join(d));
    search.iter().chain(std_dirs.iter()).flat_map(|d| files.iter().map(move |f| d.join(f))).find(|p| p.is_file())
}

/// The directory of the shader library shipped with rtsl (searched last).
pub fn stdlib_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("stdlib_shaders")
}

impl Context {
    pub fn new() -> Context {
        Context {
            programs: Vec::new(),
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
            warnings: Vec::new(),
            events: Vec::new(),
            built_materials: Vec::new(),
        }
    }

    // ---- shaders ----

    /// Directories searched (in order, before the standard library) by [`Context::find_shader`].
    pub fn set_shader_search_path(&mut self, dirs: Vec<PathBuf>) {
        self.shader_search_path = dirs;
    }

    pub fn shader_search_path(&self) -> &[PathBuf] {
        &self.shader_search_path
    }

    /// Adds a directory where textures named by relative paths are looked for.
    pub fn add_texture_search_path(&mut self, dir: PathBuf) {
        if !self.texture_search_path.contains(&dir) {
            self.texture_search_path.push(dir);
            self.textures = Arc::new(TextureCache::with_search_paths(self.texture_search_path.clone()));
            self.insert_memory_textures();
        }
    }

    /// Makes `name` a texture from memory (OpenGL's `glTexImage2D`): `width x height` texels of
    /// `channels` linear floats each, rows top to bottom. Shaders look it up by that name, before
    /// any file of the same name; it repeats (periodic wrap).
    pub fn tex_image_2d(
        &mut self,
        name: &str,
        width: usize,
        height: usize,
        channels: usize,
        texels: &[f32],
    ) -> Result<(), ApiError> {
        let image = TexImage::new(width, height, channels, texels.to_vec()).ok_or(ApiError::BadTexture {
            name: name.to_string(),
            width,
            height,
            channels,
            given: texels.len(),
        })?;
        self.textures.insert_texture(name, image.clone(), [Wrap::Periodic; 2]);
        self.memory_textures.retain(|(n, _)| n != name);
        self.memory_textures.push((name.to_string(), image));
        self.memory_changes += 1;
        Ok(())
    }

    /// Makes `name` a texture decoded from a texture file's bytes held in memory (PNG, JPEG, TGA
    /// or PPM, 8-bit colour taken as sRGB like a file's): an application's embedded assets. Shaders
    /// look it up by that name before any file of the same name; it repeats (periodic wrap).
    pub fn texture_file_in_memory(&mut self, name: &str, bytes: &[u8]) -> Result<(), ApiError> {
        let loaded = crate::texture::image::decode_texture_image(Path::new(name), bytes, false)
            .map_err(|e| ApiError::BadTextureFile { name: name.to_string(), message: e.to_string() })?;
        self.textures.insert_texture(name, loaded.image.clone(), [Wrap::Periodic; 2]);
        self.memory_textures.retain(|(n, _)| n != name);
        self.memory_textures.push((name.to_string(), loaded.image));
        self.memory_changes += 1;
        Ok(())
    }

    /// Makes `name` a 3-D grid for `texture3d` parsed from a grid file's bytes held in memory (the
    /// RTSLGRID format of `docs/volumes.md`), looked up before any file of the same name.
    pub fn grid_file_in_memory(&mut self, name: &str, bytes: &[u8]) -> Result<(), ApiError> {
        let grid = crate::texture::grid::Grid::parse(bytes)
            .map_err(|message| ApiError::BadTextureFile { name: name.to_string(), message })?;
        self.textures.insert_grid(name, grid.clone());
        self.memory_grids.retain(|(n, _)| n != name);
        self.memory_grids.push((name.to_string(), grid));
        self.memory_changes += 1;
        Ok(())
    }

    /// The texture cache frames use (textures load once and stay loaded across frames).
    pub fn textures(&self) -> &Arc<TextureCache> {
        &self.textures
    }

    /// Directories searched by `#include`.
    pub fn set_include_paths(&mut self, dirs: Vec<PathBuf>) {
        self.include_paths = dirs;
    }

    /// Where shader `name` would be loaded from: `NAME.sl` in the search path, then in the standard
    /// library's folders.
    pub fn which_shader(&self, name: &str) -> Option<PathBuf> {
        find_shader_file(name, &self.shader_search_path)
    }

    /// Compiles the shader file at `path`.
    pub fn shader_file(&mut self, path: &Path) -> Result<ShaderId, ApiError> {
        let program = ShaderProgram::from_file(path, &self.include_paths)?;
        Ok(self.add_program(program))
    }

    /// Compiles shader source given as a string (`name` names it in diagnostics).
    pub fn compile_shader(&mut self, name: &str, source: &str) -> Result<ShaderId, ApiError> {
        let program = ShaderProgram::from_source(name, source, &self.include_paths)?;
        Ok(self.add_program(program))
    }

    /// Finds shader `name` on the search path (see [`Context::which_shader`]) and compiles it, once:
    /// later calls with the same name return the same id.
    pub fn find_shader(&mut self, name: &str) -> Result<ShaderId, ApiError> {
        if let Some(i) = self.programs.iter().position(|p| p.as_ref().is_some_and(|p| p.name == name)) {
            return Ok(ShaderId(i as u32));
        }
        let path = self.which_shader(name).ok_or_else(|| ShaderError::NotFound { name: name.to_string() })?;
        self.shader_file(&path)
    }

    /// Replaces the program behind `id` (hot reload): frames from now on use the new code. The
    /// new program must be of the same shader type. Values bound by name stay bound where the new
    /// shader still has a parameter of that name and type; the others are dropped with a warning
    /// at the next frame ([`Context::take_warnings`]), and reported now as
    /// [`ShaderEvent::ParameterDropped`] events ([`Context::take_shader_events`]).
    pub fn replace_shader(&mut self, id: ShaderId, program: ShaderProgram) -> Result<(), ApiError> {
        let dropped = self.swap_program(id, program)?;
        self.events.extend(dropped);
        Ok(())
    }

    /// [`Context::replace_shader`], returning the [`ShaderEvent::ParameterDropped`] events instead
    /// of queueing them (hot reload queues them after its own event).
    pub(crate) fn swap_program(&mut self, id: ShaderId, program: ShaderProgram) -> Result<Vec<ShaderEvent>, ApiError> {
        let dropped = self.dropped_parameters(id, &program);
        let slot = self.programs.get_mut(id.0 as usize).ok_or(ApiError::UnknownShader(id.0))?;
        if let Some(old) = slot.as_ref() {
            if old.kind != program.kind {
                return Err(ApiError::WrongKind {
                    name: program.name.clone(),
                    expected: kind_name(old.kind),
                    got: kind_name(program.kind),
                });
            }
        }
        *slot = Some(Arc::new(program));
        Ok(dropped)
    }

    /// The values bound to shader `id` (surface bindings of objects and of the current and saved
    /// state, lights, the pixel shader) that `program` would not take, once per (parameter, reason).
    fn dropped_parameters(&self, id: ShaderId, program: &ShaderProgram) -> Vec<ShaderEvent> {
        let surfaces =
            std::iter::once(&self.appearance)
                .chain(&self.appearance_stack)
                .chain(self.objects.iter().filter(|o| !o.deleted).flat_map(|o| {
                    std::iter::once(&o.appearance).chain(o.parts.iter().flat_map(|p| p.appearances.iter()))
                }))
                .flat_map(|a| a.surface.iter().chain(a.interior.iter()))
                .chain(self.pixel.as_ref())
                .chain(self.atmosphere.as_ref())
                .filter(|b| b.shader == id)
                .flat_map(|b| b.params.iter());
        let lights = self.lights.iter().filter(|l| l.shader == id).flat_map(|l| l.params.iter());
        let mut out = Vec::new();
        for (parameter, value, m) in surfaces.chain(lights) {
            if let Err(e) = crate::shading::bind_param(program, parameter, value, m) {
                let event = ShaderEvent::ParameterDropped {
                    shader: id,
                    name: program.name.clone(),
                    parameter: parameter.clone(),
                    reason: e.to_string(),
                };
                if !out.contains(&event) {
                    out.push(event);
                }
            }
        }
        out
    }

    /// The hot-reload events since the last call, oldest first: shaders reloaded or not
    /// ([`crate::reload`]), and bound values a new parameter list no longer takes. The queue grows
    /// until taken.
    pub fn take_shader_events(&mut self) -> Vec<ShaderEvent> {
        std::mem::take(&mut self.events)
    }

    pub(crate) fn push_shader_events(&mut self, events: impl IntoIterator<Item = ShaderEvent>) {
        self.events.extend(events);
    }

    /// Every file the loaded shaders were compiled from (sources and included headers), for a
    /// watcher.
    pub fn shader_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.programs.iter().flatten().flat_map(|p| p.files.iter().cloned()).collect();
        files.sort();
        files.dedup();
        files
    }

    /// The loaded programs with their ids.
    pub fn programs_by_id(&self) -> Vec<(ShaderId, Program)> {
        self.programs.iter().enumerate().filter_map(|(i, p)| Some((ShaderId(i as u32), p.clone()?))).collect()
    }

    pub fn include_paths(&self) -> &[PathBuf] {
        &self.include_paths
    }

    /// Warnings of the last frames (values that no longer fit a reloaded shader), drained.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    pub fn program(&self, id: ShaderId) -> Result<&Program, ApiError> {
        self.programs.get(id.0 as usize).and_then(Option::as_ref).ok_or(ApiError::UnknownShader(id.0))
    }

    fn add_program(&mut self, program: ShaderProgram) -> ShaderId {
        self.programs.push(Some(Arc::new(program)));
        ShaderId(self.programs.len() as u32 - 1)
    }

    fn expect_kind(&self, id: ShaderId, expected: ShaderKind) -> Result<Program, ApiError> {
        let p = self.program(id)?.clone();
        if p.kind != expected {
            return Err(ApiError::WrongKind {
                name: p.name.clone(),
                expected: kind_name(expected),
                got: kind_name(p.kind),
            });
        }
        Ok(p)
    }

    /// Binds a surface (or lightfield) shader: the object being built (or, outside objects, the
    /// objects built from now on) is shaded by it. Its "shader" space is the current matrix.
    pub fn bind_shader(&mut self, id: ShaderId) -> Result<(), ApiError> {
        // A lightfield shader is bound like a surface: it shades the rays that hit the object.
        if self.program(id)?.kind != ShaderKind::Lightfield {
            self.expect_kind(id, ShaderKind::Surface)?;
        }
        self.appearance.surface = Some(Binding { shader: id, params: Vec::new(), world_from_shader: self.matrix });
        Ok(())
    }

    /// The surface shader bound now, if any.
    pub fn bound_surface(&self) -> Option<ShaderId> {
        self.appearance.surface.as_ref().map(|b| b.shader)
    }

    /// Sets a parameter of the bound surface shader (object scope). The value is checked against the
    /// shader's declaration now; point-like values are in the current space.
    pub fn parameter(&mut self, name: &str, value: ParamValue) -> Result<(), ApiError> {
        let binding = self.appearance.surface.as_ref().ok_or_else(|| ApiError::NoShaderBound(name.to_string()))?;
        let program = self.program(binding.shader)?.clone();
        crate::shading::bind_param(&program, name, &value, &self.matrix)?;
        let m = self.matrix;
        if let Some(b) = self.appearance.surface.as_mut() {
            b.params.retain(|(n, _, _)| n != name);
            b.params.push((name.to_string(), value, m));
        }
        Ok(())
    }

    fn varying_param_floats(&self, name: &str, value: &ParamValue) -> Result<Vec<f32>, ApiError> {
        let binding = self.appearance.surface.as_ref().ok_or_else(|| ApiError::NoShaderBound(name.to_string()))?;
        let program = self.program(binding.shader)?.clone();
        let bound = crate::shading::bind_param(&program, name, value, &self.matrix)?;
        if !program.layout().params[bound.index].varying || bound.string.is_some() {
            return Err(ApiError::NotVarying { shader: program.name.clone(), name: name.to_string() });
        }
        Ok(bound.floats)
    }

    /// Sets a varying parameter of the bound surface shader for the open primitive.
    pub fn primitive_parameter(&mut self, name: &str, value: ParamValue) -> Result<(), ApiError> {
        if self.primitive.is_none() {
            return Err(ApiError::Unbalanced("primitive_parameter", "begin"));
        }
        let floats = self.varying_param_floats(name, &value)?;
        self.primitive_values.retain(|(n, _)| n != name);
        self.primitive_values.push((name.to_string(), floats));
        Ok(())
    }

    /// Sets a varying parameter of the bound surface shader for the vertices that follow.
    pub fn vertex_parameter(&mut self, name: &str, value: ParamValue) -> Result<(), ApiError> {
        let floats = self.varying_param_floats(name, &value)?;
        self.vertex_values.retain(|(n, _)| n != name);
        self.vertex_values.push((name.to_string(), floats));
        Ok(())
    }

    /// Adds a light source at the current matrix, with its parameter values.
    pub fn light_source(&mut self, shader: ShaderId, params: &[(&str, ParamValue)]) -> Result<LightId, ApiError> {
        let program = self.expect_kind(shader, ShaderKind::Light)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        self.lights.push(LightRecord {
            shader,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
            shadows: true,
            area_triangles: Vec::new(),
            area_samples: 16,
            on: true,
        });
        Ok(LightId(self.lights.len() as u32 - 1))
    }

    /// Makes a light an area light (RenderMan's `AreaLightSource`) emitting from `mesh` too (in the
    /// current space): its shader runs with `P` and `N` at samples on the geometry, each sample a
    /// light of its own with a traced shadow (soft shadows).
    pub fn area_light_geometry(&mut self, light: LightId, mesh: &Mesh) -> Result<(), ApiError> {
        let m = self.matrix;
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        rec.area_triangles
            .extend((0..mesh.triangle_count()).map(|i| mesh.corners(i).map(|c| m.transform_point3a(Vec3A::from(c)))));
        Ok(())
    }

    /// Samples of an area light per shading point (16 by default).
    pub fn set_area_light_samples(&mut self, light: LightId, samples: u32) {
        if let Some(rec) = self.lights.get_mut(light.0 as usize) {
            rec.area_samples = samples.clamp(1, crate::render::MAX_AREA_SAMPLES);
        }
    }

    /// The pixel shader (RenderMan's imager, OpenRT's pixel shader) run on every finished tile, with
    /// its parameter values; `None` removes it.
    pub fn pixel_shader(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        let Some(id) = shader else {
            self.pixel = None;
            return Ok(());
        };
        let program = self.expect_kind(id, ShaderKind::Imager)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        self.pixel = Some(Binding {
            shader: id,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
        });
        Ok(())
    }

    /// The camera shader that generates the primary rays (`None`: the built-in pinhole camera). Its
    /// "shader" and "object" spaces are camera space, whatever the current matrix; the camera's
    /// placement still comes from [`Context::camera_look_at`] / [`Context::set_camera`]. The globals it
    /// reads and writes are specified in `docs/cameras.md`.
    pub fn camera_shader(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        let Some(id) = shader else {
            self.camera_shader = None;
            return Ok(());
        };
        let program = self.expect_kind(id, ShaderKind::Camera)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        self.camera_shader = Some(Binding {
            shader: id,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
        });
        Ok(())
    }

    /// The camera shader bound with [`Context::camera_shader`], if any.
    pub fn camera_shader_id(&self) -> Option<ShaderId> {
        self.camera_shader.as_ref().map(|b| b.shader)
    }

    /// The atmosphere (RenderMan's `Atmosphere`): a volume shader run on every ray segment that ends
    /// on a surface outside objects with an interior shader (`docs/volumes.md`), with its parameter
    /// values; `None` removes it.
    pub fn atmosphere(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.atmosphere = self.volume_binding(shader, params)?;
        Ok(())
    }

    /// The displacement shader (RenderMan's `Displacement`) of objects built from now on, an
    /// attribute like the surface shader. It runs on every hit before the surface shader, and the
    /// normal it leaves is the surface shader's `N`: displacement as bump mapping. The traced
    /// geometry does not move (silhouettes and shadows keep the undisplaced shape) and `P` stays on
    /// it (`docs/rendering.md`). `None` removes it.
    pub fn displacement(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.appearance.displacement = self.kind_binding(ShaderKind::Displacement, shader, params)?;
        Ok(())
    }

    /// The interior volume shader (RenderMan's `Interior`) of objects built from now on, an
    /// attribute like the surface shader (saved by `push_attributes`): it runs on ray segments that
    /// reach such an object's surface from behind, i.e. travel inside it (`docs/volumes.md`).
    /// `None` removes it.
    pub fn interior(&mut self, shader: Option<ShaderId>, params: &[(&str, ParamValue)]) -> Result<(), ApiError> {
        self.appearance.interior = self.volume_binding(shader, params)?;
        Ok(())
    }

    /// A volume shader's binding with its values checked now; `None` for `None`.
    fn volume_binding(
        &self,
        shader: Option<ShaderId>,
        params: &[(&str, ParamValue)],
    ) -> Result<Option<Binding>, ApiError> {
        self.kind_binding(ShaderKind::Volume, shader, params)
    }

    /// A binding of a shader of `kind` with its values checked now; `None` for `None`.
    fn kind_binding(
        &self,
        kind: ShaderKind,
        shader: Option<ShaderId>,
        params: &[(&str, ParamValue)],
    ) -> Result<Option<Binding>, ApiError> {
        let Some(id) = shader else { return Ok(None) };
        let program = self.expect_kind(id, kind)?;
        for (name, value) in params {
            crate::shading::bind_param(&program, name, value, &self.matrix)?;
        }
        Ok(Some(Binding {
            shader: id,
            params: params.iter().map(|(n, v)| (n.to_string(), v.clone(), self.matrix)).collect(),
            world_from_shader: self.matrix,
        }))
    }

    /// Switches a light on or off, and its ray-traced shadows.
    pub fn set_light(&mut self, light: LightId, on: bool, shadows: bool) -> Result<(), ApiError> {
        let rec = self.lights.get_mut(light.0 as usize).ok_or(ApiError::UnknownLight(light.0))?;
        rec.on = on;
        rec.shadows = shadows;
        Ok(())
    }

    // ---- attributes ----

    /// The current colour (`Cs`) for objects built from now on.
    pub fn color(&mut self, r: f32, g: f32, b: f32) {
        self.appearance.color = [r, g, b];
    }

    /// The current opacity (`Os`).
    pub fn opacity(&mut self, r: f32, g: f32, b: f32) {
        self.appearance.opacity = [r, g, b];
    }

    /// Shadow rays run the surface shader to find the opacity of objects built from now on.
    pub fn shadows_from_shader(&mut self, on: bool) {
        self.appearance.shadow_by_shader = on;
    }

    /// Cuts objects built from now on where the alpha of texture `name` (at their texture
    /// coordinates) is below one half, for every ray: cut-outs such as leaves drawn on quads are
    /// seen through and cast shaped shadows, with no shading. `None` makes them solid again. The
    /// texture is found as shader textures are; one that cannot be read, or has no transparent
    /// texel, leaves the object solid (a missing one with a warning).
    pub fn alpha_mask(&mut self, name: Option<&str>) {
        self.alpha_mask_with_cutoff(name, ALPHA_CUTOFF);
    }

    /// [`Context::alpha_mask`] with the alpha below which a texel is cut (glTF's `alphaCutoff`).
    pub fn alpha_mask_with_cutoff(&mut self, name: Option<&str>, cutoff: f32) {
        self.appearance.alpha_mask = name.map(|n| (n.to_string(), cutoff));
    }

    /// Saves the attribute state (colour, opacity, shader binding) and the matrix.
    pub fn push_attributes(&mut self) {
        self.appearance_stack.push(self.appearance.clone());
        self.stack.push((self.matrix, self.close_matrix));
    }

    pub fn pop_attributes(&mut self) -> Result<(), ApiError> {
        self.appearance =
            self.appearance_stack.pop().ok_or(ApiError::Unbalanced("pop_attributes", "push_attributes"))?;
        (self.matrix, self.close_matrix) = self.stack.pop().ok_or(ApiError::MatrixStackEmpty)?;
        Ok(())
    }

    // ---- matrices ----

    pub fn push_matrix(&mut self) {
        self.stack.push((self.matrix, self.close_matrix));
    }

    pub fn pop_matrix(&mut self) -> Result<(), ApiError> {
        (self.matrix, self.close_matrix) = self.stack.pop().ok_or(ApiError::MatrixStackEmpty)?;
        Ok(())
    }

    pub fn load_identity(&mut self) {
        self.matrix = Affine3A::IDENTITY;
        self.close_matrix = None;
    }

    pub fn current_matrix(&self) -> Affine3A {
        self.matrix
    }

    pub fn load_matrix(&mut self, m: Affine3A) {
        self.matrix = m;
        self.close_matrix = None;
    }

    /// Post-multiplies the current matrix (OpenGL's order: the last call applies first to points).
    pub fn mult_matrix(&mut self, m: Affine3A) {
        self.matrix *= m;
        if let Some(close) = &mut self.close_matrix {
            *close *= m;
        }
    }

    /// A transform that moves during the shutter interval (RIB's `MotionBegin` around a
    /// transform): post-multiplies the current matrix by `open` for the shutter's opening and by
    /// `close` for its closing. Instances placed from now on (within the current matrix scope) move
    /// between the two, so they are motion-blurred when the shutter interval
    /// ([`crate::render::RenderOptions::shutter`]) is not empty.
    pub fn motion_transform(&mut self, open: Affine3A, close: Affine3A) {
        let before = self.matrix;
        let close_before = self.close_matrix.unwrap_or(before);
        self.matrix = before * open;
        let close = close_before * close;
        self.close_matrix = (close != self.matrix).then_some(close);
    }

    /// The current matrix at the shutter's close (the current matrix unless a motion transform
    /// applies).
    pub fn close_matrix(&self) -> Affine3A {
        self.close_matrix.unwrap_or(self.matrix)
    }

    /// Places instance `id` at `open` when the shutter opens and at `close` when it closes (motion
    /// blur; see [`Context::motion_transform`]).
    pub fn set_instance_motion(&mut self, id: InstanceId, open: Affine3A, close: Affine3A) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.transform = open;
        rec.close_transform = (close != open).then_some(close);
        Ok(())
    }

    pub fn translate(&mut self, x: f32, y: f32, z: f32) {
        self.mult_matrix(Affine3A::from_translation(Vec3::new(x, y, z)));
    }

    /// Rotation by `degrees` about the axis.
    pub fn rotate(&mut self, degrees: f32, x: f32, y: f32, z: f32) {
        let axis = Vec3::new(x, y, z).normalize_or_zero();
        if axis != Vec3::ZERO {
            self.mult_matrix(Affine3A::from_quat(Quat::from_axis_angle(axis, degrees.to_radians())));
        }
    }

    pub fn scale(&mut self, x: f32, y: f32, z: f32) {
        self.mult_matrix(Affine3A::from_mat3(glam::Mat3::from_diagonal(Vec3::new(x, y, z))));
    }

    /// Names the current space (RenderMan's `CoordinateSystem`), for shaders' space casts.
    pub fn coordinate_system(&mut self, name: &str) {
        self.spaces.insert(name.to_string(), self.matrix);
    }

    /// Makes a named space current (RenderMan's `CoordSysTransform`); false for an unknown name.
    pub fn load_coordinate_system(&mut self, name: &str) -> bool {
        match self.spaces.get(name) {
            Some(m) => {
                self.matrix = *m;
                self.close_matrix = None;
                true
            }
            None => false,
        }
    }

    // ---- camera and options ----

    /// A pinhole camera at `eye` looking at `target`; `fov_degrees` spans the image's shorter side.
    pub fn camera_look_at(&mut self, eye: Vec3A, target: Vec3A, up: Vec3A, fov_degrees: f32) {
        self.camera = CameraSetup::look_at(eye, target, up, fov_degrees);
    }

    /// Sets the camera directly (RenderMan's convention: camera space x right, y up, z forward).
    pub fn set_camera(&mut self, camera: CameraSetup) {
        self.camera = camera;
    }

    pub fn camera(&self) -> &CameraSetup {
        &self.camera
    }

    // ---- objects and geometry ----

    /// Starts a retained object; geometry calls until `end_object` go into it.
    pub fn begin_object(&mut self) -> Result<ObjectId, ApiError> {
        self.begin_object_in(self.matrix)
    }

    /// Starts a retained object whose own space is `frame`: its geometry is placed by the current
    /// matrix relative to `frame` (with `begin_object`, `frame` is the current matrix).
    pub fn begin_object_in(&mut self, frame: Affine3A) -> Result<ObjectId, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("begin_object", "an object"));
        }
        let id = ObjectId(self.objects.len() as u32);
        self.objects.push(ObjectRecord {
            mesh: None,
            remote: None,
            appearance: Appearance::default(),
            parts: None,
            scene_object: None,
            dirty: true,
            deleted: false,
        });
        self.building = Some((id, frame, MeshBuilder::default()));
        Ok(id)
    }

    /// Starts replacing the geometry of `id` (its appearance is taken from the state, as when it was
    /// built).
    pub fn redefine_object(&mut self, id: ObjectId) -> Result<(), ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("redefine_object", "an object"));
        }
        match self.objects.get(id.0 as usize) {
            Some(o) if !o.deleted => {}
            _ => return Err(ApiError::UnknownObject(id.0)),
        }
        self.building = Some((id, self.matrix, MeshBuilder::default()));
        Ok(())
    }

    /// Ends a part of the object being built: the triangles added since the object began (or since
    /// the last part) are shaded with the current appearance (colour, opacity, shaders), as
    /// [`Context::end_object`] gives a whole object its appearance; later triangles make the next
    /// part. One object of several materials is one BVH, where an object per material would make
    /// rays enter every one of them that overlaps. Without `end_part` an object has one appearance.
    /// A part without triangles is dropped. The alpha mask ([`Context::alpha_mask`]) stays the
    /// object's: the one current at `end_object`.
    pub fn end_part(&mut self) -> Result<(), ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("end_part", "begin/end"));
        }
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::Unbalanced("end_part", "begin_object"))?;
        b.close_part(&self.appearance);
        Ok(())
    }

    /// Finishes the object: its geometry, and the current appearance (colour, opacity, shader
    /// binding) as its material (that of its last part, when it was built in parts).
    pub fn end_object(&mut self) -> Result<ObjectId, ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("end_object", "begin/end"));
        }
        let (id, _, mut b) = self.building.take().ok_or(ApiError::Unbalanced("end_object", "begin_object"))?;
        if !b.parts.is_empty() {
            b.close_part(&self.appearance);
        }
        // One part is an object of one appearance.
        let parts = (b.parts.len() > 1).then(|| {
            let mut of_triangle = Vec::with_capacity(b.triangles.len());
            let mut from = 0;
            for (k, (end, _)) in b.parts.iter().enumerate() {
                of_triangle.resize(of_triangle.len() + (end - from), k as u32);
                from = *end;
            }
            ObjectParts {
                appearances: b.parts.iter().map(|(_, a)| a.clone()).collect(),
                of_triangle: of_triangle.into(),
            }
        });
        let appearance = match b.parts.as_slice() {
            [(_, only)] => only.clone(),
            _ => self.appearance.clone(),
        };
        let mesh = if b.triangles.is_empty() {
            None
        } else {
            let mesh = Mesh {
                positions: b.positions,
                normals: b.has_normals.then_some(b.normals),
                uvs: b.has_uvs.then_some(b.uvs),
                attributes: b.attributes,
                triangles: b.triangles,
            };
            mesh.validate()?;
            Some(Arc::new(mesh))
        };
        let rec = &mut self.objects[id.0 as usize];
        rec.mesh = mesh;
        rec.remote = None;
        rec.appearance = appearance;
        rec.parts = parts;
        rec.dirty = true;
        Ok(id)
    }

    /// The mesh of object `id` as it stands (`None`: deleted, empty, or demand-loaded here).
    pub fn object_mesh(&self, id: ObjectId) -> Option<&Arc<Mesh>> {
        self.objects.get(id.0 as usize)?.mesh.as_ref()
    }

    /// Where the meshes of demand-loaded objects come from: a worker's link to its master
    /// ([`Replicator::demand_loading`]). Objects built or replaced from now on use it.
    pub fn set_mesh_source(&mut self, source: Arc<dyn MeshSource>) {
        self.mesh_source = Some(source);
    }

    /// Deletes an object and its instances.
    pub fn delete_object(&mut self, id: ObjectId) -> Result<(), ApiError> {
        let rec = self.objects.get_mut(id.0 as usize).filter(|o| !o.deleted).ok_or(ApiError::UnknownObject(id.0))?;
        rec.deleted = true;
        rec.mesh = None;
        rec.remote = None;
        rec.dirty = true;
        for i in &mut self.instances {
            if i.object == id {
                i.deleted = true;
            }
        }
        Ok(())
    }

    /// Places an instance of `id` with the current matrix.
    pub fn instantiate_object(&mut self, id: ObjectId) -> Result<InstanceId, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("instantiate_object", "an object"));
        }
        match self.objects.get(id.0 as usize) {
            Some(o) if !o.deleted => {}
            _ => return Err(ApiError::UnknownObject(id.0)),
        }
        self.instances.push(InstanceRecord {
            object: id,
            transform: self.matrix,
            close_transform: self.close_matrix,
            deleted: false,
        });
        Ok(InstanceId(self.instances.len() as u32 - 1))
    }

    /// Moves an instance (per frame, for animation).
    pub fn set_instance_transform(&mut self, id: InstanceId, transform: Affine3A) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.transform = transform;
        rec.close_transform = None;
        Ok(())
    }

    /// Where an instance is (its world-from-object transform).
    pub fn instance_transform(&self, id: InstanceId) -> Result<Affine3A, ApiError> {
        self.instances
            .get(id.0 as usize)
            .filter(|i| !i.deleted)
            .map(|i| i.transform)
            .ok_or(ApiError::UnknownInstance(id.0))
    }

    /// The instances a world built now holds, in its order: `World::instances[k]` and a hit's
    /// `instance == k` are `world_instance_ids()[k]` (for picking).
    pub fn world_instance_ids(&self) -> Vec<InstanceId> {
        self.instances
            .iter()
            .enumerate()
            .filter(|(_, inst)| {
                let rec = &self.objects[inst.object.0 as usize];
                !inst.deleted && !rec.deleted && rec.has_geometry() && (rec.scene_object.is_some() || rec.dirty)
            })
            .map(|(i, _)| InstanceId(i as u32))
            .collect()
    }

    pub fn delete_instance(&mut self, id: InstanceId) -> Result<(), ApiError> {
        let rec =
            self.instances.get_mut(id.0 as usize).filter(|i| !i.deleted).ok_or(ApiError::UnknownInstance(id.0))?;
        rec.deleted = true;
        Ok(())
    }

    fn object_from_current(&self) -> Result<Affine3A, ApiError> {
        let (_, start, _) = self.building.as_ref().ok_or(ApiError::NoObject("geometry"))?;
        Ok(start.inverse() * self.matrix)
    }

    /// Starts a primitive; vertices follow.
    pub fn begin(&mut self, kind: Primitive) -> Result<(), ApiError> {
        if self.primitive.is_some() {
            return Err(ApiError::Nested("begin", "begin/end"));
        }
        let (_, _, b) = self.building.as_ref().ok_or(ApiError::NoObject("begin"))?;
        self.primitive = Some(OpenPrimitive { kind, first_vertex: b.positions.len() as u32 });
        self.primitive_values.clear();
        Ok(())
    }

    /// The normal of the following vertices (object space of the current matrix).
    pub fn normal(&mut self, x: f32, y: f32, z: f32) {
        self.current_normal = Vec3::new(x, y, z);
        if let Some((_, _, b)) = self.building.as_mut() {
            b.has_normals = true;
        }
    }

    /// The texture coordinates (s, t) of the following vertices.
    pub fn tex_coord(&mut self, s: f32, t: f32) {
        self.current_uv = Vec2::new(s, t);
        if let Some((_, _, b)) = self.building.as_mut() {
            b.has_uvs = true;
        }
    }

    /// Adds a vertex to the open primitive.
    pub fn vertex(&mut self, x: f32, y: f32, z: f32) -> Result<(), ApiError> {
        if self.primitive.is_none() {
            return Err(ApiError::Unbalanced("vertex", "begin"));
        }
        let xf = self.object_from_current()?;
        let normal_xf = xf.matrix3.inverse().transpose();
        let p = xf.transform_point3(Vec3::new(x, y, z));
        let n = Vec3::from(normal_xf * Vec3A::from(self.current_normal));
        let uv = self.current_uv;
        let values = self.vertex_values.iter().chain(self.primitive_values.iter());
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("vertex"))?;
        let index = b.positions.len();
        b.positions.push(p);
        b.normals.push(n);
        b.uvs.push(uv);
        for (name, v) in values {
            let pos = match b.attributes.iter().position(|a| &a.name == name) {
                Some(i) => i,
                None => {
                    b.attributes.push(Attribute {
                        name: name.clone(),
                        components: v.len(),
                        data: vec![0.0; index * v.len()],
                    });
                    b.attributes.len() - 1
                }
            };
            let a = &mut b.attributes[pos];
            if a.components == v.len() {
                a.data.truncate(index * a.components);
                a.data.resize(index * a.components, 0.0);
                a.data.extend_from_slice(v);
            }
        }
        for a in &mut b.attributes {
            a.data.resize((index + 1) * a.components, 0.0);
        }
        Ok(())
    }

    /// Ends the open primitive, triangulating it.
    pub fn end(&mut self) -> Result<(), ApiError> {
        let prim = self.primitive.take().ok_or(ApiError::Unbalanced("end", "begin"))?;
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("end"))?;
        let first = prim.first_vertex;
        let n = b.positions.len() as u32 - first;
        let v = |i: u32| first + i;
        match prim.kind {
            Primitive::Triangles => {
                if n % 3 != 0 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "triangles"));
                }
                for t in 0..n / 3 {
                    b.triangles.push([v(3 * t), v(3 * t + 1), v(3 * t + 2)]);
                }
            }
            Primitive::Quads => {
                if n % 4 != 0 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "quads"));
                }
                for q in 0..n / 4 {
                    b.triangles.push([v(4 * q), v(4 * q + 1), v(4 * q + 2)]);
                    b.triangles.push([v(4 * q), v(4 * q + 2), v(4 * q + 3)]);
                }
            }
            Primitive::Polygon => {
                if n < 3 {
                    return Err(ApiError::IncompletePrimitive(n as usize, "a polygon"));
                }
                let poly: Vec<u32> = (0..n).map(v).collect();
                crate::geometry::mesh::triangulate_into(b.triangles.len(), &poly, &mut b.triangles)?;
            }
            Primitive::TriangleStrip => {
                for i in 2..n {
                    if i % 2 == 0 {
                        b.triangles.push([v(i - 2), v(i - 1), v(i)]);
                    } else {
                        b.triangles.push([v(i - 1), v(i - 2), v(i)]);
                    }
                }
            }
            Primitive::TriangleFan => {
                for i in 2..n {
                    b.triangles.push([v(0), v(i - 1), v(i)]);
                }
            }
        }
        Ok(())
    }

    /// Adds a whole mesh to the object being built (placed by the current matrix relative to the
    /// object's).
    pub fn mesh(&mut self, mesh: &Mesh) -> Result<(), ApiError> {
        let xf = self.object_from_current()?;
        let normal_xf = xf.matrix3.inverse().transpose();
        let (_, _, b) = self.building.as_mut().ok_or(ApiError::NoObject("mesh"))?;
        let base = b.positions.len() as u32;
        let count = mesh.positions.len();
        b.positions.extend(mesh.positions.iter().map(|p| xf.transform_point3(*p)));
        match &mesh.normals {
            Some(ns) => {
                b.has_normals = true;
                b.normals.extend(ns.iter().map(|n| Vec3::from(normal_xf * Vec3A::from(*n))));
            }
            None => b.normals.extend(std::iter::repeat_n(Vec3::ZERO, count)),
        }
        match &mesh.uvs {
            Some(uvs) => {
                b.has_uvs = true;
                b.uvs.extend_from_slice(uvs);
            }
            None => b.uvs.extend(std::iter::repeat_n(Vec2::ZERO, count)),
        }
        for a in &mesh.attributes {
            let pos = match b.attributes.iter().position(|x| x.name == a.name && x.components == a.components) {
                Some(i) => i,
                None => {
                    b.attributes.push(Attribute {
                        name: a.name.clone(),
                        components: a.components,
                        data: vec![0.0; base as usize * a.components],
                    });
                    b.attributes.len() - 1
                }
            };
            b.attributes[pos].data.extend_from_slice(&a.data);
        }
        let total = b.positions.len();
        for x in &mut b.attributes {
            x.data.resize(total * x.components, 0.0);
        }
        b.triangles.extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
        Ok(())
    }

    // ---- frames ----

    /// A binding's instance; values the (possibly reloaded) program no longer takes are left out and
    /// reported.
    fn instance_for(&self, binding: &Binding, warnings: &mut Vec<String>) -> Result<ShaderInstance, ApiError> {
        let program = self.program(binding.shader)?.clone();
        let mut inst = ShaderInstance::new(program, binding.world_from_shader);
        for (name, value, m) in &binding.params {
            if let Err(e) = inst.set(name, value, m) {
                let w = format!("{e}; the value is not used");
                if !warnings.contains(&w) {
                    warnings.push(w);
                }
            }
        }
        Ok(inst)
    }

    /// Builds the world as it stands (resolving shader and object references now) and renders it.
    pub fn render_frame(&mut self) -> Result<(Framebuffer, FrameReport), ApiError> {
        let world = self.build_world()?;
        let out = render_frame(&world, None);
        self.scene = Some(world.scene);
        Ok(out)
    }

    /// Builds the world as it stands, for rendering with options (progress, threads) of the caller's
    /// choosing. Give the scene back with [`Context::return_scene`] to keep object BVHs for the next
    /// frame.
    pub fn build_world(&mut self) -> Result<World, ApiError> {
        if self.building.is_some() {
            return Err(ApiError::Nested("render_frame", "an object"));
        }
        // Refused here, before the scene is built, rather than when the framebuffer is allocated.
        crate::render::check_image_size(u64::from(self.options.width), u64::from(self.options.height))
            .map_err(ApiError::ImageSize)?;
        let mut scene = self.scene.take().unwrap_or_default();
        // Objects: (re)build only the BVHs of changed geometry.
        let bvh_start = std::time::Instant::now();
        let mut objects_rebuilt = 0;
        let mut masks: HashMap<(String, u32), Option<Arc<AlphaMask>>> = HashMap::new();
        for (index, rec) in self.objects.iter_mut().enumerate() {
            if !rec.dirty {
                continue;
            }
            rec.dirty = false;
            objects_rebuilt += 1;
            let remote = match (&rec.remote, &self.mesh_source) {
                (Some(summary), Some(source)) => Some((summary.clone(), source.clone())),
                (Some(_), None) => return Err(ApiError::NoMeshSource(index as u32)),
                (None, _) => None,
            };
            match (&rec.mesh, remote, rec.scene_object) {
                (Some(mesh), _, Some(id)) => scene.set_object_mesh(id, mesh.clone())?,
                (Some(mesh), _, None) => rec.scene_object = Some(scene.add_object(mesh.clone())),
                (None, Some((summary, source)), Some(id)) => {
                    scene.set_object_remote(id, summary, index as u32, source)?
                }
                (None, Some((summary, source)), None) => {
                    rec.scene_object = Some(scene.add_remote_object(summary, index as u32, source))
                }
                (None, None, Some(id)) => {
                    // An emptied or deleted object keeps its slot with no triangles.
                    let empty = Mesh::from_triangles(Vec::new(), Vec::new())?;
                    scene.set_object_mesh(id, empty)?;
                }
                (None, None, None) => {}
            }
            if let Some(id) = rec.scene_object {
                let mask = rec.appearance.alpha_mask.as_ref().and_then(|(name, cutoff)| {
                    let textures = &self.textures;
                    let warnings = &mut self.warnings;
                    masks
                        .entry((name.clone(), cutoff.to_bits()))
                        .or_insert_with(|| match textures.get_texture(name, false) {
                            Some(mip) => {
                                mip.levels().first().and_then(|l| AlphaMask::from_image(l, *cutoff)).map(Arc::new)
                            }
                            None => {
                                warnings.push(format!("alpha mask \"{name}\": texture not found; the object is solid"));
                                None
                            }
                        })
                        .clone()
                });
                scene.set_object_alpha_mask(id, mask)?;
            }
        }
        let object_bvhs = bvh_start.elapsed();
        let mut warnings = Vec::new();
        let mut materials = vec![Material::DEFAULT];
        let mut object_material = vec![0u32; self.objects.len()];
        let mut object_parts: Vec<Option<InstanceParts>> = vec![None; self.objects.len()];
        let mut built = std::mem::take(&mut self.built_materials);
        built.resize_with(self.objects.len(), || None);
        for (i, rec) in self.objects.iter().enumerate() {
            if rec.deleted || !rec.has_geometry() {
                continue;
            }
            let appearances = match &rec.parts {
                Some(parts) => &parts.appearances[..],
                None => std::slice::from_ref(&rec.appearance),
            };
            let first = materials.len() as u32;
            let bindings = || appearances.iter().flat_map(|a| [&a.surface, &a.interior, &a.displacement]).flatten();
            // Equal appearances name the same shaders, so the programs line up one for one.
            let reusable = built[i].as_ref().is_some_and(|b| {
                b.appearances == appearances
                    && b.programs
                        .iter()
                        .zip(bindings())
                        .all(|(was, binding)| self.program(binding.shader).is_ok_and(|is| Arc::ptr_eq(was, is)))
            });
            if !reusable {
                let programs = bindings().map(|b| self.program(b.shader).cloned()).collect::<Result<Vec<_>, _>>()?;
                let mut object_warnings = Vec::new();
                let built_now = appearances
                    .iter()
                    .map(|a| self.material_of(a, i as u32 + 1, &mut object_warnings))
                    .collect::<Result<Vec<_>, _>>()?;
                built[i] = Some(BuiltMaterials {
                    appearances: appearances.to_vec(),
                    programs,
                    materials: built_now,
                    warnings: object_warnings,
                });
            }
            if let Some(b) = &built[i] {
                materials.extend(b.materials.iter().cloned());
                for w in &b.warnings {
                    if !warnings.contains(w) {
                        warnings.push(w.clone());
                    }
                }
            }
            object_material[i] = first;
            if let Some(parts) = &rec.parts {
                let ids: Vec<u32> = (first..materials.len() as u32).collect();
                object_parts[i] = Some(InstanceParts { of_triangle: parts.of_triangle.clone(), materials: ids.into() });
            }
        }
        self.built_materials = built;
        scene.clear_instances();
        let mut instances = Vec::new();
        for inst in &self.instances {
            let rec = &self.objects[inst.object.0 as usize];
            let (Some(obj), false) = (rec.scene_object, inst.deleted || rec.deleted || !rec.has_geometry()) else {
                continue;
            };
            let (open, close) = self.options.shutter;
            match inst.close_transform {
                Some(end) if close > open => scene.add_moving_instance(obj, inst.transform, end, (open, close))?,
                _ => scene.add_instance(obj, inst.transform)?,
            };
            instances.push(InstanceShading {
                material: object_material[inst.object.0 as usize],
                object: obj.0,
                world_from_object: inst.transform,
                parts: object_parts[inst.object.0 as usize].clone(),
            });
        }
        let mut lights = Vec::new();
        for l in self.lights.iter().filter(|l| l.on) {
            let program = self.program(l.shader)?.clone();
            let binding =
                Binding { shader: l.shader, params: l.params.clone(), world_from_shader: l.world_from_shader };
            let inst = self.instance_for(&binding, &mut warnings)?;
            let categories = inst
                .string_param("__category")
                .map(|c| c.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect())
                .unwrap_or_default();
            let area = (!l.area_triangles.is_empty()).then(|| AreaLight::new(l.area_triangles.clone(), l.area_samples));
            let kind = if area.is_some() { LightKind::Local } else { program.light_kind };
            lights.push(LightSource { shader: Arc::new(inst), kind, shadows: l.shadows, categories, area });
        }
        let mut world = World::new(scene);
        world.accel.objects_rebuilt = objects_rebuilt;
        world.accel.object_bvhs = object_bvhs;
        world.materials = materials;
        world.instances = instances;
        world.lights = lights;
        world.pixel = self.pixel.as_ref().map(|b| self.instance_for(b, &mut warnings)).transpose()?.map(Arc::new);
        world.atmosphere =
            self.atmosphere.as_ref().map(|b| self.instance_for(b, &mut warnings)).transpose()?.map(Arc::new);
        world.camera = self.camera;
        world.camera_shader = match &self.camera_shader {
            Some(b) => {
                let mut inst = self.instance_for(b, &mut warnings)?;
                inst.world_from_shader = self.camera.world_from_camera;
                Some(Arc::new(inst))
            }
            None => None,
        };
        world.options = self.options.clone();
        world.spaces = self.spaces.clone();
        world.textures = self.textures.clone();
        world.prepare();
        for w in warnings {
            if !self.warnings.contains(&w) {
                self.warnings.push(w);
            }
        }
        Ok(world)
    }

    /// The material of an appearance, for an object with id `object_id` (1-based).
    fn material_of(&self, a: &Appearance, object_id: u32, warnings: &mut Vec<String>) -> Result<Material, ApiError> {
        let mut shader = |b: &Option<Binding>| -> Result<_, ApiError> {
            Ok(b.as_ref().map(|b| self.instance_for(b, warnings)).transpose()?.map(Arc::new))
        };
        Ok(Material {
            surface: shader(&a.surface)?,
            interior: shader(&a.interior)?,
            displacement: shader(&a.displacement)?,
            color: a.color,
            opacity: a.opacity,
            shadow_by_shader: a.shadow_by_shader,
            object_id,
            native: None,
        })
    }

    /// Takes back the scene of a world made by [`Context::build_world`], so the next frame reuses its
    /// object BVHs.
    pub fn return_scene(&mut self, world: World) {
        self.scene = Some(world.scene);
    }
}

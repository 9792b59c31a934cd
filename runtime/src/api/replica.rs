//! A [`Context`]'s scene copied into contexts elsewhere: the workers of a distributed render
//! (`crate::distributed`). A [`Replicator`] beside the application's context turns what changed
//! since its last update into bytes; [`Context::apply_update`] brings another context to the same
//! state, so that `build_world` there makes the world the application's context makes (the same
//! objects in the same order, the same materials, lights and options) and frames render
//! bit-identical.
//!
//! What travels:
//! - shader programs as compiled artifacts (checked IR and sources: the receiver runs only the JIT),
//!   when they first appear and whenever one is replaced (hot reload);
//! - objects (mesh, appearance, parts) when they are built, rebuilt or deleted. With
//!   [`Replicator::demand_loading`], an object's mesh stays behind: the update carries its summary
//!   (bounds, triangle count, attribute names) and the receiver fetches the mesh from its
//!   [`crate::accel::object::MeshSource`] when a ray first needs it (the paper's section 5.4:
//!   geometry no ray reaches is never sent);
//! - instances when they appear, move or go; the solids made of them with the frame's settings;
//! - the frame's settings (lights, pixel, camera and atmosphere shaders, camera, options,
//!   coordinate systems, texture search path) whenever any of them changes;
//! - with [`Replicator::demand_loading`], the instances the world truly displaces
//!   (`render/true_displacement.rs`) and the summaries of their displaced meshes, which the
//!   receiver fetches as it fetches objects (`render/remote_displacement.rs`): it cannot dice
//!   meshes it does not hold;
//! - textures and grids given in memory, whole; with [`Replicator::demand_loading`], only the news
//!   that they changed. Textures named by file are read by a receiver from its own file system, at
//!   the same paths, unless it has a [`crate::texture::TextureSource`]: a demand-loading receiver
//!   fetches every texture, shadow map and grid it looks up, file or memory, from the context it
//!   replicates ([`Context::deliver_texture`]).
//!
//! The building state (matrix and attribute stacks, the current appearance, an object being built)
//! stays behind: it is not part of what a frame renders. An update of a context that did not change
//! is empty.
//!
//! Contexts only grow (ids are never reused), so an update lists every record new since the last
//! one: a receiver checks that, and every id an update names, before it changes anything an index
//! could go wrong on. A damaged update is a [`ReplicaError`], never a panic.
//!
//! A replicator follows one context. Another context is another scene (a RIB file's next frame,
//! a scene loaded again), whose ids start from 0 again: its replicas start again from an empty
//! context, and the replicator with them ([`Replicator::restart`]), so that the next update
//! carries the new scene whole.

use super::{Appearance, Binding, Context, InstanceId, InstanceRecord, LightRecord, ObjectParts, ObjectRecord};
use crate::accel::bvh4::BuildQuality;
use crate::accel::object::{MeshSummary, ObjectBvh};
use crate::csg::Solid;
use crate::geometry::Mesh;
use crate::render::remote_displacement::AnnouncedMesh;
use crate::render::{CameraSetup, RenderOptions, World};
use crate::shading::{ParamValue, Program, ShaderError, ShaderProgram};
use crate::texture::{Delivered, TexImage, TextureKind, Wrap};
use glam::Affine3A;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

/// Why an update could not be applied.
#[derive(Debug, thiserror::Error)]
pub enum ReplicaError {
    #[error("a scene update cannot be decoded: {0}")]
    Undecodable(String),
    #[error("a scene update is inconsistent: {0}")]
    Inconsistent(String),
    #[error("shader {id} of a scene update: {error}")]
    Shader { id: u32, error: ShaderError },
    #[error("shader {0} cannot be encoded to send it")]
    Unencodable(String),
    #[error("object {id} of a scene update: {error}")]
    Mesh { id: u32, error: crate::geometry::MeshError },
}

/// Makes the updates of one context for the contexts that replicate it; keeps what it sent last
/// (sharing the meshes and programs, not copying them) to tell what changed since.
#[derive(Default)]
pub struct Replicator {
    /// Whether objects travel as summaries, their meshes fetched on demand.
    demand: bool,
    /// The context the updates so far were made of (none: no update yet).
    source: Option<u64>,
    programs: Vec<Option<Program>>,
    objects: Vec<SentObject>,
    instances: Vec<InstanceRecord>,
    settings: Option<Vec<u8>>,
    memory_changes: Option<u64>,
    /// The displaced instances last sent, and the displaced meshes by the master's scene object.
    displaced_instances: Vec<(u32, u32)>,
    displaced_meshes: HashMap<u32, Arc<Mesh>>,
}

#[derive(Clone, PartialEq)]
struct SentObject {
    /// The record's [`ObjectRecord::version`] when sent.
    version: u64,
    mesh: Option<Arc<Mesh>>,
    appearance: Appearance,
    parts: Option<ObjectParts>,
    deleted: bool,
}

impl SentObject {
    fn of(rec: &ObjectRecord) -> SentObject {
        SentObject {
            version: rec.version,
            mesh: rec.mesh.clone(),
            appearance: rec.appearance.clone(),
            parts: rec.parts.clone(),
            deleted: rec.deleted,
        }
    }

    /// Whether `rec` is what was sent: the same version (the same mesh, appearance and parts).
    fn is(&self, rec: &ObjectRecord) -> bool {
        let same = self.version == rec.version;
        debug_assert!(!same || self.same_contents(rec), "an object changed without a new version");
        same
    }

    /// Whether `rec` has the contents that were sent: the same mesh (by address: the kept `Arc`
    /// cannot be freed and its address reused), appearance and parts.
    fn same_contents(&self, rec: &ObjectRecord) -> bool {
        let same_mesh = match (&self.mesh, &rec.mesh) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        let same_parts = match (&self.parts, &rec.parts) {
            (Some(a), Some(b)) => Arc::ptr_eq(&a.of_triangle, &b.of_triangle) && a.appearances == b.appearances,
            (None, None) => true,
            _ => false,
        };
        same_mesh && same_parts && self.deleted == rec.deleted && self.appearance == rec.appearance
    }
}

#[derive(Serialize)]
struct UpdateOut<'a> {
    programs: Vec<(u32, Vec<u8>)>,
    program_count: u32,
    objects: Vec<(u32, ObjectOut<'a>)>,
    object_count: u32,
    instances: Vec<(u32, &'a InstanceRecord)>,
    instance_count: u32,
    settings: Option<&'a [u8]>,
    memory: Option<Memory>,
    displaced: Option<Displaced>,
}

#[derive(Deserialize)]
struct UpdateIn {
    programs: Vec<(u32, Vec<u8>)>,
    program_count: u32,
    objects: Vec<(u32, ObjectIn)>,
    object_count: u32,
    instances: Vec<(u32, InstanceRecord)>,
    instance_count: u32,
    settings: Option<Vec<u8>>,
    memory: Option<Memory>,
    displaced: Option<Displaced>,
}

/// The world's truly displaced instances (all of them), each with the master's scene object
/// holding its displaced mesh, and the displaced meshes the receiver was not sent yet.
#[derive(Serialize, Deserialize)]
struct Displaced {
    instances: Vec<(u32, u32)>,
    meshes: Vec<AnnouncedMesh>,
}

#[derive(Serialize)]
struct ObjectOut<'a> {
    mesh: Option<&'a Mesh>,
    summary: Option<MeshSummary>,
    appearance: &'a Appearance,
    parts: Option<&'a ObjectParts>,
    deleted: bool,
}

#[derive(Deserialize)]
struct ObjectIn {
    mesh: Option<Mesh>,
    summary: Option<MeshSummary>,
    appearance: Appearance,
    parts: Option<ObjectParts>,
    deleted: bool,
}

#[derive(Serialize)]
struct SettingsOut<'a> {
    lights: &'a [LightRecord],
    pixel: &'a Option<Binding>,
    camera_shader: &'a Option<Binding>,
    atmosphere: &'a Option<Binding>,
    camera: &'a CameraSetup,
    options: &'a RenderOptions,
    spaces: Vec<(&'a String, &'a Affine3A)>,
    texture_search_path: &'a [PathBuf],
    solids: &'a [Solid<InstanceId>],
}

#[derive(Deserialize)]
struct SettingsIn {
    lights: Vec<LightRecord>,
    pixel: Option<Binding>,
    camera_shader: Option<Binding>,
    atmosphere: Option<Binding>,
    camera: CameraSetup,
    options: RenderOptions,
    spaces: Vec<(String, Affine3A)>,
    texture_search_path: Vec<PathBuf>,
    solids: Vec<Solid<InstanceId>>,
}

/// Textures and grids given in memory: a texture as its size and values, a grid as its file's bytes.
#[derive(Serialize, Deserialize)]
struct Memory {
    textures: Vec<(String, [u32; 3], Vec<f32>)>,
    grids: Vec<(String, Vec<u8>)>,
}

fn encode<T: Serialize>(value: &T) -> Result<Vec<u8>, ReplicaError> {
    postcard::to_stdvec(value).map_err(|e| ReplicaError::Undecodable(e.to_string()))
}

fn count(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

impl Replicator {
    pub fn new() -> Replicator {
        Replicator::default()
    }

    /// A replicator whose updates carry objects' summaries instead of their meshes: the receiver
    /// fetches a mesh when a ray first needs it (see the module's notes).
    pub fn demand_loading() -> Replicator {
        Replicator { demand: true, ..Replicator::default() }
    }

    /// Whether the updates so far are of `rt` (or there were none): the next update of `rt` is
    /// then what changed since. Another context is another scene, whose records reuse the ids of
    /// this one's: its replicas start again from empty ([`Replicator::restart`]).
    pub fn follows(&self, rt: &Context) -> bool {
        self.source.is_none_or(|s| s == rt.identity)
    }

    /// Forgets what was sent, for replicas that start again from an empty context: the next
    /// update carries the whole of its context, whichever it is.
    pub fn restart(&mut self) {
        *self = Replicator { demand: self.demand, ..Replicator::default() };
    }

    /// What changed in `rt` since the last update (everything, the first time), as bytes for
    /// [`Context::apply_update`]; empty when nothing did. `world`, the world `rt` built last,
    /// gives demand-loaded objects the bounds of the BVHs built there, so that the receiver's
    /// top-level BVH is the same, and says which instances it truly displaced into which meshes.
    ///
    /// The updates of one replicator are of one context: an update of another is an error until
    /// [`Replicator::restart`] (see [`Replicator::follows`]).
    pub fn update(&mut self, rt: &Context, world: Option<&World>) -> Result<Vec<u8>, ReplicaError> {
        let scene = world.map(|w| &w.scene);
        if !self.follows(rt) {
            return Err(ReplicaError::Inconsistent(
                "an update of another context than the replicas follow (restart them first)".into(),
            ));
        }
        // First, so that a world that does not fit the context changes nothing.
        let displaced = match (self.demand, world) {
            (true, Some(world)) => self.displaced(rt, world)?,
            _ => None,
        };
        self.source = Some(rt.identity);
        let mut programs = Vec::new();
        self.programs.resize(rt.programs.len(), None);
        for (i, (sent, now)) in self.programs.iter_mut().zip(&rt.programs).enumerate() {
            let same = match (sent.as_ref(), now.as_ref()) {
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                (None, None) => true,
                _ => false,
            };
            if same {
                continue;
            }
            if let Some(p) = now {
                let bytes = p.artifact().ok_or_else(|| ReplicaError::Unencodable(p.name.clone()))?;
                programs.push((i as u32, bytes));
            }
            *sent = now.clone();
        }
        let mut objects = Vec::new();
        for (i, rec) in rt.objects.iter().enumerate() {
            if self.objects.get(i).is_some_and(|s| s.is(rec)) {
                continue;
            }
            let summary = match (&rec.mesh, self.demand) {
                (Some(mesh), true) => {
                    let built = rec.scene_object.and_then(|id| scene?.objects().get(id.0 as usize));
                    let summary = match built {
                        Some(object) => match object.resident_data() {
                            Some(data) => MeshSummary::of_tree(mesh, &data.bvh.bvh),
                            None => MeshSummary::of(mesh, object.bounds()),
                        },
                        None => MeshSummary::of(mesh, ObjectBvh::build(mesh, BuildQuality::High).bvh.bounds),
                    };
                    Some(summary)
                }
                _ => None,
            };
            objects.push((
                i as u32,
                ObjectOut {
                    mesh: if self.demand { None } else { rec.mesh.as_deref() },
                    summary,
                    appearance: &rec.appearance,
                    parts: rec.parts.as_ref(),
                    deleted: rec.deleted,
                },
            ));
            let sent = SentObject::of(rec);
            match self.objects.get_mut(i) {
                Some(s) => *s = sent,
                None => self.objects.push(sent),
            }
        }
        let mut instances = Vec::new();
        for (i, rec) in rt.instances.iter().enumerate() {
            if self.instances.get(i) == Some(rec) {
                continue;
            }
            instances.push((i as u32, rec));
            match self.instances.get_mut(i) {
                Some(s) => *s = rec.clone(),
                None => self.instances.push(rec.clone()),
            }
        }
        let mut spaces: Vec<(&String, &Affine3A)> = rt.spaces.iter().collect();
        spaces.sort_by(|a, b| a.0.cmp(b.0));
        let settings = encode(&SettingsOut {
            lights: &rt.lights,
            pixel: &rt.pixel,
            camera_shader: &rt.camera_shader,
            atmosphere: &rt.atmosphere,
            camera: &rt.camera,
            options: &rt.options,
            spaces,
            texture_search_path: &rt.texture_search_path,
            solids: &rt.solids,
        })?;
        let settings_changed = self.settings.as_ref() != Some(&settings);
        // With demand loading, memory textures and grids are fetched as files are: the update
        // says only that they changed.
        let sent_whole = !self.demand;
        let memory = (self.memory_changes != Some(rt.memory_changes)).then(|| Memory {
            textures: rt
                .memory_textures
                .iter()
                .filter(|_| sent_whole)
                .map(|(name, image)| {
                    let size = [image.width(), image.height(), image.channels()].map(count);
                    (name.clone(), size, image.data().to_vec())
                })
                .collect(),
            grids: rt
                .memory_grids
                .iter()
                .filter(|_| sent_whole)
                .map(|(name, grid)| (name.clone(), grid.to_bytes(crate::texture::grid::GridType::F32)))
                .collect(),
        });
        self.memory_changes = Some(rt.memory_changes);
        if programs.is_empty()
            && objects.is_empty()
            && instances.is_empty()
            && !settings_changed
            && memory.is_none()
            && displaced.is_none()
        {
            return Ok(Vec::new());
        }
        let bytes = encode(&UpdateOut {
            programs,
            program_count: count(rt.programs.len()),
            objects,
            object_count: count(rt.objects.len()),
            instances,
            instance_count: count(rt.instances.len()),
            settings: settings_changed.then_some(settings.as_slice()),
            memory,
            displaced,
        })?;
        self.settings = Some(settings);
        Ok(bytes)
    }
}

impl Replicator {
    /// The instances `world` (which `rt` built) truly displaces and the displaced meshes not sent
    /// yet, where they changed since the last update.
    fn displaced(&mut self, rt: &Context, world: &World) -> Result<Option<Displaced>, ReplicaError> {
        let placed: HashMap<u32, (&Arc<Mesh>, &[u32])> =
            rt.displaced.placed().map(|(object, mesh, per_source)| (object.0, (mesh, per_source))).collect();
        let instances: Vec<(u32, u32)> = world
            .instances
            .iter()
            .enumerate()
            .filter(|(_, inst)| inst.displaced)
            .map(|(i, inst)| (count(i), inst.object))
            .collect();
        let mut meshes = Vec::new();
        let mut sent = HashMap::new();
        for &(_, slot) in &instances {
            if sent.contains_key(&slot) {
                continue;
            }
            let object = crate::scene::ObjectId(slot);
            let mesh = world.scene.mesh(object);
            let Some((mesh, diced_at)) = placed.get(&slot).filter(|(m, _)| mesh.is_some_and(|w| Arc::ptr_eq(w, m)))
            else {
                return Err(ReplicaError::Inconsistent(format!(
                    "displaced object {slot} is not the one the context displaced (a world of another context?)"
                )));
            };
            if !self.displaced_meshes.get(&slot).is_some_and(|was| Arc::ptr_eq(was, mesh)) {
                let built = world.scene.objects().get(slot as usize).and_then(|o| o.resident_data());
                let summary = match built.filter(|data| Arc::ptr_eq(&data.mesh, mesh)) {
                    Some(data) => MeshSummary::of_tree(mesh, &data.bvh.bvh),
                    None => MeshSummary::of(mesh, ObjectBvh::build(mesh, BuildQuality::High).bvh.bounds),
                };
                meshes.push((slot, summary, diced_at.to_vec()));
            }
            sent.insert(slot, Arc::clone(mesh));
        }
        self.displaced_meshes = sent;
        if meshes.is_empty() && instances == self.displaced_instances {
            return Ok(None);
        }
        self.displaced_instances = instances.clone();
        Ok(Some(Displaced { instances, meshes }))
    }
}

/// Checks that an update's records cover every id new since the last (`old` of them) up to
/// `count`, and name no id beyond it.
fn check_ids(what: &str, old: usize, count: u32, ids: impl Iterator<Item = u32>) -> Result<(), ReplicaError> {
    let count = count as usize;
    if count < old {
        return Err(ReplicaError::Inconsistent(format!("{what}: {count} after {old}")));
    }
    let mut new = vec![false; count - old.min(count)];
    let mut listed = 0usize;
    for id in ids {
        let id = id as usize;
        if id >= count {
            return Err(ReplicaError::Inconsistent(format!("{what} {id} of {count}")));
        }
        listed += 1;
        if id >= old {
            new[id - old] = true;
        }
    }
    // Bounds the allocation above by what the update holds, not by what it claims.
    if count - old > listed || new.iter().any(|&seen| !seen) {
        return Err(ReplicaError::Inconsistent(format!("{what}: a new one is missing")));
    }
    Ok(())
}

impl Context {
    /// Brings this context's scene to the state of the context a [`Replicator`] made `update`
    /// from (see the module's notes); returns whether anything changed (an empty update changes
    /// nothing). On an error the context may hold part of the update; a replica that failed is
    /// not used again.
    pub fn apply_update(&mut self, update: &[u8]) -> Result<bool, ReplicaError> {
        if update.is_empty() {
            return Ok(false);
        }
        let u: UpdateIn = postcard::from_bytes(update).map_err(|e| ReplicaError::Undecodable(e.to_string()))?;
        check_ids("shaders", self.programs.len(), u.program_count, u.programs.iter().map(|(i, _)| *i))?;
        check_ids("objects", self.objects.len(), u.object_count, u.objects.iter().map(|(i, _)| *i))?;
        check_ids("instances", self.instances.len(), u.instance_count, u.instances.iter().map(|(i, _)| *i))?;
        let settings: Option<SettingsIn> = u
            .settings
            .as_deref()
            .map(postcard::from_bytes)
            .transpose()
            .map_err(|e| ReplicaError::Undecodable(e.to_string()))?;
        for (id, object) in &u.objects {
            check_object(*id, object)?;
        }
        if u.object_count >= crate::render::remote_displacement::DISPLACED_MESH_KEY {
            return Err(ReplicaError::Inconsistent(format!("{} objects", u.object_count)));
        }
        for solid in settings.iter().flat_map(|s| &s.solids) {
            solid.check().map_err(|e| ReplicaError::Inconsistent(e.to_string()))?;
            if let Some(bad) = solid.instances().find(|id| id.0 >= u.instance_count) {
                return Err(ReplicaError::Inconsistent(format!("a solid of instance {}", bad.0)));
            }
        }
        for (id, inst) in &u.instances {
            if inst.object.0 >= u.object_count {
                return Err(ReplicaError::Inconsistent(format!("instance {id} of object {}", inst.object.0)));
            }
        }

        self.programs.resize(u.program_count as usize, None);
        for (id, bytes) in u.programs {
            // The same artifact a context sharing this one's cache compiled (an earlier scene's).
            let cache = self.shader_cache.clone();
            let program = match cache.as_ref().and_then(|c| c.artifact(&bytes)) {
                Some(program) => program,
                None => {
                    let program = ShaderProgram::from_artifact_bytes(&format!("shader {id}"), &bytes)
                        .map_err(|error| ReplicaError::Shader { id, error })?;
                    let program = Arc::new(program);
                    if let Some(cache) = cache {
                        cache.insert_artifact(&bytes, &program);
                    }
                    program
                }
            };
            self.programs[id as usize] = Some(program);
        }
        self.objects.resize_with(u.object_count as usize, ObjectRecord::empty);
        for (id, o) in u.objects {
            let version = self.next_object_version();
            let rec = &mut self.objects[id as usize];
            rec.mesh = o.mesh.map(Arc::new);
            rec.remote = o.summary;
            rec.appearance = o.appearance;
            rec.parts = o.parts;
            rec.deleted = o.deleted;
            rec.dirty = true;
            rec.version = version;
        }
        let mut instances = u.instances.into_iter().peekable();
        let old = self.instances.len();
        for id in 0..u.instance_count as usize {
            match instances.next_if(|(i, _)| *i as usize == id) {
                Some((_, inst)) if id < old => self.instances[id] = inst,
                Some((_, inst)) => self.instances.push(inst),
                None => {}
            }
        }
        for (id, inst) in instances {
            // Out of order: still checked above.
            self.instances[id as usize] = inst;
        }
        if let Some(s) = settings {
            self.lights = s.lights;
            self.pixel = s.pixel;
            self.camera_shader = s.camera_shader;
            self.atmosphere = s.atmosphere;
            self.camera = s.camera;
            self.options = s.options;
            self.spaces = s.spaces.into_iter().collect();
            self.solids = s.solids;
            if s.texture_search_path != self.texture_search_path {
                self.texture_search_path = s.texture_search_path;
                self.renew_texture_cache();
            }
        }
        if let Some(m) = u.memory {
            self.memory_textures.clear();
            for (name, [w, h, c], data) in m.textures {
                let image = TexImage::new(w as usize, h as usize, c as usize, data)
                    .ok_or_else(|| ReplicaError::Inconsistent(format!("texture {name}: its size and values differ")))?;
                self.memory_textures.push((name, image));
            }
            self.memory_grids.clear();
            for (name, bytes) in m.grids {
                let grid = crate::texture::grid::Grid::parse(&bytes)
                    .map_err(|e| ReplicaError::Inconsistent(format!("grid {name}: {e}")))?;
                self.memory_grids.push((name, grid));
            }
            // Names fetched from a source may stand for something else now.
            self.renew_texture_cache();
        }
        if let Some(d) = u.displaced {
            self.remote_displaced.update(d.instances, d.meshes).map_err(ReplicaError::Inconsistent)?;
        }
        Ok(true)
    }

    pub(super) fn insert_memory_textures(&self) {
        for (name, image) in &self.memory_textures {
            self.textures.insert_texture(name, image.clone(), [Wrap::Periodic; 2]);
        }
        for (name, grid) in &self.memory_grids {
            self.textures.insert_grid(name, grid.clone());
        }
    }
}

/// What the renderer indexes by in an object: its mesh's indices and its parts' map.
fn check_object(id: u32, o: &ObjectIn) -> Result<(), ReplicaError> {
    if let Some(mesh) = &o.mesh {
        mesh.validate().map_err(|error| ReplicaError::Mesh { id, error })?;
    }
    if o.mesh.is_some() && o.summary.is_some() {
        return Err(ReplicaError::Inconsistent(format!("object {id} has both a mesh and a summary")));
    }
    if let Some(parts) = &o.parts {
        let triangles = match (&o.mesh, &o.summary) {
            (Some(m), _) => m.triangles.len(),
            (None, Some(s)) => s.triangles as usize,
            (None, None) => 0,
        };
        let n = parts.appearances.len();
        if parts.of_triangle.len() != triangles || parts.of_triangle.iter().any(|&p| p as usize >= n) {
            return Err(ReplicaError::Inconsistent(format!("object {id}: its parts do not match its triangles")));
        }
    }
    Ok(())
}

/// A mesh as a demand-loading master sends it.
pub fn encode_mesh(mesh: &Mesh) -> Vec<u8> {
    // Encoding a mesh into memory cannot fail: it holds nothing serde refuses.
    postcard::to_stdvec(mesh).unwrap_or_default()
}

/// A mesh [`encode_mesh`] wrote, checked (indices in range, attribute sizes).
pub fn decode_mesh(bytes: &[u8]) -> Result<Mesh, ReplicaError> {
    let mesh: Mesh = postcard::from_bytes(bytes).map_err(|e| ReplicaError::Undecodable(e.to_string()))?;
    mesh.validate().map_err(|error| ReplicaError::Mesh { id: u32::MAX, error })?;
    Ok(mesh)
}

impl Context {
    /// The strings that may name textures: every string parameter of the scene's shader
    /// bindings (objects' surfaces, interiors and displacements, lights, the pixel, camera and
    /// atmosphere shaders) and the alpha masks' textures, each once. A master decodes those that
    /// name textures ([`Context::delivers_texture`]) for its workers before they ask.
    pub fn texture_name_candidates(&self) -> Vec<&str> {
        fn strings(params: &[(String, ParamValue, Affine3A)]) -> impl Iterator<Item = &str> {
            params.iter().filter_map(|(_, value, _)| match value {
                ParamValue::String(name) => Some(name.as_str()),
                _ => None,
            })
        }
        let appearances = self
            .objects
            .iter()
            .filter(|o| !o.deleted)
            .flat_map(|object| {
                let parts = object.parts.as_ref().map_or(&[][..], |p| &p.appearances[..]);
                std::iter::once(&object.appearance).chain(parts)
            })
            .chain(self.instances.iter().filter(|i| !i.deleted).filter_map(|i| i.appearance.as_ref()));
        let mut names: Vec<&str> = Vec::new();
        for appearance in appearances {
            for binding in [&appearance.surface, &appearance.interior, &appearance.displacement].into_iter().flatten() {
                names.extend(strings(&binding.params));
            }
            names.extend(appearance.alpha_mask.as_ref().map(|(name, _)| name.as_str()));
        }
        for binding in [&self.pixel, &self.camera_shader, &self.atmosphere].into_iter().flatten() {
            names.extend(strings(&binding.params));
        }
        for light in &self.lights {
            names.extend(strings(&light.params));
        }
        names.retain(|n| !n.is_empty());
        names.sort_unstable();
        names.dedup();
        names
    }

    /// Whether `name` stands for a texture here: one given in memory, or a file on the texture
    /// search path.
    pub fn delivers_texture(&self, name: &str) -> bool {
        self.memory_textures.iter().any(|(n, _)| n == name) || self.textures.locate(name).is_ok()
    }

    /// What `name` stands for as a `kind`, for a replica's [`crate::texture::TextureSource`] to
    /// deliver: a texture or grid given in memory, else the bytes of the file the name resolves
    /// to on this context's search path, else why there is none (the warning a lookup here would
    /// give).
    pub fn deliver_texture(&self, kind: TextureKind, name: &str) -> Delivered {
        self.texture_delivery(kind, name).deliver()
    }

    /// [`Context::deliver_texture`] with the file, if it is one, still to read: a master reads
    /// it on another thread than the one that answers its workers.
    pub fn texture_delivery(&self, kind: TextureKind, name: &str) -> TextureDelivery {
        match kind {
            TextureKind::Texture => {
                if let Some((_, image)) = self.memory_textures.iter().find(|(n, _)| n == name) {
                    return TextureDelivery::Ready(Delivered::image(image));
                }
            }
            TextureKind::Grid => {
                if let Some((_, grid)) = self.memory_grids.iter().find(|(n, _)| n == name) {
                    let bytes = grid.to_bytes(crate::texture::grid::GridType::F32);
                    return TextureDelivery::Ready(Delivered::File { path: PathBuf::from(name), bytes });
                }
            }
            TextureKind::Shadow => {}
        }
        match self.textures.locate(name) {
            Ok(path) => TextureDelivery::File(path),
            Err(reason) => TextureDelivery::Ready(Delivered::Missing { path: None, reason }),
        }
    }
}

/// What a texture name stands for, the file (if it is one) not yet read
/// ([`Context::texture_delivery`]).
pub enum TextureDelivery {
    Ready(Delivered),
    File(PathBuf),
}

impl TextureDelivery {
    /// What the name stands for: the file's bytes read now, or why they cannot be.
    pub fn deliver(self) -> Delivered {
        let path = match self {
            TextureDelivery::Ready(delivered) => return delivered,
            TextureDelivery::File(path) => path,
        };
        let too_large = std::fs::metadata(&path).is_ok_and(|m| m.len() > MAX_DELIVERED_FILE_BYTES);
        if too_large {
            let reason = format!("larger than a worker fetches ({} MiB)", MAX_DELIVERED_FILE_BYTES >> 20);
            return Delivered::Missing { path: Some(path), reason };
        }
        match std::fs::read(&path) {
            Ok(bytes) => Delivered::File { path, bytes },
            Err(e) => Delivered::Missing { reason: e.to_string(), path: Some(path) },
        }
    }

    /// The bytes of the file to read, if it is a file that can be looked at.
    pub fn file_bytes(&self) -> Option<u64> {
        match self {
            TextureDelivery::Ready(_) => None,
            TextureDelivery::File(path) => std::fs::metadata(path).ok().map(|m| m.len()),
        }
    }
}

/// The largest file [`Context::deliver_texture`] sends: one message to one worker, and MPI counts
/// a message's bytes in 32 bits.
const MAX_DELIVERED_FILE_BYTES: u64 = 1 << 30;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_texture_names_a_scene_gives_are_its_shaders_string_parameters_and_alpha_masks() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        std::fs::write(dir.path().join("wood.tex"), b"not read here").expect("written");
        let mut rt = Context::new();
        rt.add_texture_search_path(dir.path());
        rt.tex_image_2d("in-memory", 1, 1, 3, &[0.5; 3]).expect("a texture");
        let paper = "surface paper(string texname = \"\"; string space = \"\"; float Kd = 1) { Ci = Kd; }";
        let paper = rt.compile_shader("paper", paper).expect("a shader");
        let object = |rt: &mut Context, params: &[(&str, ParamValue)]| {
            rt.begin_object().expect("an object");
            rt.bind_shader(paper).expect("bound");
            rt.parameters(params).expect("parameters");
            rt.begin(crate::api::Primitive::Triangles).expect("triangles");
            for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
                rt.vertex(p[0], p[1], p[2]).expect("a vertex");
            }
            rt.end().expect("end");
            rt.end_object().expect("end_object");
        };
        object(&mut rt, &[("texname", "wood.tex".into()), ("space", "world".into()), ("Kd", 0.5.into())]);
        rt.alpha_mask(Some("leaf.png"));
        object(&mut rt, &[("texname", "in-memory".into()), ("space", "".into())]);
        let light = rt.compile_shader("slide", "light slide(string slidename = \"\") { }").expect("a shader");
        rt.light_source(light, &[("slidename", "wood.tex".into())]).expect("a light");
        // Every string given, each once; whether it names a texture is for the master to ask.
        assert_eq!(rt.texture_name_candidates(), ["in-memory", "leaf.png", "wood.tex", "world"]);
        assert!(rt.delivers_texture("wood.tex") && rt.delivers_texture("in-memory"));
        assert!(!rt.delivers_texture("world") && !rt.delivers_texture("leaf.png"));
    }
}

//! Scenes from files: a RIB file, or a mesh file (OBJ with its materials, PLY, glTF 2.0) given on its
//! own, which gets a camera framing it and a default light rig.
//!
//! glTF: every mesh primitive (triangles) becomes an object, placed by each node that uses it with
//! the node's world transform (so shared meshes are instances of one BVH); the material's base
//! colour factor becomes `Cs`, its base colour texture (decoded by the importer, colour taken as
//! sRGB) an in-memory texture `FILE#imageN` that the `material` shader multiplies in. Alpha follows
//! `alphaMode`: `BLEND` makes the factor's alpha the transparency, `MASK` cuts the geometry where
//! the texture's alpha is below `alphaCutoff` ([`Context::alpha_mask_with_cutoff`]), `OPAQUE`
//! ignores alpha. Animations are not played here.
//!
//! OBJ materials become instances of the `material` shader (`docs/shaders.md`): `Kd` -> diffuse
//! colour, `Ks` -> specular colour, `Ns` -> shininess, `d`/`Tr` -> transparency, `Ke` -> emission,
//! `map_Kd` -> diffuse texture (resolved next to the OBJ file). The alpha of `map_d`, or else of
//! `map_Kd`, cuts the geometry where it is below one half ([`Context::alpha_mask`]), as alpha-tested
//! leaves and fences expect. Without materials every object gets
//! `plastic`. When a surface shader is already bound (a RIB `Surface` before `ReadArchive "x.obj"`),
//! it shades every object, with the material's diffuse colour as `Cs`.

use crate::api::{ApiError, Context, ObjectId};
use crate::geometry::{Mesh, MeshError};
use crate::mesh_io::{load_mesh, read_obj_reading, MeshIoError};
use crate::shading::ParamValue;
use glam::{Affine3A, Vec2, Vec3, Vec3A};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error("{path}: invalid mesh")]
    BadMesh { path: PathBuf, source: MeshError },
    #[error(transparent)]
    Api(#[from] ApiError),
    #[error("{path}: cannot load glTF file")]
    Gltf { path: PathBuf, source: gltf::Error },
    /// A limit that protects memory was passed; the load stops.
    #[error("{at}: {message}")]
    TooLarge { at: String, message: String },
    #[error("{path}: {message}")]
    InvalidGltf { path: PathBuf, message: String },
    /// A VRML file that could not be read, with its file, line and column (`crate::vrml`).
    #[error("{loc}: {message}")]
    Vrml { loc: crate::rib::Location, message: String },
    #[error("{path}: unknown scene file type (expected .rib, .obj, .ply, .gltf, .glb or .wrl)")]
    UnknownType { path: PathBuf },
    #[error("{path}: {message}")]
    Rib { path: PathBuf, message: String },
    #[error("{path}: a glTF file places its own instances, so it cannot be read into a retained object (ObjectBegin)")]
    NotRetainable { path: PathBuf },
}

/// The most triangles one model file (OBJ, PLY, glTF) may hold, its objects together: each
/// triangle takes the bytes of the file's data, so the file bounds them too, but loading one
/// costs far more than its bytes (its BVH above all). Four times a RIB load's
/// ([`crate::rib::MAX_RIB_TRIANGLES`]), whose text can ask for thousands a line.
pub const MAX_MODEL_TRIANGLES: usize = 1 << 26;

/// Whether a model file's `count` triangles are within [`MAX_MODEL_TRIANGLES`].
pub fn check_model_triangles(path: &Path, count: usize) -> Result<(), SceneFileError> {
    if count > MAX_MODEL_TRIANGLES {
        return Err(SceneFileError::TooLarge {
            at: path.display().to_string(),
            message: format!("{count} triangles: a model file may hold at most {MAX_MODEL_TRIANGLES}"),
        });
    }
    Ok(())
}

/// Adds a mesh file of any supported kind (by extension: `.obj`, `.ply`, `.gltf`, `.glb`).
pub fn add_model_file(rt: &mut Context, path: impl AsRef<Path>) -> Result<(Vec3A, Vec3A), SceneFileError> {
    let path = path.as_ref();
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("gltf" | "glb") => add_gltf(rt, path),
        Some("obj" | "ply") => add_mesh_file(rt, path),
        _ => Err(SceneFileError::UnknownType { path: path.to_path_buf() }),
    }
}

/// Where the objects made from a model file go.
pub enum Placement<'a> {
    /// Each object is instanced once, by the current matrix.
    Instanced,
    /// Retained objects in the space `frame` (the geometry placed by the current matrix relative
    /// to it), not instanced; their ids are appended to `objects`. This is how one RIB
    /// `ObjectBegin` block holds a model with several materials.
    Retained { frame: Affine3A, objects: &'a mut Vec<ObjectId> },
}

impl Placement<'_> {
    fn begin(&self, rt: &mut Context) -> Result<ObjectId, ApiError> {
        match self {
            Placement::Instanced => rt.begin_object(),
            Placement::Retained { frame, .. } => rt.begin_object_in(*frame),
        }
    }

    fn place(&mut self, rt: &mut Context, object: ObjectId) -> Result<(), ApiError> {
        match self {
            Placement::Instanced => rt.instantiate_object(object).map(drop),
            Placement::Retained { objects, .. } => {
                objects.push(object);
                Ok(())
            }
        }
    }
}

/// Adds an OBJ or PLY file's objects to the context as `placement` says, returning the world-space
/// bounds of what was added (as placed by the current matrix). glTF files, whose nodes place their
/// own instances, are only [`Placement::Instanced`].
pub fn add_model_file_placed(
    rt: &mut Context,
    path: &Path,
    placement: Placement,
) -> Result<(Vec3A, Vec3A), SceneFileError> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("gltf" | "glb") if matches!(placement, Placement::Instanced) => add_gltf(rt, path),
        Some("gltf" | "glb") => Err(SceneFileError::NotRetainable { path: path.to_path_buf() }),
        Some("obj" | "ply") => add_mesh_file_placed(rt, path, placement),
        _ => Err(SceneFileError::UnknownType { path: path.to_path_buf() }),
    }
}

/// Adds the meshes of a glTF 2.0 file (`.gltf` with its buffers, or `.glb`) to the context, under
/// the current matrix, and returns the world-space bounds of what was added.
pub fn add_gltf_file(rt: &mut Context, path: impl AsRef<Path>) -> Result<(Vec3A, Vec3A), SceneFileError> {
    add_gltf(rt, path.as_ref())
}

// One copy of the reader whatever path type callers use.
fn add_gltf(rt: &mut Context, path: &Path) -> Result<(Vec3A, Vec3A), SceneFileError> {
    let (doc, buffers, images) = import_gltf(path)?;
    // Images become in-memory textures named after the file, made when a material first uses one.
    let image_name = |i: usize| format!("{}#image{i}", path.display());
    let mut made = vec![false; images.len()];
    let bad = |source: MeshError| SceneFileError::BadMesh { path: path.to_path_buf(), source };
    let bound = rt.bound_surface();
    let shader = match bound {
        Some(s) => s,
        None => rt.find_shader("material")?,
    };
    // Counted from the accessors (checked against their buffers), before any is read.
    let triangles = doc
        .meshes()
        .flat_map(|m| m.primitives())
        .filter(|p| p.mode() == gltf::mesh::Mode::Triangles)
        .map(|p| p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count() / 3))
        .fold(0, usize::saturating_add);
    check_model_triangles(path, triangles)?;
    // Objects per (mesh, primitive), made once.
    let mut objects: Vec<Vec<Option<crate::api::ObjectId>>> = Vec::new();
    for mesh in doc.meshes() {
        let mut prims = Vec::new();
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                prims.push(None);
                continue;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let Some(positions) = reader.read_positions() else {
                prims.push(None);
                continue;
            };
            let positions: Vec<Vec3> = positions.map(Vec3::from).collect();
            let triangles: Vec<[u32; 3]> = match reader.read_indices() {
                Some(ix) => {
                    let ix: Vec<u32> = ix.into_u32().collect();
                    ix.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
                }
                None => (0..positions.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
            };
            let count = positions.len();
            let mut m = Mesh::from_triangles(positions, triangles).map_err(bad)?;
            if let Some(ns) = reader.read_normals() {
                let ns: Vec<Vec3> = ns.map(Vec3::from).collect();
                if ns.len() == count {
                    m.normals = Some(ns);
                }
            }
            if let Some(uv) = reader.read_tex_coords(0) {
                // glTF's texture coordinates already have t growing downwards, as RenderMan's.
                let uv: Vec<Vec2> = uv.into_f32().map(Vec2::from).collect();
                if uv.len() == count {
                    m.uvs = Some(uv);
                }
            }
            let material = prim.material();
            let base = material.pbr_metallic_roughness().base_color_factor();
            let texture = material.pbr_metallic_roughness().base_color_texture().map(|t| t.texture().source().index());
            let texture = texture.filter(|&i| {
                if !made.get(i).copied().unwrap_or(true) {
                    made[i] = gltf_texture(rt, &image_name(i), &images[i]);
                }
                made.get(i).copied().unwrap_or(false)
            });
            rt.push_attributes();
            rt.bind_shader(shader)?;
            if bound.is_none() {
                let _ = rt.parameter("diffusecolor", ParamValue::Color([1.0; 3]));
                // Only BLEND blends; OPAQUE and MASK ignore the alpha factor.
                if material.alpha_mode() == gltf::material::AlphaMode::Blend {
                    let _ = rt.parameter("transparency", ParamValue::Float((1.0 - base[3]).clamp(0.0, 1.0)));
                }
                if let Some(i) = texture {
                    let _ = rt.parameter("texturename", ParamValue::String(image_name(i)));
                }
            }
            if let (gltf::material::AlphaMode::Mask, Some(i)) = (material.alpha_mode(), texture) {
                rt.alpha_mask_with_cutoff(Some(&image_name(i)), material.alpha_cutoff().unwrap_or(0.5));
            }
            rt.color(base[0], base[1], base[2]);
            let o = rt.begin_object()?;
            rt.mesh(&m)?;
            rt.end_object()?;
            rt.pop_attributes()?;
            prims.push(Some(o));
        }
        objects.push(prims);
    }
    let mut bounds = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
    let root = rt.current_matrix();
    // Checked to be trees of bounded depth, so the walk below ends and needs no recursion limit.
    let tops = gltf_hierarchy(path, &doc)?;
    let mut stack: Vec<(gltf::Node, glam::Affine3A)> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| (n, root)).collect(),
        // Without a scene every tree is placed, each once from its top.
        None => doc.nodes().filter(|n| tops.get(n.index()).copied().unwrap_or(false)).map(|n| (n, root)).collect(),
    };
    while let Some((node, parent)) = stack.pop() {
        let local = glam::Affine3A::from_mat4(glam::Mat4::from_cols_array_2d(&node.transform().matrix()));
        let xf = parent * local;
        if let Some(mesh) = node.mesh() {
            for (k, o) in objects.get(mesh.index()).into_iter().flatten().enumerate() {
                let Some(o) = o else { continue };
                rt.load_matrix(xf);
                rt.instantiate_object(*o)?;
                if let Some(prim) = mesh.primitives().nth(k) {
                    let bb = prim.bounding_box();
                    for corner in 0..8 {
                        let c = Vec3::new(
                            if corner & 1 == 0 { bb.min[0] } else { bb.max[0] },
                            if corner & 2 == 0 { bb.min[1] } else { bb.max[1] },
                            if corner & 4 == 0 { bb.min[2] } else { bb.max[2] },
                        );
                        let w = xf.transform_point3a(c.into());
                        bounds = (bounds.0.min(w), bounds.1.max(w));
                    }
                }
            }
        }
        stack.extend(node.children().map(|c| (c, xf)));
    }
    rt.load_matrix(root);
    Ok(bounds)
}

/// How deeply glTF nodes may nest: deeper hierarchies are refused, so that nothing that walks
/// one (here or in a library) runs out of stack.
pub const MAX_GLTF_NODE_DEPTH: usize = 1024;

/// A glTF document with its buffers' and images' data.
type GltfImport = (gltf::Document, Vec<gltf::buffer::Data>, Vec<gltf::image::Data>);

/// Reads a glTF file and the buffers and images it refers to, refusing external files outside the
/// model's folder and accessors that claim more data than their buffers hold. A panic in the glTF
/// library (it has had two on malformed files, both checked for before it reads now) is an error
/// about the file, as a panicking image decoder's is (`image_io`).
fn import_gltf(path: &Path) -> Result<GltfImport, SceneFileError> {
    std::panic::catch_unwind(|| import_gltf_checked(path)).unwrap_or_else(|_| {
        let message = "the glTF library panicked reading it".to_string();
        Err(SceneFileError::InvalidGltf { path: path.to_path_buf(), message })
    })
}

/// [`import_gltf`] without the guard against the library's panics.
fn import_gltf_checked(path: &Path) -> Result<GltfImport, SceneFileError> {
    let gltf_err = |source| SceneFileError::Gltf { path: path.to_path_buf(), source };
    let invalid = |message: String| SceneFileError::InvalidGltf { path: path.to_path_buf(), message };
    let data = std::fs::read(path).map_err(|e| gltf_err(gltf::Error::Io(e)))?;
    check_glb_length(&data).map_err(invalid)?;
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(&data).map_err(gltf_err)?;
    // gltf-json's validation reads a primitive's POSITION accessor before it checks that the
    // accessor exists, and panics on an index past the list: checked here first.
    check_gltf_position_accessors(document.as_json()).map_err(invalid)?;
    let document = gltf::Document::from_json(document.into_json()).map_err(gltf_err)?;
    let uris = document
        .buffers()
        .filter_map(|b| match b.source() {
            gltf::buffer::Source::Uri(uri) => Some(("buffer", b.index(), uri)),
            gltf::buffer::Source::Bin => None,
        })
        .chain(document.images().filter_map(|i| match i.source() {
            gltf::image::Source::Uri { uri, .. } => Some(("image", i.index(), uri)),
            gltf::image::Source::View { .. } => None,
        }));
    for (what, index, uri) in uris {
        if let Err(why) = check_gltf_uri(uri) {
            return Err(invalid(format!("{what} {index}: uri \"{uri}\" {why}")));
        }
    }
    let base = path.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let buffers = gltf::import_buffers(&document, Some(&base), blob).map_err(gltf_err)?;
    check_gltf_accessors(&document, &buffers).map_err(invalid)?;
    let images = gltf::import_images(&document, Some(&base), &buffers).map_err(gltf_err)?;
    Ok((document, buffers, images))
}

/// The size of a binary glTF (GLB) file's header: magic, version, total length.
const GLB_HEADER_BYTES: usize = 12;

/// Checks the total length a GLB file's header gives (files that do not start with the GLB magic
/// are JSON, and pass): the glTF library subtracts the header's size from it unchecked, and sizes
/// a buffer by it when it reads from a stream.
fn check_glb_length(data: &[u8]) -> Result<(), String> {
    if !data.starts_with(b"glTF") {
        return Ok(());
    }
    let Some(length) = data.get(8..GLB_HEADER_BYTES) else {
        return Err(format!("the GLB header is cut short: {} bytes of {GLB_HEADER_BYTES}", data.len()));
    };
    let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
    if length < GLB_HEADER_BYTES || length > data.len() {
        return Err(format!("the GLB header gives a length of {length} bytes, but the file has {}", data.len()));
    }
    Ok(())
}

/// An error naming the first mesh primitive whose POSITION names an accessor the file lacks.
fn check_gltf_position_accessors(root: &gltf::json::Root) -> Result<(), String> {
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position).filter(|i| i.value() >= accessors) {
                return Err(format!(
                    "mesh {m}, primitive {p}: POSITION is accessor {}, but the file has {accessors} accessors",
                    index.value()
                ));
            }
        }
    }
    Ok(())
}

/// Why a glTF file's `uri` is not read: only data URIs and relative paths that stay inside the
/// model's folder are. (The importer would read any absolute path or `file:` URI, and panics on a
/// percent-escape that does not decode to UTF-8.)
fn check_gltf_uri(uri: &str) -> Result<(), &'static str> {
    if uri.starts_with("data:") {
        return Ok(());
    }
    if uri.contains(':') {
        return Err("is not a data URI or a relative path");
    }
    match decode_relative_path(uri) {
        Ok(_) => {}
        Err(PathRefusal::MalformedEscape) => return Err("has a malformed percent-escape"),
        Err(PathRefusal::NotUtf8) => return Err("does not decode to UTF-8"),
        Err(PathRefusal::LeavesFolder) => return Err("leads out of the model's folder"),
        Err(PathRefusal::Absolute) => {
            return Err("is an absolute path; only paths relative to the model's folder are read")
        }
    }
    Ok(())
}

/// Why a path named inside a scene file (a glTF `uri`, a VRML `url`) is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PathRefusal {
    /// A `%` not followed by two hexadecimal digits.
    MalformedEscape,
    /// The decoded bytes are not UTF-8.
    NotUtf8,
    /// Its `..`s climb above the folder it is relative to.
    LeavesFolder,
    /// It starts at a root or a drive.
    Absolute,
}

/// A URL-style path with its `%XX` escapes decoded, refused unless it stays inside the folder it
/// is relative to.
pub(crate) fn decode_relative_path(encoded: &str) -> Result<PathBuf, PathRefusal> {
    let mut bytes = Vec::with_capacity(encoded.len());
    let mut rest = encoded.as_bytes();
    while let Some((&b, tail)) = rest.split_first() {
        if b == b'%' {
            let hex = tail.get(..2).and_then(|h| std::str::from_utf8(h).ok());
            let value = hex.and_then(|h| u8::from_str_radix(h, 16).ok()).ok_or(PathRefusal::MalformedEscape)?;
            bytes.push(value);
            rest = &tail[2..];
        } else {
            bytes.push(b);
            rest = tail;
        }
    }
    let path = PathBuf::from(String::from_utf8(bytes).map_err(|_| PathRefusal::NotUtf8)?);
    let mut depth = 0usize;
    for part in path.components() {
        match part {
            std::path::Component::Normal(_) => depth += 1,
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => depth = depth.checked_sub(1).ok_or(PathRefusal::LeavesFolder)?,
            std::path::Component::RootDir | std::path::Component::Prefix(_) => return Err(PathRefusal::Absolute),
        }
    }
    Ok(path)
}

/// Checks that every accessor's elements lie inside its buffer view, and the view inside its
/// buffer's data, so that no count in the file makes the reader invent or allocate data.
fn check_gltf_accessors(doc: &gltf::Document, buffers: &[gltf::buffer::Data]) -> Result<(), String> {
    let view_end = |view: &gltf::buffer::View| -> Result<u64, String> {
        let end = view.offset() as u64 + view.length() as u64;
        let data = buffers.get(view.buffer().index()).map_or(0, |d| d.0.len() as u64);
        if end > data {
            return Err(format!("buffer view {} ends at byte {end}, past its buffer's {data} bytes", view.index()));
        }
        Ok(end)
    };
    // The bytes `count` elements of `size` bytes take from `offset` into `view`, strided as the view says.
    let fits = |view: &gltf::buffer::View, offset: usize, count: usize, size: usize| -> Result<bool, String> {
        view_end(view)?;
        if count == 0 {
            return Ok(true);
        }
        let stride = view.stride().unwrap_or(size).max(size) as u64;
        let needed = (count as u64 - 1).checked_mul(stride).and_then(|n| n.checked_add(offset as u64 + size as u64));
        Ok(needed.is_some_and(|n| n <= view.length() as u64))
    };
    let total: u64 = buffers.iter().map(|d| d.0.len() as u64).sum();
    for a in doc.accessors() {
        let (count, size) = (a.count(), a.size());
        match a.view() {
            Some(view) if !fits(&view, a.offset(), count, size)? => {
                return Err(format!(
                    "accessor {} claims {count} elements of {size} bytes, more than buffer view {} holds ({} bytes)",
                    a.index(),
                    view.index(),
                    view.length()
                ));
            }
            Some(_) => {}
            // Without a view the elements are zeros the reader makes up: no more than the file's
            // data could plausibly describe.
            None if count as u64 > total => {
                return Err(format!(
                    "accessor {} claims {count} elements but has no buffer view (and the buffers hold {total} bytes)",
                    a.index()
                ));
            }
            None => {}
        }
        if let Some(sparse) = a.sparse() {
            let (indices, values) = (sparse.indices(), sparse.values());
            // At least a byte an index: `index_type` panics on a component type that is not an
            // integer, so the file's own type is not asked for.
            let index_size = 1;
            if sparse.count() > count
                || !fits(&indices.view(), indices.offset(), sparse.count(), index_size)?
                || !fits(&values.view(), values.offset(), sparse.count(), size)?
            {
                return Err(format!(
                    "accessor {}'s {} sparse elements do not fit their buffer views",
                    a.index(),
                    sparse.count()
                ));
            }
        }
    }
    Ok(())
}

/// Which of a glTF file's nodes are tops of its hierarchy, after checking that it is a set of trees (no node is
/// the child of two nodes, or its own ancestor) no deeper than [`MAX_GLTF_NODE_DEPTH`].
fn gltf_hierarchy(path: &Path, doc: &gltf::Document) -> Result<Vec<bool>, SceneFileError> {
    let invalid = |message: String| SceneFileError::InvalidGltf { path: path.to_path_buf(), message };
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let count = nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; count];
    for node in doc.nodes() {
        for child in node.children() {
            let c = child.index();
            if c == node.index() {
                return Err(invalid(format!("node {c} lists itself as a child")));
            }
            match parent.get_mut(c) {
                Some(Some(first)) => {
                    return Err(invalid(format!("node {c} is a child of both node {first} and node {}", node.index())))
                }
                Some(slot) => *slot = Some(node.index()),
                None => return Err(invalid(format!("node {} has a child {c} that does not exist", node.index()))),
            }
        }
    }
    let tops: Vec<usize> = (0..count).filter(|&n| parent[n].is_none()).collect();
    let mut seen = vec![false; count];
    let mut stack: Vec<(usize, usize)> = tops.iter().map(|&n| (n, 1)).collect();
    while let Some((n, depth)) = stack.pop() {
        if depth > MAX_GLTF_NODE_DEPTH {
            return Err(invalid(format!("nodes nest deeper than {MAX_GLTF_NODE_DEPTH} levels (at node {n})")));
        }
        seen[n] = true;
        if let Some(node) = nodes.get(n) {
            stack.extend(node.children().map(|c| (c.index(), depth + 1)));
        }
    }
    // Every node has at most one parent, so one not reached from a top is on a cycle or under one.
    if let Some(n) = seen.iter().position(|&s| !s) {
        return Err(invalid(format!("node {n} is its own ancestor (the children form a cycle)")));
    }
    let mut is_top = vec![false; count];
    for n in tops {
        is_top[n] = true;
    }
    Ok(is_top)
}

/// Adds the meshes of `path` (OBJ or PLY) to the context, each as an object instanced once at the
/// current matrix, and returns the world-space bounds of what was added.
pub fn add_mesh_file(rt: &mut Context, path: impl AsRef<Path>) -> Result<(Vec3A, Vec3A), SceneFileError> {
    let path = path.as_ref();
    add_mesh_file_placed(rt, path, Placement::Instanced)
}

fn add_mesh_file_placed(
    rt: &mut Context,
    path: &Path,
    mut placement: Placement,
) -> Result<(Vec3A, Vec3A), SceneFileError> {
    let is_obj = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let mut bounds = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
    let mut grow = |rt: &Context, mesh: &Mesh| {
        let m = rt.current_matrix();
        for p in &mesh.positions {
            let w = m.transform_point3a(Vec3A::from(*p));
            bounds.0 = bounds.0.min(w);
            bounds.1 = bounds.1.max(w);
        }
    };
    let bound = rt.bound_surface();
    if !is_obj {
        let mesh = shared_model(rt, path, "mesh file", || {
            let mesh = load_mesh(path)?;
            check_model_triangles(path, mesh.triangles.len())?;
            Ok((mesh, Vec::new()))
        })?;
        grow(rt, &mesh);
        let shader = match bound {
            Some(s) => s,
            None => rt.find_shader("plastic")?,
        };
        rt.push_attributes();
        if bound.is_none() {
            rt.bind_shader(shader)?;
        }
        let o = placement.begin(rt)?;
        rt.mesh(&mesh)?;
        rt.end_object()?;
        placement.place(rt, o)?;
        rt.pop_attributes()?;
        return Ok(bounds);
    }
    // A missing .mtl file leaves the objects without materials (plastic); a malformed one is an error.
    let model = shared_model(rt, path, "obj model", || {
        let (models, materials, libraries) = read_obj_reading(path, true)?;
        check_model_triangles(path, models.iter().map(|m| m.mesh.indices.len() / 3).fold(0, usize::saturating_add))?;
        let meshes = obj_meshes_by_material(path, &models)?;
        Ok(((meshes, materials), libraries))
    })?;
    let (meshes, materials) = &*model;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let plastic = rt.find_shader("plastic")?;
    let material_shader = if materials.is_empty() || bound.is_some() { None } else { rt.find_shader("material").ok() };
    let plastic = bound.unwrap_or(plastic);
    for (material_id, mesh) in meshes {
        grow(rt, mesh);
        rt.push_attributes();
        let material = material_id.and_then(|i| materials.get(i));
        // Cut-outs (leaves on quads): the alpha of `map_d`, else of `map_Kd` where it has any.
        if let Some(tex) = material.and_then(|mat| mat.dissolve_texture.as_ref().or(mat.diffuse_texture.as_ref())) {
            rt.alpha_mask(Some(&dir.join(tex.replace('\\', "/")).display().to_string()));
        }
        match (material, material_shader) {
            (Some(mat), Some(shader)) => {
                rt.bind_shader(shader)?;
                bind_obj_material(rt, mat, &dir);
                if mat.dissolve.is_some_and(|d| d < 1.0) {
                    rt.shadows_from_shader(true);
                }
            }
            (Some(mat), None) => {
                if bound.is_none() {
                    rt.bind_shader(plastic)?;
                }
                if let Some(kd) = mat.diffuse {
                    rt.color(kd[0], kd[1], kd[2]);
                }
            }
            (None, _) => {
                if bound.is_none() {
                    rt.bind_shader(plastic)?;
                }
            }
        }
        let o = placement.begin(rt)?;
        rt.mesh(mesh)?;
        rt.end_object()?;
        placement.place(rt, o)?;
        rt.pop_attributes()?;
    }
    Ok(bounds)
}

/// What `load` makes of model file `path` (and says it read besides): taken from what the context
/// shares with others ([`Context::share_files`]) while those files are unchanged, so that the
/// frames of a render read a model file once.
fn shared_model<T: std::any::Any + Send + Sync>(
    rt: &Context,
    path: &Path,
    variant: &'static str,
    load: impl FnOnce() -> Result<(T, Vec<PathBuf>), SceneFileError>,
) -> Result<Arc<T>, SceneFileError> {
    match rt.shared_files() {
        Some(shared) => shared.get_or_load_reading(path, variant, load),
        None => load().map(|(value, _)| Arc::new(value)),
    }
}

/// The meshes of an OBJ file's models, those of one material merged into one mesh (in the order
/// the materials first appear). An object per OBJ group would give the tracer a top-level BVH
/// over overlapping objects, each entered on its own, where one object is entered once (the
/// Dabrovic Sponza's 34 groups, of one material, overlap throughout its atrium). Groups whose meshes differ in
/// having normals or texture coordinates stay apart, so no vertex gets made-up values.
fn obj_meshes_by_material(path: &Path, models: &[tobj::Model]) -> Result<Vec<(Option<usize>, Mesh)>, SceneFileError> {
    let mut merged: Vec<(Option<usize>, Mesh)> = Vec::new();
    for model in models {
        let m = &model.mesh;
        if m.indices.is_empty() {
            continue;
        }
        let positions: Vec<Vec3> = m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])).collect();
        let triangles: Vec<[u32; 3]> = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let mut mesh = Mesh::from_triangles(positions, triangles)
            .map_err(|source| SceneFileError::BadMesh { path: path.to_path_buf(), source })?;
        if m.normals.len() == m.positions.len() {
            mesh.normals = Some(m.normals.chunks_exact(3).map(|n| Vec3::new(n[0], n[1], n[2])).collect());
        }
        if m.texcoords.len() / 2 == m.positions.len() / 3 {
            // OBJ's v grows upwards; RenderMan's t grows downwards.
            mesh.uvs = Some(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], 1.0 - t[1])).collect());
        }
        let same = |(id, into): &(Option<usize>, Mesh)| {
            *id == m.material_id
                && into.normals.is_some() == mesh.normals.is_some()
                && into.uvs.is_some() == mesh.uvs.is_some()
        };
        match merged.iter_mut().find(|entry| same(entry)) {
            Some((_, into)) => append_mesh(into, mesh),
            None => merged.push((m.material_id, mesh)),
        }
    }
    Ok(merged)
}

/// Appends `mesh`'s vertices and triangles to `into` (both without further attributes, with normals
/// and texture coordinates alike).
fn append_mesh(into: &mut Mesh, mesh: Mesh) {
    let base = into.positions.len() as u32;
    into.positions.extend(mesh.positions);
    into.triangles.extend(mesh.triangles.into_iter().map(|t| t.map(|i| i + base)));
    if let (Some(a), Some(b)) = (into.normals.as_mut(), mesh.normals) {
        a.extend(b);
    }
    if let (Some(a), Some(b)) = (into.uvs.as_mut(), mesh.uvs) {
        a.extend(b);
    }
}

/// Makes a glTF image the in-memory texture `name`: 8- and 16-bit colour channels are sRGB (a base
/// colour texture), alpha is linear, floats are taken as they are. Returns whether it was made.
fn gltf_texture(rt: &mut Context, name: &str, image: &gltf::image::Data) -> bool {
    use gltf::image::Format as F;
    let (channels, bytes) = match image.format {
        F::R8 => (1, 1),
        F::R8G8 => (2, 1),
        F::R8G8B8 => (3, 1),
        F::R8G8B8A8 => (4, 1),
        F::R16 => (1, 2),
        F::R16G16 => (2, 2),
        F::R16G16B16 => (3, 2),
        F::R16G16B16A16 => (4, 2),
        F::R32G32B32FLOAT => (3, 4),
        F::R32G32B32A32FLOAT => (4, 4),
    };
    let values: Vec<f32> = match bytes {
        1 => image.pixels.iter().map(|&b| f32::from(b) / 255.0).collect(),
        2 => image.pixels.chunks_exact(2).map(|b| f32::from(u16::from_ne_bytes([b[0], b[1]])) / 65535.0).collect(),
        _ => image.pixels.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect(),
    };
    let alpha = |c: usize| (channels == 2 || channels == 4) && c == channels - 1;
    let texels: Vec<f32> = if bytes == 4 {
        values
    } else {
        values
            .iter()
            .enumerate()
            .map(|(i, &v)| if alpha(i % channels) { v } else { crate::texture::srgb_to_linear(v) })
            .collect()
    };
    rt.tex_image_2d(name, image.width as usize, image.height as usize, channels, &texels).is_ok()
}

/// Binds the parameters of the `material` shader that the OBJ material gives; a parameter the shader
/// lacks is skipped (the library's shader defines them all).
fn bind_obj_material(rt: &mut Context, mat: &tobj::Material, dir: &Path) {
    let mut set = |name: &str, v: ParamValue| {
        let _ = rt.parameter(name, v);
    };
    if let Some(kd) = mat.diffuse {
        set("diffusecolor", ParamValue::Color(kd));
    }
    if let Some(ks) = mat.specular {
        set("specularcolor", ParamValue::Color(ks));
    }
    if let Some(ns) = mat.shininess {
        // OBJ's exponent is 0..1000; VRML's shininess is 0..1 (exponent = 128 * shininess).
        set("shininess", ParamValue::Float((ns / 128.0).clamp(0.0, 1.0)));
    }
    if let Some(d) = mat.dissolve {
        set("transparency", ParamValue::Float((1.0 - d).clamp(0.0, 1.0)));
    }
    if let Some(ke) = mat.unknown_param.get("Ke").and_then(|s| parse3(s)) {
        set("emissivecolor", ParamValue::Color(ke));
    }
    if let Some(tex) = &mat.diffuse_texture {
        set("texturename", ParamValue::String(dir.join(tex.replace('\\', "/")).display().to_string()));
    }
}

fn parse3(s: &str) -> Option<[f32; 3]> {
    let v: Vec<f32> = s.split_whitespace().filter_map(|x| x.parse().ok()).collect();
    (v.len() == 3).then(|| [v[0], v[1], v[2]])
}

/// Points the camera at the box `bounds` from the front (+z) and a little above, far enough back
/// for the box to fill the view; returns the box's centre and the camera's distance from it
/// (`None`, the camera unchanged, for an empty or infinite box).
pub fn frame_camera(rt: &mut Context, bounds: (Vec3A, Vec3A)) -> Option<(Vec3A, f32)> {
    let (lo, hi) = bounds;
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let center = (lo + hi) * 0.5;
    let size = hi - lo;
    let radius = 0.5 * size.length().max(1e-3);
    let fov: f32 = 40.0;
    let distance = radius / (fov.to_radians() * 0.5).sin();
    let eye = center + Vec3A::new(0.0, 0.15, 1.0).normalize() * distance;
    rt.camera_look_at(eye, center, Vec3A::Y, fov);
    Some((center, distance))
}

/// A camera looking at the box `bounds` from the front (+z) and a little above, and a light rig: a
/// shadowed key light above and to the right of the camera, and a dim ambient light. (Interiors,
/// which such a rig cannot light, come as RIB files with their own lights.)
pub fn frame_bounds(rt: &mut Context, bounds: (Vec3A, Vec3A)) -> Result<(), ApiError> {
    let Some((center, distance)) = frame_camera(rt, bounds) else { return Ok(()) };
    let point = rt.find_shader("pointlight")?;
    let ambient = rt.find_shader("ambientlight")?;
    let from = center + Vec3A::new(0.5, 1.2, 0.9) * distance;
    let to_light = (from - center).length();
    rt.push_matrix();
    rt.load_identity();
    rt.light_source(
        point,
        &[("intensity", ParamValue::Float(to_light * to_light)), ("from", ParamValue::Point(from.to_array()))],
    )?;
    rt.light_source(ambient, &[("intensity", ParamValue::Float(0.08))])?;
    rt.pop_matrix()?;
    Ok(())
}

//! Loading meshes from files: Wavefront OBJ (via tobj) and PLY, ASCII or binary (via ply-rs-bw).
//!
//! Invariants: loading never panics on bad input. Every error names the file; the mesh returned
//! has passed [`Mesh::validate`]. OBJ groups are merged into one mesh; normals, texture coordinates
//! and vertex colours are kept only if every group has them. PLY vertex properties other than
//! positions, normals and texture coordinates become one-component attributes of the same name.

use crate::geometry::mesh::triangulate_into;
use crate::geometry::{Attribute, Mesh, MeshError};
use glam::{Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::path::{Path, PathBuf};

/// A failure to load a mesh file.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// The file could not be read.
    #[error("cannot read {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// tobj rejected the OBJ file.
    #[error("cannot load OBJ file {}", path.display())]
    Obj {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: tobj::LoadError,
    },
    /// The PLY file is malformed or lacks what a mesh needs.
    #[error("cannot load PLY file {}: {message}", path.display())]
    Ply {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The file's extension is neither `.obj` nor `.ply`.
    #[error("{}: unknown mesh format (expected a .obj or .ply file)", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file parsed but its data is inconsistent.
    #[error("invalid mesh in {}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The inconsistency.
        source: MeshError,
    },
}

/// Loads a mesh, choosing the format by the file extension.
pub fn load_mesh(path: impl AsRef<Path>) -> Result<Mesh, MeshIoError> {
    let path = path.as_ref();
    if let Err(source) = std::fs::metadata(path) {
        return Err(MeshIoError::Io { path: path.to_path_buf(), source });
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("obj") => load_obj(path),
        Some("ply") => load_ply(path),
        _ => Err(MeshIoError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// Loads a Wavefront OBJ file (materials are ignored).
pub fn load_obj(path: &Path) -> Result<Mesh, MeshIoError> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let (models, _materials) =
        tobj::load_obj(path, &opts).map_err(|source| MeshIoError::Obj { path: path.to_path_buf(), source })?;
    let all = |f: &dyn Fn(&tobj::Mesh) -> bool| models.iter().all(|m| f(&m.mesh));
    let has_n = all(&|m| !m.normals.is_empty() && m.normals.len() == m.positions.len());
    let has_uv = all(&|m| !m.texcoords.is_empty() && m.texcoords.len() / 2 == m.positions.len() / 3);
    let has_c = all(&|m| !m.vertex_color.is_empty() && m.vertex_color.len() == m.positions.len());
    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut colors = Vec::new();
    for m in &models {
        let m = &m.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        if has_n {
            normals.extend(m.normals.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        }
        if has_uv {
            uvs.extend(m.texcoords.chunks_exact(2).map(|p| Vec2::new(p[0], p[1])));
        }
        if has_c {
            colors.extend_from_slice(&m.vertex_color);
        }
        mesh.triangles.extend(m.indices.chunks_exact(3).map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    if has_n {
        mesh.normals = Some(normals);
    }
    if has_uv {
        mesh.uvs = Some(uvs);
    }
    if has_c {
        mesh.attributes.push(Attribute { name: "Cs".to_string(), components: 3, data: colors });
    }
    mesh.validate().map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    Ok(mesh)
}

/// Loads a PLY file (ASCII or binary).
pub fn load_ply(path: &Path) -> Result<Mesh, MeshIoError> {
    let err = |message: String| MeshIoError::Ply { path: path.to_path_buf(), message };
    let file = std::fs::File::open(path).map_err(|source| MeshIoError::Io { path: path.to_path_buf(), source })?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<DefaultElement>::new().read_ply(&mut reader).map_err(|e| err(e.to_string()))?;
    let vertices = ply.payload.get("vertex").ok_or_else(|| err("no `vertex` element".to_string()))?;
    let faces = ply.payload.get("face").ok_or_else(|| err("no `face` element".to_string()))?;
    let scalar = |e: &DefaultElement, k: &str| e.get(k).and_then(Property::to_f32_lossy);
    let first = vertices.first();
    let has = |k: &str| first.is_some_and(|e| scalar(e, k).is_some());
    let has_n = has("nx") && has("ny") && has("nz");
    let uv_keys = [("u", "v"), ("s", "t"), ("texture_u", "texture_v")].into_iter().find(|(a, b)| has(a) && has(b));
    let known = ["x", "y", "z", "nx", "ny", "nz", "u", "v", "s", "t", "texture_u", "texture_v"];
    let extra: Vec<String> = first
        .map(|e| {
            e.iter()
                .filter(|(k, p)| !known.contains(&k.as_str()) && p.to_f32_lossy().is_some())
                .map(|(k, _)| k.clone())
                .collect()
        })
        .unwrap_or_default();
    let mut mesh = Mesh { positions: Vec::with_capacity(vertices.len()), ..Default::default() };
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut attrs: Vec<Attribute> = extra
        .iter()
        .map(|name| Attribute { name: name.clone(), components: 1, data: Vec::with_capacity(vertices.len()) })
        .collect();
    for (i, e) in vertices.iter().enumerate() {
        let get = |k: &str| scalar(e, k).ok_or_else(|| err(format!("vertex {i} has no scalar `{k}`")));
        mesh.positions.push(Vec3::new(get("x")?, get("y")?, get("z")?));
        if has_n {
            normals.push(Vec3::new(get("nx")?, get("ny")?, get("nz")?));
        }
        if let Some((a, b)) = uv_keys {
            uvs.push(Vec2::new(get(a)?, get(b)?));
        }
        for at in &mut attrs {
            at.data.push(get(&at.name)?);
        }
    }
    for (face, e) in faces.iter().enumerate() {
        let list = e
            .get("vertex_indices")
            .or_else(|| e.get("vertex_index"))
            .ok_or_else(|| err(format!("face {face} has no `vertex_indices` list")))?;
        let idx = list
            .to_u32_list()
            .ok_or_else(|| err(format!("face {face}: vertex indices are not a list of non-negative integers")))?;
        triangulate_into(face, &idx, &mut mesh.triangles)
            .map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    }
    if has_n {
        mesh.normals = Some(normals);
    }
    if uv_keys.is_some() {
        mesh.uvs = Some(uvs);
    }
    mesh.attributes = attrs;
    mesh.validate().map_err(|source| MeshIoError::Invalid { path: path.to_path_buf(), source })?;
    Ok(mesh)
}

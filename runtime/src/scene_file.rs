//! Scenes from files: a RIB file, or a mesh file (OBJ with its materials, PLY) given on its own, which
//! gets a camera framing it and a default light rig.
//!
//! OBJ materials become instances of the `material` shader (`docs/shaders.md`): `Kd` -> diffuse
//! colour, `Ks` -> specular colour, `Ns` -> shininess, `d`/`Tr` -> transparency, `Ke` -> emission,
//! `map_Kd` -> diffuse texture (resolved next to the OBJ file). Without materials every object gets
//! `plastic`. When a surface shader is already bound (a RIB `Surface` before `ReadArchive "x.obj"`),
//! it shades every object, with the material's diffuse colour as `Cs`.

use crate::api::{ApiError, Context};
use crate::geometry::{Mesh, MeshError};
use crate::mesh_io::{load_mesh, MeshIoError};
use crate::shading::ParamValue;
use glam::{Vec2, Vec3, Vec3A};
use std::path::{Path, PathBuf};

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error("{path}: {source}")]
    Obj { path: PathBuf, source: tobj::LoadError },
    #[error("{path}: {source}")]
    BadMesh { path: PathBuf, source: MeshError },
    #[error(transparent)]
    Api(#[from] ApiError),
    #[error("{path}: unknown scene file type (expected .rib, .obj or .ply)")]
    UnknownType { path: PathBuf },
    #[error("{path}: {message}")]
    Rib { path: PathBuf, message: String },
}

/// Adds the meshes of `path` (OBJ or PLY) to the context, each as an object instanced once at the
/// current matrix, and returns the world-space bounds of what was added.
pub fn add_mesh_file(rt: &mut Context, path: &Path) -> Result<(Vec3A, Vec3A), SceneFileError> {
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
        let mesh = load_mesh(path)?;
        grow(rt, &mesh);
        let shader = match bound {
            Some(s) => s,
            None => rt.find_shader("plastic")?,
        };
        rt.push_attributes();
        if bound.is_none() {
            rt.bind_shader(shader)?;
        }
        let o = rt.begin_object()?;
        rt.mesh(&mesh)?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        rt.pop_attributes()?;
        return Ok(bounds);
    }
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let (models, materials) =
        tobj::load_obj(path, &opts).map_err(|source| SceneFileError::Obj { path: path.to_path_buf(), source })?;
    // A missing or broken .mtl file leaves the objects without materials (plastic), not an error.
    let materials = materials.unwrap_or_default();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let plastic = rt.find_shader("plastic")?;
    let material_shader = if materials.is_empty() || bound.is_some() { None } else { rt.find_shader("material").ok() };
    let plastic = bound.unwrap_or(plastic);
    for model in &models {
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
        grow(rt, &mesh);
        rt.push_attributes();
        match (m.material_id.and_then(|i| materials.get(i)), material_shader) {
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
        let o = rt.begin_object()?;
        rt.mesh(&mesh)?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
        rt.pop_attributes()?;
    }
    Ok(bounds)
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

/// A camera looking at the box `bounds` from the front (+z) and a little above, and a light rig: a
/// shadowed point light inside the top of the box (which is where the lamp of a room or a Cornell box
/// is) and a dim ambient light.
pub fn frame_bounds(rt: &mut Context, bounds: (Vec3A, Vec3A)) -> Result<(), ApiError> {
    let (lo, hi) = bounds;
    if !(lo.is_finite() && hi.is_finite()) {
        return Ok(());
    }
    let center = (lo + hi) * 0.5;
    let size = hi - lo;
    let radius = 0.5 * size.length().max(1e-3);
    let fov: f32 = 40.0;
    let distance = radius / (fov.to_radians() * 0.5).sin();
    let eye = center + Vec3A::new(0.0, 0.15, 1.0).normalize() * distance;
    rt.camera_look_at(eye, center, Vec3A::Y, fov);
    let point = rt.find_shader("pointlight")?;
    let ambient = rt.find_shader("ambientlight")?;
    let from = center + Vec3A::new(0.0, 0.4 * size.y, 0.0);
    rt.push_matrix();
    rt.load_identity();
    rt.light_source(
        point,
        &[("intensity", ParamValue::Float(radius * radius * 1.2)), ("from", ParamValue::Point(from.to_array()))],
    )?;
    rt.light_source(ambient, &[("intensity", ParamValue::Float(0.08))])?;
    rt.pop_matrix()?;
    Ok(())
}

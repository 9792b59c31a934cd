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
use crate::mesh_io::{load_mesh, MeshIoError};
use crate::shading::ParamValue;
use glam::{Affine3A, Vec2, Vec3, Vec3A};
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
    #[error("{path}: {source}")]
    Gltf { path: PathBuf, source: gltf::Error },
    #[error("{path}: unknown scene file type (expected .rib, .obj, .ply, .gltf or .glb)")]
    UnknownType { path: PathBuf },
    #[error("{path}: {message}")]
    Rib { path: PathBuf, message: String },
    #[error("{path}: a glTF file places its own instances, so it cannot be read into a retained object (ObjectBegin)")]
    NotRetainable { path: PathBuf },
}

/// Adds a mesh file of any supported kind (by extension: `.obj`, `.ply`, `.gltf`, `.glb`).
pub fn add_model_file(rt: &mut Context, path: &Path) -> Result<(Vec3A, Vec3A), SceneFileError> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("gltf" | "glb") => add_gltf_file(rt, path),
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
        Some("gltf" | "glb") if matches!(placement, Placement::Instanced) => add_gltf_file(rt, path),
        Some("gltf" | "glb") => Err(SceneFileError::NotRetainable { path: path.to_path_buf() }),
        Some("obj" | "ply") => add_mesh_file_placed(rt, path, placement),
        _ => Err(SceneFileError::UnknownType { path: path.to_path_buf() }),
    }
}

/// Adds the meshes of a glTF 2.0 file (`.gltf` with its buffers, or `.glb`) to the context, under
/// the current matrix, and returns the world-space bounds of what was added.
pub fn add_gltf_file(rt: &mut Context, path: &Path) -> Result<(Vec3A, Vec3A), SceneFileError> {
    let (doc, buffers, images) =
        gltf::import(path).map_err(|source| SceneFileError::Gltf { path: path.to_path_buf(), source })?;
    // Images become in-memory textures named after the file, made when a material first uses one.
    let image_name = |i: usize| format!("{}#image{i}", path.display());
    let mut made = vec![false; images.len()];
    let bad = |source: MeshError| SceneFileError::BadMesh { path: path.to_path_buf(), source };
    let bound = rt.bound_surface();
    let shader = match bound {
        Some(s) => s,
        None => rt.find_shader("material")?,
    };
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
    let mut stack: Vec<(gltf::Node, glam::Affine3A)> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| (n, root)).collect(),
        None => doc.nodes().map(|n| (n, root)).collect(),
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

/// Adds the meshes of `path` (OBJ or PLY) to the context, each as an object instanced once at the
/// current matrix, and returns the world-space bounds of what was added.
pub fn add_mesh_file(rt: &mut Context, path: &Path) -> Result<(Vec3A, Vec3A), SceneFileError> {
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
        let o = placement.begin(rt)?;
        rt.mesh(&mesh)?;
        rt.end_object()?;
        placement.place(rt, o)?;
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
    for (material_id, mesh) in obj_meshes_by_material(path, &models)? {
        grow(rt, &mesh);
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
        rt.mesh(&mesh)?;
        rt.end_object()?;
        placement.place(rt, o)?;
        rt.pop_attributes()?;
    }
    Ok(bounds)
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

/// A camera looking at the box `bounds` from the front (+z) and a little above, and a light rig: a
/// shadowed key light above and to the right of the camera, and a dim ambient light. (Interiors,
/// which such a rig cannot light, come as RIB files with their own lights.)
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

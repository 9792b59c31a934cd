//! Geometry requests to triangle [`Mesh`]es: polygons (with holes), bilinear patches and patch
//! meshes, and quadrics.
//!
//! What goes where in the mesh:
//! - `P` (or `Pw`, divided by `w`; `Pz` for patches) gives the positions;
//! - `N` gives the per-vertex normals (normalised). Patches, patch meshes and quadrics get their
//!   `(u, v)` parameters as uvs (over the whole patch mesh) and, without `N`, their analytic
//!   normals; their
//!   texture coordinates, where they are not those parameters (`st`, or `s` or `t` alone, given;
//!   or a `TextureCoordinates` other than RISpec's default), are a two-float `st` attribute, so
//!   that shaders see `u v` as the surface's parameters and `s t` as its texture coordinates.
//!   Polygons without `N` get no normals; their uvs are `st` (or `s` and `t`) when given, else
//!   their `(x, y)` (RISpec: a polygon's surface parameters), `s` or `t` alone replacing that
//!   coordinate;
//! - every other float-typed `vertex`, `varying`, `facevarying` or `uniform` parameter becomes a
//!   named per-vertex [`Attribute`] (uniform values repeat at each vertex of their face) of the
//!   kind its type says (points, vectors and normals move with the object; an `hpoint` is divided
//!   by its `w` into a point);
//! - `constant` parameters, integers and strings are not per-vertex data: the loader passes
//!   `constant` ones (and `uniform` ones of one-face primitives) to the shaders as parameter values
//!   (`docs/rib.md`, "Primitive variables").
//!
//! Invariants: every mesh returned passes [`Mesh::validate`]. Polygons share vertices between
//! faces unless a facevarying or uniform parameter needs per-corner values, in which case every
//! face corner is a vertex of its own. Triangles keep the winding of the polygon as written
//! (holes run either way). Malformed data (counts, indices) is an `Err` with a message, never a
//! panic.

use std::borrow::Cow;
use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::decl::{Class, Ty};
use super::request::{find_param, Basis, Param};
use super::trim::{Trim, TrimSense};
use super::view::View;
use crate::geometry::quadric::{Quadric, Tessellation};
use crate::geometry::{Attribute, AttributeKind, Mesh};

/// Polygons with more vertices than this are fanned instead of ear-clipped (ear clipping is
/// quadratic; RIB polygons this large are in practice convex).
pub const MAX_EAR_CLIP_VERTICES: usize = 4096;

/// What the graphics state contributes to a primitive's mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshOptions {
    /// Tessellation of each quadric, or of each patch of a patch mesh; `None` for the defaults
    /// ([`Quadric::default_tessellation`], one quad per flat bilinear patch, otherwise
    /// [`DEFAULT_PATCH_SEGMENTS`] per side).
    pub tessellation: Option<Tessellation>,
    /// The current `Basis` along u (RenderMan's default is Bezier, step 3).
    pub u_basis: Basis,
    /// Its step.
    pub u_step: i32,
    /// The current `Basis` along v.
    pub v_basis: Basis,
    /// Its step.
    pub v_step: i32,
    /// The current `TextureCoordinates`: the `(s, t)` at the `(u, v)` corners `(0, 0) (1, 0)
    /// (0, 1) (1, 1)` that patches and quadrics without `st` get as uvs, bilinearly (RISpec's
    /// default maps `s = u`, `t = v`).
    pub texture_coordinates: [f32; 8],
    /// The current `TrimCurve`: the loops that trim the `NuPatch`es that follow (attribute
    /// state, like the rest).
    pub trim: Option<Arc<Trim>>,
    /// `Attribute "trimcurve" "sense"`: which side of the trim loops is removed.
    pub trim_sense: TrimSense,
    /// The camera seen from the request (its transform and the projection): what camera-facing
    /// primitives face, and how large they look. The loader sets it for each geometry request.
    pub view: View,
    /// Segments per point (`Points`) or per span (`Curves`) chosen by the caller instead of by
    /// their size on screen: a motion block's later samples take its first's, so that their meshes
    /// correspond vertex by vertex. Ignored where the request has another number of points or
    /// spans.
    pub segments: Option<Arc<[u32]>>,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            tessellation: None,
            u_basis: Basis::Named("bezier".into()),
            u_step: 3,
            v_basis: Basis::Named("bezier".into()),
            v_step: 3,
            texture_coordinates: [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            trim: None,
            trim_sense: TrimSense::Inside,
            view: View::default(),
            segments: None,
        }
    }
}

impl MeshOptions {
    /// The default `(s, t)` at surface parameters `uv`, from [`MeshOptions::texture_coordinates`].
    pub fn default_st(&self, uv: Vec2) -> Vec2 {
        let c = self.texture_coordinates;
        let corner = |k: usize| Vec2::new(c[2 * k], c[2 * k + 1]);
        bilerp([corner(0), corner(1), corner(2), corner(3)], uv.x, uv.y)
    }
}

/// `Polygon`: one convex polygon whose vertices are the `P` values.
pub fn polygon_mesh(params: &[Param], warnings: &mut Vec<String>) -> Result<Mesh, String> {
    let n = point_count(params)?;
    general_polygon_mesh(&[n as i32], params, warnings)
}

/// `GeneralPolygon`: one polygon of several loops (the first the outline, the rest holes) whose
/// vertices are the `P` values, loop after loop.
pub fn general_polygon_mesh(nvertices: &[i32], params: &[Param], warnings: &mut Vec<String>) -> Result<Mesh, String> {
    let total: i64 = nvertices.iter().map(|&n| i64::from(n)).sum();
    // Checked before the index list is made, so a bogus count cannot ask for a huge allocation.
    let points = point_count(params)?;
    if total != points as i64 {
        return Err(format!("the loops have {total} vertices in all but \"P\" has {points}"));
    }
    let total = i32::try_from(total).map_err(|_| "too many vertices".to_string())?;
    let vertices: Vec<i32> = (0..total.max(0)).collect();
    let nloops = [i32::try_from(nvertices.len()).map_err(|_| "too many loops".to_string())?];
    points_general_polygons_mesh(&nloops, nvertices, &vertices, params, warnings)
}

/// `PointsPolygons`: polygons indexing shared vertices.
pub fn points_polygons_mesh(
    nvertices: &[i32],
    vertices: &[i32],
    params: &[Param],
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let nloops = vec![1; nvertices.len()];
    points_general_polygons_mesh(&nloops, nvertices, vertices, params, warnings)
}

/// `PointsGeneralPolygons`: polygons with holes indexing shared vertices.
pub fn points_general_polygons_mesh(
    nloops: &[i32],
    nvertices: &[i32],
    vertices: &[i32],
    params: &[Param],
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let nloops = counts(nloops, 1, "loops per polygon")?;
    let nvertices = counts(nvertices, 3, "vertices per loop")?;
    if nloops.iter().sum::<usize>() != nvertices.len() {
        return Err(format!(
            "the polygons have {} loops in all but {} loop sizes are given",
            nloops.iter().sum::<usize>(),
            nvertices.len()
        ));
    }
    if nvertices.iter().sum::<usize>() != vertices.len() {
        return Err(format!(
            "the loops have {} vertices in all but {} vertex indices are given",
            nvertices.iter().sum::<usize>(),
            vertices.len()
        ));
    }
    let points = positions(params)?;
    let vertices: Vec<u32> = vertices
        .iter()
        .map(|&v| u32::try_from(v).ok().filter(|&v| (v as usize) < points.len()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("a vertex index is negative or not below the number of points ({})", points.len()))?;

    // Which polygon each corner belongs to, for uniform values.
    let mut face_of_corner = Vec::with_capacity(vertices.len());
    let mut loop_sizes = nvertices.iter();
    for (face, &loops) in nloops.iter().enumerate() {
        for size in loop_sizes.by_ref().take(loops) {
            face_of_corner.extend(std::iter::repeat_n(face, *size));
        }
    }
    let counts =
        ClassCounts { vertex: points.len(), varying: points.len(), face: nloops.len(), corner: Some(vertices.len()) };
    let data = per_vertex_params(params, &counts, warnings);
    let per_corner = data.iter().any(|d| matches!(d.class, Class::Uniform | Class::FaceVarying));

    let mut attributes = Vec::with_capacity(data.len());
    let mesh_positions = if per_corner {
        for d in &data {
            let mut values = Vec::with_capacity(d.components * vertices.len());
            for (corner, &vertex) in vertices.iter().enumerate() {
                let index = match d.class {
                    Class::Uniform => face_of_corner[corner],
                    Class::FaceVarying => corner,
                    _ => vertex as usize,
                };
                values.extend_from_slice(&d.values[index * d.components..(index + 1) * d.components]);
            }
            attributes.push(d.attribute(values));
        }
        vertices.iter().map(|&v| points[v as usize]).collect()
    } else {
        for d in &data {
            attributes.push(d.attribute(d.values.to_vec()));
        }
        points
    };

    let mut triangles = Vec::with_capacity(vertices.len());
    let mut corner = 0usize;
    let mut loop_sizes = nvertices.iter();
    // Polygons too large to ear-clip, and of them those whose holes were left out.
    let (mut fanned, mut holes_lost) = (0usize, 0usize);
    for &loops in &nloops {
        let mut polygon_loops = Vec::with_capacity(loops);
        for &size in loop_sizes.by_ref().take(loops) {
            let ids: Vec<u32> = if per_corner {
                (corner as u32..(corner + size) as u32).collect()
            } else {
                vertices[corner..corner + size].to_vec()
            };
            polygon_loops.push(ids);
            corner += size;
        }
        if !triangulate_polygon(&polygon_loops, &mesh_positions, &mut triangles) {
            fanned += 1;
            holes_lost += usize::from(polygon_loops.len() > 1);
        }
    }
    if fanned > 0 {
        warnings.push(format!(
            "{fanned} polygon{} of more than {MAX_EAR_CLIP_VERTICES} vertices (outline and holes together) cut into a fan \
             from the first vertex instead of ear-clipped: a concave outline is not followed{}",
            if fanned == 1 { "" } else { "s" },
            if holes_lost > 0 { format!(", and the holes of {holes_lost} are not cut out") } else { String::new() }
        ));
    }
    // RISpec: a polygon's surface parameters are its (x, y) in its own space, and its texture
    // coordinates are those unless given.
    let uvs = mesh_positions.iter().map(|p| Vec2::new(p.x, p.y)).collect();
    let mut mesh = Mesh { positions: mesh_positions, triangles, uvs: Some(uvs), ..Default::default() };
    route_attributes(&mut mesh, attributes);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

/// A quadric's mesh, with its varying parameters (four values, at the corners of `(u, v)` space)
/// interpolated over it.
pub fn quadric_mesh(
    quadric: &Quadric,
    params: &[Param],
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let tessellation = options.tessellation.unwrap_or_else(|| quadric.default_tessellation());
    let mut mesh = quadric.tessellate(tessellation).map_err(|_| {
        format!("{} has a parameter that is not finite, or a surface too large for f32", quadric.name())
    })?;
    // Uniform values count one per surface, like constant ones: they are not per-vertex data.
    let counts = ClassCounts { vertex: 4, varying: 4, face: 1, corner: Some(4) };
    let uvs = mesh.uvs.clone().unwrap_or_default();
    let mut attributes = Vec::new();
    for d in per_vertex_params(params, &counts, warnings) {
        if d.class == Class::Uniform {
            continue;
        }
        let mut data = Vec::with_capacity(d.components * uvs.len());
        interpolate_corners(&d, [0, 1, 2, 3], 0, &uvs, &mut data);
        attributes.push(d.attribute(data));
    }
    route_attributes_parametric(&mut mesh, attributes, options);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

/// Values expected per storage class for one primitive.
pub(super) struct ClassCounts {
    pub(super) vertex: usize,
    pub(super) varying: usize,
    /// Uniform values: one per face (polygon or patch).
    pub(super) face: usize,
    /// Facevarying values: one per face corner; `None` where facevarying data is not supported.
    pub(super) corner: Option<usize>,
}

/// A float-typed parameter with per-vertex, per-corner or per-face values.
pub(super) struct PerVertex<'a> {
    pub(super) name: String,
    pub(super) class: Class,
    pub(super) components: usize,
    /// The parameter's own values, or an `hpoint`'s divided by their `w`.
    pub(super) values: Cow<'a, [f32]>,
    pub(super) kind: AttributeKind,
}

impl PerVertex<'_> {
    /// The mesh attribute of these values: `data` (one value per mesh vertex), named and moved
    /// with the object as the parameter's type says.
    pub(super) fn attribute(&self, data: Vec<f32>) -> Attribute {
        Attribute { name: self.name.clone(), components: self.components, data, kind: self.kind }
    }
}

/// How a parameter of type `ty` moves with the object.
pub(super) fn attribute_kind(ty: Ty) -> AttributeKind {
    match ty {
        Ty::Point | Ty::HPoint => AttributeKind::Point,
        Ty::Vector => AttributeKind::Vector,
        Ty::Normal => AttributeKind::Normal,
        _ => AttributeKind::Data,
    }
}

/// An empty mesh with room for `vertices` vertices (positions, normals, uvs) and `triangles`
/// triangles, and an empty attribute for each of `data`: what the builders that make their own
/// vertices (points, curves) fill.
pub(super) fn reserve_mesh(vertices: usize, triangles: usize, data: &[PerVertex<'_>]) -> (Mesh, Vec<Attribute>) {
    let mesh = Mesh {
        positions: Vec::with_capacity(vertices),
        normals: Some(Vec::with_capacity(vertices)),
        uvs: Some(Vec::with_capacity(vertices)),
        triangles: Vec::with_capacity(triangles),
        ..Default::default()
    };
    let attributes = data.iter().map(|d| d.attribute(Vec::with_capacity(vertices * d.components))).collect();
    (mesh, attributes)
}

/// The float parameters that are data over the surface (not positions), with counts checked: a
/// parameter with the wrong count, or unsupported facevarying data, is dropped with a warning.
pub(super) fn per_vertex_params<'a>(
    params: &'a [Param],
    counts: &ClassCounts,
    warnings: &mut Vec<String>,
) -> Vec<PerVertex<'a>> {
    let mut out = Vec::new();
    for p in params {
        let Some(values) = p.floats() else { continue };
        if matches!(p.name.as_str(), "P" | "Pw" | "Pz" | "Np")
            || matches!(p.decl.class, Class::Constant | Class::Implicit)
        {
            continue;
        }
        let expected = match p.decl.class {
            Class::Vertex => counts.vertex,
            Class::Varying => counts.varying,
            Class::Uniform => counts.face,
            Class::FaceVarying => match counts.corner {
                Some(corners) => corners,
                None => {
                    warnings
                        .push(format!("facevarying \"{}\" is not supported on this primitive and is dropped", p.name));
                    continue;
                }
            },
            Class::Constant | Class::Implicit => continue,
        };
        if p.value_count() != expected {
            warnings.push(format!(
                "\"{}\" ({}) has {} values where this primitive needs {expected}: it is dropped",
                p.name,
                p.decl,
                p.value_count()
            ));
            continue;
        }
        // Shaders have no homogeneous type: an `hpoint` reaches them as the point it stands for.
        let (components, values) = match p.decl.ty {
            Ty::HPoint => (
                3 * p.decl.array_len.unwrap_or(1),
                Cow::Owned(values.chunks_exact(4).flat_map(|h| [h[0] / h[3], h[1] / h[3], h[2] / h[3]]).collect()),
            ),
            _ => (p.decl.components(), Cow::Borrowed(values)),
        };
        let kind = attribute_kind(p.decl.ty);
        out.push(PerVertex { name: p.name.clone(), class: p.decl.class, components, values, kind });
    }
    out
}

/// Moves `N` into the normals and `st` (or `s` and `t`) into the uvs; the rest become attributes.
pub(super) fn route_attributes(mesh: &mut Mesh, attributes: Vec<Attribute>) {
    let mut s = None;
    let mut t = None;
    for attribute in attributes {
        match (attribute.name.as_str(), attribute.components) {
            ("N", 3) => {
                let normals =
                    attribute.data.chunks_exact(3).map(|n| Vec3::from_slice(n).normalize_or(Vec3::Z)).collect();
                mesh.normals = Some(normals);
            }
            ("st", 2) => mesh.uvs = Some(attribute.data.chunks_exact(2).map(Vec2::from_slice).collect()),
            ("s", 1) => s = Some(attribute.data),
            ("t", 1) => t = Some(attribute.data),
            _ => mesh.attributes.push(attribute),
        }
    }
    // One of `s` and `t` alone replaces that coordinate of the surface's own (its default
    // `TextureCoordinates` mapping, or a polygon's `(x, y)`); a mesh without them keeps it as data.
    let uvs = mesh.uvs.as_mut().filter(|uvs| s.as_ref().or(t.as_ref()).is_some_and(|c| c.len() == uvs.len()));
    match (s, t, uvs) {
        (Some(s), Some(t), _) => mesh.uvs = Some(s.into_iter().zip(t).map(|(s, t)| Vec2::new(s, t)).collect()),
        (Some(s), None, Some(uvs)) => uvs.iter_mut().zip(s).for_each(|(uv, s)| uv.x = s),
        (None, Some(t), Some(uvs)) => uvs.iter_mut().zip(t).for_each(|(uv, t)| uv.y = t),
        (Some(s), None, None) => mesh.attributes.push(Attribute::data("s", 1, s)),
        (None, Some(t), None) => mesh.attributes.push(Attribute::data("t", 1, t)),
        (None, None, _) => {}
    }
}

/// [`route_attributes`] for surfaces whose uvs are their own `(u, v)` parameters (patches, patch
/// meshes, quadrics): the uvs stay those (RISpec: `u` and `v` are the surface's parameters, which
/// `Du`, `Dv` and `du`, `dv` go by, whatever its texture coordinates). Where the texture
/// coordinates differ from them (`st` given; `s` or `t` given, replacing that coordinate; or
/// `options`' `TextureCoordinates` not RISpec's default) they are a two-float `st` attribute,
/// which shaders read as `s t`. The rest as [`route_attributes`].
pub(super) fn route_attributes_parametric(mesh: &mut Mesh, attributes: Vec<Attribute>, options: &MeshOptions) {
    let mut given = None;
    let mut s = None;
    let mut t = None;
    let mut rest = Vec::with_capacity(attributes.len());
    for attribute in attributes {
        match (attribute.name.as_str(), attribute.components) {
            ("st", 2) => given = Some(attribute.data),
            ("s", 1) => s = Some(attribute.data),
            ("t", 1) => t = Some(attribute.data),
            _ => rest.push(attribute),
        }
    }
    route_attributes(mesh, rest);
    let uvs = mesh.uvs.as_deref().unwrap_or_default();
    let default_mapping = options.texture_coordinates == MeshOptions::default().texture_coordinates;
    if given.is_none() && s.is_none() && t.is_none() && default_mapping {
        return;
    }
    let mut st: Vec<f32> = match given {
        Some(st) if st.len() == 2 * uvs.len() => st,
        _ => uvs.iter().flat_map(|&uv| options.default_st(uv).to_array()).collect(),
    };
    for (k, coordinate) in [s, t].into_iter().enumerate() {
        if let Some(values) = coordinate.filter(|c| c.len() == uvs.len()) {
            st.iter_mut().skip(k).step_by(2).zip(values).for_each(|(to, from)| *to = from);
        }
    }
    mesh.attributes.push(Attribute::data("st", 2, st));
}

/// [`route_attributes`] for primitives whose uvs are their own `(u, v)` parameters (points and
/// curves): `st` (or `s` and `t` together) stays a two-float `st` attribute, which shaders read as
/// `s t` while `u v` stay the parameters; the rest become attributes.
pub(super) fn route_attributes_keeping_uv(mesh: &mut Mesh, attributes: Vec<Attribute>) {
    let mut s = None;
    let mut t = None;
    for attribute in attributes {
        match (attribute.name.as_str(), attribute.components) {
            ("s", 1) => s = Some(attribute),
            ("t", 1) => t = Some(attribute),
            _ => mesh.attributes.push(attribute),
        }
    }
    match (s, t) {
        (Some(s), Some(t)) => {
            let data = s.data.iter().zip(&t.data).flat_map(|(&s, &t)| [s, t]).collect();
            mesh.attributes.push(Attribute::data("st", 2, data));
        }
        (s, t) => mesh.attributes.extend(s.into_iter().chain(t)),
    }
}

fn counts(values: &[i32], min: usize, what: &str) -> Result<Vec<usize>, String> {
    values
        .iter()
        .map(|&n| usize::try_from(n).ok().filter(|&n| n >= min))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("every count of {what} must be at least {min}"))
}

fn point_count(params: &[Param]) -> Result<usize, String> {
    positions(params).map(|p| p.len())
}

/// The positions from `P` (points) or `Pw` (homogeneous points, divided by `w`).
pub(super) fn positions(params: &[Param]) -> Result<Vec<Vec3>, String> {
    if let Some(p) = find_param(params, "P").filter(|p| p.decl.components() == 3) {
        let values = p.floats().unwrap_or_default();
        return Ok(values.chunks_exact(3).map(Vec3::from_slice).collect());
    }
    if let Some(p) = find_param(params, "Pw").filter(|p| p.decl.ty == Ty::HPoint && p.decl.array_len.is_none()) {
        let values = p.floats().unwrap_or_default();
        return Ok(values.chunks_exact(4).map(|h| Vec3::new(h[0], h[1], h[2]) / h[3]).collect());
    }
    Err("the primitive has no positions: give \"P\" (or \"Pw\")".to_string())
}

pub(super) fn bilerp<T>(c: [T; 4], u: f32, v: f32) -> T
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    c[0] * ((1.0 - u) * (1.0 - v)) + c[1] * (u * (1.0 - v)) + c[2] * ((1.0 - u) * v) + c[3] * (u * v)
}

/// Appends to `out` the values of `d` at each local `(u, v)`: bilinear between the four corner
/// values for vertex and varying data, the face's value for uniform data.
fn interpolate_corners(d: &PerVertex, corner_index: [usize; 4], face: usize, uvs: &[Vec2], out: &mut Vec<f32>) {
    let value = |k: usize, c: usize| d.values[k * d.components + c];
    for uv in uvs {
        for c in 0..d.components {
            out.push(match d.class {
                Class::Uniform => value(face, c),
                _ => bilerp(corner_index.map(|k| value(k, c)), uv.x, uv.y),
            });
        }
    }
}

/// Triangulates one polygon given as loops of vertex ids (the first the outline, the rest holes)
/// into `out`, keeping the outline's winding; false when it has more than
/// [`MAX_EAR_CLIP_VERTICES`] and was fanned from its first vertex instead, its holes left out.
pub fn triangulate_polygon(loops: &[Vec<u32>], positions: &[Vec3], out: &mut Vec<[u32; 3]>) -> bool {
    let Some(outline) = loops.first() else { return true };
    let position = |id: u32| positions[id as usize];
    if loops.len() == 1 && outline.len() == 3 {
        out.push([outline[0], outline[1], outline[2]]);
        return true;
    }
    let fan = |ids: &[u32], out: &mut Vec<[u32; 3]>| {
        for k in 1..ids.len().saturating_sub(1) {
            out.push([ids[0], ids[k], ids[k + 1]]);
        }
    };
    // Newell's normal of the outline: its direction is the side the outline winds
    // counter-clockwise around, which is the 2D frame's +z, so the outline projects to a
    // counter-clockwise ring.
    let mut normal = Vec3::ZERO;
    for (k, &id) in outline.iter().enumerate() {
        let (a, b) = (position(id), position(outline[(k + 1) % outline.len()]));
        normal += a.cross(b);
    }
    let total: usize = loops.iter().map(Vec::len).sum();
    if total > MAX_EAR_CLIP_VERTICES {
        fan(outline, out);
        return false;
    }
    if !normal.is_finite() || normal.length_squared() < 1e-30 {
        fan(outline, out);
        return true;
    }
    let normal = normal.normalize();
    let tangent = normal.any_orthonormal_vector();
    let bitangent = normal.cross(tangent);
    let project = |id: u32| {
        let p = position(id);
        Vertex2 { id, p: Vec2::new(p.dot(tangent), p.dot(bitangent)) }
    };
    let mut ring: Vec<Vertex2> = outline.iter().map(|&id| project(id)).collect();
    let mut holes: Vec<Vec<Vertex2>> = loops[1..]
        .iter()
        .map(|hole| {
            let mut hole: Vec<Vertex2> = hole.iter().map(|&id| project(id)).collect();
            if signed_area(&hole) > 0.0 {
                hole.reverse();
            }
            hole
        })
        .collect();
    // Bridge holes to the outline, rightmost hole first, so each bridge stays clear of the
    // holes still to come.
    holes.sort_by(|a, b| max_x(b).total_cmp(&max_x(a)));
    for k in 0..holes.len() {
        let (bridged, rest) = holes.split_at(k + 1);
        bridge(&mut ring, &bridged[k], rest);
    }
    ear_clip(ring, out);
    true
}

#[derive(Clone, Copy, Debug)]
struct Vertex2 {
    id: u32,
    p: Vec2,
}

fn max_x(ring: &[Vertex2]) -> f32 {
    ring.iter().fold(f32::NEG_INFINITY, |m, v| m.max(v.p.x))
}

fn signed_area(ring: &[Vertex2]) -> f32 {
    let mut area = 0.0;
    for (k, a) in ring.iter().enumerate() {
        let b = ring[(k + 1) % ring.len()];
        area += a.p.perp_dot(b.p);
    }
    area * 0.5
}

fn cross2(o: Vec2, a: Vec2, b: Vec2) -> f32 {
    (a - o).perp_dot(b - o)
}

/// Whether segments `ab` and `cd` cross at a point inside both (touching endpoints do not count).
fn segments_cross(a: Vec2, b: Vec2, c: Vec2, d: Vec2) -> bool {
    let (d1, d2) = (cross2(a, b, c), cross2(a, b, d));
    let (d3, d4) = (cross2(c, d, a), cross2(c, d, b));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// Splices `hole` into `ring` through a bridge from the hole's rightmost vertex to the nearest
/// ring vertex it can see (no edge of the ring or of the `other` holes in the way).
fn bridge(ring: &mut Vec<Vertex2>, hole: &[Vertex2], other: &[Vec<Vertex2>]) {
    let Some((m_index, m)) = hole.iter().enumerate().max_by(|a, b| a.1.p.x.total_cmp(&b.1.p.x)) else { return };
    let mut candidates: Vec<usize> = (0..ring.len()).collect();
    candidates.sort_by(|&a, &b| ring[a].p.distance_squared(m.p).total_cmp(&ring[b].p.distance_squared(m.p)));
    let edges =
        |ring: &[Vertex2]| (0..ring.len()).map(move |k| (ring[k].p, ring[(k + 1) % ring.len()].p)).collect::<Vec<_>>();
    let mut blocking = edges(ring);
    blocking.extend(edges(hole));
    for h in other {
        blocking.extend(edges(h));
    }
    let visible = |v: Vec2| blocking.iter().all(|&(a, b)| !segments_cross(m.p, v, a, b));
    let chosen = candidates.iter().copied().find(|&k| visible(ring[k].p)).unwrap_or(candidates[0]);
    let mut spliced = Vec::with_capacity(ring.len() + hole.len() + 2);
    spliced.extend_from_slice(&ring[..=chosen]);
    spliced.extend(hole[m_index..].iter().chain(&hole[..=m_index]).copied());
    spliced.push(ring[chosen]);
    spliced.extend_from_slice(&ring[chosen + 1..]);
    *ring = spliced;
}

/// Ear clipping of a counter-clockwise ring (possibly with bridge edges, where vertices repeat).
/// If no ear can be found (degenerate input) the rest is fanned.
fn ear_clip(mut ring: Vec<Vertex2>, out: &mut Vec<[u32; 3]>) {
    let mut k = 0;
    let mut misses = 0;
    while ring.len() > 3 {
        let n = ring.len();
        let (a, b, c) = (ring[(k + n - 1) % n], ring[k % n], ring[(k + 1) % n]);
        if is_ear(&ring, a, b, c) {
            out.push([a.id, b.id, c.id]);
            ring.remove(k % n);
            misses = 0;
        } else {
            k = (k + 1) % n;
            misses += 1;
            if misses > n {
                for j in 1..ring.len() - 1 {
                    out.push([ring[0].id, ring[j].id, ring[j + 1].id]);
                }
                return;
            }
        }
    }
    if let [a, b, c] = ring[..] {
        out.push([a.id, b.id, c.id]);
    }
}

fn is_ear(ring: &[Vertex2], a: Vertex2, b: Vertex2, c: Vertex2) -> bool {
    if cross2(a.p, b.p, c.p) <= 0.0 {
        return false;
    }
    ring.iter().all(|v| {
        let at_corner = v.p == a.p || v.p == b.p || v.p == c.p;
        at_corner || !(cross2(a.p, b.p, v.p) >= 0.0 && cross2(b.p, c.p, v.p) >= 0.0 && cross2(c.p, a.p, v.p) >= 0.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::{
        mesh_from_request, mesh_from_request_with, parse_str, RequestKind as K, RibDiagnostic, DEFAULT_PATCH_SEGMENTS,
    };

    fn only_mesh(text: &str) -> (Mesh, Vec<RibDiagnostic>) {
        let parse = parse_str(text, "test.rib");
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let mut diagnostics = Vec::new();
        let mesh = mesh_from_request(&parse.requests[0], &mut diagnostics);
        (mesh.unwrap_or_else(|| panic!("{diagnostics:?}")), diagnostics)
    }

    fn area(mesh: &Mesh) -> (f32, f32) {
        let (mut signed, mut unsigned) = (0.0, 0.0);
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.corners(t);
            let n = (b - a).cross(c - a);
            signed += 0.5 * n.z;
            unsigned += 0.5 * n.length();
        }
        (signed, unsigned)
    }

    #[test]
    fn polygon_keeps_data_and_winding() {
        let (mesh, d) = only_mesh(
            r#"Polygon "P" [0 0 0 1 0 0 1 1 0 0 1 0] "st" [0 0 1 0 1 1 0 1] "Cs" [1 0 0 0 1 0 0 0 1 1 1 1]
                "N" [0 0 2 0 0 1 0 0 1 0 0 1] "constant float Kd" 0.5"#,
        );
        assert!(d.is_empty());
        assert_eq!(mesh.triangle_count(), 2);
        assert_eq!(area(&mesh), (1.0, 1.0));
        assert_eq!(mesh.uvs.as_ref().unwrap()[2], Vec2::new(1.0, 1.0));
        assert_eq!(mesh.normals.as_ref().unwrap()[0], Vec3::Z);
        assert_eq!(mesh.attributes.len(), 1);
        assert_eq!((mesh.attributes[0].name.as_str(), mesh.attributes[0].components), ("Cs", 3));
    }

    #[test]
    fn general_polygon_with_holes() {
        // A 4 x 4 square (clockwise, to check the winding is kept) with two 1 x 1 holes.
        let (mesh, _) = only_mesh(
            r#"GeneralPolygon [4 4 4] "P" [0 0 0  0 4 0  4 4 0  4 0 0
                 1 1 0  2 1 0  2 2 0  1 2 0
                 3 3 0  2.5 3 0  2.5 2.5 0  3 2.5 0]"#,
        );
        let (signed, unsigned) = area(&mesh);
        assert!((signed + 14.75).abs() < 1e-4 && (unsigned - 14.75).abs() < 1e-4, "{signed} {unsigned}");
        // 12 vertices, two of them repeated per bridge: 16 - 2 triangles.
        assert_eq!(mesh.triangle_count(), 14);
    }

    #[test]
    fn concave_polygon_is_ear_clipped() {
        let (mesh, _) = only_mesh(r#"GeneralPolygon [6] "P" [0 0 0 4 0 0 4 4 0 2 1 0 0 4 0 0 2 0]"#);
        let (signed, unsigned) = area(&mesh);
        assert!((signed - 10.0).abs() < 1e-4 && (unsigned - 10.0).abs() < 1e-4, "{signed} {unsigned}");
    }

    #[test]
    fn points_polygons_share_vertices_unless_uniform_data() {
        let text = r#"PointsPolygons [3 3] [0 1 2 0 2 3] "P" [0 0 0 1 0 0 1 1 0 0 1 0]"#;
        let (mesh, _) = only_mesh(text);
        assert_eq!((mesh.positions.len(), mesh.triangles.clone()), (4, vec![[0, 1, 2], [0, 2, 3]]));
        let (mesh, _) = only_mesh(&format!(
            r#"{text} "uniform float id" [7 9] "facevarying float[2] st" [0 0 1 0 1 1 0 0 1 1 0 1]"#
        ));
        assert_eq!(mesh.positions.len(), 6);
        assert_eq!(mesh.attributes[0].data, vec![7.0, 7.0, 7.0, 9.0, 9.0, 9.0]);
        assert_eq!(mesh.uvs.as_ref().unwrap()[5], Vec2::new(0.0, 1.0));
        mesh.validate().unwrap();
        // PRMan's `facevertex` class: a value per corner, as facevarying (lucille's `st1.rib`).
        let (corners, _) = only_mesh(&format!(
            r#"{text} "uniform float id" [7 9] "facevertex float[2] st" [0 0 1 0 1 1 0 0 1 1 0 1]"#
        ));
        assert_eq!(corners.uvs, mesh.uvs);
        assert_eq!(corners.positions, mesh.positions);
    }

    #[test]
    fn points_general_polygons() {
        let (mesh, _) = only_mesh(
            r#"PointsGeneralPolygons [2 1] [4 3 3] [0 1 2 3 4 5 6 0 1 3]
               "P" [0 0 0 3 0 0 3 3 0 0 3 0 1 1 0 2 1 0 1 2 0]"#,
        );
        let (signed, _) = area(&mesh);
        assert!((signed - (9.0 - 0.5 + 4.5)).abs() < 1e-4, "{signed}");
    }

    #[test]
    fn bad_polygon_data_is_an_error() {
        for text in [
            r#"PointsPolygons [3] [0 1 5] "P" [0 0 0 1 0 0 1 1 0]"#,
            r#"PointsPolygons [3 3] [0 1 2] "P" [0 0 0 1 0 0 1 1 0]"#,
            r#"PointsPolygons [2] [0 1] "P" [0 0 0 1 0 0]"#,
            r#"PointsGeneralPolygons [2] [3] [0 1 2] "P" [0 0 0 1 0 0 1 1 0]"#,
            r#"Polygon "Cs" [1 1 1]"#,
            r#"GeneralPolygon [2000000000] "P" [0 0 0 1 0 0 1 1 0]"#,
            r#"GeneralPolygon [3 -3] "P" [0 0 0 1 0 0 1 1 0]"#,
        ] {
            let parse = parse_str(text, "bad.rib");
            let mut diagnostics = Vec::new();
            assert!(mesh_from_request(&parse.requests[0], &mut diagnostics).is_none(), "{text}");
            assert_eq!(diagnostics.len(), 1, "{text}: {diagnostics:?}");
            assert!(diagnostics[0].to_string().starts_with("bad.rib:1:1: error: "));
        }
    }

    #[test]
    fn wrong_count_attribute_is_dropped_with_a_warning() {
        let (mesh, d) = only_mesh(r#"Polygon "P" [0 0 0 1 0 0 1 1 0] "Cs" [1 0 0 0 1 0]"#);
        assert!(mesh.attributes.is_empty());
        assert!(d[0].message.contains("\"Cs\" (varying color) has 2 values where this primitive needs 3"));
    }

    #[test]
    fn bilinear_patches() {
        let (flat, _) = only_mesh(
            r#"Patch "bilinear" "P" [0 0 0 1 0 0 0 1 0 1 1 0] "varying float s" [0 1 0 1] "varying float t" [0 0 1 1]"#,
        );
        assert_eq!(flat.triangle_count(), 2);
        assert_eq!(flat.normals.as_ref().unwrap()[0], Vec3::Z);
        assert_eq!(flat.uvs.as_ref().unwrap()[3], Vec2::new(1.0, 1.0));
        let (warped, _) = only_mesh(r#"Patch "bilinear" "P" [0 0 0 1 0 0 0 1 0 1 1 1]"#);
        assert_eq!(warped.triangle_count() as u32, 2 * DEFAULT_PATCH_SEGMENTS * DEFAULT_PATCH_SEGMENTS);
        for (p, uv) in warped.positions.iter().zip(warped.uvs.as_ref().unwrap()) {
            assert!((p.z - uv.x * uv.y).abs() < 1e-5); // z = u v on this patch
        }
        // A 3 x 2 mesh periodic in u: three patches around, uvs spanning the mesh.
        let (ring, _) = only_mesh(
            r#"PatchMesh "bilinear" 3 "periodic" 2 "nonperiodic" "P" [1 0 0 -1 1 0 -1 -1 0 1 0 1 -1 1 1 -1 -1 1] "Cs" [1 0 0 0 1 0 0 0 1 1 0 0 0 1 0 0 0 1]"#,
        );
        assert_eq!(ring.triangle_count(), 6);
        assert_eq!(ring.attributes[0].data.len(), 3 * ring.positions.len());
        // `nowrap`, the older name of `nonperiodic`, makes the same mesh.
        let (old_name, _) = only_mesh(
            r#"PatchMesh "bilinear" 3 "periodic" 2 "nowrap" "P" [1 0 0 -1 1 0 -1 -1 0 1 0 1 -1 1 1 -1 -1 1] "Cs" [1 0 0 0 1 0 0 0 1 1 0 0 0 1 0 0 0 1]"#,
        );
        assert_eq!((old_name.positions, old_name.triangles), (ring.positions.clone(), ring.triangles.clone()));
        let max_u = ring.uvs.as_ref().unwrap().iter().fold(0.0f32, |m, uv| m.max(uv.x));
        assert_eq!(max_u, 1.0);
    }

    #[test]
    fn bicubic_patches_follow_the_basis() {
        // A flat Bezier patch with evenly spaced control points is the square, linearly.
        let grid: Vec<String> = (0..16).map(|k| format!("{} {} 0", k % 4, k / 4)).collect();
        let (flat, _) = only_mesh(&format!(r#"Patch "bicubic" "P" [{}]"#, grid.join(" ")));
        for (p, uv) in flat.positions.iter().zip(flat.uvs.as_ref().unwrap()) {
            assert!((p.x - 3.0 * uv.x).abs() < 1e-5 && (p.y - 3.0 * uv.y).abs() < 1e-5 && p.z == 0.0);
        }
        assert!(flat.normals.as_ref().unwrap().iter().all(|n| (*n - Vec3::Z).length() < 1e-5));
        // Raised inner control points: corners stay put, the middle rises to 3/4 * 9/16... of 1.
        let raised: Vec<String> = (0..16)
            .map(|k| {
                format!("{} {} {}", k % 4, k / 4, u8::from((1..3).contains(&(k % 4)) && (1..3).contains(&(k / 4))))
            })
            .collect();
        let parse = parse_str(&format!(r#"Patch "bicubic" "P" [{}]"#, raised.join(" ")), "b.rib");
        let options =
            MeshOptions { tessellation: Some(Tessellation { u_segments: 2, v_segments: 2 }), ..Default::default() };
        let mesh = mesh_from_request_with(&parse.requests[0], &options, &mut Vec::new()).unwrap();
        assert_eq!(mesh.positions[0], Vec3::ZERO);
        assert!((mesh.positions[4].z - 0.5625).abs() < 1e-6, "{}", mesh.positions[4]); // (3/4)^2 at the centre
        assert!(mesh.normals.as_ref().unwrap()[4].dot(Vec3::Z) > 0.999);

        // A periodic B-spline mesh around a square of 4 x 4 points: 4 x 1 patches.
        let ring: Vec<String> = (0..16)
            .map(|k| {
                let corner = [(1, 1), (-1, 1), (-1, -1), (1, -1)][k % 4];
                format!("{} {} {}", corner.0, corner.1, k / 4)
            })
            .collect();
        let parse = parse_str(
            &format!(
                r#"Basis "b-spline" 1 "b-spline" 1 PatchMesh "bicubic" 4 "periodic" 4 "nonperiodic" "P" [{}]"#,
                ring.join(" ")
            ),
            "b.rib",
        );
        assert!(!parse.has_errors());
        let K::Basis { u, ustep, v, vstep } = parse.requests[0].kind.clone() else { panic!() };
        let options = MeshOptions { u_basis: u, u_step: ustep, v_basis: v, v_step: vstep, ..Default::default() };
        let mesh = mesh_from_request_with(&parse.requests[1], &options, &mut Vec::new()).unwrap();
        assert_eq!(mesh.triangle_count() as u32, 4 * 2 * DEFAULT_PATCH_SEGMENTS * DEFAULT_PATCH_SEGMENTS);
        for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
            assert!(p.z >= 1.0 - 1e-5 && p.z <= 2.0 + 1e-5); // a B-spline only spans the middle rows
            assert!(n.dot(Vec3::new(p.x, p.y, 0.0)) > 0.0, "normal {n} at {p} points inwards");
        }

        let mut diagnostics = Vec::new();
        let bad = parse_str(r#"PatchMesh "bicubic" 5 "nonperiodic" 4 "nonperiodic" "P" [0 0 0]"#, "b.rib");
        assert!(mesh_from_request(&bad.requests[0], &mut diagnostics).is_none());
        assert!(
            diagnostics[0].message.contains("5 control points along u do not make whole patches"),
            "{diagnostics:?}"
        );
    }

    /// What a patch or a quadric is counted as before it is tessellated is what it makes: exactly
    /// for patches (flat bilinear ones one quad, others a grid each), at least for quadrics (whose
    /// rows at a pole collapse), and nothing for the requests their own data bound.
    #[test]
    fn requests_are_counted_as_they_tessellate() {
        let saddle = "0 0 0  1 0 1  0 1 1  1 1 0";
        let flat = "0 0 0  1 0 0  0 1 0  1 1 0";
        let ring: Vec<String> = (0..16).map(|k| format!("{} {} {}", k % 4, k / 4, (k % 3) as f32 * 0.5)).collect();
        let texts = [
            format!(r#"Patch "bilinear" "P" [{saddle}]"#),
            format!(r#"Patch "bilinear" "P" [{flat}]"#),
            format!(r#"PatchMesh "bilinear" 2 "nonperiodic" 4 "nonperiodic" "P" [{flat}  {saddle}]"#),
            format!(r#"Patch "bicubic" "P" [{}]"#, ring.join(" ")),
            "Sphere 1 -0.5 1 270".to_string(),
            "Torus 1 0.25 0 360 180".to_string(),
            "Disk 0 1 360".to_string(),
        ];
        for options in [
            MeshOptions::default(),
            MeshOptions { tessellation: Some(Tessellation { u_segments: 5, v_segments: 3 }), ..Default::default() },
        ] {
            for text in &texts {
                let parse = parse_str(text, "t.rib");
                let request = &parse.requests[0];
                let counted = crate::rib::request_triangles(request, &options);
                let made = mesh_from_request_with(request, &options, &mut Vec::new()).expect(text).triangle_count();
                if matches!(request.kind, K::Quadric { .. }) {
                    assert!(counted >= made && counted <= 2 * made, "{text}: {counted} for {made}");
                } else {
                    assert_eq!(counted, made, "{text}");
                }
            }
        }
        let polygon = parse_str("Polygon \"P\" [0 0 0  1 0 0  0 1 0]", "t.rib");
        assert_eq!(crate::rib::request_triangles(&polygon.requests[0], &MeshOptions::default()), 0);
    }

    #[test]
    fn quadric_with_varying_colour() {
        let (mesh, _) = only_mesh(r#"Sphere 1 -1 1 360 "Cs" [1 0 0  0 1 0  0 0 1  1 1 1] "uniform float Kd" 1"#);
        assert_eq!(mesh.attributes.len(), 1);
        let cs = &mesh.attributes[0].data;
        assert_eq!(&cs[..3], &[1.0, 0.0, 0.0]); // vertex (u, v) = (0, 0)
        let last = cs.len() - 3;
        assert_eq!(&cs[last..], &[1.0, 1.0, 1.0]); // vertex (1, 1)
        let parse = parse_str("Sphere 1 -1 1 360", "s.rib");
        let options =
            MeshOptions { tessellation: Some(Tessellation { u_segments: 4, v_segments: 2 }), ..Default::default() };
        let mesh = mesh_from_request_with(&parse.requests[0], &options, &mut Vec::new()).unwrap();
        assert_eq!(mesh.positions.len(), 15);
        assert!(mesh.attributes.is_empty(), "RISpec's default texture coordinates are the parameters");
        // TextureCoordinates remap the texture coordinates, not the parameters.
        let options = MeshOptions { texture_coordinates: [1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0], ..options };
        let mapped = mesh_from_request_with(&parse.requests[0], &options, &mut Vec::new()).unwrap();
        assert_eq!(mapped.uvs, mesh.uvs);
        let uvs = mesh.uvs.as_ref().unwrap();
        assert_eq!((uvs[0], uvs[14]), (Vec2::new(0.0, 0.0), Vec2::new(1.0, 1.0)));
        let st = mapped.attributes.iter().find(|a| a.name == "st").expect("an st attribute");
        assert_eq!((&st.data[..2], &st.data[28..30]), (&[1.0, 1.0][..], &[0.0, 0.0][..]));
    }
}

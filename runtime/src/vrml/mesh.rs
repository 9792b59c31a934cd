//! VRML geometry as triangle meshes, in the node's own coordinates: indexed face sets (and the
//! elevation grids and extrusions that are made as face sets), and the four primitives.
//!
//! Texture coordinates are VRML's here (`t` up, `(0, 0)` the image's lower left corner); the
//! builder applies the TextureTransform and turns them into rtsl's (`t` down).

use crate::geometry::{Attribute, Mesh};
use crate::rib::mesh::triangulate_polygon;
use glam::{Quat, Vec2, Vec3};
use std::collections::HashMap;

/// Segments around the axis of a Sphere, Cylinder or Cone (a Sphere has half as many rings).
pub const ROUND_SEGMENTS: u32 = 48;

/// Colours or normals with their index, per vertex or per face (VRML's `colorPerVertex`,
/// `normalPerVertex`).
#[derive(Clone, Copy, Debug)]
pub struct Indexed<'a> {
    pub values: &'a [Vec3],
    /// Empty: the values are taken in the order of the vertices' coordinate indices (per vertex)
    /// or of the faces (per face).
    pub index: &'a [i32],
    pub per_vertex: bool,
}

/// An indexed face set as its fields give it.
#[derive(Clone, Copy, Debug, Default)]
pub struct FaceSet<'a> {
    pub points: &'a [Vec3],
    /// Vertex indices, each face ended by -1 (or by the end).
    pub coord_index: &'a [i32],
    pub ccw: bool,
    /// Radians; above it, faces meeting at a vertex keep their own normals there.
    pub crease_angle: f32,
    pub normals: Option<Indexed<'a>>,
    pub colors: Option<Indexed<'a>>,
    /// Texture coordinates and their index (empty: the coordinate index), per vertex.
    pub tex_coords: Option<(&'a [Vec2], &'a [i32])>,
    /// Without `tex_coords`, make VRML's default ones (from the bounding box).
    pub default_tex_coords: bool,
}

/// A mesh made from a face set, and what was wrong with the input (each a sentence).
#[derive(Clone, Debug, Default)]
pub struct Made {
    pub mesh: Mesh,
    pub problems: Vec<String>,
}

/// Which value a corner takes from an indexed attribute, or why none.
fn pick(attr: &Indexed, k: usize, face: usize, coord: i32) -> Option<usize> {
    let i = match (attr.per_vertex, attr.index.is_empty()) {
        (true, true) => coord,
        (true, false) => *attr.index.get(k)?,
        (false, true) => i32::try_from(face).ok()?,
        (false, false) => *attr.index.get(face)?,
    };
    usize::try_from(i).ok().filter(|&i| i < attr.values.len())
}

/// Newell's normal of a polygon: its direction is the side it winds counter-clockwise around, its
/// length twice its area.
fn newell(points: impl Iterator<Item = Vec3> + Clone) -> Vec3 {
    let mut n = Vec3::ZERO;
    let mut next = points.clone().cycle().skip(1);
    for a in points {
        let b = next.next().unwrap_or(a);
        n += a.cross(b);
    }
    n
}

/// VRML's default texture coordinates of points: `s` along the bounding box's longest side from 0
/// to 1, `t` along the next longest from 0 to its length over the longest (ties go to x, then y).
pub fn default_tex_coords(points: &[Vec3]) -> Vec<Vec2> {
    let (lo, hi) = points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let size = (hi - lo).max(Vec3::ZERO);
    let mut axes = [0usize, 1, 2];
    // Longest first; stable, so ties keep x, y, z order.
    axes.sort_by(|&a, &b| size[b].total_cmp(&size[a]));
    let (s_axis, t_axis) = (axes[0], axes[1]);
    let long = size[s_axis];
    if long.is_nan() || long <= 0.0 {
        return vec![Vec2::ZERO; points.len()];
    }
    points.iter().map(|p| Vec2::new((p[s_axis] - lo[s_axis]) / long, (p[t_axis] - lo[t_axis]) / long)).collect()
}

/// The triangles of a face set, with normals (given, or smoothed across edges within the crease
/// angle, or none for flat faces), colours (`Cs`) and texture coordinates per vertex. Vertices are
/// shared between faces wherever all of their values agree. Faces with fewer than three vertices
/// or an index out of range are left out; an attribute whose indices do not fit is ignored; each is
/// a problem reported. Ear clipping a face of `n` vertices costs `n * n` of `budget` (about what it
/// takes); faces past the budget are fanned from their first vertex, a problem reported.
pub fn face_set(input: &FaceSet, budget: &mut usize) -> Made {
    let mut problems = Vec::new();
    let points = input.points;
    // Faces: (face number, the positions k in coord_index of its corners).
    let mut faces: Vec<(usize, Vec<usize>)> = Vec::new();
    let (mut short, mut out_of_range) = (0usize, 0usize);
    let mut current = Vec::new();
    let mut number = 0;
    for (k, &i) in input.coord_index.iter().chain(std::iter::once(&-1)).enumerate() {
        if i != -1 {
            current.push(k);
            continue;
        }
        if current.is_empty() && k == input.coord_index.len() {
            break;
        }
        let corners = std::mem::take(&mut current);
        if corners.iter().any(|&k| usize::try_from(input.coord_index[k]).map_or(true, |p| p >= points.len())) {
            out_of_range += 1;
        } else if corners.len() < 3 {
            short += 1;
        } else {
            faces.push((number, corners));
        }
        number += 1;
    }
    if out_of_range > 0 {
        problems.push(format!(
            "{out_of_range} face(s) with a coordinate index out of range (there are {} points) left out",
            points.len()
        ));
    }
    if short > 0 {
        problems.push(format!("{short} face(s) of fewer than three vertices left out"));
    }
    let coord = |k: usize| input.coord_index[k];
    let position = |k: usize| points[coord(k) as usize];

    // Attributes whose indices do not all fit are ignored.
    let fits = |attr: &Indexed| {
        faces.iter().all(|(f, corners)| corners.iter().all(|&k| pick(attr, k, *f, coord(k)).is_some()))
    };
    let normals = input.normals.filter(|a| fits(a));
    if input.normals.is_some() && normals.is_none() {
        problems.push("the normals and their index do not fit the faces; they are ignored".into());
    }
    let colors = input.colors.filter(|a| fits(a));
    if input.colors.is_some() && colors.is_none() {
        problems.push("the colours and their index do not fit the faces; they are ignored".into());
    }
    let tex = input.tex_coords.and_then(|(values, index)| {
        let fits = faces.iter().all(|(_, corners)| {
            corners.iter().all(|&k| {
                let i = if index.is_empty() { Some(coord(k)) } else { index.get(k).copied() };
                i.and_then(|i| usize::try_from(i).ok()).is_some_and(|i| i < values.len())
            })
        });
        if !fits {
            problems.push("the texture coordinates and their index do not fit the faces; they are ignored".into());
        }
        fits.then_some((values, index))
    });
    let defaults = (tex.is_none() && input.default_tex_coords).then(|| default_tex_coords(points));

    // Face normals (area-weighted), facing the front side.
    let face_normals: Vec<Vec3> = faces
        .iter()
        .map(|(_, corners)| {
            let n = newell(corners.iter().map(|&k| position(k)));
            if input.ccw {
                n
            } else {
                -n
            }
        })
        .collect();
    // Smoothing: the faces around each point.
    let smooth = normals.is_none() && input.crease_angle > 1e-4;
    let around: Vec<Vec<u32>> = if smooth {
        let mut around = vec![Vec::new(); points.len()];
        for (face, (_, corners)) in faces.iter().enumerate() {
            for &k in corners {
                let list: &mut Vec<u32> = &mut around[coord(k) as usize];
                if list.last() != Some(&(face as u32)) {
                    list.push(face as u32);
                }
            }
        }
        around
    } else {
        Vec::new()
    };
    let cos_crease = input.crease_angle.min(std::f32::consts::PI).cos();

    let mut mesh = Mesh::default();
    let mut mesh_normals = Vec::new();
    let mut mesh_colors = Vec::new();
    let mut mesh_uvs = Vec::new();
    let mut vertices: HashMap<(u32, [u32; 3], u32, u32), u32> = HashMap::new();
    let (mut fanned, mut over_budget) = (0usize, 0usize);
    let mut local = Vec::new();
    let mut ids = Vec::new();
    let mut triangles = Vec::new();
    for (face, (number, corners)) in faces.iter().enumerate() {
        let unit = face_normals[face].normalize_or_zero();
        ids.clear();
        for &k in corners {
            let p = coord(k);
            let (normal, normal_key) = match (&normals, smooth) {
                (Some(attr), _) => {
                    let i = pick(attr, k, *number, p).unwrap_or(0);
                    let n = if input.ccw { attr.values[i] } else { -attr.values[i] };
                    (Some(n), [i as u32, 0, 0])
                }
                (None, true) => {
                    let mut sum = Vec3::ZERO;
                    for &g in &around[p as usize] {
                        let other = face_normals[g as usize];
                        if g as usize == face || unit.dot(other.normalize_or_zero()) >= cos_crease {
                            sum += other;
                        }
                    }
                    let n = sum.normalize_or(unit);
                    (Some(n), n.to_array().map(f32::to_bits))
                }
                (None, false) => (None, [0; 3]),
            };
            let color = colors.as_ref().and_then(|attr| pick(attr, k, *number, p));
            let uv_index = match tex {
                Some((_, index)) if !index.is_empty() => index[k] as u32,
                _ => p as u32,
            };
            let key = (p as u32, normal_key, color.map_or(0, |c| c as u32), uv_index);
            let id = *vertices.entry(key).or_insert_with(|| {
                mesh.positions.push(points[p as usize]);
                if let Some(n) = normal {
                    mesh_normals.push(n);
                }
                if let (Some(attr), Some(c)) = (&colors, color) {
                    mesh_colors.extend_from_slice(&attr.values[c].to_array());
                }
                match (tex, &defaults) {
                    (Some((values, _)), _) => mesh_uvs.push(values[uv_index as usize]),
                    (None, Some(d)) => mesh_uvs.push(d[p as usize]),
                    (None, None) => {}
                }
                mesh.positions.len() as u32 - 1
            });
            ids.push(id);
        }
        local.clear();
        local.extend(corners.iter().map(|&k| position(k)));
        triangles.clear();
        let outline: Vec<u32> = (0..corners.len() as u32).collect();
        let cost = if corners.len() > 3 { corners.len().saturating_mul(corners.len()) } else { 0 };
        if cost > *budget {
            over_budget += 1;
            for k in 1..outline.len() - 1 {
                triangles.push([0, k as u32, k as u32 + 1]);
            }
        } else {
            *budget -= cost;
            if !triangulate_polygon(&[outline], &local, &mut triangles) {
                fanned += 1;
            }
        }
        for t in &triangles {
            let [a, b, c] = t.map(|i| ids[i as usize]);
            if a == b || b == c || a == c {
                continue;
            }
            mesh.triangles.push(if input.ccw { [a, b, c] } else { [a, c, b] });
        }
    }
    if over_budget > 0 {
        problems.push(format!(
            "{over_budget} face(s) cut into a fan from their first vertex: the scene's ear-clipping budget ({}) is spent",
            super::VRML_EAR_CLIP_BUDGET
        ));
    }
    if fanned > 0 {
        problems.push(format!(
            "{fanned} face(s) of more than {} vertices cut into a fan from their first vertex",
            crate::rib::mesh::MAX_EAR_CLIP_VERTICES
        ));
    }
    let count = mesh.positions.len();
    if mesh_normals.len() == count && (normals.is_some() || smooth) {
        mesh.normals = Some(mesh_normals);
    }
    if mesh_uvs.len() == count && count > 0 {
        mesh.uvs = Some(mesh_uvs);
    }
    if mesh_colors.len() == 3 * count && colors.is_some() && count > 0 {
        mesh.attributes.push(Attribute::data("Cs", 3, mesh_colors));
    }
    Made { mesh, problems }
}

/// An ElevationGrid's fields.
#[derive(Clone, Copy, Debug)]
pub struct Grid<'a> {
    pub x_dimension: usize,
    pub z_dimension: usize,
    pub x_spacing: f32,
    pub z_spacing: f32,
    pub height: &'a [f32],
    pub ccw: bool,
    pub crease_angle: f32,
    pub colors: Option<(&'a [Vec3], bool)>,
    pub normals: Option<(&'a [Vec3], bool)>,
    pub tex_coords: Option<&'a [Vec2]>,
}

/// An ElevationGrid: a face set of quads between its points, `x` then `z`, the heights in `y`.
/// The caller checks that `height` has `x_dimension * z_dimension` values.
pub fn elevation_grid<'a>(g: &Grid<'a>, budget: &mut usize) -> Made {
    let (nx, nz) = (g.x_dimension, g.z_dimension);
    let mut points = Vec::with_capacity(nx * nz);
    let mut uvs = Vec::with_capacity(nx * nz);
    for j in 0..nz {
        for i in 0..nx {
            let h = g.height.get(i + j * nx).copied().unwrap_or(0.0);
            points.push(Vec3::new(i as f32 * g.x_spacing, h, j as f32 * g.z_spacing));
            let s = if nx > 1 { i as f32 / (nx - 1) as f32 } else { 0.0 };
            let t = if nz > 1 { j as f32 / (nz - 1) as f32 } else { 0.0 };
            uvs.push(Vec2::new(s, t));
        }
    }
    let mut index = Vec::with_capacity(nx.saturating_sub(1) * nz.saturating_sub(1) * 5);
    for j in 0..nz.saturating_sub(1) {
        for i in 0..nx.saturating_sub(1) {
            let at = |i: usize, j: usize| (i + j * nx) as i32;
            index.extend_from_slice(&[at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j), -1]);
        }
    }
    let indexed = |(values, per_vertex): (&'a [Vec3], bool)| Indexed { values, index: &[], per_vertex };
    face_set(
        &FaceSet {
            points: &points,
            coord_index: &index,
            ccw: g.ccw,
            crease_angle: g.crease_angle,
            normals: g.normals.map(indexed),
            colors: g.colors.map(indexed),
            tex_coords: Some((g.tex_coords.unwrap_or(&uvs), &[])),
            default_tex_coords: false,
        },
        budget,
    )
}

/// An Extrusion's fields.
#[derive(Clone, Debug)]
pub struct Extrusion<'a> {
    pub spine: &'a [Vec3],
    pub cross_section: &'a [Vec2],
    pub scale: &'a [Vec2],
    pub orientation: &'a [Quat],
    pub begin_cap: bool,
    pub end_cap: bool,
    pub ccw: bool,
    pub crease_angle: f32,
}

/// Triangles an extrusion makes at most (sides and caps), from its counts alone.
pub fn extrusion_triangles(spine: usize, cross_section: usize) -> usize {
    let sides = spine.saturating_sub(1).saturating_mul(cross_section.saturating_sub(1)).saturating_mul(2);
    sides.saturating_add(cross_section.saturating_mul(2))
}

/// The spine-aligned cross-section planes: each spine point's x, y and z axes (ISO/IEC 14772-1,
/// 6.18.1).
fn spine_frames(spine: &[Vec3]) -> Vec<[Vec3; 3]> {
    let n = spine.len();
    let closed = n > 2 && spine[0].abs_diff_eq(spine[n - 1], 1e-6);
    let end = |i: usize| i == 0 || i == n - 1;
    let y_at = |i: usize| {
        let d = if closed && end(i) {
            spine[1] - spine[n - 2]
        } else if i == 0 {
            spine[1] - spine[0]
        } else if i == n - 1 {
            spine[n - 1] - spine[n - 2]
        } else {
            spine[i + 1] - spine[i - 1]
        };
        d.normalize_or_zero()
    };
    let z_at = |i: usize| {
        let (here, next, prev) = if closed && end(i) {
            (spine[0], spine[1], spine[n - 2])
        } else if end(i) {
            return None;
        } else {
            (spine[i], spine[i + 1], spine[i - 1])
        };
        let z = (next - here).cross(prev - here);
        (z.length_squared() > 1e-12).then(|| z.normalize())
    };
    let mut zs: Vec<Option<Vec3>> = (0..n).map(z_at).collect();
    if !closed && n >= 3 {
        zs[0] = zs[1];
        zs[n - 1] = zs[n - 2];
    }
    let direction = (0..n).map(y_at).find(|y| y.length_squared() > 0.0).unwrap_or(Vec3::Y);
    let Some(first) = zs.iter().flatten().next().copied() else {
        // A straight spine: the rotation taking +y to it turns the cross-section's plane.
        let r = Quat::from_rotation_arc(Vec3::Y, direction);
        return vec![[r * Vec3::X, r * Vec3::Y, r * Vec3::Z]; n];
    };
    let mut previous: Option<Vec3> = None;
    let mut frames = Vec::with_capacity(n);
    for (i, z) in zs.iter().enumerate() {
        // An undefined z (collinear points) is the one before.
        let mut z = z.or(previous).unwrap_or(first);
        if previous.is_some_and(|p| z.dot(p) < 0.0) {
            z = -z;
        }
        previous = Some(z);
        let y = y_at(i);
        let y = if y.length_squared() > 0.0 { y } else { direction };
        let x = y.cross(z).normalize_or(Vec3::X);
        frames.push([x, y, z]);
    }
    frames
}

/// An Extrusion as a face set: the cross-section scaled, rotated and placed at every spine point,
/// joined by quads, and the caps.
pub fn extrusion(e: &Extrusion, budget: &mut usize) -> Made {
    let (n, m) = (e.spine.len(), e.cross_section.len());
    if n < 2 || m < 2 {
        return Made {
            mesh: Mesh::default(),
            problems: vec!["an Extrusion needs two spine points and two cross-section points".into()],
        };
    }
    let frames = spine_frames(e.spine);
    let pick_scale = |i: usize| e.scale.get(i).or(e.scale.last()).copied().unwrap_or(Vec2::ONE);
    let pick_orient = |i: usize| e.orientation.get(i).or(e.orientation.last()).copied().unwrap_or(Quat::IDENTITY);
    let mut points = Vec::with_capacity(n * m);
    for (i, [x, y, z]) in frames.iter().enumerate() {
        let (s, r) = (pick_scale(i), pick_orient(i));
        for c in e.cross_section {
            let local = r * Vec3::new(c.x * s.x, 0.0, c.y * s.y);
            points.push(e.spine[i] + *x * local.x + *y * local.y + *z * local.z);
        }
    }
    // Texture coordinates: s along the cross-section, t along the spine, by length.
    let along = |lengths: Vec<f32>| {
        let total = lengths.last().copied().unwrap_or(0.0);
        let count = lengths.len().saturating_sub(1).max(1) as f32;
        lengths
            .iter()
            .enumerate()
            .map(|(k, l)| if total > 0.0 { l / total } else { k as f32 / count })
            .collect::<Vec<f32>>()
    };
    let cumulative = |d: &mut dyn Iterator<Item = f32>| {
        let mut acc = 0.0;
        std::iter::once(0.0)
            .chain(d.map(|x| {
                acc += x;
                acc
            }))
            .collect::<Vec<f32>>()
    };
    let ss = along(cumulative(&mut e.cross_section.windows(2).map(|w| w[0].distance(w[1]))));
    let ts = along(cumulative(&mut e.spine.windows(2).map(|w| w[0].distance(w[1]))));
    let mut uvs = Vec::with_capacity(n * m + 2 * m);
    for t in &ts {
        for s in &ss {
            uvs.push(Vec2::new(*s, *t));
        }
    }
    let mut index = Vec::new();
    let mut uv_index = Vec::new();
    let at = |i: usize, j: usize| (i * m + j) as i32;
    for i in 0..n - 1 {
        for j in 0..m - 1 {
            let quad = [at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)];
            index.extend_from_slice(&quad);
            index.push(-1);
            uv_index.extend_from_slice(&quad);
            uv_index.push(-1);
        }
    }
    // Caps: the cross-section (without a repeated closing point), its texture coordinates the
    // cross-section scaled so that its longer side spans 0 to 1.
    let closed_section = m > 2 && e.cross_section[0].abs_diff_eq(e.cross_section[m - 1], 1e-6);
    let cap_count = if closed_section { m - 1 } else { m };
    let (lo, hi) =
        e.cross_section.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), c| (lo.min(*c), hi.max(*c)));
    let side = (hi - lo).max_element();
    let cap_uv_base = uvs.len() as i32;
    for c in &e.cross_section[..cap_count] {
        let uv = if side > 0.0 { (*c - lo) / side } else { Vec2::ZERO };
        // The cross-section's z runs down the texture as seen from +y.
        uvs.push(Vec2::new(uv.x, 1.0 - uv.y));
    }
    let cap = |i: usize, reverse: bool, index: &mut Vec<i32>, uv_index: &mut Vec<i32>| {
        let mut js: Vec<usize> = (0..cap_count).collect();
        if reverse {
            js.reverse();
        }
        for j in js {
            index.push(at(i, j));
            uv_index.push(cap_uv_base + j as i32);
        }
        index.push(-1);
        uv_index.push(-1);
    };
    if e.begin_cap && cap_count >= 3 {
        cap(0, true, &mut index, &mut uv_index);
    }
    if e.end_cap && cap_count >= 3 {
        cap(n - 1, false, &mut index, &mut uv_index);
    }
    face_set(
        &FaceSet {
            points: &points,
            coord_index: &index,
            ccw: e.ccw,
            crease_angle: e.crease_angle,
            normals: None,
            colors: None,
            tex_coords: Some((&uvs, &uv_index)),
            default_tex_coords: false,
        },
        budget,
    )
}

/// A mesh from per-vertex arrays.
fn mesh_of(positions: Vec<Vec3>, normals: Vec<Vec3>, uvs: Vec<Vec2>, triangles: Vec<[u32; 3]>) -> Mesh {
    Mesh { positions, normals: Some(normals), uvs: Some(uvs), triangles, ..Default::default() }
}

/// A Box of `size` about the origin, each face textured whole, upright as VRML says.
pub fn box_mesh(size: Vec3) -> Mesh {
    let h = size * 0.5;
    // (normal, s direction, t direction): s x t = normal, so faces wind counter-clockwise.
    let faces = [
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
    ];
    let (mut p, mut n, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (normal, s, t) in faces {
        let base = p.len() as u32;
        for (a, b) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            let local = normal + s * (2.0 * a - 1.0) + t * (2.0 * b - 1.0);
            p.push(local * h);
            n.push(normal);
            uv.push(Vec2::new(a, b));
        }
        tris.push([base, base + 1, base + 2]);
        tris.push([base, base + 2, base + 3]);
    }
    mesh_of(p, n, uv, tris)
}

/// The point of a round shape at angle `theta` around +y (0 at -z, turning towards -x: VRML's
/// texture seam at the back, `s` growing counter-clockwise seen from above).
fn around(theta: f32) -> Vec3 {
    Vec3::new(-theta.sin(), 0.0, -theta.cos())
}

/// A Sphere of `radius`.
pub fn sphere(radius: f32) -> Mesh {
    let (segments, rings) = (ROUND_SEGMENTS, ROUND_SEGMENTS / 2);
    let (mut p, mut n, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for r in 0..=rings {
        let t = r as f32 / rings as f32;
        let phi = std::f32::consts::PI * (t - 0.5);
        for s in 0..=segments {
            let u = s as f32 / segments as f32;
            let dir = around(u * std::f32::consts::TAU) * phi.cos() + Vec3::Y * phi.sin();
            p.push(dir * radius);
            n.push(dir);
            uv.push(Vec2::new(u, t));
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (r * row + s, r * row + s + 1, (r + 1) * row + s + 1, (r + 1) * row + s);
            if r > 0 {
                tris.push([a, b, c]);
            }
            if r + 1 < rings {
                tris.push([a, c, d]);
            }
        }
    }
    mesh_of(p, n, uv, tris)
}

/// A disk cap of a Cylinder or Cone at height `y`, facing up or down.
fn cap(
    p: &mut Vec<Vec3>,
    n: &mut Vec<Vec3>,
    uv: &mut Vec<Vec2>,
    tris: &mut Vec<[u32; 3]>,
    y: f32,
    radius: f32,
    up: bool,
) {
    let base = p.len() as u32;
    let normal = if up { Vec3::Y } else { Vec3::NEG_Y };
    p.push(Vec3::new(0.0, y, 0.0));
    n.push(normal);
    uv.push(Vec2::splat(0.5));
    for s in 0..=ROUND_SEGMENTS {
        let d = around(s as f32 / ROUND_SEGMENTS as f32 * std::f32::consts::TAU);
        p.push(Vec3::new(d.x * radius, y, d.z * radius));
        n.push(normal);
        // Seen from above with -z up (top), or from below with +z up (bottom).
        uv.push(if up {
            Vec2::new(0.5 + d.x * 0.5, 0.5 - d.z * 0.5)
        } else {
            Vec2::new(0.5 + d.x * 0.5, 0.5 + d.z * 0.5)
        });
    }
    for s in 0..ROUND_SEGMENTS {
        let (a, b) = (base + 1 + s, base + 2 + s);
        // `around` turns counter-clockwise seen from +y.
        tris.push(if up { [base, a, b] } else { [base, b, a] });
    }
}

/// A Cylinder along y, its parts as its flags say.
pub fn cylinder(radius: f32, height: f32, side: bool, top: bool, bottom: bool) -> Mesh {
    let (mut p, mut n, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let h = height * 0.5;
    if side {
        for s in 0..=ROUND_SEGMENTS {
            let u = s as f32 / ROUND_SEGMENTS as f32;
            let d = around(u * std::f32::consts::TAU);
            for (y, t) in [(-h, 0.0), (h, 1.0)] {
                p.push(Vec3::new(d.x * radius, y, d.z * radius));
                n.push(d);
                uv.push(Vec2::new(u, t));
            }
        }
        for s in 0..ROUND_SEGMENTS {
            let (a, b, c, d) = (2 * s, 2 * s + 2, 2 * s + 3, 2 * s + 1);
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    if top {
        cap(&mut p, &mut n, &mut uv, &mut tris, h, radius, true);
    }
    if bottom {
        cap(&mut p, &mut n, &mut uv, &mut tris, -h, radius, false);
    }
    mesh_of(p, n, uv, tris)
}

/// A Cone along y, apex up, its parts as its flags say.
pub fn cone(bottom_radius: f32, height: f32, side: bool, bottom: bool) -> Mesh {
    let (mut p, mut n, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let h = height * 0.5;
    if side {
        let slope = Vec2::new(height, bottom_radius).normalize_or(Vec2::X);
        for s in 0..=ROUND_SEGMENTS {
            let u = s as f32 / ROUND_SEGMENTS as f32;
            let d = around(u * std::f32::consts::TAU);
            let normal = (d * slope.x + Vec3::Y * slope.y).normalize_or(Vec3::Y);
            p.push(Vec3::new(d.x * bottom_radius, -h, d.z * bottom_radius));
            p.push(Vec3::new(0.0, h, 0.0));
            n.push(normal);
            n.push(normal);
            uv.push(Vec2::new(u, 0.0));
            uv.push(Vec2::new(u, 1.0));
        }
        for s in 0..ROUND_SEGMENTS {
            tris.push([2 * s, 2 * s + 2, 2 * s + 1]);
        }
    }
    if bottom {
        cap(&mut p, &mut n, &mut uv, &mut tris, -h, bottom_radius, false);
    }
    mesh_of(p, n, uv, tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fs(input: &FaceSet) -> Made {
        let mut budget = usize::MAX;
        face_set(input, &mut budget)
    }

    fn ext(input: &Extrusion) -> Made {
        let mut budget = usize::MAX;
        extrusion(input, &mut budget)
    }

    /// The signed volume a closed mesh encloses: positive when its triangles face out.
    fn outward(mesh: &Mesh) -> f32 {
        let mut flux = 0.0;
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.corners(t);
            flux += a.dot((b - a).cross(c - a)) / 6.0;
        }
        flux
    }

    #[test]
    fn primitives_are_closed_and_face_out() {
        let b = box_mesh(Vec3::new(2.0, 4.0, 6.0));
        b.validate().expect("valid");
        assert!((outward(&b) - 48.0).abs() < 1e-3, "{}", outward(&b));
        let s = sphere(1.0);
        s.validate().expect("valid");
        let v = outward(&s);
        assert!(v > 4.0 && v < 4.19, "{v}");
        let c = cylinder(1.0, 2.0, true, true, true);
        c.validate().expect("valid");
        let v = outward(&c);
        assert!(v > 6.1 && v < 6.29, "{v}");
        let k = cone(1.0, 3.0, true, true);
        k.validate().expect("valid");
        let v = outward(&k);
        assert!(v > 3.0 && v < 3.15, "{v}");
        // The front of a Box shows its texture upright: (0, 0) at the lower left.
        let front: Vec<(Vec3, Vec2)> = (0..4).map(|i| (b.positions[i], b.uvs.as_ref().unwrap()[i])).collect();
        assert_eq!(front[0], (Vec3::new(-1.0, -2.0, 3.0), Vec2::new(0.0, 0.0)));
        assert_eq!(front[2], (Vec3::new(1.0, 2.0, 3.0), Vec2::new(1.0, 1.0)));
    }

    #[test]
    fn concave_faces_and_separators() {
        // An L-shaped hexagon (concave at (1, 1)), then a triangle, with -1 between and a
        // trailing -1.
        let points = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(5.0, 0.0, 0.0),
        ];
        let index = [0, 1, 2, 3, 4, 5, -1, 1, 6, 2, -1];
        let made = fs(&FaceSet { points: &points, coord_index: &index, ccw: true, ..FaceSet::default() });
        assert!(made.problems.is_empty(), "{:?}", made.problems);
        let m = made.mesh;
        assert_eq!(m.triangle_count(), 4 + 1);
        let mut area = 0.0;
        for t in 0..m.triangle_count() {
            let [a, b, c] = m.corners(t);
            let z = (b - a).cross(c - a).z;
            assert!(z > 0.0, "every triangle faces +z as the face winds");
            area += 0.5 * z;
        }
        // The L is 3 units, the triangle 1.5: fanning the L from its first vertex would cover 4.
        assert!((area - 4.5).abs() < 1e-5, "{area}");
        assert!(m.normals.is_none(), "flat faces need no normals");
        // Past the ear-clipping budget faces are fanned: the L's fan covers its notch.
        let mut budget = 35;
        let fanned =
            face_set(&FaceSet { points: &points, coord_index: &index, ccw: true, ..FaceSet::default() }, &mut budget);
        assert!(fanned.problems[0].contains("budget"), "{:?}", fanned.problems);
        assert_eq!(budget, 35, "nothing was spent: the L costs 36");
        // ccw FALSE turns the triangles around.
        let flipped = fs(&FaceSet { points: &points, coord_index: &index, ccw: false, ..FaceSet::default() }).mesh;
        let [a, b, c] = flipped.corners(0);
        assert!((b - a).cross(c - a).z < 0.0);
    }

    #[test]
    fn bad_indices_are_problems_not_panics() {
        let points = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let made = fs(&FaceSet {
            points: &points,
            coord_index: &[0, 1, 7, -1, 0, 1, -1, 0, 1, 2],
            ccw: true,
            ..FaceSet::default()
        });
        assert_eq!(made.mesh.triangle_count(), 1);
        assert_eq!(made.problems.len(), 2, "{:?}", made.problems);
        let colors = [Vec3::ONE];
        let made = fs(&FaceSet {
            points: &points,
            coord_index: &[0, 1, 2],
            ccw: true,
            colors: Some(Indexed { values: &colors, index: &[0, 0, 3], per_vertex: true }),
            ..FaceSet::default()
        });
        assert!(made.mesh.attributes.is_empty());
        assert!(made.problems[0].contains("colours"), "{:?}", made.problems);
    }

    #[test]
    fn crease_angle_smooths_shared_vertices() {
        // A 3x3 grid of points bent along its middle row by a small angle: four quads.
        let mut points = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                let y = if j == 1 { 0.1 } else { 0.0 };
                points.push(Vec3::new(i as f32, y, j as f32));
            }
        }
        let at = |i: i32, j: i32| i + 3 * j;
        let mut index = Vec::new();
        for j in 0..2 {
            for i in 0..2 {
                index.extend_from_slice(&[at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j), -1]);
            }
        }
        let smooth =
            fs(&FaceSet { points: &points, coord_index: &index, ccw: true, crease_angle: 0.5, ..FaceSet::default() })
                .mesh;
        // One vertex a point, each with the mean of the normals around it.
        assert_eq!(smooth.positions.len(), 9);
        let normals = smooth.normals.as_ref().expect("smoothed");
        let centre = smooth.positions.iter().position(|p| *p == Vec3::new(1.0, 0.1, 1.0)).expect("centre");
        assert!(normals[centre].abs_diff_eq(Vec3::Y, 1e-5), "{}", normals[centre]);
        assert!(normals.iter().all(|n| n.y > 0.9));
        // Below the bend's angle the faces keep their own normals: points are split.
        let creased =
            fs(&FaceSet { points: &points, coord_index: &index, ccw: true, crease_angle: 0.05, ..FaceSet::default() })
                .mesh;
        assert!(creased.positions.len() > 9, "{}", creased.positions.len());
    }

    #[test]
    fn per_face_colours_and_given_normals() {
        let points = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let colors = [Vec3::X, Vec3::Y];
        let normals = [Vec3::Z];
        let made = fs(&FaceSet {
            points: &points,
            coord_index: &[0, 1, 2, -1, 0, 2, 3, -1],
            ccw: true,
            colors: Some(Indexed { values: &colors, index: &[], per_vertex: false }),
            normals: Some(Indexed { values: &normals, index: &[0, 0, 0, 0, 0, 0, 0, 0], per_vertex: true }),
            ..FaceSet::default()
        });
        let m = made.mesh;
        assert!(made.problems.is_empty(), "{:?}", made.problems);
        // Points 0 and 2 are in both faces, with different colours: six vertices.
        assert_eq!(m.positions.len(), 6);
        let cs = &m.attributes[0];
        assert_eq!(cs.name, "Cs");
        let colour = |v: u32| Vec3::from_slice(&cs.data[3 * v as usize..]);
        assert_eq!(colour(m.triangles[0][0]), Vec3::X);
        assert_eq!(colour(m.triangles[1][0]), Vec3::Y);
        assert!(m.normals.as_ref().unwrap().iter().all(|n| *n == Vec3::Z));
    }

    #[test]
    fn default_texture_coordinates_follow_the_longest_side() {
        let uv = default_tex_coords(&[Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 2.0, 0.0)]);
        assert_eq!(uv, vec![Vec2::ZERO, Vec2::new(1.0, 0.5)]);
    }

    #[test]
    fn grids_and_extrusions() {
        let heights = [0.0; 6];
        let g = elevation_grid(
            &Grid {
                x_dimension: 3,
                z_dimension: 2,
                x_spacing: 1.0,
                z_spacing: 2.0,
                height: &heights,
                ccw: true,
                crease_angle: 0.0,
                colors: None,
                normals: None,
                tex_coords: None,
            },
            &mut 1000,
        );
        assert_eq!(g.mesh.triangle_count(), 4);
        let [a, b, c] = g.mesh.corners(0);
        assert!((b - a).cross(c - a).y > 0.0, "a grid faces +y");
        // VRML's default Extrusion: the unit cube from y = 0 to 1, closed, facing out.
        let section = [
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, -1.0),
            Vec2::new(-1.0, -1.0),
            Vec2::new(-1.0, 1.0),
            Vec2::new(1.0, 1.0),
        ];
        let e = ext(&Extrusion {
            spine: &[Vec3::ZERO, Vec3::Y],
            cross_section: &section,
            scale: &[Vec2::ONE],
            orientation: &[Quat::IDENTITY],
            begin_cap: true,
            end_cap: true,
            ccw: true,
            crease_angle: 0.0,
        });
        assert!(e.problems.is_empty(), "{:?}", e.problems);
        assert_eq!(e.mesh.triangle_count(), 8 + 4);
        let flux = outward(&e.mesh);
        // Volume 4 (2 x 1 x 2).
        assert!((flux - 4.0).abs() < 1e-4, "{flux}");
        // A bent spine keeps the sections perpendicular to it.
        let e = ext(&Extrusion {
            spine: &[Vec3::ZERO, Vec3::Y, Vec3::new(1.0, 2.0, 0.0)],
            cross_section: &section,
            scale: &[Vec2::splat(0.1)],
            orientation: &[],
            begin_cap: false,
            end_cap: false,
            ccw: true,
            crease_angle: 0.0,
        });
        assert_eq!(e.mesh.triangle_count(), 16);
        e.mesh.validate().expect("valid");
    }
}

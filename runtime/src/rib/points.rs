//! `Points` (RISpec 3.2, section 5.6) to triangle meshes: each point of `P` a small disk (or a
//! sphere), tessellated, not intersected exactly.
//!
//! - Size: `"width"` (varying float: one diameter per point; uniform or constant: one for all),
//!   else `"constantwidth"` (one value), else 1, in object space. A point whose width is not
//!   positive and finite is left out.
//! - Shape: a disk facing the camera ([`View::facing`]: RenderMan's default), or facing along the
//!   point's `"N"` when given; with `"uniform string type" "sphere"` (3Delight's name for it) a
//!   sphere of that diameter. Another type is a warning, and the point is a disk.
//! - Segments: a disk is a fan of `n` triangles around its centre, `n` one for every 1/512 of the
//!   image's shorter side that the point's diameter spans ([`View::fraction`]), at least
//!   [`MIN_POINT_SEGMENTS`], at most [`MAX_POINT_SEGMENTS`]. A sphere has `n` segments around and
//!   `max(n / 2, 4)` rings from pole to pole, `2 n (rings - 1)` triangles (the triangles collapsed
//!   at the poles are left out). All of it comes from `P`, the widths and the view, so the
//!   triangles are counted before any is made ([`points_triangles`]).
//! - Parameters: a disk's `(u, v)` run across it from 0 to 1 as a square texture laid over it
//!   (`(0.5, 0.5)` at the centre); a sphere's as a `Sphere`'s (`u` around its z axis, `v` from the
//!   bottom pole to the top). `s t` are `u v` unless `st` (or `s` and `t`) is given.
//! - Primitive variables: varying, vertex and facevarying data has one value per point, uniform
//!   and constant data one for all; each point takes its value all over (RISpec: a particle is
//!   shaded as one). `Cs`, `Os` and the rest reach the shaders as per-vertex attributes.
//!
//! Invariants: a wrong count of `"width"`, `"constantwidth"` or `"N"`, or a `P` that is not finite,
//! is an `Err` (the request is skipped); a wrong count of other data drops it with a warning, as
//! for every primitive. Allocations are bounded by the point count times
//! [`MAX_POINT_SEGMENTS`]-based sizes; nothing recurses; normals are never NaN.

use glam::{Vec2, Vec3};

use super::decl::Class;
use super::mesh::{per_vertex_params, positions, reserve_mesh, route_attributes_keeping_uv, ClassCounts, MeshOptions};
use super::request::{find_param, Param};
use super::view::View;
use crate::geometry::Mesh;

/// The most segments around a point's disk (or sphere).
pub const MAX_POINT_SEGMENTS: u32 = 64;

/// The fewest segments around a point's disk (or sphere).
pub const MIN_POINT_SEGMENTS: u32 = 8;

/// Segments a point gets for each image's shorter side its diameter spans.
const SEGMENTS_PER_VIEW: f32 = 512.0;

/// The fewest rings of a point's sphere.
const MIN_SPHERE_RINGS: u32 = 4;

/// What each point is drawn as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Disk,
    Sphere,
}

/// A `Points` request checked and sized, before anything is tessellated.
struct PointsPlan {
    points: Vec<Vec3>,
    /// The diameter of each point.
    widths: Vec<f32>,
    /// The `N` of each point, when given.
    normals: Option<Vec<Vec3>>,
    shape: Shape,
    /// Segments around each point; 0 for a point left out.
    segments: Vec<u32>,
}

/// The rings of a sphere of `segments` segments around.
fn rings(segments: u32) -> u32 {
    (segments / 2).max(MIN_SPHERE_RINGS)
}

/// The segments around a point whose diameter spans `fraction` of the image's shorter side.
fn point_segments(fraction: f32) -> u32 {
    let n = (SEGMENTS_PER_VIEW * fraction).ceil();
    if n.is_finite() {
        (n.min(MAX_POINT_SEGMENTS as f32) as u32).max(MIN_POINT_SEGMENTS)
    } else {
        MIN_POINT_SEGMENTS
    }
}

/// One float per point (`values` of a class with one value per point) or one for all (uniform and
/// constant): the value of each point, or an error naming the parameter.
fn per_point(p: &Param, n: usize) -> Result<Vec<f32>, String> {
    let values = p
        .floats()
        .filter(|_| p.decl.components() == 1)
        .ok_or_else(|| format!("\"{}\" ({}) must be a float", p.name, p.decl))?;
    match p.decl.class {
        Class::Constant | Class::Uniform if values.len() == 1 => Ok(vec![values[0]; n]),
        Class::Constant | Class::Uniform => {
            Err(format!("\"{}\" ({}) has {} values where Points needs 1", p.name, p.decl, values.len()))
        }
        _ if values.len() == n => Ok(values.to_vec()),
        _ => Err(format!("\"{}\" ({}) has {} values where {n} points need {n}", p.name, p.decl, values.len())),
    }
}

impl PointsPlan {
    fn new(params: &[Param], view: &View, warnings: &mut Vec<String>) -> Result<PointsPlan, String> {
        let points = positions(params)?;
        if points.iter().any(|p| !p.is_finite()) {
            return Err("a point of \"P\" is not finite".into());
        }
        let n = points.len();
        let widths = match (find_param(params, "width"), find_param(params, "constantwidth")) {
            (Some(width), _) => per_point(width, n)?,
            (None, Some(constant)) => match constant.floats() {
                Some(&[w]) => vec![w; n],
                _ => return Err(format!("\"constantwidth\" ({}) must be one float", constant.decl)),
            },
            (None, None) => vec![1.0; n],
        };
        let normals = match find_param(params, "N") {
            None => None,
            Some(p) => {
                let values = p
                    .floats()
                    .filter(|_| p.decl.components() == 3)
                    .ok_or_else(|| format!("\"N\" ({}) must be a normal (three floats a value)", p.decl))?;
                let given: Vec<Vec3> = values.chunks_exact(3).map(Vec3::from_slice).collect();
                Some(match p.decl.class {
                    Class::Constant | Class::Uniform if given.len() == 1 => vec![given[0]; n],
                    Class::Constant | Class::Uniform => {
                        return Err(format!("\"N\" ({}) has {} values where Points needs 1", p.decl, given.len()))
                    }
                    _ if given.len() == n => given,
                    _ => {
                        return Err(format!("\"N\" ({}) has {} values where {n} points need {n}", p.decl, given.len()))
                    }
                })
            }
        };
        let shape = match find_param(params, "type") {
            None => Shape::Disk,
            Some(p) => match p.strings().and_then(|s| s.first()).map(String::as_str) {
                Some("disk") => Shape::Disk,
                Some("sphere") => Shape::Sphere,
                other => {
                    warnings.push(format!(
                        "point type {} is not supported (\"disk\" or \"sphere\"): the points are disks",
                        other.map_or_else(|| "that is not a string".to_string(), |s| format!("\"{s}\""))
                    ));
                    Shape::Disk
                }
            },
        };
        let segments = points
            .iter()
            .zip(&widths)
            .map(|(&p, &w)| if w > 0.0 && w.is_finite() { point_segments(view.fraction(p, w)) } else { 0 })
            .collect();
        Ok(PointsPlan { points, widths, normals, shape, segments })
    }

    /// The triangles of a point of `segments` segments.
    fn point_triangles(&self, segments: u32) -> usize {
        let n = segments as usize;
        match (segments, self.shape) {
            (0, _) => 0,
            (_, Shape::Disk) => n,
            (_, Shape::Sphere) => 2 * n * (rings(segments) as usize - 1),
        }
    }

    /// The vertices of a point of `segments` segments.
    fn point_vertices(&self, segments: u32) -> usize {
        let n = segments as usize;
        match (segments, self.shape) {
            (0, _) => 0,
            (_, Shape::Disk) => n + 1,
            (_, Shape::Sphere) => (n + 1) * (rings(segments) as usize + 1),
        }
    }

    fn triangles(&self) -> usize {
        self.segments.iter().map(|&s| self.point_triangles(s)).fold(0, usize::saturating_add)
    }
}

/// The triangles [`points_mesh`] makes of the same request, worked out without tessellating (0 for
/// a request it refuses).
pub fn points_triangles(params: &[Param], options: &MeshOptions) -> usize {
    plan(params, options, &mut Vec::new()).map_or(0, |plan| plan.triangles())
}

/// The segments of each point [`points_mesh`] makes of the same request (`None` when it refuses
/// it).
pub fn points_segments(params: &[Param], options: &MeshOptions) -> Option<Vec<u32>> {
    plan(params, options, &mut Vec::new()).ok().map(|plan| plan.segments)
}

/// The plan of a `Points` request, with the segments `options` fixes where it fixes them.
fn plan(params: &[Param], options: &MeshOptions, warnings: &mut Vec<String>) -> Result<PointsPlan, String> {
    let mut plan = PointsPlan::new(params, &options.view, warnings)?;
    if let Some(fixed) = options.segments.as_deref().filter(|s| s.len() == plan.segments.len()) {
        plan.segments = fixed.to_vec();
    }
    Ok(plan)
}

/// `Points`: a disk (or sphere) per point of `P`.
pub fn points_mesh(params: &[Param], options: &MeshOptions, warnings: &mut Vec<String>) -> Result<Mesh, String> {
    let plan = plan(params, options, warnings)?;
    let n = plan.points.len();
    let counts = ClassCounts { vertex: n, varying: n, face: 1, corner: Some(n) };
    let data: Vec<_> = per_vertex_params(params, &counts, warnings)
        .into_iter()
        .filter(|d| !matches!(d.name.as_str(), "N" | "width"))
        .collect();

    let vertices = plan.segments.iter().map(|&s| plan.point_vertices(s)).fold(0, usize::saturating_add);
    let (mut mesh, mut attributes) = reserve_mesh(vertices, plan.triangles(), &data);
    for (k, (&centre, &segments)) in plan.points.iter().zip(&plan.segments).enumerate() {
        if segments == 0 {
            continue;
        }
        let radius = 0.5 * plan.widths[k];
        let before = mesh.positions.len();
        match plan.shape {
            Shape::Disk => {
                let given = plan.normals.as_ref().and_then(|normals| normals[k].try_normalize());
                let facing = given.unwrap_or_else(|| options.view.facing(centre));
                disk(&mut mesh, centre, radius, facing, segments);
            }
            Shape::Sphere => sphere(&mut mesh, centre, radius, segments),
        }
        let added = mesh.positions.len() - before;
        for (attribute, d) in attributes.iter_mut().zip(&data) {
            let index = if d.class == Class::Uniform { 0 } else { k };
            let value = &d.values[index * d.components..(index + 1) * d.components];
            for _ in 0..added {
                attribute.data.extend_from_slice(value);
            }
        }
    }
    route_attributes_keeping_uv(&mut mesh, attributes);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

/// A disk of `segments` triangles around `centre`, perpendicular to the unit vector `facing` and
/// wound counter-clockwise seen from where it points.
fn disk(mesh: &mut Mesh, centre: Vec3, radius: f32, facing: Vec3, segments: u32) {
    let a = facing.any_orthonormal_vector();
    let b = facing.cross(a);
    let first = mesh.positions.len() as u32;
    mesh.positions.push(centre);
    push_vertex_data(mesh, facing, Vec2::splat(0.5));
    for k in 0..segments {
        let angle = std::f32::consts::TAU * k as f32 / segments as f32;
        let (sin, cos) = angle.sin_cos();
        mesh.positions.push(centre + radius * (cos * a + sin * b));
        push_vertex_data(mesh, facing, Vec2::new(0.5 + 0.5 * cos, 0.5 + 0.5 * sin));
    }
    for k in 0..segments {
        mesh.triangles.push([first, first + 1 + k, first + 1 + (k + 1) % segments]);
    }
}

/// A sphere about `centre`: `segments` around its z axis, [`rings`] from pole to pole, normals out.
fn sphere(mesh: &mut Mesh, centre: Vec3, radius: f32, segments: u32) {
    let rings = rings(segments);
    let first = mesh.positions.len() as u32;
    for j in 0..=rings {
        let v = j as f32 / rings as f32;
        let (sin_polar, cos_polar) = (std::f32::consts::PI * v).sin_cos();
        for k in 0..=segments {
            let u = k as f32 / segments as f32;
            let (sin, cos) = (std::f32::consts::TAU * u).sin_cos();
            let normal = Vec3::new(sin_polar * cos, sin_polar * sin, -cos_polar);
            mesh.positions.push(centre + radius * normal);
            push_vertex_data(mesh, normal, Vec2::new(u, v));
        }
    }
    let at = |j: u32, k: u32| first + j * (segments + 1) + k;
    for j in 0..rings {
        for k in 0..segments {
            let (a, b, c, d) = (at(j, k), at(j, k + 1), at(j + 1, k + 1), at(j + 1, k));
            // The triangle against a pole, whose two corners there coincide, is left out.
            if j > 0 {
                mesh.triangles.push([a, b, c]);
            }
            if j + 1 < rings {
                mesh.triangles.push([a, c, d]);
            }
        }
    }
}

fn push_vertex_data(mesh: &mut Mesh, normal: Vec3, uv: Vec2) {
    if let Some(normals) = mesh.normals.as_mut() {
        normals.push(normal);
    }
    if let Some(uvs) = mesh.uvs.as_mut() {
        uvs.push(uv);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::view::Projection;
    use crate::rib::{mesh_from_request_with, parse_str, request_triangles, RibDiagnostic};
    use glam::Affine3A;

    fn build(text: &str, options: &MeshOptions) -> (Option<Mesh>, Vec<RibDiagnostic>) {
        let parse = parse_str(text, "points.rib");
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let mut diagnostics = Vec::new();
        let mesh = mesh_from_request_with(&parse.requests[0], options, &mut diagnostics);
        if let Some(mesh) = &mesh {
            assert_eq!(request_triangles(&parse.requests[0], options), mesh.triangle_count(), "{text}");
        }
        (mesh, diagnostics)
    }

    fn mesh(text: &str) -> Mesh {
        let (mesh, diagnostics) = build(text, &MeshOptions::default());
        mesh.unwrap_or_else(|| panic!("{diagnostics:?}"))
    }

    /// The unit normal of triangle `t` by its winding.
    fn winding_normal(mesh: &Mesh, t: usize) -> Vec3 {
        let [a, b, c] = mesh.corners(t);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn a_disk_faces_the_camera_with_its_radius() {
        // The default view: the eye at the origin.
        let mesh = mesh(r#"Points "P" [0 0 5  3 4 10] "constantwidth" 2"#);
        for (k, centre) in [Vec3::new(0.0, 0.0, 5.0), Vec3::new(3.0, 4.0, 10.0)].into_iter().enumerate() {
            let to_eye = -centre.normalize();
            let disk: Vec<usize> = (0..mesh.triangle_count()).filter(|&t| mesh.corners(t)[0] == centre).collect();
            assert!(disk.len() >= MIN_POINT_SEGMENTS as usize, "point {k}");
            for &t in &disk {
                for (corner, &i) in mesh.triangles[t].iter().enumerate().skip(1) {
                    let p = mesh.positions[i as usize];
                    assert!(((p - centre).length() - 1.0).abs() < 1e-5, "radius at corner {corner}");
                    assert!((p - centre).dot(to_eye).abs() < 1e-5, "the disk is not perpendicular to the view");
                }
                assert!(winding_normal(&mesh, t).dot(to_eye) > 0.999);
                for &i in &mesh.triangles[t] {
                    assert!((mesh.normals.as_ref().unwrap()[i as usize] - to_eye).length() < 1e-5);
                }
            }
        }
        // The view through a transform, and an orthographic one.
        let options = MeshOptions {
            view: View {
                world_from_object: Affine3A::from_translation(Vec3::new(0.0, 0.0, 5.0)),
                projection: Projection::Orthographic { forward: Vec3::new(1.0, 0.0, 1.0).normalize(), across: 2.0 },
            },
            ..Default::default()
        };
        let (m, _) = build(r#"Points "P" [0 0 0]"#, &options);
        let m = m.unwrap();
        assert!(winding_normal(&m, 0).dot(-Vec3::new(1.0, 0.0, 1.0).normalize()) > 0.999);
    }

    #[test]
    fn points_take_n_width_and_data() {
        let m = mesh(
            r#"Points "P" [0 0 5  3 0 5] "width" [0.5 1] "N" [1 0 0  0 1 0] "Cs" [1 0 0  0 0 1]
               "uniform float id" 7 "st" [0.1 0.2  0.3 0.4]"#,
        );
        let normals = m.normals.as_ref().unwrap();
        let cs = m.attributes.iter().find(|a| a.name == "Cs").unwrap();
        let st = m.attributes.iter().find(|a| a.name == "st").unwrap();
        let id = m.attributes.iter().find(|a| a.name == "id").unwrap();
        assert!(m.attributes.iter().all(|a| a.name != "N" && a.name != "width"));
        for (i, p) in m.positions.iter().enumerate() {
            let first = p.x < 1.5;
            let (centre, radius, n) = if first {
                (Vec3::new(0.0, 0.0, 5.0), 0.25, Vec3::X)
            } else {
                (Vec3::new(3.0, 0.0, 5.0), 0.5, Vec3::Y)
            };
            assert!((*p - centre).length() <= radius + 1e-5);
            assert!((*p - centre).dot(n).abs() < 1e-6, "disk {i} is not across its N");
            assert_eq!(normals[i], n);
            assert_eq!(&cs.data[3 * i..3 * i + 3], if first { &[1.0, 0.0, 0.0] } else { &[0.0, 0.0, 1.0] });
            assert_eq!(&st.data[2 * i..2 * i + 2], if first { &[0.1, 0.2] } else { &[0.3, 0.4] });
            assert_eq!(id.data[i], 7.0);
        }
        // The uvs lay a square texture over the disk: the centre at (0.5, 0.5).
        assert_eq!(m.uvs.as_ref().unwrap()[0], Vec2::splat(0.5));
    }

    #[test]
    fn segments_follow_the_apparent_size() {
        let far = mesh(r#"Points "P" [0 0 100] "constantwidth" 0.01"#);
        assert_eq!(far.triangle_count(), MIN_POINT_SEGMENTS as usize);
        // 0.1 across at distance 5 spans about 1/78 of the 90 degree view: 512 / 78, so 7, and 8.
        let small = mesh(r#"Points "P" [0 0 5] "constantwidth" 0.1"#);
        assert_eq!(small.triangle_count(), 8);
        // 1 across at distance 5: about 11.4 degrees, 0.127 of the view: 65 segments, capped.
        let near = mesh(r#"Points "P" [0 0 5] "constantwidth" 1"#);
        assert_eq!(near.triangle_count(), MAX_POINT_SEGMENTS as usize);
        let middle = mesh(r#"Points "P" [0 0 10] "constantwidth" 0.25"#);
        let expected = point_segments(View::default().fraction(Vec3::new(0.0, 0.0, 10.0), 0.25));
        assert!(expected > MIN_POINT_SEGMENTS && expected < MAX_POINT_SEGMENTS);
        assert_eq!(middle.triangle_count(), expected as usize);
    }

    #[test]
    fn sphere_points_are_spheres() {
        let m = mesh(r#"Points "P" [1 2 300] "constantwidth" 0.5 "uniform string type" "sphere""#);
        let n = MIN_POINT_SEGMENTS as usize;
        assert_eq!(m.triangle_count(), 2 * n * (rings(MIN_POINT_SEGMENTS) as usize - 1));
        let centre = Vec3::new(1.0, 2.0, 300.0);
        for (p, normal) in m.positions.iter().zip(m.normals.as_ref().unwrap()) {
            assert!(((*p - centre).length() - 0.25).abs() < 1e-5);
            assert!((*normal - (*p - centre) * 4.0).length() < 1e-4);
        }
        for t in 0..m.triangle_count() {
            let [a, ..] = m.corners(t);
            assert!(winding_normal(&m, t).dot(a - centre) > 0.0, "triangle {t} faces in");
        }
    }

    #[test]
    fn points_of_no_width_are_left_out_and_types_warned_about() {
        let m = mesh(r#"Points "P" [0 0 100  1 0 100  2 0 100] "width" [0 -1 0.5]"#);
        assert_eq!(m.triangle_count(), MIN_POINT_SEGMENTS as usize);
        let (m, diagnostics) = build(r#"Points "P" [0 0 500] "uniform string type" "blobby""#, &MeshOptions::default());
        assert_eq!(m.unwrap().triangle_count(), MIN_POINT_SEGMENTS as usize);
        assert!(diagnostics[0].message.contains("point type \"blobby\" is not supported"), "{diagnostics:?}");
    }

    #[test]
    fn wrong_counts_are_errors_at_the_request() {
        for (text, message) in [
            (
                r#"Points "P" [0 0 5  1 0 5] "width" [1 2 3]"#,
                "\"width\" (varying float) has 3 values where 2 points need 2",
            ),
            (r#"Points "P" [0 0 5  1 0 5] "uniform float width" [1 2]"#, "where Points needs 1"),
            (r#"Points "P" [0 0 5] "constantwidth" [1 2]"#, "\"constantwidth\" (constant float) must be one float"),
            (r#"Points "P" [0 0 5  1 0 5] "N" [0 0 1]"#, "\"N\" (varying normal) has 1 values where 2 points need 2"),
            (r#"Points "Cs" [1 1 1]"#, "no positions"),
            (r#"Points "Pw" [0 0 5 0]"#, "not finite"),
        ] {
            let (m, diagnostics) = build(text, &MeshOptions::default());
            assert!(m.is_none(), "{text}");
            assert_eq!(diagnostics.len(), 1, "{text}: {diagnostics:?}");
            let shown = diagnostics[0].to_string();
            assert!(shown.starts_with("points.rib:1:1: error: ") && shown.contains(message), "{text}: {shown}");
            let parse = parse_str(text, "points.rib");
            assert_eq!(request_triangles(&parse.requests[0], &MeshOptions::default()), 0);
        }
    }
}

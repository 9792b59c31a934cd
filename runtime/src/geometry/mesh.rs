//! Triangle meshes: positions, optional per-vertex normals and texture coordinates, and any number
//! of named per-vertex attributes. Quads and polygons are triangulated on input (as fans).
//!
//! Invariants (checked by [`Mesh::validate`], which every constructor that takes user data runs):
//! - every triangle index is `< positions.len()`;
//! - `normals` and `uvs`, when present, have one entry per position;
//! - each attribute has `components * positions.len()` values;
//! - positions are finite;
//! - there are at most [`MAX_PRIMITIVES`] triangles, what one BVH holds;
//! - a [`Deformation`] has one position (and one normal, when the mesh has normals) per position,
//!   finite, and times `open < close`, both finite.
//!
//! Triangle `i` of the mesh is primitive `i` in hit records, whatever the BVH's internal order.

use crate::accel::bvh4::MAX_PRIMITIVES;
use glam::{Vec2, Vec3};

/// A problem with mesh data handed to the tracer.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but the mesh has only {count} vertices")]
    IndexOutOfRange {
        /// The face (polygon) number.
        face: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A polygon has fewer than three vertices.
    #[error("face {face} has {count} vertices; polygons need at least 3")]
    DegeneratePolygon {
        /// The face number.
        face: usize,
        /// Its vertex count.
        count: usize,
    },
    /// A per-vertex array has the wrong length.
    #[error("per-vertex data `{name}` has {got} values, expected {expected}")]
    LengthMismatch {
        /// Which array.
        name: String,
        /// Its length.
        got: usize,
        /// The expected length.
        expected: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {index} has a non-finite position")]
    NonFinite {
        /// The vertex.
        index: usize,
    },
    /// A deformation's times are not two finite numbers, the first the smaller.
    #[error("a deformation's times must be finite and increasing, not {open} and {close}")]
    DeformationTimes {
        /// The time of the mesh's own positions.
        open: f32,
        /// The time of the deformation's positions.
        close: f32,
    },
    /// More triangles than one object's BVH holds ([`MAX_PRIMITIVES`]).
    #[error("{count} triangles in one mesh: at most {MAX_PRIMITIVES}, what one object's BVH holds")]
    TooManyTriangles {
        /// The triangles.
        count: usize,
    },
}

/// Whether `count` triangles fit in one mesh, and so in one object's BVH.
pub fn check_triangle_count(count: usize) -> Result<(), MeshError> {
    if count > MAX_PRIMITIVES {
        return Err(MeshError::TooManyTriangles { count });
    }
    Ok(())
}

/// A named per-vertex attribute with `components` floats per vertex (e.g. a colour has 3).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Attribute {
    /// The attribute's name (e.g. `"Cs"`, `"confidence"`).
    pub name: String,
    /// Floats per vertex.
    pub components: usize,
    /// `components * vertex_count` values, vertex-major.
    pub data: Vec<f32>,
    /// How the values move with the object.
    pub kind: AttributeKind,
}

impl Attribute {
    /// Values that stay as they are wherever the object is placed (floats, colours, texture
    /// coordinates).
    pub fn data(name: impl Into<String>, components: usize, data: Vec<f32>) -> Attribute {
        Attribute { name: name.into(), components, data, kind: AttributeKind::Data }
    }
}

/// What an attribute's values are, for where the object is placed: RISpec gives point, vector
/// and normal primitive variables in object space, and shaders see them in the current space
/// (world space here), moved by the object's transform as `P` and `N` are. An attribute of one
/// of those kinds holds whole triples (arrays of them too).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AttributeKind {
    #[default]
    Data,
    /// Moved as positions are.
    Point,
    /// Moved as directions are (the transform without its translation).
    Vector,
    /// Moved as normals are (by the inverse transpose), not normalised.
    Normal,
}

impl AttributeKind {
    /// Moves every whole triple of `values` (one vertex's, or an interpolated value) by the
    /// transform `xf` whose normals move by `normal_xf` (its inverse transpose); data stays.
    pub fn transform(self, values: &mut [f32], xf: &glam::Affine3A, normal_xf: &glam::Mat3A) {
        if self == AttributeKind::Data {
            return;
        }
        for v in values.chunks_exact_mut(3) {
            let x = glam::Vec3A::new(v[0], v[1], v[2]);
            let moved = match self {
                AttributeKind::Point => xf.transform_point3a(x),
                AttributeKind::Vector => xf.transform_vector3a(x),
                AttributeKind::Normal => *normal_xf * x,
                AttributeKind::Data => x,
            };
            v.copy_from_slice(&moved.to_array());
        }
    }
}

/// A triangle mesh.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    /// Vertex positions (object space).
    pub positions: Vec<Vec3>,
    /// Optional per-vertex shading normals.
    pub normals: Option<Vec<Vec3>>,
    /// Optional per-vertex texture coordinates.
    pub uvs: Option<Vec<Vec2>>,
    /// Further per-vertex attributes.
    pub attributes: Vec<Attribute>,
    /// Triangles as vertex index triples.
    pub triangles: Vec<[u32; 3]>,
    /// Deformation blur: where the vertices are at a second time (`None`: the mesh stands still).
    pub deformation: Option<Deformation>,
}

/// A mesh's vertices at a second time. At `open` they are the mesh's own positions, at `close`
/// these; in between each moves on a straight line, and before `open` or after `close` it stands
/// at the nearer end (RIB `MotionBegin` around geometry: its first and last samples). A triangle
/// in between is the linear blend of its two ends, so the union of its two boxes bounds its whole
/// motion.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Deformation {
    /// The positions at `close`, one per mesh position.
    pub positions: Vec<Vec3>,
    /// The shading normals at `close` (only with the mesh's own normals; `None`: they do not
    /// change).
    pub normals: Option<Vec<Vec3>>,
    /// The times of the two ends, in the shutter's units ([`crate::render::RenderOptions::shutter`]).
    pub open: f32,
    pub close: f32,
}

impl Deformation {
    /// How far between the two ends the mesh is at `time`: 0 at `open` (and before), 1 at `close`
    /// (and after).
    #[inline(always)]
    pub fn blend(&self, time: f32) -> f32 {
        blend_between(self.open, self.close, time)
    }
}

/// How far `time` is from `open` to `close`, clamped to `[0, 1]`: the weight of the close end of
/// a linear motion (a deforming mesh's and its prepared triangles' alike).
#[inline(always)]
pub fn blend_between(open: f32, close: f32, time: f32) -> f32 {
    ((time - open) / (close - open)).clamp(0.0, 1.0)
}

impl Mesh {
    /// A mesh from positions and triangles, validated.
    pub fn from_triangles(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let mesh = Mesh { positions, triangles, ..Default::default() };
        mesh.validate()?;
        Ok(mesh)
    }

    /// A mesh from positions and polygons of any size (3 or more vertices each), each triangulated
    /// as a fan around its first vertex. Quads and convex polygons are triangulated exactly.
    pub fn from_polygons<P: AsRef<[u32]>>(positions: Vec<Vec3>, polygons: &[P]) -> Result<Self, MeshError> {
        let mut triangles = Vec::with_capacity(polygons.len());
        for (face, poly) in polygons.iter().enumerate() {
            triangulate_into(face, poly.as_ref(), &mut triangles)?;
        }
        Self::from_triangles(positions, triangles)
    }

    /// The axis-aligned box between corners `a` and `b` (in either order): six faces of two
    /// triangles, each face with its own four vertices so that its normals are its outward normal
    /// (flat, not averaged at the corners) and its uvs run from (0, 0) to (1, 1). Triangles wind
    /// counter-clockwise seen from outside, as a quadric's do.
    pub fn cuboid(a: Vec3, b: Vec3) -> Mesh {
        let centre = (a + b) * 0.5;
        let half = (a - b).abs() * 0.5;
        // (normal, u, v) with u x v = normal, so (0,0) (1,0) (1,1) (0,1) turn counter-clockwise.
        let faces = [
            (Vec3::X, Vec3::Y, Vec3::Z),
            (Vec3::NEG_X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::Z, Vec3::X),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::Y, Vec3::X),
        ];
        let corners = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
        let mut positions = Vec::with_capacity(24);
        let mut normals = Vec::with_capacity(24);
        let mut uvs = Vec::with_capacity(24);
        let mut triangles = Vec::with_capacity(12);
        for (n, u, v) in faces {
            let base = positions.len() as u32;
            for uv in corners {
                let offset = n + (2.0 * uv.x - 1.0) * u + (2.0 * uv.y - 1.0) * v;
                positions.push(centre + offset * half);
                normals.push(n);
                uvs.push(uv);
            }
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        }
        Mesh { positions, normals: Some(normals), uvs: Some(uvs), triangles, ..Default::default() }
    }

    /// Checks the invariants in the module documentation.
    pub fn validate(&self) -> Result<(), MeshError> {
        check_triangle_count(self.triangles.len())?;
        let count = self.positions.len();
        for (index, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFinite { index });
            }
        }
        for (face, tri) in self.triangles.iter().enumerate() {
            for &index in tri {
                if index as usize >= count {
                    return Err(MeshError::IndexOutOfRange { face, index, count });
                }
            }
        }
        let check = |name: &str, got: usize, expected: usize| {
            if got == expected {
                Ok(())
            } else {
                Err(MeshError::LengthMismatch { name: name.to_string(), got, expected })
            }
        };
        if let Some(n) = &self.normals {
            check("normals", n.len(), count)?;
        }
        if let Some(uv) = &self.uvs {
            check("uvs", uv.len(), count)?;
        }
        for a in &self.attributes {
            check(&a.name, a.data.len(), a.components * count)?;
        }
        if let Some(d) = &self.deformation {
            if !(d.open.is_finite() && d.close.is_finite() && d.open < d.close) {
                return Err(MeshError::DeformationTimes { open: d.open, close: d.close });
            }
            check("deformation positions", d.positions.len(), count)?;
            if let Some(index) = d.positions.iter().position(|p| !p.is_finite()) {
                return Err(MeshError::NonFinite { index });
            }
            match (&d.normals, &self.normals) {
                (Some(n), Some(_)) => check("deformation normals", n.len(), count)?,
                (Some(n), None) => check("deformation normals", n.len(), 0)?,
                (None, _) => {}
            }
        }
        Ok(())
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corner positions of triangle `i`.
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// The three corner positions of triangle `i` at `time` (where a deforming mesh then is).
    pub fn corners_at(&self, i: usize, time: f32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i].map(|k| k as usize);
        [a, b, c].map(|k| self.position_at(k, time))
    }

    /// Vertex `k`'s position at `time`.
    #[inline]
    pub fn position_at(&self, k: usize, time: f32) -> Vec3 {
        match &self.deformation {
            None => self.positions[k],
            Some(d) => self.positions[k].lerp(d.positions[k], d.blend(time)),
        }
    }

    /// The vertex normal interpolated at barycentric weights `w` of the triangle with vertices
    /// `[a, b, c]` (object space, not normalised), when the mesh has normals.
    pub fn interpolate_normal(&self, [a, b, c]: [usize; 3], w: [f32; 3]) -> Option<Vec3> {
        let ns = self.normals.as_ref()?;
        Some(ns[a] * w[0] + ns[b] * w[1] + ns[c] * w[2])
    }

    /// [`Mesh::interpolate_normal`] at `time` (where a deforming mesh's normals then are).
    pub fn interpolate_normal_at(&self, [a, b, c]: [usize; 3], w: [f32; 3], time: f32) -> Option<Vec3> {
        let at_open = self.interpolate_normal([a, b, c], w)?;
        match self.deformation.as_ref().and_then(|d| Some((d, d.normals.as_ref()?))) {
            None => Some(at_open),
            Some((d, ns)) => Some(at_open.lerp(ns[a] * w[0] + ns[b] * w[1] + ns[c] * w[2], d.blend(time))),
        }
    }

    /// Every per-vertex attribute interpolated at barycentric weights `w` of the triangle with
    /// vertices `[a, b, c]`, in the mesh's attribute order.
    pub fn interpolate_attributes(&self, [a, b, c]: [usize; 3], w: [f32; 3]) -> Vec<Vec<f32>> {
        if self.attributes.is_empty() {
            return Vec::new();
        }
        self.attributes
            .iter()
            .map(|at| {
                let k = at.components;
                (0..k)
                    .map(|j| at.data[a * k + j] * w[0] + at.data[b * k + j] * w[1] + at.data[c * k + j] * w[2])
                    .collect()
            })
            .collect()
    }

    /// blake3 of everything the mesh holds (each part tagged, with its length, in a fixed order,
    /// floats as their bits in the machine's byte order): two meshes with the same digest are
    /// taken to be the same mesh, so that a process that holds one need not be sent the other (a
    /// distributed worker keeps the meshes of one scene for the next; ranks of another byte order
    /// are refused at start-up).
    pub fn digest(&self) -> [u8; 32] {
        let mut h = blake3::Hasher::new();
        let mut part = |tag: &[u8], len: usize, bytes: &[u8]| {
            h.update(tag);
            h.update(&(len as u64).to_le_bytes());
            h.update(bytes);
        };
        part(b"positions", self.positions.len(), bytemuck::cast_slice(&self.positions));
        part(b"triangles", self.triangles.len(), bytemuck::cast_slice(&self.triangles));
        if let Some(normals) = &self.normals {
            part(b"normals", normals.len(), bytemuck::cast_slice(normals));
        }
        if let Some(uvs) = &self.uvs {
            part(b"uvs", uvs.len(), bytemuck::cast_slice(uvs));
        }
        for a in &self.attributes {
            part(b"attribute", a.name.len(), a.name.as_bytes());
            part(b"components", a.components, &[]);
            part(b"kind", a.kind as usize, &[]);
            part(b"values", a.data.len(), bytemuck::cast_slice(&a.data));
        }
        if let Some(d) = &self.deformation {
            let times = [d.open.to_bits(), d.close.to_bits()];
            part(b"deformation", d.positions.len(), bytemuck::cast_slice(&d.positions));
            part(b"times", 2, bytemuck::cast_slice(&times));
            if let Some(normals) = &d.normals {
                part(b"close normals", normals.len(), bytemuck::cast_slice(normals));
            }
        }
        h.finalize().into()
    }

    /// Bytes of heap memory held by the mesh data.
    pub fn memory_bytes(&self) -> usize {
        self.positions.len() * size_of::<Vec3>()
            + self.normals.as_ref().map_or(0, |n| n.len() * size_of::<Vec3>())
            + self.uvs.as_ref().map_or(0, |n| n.len() * size_of::<Vec2>())
            + self.attributes.iter().map(|a| a.data.len() * 4).sum::<usize>()
            + self.triangles.len() * 12
            + self
                .deformation
                .as_ref()
                .map_or(0, |d| (d.positions.len() + d.normals.as_ref().map_or(0, Vec::len)) * size_of::<Vec3>())
    }
}

/// Appends the fan triangulation of polygon `poly` (face number `face`) to `out`.
pub fn triangulate_into(face: usize, poly: &[u32], out: &mut Vec<[u32; 3]>) -> Result<(), MeshError> {
    if poly.len() < 3 {
        return Err(MeshError::DegeneratePolygon { face, count: poly.len() });
    }
    for k in 1..poly.len() - 1 {
        out.push([poly[0], poly[k], poly[k + 1]]);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal meshes have one digest; a change to any part a worker would render (one bit of a
    /// position, a normal, a texture coordinate, an attribute's name or values, a deformation)
    /// gives another.
    #[test]
    fn a_mesh_digest_covers_everything_the_mesh_holds() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let base = Mesh::from_polygons(p, &[[0u32, 1, 2, 3]]).unwrap();
        assert_eq!(base.digest(), base.clone().digest());
        let mut changes: Vec<Mesh> = Vec::new();
        let mut m = base.clone();
        m.positions[2].y = f32::from_bits(m.positions[2].y.to_bits() + 1);
        changes.push(m);
        let mut m = base.clone();
        m.triangles.swap(0, 1);
        changes.push(m);
        let mut m = base.clone();
        m.normals = Some(vec![Vec3::Z; 4]);
        changes.push(m.clone());
        m.normals = Some(vec![Vec3::Z, Vec3::Z, Vec3::Z, -Vec3::Z]);
        changes.push(m);
        let mut m = base.clone();
        m.uvs = Some(vec![Vec2::ZERO; 4]);
        changes.push(m);
        let attribute = |name: &str, value: f32| Attribute::data(name, 1, vec![value; 4]);
        let mut m = base.clone();
        m.attributes.push(attribute("Cs", 0.5));
        changes.push(m.clone());
        m.attributes[0] = attribute("Os", 0.5);
        changes.push(m.clone());
        m.attributes[0] = attribute("Os", 0.25);
        changes.push(m);
        let mut m = base.clone();
        let close = m.positions.iter().map(|p| *p + Vec3::Z).collect();
        m.deformation = Some(Deformation { positions: close, normals: None, open: 0.0, close: 1.0 });
        changes.push(m.clone());
        if let Some(d) = m.deformation.as_mut() {
            d.close = 0.5;
        }
        changes.push(m);
        let mut digests: Vec<[u8; 32]> = changes.iter().map(Mesh::digest).collect();
        digests.push(base.digest());
        let count = digests.len();
        digests.sort_unstable();
        digests.dedup();
        assert_eq!(digests.len(), count, "every change has a digest of its own");
    }

    #[test]
    fn quads_become_two_triangles() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let m = Mesh::from_polygons(p, &[[0u32, 1, 2, 3]]).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    /// A mesh is refused past what one BVH holds, by its count alone (a mesh that large would
    /// take gigabytes to make here).
    #[test]
    fn meshes_past_the_bvh_limit_are_errors() {
        assert!(check_triangle_count(MAX_PRIMITIVES).is_ok());
        let e = check_triangle_count(MAX_PRIMITIVES + 1).unwrap_err();
        assert!(matches!(e, MeshError::TooManyTriangles { count } if count == MAX_PRIMITIVES + 1));
        assert!(e.to_string().contains(&MAX_PRIMITIVES.to_string()), "{e}");
        // The largest slot a leaf of a BVH of MAX_PRIMITIVES refers to is encoded whole.
        let last = MAX_PRIMITIVES as u32 - 1;
        assert_eq!(crate::accel::bvh4::leaf_range(crate::accel::bvh4::leaf_ref(last, 3)), (last, 3));
    }

    #[test]
    fn bad_index_is_an_error() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let e = Mesh::from_triangles(p, vec![[0, 1, 3]]).unwrap_err();
        assert!(matches!(e, MeshError::IndexOutOfRange { index: 3, .. }));
    }

    #[test]
    fn short_polygon_is_an_error() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let e = Mesh::from_polygons(p, &[vec![0u32, 1]]).unwrap_err();
        assert!(matches!(e, MeshError::DegeneratePolygon { count: 2, .. }));
    }

    #[test]
    fn cuboid_faces_wind_around_their_outward_normals() {
        // Corners given high first: the box is the same.
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 4.0));
        let m = Mesh::cuboid(hi, lo);
        m.validate().unwrap();
        assert_eq!((m.positions.len(), m.triangle_count()), (24, 12));
        assert!(m.positions.iter().all(|p| p.cmpge(lo).all() && p.cmple(hi).all()));
        let normals = m.normals.as_ref().unwrap();
        let centre = (lo + hi) * 0.5;
        let mut area = 0.0;
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let winding = (b - a).cross(c - a);
            area += winding.length() * 0.5;
            for &i in t {
                let n = normals[i as usize];
                assert!(winding.dot(n) > 0.0, "triangle {t:?} winds against its normal");
                assert!((a - centre).dot(n) > 0.0, "normal {n} points into the box");
            }
        }
        let size = hi - lo;
        let surface = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
        assert!((area - surface).abs() < 1e-4, "area {area}, expected {surface}");
    }
}

//! `SubdivisionMesh` (RISpec 3.2, section 5.5) to triangle meshes: Catmull-Clark subdivision
//! (Catmull and Clark 1978) with semi-sharp creases and corners (DeRose, Kass and Truong 1998),
//! holes and boundary interpolation, refined a fixed number of levels and then pushed to the limit
//! surface (the limit masks of Halstead, Kass and DeRose 1993). The `"bilinear"` scheme refines the
//! same way with linear rules.
//!
//! The surface:
//! - every face, of any number of sides, becomes one quad per corner at the first level, and each
//!   quad four at the next; [`levels`] chooses how many levels (at most [`MAX_SUBDIVISION_LEVELS`],
//!   fewer where the mesh would pass [`SUBDIVISION_TRIANGLE_BUDGET`] triangles, never fewer than
//!   one), and every quad of the last level is two triangles;
//! - the last level's vertices are moved to their limit positions: smooth vertices by the
//!   Catmull-Clark limit mask, crease vertices (two sharp edges) to the limit of their B-spline
//!   crease curve, corners (a `"corner"` tag, three or more sharp edges, a non-manifold vertex)
//!   stay. A crease sharper than the levels refined is taken as infinitely sharp there;
//! - normals: at a smooth vertex the cross product of its two limit tangents; at a vertex on a
//!   sharp edge each side of the crease gets its own normal, the average of the limit quads'
//!   normals on that side (an approximation of the one-sided limit normal);
//! - a crease of sharpness `s` is refined with the sharp rules for `floor(s)` levels and a blend
//!   of the sharp and the smooth rule by the fraction left (the vertex rule blended by the average
//!   sharpness of the edges that turn smooth), each level's children one less sharp;
//! - boundary edges and non-manifold edges (more than two faces, or two faces that run the same
//!   way along them) are infinitely sharp for the refinement. Without `"interpolateboundary"`
//!   (RenderMan's default) a face with a vertex on the boundary is not drawn: it only shapes its
//!   neighbours, whose full neighbourhoods define the surface. With it (argument 1, the default,
//!   or 2) every face is drawn, the boundary being a crease; with 1 a boundary vertex of two edges
//!   is also a corner;
//! - `"hole"` faces are refined and shape their neighbours, but are not drawn.
//!
//! Primitive variables: `vertex` data follows the subdivision rules and the limit masks, as `P`
//! does; `varying` data is refined linearly (bilinear over each face); `facevarying` data linearly
//! within each face from its corner values; `uniform` data is constant over each face's quads; `N`,
//! `st`, `s` and `t` go where [`route_attributes`] sends them (a given `N` replaces the normals
//! computed).
//!
//! Invariants: nothing in the request is trusted. Counts and indices are checked before anything
//! is allocated from them, the triangles are counted before refining ([`subdivision_mesh_triangles`]
//! is exactly what [`subdivision_mesh`] makes), nothing recurses, and malformed data is an `Err`
//! with a message, never a panic.

use std::collections::HashMap;

use glam::Vec3;

use super::decl::Class;
use super::mesh::{per_vertex_params, positions, route_attributes, ClassCounts, PerVertex};
use super::request::Param;
use super::MAX_RIB_TRIANGLES;
use crate::geometry::{Attribute, Mesh};

/// The most levels a subdivision mesh is refined before its vertices are moved to the limit
/// surface: a cube becomes 6 x 4^4 quads, smooth at any size an image shows it.
pub const MAX_SUBDIVISION_LEVELS: u32 = 4;

/// The triangles one subdivision mesh is refined up to: the most levels (up to
/// [`MAX_SUBDIVISION_LEVELS`]) are chosen whose triangles stay within it, and never fewer than one.
pub const SUBDIVISION_TRIANGLE_BUDGET: usize = 1 << 20;

/// Sharpness of boundary and non-manifold edges, and of non-manifold vertices.
const SHARP: f32 = f32::INFINITY;

/// No face (an edge side without one).
const NONE: u32 = u32::MAX;

/// A `SubdivisionMesh` request's arguments.
#[derive(Clone, Copy, Debug)]
pub struct SubdivisionInput<'a> {
    /// The scheme, as written.
    pub scheme: &'a str,
    /// Vertices per face.
    pub nvertices: &'a [i32],
    /// Vertex indices, face after face.
    pub vertices: &'a [i32],
    /// Tag names.
    pub tags: &'a [String],
    /// Integer and float argument counts, two per tag.
    pub nargs: &'a [i32],
    /// The tags' integer arguments.
    pub intargs: &'a [i32],
    /// The tags' float arguments.
    pub floatargs: &'a [f32],
    /// The parameter list.
    pub params: &'a [Param],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scheme {
    CatmullClark,
    Bilinear,
}

/// `"interpolateboundary"`'s argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Boundary {
    /// Faces on the boundary are not drawn (no tag, or argument 0).
    None,
    /// Boundary edges are creases, boundary vertices of two edges corners (argument 1).
    EdgesAndCorners,
    /// Boundary edges are creases (argument 2).
    EdgesOnly,
}

/// One level of the mesh: faces, their edges, and the sharpness of edges and vertices.
#[derive(Clone, Debug)]
struct Level {
    vertices: usize,
    /// Face `f`'s corners are `face_start[f]..face_start[f + 1]`.
    face_start: Vec<u32>,
    /// The vertex at each corner.
    face_verts: Vec<u32>,
    /// The edge from each corner to the next of its face.
    face_edges: Vec<u32>,
    /// The face of the request each face comes from.
    face_origin: Vec<u32>,
    /// Edge endpoints.
    edges: Vec<[u32; 2]>,
    edge_sharpness: Vec<f32>,
    vertex_sharpness: Vec<f32>,
}

impl Level {
    fn faces(&self) -> usize {
        self.face_start.len().saturating_sub(1)
    }

    fn corners(&self, f: usize) -> std::ops::Range<usize> {
        self.face_start[f] as usize..self.face_start[f + 1] as usize
    }
}

/// What is around each edge and vertex of a level.
struct Adjacency {
    /// Faces on each edge: how many, and the first two.
    edge_face_count: Vec<u32>,
    edge_faces: Vec<[u32; 2]>,
    /// The edges at each vertex (`vertex_edges[vertex_edge_start[v]..vertex_edge_start[v + 1]]`).
    vertex_edge_start: Vec<u32>,
    vertex_edges: Vec<u32>,
    /// The corners at each vertex, likewise.
    vertex_corner_start: Vec<u32>,
    vertex_corners: Vec<u32>,
    /// The face of each corner.
    corner_face: Vec<u32>,
}

impl Adjacency {
    fn new(level: &Level) -> Adjacency {
        let mut edge_face_count = vec![0u32; level.edges.len()];
        let mut edge_faces = vec![[NONE; 2]; level.edges.len()];
        let mut corner_face = Vec::with_capacity(level.face_verts.len());
        for f in 0..level.faces() {
            for c in level.corners(f) {
                let e = level.face_edges[c] as usize;
                if let Some(slot) = edge_faces[e].get_mut(edge_face_count[e] as usize) {
                    *slot = f as u32;
                }
                edge_face_count[e] = edge_face_count[e].saturating_add(1);
                corner_face.push(f as u32);
            }
        }
        let (vertex_edge_start, vertex_edges) = group(
            level.vertices,
            level.edges.iter().enumerate().flat_map(|(e, &[a, b])| [(a, e as u32), (b, e as u32)]),
        );
        let (vertex_corner_start, vertex_corners) =
            group(level.vertices, level.face_verts.iter().enumerate().map(|(c, &v)| (v, c as u32)));
        Adjacency {
            edge_face_count,
            edge_faces,
            vertex_edge_start,
            vertex_edges,
            vertex_corner_start,
            vertex_corners,
            corner_face,
        }
    }

    fn edges_at(&self, v: usize) -> &[u32] {
        &self.vertex_edges[self.vertex_edge_start[v] as usize..self.vertex_edge_start[v + 1] as usize]
    }

    fn corners_at(&self, v: usize) -> &[u32] {
        &self.vertex_corners[self.vertex_corner_start[v] as usize..self.vertex_corner_start[v + 1] as usize]
    }
}

/// `(key, value)` pairs grouped by key (below `keys`): the start of each key's values, and the
/// values.
fn group(keys: usize, pairs: impl Iterator<Item = (u32, u32)> + Clone) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; keys + 1];
    for (k, _) in pairs.clone() {
        start[k as usize + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    let mut next = start.clone();
    let mut values = vec![0u32; start[keys] as usize];
    for (k, v) in pairs {
        let at = &mut next[k as usize];
        values[*at as usize] = v;
        *at += 1;
    }
    (start, values)
}

/// The other end of edge `e` from `v`.
fn other_end(edge: [u32; 2], v: usize) -> usize {
    if edge[0] as usize == v {
        edge[1] as usize
    } else {
        edge[0] as usize
    }
}

/// The control mesh of a request, checked, with its tags applied, before any refinement.
struct Cage {
    scheme: Scheme,
    level: Level,
    /// The request's vertex-list index of each corner kept (for facevarying data).
    corner_origin: Vec<u32>,
    /// Per face of the request: whether its part of the surface is drawn.
    drawn: Vec<bool>,
    points: Vec<Vec3>,
    levels: u32,
}

/// `n what`, with an `s` unless `n` is 1 (for messages).
fn plural(n: usize, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

impl Cage {
    fn new(input: &SubdivisionInput, warnings: &mut Vec<String>) -> Result<Cage, String> {
        let scheme = match input.scheme {
            "catmull-clark" => Scheme::CatmullClark,
            "bilinear" => Scheme::Bilinear,
            other => {
                return Err(format!(
                    "subdivision scheme \"{other}\" is not supported (rtsl subdivides \"catmull-clark\" and \
                     \"bilinear\" meshes)"
                ))
            }
        };
        let nfaces = input.nvertices.len();
        if nfaces == 0 {
            return Err("the subdivision mesh has no faces".into());
        }
        let mut sizes = Vec::with_capacity(nfaces);
        for (f, &n) in input.nvertices.iter().enumerate() {
            match usize::try_from(n) {
                Ok(n) if n >= 3 => sizes.push(n),
                _ => return Err(format!("face {f} has {n} vertices: every face needs at least 3")),
            }
        }
        let total: usize = sizes.iter().sum();
        if total != input.vertices.len() {
            return Err(format!(
                "the faces have {total} vertices in all but {} vertex indices are given",
                input.vertices.len()
            ));
        }
        let all = quad_triangles(total, levels(total));
        if all > MAX_RIB_TRIANGLES {
            return Err(format!(
                "the subdivision mesh makes {all} triangles refined once, more than the {MAX_RIB_TRIANGLES} one RIB \
                 load may make"
            ));
        }
        let points = positions(input.params)?;
        if points.len() >= (u32::MAX / 4) as usize || total >= (u32::MAX / 4) as usize {
            return Err("the subdivision mesh has too many vertices".into());
        }
        let point = |k: usize, v: i32, what: &str| {
            u32::try_from(v).ok().filter(|&v| (v as usize) < points.len()).ok_or_else(|| {
                format!("{what} {v} (entry {k}) is negative or not below the number of points ({})", points.len())
            })
        };
        let vertices: Vec<u32> =
            input.vertices.iter().enumerate().map(|(k, &v)| point(k, v, "vertex index")).collect::<Result<_, _>>()?;

        // Faces that repeat a vertex have no surface: they are left out of the mesh.
        let mut level = Level {
            vertices: points.len(),
            face_start: vec![0],
            face_verts: Vec::with_capacity(total),
            face_edges: Vec::with_capacity(total),
            face_origin: Vec::with_capacity(nfaces),
            edges: Vec::new(),
            edge_sharpness: Vec::new(),
            vertex_sharpness: vec![0.0; points.len()],
        };
        let mut corner_origin = Vec::with_capacity(total);
        let mut kept = vec![false; nfaces];
        let mut skipped = 0usize;
        let mut start = 0usize;
        for (f, &n) in sizes.iter().enumerate() {
            let face = &vertices[start..start + n];
            if repeats(face) {
                skipped += 1;
            } else {
                kept[f] = true;
                level.face_verts.extend_from_slice(face);
                corner_origin.extend((start..start + n).map(|c| c as u32));
                level.face_origin.push(f as u32);
                level.face_start.push(level.face_verts.len() as u32);
            }
            start += n;
        }
        if skipped > 0 {
            warnings.push(format!(
                "{} that repeat{} a vertex skipped: a face must have distinct vertices",
                plural(skipped, "face"),
                if skipped == 1 { "s" } else { "" }
            ));
        }
        if level.faces() == 0 {
            return Err("no face of the subdivision mesh can be subdivided".into());
        }

        // Edges, and how the faces use them: a manifold edge has two faces running opposite ways.
        let mut edge_index: HashMap<(u32, u32), u32> = HashMap::with_capacity(level.face_verts.len());
        let mut uses: Vec<(u32, bool, bool)> = Vec::new(); // (faces, first use runs low to high, manifold)
        for f in 0..level.faces() {
            let corners = level.corners(f);
            for c in corners.clone() {
                let a = level.face_verts[c];
                let b = level.face_verts[if c + 1 == corners.end { corners.start } else { c + 1 }];
                let key = (a.min(b), a.max(b));
                let e = *edge_index.entry(key).or_insert_with(|| {
                    level.edges.push([key.0, key.1]);
                    uses.push((0, a < b, true));
                    (level.edges.len() - 1) as u32
                });
                let use_ = &mut uses[e as usize];
                use_.0 += 1;
                if use_.0 == 2 && use_.1 == (a < b) {
                    use_.2 = false;
                }
                level.face_edges.push(e);
            }
        }
        let boundary_edge: Vec<bool> = uses.iter().map(|u| u.0 == 1).collect();
        level.edge_sharpness = uses
            .iter()
            .map(
                |&(faces, _, manifold)| if faces != 2 || !manifold || scheme == Scheme::Bilinear { SHARP } else { 0.0 },
            )
            .collect();

        // Tags.
        let mut drawn = kept;
        let mut boundary = Boundary::None;
        if input.nargs.len() != 2 * input.tags.len() {
            return Err(format!(
                "{} need {} argument counts (an integer count and a float count each), but {} are given",
                plural(input.tags.len(), "tag"),
                2 * input.tags.len(),
                input.nargs.len()
            ));
        }
        let (mut int_at, mut float_at) = (0usize, 0usize);
        let mut missing_edges = 0usize;
        for (t, name) in input.tags.iter().enumerate() {
            let count = |k: usize| {
                usize::try_from(input.nargs[2 * t + k])
                    .map_err(|_| format!("tag \"{name}\" has a negative argument count ({})", input.nargs[2 * t + k]))
            };
            let (ni, nf) = (count(0)?, count(1)?);
            let ints = input.intargs.get(int_at..int_at.saturating_add(ni)).ok_or_else(|| {
                format!(
                    "tag \"{name}\" takes {} from {int_at} on, but only {} are given",
                    plural(ni, "integer argument"),
                    input.intargs.len()
                )
            })?;
            let floats = input.floatargs.get(float_at..float_at.saturating_add(nf)).ok_or_else(|| {
                format!(
                    "tag \"{name}\" takes {} from {float_at} on, but only {} are given",
                    plural(nf, "float argument"),
                    input.floatargs.len()
                )
            })?;
            int_at += ni;
            float_at += nf;
            let expect = |ok: bool, wanted: &str| {
                if ok {
                    Ok(())
                } else {
                    Err(format!(
                        "tag \"{name}\" takes {wanted}, but has {} and {}",
                        plural(ni, "integer"),
                        plural(nf, "float")
                    ))
                }
            };
            let sharpness = |s: f32| {
                if s.is_nan() {
                    Err(format!("tag \"{name}\" has a sharpness that is not a number"))
                } else {
                    Ok(s.max(0.0))
                }
            };
            match name.as_str() {
                "hole" => {
                    expect(nf == 0, "face indices and no floats")?;
                    for &f in ints {
                        let face = usize::try_from(f).ok().filter(|&f| f < nfaces).ok_or_else(|| {
                            format!("tag \"hole\" names face {f}, but the mesh has {}", plural(nfaces, "face"))
                        })?;
                        drawn[face] = false;
                    }
                }
                "crease" => {
                    expect(
                        ni >= 2 && (nf == 1 || nf == ni - 1),
                        "two or more vertex indices and one sharpness (or one per edge)",
                    )?;
                    let chain: Vec<u32> = ints
                        .iter()
                        .enumerate()
                        .map(|(k, &v)| point(int_at - ni + k, v, "tag \"crease\": vertex index"))
                        .collect::<Result<_, _>>()?;
                    for (k, pair) in chain.windows(2).enumerate() {
                        let s = sharpness(floats[if nf == 1 { 0 } else { k }])?;
                        match edge_index.get(&(pair[0].min(pair[1]), pair[0].max(pair[1]))) {
                            Some(&e) => {
                                let current = &mut level.edge_sharpness[e as usize];
                                *current = current.max(s);
                            }
                            None => missing_edges += 1,
                        }
                    }
                }
                "corner" => {
                    expect(ni >= 1 && (nf == 1 || nf == ni), "vertex indices and one sharpness (or one per vertex)")?;
                    for (k, &v) in ints.iter().enumerate() {
                        let v = point(int_at - ni + k, v, "tag \"corner\": vertex index")? as usize;
                        let s = sharpness(floats[if nf == 1 { 0 } else { k }])?;
                        level.vertex_sharpness[v] = level.vertex_sharpness[v].max(s);
                    }
                }
                "interpolateboundary" => {
                    expect(ni <= 1 && nf == 0, "at most one integer (0, 1 or 2) and no floats")?;
                    boundary = match ints.first().copied().unwrap_or(1) {
                        0 => Boundary::None,
                        1 => Boundary::EdgesAndCorners,
                        2 => Boundary::EdgesOnly,
                        other => return Err(format!("tag \"interpolateboundary\" takes 0, 1 or 2, not {other}")),
                    };
                }
                other => warnings.push(format!("subdivision mesh tag \"{other}\" is not supported and is ignored")),
            }
        }
        if int_at != input.intargs.len() || float_at != input.floatargs.len() {
            return Err(format!(
                "the tags take {} and {}, but {} and {} are given",
                plural(int_at, "integer argument"),
                plural(float_at, "float argument"),
                input.intargs.len(),
                input.floatargs.len()
            ));
        }
        if missing_edges > 0 {
            warnings.push(format!(
                "{} of tag \"crease\" join{} vertices that no edge of the mesh joins: ignored",
                plural(missing_edges, "pair"),
                if missing_edges == 1 { "s" } else { "" }
            ));
        }

        // Vertices: on the boundary, at a corner of the boundary, or where separate fans of faces
        // meet (non-manifold, made a corner).
        let mut on_boundary = vec![false; points.len()];
        let mut edge_count = vec![0u32; points.len()];
        for (e, &[a, b]) in level.edges.iter().enumerate() {
            for v in [a, b] {
                edge_count[v as usize] += 1;
                on_boundary[v as usize] |= boundary_edge[e];
            }
        }
        for v in fan_meetings(&level, &uses) {
            level.vertex_sharpness[v] = SHARP;
        }
        if scheme == Scheme::CatmullClark {
            match boundary {
                Boundary::None => {
                    for f in 0..level.faces() {
                        if level.corners(f).any(|c| on_boundary[level.face_verts[c] as usize]) {
                            drawn[level.face_origin[f] as usize] = false;
                        }
                    }
                }
                Boundary::EdgesAndCorners => {
                    for v in 0..points.len() {
                        if on_boundary[v] && edge_count[v] == 2 {
                            level.vertex_sharpness[v] = SHARP;
                        }
                    }
                }
                Boundary::EdgesOnly => {}
            }
        }
        let levels = levels(level.face_verts.len());
        Ok(Cage { scheme, level, corner_origin, drawn, points, levels })
    }

    /// The triangles drawn.
    fn drawn_triangles(&self) -> usize {
        let corners: usize = (0..self.level.faces())
            .filter(|&f| self.drawn[self.level.face_origin[f] as usize])
            .map(|f| self.level.corners(f).len())
            .sum();
        quad_triangles(corners, self.levels)
    }
}

/// Whether a face names a vertex twice.
fn repeats(face: &[u32]) -> bool {
    if face.len() <= 16 {
        return face.iter().enumerate().any(|(k, v)| face[k + 1..].contains(v));
    }
    let mut sorted = face.to_vec();
    sorted.sort_unstable();
    sorted.windows(2).any(|w| w[0] == w[1])
}

/// The vertices where faces meet that do not form one fan joined by manifold edges.
fn fan_meetings(level: &Level, uses: &[(u32, bool, bool)]) -> Vec<usize> {
    let corners = level.face_verts.len();
    let mut sets = UnionFind::new(corners);
    // The corner of each face at each end of each manifold edge, joined across the edge.
    let mut first_corner = vec![NONE; level.edges.len()];
    for f in 0..level.faces() {
        for c in level.corners(f) {
            let e = level.face_edges[c] as usize;
            let (faces, _, manifold) = uses[e];
            if faces != 2 || !manifold {
                continue;
            }
            if first_corner[e] == NONE {
                first_corner[e] = c as u32;
                continue;
            }
            let other = first_corner[e] as usize;
            let next = |c: usize| {
                let f = level.corners(find_face(level, c));
                if c + 1 == f.end {
                    f.start
                } else {
                    c + 1
                }
            };
            // Opposite directions: this corner's start is the other's end, and the reverse.
            sets.union(c, next(other));
            sets.union(next(c), other);
        }
    }
    let mut root_of = vec![NONE; level.vertices];
    let mut meeting = vec![false; level.vertices];
    for c in 0..corners {
        let v = level.face_verts[c] as usize;
        let root = sets.find(c) as u32;
        if root_of[v] == NONE {
            root_of[v] = root;
        } else if root_of[v] != root {
            meeting[v] = true;
        }
    }
    (0..level.vertices).filter(|&v| meeting[v]).collect()
}

/// The face of corner `c`.
fn find_face(level: &Level, c: usize) -> usize {
    level.face_start.partition_point(|&s| s as usize <= c) - 1
}

/// Two triangles a quad: `corners` corners at the cage make as many quads at the first level, and
/// each quad four at each level after.
fn quad_triangles(corners: usize, levels: u32) -> usize {
    let per_corner = 1usize.checked_shl(2 * levels.saturating_sub(1)).unwrap_or(usize::MAX);
    corners.saturating_mul(per_corner).saturating_mul(2)
}

/// The levels a cage of `corners` face corners is refined: the most, up to
/// [`MAX_SUBDIVISION_LEVELS`], within [`SUBDIVISION_TRIANGLE_BUDGET`] triangles, and at least one.
pub fn levels(corners: usize) -> u32 {
    (1..=MAX_SUBDIVISION_LEVELS).rev().find(|&l| quad_triangles(corners, l) <= SUBDIVISION_TRIANGLE_BUDGET).unwrap_or(1)
}

/// Disjoint sets of indices, joined by [`UnionFind::union`].
struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind { parent: (0..n as u32).collect() }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let grand = self.parent[self.parent[x] as usize];
            self.parent[x] = grand;
            x = grand as usize;
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.parent[a.max(b)] = a.min(b) as u32;
        }
    }
}

/// The data refined with the mesh: vertex data (positions first) by the scheme's rules, varying
/// data linearly, facevarying data per corner.
struct Data {
    vertex: Vec<f32>,
    vertex_width: usize,
    varying: Vec<f32>,
    varying_width: usize,
    corner: Vec<f32>,
    corner_width: usize,
}

/// `out += weight * row`
fn add(out: &mut [f32], row: &[f32], weight: f32) {
    for (o, r) in out.iter_mut().zip(row) {
        *o += weight * r;
    }
}

/// How a vertex moves: by the smooth rule, along a crease, or not at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rule {
    Smooth,
    Crease,
    Corner,
}

/// The rule of a vertex with `sharp_edges` sharp edges, sharp itself or not; a vertex whose edges
/// and faces do not make a closed fan cannot be smooth.
fn rule(sharp_edges: usize, sharp_vertex: bool, closed_fan: bool) -> Rule {
    if sharp_vertex || sharp_edges > 2 {
        Rule::Corner
    } else if sharp_edges == 2 {
        Rule::Crease
    } else if closed_fan {
        Rule::Smooth
    } else {
        Rule::Corner
    }
}

/// The next level: each face split into a quad per corner (its corner, the midpoints of the two
/// edges there, its centre), and the data refined.
fn refine(level: &Level, adj: &Adjacency, scheme: Scheme, data: &Data) -> (Level, Data) {
    let (nv, ne, nf) = (level.vertices, level.edges.len(), level.faces());
    let corners = level.face_verts.len();
    let child_sharpness = |s: f32| (s - 1.0).max(0.0);

    // Topology: vertices are the old ones, then one per edge, then one per face.
    let mut child = Level {
        vertices: nv + ne + nf,
        face_start: Vec::with_capacity(corners + 1),
        face_verts: Vec::with_capacity(4 * corners),
        face_edges: Vec::with_capacity(4 * corners),
        face_origin: Vec::with_capacity(corners),
        edges: Vec::with_capacity(2 * ne + corners),
        edge_sharpness: Vec::with_capacity(2 * ne + corners),
        vertex_sharpness: Vec::with_capacity(nv + ne + nf),
    };
    // Edge e splits into 2e (from its first end) and 2e + 1; corner c of face f adds the edge
    // 2 ne + c from the face's centre to the midpoint of the edge that leaves c.
    for (e, &[a, b]) in level.edges.iter().enumerate() {
        let mid = (nv + e) as u32;
        child.edges.extend([[a, mid], [mid, b]]);
        let s = child_sharpness(level.edge_sharpness[e]);
        child.edge_sharpness.extend([s, s]);
    }
    let half = |e: u32, v: u32| 2 * e + u32::from(level.edges[e as usize][0] != v);
    child.face_start.push(0);
    for f in 0..nf {
        let range = level.corners(f);
        let centre = (nv + ne + f) as u32;
        for c in range.clone() {
            child.edges.push([centre, (nv as u32) + level.face_edges[c]]);
            child.edge_sharpness.push(0.0);
            let previous = if c == range.start { range.end - 1 } else { c - 1 };
            let (v, next_edge, previous_edge) = (level.face_verts[c], level.face_edges[c], level.face_edges[previous]);
            child.face_verts.extend([v, nv as u32 + next_edge, centre, nv as u32 + previous_edge]);
            child.face_edges.extend([
                half(next_edge, v),
                (2 * ne + c) as u32,
                (2 * ne + previous) as u32,
                half(previous_edge, v),
            ]);
            child.face_origin.push(level.face_origin[f]);
            child.face_start.push(child.face_verts.len() as u32);
        }
    }
    child.vertex_sharpness.extend(level.vertex_sharpness.iter().map(|&s| child_sharpness(s)));
    child.vertex_sharpness.resize(nv + ne + nf, 0.0);

    let vertex = refine_vertex_data(level, adj, scheme, &data.vertex, data.vertex_width);
    let varying = refine_vertex_data(level, adj, Scheme::Bilinear, &data.varying, data.varying_width);
    let w = data.corner_width;
    let mut corner = vec![0.0; 4 * corners * w];
    if w > 0 {
        for f in 0..nf {
            let range = level.corners(f);
            let n = range.len() as f32;
            let row = |c: usize| &data.corner[c * w..(c + 1) * w];
            let mut centre = vec![0.0; w];
            for c in range.clone() {
                add(&mut centre, row(c), 1.0 / n);
            }
            for c in range.clone() {
                let next = if c + 1 == range.end { range.start } else { c + 1 };
                let previous = if c == range.start { range.end - 1 } else { c - 1 };
                let out = &mut corner[4 * c * w..4 * (c + 1) * w];
                let (at_vertex, rest) = out.split_at_mut(w);
                let (at_next, rest) = rest.split_at_mut(w);
                let (at_centre, at_previous) = rest.split_at_mut(w);
                add(at_vertex, row(c), 1.0);
                add(at_next, row(c), 0.5);
                add(at_next, row(next), 0.5);
                at_centre.copy_from_slice(&centre);
                add(at_previous, row(c), 0.5);
                add(at_previous, row(previous), 0.5);
            }
        }
    }
    let data = Data {
        vertex,
        vertex_width: data.vertex_width,
        varying,
        varying_width: data.varying_width,
        corner,
        corner_width: w,
    };
    (child, data)
}

/// One level of refinement of per-vertex data (`w` floats a vertex) by the scheme's rules: face
/// points, edge points, then vertex points, in the child's vertex order.
fn refine_vertex_data(level: &Level, adj: &Adjacency, scheme: Scheme, values: &[f32], w: usize) -> Vec<f32> {
    let (nv, ne, nf) = (level.vertices, level.edges.len(), level.faces());
    let mut out = vec![0.0; (nv + ne + nf) * w];
    if w == 0 {
        return out;
    }
    let row = |v: usize| &values[v * w..(v + 1) * w];
    let (vertex_points, rest) = out.split_at_mut(nv * w);
    let (edge_points, face_points) = rest.split_at_mut(ne * w);
    for f in 0..nf {
        let range = level.corners(f);
        let weight = 1.0 / range.len() as f32;
        let out = &mut face_points[f * w..(f + 1) * w];
        for c in range {
            add(out, row(level.face_verts[c] as usize), weight);
        }
    }
    let face_point = |f: u32| &face_points[f as usize * w..(f as usize + 1) * w];
    for (e, &[a, b]) in level.edges.iter().enumerate() {
        let s = level.edge_sharpness[e];
        // The share of the smooth rule: all of it on a smooth edge, none on a sharp one, the
        // fraction left on a semi-sharp one in its last sharp level.
        let smooth =
            if scheme == Scheme::CatmullClark && adj.edge_face_count[e] == 2 { (1.0 - s).clamp(0.0, 1.0) } else { 0.0 };
        let out = &mut edge_points[e * w..(e + 1) * w];
        let ends = 0.5 * (1.0 - smooth) + 0.25 * smooth;
        add(out, row(a as usize), ends);
        add(out, row(b as usize), ends);
        if smooth > 0.0 {
            for f in adj.edge_faces[e] {
                add(out, face_point(f), 0.25 * smooth);
            }
        }
    }
    for v in 0..nv {
        let out = &mut vertex_points[v * w..(v + 1) * w];
        let edges = adj.edges_at(v);
        let corners = adj.corners_at(v);
        if scheme == Scheme::Bilinear || edges.is_empty() {
            out.copy_from_slice(row(v));
            continue;
        }
        let closed = edges.len() == corners.len() && edges.len() >= 2;
        let vs = level.vertex_sharpness[v];
        let sharp = |threshold: f32| edges.iter().filter(|&&e| level.edge_sharpness[e as usize] > threshold).count();
        let parent = rule(sharp(0.0), vs > 0.0, closed);
        let child = rule(sharp(1.0), vs > 1.0, closed);
        // `threshold` picks the sharp edges the rule sees: those of this level (0) or the next (1).
        let mut apply = |rule: Rule, threshold: f32, weight: f32| match rule {
            Rule::Corner => add(out, row(v), weight),
            Rule::Crease => {
                add(out, row(v), 0.75 * weight);
                for &e in edges.iter().filter(|&&e| level.edge_sharpness[e as usize] > threshold).take(2) {
                    add(out, row(other_end(level.edges[e as usize], v)), 0.125 * weight);
                }
            }
            Rule::Smooth => {
                let n = edges.len() as f32;
                add(out, row(v), weight * (n - 2.0) / n);
                for &e in edges {
                    add(out, row(other_end(level.edges[e as usize], v)), weight / (n * n));
                }
                for &c in corners {
                    add(out, face_point(adj.corner_face[c as usize]), weight / (n * n));
                }
            }
        };
        if parent == child {
            apply(parent, 0.0, 1.0);
        } else {
            // The rule turns smoother at the next level: blend by the average sharpness of what
            // turns smooth (each at most 1).
            let mut turning: Vec<f32> =
                edges.iter().map(|&e| level.edge_sharpness[e as usize]).filter(|&s| s > 0.0 && s <= 1.0).collect();
            if vs > 0.0 && vs <= 1.0 {
                turning.push(vs);
            }
            let weight = if turning.is_empty() { 1.0 } else { turning.iter().sum::<f32>() / turning.len() as f32 }
                .clamp(0.0, 1.0);
            apply(parent, 0.0, weight);
            apply(child, 1.0, 1.0 - weight);
        }
    }
    out
}

/// The vertex data of the last level moved to the limit surface (Catmull-Clark only).
fn limit_positions(level: &Level, adj: &Adjacency, values: &[f32], w: usize) -> Vec<f32> {
    let mut out = values.to_vec();
    let row = |v: usize| &values[v * w..(v + 1) * w];
    for v in 0..level.vertices {
        let edges = adj.edges_at(v);
        let corners = adj.corners_at(v);
        let n = edges.len();
        let closed = n == corners.len()
            && n >= 3
            && corners.iter().all(|&c| level.corners(adj.corner_face[c as usize] as usize).len() == 4);
        let sharp: Vec<u32> = edges.iter().copied().filter(|&e| level.edge_sharpness[e as usize] > 0.0).collect();
        let target = &mut out[v * w..(v + 1) * w];
        match rule(sharp.len(), level.vertex_sharpness[v] > 0.0, closed) {
            Rule::Corner => {}
            Rule::Crease => {
                // The limit of a cubic B-spline curve at a control point.
                target.fill(0.0);
                add(target, row(v), 4.0 / 6.0);
                for &e in &sharp {
                    add(target, row(other_end(level.edges[e as usize], v)), 1.0 / 6.0);
                }
            }
            Rule::Smooth => {
                // (n^2 v + 4 sum(edge neighbours) + sum(diagonal neighbours)) / (n (n + 5))
                let nf = n as f32;
                let scale = 1.0 / (nf * (nf + 5.0));
                target.fill(0.0);
                add(target, row(v), nf * nf * scale);
                for &e in edges {
                    add(target, row(other_end(level.edges[e as usize], v)), 4.0 * scale);
                }
                for &c in corners {
                    let face = level.corners(adj.corner_face[c as usize] as usize);
                    let diagonal = face.start + (c as usize - face.start + 2) % 4;
                    add(target, row(level.face_verts[diagonal] as usize), scale);
                }
            }
        }
    }
    out
}

/// The limit normal at a smooth vertex of the last level, from its two limit tangents, or `None`
/// where the vertex is not smooth or its faces do not make an oriented ring of quads.
fn limit_normal(level: &Level, adj: &Adjacency, position: impl Fn(usize) -> Vec3, v: usize) -> Option<Vec3> {
    let corners = adj.corners_at(v);
    let n = corners.len();
    if n < 3
        || adj.edges_at(v).len() != n
        || level.vertex_sharpness[v] > 0.0
        || adj.edges_at(v).iter().any(|&e| level.edge_sharpness[e as usize] > 0.0)
    {
        return None;
    }
    // Walk around v: in each quad (v, a, d, b) the next quad is the one across edge (v, a), in
    // which v follows a. The edge neighbours `a` go round clockwise seen from the front.
    let mut ring = Vec::with_capacity(n);
    let start = corners[0] as usize;
    let mut c = start;
    for _ in 0..n {
        let f = adj.corner_face[c] as usize;
        let face = level.corners(f);
        if face.len() != 4 {
            return None;
        }
        let at = |k: usize| level.face_verts[face.start + (c - face.start + k) % 4] as usize;
        let (a, d) = (at(1), at(2));
        ring.push((a, d));
        let e = level.face_edges[c] as usize;
        if adj.edge_face_count[e] != 2 {
            return None;
        }
        let [f0, f1] = adj.edge_faces[e];
        let next = if f0 as usize == f { f1 } else { f0 } as usize;
        if next == f {
            return None;
        }
        let quad = level.corners(next);
        if quad.len() != 4 {
            return None;
        }
        c = quad.clone().find(|&k| {
            level.face_verts[k] as usize == v && level.face_verts[quad.start + (k - quad.start + 3) % 4] as usize == a
        })?;
    }
    if c != start {
        return None;
    }
    // Halstead, Kass and DeRose's tangent masks: edge neighbour i weighs A cos(2 pi i / n), the
    // diagonal between edge neighbours i and i + 1 weighs cos(2 pi i / n) + cos(2 pi (i + 1) / n)
    // (the second tangent with sines).
    let step = std::f32::consts::TAU / n as f32;
    let big_a = 1.0 + step.cos() + (0.5 * step).cos() * (2.0 * (9.0 + step.cos())).sqrt();
    let (mut t0, mut t1) = (Vec3::ZERO, Vec3::ZERO);
    for i in 0..n {
        let (theta, theta_next) = (step * i as f32, step * (i + 1) as f32);
        let edge = position(ring[i].0);
        let diagonal = position(ring[(i + 1) % n].1);
        t0 += edge * (big_a * theta.cos()) + diagonal * (theta.cos() + theta_next.cos());
        t1 += edge * (big_a * theta.sin()) + diagonal * (theta.sin() + theta_next.sin());
    }
    let normal = t1.cross(t0);
    (normal.is_finite() && normal.length_squared() > 1e-30).then(|| normal.normalize())
}

/// The triangles [`subdivision_mesh`] makes of `input`, worked out without refining it: exactly
/// the triangles it draws; for a request whose faces make more than [`MAX_RIB_TRIANGLES`] at one
/// level, which it refuses, all of those (counted from the face sizes alone); 0 for a request it
/// refuses otherwise.
pub fn subdivision_mesh_triangles(input: SubdivisionInput) -> usize {
    let corners = input.nvertices.iter().try_fold(0usize, |sum, &n| Some(sum.saturating_add(usize::try_from(n).ok()?)));
    if let Some(all) = corners.map(|c| quad_triangles(c, levels(c))).filter(|&all| all > MAX_RIB_TRIANGLES) {
        return all;
    }
    Cage::new(&input, &mut Vec::new()).map_or(0, |cage| cage.drawn_triangles())
}

/// `SubdivisionMesh`: the faces refined and pushed to the limit surface, as triangles.
pub fn subdivision_mesh(input: SubdivisionInput, warnings: &mut Vec<String>) -> Result<Mesh, String> {
    let cage = Cage::new(&input, warnings)?;
    let counts = ClassCounts {
        vertex: cage.points.len(),
        varying: cage.points.len(),
        face: input.nvertices.len(),
        corner: Some(input.vertices.len()),
    };
    let params = per_vertex_params(input.params, &counts, warnings);

    // Each class's parameters side by side: (parameter, offset in its class's rows).
    let mut layout = Vec::with_capacity(params.len());
    let (mut vertex_width, mut varying_width, mut corner_width) = (3, 0, 0);
    for d in &params {
        let width = match d.class {
            Class::Vertex => &mut vertex_width,
            Class::Varying => &mut varying_width,
            Class::FaceVarying => &mut corner_width,
            _ => &mut 0,
        };
        layout.push(*width);
        *width += d.components;
    }
    let points = cage.points.len();
    let mut data = Data {
        vertex: vec![0.0; points * vertex_width],
        vertex_width,
        varying: vec![0.0; points * varying_width],
        varying_width,
        corner: vec![0.0; cage.level.face_verts.len() * corner_width],
        corner_width,
    };
    for (v, p) in cage.points.iter().enumerate() {
        data.vertex[v * vertex_width..v * vertex_width + 3].copy_from_slice(&p.to_array());
    }
    for (d, &offset) in params.iter().zip(&layout) {
        let k = d.components;
        let (values, width, rows): (&mut Vec<f32>, usize, Vec<usize>) = match d.class {
            Class::Vertex => (&mut data.vertex, vertex_width, (0..points).collect()),
            Class::Varying => (&mut data.varying, varying_width, (0..points).collect()),
            Class::FaceVarying => {
                (&mut data.corner, corner_width, cage.corner_origin.iter().map(|&c| c as usize).collect())
            }
            _ => continue,
        };
        for (row, source) in rows.into_iter().enumerate() {
            values[row * width + offset..row * width + offset + k]
                .copy_from_slice(&d.values[source * k..(source + 1) * k]);
        }
    }

    let mut level = cage.level;
    for _ in 0..cage.levels {
        let adj = Adjacency::new(&level);
        let (next, next_data) = refine(&level, &adj, cage.scheme, &data);
        level = next;
        data = next_data;
    }
    let adj = Adjacency::new(&level);
    let control = &data.vertex;
    let position = |values: &[f32], v: usize| Vec3::from_slice(&values[v * vertex_width..v * vertex_width + 3]);
    let (limit, normals) = if cage.scheme == Scheme::CatmullClark {
        let limit = limit_positions(&level, &adj, control, vertex_width);
        let normals: Vec<Option<Vec3>> =
            (0..level.vertices).map(|v| limit_normal(&level, &adj, |u| position(control, u), v)).collect();
        (limit, normals)
    } else {
        (control.clone(), vec![None; level.vertices])
    };
    assemble(&level, &adj, &cage.drawn, &limit, &normals, &data, &params, &layout)
}

/// The drawn quads of the last level as a mesh: vertices shared across smooth edges (one per
/// corner where facevarying or uniform data needs it), normals from the limit or, at sharp
/// features, per side.
#[allow(clippy::too_many_arguments)]
fn assemble(
    level: &Level,
    adj: &Adjacency,
    drawn: &[bool],
    limit: &[f32],
    limit_normals: &[Option<Vec3>],
    data: &Data,
    params: &[PerVertex],
    layout: &[usize],
) -> Result<Mesh, String> {
    let w = data.vertex_width;
    let position = |v: usize| Vec3::from_slice(&limit[v * w..v * w + 3]);
    let corners = level.face_verts.len();
    // Sides: the corners at a vertex joined across edges that are not sharp.
    let mut sides = UnionFind::new(corners);
    for (e, &[a, b]) in level.edges.iter().enumerate() {
        if adj.edge_face_count[e] != 2 || level.edge_sharpness[e] > 0.0 {
            continue;
        }
        let [f0, f1] = adj.edge_faces[e];
        for v in [a, b] {
            let at = |f: u32| level.corners(f as usize).find(|&c| level.face_verts[c] == v);
            if let (Some(c0), Some(c1)) = (at(f0), at(f1)) {
                sides.union(c0, c1);
            }
        }
    }
    let mut side_normal = vec![Vec3::ZERO; corners];
    let mut face_normals = Vec::with_capacity(level.faces());
    for f in 0..level.faces() {
        let range = level.corners(f);
        // Newell's normal: twice the area, along the normal.
        let mut normal = Vec3::ZERO;
        for c in range.clone() {
            let next = if c + 1 == range.end { range.start } else { c + 1 };
            normal += position(level.face_verts[c] as usize).cross(position(level.face_verts[next] as usize));
        }
        let normal = if normal.is_finite() { normal } else { Vec3::ZERO };
        face_normals.push(normal);
        for c in range {
            let side = sides.find(c);
            side_normal[side] += normal;
        }
    }

    let per_corner = params.iter().any(|d| matches!(d.class, Class::Uniform | Class::FaceVarying));
    let mut index = vec![NONE; corners];
    let mut mesh = Mesh { normals: Some(Vec::new()), ..Default::default() };
    let mut attributes: Vec<Attribute> = params.iter().map(|d| d.attribute(Vec::new())).collect();
    for f in 0..level.faces() {
        if !drawn[level.face_origin[f] as usize] {
            continue;
        }
        let range = level.corners(f);
        let mut ids = Vec::with_capacity(range.len());
        for c in range {
            let key = if per_corner { c } else { sides.find(c) };
            if index[key] == NONE {
                let v = level.face_verts[c] as usize;
                index[key] = u32::try_from(mesh.positions.len()).map_err(|_| "too many vertices".to_string())?;
                mesh.positions.push(position(v));
                let normal = limit_normals[v].unwrap_or_else(|| {
                    side_normal[sides.find(c)].try_normalize().unwrap_or_else(|| face_normals[f].normalize_or(Vec3::Z))
                });
                if let Some(normals) = mesh.normals.as_mut() {
                    normals.push(normal);
                }
                for ((attribute, d), &offset) in attributes.iter_mut().zip(params).zip(layout) {
                    let k = d.components;
                    let values = match d.class {
                        Class::Vertex => &limit[v * w + offset..v * w + offset + k],
                        Class::Varying => {
                            let at = v * data.varying_width + offset;
                            &data.varying[at..at + k]
                        }
                        Class::FaceVarying => {
                            let at = c * data.corner_width + offset;
                            &data.corner[at..at + k]
                        }
                        _ => {
                            let face = level.face_origin[f] as usize;
                            &d.values[face * k..(face + 1) * k]
                        }
                    };
                    attribute.data.extend_from_slice(values);
                }
            }
            ids.push(index[key]);
        }
        for k in 1..ids.len().saturating_sub(1) {
            mesh.triangles.push([ids[0], ids[k], ids[k + 1]]);
        }
    }
    route_attributes(&mut mesh, attributes);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::{mesh_from_request, parse_str, request_triangles, MeshOptions, RibDiagnostic, Severity};
    use glam::Vec2;

    /// The cube -1..1: the square at z = -1, then the one at z = 1, each counter-clockwise seen
    /// from +z; faces counter-clockwise seen from outside (bottom, top, front, right, back, left).
    const CUBE_POINTS: &str = "-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1";
    const CUBE_FACES: &str = "[4 4 4 4 4 4] [0 3 2 1  4 5 6 7  0 1 5 4  1 2 6 5  2 3 7 6  3 0 4 7]";
    /// Every edge of the cube, as crease chains (top loop, bottom loop, four verticals).
    const CUBE_EDGES: &str = "[0 1 2 3 0  4 5 6 7 4  0 4  1 5  2 6  3 7]";

    fn cube(tags: &str, params: &str) -> String {
        format!(r#"SubdivisionMesh "catmull-clark" {CUBE_FACES} {tags} "P" [{CUBE_POINTS}] {params}"#)
    }

    /// `crease` on all twelve edges of the cube, sharpness `s`.
    fn creased_cube(s: f32) -> String {
        let tags = format!(
            r#"["crease" "crease" "crease" "crease" "crease" "crease"] [5 1 5 1 2 1 2 1 2 1 2 1] {CUBE_EDGES} [{s} {s} {s} {s} {s} {s}]"#
        );
        cube(&tags, "")
    }

    /// The mesh of the only request in `text`, its diagnostics, and what the request was counted as.
    fn build(text: &str) -> (Mesh, Vec<RibDiagnostic>, usize) {
        let parse = parse_str(text, "test.rib");
        assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
        let mut diagnostics = Vec::new();
        let request = &parse.requests[0];
        let counted = request_triangles(request, &MeshOptions::default());
        let mesh = mesh_from_request(request, &mut diagnostics).unwrap_or_else(|| panic!("{diagnostics:?}"));
        mesh.validate().unwrap();
        assert_eq!(counted, mesh.triangle_count(), "{text}");
        (mesh, diagnostics, counted)
    }

    fn nearest(mesh: &Mesh, target: Vec3) -> (usize, f32) {
        mesh.positions
            .iter()
            .enumerate()
            .map(|(k, p)| (k, p.distance(target)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap()
    }

    fn triangle_normal(mesh: &Mesh, t: usize) -> Vec3 {
        let [a, b, c] = mesh.corners(t);
        (b - a).cross(c - a).normalize()
    }

    /// The Catmull-Clark limit point of a vertex of valence `n` with edge neighbours `edges` and
    /// diagonal neighbours `diagonals`: (n^2 v + 4 sum(edges) + sum(diagonals)) / (n (n + 5)).
    fn limit_mask(v: Vec3, edges: &[Vec3], diagonals: &[Vec3]) -> Vec3 {
        let n = edges.len() as f32;
        (n * n * v + 4.0 * edges.iter().sum::<Vec3>() + diagonals.iter().sum::<Vec3>()) / (n * (n + 5.0))
    }

    #[test]
    fn a_cube_becomes_its_limit_surface() {
        let (mesh, diagnostics, _) = build(&cube("", ""));
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        // Four levels: 6 faces x 4 corners x 4^3 quads, two triangles each; shared vertices.
        assert_eq!(mesh.triangle_count(), 6 * 4 * 64 * 2);
        assert_eq!(mesh.positions.len(), 6 * 16 * 16 + 2);
        let normals = mesh.normals.as_ref().unwrap();

        // A cube corner (valence 3) goes to its limit point straight from the cage.
        let v = Vec3::ONE;
        let edges = [Vec3::new(-1.0, 1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, -1.0)];
        let diagonals = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, -1.0, -1.0)];
        let corner = limit_mask(v, &edges, &diagonals);
        assert!((corner - Vec3::splat(0.5)).length() < 1e-6);
        let (k, d) = nearest(&mesh, corner);
        assert!(d < 1e-5, "corner limit {corner}, nearest {}", mesh.positions[k]);
        assert!(normals[k].dot(Vec3::ONE.normalize()) > 0.99999, "{}", normals[k]);

        // A face centre (valence 4) after one level by hand: the face point of the top face, the
        // edge points of its edges, the vertex points of its corners.
        let top = Vec3::Z;
        let face_points = [Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y];
        let corners = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, 1.0),
        ];
        // Edge k joins corner k and k + 1, between the top face and the side face k + 1 (of +y, -x, -y, +x).
        let edge_points: Vec<Vec3> =
            (0..4).map(|k| (corners[k] + corners[(k + 1) % 4] + top + face_points[(k + 1) % 4]) / 4.0).collect();
        // A corner (valence 3): its three edge neighbours sum to the corner itself (one coordinate
        // flipped each), its three face points to the corner's direction.
        let vertex_points: Vec<Vec3> = corners.iter().map(|&c| c / 3.0 + c / 9.0 + c / 9.0).collect();
        let centre = limit_mask(top, &edge_points, &vertex_points);
        assert!((centre.z - (16.0 + 12.0 + 20.0 / 9.0) / 36.0).abs() < 1e-6);
        let (k, d) = nearest(&mesh, centre);
        assert!(d < 1e-5, "face centre limit {centre}, nearest {}", mesh.positions[k]);
        assert!(normals[k].dot(Vec3::Z) > 0.99999, "{}", normals[k]);

        // The whole surface lies inside the cage, between those two points' distances, and is lit
        // from outside: each vertex normal close to its triangles' normals, pointing out.
        for p in &mesh.positions {
            assert!(
                p.abs().max_element() < 1.0 && p.length() > centre.z - 1e-5 && p.length() < 0.5 * 3f32.sqrt() + 1e-5
            );
        }
        for t in 0..mesh.triangle_count() {
            let n = triangle_normal(&mesh, t);
            for i in mesh.triangles[t] {
                assert!(normals[i as usize].dot(n) > 0.99, "{t}: {} vs {n}", normals[i as usize]);
            }
        }
    }

    #[test]
    fn a_fully_creased_cube_keeps_its_edges() {
        let (mesh, _, _) = build(&creased_cube(10.0));
        let normals = mesh.normals.as_ref().unwrap();
        for p in &mesh.positions {
            assert!((p.abs().max_element() - 1.0).abs() < 1e-5, "{p} is off the cube");
        }
        for corner in 0..8 {
            let c = Vec3::new([-1.0, 1.0][corner & 1], [-1.0, 1.0][(corner >> 1) & 1], [-1.0, 1.0][corner >> 2]);
            assert!(nearest(&mesh, c).1 < 1e-5, "corner {c} missing");
        }
        // Flat faces, each with its own normals along the edges.
        for t in 0..mesh.triangle_count() {
            let n = triangle_normal(&mesh, t);
            assert!(n.abs().max_element() > 0.99999, "{n}");
            for i in mesh.triangles[t] {
                assert!(normals[i as usize].dot(n) > 0.99999);
            }
        }
        // The same with interpolateboundary on a flat quad: the quad itself.
        let (quad, _, _) = build(
            r#"SubdivisionMesh "catmull-clark" [4] [0 1 2 3] ["interpolateboundary"] [0 0] [] [] "P" [0 0 0  2 0 0  2 1 0  0 1 0]"#,
        );
        let (min, max) = quad.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(a, b), &p| (a.min(p), b.max(p)));
        assert!(min.abs().max_element() < 1e-6 && (max - Vec3::new(2.0, 1.0, 0.0)).abs().max_element() < 1e-6);
        assert!(quad.normals.as_ref().unwrap().iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn semi_sharp_creases_blend_smooth_and_sharp() {
        // The top face's edges creased with sharpness s: the centre of the top face, and how far the
        // surface reaches towards the middle of a top edge (1, 0, 1).
        let measure = |s: f32| {
            let tags = format!(r#"["crease"] [5 1] [4 5 6 7 4] [{s}]"#);
            let (mesh, _, _) = build(&cube(&tags, ""));
            let centre = mesh.positions.iter().filter(|p| p.x.abs() < 1e-5 && p.y.abs() < 1e-5 && p.z > 0.0);
            let reach = mesh.positions.iter().map(|p| p.x + p.z).fold(f32::MIN, f32::max);
            (centre.map(|p| p.z).fold(f32::MIN, f32::max), reach)
        };
        let sharpness = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 10.0];
        let (centres, reaches): (Vec<f32>, Vec<f32>) = sharpness.iter().map(|&s| measure(s)).unzip();
        let smooth = (16.0 + 12.0 + 20.0 / 9.0) / 36.0;
        assert!((centres[0] - smooth).abs() < 1e-5, "{centres:?}");
        // Half as sharp: a blend of the two rules for one level, half way up.
        assert!(centres[1] > smooth + 0.01 && centres[1] < 1.0 - 0.01, "{centres:?}");
        // Sharp for one level or more: the top face's points of the first level all lie on the top,
        // and so does the limit of its centre.
        assert!(centres[2..].iter().all(|&z| (z - 1.0).abs() < 1e-5), "{centres:?}");
        assert!(reaches.windows(2).all(|w| w[1] > w[0] + 1e-4), "{reaches:?}");
        // Sharpness past the levels refined is as sharp as can be.
        assert!((measure(10.0).1 - measure(1000.0).1).abs() < 1e-6);
    }

    #[test]
    fn corners_stay_where_they_are_sharp() {
        let corner = |s: f32| {
            let (mesh, _, _) = build(&cube(&format!(r#"["corner"] [1 1] [6] [{s}]"#), ""));
            mesh.positions[nearest(&mesh, Vec3::ONE).0]
        };
        // The smooth limit of the corner is (1/2, 1/2, 1/2); a sharp corner stays at (1, 1, 1).
        assert!((corner(0.0) - Vec3::splat(0.5)).length() < 1e-5);
        assert!((corner(10.0) - Vec3::ONE).length() < 1e-5);
        let (half, one) = (corner(0.5), corner(1.0));
        assert!(half.x > 0.5 + 1e-3 && half.x < one.x - 1e-3 && one.x < 1.0 - 1e-3, "{half} {one}");
        assert!((half.x - half.y).abs() < 1e-6 && (half.x - half.z).abs() < 1e-6);
    }

    /// A flat 4 x 4 grid of points (3 x 3 quads), wound counter-clockwise seen from +z.
    fn grid(tags: &str) -> String {
        let points: Vec<String> = (0..16).map(|k| format!("{} {} 0", k % 4, k / 4)).collect();
        let faces: Vec<String> = (0..9)
            .map(|f| {
                let v = f % 3 + 4 * (f / 3);
                format!("{} {} {} {}", v, v + 1, v + 5, v + 4)
            })
            .collect();
        format!(
            r#"SubdivisionMesh "catmull-clark" [4 4 4 4 4 4 4 4 4] [{}] {tags} "P" [{}]"#,
            faces.join(" "),
            points.join(" ")
        )
    }

    fn extent(mesh: &Mesh) -> (Vec3, Vec3) {
        mesh.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(a, b), &p| (a.min(p), b.max(p)))
    }

    #[test]
    fn boundaries_are_interpolated_only_when_asked() {
        // RenderMan's default: the faces on the boundary only shape the middle one, a uniform
        // B-spline patch, which spans the middle square of a regular grid exactly.
        let (middle, _, _) = build(&grid(""));
        assert_eq!(middle.triangle_count(), 4 * 64 * 2);
        let (min, max) = extent(&middle);
        assert!((min - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-5 && (max - Vec3::new(2.0, 2.0, 0.0)).length() < 1e-5);
        // Edges and corners: the whole grid, out to its corners.
        let (whole, _, _) = build(&grid(r#"["interpolateboundary"] [0 0] [] []"#));
        assert_eq!(whole.triangle_count(), 9 * 4 * 64 * 2);
        let (min, max) = extent(&whole);
        assert!(min.length() < 1e-5 && (max - Vec3::new(3.0, 3.0, 0.0)).length() < 1e-5, "{min} {max}");
        assert!(whole.normals.as_ref().unwrap().iter().all(|n| (*n - Vec3::Z).length() < 1e-5));
        let (same, _, _) = build(&grid(r#"["interpolateboundary"] [1 0] [1] []"#));
        assert_eq!(same.positions, whole.positions);
        // Edges only: the corners are crease vertices, at the limit of their boundary curve.
        let (rounded, _, _) = build(&grid(r#"["interpolateboundary"] [1 0] [2] []"#));
        let (k, d) = nearest(&rounded, Vec3::ZERO);
        assert!(
            (rounded.positions[k] - Vec3::new(1.0, 1.0, 0.0) / 6.0).length() < 1e-5,
            "{} at {d}",
            rounded.positions[k]
        );
        // Argument 0 is the default.
        let (none, _, _) = build(&grid(r#"["interpolateboundary"] [1 0] [0] []"#));
        assert_eq!(none.positions, middle.positions);
    }

    #[test]
    fn holes_are_not_drawn_but_shape_their_neighbours() {
        let (full, _, _) = build(&cube("", ""));
        let (holed, diagnostics, counted) = build(&cube(r#"["hole"] [1 0] [1] []"#, ""));
        assert!(diagnostics.is_empty());
        assert_eq!(counted, full.triangle_count() * 5 / 6);
        for p in &holed.positions {
            assert!(nearest(&full, *p).1 < 1e-6, "{p} is not on the cube's surface");
        }
        let on_top = |mesh: &Mesh| {
            (0..mesh.triangle_count())
                .filter(|&t| {
                    let c = mesh.corners(t).iter().sum::<Vec3>() / 3.0;
                    c.z > 0.8 && c.x.abs() < 0.5 && c.y.abs() < 0.5
                })
                .count()
        };
        assert!(on_top(&full) > 0);
        assert_eq!(on_top(&holed), 0);
    }

    #[test]
    fn other_shapes_and_schemes() {
        // Triangles (a tetrahedron), n-gons (a pentagonal prism): smooth, closed, lit from outside.
        let tetrahedron = r#"SubdivisionMesh "catmull-clark" [3 3 3 3] [0 1 2  0 3 1  1 3 2  0 2 3]
            "P" [1 1 1  1 -1 -1  -1 1 -1  -1 -1 1]"#;
        let ring = |z: f32| {
            (0..5).map(move |k| {
                let a = std::f32::consts::TAU * k as f32 / 5.0;
                format!("{} {} {z}", a.cos(), a.sin())
            })
        };
        let prism = format!(
            r#"SubdivisionMesh "catmull-clark" [5 5 4 4 4 4 4] [4 3 2 1 0  5 6 7 8 9  0 1 6 5  1 2 7 6  2 3 8 7  3 4 9 8  4 0 5 9] "P" [{}]"#,
            ring(-1.0).chain(ring(1.0)).collect::<Vec<_>>().join("  ")
        );
        for text in [tetrahedron, prism.as_str()] {
            let (mesh, _, _) = build(text);
            assert!(mesh.triangle_count() > 0);
            let centre = mesh.positions.iter().sum::<Vec3>() / mesh.positions.len() as f32;
            for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
                assert!(n.dot(*p - centre) > 0.0, "{text}: normal {n} at {p}");
            }
        }
        // Bilinear: the cage refined flat, each face with its own normals.
        let (bilinear, _, _) = build(&cube("", "").replace("catmull-clark", "bilinear"));
        assert_eq!(bilinear.triangle_count(), 6 * 4 * 64 * 2);
        assert!(bilinear.positions.iter().all(|p| (p.abs().max_element() - 1.0).abs() < 1e-6));
        for t in 0..bilinear.triangle_count() {
            let n = triangle_normal(&bilinear, t);
            assert!(bilinear.triangles[t]
                .iter()
                .all(|&i| bilinear.normals.as_ref().unwrap()[i as usize].dot(n) > 0.99999));
        }
    }

    #[test]
    fn primitive_variables_follow_their_classes() {
        let xs = "-1 1 1 -1 -1 1 1 -1";
        let colours = "0 0 0  1 0 0  1 1 0  0 1 0  0 0 1  1 0 1  1 1 1  0 1 1";
        let corners = "0 0 1 0 1 1 0 1 ".repeat(6);
        let (mesh, diagnostics, _) = build(&cube(
            "",
            &format!(
                r#""vertex float px" [{xs}] "varying color Cs" [{colours}] "uniform float id" [0 1 2 3 4 5]
                   "facevarying float[2] st" [{corners}] "constant float Kd" 0.5"#
            ),
        ));
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let attribute = |name: &str| &mesh.attributes.iter().find(|a| a.name == name).unwrap().data;
        // Vertex data follows the subdivision rules and the limit, as P does.
        for (p, x) in mesh.positions.iter().zip(attribute("px")) {
            assert!((p.x - x).abs() < 1e-5);
        }
        // Varying data is linear: the cage corner's colour stays at the corner's limit point.
        let (k, _) = nearest(&mesh, Vec3::splat(0.5));
        assert_eq!(&attribute("Cs")[3 * k..3 * k + 3], &[1.0, 1.0, 1.0]);
        assert!(attribute("Cs").iter().all(|c| (0.0..=1.0).contains(c)));
        // Uniform data is the face's over its quads.
        let id = attribute("id");
        let mut per_face = [0usize; 6];
        for t in &mesh.triangles {
            let face = id[t[0] as usize];
            assert!(t.iter().all(|&i| id[i as usize] == face));
            per_face[face as usize] += 1;
        }
        assert_eq!(per_face, [mesh.triangle_count() / 6; 6]);
        // Facevarying data is linear within each face: the face centres have st (1/2, 1/2).
        let uvs = mesh.uvs.as_ref().unwrap();
        let centres: Vec<Vec3> =
            (0..mesh.positions.len()).filter(|&k| uvs[k] == Vec2::splat(0.5)).map(|k| mesh.positions[k]).collect();
        assert!(centres.len() >= 6);
        for c in centres {
            assert!((c.abs().max_element() - 0.8395062).abs() < 1e-5 && c.abs().min_element() < 1e-5, "{c}");
        }
        assert!(uvs.iter().all(|uv| uv.min_element() >= 0.0 && uv.max_element() <= 1.0));
        // A given N replaces the computed normals.
        let (given, _, _) = build(&cube("", r#""vertex normal N" [0 0 2 0 0 2 0 0 2 0 0 2 0 0 2 0 0 2 0 0 2 0 0 2]"#));
        assert!(given.normals.as_ref().unwrap().iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn bad_data_is_an_error_at_the_request() {
        let quad = r#""P" [0 0 0  1 0 0  1 1 0  0 1 0]"#;
        for (args, message) in [
            ("[4] [0 1 2 9]", "vertex index 9 (entry 3) is negative or not below the number of points (4)"),
            ("[4] [0 1 -2 3]", "vertex index -2"),
            ("[4 4] [0 1 2 3]", "the faces have 8 vertices in all but 4 vertex indices are given"),
            ("[2 2] [0 1 2 3]", "face 0 has 2 vertices: every face needs at least 3"),
            ("[] []", "the subdivision mesh has no faces"),
            ("[4] [0 0 1 2]", "no face of the subdivision mesh can be subdivided"),
            (r#"[4] [0 1 2 3] ["crease"] [2] [0 1] [5]"#, "1 tag need 2 argument counts"),
            (r#"[4] [0 1 2 3] ["crease"] [1 1] [0] [5]"#, "tag \"crease\" takes two or more vertex indices"),
            (r#"[4] [0 1 2 3] ["crease"] [2 1] [0 7] [5]"#, "tag \"crease\": vertex index 7 (entry 1)"),
            (r#"[4] [0 1 2 3] ["corner"] [1 2] [0] [1 2]"#, "tag \"corner\" takes vertex indices"),
            (r#"[4] [0 1 2 3] ["hole"] [1 0] [7] []"#, "tag \"hole\" names face 7, but the mesh has 1 face"),
            (
                r#"[4] [0 1 2 3] ["hole"] [2 0] [0] []"#,
                "tag \"hole\" takes 2 integer arguments from 0 on, but only 1 are given",
            ),
            (
                r#"[4] [0 1 2 3] ["hole"] [1 0] [0 0] []"#,
                "the tags take 1 integer argument and 0 float arguments, but 2 and 0",
            ),
            (r#"[4] [0 1 2 3] ["hole"] [-1 0] [] []"#, "negative argument count"),
            (r#"[4] [0 1 2 3] ["interpolateboundary"] [1 0] [5] []"#, "takes 0, 1 or 2, not 5"),
            (r#"[4] [0 1 2 3] ["interpolateboundary"] [0 1] [] [1]"#, "at most one integer"),
        ] {
            let text = format!(r#"SubdivisionMesh "catmull-clark" {args} {quad}"#);
            let parse = parse_str(&text, "bad.rib");
            assert!(parse.diagnostics.is_empty(), "{text}: {:?}", parse.diagnostics);
            let mut diagnostics = Vec::new();
            assert!(mesh_from_request(&parse.requests[0], &mut diagnostics).is_none(), "{text}");
            let errors: Vec<String> =
                diagnostics.iter().filter(|d| d.severity == Severity::Error).map(ToString::to_string).collect();
            assert_eq!(errors.len(), 1, "{text}: {diagnostics:?}");
            assert!(
                errors[0].starts_with("bad.rib:1:1: error: ") && errors[0].contains(message),
                "{text}: {}",
                errors[0]
            );
            assert_eq!(request_triangles(&parse.requests[0], &MeshOptions::default()), 0);
        }
        // Not a number (which only the API can pass).
        let params = parse_str(&format!("Polygon {quad}"), "p.rib").requests.remove(0);
        let crate::rib::RequestKind::Polygon(params) = params.kind else { panic!() };
        let nan = SubdivisionInput {
            scheme: "catmull-clark",
            nvertices: &[4],
            vertices: &[0, 1, 2, 3],
            tags: &["crease".to_string()],
            nargs: &[2, 1],
            intargs: &[0, 1],
            floatargs: &[f32::NAN],
            params: &params,
        };
        assert!(subdivision_mesh(nan, &mut Vec::new()).unwrap_err().contains("has a sharpness that is not a number"));
        for (text, message) in [
            (
                r#"SubdivisionMesh "loop" [3] [0 1 2] "P" [0 0 0 1 0 0 0 1 0]"#,
                "subdivision scheme \"loop\" is not supported",
            ),
            (r#"SubdivisionMesh "catmull-clark" [3] [0 1 2] "Cs" [1 1 1]"#, "no positions"),
        ] {
            let parse = parse_str(text, "bad.rib");
            let mut diagnostics = Vec::new();
            assert!(mesh_from_request(&parse.requests[0], &mut diagnostics).is_none());
            assert!(diagnostics[0].to_string().contains(message), "{diagnostics:?}");
        }
    }

    #[test]
    fn odd_input_is_warned_about_and_odd_topology_still_makes_a_surface() {
        // An unknown tag, a face that repeats a vertex, a crease between unjoined vertices.
        let text = cube(r#"["facevaryinginterpolateboundary" "crease"] [1 0 2 1] [1 0 6] [2]"#, "")
            .replace("[4 4 4 4 4 4]", "[4 4 4 4 4 4 3]")
            .replace("3 0 4 7]", "3 0 4 7  1 1 2]");
        let (mesh, diagnostics, _) = build(&text);
        let messages: Vec<&str> = diagnostics.iter().map(|d| d.message.as_str()).collect();
        assert_eq!(
            messages,
            [
                "1 face that repeats a vertex skipped: a face must have distinct vertices",
                "subdivision mesh tag \"facevaryinginterpolateboundary\" is not supported and is ignored",
                "1 pair of tag \"crease\" joins vertices that no edge of the mesh joins: ignored",
            ]
        );
        assert_eq!(mesh.triangle_count(), 6 * 4 * 64 * 2);

        for text in [
            // Three quads on one edge (a fin).
            r#"SubdivisionMesh "catmull-clark" [4 4 4] [0 1 2 3  1 0 4 5  0 1 6 7] ["interpolateboundary"] [0 0] [] []
               "P" [0 0 0  1 0 0  1 1 0  0 1 0  0 -1 0  1 -1 0  1 0 1  0 0 1]"#,
            // Two triangles meeting at a vertex only (a bow tie), with interpolateboundary.
            r#"SubdivisionMesh "catmull-clark" [3 3] [0 1 2  0 3 4] ["interpolateboundary"] [0 0] [] []
               "P" [0 0 0  1 0 0  1 1 0  -1 0 0  -1 -1 0]"#,
            // Two quads that disagree on their shared edge's direction.
            r#"SubdivisionMesh "catmull-clark" [4 4] [0 1 2 3  1 4 5 2] ["interpolateboundary"] [0 0] [] []
               "P" [0 0 0  1 0 0  1 1 0  0 1 0  2 0 0  2 1 0]"#,
            // A large n-gon, and an unused point.
            &format!(
                r#"SubdivisionMesh "catmull-clark" [40] [{}] ["interpolateboundary"] [0 0] [] [] "P" [{} 9 9 9]"#,
                (0..40).map(|k| k.to_string()).collect::<Vec<_>>().join(" "),
                (0..40)
                    .map(|k| {
                        let a = std::f32::consts::TAU * k as f32 / 40.0;
                        format!("{} {} 0", a.cos(), a.sin())
                    })
                    .collect::<Vec<_>>()
                    .join(" ")
            ),
        ] {
            let (mesh, _, _) = build(text);
            assert!(mesh.triangle_count() > 0, "{text}");
            assert!(
                mesh.positions.iter().all(|p| p.is_finite())
                    && mesh.normals.as_ref().unwrap().iter().all(|n| n.is_finite())
            );
        }
    }

    #[test]
    fn levels_keep_within_the_budget() {
        assert_eq!(levels(24), MAX_SUBDIVISION_LEVELS);
        assert!(quad_triangles(100_000, levels(100_000)) <= SUBDIVISION_TRIANGLE_BUDGET);
        assert_eq!(levels(10_000_000), 1);
        // One level of a cage too large is refused before it is refined (and counted as what it
        // would make, for the load to refuse first).
        let parse = parse_str(r#"Polygon "P" [0 0 0  1 0 0  0 1 0]"#, "p.rib");
        let crate::rib::RequestKind::Polygon(params) = &parse.requests[0].kind else { panic!() };
        let triangles = MAX_RIB_TRIANGLES / 6 + 1;
        let (nvertices, vertices) = (vec![3; triangles], [0, 1, 2].repeat(triangles));
        let big = SubdivisionInput {
            scheme: "catmull-clark",
            nvertices: &nvertices,
            vertices: &vertices,
            tags: &[],
            nargs: &[],
            intargs: &[],
            floatargs: &[],
            params,
        };
        assert_eq!(subdivision_mesh_triangles(big), 6 * triangles);
        let error = subdivision_mesh(big, &mut Vec::new()).unwrap_err();
        assert!(error.contains(&format!("more than the {MAX_RIB_TRIANGLES}")), "{error}");
    }

    #[test]
    fn hierarchical_meshes_are_subdivision_meshes_with_string_arguments() {
        // PRMan's request as RenderMan for Maya writes it: three counts a tag, then strings.
        let creased = creased_cube(2.0);
        let (plain, _, _) = build(&creased);
        let hierarchical = creased
            .replace("SubdivisionMesh", "HierarchicalSubdivisionMesh")
            .replace("[5 1 5 1 2 1 2 1 2 1 2 1]", "[5 1 0 5 1 0 2 1 0 2 1 0 2 1 0 2 1 0]")
            .replace("2 2 2 2 2]", "2 2 2 2 2] []");
        let (same, _, _) = build(&hierarchical);
        assert_eq!((same.positions, same.triangles), (plain.positions, plain.triangles));
        // A tag of strings alone is read past and warned of, as any tag this loader does not use.
        let (_, diagnostics, _) = build(
            &cube(r#"["creasemethod" "interpolateboundary"] [0 0 1 1 0 0] [1] [] ["chaikin"]"#, "")
                .replace("SubdivisionMesh", "HierarchicalSubdivisionMesh"),
        );
        let messages: Vec<&str> = diagnostics.iter().map(|d| d.message.as_str()).collect();
        assert_eq!(messages, ["subdivision mesh tag \"creasemethod\" is not supported and is ignored"]);

        for (tags, message) in [
            (r#"["corner"] [1 1] [0] [2.5] []"#, "which take 3 argument counts (three a tag), but 2 are given"),
            (r#"["creasemethod"] [0 0 1] [] [] []"#, "take 1 string arguments, but 0 are given"),
            (r#"["creasemethod"] [0 0 -1] [] [] ["a"]"#, "take -1 string arguments, but 1 are given"),
        ] {
            let parse = parse_str(&cube(tags, "").replace("SubdivisionMesh", "HierarchicalSubdivisionMesh"), "t.rib");
            let errors: Vec<String> = parse.errors().map(ToString::to_string).collect();
            assert!(errors.len() == 1 && errors[0].contains(message), "{tags}: {errors:?}");
            assert!(parse.requests.is_empty());
        }
    }

    #[test]
    fn tag_arrays_are_optional_in_the_request() {
        use crate::rib::RequestKind as K;
        let parse = parse_str(
            r#"SubdivisionMesh "catmull-clark" [3] [0 1 2] "P" [0 0 0 1 0 0 0 1 0]
               SubdivisionMesh "catmull-clark" [3] [0 1 2] [] [] [] [] "P" [0 0 0 1 0 0 0 1 0]
               SubdivisionMesh "catmull-clark" [3] [0 1 2] ["corner"] [1 1] [0] [2.5] "P" [0 0 0 1 0 0 0 1 0]
               SubdivisionMesh "catmull-clark" [3] [0 1 2] ["corner"] "P" [0 0 0 1 0 0 0 1 0]"#,
            "t.rib",
        );
        let kinds: Vec<&K> = parse.requests.iter().map(|r| &r.kind).collect();
        assert_eq!(kinds.len(), 3);
        assert!(matches!(kinds[0], K::SubdivisionMesh { tags, params, .. } if tags.is_empty() && params.len() == 1));
        assert!(matches!(kinds[1], K::SubdivisionMesh { tags, .. } if tags.is_empty()));
        assert!(
            matches!(kinds[2], K::SubdivisionMesh { tags, floatargs, .. } if tags == &["corner"] && floatargs == &[2.5])
        );
        let errors: Vec<String> = parse.errors().map(ToString::to_string).collect();
        assert_eq!(errors.len(), 1);
        assert!(errors[0].contains("expects an array of integers (tag argument counts), found a string"), "{errors:?}");
    }
}

//! Dicing: each triangle of a mesh split into `n * n` smaller ones, so that a displacement
//! shader, run once per vertex, has vertices to move between the source's corners. [`dice`] cuts
//! every triangle and edge at one rate; [`dice_at`] gives each triangle a rate of its own and each
//! edge one (a mesh seen near and far is diced finely near and coarsely far).
//!
//! A source triangle `[a, b, c]` diced at rate `n` has the points `(i, j)` with `i + j <= n`, the
//! point at hit coordinates `(i / n, j / n)` (weights `[1 - u - v, u, v]` on `[a, b, c]`, as a hit
//! is interpolated in [`crate::scene::Scene::surface_at`]). An edge diced at rate `e` (never above
//! the rates of the triangles that use it) has `e - 1` points inside; a triangle's grid points on
//! that edge are moved to the edge's nearest point (`round(s * e / n)` of `e`, counted from the
//! edge's lower vertex), so that where an edge is coarser than its triangle, the triangle's
//! outermost cells fold into triangles of no area along it.
//!
//! Invariants of [`dice_at`]'s result (and so of [`dice`]'s):
//! - watertight: each source vertex that a triangle uses becomes one diced vertex; the `e - 1`
//!   points inside a source edge (an unordered pair of vertex indices, whichever triangles use it)
//!   are made once and shared by all of them, and every triangle's boundary along the edge passes
//!   through all of them in order; the points inside a triangle are its own. So a closed mesh
//!   dices to a closed mesh. An edge's points are computed from its two ends alone, measured
//!   from the lower-indexed one, so that they do not depend on which triangle made them;
//! - source vertices that no triangle uses are dropped, so that every diced vertex lies on a
//!   source triangle ([`Diced::origins`]); with V used vertices, E distinct edges and T triangles
//!   there are `V + E (n - 1) + T (n - 1) (n - 2) / 2` vertices at one rate `n` (the sum of each
//!   edge's `e - 1` and each triangle's `(n - 1) (n - 2) / 2` at several): the used source vertices first,
//!   in source order (so rate 1 gives the source mesh back), then the new points in the order the
//!   triangles first need them;
//! - every diced triangle winds as its source triangle does, and a source triangle's diced
//!   triangles cover it exactly; source triangle `t` gives `n * n` diced triangles (those of area
//!   0 along coarser edges included), after those of the triangles before it;
//! - per-vertex data (positions, normals, uvs, every attribute's components, a deformation's
//!   positions and normals) is interpolated linearly, by the same expressions as positions, and
//!   normals are left as interpolated, not renormalised, as a hit's interpolated normal is before
//!   shading normalises it;
//! - the result passes [`Mesh::validate`]: sizes are counted with checked arithmetic and refused
//!   past [`check_triangle_count`] before anything is allocated.

use super::mesh::{check_triangle_count, Attribute, Deformation, Mesh, MeshError};
use std::ops::{Add, Mul, Sub};

/// Where a diced vertex lies on the source mesh: a source triangle it lies on and its hit
/// coordinates there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DicedVertex {
    /// The source triangle (the first one that uses the vertex, for a vertex on its corners or
    /// edges).
    pub triangle: u32,
    /// Hit coordinates on it: the point with weights `[1 - u - v, u, v]` on its corners.
    pub u: f32,
    pub v: f32,
}

/// A diced mesh, with where each of its vertices and triangles came from on the source mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Diced {
    /// The diced mesh: same attributes (normals, uvs, each [`Attribute`] with its name,
    /// components and kind, deformation) interpolated to the new vertices.
    pub mesh: Mesh,
    /// One per vertex of `mesh`.
    pub origins: Vec<DicedVertex>,
    /// One per triangle of `mesh`: the source triangle it was cut from.
    pub of_triangle: Vec<u32>,
}

/// The number of triangles dicing `mesh` at rate `n` makes (triangles * n * n), None on overflow.
pub fn diced_triangle_count(mesh: &Mesh, n: u32) -> Option<usize> {
    let n = usize::try_from(n.max(1)).ok()?;
    mesh.triangles.len().checked_mul(n.checked_mul(n)?)
}

/// Splits each triangle of `mesh` into n*n (n >= 1; n == 0 is treated as 1).
///
/// Errors: the source mesh's own [`Mesh::validate`] errors; [`MeshError::TooManyTriangles`] when
/// the diced mesh would hold more triangles than one mesh may (its count saturated at
/// `usize::MAX` where it overflows), or per-vertex arrays past what memory can address;
/// [`MeshError::NonFinite`] when interpolating between huge positions overflows.
pub fn dice(mesh: &Mesh, n: u32) -> Result<Diced, MeshError> {
    let count = mesh.triangles.len();
    dice_at(mesh, &vec![n; count], &vec![[n; 3]; count])
}

/// The number of triangles dicing triangles at `rates` makes (the sum of their squares), None on
/// overflow.
pub fn diced_triangle_count_at(rates: &[u32]) -> Option<usize> {
    rates.iter().try_fold(0usize, |sum, &n| {
        let n = usize::try_from(n.max(1)).ok()?;
        sum.checked_add(n.checked_mul(n)?)
    })
}

/// Splits triangle `t` of `mesh` into `rates[t] * rates[t]`, and its edge from corner `k` to the
/// next (`[a-b, b-c, c-a]`) into `edge_rates[t][k]` pieces, at most; an edge shared by several
/// triangles is cut at the fewest any of them asks and allows (its rate never above theirs), so
/// that they share its points. Rates of 0, and those of triangles past the end of `rates` or
/// `edge_rates`, are 1. Errors as [`dice`].
pub fn dice_at(mesh: &Mesh, rates: &[u32], edge_rates: &[[u32; 3]]) -> Result<Diced, MeshError> {
    dice_blended(mesh, rates, edge_rates).map(|(diced, _)| diced)
}

/// A mesh cut into pieces to be diced again ([`split_at`]), so that one large source triangle
/// can be diced finely where it is seen near and coarsely where far: a first dicing whose
/// triangles are the pieces, with where each piece's corners lie on its source triangle.
#[derive(Clone, Debug)]
pub struct Pieces {
    /// The pieces as a mesh ([`dice_at`]'s result): `of_triangle` names each one's source
    /// triangle.
    pub diced: Diced,
    /// Per piece: hit coordinates of its three corners on its source triangle.
    corners: Vec<[[f32; 2]; 3]>,
}

/// Cuts `mesh` into pieces as [`dice_at`] dices it, keeping where each piece lies on its source
/// triangle, for [`Pieces::compose`]. Errors as [`dice`].
pub fn split_at(mesh: &Mesh, rates: &[u32], edge_rates: &[[u32; 3]]) -> Result<Pieces, MeshError> {
    let (mut diced, blends) = dice_blended(mesh, rates, edge_rates)?;
    // Pieces folded to no area along coarser edges (two corners one vertex) go: diced again,
    // their folded edge's points would be distinct vertices at one place, and the dicing's edges
    // shared three ways. The rest still cover the source, closed where it is.
    let folded = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
    if diced.mesh.triangles.iter().any(folded) {
        let kept: Vec<bool> = diced.mesh.triangles.iter().map(|t| !folded(t)).collect();
        let mut keep = kept.iter();
        diced.of_triangle.retain(|_| keep.next().copied().unwrap_or(false));
        diced.mesh.triangles.retain(|t| !folded(t));
    }
    let corners = diced
        .mesh
        .triangles
        .iter()
        .zip(&diced.of_triangle)
        .map(|(piece, &t)| {
            let tri = mesh.triangles.get(t as usize).copied().unwrap_or([u32::MAX; 3]);
            let corner_uv = |v: u32| tri.iter().position(|&c| c == v).map(|k| CORNER_UV[k]);
            piece.map(|w| {
                let own = diced.origins.get(w as usize).map_or([0.0; 2], |o| [o.u, o.v]);
                // A vertex inside the source triangle is its own; one on a corner or an edge may
                // have been made by a neighbour, and its coordinates here are worked out again.
                let on_this = match blends.get(w as usize) {
                    Some(Blend::Corner(v)) => corner_uv(*v),
                    Some(Blend::Edge { lo, hi, t }) => corner_uv(*lo)
                        .zip(corner_uv(*hi))
                        .map(|(a, b)| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]),
                    Some(Blend::Inside { .. }) | None => None,
                };
                on_this.unwrap_or(own)
            })
        })
        .collect();
    Ok(Pieces { diced, corners })
}

impl Pieces {
    /// A dicing of the pieces' mesh (`diced`, made by [`dice_at`] from `self.diced.mesh`) as a
    /// dicing of the source mesh: each vertex's origin and each triangle's source triangle taken
    /// back through the pieces.
    pub fn compose(&self, diced: Diced) -> Diced {
        let Diced { mesh, origins, of_triangle } = diced;
        let pieces = &self.diced.of_triangle;
        let origins = origins
            .into_iter()
            .map(|o| {
                let p = o.triangle as usize;
                let (Some(&triangle), Some(c)) = (pieces.get(p), self.corners.get(p)) else { return o };
                let w = [1.0 - o.u - o.v, o.u, o.v];
                let at = |axis: usize| w[0] * c[0][axis] + w[1] * c[1][axis] + w[2] * c[2][axis];
                DicedVertex { triangle, u: at(0), v: at(1) }
            })
            .collect();
        let of_triangle = of_triangle.into_iter().map(|p| pieces.get(p as usize).copied().unwrap_or(p)).collect();
        Diced { mesh, origins, of_triangle }
    }
}

/// [`dice_at`], with how each diced vertex was made from the source's.
fn dice_blended(mesh: &Mesh, rates: &[u32], edge_rates: &[[u32; 3]]) -> Result<(Diced, Vec<Blend>), MeshError> {
    mesh.validate()?;
    let rate_of = |t: usize| rates.get(t).copied().unwrap_or(1).max(1);
    let triangle_rates: Vec<u32> = (0..mesh.triangles.len()).map(rate_of).collect();
    let triangle_count = diced_triangle_count_at(&triangle_rates).unwrap_or(usize::MAX);
    check_triangle_count(triangle_count)?;
    let too_large = || MeshError::TooManyTriangles { count: triangle_count };
    // Past the check, every `n * n` and every source triangle index fit in a u32.
    let finest = triangle_rates.iter().copied().max().unwrap_or(1) as usize;

    let corners = Corners::of(mesh);
    let mut edges = if finest > 1 { Edges::of(mesh) } else { Edges::default() };
    if finest > 1 {
        edges.rate_edges(mesh, &triangle_rates, edge_rates);
    }
    let inside = triangle_rates.iter().try_fold(0usize, |sum, &n| {
        let inner = n as usize - 1;
        sum.checked_add(inner * inner.saturating_sub(1) / 2)
    });
    let vertex_count = inside
        .and_then(|v| v.checked_add(edges.inner_points))
        .and_then(|v| v.checked_add(corners.used))
        .ok_or_else(too_large)?;
    u32::try_from(vertex_count).map_err(|_| too_large())?;

    let mut dicer = Dicer {
        rate: 1,
        blends: Vec::with_capacity(vertex_count),
        origins: Vec::with_capacity(vertex_count),
        triangles: Vec::with_capacity(triangle_count),
        grid: vec![0; (finest + 1) * (finest + 2) / 2],
    };
    let mut new_index = vec![NONE; mesh.positions.len()];
    for (v, &first) in corners.first_use.iter().enumerate() {
        if first != NONE {
            new_index[v] = dicer.blends.len() as u32;
            dicer.blends.push(Blend::Corner(v as u32));
            let [u, w] = CORNER_UV[(first % 3) as usize];
            dicer.origins.push(DicedVertex { triangle: first / 3, u, v: w });
        }
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        dicer.rate = triangle_rates[t] as usize;
        dicer.triangle(t as u32, *tri, &new_index, &mut edges);
    }
    let Dicer { blends, origins, triangles, .. } = dicer;
    let of_triangle =
        triangle_rates.iter().enumerate().flat_map(|(t, &n)| std::iter::repeat_n(t as u32, (n * n) as usize)).collect();

    let attributes = mesh
        .attributes
        .iter()
        .map(|a| {
            let k = a.components;
            let mut data = Vec::with_capacity(k.checked_mul(vertex_count).ok_or_else(too_large)?);
            for blend in &blends {
                data.extend((0..k).map(|j| blend.apply(|v| a.data[v * k + j])));
            }
            Ok(Attribute { name: a.name.clone(), components: k, data, kind: a.kind })
        })
        .collect::<Result<Vec<_>, MeshError>>()?;
    let deformation = mesh.deformation.as_ref().map(|d| Deformation {
        positions: interpolate(&blends, &d.positions),
        // Without the mesh's own normals a deformation's normals are an empty array.
        normals: d
            .normals
            .as_ref()
            .map(|ns| if mesh.normals.is_some() { interpolate(&blends, ns) } else { Vec::new() }),
        open: d.open,
        close: d.close,
    });
    let diced = Mesh {
        positions: interpolate(&blends, &mesh.positions),
        normals: mesh.normals.as_ref().map(|ns| interpolate(&blends, ns)),
        uvs: mesh.uvs.as_ref().map(|uvs| interpolate(&blends, uvs)),
        attributes,
        triangles,
        deformation,
    };
    diced.validate()?;
    Ok((Diced { mesh: diced, origins, of_triangle }, blends))
}

/// An index not yet given (an unused vertex, an edge whose points are not yet made).
const NONE: u32 = u32::MAX;

/// Hit coordinates of a triangle's three corners.
const CORNER_UV: [[f32; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];

/// Grid coordinates of a triangle's three corners at rate 1 (multiplied by the rate at others).
const CORNER_STEP: [[usize; 2]; 3] = [[0, 0], [1, 0], [0, 1]];

/// A triangle's edges as pairs of its corners, in winding order.
const EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];

/// How a diced vertex's data is made from the source's: the expression is fixed by where the
/// vertex lies, not by which triangle made it, so that shared points are the same whoever asks.
#[derive(Clone, Copy, Debug)]
enum Blend {
    /// A source vertex, copied.
    Corner(u32),
    /// A point inside the edge from `lo` to `hi` (`lo < hi`, or equal on a degenerate edge), a
    /// fraction `t` of the way from `lo`.
    Edge { lo: u32, hi: u32, t: f32 },
    /// A point inside a triangle, with its weights on the triangle's corners.
    Inside { corners: [u32; 3], weights: [f32; 3] },
}

impl Blend {
    /// The value at this vertex of per-vertex data whose value at source vertex `v` is `at(v)`.
    #[inline]
    fn apply<T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f32, Output = T>>(self, at: impl Fn(usize) -> T) -> T {
        match self {
            Blend::Corner(v) => at(v as usize),
            Blend::Edge { lo, hi, t } => {
                let from = at(lo as usize);
                from + (at(hi as usize) - from) * t
            }
            Blend::Inside { corners: [a, b, c], weights: w } => {
                at(a as usize) * w[0] + at(b as usize) * w[1] + at(c as usize) * w[2]
            }
        }
    }
}

/// Per-vertex `values` at every diced vertex.
fn interpolate<T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f32, Output = T>>(
    blends: &[Blend],
    values: &[T],
) -> Vec<T> {
    blends.iter().map(|b| b.apply(|v| values[v])).collect()
}

/// Which source vertices the triangles use, and where each is first used.
struct Corners {
    /// Per source vertex: `3 * triangle + corner` of its first use, or [`NONE`] when unused.
    first_use: Vec<u32>,
    /// The number of used vertices.
    used: usize,
}

impl Corners {
    /// The corners of `mesh`, whose triangle count has passed [`check_triangle_count`] (so that
    /// `3 * triangle + corner` fits in a u32).
    fn of(mesh: &Mesh) -> Corners {
        let mut first_use = vec![NONE; mesh.positions.len()];
        let mut used = 0;
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for (corner, &v) in tri.iter().enumerate() {
                let first = &mut first_use[v as usize];
                if *first == NONE {
                    *first = (3 * t + corner) as u32;
                    used += 1;
                }
            }
        }
        Corners { first_use, used }
    }
}

/// The distinct edges of a mesh, each an unordered pair of vertex indices, grouped by their lower
/// vertex and sorted by their higher within each group: a counting sort, linear in the triangles
/// and with no hashing, and a binary search within one vertex's group to find an edge (a vertex
/// many triangles share, such as a fan's centre, has a long group).
#[derive(Default)]
struct Edges {
    /// The group of lower vertex `lo` is `upper[starts[lo]..starts[lo + 1]]`.
    starts: Vec<usize>,
    /// The higher vertex of each triangle's each edge; equal entries in a group are one edge.
    upper: Vec<u32>,
    /// At the first entry of each edge: the index of its first inside point once made, else
    /// [`NONE`]; its `e - 1` points are consecutive, from its lower vertex on.
    first_point: Vec<u32>,
    /// At the first entry of each edge: its rate `e`.
    rate: Vec<u32>,
    /// The points inside all edges together.
    inner_points: usize,
}

impl Edges {
    fn of(mesh: &Mesh) -> Edges {
        let ends = |tri: &[u32; 3], [p, q]: [usize; 2]| (tri[p].min(tri[q]) as usize, tri[p].max(tri[q]));
        let mut starts = vec![0usize; mesh.positions.len() + 1];
        for tri in &mesh.triangles {
            for pair in EDGES {
                starts[ends(tri, pair).0 + 1] += 1;
            }
        }
        for v in 1..starts.len() {
            starts[v] += starts[v - 1];
        }
        let mut next = starts.clone();
        let mut upper = vec![0u32; 3 * mesh.triangles.len()];
        for tri in &mesh.triangles {
            for pair in EDGES {
                let (lo, hi) = ends(tri, pair);
                upper[next[lo]] = hi;
                next[lo] += 1;
            }
        }
        for group in starts.windows(2) {
            upper[group[0]..group[1]].sort_unstable();
        }
        let first_point = vec![NONE; upper.len()];
        Edges { starts, upper, first_point, rate: Vec::new(), inner_points: 0 }
    }

    /// Gives each edge the fewest pieces any triangle using it asks for or allows (its own rate).
    fn rate_edges(&mut self, mesh: &Mesh, triangle_rates: &[u32], edge_rates: &[[u32; 3]]) {
        self.rate = vec![u32::MAX; self.upper.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let asked = edge_rates.get(t).copied().unwrap_or([1; 3]);
            for (k, [p, q]) in EDGES.into_iter().enumerate() {
                let entry = self.entry(tri[p].min(tri[q]), tri[p].max(tri[q]));
                let e = asked[k].clamp(1, triangle_rates[t]);
                self.rate[entry] = self.rate[entry].min(e);
            }
        }
        self.inner_points = self.rate.iter().filter(|&&e| e != u32::MAX).map(|&e| e as usize - 1).sum();
    }

    /// The entry that stands for edge `lo`-`hi` (`lo <= hi`), one of the mesh's edges.
    fn entry(&self, lo: u32, hi: u32) -> usize {
        let (start, end) = (self.starts[lo as usize], self.starts[lo as usize + 1]);
        start + self.upper[start..end].partition_point(|&h| h < hi)
    }
}

/// The diced mesh as it is built, triangle by triangle.
struct Dicer {
    /// The dicing rate, at least 1.
    rate: usize,
    /// One per diced vertex so far.
    blends: Vec<Blend>,
    origins: Vec<DicedVertex>,
    triangles: Vec<[u32; 3]>,
    /// The diced vertex at each point `(i, j)` of the triangle being diced, at [`Dicer::at`].
    grid: Vec<u32>,
}

impl Dicer {
    /// The place of point `(i, j)` (`i + j <= rate`) in the grid: row `j` holds `rate + 1 - j`
    /// points.
    #[inline]
    fn at(&self, i: usize, j: usize) -> usize {
        j * (2 * self.rate + 3 - j) / 2 + i
    }

    /// A new diced vertex, returning its index (which fits: the vertex count was checked).
    fn push(&mut self, blend: Blend, origin: DicedVertex) -> u32 {
        self.blends.push(blend);
        self.origins.push(origin);
        (self.blends.len() - 1) as u32
    }

    /// Dices source triangle `t` with vertices `tri`, whose corners are diced vertices
    /// `new_index[..]`, making the points of its edges that no earlier triangle has made.
    fn triangle(&mut self, t: u32, tri: [u32; 3], new_index: &[u32], edges: &mut Edges) {
        let n = self.rate;
        let scale = n as f32;
        let origin = |[i, j]: [usize; 2]| DicedVertex { triangle: t, u: i as f32 / scale, v: j as f32 / scale };
        for (corner, step) in CORNER_STEP.iter().enumerate() {
            let slot = self.at(step[0] * n, step[1] * n);
            self.grid[slot] = new_index[tri[corner] as usize];
        }
        // At rate 1 edges have no points inside, and there is no edge table to look in.
        let edges_with_points: &[[usize; 2]] = if n > 1 { &EDGES } else { &[] };
        for &[p, q] in edges_with_points {
            let (from, to) = (tri[p], tri[q]);
            let (lo, hi) = (from.min(to), from.max(to));
            let entry = edges.entry(lo, hi);
            let e = edges.rate[entry] as usize;
            // Point `s` of `m` from corner p towards corner q, in grid units of `m`; and steps
            // counted from the edge's lower vertex instead (the same when p is the lower, else
            // the rest of `m`).
            let point =
                |s: usize, m: usize| [0, 1].map(|axis| CORNER_STEP[p][axis] * (m - s) + CORNER_STEP[q][axis] * s);
            let from_lo = |s: usize, m: usize| if from == lo { s } else { m - s };
            if edges.first_point[entry] == NONE && e > 1 {
                edges.first_point[entry] = self.blends.len() as u32;
                let edge_scale = e as f32;
                for k in 1..e {
                    let fraction = k as f32 / edge_scale;
                    let [i, j] = point(from_lo(k, e), e);
                    let origin = DicedVertex { triangle: t, u: i as f32 / edge_scale, v: j as f32 / edge_scale };
                    self.push(Blend::Edge { lo, hi, t: fraction }, origin);
                }
            }
            let first = edges.first_point[entry];
            for s in 1..n {
                // The edge's point nearest the grid's (halves rounded away from the lower vertex).
                let k = (2 * from_lo(s, n) * e + n) / (2 * n);
                let index = match k {
                    0 => new_index[lo as usize],
                    k if k >= e => new_index[hi as usize],
                    k => first + (k - 1) as u32,
                };
                let [i, j] = point(s, n);
                let slot = self.at(i, j);
                self.grid[slot] = index;
            }
        }
        for j in 1..n {
            for i in 1..n - j {
                let (u, v) = (i as f32 / scale, j as f32 / scale);
                let blend = Blend::Inside { corners: tri, weights: [1.0 - u - v, u, v] };
                let index = self.push(blend, origin([i, j]));
                let slot = self.at(i, j);
                self.grid[slot] = index;
            }
        }
        // Each cell of the grid: the triangle with its corner at (i, j) winds as (0, 0) (n, 0)
        // (0, n) do, and so does the one turned over inside the cell's other half.
        for j in 0..n {
            for i in 0..n - j {
                let [here, right, up] = [self.at(i, j), self.at(i + 1, j), self.at(i, j + 1)].map(|k| self.grid[k]);
                self.triangles.push([here, right, up]);
                if i + j + 1 < n {
                    let across = self.grid[self.at(i + 1, j + 1)];
                    self.triangles.push([right, across, up]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::AttributeKind;
    use glam::{Vec2, Vec3};
    use std::collections::HashMap;

    /// `mesh` with vertices at bit-identical positions merged (first one kept): a closed mesh
    /// from a cuboid, whose faces have vertices of their own.
    fn welded(mesh: &Mesh) -> Mesh {
        let mut index: HashMap<[u32; 3], u32> = HashMap::new();
        let mut positions = Vec::new();
        let remap: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                    positions.push(*p);
                    positions.len() as u32 - 1
                })
            })
            .collect();
        let triangles = mesh.triangles.iter().map(|t| t.map(|v| remap[v as usize])).collect();
        Mesh::from_triangles(positions, triangles).unwrap()
    }

    /// A closed octahedron with uneven vertices, written out of order (so that edges run both
    /// ways between low and high indices), with normals, uvs, attributes of one and three
    /// components, and a deformation with normals.
    fn irregular() -> Mesh {
        let positions = vec![
            Vec3::new(0.1, 0.2, 1.3),
            Vec3::new(1.1, -0.1, 0.05),
            Vec3::new(-0.05, 0.9, -0.1),
            Vec3::new(-1.2, 0.1, 0.2),
            Vec3::new(0.15, -1.05, 0.0),
            Vec3::new(-0.2, 0.05, -0.8),
        ];
        // Top 0, bottom 5, around 1 2 3 4 counter-clockwise seen from above.
        let triangles = vec![[0, 1, 2], [3, 0, 2], [0, 3, 4], [4, 1, 0], [5, 2, 1], [3, 2, 5], [4, 3, 5], [5, 1, 4]];
        let count = positions.len();
        let normals: Vec<Vec3> = positions.iter().map(|p| p.normalize() * 1.5).collect();
        let uvs = (0..count).map(|k| Vec2::new(k as f32 * 0.3, 1.0 - k as f32 * 0.17)).collect();
        let colour = (0..3 * count).map(|k| (k as f32 * 0.37).sin()).collect();
        let width = (0..count).map(|k| 2.0 + k as f32).collect();
        let pref = positions.iter().flat_map(|p| (*p * 2.0 + Vec3::X).to_array()).collect();
        let attributes = vec![
            Attribute::data("Cs", 3, colour),
            Attribute::data("width", 1, width),
            Attribute { name: "Pref".into(), components: 3, data: pref, kind: AttributeKind::Point },
        ];
        let deformation = Deformation {
            positions: positions.iter().map(|p| *p * 1.25 + Vec3::new(0.0, 0.5, -0.25)).collect(),
            normals: Some(normals.iter().map(|n| Vec3::new(n.y, n.z, n.x)).collect()),
            open: 0.0,
            close: 1.0,
        };
        let mesh = Mesh {
            positions,
            normals: Some(normals),
            uvs: Some(uvs),
            attributes,
            triangles,
            deformation: Some(deformation),
        };
        mesh.validate().unwrap();
        mesh
    }

    fn distinct_edges(mesh: &Mesh) -> usize {
        let mut edges: Vec<(u32, u32)> =
            mesh.triangles.iter().flat_map(|t| EDGES.map(|[p, q]| (t[p].min(t[q]), t[p].max(t[q])))).collect();
        edges.sort_unstable();
        edges.dedup();
        edges.len()
    }

    /// How many triangles use each directed edge of `mesh`.
    fn directed_edges(mesh: &Mesh) -> HashMap<(u32, u32), usize> {
        let mut uses = HashMap::new();
        for t in &mesh.triangles {
            for [p, q] in EDGES {
                *uses.entry((t[p], t[q])).or_insert(0) += 1;
            }
        }
        uses
    }

    fn close(a: f32, b: f32, scale: f32) -> bool {
        (a - b).abs() <= 1e-5 * scale.max(1.0)
    }

    /// Every edge of a closed mesh's dicing is used by exactly two triangles, once each way, and
    /// no two vertices lie at the same point: the dicing is closed, with its edges' points shared.
    #[test]
    fn closed_meshes_dice_to_closed_meshes() {
        for source in [welded(&Mesh::cuboid(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0))), irregular()] {
            assert!(directed_edges(&source)
                .iter()
                .all(|(&(a, b), &uses)| uses == 1 && directed_edges(&source).get(&(b, a)).is_some_and(|&u| u == 1)));
            for n in 1..=6 {
                let diced = dice(&source, n).unwrap().mesh;
                let uses = directed_edges(&diced);
                for (&(a, b), &count) in &uses {
                    assert_eq!(count, 1, "edge {a}-{b} used twice the same way at rate {n}");
                    assert_eq!(uses.get(&(b, a)), Some(&1), "edge {a}-{b} is open at rate {n}");
                }
                let mut points: Vec<[u32; 3]> =
                    diced.positions.iter().map(|p| p.to_array().map(f32::to_bits)).collect();
                points.sort_unstable();
                points.dedup();
                assert_eq!(points.len(), diced.positions.len(), "two vertices at one point at rate {n}");
                // A closed surface of genus 0: V - E + F = 2.
                let euler = diced.positions.len() as i64 - distinct_edges(&diced) as i64 + diced.triangles.len() as i64;
                assert_eq!(euler, 2, "rate {n}");
            }
        }
    }

    /// An edge's points are the same bits whichever way its triangles run along it, measured
    /// from its lower vertex, and made once however many triangles share the edge.
    #[test]
    fn edge_points_are_measured_from_the_lower_vertex_and_made_once() {
        let positions = vec![
            Vec3::new(0.3, 0.0, 0.0),
            Vec3::new(0.1, 0.7, 0.2),
            Vec3::new(1.3, 0.9, -0.4),
            Vec3::new(0.9, -0.6, 0.1),
        ];
        let positions = [positions, vec![Vec3::new(0.5, 0.5, 1.0)]].concat();
        // Edge 1-2 is shared by three triangles, two running 1 to 2 and one 2 to 1.
        let source = Mesh::from_triangles(positions, vec![[0, 1, 2], [2, 1, 3], [1, 2, 4]]).unwrap();
        let n = 5;
        let diced = dice(&source, n).unwrap();
        let (lo, hi) = (source.positions[1], source.positions[2]);
        for k in 1..n {
            let expected = lo + (hi - lo) * (k as f32 / n as f32);
            let at = diced.mesh.positions.iter().filter(|p| p.to_array() == expected.to_array()).count();
            assert_eq!(at, 1, "point {k} of edge 1-2");
        }
        let edges = distinct_edges(&source) as u32;
        let expected = 5 + edges * (n - 1) + 3 * (n - 1) * (n - 2) / 2;
        assert_eq!(diced.mesh.positions.len(), expected as usize);
    }

    #[test]
    fn vertex_count_is_vertices_plus_edge_and_inside_points() {
        let cuboid = Mesh::cuboid(Vec3::splat(-1.0), Vec3::ONE);
        assert_eq!(distinct_edges(&cuboid), 30);
        for n in 1..=7usize {
            let diced = dice(&cuboid, n as u32).unwrap();
            assert_eq!(diced.mesh.positions.len(), 24 + 30 * (n - 1) + 12 * (n - 1) * (n.max(2) - 2) / 2, "rate {n}");
            assert_eq!(diced.origins.len(), diced.mesh.positions.len());
        }
        let source = irregular();
        for n in 1..=7usize {
            let diced = dice(&source, n as u32).unwrap();
            let expected = 6 + distinct_edges(&source) * (n - 1) + 8 * (n - 1) * (n.max(2) - 2) / 2;
            assert_eq!(diced.mesh.positions.len(), expected, "rate {n}");
        }
    }

    /// A vertex no triangle uses is dropped: every diced vertex lies on a source triangle.
    #[test]
    fn unused_vertices_are_dropped() {
        let positions = vec![Vec3::splat(9.0), Vec3::ZERO, Vec3::X, Vec3::Y];
        let source = Mesh::from_triangles(positions, vec![[1, 2, 3]]).unwrap();
        let diced = dice(&source, 1).unwrap();
        assert_eq!(diced.mesh.positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(diced.mesh.triangles, vec![[0, 1, 2]]);
        assert_eq!(dice(&source, 3).unwrap().mesh.positions.len(), 3 + 3 * 2 + 1);
    }

    /// Each diced triangle winds as its source does, and they cover the source's area.
    #[test]
    fn diced_triangles_keep_winding_and_cover_their_source() {
        for source in [Mesh::cuboid(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 4.0)), irregular()] {
            for n in [1, 2, 3, 5, 8] {
                let diced = dice(&source, n).unwrap();
                let cross = |m: &Mesh, t: [u32; 3]| {
                    let [a, b, c] = t.map(|k| m.positions[k as usize]);
                    (b - a).cross(c - a)
                };
                let mut areas = vec![0.0f32; source.triangles.len()];
                for (k, &t) in diced.mesh.triangles.iter().enumerate() {
                    let from = diced.of_triangle[k] as usize;
                    let whole = cross(&source, source.triangles[from]);
                    let part = cross(&diced.mesh, t);
                    assert!(part.dot(whole) > 0.0, "triangle {k} of rate {n} winds against its source {from}");
                    areas[from] += part.length() * 0.5;
                }
                for (t, &area) in areas.iter().enumerate() {
                    let whole = cross(&source, source.triangles[t]).length() * 0.5;
                    assert!((area - whole).abs() <= 1e-5 * whole, "triangle {t} at rate {n}: {area} of {whole}");
                }
            }
        }
    }

    /// Each vertex's data is its source triangle's interpolated at its origin's hit coordinates.
    #[test]
    fn every_vertex_is_its_origin_interpolated() {
        for source in [Mesh::cuboid(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 4.0)), irregular()] {
            for n in [1, 2, 3, 4, 7] {
                let diced = dice(&source, n).unwrap();
                let mesh = &diced.mesh;
                assert_eq!(diced.origins.len(), mesh.positions.len());
                for (k, o) in diced.origins.iter().enumerate() {
                    let tri = source.triangles[o.triangle as usize].map(|v| v as usize);
                    let w = [1.0 - o.u - o.v, o.u, o.v];
                    assert!(w.iter().all(|&w| (-1e-6..=1.0).contains(&w)), "vertex {k}: {o:?}");
                    let mix3 = |at: &[Vec3]| at[tri[0]] * w[0] + at[tri[1]] * w[1] + at[tri[2]] * w[2];
                    let near3 = |a: Vec3, b: Vec3| (0..3).all(|i| close(a[i], b[i], b.abs().max_element()));
                    assert!(near3(mesh.positions[k], mix3(&source.positions)), "position of vertex {k}, rate {n}");
                    let normal = source.interpolate_normal(tri, w).unwrap();
                    assert!(near3(mesh.normals.as_ref().unwrap()[k], normal), "normal of vertex {k}");
                    let (uvs, at) = (source.uvs.as_ref().unwrap(), mesh.uvs.as_ref().unwrap()[k]);
                    let uv = uvs[tri[0]] * w[0] + uvs[tri[1]] * w[1] + uvs[tri[2]] * w[2];
                    assert!(close(at.x, uv.x, 1.0) && close(at.y, uv.y, 1.0), "uv of vertex {k}");
                    for (a, expected) in mesh.attributes.iter().zip(source.interpolate_attributes(tri, w)) {
                        let got = &a.data[k * a.components..(k + 1) * a.components];
                        assert!(got.iter().zip(&expected).all(|(&g, &e)| close(g, e, e.abs())), "{} of {k}", a.name);
                    }
                    if let (Some(d), Some(sd)) = (&mesh.deformation, &source.deformation) {
                        assert!(near3(d.positions[k], mix3(&sd.positions)), "close position of vertex {k}");
                        let (ns, sns) = (d.normals.as_ref().unwrap(), sd.normals.as_ref().unwrap());
                        assert!(near3(ns[k], mix3(sns)), "close normal of vertex {k}");
                    }
                }
                for (a, s) in mesh.attributes.iter().zip(&source.attributes) {
                    assert_eq!((&a.name, a.components, a.kind), (&s.name, s.components, s.kind));
                }
                let (d, sd) = (mesh.deformation.as_ref(), source.deformation.as_ref());
                assert_eq!(d.map(|d| (d.open, d.close)), sd.map(|d| (d.open, d.close)));
            }
        }
    }

    /// Normals are interpolated, not renormalised: between two unit normals at right angles the
    /// midpoint's is shorter than one.
    #[test]
    fn normals_are_left_as_interpolated() {
        let mut source = Mesh::from_triangles(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap();
        source.normals = Some(vec![Vec3::Z, Vec3::X, Vec3::Z]);
        let diced = dice(&source, 2).unwrap();
        let k = diced.mesh.positions.iter().position(|p| *p == Vec3::new(0.5, 0.0, 0.0)).unwrap();
        assert_eq!(diced.mesh.normals.unwrap()[k], Vec3::new(0.5, 0.0, 0.5));
    }

    #[test]
    fn diced_triangles_follow_their_source_in_order() {
        let source = irregular();
        for n in [1u32, 2, 3, 6] {
            let diced = dice(&source, n).unwrap();
            let per = (n * n) as usize;
            assert_eq!(diced.mesh.triangles.len(), source.triangles.len() * per);
            assert_eq!(Some(diced.mesh.triangles.len()), diced_triangle_count(&source, n));
            assert_eq!(diced.of_triangle.len(), diced.mesh.triangles.len());
            assert!(diced.of_triangle.iter().enumerate().all(|(k, &t)| t as usize == k / per));
        }
    }

    /// Rate 1 (and 0, taken as 1) gives the source mesh back.
    #[test]
    fn rate_one_gives_the_source_back() {
        for source in [Mesh::cuboid(Vec3::ZERO, Vec3::ONE), irregular()] {
            for n in [0, 1] {
                let diced = dice(&source, n).unwrap();
                assert_eq!(diced.mesh, source);
                assert_eq!(diced.of_triangle, (0..source.triangles.len() as u32).collect::<Vec<_>>());
            }
        }
    }

    #[test]
    fn results_pass_validation() {
        let empty = dice(&Mesh::default(), u32::MAX).unwrap();
        assert!(empty.mesh.positions.is_empty() && empty.mesh.triangles.is_empty());
        for n in [1, 2, 9] {
            dice(&irregular(), n).unwrap().mesh.validate().unwrap();
        }
    }

    /// Rates past what one mesh holds, bad source data and overflowing interpolation are errors,
    /// found before anything of the diced mesh's size is allocated.
    #[test]
    fn impossible_dicings_are_errors() {
        let source = irregular();
        assert_eq!(diced_triangle_count(&source, 0), Some(8));
        assert_eq!(diced_triangle_count(&source, u32::MAX), None);
        let e = dice(&source, u32::MAX).unwrap_err();
        assert!(matches!(e, MeshError::TooManyTriangles { .. }), "{e}");
        let e = dice(&source, 5000).unwrap_err();
        assert_eq!(e, MeshError::TooManyTriangles { count: 8 * 5000 * 5000 });

        let mut bad = source.clone();
        bad.triangles[3][1] = 6;
        assert!(matches!(dice(&bad, 2), Err(MeshError::IndexOutOfRange { index: 6, .. })));

        let huge = vec![Vec3::new(-3e38, 0.0, 0.0), Vec3::new(3e38, 0.0, 0.0), Vec3::Y];
        let huge = Mesh::from_triangles(huge, vec![[0, 1, 2]]).unwrap();
        assert!(matches!(dice(&huge, 2), Err(MeshError::NonFinite { .. })));
    }

    /// A deformation's normals, given as an empty array on a mesh without normals, stay empty.
    #[test]
    fn a_deformation_without_normals_dices() {
        let mut source = irregular();
        source.normals = None;
        if let Some(d) = source.deformation.as_mut() {
            d.normals = Some(Vec::new());
        }
        let diced = dice(&source, 3).unwrap();
        assert_eq!(diced.mesh.deformation.and_then(|d| d.normals), Some(Vec::new()));
    }

    /// A fan around one vertex shared by many triangles dices as quickly as any other mesh and
    /// stays closed around its centre.
    /// Rates that differ from triangle to triangle and edge to edge (from a hash of the edge's
    /// ends, as a caller's from its own geometry would be).
    fn mixed_rates(mesh: &Mesh, finest: u32) -> (Vec<u32>, Vec<[u32; 3]>) {
        let edge = |a: u32, b: u32| (a.min(b) * 7 + a.max(b) * 13) % finest + 1;
        let edges: Vec<[u32; 3]> = mesh.triangles.iter().map(|t| EDGES.map(|[p, q]| edge(t[p], t[q]))).collect();
        let rates =
            edges.iter().enumerate().map(|(k, e)| (e[0].max(e[1]).max(e[2]) + k as u32 % 3).min(finest)).collect();
        (rates, edges)
    }

    /// Without the triangles of no area that coarser edges fold away, a closed mesh diced at mixed
    /// rates is closed: every edge used once each way.
    #[test]
    fn mixed_rates_keep_closed_meshes_closed() {
        for source in [welded(&Mesh::cuboid(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0))), irregular()] {
            for finest in [2, 3, 5, 8] {
                let (rates, edges) = mixed_rates(&source, finest);
                let diced = dice_at(&source, &rates, &edges).unwrap();
                let folded = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
                let mut open = diced.mesh.clone();
                open.triangles.retain(|t| !folded(t));
                let uses = directed_edges(&open);
                for (&(a, b), &count) in &uses {
                    assert_eq!(count, 1, "edge {a}-{b} used twice the same way at rates up to {finest}");
                    assert_eq!(uses.get(&(b, a)), Some(&1), "edge {a}-{b} is open at rates up to {finest}");
                }
                // Each triangle makes the square of its rate.
                let expected: usize = rates.iter().map(|&n| (n * n) as usize).sum();
                assert_eq!(diced.mesh.triangles.len(), expected);
                assert_eq!(diced.of_triangle.len(), expected);
                assert_eq!(diced_triangle_count_at(&rates), Some(expected));
            }
        }
    }

    /// At mixed rates every diced triangle keeps its source's winding (or has no area) and a
    /// source triangle's diced triangles cover exactly its area.
    #[test]
    fn mixed_rates_keep_winding_and_cover_their_source() {
        let source = irregular();
        let (rates, edges) = mixed_rates(&source, 6);
        let diced = dice_at(&source, &rates, &edges).unwrap();
        let normal = |m: &Mesh, t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| m.positions[v as usize]);
            (b - a).cross(c - a)
        };
        let mut area = vec![0.0f32; source.triangles.len()];
        for (t, &from) in diced.mesh.triangles.iter().zip(&diced.of_triangle) {
            let (n, whole) = (normal(&diced.mesh, t), normal(&source, &source.triangles[from as usize]));
            assert!(n.dot(whole) >= -1e-6 * whole.length_squared(), "a diced triangle turned over");
            area[from as usize] += n.length() / 2.0;
        }
        for (t, tri) in source.triangles.iter().enumerate() {
            let whole = normal(&source, tri).length() / 2.0;
            assert!(close(area[t], whole, whole), "triangle {t}: {} against {whole}", area[t]);
        }
    }

    /// An edge is cut at the fewest pieces its triangles ask for, never more than either
    /// triangle's own rate: its points are the vertices of both sides, and vertex counts follow.
    #[test]
    fn an_edge_takes_the_coarsest_rate_asked() {
        // Two triangles sharing the edge 1-2: rates 4 and 2; the first asks 3 of the shared edge.
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let mesh = Mesh::from_triangles(positions, vec![[0, 1, 2], [2, 1, 3]]).unwrap();
        let diced = dice_at(&mesh, &[4, 2], &[[4, 3, 4], [2, 2, 2]]).unwrap();
        // Corners 4; edge 1-2 at 2 (the second triangle's rate): 1 point; the first's other
        // edges at 4: 3 points each; the second's other edges at 2: 1 each; inside: 3 and 0.
        assert_eq!(diced.mesh.positions.len(), 4 + 1 + 2 * 3 + 2 + 3);
        assert_eq!(diced.mesh.triangles.len(), 16 + 4);
        // The shared edge's one point is its middle, used by both sides.
        let middle = Vec3::new(0.5, 0.5, 0.0);
        let at: Vec<usize> = (0..diced.mesh.positions.len()).filter(|&v| diced.mesh.positions[v] == middle).collect();
        assert_eq!(at.len(), 1);
        let users: Vec<u32> = diced
            .mesh
            .triangles
            .iter()
            .zip(&diced.of_triangle)
            .filter(|(t, _)| t.contains(&(at[0] as u32)))
            .map(|(_, &from)| from)
            .collect();
        assert!(users.contains(&0) && users.contains(&1), "{users:?}");
        // Rates of 0 or missing are 1.
        assert_eq!(dice_at(&mesh, &[0], &[]).unwrap().mesh.triangles.len(), 2);
    }

    #[test]
    fn a_wide_fan_dices() {
        let spokes = 20_000u32;
        let mut positions = vec![Vec3::ZERO];
        positions.extend((0..spokes).map(|k| {
            let a = k as f32 / spokes as f32 * std::f32::consts::TAU;
            Vec3::new(a.cos(), a.sin(), 0.0)
        }));
        let triangles = (0..spokes).map(|k| [0, 1 + k, 1 + (k + 1) % spokes]).collect();
        let source = Mesh::from_triangles(positions, triangles).unwrap();
        let diced = dice(&source, 3).unwrap().mesh;
        let uses = directed_edges(&diced);
        let inside = uses.iter().filter(|(&(a, b), _)| uses.contains_key(&(b, a))).count();
        // Only the rim, 3 diced edges per spoke, is open.
        assert_eq!(uses.len() - inside, 3 * spokes as usize);
    }

    /// Pieces diced again, taken back through the pieces, are a dicing of the source: closed
    /// where it is closed, each vertex its origin on the source interpolated, each triangle inside
    /// its source triangle, with the pieces' and their dicing's rates differing from triangle to
    /// triangle.
    #[test]
    fn pieces_diced_again_are_a_dicing_of_the_source() {
        for source in [welded(&Mesh::cuboid(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0))), irregular()] {
            let count = source.triangles.len();
            let split: Vec<u32> = (0..count).map(|t| [1, 2, 3][t % 3]).collect();
            let split_edges: Vec<[u32; 3]> = split.iter().map(|&k| [k; 3]).collect();
            let pieces = split_at(&source, &split, &split_edges).unwrap();
            let pieces_count = pieces.diced.mesh.triangles.len();
            let rates: Vec<u32> = (0..pieces_count).map(|p| [2, 1, 4, 3][p % 4]).collect();
            let edge_rates: Vec<[u32; 3]> = rates.iter().map(|&r| [r, r.div_ceil(2), r]).collect();
            let again = dice_at(&pieces.diced.mesh, &rates, &edge_rates).unwrap();
            let composed = pieces.compose(again.clone());
            assert_eq!(composed.mesh, again.mesh);
            let closed = directed_edges(&source).keys().all(|&(a, b)| directed_edges(&source).contains_key(&(b, a)));
            if closed {
                // Triangles folded to no area along coarser edges (two corners one vertex) aside.
                let mut proper = composed.mesh.clone();
                proper.triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
                let uses = directed_edges(&proper);
                assert!(uses.iter().all(|(&(a, b), &n)| n == 1 && uses.get(&(b, a)) == Some(&1)), "open");
            }
            for (k, o) in composed.origins.iter().enumerate() {
                let tri = source.triangles[o.triangle as usize].map(|v| source.positions[v as usize]);
                let w = [1.0 - o.u - o.v, o.u, o.v];
                assert!(w.iter().all(|&w| (-1e-5..=1.0 + 1e-5).contains(&w)), "vertex {k}: {o:?}");
                let at = tri[0] * w[0] + tri[1] * w[1] + tri[2] * w[2];
                let there = composed.mesh.positions[k];
                assert!((at - there).length() <= 1e-5 * at.length().max(1.0), "vertex {k}: {at} for {there}");
            }
            for (k, t) in composed.mesh.triangles.iter().enumerate() {
                let from = composed.of_triangle[k];
                assert_eq!(from, pieces.diced.of_triangle[again.of_triangle[k] as usize]);
                // Every corner lies on the source triangle it came from.
                let [a, b, c] = source.triangles[from as usize].map(|v| source.positions[v as usize]);
                let normal = (b - a).cross(c - a).normalize();
                for &v in t {
                    let off = (composed.mesh.positions[v as usize] - a).dot(normal);
                    assert!(off.abs() <= 1e-5, "triangle {k} leaves its source {from} by {off}");
                }
            }
            // Source triangle t makes the sum of its pieces' rates squared.
            for t in 0..count as u32 {
                let made = composed.of_triangle.iter().filter(|&&f| f == t).count();
                let asked: u32 =
                    (0..pieces_count).filter(|&p| pieces.diced.of_triangle[p] == t).map(|p| rates[p].pow(2)).sum();
                assert_eq!(made, asked as usize, "source triangle {t}");
            }
        }
    }
}

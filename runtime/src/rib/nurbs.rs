//! Non-uniform rational B-spline patches (RISpec 3.2 section 5.4, `NuPatch`) and the trim curves
//! that cut them (`TrimCurve`) to triangle meshes.
//!
//! A direction of `n` control points of order `k` (degree `k - 1`) has a knot vector of `n + k`
//! non-decreasing values; the spline is defined from knot `k - 1` to knot `n` (0-based), and a
//! patch renders the part `[min, max]` of that. `Pw` gives homogeneous control points
//! `(x w, y w, z w, w)` (a rational patch; weights must be positive), `P` points of weight 1.
//! Control points run u fastest.
//!
//! Invariants:
//! - every vertex is on the surface: the surface is evaluated exactly there (Cox-de Boor basis
//!   functions, `spline.rs`, in `f64`), and its normal is `dP/du x dP/dv` from the exact
//!   derivatives of the rational surface (the quotient rule). Where that vanishes (a pole, a
//!   collapsed edge) the normal is the one a little way towards the middle of the patch; it is
//!   never NaN;
//! - the patch is tessellated span by span (a span lies between two distinct knots). Along a
//!   direction of order 2 (straight lines) a span is one segment; otherwise one segment for each
//!   5.625 degrees that the span's control polygon turns (64 a full turn, as a default `Sphere`),
//!   at least 4. A patch of order 2 both ways that is not flat gets 8 segments a span, like a
//!   bilinear patch. `MeshOptions::tessellation`, when set, gives the segments per span instead.
//!   Under a trim loop a span is cut finer, so that a cell is at most 1/16 of the loop's extent in
//!   each direction. At most [`MAX_SPAN_SEGMENTS`] a span. All of this comes from the control
//!   points, the knots and the trim loops, so the triangles are counted before any point is
//!   evaluated ([`nupatch_triangles`]; a trimmed patch by classifying its grid in parameter
//!   space, unless the grid alone passes twice [`MAX_RIB_TRIANGLES`]: then as two triangles for
//!   each of the grid's);
//! - vertex data follows the spline (the rational basis, weights included), varying data is
//!   bilinear over each span between the values at its knots (`(2 + nu - uorder) x (2 + nv -
//!   vorder)` of them), uniform data is one value per span (`(1 + nu - uorder) x (1 + nv -
//!   vorder)`); the uvs are `(u, v)` mapped from `[min, max]` to `[0, 1]`, and texture
//!   coordinates that differ from those (`st`, or `TextureCoordinates`) an `st` attribute
//!   (`mesh.rs`);
//! - trimming is done on the tessellation, with the trim loops sampled to polygons (`trim.rs`): a
//!   grid vertex is inside when it is inside an odd number of loops, and the side [`TrimSense`]
//!   names is removed. A triangle with vertices on both sides is cut where its edges cross the
//!   loops (marching triangles), so the trim edge runs through those crossings and is straight
//!   inside each triangle: a trim loop's corners, and loops smaller than a grid cell, are rounded
//!   off or lost.
//!
//! Malformed data (counts, knots, ranges, weights) is an `Err` with a message, never a panic.

use std::collections::HashMap;

use glam::{DVec2, DVec3, DVec4, Vec2, Vec3};

use super::decl::{Class, Ty};
use super::mesh::{per_vertex_params, route_attributes_parametric, ClassCounts, MeshOptions};
use super::request::{find_param, NuDirection, Param};
use super::spline::{ratio, segments_for_turn, turning, Basis, Knots};
use super::trim::TrimSense;
use super::MAX_RIB_TRIANGLES;
use crate::geometry::{Attribute, Mesh};

/// The most segments a span of a `NuPatch` is cut into along a direction.
pub const MAX_SPAN_SEGMENTS: u32 = 256;

/// Degrees a span's control polygon may turn per segment of a patch (64 segments a full turn).
const SURFACE_DEGREES_PER_SEGMENT: f64 = 360.0 / 64.0;

/// Segments a curved span of a patch is cut into at least.
const MIN_CURVED_SEGMENTS: u32 = 4;

/// Segments a span of a patch of order 2 both ways that is not flat is cut into.
const TWISTED_SEGMENTS: u32 = 8;

/// Cells a trim loop spans at least, in each direction.
const CELLS_PER_TRIM_LOOP: f64 = 16.0;

/// One span of a direction as tessellated: its index, the part of it rendered, its segments.
#[derive(Clone, Copy, Debug)]
struct SpanPlan {
    span: usize,
    start: f64,
    end: f64,
    segments: u32,
}

impl SpanPlan {
    /// The grid's parameters along the span, `segments + 1` of them.
    fn steps(&self) -> Vec<f64> {
        let n = self.segments.max(1);
        (0..=n)
            .map(|k| if k == n { self.end } else { self.start + (self.end - self.start) * f64::from(k) / f64::from(n) })
            .collect()
    }
}

/// A corner of a triangle in parameter space: a grid vertex, or where the edge from a kept grid
/// vertex to a removed one crosses the trim.
#[derive(Clone, Copy, Debug)]
enum Corner {
    Grid(u32),
    Cross { kept: u32, removed: u32 },
}

/// The trim as the tessellation uses it: every loop edge, and which side is removed.
struct TrimEdges {
    segments: Vec<(DVec2, DVec2)>,
    sense: TrimSense,
}

/// The trim along one band of grid rows (a span along v).
struct Band {
    /// Per row, the `u` where the loops cross it, sorted.
    crossings: Vec<Vec<f64>>,
    /// Per strip between two rows, the loop edges that meet it (only to cut triangles).
    strips: Vec<Vec<u32>>,
}

impl Band {
    fn new(trim: &TrimEdges, vs: &[f64], with_strips: bool) -> Band {
        let meets = |s: usize, lo: f64, hi: f64| {
            let (a, b) = trim.segments[s];
            a.y.min(b.y) <= hi && a.y.max(b.y) >= lo
        };
        let (first, last) = (vs.first().copied().unwrap_or_default(), vs.last().copied().unwrap_or_default());
        let near: Vec<usize> = (0..trim.segments.len()).filter(|&s| meets(s, first, last)).collect();
        let crossings = vs
            .iter()
            .map(|&v| {
                // Half-open in v, so that a row through a polygon vertex counts it once.
                let mut us: Vec<f64> = near
                    .iter()
                    .map(|&s| trim.segments[s])
                    .filter(|(a, b)| (a.y <= v) != (b.y <= v))
                    .map(|(a, b)| a.x + (v - a.y) * (b.x - a.x) / (b.y - a.y))
                    .collect();
                us.sort_by(f64::total_cmp);
                us
            })
            .collect();
        let strips = if with_strips {
            vs.windows(2).map(|w| near.iter().filter(|&&s| meets(s, w[0], w[1])).map(|&s| s as u32).collect()).collect()
        } else {
            Vec::new()
        };
        Band { crossings, strips }
    }

    /// Whether each grid vertex (`us` fastest, then this band's rows) is kept.
    fn kept(&self, us: &[f64], sense: TrimSense) -> Vec<bool> {
        self.crossings
            .iter()
            .flat_map(|row| {
                us.iter().map(move |&u| {
                    let inside = row.partition_point(|&c| c < u) % 2 == 1;
                    inside == (sense == TrimSense::Outside)
                })
            })
            .collect()
    }
}

/// Where the way from `p` to `q` first crosses one of the loop edges `candidates`, as a fraction
/// of it (0.5 when no edge is found, which only rounding can cause).
fn first_crossing(p: DVec2, q: DVec2, segments: &[(DVec2, DVec2)], candidates: &[u32]) -> f64 {
    let d = q - p;
    let mut best: Option<f64> = None;
    for &s in candidates {
        let Some(&(a, b)) = segments.get(s as usize) else { continue };
        let e = b - a;
        let denominator = d.perp_dot(e);
        if denominator == 0.0 {
            continue;
        }
        let w = a - p;
        let t = w.perp_dot(e) / denominator;
        let s = w.perp_dot(d) / denominator;
        if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&s) && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best.unwrap_or(0.5)
}

/// The triangles of a `columns` x `rows` vertex grid (two a cell, `a b c` and `a c d` with `a` at
/// the cell's low corner and `b` along u, as quadrics and patches are cut), cut where `kept`
/// (empty: every vertex kept) changes.
fn grid_triangles(columns: usize, rows: usize, kept: &[bool]) -> Vec<[Corner; 3]> {
    let cells = columns.saturating_sub(1) * rows.saturating_sub(1);
    let mut out = Vec::with_capacity(2 * cells);
    let index = |i: usize, j: usize| (i + columns * j) as u32;
    for j in 0..rows.saturating_sub(1) {
        for i in 0..columns.saturating_sub(1) {
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            march([a, b, c], kept, &mut out);
            march([a, c, d], kept, &mut out);
        }
    }
    out
}

/// Marching triangles: the kept part of `t`, as 0, 1 or 2 triangles of the same winding.
fn march(t: [u32; 3], kept: &[bool], out: &mut Vec<[Corner; 3]>) {
    let flags = t.map(|v| kept.get(v as usize).copied().unwrap_or(true));
    let cross = |kept: u32, removed: u32| Corner::Cross { kept, removed };
    // Rotations keep the winding.
    let rotated = |r: usize| [t[r % 3], t[(r + 1) % 3], t[(r + 2) % 3]];
    match flags.iter().filter(|&&k| k).count() {
        3 => out.push(t.map(Corner::Grid)),
        1 => {
            let [a, b, c] = rotated(flags.iter().position(|&k| k).unwrap_or(0));
            out.push([Corner::Grid(a), cross(a, b), cross(a, c)]);
        }
        2 => {
            // The removed vertex last.
            let [a, b, c] = rotated(flags.iter().position(|&k| !k).map_or(0, |r| r + 1));
            out.push([Corner::Grid(a), Corner::Grid(b), cross(b, c)]);
            out.push([Corner::Grid(a), cross(b, c), cross(a, c)]);
        }
        _ => {}
    }
}

/// A checked `NuPatch`: its knots, parameter ranges and homogeneous control points.
struct Surface {
    u: Knots,
    v: Knots,
    urange: (f64, f64),
    vrange: (f64, f64),
    /// `(x w, y w, z w, w)`, u fastest.
    points: Vec<DVec4>,
    /// The size of the control points' bounding box.
    scale: f64,
}

/// The basis functions at one point, on the spans it is evaluated in.
struct Local {
    u: (Basis, Basis),
    v: (Basis, Basis),
    first_u: usize,
    first_v: usize,
}

impl Surface {
    fn new(u: &NuDirection, v: &NuDirection, params: &[Param]) -> Result<Surface, String> {
        let uk = Knots::new(u.n, u.order, &u.knots, "NuPatch u")?;
        let vk = Knots::new(v.n, v.order, &v.knots, "NuPatch v")?;
        let urange = uk.range(u.min, u.max, "NuPatch u")?;
        let vrange = vk.range(v.min, v.max, "NuPatch v")?;
        let count = uk.n.checked_mul(vk.n).ok_or("too many control points")?;
        let float = |x: f32| f64::from(x);
        let (points, source): (Vec<DVec4>, &str) = if let Some(p) =
            find_param(params, "Pw").filter(|p| p.decl.ty == Ty::HPoint && p.decl.array_len.is_none())
        {
            let values = p.floats().unwrap_or_default();
            let points = values.chunks_exact(4).map(|h| DVec4::new(float(h[0]), float(h[1]), float(h[2]), float(h[3])));
            (points.collect(), "Pw")
        } else if let Some(p) = find_param(params, "P").filter(|p| p.decl.components() == 3) {
            let values = p.floats().unwrap_or_default();
            let points = values.chunks_exact(3).map(|c| DVec4::new(float(c[0]), float(c[1]), float(c[2]), 1.0));
            (points.collect(), "P")
        } else {
            return Err("the NuPatch has no control points: give \"P\" or \"Pw\"".to_string());
        };
        if points.len() != count {
            return Err(format!(
                "a {} x {} NuPatch needs {count} control points, but \"{source}\" has {}",
                uk.n,
                vk.n,
                points.len()
            ));
        }
        if let Some(k) = points.iter().position(|p| !p.is_finite()) {
            return Err(format!("control point {k} of \"{source}\" is not finite"));
        }
        if let Some(k) = points.iter().position(|p| p.w <= 0.0) {
            return Err(format!(
                "control point {k} of \"{source}\" has weight {}: weights must be positive",
                points[k].w
            ));
        }
        let (lo, hi) = points
            .iter()
            .map(|p| p.truncate() / p.w)
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
        let scale = (hi - lo).length();
        if !scale.is_finite() || hi.abs().max(lo.abs()).max_element() > f64::from(f32::MAX) / 4.0 {
            return Err(format!("the control points of \"{source}\" are too large for f32"));
        }
        Ok(Surface { u: uk, v: vk, urange, vrange, points, scale })
    }

    /// Control point `(i, j)`, `i` along u, divided by its weight.
    fn point(&self, i: usize, j: usize) -> DVec3 {
        let h = self.points[i + self.u.n * j];
        h.truncate() / h.w
    }

    /// Whether every quad of neighbouring control points is flat.
    fn flat(&self) -> bool {
        (0..self.v.n - 1).all(|j| {
            (0..self.u.n - 1).all(|i| {
                let c = [self.point(i, j), self.point(i + 1, j), self.point(i, j + 1), self.point(i + 1, j + 1)];
                let n = (c[1] - c[0]).cross(c[2] - c[0]);
                n.length() <= 1e-12 * self.scale * self.scale
                    || n.normalize().dot(c[3] - c[0]).abs() <= 1e-6 * self.scale
            })
        })
    }

    /// How the spans along one direction are cut: by how much their control polygons turn, or
    /// `fixed` segments, and finer under the trim loops whose bounding boxes are `extents`.
    fn plan(&self, along_u: bool, fixed: Option<u32>, extents: &[(DVec2, DVec2)]) -> Vec<SpanPlan> {
        let (knots, other, range) =
            if along_u { (&self.u, &self.v, self.urange) } else { (&self.v, &self.u, self.vrange) };
        let twisted = knots.order == 2 && other.order == 2 && !self.flat();
        let axis = |p: DVec2| if along_u { p.x } else { p.y };
        knots
            .spans(range)
            .into_iter()
            .map(|(span, start, end)| {
                let natural = match knots.order {
                    2 if twisted => TWISTED_SEGMENTS,
                    2 => 1,
                    _ => {
                        let first = span - knots.degree();
                        let turn = (0..other.n)
                            .map(|row| {
                                let point = |k: usize| if along_u { self.point(k, row) } else { self.point(row, k) };
                                turning((first..=span).map(point), 1e-9 * self.scale)
                            })
                            .fold(0.0, f64::max);
                        segments_for_turn(turn, SURFACE_DEGREES_PER_SEGMENT, MIN_CURVED_SEGMENTS, MAX_SPAN_SEGMENTS)
                    }
                };
                let mut segments = fixed.unwrap_or(natural);
                for &(lo, hi) in extents {
                    let size = axis(hi) - axis(lo);
                    if axis(lo) <= end && axis(hi) >= start && size > 0.0 {
                        let cells = ((end - start) * CELLS_PER_TRIM_LOOP / size).ceil();
                        segments = segments.max(cells.min(f64::from(MAX_SPAN_SEGMENTS)) as u32);
                    }
                }
                SpanPlan { span, start, end, segments: segments.clamp(1, MAX_SPAN_SEGMENTS) }
            })
            .collect()
    }

    fn local(&self, (su, sv): (usize, usize), uv: DVec2) -> Local {
        Local {
            u: self.u.basis(su, uv.x),
            v: self.v.basis(sv, uv.y),
            first_u: su - self.u.degree(),
            first_v: sv - self.v.degree(),
        }
    }

    /// The position, `dP/du`, `dP/dv` and the homogeneous weight at a point.
    fn evaluate(&self, l: &Local) -> (DVec3, DVec3, DVec3, f64) {
        let (mut a, mut au, mut av) = (DVec4::ZERO, DVec4::ZERO, DVec4::ZERO);
        for b in 0..self.v.order {
            let row = (l.first_v + b) * self.u.n + l.first_u;
            let (nv, dnv) = (l.v.0[b], l.v.1[b]);
            for c in 0..self.u.order {
                let q = self.points[row + c];
                a += q * (l.u.0[c] * nv);
                au += q * (l.u.1[c] * nv);
                av += q * (l.u.0[c] * dnv);
            }
        }
        // Weights are positive and the basis functions sum to 1, so `a.w` is positive.
        let p = a.truncate() / a.w;
        (p, (au.truncate() - p * au.w) / a.w, (av.truncate() - p * av.w) / a.w, a.w)
    }

    /// `dP/du x dP/dv` normalised, or `None` where a derivative vanishes or they are parallel.
    fn normal_from(&self, dpdu: DVec3, dpdv: DVec3) -> Option<DVec3> {
        let tiny_u = 1e-7 * self.scale / (self.urange.1 - self.urange.0);
        let tiny_v = 1e-7 * self.scale / (self.vrange.1 - self.vrange.0);
        let n = dpdu.cross(dpdv);
        let fine = dpdu.length() > tiny_u
            && dpdv.length() > tiny_v
            && n.length() > 1e-9 * dpdu.length() * dpdv.length()
            && n.is_finite();
        fine.then(|| n.normalize())
    }

    /// The normal at `uv` from its derivatives there, or where those fail, the normal a little way
    /// towards the middle of the patch.
    fn normal(&self, uv: DVec2, dpdu: DVec3, dpdv: DVec3) -> Vec3 {
        if let Some(n) = self.normal_from(dpdu, dpdv) {
            return n.as_vec3();
        }
        let middle = DVec2::new(self.urange.0 + self.urange.1, self.vrange.0 + self.vrange.1) * 0.5;
        for step in [1e-4, 1e-3, 1e-2, 1e-1] {
            let q = uv + (middle - uv) * step;
            let spans = (self.u.span_of(q.x), self.v.span_of(q.y));
            let (_, du, dv, _) = self.evaluate(&self.local(spans, q));
            if let Some(n) = self.normal_from(du, dv) {
                return n.as_vec3();
            }
        }
        Vec3::Z
    }

    /// The rational basis at a point: each control point that acts there and its weight.
    fn rational_weights(&self, l: &Local, w: f64) -> Vec<(usize, f64)> {
        let mut out = Vec::with_capacity(self.u.order * self.v.order);
        for b in 0..self.v.order {
            for c in 0..self.u.order {
                let k = (l.first_v + b) * self.u.n + l.first_u + c;
                out.push((k, l.u.0[c] * l.v.0[b] * self.points[k].w / w));
            }
        }
        out
    }
}

/// A `NuPatch` ready to tessellate: the surface, how each direction is cut, and the trim.
struct Tessellation {
    surface: Surface,
    u: Vec<SpanPlan>,
    v: Vec<SpanPlan>,
    trim: Option<TrimEdges>,
}

/// One block of a tessellation: a span along u by a span along v, in parameter space.
struct Block<'a> {
    /// The span indices along u and v.
    spans: (usize, usize),
    us: Vec<f64>,
    vs: &'a [f64],
    band: Option<&'a Band>,
    triangles: Vec<[Corner; 3]>,
}

impl Tessellation {
    fn new(u: &NuDirection, v: &NuDirection, params: &[Param], options: &MeshOptions) -> Result<Self, String> {
        let surface = Surface::new(u, v, params)?;
        // Only loops that reach the rendered part of the patch refine it.
        let ((ulo, uhi), (vlo, vhi)) = (surface.urange, surface.vrange);
        let extents: Vec<(DVec2, DVec2)> = options
            .trim
            .as_ref()
            .map(|t| t.extents())
            .unwrap_or_default()
            .into_iter()
            .filter(|(lo, hi)| lo.x <= uhi && hi.x >= ulo && lo.y <= vhi && hi.y >= vlo)
            .collect();
        let fixed = options.tessellation;
        let uplan = surface.plan(true, fixed.map(|t| t.u_segments), &extents);
        let vplan = surface.plan(false, fixed.map(|t| t.v_segments), &extents);
        let trim = options.trim.as_ref().map(|t| TrimEdges { segments: t.segments(), sense: options.trim_sense });
        Ok(Tessellation { surface, u: uplan, v: vplan, trim })
    }

    /// Walks the blocks with their grids, which vertices are kept and their triangles;
    /// `with_strips` readies the bands to cut triangles.
    fn blocks(&self, with_strips: bool, mut visit: impl FnMut(&Block) -> Result<(), String>) -> Result<(), String> {
        for sv in &self.v {
            let vs = sv.steps();
            let band = self.trim.as_ref().map(|t| Band::new(t, &vs, with_strips));
            for su in &self.u {
                let us = su.steps();
                let kept = match (&band, &self.trim) {
                    (Some(band), Some(trim)) => band.kept(&us, trim.sense),
                    _ => Vec::new(),
                };
                let triangles = grid_triangles(us.len(), vs.len(), &kept);
                visit(&Block { spans: (su.span, sv.span), us, vs: &vs, band: band.as_ref(), triangles })?;
            }
        }
        Ok(())
    }

    /// The triangles of the tessellation, before those that collapse are dropped. A trimmed grid
    /// is walked to count what the trim leaves, unless its cells alone are past any load's
    /// triangles: then every grid triangle counts as the two a cut can make of it.
    fn triangles(&self) -> usize {
        let cells = |plan: &[SpanPlan]| plan.iter().map(|s| s.segments as usize).fold(0usize, usize::saturating_add);
        let grid = 2usize.saturating_mul(cells(&self.u).saturating_mul(cells(&self.v)));
        if self.trim.is_none() {
            return grid;
        }
        if grid > 2 * MAX_RIB_TRIANGLES {
            return grid.saturating_mul(2);
        }
        let mut total = 0usize;
        let _ = self.blocks(false, |block| {
            total = total.saturating_add(block.triangles.len());
            Ok(())
        });
        total
    }
}

/// At most the triangles [`nupatch_mesh`] makes of the same request, worked out without evaluating
/// the surface (0 for a request it refuses).
pub fn nupatch_triangles(u: &NuDirection, v: &NuDirection, params: &[Param], options: &MeshOptions) -> usize {
    Tessellation::new(u, v, params, options).map_or(0, |t| t.triangles())
}

/// `NuPatch`, trimmed by `options.trim`.
pub fn nupatch_mesh(
    u: &NuDirection,
    v: &NuDirection,
    params: &[Param],
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let tessellation = Tessellation::new(u, v, params, options)?;
    let planned = tessellation.triangles();
    if planned > MAX_RIB_TRIANGLES {
        return Err(format!("the NuPatch would make {planned} triangles, more than {MAX_RIB_TRIANGLES}"));
    }
    let s = &tessellation.surface;
    let (uk, vk) = (&s.u, &s.v);
    // Spans as RenderMan counts them (empty ones too): uniform values per span, varying per knot.
    let (u_spans, v_spans) = (uk.n - uk.degree(), vk.n - vk.degree());
    let counts = ClassCounts {
        vertex: uk.n * vk.n,
        varying: (u_spans + 1) * (v_spans + 1),
        face: u_spans * v_spans,
        corner: None,
    };
    let data = per_vertex_params(params, &counts, warnings);
    let vertex_data = data.iter().any(|d| d.class == Class::Vertex);

    let mut mesh = Mesh::default();
    let mut normals = Vec::new();
    let mut uvs_out = Vec::new();
    let mut attributes: Vec<Attribute> = data.iter().map(|d| d.attribute(Vec::new())).collect();
    let (du, dv) = (s.urange.1 - s.urange.0, s.vrange.1 - s.vrange.0);
    let segments = tessellation.trim.as_ref().map(|t| t.segments.as_slice()).unwrap_or_default();
    tessellation.blocks(true, |block| {
        let (columns, rows) = (block.us.len(), block.vs.len());
        // Parameter-space points: the grid, then the trim crossings the triangles need.
        let mut uvs: Vec<DVec2> =
            block.vs.iter().flat_map(|&v| block.us.iter().map(move |&u| DVec2::new(u, v))).collect();
        let mut crossings: HashMap<(u32, u32), u32> = HashMap::new();
        let mut triangles = Vec::with_capacity(block.triangles.len());
        for t in &block.triangles {
            let mut ids = [0u32; 3];
            for (id, corner) in ids.iter_mut().zip(t) {
                *id = match *corner {
                    Corner::Grid(g) => g,
                    Corner::Cross { kept, removed } => *crossings.entry((kept, removed)).or_insert_with(|| {
                        let (p, q) = (uvs[kept as usize], uvs[removed as usize]);
                        let row = (kept as usize / columns).min(removed as usize / columns);
                        let strip = row.min(rows.saturating_sub(2));
                        let candidates = block.band.and_then(|b| b.strips.get(strip)).map_or(&[][..], Vec::as_slice);
                        uvs.push(p + (q - p) * first_crossing(p, q, segments, candidates));
                        (uvs.len() - 1) as u32
                    }),
                };
            }
            triangles.push(ids);
        }

        // Only the points the triangles use, in the order of the grid.
        let mut used = vec![false; uvs.len()];
        for &k in triangles.iter().flatten() {
            used[k as usize] = true;
        }
        let mut remap = vec![0u32; uvs.len()];
        for (next, (k, _)) in used.iter().enumerate().filter(|(_, &u)| u).enumerate() {
            remap[k] = next as u32;
        }
        for t in &mut triangles {
            *t = t.map(|k| remap[k as usize]);
        }
        let uvs: Vec<DVec2> = uvs.into_iter().zip(used).filter(|(_, u)| *u).map(|(uv, _)| uv).collect();

        // The surface and its data at each point.
        let offset = mesh.positions.len();
        let (su, sv) = block.spans;
        let (iu, iv) = (su - uk.degree(), sv - vk.degree());
        let mut positions = Vec::with_capacity(uvs.len());
        for &uv in &uvs {
            let local = s.local(block.spans, uv);
            let (p, dpdu, dpdv, w) = s.evaluate(&local);
            positions.push(p);
            normals.push(s.normal(uv, dpdu, dpdv));
            let st = Vec2::new(((uv.x - s.urange.0) / du) as f32, ((uv.y - s.vrange.0) / dv) as f32);
            uvs_out.push(st);
            let weights = if vertex_data { s.rational_weights(&local, w) } else { Vec::new() };
            let fu = ratio(uv.x - uk.knots[su], uk.knots[su + 1] - uk.knots[su]);
            let fv = ratio(uv.y - vk.knots[sv], vk.knots[sv + 1] - vk.knots[sv]);
            let corners = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| (iu + a) + (u_spans + 1) * (iv + b));
            let bilinear = [(1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv];
            for (attribute, d) in attributes.iter_mut().zip(&data) {
                let value = |k: usize, c: usize| f64::from(d.values[k * d.components + c]);
                for c in 0..d.components {
                    let x: f64 = match d.class {
                        Class::Uniform => value(iu + u_spans * iv, c),
                        Class::Vertex => weights.iter().map(|&(k, w)| w * value(k, c)).sum(),
                        _ => corners.iter().zip(bilinear).map(|(&k, w)| w * value(k, c)).sum(),
                    };
                    attribute.data.push(x as f32);
                }
            }
        }
        mesh.positions.extend(positions.iter().map(|p| p.as_vec3()));
        // Triangles that collapse (at a pole, or where the trim runs through a grid vertex) are dropped.
        let tiny = 1e-10 * s.scale;
        let distinct = |a: u32, b: u32| positions[a as usize].distance(positions[b as usize]) > tiny;
        mesh.triangles.extend(
            triangles
                .into_iter()
                .filter(|&[a, b, c]| distinct(a, b) && distinct(b, c) && distinct(c, a))
                .map(|t| t.map(|k| k + offset as u32)),
        );
        Ok(())
    })?;
    mesh.normals = Some(normals);
    mesh.uvs = Some(uvs_out);
    route_attributes_parametric(&mut mesh, attributes, options);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::quadric::Tessellation as Segments;
    use crate::rib::trim::trim_from_request;
    use crate::rib::{
        mesh_from_request, mesh_from_request_with, parse_str, request_triangles, Request, RequestKind as K,
        RibDiagnostic,
    };
    use std::f64::consts::FRAC_1_SQRT_2;
    use std::sync::Arc;

    fn request(text: &str) -> Request {
        let parse = parse_str(text, "n.rib");
        assert!(!parse.has_errors(), "{text}: {:?}", parse.diagnostics);
        parse.requests.into_iter().next().expect("a request")
    }

    fn mesh_with(text: &str, options: &MeshOptions) -> Mesh {
        let mut diagnostics = Vec::new();
        let r = request(text);
        let mesh = mesh_from_request_with(&r, options, &mut diagnostics).unwrap_or_else(|| panic!("{diagnostics:?}"));
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let counted = request_triangles(&r, options);
        assert!(counted >= mesh.triangle_count(), "{counted} counted for {} made", mesh.triangle_count());
        mesh
    }

    fn numbers(values: impl IntoIterator<Item = f64>) -> String {
        values.into_iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(" ")
    }

    /// The unit circle as a rational quadratic B-spline: 9 control points `(x, y, weight)`.
    const CIRCLE: [(f64, f64, f64); 9] = [
        (1.0, 0.0, 1.0),
        (1.0, 1.0, FRAC_1_SQRT_2),
        (0.0, 1.0, 1.0),
        (-1.0, 1.0, FRAC_1_SQRT_2),
        (-1.0, 0.0, 1.0),
        (-1.0, -1.0, FRAC_1_SQRT_2),
        (0.0, -1.0, 1.0),
        (1.0, -1.0, FRAC_1_SQRT_2),
        (1.0, 0.0, 1.0),
    ];
    const CIRCLE_KNOTS: &str = "0 0 0 .25 .25 .5 .5 .75 .75 1 1 1";

    /// The standard NURBS sphere of radius `r`: the circle swept around a half circle (9 x 5
    /// control points, weights the products of the two curves' `1`s and `1/sqrt(2)`s).
    fn sphere(r: f64) -> String {
        // The meridian from the south pole to the north pole: (distance from the axis, z, weight).
        let meridian =
            [(0.0, -1.0, 1.0), (1.0, -1.0, FRAC_1_SQRT_2), (1.0, 0.0, 1.0), (1.0, 1.0, FRAC_1_SQRT_2), (0.0, 1.0, 1.0)];
        let mut pw = Vec::new();
        for &(rho, z, wv) in &meridian {
            for &(x, y, wu) in &CIRCLE {
                let w = wu * wv;
                pw.extend([r * rho * x * w, r * rho * y * w, r * z * w, w]);
            }
        }
        format!(r#"NuPatch 9 3 [{CIRCLE_KNOTS}] 0 1 5 3 [0 0 0 .5 .5 1 1 1] 0 1 "Pw" [{}]"#, numbers(pw))
    }

    /// Circles `(cx, cy, r)` in parameter space, a trim loop each.
    fn circles(circles: &[(f64, f64, f64)]) -> String {
        let (mut u, mut v, mut w) = (Vec::new(), Vec::new(), Vec::new());
        for &(cx, cy, r) in circles {
            for &(x, y, weight) in &CIRCLE {
                u.push((cx + r * x) * weight);
                v.push((cy + r * y) * weight);
                w.push(weight);
            }
        }
        let each = |x: &str| vec![x; circles.len()].join(" ");
        format!(
            "TrimCurve [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}]",
            each("1"),
            each("3"),
            each(CIRCLE_KNOTS),
            each("0"),
            each("1"),
            each("9"),
            numbers(u),
            numbers(v),
            numbers(w)
        )
    }

    fn trimmed(trim: &str, sense: TrimSense) -> MeshOptions {
        let K::TrimCurve(t) = request(trim).kind else { panic!("not a TrimCurve") };
        let trim = trim_from_request(&t).expect("a valid trim curve").map(Arc::new);
        MeshOptions { trim, trim_sense: sense, ..Default::default() }
    }

    fn area(mesh: &Mesh) -> f64 {
        (0..mesh.triangle_count())
            .map(|t| {
                let [a, b, c] = mesh.corners(t).map(|p| p.as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    const SQUARE: &str = r#"NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [0 0 0  1 0 0  0 1 0  1 1 0]"#;

    /// The rational sphere lies on the sphere: every vertex at the radius (to f32 precision), every
    /// normal radial, the poles' normals (where dP/du vanishes) the axis, and as much surface as a
    /// `Sphere` of the same radius.
    #[test]
    fn a_rational_nurbs_sphere_lies_on_the_sphere() {
        let r = 2.0;
        let mesh = mesh_with(&sphere(r), &MeshOptions::default());
        let normals = mesh.normals.as_ref().expect("normals");
        let mut worst = 0.0f64;
        for (p, n) in mesh.positions.iter().zip(normals) {
            worst = worst.max((f64::from(p.length()) - r).abs());
            assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "normal {n} at {p}");
            assert!(n.dot(p.normalize()) > 0.9999, "normal {n} at {p} is not radial");
        }
        assert!(worst < 1e-4 * r, "a vertex is {worst} off the sphere");
        assert!(mesh.positions.iter().any(|p| (*p - Vec3::new(0.0, 0.0, 2.0)).length() < 1e-6), "no north pole");
        // 16 segments a quarter circle (64 a turn) both ways; the rows at the poles collapse.
        assert_eq!(mesh.triangle_count(), 2 * 64 * 32 - 2 * 64);
        let quadric = mesh_with("Sphere 2 -2 2 360", &MeshOptions::default());
        let (nurbs_area, sphere_area) = (area(&mesh), area(&quadric));
        assert!((nurbs_area / sphere_area - 1.0).abs() < 2e-3, "{nurbs_area} against {sphere_area}");
        let exact = 4.0 * std::f64::consts::PI * r * r;
        assert!((nurbs_area / exact - 1.0).abs() < 5e-3, "{nurbs_area} against {exact}");
        // Vertex data follows the rational spline: a value equal to each control point's z
        // interpolates to the surface's z.
        let heights: Vec<String> = (0..45).map(|k| format!("{}", r * [-1.0, -1.0, 0.0, 1.0, 1.0][k / 9])).collect();
        let with_data = format!("{} \"vertex float h\" [{}]", sphere(r), heights.join(" "));
        let mesh = mesh_with(&with_data, &MeshOptions::default());
        let h = &mesh.attributes[0];
        for (p, h) in mesh.positions.iter().zip(&h.data) {
            assert!((p.z - h).abs() < 1e-5, "h {h} at {p}");
        }
    }

    /// A NuPatch with Bezier or uniform B-spline knots is the bicubic patch of that basis.
    #[test]
    fn nurbs_evaluation_matches_the_bicubic_bases() {
        let points: Vec<String> =
            (0..16).map(|k| format!("{} {} {}", k % 4, k / 4, [0.0, 1.0, -0.5, 2.0][(k * 7) % 4] * 0.3)).collect();
        let points = points.join(" ");
        let options =
            MeshOptions { tessellation: Some(Segments { u_segments: 5, v_segments: 3 }), ..Default::default() };
        for (knots, basis) in [("0 0 0 0 1 1 1 1", "bezier"), ("0 1 2 3 4 5 6 7", "b-spline")] {
            let (lo, hi) = if basis == "bezier" { (0, 1) } else { (3, 4) };
            let nurbs = mesh_with(
                &format!(r#"NuPatch 4 4 [{knots}] {lo} {hi} 4 4 [{knots}] {lo} {hi} "P" [{points}]"#),
                &options,
            );
            let parse = parse_str(&format!(r#"Basis "{basis}" 1 "{basis}" 1 Patch "bicubic" "P" [{points}]"#), "p.rib");
            let K::Basis { u, v, .. } = parse.requests[0].kind.clone() else { panic!() };
            let patch_options = MeshOptions { u_basis: u, v_basis: v, u_step: 1, v_step: 1, ..options.clone() };
            let patch = mesh_from_request_with(&parse.requests[1], &patch_options, &mut Vec::new()).expect("a patch");
            assert_eq!(nurbs.positions.len(), patch.positions.len());
            assert_eq!(nurbs.triangles, patch.triangles);
            let normals = nurbs.normals.as_ref().unwrap().iter().zip(patch.normals.as_ref().unwrap());
            for ((a, b), (m, n)) in nurbs.positions.iter().zip(&patch.positions).zip(normals) {
                assert!(a.distance(*b) < 1e-5 && m.distance(*n) < 1e-4, "{basis}: {a} {m} against {b} {n}");
            }
            assert_eq!(nurbs.uvs, patch.uvs);
        }
    }

    /// Varying data is bilinear over the span, uniform data constant, uvs `(u, v)`; a flat patch of
    /// order 2 is one quad, counted as made.
    #[test]
    fn primitive_variables_follow_their_class() {
        let text =
            format!(r#"{SQUARE} "varying float q" [0 1 2 3] "uniform float id" [7] "Cs" [1 0 0 0 1 0 0 0 1 1 1 1]"#);
        let mesh = mesh_with(&text, &MeshOptions::default());
        assert_eq!(mesh.triangle_count(), 2);
        assert_eq!(request_triangles(&request(&text), &MeshOptions::default()), 2);
        let find = |name: &str| mesh.attributes.iter().find(|a| a.name == name).unwrap_or_else(|| panic!("{name}"));
        for (k, p) in mesh.positions.iter().enumerate() {
            assert!((find("q").data[k] - (p.x + 2.0 * p.y)).abs() < 1e-6);
            assert_eq!(find("id").data[k], 7.0);
            assert_eq!(mesh.uvs.as_ref().unwrap()[k], Vec2::new(p.x, p.y));
            assert_eq!(mesh.normals.as_ref().unwrap()[k], Vec3::Z);
        }
        // Two spans along u (a quadratic B-spline of 4 points): 3 varying values along u, 2 uniform.
        let text = r#"NuPatch 4 3 [0 0 0 1 2 2 2] 0 2 2 2 [0 0 1 1] 0 1 "P" [0 0 0 1 0 1 2 0 1 3 0 0  0 1 0 1 1 1 2 1 1 3 1 0]
            "varying float q" [0 10 20  0 10 20] "uniform float id" [1 2]"#;
        let mesh = mesh_with(text, &MeshOptions::default());
        let (q, id) = (&mesh.attributes[0].data, &mesh.attributes[1].data);
        let uvs = mesh.uvs.as_ref().unwrap();
        for k in 0..mesh.positions.len() {
            let u = 2.0 * uvs[k].x;
            assert!((q[k] - 10.0 * u).abs() < 1e-4, "q {} at u {u}", q[k]);
            assert!(
                id[k]
                    == if u < 1.0 - 1e-6 {
                        1.0
                    } else if u > 1.0 + 1e-6 {
                        2.0
                    } else {
                        id[k]
                    },
                "{u}"
            );
        }
        // Wrong counts drop the data with a warning.
        let mut warnings = Vec::new();
        let bad = request(&format!(r#"{SQUARE} "varying float q" [0 1 2]"#));
        let mesh = mesh_from_request(&bad, &mut warnings).expect("a mesh");
        assert!(mesh.attributes.is_empty() && warnings.len() == 1, "{warnings:?}");
    }

    /// A circular hole trimmed out of a unit square leaves the square's area less the disk's; the
    /// "outside" sense keeps the disk instead. No vertex is inside the hole.
    #[test]
    fn a_trim_loop_cuts_a_hole_of_its_area() {
        let disk = std::f64::consts::PI * 0.25 * 0.25;
        let hole = circles(&[(0.5, 0.5, 0.25)]);
        for (sense, expected) in [(TrimSense::Inside, 1.0 - disk), (TrimSense::Outside, disk)] {
            let mesh = mesh_with(SQUARE, &trimmed(&hole, sense));
            let got = area(&mesh);
            assert!((got - expected).abs() < 1e-3, "{sense:?}: area {got}, expected {expected}");
            for p in &mesh.positions {
                let d = (*p - Vec3::new(0.5, 0.5, 0.0)).length();
                let ok = if sense == TrimSense::Inside { d > 0.25 * (1.0 - 1e-3) } else { d < 0.25 * (1.0 + 1e-5) };
                assert!(ok, "{sense:?}: vertex {p} on the wrong side");
            }
        }
        // A loop that misses the patch changes nothing; two nested loops keep the ring between them.
        let away = mesh_with(SQUARE, &trimmed(&circles(&[(3.0, 3.0, 0.25)]), TrimSense::Inside));
        assert_eq!(away.triangle_count(), 2);
        let ring = mesh_with(SQUARE, &trimmed(&circles(&[(0.5, 0.5, 0.4), (0.5, 0.5, 0.2)]), TrimSense::Inside));
        let expected = 1.0 - std::f64::consts::PI * (0.4 * 0.4 - 0.2 * 0.2);
        assert!((area(&ring) - expected).abs() < 2e-3, "{} against {expected}", area(&ring));
    }

    #[test]
    fn degenerate_edges_get_finite_normals() {
        // A patch whose v = 0 edge collapses to a point (a cone's tip).
        let text = r#"NuPatch 3 3 [0 0 0 1 1 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [0 0 1  0 0 1  0 0 1  -1 0 0  0 1 0  1 0 0]"#;
        let mesh = mesh_with(text, &MeshOptions::default());
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        for n in mesh.normals.as_ref().unwrap() {
            assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "{n}");
        }
        // The tip row is dropped, not kept as zero-area triangles.
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.corners(t);
            assert!((b - a).cross(c - a).length() > 0.0);
        }
    }

    #[test]
    fn nupatch_and_trimcurve_parse() {
        let K::NuPatch { u, v, params } = request(SQUARE).kind else { panic!() };
        assert_eq!((u.n, u.order, u.knots.as_slice(), u.min, u.max), (2, 2, &[0.0, 0.0, 1.0, 1.0][..], 0.0, 1.0));
        assert_eq!((v.n, params.len()), (2, 1));
        // RIB has no `nloops`; a file that writes C's leading count is read too, and checked.
        let t = "[1] [2] [0 0 1 1] [0] [1] [2] [0 1] [0 0] [1 1]";
        let K::TrimCurve(plain) = request(&format!("TrimCurve {t}")).kind else { panic!() };
        let K::TrimCurve(counted) = request(&format!("TrimCurve 1 {t}")).kind else { panic!() };
        assert_eq!(plain, counted);
        let parse = parse_str(&format!("TrimCurve 2 {t}"), "t.rib");
        assert!(parse.diagnostics[0].message.contains("2 loops but 1 curve counts"), "{:?}", parse.diagnostics);
    }

    fn error_of(text: &str) -> String {
        let parse = parse_str(text, "bad.rib");
        assert!(!parse.has_errors(), "{text}: {:?}", parse.diagnostics);
        let mut diagnostics: Vec<RibDiagnostic> = Vec::new();
        assert!(mesh_from_request(&parse.requests[0], &mut diagnostics).is_none(), "{text}");
        assert_eq!(diagnostics.len(), 1, "{text}: {diagnostics:?}");
        let d = diagnostics[0].to_string();
        assert!(d.starts_with("bad.rib:1:1: error: "), "{d}");
        d
    }

    #[test]
    fn bad_nupatches_are_errors_at_the_request() {
        let p = r#""P" [0 0 0  1 0 0  0 1 0  1 1 0]"#;
        let v = "2 2 [0 0 1 1] 0 1";
        let knots17: Vec<String> = (0..34).map(|k| (k / 17).to_string()).collect();
        for (text, expected) in [
            (format!("NuPatch 2 1 [0 1 2] 0 1 {v} {p}"), "order 1 is not 2 to 16"),
            (format!("NuPatch 17 17 [{}] 0 1 {v} {p}", knots17.join(" ")), "order 17 is not 2 to 16"),
            (format!("NuPatch 1 2 [0 0 1] 0 1 {v} {p}"), "1 control points, fewer than the order (2)"),
            (format!("NuPatch 2 2 [0 0 1] 0 1 {v} {p}"), "3 knots given, where 2 control points of order 2 need 4"),
            (format!("NuPatch 2 2 [0 1 0 1] 0 1 {v} {p}"), "the knots decrease (knot 2 is 0 after 1)"),
            (format!("NuPatch 2 2 [1 1 1 1] 0 1 {v} {p}"), "the spline is empty"),
            (format!("NuPatch 2 2 [0 0 1 1] 1 0 {v} {p}"), "the parameter range 1 to 0 is empty"),
            (format!("NuPatch 2 2 [0 0 1 1] 0 2 {v} {p}"), "not within the knots' 0 to 1"),
            (format!(r#"NuPatch 2 2 [0 0 1 1] 0 1 {v} "Cs" [1 1 1]"#), "no control points"),
            (
                format!(r#"NuPatch 2 2 [0 0 1 1] 0 1 {v} "P" [0 0 0 1 0 0 0 1 0]"#),
                "needs 4 control points, but \"P\" has 3",
            ),
            (
                format!(r#"NuPatch 2 2 [0 0 1 1] 0 1 {v} "Pw" [0 0 0 1  1 0 0 0  0 1 0 1  1 1 0 1]"#),
                "control point 1 of \"Pw\" has weight 0",
            ),
            (format!(r#"NuPatch 2 2 [0 0 1 1] 0 1 {v} "P" [0 0 0 1 0 0 0 1 0 1e38 1 0]"#), "too large"),
        ] {
            let d = error_of(&text);
            assert!(d.contains(expected), "{text}: {d}");
        }
    }

    /// The count comes before the tessellation: a NuPatch whose trim loops would cut it into more
    /// triangles than a RIB load may hold is counted as such, and refused without being built.
    #[test]
    fn a_nupatch_past_the_triangle_limit_is_refused_from_its_count() {
        let side = 14;
        let knots = numbers((0..side + 2).map(|k| (k.max(1) - 1).min(side - 1) as f64));
        let points = numbers((0..side * side).flat_map(|k| [(k % side) as f64, (k / side) as f64, 0.0]));
        let last = side - 1;
        let text = format!(r#"NuPatch {side} 2 [{knots}] 0 {last} {side} 2 [{knots}] 0 {last} "P" [{points}]"#);
        // A tiny square loop in each span along the diagonal: 256 segments a span both ways.
        let (mut u, mut v) = (Vec::new(), Vec::new());
        for s in 0..last {
            let c = s as f64 + 0.5;
            for (du, dv) in [(0.0, 0.0), (0.01, 0.0), (0.01, 0.01), (0.0, 0.01), (0.0, 0.0)] {
                u.push(c + du);
                v.push(c + dv);
            }
        }
        let loops = last;
        let trim = format!(
            "TrimCurve [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}]",
            numbers((0..loops).map(|_| 1.0)),
            numbers((0..loops).map(|_| 2.0)),
            numbers((0..loops).flat_map(|_| [0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0])),
            numbers((0..loops).map(|_| 0.0)),
            numbers((0..loops).map(|_| 4.0)),
            numbers((0..loops).map(|_| 5.0)),
            numbers(u),
            numbers(v),
            numbers((0..5 * loops).map(|_| 1.0)),
        );
        let options = trimmed(&trim, TrimSense::Inside);
        let r = request(&text);
        let counted = request_triangles(&r, &options);
        // Two triangles a cell, and one more where a loop cuts a triangle's corner off.
        assert!(counted >= 2 * (256 * last) * (256 * last), "{counted}");
        assert!(counted > MAX_RIB_TRIANGLES);
        let start = std::time::Instant::now();
        let mut diagnostics = Vec::new();
        assert!(mesh_from_request_with(&r, &options, &mut diagnostics).is_none());
        assert!(diagnostics[0].message.contains("more than"), "{diagnostics:?}");
        assert!(start.elapsed() < std::time::Duration::from_secs(20), "{:?}", start.elapsed());
    }
}

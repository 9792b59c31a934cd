//! `Curves` (RISpec 3.2, section 5.7) to triangle meshes: flat ribbons along linear or cubic
//! curves, tessellated, not intersected exactly.
//!
//! `Curves type [nvertices] wrap params` draws one curve per `nvertices` entry through that many
//! control points of `P` (or `Pw`), curve after curve. A `"linear"` curve is a polyline; a
//! `"cubic"` one is piecewise cubic under the current `Basis`'s **v** basis and v step (RISpec:
//! "Cubic curves interpolate using the v basis matrix and step size set by RiBasis"; `u` runs
//! across a curve and `v` along it). A curve has `nsegs` segments (spans):
//!
//! | type, wrap | nsegs | control points per curve |
//! |---|---|---|
//! | linear, nonperiodic | `nvertices - 1` | at least 2 |
//! | linear, periodic | `nvertices` | at least 2 |
//! | cubic, nonperiodic | `(nvertices - 4) / vstep + 1` | at least 4, `nvertices - 4` a multiple of vstep |
//! | cubic, periodic | `nvertices / vstep` | at least 4, a multiple of vstep |
//!
//! A periodic curve closes on itself: its last spans take their control points from the start.
//!
//! Primitive variables count (RISpec 3.2, 5.7): `constant` one value; `uniform` one per curve;
//! `varying` `nsegs + 1` per nonperiodic curve and `nsegs` per periodic one (a value at each end of
//! each segment; a periodic curve's last segment ends on its first value); `vertex` one per
//! control point; `facevarying` as varying (PRMan's rule; RISpec 3.2 does not list it for curves).
//! Vertex data follows the curve's basis; varying data is linear along each segment.
//!
//! - Width: `"width"` (varying by default; any class, counted as above), else `"constantwidth"`
//!   (one value), else 1, in object space; negative widths (a Catmull-Rom basis can overshoot)
//!   are 0.
//! - Ribbons: at each sample along the curve the ribbon spans `width` across, perpendicular to the
//!   tangent and to the direction it faces: the camera ([`View::facing`], RenderMan's default for
//!   curves without `N`), or `"N"` when given (an oriented ribbon: its normal is `N` made
//!   perpendicular to the tangent). Its normals are that facing direction; triangles wind
//!   counter-clockwise seen from it (`dP/du x dP/dv`).
//! - Parameters: `u` from 0 to 1 across the ribbon, `v` from 0 to 1 along the whole curve (segment
//!   `i` of `nsegs` spans `i / nsegs` to `(i + 1) / nsegs`); `s t` are `u v` unless `st` (or `s`
//!   and `t`) is given.
//! - Tessellation: a linear segment is one quad (two triangles); a cubic segment is cut into one
//!   piece for every 5.625 degrees that its control polygon in Bezier form turns (the curve turns
//!   no more than that), at least [`MIN_CUBIC_SPAN_SEGMENTS`], at most [`MAX_CURVE_SPAN_SEGMENTS`].
//!   That comes from the control points and the basis alone, so the triangles are counted before
//!   any is made ([`curves_triangles`]).
//!
//! Invariants: a curve whose control points all coincide, or whose widths are all zero (or not
//! finite), is left out; at a point where the tangent vanishes the segment's chord stands in for
//! it, and where the ribbon's direction is undefined (the curve points at the camera, or along `N`)
//! the previous sample's is kept: normals are never NaN. Wrong counts (`nvertices`, `P`, `width`,
//! `constantwidth`, `N`) and an unknown basis or bad step are an `Err` naming them; other data of
//! the wrong count is dropped with a warning, as for every primitive. Allocations are bounded by
//! the control points times [`MAX_CURVE_SPAN_SEGMENTS`]; nothing recurses.

use std::borrow::Cow;

use glam::{Vec2, Vec3};

use super::decl::Class;
use super::mesh::{
    per_vertex_params, positions, reserve_mesh, route_attributes_keeping_uv, ClassCounts, MeshOptions, PerVertex,
};
use super::patch::PatchCurve;
use super::request::{find_param, CurveType, Param, Wrap};
use super::spline::{segments_for_turn, turning};
use super::view::View;
use crate::geometry::{AttributeKind, Mesh};

/// The most pieces a segment (span) of a cubic curve is cut into.
pub const MAX_CURVE_SPAN_SEGMENTS: u32 = 64;

/// The fewest pieces a segment (span) of a cubic curve is cut into.
pub const MIN_CUBIC_SPAN_SEGMENTS: u32 = 2;

/// Degrees a cubic span's Bezier control polygon may turn per piece (64 pieces a full turn).
const CURVE_DEGREES_PER_SEGMENT: f64 = 360.0 / 64.0;

/// The width of curves that give none.
const DEFAULT_WIDTH: [f32; 1] = [1.0];

/// One curve of the request, as indices into the request's data.
#[derive(Clone, Copy, Debug)]
struct Curve {
    /// Its first control point in `P`.
    first_vertex: usize,
    /// Its control points.
    vertices: usize,
    /// Its first varying value.
    first_varying: usize,
    /// Its varying values.
    varying: usize,
    /// Its segments (spans).
    spans: usize,
    /// Its first span's index in [`CurvesPlan::segments`].
    first_span: usize,
    /// Whether it is drawn (not of zero length or width).
    drawn: bool,
}

/// A `Curves` request checked and sized, before anything is tessellated.
struct CurvesPlan<'a> {
    basis: PatchCurve,
    points: Vec<Vec3>,
    curves: Vec<Curve>,
    width: PerVertex<'a>,
    normal: Option<PerVertex<'a>>,
    /// Pieces of each span, curve after curve (also for curves not drawn).
    segments: Vec<u32>,
    vertex_total: usize,
    varying_total: usize,
}

/// Where along a curve a sample is: what each class of data is interpolated from.
struct Sample {
    curve: usize,
    /// The span's control points (global indices into `P`) and their weights.
    control: [usize; 4],
    weights: [f32; 4],
    order: usize,
    /// The varying values at the span's two ends (global indices), and how far along it is.
    varying: [usize; 2],
    t: f32,
}

impl Sample {
    /// The value of `d` here, appended to `out`.
    fn value(&self, d: &PerVertex, out: &mut Vec<f32>) {
        let c = d.components;
        let at = |k: usize, i: usize| d.values.get(k * c + i).copied().unwrap_or(0.0);
        for i in 0..c {
            out.push(match d.class {
                Class::Constant | Class::Implicit => at(0, i),
                Class::Uniform => at(self.curve, i),
                Class::Vertex => (0..self.order).map(|k| self.weights[k] * at(self.control[k], i)).sum(),
                Class::Varying | Class::FaceVarying => {
                    (1.0 - self.t) * at(self.varying[0], i) + self.t * at(self.varying[1], i)
                }
            });
        }
    }
}

/// The values of `class` a curve set of `curves` curves, `vertices` control points and `varying`
/// varying values takes.
fn expected(class: Class, curves: usize, vertices: usize, varying: usize) -> usize {
    match class {
        Class::Constant | Class::Implicit => 1,
        Class::Uniform => curves,
        Class::Vertex => vertices,
        Class::Varying | Class::FaceVarying => varying,
    }
}

impl<'a> CurvesPlan<'a> {
    fn new(
        ty: CurveType,
        nvertices: &[i32],
        wrap: Wrap,
        params: &'a [Param],
        options: &MeshOptions,
    ) -> Result<CurvesPlan<'a>, String> {
        let basis = match ty {
            CurveType::Linear => PatchCurve::bilinear(),
            CurveType::Cubic => PatchCurve::bicubic(&options.v_basis, options.v_step)?,
        };
        let mut curves = Vec::with_capacity(nvertices.len());
        let (mut vertex_total, mut varying_total, mut span_total) = (0usize, 0usize, 0usize);
        for (index, &n) in nvertices.iter().enumerate() {
            let spans = usize::try_from(n).ok().and_then(|n| basis.patches(n, wrap)).ok_or_else(|| {
                let kind = match (ty, wrap) {
                    (CurveType::Linear, _) => "a linear curve needs at least 2".to_string(),
                    (CurveType::Cubic, Wrap::NonPeriodic) => {
                        format!("a nonperiodic cubic curve needs 4 plus a multiple of the v step ({})", basis.step())
                    }
                    (CurveType::Cubic, Wrap::Periodic) => {
                        format!("a periodic cubic curve needs at least 4, a multiple of the v step ({})", basis.step())
                    }
                };
                format!("curve {index} has {n} control points: {kind}")
            })?;
            let vertices = n as usize;
            let varying = if wrap == Wrap::Periodic { spans } else { spans + 1 };
            curves.push(Curve {
                first_vertex: vertex_total,
                vertices,
                first_varying: varying_total,
                varying,
                spans,
                first_span: span_total,
                drawn: true,
            });
            vertex_total = vertex_total.saturating_add(vertices);
            varying_total = varying_total.saturating_add(varying);
            span_total = span_total.saturating_add(spans);
        }
        let points = positions(params)?;
        if points.len() != vertex_total {
            return Err(format!(
                "the curves have {vertex_total} control points in all (nvertices) but \"P\" has {}",
                points.len()
            ));
        }
        if points.iter().any(|p| !p.is_finite()) {
            return Err("a control point of \"P\" is not finite".into());
        }
        let ncurves = curves.len();
        let checked = |p: &'a Param, components: usize, what: &str| -> Result<PerVertex<'a>, String> {
            let values = p
                .floats()
                .filter(|_| p.decl.components() == components)
                .ok_or_else(|| format!("\"{}\" ({}) must be {what}", p.name, p.decl))?;
            let want = expected(p.decl.class, ncurves, vertex_total, varying_total);
            if p.value_count() != want {
                return Err(format!(
                    "\"{}\" ({}) has {} values where these curves need {want} ({ncurves} curves, {vertex_total} \
                     control points, {varying_total} varying values)",
                    p.name,
                    p.decl,
                    p.value_count()
                ));
            }
            let kind = super::mesh::attribute_kind(p.decl.ty);
            Ok(PerVertex { name: p.name.clone(), class: p.decl.class, components, values: Cow::Borrowed(values), kind })
        };
        let width = match (find_param(params, "width"), find_param(params, "constantwidth")) {
            (Some(width), _) => checked(width, 1, "a float")?,
            (None, Some(constant)) => match constant.floats() {
                Some(values @ &[_]) => PerVertex {
                    name: "constantwidth".into(),
                    class: Class::Constant,
                    components: 1,
                    values: Cow::Borrowed(values),
                    kind: AttributeKind::Data,
                },
                _ => return Err(format!("\"constantwidth\" ({}) must be one float", constant.decl)),
            },
            (None, None) => PerVertex {
                name: "width".into(),
                class: Class::Constant,
                components: 1,
                values: Cow::Borrowed(&DEFAULT_WIDTH),
                kind: AttributeKind::Data,
            },
        };
        let normal = find_param(params, "N").map(|n| checked(n, 3, "a normal (three floats a value)")).transpose()?;
        let mut plan =
            CurvesPlan { basis, points, curves, width, normal, segments: Vec::new(), vertex_total, varying_total };
        plan.segments = Vec::with_capacity(span_total);
        for index in 0..plan.curves.len() {
            let curve = plan.curves[index];
            let drawn = plan.has_length(&curve) && plan.has_width(index, &curve);
            plan.curves[index].drawn = drawn;
            for span in 0..curve.spans {
                let pieces = match ty {
                    CurveType::Linear => 1,
                    CurveType::Cubic => plan.cubic_pieces(&curve, span),
                };
                plan.segments.push(pieces);
            }
        }
        if let Some(fixed) = options.segments.as_deref().filter(|s| s.len() == plan.segments.len()) {
            plan.segments = fixed.to_vec();
        }
        Ok(plan)
    }

    /// Whether some control point of `curve` is not where its first is.
    fn has_length(&self, curve: &Curve) -> bool {
        let points = &self.points[curve.first_vertex..curve.first_vertex + curve.vertices];
        points.iter().any(|p| *p != points[0])
    }

    /// Whether some width of curve `index` is positive.
    fn has_width(&self, index: usize, curve: &Curve) -> bool {
        let values = &self.width.values[..];
        let own = match self.width.class {
            Class::Constant | Class::Implicit => values.get(..1),
            Class::Uniform => values.get(index..index + 1),
            Class::Vertex => values.get(curve.first_vertex..curve.first_vertex + curve.vertices),
            Class::Varying | Class::FaceVarying => values.get(curve.first_varying..curve.first_varying + curve.varying),
        };
        own.unwrap_or_default().iter().any(|&w| w > 0.0 && w.is_finite())
    }

    /// The global indices of the control points of span `span` of `curve`.
    fn control(&self, curve: &Curve, span: usize) -> [usize; 4] {
        let step = self.basis.step();
        [0, 1, 2, 3].map(|k| curve.first_vertex + (span * step + k) % curve.vertices)
    }

    /// Where on the curve parameter `t` of span `span` is: the point and the tangent.
    fn evaluate(&self, control: &[usize; 4], t: f32) -> (Vec3, Vec3, [f32; 4]) {
        let (w, dw) = self.basis.weights(t);
        let (mut p, mut dp) = (Vec3::ZERO, Vec3::ZERO);
        for k in 0..self.basis.order() {
            p += w[k] * self.points[control[k]];
            dp += dw[k] * self.points[control[k]];
        }
        (p, dp, w)
    }

    /// The pieces a cubic span is cut into, from how much its control polygon in Bezier form turns.
    fn cubic_pieces(&self, curve: &Curve, span: usize) -> u32 {
        let control = self.control(curve, span);
        let (p0, d0, _) = self.evaluate(&control, 0.0);
        let (p3, d3, _) = self.evaluate(&control, 1.0);
        let bezier = [p0, p0 + d0 / 3.0, p3 - d3 / 3.0, p3].map(|p| p.as_dvec3());
        let length: f64 = bezier.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        let degrees = turning(bezier.into_iter(), 1e-6 * length);
        segments_for_turn(degrees, CURVE_DEGREES_PER_SEGMENT, MIN_CUBIC_SPAN_SEGMENTS, MAX_CURVE_SPAN_SEGMENTS)
    }

    /// The pieces of the spans of `curve`.
    fn pieces(&self, curve: &Curve) -> &[u32] {
        self.segments.get(curve.first_span..curve.first_span + curve.spans).unwrap_or_default()
    }

    fn triangles(&self) -> usize {
        self.curves
            .iter()
            .filter(|c| c.drawn)
            .flat_map(|c| self.pieces(c))
            .map(|&pieces| 2 * pieces as usize)
            .fold(0, usize::saturating_add)
    }

    fn vertices(&self) -> usize {
        self.curves
            .iter()
            .filter(|c| c.drawn)
            .flat_map(|c| self.pieces(c))
            .map(|&pieces| 2 * (pieces as usize + 1))
            .fold(0, usize::saturating_add)
    }
}

/// The triangles [`curves_mesh`] makes of the same request, worked out without tessellating (0 for
/// a request it refuses).
pub fn curves_triangles(
    ty: CurveType,
    nvertices: &[i32],
    wrap: Wrap,
    params: &[Param],
    options: &MeshOptions,
) -> usize {
    CurvesPlan::new(ty, nvertices, wrap, params, options).map_or(0, |plan| plan.triangles())
}

/// The segments of each span [`curves_mesh`] makes of the same request (`None` when it refuses
/// it).
pub fn curves_segments(
    ty: CurveType,
    nvertices: &[i32],
    wrap: Wrap,
    params: &[Param],
    options: &MeshOptions,
) -> Option<Vec<u32>> {
    CurvesPlan::new(ty, nvertices, wrap, params, options).ok().map(|plan| plan.segments)
}

/// The ribbon's direction across a curve at one sample, and its normal.
struct Frame {
    across: Vec3,
    normal: Vec3,
}

/// The frame at a sample of tangent `tangent` (or, where that vanishes, `chord`) facing `facing`
/// (unit), keeping `previous`'s direction where the new one is undefined.
fn frame(tangent: Vec3, chord: Vec3, facing: Vec3, previous: Option<Vec3>) -> Frame {
    let Some(t) = tangent.try_normalize().or_else(|| chord.try_normalize()) else {
        let across = previous.unwrap_or_else(|| facing.any_orthonormal_vector());
        return Frame { across, normal: facing };
    };
    let cross = t.cross(facing);
    let across = if cross.length_squared() > 1e-12 {
        cross.normalize()
    } else {
        previous.and_then(|w| (w - t * t.dot(w)).try_normalize()).unwrap_or_else(|| t.any_orthonormal_vector())
    };
    Frame { across, normal: across.cross(t).normalize_or(facing) }
}

/// `Curves`: a ribbon along each curve, under the basis and view in `options`.
pub fn curves_mesh(
    ty: CurveType,
    nvertices: &[i32],
    wrap: Wrap,
    params: &[Param],
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let plan = CurvesPlan::new(ty, nvertices, wrap, params, options)?;
    let counts = ClassCounts {
        vertex: plan.vertex_total,
        varying: plan.varying_total,
        face: plan.curves.len(),
        corner: Some(plan.varying_total),
    };
    let data: Vec<_> = per_vertex_params(params, &counts, warnings)
        .into_iter()
        .filter(|d| !matches!(d.name.as_str(), "N" | "width"))
        .collect();
    let vertices = plan.vertices();
    let (mut mesh, mut attributes) = reserve_mesh(vertices, plan.triangles(), &data);
    let view: &View = &options.view;
    let mut scratch = Vec::new();
    for (index, curve) in plan.curves.iter().enumerate().filter(|(_, c)| c.drawn) {
        let mut previous = None;
        for (span, &pieces) in plan.pieces(curve).iter().enumerate() {
            let control = plan.control(curve, span);
            let varying = [curve.first_varying + span, curve.first_varying + (span + 1) % curve.varying.max(1)];
            let chord = plan.evaluate(&control, 1.0).0 - plan.evaluate(&control, 0.0).0;
            let first = mesh.positions.len() as u32;
            for piece in 0..=pieces {
                let t = piece as f32 / pieces as f32;
                let (p, tangent, weights) = plan.evaluate(&control, t);
                let sample = Sample { curve: index, control, weights, order: plan.basis.order(), varying, t };
                scratch.clear();
                sample.value(&plan.width, &mut scratch);
                let half = 0.5 * scratch.first().copied().filter(|w| w.is_finite()).unwrap_or(0.0).max(0.0);
                let facing = match &plan.normal {
                    Some(n) => {
                        scratch.clear();
                        sample.value(n, &mut scratch);
                        Vec3::from_slice(&scratch).try_normalize().unwrap_or_else(|| view.facing(p))
                    }
                    None => view.facing(p),
                };
                let Frame { across, normal } = frame(tangent, chord, facing, previous);
                previous = Some(across);
                let v = (span as f32 + t) / curve.spans as f32;
                for (side, u) in [(-1.0, 0.0), (1.0, 1.0)] {
                    mesh.positions.push(p + side * half * across);
                    if let Some(normals) = mesh.normals.as_mut() {
                        normals.push(normal);
                    }
                    if let Some(uvs) = mesh.uvs.as_mut() {
                        uvs.push(Vec2::new(u, v));
                    }
                }
                for (attribute, d) in attributes.iter_mut().zip(&data) {
                    scratch.clear();
                    sample.value(d, &mut scratch);
                    attribute.data.extend_from_slice(&scratch);
                    attribute.data.extend_from_slice(&scratch);
                }
            }
            for piece in 0..pieces {
                let (l0, r0) = (first + 2 * piece, first + 2 * piece + 1);
                let (l1, r1) = (l0 + 2, r0 + 2);
                mesh.triangles.push([l0, r0, r1]);
                mesh.triangles.push([l0, r1, l1]);
            }
        }
    }
    route_attributes_keeping_uv(&mut mesh, attributes);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::{mesh_from_request_with, parse_str, request_triangles, RequestKind, RibDiagnostic};

    /// Builds the last request of `text` under the `Basis` before it (the default view: the eye at
    /// the origin, looking along +z), checking that it was counted as built.
    fn build(text: &str) -> (Option<Mesh>, Vec<RibDiagnostic>) {
        let parse = parse_str(text, "curves.rib");
        assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
        let mut options = MeshOptions::default();
        let mut diagnostics = Vec::new();
        let mut mesh = None;
        for request in &parse.requests {
            if let RequestKind::Basis { u, ustep, v, vstep } = &request.kind {
                options =
                    MeshOptions { u_basis: u.clone(), u_step: *ustep, v_basis: v.clone(), v_step: *vstep, ..options };
                continue;
            }
            mesh = mesh_from_request_with(request, &options, &mut diagnostics);
            let counted = request_triangles(request, &options);
            assert_eq!(counted, mesh.as_ref().map_or(0, Mesh::triangle_count), "{text}");
        }
        (mesh, diagnostics)
    }

    fn mesh(text: &str) -> Mesh {
        let (mesh, diagnostics) = build(text);
        mesh.unwrap_or_else(|| panic!("{diagnostics:?}"))
    }

    /// The middle of each pair of ribbon vertices (a point on the curve), and its width.
    fn spine(mesh: &Mesh) -> Vec<(Vec3, f32)> {
        mesh.positions.chunks_exact(2).map(|p| ((p[0] + p[1]) * 0.5, (p[1] - p[0]).length())).collect()
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn a_linear_curve_is_a_ribbon_of_its_width_facing_the_camera() {
        let m = mesh(r#"Curves "linear" [3] "nonperiodic" "P" [0 0 5  1 0 5  1 1 5] "constantwidth" 0.2"#);
        assert_eq!(m.triangle_count(), 4);
        let normals = m.normals.as_ref().unwrap();
        let tangents = [Vec3::X, Vec3::X, Vec3::Y, Vec3::Y];
        for (k, pair) in m.positions.chunks_exact(2).enumerate() {
            let (across, middle) = (pair[1] - pair[0], (pair[0] + pair[1]) * 0.5);
            assert!((across.length() - 0.2).abs() < 1e-6, "{across}");
            // Across the curve and the line of sight from the eye at the origin, facing the eye.
            assert!(across.dot(tangents[k]).abs() < 1e-6 && across.dot(middle).abs() < 1e-5, "{across} at {middle}");
            assert!(normals[2 * k].dot(-middle.normalize()) > 0.98, "{}", normals[2 * k]);
            assert!(normals[2 * k].dot(tangents[k]).abs() < 1e-6);
        }
        assert!(close(normals[0], -Vec3::Z));
        for t in 0..m.triangle_count() {
            let [a, b, c] = m.corners(t);
            assert!((b - a).cross(c - a).normalize().dot(-a.normalize()) > 0.98, "triangle {t} faces away");
        }
        let spine = spine(&m);
        assert!(close(spine[0].0, Vec3::new(0.0, 0.0, 5.0)) && close(spine[3].0, Vec3::new(1.0, 1.0, 5.0)));
        // u across, v along the whole curve.
        let uvs = m.uvs.as_ref().unwrap();
        assert_eq!((uvs[0], uvs[1], uvs[2], uvs[7]), (Vec2::ZERO, Vec2::X, Vec2::new(0.0, 0.5), Vec2::ONE));
    }

    #[test]
    fn varying_width_and_data_follow_their_counts() {
        // Two linear segments: three varying values; one uniform value per curve.
        let m = mesh(
            r#"Curves "linear" [3 2] "nonperiodic" "P" [0 0 5  1 0 5  2 0 5  0 2 5  1 2 5]
               "width" [0.1 0.3 0.5  0.2 0.2] "Cs" [1 0 0  0 1 0  0 0 1  1 1 1  1 1 1] "uniform float id" [4 9]"#,
        );
        let widths: Vec<f32> = spine(&m).iter().map(|s| s.1).collect();
        for (got, want) in widths.iter().zip([0.1, 0.3, 0.3, 0.5, 0.2, 0.2]) {
            assert!((got - want).abs() < 1e-6, "{widths:?}");
        }
        let cs = &m.attributes.iter().find(|a| a.name == "Cs").unwrap().data;
        assert_eq!(&cs[3 * 6..3 * 7], &[0.0, 0.0, 1.0]); // the first curve's end, its left side
        let id = &m.attributes.iter().find(|a| a.name == "id").unwrap().data;
        assert_eq!((id[0], id[11]), (4.0, 9.0));
        assert!(m.attributes.iter().all(|a| a.name != "width"));
    }

    #[test]
    fn a_cubic_bezier_curve_passes_through_its_end_points() {
        let m = mesh(r#"Curves "cubic" [4] "nonperiodic" "P" [0 0 5  1 2 5  2 -2 5  3 0 5] "constantwidth" 0.05"#);
        let spine = spine(&m);
        assert!(close(spine[0].0, Vec3::new(0.0, 0.0, 5.0)));
        assert!(close(spine[spine.len() - 1].0, Vec3::new(3.0, 0.0, 5.0)));
        // The middle of the span, where t = 1/2 if the pieces are even: (P0 + 3 P1 + 3 P2 + P3) / 8.
        let pieces = spine.len() - 1;
        assert!(pieces >= MIN_CUBIC_SPAN_SEGMENTS as usize && pieces % 2 == 0, "{pieces} pieces");
        assert!(close(spine[pieces / 2].0, Vec3::new(1.5, 0.0, 5.0)), "{}", spine[pieces / 2].0);
        let uvs = m.uvs.as_ref().unwrap();
        assert_eq!((uvs[0].y, uvs[uvs.len() - 1].y), (0.0, 1.0));
    }

    #[test]
    fn pieces_follow_how_much_a_span_turns() {
        // A straight cubic span gets the fewest pieces; a half turn 32 of them.
        let straight = mesh(r#"Curves "cubic" [4] "nonperiodic" "P" [0 0 5  1 0 5  2 0 5  3 0 5]"#);
        assert_eq!(straight.triangle_count(), 2 * MIN_CUBIC_SPAN_SEGMENTS as usize);
        // The control polygon turns 90 + 63.43 degrees: 27.3 times 5.625, so 28 pieces.
        let turned = mesh(r#"Curves "cubic" [4] "nonperiodic" "P" [0 0 5  0 1 5  1 1 5  1.5 0 5]"#);
        assert_eq!(turned.triangle_count(), 2 * 28);
    }

    #[test]
    fn curves_use_the_v_basis_and_step() {
        // B-spline, step 1: 6 points make 3 segments, starting at (P0 + 4 P1 + P2) / 6.
        let text = r#"Basis "bezier" 3 "b-spline" 1
            Curves "cubic" [6] "nonperiodic" "P" [0 0 6  1 0 6  2 1 6  3 0 6  4 0 6  5 1 6] "width" [.1 .1 .1 .1]"#;
        let m = mesh(text);
        let spine = spine(&m);
        assert!(close(spine[0].0, Vec3::new(1.0, 1.0 / 6.0, 6.0)), "{}", spine[0].0);
        assert!(close(spine[spine.len() - 1].0, Vec3::new(4.0, 1.0 / 6.0, 6.0)), "{}", spine[spine.len() - 1].0);
        // Under the u basis the same curve would be refused (Bezier, step 3: 6 points is no whole span).
        let (m, diagnostics) = build(&text.replace(r#""bezier" 3 "b-spline" 1"#, r#""b-spline" 1 "bezier" 3"#));
        assert!(m.is_none());
        assert!(diagnostics[0].message.contains("curve 0 has 6 control points"), "{diagnostics:?}");
    }

    #[test]
    fn periodic_curves_wrap() {
        // A periodic B-spline through a square's corners: 4 segments, closed.
        let m = mesh(
            r#"Basis "b-spline" 1 "b-spline" 1
               Curves "cubic" [4] "periodic" "P" [1 1 5  -1 1 5  -1 -1 5  1 -1 5] "width" [.1 .2 .3 .4]"#,
        );
        let spine = spine(&m);
        assert!(close(spine[0].0, spine[spine.len() - 1].0), "{} {}", spine[0].0, spine[spine.len() - 1].0);
        // The last segment's width runs from the fourth varying value back to the first.
        assert!((spine[spine.len() - 1].1 - 0.1).abs() < 1e-6);
        // A periodic linear curve closes too: 3 points, 3 segments.
        let m = mesh(r#"Curves "linear" [3] "periodic" "P" [0 0 5  1 0 5  0 1 5] "constantwidth" 0.1"#);
        assert_eq!(m.triangle_count(), 6);
        assert!(close(spine_of(&m, 5), spine_of(&m, 0)));
    }

    fn spine_of(m: &Mesh, k: usize) -> Vec3 {
        spine(m)[k].0
    }

    #[test]
    fn oriented_ribbons_follow_n() {
        let m = mesh(r#"Curves "linear" [2] "nonperiodic" "P" [0 0 5  1 0 5] "N" [0 1 1  0 1 0] "constantwidth" 0.5"#);
        let normals = m.normals.as_ref().unwrap();
        assert!(close(normals[0], Vec3::new(0.0, 1.0, 1.0).normalize()));
        assert!(close(normals[2], Vec3::Y));
        // The ribbon runs across N and the tangent.
        let across = m.positions[3] - m.positions[2];
        assert!(close(across, Vec3::new(0.0, 0.0, 0.5)), "{across}");
    }

    #[test]
    fn degenerate_curves_are_left_out_and_normals_stay_finite() {
        // Zero length, zero width: nothing.
        let m = mesh(r#"Curves "linear" [2 2] "nonperiodic" "P" [1 1 5  1 1 5  0 0 5  1 0 5] "width" [1 1  0 0]"#);
        assert_eq!(m.triangle_count(), 0);
        // A Bezier curve with repeated end points (the tangent vanishes there), one pointing at
        // the camera, a tapering tip, N along the tangent.
        for text in [
            r#"Curves "cubic" [4] "nonperiodic" "P" [0 0 5  0 0 5  1 1 5  1 1 5] "width" [0.1 0]"#,
            r#"Curves "linear" [2] "nonperiodic" "P" [0 0 2  0 0 5] "constantwidth" 0.1"#,
            r#"Curves "linear" [3] "nonperiodic" "P" [0 0 5  1 0 5  1 0 5] "N" [1 0 0  1 0 0  0 0 0]"#,
        ] {
            let m = mesh(text);
            assert!(m.triangle_count() > 0, "{text}");
            for n in m.normals.as_ref().unwrap() {
                assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-4, "{text}: {n}");
            }
            assert!(m.positions.iter().all(|p| p.is_finite()));
        }
    }

    #[test]
    fn wrong_counts_are_errors_at_the_request() {
        for (text, message) in [
            (
                r#"Curves "linear" [3] "nonperiodic" "P" [0 0 0  1 0 0]"#,
                "3 control points in all (nvertices) but \"P\" has 2",
            ),
            (
                r#"Curves "linear" [1] "nonperiodic" "P" [0 0 0]"#,
                "curve 0 has 1 control points: a linear curve needs at least 2",
            ),
            (
                r#"Curves "cubic" [5] "nonperiodic" "P" [0 0 0  1 0 0  2 0 0  3 0 0  4 0 0]"#,
                "4 plus a multiple of the v step (3)",
            ),
            (
                r#"Curves "cubic" [4 -4] "nonperiodic" "P" [0 0 0  1 0 0  2 0 0  3 0 0]"#,
                "curve 1 has -4 control points",
            ),
            (r#"Curves "cubic" [4] "periodic" "P" [0 0 0  1 0 0  2 0 0  3 0 0]"#, "a multiple of the v step (3)"),
            (
                r#"Curves "linear" [2 3] "nonperiodic" "P" [0 0 0  1 0 0  0 1 0  1 1 0  2 1 0] "width" [1 1 1 1]"#,
                "\"width\" (varying float) has 4 values where these curves need 5",
            ),
            (
                r#"Curves "linear" [2] "nonperiodic" "P" [0 0 0  1 0 0] "uniform float width" [1 1]"#,
                "has 2 values where these curves need 1",
            ),
            (r#"Curves "linear" [2] "nonperiodic" "P" [0 0 0  1 0 0] "constantwidth" [1 1]"#, "must be one float"),
            (
                r#"Curves "linear" [2] "nonperiodic" "P" [0 0 0  1 0 0] "N" [0 0 1]"#,
                "\"N\" (varying normal) has 1 values",
            ),
            (
                r#"Basis "spline" 1 "spline" 1 Curves "cubic" [4] "nonperiodic" "P" [0 0 0  1 0 0  2 0 0  3 0 0]"#,
                "unknown basis",
            ),
            (r#"Curves "linear" [2] "nonperiodic" "Pw" [0 0 0 1  1 0 0 0]"#, "not finite"),
        ] {
            let (m, diagnostics) = build(text);
            assert!(m.is_none(), "{text}");
            assert_eq!(diagnostics.len(), 1, "{text}: {diagnostics:?}");
            let shown = diagnostics[0].to_string();
            assert!(shown.contains(": error: ") && shown.contains(message), "{text}: {shown}");
            assert!(shown.starts_with("curves.rib:1:"), "{shown}");
        }
        // Other data of the wrong count is dropped with a warning.
        let (m, diagnostics) = build(r#"Curves "linear" [2] "nonperiodic" "P" [0 0 5  1 0 5] "Cs" [1 0 0]"#);
        assert!(m.unwrap().attributes.is_empty());
        assert!(diagnostics[0].message.contains("\"Cs\" (varying color) has 1 values where this primitive needs 2"));
    }

    #[test]
    fn curve_types_parse() {
        let parse = parse_str(r#"Curves "cubic" [4 7] "periodic" "P" [0 0 0]"#, "c.rib");
        let RequestKind::Curves { ty, nvertices, wrap, .. } = &parse.requests[0].kind else { panic!() };
        assert_eq!((*ty, nvertices.as_slice(), *wrap), (CurveType::Cubic, &[4, 7][..], Wrap::Periodic));
        let bad = parse_str(r#"Curves "bicubic" [4] "nonperiodic" "P" [0 0 0]"#, "c.rib");
        assert!(bad.diagnostics[0].message.contains("unknown curve type \"bicubic\""), "{:?}", bad.diagnostics);
    }
}

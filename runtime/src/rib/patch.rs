//! Bilinear and bicubic patch meshes (RISpec 3.2, section 5.3) to triangle meshes.
//!
//! A patch mesh of `nu` x `nv` control points (u varying fastest) is cut into patches along each
//! direction by its basis: a bilinear patch spans 2 points with step 1, a bicubic one 4 points
//! with the basis step (3 for Bezier, 1 for B-spline and Catmull-Rom, 2 for Hermite, 4 for power).
//! Periodic directions wrap around.
//!
//! Invariants: each patch is tessellated on its own grid, evaluated exactly on the surface, with
//! normals `dP/du x dP/dv` (normalised) and uvs `(u, v)` running from 0 to 1 over the whole mesh
//! (texture coordinates other than those, `TextureCoordinates` or `st`, are an `st` attribute:
//! `mesh.rs`); vertex data follows the basis, varying data is bilinear between the patch's
//! corners, uniform data is constant per patch.

use glam::{Vec2, Vec3};

use super::decl::Class;
use super::mesh::{per_vertex_params, positions, route_attributes_parametric, ClassCounts, MeshOptions};
use super::request::{find_param, Basis, Param, PatchType, Wrap};
use crate::geometry::quadric::{tessellate_grid, Tessellation};
use crate::geometry::{Attribute, Mesh};

/// Segments per side of a patch by default (a flat bilinear patch needs one).
pub const DEFAULT_PATCH_SEGMENTS: u32 = 8;

/// The most segments per side of one patch.
const MAX_PATCH_SEGMENTS: u32 = 256;

/// Patch curves along one direction: how many control points each patch spans, its basis and
/// the step between patches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchCurve {
    order: usize,
    /// Rows are the coefficients of `t^3, t^2, t, 1` (RISpec's `RtBasis`), unused when `order`
    /// is 2.
    matrix: [[f32; 4]; 4],
    step: usize,
}

/// RISpec's standard bases and their conventional steps.
pub fn standard_basis(name: &str) -> Option<([f32; 16], i32)> {
    let (m, step): ([f32; 16], i32) = match name {
        "bezier" => ([-1., 3., -3., 1., 3., -6., 3., 0., -3., 3., 0., 0., 1., 0., 0., 0.], 3),
        "b-spline" | "bspline" => {
            ([-1., 3., -3., 1., 3., -6., 3., 0., -3., 0., 3., 0., 1., 4., 1., 0.].map(|x: f32| x / 6.0), 1)
        }
        "catmull-rom" | "catmullrom" => {
            ([-1., 3., -3., 1., 2., -5., 4., -1., -1., 0., 1., 0., 0., 2., 0., 0.].map(|x: f32| x / 2.0), 1)
        }
        "hermite" => ([2., 1., -2., 1., -3., -2., 3., -1., 0., 1., 0., 0., 1., 0., 0., 0.], 2),
        "power" => ([1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.], 4),
        _ => return None,
    };
    Some((m, step))
}

impl PatchCurve {
    /// Two points per patch, step 1.
    pub fn bilinear() -> Self {
        PatchCurve { order: 2, matrix: [[0.0; 4]; 4], step: 1 }
    }

    /// Four points per patch under `basis`, `step` points apart.
    pub fn bicubic(basis: &Basis, step: i32) -> Result<Self, String> {
        let m = match basis {
            Basis::Named(name) => standard_basis(name).map(|(m, _)| m).ok_or_else(|| {
                format!("unknown basis \"{name}\" (expected bezier, b-spline, catmull-rom, hermite or power)")
            })?,
            Basis::Matrix(m) => *m,
        };
        let step = usize::try_from(step).ok().filter(|s| (1..=4).contains(s)).ok_or("a basis step must be 1 to 4")?;
        let row = |r: usize| [m[4 * r], m[4 * r + 1], m[4 * r + 2], m[4 * r + 3]];
        Ok(PatchCurve { order: 4, matrix: [row(0), row(1), row(2), row(3)], step })
    }

    /// Control points per patch (or curve segment): 2 or 4.
    pub(super) fn order(&self) -> usize {
        self.order
    }

    /// Control points from one patch (or curve segment) to the next.
    pub(super) fn step(&self) -> usize {
        self.step
    }

    /// The weights of the patch's control points at `t`, and their derivatives.
    pub(super) fn weights(&self, t: f32) -> ([f32; 4], [f32; 4]) {
        if self.order == 2 {
            return ([1.0 - t, t, 0.0, 0.0], [-1.0, 1.0, 0.0, 0.0]);
        }
        let powers = [t * t * t, t * t, t, 1.0];
        let slopes = [3.0 * t * t, 2.0 * t, 1.0, 0.0];
        let mut w = [0.0; 4];
        let mut dw = [0.0; 4];
        for k in 0..4 {
            for r in 0..4 {
                w[k] += powers[r] * self.matrix[r][k];
                dw[k] += slopes[r] * self.matrix[r][k];
            }
        }
        (w, dw)
    }

    /// Patches along a direction of `n` control points (`None` where they do not make whole
    /// patches).
    pub(super) fn patches(&self, n: usize, wrap: Wrap) -> Option<usize> {
        match wrap {
            Wrap::Periodic if n >= self.order && n % self.step == 0 => Some(n / self.step),
            Wrap::NonPeriodic if n >= self.order && (n - self.order) % self.step == 0 => {
                Some((n - self.order) / self.step + 1)
            }
            _ => None,
        }
    }
}

/// A patch mesh's control points and how they make patches, before anything is tessellated.
struct PatchGrid {
    ucurve: PatchCurve,
    vcurve: PatchCurve,
    nu: usize,
    nv: usize,
    nu_patches: usize,
    nv_patches: usize,
    points: Vec<Vec3>,
}

impl PatchGrid {
    fn new(
        ty: PatchType,
        (nu, uwrap): (i32, Wrap),
        (nv, vwrap): (i32, Wrap),
        params: &[Param],
        options: &MeshOptions,
    ) -> Result<PatchGrid, String> {
        let (ucurve, vcurve) = match ty {
            PatchType::Bilinear => (PatchCurve::bilinear(), PatchCurve::bilinear()),
            PatchType::Bicubic => (
                PatchCurve::bicubic(&options.u_basis, options.u_step)?,
                PatchCurve::bicubic(&options.v_basis, options.v_step)?,
            ),
        };
        let size = |n: i32, curve: &PatchCurve, wrap: Wrap, axis: &str| {
            usize::try_from(n).ok().and_then(|n| Some((n, curve.patches(n, wrap)?))).ok_or_else(|| {
                format!(
                    "{n} control points along {axis} do not make whole patches ({} points per patch, step {}, {})",
                    curve.order,
                    curve.step,
                    if wrap == Wrap::Periodic { "periodic" } else { "nonperiodic" }
                )
            })
        };
        let (nu, nu_patches) = size(nu, &ucurve, uwrap, "u")?;
        let (nv, nv_patches) = size(nv, &vcurve, vwrap, "v")?;
        let points = patch_points(params, nu, nv)?;
        if Some(points.len()) != nu.checked_mul(nv) {
            return Err(format!(
                "a {nu} x {nv} patch mesh needs {} control points, but P has {}",
                nu.saturating_mul(nv),
                points.len()
            ));
        }
        Ok(PatchGrid { ucurve, vcurve, nu, nv, nu_patches, nv_patches, points })
    }

    /// Control point `(a, b)` of patch `(pi, pj)`, `a` along u.
    fn control(&self, (pi, pj): (usize, usize), a: usize, b: usize) -> usize {
        (pi * self.ucurve.step + a) % self.nu + self.nu * ((pj * self.vcurve.step + b) % self.nv)
    }

    /// The segments patch `(pi, pj)` is cut into along u and v.
    fn segments(&self, ty: PatchType, options: &MeshOptions, patch: (usize, usize)) -> (u32, u32) {
        let flat =
            ty == PatchType::Bilinear && is_flat([0, 1, 2, 3].map(|k| self.points[self.control(patch, k % 2, k / 2)]));
        let t = options.tessellation.unwrap_or(if flat {
            Tessellation { u_segments: 1, v_segments: 1 }
        } else {
            Tessellation { u_segments: DEFAULT_PATCH_SEGMENTS, v_segments: DEFAULT_PATCH_SEGMENTS }
        });
        (t.u_segments.clamp(1, MAX_PATCH_SEGMENTS), t.v_segments.clamp(1, MAX_PATCH_SEGMENTS))
    }

    /// The triangles the patches are cut into: two a grid cell (fewer where a row collapses).
    fn triangles(&self, ty: PatchType, options: &MeshOptions) -> usize {
        (0..self.nv_patches)
            .flat_map(|pj| (0..self.nu_patches).map(move |pi| (pi, pj)))
            .map(|patch| {
                let (su, sv) = self.segments(ty, options, patch);
                2 * su as usize * sv as usize
            })
            .fold(0, usize::saturating_add)
    }
}

/// At most the triangles [`patch_mesh`] makes of the same request, worked out without tessellating
/// (0 for a request it refuses).
pub fn patch_mesh_triangles(
    ty: PatchType,
    (nu, uwrap): (i32, Wrap),
    (nv, vwrap): (i32, Wrap),
    params: &[Param],
    options: &MeshOptions,
) -> usize {
    PatchGrid::new(ty, (nu, uwrap), (nv, vwrap), params, options).map_or(0, |g| g.triangles(ty, options))
}

/// `Patch` (`nu = nv = 2` or `4`) and `PatchMesh` of either type. Bicubic patches use the
/// basis in `options`.
#[allow(clippy::too_many_arguments)]
pub fn patch_mesh(
    ty: PatchType,
    nu: i32,
    uwrap: Wrap,
    nv: i32,
    vwrap: Wrap,
    params: &[Param],
    options: &MeshOptions,
    warnings: &mut Vec<String>,
) -> Result<Mesh, String> {
    let grid = PatchGrid::new(ty, (nu, uwrap), (nv, vwrap), params, options)?;
    let PatchGrid { ucurve, vcurve, nu, nv, nu_patches, nv_patches, .. } = grid;
    let points = &grid.points;
    // Varying values sit at patch corners: one more than the patches along an open direction.
    let varying_along = |patches: usize, wrap: Wrap| if wrap == Wrap::Periodic { patches } else { patches + 1 };
    let (nu_varying, nv_varying) = (varying_along(nu_patches, uwrap), varying_along(nv_patches, vwrap));
    let counts =
        ClassCounts { vertex: nu * nv, varying: nu_varying * nv_varying, face: nu_patches * nv_patches, corner: None };
    let data = per_vertex_params(params, &counts, warnings);

    let mut mesh = Mesh { normals: Some(Vec::new()), uvs: Some(Vec::new()), ..Default::default() };
    let mut attributes: Vec<Attribute> = data.iter().map(|d| d.attribute(Vec::new())).collect();
    for pj in 0..nv_patches {
        for pi in 0..nu_patches {
            let control = |a: usize, b: usize| grid.control((pi, pj), a, b);
            let surface = |u: f32, v: f32| {
                let (wu, dwu) = ucurve.weights(u);
                let (wv, dwv) = vcurve.weights(v);
                let (mut p, mut dpdu, mut dpdv) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
                for b in 0..vcurve.order {
                    for a in 0..ucurve.order {
                        let q = points[control(a, b)];
                        p += q * (wu[a] * wv[b]);
                        dpdu += q * (dwu[a] * wv[b]);
                        dpdv += q * (wu[a] * dwv[b]);
                    }
                }
                (p, dpdu.cross(dpdv))
            };
            let (su, sv) = grid.segments(ty, options, (pi, pj));
            let patch = tessellate_grid(su, sv, |u, v| {
                let (p, n) = surface(u, v);
                // Where dP/du x dP/dv vanishes (a collapsed edge), look a little inside.
                let n = if n.length_squared() > 1e-20 {
                    n
                } else {
                    surface(0.5 + 0.99 * (u - 0.5), 0.5 + 0.99 * (v - 0.5)).1
                };
                (p, n.normalize_or(Vec3::Z))
            });
            let local_uvs = patch.uvs.clone().unwrap_or_default();
            let face = pi + nu_patches * pj;
            let varying_corner = |du: usize, dv: usize| (pi + du) % nu_varying + nu_varying * ((pj + dv) % nv_varying);
            let corners = [varying_corner(0, 0), varying_corner(1, 0), varying_corner(0, 1), varying_corner(1, 1)];
            for (attribute, d) in attributes.iter_mut().zip(&data) {
                let value = |k: usize, c: usize| d.values[k * d.components + c];
                for uv in &local_uvs {
                    let (wu, _) = ucurve.weights(uv.x);
                    let (wv, _) = vcurve.weights(uv.y);
                    for c in 0..d.components {
                        attribute.data.push(match d.class {
                            Class::Uniform => value(face, c),
                            Class::Vertex => (0..vcurve.order)
                                .flat_map(|b| (0..ucurve.order).map(move |a| (a, b)))
                                .map(|(a, b)| wu[a] * wv[b] * value(control(a, b), c))
                                .sum(),
                            _ => super::mesh::bilerp(corners.map(|k| value(k, c)), uv.x, uv.y),
                        });
                    }
                }
            }
            let global_uvs = local_uvs
                .iter()
                .map(|uv| Vec2::new((pi as f32 + uv.x) / nu_patches as f32, (pj as f32 + uv.y) / nv_patches as f32));
            append(&mut mesh, patch, global_uvs);
        }
    }
    route_attributes_parametric(&mut mesh, attributes, options);
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(mesh)
}

/// Patch control points: `P`, `Pw`, or the height field `Pz` over the unit square.
fn patch_points(params: &[Param], nu: usize, nv: usize) -> Result<Vec<Vec3>, String> {
    if let Some(pz) = find_param(params, "Pz").filter(|p| p.decl.components() == 1) {
        let heights = pz.floats().unwrap_or_default();
        if heights.len() != nu * nv {
            return Err(format!("\"Pz\" has {} values, the patch mesh needs {}", heights.len(), nu * nv));
        }
        let coordinate = |i: usize, n: usize| i as f32 / (n - 1).max(1) as f32;
        return Ok(heights
            .iter()
            .enumerate()
            .map(|(k, &z)| Vec3::new(coordinate(k % nu, nu), coordinate(k / nu, nv), z))
            .collect());
    }
    positions(params)
}

/// Whether the four corners (order `00 10 01 11`) lie in one plane.
fn is_flat(c: [Vec3; 4]) -> bool {
    let n = (c[1] - c[0]).cross(c[2] - c[0]);
    let scale = c.iter().fold(0.0f32, |m, p| m.max((*p - c[0]).length()));
    n.length_squared() == 0.0 || n.normalize().dot(c[3] - c[0]).abs() <= 1e-6 * scale
}

/// Appends `part` (with normals) to `mesh`, with `uvs` in place of its own.
fn append(mesh: &mut Mesh, part: Mesh, uvs: impl Iterator<Item = Vec2>) {
    let offset = mesh.positions.len() as u32;
    mesh.positions.extend(part.positions);
    if let (Some(normals), Some(part_normals)) = (mesh.normals.as_mut(), part.normals) {
        normals.extend(part_normals);
    }
    if let Some(mesh_uvs) = mesh.uvs.as_mut() {
        mesh_uvs.extend(uvs);
    }
    mesh.triangles.extend(part.triangles.into_iter().map(|t| t.map(|i| i + offset)));
}

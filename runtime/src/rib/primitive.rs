//! Geometry requests to triangle meshes: which of the builders (`mesh.rs` for polygons and
//! quadrics, `patch.rs` for patches and patch meshes, `nurbs.rs` for NURBS patches, `subdiv.rs` for
//! subdivision meshes, `teapot.rs` for `Geometry`, `points.rs` for points, `curves.rs` for curves,
//! `blobby.rs` for implicit surfaces) a request goes to, and its warnings and errors as diagnostics
//! at the request's location.

use super::blobby::{blobby_mesh, blobby_triangles, BlobbyInput};
use super::curves::{curves_mesh, curves_segments, curves_triangles};
use super::mesh::{
    general_polygon_mesh, points_general_polygons_mesh, points_polygons_mesh, polygon_mesh, quadric_mesh, MeshOptions,
};
use super::nurbs::{nupatch_mesh, nupatch_triangles};
use super::patch::{patch_mesh, patch_mesh_triangles};
use super::points::{points_mesh, points_segments, points_triangles};
use super::request::{PatchType, Request, RequestKind, Wrap};
use super::subdiv::{subdivision_mesh, subdivision_mesh_triangles, SubdivisionInput};
use super::teapot::{geometry_mesh, geometry_triangles};
use super::RibDiagnostic;
use crate::geometry::{Mesh, Quadric};

/// The mesh of a geometry request with default options, or `None` for requests that are not
/// geometry or whose data is malformed (an error is pushed then). Warnings about dropped data are
/// pushed too.
pub fn mesh_from_request(request: &Request, diagnostics: &mut Vec<RibDiagnostic>) -> Option<Mesh> {
    mesh_from_request_with(request, &MeshOptions::default(), diagnostics)
}

/// At most the triangles [`mesh_from_request_with`] makes of a patch, a NURBS patch, a quadric, a
/// subdivision mesh, a `Geometry`, `Points`, `Curves` or a `Blobby`, worked out without
/// tessellating it (exactly for patches, subdivision meshes, points and curves; for a blobby
/// twelve a cell of its grid, a loose bound the loader does not use; 0 for other requests, whose
/// triangles their own data bound, and for a request the builder refuses).
pub fn request_triangles(request: &Request, options: &MeshOptions) -> usize {
    match &request.kind {
        RequestKind::Patch { ty, params } => {
            let n = if *ty == PatchType::Bilinear { 2 } else { 4 };
            patch_mesh_triangles(*ty, (n, Wrap::NonPeriodic), (n, Wrap::NonPeriodic), params, options)
        }
        RequestKind::PatchMesh { ty, nu, uwrap, nv, vwrap, params } => {
            patch_mesh_triangles(*ty, (*nu, *uwrap), (*nv, *vwrap), params, options)
        }
        RequestKind::Quadric { quadric, .. } => {
            Quadric::triangle_count(options.tessellation.unwrap_or_else(|| quadric.default_tessellation()))
        }
        RequestKind::SubdivisionMesh { .. } => subdivision_input(&request.kind).map_or(0, subdivision_mesh_triangles),
        RequestKind::NuPatch { u, v, params } => nupatch_triangles(u, v, params, options),
        RequestKind::Geometry { name, .. } => geometry_triangles(name, options),
        RequestKind::Points(params) => points_triangles(params, options),
        RequestKind::Curves { ty, nvertices, wrap, params } => curves_triangles(*ty, nvertices, *wrap, params, options),
        RequestKind::Blobby { .. } => blobby_input(&request.kind).map_or(0, |input| blobby_triangles(&input, options)),
        _ => 0,
    }
}

/// The segments per point of a `Points` request, or per span of a `Curves` request, that
/// [`mesh_from_request_with`] would choose (what [`MeshOptions::segments`] fixes); `None` for
/// other requests and for one the builder refuses.
pub fn request_segments(request: &Request, options: &MeshOptions) -> Option<std::sync::Arc<[u32]>> {
    let segments = match &request.kind {
        RequestKind::Points(params) => points_segments(params, options),
        RequestKind::Curves { ty, nvertices, wrap, params } => curves_segments(*ty, nvertices, *wrap, params, options),
        _ => None,
    };
    segments.map(Into::into)
}

/// [`mesh_from_request`] under the graphics state's basis and a chosen tessellation.
pub fn mesh_from_request_with(
    request: &Request,
    options: &MeshOptions,
    diagnostics: &mut Vec<RibDiagnostic>,
) -> Option<Mesh> {
    let mut warnings = Vec::new();
    let result = match &request.kind {
        RequestKind::Polygon(params) => polygon_mesh(params, &mut warnings),
        RequestKind::GeneralPolygon { nvertices, params } => general_polygon_mesh(nvertices, params, &mut warnings),
        RequestKind::PointsPolygons { nvertices, vertices, params } => {
            points_polygons_mesh(nvertices, vertices, params, &mut warnings)
        }
        RequestKind::PointsGeneralPolygons { nloops, nvertices, vertices, params } => {
            points_general_polygons_mesh(nloops, nvertices, vertices, params, &mut warnings)
        }
        RequestKind::Patch { ty, params } => {
            let n = if *ty == PatchType::Bilinear { 2 } else { 4 };
            patch_mesh(*ty, n, Wrap::NonPeriodic, n, Wrap::NonPeriodic, params, options, &mut warnings)
        }
        RequestKind::PatchMesh { ty, nu, uwrap, nv, vwrap, params } => {
            patch_mesh(*ty, *nu, *uwrap, *nv, *vwrap, params, options, &mut warnings)
        }
        RequestKind::Quadric { quadric, params } => quadric_mesh(quadric, params, options, &mut warnings),
        RequestKind::SubdivisionMesh { .. } => match subdivision_input(&request.kind) {
            Some(input) => subdivision_mesh(input, &mut warnings),
            None => return None,
        },
        RequestKind::NuPatch { u, v, params } => nupatch_mesh(u, v, params, options, &mut warnings),
        RequestKind::Geometry { name, params } => geometry_mesh(name, params, options, &mut warnings),
        RequestKind::Points(params) => points_mesh(params, options, &mut warnings),
        RequestKind::Curves { ty, nvertices, wrap, params } => {
            curves_mesh(*ty, nvertices, *wrap, params, options, &mut warnings)
        }
        RequestKind::Blobby { .. } => match blobby_input(&request.kind) {
            Some(input) => blobby_mesh(&input, options, &mut warnings),
            None => return None,
        },
        _ => return None,
    };
    diagnostics.extend(warnings.into_iter().map(|w| RibDiagnostic::warning(&request.loc, w)));
    match result {
        Ok(mesh) => Some(mesh),
        Err(message) => {
            diagnostics.push(RibDiagnostic::error(&request.loc, message));
            None
        }
    }
}

/// A `SubdivisionMesh` request's arguments, borrowed.
fn subdivision_input(kind: &RequestKind) -> Option<SubdivisionInput<'_>> {
    match kind {
        RequestKind::SubdivisionMesh { scheme, nvertices, vertices, tags, nargs, intargs, floatargs, params } => {
            Some(SubdivisionInput { scheme, nvertices, vertices, tags, nargs, intargs, floatargs, params })
        }
        _ => None,
    }
}

/// A `Blobby` request's arguments, borrowed.
fn blobby_input(kind: &RequestKind) -> Option<BlobbyInput<'_>> {
    match kind {
        RequestKind::Blobby { nleaf, code, floats, strings, params } => {
            Some(BlobbyInput { nleaf: *nleaf, code, floats, strings, params })
        }
        _ => None,
    }
}

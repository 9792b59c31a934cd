//! Placeholder
use super::{Request, RibDiagnostic};
use crate::geometry::Mesh;
/// todo
pub fn mesh_from_request(_request: &Request, _diagnostics: &mut Vec<RibDiagnostic>) -> Option<Mesh> {
    None
}

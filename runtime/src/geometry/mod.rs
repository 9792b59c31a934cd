//! Geometry the tracer intersects: triangle meshes with per-vertex data, and the triangle
//! intersection test shared by every traversal path.
//!
//! Invariant: every query path (single ray, packet, brute force) calls the one generic
//! [`triangle::intersect`] formula, so they compute bit-identical `t`, `u` and `v` for the same ray
//! and triangle.

pub mod alpha;
pub mod dice;
pub mod mesh;
pub mod quadric;
pub mod triangle;

pub use alpha::AlphaMask;
pub use dice::{dice, Diced, DicedVertex};
pub use mesh::{Attribute, AttributeKind, Deformation, Mesh, MeshError};
pub use quadric::{Quadric, Tessellation};

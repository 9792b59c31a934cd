//! Scalar implementations of the built-in functions: the reference semantics of the language.
//!
//! The reference interpreter calls these once per lane; the JIT's vectorised helpers must agree with
//! them within the documented accuracy (differential tests compare the two). Everything here is a
//! pure function of its arguments, deterministic across runs and platforms (no platform `libm`
//! differences in the noise family: it uses only IEEE-exact operations and integer hashing).
//!
//! Conventions (RenderMan's): points are row vectors transformed as `p * M`; matrices are stored
//! row-major as 16 floats, with the translation in elements 12, 13, 14; angles are in radians.

pub mod color;
pub mod deriv;
pub mod format;
pub mod gather;
pub mod geom;
pub mod matrix;
pub mod noise;
pub mod spline;
pub mod transcendental;

/// A triple: colour, point, vector or normal.
pub type V3 = [f32; 3];
/// A 4x4 matrix, row-major.
pub type M4 = [f32; 16];

//! The camera as a geometry request sees it, for primitives built to face it: which way a surface
//! at a point faces the viewer, and how large a length there looks (to cut what looks larger
//! finer).
//!
//! A [`View`] holds the request's object-to-world transform and the camera in world space, so both
//! questions are answered in object space, where the builders work:
//! - [`View::facing`]: the object-space normal of a surface at a point that faces the viewer. A
//!   plane's normal maps to world space by the inverse transpose of the transform's linear part
//!   `L`, so the object-space normal whose world normal is the line of sight `d` is `L^T d`: a disk
//!   built perpendicular to it faces the camera exactly in world space, whatever the transform.
//! - [`View::fraction`]: how much of the image's shorter side a length at a point spans: its angle
//!   over the field of view (perspective), or its world length over the screen window's
//!   (orthographic). Object-space lengths are taken to world space by the transform's mean scale
//!   (the cube root of its determinant).
//!
//! Invariants: both are total: a point at the eye, a singular transform or non-finite input give
//! `Vec3::Z` and a finite fraction (0 where undefined), never NaN.

use glam::{Affine3A, Mat3, Vec3};

/// How the camera projects, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole at `eye`; `across` is the angle (radians) the image's shorter side spans.
    Perspective {
        /// The eye, in world space.
        eye: Vec3,
        /// The field of view across the image's shorter side, in radians.
        across: f32,
    },
    /// Parallel rays along `forward`; `across` is the world-space length the image's shorter side
    /// spans.
    Orthographic {
        /// The viewing direction, in world space.
        forward: Vec3,
        /// The screen window's shorter side, in world units.
        across: f32,
    },
}

/// The camera seen from one geometry request: its object-to-world transform and the projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// The request's object space to world space (the current transform).
    pub world_from_object: Affine3A,
    /// The camera.
    pub projection: Projection,
}

impl Default for View {
    /// Object space is world space, and the eye is at its origin with RenderMan's default 90 degree
    /// field of view: camera space, as a request outside any camera setup sees it.
    fn default() -> Self {
        View {
            world_from_object: Affine3A::IDENTITY,
            projection: Projection::Perspective { eye: Vec3::ZERO, across: 90f32.to_radians() },
        }
    }
}

impl View {
    /// The unit object-space normal of a surface at `p` (object space) that faces the viewer:
    /// `L^T d` for the world-space direction `d` from `p` to the eye (perspective) or against the
    /// view (orthographic). `Vec3::Z` where that is undefined (`p` at the eye, a singular
    /// transform).
    pub fn facing(&self, p: Vec3) -> Vec3 {
        let towards = match self.projection {
            Projection::Perspective { eye, .. } => eye - self.world_from_object.transform_point3(p),
            Projection::Orthographic { forward, .. } => -forward,
        };
        let linear = Mat3::from(self.world_from_object.matrix3);
        (linear.transpose() * towards).try_normalize().unwrap_or(Vec3::Z)
    }

    /// The fraction of the image's shorter side that a length `size` (object space) at `p` spans
    /// seen from the camera: finite and at least 0 (0 where undefined; large for a point at the
    /// eye).
    pub fn fraction(&self, p: Vec3, size: f32) -> f32 {
        let scale = Mat3::from(self.world_from_object.matrix3).determinant().abs().cbrt();
        let world = size * scale;
        let fraction = match self.projection {
            Projection::Perspective { eye, across } => {
                let distance = (eye - self.world_from_object.transform_point3(p)).length();
                2.0 * (0.5 * world).atan2(distance) / across
            }
            Projection::Orthographic { across, .. } => world / across,
        };
        if fraction.is_finite() {
            fraction.max(0.0)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_points_to_the_eye_in_object_space() {
        let view = View::default();
        assert_eq!(view.facing(Vec3::new(0.0, 0.0, 5.0)), -Vec3::Z);
        assert_eq!(view.facing(Vec3::ZERO), Vec3::Z);
        // A non-uniform scale: the object-space normal is the one whose world normal is the line
        // of sight.
        let view = View {
            world_from_object: Affine3A::from_scale(Vec3::new(1.0, 4.0, 1.0)),
            projection: Projection::Orthographic { forward: Vec3::new(0.0, 1.0, 1.0).normalize(), across: 2.0 },
        };
        let n = view.facing(Vec3::ZERO);
        let world_normal = (Mat3::from(view.world_from_object.matrix3).inverse().transpose() * n).normalize();
        assert!((world_normal + Vec3::new(0.0, 1.0, 1.0).normalize()).length() < 1e-6, "{world_normal}");
        // Degenerate input falls back to +z.
        let flat = View { world_from_object: Affine3A::from_scale(Vec3::ZERO), ..View::default() };
        assert_eq!(flat.facing(Vec3::ONE), Vec3::Z);
    }

    #[test]
    fn fraction_is_the_apparent_size() {
        let view = View::default();
        // A length of 2 at distance 1 spans 90 degrees: the whole default field of view.
        assert!((view.fraction(Vec3::new(0.0, 0.0, 1.0), 2.0) - 1.0).abs() < 1e-6);
        let ortho = View {
            world_from_object: Affine3A::from_scale(Vec3::splat(2.0)),
            projection: Projection::Orthographic { forward: Vec3::Z, across: 8.0 },
        };
        assert!((ortho.fraction(Vec3::ZERO, 1.0) - 0.25).abs() < 1e-6);
        assert_eq!(ortho.fraction(Vec3::ZERO, f32::NAN), 0.0);
    }
}

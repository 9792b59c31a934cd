//! Camera navigation and object dragging for `rtsl view`, as pure functions of the camera.
//!
//! Every move multiplies the camera's world-from-camera matrix on the left by a rigid motion, so
//! the camera keeps its field of view, scale and handedness (RenderMan's camera space is
//! left-handed; a RIB's camera may be any affine map).

use glam::{Affine3A, Quat, Vec3, Vec3A};
use rtsl_runtime::render::CameraSetup;

/// Radians of orbit per pixel dragged.
const ORBIT_PER_PIXEL: f32 = 0.008;
/// Radians of looking around per pixel dragged (fly mode).
const LOOK_PER_PIXEL: f32 = 0.004;
/// Scene sizes per second of flying.
const FLY_SPEED: f32 = 0.4;
/// Each scroll step brings the camera this much closer to the pivot.
const DOLLY_PER_STEP: f32 = 0.85;

/// The navigation state: the camera, the point orbits turn about, the direction that stays up.
#[derive(Clone, Copy, Debug)]
pub struct Navigation {
    pub camera: CameraSetup,
    pub pivot: Vec3A,
    /// The world's up for orbiting and looking (the first camera's up), so the horizon stays level.
    pub up: Vec3A,
    /// A length for the scene, to scale flying.
    pub scene_size: f32,
}

fn unit(v: Vec3A, fallback: Vec3A) -> Vec3A {
    v.try_normalize().unwrap_or(fallback)
}

/// The rotation by `angle` about `axis` through `center`.
fn rotation_about(center: Vec3A, axis: Vec3A, angle: f32) -> Affine3A {
    let r = Affine3A::from_quat(Quat::from_axis_angle(Vec3::from(axis), angle));
    Affine3A::from_translation(Vec3::from(center)) * r * Affine3A::from_translation(-Vec3::from(center))
}

impl Navigation {
    /// Navigation for `camera` over a scene with bounds `bounds`: the pivot is on the view axis,
    /// as far ahead as the scene's centre.
    pub fn new(camera: CameraSetup, bounds: Option<(Vec3A, Vec3A)>) -> Navigation {
        let eye = camera.eye();
        let forward = self::unit(camera.world_from_camera.matrix3.z_axis, Vec3A::Z);
        let up = self::unit(camera.world_from_camera.matrix3.y_axis, Vec3A::Y);
        let (center, size) = match bounds {
            Some((lo, hi)) if (hi - lo).is_finite() => ((lo + hi) * 0.5, (hi - lo).length().max(1e-3)),
            _ => (eye + forward, 1.0),
        };
        let ahead = (center - eye).dot(forward).max(0.1 * size);
        Navigation { camera, pivot: eye + forward * ahead, up, scene_size: size }
    }

    fn right(&self) -> Vec3A {
        self::unit(self.camera.world_from_camera.matrix3.x_axis, Vec3A::X)
    }

    fn apply(&mut self, motion: Affine3A) {
        self.camera.world_from_camera = motion * self.camera.world_from_camera;
    }

    /// Turns the camera about the pivot: dragging right turns the scene right (about the world's
    /// up), dragging down tilts it towards the viewer.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        let yaw = rotation_about(self.pivot, self.up, -dx * ORBIT_PER_PIXEL);
        self.apply(yaw);
        let pitch = rotation_about(self.pivot, self.right(), -dy * ORBIT_PER_PIXEL);
        self.apply(pitch);
    }

    /// Turns the camera about its own position (fly mode's mouse look); the pivot turns with it.
    pub fn look(&mut self, dx: f32, dy: f32) {
        let eye = self.camera.eye();
        let yaw = rotation_about(eye, self.up, -dx * LOOK_PER_PIXEL);
        let pitch = rotation_about(eye, self.right(), -dy * LOOK_PER_PIXEL);
        let motion = pitch * yaw;
        self.apply(motion);
        self.pivot = motion.transform_point3a(self.pivot);
    }

    /// Moves the camera (and its pivot) along its own axes: `direction` is (right, up, forward),
    /// for `seconds` at the flying speed.
    pub fn fly(&mut self, direction: Vec3A, seconds: f32) {
        let m = &self.camera.world_from_camera.matrix3;
        let along = self.right() * direction.x
            + self::unit(m.y_axis, Vec3A::Y) * direction.y
            + self::unit(m.z_axis, Vec3A::Z) * direction.z;
        let step = along * (FLY_SPEED * self.scene_size * seconds);
        self.apply(Affine3A::from_translation(Vec3::from(step)));
        self.pivot += step;
    }

    /// Moves the camera towards the pivot (positive `steps`, scroll up) or away from it.
    pub fn dolly(&mut self, steps: f32) {
        let to_pivot = self.pivot - self.camera.eye();
        let distance = to_pivot.length();
        if distance <= 1e-6 || !steps.is_finite() {
            return;
        }
        let new_distance = (distance * DOLLY_PER_STEP.powf(steps.clamp(-20.0, 20.0))).max(1e-3 * self.scene_size);
        let step = to_pivot / distance * (distance - new_distance);
        self.apply(Affine3A::from_translation(Vec3::from(step)));
    }

    /// How far a point at camera-space depth `depth` moves in the world when it moves `(dx, dy)`
    /// pixels across an image of `width x height` (image y points down).
    pub fn view_plane_offset(&self, depth: f32, dx: f32, dy: f32, width: u32, height: u32) -> Vec3A {
        let (wf, hf) = (width.max(1) as f32, height.max(1) as f32);
        let tan = (self.camera.fov_degrees.to_radians() * 0.5).tan();
        let (ax, ay) = if wf >= hf { (wf / hf, 1.0) } else { (1.0, hf / wf) };
        // Camera rays are z + x * sx + y * sy: a pixel moves sx by 2 tan ax / w at depth z = 1.
        let (dsx, dsy) = (2.0 * dx * tan * ax / wf, -2.0 * dy * tan * ay / hf);
        self.camera.world_from_camera.matrix3 * Vec3A::new(dsx * depth, dsy * depth, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nav() -> Navigation {
        let cam = CameraSetup::look_at(Vec3A::new(0.0, 0.0, 10.0), Vec3A::ZERO, Vec3A::Y, 40.0);
        Navigation::new(cam, Some((Vec3A::splat(-1.0), Vec3A::splat(1.0))))
    }

    fn close(a: Vec3A, b: Vec3A) -> bool {
        (a - b).length() < 1e-4
    }

    #[test]
    fn the_pivot_is_ahead_at_the_scene_centre() {
        assert!(close(nav().pivot, Vec3A::ZERO));
    }

    #[test]
    fn orbiting_keeps_the_distance_and_the_pivot_centred() {
        let mut n = nav();
        n.orbit(120.0, -40.0);
        assert!(((n.camera.eye() - n.pivot).length() - 10.0).abs() < 1e-3);
        let forward = n.camera.world_from_camera.matrix3.z_axis.normalize();
        assert!(close(n.camera.eye() + forward * 10.0, n.pivot), "the camera still looks at the pivot");
        // Dragging right turns the scene right: the camera goes left (towards -x seen from +z).
        let mut m = nav();
        m.orbit(50.0, 0.0);
        assert!(m.camera.eye().x < -1.0, "{:?}", m.camera.eye());
        // The horizon stays level: the camera's right axis stays horizontal.
        assert!(n.camera.world_from_camera.matrix3.x_axis.y.abs() < 1e-4);
    }

    #[test]
    fn flying_and_dollying_move_along_the_view() {
        let mut n = nav();
        n.fly(Vec3A::new(0.0, 0.0, 1.0), 1.0);
        let size = 2.0 * 3f32.sqrt();
        assert!(close(n.camera.eye(), Vec3A::new(0.0, 0.0, 10.0 - FLY_SPEED * size)));
        assert!(close(n.pivot, Vec3A::new(0.0, 0.0, -FLY_SPEED * size)), "the pivot moves with the camera");
        let mut d = nav();
        d.dolly(1.0);
        assert!(close(d.camera.eye(), Vec3A::new(0.0, 0.0, 10.0 * DOLLY_PER_STEP)));
        d.dolly(-1.0);
        assert!(close(d.camera.eye(), Vec3A::new(0.0, 0.0, 10.0)));
    }

    #[test]
    fn looking_turns_about_the_eye() {
        let mut n = nav();
        n.look(100.0, 30.0);
        assert!(close(n.camera.eye(), Vec3A::new(0.0, 0.0, 10.0)));
        assert!(((n.pivot - n.camera.eye()).length() - 10.0).abs() < 1e-3);
    }

    #[test]
    fn a_view_plane_drag_follows_the_cursor() {
        let n = nav();
        // At depth 10 with a 40 degree field of view spanning 100 pixels, 50 pixels are tan(20) * 10.
        let d = n.view_plane_offset(10.0, 50.0, 0.0, 100, 100);
        let expected = (20f32).to_radians().tan() * 10.0;
        // look_at's camera space is mirrored: +x in the image is the world's +x seen from +z.
        assert!(close(d, Vec3A::new(expected, 0.0, 0.0)), "{d:?}");
        let up = n.view_plane_offset(10.0, 0.0, -50.0, 100, 100);
        assert!(close(up, Vec3A::new(0.0, expected, 0.0)), "{up:?}");
    }
}

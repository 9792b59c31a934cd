//! Two-plane light fields captured by the engine itself (`rtsl lightfield capture`), for the
//! `twoplane` lightfield shader (`stdlib_shaders/lightfield/twoplane.sl`, `docs/lightfields.md`).
//!
//! The light slab: a square uv plane (the rectangle the light field is shown on; x and y from -1 to
//! 1 in its object space, z = 0) and a parallel st plane at z = -distance where a grid of cameras
//! stands. View (i, j) is the image of the uv square seen from camera (s_i, t_j), made by a camera
//! shader whose rays go from the camera's point through points of the uv square (an off-axis
//! projection), so every ray of the light field is a ray the engine traced.
//!
//! Invariant: the atlas layout here and the lookup in `twoplane.sl` agree: view (i, j) (i along s,
//! j along t from +1 down) is the tile at column i, row j; camera i stands at s = -1 + 2i/(n-1);
//! pixel x of a view looks at u = -1 + 2(x + 1/2)/size, row y at v = 1 - 2(y + 1/2)/size.

use crate::api::{ApiError, Context};
use crate::render::{render_frame, Antialiasing};
use crate::shading::ParamValue;
use glam::{Affine3A, Vec3A};

/// The camera shader of one view: rays from `from` through the raster position's point of the uv
/// square (`corner` is its top-left corner, `across` and `down` its edges; all in world space).
pub const CAPTURE_CAMERA: &str = r#"
camera lightfield_view(point from = 0; point corner = 0; vector across = 0; vector down = 0;
                       float size = 32;)
{
    point target = corner + across * (xcomp(P) / size) + down * (ycomp(P) / size);
    E = from;
    I = target - from;
    Ci = 1;
}
"#;

/// Where a light field is and how finely it is sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightfieldSpec {
    /// The centre of the uv square.
    pub center: Vec3A,
    /// Half the square's side along s/u (world units and direction).
    pub axis_s: Vec3A,
    /// Half the square's side along t/v (up in the views).
    pub axis_t: Vec3A,
    /// From the uv plane to the st plane, in units of the half side.
    pub distance: f32,
    /// Cameras along each side of the st square.
    pub views: u32,
    /// Pixels along each side of a view.
    pub view_size: u32,
    /// Samples per pixel of each view (a square grid of this side).
    pub samples: u32,
}

impl LightfieldSpec {
    /// A light field of the square with centre `center` and half side `half`, its cameras on the
    /// side `toward` points to (from the square towards the cameras), `up` up in the views.
    pub fn facing(center: Vec3A, half: f32, toward: Vec3A, up: Vec3A) -> LightfieldSpec {
        let back = toward.normalize_or(Vec3A::NEG_Z);
        // Seen from the cameras (looking along -back), s goes right and t up.
        let right = (-back).cross(up).normalize_or(Vec3A::X);
        let up = right.cross(-back);
        LightfieldSpec {
            center,
            axis_s: right * half,
            axis_t: up * half,
            distance: 2.0,
            views: 8,
            view_size: 32,
            samples: 2,
        }
    }

    /// Object to world for the rectangle that shows the light field: object x and y from -1 to 1
    /// span the square, object +z points away from the cameras (with the half side's length).
    pub fn world_from_object(&self) -> Affine3A {
        // (s, t, away) is a left-handed frame, like RenderMan's camera space: t x s points away.
        let away = self.axis_t.cross(self.axis_s).normalize_or(Vec3A::Z) * self.axis_s.length();
        Affine3A::from_cols(self.axis_s, self.axis_t, away, self.center)
    }

    /// The atlas's side in pixels (`views * view_size`, each at least its least), or why it is
    /// past the image limits ([`crate::render::check_image_size`]).
    pub fn atlas_side(&self) -> Result<u32, String> {
        let (n, size) = (self.views.max(2), self.view_size.max(1));
        let side = u64::from(n) * u64::from(size);
        let too_large = |e: String| format!("{n}x{n} views of {size}x{size} pixels: the atlas's {e}");
        crate::render::check_image_size(side, side).map_err(too_large)?;
        u32::try_from(side).map_err(|e| too_large(e.to_string()))
    }

    /// The world position of camera (i, j).
    pub fn camera(&self, i: u32, j: u32) -> Vec3A {
        let n = self.views.max(2) as f32;
        let s = -1.0 + 2.0 * i as f32 / (n - 1.0);
        let t = 1.0 - 2.0 * j as f32 / (n - 1.0);
        self.world_from_object().transform_point3a(Vec3A::new(s, t, -self.distance))
    }
}

/// The atlas: linear RGBA, premultiplied (as framebuffers are), `views * view_size` pixels square.
pub struct LightfieldAtlas {
    pub side: u32,
    pub rgba: Vec<f32>,
}

/// Renders every view of `spec` of the scene in `rt` (its camera shader and image options are
/// restored afterwards) with the current rayon pool; `progress` hears of each finished view.
pub fn capture(
    rt: &mut Context,
    spec: &LightfieldSpec,
    progress: &mut dyn FnMut(u32, u32),
) -> Result<LightfieldAtlas, ApiError> {
    // Refused before the atlas is allocated.
    let side = spec.atlas_side().map_err(ApiError::ImageSize)?;
    let camera = rt.compile_shader("lightfield_view", CAPTURE_CAMERA)?;
    let (saved_options, saved_camera, saved_matrix) = (rt.options.clone(), rt.camera_shader_id(), rt.current_matrix());
    let (n, size) = (spec.views.max(2), spec.view_size.max(1));
    let mut rgba = vec![0.0f32; 4 * side as usize * side as usize];
    rt.options.width = size;
    rt.options.height = size;
    let k = spec.samples.max(1);
    rt.options.samples = (k, k);
    rt.options.antialiasing = Antialiasing::Grid { jitter: true };
    // Parameters are world-space points: bind them under the identity.
    rt.load_identity();
    let corner = spec.center - spec.axis_s + spec.axis_t;
    let result = (|| {
        for j in 0..n {
            for i in 0..n {
                let from = spec.camera(i, j);
                rt.camera_shader(
                    Some(camera),
                    &[
                        ("from", ParamValue::Point(from.to_array())),
                        ("corner", ParamValue::Point(corner.to_array())),
                        ("across", ParamValue::Vector((spec.axis_s * 2.0).to_array())),
                        ("down", ParamValue::Vector((spec.axis_t * -2.0).to_array())),
                        ("size", ParamValue::Float(size as f32)),
                    ],
                )?;
                let world = rt.build_world()?;
                let (fb, _) = render_frame(&world, None);
                rt.return_scene(world);
                for y in 0..size {
                    let src = 4 * (y * size) as usize;
                    let dst = 4 * ((j * size + y) * side + i * size) as usize;
                    rgba[dst..dst + 4 * size as usize].copy_from_slice(&fb.rgba[src..src + 4 * size as usize]);
                }
                progress(j * n + i + 1, n * n);
            }
        }
        Ok(())
    })();
    rt.options = saved_options;
    rt.load_matrix(saved_matrix);
    match saved_camera {
        Some(id) => rt.camera_shader(Some(id), &[])?,
        None => rt.camera_shader(None, &[])?,
    }
    result.map(|()| LightfieldAtlas { side, rgba })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rectangle_and_the_cameras_agree_with_the_layout() {
        let spec = LightfieldSpec::facing(Vec3A::new(1.0, 2.0, 3.0), 0.5, Vec3A::NEG_Z, Vec3A::Y);
        let m = spec.world_from_object();
        // The square's corners and the side the cameras are on.
        // Seen from the cameras (on the -z side, looking along +z), right is -x.
        assert!((m.transform_point3a(Vec3A::new(1.0, 1.0, 0.0)) - Vec3A::new(0.5, 2.5, 3.0)).length() < 1e-6);
        assert!(m.transform_vector3a(Vec3A::Z).z > 0.0, "object +z points away from the cameras");
        let cam = spec.camera(0, 0);
        // Camera (0, 0) is at s = -1, t = +1 (left, top), two half sides towards the cameras' side.
        assert!((cam - Vec3A::new(1.5, 2.5, 2.0)).length() < 1e-6, "{cam}");
        let last = spec.camera(spec.views - 1, spec.views - 1);
        assert!((last - Vec3A::new(0.5, 1.5, 2.0)).length() < 1e-6, "{last}");
    }
}

//! The work items of a frame's shading: the frame itself (the world and what is worked out from
//! it once), a ray's finished sample, a hit waiting to be shaded, and what shading a hit produced.
//! The stages (`primary.rs`, `shade.rs`, `lights.rs`, `volume.rs`, `host.rs`, `trace_ahead.rs`)
//! pass these between them.

use super::differential::RayDifferential;
use super::stats::Stats;
use super::world::{InstanceShadows, World};
use crate::ray::{Hit, Ray};
use glam::{Affine3A, Vec3A};

/// The frame being rendered: the world and the counters.
pub struct Frame<'w> {
    pub world: &'w World,
    pub stats: Stats,
    pub(crate) transparent_shadows: bool,
    /// Per instance: what shadow rays do at its triangles (empty without `transparent_shadows`).
    /// A shadow ray's hit filter answers from these without finding the triangle's material.
    pub(crate) instance_shadows: Vec<InstanceShadows>,
    /// [`World::has_volumes`], asked once a frame rather than for every packet: it scans every
    /// material (thousands in an animation of many parts).
    pub(crate) volumes: bool,
    pub(crate) camera_from_world: Affine3A,
    /// The camera's forward axis and how an unnormalised camera ray's direction changes per pixel.
    pub(crate) forward: Vec3A,
    pub(crate) pixel_dx: Vec3A,
    pub(crate) pixel_dy: Vec3A,
    /// The angle one pixel spans (radians, small-angle), for the cones of secondary rays.
    pub(crate) pixel_spread: f32,
    /// Per light: the row of a lane-invariant ambient light, worked out by the first batch that
    /// asks (its value depends on the light's parameters alone, fixed for the frame).
    pub(crate) invariant_light_rows: Vec<std::sync::OnceLock<rtsl_compiler::back::jit::LightLanes>>,
}

impl<'w> Frame<'w> {
    pub fn new(world: &'w World) -> Frame<'w> {
        let cam = &world.camera;
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let tan = (cam.fov_degrees.to_radians() * 0.5).tan();
        let (ax, ay) = world.options.screen_extent().half;
        let m = &cam.world_from_camera.matrix3;
        let transparent_shadows = world.has_transparent_shadows();
        let instance_shadows = if transparent_shadows { world.instance_shadows() } else { Vec::new() };
        Frame {
            world,
            stats: Stats { timed: world.options.time_shaders, ..Stats::default() },
            transparent_shadows,
            instance_shadows,
            volumes: world.has_volumes(),
            camera_from_world: cam.world_from_camera.inverse(),
            forward: m.z_axis.normalize_or_zero(),
            pixel_dx: m.x_axis * (2.0 * tan * ax / w),
            pixel_dy: m.y_axis * (-2.0 * tan * ay / h),
            pixel_spread: 2.0 * tan * ay / h,
            invariant_light_rows: world.lights.iter().map(|_| std::sync::OnceLock::new()).collect(),
        }
    }
}

/// The colour seen along a ray and its coverage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    pub color: Vec3A,
    pub alpha: f32,
    /// Distance to the first surface (infinite on a miss).
    pub depth: f32,
    /// Object id of the first surface hit (`u32::MAX` on a miss), for pixel shaders and adaptive
    /// sampling.
    pub object_id: u32,
    /// Material (shader instance) of the first surface hit (`u32::MAX` on a miss).
    pub shader_id: u32,
}

pub(crate) struct Pending {
    pub(crate) index: usize,
    pub(crate) ray: Ray,
    pub(crate) diff: RayDifferential,
    pub(crate) hit: Hit,
}

/// What shading one hit produced.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Shaded {
    pub(crate) ci: Vec3A,
    pub(crate) oi: Vec3A,
    pub(crate) p: Vec3A,
    pub(crate) ng: Vec3A,
    /// Whether a surface's geometry was found for the hit: its footprint (dP/dx, dP/dy) then
    /// follows from the ray's differential and `ng`, computed only for the rays that go on
    /// through it (`shade_pending`).
    pub(crate) on_surface: bool,
}

pub(crate) fn finite_or_zero(v: Vec3A) -> Vec3A {
    if v.is_finite() {
        v
    } else {
        Vec3A::ZERO
    }
}

//! Primary rays: the built-in pinhole camera, or the bound camera shader run over a packet of camera
//! samples through the packet ABI (`docs/cameras.md` specifies the shader's globals).
//!
//! A camera sample is a raster position (pixel plus sub-pixel offset), a lens sample and a time. The
//! lens sample is shared by the whole packet (one per packet and pixel sample, well spread over the
//! samples of a pixel), so a thin-lens packet has one origin and stays coherent; the time sample is
//! per pixel. Ray differentials of shader-made rays come from the packet itself: lanes come in 2x2
//! raster quads, so the difference to the lane beside and the lane below, divided by their raster
//! distance, is the change per pixel (what a GPU does for derivatives). Lanes whose neighbours do
//! not form such a quad get a pinhole-like cone.
//!
//! Invariants: a ray with a zero, negative or non-finite weight, or a non-finite or zero direction,
//! is inactive (it contributes nothing to its pixel); every value here is a function of the sample,
//! never of the thread.

use super::differential::RayDifferential;
use super::host::ShadeCall;
use super::shade::{finite_or_zero, Frame};
use super::world::World;
use crate::ray::{Ray, RayPacket, PACKET_SIZE};
use crate::shading::{fill1, fill3, get_row, put_row, with_batch};
use glam::Vec3A;

/// Where on the image, lens and shutter a primary ray starts.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraSample {
    /// Raster position: pixel `(x, y)` plus a sub-pixel offset in [0, 1), y down.
    pub raster: (f32, f32),
    /// Lens sample in [0, 1)^2.
    pub lens: (f32, f32),
    /// Time within the shutter interval.
    pub time: f32,
}

/// The primary rays of a packet: the rays (inactive where the camera made no ray), their
/// differentials, and their weights (the colour a sample's radiance is multiplied by).
#[derive(Clone, Debug)]
pub struct PrimaryRays {
    pub packet: RayPacket,
    pub diffs: [RayDifferential; PACKET_SIZE],
    pub weights: [Vec3A; PACKET_SIZE],
}

impl Default for PrimaryRays {
    fn default() -> Self {
        PrimaryRays {
            packet: RayPacket::new(),
            diffs: [RayDifferential::default(); PACKET_SIZE],
            weights: [Vec3A::ONE; PACKET_SIZE],
        }
    }
}

/// RenderMan's screen space position of a raster position, x right and y up: by default the
/// shorter side of the image spans [-1, 1]; `ScreenWindow` chooses another window.
pub fn screen_position(world: &World, raster: (f32, f32)) -> (f32, f32) {
    ScreenWindow::of(world).position(raster)
}

/// [`screen_position`] with its per-image factors worked out once (the same arithmetic, so the same
/// bits).
struct ScreenWindow {
    w: f32,
    h: f32,
    ax: f32,
    ay: f32,
    cx: f32,
    cy: f32,
}

impl ScreenWindow {
    fn of(world: &World) -> ScreenWindow {
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let e = world.options.screen_extent();
        ScreenWindow { w, h, ax: e.half.0, ay: e.half.1, cx: e.centre.0, cy: e.centre.1 }
    }

    #[inline]
    fn position(&self, (x, y): (f32, f32)) -> (f32, f32) {
        ((2.0 * x / self.w - 1.0) * self.ax + self.cx, (1.0 - 2.0 * y / self.h) * self.ay + self.cy)
    }
}

/// The built-in pinhole camera's ray through a raster position.
pub fn pinhole_ray(world: &World, raster: (f32, f32)) -> Ray {
    Pinhole::of(world).ray(raster)
}

/// The built-in pinhole camera, worked out once per packet: a ray's unnormalised direction is
/// `forward + right * x + up * y` for raster position `(x, y)`.
struct Pinhole {
    eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
}

impl Pinhole {
    fn of(world: &World) -> Pinhole {
        let cam = &world.camera;
        let tan = (cam.fov_degrees.to_radians() * 0.5).tan();
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let e = world.options.screen_extent();
        let ((ax, ay), (cx, cy)) = (e.half, e.centre);
        let m = &cam.world_from_camera;
        // screen_position: sx = (2x/w - 1) ax + cx, sy = (1 - 2y/h) ay + cy; the direction adds sx,
        // sy times tan.
        let (kx, ky) = (2.0 * ax * tan / w, -2.0 * ay * tan / h);
        Pinhole {
            eye: m.translation,
            forward: m.matrix3.z_axis + m.matrix3.x_axis * ((cx - ax) * tan) + m.matrix3.y_axis * ((cy + ay) * tan),
            right: m.matrix3.x_axis * kx,
            up: m.matrix3.y_axis * ky,
        }
    }

    #[inline]
    fn ray(&self, (x, y): (f32, f32)) -> Ray {
        Ray::new(self.eye, (self.forward + self.right * x + self.up * y).normalize())
    }
}

/// The primary rays for `samples` (lane `i` from `samples[i]`, only lanes set in `active`).
pub fn primary_rays(frame: &Frame, samples: &[CameraSample; PACKET_SIZE], active: u64) -> PrimaryRays {
    let mut out = PrimaryRays::default();
    match &frame.world.camera_shader {
        None => {
            let pinhole = Pinhole::of(frame.world);
            for (i, s) in samples.iter().enumerate().filter(|(i, _)| active >> i & 1 != 0) {
                let mut ray = pinhole.ray(s.raster);
                ray.time = s.time;
                out.packet.set(i, &ray);
                out.diffs[i] = frame.pinhole_differential(ray.direction);
            }
        }
        Some(camera) => run_camera_shader(frame, camera, samples, active, &mut out),
    }
    out
}

fn run_camera_shader(
    frame: &Frame,
    camera: &crate::shading::ShaderInstance,
    samples: &[CameraSample; PACKET_SIZE],
    active: u64,
    out: &mut PrimaryRays,
) {
    let world = frame.world;
    let program = &camera.program;
    let slots = &program.slots;
    let (open, close) = world.options.shutter;
    let eye = world.camera.eye();
    let mut origins = [Vec3A::ZERO; PACKET_SIZE];
    // What E and I hold on entry (and keep when the shader does not write them).
    let pinhole = Pinhole::of(world);
    let mut dirs: [Vec3A; PACKET_SIZE] = std::array::from_fn(|i| pinhole.ray(samples[i].raster).direction);
    let mut valid = 0u64;
    {
        let _timer = super::stats::ShadingTimer::start(&frame.stats);
        with_batch(program, PACKET_SIZE, |batch| {
            // Every lane runs, those off the image too: their rays give their neighbours'
            // differentials (they are dropped below).
            {
                let mut raw = batch.raw_mut();
                camera.write_params(&mut raw);
                fill1(&mut raw, slots.dtime, close - open);
                fill1(&mut raw, slots.ncomps, 3.0);
                fill3(&mut raw, slots.e, eye);
                fill3(&mut raw, slots.ci, Vec3A::ONE);
                // Row by row (structure of arrays, as the batch holds them): the same values as
                // `put1`/`put3` lane by lane.
                let screen = ScreenWindow::of(world);
                // Generic, so each row's loop is compiled for its own values (no call per lane).
                fn put(
                    raw: &mut rtsl_compiler::back::jit::RawBatch<'_>,
                    slot: Option<crate::shading::Slot>,
                    comp: usize,
                    f: impl Fn(usize) -> f32,
                ) {
                    if slot.is_some() {
                        let row: [f32; PACKET_SIZE] = std::array::from_fn(f);
                        put_row(raw, slot, comp, &row);
                    }
                }
                put(&mut raw, slots.p, 0, |l| samples[l].raster.0);
                put(&mut raw, slots.p, 1, |l| samples[l].raster.1);
                put(&mut raw, slots.p, 2, |_| 0.0);
                put(&mut raw, slots.s, 0, |l| screen.position(samples[l].raster).0);
                put(&mut raw, slots.t, 0, |l| screen.position(samples[l].raster).1);
                put(&mut raw, slots.u, 0, |l| samples[l].lens.0);
                put(&mut raw, slots.v, 0, |l| samples[l].lens.1);
                put(&mut raw, slots.time, 0, |l| samples[l].time);
                put(&mut raw, slots.i, 0, |l| dirs[l].x);
                put(&mut raw, slots.i, 1, |l| dirs[l].y);
                put(&mut raw, slots.i, 2, |l| dirs[l].z);
            }
            let mut call = ShadeCall::new(frame, camera, world.camera.world_from_camera, 0);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            let mut rows = [[0.0f32; PACKET_SIZE]; 9];
            for k in 0..3 {
                get_row(&raw, slots.e, k, eye[k], &mut rows[k]);
                get_row(&raw, slots.ci, k, 1.0, &mut rows[6 + k]);
            }
            if slots.i.is_some() {
                for k in 0..3 {
                    get_row(&raw, slots.i, k, 0.0, &mut rows[3 + k]);
                }
            } else {
                for (lane, d) in dirs.iter().enumerate() {
                    (rows[3][lane], rows[4][lane], rows[5][lane]) = (d.x, d.y, d.z);
                }
            }
            let at = |r: usize, lane: usize| Vec3A::new(rows[r][lane], rows[r + 1][lane], rows[r + 2][lane]);
            for lane in 0..PACKET_SIZE {
                let o = at(0, lane);
                let d = at(3, lane);
                let w = at(6, lane);
                let len = d.length();
                origins[lane] = o;
                if o.is_finite() && len.is_finite() && len > 0.0 {
                    dirs[lane] = d / len;
                    if w.is_finite() && w.max_element() > 0.0 {
                        out.weights[lane] = w.max(Vec3A::ZERO);
                        valid |= 1 << lane;
                    }
                }
            }
        });
    }
    for (lane, s) in samples.iter().enumerate() {
        if (active & valid) >> lane & 1 == 0 {
            continue;
        }
        let mut ray = Ray::new(origins[lane], dirs[lane]);
        ray.time = s.time;
        out.packet.set(lane, &ray);
        let neighbour = |other: usize| {
            let (dx, dy) = (samples[other].raster.0 - s.raster.0, samples[other].raster.1 - s.raster.1);
            (valid >> other & 1 != 0).then_some((dx, dy, other))
        };
        // Lane ^ 1 is the quad's horizontal neighbour, lane ^ 2 its vertical one.
        let along_x = neighbour(lane ^ 1).filter(|(dx, dy, _)| dx.abs() >= 0.25 && dy.abs() <= 0.5 * dx.abs());
        let along_y = neighbour(lane ^ 2).filter(|(dx, dy, _)| dy.abs() >= 0.25 && dx.abs() <= 0.5 * dy.abs());
        out.diffs[lane] = match (along_x, along_y) {
            (Some((dx, _, nx)), Some((_, dy, ny))) => RayDifferential {
                dodx: finite_or_zero((origins[nx] - origins[lane]) / dx),
                dody: finite_or_zero((origins[ny] - origins[lane]) / dy),
                dddx: finite_or_zero((dirs[nx] - dirs[lane]) / dx),
                dddy: finite_or_zero((dirs[ny] - dirs[lane]) / dy),
            },
            _ => RayDifferential::cone(dirs[lane], 0.0, frame.pixel_spread),
        };
    }
}

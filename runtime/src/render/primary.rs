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
use super::shade::Frame;
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
    primary_rays_into(frame, samples, active, &mut out);
    out
}

/// [`primary_rays`] into `out`, which loops over packets reuse (a packet's rays are several
/// kilobytes: making a fresh one per packet was a measurable share of making the rays). Lanes
/// that make no ray keep whatever `out` held; only active lanes are defined.
pub fn primary_rays_into(frame: &Frame, samples: &[CameraSample; PACKET_SIZE], active: u64, out: &mut PrimaryRays) {
    match &frame.world.camera_shader {
        None => pinhole_rays(frame, samples, active, out),
        Some(camera) => run_camera_shader(frame, camera, samples, active, out),
    }
}

/// One value per lane of a packet.
type Row = [f32; PACKET_SIZE];

/// Three rows: a vector per lane.
type Rows3 = [Row; 3];

/// The built-in pinhole camera's rays, by rows (the arithmetic of [`Pinhole::ray`] and
/// the camera's ray differentials, as vector code over the packet).
fn pinhole_rays(frame: &Frame, samples: &[CameraSample; PACKET_SIZE], active: u64, out: &mut PrimaryRays) {
    let pinhole = Pinhole::of(frame.world);
    let rx: Row = std::array::from_fn(|l| samples[l].raster.0);
    let ry: Row = std::array::from_fn(|l| samples[l].raster.1);
    let packet = &mut out.packet;
    pinhole_directions(&pinhole, &rx, &ry, [&mut packet.dx.0, &mut packet.dy.0, &mut packet.dz.0]);
    let dir = [packet.dx.0, packet.dy.0, packet.dz.0];
    let origin = pinhole.eye.to_array();
    for (k, o) in [&mut packet.ox, &mut packet.oy, &mut packet.oz].into_iter().enumerate() {
        o.0 = [origin[k]; PACKET_SIZE];
    }
    packet.tmin.0 = [0.0; PACKET_SIZE];
    packet.tmax.0 = [f32::INFINITY; PACKET_SIZE];
    packet.time.0 = std::array::from_fn(|l| samples[l].time);
    packet.active = active;
    out.weights = [Vec3A::ONE; PACKET_SIZE];
    // The differentials: the unnormalised direction has a forward component of 1.
    let fw = frame.forward.to_array();
    let mut d = dir;
    for l in 0..PACKET_SIZE {
        let along = dir[0][l] * fw[0] + dir[1][l] * fw[1] + dir[2][l] * fw[2];
        let scale = if along > 1e-6 { 1.0 / along } else { 1.0 };
        for row in d.iter_mut() {
            row[l] *= scale;
        }
    }
    let (ddx, ddy) = camera_derivatives(&d, frame.pixel_dx, frame.pixel_dy);
    for l in (0..PACKET_SIZE).filter(|l| active >> l & 1 != 0) {
        out.diffs[l] = RayDifferential {
            dodx: Vec3A::ZERO,
            dody: Vec3A::ZERO,
            dddx: Vec3A::new(ddx[0][l], ddx[1][l], ddx[2][l]),
            dddy: Vec3A::new(ddy[0][l], ddy[1][l], ddy[2][l]),
        };
    }
}

/// [`RayDifferential::from_camera`] by rows: the change per pixel of the unit direction `d / |d|`
/// when the unnormalised direction `d` changes by `dd_dx` and `dd_dy` (zero where `d` is zero).
// Lane-indexed loops over several rows at once are the point here (they compile to vector code).
#[allow(clippy::needless_range_loop)]
fn camera_derivatives(d: &Rows3, dd_dx: Vec3A, dd_dy: Vec3A) -> (Rows3, Rows3) {
    let (vx, vy) = (dd_dx.to_array(), dd_dy.to_array());
    let mut out = ([[0.0f32; PACKET_SIZE]; 3], [[0.0f32; PACKET_SIZE]; 3]);
    for l in 0..PACKET_SIZE {
        let len = (d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l]).sqrt();
        let inv = if len > 0.0 { 1.0 / len } else { 0.0 };
        let n = [d[0][l] * inv, d[1][l] * inv, d[2][l] * inv];
        let (nx, ny) = (n[0] * vx[0] + n[1] * vx[1] + n[2] * vx[2], n[0] * vy[0] + n[1] * vy[1] + n[2] * vy[2]);
        for k in 0..3 {
            out.0[k][l] = (vx[k] - n[k] * nx) * inv;
            out.1[k][l] = (vy[k] - n[k] * ny) * inv;
        }
    }
    out
}

/// Runs the camera shader over the packet. The renderer's side works row by row (structure of
/// arrays, as the batch and the ray packet hold them) so that its loops compile to vector code:
/// per packet it is as much work as the shader itself for a simple camera.
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
    let rx: Row = std::array::from_fn(|l| samples[l].raster.0);
    let ry: Row = std::array::from_fn(|l| samples[l].raster.1);
    // I on entry: the built-in pinhole ray's direction, made in the packet's direction rows (the
    // shader's I replaces it there after the call).
    let packet = &mut out.packet;
    pinhole_directions(&Pinhole::of(world), &rx, &ry, [&mut packet.dx.0, &mut packet.dy.0, &mut packet.dz.0]);
    // The shader's weight, Ci.
    let mut w = [[1.0f32; PACKET_SIZE]; 3];
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
                put_row(&mut raw, slots.p, 0, &rx);
                put_row(&mut raw, slots.p, 1, &ry);
                put_row(&mut raw, slots.p, 2, &[0.0; PACKET_SIZE]);
                if slots.s.is_some() || slots.t.is_some() {
                    let screen = ScreenWindow::of(world);
                    let (mut sx, mut sy) = ([0.0f32; PACKET_SIZE], [0.0f32; PACKET_SIZE]);
                    for l in 0..PACKET_SIZE {
                        (sx[l], sy[l]) = screen.position((rx[l], ry[l]));
                    }
                    put_row(&mut raw, slots.s, 0, &sx);
                    put_row(&mut raw, slots.t, 0, &sy);
                }
                if slots.u.is_some() || slots.v.is_some() || slots.time.is_some() {
                    let row = |f: fn(&CameraSample) -> f32| -> Row { std::array::from_fn(|l| f(&samples[l])) };
                    put_row(&mut raw, slots.u, 0, &row(|s| s.lens.0));
                    put_row(&mut raw, slots.v, 0, &row(|s| s.lens.1));
                    put_row(&mut raw, slots.time, 0, &row(|s| s.time));
                }
                for (k, row) in [&packet.dx, &packet.dy, &packet.dz].into_iter().enumerate() {
                    put_row(&mut raw, slots.i, k, &row.0);
                }
            }
            let mut call = ShadeCall::new(frame, camera, world.camera.world_from_camera, 0);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for (k, row) in [&mut packet.ox, &mut packet.oy, &mut packet.oz].into_iter().enumerate() {
                get_row(&raw, slots.e, k, eye[k], &mut row.0);
            }
            if slots.i.is_some() {
                for (k, row) in [&mut packet.dx, &mut packet.dy, &mut packet.dz].into_iter().enumerate() {
                    get_row(&raw, slots.i, k, 0.0, &mut row.0);
                }
            }
            for (k, row) in w.iter_mut().enumerate() {
                get_row(&raw, slots.ci, k, 1.0, row);
            }
        });
    }
    let (ox, oy, oz) = (&mut packet.ox.0, &mut packet.oy.0, &mut packet.oz.0);
    let (dx, dy, dz) = (&mut packet.dx.0, &mut packet.dy.0, &mut packet.dz.0);
    let [wr, wg, wb] = &w;
    // A lane makes a ray when its origin is finite, its direction finite and not zero, and its
    // weight finite with a positive component; the others are zeroed.
    let mut ok = [false; PACKET_SIZE];
    for l in 0..PACKET_SIZE {
        let len = (dx[l] * dx[l] + dy[l] * dy[l] + dz[l] * dz[l]).sqrt();
        let finite = ox[l].is_finite()
            & oy[l].is_finite()
            & oz[l].is_finite()
            & len.is_finite()
            & wr[l].is_finite()
            & wg[l].is_finite()
            & wb[l].is_finite();
        ok[l] = finite & (len > 0.0) & (wr[l].max(wg[l]).max(wb[l]) > 0.0);
        let inv = 1.0 / len;
        (dx[l], dy[l], dz[l]) = if ok[l] { (dx[l] * inv, dy[l] * inv, dz[l] * inv) } else { (0.0, 0.0, 0.0) };
        (ox[l], oy[l], oz[l]) = if ok[l] { (ox[l], oy[l], oz[l]) } else { (0.0, 0.0, 0.0) };
    }
    let valid = ok.iter().enumerate().fold(0u64, |m, (l, &v)| m | (u64::from(v) << l));
    packet.tmin.0 = [0.0; PACKET_SIZE];
    packet.tmax.0 = [f32::INFINITY; PACKET_SIZE];
    packet.time.0 = std::array::from_fn(|l| samples[l].time);
    packet.active = active & valid;
    for l in (0..PACKET_SIZE).filter(|l| ok[*l]) {
        out.weights[l] = Vec3A::new(wr[l], wg[l], wb[l]).max(Vec3A::ZERO);
    }
    // Differentials from the 2x2 quads: lane ^ 1 is a lane's horizontal neighbour, lane ^ 2 its
    // vertical one; a neighbour counts when it made a ray and lies about one step along its axis.
    let o = [&*ox, &*oy, &*oz];
    let d = [&*dx, &*dy, &*dz];
    let neighbour = |flip: usize, across: bool| -> (Row, [bool; PACKET_SIZE]) {
        let mut step = [0.0f32; PACKET_SIZE];
        let mut usable = [false; PACKET_SIZE];
        for l in 0..PACKET_SIZE {
            let (ex, ey) = (rx[l ^ flip] - rx[l], ry[l ^ flip] - ry[l]);
            let (along, other) = if across { (ey, ex) } else { (ex, ey) };
            step[l] = along;
            usable[l] = ok[l ^ flip] & (along.abs() >= 0.25) & (other.abs() <= 0.5 * along.abs());
        }
        (step, usable)
    };
    // (v[neighbour] - v[lane]) / step, zero where a component is not finite.
    let change = |v: &[&Row; 3], flip: usize, step: &Row| -> Rows3 {
        let mut c = [[0.0f32; PACKET_SIZE]; 3];
        for l in 0..PACKET_SIZE {
            let inv = 1.0 / step[l];
            let x = (v[0][l ^ flip] - v[0][l]) * inv;
            let y = (v[1][l ^ flip] - v[1][l]) * inv;
            let z = (v[2][l ^ flip] - v[2][l]) * inv;
            let finite = x.is_finite() & y.is_finite() & z.is_finite();
            (c[0][l], c[1][l], c[2][l]) = if finite { (x, y, z) } else { (0.0, 0.0, 0.0) };
        }
        c
    };
    let (sx, ux) = neighbour(1, false);
    let (sy, uy) = neighbour(2, true);
    let (dodx, dody, dddx, dddy) = (change(&o, 1, &sx), change(&o, 2, &sy), change(&d, 1, &sx), change(&d, 2, &sy));
    let at = |v: &Rows3, l: usize| Vec3A::new(v[0][l], v[1][l], v[2][l]);
    for l in (0..PACKET_SIZE).filter(|l| packet.active >> l & 1 != 0) {
        out.diffs[l] = if ux[l] && uy[l] {
            RayDifferential { dodx: at(&dodx, l), dody: at(&dody, l), dddx: at(&dddx, l), dddy: at(&dddy, l) }
        } else {
            RayDifferential::cone(Vec3A::new(d[0][l], d[1][l], d[2][l]), 0.0, frame.pixel_spread)
        };
    }
}

/// The built-in pinhole camera's unit directions through raster positions `(rx, ry)`, as rows
/// (the arithmetic of [`Pinhole::ray`]).
fn pinhole_directions(pinhole: &Pinhole, rx: &Row, ry: &Row, [x, y, z]: [&mut Row; 3]) {
    let (f, r, u) = (pinhole.forward.to_array(), pinhole.right.to_array(), pinhole.up.to_array());
    for (k, row) in [&mut *x, &mut *y, &mut *z].into_iter().enumerate() {
        for l in 0..PACKET_SIZE {
            row[l] = f[k] + r[k] * rx[l] + u[k] * ry[l];
        }
    }
    for l in 0..PACKET_SIZE {
        let inv = 1.0 / (x[l] * x[l] + y[l] * y[l] + z[l] * z[l]).sqrt();
        (x[l], y[l], z[l]) = (x[l] * inv, y[l] * inv, z[l] * inv);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row-by-row derivatives are [`RayDifferential::from_camera`]'s, to rounding.
    #[test]
    fn camera_derivatives_by_rows_match_the_scalar_formula() {
        let (vx, vy) = (Vec3A::new(0.002, 0.0, 0.0003), Vec3A::new(0.0, -0.002, 0.0001));
        let mut d = [[0.0f32; PACKET_SIZE]; 3];
        #[allow(clippy::needless_range_loop)]
        for l in 0..PACKET_SIZE {
            let a = l as f32 / PACKET_SIZE as f32;
            (d[0][l], d[1][l], d[2][l]) = (a - 0.5, 0.3 - a * a, if l == 7 { 0.0 } else { 1.0 + a });
        }
        // One zero direction: no change.
        (d[0][9], d[1][9], d[2][9]) = (0.0, 0.0, 0.0);
        let (ddx, ddy) = camera_derivatives(&d, vx, vy);
        for l in 0..PACKET_SIZE {
            let want = RayDifferential::from_camera(Vec3A::new(d[0][l], d[1][l], d[2][l]), vx, vy);
            let got = (Vec3A::new(ddx[0][l], ddx[1][l], ddx[2][l]), Vec3A::new(ddy[0][l], ddy[1][l], ddy[2][l]));
            assert!((got.0 - want.dddx).length() <= 1e-6 * want.dddx.length().max(1e-3), "lane {l}: {got:?} {want:?}");
            assert!((got.1 - want.dddy).length() <= 1e-6 * want.dddy.length().max(1e-3), "lane {l}: {got:?} {want:?}");
        }
    }
}

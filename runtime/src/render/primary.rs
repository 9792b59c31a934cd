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

use super::differential::{DifferentialRows, LaneRows3, RayDifferential};
use super::host::ShadeCall;
use super::ray_budget::RayBudget;
use super::work::Frame;
use super::world::World;
use crate::ray::{Ray, RayPacket, PACKET_SIZE};
use crate::shading::{fill1, fill3, put_row_at, varying_rows, with_filled_batch, Slot};
use glam::{BVec4A, Vec3A, Vec4, Vec4Swizzles};
use rtsl_compiler::abi::RawBatch;

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
/// differentials, and their weights (the colour a sample's radiance is multiplied by), all by rows
/// like the packet itself.
#[derive(Clone, Debug)]
pub struct PrimaryRays {
    pub packet: RayPacket,
    pub diffs: DifferentialRows,
    pub weights: LaneRows3,
    /// Each lane's pixel, `y * width + x` (`u32::MAX` off the image): the pixel whose ray
    /// parameters the lane's tree of rays reads (`ray_params.rs`).
    pub pixels: [u32; PACKET_SIZE],
}

impl Default for PrimaryRays {
    fn default() -> Self {
        PrimaryRays {
            packet: RayPacket::new(),
            diffs: DifferentialRows::default(),
            weights: [[1.0; PACKET_SIZE]; 3],
            pixels: [u32::MAX; PACKET_SIZE],
        }
    }
}

/// Notes the pixel of each of a packet's samples in `out`.
fn note_pixels(frame: &Frame, samples: &[CameraSample; PACKET_SIZE], out: &mut PrimaryRays) {
    let (w, h) = (frame.world.options.width, frame.world.options.height);
    for (p, s) in out.pixels.iter_mut().zip(samples) {
        let (x, y) = (s.raster.0.floor(), s.raster.1.floor());
        *p = if x >= 0.0 && y >= 0.0 && (x as u32) < w && (y as u32) < h {
            (y as u32).saturating_mul(w).saturating_add(x as u32)
        } else {
            u32::MAX
        };
    }
}

impl PrimaryRays {
    /// Lane `l`'s weight.
    pub fn weight(&self, l: usize) -> Vec3A {
        Vec3A::new(self.weights[0][l], self.weights[1][l], self.weights[2][l])
    }
}

/// RenderMan's screen space position of a raster position, x right and y up: by default the
/// shorter side of the image spans [-1, 1]; `ScreenWindow` chooses another window.
pub fn screen_position(world: &World, raster: (f32, f32)) -> (f32, f32) {
    ScreenWindow::of(world).position(raster)
}

/// [`screen_position`] with its per-image factors worked out once (`kx`, `ky`: 2 over the width and
/// the height, so that a position costs no division).
struct ScreenWindow {
    kx: f32,
    ky: f32,
    ax: f32,
    ay: f32,
    cx: f32,
    cy: f32,
}

impl ScreenWindow {
    fn of(world: &World) -> ScreenWindow {
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let e = world.options.screen_extent();
        ScreenWindow { kx: 2.0 / w, ky: 2.0 / h, ax: e.half.0, ay: e.half.1, cx: e.centre.0, cy: e.centre.1 }
    }

    #[inline]
    fn position(&self, (x, y): (f32, f32)) -> (f32, f32) {
        ((x * self.kx - 1.0) * self.ax + self.cx, (1.0 - y * self.ky) * self.ay + self.cy)
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
/// kilobytes: making a fresh one per packet was a measurable share of making the rays). Only the
/// active lanes are defined: the others hold whatever `out` held or the camera left.
pub fn primary_rays_into(frame: &Frame, samples: &[CameraSample; PACKET_SIZE], active: u64, out: &mut PrimaryRays) {
    note_pixels(frame, samples, out);
    match &frame.world.camera_shader {
        None => pinhole_rays(frame, samples, active, out),
        Some(camera) => {
            let packet = PacketSamples::new(*samples, active);
            run_camera_shader(frame, camera, std::slice::from_ref(&packet), std::slice::from_mut(out));
        }
    }
}

/// One value per lane of a packet.
type Row = [f32; PACKET_SIZE];

/// Three rows: a vector per lane.
type Rows3 = LaneRows3;

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
    out.weights = [[1.0; PACKET_SIZE]; 3];
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
    let diffs = &mut out.diffs;
    camera_derivatives(&d, frame.pixel_dx, frame.pixel_dy, &mut diffs.dddx, &mut diffs.dddy);
    diffs.fixed_origin();
}

/// [`RayDifferential::from_camera`] by rows: the change per pixel of the unit direction `d / |d|`
/// when the unnormalised direction `d` changes by `dd_dx` and `dd_dy` (zero where `d` is zero),
/// into `ddx` and `ddy`.
// Lane-indexed loops over several rows at once are the point here (they compile to vector code).
#[allow(clippy::needless_range_loop)]
fn camera_derivatives(d: &Rows3, dd_dx: Vec3A, dd_dy: Vec3A, ddx: &mut Rows3, ddy: &mut Rows3) {
    let (vx, vy) = (dd_dx.to_array(), dd_dy.to_array());
    for l in 0..PACKET_SIZE {
        let len = (d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l]).sqrt();
        let inv = if len > 0.0 { 1.0 / len } else { 0.0 };
        let n = [d[0][l] * inv, d[1][l] * inv, d[2][l] * inv];
        let (nx, ny) = (n[0] * vx[0] + n[1] * vx[1] + n[2] * vx[2], n[0] * vy[0] + n[1] * vy[1] + n[2] * vy[2]);
        for k in 0..3 {
            ddx[k][l] = (vx[k] - n[k] * nx) * inv;
            ddy[k][l] = (vy[k] - n[k] * ny) * inv;
        }
    }
}

/// The camera samples of one packet and the lanes to make rays for.
#[derive(Clone, Copy, Debug)]
pub struct PacketSamples {
    pub samples: [CameraSample; PACKET_SIZE],
    pub active: u64,
    /// The lens sample of every lane, when all share one (a frame's packets do); `None` when
    /// they may differ. A camera shader that reads the lens sample runs once for a run of
    /// packets that share one, and once per distinct lens sample for a packet whose lanes
    /// differ. [`PacketSamples::new`] works it out; a frame knows it without looking.
    pub shared_lens: Option<(f32, f32)>,
    /// The samples lie on the pixel grid with one sub-pixel offset for all (a frame's packets
    /// without jitter): each 2x2 quad of lanes is one pixel apart along x and along y, so the
    /// differentials need no steps worked out from the raster positions. `false` says nothing.
    pub unit_steps: bool,
}

impl Default for PacketSamples {
    fn default() -> Self {
        PacketSamples::new([CameraSample::default(); PACKET_SIZE], 0)
    }
}

impl PacketSamples {
    /// A packet's samples, with [`PacketSamples::shared_lens`] worked out from them.
    pub fn new(samples: [CameraSample; PACKET_SIZE], active: u64) -> PacketSamples {
        let lens = samples[0].lens;
        let shared = samples.iter().fold(true, |all, s| all & same_lens(s.lens, lens));
        PacketSamples { samples, active, shared_lens: shared.then_some(lens), unit_steps: false }
    }
}

/// Whether two lens samples are the same (bit for bit, so that a NaN matches itself).
fn same_lens(a: (f32, f32), b: (f32, f32)) -> bool {
    a.0.to_bits() == b.0.to_bits() && a.1.to_bits() == b.1.to_bits()
}

/// The primary rays of several packets, `out[p]` from `packets[p]` (the shorter of the two counts):
/// a camera shader makes them in one call, so that its per-call costs (the batch, the timers, the
/// shader's uniform prologue: `option()` queries, the camera space matrix) are paid once for
/// all of them. A frame passes the packets of a tile.
pub fn primary_rays_of_packets(frame: &Frame, packets: &[PacketSamples], out: &mut [PrimaryRays]) {
    for (p, o) in packets.iter().zip(out.iter_mut()) {
        note_pixels(frame, &p.samples, o);
    }
    match &frame.world.camera_shader {
        None => {
            for (p, o) in packets.iter().zip(out.iter_mut()) {
                pinhole_rays(frame, &p.samples, p.active, o);
            }
        }
        Some(camera) => {
            let n = packets.len().min(out.len());
            for (ps, os) in packets[..n].chunks(MAX_PACKETS_PER_CALL).zip(out[..n].chunks_mut(MAX_PACKETS_PER_CALL)) {
                run_camera_shader(frame, camera, ps, os);
            }
        }
    }
}

/// The most packets one camera shader call makes (its batch holds `PACKET_SIZE` lanes for each).
const MAX_PACKETS_PER_CALL: usize = 16;

/// The raster positions of a packet's samples, as rows.
fn raster_rows(samples: &[CameraSample; PACKET_SIZE]) -> (Row, Row) {
    (std::array::from_fn(|l| samples[l].raster.0), std::array::from_fn(|l| samples[l].raster.1))
}

/// Runs the camera shader over packets (at most [`MAX_PACKETS_PER_CALL`]), packet `p` in lanes
/// `p * PACKET_SIZE ..` of a batch, and finishes their rays. The renderer's side works row by row
/// (structure of arrays, as the batch and the ray packet hold them) so that its loops compile to
/// vector code: per packet it is as much work as the shader itself for a simple camera.
///
/// The lens sample (`u`, `v`) is uniform in camera shaders: one call covers a run of packets
/// that share a lens sample (a frame gives a tile's packets one). A packet whose lanes have
/// different lens samples takes a call per lens sample, each keeping its own lanes.
fn run_camera_shader(
    frame: &Frame,
    camera: &crate::shading::ShaderInstance,
    packets: &[PacketSamples],
    out: &mut [PrimaryRays],
) {
    let n = packets.len().min(out.len()).min(MAX_PACKETS_PER_CALL);
    let (packets, out) = (&packets[..n], &mut out[..n]);
    let slots = &camera.program.slots;
    let reads_lens = [slots.u, slots.v].iter().flatten().any(|s| !s.varying);
    if !reads_lens {
        return camera_call(frame, camera, packets, None, out, None);
    }
    let lanes_with = |ps: &PacketSamples, lens: (f32, f32)| -> u64 {
        ps.samples.iter().enumerate().fold(0, |m, (l, s)| m | u64::from(same_lens(s.lens, lens)) << l)
    };
    let mut start = 0;
    while start < n {
        if let Some(lens) = packets[start].shared_lens {
            let mut end = start + 1;
            while end < n && packets[end].shared_lens.is_some_and(|l| same_lens(l, lens)) {
                end += 1;
            }
            camera_call(frame, camera, &packets[start..end], Some(lens), &mut out[start..end], None);
            start = end;
            continue;
        }
        // Lanes with different lens samples (an application's own samples): a call for each lens
        // sample, which keeps the lanes that have it; the rays are finished once all are made.
        let (ps, o) = (std::slice::from_ref(&packets[start]), std::slice::from_mut(&mut out[start]));
        let mut weights: Rows3 = [[1.0; PACKET_SIZE]; 3];
        let mut done = 0u64;
        while done != u64::MAX {
            let lens = ps[0].samples[(!done).trailing_zeros() as usize].lens;
            let lanes = lanes_with(&ps[0], lens);
            camera_call(frame, camera, ps, Some(lens), o, Some((lanes, &mut weights)));
            done |= lanes;
        }
        let packet = &o[0].packet;
        let (origin, dir) = ([packet.ox.0, packet.oy.0, packet.oz.0], [packet.dx.0, packet.dy.0, packet.dz.0]);
        let made = MadeRays { origin: origin.each_ref(), dir: dir.each_ref(), weight: weights.each_ref() };
        finish_shader_rays(frame, &ps[0], &raster_rows(&ps[0].samples), &made, &mut o[0]);
        start += 1;
    }
}

/// One call of the camera shader over `packets`. `lens`: the lens sample shared by the call (when
/// the shader reads it). Without `unfinished` each packet's rays are finished at once; with it
/// (one packet: the lanes to keep and their weights) the kept lanes' origins and directions go to
/// the packet's rows and their weights to the given rows, the other lanes keep what they held,
/// and the caller finishes the rays.
fn camera_call(
    frame: &Frame,
    camera: &crate::shading::ShaderInstance,
    packets: &[PacketSamples],
    lens: Option<(f32, f32)>,
    out: &mut [PrimaryRays],
    mut unfinished: Option<(u64, &mut Rows3)>,
) {
    let n = packets.len();
    let world = frame.world;
    let program = &camera.program;
    let slots = &program.slots;
    let (open, close) = world.options.shutter;
    let eye = world.camera.eye();
    // I on entry is the built-in pinhole ray's direction; a shader without I makes those rays.
    // Globals the shader assigns before it could read them are not filled (the cameras of the
    // library assign E, I and Ci first thing).
    let needed = |slot: Option<Slot>| slot.is_some_and(|s| !s.entry_unused);
    let pinhole = (needed(slots.i) || slots.i.is_none()).then(|| Pinhole::of(world));
    // Each packet's raster positions as rows, gathered once for the fills and the finish (only
    // the call's packets: a frame's calls have a tile's few, and zeroing rows for the most a call
    // may have was a measurable part of a call).
    let rasters: Vec<(Row, Row)> = packets.iter().map(|ps| raster_rows(&ps.samples)).collect();
    // Every lane of these globals is written below, or by the shader before it reads them (the
    // ones not filled here are `entry_unused`): the batch need not zero them first.
    let filled = varying_rows([
        (slots.p, 3),
        (slots.s, 1),
        (slots.t, 1),
        (slots.u, 1),
        (slots.v, 1),
        (slots.time, 1),
        (slots.dtime, 1),
        (slots.ncomps, 1),
        (slots.i, 3),
        (slots.e, 3),
        (slots.ci, 3),
    ]);
    let screen = ScreenWindow::of(world);
    let timer = super::stats::ShadingTimer::start(&frame.stats);
    with_filled_batch(program, n * PACKET_SIZE, &filled, |batch| {
        // Every lane runs, those off the image too: their rays give their neighbours'
        // differentials (they are dropped after the call).
        {
            let mut raw = batch.raw_mut();
            camera.write_params(&mut raw);
            fill1(&mut raw, slots.dtime, close - open);
            fill1(&mut raw, slots.ncomps, 3.0);
            if needed(slots.e) {
                fill3(&mut raw, slots.e, eye);
            }
            if needed(slots.ci) {
                fill3(&mut raw, slots.ci, Vec3A::ONE);
            }
            if let Some((lu, lv)) = lens {
                fill1(&mut raw, slots.u, lu);
                fill1(&mut raw, slots.v, lv);
            }
            fill1(&mut raw, slots.p.map(|s| Slot { offset: s.offset + 2, ..s }), 0.0);
            for (p, ps) in packets.iter().enumerate() {
                let first = p * PACKET_SIZE;
                let (rx, ry) = &rasters[p];
                put_row_at(&mut raw, slots.p, 0, first, rx);
                put_row_at(&mut raw, slots.p, 1, first, ry);
                if slots.s.is_some() || slots.t.is_some() {
                    let (mut sx, mut sy) = ([0.0f32; PACKET_SIZE], [0.0f32; PACKET_SIZE]);
                    for l in 0..PACKET_SIZE {
                        (sx[l], sy[l]) = screen.position((rx[l], ry[l]));
                    }
                    put_row_at(&mut raw, slots.s, 0, first, &sx);
                    put_row_at(&mut raw, slots.t, 0, first, &sy);
                }
                let row = |f: fn(&CameraSample) -> f32| -> Row { std::array::from_fn(|l| f(&ps.samples[l])) };
                if lens.is_none() && (slots.u.is_some() || slots.v.is_some()) {
                    put_row_at(&mut raw, slots.u, 0, first, &row(|s| s.lens.0));
                    put_row_at(&mut raw, slots.v, 0, first, &row(|s| s.lens.1));
                }
                if slots.time.is_some() {
                    put_row_at(&mut raw, slots.time, 0, first, &row(|s| s.time));
                }
                if let (Some(pinhole), true) = (&pinhole, needed(slots.i)) {
                    let [mut x, mut y, mut z] = [[0.0f32; PACKET_SIZE]; 3];
                    pinhole_directions(pinhole, rx, ry, [&mut x, &mut y, &mut z]);
                    for (k, row) in [x, y, z].iter().enumerate() {
                        put_row_at(&mut raw, slots.i, k, first, row);
                    }
                }
            }
        }
        // Each lane a camera sample: the rays the camera shader spawns are a tree of their own.
        let mut budgets: Vec<RayBudget> = out.iter().flat_map(|o| o.pixels.map(RayBudget::from_pixel)).collect();
        budgets.resize(n * PACKET_SIZE, RayBudget::FULL);
        let mut call = ShadeCall::new(frame, camera, world.camera.world_from_camera, 0, &mut budgets);
        let table = call.table();
        program.code.shade_with_table(batch, &table);
        // The rays are read straight from the batch (the renderer's side of the call, so within
        // the shading timers), without copying them out first.
        let raw = batch.raw_mut();
        // Where the rays' parts are: the batch's rows for a varying global, else rows holding its
        // uniform value (or the default), filled once for the call's packets.
        let origins = MadeRows::of(&raw, slots.e, eye.to_array());
        let weights = MadeRows::of(&raw, slots.ci, [1.0; 3]);
        // A shader without `I` makes the pinhole's rays.
        let dirs = match (slots.i, &pinhole) {
            (None, Some(pinhole)) => Err(pinhole),
            _ => Ok(MadeRows::of(&raw, slots.i, [0.0; 3])),
        };
        let mut pinhole_rows = [[0.0f32; PACKET_SIZE]; 3];
        for (p, (ps, o)) in packets.iter().zip(out.iter_mut()).enumerate() {
            let first = p * PACKET_SIZE;
            let dir = match &dirs {
                Ok(dirs) => dirs.rows(raw.varying, first),
                Err(pinhole) => {
                    let [x, y, z] = &mut pinhole_rows;
                    pinhole_directions(pinhole, &rasters[p].0, &rasters[p].1, [x, y, z]);
                    pinhole_rows.each_ref()
                }
            };
            let made =
                MadeRays { origin: origins.rows(raw.varying, first), dir, weight: weights.rows(raw.varying, first) };
            match unfinished.as_mut() {
                None => finish_shader_rays(frame, ps, &rasters[p], &made, o),
                Some((keep, weights)) => made.keep(*keep, &mut o.packet, weights),
            }
        }
    });
    drop(timer);
}

/// A packet's rays as the camera shader made them: origins (`E`), directions (`I`) and weights
/// (`Ci`), by component, each a row of the packet's lanes (read where the shader left them).
struct MadeRays<'a> {
    origin: [&'a Row; 3],
    dir: [&'a Row; 3],
    weight: [&'a Row; 3],
}

/// Where a triple global's rows lie after a camera shader call, worked out once per call.
// One lives on the stack for a call: boxing the uniform rows would allocate per call.
#[allow(clippy::large_enum_variant)]
enum MadeRows {
    /// A varying global: where its three rows start in the batch's varying floats (lane 0).
    Batch([usize; 3]),
    /// A uniform global (or one the shader does not have): its value in every lane.
    Uniform(Rows3),
}

impl MadeRows {
    /// The rows of the global in `slot` (its value when uniform, `defaults` when absent).
    fn of(raw: &RawBatch<'_>, slot: Option<Slot>, defaults: [f32; 3]) -> MadeRows {
        match slot {
            Some(s) if s.varying => MadeRows::Batch([0, 1, 2].map(|k| (s.offset + k) * raw.stride)),
            _ => {
                let value = |k: usize| match slot {
                    Some(s) => raw.uniform.get(s.offset + k).copied().unwrap_or(defaults[k]),
                    None => defaults[k],
                };
                MadeRows::Uniform([0, 1, 2].map(|k| [value(k); PACKET_SIZE]))
            }
        }
    }

    /// The rows of the packet at lanes `first ..` of the batch whose varying floats are `varying`
    /// (zero rows where the batch is too short, which a batch of the call's lanes never is).
    fn rows<'a>(&'a self, varying: &'a [f32], first: usize) -> [&'a Row; 3] {
        const ZERO: Row = [0.0; PACKET_SIZE];
        match self {
            MadeRows::Batch(starts) => starts.map(|start| {
                let at = start + first;
                varying.get(at..at + PACKET_SIZE).and_then(|row| row.try_into().ok()).unwrap_or(&ZERO)
            }),
            MadeRows::Uniform(rows) => rows.each_ref(),
        }
    }
}

impl MadeRays<'_> {
    /// Copies the lanes in `keep` into `packet`'s origin and direction rows and into `weights`,
    /// for the caller to finish later; the other lanes keep what they held.
    fn keep(&self, keep: u64, packet: &mut RayPacket, weights: &mut Rows3) {
        let rows = [
            (&mut packet.ox.0, self.origin[0]),
            (&mut packet.oy.0, self.origin[1]),
            (&mut packet.oz.0, self.origin[2]),
            (&mut packet.dx.0, self.dir[0]),
            (&mut packet.dy.0, self.dir[1]),
            (&mut packet.dz.0, self.dir[2]),
        ];
        let weight_rows = weights.iter_mut().zip(self.weight);
        for (row, made) in rows.into_iter().chain(weight_rows) {
            for (l, v) in row.iter_mut().enumerate() {
                if keep >> l & 1 != 0 {
                    *v = made[l];
                }
            }
        }
    }
}

/// Makes a packet of rays from what a camera shader made (`made`, read where the shader left it)
/// for samples at raster positions `(rx, ry)`: drops the lanes that made no usable ray, normalises
/// the directions, and works out the ray differentials. One pass over the packet, four lanes at a
/// time (`Vec4`), the differentials taken from each quad's directions while they are in registers:
/// this runs for every packet a camera shader makes, and written lane by lane it cost several times
/// the shader.
fn finish_shader_rays(
    frame: &Frame,
    ps: &PacketSamples,
    (rx, ry): &(Row, Row),
    made: &MadeRays,
    out: &mut PrimaryRays,
) {
    let PrimaryRays { packet, diffs, weights, .. } = out;
    // Most cameras give every ray of a packet one origin (a thin lens samples one lens position
    // per packet): then it is checked and written once, and the origins do not change from lane to
    // lane. Bit for bit, without an early exit per lane, so that it compiles to vector code.
    let same = |row: &Row| {
        let first = row[0].to_bits();
        row.iter().fold(0, |differ, v| differ | (v.to_bits() ^ first)) == 0
    };
    let fixed = made.origin.iter().all(|o| same(o)).then(|| made.origin.map(|row| row[0]));
    let origin_ok = BVec4A::splat(fixed.is_none_or(|o| o.iter().all(|v| v.is_finite())));
    if let Some(o) = fixed {
        for (row, v) in [&mut packet.ox.0, &mut packet.oy.0, &mut packet.oz.0].into_iter().zip(o) {
            *row = [v; PACKET_SIZE];
        }
        diffs.fixed_origin();
    }
    // A lane makes a ray when its origin is finite, its direction finite and not zero, and its
    // weight finite with a positive component; the others get a zero direction (and a zero origin
    // when the origins differ). Weights are clamped at zero in every lane, active or not (inactive
    // lanes are undefined).
    let (mut valid, mut near_x, mut near_y) = (0u64, 0u64, 0u64);
    for q in (0..PACKET_SIZE).step_by(4) {
        let [dx, dy, dz] = made.dir.map(|r| quad(r, q));
        let [wr, wg, wb] = made.weight.map(|r| quad(r, q));
        let origin = fixed.is_none().then(|| made.origin.map(|r| quad(r, q)));
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        // `x * 0` is zero for a finite `x` and NaN otherwise, so the sum is zero only when all
        // are finite (`len` is not when a component of the direction is not).
        let z = |x: Vec4| x * Vec4::ZERO;
        let mut finite = z(len) + z(wr) + z(wg) + z(wb);
        if let Some([ox, oy, oz]) = origin {
            finite += z(ox) + z(oy) + z(oz);
        }
        let ok = finite.cmpeq(Vec4::ZERO) & len.cmpgt(Vec4::ZERO) & wr.max(wg).max(wb).cmpgt(Vec4::ZERO) & origin_ok;
        let inv = Vec4::ONE / len;
        let d = [dx, dy, dz].map(|v| Vec4::select(ok, v * inv, Vec4::ZERO));
        for (row, v) in [&mut packet.dx.0, &mut packet.dy.0, &mut packet.dz.0].into_iter().zip(d) {
            v.write_to_slice(&mut row[q..q + 4]);
        }
        for (row, w) in weights.iter_mut().zip([wr, wg, wb]) {
            // `max` answers zero for NaN, as `f32::max` does.
            w.max(Vec4::ZERO).write_to_slice(&mut row[q..q + 4]);
        }
        valid |= u64::from(ok.bitmask()) << q;
        let steps = if ps.unit_steps { QuadSteps::UNIT } else { QuadSteps::new(quad(rx, q), quad(ry, q)) };
        near_x |= u64::from(steps.near_x) << q;
        near_y |= u64::from(steps.near_y) << q;
        steps.changes(d, [&mut diffs.dddx, &mut diffs.dddy], q);
        if let Some(o) = origin {
            let o = o.map(|v| Vec4::select(ok, v, Vec4::ZERO));
            for (row, v) in [&mut packet.ox.0, &mut packet.oy.0, &mut packet.oz.0].into_iter().zip(o) {
                v.write_to_slice(&mut row[q..q + 4]);
            }
            steps.finite_changes(o, [&mut diffs.dodx, &mut diffs.dody], q);
        }
    }
    packet.tmin.0 = [0.0; PACKET_SIZE];
    packet.tmax.0 = [f32::INFINITY; PACKET_SIZE];
    packet.time.0 = std::array::from_fn(|l| ps.samples[l].time);
    packet.active = ps.active & valid;
    // Lane l ^ 1 is a lane's horizontal neighbour, l ^ 2 its vertical one: whether the neighbour
    // made a ray is `valid` with those bits swapped.
    let valid_x = ((valid >> 1) & 0x5555_5555_5555_5555) | ((valid << 1) & 0xAAAA_AAAA_AAAA_AAAA);
    let valid_y = ((valid >> 2) & 0x3333_3333_3333_3333) | ((valid << 2) & 0xCCCC_CCCC_CCCC_CCCC);
    // Every lane from its quad first (loops without a test per lane), then the few whose quad does
    // not count get a cone instead.
    let d = [&packet.dx.0, &packet.dy.0, &packet.dz.0];
    let mut cones = packet.active & !(near_x & valid_x & near_y & valid_y);
    while cones != 0 {
        let l = cones.trailing_zeros() as usize;
        cones &= cones - 1;
        diffs.set_lane(l, RayDifferential::cone(Vec3A::new(d[0][l], d[1][l], d[2][l]), 0.0, frame.pixel_spread));
    }
}

/// Lanes `q .. q + 4` of a row.
#[inline(always)]
fn quad(row: &Row, q: usize) -> Vec4 {
    Vec4::from_slice(&row[q..q + 4])
}

/// The steps across one 2x2 raster quad (four consecutive lanes of a packet): lane `l ^ 1` is lane
/// `l`'s neighbour along x, lane `l ^ 2` along y. A value's change per step is
/// `(v[neighbour] - v[lane]) / step`.
struct QuadSteps {
    /// The reciprocal step to each lane's neighbour along x where that neighbour lies about one
    /// step away along x (at least a quarter pixel, drifting at most half a step in y), zero
    /// elsewhere, so that no change is infinite.
    inv_x: Vec4,
    /// The same along y.
    inv_y: Vec4,
    /// The lanes whose neighbour along x, and along y, is near (bit per lane; the caller also asks
    /// whether the neighbours made rays, and gives the others a cone).
    near_x: u32,
    near_y: u32,
}

impl QuadSteps {
    /// A quad of samples one pixel apart: lanes 0 and 2 have their x neighbour one pixel to the
    /// right, lanes 0 and 1 their y neighbour one pixel down.
    const UNIT: QuadSteps = QuadSteps {
        inv_x: Vec4::new(1.0, -1.0, 1.0, -1.0),
        inv_y: Vec4::new(1.0, 1.0, -1.0, -1.0),
        near_x: 0b1111,
        near_y: 0b1111,
    };

    /// The steps of a quad at raster positions `(x, y)`.
    #[inline(always)]
    fn new(x: Vec4, y: Vec4) -> QuadSteps {
        let near = |step: Vec4, drift: Vec4| {
            let near = step.abs().cmpge(Vec4::splat(0.25)) & drift.abs().cmple(step.abs() * 0.5);
            (Vec4::select(near, Vec4::ONE / step, Vec4::ZERO), near.bitmask())
        };
        let (inv_x, near_x) = near(x.yxwz() - x, y.yxwz() - y);
        let (inv_y, near_y) = near(y.zwxy() - y, x.zwxy() - x);
        QuadSteps { inv_x, inv_y, near_x, near_y }
    }

    /// Writes the change per step of a vector `v` along x and along y into lanes `q .. q + 4` of
    /// `[dx, dy]`. Finite when `v` is: the directions are finite unit vectors or zero.
    #[inline(always)]
    fn changes(&self, v: [Vec4; 3], [dx, dy]: [&mut Rows3; 2], q: usize) {
        for (k, v) in v.into_iter().enumerate() {
            ((v.yxwz() - v) * self.inv_x).write_to_slice(&mut dx[k][q..q + 4]);
            ((v.zwxy() - v) * self.inv_y).write_to_slice(&mut dy[k][q..q + 4]);
        }
    }

    /// [`QuadSteps::changes`] of a vector whose components may be any finite values (origins), so
    /// that a difference may overflow: a lane whose change is not finite gets zero.
    #[inline(always)]
    fn finite_changes(&self, v: [Vec4; 3], [dx, dy]: [&mut Rows3; 2], q: usize) {
        let cx = v.map(|v| (v.yxwz() - v) * self.inv_x);
        let cy = v.map(|v| (v.zwxy() - v) * self.inv_y);
        let finite = |c: &[Vec4; 3]| c[0].is_finite_mask() & c[1].is_finite_mask() & c[2].is_finite_mask();
        let (fx, fy) = (finite(&cx), finite(&cy));
        for k in 0..3 {
            Vec4::select(fx, cx[k], Vec4::ZERO).write_to_slice(&mut dx[k][q..q + 4]);
            Vec4::select(fy, cy[k], Vec4::ZERO).write_to_slice(&mut dy[k][q..q + 4]);
        }
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
        let (mut ddx, mut ddy) = ([[0.0f32; PACKET_SIZE]; 3], [[0.0f32; PACKET_SIZE]; 3]);
        camera_derivatives(&d, vx, vy, &mut ddx, &mut ddy);
        for l in 0..PACKET_SIZE {
            let want = RayDifferential::from_camera(Vec3A::new(d[0][l], d[1][l], d[2][l]), vx, vy);
            let got = (Vec3A::new(ddx[0][l], ddx[1][l], ddx[2][l]), Vec3A::new(ddy[0][l], ddy[1][l], ddy[2][l]));
            assert!((got.0 - want.dddx).length() <= 1e-6 * want.dddx.length().max(1e-3), "lane {l}: {got:?} {want:?}");
            assert!((got.1 - want.dddy).length() <= 1e-6 * want.dddy.length().max(1e-3), "lane {l}: {got:?} {want:?}");
        }
    }
}

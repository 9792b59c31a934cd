//! Interactive rendering in pieces: packets of chosen pixels, accumulated over passes.
//!
//! A viewer cannot wait for whole frames. It renders **lattices** (a packet of 64 pixels on an 8x8
//! grid `stride` pixels apart) and adds their samples to an [`Accumulator`], whose running mean is
//! the image shown. Three ways to use it:
//!
//! - **Progressive** refinement: while the view is still, each pass over [`pass_lattices`] at stride 1
//!   adds one sample per pixel at a new sub-pixel offset ([`pass_offset`]: a low-discrepancy sequence
//!   per pixel), so the image converges to the supersampled frame.
//! - **Preview** while the view moves: a pass at stride 2, 4 or 8 traces one ray per block and
//!   [`Accumulator::preview`] fills the block with it (nearest-neighbour upscaling), so a pass costs a
//!   quarter, a sixteenth or a sixty-fourth of a full one. The first real sample of a pixel replaces
//!   its preview.
//! - **Frameless** rendering (Bishop et al. 1994; OpenRT paper 5.1.1): [`frameless_order`] lists
//!   lattices that together visit every pixel once per pass, in an interleaved low-discrepancy
//!   order (every 4th pixel of each 32x32 region, regions in van der Corput order, then the next
//!   offset of the 4x4 cell), so any prefix of the list is spread evenly over the image. A viewer
//!   works through it in chunks with the latest camera and shows the buffer at a steady rate;
//!   [`Accumulator::restart`] makes the next sample of each pixel replace what it held, so old
//!   pixels stay on screen until they are revisited.
//!
//! [`trace_lattice`] is the one place this module calls into the frame renderer (primary rays and
//! their shading); [`Accumulator::resolve`] the one place it runs the pixel shader.
//!
//! Invariant: as in [`super::render_frame`], a sample depends only on the world, the pixel and the
//! pass number, never on threads or timing, so a given sequence of passes gives the same image.

use super::frame::Framebuffer;
use super::pixel::{reads_pixels, shade_pixels, TilePixels};
use super::primary::{primary_rays, CameraSample};
use super::sampling::radical_inverse;
use super::shade::shade_packet;
use super::work::{captured_outputs, refined_output, Frame, LightPathCache, LightPaths, PixelImage, Sample};
use super::world::{Antialiasing, RefineOn, World, MAX_FRAME_OUTPUTS};
use crate::camera::packet_lane_offset;
use crate::ray::{HitPacket, PACKET_SIZE};
use rayon::prelude::*;

/// Pixels per lattice side (a lattice is one packet of rays).
pub const LATTICE_SIDE: u32 = 8;

/// The spacing of frameless lattices: each visits every 4th pixel of a 32x32 region.
pub const FRAMELESS_STRIDE: u32 = 4;

/// One packet of pixels: `(x0 + stride * i, y0 + stride * j)` for `i, j` in `0..8`, those inside
/// the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelLattice {
    pub x0: u32,
    pub y0: u32,
    pub stride: u32,
}

impl PixelLattice {
    /// The pixel of packet lane `lane` (lanes follow the camera's 2x2-quad order, so the shading
    /// chunks of four lanes stay neighbours).
    pub fn pixel(&self, lane: usize) -> (u32, u32) {
        let (i, j) = packet_lane_offset(lane);
        (self.x0 + self.stride * i, self.y0 + self.stride * j)
    }
}

/// The lattices of one pass at `stride`: the lattice points are the pixels whose coordinates are
/// multiples of `stride`, each standing for the `stride x stride` block it starts. Stride 1 is every
/// pixel once, in 8x8 packets.
pub fn pass_lattices(width: u32, height: u32, stride: u32) -> Vec<PixelLattice> {
    let stride = stride.max(1);
    let span = (LATTICE_SIDE * stride) as usize;
    let mut out = Vec::new();
    for y0 in (0..height).step_by(span) {
        for x0 in (0..width).step_by(span) {
            out.push(PixelLattice { x0, y0, stride });
        }
    }
    out
}

/// The frameless update order: lattices at [`FRAMELESS_STRIDE`] that visit each pixel exactly once
/// per pass. The 16 offsets within a 4x4 cell come in a bit-reversed (stratified) order, and for
/// each offset every 32x32 region once, regions ordered by the van der Corput radical inverse of
/// their index, so each prefix of the list is spread evenly over the image.
pub fn frameless_order(width: u32, height: u32) -> Vec<PixelLattice> {
    let s = FRAMELESS_STRIDE;
    let mut regions = pass_lattices(width, height, s);
    let mut keys: Vec<(u32, usize)> = (0..regions.len()).map(|i| ((i as u32).reverse_bits(), i)).collect();
    keys.sort_unstable();
    regions = keys.into_iter().map(|(_, i)| regions[i]).collect();
    // Offsets of the 4x4 cell: bit-reversing the index spreads consecutive offsets apart.
    let mut offsets: Vec<(u32, u32)> = (0..s * s).map(|k| (k % s, k / s)).collect();
    offsets.sort_by_key(|&(x, y)| (x & 1) << 3 | (y & 1) << 2 | (x >> 1 & 1) << 1 | (y >> 1 & 1));
    let mut out = Vec::with_capacity(regions.len() * offsets.len());
    for (ox, oy) in offsets {
        for r in &regions {
            if r.x0 + ox < width && r.y0 + oy < height {
                out.push(PixelLattice { x0: r.x0 + ox, y0: r.y0 + oy, stride: s });
            }
        }
    }
    out
}

/// A 64-bit finaliser (splitmix64), to hash pixel and pass into jitter.
fn hash(mut x: u64) -> u64 {
    x ^= x >> 30;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// The sub-pixel offset, in [0, 1)², of pass `pass`'s sample of pixel `(x, y)` under `aa`:
/// `regular`: the centre every pass (no anti-aliasing); `jittered`: a hash of pixel and pass;
/// `interleaved`: Keller and Heidrich's interleaved Halton points (the 16 pixels of a 4x4 block
/// take successive points, pass after pass, so each pixel gets a stratified sequence and neighbours
/// differ); `adaptive`: the centre first, jittered after (only where [`Accumulator::needs_refinement`]).
pub fn pass_offset(aa: Antialiasing, x: u32, y: u32, pass: u32) -> (f32, f32) {
    match aa {
        Antialiasing::Grid { jitter: false } => (0.5, 0.5),
        Antialiasing::Adaptive { .. } if pass == 0 => (0.5, 0.5),
        Antialiasing::Interleaved => {
            let class = (x % 4) + 4 * (y % 4);
            let i = pass.wrapping_mul(16).wrapping_add(class + 1);
            (radical_inverse(i, 2), radical_inverse(i, 3))
        }
        Antialiasing::Grid { jitter: true } | Antialiasing::Adaptive { .. } => {
            let h = hash((u64::from(y) << 40) ^ (u64::from(x) << 16) ^ u64::from(pass) ^ 0x9e37_79b9_0000_0000);
            let r = |b: u64| ((h >> b) & 0xFFFF) as f32 / 65536.0;
            (r(0), r(16))
        }
    }
}

/// The samples of one traced lattice.
#[derive(Clone, Debug)]
pub struct LatticeSamples {
    pub lattice: PixelLattice,
    /// Lanes traced (bit per lane).
    pub active: u64,
    pub samples: [Sample; PACKET_SIZE],
    /// Camera-space depth of each lane's first hit (infinite for none).
    pub depth: [f32; PACKET_SIZE],
    /// Whether the samples keep their normals ([`Sample::normal`]): only where the world's pixel
    /// shader reads other pixels, the one reader of them; every normal is zero otherwise.
    pub normals: bool,
    /// How many output variables the samples keep ([`Sample::outputs`]: the frame's
    /// `captured_outputs`, the first this many); the rest are zero.
    pub outputs: usize,
}

/// The lanes of `lattice` inside a `width x height` image where `wanted(x, y)`, as a lane mask.
pub fn lattice_lanes(
    lattice: PixelLattice,
    width: u32,
    height: u32,
    wanted: &(dyn Fn(u32, u32) -> bool + Sync),
) -> u64 {
    (0..PACKET_SIZE).fold(0u64, |mask, lane| {
        let (x, y) = lattice.pixel(lane);
        if x < width && y < height && wanted(x, y) {
            mask | 1 << lane
        } else {
            mask
        }
    })
}

/// Traces and shades one lattice: lane `k` through its pixel at the sub-pixel offset `offset(x, y)`
/// scaled by `block` (a preview sample stands for the `block x block` pixels it starts, and lands
/// anywhere in them), for the lanes of `lanes` inside the image. The only call into the frame
/// renderer.
pub fn trace_lattice(
    frame: &Frame,
    lattice: PixelLattice,
    block: u32,
    offset: &(dyn Fn(u32, u32) -> (f32, f32) + Sync),
    lanes: u64,
) -> LatticeSamples {
    let world = frame.world;
    let (w, h) = (world.options.width, world.options.height);
    let mut cams = [CameraSample::default(); PACKET_SIZE];
    let mut active = 0u64;
    let (open, close) = world.options.shutter;
    let scale = block.max(1) as f32;
    // One lens sample per lattice (coherent thin-lens packets), moved along with the pass's
    // sub-pixel offsets so that passes cover the lens; the time follows each pixel's offset.
    let (x0, y0) = lattice.pixel(0);
    let (jx0, jy0) = offset(x0, y0);
    let lens = ((jx0 + 0.618_034).fract(), (jy0 + 0.381_966).fract());
    for (lane, cam) in cams.iter_mut().enumerate() {
        let (x, y) = lattice.pixel(lane);
        let (jx, jy) = offset(x, y);
        let time = open + (close - open) * (jx + 0.754_877_7 * jy).fract();
        *cam = CameraSample { raster: (x as f32 + jx * scale, y as f32 + jy * scale), lens, time };
        if x < w && y < h && lanes >> lane & 1 != 0 {
            active |= 1 << lane;
        }
    }
    let primary = primary_rays(frame, &cams, active);
    let packet = &primary.packet;
    // Lanes the camera made no ray for (outside a fisheye's circle) are samples too: empty ones.
    let mut out = LatticeSamples {
        lattice,
        active,
        samples: [EMPTY_SAMPLE; PACKET_SIZE],
        depth: [f32::INFINITY; PACKET_SIZE],
        normals: reads_pixels(world),
        outputs: frame.captured.len(),
    };
    if packet.active == 0 {
        return out;
    }
    let mut hits = HitPacket::default();
    world.intersect_packet(super::RayKind::Camera, packet, &mut hits);
    shade_packet(frame, &primary, &hits, &mut out.samples);
    let forward = world.camera.world_from_camera.matrix3.z_axis.normalize_or_zero();
    for lane in (0..PACKET_SIZE).filter(|l| packet.active >> l & 1 != 0) {
        out.depth[lane] = out.samples[lane].depth * packet.get(lane).direction.dot(forward);
        if !out.normals {
            // As another rank's samples arrive without them.
            out.samples[lane].normal = glam::Vec3A::ZERO;
        }
    }
    out
}

/// What a lane the camera made no ray for holds.
const EMPTY_SAMPLE: Sample = Sample {
    color: glam::Vec3A::ZERO,
    alpha: 0.0,
    depth: f32::INFINITY,
    object_id: u32::MAX,
    shader_id: u32::MAX,
    normal: glam::Vec3A::ZERO,
    outputs: [[0.0; 3]; MAX_FRAME_OUTPUTS],
};

/// What a batch of lattices cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BatchReport {
    pub primary_rays: u64,
    /// Every ray: primary, shadow, secondary and transparency.
    pub total_rays: u64,
    pub elapsed: std::time::Duration,
}

/// Traces lattices of one pass, each on its own (any thread, any order): the frame, the pass's
/// sub-pixel offsets under the world's anti-aliasing mode, and whether the samples are previews
/// (each spread over its lattice's `stride x stride` block, for [`Accumulator::add_lattices`]
/// with `preview`). A distributed worker traces the lattices it is handed with one of these.
pub struct LatticeTracer<'w> {
    frame: Frame<'w>,
    pass: u32,
    preview: bool,
}

impl<'w> LatticeTracer<'w> {
    pub fn new(world: &'w World, pass: u32, preview: bool) -> LatticeTracer<'w> {
        let mut frame = Frame::new(world);
        // Each pass gathers virtual lights of its own, so that passes converge.
        frame.gi_seed = world.options.gi.seed.wrapping_add(pass);
        LatticeTracer { frame, pass, preview }
    }

    /// Traces the pass's light paths (as [`crate::render::TileRenderer::prepare_light_paths`]).
    pub fn prepare_light_paths(&self) {
        super::virtual_lights::prepare(&self.frame);
    }

    /// Takes the pass's light paths from `cache` where it holds them (traced for another piece of
    /// the same pass of the same world); returns whether it did.
    pub fn reuse_light_paths(&self, cache: &LightPathCache) -> bool {
        cache.lend(&self.frame)
    }

    /// Leaves the light paths traced so far in `cache`, for the pass's next pieces.
    pub fn keep_light_paths(&self, cache: &LightPathCache) {
        cache.keep(&self.frame);
    }

    /// The light paths the pass has traced so far.
    pub fn light_paths(&self) -> LightPaths {
        LightPaths::of(&self.frame)
    }

    /// Gives the pass light paths traced elsewhere for the same world and pass (a distributed
    /// master's), before any lattice is traced; returns whether it took any.
    pub fn use_light_paths(&self, paths: &LightPaths) -> bool {
        paths.lend(&self.frame)
    }

    /// Traces the lanes `lanes` of `lattice` (see [`trace_lattice`]).
    pub fn trace(&self, lattice: PixelLattice, lanes: u64) -> LatticeSamples {
        let (aa, pass) = (self.frame.world.options.antialiasing, self.pass);
        let offset = move |x: u32, y: u32| pass_offset(aa, x, y, pass);
        trace_lattice(&self.frame, lattice, if self.preview { lattice.stride } else { 1 }, &offset, lanes)
    }

    /// What the lattices traced so far cost since `start`.
    pub fn report(&self, start: std::time::Instant) -> BatchReport {
        let s = &self.frame.stats;
        let load = |c: &super::stats::Counter| c.load();
        let primary_rays = load(&s.primary_rays);
        let total_rays = primary_rays + load(&s.shadow_rays) + load(&s.secondary_rays) + load(&s.transparency_rays);
        BatchReport { primary_rays, total_rays, elapsed: start.elapsed() }
    }

    /// The same, in full (rays by kind, shading time by shader), as a frame reports it.
    pub fn frame_report(&self, start: std::time::Instant) -> super::FrameReport {
        super::frame::frame_report(&self.frame, start)
    }
}

/// Traces `lattices` over the threads of the current rayon pool (see [`LatticeTracer`]), with the
/// offsets of pass `pass`, the lanes where `wanted(x, y)`. Results come back in list order.
pub fn trace_lattices(
    world: &World,
    lattices: &[PixelLattice],
    pass: u32,
    preview: bool,
    wanted: &(dyn Fn(u32, u32) -> bool + Sync),
) -> (Vec<LatticeSamples>, BatchReport) {
    trace_lattices_keeping(world, lattices, pass, preview, wanted, &LightPathCache::default())
}

/// [`trace_lattices`] for a caller that traces a pass in pieces: the pass's light paths come from
/// `cache` when an earlier piece traced them, and are left there for the next.
pub fn trace_lattices_keeping(
    world: &World,
    lattices: &[PixelLattice],
    pass: u32,
    preview: bool,
    wanted: &(dyn Fn(u32, u32) -> bool + Sync),
    cache: &LightPathCache,
) -> (Vec<LatticeSamples>, BatchReport) {
    let start = std::time::Instant::now();
    let tracer = LatticeTracer::new(world, pass, preview);
    tracer.reuse_light_paths(cache);
    tracer.prepare_light_paths();
    tracer.keep_light_paths(cache);
    let (w, h) = (world.options.width, world.options.height);
    let out: Vec<LatticeSamples> =
        lattices.par_iter().map(|l| tracer.trace(*l, lattice_lanes(*l, w, h, wanted))).collect();
    (out, tracer.report(start))
}

impl PixelLattice {
    /// Whether the lattice starts inside a `width x height` image and its pixels' coordinates fit
    /// (what a lattice from elsewhere, such as another rank, is checked for).
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x0 < width
            && self.y0 < height
            && self.stride >= 1
            && self.stride.checked_mul(LATTICE_SIDE).and_then(|span| span.checked_add(self.x0.max(self.y0))).is_some()
    }
}

/// Bytes of one traced lane in [`LatticeSamples::encode`]: colour, alpha, depth, object and
/// shader ids, camera depth.
const LANE_BYTES: usize = 32;

/// Bytes a lane's normal adds where the samples keep their normals ([`LatticeSamples::normals`]).
const NORMAL_BYTES: usize = 12;

/// Bytes each kept output variable adds to a lane ([`LatticeSamples::outputs`]).
const OUTPUT_BYTES: usize = 12;

impl LatticeSamples {
    /// The samples as bytes, for another rank: the lattice, the lane mask, then the traced lanes'
    /// samples (little-endian), each followed by its normal where the samples keep them and by
    /// the output variables they keep (whoever decodes knows both from the world: its pixel
    /// shader reads other pixels, and the outputs its frames keep).
    pub fn encode(&self, out: &mut Vec<u8>) {
        for v in [self.lattice.x0, self.lattice.y0, self.lattice.stride] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.active.to_le_bytes());
        for lane in (0..PACKET_SIZE).filter(|l| self.active >> l & 1 != 0) {
            let s = &self.samples[lane];
            for v in [s.color.x, s.color.y, s.color.z, s.alpha, s.depth] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&s.object_id.to_le_bytes());
            out.extend_from_slice(&s.shader_id.to_le_bytes());
            out.extend_from_slice(&self.depth[lane].to_le_bytes());
            if self.normals {
                for v in s.normal.to_array() {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
            for v in s.outputs.iter().take(self.outputs).flatten() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }

    /// Reads what [`LatticeSamples::encode`] wrote for a pass of `world`, checking that it is the
    /// samples of `lattice` and no lane outside `lanes` (the lanes asked for), with normals (unit
    /// or zero) exactly where the world's pixel shader reads other pixels, and the output
    /// variables the world's frames keep.
    pub fn decode(world: &World, lattice: PixelLattice, lanes: u64, bytes: &[u8]) -> Result<LatticeSamples, String> {
        let normals = reads_pixels(world);
        let outputs = captured_outputs(world).len();
        let normal_bytes = if normals { NORMAL_BYTES } else { 0 };
        let lane_bytes = LANE_BYTES + normal_bytes + OUTPUT_BYTES * outputs;
        let word = |at: usize| -> [u8; 4] {
            let mut b = [0; 4];
            b.copy_from_slice(&bytes[at..at + 4]);
            b
        };
        if bytes.len() < 20 {
            return Err("a lattice's samples are cut short".into());
        }
        let header = [0, 4, 8].map(|at| u32::from_le_bytes(word(at)));
        if header != [lattice.x0, lattice.y0, lattice.stride] {
            return Err(format!("samples of lattice {header:?} where lattice {lattice:?} was asked for"));
        }
        let mut mask = [0; 8];
        mask.copy_from_slice(&bytes[12..20]);
        let active = u64::from_le_bytes(mask);
        if active & !lanes != 0 {
            return Err(format!("samples of lanes {:#x} of a lattice whose lanes {lanes:#x} were asked for", active));
        }
        if bytes.len() != 20 + lane_bytes * active.count_ones() as usize {
            return Err("a lattice's samples do not match its lane mask".into());
        }
        let mut out = LatticeSamples {
            lattice,
            active,
            samples: [EMPTY_SAMPLE; PACKET_SIZE],
            depth: [f32::INFINITY; PACKET_SIZE],
            normals,
            outputs,
        };
        let mut at = 20;
        for lane in (0..PACKET_SIZE).filter(|l| active >> l & 1 != 0) {
            let f = |k: usize| f32::from_le_bytes(word(at + 4 * k));
            let u = |k: usize| u32::from_le_bytes(word(at + 4 * k));
            let mut kept = [[0.0; 3]; MAX_FRAME_OUTPUTS];
            let first_output = (LANE_BYTES + normal_bytes) / 4;
            for (o, value) in kept.iter_mut().take(outputs).enumerate() {
                *value = [0, 1, 2].map(|c| f(first_output + 3 * o + c));
            }
            out.samples[lane] = Sample {
                color: glam::Vec3A::new(f(0), f(1), f(2)),
                alpha: f(3),
                depth: f(4),
                object_id: u(5),
                shader_id: u(6),
                normal: if normals { glam::Vec3A::new(f(8), f(9), f(10)) } else { glam::Vec3A::ZERO },
                outputs: kept,
            };
            out.depth[lane] = f(7);
            // Unit or zero: anything longer (or not a number) is damage.
            let length_squared = out.samples[lane].normal.length_squared();
            if length_squared.is_nan() || length_squared > 1.01 {
                return Err(format!("lane {lane} of a lattice's samples has a damaged normal"));
            }
            at += lane_bytes;
        }
        Ok(out)
    }
}

/// A running mean per pixel, with what the pixel shader needs (depth, object and shader ids and
/// the normal of the latest first sample, and the mean of the output variables the samples keep).
/// Samples carry the epoch they were taken in: [`Accumulator::restart`]
/// starts a new one, and a pixel's first sample of the new epoch replaces its old mean, so the
/// buffer always holds a complete image (stale pixels until they are revisited).
#[derive(Clone, Debug)]
pub struct Accumulator {
    width: u32,
    height: u32,
    sum: Vec<[f32; 4]>,
    /// Samples in `sum`; 0 marks a preview value (see [`Accumulator::preview`]).
    count: Vec<u32>,
    epoch: Vec<u32>,
    depth: Vec<f32>,
    object_id: Vec<u32>,
    shader_id: Vec<u32>,
    /// The normals of the samples the depths come from; empty until a sample brings one (samples
    /// keep their normals only for a pixel shader that reads other pixels).
    normal: Vec<[f32; 3]>,
    /// The sums of the samples' kept output variables ([`Sample::outputs`]), as `sum` holds their
    /// colours; empty until a sample brings one that is not zero.
    outputs: Vec<[[f32; 3]; MAX_FRAME_OUTPUTS]>,
    current: u32,
}

impl Accumulator {
    /// An empty (black, stale) buffer.
    pub fn new(width: u32, height: u32) -> Accumulator {
        let n = width as usize * height as usize;
        Accumulator {
            width,
            height,
            sum: vec![[0.0; 4]; n],
            count: vec![0; n],
            epoch: vec![0; n],
            depth: vec![f32::INFINITY; n],
            object_id: vec![u32::MAX; n],
            shader_id: vec![u32::MAX; n],
            normal: Vec::new(),
            outputs: Vec::new(),
            current: 1,
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Something changed (camera, scene, shader): the next sample of each pixel replaces its value.
    pub fn restart(&mut self) {
        self.current = self.current.wrapping_add(1);
    }

    /// Samples pixel `(x, y)` holds in the current epoch (0 for a preview or a stale value).
    pub fn samples(&self, x: u32, y: u32) -> u32 {
        let i = self.index(x, y);
        if self.epoch[i] == self.current {
            self.count[i]
        } else {
            0
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// Pixel `i`'s normal becomes `n` (room for normals made when the first one comes).
    fn set_normal(&mut self, i: usize, n: glam::Vec3A) {
        if self.normal.is_empty() {
            if n == glam::Vec3A::ZERO {
                return;
            }
            self.normal = vec![[0.0; 3]; self.depth.len()];
        }
        self.normal[i] = n.to_array();
    }

    /// Pixel `i`'s output sums become `outputs` (room for them made when the first that is not
    /// zero comes: until then every sum is zero).
    fn set_outputs(&mut self, i: usize, outputs: &[[f32; 3]; MAX_FRAME_OUTPUTS]) {
        if self.outputs.is_empty() {
            if outputs.iter().flatten().all(|v| *v == 0.0) {
                return;
            }
            self.outputs = vec![[[0.0; 3]; MAX_FRAME_OUTPUTS]; self.depth.len()];
        }
        self.outputs[i] = *outputs;
    }

    /// Adds `outputs` to pixel `i`'s output sums.
    fn add_outputs(&mut self, i: usize, outputs: &[[f32; 3]; MAX_FRAME_OUTPUTS]) {
        if self.outputs.is_empty() {
            // Every sum so far is zero: the pixel's sum is its new sample's.
            return self.set_outputs(i, outputs);
        }
        for (sum, value) in self.outputs[i].iter_mut().flatten().zip(outputs.iter().flatten()) {
            *sum += value;
        }
    }

    /// Adds one sample to pixel `(x, y)`.
    pub fn add(&mut self, x: u32, y: u32, sample: &Sample, depth: f32) {
        let i = self.index(x, y);
        let v = [sample.color.x, sample.color.y, sample.color.z, sample.alpha];
        if self.epoch[i] != self.current || self.count[i] == 0 {
            self.sum[i] = v;
            self.count[i] = 1;
            self.epoch[i] = self.current;
            self.depth[i] = depth;
            self.object_id[i] = sample.object_id;
            self.shader_id[i] = sample.shader_id;
            self.set_normal(i, sample.normal);
            self.set_outputs(i, &sample.outputs);
        } else {
            for (s, v) in self.sum[i].iter_mut().zip(v) {
                *s += v;
            }
            self.count[i] += 1;
            self.add_outputs(i, &sample.outputs);
        }
    }

    /// Fills the `size x size` block at `(x, y)` (clipped to the image) with a preview sample: shown
    /// until the pixel's first real sample of the epoch replaces it.
    pub fn preview(&mut self, x: u32, y: u32, size: u32, sample: &Sample, depth: f32) {
        let v = [sample.color.x, sample.color.y, sample.color.z, sample.alpha];
        for py in y..(y + size).min(self.height) {
            for px in x..(x + size).min(self.width) {
                let i = self.index(px, py);
                self.sum[i] = v;
                self.count[i] = 0;
                self.epoch[i] = self.current;
                self.depth[i] = depth;
                self.object_id[i] = sample.object_id;
                self.shader_id[i] = sample.shader_id;
                self.set_normal(i, sample.normal);
                self.set_outputs(i, &sample.outputs);
            }
        }
    }

    /// Adds traced lattices: each sample to its pixel, or with `preview`, to its whole block.
    pub fn add_lattices(&mut self, results: &[LatticeSamples], preview: bool) {
        for r in results {
            for lane in (0..PACKET_SIZE).filter(|l| r.active >> l & 1 != 0) {
                let (x, y) = r.lattice.pixel(lane);
                if preview {
                    self.preview(x, y, r.lattice.stride, &r.samples[lane], r.depth[lane]);
                } else {
                    self.add(x, y, &r.samples[lane], r.depth[lane]);
                }
            }
        }
    }

    /// The running mean of pixel `(x, y)`: premultiplied linear RGBA.
    pub fn mean(&self, x: u32, y: u32) -> [f32; 4] {
        let i = self.index(x, y);
        let n = self.count[i].max(1) as f32;
        self.sum[i].map(|v| v / n)
    }

    /// The mean of pixel `i`'s kept output variables (zero where no sample kept any).
    fn output_mean(&self, i: usize) -> [[f32; 3]; MAX_FRAME_OUTPUTS] {
        let n = self.count[i].max(1) as f32;
        match self.outputs.get(i) {
            Some(sums) => sums.map(|sum| sum.map(|v| v / n)),
            None => [[0.0; 3]; MAX_FRAME_OUTPUTS],
        }
    }

    /// Adaptive sampling's test: the pixel differs from a neighbour by more than the threshold in
    /// a channel of its mean, in the object or shader it sees, or in a component of the mean of
    /// the output variable refined on, each as `test` chooses.
    pub fn needs_refinement(&self, x: u32, y: u32, test: &RefineTest) -> bool {
        let (on, threshold) = (&test.on, test.threshold);
        let i = self.index(x, y);
        let m = self.mean(x, y);
        let watched = |k: usize| test.watched.map(|o| self.output_mean(k)[o]);
        let output = watched(i);
        let neighbours = [
            (x > 0).then(|| (x - 1, y)),
            (x + 1 < self.width).then(|| (x + 1, y)),
            (y > 0).then(|| (x, y - 1)),
            (y + 1 < self.height).then(|| (x, y + 1)),
        ];
        neighbours.into_iter().flatten().any(|(nx, ny)| {
            let j = self.index(nx, ny);
            let n = self.mean(nx, ny);
            (on.object && self.object_id[i] != self.object_id[j])
                || (on.shader && self.shader_id[i] != self.shader_id[j])
                || (on.color && m.iter().zip(n).any(|(a, b)| (a - b).abs() > threshold))
                || output.zip(watched(j)).is_some_and(|(a, b)| a.iter().zip(b).any(|(a, b)| (a - b).abs() > threshold))
        })
    }

    /// The image as `render_frame` would finish it: the means, through the world's pixel shader (in
    /// bands of 16 rows over the rayon pool) and its exposure.
    pub fn resolve(&self, world: &World) -> Framebuffer {
        let (w, h) = (self.width, self.height);
        let mut fb = Framebuffer::new(w, h);
        let mut colors: Vec<[f32; 4]> =
            (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| self.mean(x, y)).collect();
        if world.pixel.is_some() && w > 0 {
            let frame = Frame::new(world);
            // A pixel shader that reads other pixels reads them as they were.
            let image = reads_pixels(world).then(|| PixelImage {
                width: w,
                height: h,
                rgba: colors.clone(),
                depth: self.depth.clone(),
                object_id: self.object_id.clone(),
                shader_id: self.shader_id.clone(),
                normal: if self.normal.is_empty() { vec![[0.0; 3]; self.depth.len()] } else { self.normal.clone() },
                outputs: captured_outputs(world)
                    .into_iter()
                    .enumerate()
                    .map(|(o, name)| (name, (0..self.depth.len()).map(|i| self.output_mean(i)[o]).collect()))
                    .collect(),
            });
            let band = 16 * w as usize;
            colors.par_chunks_mut(band).enumerate().for_each(|(b, rgba)| {
                let start = b * band;
                let end = start + rgba.len();
                shade_pixels(
                    &frame,
                    TilePixels {
                        x0: 0,
                        y0: (start / w as usize) as u32,
                        width: w,
                        rgba,
                        depth: &self.depth[start..end],
                        object_id: &self.object_id[start..end],
                        shader_id: &self.shader_id[start..end],
                    },
                    image.as_ref(),
                );
            });
        }
        let exposure = super::frame::frame_exposure(world);
        for (i, mut c) in colors.into_iter().enumerate() {
            if let Some(exposure) = exposure {
                super::frame::expose(&mut c, exposure);
            }
            fb.rgba[4 * i..4 * i + 4].copy_from_slice(&c);
        }
        if world.options.depth_and_ids {
            fb.depth.copy_from_slice(&self.depth);
            fb.object_id.copy_from_slice(&self.object_id);
        }
        fb
    }
}

/// What adaptive sampling refines an [`Accumulator`]'s pixels on ([`Accumulator::needs_refinement`]).
#[derive(Clone, Debug)]
pub struct RefineTest {
    pub threshold: f32,
    pub on: RefineOn,
    /// The place of `on.output` among the output variables the samples keep (`None` where it
    /// names none: then it refines nothing).
    pub watched: Option<usize>,
}

impl RefineTest {
    /// The test of `world`'s options at `threshold` (its [`Antialiasing::Adaptive`] threshold).
    pub fn of(world: &World, threshold: f32) -> RefineTest {
        RefineTest { threshold, on: world.options.refine_on.clone(), watched: refined_output(world) }
    }
}

/// Renders `passes` full passes of progressive refinement into a fresh accumulator (adaptive mode
/// refines only where [`Accumulator::needs_refinement`] after the first pass). For tests and
/// batch use; a viewer drives the same pieces pass by pass.
pub fn render_progressive(world: &World, passes: u32) -> (Accumulator, BatchReport) {
    let (w, h) = (world.options.width, world.options.height);
    let mut acc = Accumulator::new(w, h);
    let lattices = pass_lattices(w, h, 1);
    let mut total = BatchReport::default();
    for pass in 0..passes {
        let results = match world.options.antialiasing {
            Antialiasing::Adaptive { threshold } if pass > 0 => {
                let (snapshot, test) = (acc.clone(), RefineTest::of(world, threshold));
                trace_lattices(world, &lattices, pass, false, &move |x, y| snapshot.needs_refinement(x, y, &test))
            }
            _ => trace_lattices(world, &lattices, pass, false, &|_, _| true),
        };
        acc.add_lattices(&results.0, false);
        total.primary_rays += results.1.primary_rays;
        total.total_rays += results.1.total_rays;
        total.elapsed += results.1.elapsed;
    }
    (acc, total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::Context;
    use crate::render::render_frame;
    use std::path::Path;

    /// A plastic sphere on a matte floor under a shadowing point light, 48x32.
    fn world(aa: Antialiasing, samples: (u32, u32)) -> World {
        let rib = r#"
            Format 48 32 1
            Projection "perspective" "fov" 40
            Translate 0 -0.5 5
            WorldBegin
            LightSource "pointlight" 1 "intensity" 12 "from" [2 3 -2]
            Surface "plastic"
            Color [0.9 0.3 0.2]
            Sphere 1 -1 1 360
            Surface "matte"
            Color [0.6 0.7 0.8]
            Polygon "P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4]
            WorldEnd
        "#;
        let mut rt = Context::new();
        crate::rib::load::load_str(&mut rt, rib, Path::new("<test>")).expect("the test scene loads");
        rt.options.antialiasing = aa;
        rt.options.samples = samples;
        rt.build_world().expect("the test scene builds")
    }

    fn mean_abs_difference(a: &Framebuffer, b: &Framebuffer) -> f32 {
        let n = a.rgba.len() as f32;
        a.rgba.iter().zip(&b.rgba).map(|(x, y)| (x - y).abs()).sum::<f32>() / n
    }

    #[test]
    fn one_regular_pass_is_the_regular_frame() {
        let w = world(Antialiasing::Grid { jitter: false }, (1, 1));
        let (reference, _) = render_frame(&w, None);
        let (acc, report) = render_progressive(&w, 1);
        let image = acc.resolve(&w);
        assert_eq!(report.primary_rays, 48 * 32);
        assert!(reference.rgba.iter().any(|v| *v > 0.05), "the test scene is not black");
        let worst = reference.rgba.iter().zip(&image.rgba).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "largest difference {worst}");
        assert_eq!(reference.object_id, image.object_id);
    }

    #[test]
    fn accumulation_converges_to_the_supersampled_frame() {
        for aa in [Antialiasing::Grid { jitter: true }, Antialiasing::Interleaved] {
            let w = world(aa, (8, 8));
            let (reference, _) = render_frame(&w, None);
            let (one, _) = render_progressive(&w, 1);
            let (many, _) = render_progressive(&w, 64);
            let (err1, err64) =
                (mean_abs_difference(&one.resolve(&w), &reference), mean_abs_difference(&many.resolve(&w), &reference));
            assert!(err64 < 0.004, "{aa:?}: 64 passes differ from the 8x8-sample frame by {err64} on average");
            // The reference has its own sampling error, so the gain is bounded by it.
            assert!(err64 < err1 / 2.0, "{aa:?}: 1 pass {err1}, 64 passes {err64}");
            assert_eq!(many.samples(10, 10), 64);
        }
    }

    #[test]
    fn adaptive_passes_refine_only_edges() {
        let w = world(Antialiasing::Adaptive { threshold: 0.05 }, (1, 1));
        let (_, first) = render_progressive(&w, 1);
        let (acc, both) = render_progressive(&w, 2);
        let second = both.primary_rays - first.primary_rays;
        assert!(second > 0 && second < first.primary_rays / 2, "second pass traced {second} rays");
        let refined =
            (0..32).flat_map(|y| (0..48).map(move |x| (x, y))).filter(|&(x, y)| acc.samples(x, y) == 2).count();
        assert_eq!(refined as u64, second);
    }

    #[test]
    fn frameless_order_visits_every_pixel_once_per_pass() {
        for (w, h) in [(37, 23), (64, 64), (1, 1), (100, 7)] {
            let mut visits = vec![0u32; (w * h) as usize];
            for l in frameless_order(w, h) {
                for lane in 0..PACKET_SIZE {
                    let (x, y) = l.pixel(lane);
                    if x < w && y < h {
                        visits[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(visits.iter().all(|v| *v == 1), "{w}x{h}: {visits:?}");
        }
    }

    #[test]
    fn a_frameless_sweep_is_a_progressive_pass() {
        // Same pixels, same offsets: one sweep in frameless order equals one full pass.
        let w = world(Antialiasing::Interleaved, (1, 1));
        let mut acc = Accumulator::new(48, 32);
        for chunk in frameless_order(48, 32).chunks(5) {
            acc.add_lattices(&trace_lattices(&w, chunk, 0, false, &|_, _| true).0, false);
        }
        let (reference, _) = render_progressive(&w, 1);
        assert_eq!(acc.resolve(&w), reference.resolve(&w));
    }

    #[test]
    fn a_frameless_prefix_is_spread_over_the_image() {
        // The first sixteenth of the order touches every 32x32 region of a 128x128 image.
        let order = frameless_order(128, 128);
        let prefix = &order[..order.len() / 16];
        let mut regions: Vec<(u32, u32)> = prefix.iter().map(|l| (l.x0 / 32, l.y0 / 32)).collect();
        regions.sort_unstable();
        regions.dedup();
        assert_eq!(regions.len(), 16);
    }

    #[test]
    fn previews_cover_blocks_and_real_samples_replace_them() {
        let w = world(Antialiasing::Grid { jitter: true }, (1, 1));
        let mut acc = Accumulator::new(48, 32);
        let (coarse, report) = trace_lattices(&w, &pass_lattices(48, 32, 4), 0, true, &|_, _| true);
        assert_eq!(report.primary_rays, 12 * 8);
        acc.add_lattices(&coarse, true);
        let image = acc.resolve(&w);
        // Each 4x4 block is one colour.
        for y in 0..32 {
            for x in 0..48 {
                assert_eq!(image.pixel(x, y), image.pixel(x / 4 * 4, y / 4 * 4));
            }
        }
        assert_eq!(acc.samples(5, 5), 0);
        let (fine, _) = trace_lattices(&w, &pass_lattices(48, 32, 1), 0, false, &|_, _| true);
        acc.add_lattices(&fine, false);
        assert_eq!(acc.samples(5, 5), 1, "the first real sample replaces the preview");
        let (reference, _) = render_progressive(&w, 1);
        assert_eq!(acc.resolve(&w), reference.resolve(&w));
    }

    #[test]
    fn a_restart_replaces_stale_pixels_on_their_next_sample() {
        let mut acc = Accumulator::new(2, 1);
        let red = Sample { color: glam::Vec3A::new(1.0, 0.0, 0.0), alpha: 1.0, ..Sample::default() };
        let blue = Sample { color: glam::Vec3A::new(0.0, 0.0, 1.0), alpha: 1.0, ..Sample::default() };
        acc.add(0, 0, &red, 1.0);
        acc.add(1, 0, &red, 1.0);
        acc.add(0, 0, &red, 1.0);
        assert_eq!(acc.samples(0, 0), 2);
        acc.restart();
        assert_eq!(acc.samples(0, 0), 0);
        acc.add(0, 0, &blue, 1.0);
        assert_eq!(acc.mean(0, 0), [0.0, 0.0, 1.0, 1.0]);
        assert_eq!(acc.mean(1, 0), [1.0, 0.0, 0.0, 1.0], "an unvisited pixel keeps its old value");
    }

    #[test]
    fn kept_outputs_are_averaged_like_colours() {
        let with_outputs = |first: [f32; 3], second: [f32; 3]| {
            let mut outputs = [[0.0; 3]; MAX_FRAME_OUTPUTS];
            (outputs[0], outputs[1]) = (first, second);
            Sample { alpha: 1.0, outputs, ..Sample::default() }
        };
        let mut acc = Accumulator::new(3, 1);
        let plain = Sample { alpha: 1.0, ..Sample::default() };
        acc.add(0, 0, &plain, 1.0);
        assert!(acc.outputs.is_empty(), "no room for outputs until one is not zero");
        // A pixel's sums start from its first sample; one whose samples were all zero before the
        // room was made has zero sums.
        acc.add(0, 0, &with_outputs([2.0, 4.0, 6.0], [1.0, 0.0, 0.0]), 1.0);
        acc.add(1, 0, &with_outputs([1.0, 1.0, 1.0], [0.0; 3]), 1.0);
        acc.add(1, 0, &with_outputs([3.0, 1.0, 5.0], [0.0; 3]), 1.0);
        assert_eq!(acc.output_mean(0)[..2], [[1.0, 2.0, 3.0], [0.5, 0.0, 0.0]]);
        assert_eq!(acc.output_mean(1)[0], [2.0, 1.0, 3.0]);
        assert_eq!(acc.output_mean(2), [[0.0; 3]; MAX_FRAME_OUTPUTS], "never sampled");
        // A preview sets its block; a new epoch's first sample replaces the sums.
        acc.preview(1, 0, 2, &with_outputs([7.0; 3], [0.0; 3]), 1.0);
        assert_eq!((acc.output_mean(1)[0], acc.output_mean(2)[0]), ([7.0; 3], [7.0; 3]));
        acc.restart();
        acc.add(0, 0, &with_outputs([0.0; 3], [9.0; 3]), 1.0);
        assert_eq!(acc.output_mean(0)[..2], [[0.0; 3], [9.0; 3]]);
    }
}

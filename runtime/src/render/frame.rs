//! One frame: primary rays per 8x8 packet, tiles demand-driven over rayon, samples per pixel on a
//! jittered grid, averaged per pixel (the default box 1x1 filter) or splatted through the pixel
//! filter (`film.rs`), and the frame's statistics.
//!
//! Invariant: the image depends only on the world and the options, not on the thread count (tiles
//! are independent, jitter is a hash of pixel and sample, results land in tile order, and filtered
//! tiles are added up in tile order).

use super::film::{Film, TileFilm};
use super::pixel::{reads_pixels, shade_pixels, TilePixels};
use super::primary::{
    pinhole_ray, primary_rays, primary_rays_into, primary_rays_of_packets, CameraSample, PacketSamples, PrimaryRays,
};
use super::ray_params::{samples_for_relevance, RayValue, RELEVANCE};
use super::sampling::{mix, radical_inverse};
use super::shade::{shade_packet, shade_packets};
use super::work::{captured_outputs, refined_output};
use super::work::{Frame, LightPaths, PixelImage, Sample, SampleRows};
use super::world::{Antialiasing, World, MAX_FRAME_OUTPUTS};
use crate::camera::{packet_lane_offset, PACKET_LANE_OFFSETS, PACKET_SIDE};
use crate::image_io::{ImageError, WriteOptions};
use crate::ray::{HitPacket, Ray, RayPacket, PACKET_SIZE};
use crate::tiles::{render_tiles, Tile};
use glam::Vec3A;
use rayon::prelude::*;
use rtsl_compiler::interface::ShaderKind;
use std::path::Path;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Tile side in pixels (a whole number of packets).
pub const TILE_SIZE: u32 = 16;

/// A rendered image: linear RGBA (premultiplied, as RenderMan's `Ci`/`Oi`, after the pixel shader),
/// camera-space depth and the object id of the first hit per pixel (rows top to bottom).
#[derive(Clone, Debug, PartialEq)]
pub struct Framebuffer {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<f32>,
    pub depth: Vec<f32>,
    pub object_id: Vec<u32>,
    /// The output variables the frame kept ([`super::RenderOptions::outputs`]), by name: each
    /// pixel's mean of its samples' values (three components; a float in the first).
    pub outputs: Vec<(String, Vec<[f32; 3]>)>,
}

impl Framebuffer {
    pub fn new(width: u32, height: u32) -> Framebuffer {
        let n = width as usize * height as usize;
        Framebuffer {
            width,
            height,
            rgba: vec![0.0; 4 * n],
            depth: vec![f32::INFINITY; n],
            object_id: vec![u32::MAX; n],
            outputs: Vec::new(),
        }
    }

    /// Output variable `name` ([`Framebuffer::outputs`]) as a three-channel image, rows from the
    /// top; `None` when the frame did not keep it.
    pub fn output(&self, name: &str) -> Option<&[[f32; 3]]> {
        self.outputs.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_slice())
    }

    pub fn pixel(&self, x: u32, y: u32) -> [f32; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }

    /// The channels `mode` asks for, named as [`crate::image_io::write_channels`] takes them,
    /// interleaved. Depth is camera-space z, infinite where no surface was hit.
    pub fn channels(&self, mode: DisplayMode) -> (&'static [&'static str], Vec<f32>) {
        let pixels = self.rgba.chunks_exact(4).zip(&self.depth);
        match mode {
            DisplayMode::Rgba => (&["R", "G", "B", "A"], self.rgba.clone()),
            DisplayMode::Rgb => (&["R", "G", "B"], pixels.flat_map(|(p, _)| [p[0], p[1], p[2]]).collect()),
            DisplayMode::A => (&["A"], pixels.map(|(p, _)| p[3]).collect()),
            DisplayMode::Z => (&["Z"], self.depth.clone()),
            DisplayMode::Rgbaz => {
                (&["R", "G", "B", "A", "Z"], pixels.flat_map(|(p, &z)| [p[0], p[1], p[2], p[3], z]).collect())
            }
        }
    }

    /// Writes the colour and alpha to an image file whose format follows the extension (`.png`,
    /// `.tga`, `.ppm`, `.tif`: 8-bit; `.exr`: 32-bit float), as [`crate::write_image`] does.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ImageError> {
        self.save_with(path, &WriteOptions::default())
    }

    /// [`Framebuffer::save`] with the encoding chosen (half-float EXR, dither, sRGB curve).
    pub fn save_with(&self, path: impl AsRef<Path>, options: &WriteOptions) -> Result<(), ImageError> {
        crate::write_image(path, self.width as usize, self.height as usize, &self.rgba, options)
    }
}

/// Which of a frame's channels an image holds: RIB `Display` modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DisplayMode {
    #[default]
    Rgba,
    Rgb,
    /// Alpha alone.
    A,
    /// Camera-space depth alone (float files only).
    Z,
    /// Colour, alpha and depth (EXR only).
    Rgbaz,
}

impl DisplayMode {
    /// A RIB `Display` mode (`"rgb"`, `"rgba"`, `"a"`, `"z"`, `"rgbaz"`; `"rgbz"` as `"rgbaz"`);
    /// `None` for others (output variables).
    pub fn parse(mode: &str) -> Option<DisplayMode> {
        Some(match mode {
            "rgba" => DisplayMode::Rgba,
            "rgb" => DisplayMode::Rgb,
            "a" => DisplayMode::A,
            "z" => DisplayMode::Z,
            "rgbaz" | "rgbz" => DisplayMode::Rgbaz,
            _ => return None,
        })
    }

    /// The RIB name of the mode (`rgba`, `rgb`, `a`, `z`, `rgbaz`).
    pub fn name(self) -> &'static str {
        match self {
            DisplayMode::Rgba => "rgba",
            DisplayMode::Rgb => "rgb",
            DisplayMode::A => "a",
            DisplayMode::Z => "z",
            DisplayMode::Rgbaz => "rgbaz",
        }
    }

    /// Whether its values are floats whatever the file (depth).
    pub fn has_depth(self) -> bool {
        matches!(self, DisplayMode::Z | DisplayMode::Rgbaz)
    }
}

/// What a frame cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    pub elapsed: Duration,
    pub primary_rays: u64,
    pub shadow_rays: u64,
    pub secondary_rays: u64,
    pub transparency_rays: u64,
    pub shaded_points: u64,
    pub light_evaluations: u64,
    /// Rays the shaders asked for past their camera sample's ray budget
    /// ([`super::RAY_TREE_BUDGET`]), answered as past the ray depth: the frame is not what the
    /// scene asks for where this is not zero ([`FrameReport::warnings`]).
    pub rays_cut: u64,
    /// Lights left out at shading points that more than `MAX_LIGHTS` (32) reached, each area-light
    /// sample counted as a light ([`FrameReport::warnings`]).
    pub lights_dropped: u64,
    /// Thread time spent shading (tracing excluded), summed over threads.
    pub shading: Duration,
    /// Of that, the time in each type of shader (in [`ShaderKind::ALL`] order; see
    /// [`FrameReport::shader_time`]).
    pub by_kind: [Duration; ShaderKind::ALL.len()],
    /// The same per shader: name, type and time, the longest first.
    pub by_shader: Vec<(String, ShaderKind, Duration)>,
    /// Threads that rendered.
    pub threads: usize,
    /// What the shaders' runtime checks found during the frame (a loop stopped by its budget, an
    /// array index clamped), each place once, prefixed by the shader's name.
    pub shader_messages: Vec<String>,
    /// The acceleration-structure update made for this frame (before `elapsed` started).
    pub accel: super::world::AccelUpdate,
    /// Global illumination: tracing the frame's light paths, and the threads' time gathering
    /// virtual lights (both within `shading`; zero without them or untimed).
    pub light_paths: Duration,
    pub gathering: Duration,
    /// Each tile's render time, in tile order, where this process rendered the frame's tiles on
    /// its threads ([`render_frame`]); empty otherwise. What the frame's tail is made of:
    /// [`crate::tiles::hand_out_busy_share`].
    pub tile_times: Vec<Duration>,
}

impl FrameReport {
    /// What the renderer left out of the frame because a limit was passed, a warning for each
    /// limit: rays cut ([`FrameReport::rays_cut`]) and lights dropped
    /// ([`FrameReport::lights_dropped`]). Empty when the frame is all the scene asks for.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.rays_cut > 0 {
            out.push(format!(
                "{} ray{} cut: a camera sample's shaders may spawn {} rays (`trace`, `gather`, `indirectdiffuse`), \
                 and past that `trace` returned black, `gather` missed and `indirectdiffuse` went unshaded; \
                 lower Option \"trace\" \"maxdepth\" or the rays the shaders send",
                self.rays_cut,
                if self.rays_cut == 1 { " was" } else { "s were" },
                super::RAY_TREE_BUDGET
            ));
        }
        if self.lights_dropped > 0 {
            let (n, most) = (self.lights_dropped, rtsl_compiler::abi::MAX_LIGHTS);
            out.push(format!(
                "{n} light{} left out at shading points that more than {most} lights reached (each area-light \
                 sample counts as a light): `illuminance`, `diffuse` and `specular` see the first {most}",
                if n == 1 { " was" } else { "s were" },
            ));
        }
        out
    }

    pub fn total_rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays + self.secondary_rays + self.transparency_rays
    }

    pub fn rays_per_second(&self) -> f64 {
        self.total_rays() as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    /// " (surface 41%, light 12%, ...)" for the shader types that ran, by share of the threads'
    /// time.
    fn shader_shares(&self) -> String {
        let parts: Vec<String> = ShaderKind::ALL
            .iter()
            .zip(&self.by_kind)
            .filter(|(_, t)| !t.is_zero())
            .map(|(kind, t)| format!("{} {:.0}%", kind.name(), 100.0 * t.as_secs_f64() / self.thread_seconds()))
            .collect();
        if parts.is_empty() {
            String::new()
        } else {
            format!(" ({})", parts.join(", "))
        }
    }

    /// One line per shader that ran, the longest first: name, type, milliseconds (thread time) and
    /// share of the threads' time.
    pub fn shader_table(&self) -> String {
        self.by_shader
            .iter()
            .map(|(name, kind, t)| {
                format!(
                    "  {name:<16} {:<10} {:8.2} ms {:5.1}%\n",
                    kind.name(),
                    t.as_secs_f64() * 1e3,
                    100.0 * t.as_secs_f64() / self.thread_seconds()
                )
            })
            .collect()
    }

    /// The share of the threads' time spent shading.
    pub fn shading_share(&self) -> f64 {
        self.shading.as_secs_f64() / self.thread_seconds()
    }

    /// The threads' time inside shaders of `kind` (their batches: filling, running, reading back
    /// and their calls to the renderer, exclusive of tracing and of other shaders they cause to run).
    pub fn shader_time(&self, kind: ShaderKind) -> Duration {
        self.by_kind[super::stats::kind_index(kind)]
    }

    /// The share of the threads' time spent in shaders of `kind`.
    pub fn shader_share(&self, kind: ShaderKind) -> f64 {
        self.shader_time(kind).as_secs_f64() / self.thread_seconds()
    }

    fn thread_seconds(&self) -> f64 {
        (self.elapsed.as_secs_f64() * self.threads.max(1) as f64).max(1e-9)
    }
}

impl std::fmt::Display for FrameReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = |n: u64| n as f64 / 1e6;
        write!(
            f,
            "{:.1} ms, {:.2} M rays ({:.2} primary, {:.2} shadow, {:.2} secondary, {:.2} transparency), {:.2} M rays/s, {:.2} M shaded points, {:.0}% of the time shading{}; BVH update {:.2} ms ({} object{} rebuilt {:.2} ms, top level over {} instances {:.2} ms), {:.1} MB of geometry for {:.2} M triangles after instancing",
            self.elapsed.as_secs_f64() * 1e3,
            m(self.total_rays()),
            m(self.primary_rays),
            m(self.shadow_rays),
            m(self.secondary_rays),
            m(self.transparency_rays),
            self.rays_per_second() / 1e6,
            m(self.shaded_points),
            100.0 * self.shading_share(),
            self.shader_shares(),
            self.accel.total().as_secs_f64() * 1e3,
            self.accel.objects_rebuilt,
            if self.accel.objects_rebuilt == 1 { "" } else { "s" },
            self.accel.object_bvhs.as_secs_f64() * 1e3,
            self.accel.instances,
            self.accel.top_level.as_secs_f64() * 1e3,
            self.accel.memory_bytes as f64 / 1e6,
            m(self.accel.instanced_triangles as u64),
        )?;
        if !self.light_paths.is_zero() || !self.gathering.is_zero() {
            write!(
                f,
                "; global illumination: light paths {:.1} ms, gathering virtual lights {:.1} ms of thread time",
                self.light_paths.as_secs_f64() * 1e3,
                self.gathering.as_secs_f64() * 1e3
            )?;
        }
        Ok(())
    }
}

/// The built-in pinhole camera's ray through the point `(x + jx, y + jy)` of the image (pixel
/// `(x, y)`, sub-pixel offset `(jx, jy)` in [0, 1)); the field of view spans the image's shorter
/// side. A bound camera shader is not consulted: see [`primary_packet`].
pub fn camera_ray(world: &World, x: u32, y: u32, jx: f32, jy: f32) -> crate::ray::Ray {
    pinhole_ray(world, (x as f32 + jx, y as f32 + jy))
}

/// A hash of `key` as two numbers in [0, 1).
fn hash2(key: u64) -> (f32, f32) {
    let h = mix(key);
    (((h & 0xFFFF) as f32) / 65536.0, (((h >> 16) & 0xFFFF) as f32) / 65536.0)
}

/// The time within the shutter of sample `k` of pixel `(x, y)`: a low-discrepancy sequence over the
/// samples, rotated per pixel.
fn time_sample(world: &World, x: u32, y: u32, k: u32) -> f32 {
    let (open, close) = world.options.shutter;
    if close == open {
        return open;
    }
    let shift = hash2((u64::from(y) << 40) ^ (u64::from(x) << 16) ^ 0x7111_0000).0;
    let r = (radical_inverse(k.saturating_add(1), 5) + shift).fract();
    open + (close - open) * r
}

/// The lens sample of sample `k` of the pixels of the tile that holds pixel `(x, y)`: one per tile,
/// so that a thin lens's packets share their origin and a camera shader makes a tile's rays in one
/// call (the lens sample is uniform in camera shaders); a Halton sequence over the samples,
/// rotated per tile.
fn lens_sample(x: u32, y: u32, k: u32) -> (f32, f32) {
    let (x0, y0) = (x - x % TILE_SIZE, y - y % TILE_SIZE);
    let (a, b) = hash2((u64::from(y0) << 40) ^ (u64::from(x0) << 16) ^ 0x1E25_0000);
    ((radical_inverse(k.saturating_add(1), 2) + a).fract(), (radical_inverse(k.saturating_add(1), 3) + b).fract())
}

/// The index of sample `(i, j)` in a pixel's grid `sx` wide (saturating: the API may ask for a
/// sample past the grid).
fn sample_index(sample: (u32, u32), sx: u32) -> u32 {
    sample.1.saturating_mul(sx).saturating_add(sample.0)
}

/// The sub-pixel offset of sample `(i, j)` of pixel `(x, y)` under the frame's anti-aliasing mode
/// (for the fixed-pattern modes; adaptive sampling's extra samples use the jittered grid).
pub fn sample_offset(world: &World, x: u32, y: u32, sample: (u32, u32)) -> (f32, f32) {
    let (sx, sy) = world.options.pixel_samples();
    let n = sx * sy;
    let k = sample_index(sample, sx);
    match world.options.antialiasing {
        // Adaptive sampling's first sample is the pixel's centre.
        Antialiasing::Adaptive { .. } => (0.5, 0.5),
        Antialiasing::Grid { jitter: false } => {
            ((sample.0 as f32 + 0.5) / sx as f32, (sample.1 as f32 + 0.5) / sy as f32)
        }
        Antialiasing::Interleaved => {
            // Keller & Heidrich: the pixels of a 4x4 block take successive runs of one Halton
            // sequence, so neighbours sample different points of one low-discrepancy set.
            let class = (x % 4) + 4 * (y % 4);
            // Within `u32` for every sample of a pixel (`MAX_PIXEL_SAMPLES`); a sample index
            // past them (the API's) takes the sequence's last point rather than overflowing.
            let i = u64::from(class) * u64::from(n) + u64::from(k) + 1;
            let i = u32::try_from(i).unwrap_or(u32::MAX);
            (radical_inverse(i, 2), radical_inverse(i, 3))
        }
        _ if n == 1 => (0.5, 0.5),
        _ => {
            let hsh = mix((u64::from(y) << 40) ^ (u64::from(x) << 16) ^ u64::from(k));
            let r = |b: u64| ((hsh >> b) & 0xFFFF) as f32 / 65536.0;
            ((sample.0 as f32 + r(0)) / sx as f32, (sample.1 as f32 + r(16)) / sy as f32)
        }
    }
}

/// The camera samples of one 8x8 packet for sample `(i, j)` of each pixel (see [`sample_offset`]),
/// and the lanes inside the image.
pub fn camera_samples(world: &World, x0: u32, y0: u32, sample: (u32, u32)) -> ([CameraSample; PACKET_SIZE], u64) {
    let mut out = PacketSamples::default();
    camera_samples_into(world, x0, y0, sample, &mut out);
    (out.samples, out.active)
}

/// [`camera_samples`] into `out` (a tile's packets are made in place).
fn camera_samples_into(world: &World, x0: u32, y0: u32, sample: (u32, u32), out: &mut PacketSamples) {
    let (cx0, cx1, cy0, cy1) = world.options.pixel_range();
    let (sx, sy) = world.options.pixel_samples();
    let k = sample_index(sample, sx);
    let lens = lens_sample(x0, y0, k);
    // The sub-pixel offset is the same for every pixel unless it is jittered or interleaved: worked
    // out once per packet then.
    let same_offset = match world.options.antialiasing {
        Antialiasing::Adaptive { .. } | Antialiasing::Grid { jitter: false } => true,
        Antialiasing::Interleaved => false,
        Antialiasing::Grid { jitter: true } => sx * sy == 1,
    };
    let offset = same_offset.then(|| sample_offset(world, x0, y0, sample));
    let (open, close) = world.options.shutter;
    let mut active = 0u64;
    for (i, (s, &(dx, dy))) in out.samples.iter_mut().zip(&PACKET_LANE_OFFSETS).enumerate() {
        let (x, y) = (x0 + dx, y0 + dy);
        active |= u64::from((cx0..cx1).contains(&x) && (cy0..cy1).contains(&y)) << i;
        // Without jitter and motion blur (the common case) a lane is a few additions: the general
        // case's per-lane hashing is kept out of that loop.
        *s = match offset {
            Some((jx, jy)) if open == close => {
                CameraSample { raster: (x as f32 + jx, y as f32 + jy), lens, time: open }
            }
            _ => {
                let (jx, jy) = offset.unwrap_or_else(|| sample_offset(world, x, y, sample));
                CameraSample { raster: (x as f32 + jx, y as f32 + jy), lens, time: time_sample(world, x, y, k) }
            }
        };
    }
    out.active = active;
    out.shared_lens = Some(lens);
    out.unit_steps = offset.is_some();
}

/// The primary rays of one 8x8 packet for sample `(i, j)` of each pixel, from the bound camera
/// shader or the built-in pinhole camera.
pub fn primary_packet(frame: &Frame, x0: u32, y0: u32, sample: (u32, u32)) -> PrimaryRays {
    let mut out = PrimaryRays::default();
    primary_packet_into(frame, x0, y0, sample, &mut out);
    out
}

/// [`primary_packet`] into a packet that the caller reuses (see [`primary_rays_into`]).
pub fn primary_packet_into(frame: &Frame, x0: u32, y0: u32, sample: (u32, u32), out: &mut PrimaryRays) {
    let (samples, active) = camera_samples(frame.world, x0, y0, sample);
    primary_rays_into(frame, &samples, active, out);
}

/// The primary rays of every 8x8 packet of a tile for one sample of each pixel, made together (a
/// camera shader runs once for the tile: [`primary_rays_of_packets`]). Kept by a tile loop and
/// reused from sample to sample and tile to tile.
#[derive(Default)]
pub struct TilePrimary {
    /// The packets' top left pixels, rows of packets from the top left.
    pub corners: Vec<(u32, u32)>,
    samples: Vec<PacketSamples>,
    /// The rays of packet `p`, from corner `corners[p]`.
    pub rays: Vec<PrimaryRays>,
    /// Their hits, and their samples once shaded ([`sample_tile`]).
    hits: Vec<HitPacket>,
    shaded: Vec<SampleRows>,
}

thread_local! {
    /// Each thread's [`TilePrimary`]: making a tile's packets afresh (zeroed differentials and
    /// weights) cost as much as a simple camera shader.
    static TILE_PRIMARY: std::cell::Cell<Option<Box<TilePrimary>>> = const { std::cell::Cell::new(None) };
}

impl TilePrimary {
    /// Runs `f` with this thread's tile scratch (a fresh one if a caller further up holds it).
    pub fn with<R>(f: impl FnOnce(&mut TilePrimary) -> R) -> R {
        let mut scratch = TILE_PRIMARY.take().unwrap_or_default();
        let r = f(&mut scratch);
        TILE_PRIMARY.set(Some(scratch));
        r
    }

    /// Makes the rays of sample `(i, j)` of each pixel of `tile`.
    pub fn make(&mut self, frame: &Frame, tile: &Tile, sample: (u32, u32)) {
        self.corners.clear();
        for py in (tile.y0..tile.y0 + tile.height).step_by(PACKET_SIDE as usize) {
            for px in (tile.x0..tile.x0 + tile.width).step_by(PACKET_SIDE as usize) {
                self.corners.push((px, py));
            }
        }
        let n = self.corners.len();
        self.samples.resize_with(n, PacketSamples::default);
        self.rays.resize_with(n, PrimaryRays::default);
        for (&(px, py), ps) in self.corners.iter().zip(&mut self.samples) {
            camera_samples_into(frame.world, px, py, sample, ps);
        }
        primary_rays_of_packets(frame, &self.samples, &mut self.rays);
    }
}

/// Adaptive oversampling of one tile (OpenRT's, paper 5.1.2): a pixel that differs from a
/// neighbour in the tile by more than `threshold` in any colour channel, in the object or shader
/// hit, or in an output variable, as the options' [`super::RefineOn`] chooses, gets a jittered `ex x ey` grid of extra samples, averaged with its first one into `px`'s
/// colour. `splat` sees each extra sample too (raster position, colour and alpha), for a filter.
fn refine_tile(
    frame: &Frame,
    tile: &Tile,
    (threshold, relevance): (f32, &[f32]),
    extra: (u32, u32),
    px: &mut TileSamples,
    splat: &mut impl FnMut((f32, f32), [f32; 4]),
) {
    let world = frame.world;
    let mut refine = pixels_to_refine(world, tile, threshold, px);
    // Under relevance, a pixel of relevance below one half is not refined.
    for (r, &relevance) in refine.iter_mut().zip(relevance) {
        *r &= relevance >= 0.5;
    }
    let rays = extra_samples(world, tile, extra, &refine);
    let color = &mut px.color;
    let mut sums = vec![[0.0f32; 4]; color.len()];
    let mut output_sums = vec![[[0.0f32; 3]; MAX_FRAME_OUTPUTS]; px.outputs.len()];
    let mut samples = [Sample::default(); PACKET_SIZE];
    let mut hits = HitPacket::default();
    for chunk in rays.chunks(PACKET_SIZE) {
        let mut cams = [CameraSample::default(); PACKET_SIZE];
        for (lane, (_, s)) in chunk.iter().enumerate() {
            cams[lane] = *s;
        }
        let active = if chunk.len() == PACKET_SIZE { u64::MAX } else { (1u64 << chunk.len()) - 1 };
        let primary = primary_rays(frame, &cams, active);
        world.intersect_packet(super::RayKind::Camera, &primary.packet, &mut hits);
        shade_packet(frame, &primary, &hits, &mut samples);
        for (lane, ((k, cam), s)) in chunk.iter().zip(&samples).enumerate() {
            if primary.packet.active >> lane & 1 == 0 {
                continue;
            }
            let sum = &mut sums[*k];
            for (c, v) in sum.iter_mut().zip(s.color.to_array()) {
                *c += v;
            }
            sum[3] += s.alpha;
            splat(cam.raster, rgba(s));
            if let Some(o) = output_sums.get_mut(*k) {
                add_outputs(o, &s.outputs);
            }
        }
    }
    let n = (extra.0 * extra.1) as f32;
    for (k, sum) in sums.iter().enumerate().filter(|(k, _)| refine[*k]) {
        for c in 0..4 {
            color[k][c] = (color[k][c] + sum[c]) / (1.0 + n);
        }
        if let (Some(o), Some(s)) = (px.outputs.get_mut(k), output_sums.get(k)) {
            for (a, b) in o.iter_mut().flatten().zip(s.iter().flatten()) {
                *a = (*a + b) / (1.0 + n);
            }
        }
    }
}

/// Which pixels of a tile adaptive sampling refines (see [`refine_tile`]), judged on their first
/// samples.
fn pixels_to_refine(world: &World, tile: &Tile, threshold: f32, px: &TileSamples) -> Vec<bool> {
    let (color, ids, shader_ids) = (&px.color, &px.ids, &px.shader_ids);
    let (tw, th) = (tile.width as usize, tile.height as usize);
    let on = &world.options.refine_on;
    // The refined-on output's place among those kept, and each pixel's value of it.
    let outputs: Vec<[f32; 3]> = match refined_output(world) {
        Some(i) => px.outputs.iter().map(|o| o[i]).collect(),
        None => Vec::new(),
    };
    let differs = |a: usize, b: usize| {
        (on.object && ids[a] != ids[b])
            || (on.shader && shader_ids[a] != shader_ids[b])
            || (on.color && (0..4).any(|c| (color[a][c] - color[b][c]).abs() > threshold))
            || (!outputs.is_empty() && (0..3).any(|c| (outputs[a][c] - outputs[b][c]).abs() > threshold))
    };
    // Pixels outside the crop window are not rendered: they stay empty, and an edge between one and
    // a rendered pixel is no reason to refine either.
    let (cx0, cx1, cy0, cy1) = world.options.pixel_range();
    let rendered = |k: usize| {
        let (x, y) = (tile.x0 + (k % tw) as u32, tile.y0 + (k / tw) as u32);
        (cx0..cx1).contains(&x) && (cy0..cy1).contains(&y)
    };
    let mut refine = vec![false; color.len()];
    for y in 0..th {
        for x in 0..tw {
            let k = y * tw + x;
            for n in [(x + 1 < tw).then_some(k + 1), (y + 1 < th).then_some(k + tw)].into_iter().flatten() {
                if rendered(k) && rendered(n) && differs(k, n) {
                    refine[k] = true;
                    refine[n] = true;
                }
            }
        }
    }
    refine
}

/// The extra camera samples of the pixels to `refine` (tile-local index, sample): a jittered
/// `ex x ey` grid each. A pixel's extra samples are consecutive, so that once they go 64 to a
/// packet (incoherent packets fall back to single rays in the tracer) a 2x2 grid of them is a
/// raster quad. Extra sample `k` of every pixel of the tile takes the tile's lens sample `1 + k`, so
/// a camera shader that reads the lens makes such a packet in `ex * ey` calls.
fn extra_samples(world: &World, tile: &Tile, (ex, ey): (u32, u32), refine: &[bool]) -> Vec<(usize, CameraSample)> {
    let tw = tile.width as usize;
    let mut rays = Vec::new();
    for (k, _) in refine.iter().enumerate().filter(|(_, r)| **r) {
        let (x, y) = (tile.x0 + (k % tw) as u32, tile.y0 + (k / tw) as u32);
        for j in 0..ey {
            for i in 0..ex {
                let key = (u64::from(y) << 40) ^ (u64::from(x) << 16) ^ u64::from(0x5A5A_0000 + j * ex + i);
                let (rx, ry) = hash2(key);
                let (jx, jy) = ((i as f32 + rx) / ex as f32, (j as f32 + ry) / ey as f32);
                let raster = (x as f32 + jx, y as f32 + jy);
                // The pixel's first sample is the tile's lens sample 0.
                let lens = lens_sample(tile.x0, tile.y0, 1 + j * ex + i);
                rays.push((k, CameraSample { raster, lens, time: time_sample(world, x, y, 1 + j * ex + i) }));
            }
        }
    }
    rays
}

/// A sample's colour and alpha.
fn rgba(s: &Sample) -> [f32; 4] {
    [s.color.x, s.color.y, s.color.z, s.alpha]
}

/// Generates and traces the primary rays of a frame, one sample per pixel, without shading them
/// (what `rtsl bench camera` times), with the threads of the current rayon pool. Returns the rays
/// traced and how many hit something.
pub fn trace_primary_rays(world: &World) -> (u64, u64) {
    primary_rays_of_frame(world, true)
}

/// [`trace_primary_rays`] without the tracing: the rays made (and 0 hits), so that benchmarks can
/// tell the cost of making rays from the cost of tracing them.
pub fn make_primary_rays(world: &World) -> (u64, u64) {
    primary_rays_of_frame(world, false)
}

fn primary_rays_of_frame(world: &World, trace: bool) -> (u64, u64) {
    let frame = Frame::new(world);
    let (w, h) = (world.options.width, world.options.height);
    let counts = render_tiles(w, h, TILE_SIZE, |tile| {
        let mut hits = HitPacket::default();
        let (mut rays, mut hit) = (0u64, 0u64);
        TilePrimary::with(|primary| {
            primary.make(&frame, tile, (0, 0));
            for rays_of_packet in &primary.rays {
                let active = rays_of_packet.packet.active;
                rays += u64::from(active.count_ones());
                if !trace {
                    continue;
                }
                world.intersect_packet(super::RayKind::Camera, &rays_of_packet.packet, &mut hits);
                hit +=
                    (0..PACKET_SIZE).filter(|&i| active >> i & 1 != 0 && hits.instance.0[i] != u32::MAX).count() as u64;
            }
        });
        (rays, hit)
    });
    counts.into_iter().fold((0, 0), |(a, b), (c, d)| (a + c, b + d))
}

/// How a frame samples its pixels, as its options say.
struct Sampling {
    /// The grid of samples every pixel gets (1x1 under adaptive sampling, whose first sample is
    /// the pixel's centre).
    grid: (u32, u32),
    /// Adaptive sampling's threshold and its grid of extra samples: the `PixelSamples` grid, or
    /// 2x2 when that is 1x1.
    adaptive: Option<(f32, (u32, u32))>,
    /// The camera's view axis in world space, for camera-space depth.
    forward: Vec3A,
    /// Whether pixels keep their first sample's normal: only for a pixel shader that reads other
    /// pixels ([`reads_pixels`]), the one reader of the normals.
    normals: bool,
    /// Whether the ray parameter [`RELEVANCE`] sets how many of the grid's samples each pixel
    /// takes ([`samples_for_relevance`]): where it is set and the grid has more than one.
    by_relevance: bool,
}

/// The place of cell `(i, j)` of a `sx x sy` sample grid in the order a pixel takes its samples
/// when it takes fewer than the grid ([`samples_for_relevance`]): the bits of `(i ^ j, j)`
/// interleaved and reversed, so that any first few cells spread over the pixel (a 2x2 grid takes
/// its corners diagonally first).
fn sample_rank((i, j): (u32, u32), (sx, sy): (u32, u32)) -> u32 {
    let bits = 32 - sx.max(sy).saturating_sub(1).leading_zeros();
    let (a, b) = (i ^ j, j);
    let mut code = 0u64;
    for k in 0..bits {
        code |= u64::from(a >> k & 1) << (2 * k) | u64::from(b >> k & 1) << (2 * k + 1);
    }
    if bits == 0 {
        return 0;
    }
    (code.reverse_bits() >> (64 - 2 * bits)) as u32
}

impl Sampling {
    fn of(world: &World) -> Sampling {
        let grid = world.options.pixel_samples();
        let adaptive = match world.options.antialiasing {
            Antialiasing::Adaptive { threshold } => Some((threshold, if grid == (1, 1) { (2, 2) } else { grid })),
            _ => None,
        };
        let by_relevance = world.options.ray_parameters.get(RELEVANCE).is_some();
        Sampling {
            by_relevance: by_relevance && (adaptive.is_some() || grid.0 * grid.1 > 1),
            grid: if adaptive.is_some() { (1, 1) } else { grid },
            adaptive,
            forward: world.camera.world_from_camera.matrix3.z_axis.normalize_or_zero(),
            normals: reads_pixels(world),
        }
    }
}

/// A tile's pixels once sampled (rows of the tile, top to bottom): the mean of each pixel's own
/// samples, and the camera-space depth, object and shader of its first sample, and where the
/// pixel shader reads other pixels its normal (`normals` empty otherwise).
struct TileSamples {
    color: Vec<[f32; 4]>,
    depth: Vec<f32>,
    ids: Vec<u32>,
    shader_ids: Vec<u32>,
    normals: Vec<[f32; 3]>,
    /// The output variables the frame keeps ([`Frame::captured`]), each pixel's mean over its
    /// samples (empty when it keeps none).
    outputs: Vec<Outputs>,
}

impl TileSamples {
    /// Empty pixels, with room for normals if `normals`.
    fn empty(tile: &Tile, normals: bool) -> TileSamples {
        let n = (tile.width * tile.height) as usize;
        TileSamples {
            color: vec![[0.0; 4]; n],
            depth: vec![f32::INFINITY; n],
            ids: vec![u32::MAX; n],
            shader_ids: vec![u32::MAX; n],
            normals: if normals { vec![[0.0; 3]; n] } else { Vec::new() },
            outputs: Vec::new(),
        }
    }
}

/// A pixel's or a sample's kept output variables ([`Frame::captured`]).
type Outputs = [[f32; 3]; MAX_FRAME_OUTPUTS];

/// Adds the outputs of a sample to a pixel's sums.
fn add_outputs(sum: &mut Outputs, s: &Outputs) {
    for (a, b) in sum.iter_mut().zip(s) {
        for (x, y) in a.iter_mut().zip(b) {
            *x += y;
        }
    }
}

/// Tells the caller of [`render_frame`] how many tiles are done.
struct Progress<'a> {
    report: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    done: AtomicUsize,
    total: usize,
}

impl Progress<'_> {
    fn tile_done(&self) {
        if let Some(p) = self.report {
            p(self.done.fetch_add(1, Ordering::Relaxed) + 1, self.total);
        }
    }
}

/// Traces and shades every sample of a tile (adaptive sampling's extra ones included) into the
/// mean of each pixel's own samples; `splat` sees each sample's raster position, colour and alpha.
fn sample_tile(
    frame: &Frame,
    tile: &Tile,
    sampling: &Sampling,
    mut splat: impl FnMut((f32, f32), [f32; 4]),
) -> TileSamples {
    let world = frame.world;
    let mut px = TileSamples::empty(tile, sampling.normals);
    if !frame.captured.is_empty() {
        px.outputs = vec![[[0.0; 3]; MAX_FRAME_OUTPUTS]; px.color.len()];
    }
    let (sx, sy) = sampling.grid;
    // Under relevance, how many of its samples each pixel of the tile takes.
    let takes: Vec<u32> = match sampling.by_relevance {
        true => tile_relevance(world, tile).into_iter().map(|r| samples_for_relevance(sx * sy, r)).collect(),
        false => Vec::new(),
    };
    TilePrimary::with(|primary| {
        for j in 0..sy {
            for i in 0..sx {
                primary.make(frame, tile, (i, j));
                let TilePrimary { corners, samples: cameras, rays, hits, shaded } = primary;
                if !takes.is_empty() {
                    let rank = sample_rank((i, j), (sx, sy));
                    for (&(x0, y0), rays) in corners.iter().zip(rays.iter_mut()) {
                        for lane in 0..PACKET_SIZE {
                            let (dx, dy) = packet_lane_offset(lane);
                            let (x, y) = (x0 + dx - tile.x0, y0 + dy - tile.y0);
                            let k = (y * tile.width + x) as usize;
                            if x >= tile.width || takes.get(k).is_some_and(|&m| rank >= m) {
                                rays.packet.active &= !(1u64 << lane);
                            }
                        }
                    }
                }
                let n = corners.len();
                hits.resize_with(n, HitPacket::default);
                shaded.resize_with(n, SampleRows::default);
                for (rays, hits) in rays.iter().zip(hits.iter_mut()) {
                    world.intersect_packet(super::RayKind::Camera, &rays.packet, hits);
                }
                let packets: Vec<(&PrimaryRays, &HitPacket)> = rays.iter().zip(hits.iter()).collect();
                shade_packets(frame, &packets, shaded);
                for (((&(x0, y0), rays), cams), samples) in
                    corners.iter().zip(rays.iter()).zip(cameras.iter()).zip(shaded.iter())
                {
                    let packet = &rays.packet;
                    let first = i == 0 && j == 0;
                    let midpoints = (first && world.options.depth_filter == super::DepthFilter::Midpoint)
                        .then(|| midpoint_distances(world, packet, samples));
                    let s = samples;
                    for lane in (0..PACKET_SIZE).filter(|l| packet.active >> l & 1 != 0) {
                        let (dx, dy) = packet_lane_offset(lane);
                        let (x, y) = (x0 + dx - tile.x0, y0 + dy - tile.y0);
                        if x >= tile.width || y >= tile.height {
                            continue;
                        }
                        let k = (y * tile.width + x) as usize;
                        let rgba = [s.color[0][lane], s.color[1][lane], s.color[2][lane], s.alpha[lane]];
                        for (c, v) in px.color[k].iter_mut().zip(rgba) {
                            *c += v;
                        }
                        splat(cams.samples[lane].raster, rgba);
                        if let Some(o) = px.outputs.get_mut(k) {
                            add_outputs(o, &s.outputs(lane));
                        }
                        // The first sample a pixel takes (rank 0: cell (0, 0)).
                        if first {
                            // Camera-space depth: the distance along the ray times its cosine
                            // with the view axis.
                            let direction = Vec3A::new(packet.dx.0[lane], packet.dy.0[lane], packet.dz.0[lane]);
                            let distance = midpoints.as_ref().map_or(s.depth[lane], |m| m[lane]);
                            px.depth[k] = distance * direction.dot(sampling.forward);
                            px.ids[k] = s.object_id[lane];
                            px.shader_ids[k] = s.shader_id[lane];
                            if let Some(n) = px.normals.get_mut(k) {
                                *n = [s.normal[0][lane], s.normal[1][lane], s.normal[2][lane]];
                            }
                        }
                    }
                }
            }
        }
    });
    // The sums into means (a pixel of one sample is its mean already).
    if !takes.is_empty() || sx * sy != 1 {
        for (k, c) in px.color.iter_mut().enumerate() {
            let scale = 1.0 / takes.get(k).copied().unwrap_or(sx * sy) as f32;
            for v in c.iter_mut() {
                *v *= scale;
            }
            for v in px.outputs.get_mut(k).into_iter().flatten().flatten() {
                *v *= scale;
            }
        }
    }
    if let Some((threshold, extra)) = sampling.adaptive {
        let relevance = if sampling.by_relevance { tile_relevance(world, tile) } else { Vec::new() };
        refine_tile(frame, tile, (threshold, &relevance), extra, &mut px, &mut splat);
    }
    px
}

/// The relevance ([`RELEVANCE`], clamped to [0, 1]) of each pixel of a tile, rows from the top.
fn tile_relevance(world: &World, tile: &Tile) -> Vec<f32> {
    let params = &world.options.ray_parameters;
    let size = (world.options.width, world.options.height);
    let mut out = Vec::with_capacity((tile.width * tile.height) as usize);
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            let r = params.float_at(RELEVANCE, Some((x, y)), size);
            out.push(super::ray_params::relevance(r.map(RayValue::Float).as_ref()));
        }
    }
    out
}

/// Runs the pixel shader over a tile's finished colours (`image`: the whole image, for a pixel
/// shader that reads other pixels).
fn shade_tile_pixels(frame: &Frame, tile: &Tile, px: &mut TileSamples, image: Option<&PixelImage>) {
    shade_pixels(
        frame,
        TilePixels {
            x0: tile.x0,
            y0: tile.y0,
            width: tile.width,
            rgba: &mut px.color,
            depth: &px.depth,
            object_id: &px.ids,
            shader_id: &px.shader_ids,
        },
        image,
    );
}

/// The image of finished tiles before the pixel shader, for a pixel shader that reads it; the
/// tiles' kept outputs are those `captured` names.
fn pixel_image((w, h): (u32, u32), captured: &[String], tiles: &[(Tile, TileSamples)]) -> PixelImage {
    let n = w as usize * h as usize;
    let mut image = PixelImage {
        width: w,
        height: h,
        rgba: vec![[0.0; 4]; n],
        depth: vec![f32::INFINITY; n],
        object_id: vec![u32::MAX; n],
        shader_id: vec![u32::MAX; n],
        normal: vec![[0.0; 3]; n],
        outputs: captured.iter().map(|name| (name.clone(), vec![[0.0; 3]; n])).collect(),
    };
    for (tile, px) in tiles {
        for row in 0..tile.height {
            let (y, from) = (tile.y0 + row, (row * tile.width) as usize);
            let to = (y * w + tile.x0) as usize;
            let k = tile.width as usize;
            if y >= h || tile.x0 + tile.width > w || from + k > px.color.len() {
                continue;
            }
            image.rgba[to..to + k].copy_from_slice(&px.color[from..from + k]);
            image.depth[to..to + k].copy_from_slice(&px.depth[from..from + k]);
            image.object_id[to..to + k].copy_from_slice(&px.ids[from..from + k]);
            image.shader_id[to..to + k].copy_from_slice(&px.shader_ids[from..from + k]);
            if let Some(normals) = px.normals.get(from..from + k) {
                image.normal[to..to + k].copy_from_slice(normals);
            }
            if let Some(kept) = px.outputs.get(from..from + k) {
                for (o, (_, values)) in image.outputs.iter_mut().enumerate() {
                    for (value, pixel) in values[to..to + k].iter_mut().zip(kept) {
                        *value = pixel[o];
                    }
                }
            }
        }
    }
    image
}

/// Renders a frame with the threads of the current rayon pool. `progress` is told how many tiles
/// are done after each tile.
pub fn render_frame(world: &World, progress: Option<&(dyn Fn(usize, usize) + Sync)>) -> (Framebuffer, FrameReport) {
    let start = Instant::now();
    let renderer = TileRenderer::new(world);
    renderer.prepare_light_paths();
    let (w, h) = (world.options.width, world.options.height);
    let total = crate::tiles::tiles(w, h, TILE_SIZE).len();
    let progress = Progress { report: progress, done: AtomicUsize::new(0), total };
    let tile_ns: Vec<AtomicU64> = (0..total).map(|_| AtomicU64::new(0)).collect();
    let timed = |tile: &Tile, render: &mut dyn FnMut()| {
        let began = Instant::now();
        render();
        if let Some(ns) = tile_ns.get(tile.index) {
            ns.store(began.elapsed().as_nanos().try_into().unwrap_or(u64::MAX), Ordering::Relaxed);
        }
    };
    let tile_times = || tile_ns.iter().map(|ns| Duration::from_nanos(ns.load(Ordering::Relaxed))).collect();
    if renderer.assembles_as_tiles_arrive() {
        // Each tile goes into the image on the thread that rendered it, while its pixels are in
        // that core's cache: no tile is kept, and no pass over the image follows the last one.
        let exposure = frame_exposure(world);
        let mut fb = blank_framebuffer((w, h));
        let bands = Bands::of(&mut fb, world.options.depth_and_ids);
        render_tiles(w, h, TILE_SIZE, |tile| {
            timed(tile, &mut || {
                let rendered = renderer.render_tile(tile);
                bands.write(rendered.tile, &rendered.px, exposure);
            });
            progress.tile_done();
        });
        let report = FrameReport { tile_times: tile_times(), ..frame_report(&renderer.frame, start) };
        return (fb, report);
    }
    let tiles = render_tiles(w, h, TILE_SIZE, |tile| {
        let mut rendered = None;
        timed(tile, &mut || rendered = Some(renderer.render_tile(tile)));
        progress.tile_done();
        rendered
    });
    let (fb, report) = renderer.finish(tiles.into_iter().flatten().collect(), start);
    (fb, FrameReport { tile_times: tile_times(), ..report })
}

/// The frame's exposure (gain and gamma), where it has a valid one.
pub(super) fn frame_exposure(world: &World) -> Option<(f32, f32)> {
    world.options.exposure.filter(|&(gain, gamma)| gain.is_finite() && gamma > 0.0)
}

/// A finished pixel's colour under the exposure `(gain, gamma)` (alpha untouched): every path that
/// writes a framebuffer applies it here, so that their images are the same bit for bit.
#[inline]
pub(super) fn expose(c: &mut [f32; 4], (gain, gamma): (f32, f32)) {
    for v in &mut c[..3] {
        *v = (gain * *v).max(0.0).powf(1.0 / gamma);
    }
}

/// A framebuffer's bands of `TILE_SIZE` rows, each behind a lock, for the threads that render its
/// tiles to write them in as they finish: tiles of the renderer's tiling lie in one band each, so
/// two threads wait for each other only when both finish a tile of one band at once.
struct Bands<'a> {
    bands: Vec<std::sync::Mutex<BandOut<'a>>>,
}

impl<'a> Bands<'a> {
    fn of(fb: &'a mut Framebuffer, depth_and_ids: bool) -> Bands<'a> {
        let (width, band) = (fb.width as usize, TILE_SIZE as usize);
        let chunk = (width * band).max(1);
        let rgba = fb.rgba.chunks_mut(4 * chunk);
        let depth = fb.depth.chunks_mut(chunk);
        let ids = fb.object_id.chunks_mut(chunk);
        let bands = rgba
            .zip(depth)
            .zip(ids)
            .enumerate()
            .map(|(b, ((rgba, depth), ids))| {
                std::sync::Mutex::new(BandOut { rgba, depth, ids, width, y0: b * band, depth_and_ids })
            })
            .collect();
        Bands { bands }
    }

    /// Writes the finished pixels of `tile` into its band.
    fn write(&self, tile: Tile, px: &TileSamples, exposure: Option<(f32, f32)>) {
        let band = TILE_SIZE as usize;
        let (first, last) = (tile.y0 as usize / band, (tile.y0 + tile.height).max(1) as usize - 1);
        if last / band != first {
            // Band by band, each taking the rows it holds (`write_tile` skips the others).
            for b in first..=(last / band).min(self.bands.len().saturating_sub(1)) {
                self.write_into(b, tile, px, exposure);
            }
            return;
        }
        self.write_into(first, tile, px, exposure);
    }

    fn write_into(&self, b: usize, tile: Tile, px: &TileSamples, exposure: Option<(f32, f32)>) {
        let Some(band) = self.bands.get(b) else { return };
        // A poisoned lock means a thread panicked while writing; the render re-raises that panic.
        let mut out = band.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        write_tile(&mut out, &tile, px, exposure);
    }
}

/// A frame cut into tiles that are rendered one by one, wherever they are rendered (this
/// process's threads, or other processes that render the same world: `crate::distributed`), and
/// then put together by [`TileRenderer::finish`].
pub struct TileRenderer<'w> {
    frame: Frame<'w>,
    sampling: Sampling,
    /// The pixel shader reads other pixels: it runs in `finish`, over the whole image.
    pixels_later: bool,
}

/// A tile as rendered: its pixels (under the default box 1x1 filter finished, pixel shader
/// included; under any other filter the means of their own samples) and, under any other filter,
/// its samples' splats.
pub struct RenderedTile {
    pub tile: Tile,
    px: TileSamples,
    film: Option<TileFilm>,
    /// The pixel shader has yet to run (over the whole image: it reads other pixels).
    pixels_later: bool,
    /// Its encoding carries depths and object ids: always, but for a tile that goes straight
    /// into an image that keeps neither ([`super::RenderOptions::depth_and_ids`]).
    sends_depth_and_ids: bool,
}

impl RenderedTile {
    /// Appends the tile's pixels (and film) to `out`: colours, depths and object ids (left out
    /// where the image that assembles the tile keeps neither), then a byte
    /// that says whether the tile is unfinished (filtered on the master, or its pixel shader run
    /// there over the whole image), and if it is, its shader ids (for the pixel shader), its
    /// normals where the pixel shader reads other pixels (three floats a pixel), and its film's
    /// sums. Values are copied
    /// as they lie in memory (the processes that exchange tiles run one build on one kind of
    /// machine: `crate::distributed` checks), so a tile costs a few copies of its bytes. The tile
    /// itself is not written: whoever decodes knows which tile it asked for.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let px = &self.px;
        let film: &[[f32; 5]] = self.film.as_ref().map_or(&[], |f| f.sums());
        out.reserve(4 * (7 * px.depth.len() + 3 * px.normals.len() + 5 * film.len()) + 1);
        out.extend_from_slice(bytemuck::cast_slice(&px.color));
        if self.sends_depth_and_ids {
            out.extend_from_slice(bytemuck::cast_slice(&px.depth));
            out.extend_from_slice(bytemuck::cast_slice(&px.ids));
        }
        // The kept outputs, where the frame keeps any (both sides know from the world).
        out.extend_from_slice(bytemuck::cast_slice(&px.outputs));
        // 0: finished; 1: a film follows, and the shader ids the pixel shader reads after
        // filtering; 2: the shader ids alone (the pixel shader runs over the whole image).
        let kind = match (&self.film, self.pixels_later) {
            (Some(_), _) => 1,
            (None, true) => 2,
            (None, false) => 0,
        };
        out.push(kind);
        if kind != 0 {
            out.extend_from_slice(bytemuck::cast_slice(&px.shader_ids));
            if self.pixels_later {
                out.extend_from_slice(bytemuck::cast_slice(&px.normals));
            }
            out.extend_from_slice(bytemuck::cast_slice(film));
        }
    }

    /// The tile that [`RenderedTile::encode`] wrote to `bytes`, for `tile` of a frame of `world`
    /// (its pixel filter says whether a film follows and how large it is); an error unless the
    /// bytes hold exactly that.
    pub fn decode(world: &World, tile: Tile, bytes: &[u8]) -> Result<RenderedTile, String> {
        let n = tile.width as usize * tile.height as usize;
        let short = || format!("tile {} arrived short: {} bytes for {n} pixels", tile.index, bytes.len());
        let mut rest = bytes;
        let mut values = |count: usize| -> Result<&[u8], String> {
            let bytes_needed = 4 * count;
            let (head, tail) = rest.split_at_checked(bytes_needed).ok_or_else(short)?;
            rest = tail;
            Ok(head)
        };
        let options = &world.options;
        let pixels_later = reads_pixels(world);
        let mut px = TileSamples::empty(&tile, pixels_later);
        bytemuck::cast_slice_mut::<[f32; 4], u8>(&mut px.color).copy_from_slice(values(4 * n)?);
        bytemuck::cast_slice_mut::<f32, u8>(&mut px.depth).copy_from_slice(values(n)?);
        bytemuck::cast_slice_mut::<u32, u8>(&mut px.ids).copy_from_slice(values(n)?);
        if !captured_outputs(world).is_empty() {
            px.outputs = vec![[[0.0; 3]; MAX_FRAME_OUTPUTS]; n];
            bytemuck::cast_slice_mut::<Outputs, u8>(&mut px.outputs)
                .copy_from_slice(values(3 * MAX_FRAME_OUTPUTS * n)?);
        }
        // The shader ids, and the normals where the pixel shader reads other pixels.
        let mut unfinished = |rest: &[u8]| -> Result<usize, String> {
            let normals = if pixels_later { 12 * n } else { 0 };
            if rest.len() < 4 * n + normals {
                return Err(short());
            }
            bytemuck::cast_slice_mut::<u32, u8>(&mut px.shader_ids).copy_from_slice(&rest[..4 * n]);
            let into: &mut [u8] = bytemuck::cast_slice_mut(&mut px.normals);
            into.copy_from_slice(&rest[4 * n..4 * n + normals]);
            // Unit or zero: anything longer (or not a number) is damage.
            let damaged = |v: &[f32; 3]| {
                let length_squared = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                length_squared.is_nan() || length_squared > 1.01
            };
            if px.normals.iter().any(damaged) {
                return Err(format!("tile {}: its normals are damaged", tile.index));
            }
            Ok(4 * n + normals)
        };
        let film = match (rest.split_first(), options.pixel_filter.is_unit_box()) {
            (Some((0, [])), true) if !pixels_later => None,
            (Some((2, ids)), true) if pixels_later => {
                if unfinished(ids)? != ids.len() {
                    return Err(short());
                }
                None
            }
            (Some((1, ids)), false) => {
                let sums = &ids[unfinished(ids)?..];
                let mut film = TileFilm::new(options.pixel_filter, &tile, options.pixel_range());
                let into: &mut [u8] = bytemuck::cast_slice_mut(film.sums_mut());
                if sums.len() != into.len() {
                    return Err(format!("tile {}: its film does not match the frame's pixel filter", tile.index));
                }
                into.copy_from_slice(sums);
                Some(film)
            }
            _ => return Err(format!("tile {}: its pixels do not match the frame's pixel filter", tile.index)),
        };
        Ok(RenderedTile { tile, px, film, pixels_later, sends_depth_and_ids: true })
    }
}

/// A frame's image put together as its tiles arrive, encoded ([`RenderedTile::encode`]), from
/// renderers elsewhere (a distributed master's workers): each tile goes straight into the
/// framebuffer, so no tile is kept and nothing is left to assemble after the last one. Only for
/// frames whose tiles are final where they are rendered ([`TileRenderer::assembles_as_tiles_arrive`]);
/// the image is bit for bit [`TileRenderer::finish`]'s.
pub struct TileAssembly {
    /// Made when the first tile arrives, not before: the renderers elsewhere have started by then.
    fb: Option<Framebuffer>,
    size: (u32, u32),
    exposure: Option<(f32, f32)>,
    /// The image keeps depths and object ids, and the tiles carry them.
    depth_and_ids: bool,
}

impl TileAssembly {
    /// Writes the tile `tile` that `bytes` encodes into the image; an error unless the bytes hold
    /// exactly a finished tile of that size.
    pub fn add(&mut self, tile: Tile, bytes: &[u8]) -> Result<(), String> {
        let n = tile.width as usize * tile.height as usize;
        let expected = if self.depth_and_ids { 4 * 6 * n + 1 } else { 4 * 4 * n + 1 };
        if bytes.len() != expected || bytes.last() != Some(&0) {
            return Err(format!(
                "tile {}: {} bytes where a finished tile of {n} pixels takes {expected}",
                tile.index,
                bytes.len()
            ));
        }
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        let (x0, tw) = (tile.x0 as usize, tile.width as usize);
        if x0 + tw > w || tile.y0 as usize + tile.height as usize > h {
            return Err(format!("tile {} lies outside the {w}x{h} image", tile.index));
        }
        let exposure = self.exposure;
        let fb = self.fb.get_or_insert_with(|| Framebuffer::new(w as u32, h as u32));
        // Rows go in as the bytes lie: they need not be aligned for `f32`s where they sit in a
        // message, and a plain copy of a row is what the framebuffer takes.
        let (colors, rest) = bytes.split_at(16 * n);
        // Depths and ids, when the tiles carry them (the length checked above says they do).
        let (depths, ids) = rest.split_at(if self.depth_and_ids { 4 * n } else { 0 });
        for y in 0..tile.height as usize {
            let (from, to) = (y * tw, (tile.y0 as usize + y) * w + x0);
            let rgba = &mut fb.rgba[4 * to..4 * (to + tw)];
            let row = &colors[16 * from..16 * (from + tw)];
            match exposure {
                None => bytemuck::cast_slice_mut::<f32, u8>(rgba).copy_from_slice(row),
                Some(exposure) => {
                    for (c, out) in row.chunks_exact(16).zip(rgba.chunks_exact_mut(4)) {
                        let mut c: [f32; 4] = bytemuck::pod_read_unaligned(c);
                        expose(&mut c, exposure);
                        out.copy_from_slice(&c);
                    }
                }
            }
            if self.depth_and_ids {
                let depth = bytemuck::cast_slice_mut::<f32, u8>(&mut fb.depth[to..to + tw]);
                depth.copy_from_slice(&depths[4 * from..4 * (from + tw)]);
                let id = bytemuck::cast_slice_mut::<u32, u8>(&mut fb.object_id[to..to + tw]);
                id.copy_from_slice(&ids[4 * from..4 * (from + tw)]);
            }
        }
        Ok(())
    }

    /// The image, and what the frame cost since `start` by `renderer`'s counters.
    pub fn finish(self, renderer: TileRenderer, start: Instant) -> (Framebuffer, FrameReport) {
        let fb = self.fb.unwrap_or_else(|| Framebuffer::new(self.size.0, self.size.1));
        (fb, frame_report(&renderer.frame, start))
    }
}

impl<'w> TileRenderer<'w> {
    pub fn new(world: &'w World) -> TileRenderer<'w> {
        TileRenderer { frame: Frame::new(world), sampling: Sampling::of(world), pixels_later: reads_pixels(world) }
    }

    /// Traces the frame's light paths (virtual lights, caustic photons) on the current rayon
    /// pool's threads, where its options ask for them: call it before rendering tiles, so that
    /// no tile's thread waits while another traces them alone. Not on a thread that must answer
    /// the render threads' requests meanwhile (a distributed worker's talking thread: the paths'
    /// rays may reach meshes it has to fetch); without it, the first thread that needs the paths
    /// traces them.
    pub fn prepare_light_paths(&self) {
        super::virtual_lights::prepare(&self.frame);
    }

    /// The light paths the frame has traced so far (all of them after
    /// [`TileRenderer::prepare_light_paths`]).
    pub fn light_paths(&self) -> LightPaths {
        LightPaths::of(&self.frame)
    }

    /// Gives the frame light paths traced elsewhere for the same world, seed and options (a
    /// distributed master's), before any tile is rendered; returns whether it took any.
    pub fn use_light_paths(&self, paths: &LightPaths) -> bool {
        paths.lend(&self.frame)
    }

    /// Whether the frame's tiles are final where they are rendered (the box filter, no pixel
    /// shader reading other pixels, no kept outputs), so that a [`TileAssembly`] can put the image
    /// together as they arrive.
    pub fn assembles_as_tiles_arrive(&self) -> bool {
        let options = &self.frame.world.options;
        options.pixel_filter.is_unit_box() && !self.pixels_later && captured_outputs(self.frame.world).is_empty()
    }

    /// The quarters of `tile` that, each rendered by [`TileRenderer::render_tile`] apart, give
    /// exactly the pixels the whole tile gives: those of a whole tile (each quarter a whole number
    /// of packets of rays) of a frame whose tiles are final where they are rendered and take no
    /// adaptive samples (which compare each pixel with its neighbours in the tile). `None` for
    /// other tiles and frames.
    pub fn quarters(&self, tile: &Tile) -> Option<[Tile; 4]> {
        let whole = tile.width == TILE_SIZE && tile.height == TILE_SIZE;
        let packets = (TILE_SIZE / 2) % PACKET_SIDE == 0;
        let alike = self.sampling.adaptive.is_none() && self.assembles_as_tiles_arrive();
        (whole && packets && alike).then(|| tile.quarters()).flatten()
    }

    /// An empty image to put this frame's tiles into as they arrive, where
    /// [`TileRenderer::assembles_as_tiles_arrive`].
    pub fn start_assembly(&self) -> Option<TileAssembly> {
        if !self.assembles_as_tiles_arrive() {
            return None;
        }
        let world = self.frame.world;
        let exposure = world.options.exposure.filter(|&(gain, gamma)| gain.is_finite() && gamma > 0.0);
        let size = (world.options.width, world.options.height);
        Some(TileAssembly { fb: None, size, exposure, depth_and_ids: world.options.depth_and_ids })
    }

    /// The frame being rendered (its world and its counters).
    pub fn frame(&self) -> &Frame<'w> {
        &self.frame
    }

    /// What the tiles rendered so far cost since `start`, by this frame's counters.
    pub fn report(&self, start: Instant) -> FrameReport {
        frame_report(&self.frame, start)
    }

    /// The frame's tiles, in tile order.
    pub fn tiles(&self) -> Vec<Tile> {
        let options = &self.frame.world.options;
        crate::tiles::tiles(options.width, options.height, TILE_SIZE)
    }

    /// Traces and shades every sample of `tile`. Under the box filter each pixel is the mean of
    /// its own samples, so the tile is finished (pixel shader included) here; under any other
    /// filter its samples are splatted into a film of its own, for [`TileRenderer::finish`].
    pub fn render_tile(&self, tile: &Tile) -> RenderedTile {
        let options = &self.frame.world.options;
        if options.pixel_filter.is_unit_box() {
            let mut px = sample_tile(&self.frame, tile, &self.sampling, |_, _| {});
            if !self.pixels_later {
                shade_tile_pixels(&self.frame, tile, &mut px, None);
            }
            let sends_depth_and_ids = options.depth_and_ids || !self.assembles_as_tiles_arrive();
            RenderedTile { tile: *tile, px, film: None, pixels_later: self.pixels_later, sends_depth_and_ids }
        } else {
            let mut film = TileFilm::new(options.pixel_filter, tile, options.pixel_range());
            let px = sample_tile(&self.frame, tile, &self.sampling, |raster, rgba| film.splat(raster, rgba));
            RenderedTile {
                tile: *tile,
                px,
                film: Some(film),
                pixels_later: self.pixels_later,
                sends_depth_and_ids: true,
            }
        }
    }

    /// The image of every tile of the frame, rendered by [`TileRenderer::render_tile`] (in tile
    /// order), and what the frame cost since `start` by this process's counters. Under a filter
    /// other than the box, the films are added up in tile order (so the sums do not depend on
    /// who rendered which tile), then each pixel gets its filtered value (its own samples' mean
    /// where too little weight reached it, as outside the crop window) and the pixel shader runs
    /// on that.
    pub fn finish(self, tiles: Vec<RenderedTile>, start: Instant) -> (Framebuffer, FrameReport) {
        let world = self.frame.world;
        let tiles = if world.options.pixel_filter.is_unit_box() {
            tiles.into_iter().map(|t| (t.tile, t.px)).collect()
        } else {
            let mut film = Film::new(&world.options.pixel_filter, world.options.width, world.options.height);
            for t in &tiles {
                if let Some(tile_film) = &t.film {
                    film.add(tile_film);
                }
            }
            let mut tiles: Vec<(Tile, TileSamples)> = tiles.into_iter().map(|t| (t.tile, t.px)).collect();
            tiles.par_iter_mut().for_each(|(tile, px)| {
                resolve_tile(&film, tile, &mut px.color);
                if !self.pixels_later {
                    shade_tile_pixels(&self.frame, tile, px, None);
                }
            });
            tiles
        };
        let mut tiles = tiles;
        if self.pixels_later {
            let size = (world.options.width, world.options.height);
            let image = pixel_image(size, &self.frame.captured, &tiles);
            tiles.par_iter_mut().for_each(|(tile, px)| shade_tile_pixels(&self.frame, tile, px, Some(&image)));
        }
        let fb = framebuffer(world, tiles);
        (fb, frame_report(&self.frame, start))
    }
}

/// Replaces the colours of a tile's pixels by their filtered values where they have one.
fn resolve_tile(film: &Film, tile: &Tile, color: &mut [[f32; 4]]) {
    for (k, c) in color.iter_mut().enumerate() {
        let (x, y) = (tile.x0 + k as u32 % tile.width, tile.y0 + k as u32 / tile.width);
        if let Some(filtered) = film.resolve(x, y) {
            *c = filtered;
        }
    }
}

/// The image of finished tiles, with the frame's exposure applied. Written band by band of
/// `TILE_SIZE` rows, in parallel, since by one thread after the tiles, filling the frame (and faulting
/// in its fresh pages) would be serial time in every frame.
fn framebuffer(world: &World, tiles: Vec<(Tile, TileSamples)>) -> Framebuffer {
    let exposure = frame_exposure(world);
    let (w, h) = (world.options.width, world.options.height);
    // The kept outputs the options name (not the one adaptive sampling alone refines on).
    let names: Vec<String> =
        captured_outputs(world).into_iter().filter(|n| world.options.outputs.contains(n)).collect();
    let mut outputs: Vec<(String, Vec<[f32; 3]>)> =
        names.into_iter().map(|n| (n, vec![[0.0; 3]; w as usize * h as usize])).collect();
    if !outputs.is_empty() {
        for (tile, px) in &tiles {
            for (k, o) in px.outputs.iter().enumerate() {
                let (x, y) = (tile.x0 + k as u32 % tile.width.max(1), tile.y0 + k as u32 / tile.width.max(1));
                if x >= w || y >= h {
                    continue;
                }
                for (i, (_, image)) in outputs.iter_mut().enumerate() {
                    image[(y * w + x) as usize] = o[i];
                }
            }
        }
    }
    let mut fb = assemble_framebuffer((w, h), tiles, exposure, world.options.depth_and_ids);
    fb.outputs = outputs;
    fb
}

/// [`framebuffer`] of a `w x h` image.
fn assemble_framebuffer(
    (w, h): (u32, u32),
    tiles: Vec<(Tile, TileSamples)>,
    exposure: Option<(f32, f32)>,
    depth_and_ids: bool,
) -> Framebuffer {
    // `par_chunks_mut` panics on chunks of 0 elements (an image 0 pixels wide).
    let (width, band) = (w as usize, TILE_SIZE as usize);
    let chunk = (width * band).max(1);
    let mut fb = blank_framebuffer((w, h));
    let bands = (h as usize).div_ceil(band).max(1);
    let mut by_band: Vec<Vec<(Tile, TileSamples)>> = (0..bands).map(|_| Vec::new()).collect();
    let mut others = Vec::new();
    for (tile, px) in tiles {
        let (first, last) = (tile.y0 as usize / band, (tile.y0 + tile.height).max(1) as usize - 1);
        match by_band.get_mut(first) {
            Some(b) if last / band == first => b.push((tile, px)),
            _ => others.push((tile, px)),
        }
    }
    let rgba = fb.rgba.par_chunks_mut(4 * chunk);
    let depth = fb.depth.par_chunks_mut(chunk);
    let ids = fb.object_id.par_chunks_mut(chunk);
    rgba.zip(depth).zip(ids).zip(by_band).enumerate().for_each(|(b, (((rgba, depth), ids), tiles))| {
        write_tiles(BandOut { rgba, depth, ids, width, y0: b * band, depth_and_ids }, tiles, exposure);
    });
    // Tiles that straddle bands (none from the renderer's own tiling) go in one by one.
    let (rgba, depth, ids) = (&mut fb.rgba[..], &mut fb.depth[..], &mut fb.object_id[..]);
    write_tiles(BandOut { rgba, depth, ids, width, y0: 0, depth_and_ids }, others, exposure);
    fb
}

/// A `w x h` framebuffer with no pixel written yet, filled on the current pool's threads (by one
/// thread, filling the image and faulting in its fresh pages would be serial time in every frame).
fn blank_framebuffer((w, h): (u32, u32)) -> Framebuffer {
    let n = w as usize * h as usize;
    Framebuffer {
        width: w,
        height: h,
        rgba: (0..4 * n).into_par_iter().map(|_| 0.0).collect(),
        depth: (0..n).into_par_iter().map(|_| f32::INFINITY).collect(),
        object_id: (0..n).into_par_iter().map(|_| u32::MAX).collect(),
        outputs: Vec::new(),
    }
}

/// Rows of the framebuffer from row `y0` on.
struct BandOut<'a> {
    rgba: &'a mut [f32],
    depth: &'a mut [f32],
    ids: &'a mut [u32],
    width: usize,
    y0: usize,
    /// Whether depth and object ids are written ([`super::RenderOptions::depth_and_ids`]).
    depth_and_ids: bool,
}

/// Writes finished tiles into `out`, which holds their rows.
fn write_tiles(mut out: BandOut<'_>, tiles: Vec<(Tile, TileSamples)>, exposure: Option<(f32, f32)>) {
    for (tile, px) in tiles {
        write_tile(&mut out, &tile, &px, exposure);
    }
}

/// Writes the rows of a finished tile that `out` holds.
fn write_tile(out: &mut BandOut<'_>, tile: &Tile, px: &TileSamples, exposure: Option<(f32, f32)>) {
    let tw = tile.width as usize;
    for y in 0..tile.height as usize {
        let Some(row) = (tile.y0 as usize + y).checked_sub(out.y0) else { continue };
        // A row of the tile at a time, as slices, not pixel by pixel with a bounds check per
        // pixel and buffer.
        let (from, to) = (y * tw, row * out.width + tile.x0 as usize);
        let (Some(colors), Some(rgba)) = (px.color.get(from..from + tw), out.rgba.get_mut(4 * to..4 * (to + tw)))
        else {
            continue;
        };
        for (c, rgba) in colors.iter().zip(rgba.chunks_exact_mut(4)) {
            let mut c = *c;
            if let Some(exposure) = exposure {
                expose(&mut c, exposure);
            }
            rgba.copy_from_slice(&c);
        }
        if !out.depth_and_ids {
            continue;
        }
        if let (Some(d), Some(v)) = (out.depth.get_mut(to..to + tw), px.depth.get(from..from + tw)) {
            d.copy_from_slice(v);
        }
        if let (Some(d), Some(v)) = (out.ids.get_mut(to..to + tw), px.ids.get(from..from + tw)) {
            d.copy_from_slice(v);
        }
    }
}

/// What the frame cost, from its counters.
pub(crate) fn frame_report(frame: &Frame, start: Instant) -> FrameReport {
    let world = frame.world;
    let s = &frame.stats;
    let load = |c: &super::stats::Counter| c.load();
    FrameReport {
        elapsed: start.elapsed(),
        primary_rays: load(&s.primary_rays),
        shadow_rays: load(&s.shadow_rays),
        secondary_rays: load(&s.secondary_rays),
        transparency_rays: load(&s.transparency_rays),
        shaded_points: load(&s.shaded_points),
        light_evaluations: load(&s.light_evaluations),
        rays_cut: load(&s.rays_cut),
        lights_dropped: load(&s.lights_dropped),
        shading: Duration::from_nanos(s.shading_ns()),
        by_kind: s.kind_ns().map(Duration::from_nanos),
        by_shader: {
            let programs = s.program_ns();
            let mut v: Vec<_> =
                programs.iter().map(|(p, ns)| (p.name.clone(), p.kind, Duration::from_nanos(*ns))).collect();
            v.sort_by(|a, b| b.2.cmp(&a.2).then_with(|| a.0.cmp(&b.0)));
            v
        },
        threads: rayon::current_num_threads(),
        shader_messages: world.shader_messages(),
        accel: world.accel,
        light_paths: Duration::from_nanos(s.light_paths_ns.load()),
        gathering: Duration::from_nanos(s.gathering_ns.load()),
        tile_times: Vec::new(),
    }
}

/// The midpoint depth filter's distance along each active lane's ray of `packet`
/// ([`super::DepthFilter::Midpoint`]): halfway between the surface its sample met (at
/// `samples[lane].depth`, facing `samples[lane].normal`) and the next one behind it, found by a
/// ray that goes on from just behind the first; infinite where the ray met nothing or nothing
/// lies behind. A sample with no normal (a holdout's) keeps its own depth.
fn midpoint_distances(world: &World, packet: &RayPacket, samples: &SampleRows) -> [f32; PACKET_SIZE] {
    let mut distances = samples.depth;
    let mut lanes = Vec::new();
    let mut rays = Vec::new();
    for (lane, &depth) in samples.depth.iter().enumerate() {
        let normal = samples.normal(lane);
        if packet.active >> lane & 1 == 0 || !depth.is_finite() || normal == Vec3A::ZERO {
            continue;
        }
        let ray = packet.get(lane);
        let behind = crate::ray::offset_ray_origin(ray.at(depth), -normal);
        lanes.push(lane);
        rays.push(Ray::new(behind, ray.direction).at_time(ray.time));
    }
    let mut hits = Vec::new();
    world.intersect_rays(super::RayKind::Camera, &rays, &mut hits);
    for (&lane, hit) in lanes.iter().zip(&hits) {
        distances[lane] = if hit.is_hit() { samples.depth[lane] + 0.5 * hit.t } else { f32::INFINITY };
    }
    distances
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiles of `tw x th` pixels over a `w x h` image, each pixel holding its own coordinates.
    fn tiles_of((w, h): (u32, u32), (tw, th): (u32, u32)) -> Vec<(Tile, TileSamples)> {
        let mut tiles = Vec::new();
        for y0 in (0..h).step_by(th as usize) {
            for x0 in (0..w).step_by(tw as usize) {
                let tile = Tile { index: tiles.len(), x0, y0, width: tw.min(w - x0), height: th.min(h - y0) };
                let mut px = TileSamples::empty(&tile, true);
                for y in 0..tile.height {
                    for x in 0..tile.width {
                        let k = (y * tile.width + x) as usize;
                        let (gx, gy) = (x0 + x, y0 + y);
                        px.color[k] = [gx as f32, gy as f32, 1.0, 0.5];
                        px.depth[k] = (gx + 1000 * gy) as f32;
                        px.ids[k] = gx + 1000 * gy;
                        px.shader_ids[k] = gx + 2000 * gy;
                        px.normals[k] = [gx as f32, gy as f32, -1.0];
                    }
                }
                tiles.push((tile, px));
            }
        }
        tiles
    }

    #[test]
    fn every_tile_lands_at_its_place_in_bands_or_across_them() {
        // The renderer's 16-row tiles, then tiles that straddle the 16-row bands, and a few more
        // shapes; images whose height is not a multiple of 16.
        for (size, tile) in [((40, 37), (16, 16)), ((40, 37), (7, 10)), ((23, 50), (23, 3)), ((5, 16), (16, 16))] {
            let fb = assemble_framebuffer(size, tiles_of(size, tile), None, true);
            for y in 0..size.1 {
                for x in 0..size.0 {
                    let i = (y * size.0 + x) as usize;
                    assert_eq!(fb.pixel(x, y), [x as f32, y as f32, 1.0, 0.5], "{size:?} {tile:?} at ({x}, {y})");
                    assert_eq!(fb.depth[i], (x + 1000 * y) as f32);
                    assert_eq!(fb.object_id[i], x + 1000 * y);
                }
            }
        }
        let empty = assemble_framebuffer((0, 0), Vec::new(), None, true);
        assert!(empty.rgba.is_empty() && empty.depth.is_empty());
    }

    /// Tiles written into bands as they finish, from several threads and in any order (those that
    /// straddle bands too), make the image the assembly after the last tile makes.
    #[test]
    fn tiles_written_as_they_finish_make_the_assembled_image() {
        use rayon::prelude::*;
        for (size, tile) in [((40, 37), (16, 16)), ((40, 37), (7, 10)), ((23, 50), (23, 3)), ((5, 16), (16, 16))] {
            for exposure in [None, Some((2.0, 0.5))] {
                let mut fb = blank_framebuffer(size);
                {
                    let bands = Bands::of(&mut fb, true);
                    tiles_of(size, tile).par_iter().rev().for_each(|(t, px)| bands.write(*t, px, exposure));
                }
                let assembled = assemble_framebuffer(size, tiles_of(size, tile), exposure, true);
                assert_eq!(fb, assembled, "{size:?} {tile:?} {exposure:?}");
            }
        }
    }

    /// A frame rendered with its tiles going into the image as they finish is bit for bit the one
    /// put together after the last tile, for an image whose sides are no multiple of the tile's
    /// and under an exposure.
    #[test]
    fn a_frame_assembled_as_its_tiles_finish_is_the_assembled_frame() {
        let rib = "Format 37 21 1\nExposure 1.5 2.2\nProjection \"perspective\" \"fov\" 50\nTranslate 0 0 4\nWorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\nSphere 1 -1 1 360\nWorldEnd\n";
        let mut rt = crate::api::Context::new();
        crate::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        let renderer = TileRenderer::new(&world);
        assert!(renderer.assembles_as_tiles_arrive());
        let (fb, _) = render_frame(&world, None);
        let tiles: Vec<RenderedTile> = renderer.tiles().iter().map(|t| renderer.render_tile(t)).collect();
        let (assembled, _) = renderer.finish(tiles, Instant::now());
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&fb.rgba), bits(&assembled.rgba));
        assert_eq!(bits(&fb.depth), bits(&assembled.depth));
        assert_eq!(fb.object_id, assembled.object_id);
        assert!(fb.rgba.chunks_exact(4).any(|p| p[0] > 0.0 && p[0] < 1.0), "the sphere was lit and exposed");
    }

    /// Both ways of rendering a frame's tiles (into the image as they finish, and kept for the
    /// frame's filter) report each tile's time, in tile order; a frame assembled elsewhere none.
    #[test]
    fn a_frame_reports_the_time_of_each_of_its_tiles() {
        for filter in ["", "PixelFilter \"gaussian\" 2 2\n"] {
            let rib = format!("Format 70 40 1\n{filter}Projection \"perspective\" \"fov\" 50\nTranslate 0 0 4\nWorldBegin\nSurface \"matte\"\nSphere 1 -1 1 360\nWorldEnd\n");
            let mut rt = crate::api::Context::new();
            crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
            let world = rt.build_world().expect("the test scene builds");
            let renderer = TileRenderer::new(&world);
            assert_eq!(renderer.assembles_as_tiles_arrive(), filter.is_empty());
            let (_, report) = render_frame(&world, None);
            assert_eq!(report.tile_times.len(), renderer.tiles().len(), "{filter}");
            assert!(renderer.tiles().len() > 1);
            let tiles: Vec<RenderedTile> = renderer.tiles().iter().map(|t| renderer.render_tile(t)).collect();
            assert!(renderer.finish(tiles, Instant::now()).1.tile_times.is_empty());
        }
    }

    #[test]
    fn the_pixel_image_holds_every_channel_of_every_tile() {
        for (size, tile) in [((40, 37), (16, 16)), ((23, 50), (23, 3))] {
            let image = pixel_image(size, &[], &tiles_of(size, tile));
            for y in 0..size.1 {
                for x in 0..size.0 {
                    let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                    assert_eq!(image.value("Ci", fx, fy), Some([x as f32, y as f32, 1.0]));
                    assert_eq!(image.value("z", fx, fy), Some([(x + 1000 * y) as f32, 0.0, 0.0]));
                    assert_eq!(image.value("shaderid", fx, fy), Some([(x + 2000 * y) as f32, 0.0, 0.0]));
                    assert_eq!(image.value("N", fx, fy), Some([x as f32, y as f32, -1.0]), "{size:?} ({x}, {y})");
                }
            }
        }
    }

    /// Samples per pixel past `MAX_PIXEL_SAMPLES` (the API's `RenderOptions::samples` is a plain
    /// field) are taken as the cap, and a sample index past a pixel's grid overflows nothing.
    #[test]
    fn sample_counts_past_the_cap_are_the_cap() {
        let rib = "Format 4 4 1\nTranslate 0 0 5\nWorldBegin\nSphere 1 -1 1 360\nWorldEnd\n";
        let mut rt = crate::api::Context::new();
        crate::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>")).expect("the test scene loads");
        rt.options.samples = (u32::MAX, u32::MAX);
        rt.options.antialiasing = Antialiasing::Interleaved;
        let world = rt.build_world().expect("the test scene builds");
        assert_eq!(world.options.pixel_samples(), (64, 64));
        for sample in [(0, 0), (63, 63), (u32::MAX, u32::MAX)] {
            let (jx, jy) = sample_offset(&world, 3, 3, sample);
            assert!((0.0..=1.0).contains(&jx) && (0.0..=1.0).contains(&jy), "{sample:?}: {jx} {jy}");
            let (lanes, _) = camera_samples(&world, 0, 0, sample);
            assert!(lanes.iter().all(|s| s.raster.0.is_finite() && s.raster.1.is_finite()));
        }
    }

    #[test]
    fn exposure_applies_to_colour_not_alpha() {
        let fb = assemble_framebuffer((16, 16), tiles_of((16, 16), (16, 16)), Some((2.0, 0.5)), true);
        // (2 * 3)^(1 / 0.5) = 36, (2 * 1)^2 = 4; alpha untouched.
        assert_eq!(fb.pixel(3, 1), [36.0, 4.0, 4.0, 0.5]);
    }
}

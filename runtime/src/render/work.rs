//! The work items of a frame's shading: the frame itself (the world and what is worked out from
//! it once), a ray's finished sample, a hit waiting to be shaded, and what shading a hit produced.
//! The stages (`primary.rs`, `shade.rs`, `lights.rs`, `volume.rs`, `host.rs`, `trace_ahead.rs`)
//! pass these between them.

use super::jobs::GroupRows;
pub(crate) use super::jobs::Pending;
use super::photon_map::PhotonMap;
use super::ray_budget::RayBudget;
use super::stats::Stats;
use super::world::LightSource;
use super::world::{GiOptions, InstanceShadows, World, MAX_FRAME_OUTPUTS};
use crate::ray::{Ray, PACKET_SIZE};
use glam::{Affine3A, Vec3A};
use rtsl_compiler::abi::{LightLanes, PixelChannel, PixelView};
use std::sync::{Arc, Mutex, PoisonError};
use wide::f32x8;

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
    pub(crate) invariant_light_rows: Vec<std::sync::OnceLock<LightLanes>>,
    /// The frame's virtual point lights, traced when a shader first gathers them
    /// (`virtual_lights.rs`).
    pub(crate) virtual_lights: std::sync::OnceLock<Arc<VirtualLights>>,
    /// The frame's caustic photon map, traced when a shader first looks it up
    /// (`virtual_lights::trace_caustics`).
    pub(crate) caustics: std::sync::OnceLock<Arc<PhotonMap>>,
    /// The frame's global photon map (`virtual_lights::trace_global`).
    pub(crate) global_photons: std::sync::OnceLock<Arc<PhotonMap>>,
    /// Set while `virtual_lights::prepare` traces the light paths: shaders run for them (a light's
    /// shadow rays through surfaces whose shader sets their opacity) then find no photon map and
    /// no virtual lights, rather than waiting on the tracing they are part of.
    pub(crate) tracing_light_paths: std::sync::atomic::AtomicBool,
    /// The seed of the frame's light paths: the options' own, or per pass of progressive
    /// refinement another, so that passes accumulate fresh virtual lights.
    pub(crate) gi_seed: u32,
    /// The output variables primary hits keep ([`Sample::outputs`]): the options' outputs, then
    /// the one adaptive sampling refines on where it is not among them, at most
    /// [`MAX_FRAME_OUTPUTS`].
    pub(crate) captured: Vec<String>,
    /// The stages that shader callbacks reach back into.
    pub(crate) stages: Stages,
}

impl<'w> Frame<'w> {
    /// The frame of `world`, its stages reached through `stages` (`shade.rs` makes the frames
    /// of renders: `Frame::new`).
    pub(crate) fn with_stages(world: &'w World, stages: Stages) -> Frame<'w> {
        let cam = &world.camera;
        let (w, h) = (world.options.width.max(1) as f32, world.options.height.max(1) as f32);
        let tan = (cam.fov_degrees.to_radians() * 0.5).tan();
        let (ax, ay) = world.options.screen_extent().half;
        let m = &cam.world_from_camera.matrix3;
        let transparent_shadows = world.has_transparent_shadows();
        let instance_shadows = if transparent_shadows { world.instance_shadows() } else { Vec::new() };
        Frame {
            world,
            stats: Stats::with_timing(world.options.time_shaders),
            transparent_shadows,
            instance_shadows,
            volumes: world.has_volumes(),
            camera_from_world: cam.world_from_camera.inverse(),
            forward: m.z_axis.normalize_or_zero(),
            pixel_dx: m.x_axis * (2.0 * tan * ax / w),
            pixel_dy: m.y_axis * (-2.0 * tan * ay / h),
            pixel_spread: 2.0 * tan * ay / h,
            invariant_light_rows: world.lights.iter().map(|_| std::sync::OnceLock::new()).collect(),
            virtual_lights: std::sync::OnceLock::new(),
            caustics: std::sync::OnceLock::new(),
            global_photons: std::sync::OnceLock::new(),
            tracing_light_paths: std::sync::atomic::AtomicBool::new(false),
            gi_seed: world.options.gi.seed,
            captured: captured_outputs(world),
            stages,
        }
    }
}

/// The output variables a frame of `world` keeps per sample (see [`Frame::captured`]): the
/// options' outputs, the one adaptive sampling refines on, then those its pixel shader reads
/// (`CompiledShader::pixel_outputs`), at most [`MAX_FRAME_OUTPUTS`].
pub(crate) fn captured_outputs(world: &World) -> Vec<String> {
    let options = &world.options;
    let read = world.pixel.iter().flat_map(|p| p.program.code.pixel_outputs());
    let mut names: Vec<String> = Vec::new();
    for name in options.outputs.iter().chain(options.refine_on.output.iter()).chain(read) {
        if names.len() < MAX_FRAME_OUTPUTS && !names.contains(name) {
            names.push(name.clone());
        }
    }
    names
}

/// The place of the output variable adaptive sampling refines on among those a frame of `world`
/// keeps ([`captured_outputs`]); `None` where it refines on none.
pub(crate) fn refined_output(world: &World) -> Option<usize> {
    let name = world.options.refine_on.output.as_ref()?;
    captured_outputs(world).iter().position(|n| n == name)
}

/// A frame's light paths as traced: its virtual lights and its caustic photon map, each where the
/// frame's options ask for them. A distributed master traces them once and sends them to its
/// workers ([`LightPaths::encode`]), as the paper's master did.
#[derive(Clone, Debug, Default)]
pub struct LightPaths {
    pub virtual_lights: Option<Arc<VirtualLights>>,
    pub caustics: Option<Arc<PhotonMap>>,
    pub global_photons: Option<Arc<PhotonMap>>,
}

/// The most virtual lights or interleaving sets decoded light paths may hold (what the options
/// can ask for, with room to spare).
const MAX_DECODED_LIGHTS: u64 = 1 << 26;

impl LightPaths {
    /// The light paths `frame` has traced so far.
    pub(crate) fn of(frame: &Frame) -> LightPaths {
        LightPaths {
            virtual_lights: frame.virtual_lights.get().cloned(),
            caustics: frame.caustics.get().cloned(),
            global_photons: frame.global_photons.get().cloned(),
        }
    }

    /// Gives `frame` these light paths where it has not traced its own; returns whether it took
    /// any.
    pub(crate) fn lend(&self, frame: &Frame) -> bool {
        let mut lent = false;
        if let Some(v) = &self.virtual_lights {
            lent |= frame.virtual_lights.set(v.clone()).is_ok();
        }
        if let Some(c) = &self.caustics {
            lent |= frame.caustics.set(c.clone()).is_ok();
        }
        if let Some(g) = &self.global_photons {
            lent |= frame.global_photons.set(g.clone()).is_ok();
        }
        lent
    }

    pub fn is_empty(&self) -> bool {
        self.virtual_lights.is_none() && self.caustics.is_none() && self.global_photons.is_none()
    }

    /// Whether `self` and `other` are the same traced paths (not merely equal ones).
    pub fn same(&self, other: &LightPaths) -> bool {
        let same = |a: Option<&Arc<VirtualLights>>, b: Option<&Arc<VirtualLights>>| match (a, b) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (a, b) => a.is_none() && b.is_none(),
        };
        let same_map = |a: Option<&Arc<PhotonMap>>, b: Option<&Arc<PhotonMap>>| match (a, b) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (a, b) => a.is_none() && b.is_none(),
        };
        same(self.virtual_lights.as_ref(), other.virtual_lights.as_ref())
            && same_map(self.caustics.as_ref(), other.caustics.as_ref())
            && same_map(self.global_photons.as_ref(), other.global_photons.as_ref())
    }

    /// Appends the paths to `out`: a flag byte (bit 0: virtual lights follow, bit 1: a caustic
    /// photon map, bit 2: a global one), then the virtual lights (interleave, clamp, the number of
    /// sets and each set's lights, nine floats a light) and the photon maps ([`PhotonMap::encode`]),
    /// little-endian.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.push(
            u8::from(self.virtual_lights.is_some())
                | u8::from(self.caustics.is_some()) << 1
                | u8::from(self.global_photons.is_some()) << 2,
        );
        if let Some(v) = &self.virtual_lights {
            out.extend_from_slice(&v.interleave.to_le_bytes());
            out.extend_from_slice(&v.clamp_squared.to_le_bytes());
            out.extend_from_slice(&(v.sets.len() as u64).to_le_bytes());
            for set in &v.sets {
                out.extend_from_slice(&(set.len() as u64).to_le_bytes());
                for light in set {
                    for c in [light.p, light.n, light.power].iter().flat_map(|v| v.to_array()) {
                        out.extend_from_slice(&c.to_le_bytes());
                    }
                }
            }
        }
        if let Some(c) = &self.caustics {
            c.encode(out);
        }
        if let Some(g) = &self.global_photons {
            g.encode(out);
        }
    }

    /// The paths [`LightPaths::encode`] wrote, all of `bytes`; empty bytes are no paths. An error
    /// for anything else: short, too long, damaged values, counts beyond what options allow.
    pub fn decode(bytes: &[u8]) -> Result<LightPaths, String> {
        let Some((&flags, mut rest)) = bytes.split_first() else { return Ok(LightPaths::default()) };
        if flags > 7 {
            return Err(format!("light paths with flags {flags}"));
        }
        let mut take = |n: usize| -> Result<&[u8], String> {
            let (head, tail) = rest.split_at_checked(n).ok_or("light paths cut short")?;
            rest = tail;
            Ok(head)
        };
        let u64_of = |b: &[u8]| u64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
        let f32_of = |b: &[u8]| f32::from_le_bytes(b.try_into().unwrap_or([0; 4]));
        let mut paths = LightPaths::default();
        if flags & 1 != 0 {
            let interleave = u32::from_le_bytes(take(4)?.try_into().unwrap_or([0; 4]));
            let clamp_squared = f32_of(take(4)?);
            let set_count = u64_of(take(8)?);
            if interleave == 0
                || u64::from(interleave) * u64::from(interleave) != set_count
                || !clamp_squared.is_finite()
            {
                return Err(format!("virtual lights in {set_count} sets of interleave {interleave}"));
            }
            let mut sets = Vec::new();
            let mut total = 0u64;
            for _ in 0..set_count {
                let count = u64_of(take(8)?);
                total = total.saturating_add(count);
                if total > MAX_DECODED_LIGHTS {
                    return Err(format!("more than {MAX_DECODED_LIGHTS} virtual lights"));
                }
                let body = take(count as usize * 36)?;
                let mut set = Vec::with_capacity(count as usize);
                for light in body.chunks_exact(36) {
                    let f = |i: usize| f32_of(&light[4 * i..4 * i + 4]);
                    let v = |i: usize| Vec3A::new(f(i), f(i + 1), f(i + 2));
                    let light = VirtualLight { p: v(0), n: v(3), power: v(6) };
                    if !(light.p.is_finite() && light.n.is_finite() && light.power.is_finite()) {
                        return Err("a virtual light is damaged".into());
                    }
                    set.push(light);
                }
                sets.push(set);
            }
            paths.virtual_lights = Some(Arc::new(VirtualLights::new(sets, interleave, clamp_squared)));
        }
        if flags & 2 != 0 {
            let (map, tail) = PhotonMap::decode(rest)?;
            paths.caustics = Some(Arc::new(map));
            rest = tail;
        }
        if flags & 4 != 0 {
            let (map, tail) = PhotonMap::decode(rest)?;
            paths.global_photons = Some(Arc::new(map));
            rest = tail;
        }
        if !rest.is_empty() {
            return Err(format!("{} bytes after the light paths", rest.len()));
        }
        Ok(paths)
    }
}

/// The light paths of the last pass traced from a world, kept by a caller that traces each pass in
/// pieces (the viewer's slices of a pass, a worker's share of a frame's lattices), so that every
/// piece uses them instead of tracing the same paths again. They are lent to a frame only when
/// traced from the same world contents (`World::prepare` renews the world's version), seed and GI
/// options.
#[derive(Default)]
pub struct LightPathCache(Mutex<Option<(LightPathKey, LightPaths)>>);

/// What light paths are traced from: the world's version, the seed and the GI options.
type LightPathKey = (u64, u32, GiOptions);

impl LightPathCache {
    fn key(frame: &Frame) -> LightPathKey {
        (frame.world.version(), frame.gi_seed, frame.world.options.gi)
    }

    /// Gives `frame` the kept light paths that were traced for it (the same world, seed and
    /// options); returns whether there were any.
    pub(crate) fn lend(&self, frame: &Frame) -> bool {
        let kept = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        kept.as_ref().filter(|(key, _)| *key == Self::key(frame)).is_some_and(|(_, paths)| paths.lend(frame))
    }

    /// Keeps the light paths `frame` has traced so far (with those kept for the same frame that it
    /// has not traced), in place of any others.
    pub(crate) fn keep(&self, frame: &Frame) {
        let key = Self::key(frame);
        let mut kept = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let old = kept.take().filter(|(k, _)| *k == key).map(|(_, paths)| paths).unwrap_or_default();
        let new = LightPaths::of(frame);
        *kept = Some((
            key,
            LightPaths {
                virtual_lights: new.virtual_lights.or(old.virtual_lights),
                caustics: new.caustics.or(old.caustics),
                global_photons: new.global_photons.or(old.global_photons),
            },
        ));
    }
}

/// A virtual point light: where a path landed, the surface's normal there (facing where the path
/// came from), and its power: irradiance at distance 1 straight along `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualLight {
    pub p: Vec3A,
    pub n: Vec3A,
    pub power: Vec3A,
}

/// A frame's virtual lights, dealt into sets.
#[derive(Clone, Debug, Default)]
pub struct VirtualLights {
    /// The lights of set `s` are `lights[s]`.
    pub sets: Vec<Vec<VirtualLight>>,
    /// The side of the pixel blocks the sets are dealt over.
    pub interleave: u32,
    /// The least squared distance a light counts at.
    pub clamp_squared: f32,
    /// `sets` in blocks of eight lights, as gathering reads them.
    pub(super) blocks: Vec<Vec<LightBlock>>,
}

impl VirtualLights {
    pub fn new(sets: Vec<Vec<VirtualLight>>, interleave: u32, clamp_squared: f32) -> VirtualLights {
        let blocks = sets.iter().map(|set| LightBlock::of(set)).collect();
        VirtualLights { sets, interleave, clamp_squared, blocks }
    }
}

/// Up to eight virtual lights of a set, a row per coordinate, as gathering tests them together (`virtual_lights::gather`).
#[derive(Clone, Copy, Debug)]
pub(super) struct LightBlock {
    pub(super) p: [f32x8; 3],
    pub(super) n: [f32x8; 3],
    /// Read lane by lane, for the lights a point keeps.
    pub(super) power: [[f32; 8]; 3],
    /// Each light's [`epsilon`]: how far short of it its shadow rays stop.
    pub(super) epsilon: f32x8,
    /// Bit `l` set: lane `l` holds a light.
    pub(super) lanes: u32,
}

impl LightBlock {
    /// `set` in blocks, in order.
    pub(super) fn of(set: &[VirtualLight]) -> Vec<LightBlock> {
        set.chunks(8)
            .map(|lights| {
                let lane = |f: &dyn Fn(&VirtualLight) -> f32| -> [f32; 8] {
                    std::array::from_fn(|l| lights.get(l).map_or(0.0, f))
                };
                let row = |f: &dyn Fn(&VirtualLight) -> f32| f32x8::new(lane(f));
                LightBlock {
                    p: [row(&|v| v.p.x), row(&|v| v.p.y), row(&|v| v.p.z)],
                    n: [row(&|v| v.n.x), row(&|v| v.n.y), row(&|v| v.n.z)],
                    power: [lane(&|v| v.power.x), lane(&|v| v.power.y), lane(&|v| v.power.z)],
                    epsilon: row(&|v| epsilon(v.p)),
                    lanes: (1u32 << lights.len()) - 1,
                }
            })
            .collect()
    }
}

/// The whole image a pixel shader finishes, as it was before the shader ran: what `pixelvalue`
/// reads. Only for pixel shaders that read other pixels ([`reads_pixels`]); the others run tile
/// by tile.
pub struct PixelImage {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<[f32; 4]>,
    pub depth: Vec<f32>,
    pub object_id: Vec<u32>,
    pub shader_id: Vec<u32>,
    /// The unit geometric normal of the first surface each pixel sees, facing the camera (zero
    /// where it sees none): [`Sample::normal`] of the sample its depth and ids come from.
    pub normal: Vec<[f32; 3]>,
    /// Output variables of the surfaces the pixels see, by name ([`Frame::captured`]): each
    /// pixel's mean over its samples (zero where the surface has no such output). Empty where
    /// the image keeps none.
    pub outputs: Vec<(String, Vec<[f32; 3]>)>,
}

impl PixelImage {
    /// The view generated code reads the image through (`None` when its arrays do not all hold
    /// `width * height` pixels, or it has none): valid while the image is neither changed nor
    /// dropped.
    pub fn view(&self) -> Option<PixelView> {
        let ids = (&self.object_id[..], &self.shader_id[..]);
        PixelView::new((self.width, self.height), &self.rgba, &self.depth, ids, &self.normal)
    }

    /// Channel `name` of the pixel at raster `(x, y)` (the nearest pixel inside the image): `Ci`
    /// or `N` (the normal), or `alpha`, `z`, `objectid`, `shaderid` (-1 for none) in the first
    /// component, or an output variable the image keeps ([`PixelImage::outputs`]); `None` for an
    /// unknown channel or an empty image.
    pub fn value(&self, name: &str, x: f32, y: f32) -> Option<[f32; 3]> {
        match PixelChannel::of(name) {
            Some(channel) => self.channel_value(channel, x, y),
            None => self.output(name)?.get(self.index(x, y)?).copied(),
        }
    }

    /// The values of the output variable `name` the image keeps, a pixel at a time.
    pub fn output(&self, name: &str) -> Option<&[[f32; 3]]> {
        self.outputs.iter().find(|(n, _)| n == name).map(|(_, values)| &values[..])
    }

    /// The index of the pixel nearest raster `(x, y)` inside the image; `None` for an empty
    /// image or a coordinate that is not finite.
    #[inline]
    pub fn index(&self, x: f32, y: f32) -> Option<usize> {
        if self.width == 0 || self.height == 0 || !x.is_finite() || !y.is_finite() {
            return None;
        }
        let px = (x.floor().max(0.0) as u32).min(self.width - 1);
        let py = (y.floor().max(0.0) as u32).min(self.height - 1);
        Some((py * self.width + px) as usize)
    }

    /// [`PixelImage::value`] of a channel already looked up by name (a pixel shader's lookups
    /// name one channel for all their lanes).
    #[inline]
    pub fn channel_value(&self, channel: PixelChannel, x: f32, y: f32) -> Option<[f32; 3]> {
        let i = self.index(x, y)?;
        let id = |v: u32| if v == u32::MAX { -1.0 } else { v as f32 };
        let one = |v: f32| [v, 0.0, 0.0];
        Some(match channel {
            PixelChannel::Ci => {
                let c = self.rgba.get(i)?;
                [c[0], c[1], c[2]]
            }
            PixelChannel::Alpha => one(self.rgba.get(i)?[3]),
            PixelChannel::Z => one(*self.depth.get(i)?),
            PixelChannel::ObjectId => one(id(*self.object_id.get(i)?)),
            PixelChannel::ShaderId => one(id(*self.shader_id.get(i)?)),
            PixelChannel::N => *self.normal.get(i)?,
        })
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
    /// Unit geometric normal of the first surface hit, turned to face the ray's origin (zero on
    /// a miss), for pixel shaders that read it (`pixelvalue("N", x, y)`).
    pub normal: Vec3A,
    /// The output variables the frame keeps ([`Frame::captured`]: the options' outputs, then the
    /// one adaptive anti-aliasing refines on) as the first surface's shader left them (a float in
    /// the first component; zero without one).
    pub outputs: [[f32; 3]; MAX_FRAME_OUTPUTS],
}

/// A packet's samples by rows, lane `l` the sample of the packet's ray `l`: the fields of
/// [`Sample`] a row per component, as a tile's shading writes them and its pixels read them.
#[derive(Clone, Debug)]
pub struct SampleRows {
    pub color: [[f32; PACKET_SIZE]; 3],
    pub alpha: [f32; PACKET_SIZE],
    pub depth: [f32; PACKET_SIZE],
    pub object_id: [u32; PACKET_SIZE],
    pub shader_id: [u32; PACKET_SIZE],
    pub normal: [[f32; PACKET_SIZE]; 3],
    /// Output `i`'s component `k` of each lane ([`Sample::outputs`]), written only where the frame
    /// keeps outputs ([`Frame::captured`]); read them only then.
    pub outputs: [[[f32; PACKET_SIZE]; 3]; MAX_FRAME_OUTPUTS],
    /// What is left of each lane's weight while it is composited: what the surfaces its ray
    /// crossed let through (the background's share).
    pub(crate) left: [[f32; PACKET_SIZE]; 3],
}

impl Default for SampleRows {
    fn default() -> Self {
        let rows = [[0.0; PACKET_SIZE]; 3];
        SampleRows {
            color: rows,
            alpha: [0.0; PACKET_SIZE],
            depth: [f32::INFINITY; PACKET_SIZE],
            object_id: [u32::MAX; PACKET_SIZE],
            shader_id: [u32::MAX; PACKET_SIZE],
            normal: rows,
            outputs: [rows; MAX_FRAME_OUTPUTS],
            left: [[1.0; PACKET_SIZE]; 3],
        }
    }
}

impl SampleRows {
    /// Lane `l`'s colour.
    #[inline(always)]
    pub fn color(&self, l: usize) -> Vec3A {
        Vec3A::new(self.color[0][l], self.color[1][l], self.color[2][l])
    }

    /// Lane `l`'s normal.
    #[inline(always)]
    pub fn normal(&self, l: usize) -> Vec3A {
        Vec3A::new(self.normal[0][l], self.normal[1][l], self.normal[2][l])
    }

    /// Lane `l`'s outputs.
    #[inline(always)]
    pub fn outputs(&self, l: usize) -> [[f32; 3]; MAX_FRAME_OUTPUTS] {
        self.outputs.map(|o| o.map(|row| row[l]))
    }

    /// Lane `l` as one [`Sample`] (its outputs as the rows hold them).
    pub fn lane(&self, l: usize) -> Sample {
        let l = l.min(PACKET_SIZE - 1);
        Sample {
            color: self.color(l),
            alpha: self.alpha[l],
            depth: self.depth[l],
            object_id: self.object_id[l],
            shader_id: self.shader_id[l],
            normal: self.normal(l),
            outputs: self.outputs(l),
        }
    }
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
    /// The output variables the frame keeps, as the shader left them (primary hits only; see
    /// [`Sample::outputs`]).
    pub(crate) outputs: [[f32; 3]; MAX_FRAME_OUTPUTS],
    /// The rays shading the hit spawned (their trees included), of the hit's [`Pending::budget`],
    /// and whether it refused one.
    pub(crate) spent: u32,
    pub(crate) cut: bool,
}

/// What shading a group of hits (a packet at most) produced, a row per component and a lane per
/// hit: each lane's [`Shaded`], for the stages that read a group's results by rows.
pub(crate) struct ShadedRows {
    /// The group's hits (at most `PACKET_SIZE`).
    pub(crate) len: usize,
    /// The lanes whose hit had a surface ([`Shaded::on_surface`]); the others' `ci`, `oi`, `p`
    /// and `ng` are zero.
    pub(crate) on_surface: u64,
    pub(crate) ci: [[f32; PACKET_SIZE]; 3],
    pub(crate) oi: [[f32; PACKET_SIZE]; 3],
    pub(crate) p: [[f32; PACKET_SIZE]; 3],
    pub(crate) ng: [[f32; PACKET_SIZE]; 3],
    pub(crate) spent: [u32; PACKET_SIZE],
    /// The lanes that refused a ray ([`Shaded::cut`]).
    pub(crate) cut: u64,
    /// Whether `outputs` were written (primary hits of a frame that keeps some); they read as
    /// zeros otherwise.
    pub(crate) captured: bool,
    /// Output `i`'s component `k` of each lane (see [`Shaded::outputs`]).
    pub(crate) outputs: [[[f32; PACKET_SIZE]; 3]; MAX_FRAME_OUTPUTS],
}

impl Default for ShadedRows {
    fn default() -> Self {
        let rows = [[0.0; PACKET_SIZE]; 3];
        ShadedRows {
            len: 0,
            on_surface: 0,
            ci: rows,
            oi: rows,
            p: rows,
            ng: rows,
            spent: [0; PACKET_SIZE],
            cut: 0,
            captured: false,
            outputs: [rows; MAX_FRAME_OUTPUTS],
        }
    }
}

impl ShadedRows {
    /// Rows for `len` hits (at most `PACKET_SIZE`), each as [`Shaded::default`] leaves it.
    pub(crate) fn reset(&mut self, len: usize) {
        let len = len.min(PACKET_SIZE);
        self.len = len;
        self.on_surface = 0;
        self.cut = 0;
        self.captured = false;
        for row in [&mut self.ci, &mut self.oi, &mut self.p, &mut self.ng].into_iter().flatten() {
            row[..len].fill(0.0);
        }
        self.spent[..len].fill(0);
    }

    /// Lane `l`'s result, on a surface: its colour, opacity, point and geometric normal.
    #[inline(always)]
    pub(crate) fn set(&mut self, l: usize, [ci, oi, p, ng]: [Vec3A; 4]) {
        if l >= self.len {
            return;
        }
        for (rows, v) in [(&mut self.ci, ci), (&mut self.oi, oi), (&mut self.p, p), (&mut self.ng, ng)] {
            (rows[0][l], rows[1][l], rows[2][l]) = (v.x, v.y, v.z);
        }
        self.on_surface |= 1 << l;
    }

    /// Lane `l`'s colour, opacity, point and geometric normal.
    #[inline(always)]
    pub(crate) fn vectors(&self, l: usize) -> [Vec3A; 4] {
        let l = l.min(PACKET_SIZE - 1);
        [&self.ci, &self.oi, &self.p, &self.ng].map(|r| Vec3A::new(r[0][l], r[1][l], r[2][l]))
    }

    /// Lane `l`'s outputs (zeros unless [`ShadedRows::captured`]).
    #[inline(always)]
    pub(crate) fn outputs(&self, l: usize) -> [[f32; 3]; MAX_FRAME_OUTPUTS] {
        let l = l.min(PACKET_SIZE - 1);
        match self.captured {
            true => self.outputs.map(|o| o.map(|row| row[l])),
            false => [[0.0; 3]; MAX_FRAME_OUTPUTS],
        }
    }

    /// Lane `l` as one [`Shaded`].
    pub(crate) fn lane(&self, l: usize) -> Shaded {
        let [ci, oi, p, ng] = self.vectors(l);
        let l = l.min(PACKET_SIZE - 1);
        Shaded {
            ci,
            oi,
            p,
            ng,
            on_surface: self.on_surface >> l & 1 != 0,
            outputs: self.outputs(l),
            spent: self.spent[l],
            cut: self.cut >> l & 1 != 0,
        }
    }
}

pub(crate) fn finite_or_zero(v: Vec3A) -> Vec3A {
    if v.is_finite() {
        v
    } else {
        Vec3A::ZERO
    }
}

/// The stages that a shader's callbacks reach back into: the host's `trace` and `gather` shade the
/// hits of the rays they spawn, `illuminance` runs light shaders, a light's area samples shade
/// what they see. Called through this table (which `shade.rs` fills) rather than by name, so that
/// the callbacks (`host.rs`) and the light shaders (`lights.rs`) import neither `shade.rs` nor
/// each other, while `shade.rs` runs them all.
// The fields are the stages' own signatures.
#[allow(clippy::type_complexity)]
#[derive(Clone, Copy)]
pub(crate) struct Stages {
    /// Traces rays and shades what they hit: a sample each (`shade::trace_budgeted`). Each ray's
    /// budget is what its tree may spend, and is left with what it did not.
    pub(crate) trace_rays: fn(&Frame, &[Ray], &mut [RayBudget], u32) -> Vec<Sample>,
    /// Traces rays and shades the first surface each hits, with its distance (`shade::gather_rays`);
    /// budgets as for `trace_rays`.
    pub(crate) gather_rays: fn(&Frame, &[Ray], &mut [RayBudget], u32) -> Vec<Option<(f32, Shaded)>>,
    /// Shades hits grouped by material and instance (`group::shade_in_groups`).
    pub(crate) shade_in_groups: fn(&Frame, &mut [Pending], u32, &mut [Shaded]),
    /// Shades hits that share material and instance (`shade::shade_group`).
    pub(crate) shade_group: fn(&Frame, &GroupRows, u32, &mut [Shaded]),
    /// One light at four points (`lights::eval_light`), the rays its shader spawns charged to the
    /// points' budgets.
    pub(crate) eval_light: fn(
        &Frame,
        &LightSource,
        Option<u32>,
        &[i32; 4],
        &[Vec3A; 4],
        &[f32; 4],
        u32,
        &mut [RayBudget; 4],
        &mut [LightLanes],
        &mut [u32; 4],
    ),
    /// The light getting along segments (`lights::transmission_between`).
    pub(crate) transmission_between: fn(&Frame, &[Option<(Vec3A, Vec3A, f32)>], &mut [Vec3A]),
    /// The lights of a surface batch (`BatchLights::compute`), charged to the lanes' budgets.
    pub(crate) batch_lights:
        fn(&Frame, Option<u32>, &[Vec3A], &[i32], &[f32], Option<&[Vec3A]>, u32, &mut [RayBudget]) -> BatchLights,
}

/// The lights of every point of a surface batch, computed once for the whole batch when the shader
/// first asks (light shaders run over the batch, shadow rays go as packets): lane `l`'s light `k`
/// in lane `l % 4` of `lights[(l / 4) * slots + k]`, so that a chunk's lights lie together as the
/// host ABI hands them over (`LightLanes` rows).
///
/// Shadows are traced at once only for the lights in front of each point (see
/// [`BatchLights::compute`]); the others are pending (bit `k` of lane `l`'s pending mask, their
/// `cl` unshadowed) until a query whose cone takes them in resolves them.
///
/// Counts and pending masks are kept a chunk at a time (lane `l`'s in `[l / 4][l % 4]`), as the
/// rows are: appending a light's row to a chunk updates them in place, where copying them in and
/// out lane by lane was a fifth of this table's making (BART's robots).
pub(crate) struct BatchLights {
    pub(crate) n: usize,
    /// Light rows per chunk.
    pub(crate) slots: usize,
    pub(crate) counts: Vec<[u32; 4]>,
    pub(crate) lights: Vec<LightLanes>,
    pub(crate) pending: Vec<[u32; 4]>,
}

/// A start offset for rays leaving `p` (its scale grows with the coordinates' magnitude).
pub(crate) fn epsilon(p: Vec3A) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

thread_local! {
    /// The trace bias of the surface this thread is shading ([`Material::trace_bias`], RIB
    /// `Attribute "trace" "bias"`), set for the time of its shading by [`LaunchBias`]: the rays
    /// its shaders and its lights spawn start that far along. 0 outside surface shading.
    ///
    /// [`Material::trace_bias`]: super::Material::trace_bias
    static LAUNCH_BIAS: std::cell::Cell<f32> = const { std::cell::Cell::new(0.0) };
}

/// The start offset of a ray spawned at `p` by the shading under way: [`epsilon`], or the
/// surface's trace bias where that is longer.
pub(crate) fn launch_epsilon(p: Vec3A) -> f32 {
    epsilon(p).max(launch_bias())
}

/// The trace bias of the surface this thread is shading (0 outside surface shading).
pub(crate) fn launch_bias() -> f32 {
    LAUNCH_BIAS.with(std::cell::Cell::get)
}

/// Sets this thread's trace bias (see `LAUNCH_BIAS`) until dropped, then restores the one it
/// replaced: a surface shaded for a ray of another's shading has its own for that time.
pub(crate) struct LaunchBias(f32);

impl LaunchBias {
    pub(crate) fn begin(bias: f32) -> LaunchBias {
        LaunchBias(LAUNCH_BIAS.with(|b| b.replace(bias)))
    }
}

impl Drop for LaunchBias {
    fn drop(&mut self) {
        LAUNCH_BIAS.with(|b| b.set(self.0));
    }
}

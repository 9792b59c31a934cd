//! Instant radiosity (Keller 1997): each frame, paths traced from the light sources leave
//! **virtual point lights** where they meet diffuse surfaces, and `indirectdiffuse()` gathers them
//! with a shadow ray each instead of sampling the hemisphere. Interleaved sampling (Keller and
//! Heidrich 2001): the virtual lights are dealt into `interleave x interleave` sets, and the pixels
//! of each block of that many pixels use one set each, so that neighbouring pixels see different
//! lights and a filter over the block (an imager) can average them.
//!
//! Conventions (`docs/global_illumination.md`):
//! - Light paths see every surface as **matte** with reflectance `Cs` (its material's colour,
//!   clamped below 1), as PRMan's and 3Delight's photon tracing do by default (`Attribute "photon"
//!   "shadingmodel" "matte"`): a surface reflects `Cs / pi` of its irradiance as radiance.
//! - A light's emission is found by running its shader where a path from it lands: a local light
//!   (`illuminate`) at the position its `L` points back to, a distant one (`solar`) along its `L`.
//!   Paths leave a local light as it emits (`emission.rs`) and a distant one uniformly over a disc
//!   as wide as the scene. Ambient lights emit nothing; area lights emit from their sample point.
//! - `indirectdiffuse()` answers the mean radiance arriving over the hemisphere (irradiance over
//!   pi), as its hemisphere-sampling form does, so `Cs * indirectdiffuse()` is the radiance a matte
//!   surface reflects.
//! - Virtual lights closer than `clamp` to the gathering point count as if `clamp` away: the
//!   `1 / r^2` of a point light would otherwise make bright splotches near corners (the bias is a
//!   little missing light in corners).
//!
//! Invariant: the virtual lights depend only on the world and the frame's seed (the options', or
//! per pass of progressive refinement another: `Frame::gi_seed`), never on threads or timing, so
//! every tile, lattice and worker of a frame gathers the same lights.

use super::caustic_aim::{corners, Cones, Discs, Targets};
use super::emission::{probe_directions, Emission};
use super::hemisphere::orthonormal;
use super::photon_map::{Photon, PhotonMap};
use super::ray_budget::RayBudget;
use super::sampling::{mix, point_seed, radical_inverse, unit};
use super::stats::{tracing, Stats};
use super::work::{epsilon, launch_epsilon, Frame, VirtualLight, VirtualLights};
use super::world::{LightSource, PhotonModel, World, MAX_BOUNCES, MAX_INTERLEAVE, MAX_VIRTUAL_LIGHT_PATHS};
use crate::ray::{Hit, Ray};
use crate::shading::LightKind;
use glam::Vec3A;
use rtsl_compiler::abi::{LightLanes, MAX_LIGHTS};
use std::sync::Arc;
use wide::f32x8;

/// Traces the frame's light paths and leaves its virtual lights.
pub(super) fn trace(frame: &Frame) -> VirtualLights {
    let world = frame.world;
    let gi = world.options.gi;
    let interleave = gi.interleave.clamp(1, MAX_INTERLEAVE);
    let set_count = (interleave * interleave) as usize;
    let Some((lo, hi)) = world.scene.bounds() else {
        return VirtualLights::new(vec![Vec::new(); set_count], interleave, 0.0);
    };
    let diagonal = (hi - lo).length();
    let clamp = if gi.clamp > 0.0 { gi.clamp } else { 0.01 * diagonal };
    let bounces = gi.bounces.clamp(1, MAX_BOUNCES);
    let lights = for_each_landing(
        frame,
        gi.virtual_lights,
        (0x5851_F42D_4C95_7F2D, None),
        every_landing,
        |landing, seed, out| {
            follow_to_virtual_lights(frame, landing, bounces, seed, out);
        },
    );
    // Dealt round-robin: each set a stratified share of the paths.
    let mut sets = vec![Vec::with_capacity(lights.len() / set_count + 1); set_count];
    for (i, l) in lights.into_iter().enumerate() {
        sets[i % set_count].push(l);
    }
    VirtualLights::new(sets, interleave, clamp * clamp)
}

/// Traces the frame's caustic photons (`Option "gi" "causticphotons"`): paths from the lights
/// toward the instances with specular surfaces (chrome, glass; `caustic_aim.rs`), those whose
/// first surface is specular followed through specular surfaces to the first diffuse one, where
/// each leaves a photon (Jensen's caustic map, light paths L S+ D).
pub(super) fn trace_caustics(frame: &Frame) -> PhotonMap {
    let targets = specular_bounds(frame.world);
    // Only paths whose first surface is specular go on: the others are dropped as they land,
    // before their surfaces are worked out and the light's shader is run there.
    let specular = |hit: &Hit| reflectance_of(frame, hit).1 != PhotonModel::Matte;
    let gi = &frame.world.options.gi;
    let seeded_toward = (0x2545_F491_4F6C_DD1D, Some(&targets[..]));
    let photons = for_each_landing(frame, gi.caustic_photons, seeded_toward, specular, |landing, seed, out| {
        follow_to_photon(frame, landing, seed, out);
    });
    PhotonMap::new(photons)
}

/// The world boxes of the instances some of whose surfaces are specular for light paths (their
/// material's photon model is not matte).
fn specular_bounds(world: &World) -> Vec<(Vec3A, Vec3A)> {
    let specular = |m: u32| world.materials.get(m as usize).is_some_and(|m| m.photon != PhotonModel::Matte);
    let instances = world.instances.iter().enumerate();
    instances
        .filter(|(_, inst)| match &inst.parts {
            Some(parts) => parts.materials.iter().any(|&m| specular(m)),
            None => specular(inst.material),
        })
        .filter_map(|(id, _)| world.scene.instance_bounds(id as u32))
        .collect()
}

/// Traces the frame's global photons (`Option "gi" "globalphotons"`): paths from the lights that
/// leave a photon, the power they carry as they arrive, on every matte surface they reach (the
/// first one, and up to `bounces` more, cosine-distributed, through chrome and glass as these
/// direct them): Jensen's global map, light paths L (S|D)* D.
pub(super) fn trace_global(frame: &Frame) -> PhotonMap {
    let bounces = frame.world.options.gi.bounces.clamp(1, MAX_BOUNCES);
    let photons = for_each_landing(
        frame,
        frame.world.options.gi.global_photons,
        (0x9E37_79B9_7F4A_7C15, None),
        every_landing,
        |landing, seed, out| {
            follow_to_global_photons(frame, landing, bounces + 1, seed, out);
        },
    );
    PhotonMap::new(photons)
}

/// Traces the frame's light paths now, on the threads of the current rayon pool, where its options
/// ask for them: a render calls this before shading, so that no shading thread waits while the
/// first one to need them traces them alone.
pub(super) fn prepare(frame: &Frame) {
    use std::sync::atomic::Ordering;
    let gi = frame.world.options.gi;
    // Shaders the paths run (a shadow ray's, through a surface that shades its opacity) may ask
    // for the maps being traced: they get none (`Frame::tracing_light_paths`), the same whatever
    // the threads, rather than waiting on their own tracing, which would never end.
    frame.tracing_light_paths.store(true, Ordering::Release);
    if gi.virtual_lights > 0 {
        frame.virtual_lights.get_or_init(|| Arc::new(timed(frame, || trace(frame))));
    }
    if gi.caustic_photons > 0 {
        frame.caustics.get_or_init(|| Arc::new(timed(frame, || trace_caustics(frame))));
    }
    if gi.global_photons > 0 {
        frame.global_photons.get_or_init(|| Arc::new(timed(frame, || trace_global(frame))));
    }
    frame.tracing_light_paths.store(false, Ordering::Release);
}

/// The frame's virtual lights, traced first if no one has yet.
pub(super) fn of_frame<'f>(frame: &'f Frame) -> &'f VirtualLights {
    static NONE: std::sync::OnceLock<VirtualLights> = std::sync::OnceLock::new();
    if frame.tracing_light_paths.load(std::sync::atomic::Ordering::Acquire) {
        return NONE.get_or_init(|| VirtualLights::new(vec![Vec::new()], 1, 0.0));
    }
    frame.virtual_lights.get_or_init(|| Arc::new(timed(frame, || trace(frame))))
}

/// Runs `f`, adding its wall time to the frame's light-path time when the frame is timed.
pub(super) fn timed<R>(frame: &Frame, f: impl FnOnce() -> R) -> R {
    let start = frame.stats.timed.then(std::time::Instant::now);
    // Shared by every unit of the frame: traced with every object it reaches, never without
    // what a unit rendering ahead has not fetched yet.
    let r = crate::accel::ask_ahead::waiting(f);
    if let Some(start) = start {
        let ns = start.elapsed().as_nanos() as u64;
        frame.stats.light_paths_ns.add(ns as usize);
    }
    r
}

/// The photon map's search radius: 5% of the scene's diagonal.
pub(super) fn photon_search_radius(frame: &Frame) -> f32 {
    frame.world.scene.bounds().map_or(0.0, |(lo, hi)| 0.05 * (hi - lo).length())
}

/// The set of `lights` a point uses: by the pixel it projects to (the interleaving block's cell),
/// or where it projects to no pixel (behind the camera, or a camera shader's view), by a hash of it.
pub(super) fn set_of(lights: &VirtualLights, frame: &Frame, p: Vec3A) -> usize {
    let n = lights.interleave;
    let cell = match raster_of(frame, p) {
        Some((x, y)) => x.rem_euclid(n as i64) as u32 + n * y.rem_euclid(n as i64) as u32,
        None => (point_seed(p) % u64::from(n * n)) as u32,
    };
    cell as usize
}

/// A point gathering virtual lights: where it is, its unit normal, its ray time and its set.
pub(super) struct Gatherer {
    pub p: Vec3A,
    pub n: Vec3A,
    pub time: f32,
    pub set: usize,
}

/// The mean radiance arriving at each point from its set of `all` (irradiance over pi), each
/// light behind a shadow ray; the rays go as packets of one direction octant each
/// ([`super::World::occluded_rays`]: a point's lights lie all around it). Each ray's light is added
/// to its point in the order the rays were made. A set stands for all of them: its share is
/// scaled up by the number of sets.
pub(super) fn gather(all: &VirtualLights, frame: &Frame, points: &[Gatherer], out: &mut [Vec3A]) {
    // Kept per thread: a chunk's few points make a few hundred rays, whose buffers grown afresh
    // for every chunk cost a good share of the gathering.
    let GatherBuffers { mut rays, mut lights_in, mut blocked, mut ends } = super::scratch::take(&GATHER_BUFFERS);
    rays.clear();
    // The light each ray would bring if nothing blocked it; a point's rays are those before the
    // point's end and after the last point's.
    lights_in.clear();
    ends.clear();
    for g in points {
        toward_lights(all, g, |ray, light| {
            rays.push(ray);
            lights_in.push(light);
        });
        ends.push(rays.len());
    }
    tracing(|| frame.world.occluded_rays(super::RayKind::Shadow, &rays, &mut blocked));
    Stats::add(&frame.stats.shadow_rays, rays.len());
    let scale = all.sets.len() as f32 / std::f32::consts::PI;
    let mut start = 0;
    for (o, &end) in out.iter_mut().zip(&ends) {
        // Summed in a register: the same additions, in the same order, as into `o` one by one.
        let mut sum = *o;
        for (&light, &blocked) in lights_in[start..end].iter().zip(&blocked[start..end]) {
            sum = Vec3A::select(glam::BVec3A::splat(blocked), sum, sum + light);
        }
        *o = sum * scale;
        start = end;
    }
    super::scratch::give(&GATHER_BUFFERS, GatherBuffers { rays, lights_in, blocked, ends });
}

/// The shadow rays from `g` toward the lights of its set that it faces and that face it, in the
/// set's order, each handed to `each` with the light it brings if nothing blocks it. Eight lights
/// at a time, each lane by the operations (and in the order) of one light alone: `to`, its length
/// and direction, both cosines, the reach and the weight.
#[inline(always)]
fn toward_lights(all: &VirtualLights, g: &Gatherer, mut each: impl FnMut(Ray, Vec3A)) {
    let Some(blocks) = all.blocks.get(g.set) else { return };
    let zero = f32x8::ZERO;
    let clamp_squared = f32x8::splat(all.clamp_squared);
    let from = g.p.to_array().map(f32x8::splat);
    let normal = g.n.to_array().map(f32x8::splat);
    let near = launch_epsilon(g.p);
    for block in blocks {
        let to: [f32x8; 3] = std::array::from_fn(|a| block.p[a] - from[a]);
        let r2 = (to[0] * to[0] + to[1] * to[1]) + to[2] * to[2];
        let r = r2.sqrt();
        let w = to.map(|c| c / r);
        let cos_here = (normal[0] * w[0] + normal[1] * w[1]) + normal[2] * w[2];
        let cos_there = -((block.n[0] * w[0] + block.n[1] * w[1]) + block.n[2] * w[2]);
        let refused = r2.simd_le(zero) | cos_here.simd_le(zero) | cos_there.simd_le(zero);
        let mut kept = !(refused.to_bitmask() as u32) & block.lanes;
        if kept == 0 {
            continue;
        }
        // `maxps(x, 0)` is 0 for a NaN `x`, as `f32::max(x, 0.0)` is.
        let reach = (r * f32x8::splat(1.0 - 1e-3) - block.epsilon).fast_max(zero).to_array();
        let weight = ((cos_here * cos_there) / r2.fast_max(clamp_squared)).to_array();
        let w = w.map(f32x8::to_array);
        while kept != 0 {
            let l = kept.trailing_zeros() as usize;
            kept &= kept - 1;
            let direction = Vec3A::new(w[0][l], w[1][l], w[2][l]);
            let power = Vec3A::new(block.power[0][l], block.power[1][l], block.power[2][l]);
            each(Ray::segment(g.p, direction, near, reach[l]).at_time(g.time), power * weight[l]);
        }
    }
}

/// [`gather`]'s buffers: the shadow rays, each one's unblocked light, whether each is blocked, and
/// where each point's rays end.
#[derive(Default)]
struct GatherBuffers {
    rays: Vec<Ray>,
    lights_in: Vec<Vec3A>,
    blocked: Vec<bool>,
    ends: Vec<usize>,
}

thread_local! {
    /// [`gather`]'s buffers, one set per level of recursion (a shadow ray may run shaders).
    static GATHER_BUFFERS: std::cell::RefCell<Vec<GatherBuffers>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Where a light's paths start.
#[derive(Clone, Copy)]
enum Emitter {
    /// A local light at a position: paths leave it as it emits (`emission.rs`), or toward targets.
    Point(Vec3A),
    /// A distant light shining along a direction: paths start on a disc of `radius` about `centre`,
    /// across the direction, outside the scene.
    Distant { direction: Vec3A, centre: Vec3A, radius: f32 },
}

/// Where a light's paths go: everywhere, as the light emits (`emission.rs`), or toward targets
/// (`caustic_aim.rs`).
enum Aim {
    Everywhere,
    Emission(Emission),
    Cones(Cones),
    Discs(Discs),
}

impl Aim {
    /// Toward `targets` from `emitter`, where that helps.
    fn of(emitter: &Emitter, targets: &Targets) -> Aim {
        let aimed = match *emitter {
            Emitter::Point(from) => Cones::toward(from, targets).map(Aim::Cones),
            Emitter::Distant { direction, centre, radius } => {
                Discs::across(centre, orthonormal(direction), radius, targets).map(Aim::Discs)
            }
        };
        aimed.unwrap_or(Aim::Everywhere)
    }
}

/// How `light` emits, found by running it at a point of the scene (its centre, else a corner of
/// the scene's bounds its illumination reaches); `None` for an ambient light or one that lights
/// none of those points.
fn emitter(frame: &Frame, light: &LightSource, lo: Vec3A, hi: Vec3A) -> Option<Emitter> {
    if light.kind == LightKind::Ambient {
        return None;
    }
    let centre = (lo + hi) * 0.5;
    let probes: Vec<Vec3A> =
        std::iter::once(centre).chain(corners((lo, hi)).map(|c| centre + (c - centre) * 0.9)).collect();
    for four in probes.chunks(4) {
        let points: [Vec3A; 4] = std::array::from_fn(|l| four.get(l).copied().unwrap_or(centre));
        let mask: [i32; 4] = std::array::from_fn(|l| if l < four.len() { -1 } else { 0 });
        let rows = eval(frame, light, &mask, &points);
        for (l, &p) in points.iter().enumerate().take(four.len()) {
            let Some(row) = rows.iter().find(|(lane, _)| *lane == l).map(|(_, r)| r) else { continue };
            let to_light = Vec3A::from(row.lane_l(l));
            if to_light.length_squared() <= 0.0 || !to_light.is_finite() {
                continue;
            }
            return Some(match light.kind {
                LightKind::Distant => {
                    Emitter::Distant { direction: -to_light.normalize(), centre, radius: 0.5 * (hi - lo).length() }
                }
                _ => Emitter::Point(p + to_light),
            });
        }
    }
    None
}

/// `light`'s emission table from `from` (`emission.rs`): its shader run at `reach` from `from`
/// toward each probe direction, the intensity there its `Cl` times the squared distance (the
/// largest channel).
fn emission_of(frame: &Frame, light: &LightSource, from: Vec3A, reach: f32) -> Option<Emission> {
    let directions = probe_directions();
    let mut intensity = vec![0.0f32; directions.len()];
    for (k, four) in directions.chunks(4).enumerate() {
        let points: [Vec3A; 4] = std::array::from_fn(|l| from + four.get(l).copied().unwrap_or(Vec3A::Z) * reach);
        let mask: [i32; 4] = std::array::from_fn(|l| if l < four.len() { -1 } else { 0 });
        for (l, row) in eval(frame, light, &mask, &points) {
            intensity[4 * k + l] = Vec3A::from(row.lane(l).cl).max_element() * reach * reach;
        }
    }
    Emission::of_probes(&intensity)
}

/// The light of `light` at four points (no shadow rays matter here: the points are where paths
/// from the light land): each lane's first row, for the lanes it reaches.
fn eval(frame: &Frame, light: &LightSource, mask: &[i32; 4], points: &[Vec3A; 4]) -> Vec<(usize, LightLanes)> {
    let mut rows = vec![LightLanes::default(); MAX_LIGHTS];
    let mut counts = [0u32; 4];
    // A path's start: the rays a light's shader spawns here are trees of their own.
    let mut budgets = [RayBudget::FULL; 4];
    (frame.stages.eval_light)(frame, light, None, mask, points, &[0.0; 4], 0, &mut budgets, &mut rows, &mut counts);
    (0..4).filter(|&l| counts[l] > 0 && mask[l] != 0).map(|l| (l, rows[0])).collect()
}

/// Where a path from a light first landed, and the power it carried there.
struct Landing {
    /// The path's index among its light's.
    index: u32,
    ray: Ray,
    hit: Hit,
    surface: crate::scene::SurfaceHit,
    carried: Vec3A,
}

/// Traces `paths` paths from the frame's lights (shared out evenly; each light's toward the
/// targets, where given and where aiming helps, else everywhere) and hands `visit` each first
/// landing that `keep` keeps, with a seed of its own (from the salt) (the light's shader run where the path lands
/// says how much power it carries), collecting what it leaves. The paths go in chunks over the
/// threads of the current rayon pool; what they leave comes back in path order whoever traced
/// them, so the result does not depend on the threads.
fn for_each_landing<T: Send>(
    frame: &Frame,
    paths: u32,
    (salt, targets): (u64, Option<&Targets>),
    keep: impl Fn(&Hit) -> bool + Sync,
    visit: impl Fn(Landing, u64, &mut Vec<T>) + Sync,
) -> Vec<T> {
    use rayon::prelude::*;
    let world = frame.world;
    let paths = paths.min(MAX_VIRTUAL_LIGHT_PATHS);
    let Some((lo, hi)) = world.scene.bounds() else { return Vec::new() };
    let emitters: Vec<(&LightSource, Emitter)> =
        world.lights.iter().filter_map(|l| Some((l, emitter(frame, l, lo, hi)?))).collect();
    if emitters.is_empty() || paths == 0 || targets.is_some_and(<[_]>::is_empty) {
        return Vec::new();
    }
    let per_light = paths.div_ceil(emitters.len() as u32);
    let seed = mix(u64::from(frame.gi_seed) ^ salt);
    let mut out = Vec::new();
    for (k, (light, emitter)) in emitters.iter().enumerate() {
        let seed = mix(seed ^ k as u64);
        let aim = match targets {
            Some(targets) => Aim::of(emitter, targets),
            None => Aim::Everywhere,
        };
        let aim = match (aim, emitter) {
            (Aim::Everywhere, Emitter::Point(from)) => {
                emission_of(frame, light, *from, 0.25 * (hi - lo).length()).map_or(Aim::Everywhere, Aim::Emission)
            }
            (aim, _) => aim,
        };
        let chunks: Vec<u32> = (0..per_light).step_by(PATHS_PER_TASK as usize).collect();
        let left: Vec<Vec<T>> = chunks
            .par_iter()
            .map(|&first| {
                let mut left = Vec::new();
                let last = (first + PATHS_PER_TASK).min(per_light);
                let aimed = (emitter, &aim);
                for landing in landings(frame, light, aimed, (first..last, per_light), seed, &keep) {
                    let path_seed = mix(seed ^ (u64::from(landing.index) + 1));
                    visit(landing, path_seed, &mut left);
                }
                left
            })
            .collect();
        out.extend(left.into_iter().flatten());
    }
    out
}

/// Keeps every landing (for [`for_each_landing`]).
fn every_landing(_: &Hit) -> bool {
    true
}

/// Light paths a thread takes at a time.
const PATHS_PER_TASK: u32 = 256;

/// The first landings of paths `range` of `count` from `light` that `keep` keeps (asked of the hit
/// alone, before the landing's surface is worked out and the light's shader run there).
fn landings(
    frame: &Frame,
    light: &LightSource,
    (emitter, aim): (&Emitter, &Aim),
    (range, count): (std::ops::Range<u32>, u32),
    seed: u64,
    keep: &(dyn Fn(&Hit) -> bool + Sync),
) -> Vec<Landing> {
    let world = frame.world;
    // A Cranley-Patterson rotation of the Hammersley points: another seed, another stratified set.
    let shift = (unit(seed), unit(mix(seed)));
    let starts: Vec<(u32, Ray, f32)> = range
        .map(|i| {
            let (u1, u2) =
                (((i as f32 + 0.5) / count as f32 + shift.0).fract(), (radical_inverse(i, 2) + shift.1).fract());
            let (ray, share) = match (*emitter, aim) {
                (Emitter::Point(from), Aim::Cones(cones)) => {
                    let (dir, solid_angle) = cones.sample(u1, u2);
                    (Ray::segment(from, dir, epsilon(from), f32::INFINITY), solid_angle / count as f32)
                }
                (Emitter::Point(from), Aim::Emission(emission)) => {
                    let (dir, solid_angle) = emission.sample(u1, u2);
                    (Ray::segment(from, dir, epsilon(from), f32::INFINITY), solid_angle / count as f32)
                }
                (Emitter::Distant { direction, centre, radius }, Aim::Discs(discs)) => {
                    let (t1, t2) = orthonormal(direction);
                    let ((x, y), area) = discs.sample(u1, u2);
                    let origin = centre - direction * (2.0 * radius) + t1 * x + t2 * y;
                    (Ray::segment(origin, direction, 0.0, f32::INFINITY), area / count as f32)
                }
                (Emitter::Point(from), _) => {
                    let z = 1.0 - 2.0 * u1;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = std::f32::consts::TAU * u2;
                    let dir = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
                    // Point light power over paths: 4 pi steradians each path's share.
                    (Ray::segment(from, dir, epsilon(from), f32::INFINITY), 4.0 * std::f32::consts::PI / count as f32)
                }
                (Emitter::Distant { direction, centre, radius }, _) => {
                    let (t1, t2) = orthonormal(direction);
                    let (r, phi) = (radius * u1.sqrt(), std::f32::consts::TAU * u2);
                    let origin = centre - direction * (2.0 * radius) + t1 * (r * phi.cos()) + t2 * (r * phi.sin());
                    let area = std::f32::consts::PI * radius * radius;
                    (Ray::segment(origin, direction, 0.0, f32::INFINITY), area / count as f32)
                }
            };
            (i, ray, share)
        })
        .collect();
    // Traced together: a point light's paths share their origin, a distant light's their direction.
    let rays: Vec<Ray> = starts.iter().map(|&(_, ray, _)| ray).collect();
    let mut first_hits = Vec::new();
    tracing(|| world.intersect_rays(super::RayKind::Photon, &rays, &mut first_hits));
    let mut hits = Vec::with_capacity(starts.len());
    for ((index, ray, share), hit) in starts.iter().zip(first_hits) {
        if !hit.is_hit() || !keep(&hit) {
            continue;
        }
        let Some(surface) = world.scene.surface(&hit) else { continue };
        hits.push((*index, *ray, *share, hit, surface));
    }
    Stats::add(&frame.stats.secondary_rays, starts.len());
    // Their light, four at a time through the light's shader.
    let mut out = Vec::with_capacity(hits.len());
    for four in hits.chunks(4) {
        let points: [Vec3A; 4] = std::array::from_fn(|l| four.get(l).map_or(Vec3A::ZERO, |x| x.4.p));
        let mask: [i32; 4] = std::array::from_fn(|l| if l < four.len() { -1 } else { 0 });
        for (l, row) in eval(frame, light, &mask, &points) {
            let (index, ray, share, hit, surface) = &four[l];
            let cl = Vec3A::from(row.lane(l).cl);
            // A point light's intensity toward the landing is Cl times the squared distance; a
            // distant light's Cl is the irradiance across its direction.
            let d2 = match emitter {
                Emitter::Point(from) => (surface.p - *from).length_squared(),
                Emitter::Distant { .. } => 1.0,
            };
            let carried = cl * (share * d2);
            if carried.max_element() > 0.0 && carried.is_finite() {
                out.push(Landing { index: *index, ray: *ray, hit: *hit, surface: surface.clone(), carried });
            }
        }
    }
    out
}

/// The most specular surfaces a path goes through.
const MAX_SPECULAR_DEPTH: u32 = 8;

/// A light path at a matte surface: where, the normal facing where it came from, the power it
/// carries as it arrives and its direction, the surface's reflectance, and how many matte and
/// specular surfaces it met before.
struct AtMatte {
    p: Vec3A,
    n: Vec3A,
    carried: Vec3A,
    direction: Vec3A,
    reflectance: Vec3A,
    diffuse: u32,
    specular: u32,
}

/// Follows a light path from where it landed: at each matte surface `visit` leaves what it
/// leaves there and says whether the path bounces on, cosine-distributed (cosine sampling cancels
/// the matte BRDF's cosine over pi: the path then carries its power times the reflectance);
/// through chrome and glass it goes as they direct it, at most [`MAX_SPECULAR_DEPTH`] of them.
fn follow(frame: &Frame, landing: Landing, seed: u64, mut visit: impl FnMut(&AtMatte) -> bool) {
    let Landing { mut ray, mut hit, mut surface, mut carried, .. } = landing;
    let (mut diffuse, mut specular) = (0, 0);
    loop {
        let (reflectance, model) = reflectance_of(frame, &hit);
        let n = if surface.ng.dot(ray.direction) > 0.0 { -surface.ng } else { surface.ng };
        let h = mix(seed ^ (u64::from(diffuse + specular) << 32) ^ point_seed(surface.p));
        let dir = match model {
            PhotonModel::Matte => {
                let at = AtMatte { p: surface.p, n, carried, direction: ray.direction, reflectance, diffuse, specular };
                if !visit(&at) {
                    return;
                }
                diffuse += 1;
                carried *= reflectance;
                cosine_direction(n, h)
            }
            _ => {
                specular += 1;
                if specular > MAX_SPECULAR_DEPTH {
                    return;
                }
                let Some((dir, tint)) = scatter_specular(model, reflectance, ray.direction, surface.ng, h) else {
                    return;
                };
                carried *= tint;
                dir
            }
        };
        let Some(next) = bounce(frame, surface.p, dir) else { return };
        (ray, hit, surface) = next;
    }
}

/// Leaves a virtual light where the path landed on a matte surface and on each of the next
/// `bounces - 1` it reaches while power is left. Light that reaches a diffuse surface through a
/// specular one is a caustic, the photon map's: the path leaves nothing there and ends.
fn follow_to_virtual_lights(frame: &Frame, landing: Landing, bounces: u32, seed: u64, out: &mut Vec<VirtualLight>) {
    follow(frame, landing, seed, |at| {
        if at.specular > 0 {
            return false;
        }
        let power = at.carried * at.reflectance / std::f32::consts::PI;
        if power.max_element() <= 0.0 || !power.is_finite() {
            return false;
        }
        out.push(VirtualLight { p: at.p, n: at.n, power });
        at.diffuse + 1 < bounces
    });
}

/// Leaves a photon, the path's power as it arrives, on each of the first `stores` matte surfaces
/// the path reaches.
fn follow_to_global_photons(frame: &Frame, landing: Landing, stores: u32, seed: u64, out: &mut Vec<Photon>) {
    follow(frame, landing, seed, |at| {
        if at.carried.max_element() <= 0.0 || !at.carried.is_finite() {
            return false;
        }
        out.push(Photon { p: at.p, power: at.carried, direction: at.direction.normalize_or_zero() });
        at.diffuse + 1 < stores
    });
}

/// Follows a path that landed on a specular surface through specular surfaces to the first matte
/// one, and leaves a photon there.
fn follow_to_photon(frame: &Frame, landing: Landing, seed: u64, out: &mut Vec<Photon>) {
    let Landing { mut ray, mut hit, mut surface, mut carried, .. } = landing;
    for depth in 0..=MAX_SPECULAR_DEPTH {
        let (reflectance, model) = reflectance_of(frame, &hit);
        if model == PhotonModel::Matte {
            out.push(Photon { p: surface.p, power: carried, direction: ray.direction.normalize_or_zero() });
            return;
        }
        let h = mix(seed ^ (u64::from(depth) << 32) ^ point_seed(surface.p));
        let Some((dir, tint)) = scatter_specular(model, reflectance, ray.direction, surface.ng, h) else { return };
        carried *= tint;
        let Some(next) = bounce(frame, surface.p, dir) else { return };
        (ray, hit, surface) = next;
    }
}

/// The path on from `from` along `dir`: its ray, and the hit and surface it lands on (`None` when
/// it leaves the scene).
fn bounce(frame: &Frame, from: Vec3A, dir: Vec3A) -> Option<(Ray, Hit, crate::scene::SurfaceHit)> {
    let world = frame.world;
    let ray = Ray::segment(from, dir, epsilon(from), f32::INFINITY);
    Stats::add(&frame.stats.secondary_rays, 1);
    let hit = tracing(|| world.intersect(super::RayKind::Photon, &ray));
    let surface = hit.is_hit().then(|| world.scene.surface(&hit)).flatten()?;
    Some((ray, hit, surface))
}

/// A cosine-distributed direction about the unit normal `n`, from the hash `h`.
fn cosine_direction(n: Vec3A, h: u64) -> Vec3A {
    let (r1, r2) = (unit(h), unit(mix(h)));
    let (t1, t2) = orthonormal(n);
    let phi = std::f32::consts::TAU * r1;
    let (s, c) = (r2.sqrt(), (1.0 - r2).sqrt());
    t1 * (s * phi.cos()) + t2 * (s * phi.sin()) + n * c
}

/// Where a path arriving along `dir` goes on from a specular surface of geometric normal `ng` and
/// colour `color`: its new direction and the tint it takes. Chrome reflects, tinted; glass
/// reflects or refracts in Fresnel's proportions (chosen by the hash `h`), the refracted part
/// tinted; a transparent surface lets it through.
fn scatter_specular(model: PhotonModel, color: Vec3A, dir: Vec3A, ng: Vec3A, h: u64) -> Option<(Vec3A, Vec3A)> {
    let d = dir.normalize_or_zero();
    let entering = d.dot(ng) < 0.0;
    let n = if entering { ng } else { -ng };
    let reflect = d - n * (2.0 * d.dot(n));
    match model {
        PhotonModel::Matte => None,
        PhotonModel::Transparent => Some((d, Vec3A::ONE)),
        PhotonModel::Chrome => Some((reflect, color)),
        PhotonModel::Glass { eta } => {
            let ratio = if entering { 1.0 / eta } else { eta };
            let cos_i = -d.dot(n);
            let sin2_t = ratio * ratio * (1.0 - cos_i * cos_i);
            if sin2_t >= 1.0 {
                return Some((reflect, Vec3A::ONE));
            }
            let cos_t = (1.0 - sin2_t).sqrt();
            let (n1, n2) = if entering { (1.0, eta) } else { (eta, 1.0) };
            let rs = ((n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)).powi(2);
            let rp = ((n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i)).powi(2);
            if unit(h) < 0.5 * (rs + rp) {
                Some((reflect, Vec3A::ONE))
            } else {
                Some((d * ratio + n * (ratio * cos_i - cos_t), color))
            }
        }
    }
}

/// What light paths see at a hit: its material's colour (each channel clamped below 1, so that
/// paths lose power at every bounce) and its photon shading model.
fn reflectance_of(frame: &Frame, hit: &Hit) -> (Vec3A, PhotonModel) {
    let world = frame.world;
    let material = world.instances.get(hit.instance as usize).map(|i| i.material_at(hit.primitive));
    let material = material.and_then(|m| world.materials.get(m as usize));
    let (color, model) = material.map_or(([1.0; 3], PhotonModel::Matte), |m| (m.color, m.photon));
    (Vec3A::from(color).clamp(Vec3A::ZERO, Vec3A::splat(0.95)), model)
}

/// The pixel (raster x and y) that `p` projects to through the frame's pinhole camera; `None`
/// behind it, or under a camera shader (whose view is not a projection).
fn raster_of(frame: &Frame, p: Vec3A) -> Option<(i64, i64)> {
    let world = frame.world;
    if world.camera_shader.is_some() {
        return None;
    }
    let c = frame.camera_from_world.transform_point3a(p);
    if c.z <= 1e-6 {
        return None;
    }
    let tan = (world.camera.fov_degrees.to_radians() * 0.5).tan();
    let e = world.options.screen_extent();
    let ((ax, ay), (cx, cy)) = (e.half, e.centre);
    let (sx, sy) = (c.x / (c.z * tan), c.y / (c.z * tan));
    let (w, h) = (world.options.width as f32, world.options.height as f32);
    let x = ((sx - cx) / ax * 0.5 + 0.5) * w;
    let y = (0.5 - (sy - cy) / ay * 0.5) * h;
    (x.is_finite() && y.is_finite()).then(|| (x.floor() as i64, y.floor() as i64))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rays and lights of [`toward_lights`] as one light at a time makes them.
    fn one_by_one(all: &VirtualLights, g: &Gatherer) -> Vec<(Ray, Vec3A)> {
        let mut out = Vec::new();
        for vl in all.sets.get(g.set).into_iter().flatten() {
            let to = vl.p - g.p;
            let r2 = to.length_squared();
            if r2 <= 0.0 {
                continue;
            }
            let r = r2.sqrt();
            let w = to / r;
            let (cos_here, cos_there) = (g.n.dot(w), -vl.n.dot(w));
            if cos_here <= 0.0 || cos_there <= 0.0 {
                continue;
            }
            let reach = r * (1.0 - 1e-3) - epsilon(vl.p);
            let ray = Ray::segment(g.p, w, epsilon(g.p), reach.max(0.0)).at_time(g.time);
            out.push((ray, vl.power * (cos_here * cos_there / r2.max(all.clamp_squared))));
        }
        out
    }

    fn bits(v: Vec3A) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Eight lights at a time make the rays and lights one light at a time makes, bit for bit and
    /// in order: lights all around, behind, at the point itself, nearer than the clamp, and sets
    /// of every size around the blocks' width.
    #[test]
    fn lights_by_eights_are_the_lights_one_by_one() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let mut v = || Vec3A::new(next(), next(), next());
        for size in [0usize, 1, 7, 8, 9, 16, 17, 40] {
            let mut set: Vec<VirtualLight> = (0..size)
                .map(|_| VirtualLight { p: v() * 10.0, n: v().normalize_or_zero(), power: v().abs() })
                .collect();
            let g = Gatherer { p: v() * 10.0, n: v().normalize_or_zero(), time: 0.25, set: 0 };
            if size > 2 {
                set[1].p = g.p;
                set[2].p = g.p + g.n * 1e-3;
            }
            let all = VirtualLights::new(vec![set], 1, 0.5);
            let mut made = Vec::new();
            toward_lights(&all, &g, |ray, light| made.push((ray, light)));
            let want = one_by_one(&all, &g);
            assert_eq!(made.len(), want.len(), "{size} lights");
            for ((a, la), (b, lb)) in made.iter().zip(&want) {
                assert_eq!(bits(a.origin), bits(b.origin));
                assert_eq!(bits(a.direction), bits(b.direction));
                assert_eq!([a.tmin, a.tmax, a.time].map(f32::to_bits), [b.tmin, b.tmax, b.time].map(f32::to_bits));
                assert_eq!(bits(*la), bits(*lb));
            }
        }
        // A point whose set is not there gathers nothing.
        let all = VirtualLights::new(vec![vec![VirtualLight { p: Vec3A::X, n: -Vec3A::X, power: Vec3A::ONE }]], 1, 0.0);
        let g = Gatherer { p: Vec3A::ZERO, n: Vec3A::X, time: 0.0, set: 3 };
        toward_lights(&all, &g, |_, _| panic!("no set, no rays"));
        let g = Gatherer { set: 0, ..g };
        let mut n = 0;
        toward_lights(&all, &g, |_, _| n += 1);
        assert_eq!(n, 1);
    }
}

//! Shading on hits: hits grouped by (material, instance) into batches (`group.rs`), the globals
//! and their derivatives are filled from the hits, and the surface shader's packet code runs; its calls into
//! the renderer are answered by `host.rs`, lights by `lights.rs`. Also the pixel shader's pass over
//! a finished tile, and the hand-written Rust path of benchmarks.
//!
//! Invariants:
//! - A ray's colour is composited front to back: `C += w * Ci`, `w *= 1 - Oi` (RenderMan's `Ci` is
//!   premultiplied by `Oi`), continuing through surfaces while `1 - w` is below
//!   `RenderOptions::opacity_threshold` in some channel and fewer than `max_transparent_layers`
//!   were crossed; what is left of `w` sees the background.
//! - `trace` recursion stops at `RenderOptions::max_ray_depth`: deeper rays return black (RISpec).
//! - A camera sample's tree of rays spawns at most `RAY_TREE_BUDGET` (`ray_budget.rs`): each hit
//!   carries what its tree may still spend, and gives back what it did not.
//! - Everything here is deterministic per ray: random numbers (area light samples, occlusion rays,
//!   `random()` seeds) are hashes of the shading point, never of the thread or the order of work.
//! - Only the outermost shading of a thread is timed (`stats.rs`), tracing excluded.

use super::differential::RayDifferential;
use super::globals::{deriv_row, fill_hit_globals, hit_global_rows, needs_derivs};
use super::group::GroupKey;
use super::hit_geometry::{hit_geometries, GeometryNeeds, GroupHits, HitGeometry, HitRows, InstanceGeometry};
use super::host::ShadeCall;
use super::jobs::{GroupRows, JobRows};
use super::lanes::Lanes;
use super::native::{faced_against, LightSeen, NativeSurface};
use super::primary::PrimaryRays;
use super::ray_budget::RayBudget;
use super::stats::{tracing, ShadingTimer, Stats};
use super::trace_ahead::RayLog;
use super::work::{BatchLights, Pending, Shaded, ShadedRows, Stages};
use super::world::{InstanceShading, Material, RayKind, World, DEFAULT_MATERIAL, MAX_FRAME_OUTPUTS};
use crate::ray::{offset_ray_origin, Hit, HitPacket, Ray, INVALID_ID, PACKET_SIZE};
use crate::shading::{get3, get_row, with_filled_batch, ShaderInstance};
use glam::{Affine3A, Vec3A};
use std::cell::RefCell;
use wide::f32x8;

/// The pixel shader's pass (defined in `pixel.rs`).
pub use super::pixel::{shade_pixels, TilePixels};
/// The work items shading takes and gives (defined in `work.rs`).
pub use super::work::{Frame, Sample, SampleRows};

/// The stages as this module and `lights.rs` provide them.
const STAGES: Stages = Stages {
    trace_rays: trace_budgeted,
    gather_rays,
    shade_in_groups: super::group::shade_in_groups,
    shade_group,
    eval_light: super::lights::eval_light,
    transmission_between: super::lights::transmission_between,
    batch_lights: BatchLights::compute,
};

impl<'w> Frame<'w> {
    /// The frame of a render of `world`.
    pub fn new(world: &'w World) -> Frame<'w> {
        Frame::with_stages(world, STAGES)
    }
}

/// Shades the rays of a primary packet (already intersected): lane `i`'s sample is its radiance
/// times its camera weight (the packet's active lanes are written).
pub fn shade_packet(frame: &Frame, primary: &PrimaryRays, hits: &HitPacket, out: &mut [Sample; PACKET_SIZE]) {
    let mut rows = super::scratch::take(&SAMPLE_ROWS);
    shade_packets(frame, &[(primary, hits)], std::slice::from_mut(&mut *rows));
    let with_outputs = !frame.captured.is_empty();
    for (l, o) in out.iter_mut().enumerate().filter(|(l, _)| primary.packet.active >> l & 1 != 0) {
        *o = rows.lane(l);
        if !with_outputs {
            o.outputs = [[0.0; 3]; MAX_FRAME_OUTPUTS];
        }
    }
    super::scratch::give(&SAMPLE_ROWS, rows);
}

/// [`shade_packet`] of several packets together (a tile's): their hits are grouped by material
/// across the packets, so that a material's shading batches are fuller and fewer. Each batch has
/// its fixed costs (filling, its lights, its shadow packet), and a small batch's shadow packet
/// shares fewer node tests: shaded packet by packet, BART's robots averaged 43 hits a batch.
/// Lane for lane the same values as [`shade_packet`] of each packet: shading a hit reads nothing
/// of the other hits in its batch. Every lane of `out`'s rows is written, but only the active
/// lanes' are samples (and the outputs only where the frame keeps some).
pub fn shade_packets(frame: &Frame, packets: &[(&PrimaryRays, &HitPacket)], out: &mut [SampleRows]) {
    let packets = &packets[..packets.len().min(out.len())];
    let world = frame.world;
    // Each hit's group key and its sample's index (`PACKET_SIZE` a packet), sorted before any hit
    // is gathered: each is then copied once, into the rows of the group that shades it, rather
    // than in the packets' order and then moved by the sort. Misses see the background at once.
    // A packet whose every lane hit one material and instance is a group of its own, shaded
    // where its rows are (without volume shaders, whose segments take each hit's job): its keys
    // are not kept.
    let mut keys = super::group::take_keys();
    let mut whole = super::scratch::take(&WHOLE_PACKETS);
    whole.clear();
    for (k, ((primary, hits), out)) in packets.iter().zip(out.iter_mut()).enumerate() {
        let packet = &primary.packet;
        Stats::add(&frame.stats.primary_rays, packet.active.count_ones() as usize);
        begin_samples(frame, hits, out);
        if !frame.volumes {
            if let Some(key) = whole_packet_key(world, packet.active, hits) {
                whole.push((k, key));
                continue;
            }
        }
        let first = keys.len();
        for i in (0..PACKET_SIZE).filter(|i| packet.active >> i & 1 != 0) {
            let hit = hits.get(i);
            // A holdout leaves its sample transparent black: not shaded, nothing behind it shows.
            if hit.is_hit() && !world.is_holdout(&hit) {
                keys.push((super::group::group_key(world, &hit), (k * PACKET_SIZE + i) as u32));
            }
        }
        let own = &keys[first..];
        if !frame.volumes && own.len() == PACKET_SIZE && own.iter().all(|&(key, _)| key == own[0].0) {
            whole.push((k, own[0].0));
            keys.truncate(first);
        }
    }
    super::group::sort_stably(&mut keys);
    let out = &mut out[..packets.len()];
    // Each camera sample's tree its own budget (what is left of it is not needed here).
    let mut budgets = super::scratch::take(&LANE_BUDGETS);
    budgets.clear();
    budgets.extend(packets.iter().flat_map(|(primary, _)| primary.pixels.map(RayBudget::from_pixel)));
    let samples = &mut *out;
    if frame.volumes {
        // Volume shaders take the segments of each hit's job.
        let mut pending = super::scratch::take(&PENDING_JOBS);
        pending.clear();
        pending.extend(keys.iter().map(|&(_, index)| {
            let (index, lane) = (index as usize, index as usize % PACKET_SIZE);
            let (primary, hits) = packets[index / PACKET_SIZE];
            let (ray, diff, hit) = (primary.packet.get(lane), primary.diffs.lane(lane), hits.get(lane));
            Pending { index, start: 0.0, ray, diff, hit, budget: RayBudget::NONE }
        }));
        shade_pending(frame, (&mut pending, 0), Some(&keys), 0, samples, &mut budgets);
        super::scratch::give(&PENDING_JOBS, pending);
    } else {
        let going_on = shade_primary_layer(frame, packets, (&whole, &keys), samples, &mut budgets);
        let mut later = trace_going_on(frame, going_on, 0, samples);
        shade_pending(frame, (&mut later, 1), None, 0, samples, &mut budgets);
    }
    for ((primary, _), out) in packets.iter().zip(out.iter_mut()) {
        let w = &primary.weights;
        for l in 0..PACKET_SIZE {
            let left = &out.left;
            let alpha = 1.0 - (left[0][l] + left[1][l] + left[2][l]) / 3.0;
            for (c, row) in out.color.iter_mut().enumerate() {
                row[l] *= w[c][l];
            }
            out.alpha[l] = alpha * (w[0][l] + w[1][l] + w[2][l]) / 3.0;
        }
    }
    super::group::give_keys(keys);
    super::scratch::give(&WHOLE_PACKETS, whole);
    super::scratch::give(&LANE_BUDGETS, budgets);
}

/// The group key of a packet whose every lane is active and hit one instance of one material (no
/// parts) that is no holdout: what each lane's [`super::group::group_key`] would be, told from
/// the instance ids alone. `None` for every other packet (its lanes are keyed one by one).
fn whole_packet_key(world: &World, active: u64, hits: &HitPacket) -> Option<(u32, u32)> {
    let ids = &hits.instance.0;
    let id = ids[0];
    // Folded with `|` rather than `all`: no early exit, so the compare vectorises.
    if active != u64::MAX || id == INVALID_ID || ids.iter().fold(0, |acc, &i| acc | (i ^ id)) != 0 {
        return None;
    }
    let inst = world.instances.get(id as usize).filter(|inst| inst.parts.is_none())?;
    (!world.is_holdout(&hits.get(0))).then_some((inst.material, id))
}

/// Traces and shades single rays (secondary rays: incoherent, traced one by one), each the root of
/// a tree of its own budget ([`super::RAY_TREE_BUDGET`]).
pub fn trace_rays(frame: &Frame, rays: &[Ray], depth: u32) -> Vec<Sample> {
    trace_budgeted(frame, rays, &mut vec![RayBudget::FULL; rays.len()], depth)
}

/// [`trace_rays`], ray `i`'s tree spending from `budgets[i]`.
fn trace_budgeted(frame: &Frame, rays: &[Ray], budgets: &mut [RayBudget], depth: u32) -> Vec<Sample> {
    let mut hits = Vec::new();
    tracing(|| frame.world.intersect_rays(RayKind::Trace, rays, &mut hits));
    let eye = frame.world.camera.eye();
    let diffs: Vec<RayDifferential> = rays
        .iter()
        .map(|r| {
            let width = frame.pixel_spread * (r.origin - eye).length();
            RayDifferential::cone(r.direction, width, frame.pixel_spread)
        })
        .collect();
    let mut out = vec![Sample::default(); rays.len()];
    shade_hits(frame, rays, &diffs, &hits, depth, &mut out, budgets);
    out
}

/// What `gather` rays meet (`shadeops::gather`): for each ray that hits a surface, the distance
/// and that surface's own shading (its shader's Ci and Oi, not composited with what lies behind
/// it, no atmosphere). Beyond the ray-depth limit a hit is reported unshaded (black, transparent).
/// Ray `i`'s shading spends from `budgets[i]`.
pub(super) fn gather_rays(
    frame: &Frame,
    rays: &[Ray],
    budgets: &mut [RayBudget],
    depth: u32,
) -> Vec<Option<(f32, Shaded)>> {
    let mut hits = Vec::new();
    tracing(|| frame.world.intersect_rays(RayKind::Trace, rays, &mut hits));
    let eye = frame.world.camera.eye();
    let mut out = vec![None; rays.len()];
    let mut pending = Vec::new();
    for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
        if !hit.is_hit() {
            continue;
        }
        let at = ray.origin + ray.direction * hit.t;
        out[i] = Some((hit.t, Shaded { p: at, ..Shaded::default() }));
        if depth <= frame.world.options.max_ray_depth {
            let width = frame.pixel_spread * (ray.origin - eye).length();
            let diff = RayDifferential::cone(ray.direction, width, frame.pixel_spread);
            let budget = budgets.get(i).copied().unwrap_or(RayBudget::NONE);
            pending.push(Pending { index: i, start: 0.0, ray: *ray, diff, hit: *hit, budget });
        }
    }
    if !pending.is_empty() {
        let mut results = vec![Shaded::default(); pending.len()];
        super::group::shade_in_groups(frame, &mut pending, depth, &mut results);
        Stats::add(&frame.stats.shaded_points, pending.len());
        for (p, r) in pending.iter().zip(results) {
            if let Some(budget) = budgets.get_mut(p.index) {
                budget.charge(r.spent, r.cut);
            }
            out[p.index] = Some((p.hit.t, r));
        }
    }
    out
}

fn shade_hits(
    frame: &Frame,
    rays: &[Ray],
    diffs: &[RayDifferential],
    hits: &[Hit],
    depth: u32,
    out: &mut [Sample],
    budgets: &mut [RayBudget],
) {
    let mut pending = Vec::with_capacity(rays.len());
    for (i, ((ray, hit), diff)) in rays.iter().zip(hits).zip(diffs).enumerate() {
        if let Some(p) = start_sample(frame, i, *ray, *diff, *hit, &mut out[i]) {
            pending.push(p);
        }
    }
    let mut weight = vec![Vec3A::ONE; rays.len()];
    let mut samples = RaySamples { samples: &mut *out, weight: &mut weight };
    shade_pending(frame, (&mut pending, 0), None, depth, &mut samples, budgets);
    for (s, w) in out.iter_mut().zip(&weight) {
        s.alpha = 1.0 - (w.x + w.y + w.z) / 3.0;
    }
}

/// Starts the sample of ray `index`: the background on a miss (`None`), else the shading job
/// (`shade_pending` writes the hit's ids).
fn start_sample(
    frame: &Frame,
    index: usize,
    ray: Ray,
    diff: RayDifferential,
    hit: Hit,
    out: &mut Sample,
) -> Option<Pending> {
    // The hit's ids are written by `shade_pending`, once its hits are sorted by material; its
    // budget by `shade_pending` too, from the ray's.
    begin_sample(frame, hit, out).then_some(Pending { index, start: 0.0, ray, diff, hit, budget: RayBudget::NONE })
}

/// Starts the sample of a ray with `hit` in `out`: the background on a miss (`false`), else
/// nothing yet (`true`: the hit is to be shaded).
#[inline(always)]
fn begin_sample(frame: &Frame, hit: Hit, out: &mut Sample) -> bool {
    *out = Sample {
        color: Vec3A::ZERO,
        alpha: 0.0,
        depth: hit.t,
        object_id: u32::MAX,
        shader_id: u32::MAX,
        normal: Vec3A::ZERO,
        outputs: [[0.0; 3]; MAX_FRAME_OUTPUTS],
    };
    if !hit.is_hit() {
        out.color = Vec3A::from(frame.world.options.background);
        return false;
    }
    true
}

/// Starts a packet's samples in `out` (every lane) from its `hits`: the background where a lane
/// missed, else nothing yet (the hit is to be shaded), as [`begin_sample`] does one.
fn begin_samples(frame: &Frame, hits: &HitPacket, out: &mut SampleRows) {
    let background = frame.world.options.background;
    for (c, row) in out.color.iter_mut().enumerate() {
        for (v, id) in row.iter_mut().zip(&hits.instance.0) {
            *v = if *id == INVALID_ID { background[c] } else { 0.0 };
        }
    }
    out.depth = hits.t.0;
    out.alpha = [0.0; PACKET_SIZE];
    out.object_id = [u32::MAX; PACKET_SIZE];
    out.shader_id = [u32::MAX; PACKET_SIZE];
    out.normal = [[0.0; PACKET_SIZE]; 3];
    out.left = [[1.0; PACKET_SIZE]; 3];
    if !frame.captured.is_empty() {
        out.outputs = [[[0.0; PACKET_SIZE]; 3]; MAX_FRAME_OUTPUTS];
    }
}

/// Samples by index, as compositing writes them: a slice of [`Sample`]s (rays shaded one by one),
/// or a tile's packets by rows (index `PACKET_SIZE * packet + lane`). Indices past the end are
/// read as `None` and written nowhere.
trait Samples {
    fn depth(&self, i: usize) -> Option<f32>;
    fn set_depth(&mut self, i: usize, depth: f32);
    /// Adds `c` to sample `i`'s colour.
    fn add_color(&mut self, i: usize, c: Vec3A);
    /// What is left of sample `i`'s weight: what the surfaces its ray crossed let through.
    fn weight(&self, i: usize) -> Option<Vec3A>;
    fn set_weight(&mut self, i: usize, w: Vec3A);
    /// Sample `i`'s first hit: its object and material ids, its normal (faced toward the ray's
    /// origin), and its outputs where the frame keeps some.
    fn set_first_hit(&mut self, i: usize, ids: (u32, u32), normal: Vec3A, outputs: Option<&Outputs>);
}

/// A sample's kept output variables ([`Sample::outputs`]).
type Outputs = [[f32; 3]; MAX_FRAME_OUTPUTS];

/// Rays' samples one by one, and the weight left to each.
struct RaySamples<'a> {
    samples: &'a mut [Sample],
    weight: &'a mut [Vec3A],
}

impl Samples for RaySamples<'_> {
    #[inline(always)]
    fn depth(&self, i: usize) -> Option<f32> {
        self.samples.get(i).map(|s| s.depth)
    }

    #[inline(always)]
    fn set_depth(&mut self, i: usize, depth: f32) {
        if let Some(s) = self.samples.get_mut(i) {
            s.depth = depth;
        }
    }

    #[inline(always)]
    fn add_color(&mut self, i: usize, c: Vec3A) {
        if let Some(s) = self.samples.get_mut(i) {
            s.color += c;
        }
    }

    #[inline(always)]
    fn weight(&self, i: usize) -> Option<Vec3A> {
        self.weight.get(i).copied()
    }

    #[inline(always)]
    fn set_weight(&mut self, i: usize, w: Vec3A) {
        if let Some(to) = self.weight.get_mut(i) {
            *to = w;
        }
    }

    #[inline(always)]
    fn set_first_hit(&mut self, i: usize, ids: (u32, u32), normal: Vec3A, outputs: Option<&Outputs>) {
        if let Some(s) = self.samples.get_mut(i) {
            (s.object_id, s.shader_id) = ids;
            s.normal = normal;
            if let Some(o) = outputs {
                s.outputs = *o;
            }
        }
    }
}

impl Samples for [SampleRows] {
    #[inline(always)]
    fn depth(&self, i: usize) -> Option<f32> {
        self.get(i / PACKET_SIZE).map(|s| s.depth[i % PACKET_SIZE])
    }

    #[inline(always)]
    fn set_depth(&mut self, i: usize, depth: f32) {
        if let Some(s) = self.get_mut(i / PACKET_SIZE) {
            s.depth[i % PACKET_SIZE] = depth;
        }
    }

    #[inline(always)]
    fn add_color(&mut self, i: usize, c: Vec3A) {
        if let Some(s) = self.get_mut(i / PACKET_SIZE) {
            let l = i % PACKET_SIZE;
            for (row, v) in s.color.iter_mut().zip(c.to_array()) {
                row[l] += v;
            }
        }
    }

    #[inline(always)]
    fn weight(&self, i: usize) -> Option<Vec3A> {
        let l = i % PACKET_SIZE;
        self.get(i / PACKET_SIZE).map(|s| Vec3A::new(s.left[0][l], s.left[1][l], s.left[2][l]))
    }

    #[inline(always)]
    fn set_weight(&mut self, i: usize, w: Vec3A) {
        if let Some(s) = self.get_mut(i / PACKET_SIZE) {
            let l = i % PACKET_SIZE;
            for (row, v) in s.left.iter_mut().zip(w.to_array()) {
                row[l] = v;
            }
        }
    }

    #[inline(always)]
    fn set_first_hit(&mut self, i: usize, ids: (u32, u32), normal: Vec3A, outputs: Option<&Outputs>) {
        if let Some(s) = self.get_mut(i / PACKET_SIZE) {
            let l = i % PACKET_SIZE;
            (s.object_id[l], s.shader_id[l]) = ids;
            for (row, v) in s.normal.iter_mut().zip(normal.to_array()) {
                row[l] = v;
            }
            for (rows, o) in s.outputs.iter_mut().zip(outputs.into_iter().flatten()) {
                for (row, v) in rows.iter_mut().zip(o) {
                    row[l] = *v;
                }
            }
        }
    }
}

/// Shades the pending hits and composites them into `out[p.index]`, following rays through
/// transparent surfaces; the sample's weight is left with what the surfaces let through. The
/// shading of each layer of ray `p.index`'s hits spends from `budgets[p.index]`.
///
/// `first` is a layer of hits and the number of layers its rays crossed before (0: these are
/// the rays' first hits); where `sorted` gives their group keys, they are in its order
/// (`group::shade_sorted_groups`), else they are sorted here.
fn shade_pending<S: Samples + ?Sized>(
    frame: &Frame,
    (first, crossed): (&mut Vec<Pending>, u32),
    sorted: Option<&[GroupKey]>,
    depth: u32,
    out: &mut S,
    budgets: &mut [RayBudget],
) {
    let world = frame.world;
    let depth_rule = depth_rule(frame, depth);
    let mut layer = crossed;
    let mut results = super::scratch::take(&SHADED_RESULTS);
    let mut later: Vec<Pending> = Vec::new();
    loop {
        let current = if layer == crossed { &mut *first } else { &mut later };
        if current.is_empty() {
            break;
        }
        for p in current.iter_mut() {
            p.budget = budgets.get(p.index).map_or(RayBudget::NONE, |b| b.lend());
        }
        results.clear();
        results.resize(current.len(), Shaded::default());
        match sorted {
            Some(keys) if layer == crossed => {
                super::group::shade_sorted_groups(frame, current, keys, depth, &mut results)
            }
            _ => super::group::shade_in_groups(frame, current, depth, &mut results),
        }
        if layer == 0 {
            first_hit_ids(world, current, &results, out);
        }
        // The atmosphere or interior between each ray's origin and its hit (`volume.rs`).
        super::volume::shade_segments(frame, current, &mut results, depth);
        Stats::add(&frame.stats.shaded_points, current.len());
        layer += 1;
        // The rays going on through what they met, traced together (they share their directions
        // with the rays before them: whole packets).
        let mut going_on = Vec::new();
        for (p, r) in current.iter().zip(&results) {
            let at = (p.index, layer, p.start + p.hit.t);
            if composite(world, at, depth_rule, ((r.ci, r.oi), (r.spent, r.cut)), out, budgets) {
                let surface = (r.p, r.ng, r.on_surface);
                going_on.push(ray_going_on(p.index, p.start, surface, p.ray, p.diff, p.hit.t));
            }
        }
        later = trace_going_on(frame, going_on, depth, out);
    }
    super::scratch::give(&SHADED_RESULTS, results);
}

/// Which surface's distance a camera ray's sample keeps as its depth (see [`composite`]).
#[derive(Clone, Copy)]
struct DepthRule {
    /// The opacity a surface's own `Oi` must reach in every channel to count.
    threshold: Vec3A,
    /// The farthest that counts (`DepthFilter::Max`), else the nearest.
    farthest: bool,
}

/// The depth rule of rays at `depth`: the frame's for camera rays, where its threshold is not
/// zero or it keeps the farthest surface; `None` (a sample's depth is its first hit's) otherwise.
fn depth_rule(frame: &Frame, depth: u32) -> Option<DepthRule> {
    let options = &frame.world.options;
    let threshold = Vec3A::from(options.depth_threshold);
    let farthest = options.depth_filter == super::DepthFilter::Max;
    (depth == 0 && (farthest || threshold.cmpgt(Vec3A::ZERO).any())).then_some(DepthRule { threshold, farthest })
}

/// Composites what shading ray `index`'s hit gave (its `Ci` and `Oi`, and the rays it spent and
/// whether it refused one; the `layer`th surface the ray met, at `distance` along the ray that
/// began the sample) into its sample `out[index]`, the budget its tree spent into
/// `budgets[index]`, and leaves the sample's weight with what the surface lets
/// through: `true` when the ray goes on through it (enough gets through, and it is not the last
/// layer the options allow). With a depth rule (camera rays: `RenderOptions::depth_threshold`
/// and `depth_filter`), the sample's depth becomes that of the first layer whose own opacity
/// reaches the threshold in every channel (infinite until one does), or of the last such layer
/// for `DepthFilter::Max`; without, it stays its first hit's.
#[inline(always)]
fn composite<S: Samples + ?Sized>(
    world: &World,
    (index, layer, distance): (usize, u32, f32),
    depth_rule: Option<DepthRule>,
    ((ci, oi), (spent, cut)): ((Vec3A, Vec3A), (u32, bool)),
    out: &mut S,
    budgets: &mut [RayBudget],
) -> bool {
    if let Some(budget) = budgets.get_mut(index) {
        budget.charge(spent, cut);
    }
    let (Some(w), Some(depth)) = (out.weight(index), out.depth(index)) else { return false };
    if let Some(rule) = depth_rule {
        let counts = oi.cmpge(rule.threshold).all();
        if layer == 1 && !counts {
            out.set_depth(index, f32::INFINITY);
        } else if layer > 1 && counts && (rule.farthest || !depth.is_finite()) {
            out.set_depth(index, distance);
        }
    }
    out.add_color(index, w * ci);
    let left = w * (Vec3A::ONE - oi.clamp(Vec3A::ZERO, Vec3A::ONE));
    out.set_weight(index, left);
    // Exactly when the opacity so far, `1 - left`, is below the threshold in some channel.
    let hidden_below = Vec3A::ONE - Vec3A::from(world.options.opacity_threshold);
    left.cmpgt(hidden_below).any() && layer < world.options.max_transparent_layers
}

/// A ray going on through a transparent surface: its sample's index, how far along the ray that
/// began the sample it starts, the ray and its differential.
struct GoingOn {
    index: usize,
    start: f32,
    ray: Ray,
    diff: RayDifferential,
}

/// The ray `index` (`ray`, starting `start` along its sample's first ray, its differential
/// `diff`, its hit at `t`) going on through the surface its shading found at point `p`, of
/// geometric normal `ng` (`on_surface`: whether one was found): unbent, from just behind the
/// surface, its footprint starting where the surface's ended.
fn ray_going_on(
    index: usize,
    start: f32,
    (p, ng, on_surface): (Vec3A, Vec3A, bool),
    ray: Ray,
    diff: RayDifferential,
    t: f32,
) -> GoingOn {
    let side = if ng.dot(ray.direction) > 0.0 { ng } else { -ng };
    let on = Ray::new(offset_ray_origin(p, side), ray.direction).at_time(ray.time);
    let (dodx, dody) = if on_surface { diff.at_hit(ray.direction, t, ng) } else { (Vec3A::ZERO, Vec3A::ZERO) };
    GoingOn { index, start: start + t, ray: on, diff: RayDifferential { dodx, dody, ..diff } }
}

/// Traces the rays going on through transparent surfaces together (they share their directions
/// with the rays before them: whole packets): the hits to shade next, and the background added
/// to the samples of those that meet nothing. At `depth` 0 they go on from camera rays, and see
/// what those see.
fn trace_going_on<S: Samples + ?Sized>(frame: &Frame, going_on: Vec<GoingOn>, depth: u32, out: &mut S) -> Vec<Pending> {
    if going_on.is_empty() {
        return Vec::new();
    }
    let world = frame.world;
    let background = Vec3A::from(world.options.background);
    Stats::add(&frame.stats.transparency_rays, going_on.len());
    let rays: Vec<Ray> = going_on.iter().map(|g| g.ray).collect();
    let mut hits = Vec::new();
    let kind = if depth == 0 { RayKind::Camera } else { RayKind::Trace };
    tracing(|| world.intersect_rays(kind, &rays, &mut hits));
    let mut next = Vec::with_capacity(going_on.len());
    for (GoingOn { index, start, ray, diff }, hit) in going_on.into_iter().zip(hits) {
        if depth == 0 && world.is_holdout(&hit) {
            // What lies behind a holdout does not show, and it adds nothing itself.
            continue;
        }
        if hit.is_hit() {
            next.push(Pending { index, start, ray, diff, hit, budget: RayBudget::NONE });
        } else if let Some(w) = out.weight(index) {
            out.add_color(index, w * background);
        }
    }
    next
}

/// Shades the first hits of a tile's primary rays (`packets`) a group at a time by rows, and
/// composites them into `out` as [`shade_pending`] does its first layer: the rays going on
/// through what they met. `whole` are the packets whose every lane hit one material and
/// instance (the packet, its key), shaded where their rows are; `keys` are the other hits' group
/// keys, sorted, each with its sample's index (`PACKET_SIZE` a packet), whose groups' rays,
/// differentials and hits are gathered into rows straight from the packets' rows (no job per
/// hit). Not for scenes with volume shaders (their segments take each hit's job).
fn shade_primary_layer(
    frame: &Frame,
    packets: &[(&PrimaryRays, &HitPacket)],
    (whole, keys): (&[WholePacket], &[GroupKey]),
    out: &mut [SampleRows],
    budgets: &mut [RayBudget],
) -> Vec<GoingOn> {
    let mut jobs = super::scratch::take(&PRIMARY_JOBS);
    let mut results = super::scratch::take(&SHADED_ROWS);
    let mut going_on = Vec::new();
    let mut lanes = PrimaryLanes { out, budgets, going_on: &mut going_on };
    for &(k, key) in whole {
        let Some((primary, hits)) = packets.get(k) else { continue };
        let first = k * PACKET_SIZE;
        let lent: [RayBudget; PACKET_SIZE] =
            std::array::from_fn(|l| lanes.budgets.get(first + l).map_or(RayBudget::NONE, |b| b.lend()));
        let rows = GroupRows::whole_packet((&primary.packet, &primary.diffs, *hits), &lent);
        let samples = GroupSamples::<std::ops::Range<usize>>::WholePacket(k);
        shade_primary_group(frame, (rows, key), samples, &mut results, &mut lanes);
    }
    let mut start = 0;
    while start < keys.len() {
        let key = keys[start].0;
        jobs.clear();
        let mut end = start;
        while let Some(&(k, index)) = keys.get(end) {
            let index = index as usize;
            let Some((primary, hits)) = packets.get(index / PACKET_SIZE) else { break };
            let budget = lanes.budgets.get(index).map_or(RayBudget::NONE, |b| b.lend());
            let rows = (&primary.packet, &primary.diffs, *hits);
            if k != key || !jobs.push_lane(rows, index % PACKET_SIZE, budget) {
                break;
            }
            end += 1;
        }
        if end == start {
            // A key whose sample is not in the packets (the caller makes none).
            start += 1;
            continue;
        }
        jobs.finish();
        let indices = keys[start..end].iter().map(|&(_, index)| index as usize);
        shade_primary_group(frame, (jobs.rows(), key), GroupSamples::Each(indices), &mut results, &mut lanes);
        start = end;
    }
    Stats::add(&frame.stats.shaded_points, keys.len() + whole.len() * PACKET_SIZE);
    super::scratch::give(&PRIMARY_JOBS, jobs);
    super::scratch::give(&SHADED_ROWS, results);
    going_on
}

/// A tile's packet whose every lane hit one material and instance: its index among the tile's
/// packets, and the (material, instance) of its hits.
type WholePacket = (usize, (u32, u32));

/// What [`shade_primary_layer`] composites its groups into, by sample index.
struct PrimaryLanes<'a> {
    out: &'a mut [SampleRows],
    budgets: &'a mut [RayBudget],
    going_on: &'a mut Vec<GoingOn>,
}

/// Shades one group of first hits (`rows`, of group key `key`; lane `l` the sample `samples`
/// gives it) and composites them (see [`shade_primary_layer`]), `results` a buffer.
fn shade_primary_group<I: Iterator<Item = usize>>(
    frame: &Frame,
    (rows, key): (GroupRows, (u32, u32)),
    samples: GroupSamples<I>,
    results: &mut ShadedRows,
    to: &mut PrimaryLanes,
) {
    let world = frame.world;
    shade_group_rows(frame, &rows, 0, results);
    // The first hits' ids (see `first_hit_ids`): the group's material's.
    let ids = world.instances.get(rows.instance() as usize).map(|_| {
        let material = key.0;
        (world.materials.get(material as usize).map_or(0, |m| m.object_id), material)
    });
    let rule = depth_rule(frame, 0);
    let r = &*results;
    match samples {
        GroupSamples::WholePacket(k) => {
            if composite_whole_packet(world, (&rows, ids, rule), k, r, to) {
                return;
            }
            composite_lanes(world, (&rows, ids, rule), k * PACKET_SIZE..(k + 1) * PACKET_SIZE, r, to);
        }
        GroupSamples::Each(indices) => composite_lanes(world, (&rows, ids, rule), indices, r, to),
    }
}

/// [`shade_primary_group`]'s compositing lane by lane: lane `l` of `rows` and `r` into sample
/// `indices[l]`, with the group's `ids`.
fn composite_lanes(
    world: &World,
    (rows, ids, rule): (&GroupRows, Option<(u32, u32)>, Option<DepthRule>),
    indices: impl Iterator<Item = usize>,
    r: &ShadedRows,
    to: &mut PrimaryLanes,
) {
    for (lane, index) in indices.enumerate().take(r.len) {
        let [ci, oi, p, ng] = r.vectors(lane);
        if let Some(ids) = ids {
            let normal = if ng.dot(rows.direction(lane)) > 0.0 { -ng } else { ng };
            // (Zeros otherwise, as the sample began.)
            let outputs = r.captured.then(|| r.outputs(lane));
            to.out.set_first_hit(index, ids, normal, outputs.as_ref());
        }
        let t = rows.hit(lane).t;
        let used = (r.spent[lane], r.cut >> lane & 1 != 0);
        if composite(world, (index, 1, t), rule, ((ci, oi), used), to.out, to.budgets) {
            let surface = (p, ng, r.on_surface >> lane & 1 != 0);
            to.going_on.push(ray_going_on(index, 0.0, surface, rows.ray(lane), rows.diff(lane), t));
        }
    }
}

/// Whose samples a group of first hits is: lane `l`'s is `indices[l]`, or a whole packet's lane
/// `l`'s (`PACKET_SIZE * k + l`).
enum GroupSamples<I> {
    Each(I),
    WholePacket(usize),
}

/// [`shade_primary_group`]'s compositing of whole packet `k`'s first hits (lane `l` of `rows` and
/// `r` its lane `l`; `ids` the group's), a row at a time: lane by lane the arithmetic of
/// [`composite`] (a first layer's) and the ids and normals of the lane-by-lane path. `false`
/// (nothing done) when the rows are not a whole packet's.
fn composite_whole_packet(
    world: &World,
    (rows, ids, rule): (&GroupRows, Option<(u32, u32)>, Option<DepthRule>),
    k: usize,
    r: &ShadedRows,
    to: &mut PrimaryLanes,
) -> bool {
    let first = k * PACKET_SIZE;
    let (Some(out), Some(budgets)) = (to.out.get_mut(k), to.budgets.get_mut(first..first + PACKET_SIZE)) else {
        return false;
    };
    if r.len != PACKET_SIZE || rows.len() != PACKET_SIZE {
        return false;
    }
    for (l, b) in budgets.iter_mut().enumerate() {
        b.charge(r.spent[l], r.cut >> l & 1 != 0);
    }
    let threshold = world.options.opacity_threshold;
    let hidden_below = threshold.map(|t| 1.0 - t);
    let layers_left = 1 < world.options.max_transparent_layers;
    let mut going_on = 0u64;
    if let Some(rule) = rule {
        // A first layer whose own opacity falls short of the threshold leaves no depth.
        let th = rule.threshold;
        for l in 0..PACKET_SIZE {
            if !(r.oi[0][l] >= th.x && r.oi[1][l] >= th.y && r.oi[2][l] >= th.z) {
                out.depth[l] = f32::INFINITY;
            }
        }
    }
    for l in 0..PACKET_SIZE {
        let mut on = false;
        for (c, hidden_below) in hidden_below.iter().enumerate() {
            let w = out.left[c][l];
            out.color[c][l] += w * r.ci[c][l];
            // `Vec3A::clamp(ZERO, ONE)`: SSE's max and then min, which give the bound for NaN.
            let o = r.oi[c][l];
            let o = if o > 0.0 { o } else { 0.0 };
            let o = if o < 1.0 { o } else { 1.0 };
            let left = w * (1.0 - o);
            out.left[c][l] = left;
            on |= left > *hidden_below;
        }
        going_on |= u64::from(on && layers_left) << l;
    }
    if let Some((object_id, shader_id)) = ids {
        out.object_id = [object_id; PACKET_SIZE];
        out.shader_id = [shader_id; PACKET_SIZE];
        for l in 0..PACKET_SIZE {
            let ng = Vec3A::new(r.ng[0][l], r.ng[1][l], r.ng[2][l]);
            let normal = if ng.dot(rows.direction(l)) > 0.0 { -ng } else { ng };
            (out.normal[0][l], out.normal[1][l], out.normal[2][l]) = (normal.x, normal.y, normal.z);
        }
        if r.captured {
            out.outputs = r.outputs;
        }
    }
    for l in (0..PACKET_SIZE).filter(|l| going_on >> l & 1 != 0) {
        let [_, _, p, ng] = r.vectors(l);
        let surface = (p, ng, r.on_surface >> l & 1 != 0);
        let t = rows.hit(l).t;
        to.going_on.push(ray_going_on(first + l, 0.0, surface, rows.ray(l), rows.diff(l), t));
    }
    true
}

/// The object and material ids of each first hit into its sample, and its geometric normal (from
/// its shading, `shaded`) turned toward the ray's origin. `pending` comes sorted by material
/// (`shade_in_groups`), so each run of one material reads the material once, and each hit's
/// material is found again in the caches `shade_in_groups` just filled.
fn first_hit_ids<S: Samples + ?Sized>(world: &World, pending: &[Pending], shaded: &[Shaded], out: &mut S) {
    let mut last: Option<(u32, u32)> = None;
    for (p, r) in pending.iter().zip(shaded) {
        let Some(inst) = world.instances.get(p.hit.instance as usize) else { continue };
        let material = inst.material_at(p.hit.primitive);
        let object_id = match last {
            Some((m, id)) if m == material => id,
            _ => world.materials.get(material as usize).map_or(0, |m| m.object_id),
        };
        last = Some((material, object_id));
        let normal = if r.ng.dot(p.ray.direction) > 0.0 { -r.ng } else { r.ng };
        out.set_first_hit(p.index, (object_id, material), normal, Some(&r.outputs));
    }
}

/// Shades hits that share material and instance.
pub(super) fn shade_group(frame: &Frame, group: &GroupRows, depth: u32, out: &mut [Shaded]) {
    let mut rows = super::scratch::take(&SHADED_ROWS);
    shade_group_rows(frame, group, depth, &mut rows);
    for (l, o) in out.iter_mut().enumerate().take(rows.len) {
        *o = rows.lane(l);
    }
    super::scratch::give(&SHADED_ROWS, rows);
}

/// [`shade_group`], its results by rows.
fn shade_group_rows(frame: &Frame, group: &GroupRows, depth: u32, out: &mut ShadedRows) {
    out.reset(group.len());
    if group.is_empty() {
        return;
    }
    let _timer = ShadingTimer::start(&frame.stats);
    let world = frame.world;
    let Some(inst) = world.instances.get(group.instance() as usize) else { return };
    // The group's hits share their material (`shade_in_groups`).
    let material_id = inst.material_at(group.hit(0).primitive);
    let material = world.materials.get(material_id as usize).unwrap_or(&DEFAULT_MATERIAL);
    let shaders = || [&material.surface, &material.displacement].into_iter().flatten();
    let needs = GeometryNeeds {
        derivs: shaders().any(|s| needs_derivs(&s.program)),
        coords: shaders().any(|s| {
            let g = &s.program.slots;
            [g.u, g.v, g.s, g.t, g.dpdu, g.dpdv].iter().any(Option::is_some)
        }),
        dpduv: shaders().any(|s| s.program.slots.dpdu.is_some() || s.program.slots.dpdv.is_some()),
        normal_derivs: shaders().any(|s| deriv_row(s.program.slots.n, 3, s.program.layout().deriv_slots).is_some()),
    };
    let Some(ig) = InstanceGeometry::new(world, inst, group.instance(), needs) else { return };
    // The rays the group's shading spawns start past the material's trace bias.
    let _bias = super::work::LaunchBias::begin(material.trace_bias);
    // Each lane's budget, spent by its displacement, light and surface shaders in turn.
    let mut budgets = super::scratch::take(&LANE_BUDGETS);
    budgets.clear();
    let sets_parameters = !material.ray_values.is_empty();
    let given = &group.budgets[..group.len()];
    budgets.extend(given.iter().map(|b| b.through(material_id, sets_parameters, material.trace_depths)));
    shade_group_lanes(frame, group, depth, out, (inst, material_id, material), &ig, &mut budgets);
    for (l, (given, b)) in given.iter().zip(budgets.iter()).enumerate().take(out.len) {
        out.spent[l] = given.left.saturating_sub(b.left);
        out.cut |= u64::from(b.cut) << l;
    }
    super::scratch::give(&LANE_BUDGETS, budgets);
}

/// [`shade_group`] once the group's geometry is known, each lane's shaders spending from
/// `budgets`.
fn shade_group_lanes(
    frame: &Frame,
    group: &GroupRows,
    depth: u32,
    out: &mut ShadedRows,
    (inst, material_id, material): (&InstanceShading, u32, &Material),
    ig: &InstanceGeometry,
    budgets: &mut [RayBudget],
) {
    let world = frame.world;
    with_hit_geometry(|HitBuffers { geoms, rows }| {
        // The slots of earlier groups are written over in place (`hit_geometry_into`). The buffer
        // only grows: slots cut off and made again were each a `HitGeometry::default()` built on
        // the stack and copied in (with loads across its stores, which stall).
        if geoms.len() < group.len() {
            geoms.resize_with(group.len(), || None);
        }
        let geoms = &mut geoms[..group.len()];
        let vertex_params = world.vertex_params.get(&(group.instance(), material_id));
        // Whether anything here reads more of the hits than a surface batch does.
        let each = material.displacement.is_some()
            || material.native.is_some()
            || material.surface.is_none()
            || vertex_params.is_some();
        let by_rows = hit_geometries(ig, group, geoms, rows, each);
        let mut rows = by_rows.then_some(&**rows);
        let color = Vec3A::from(material.color);
        let opacity = Vec3A::from(material.opacity);
        // A truly displaced instance's mesh is where its truly displacing materials' shaders
        // moved it already; its other parts' shaders still bump-map.
        let moved_already = inst.displaced && material.true_displacement;
        if let Some(displacement) = material.displacement.as_ref().filter(|_| !moved_already) {
            let at = (material_id, inst.world_from_object);
            let moves = Moves::NormalOnly;
            displace(frame, displacement, at, group, geoms, (color, opacity), depth, budgets, moves);
            // The hits' normals (and points) are the displaced ones now, not the rows'.
            rows = None;
        }
        if let Some(native) = &material.native {
            shade_native(frame, native.as_ref(), group, geoms, (color, opacity), depth, out, budgets);
            return;
        }
        let Some(surface) = &material.surface else {
            // RenderMan's default surface: a matte that faces the viewer.
            for (lane, g) in geoms.iter().enumerate() {
                let Some(g) = g else { continue };
                let cs = g.cs.unwrap_or(color);
                let os = g.os.unwrap_or(opacity);
                // A displacement shader leaves `N` as `calculatenormal` made it, not of unit length.
                let facing = g.n.normalize_or_zero().dot(-group.direction(lane).normalize_or_zero()).abs();
                out.set(lane, [os * cs * (0.2 + 0.8 * facing), os, g.p, g.ng]);
            }
            return;
        };
        let hits = match rows {
            Some(rows) if !each => GroupHits::Rows(rows, group.len()),
            // Without `each`, `hit_geometries` wrote the slots only where it wrote no rows.
            _ => GroupHits::Each(geoms, rows),
        };
        let program = &surface.program;
        let slots = &program.slots;
        with_filled_batch(program, group.len(), &hit_global_rows(program), |batch| {
            {
                let mut raw = batch.raw_mut();
                surface.write_params(&mut raw);
                fill_hit_globals(&mut raw, program, group, hits, (color, opacity));
                if let Some(vp) = vertex_params {
                    for (lane, g) in geoms.iter().enumerate() {
                        let Some(g) = g else { continue };
                        for &(param, attr) in vp {
                            let slot = &program.layout().params[param];
                            if let Some(values) = g.attributes.get(attr) {
                                for (k, v) in values.iter().enumerate() {
                                    raw.varying[(slot.offset + k) * raw.stride + lane] = *v;
                                }
                                raw.bound[param] = 1;
                            }
                        }
                    }
                }
            }
            let at = (material_id, inst.world_from_object);
            let mut call = batch_call(frame, surface, at, group, hits, depth, &mut *budgets);
            if traces_ahead(frame, program, group.len(), depth) {
                run_tracing_ahead(frame, program, batch, &mut call, depth);
            } else {
                let table = call.table();
                program.code.shade_with_table(batch, &table);
            }
            let raw = batch.raw_mut();
            surface_results(&raw, slots, hits, opacity, out);
            // The output variables the frame keeps, of primary hits.
            let captured = if depth == 0 { &frame.captured[..] } else { &[] };
            let lanes = out.len;
            if !captured.is_empty() {
                out.captured = true;
                for row in out.outputs.iter_mut().flatten() {
                    row[..lanes].fill(0.0);
                }
            }
            for (name, to) in captured.iter().zip(out.outputs.iter_mut()) {
                // An output parameter, else a global the shader uses (`N`, `Ci`, `s`...).
                let layout = program.layout();
                let (varying, offset, components) = match layout.param(name) {
                    Some((_, p)) if p.output && !p.string && p.len == 1 => (p.varying, p.offset, p.components),
                    Some(_) => continue,
                    None => match layout.global(name) {
                        Some(g) if g.components <= 3 => (g.varying, g.offset, g.components),
                        _ => continue,
                    },
                };
                for (k, row) in to.iter_mut().enumerate().take(components.min(3)) {
                    for (lane, o) in row.iter_mut().enumerate().take(lanes) {
                        let v = if varying {
                            raw.varying.get((offset + k) * raw.stride + lane)
                        } else {
                            raw.uniform.get(offset + k)
                        };
                        *o = v.copied().filter(|v| v.is_finite()).unwrap_or(0.0);
                    }
                }
            }
        });
    })
}

/// A surface batch's results into `out` (its rows reset for the group): `Ci` and `Oi` as the
/// shader left them (no `Oi`: the surface's opacity), each zero unless all three components are
/// finite, and each hit's point and geometric normal, in the lanes whose hit has a surface.
fn surface_results(
    raw: &rtsl_compiler::abi::RawBatch<'_>,
    slots: &crate::shading::GlobalSlots,
    hits: GroupHits,
    opacity: Vec3A,
    out: &mut ShadedRows,
) {
    let lanes = out.len;
    let valid = match hits {
        GroupHits::Rows(rows, _) => rows.valid,
        GroupHits::Each(geoms, _) => {
            geoms.iter().take(lanes).enumerate().fold(0u64, |m, (l, g)| m | u64::from(g.is_some()) << l)
        }
    } & lane_mask(lanes);
    for (k, row) in out.ci.iter_mut().enumerate() {
        get_row(raw, slots.ci, k, 0.0, &mut row[..lanes]);
    }
    match slots.oi {
        Some(_) => {
            for (k, row) in out.oi.iter_mut().enumerate() {
                get_row(raw, slots.oi, k, 0.0, &mut row[..lanes]);
            }
        }
        None => {
            for lane in 0..lanes {
                let os = match hits {
                    GroupHits::Each(geoms, _) => geoms.get(lane).and_then(|g| g.as_ref()?.os),
                    GroupHits::Rows(..) => None,
                };
                let v = os.unwrap_or(opacity);
                (out.oi[0][lane], out.oi[1][lane], out.oi[2][lane]) = (v.x, v.y, v.z);
            }
        }
    }
    for rows in [&mut out.ci, &mut out.oi] {
        keep_finite(rows, valid, lanes);
    }
    match hits {
        GroupHits::Rows(r, _) => {
            for c in 0..lanes.div_ceil(8) {
                let kept = kept_lanes(valid, c);
                for (to, from) in out.p.iter_mut().zip(&r.p).chain(out.ng.iter_mut().zip(&r.ng)) {
                    let v = <f32x8 as Lanes>::load(from, 8 * c);
                    kept.select(v, f32x8::ZERO).write_to(&mut to[8 * c..]);
                }
            }
        }
        GroupHits::Each(geoms, _) => {
            for (l, g) in geoms.iter().enumerate().take(lanes) {
                let Some(g) = g else { continue };
                let (p, ng) = g.traced.unwrap_or((g.p, g.ng));
                for (rows, v) in [(&mut out.p, p), (&mut out.ng, ng)] {
                    (rows[0][l], rows[1][l], rows[2][l]) = (v.x, v.y, v.z);
                }
            }
        }
    }
    out.on_surface = valid;
}

/// The first `lanes` lanes of a packet.
fn lane_mask(lanes: usize) -> u64 {
    if lanes >= PACKET_SIZE {
        u64::MAX
    } else {
        (1u64 << lanes) - 1
    }
}

/// `finite_or_zero` of each lane's triple in `rows`, and zero in the lanes not in `keep` (eight
/// lanes at a time, up to `lanes` rounded up to eight).
fn keep_finite(rows: &mut [[f32; PACKET_SIZE]; 3], keep: u64, lanes: usize) {
    for c in 0..lanes.div_ceil(8) {
        let v: [f32x8; 3] = std::array::from_fn(|k| <f32x8 as Lanes>::load(&rows[k], 8 * c));
        let finite = v[0].is_finite() & v[1].is_finite() & v[2].is_finite() & kept_lanes(keep, c);
        for (row, v) in rows.iter_mut().zip(v) {
            finite.select(v, f32x8::ZERO).write_to(&mut row[8 * c..]);
        }
    }
}

/// The mask of lanes `8 * c..8 * c + 8` set in `bits`.
#[inline(always)]
fn kept_lanes(bits: u64, c: usize) -> f32x8 {
    let eight = bits.checked_shr(8 * c as u32).unwrap_or(0);
    <f32x8 as Lanes>::mask_from_fn(|j| eight >> j & 1 != 0)
}

/// Whether a surface batch of `lanes` lanes runs twice to trace its `trace` or `occlusion` rays,
/// or gather its virtual lights, together (`trace_ahead.rs`): when it has more than one chunk, and
/// its shader calls `trace` (whose rays may go deeper), `occlusion`, or `indirectdiffuse` under
/// instant radiosity (which gathers virtual lights), and none of the built-ins whose rays cost
/// more than a second run of the shader saves (`gather`, `indirectdiffuse` sampling the
/// hemisphere with shaded rays: the first run would trace theirs too).
fn traces_ahead(frame: &Frame, program: &crate::shading::ShaderProgram, lanes: usize, depth: u32) -> bool {
    let options = &frame.world.options;
    let calls = program.code.ray_calls();
    let traces = calls.trace && depth < options.max_ray_depth;
    let gathers_lights = options.gi.virtual_lights > 0;
    let gathers = calls.indirect && gathers_lights;
    let hemisphere = calls.indirect && !gathers_lights;
    options.trace_ahead && lanes > 4 && (traces || gathers || calls.occlusion) && !calls.gather && !hemisphere
}

/// Runs a surface batch's shader twice (`trace_ahead.rs`): a first run notes its `trace` rays,
/// they are traced and shaded together, and a second run from the same values gets their answers.
fn run_tracing_ahead(
    frame: &Frame,
    program: &crate::shading::ShaderProgram,
    batch: &mut rtsl_compiler::abi::BatchData,
    call: &mut ShadeCall,
    depth: u32,
) {
    let mut saved = super::scratch::take(&SAVED_VALUES);
    batch.save_values(&mut saved);
    call.rays_log = RayLog::Record(Default::default());
    let table = call.table();
    program.code.shade_with_table(batch, &table);
    if let RayLog::Record(noted) = std::mem::take(&mut call.rays_log) {
        if noted.needs_replay() {
            call.rays_log = RayLog::Replay(noted.trace(frame, depth + 1, call.budgets));
            batch.restore_values(&saved);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            call.rays_log = RayLog::Direct;
        }
    }
    super::scratch::give(&SAVED_VALUES, saved);
}

thread_local! {
    /// Tiles' jobs (`shade_packets`, in scenes with volume shaders).
    static PENDING_JOBS: RefCell<Vec<Vec<Pending>>> = const { RefCell::new(Vec::new()) };
    /// A tile's packets whose every lane hit one material and instance, with its key
    /// (`shade_packets`).
    static WHOLE_PACKETS: RefCell<Vec<Vec<WholePacket>>> = const { RefCell::new(Vec::new()) };
    /// Groups of a tile's first hits by rows (`shade_primary_layer`).
    static PRIMARY_JOBS: RefCell<Vec<Box<JobRows>>> = const { RefCell::new(Vec::new()) };
    /// What shading a layer of hits produced (`shade_pending`).
    static SHADED_RESULTS: RefCell<Vec<Vec<Shaded>>> = const { RefCell::new(Vec::new()) };
    /// Groups' lane budgets (`shade_group`), and tiles' samples' budgets (`shade_packets`).
    static LANE_BUDGETS: RefCell<Vec<Vec<RayBudget>>> = const { RefCell::new(Vec::new()) };
    /// A packet's samples (`shade_packet`).
    static SAMPLE_ROWS: RefCell<Vec<Box<SampleRows>>> = const { RefCell::new(Vec::new()) };
    /// Groups' results by rows (`shade_group`, `shade_primary_layer`).
    static SHADED_ROWS: RefCell<Vec<Box<ShadedRows>>> = const { RefCell::new(Vec::new()) };
    /// Batches' values kept for their second runs (`run_tracing_ahead`).
    static SAVED_VALUES: RefCell<Vec<rtsl_compiler::abi::SavedValues>> = const { RefCell::new(Vec::new()) };
}

/// A group's hit geometry, hit by hit and (for most groups) by rows.
#[derive(Default)]
struct HitBuffers {
    geoms: Vec<Option<HitGeometry>>,
    rows: Box<HitRows>,
}

thread_local! {
    /// Hit geometry buffers reused from group to group (a group's is a packet of hits of a few
    /// hundred bytes each).
    static HIT_GEOMETRY_BUFFERS: RefCell<Vec<HitBuffers>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` with a hit geometry buffer from this thread's stack of them. Its slots still hold
/// earlier groups' geometry, to be written over in place (`hit_geometry_into`).
fn with_hit_geometry<R>(f: impl FnOnce(&mut HitBuffers) -> R) -> R {
    let mut buffer = super::scratch::take(&HIT_GEOMETRY_BUFFERS);
    let r = f(&mut buffer);
    super::scratch::give(&HIT_GEOMETRY_BUFFERS, buffer);
    r
}

/// Appends each lane's point, shading mask and ray time to `points`, `mask` and `times`: what the
/// lights of a batch of hits are computed for.
fn extend_batch_lanes(
    group: &GroupRows,
    hits: GroupHits,
    (points, mask, times): (&mut Vec<Vec3A>, &mut Vec<i32>, &mut Vec<f32>),
) {
    match hits {
        // Straight from the rows: through `GroupHits::get`, each lane's whole surface was read
        // for its point and validity.
        GroupHits::Rows(rows, len) => {
            let valid = |lane: usize| lane < PACKET_SIZE && rows.valid >> lane & 1 != 0;
            points.extend((0..len).map(|l| {
                if valid(l) {
                    Vec3A::new(rows.p[0][l], rows.p[1][l], rows.p[2][l])
                } else {
                    Vec3A::ZERO
                }
            }));
            mask.extend((0..len).map(|l| if valid(l) { -1 } else { 0 }));
        }
        GroupHits::Each(..) => {
            points.extend(hits.iter().map(|g| g.map_or(Vec3A::ZERO, |g| g.p)));
            mask.extend(hits.iter().map(|g| if g.is_some() { -1 } else { 0 }));
        }
    }
    times.extend_from_slice(&group.rays.time.0[..group.len()]);
}

/// The renderer's side of a shader run over a batch of hits on `material` (placed by
/// `world_from_object`): it serves the batch's lights and answers its messages.
fn batch_call<'f, 'w>(
    frame: &'f Frame<'w>,
    shader: &'f ShaderInstance,
    (material, world_from_object): (u32, Affine3A),
    group: &GroupRows,
    hits: GroupHits,
    depth: u32,
    budgets: &'f mut [RayBudget],
) -> ShadeCall<'f, 'w> {
    let mut call = ShadeCall::new(frame, shader, world_from_object, depth, budgets);
    call.material = Some(material);
    // Into reused buffers.
    call.take_buffers();
    extend_batch_lanes(group, hits, (&mut call.batch_points, &mut call.batch_mask, &mut call.batch_times));
    call.batch_front.extend(front_normals(group, hits));
    call
}

/// Each lane's shading normal turned toward the ray's origin (by the geometric normal, as
/// `faceforward(N, I)`): the side whose lights a typical surface shader sums.
fn front_normals<'a>(group: &'a GroupRows<'a>, hits: GroupHits<'a>) -> impl Iterator<Item = Vec3A> + 'a {
    // The normals straight from the rows where there are rows (see `extend_batch_lanes`).
    let rows = match hits {
        GroupHits::Rows(rows, len) => Some((rows, len)),
        GroupHits::Each(..) => None,
    };
    let v3 = |r: &[[f32; PACKET_SIZE]; 3], l: usize| Vec3A::new(r[0][l], r[1][l], r[2][l]);
    (0..hits.len().min(group.len())).map(move |lane| {
        let (n, ng) = match rows {
            Some((rows, len)) => {
                if lane >= len.min(PACKET_SIZE) || rows.valid >> lane & 1 == 0 {
                    return Vec3A::ZERO;
                }
                (v3(&rows.n, lane), v3(&rows.ng, lane))
            }
            None => match hits.get(lane) {
                Some(g) => (g.n, g.ng),
                None => return Vec3A::ZERO,
            },
        };
        if group.direction(lane).dot(ng) > 0.0 {
            -n
        } else {
            n
        }
    })
}

/// What a displacement shader's run changes of each hit ([`displace`]).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Moves {
    /// The shading normal: bump mapping.
    NormalOnly,
    /// The point too: true displacement, of the points of a diced mesh.
    PointAndNormal,
    /// The point alone: a surface shader's `P` moving a diced mesh's points (its `N` is for its
    /// own shading).
    PointOnly,
}

/// Runs a displacement shader over a group of hits: the `N` it leaves (when finite and not
/// zero) replaces each hit's shading normal. As bump mapping (`Moves::NormalOnly`) `P` and the
/// geometry stay where the ray met them; for true displacement the `P` it leaves (when finite)
/// replaces the hit's point too. Vertex-scope parameters are bound for the surface shader only.
#[allow(clippy::too_many_arguments)]
fn displace(
    frame: &Frame,
    displacement: &ShaderInstance,
    (material, world_from_object): (u32, Affine3A),
    group: &GroupRows,
    geoms: &mut [Option<HitGeometry>],
    appearance: (Vec3A, Vec3A),
    depth: u32,
    budgets: &mut [RayBudget],
    moves: Moves,
) {
    let program = &displacement.program;
    with_filled_batch(program, group.len(), &hit_global_rows(program), |batch| {
        {
            let mut raw = batch.raw_mut();
            displacement.write_params(&mut raw);
            fill_hit_globals(&mut raw, program, group, GroupHits::Each(geoms, None), appearance);
        }
        let hits = GroupHits::Each(geoms, None);
        let at = (material, world_from_object);
        let mut call = batch_call(frame, displacement, at, group, hits, depth, &mut *budgets);
        let table = call.table();
        program.code.shade_with_table(batch, &table);
        let raw = batch.raw_mut();
        for (lane, g) in geoms.iter_mut().enumerate() {
            let Some(g) = g else { continue };
            let n = get3(&raw, program.slots.n, lane, g.n);
            if moves != Moves::PointOnly && n.is_finite() && n != Vec3A::ZERO {
                g.n = n;
            }
            if moves != Moves::NormalOnly {
                let p = get3(&raw, program.slots.p, lane, g.p);
                if p.is_finite() {
                    g.p = p;
                }
            }
        }
    });
}

/// Runs the shader that moves a group's material's geometry ([`Material::displacing_shader`]) at
/// the group's hits, as true displacement does at the points of a diced mesh
/// (`true_displacement.rs`): `out[l]` is lane `l`'s point and normal as the shader leaves them
/// (a surface shader's: the normal as it was), world space, or `None` where the lane has no
/// surface or its material does not truly displace. Returns whether a surface shader ran.
pub(super) fn displaced_points(frame: &Frame, group: &GroupRows, out: &mut [Option<(Vec3A, Vec3A)>]) -> bool {
    out.iter_mut().for_each(|o| *o = None);
    if group.is_empty() {
        return false;
    }
    let world = frame.world;
    let Some(inst) = world.instances.get(group.instance() as usize) else { return false };
    let material_id = inst.material_at(group.hit(0).primitive);
    let material = world.materials.get(material_id as usize).unwrap_or(&DEFAULT_MATERIAL);
    let Some((displacement, with_normals)) = material.displacing_shader() else { return false };
    let program = &displacement.program;
    let g = &program.slots;
    let needs = GeometryNeeds {
        derivs: needs_derivs(program),
        coords: [g.u, g.v, g.s, g.t, g.dpdu, g.dpdv].iter().any(Option::is_some),
        dpduv: g.dpdu.is_some() || g.dpdv.is_some(),
        normal_derivs: deriv_row(g.n, 3, program.layout().deriv_slots).is_some(),
    };
    let Some(ig) = InstanceGeometry::new(world, inst, group.instance(), needs) else { return false };
    let mut budgets = vec![RayBudget::FULL; group.len()];
    with_hit_geometry(|HitBuffers { geoms, rows }| {
        if geoms.len() < group.len() {
            geoms.resize_with(group.len(), || None);
        }
        let geoms = &mut geoms[..group.len()];
        hit_geometries(&ig, group, geoms, rows, true);
        let appearance = (Vec3A::from(material.color), Vec3A::from(material.opacity));
        let at = (material_id, inst.world_from_object);
        let moves = if with_normals { Moves::PointAndNormal } else { Moves::PointOnly };
        displace(frame, displacement, at, group, geoms, appearance, 0, &mut budgets, moves);
        for (o, g) in out.iter_mut().zip(geoms.iter()) {
            *o = g.as_ref().map(|g| (g.p, g.n));
        }
    });
    !with_normals
}

/// A surface shaded by Rust code: the same lights (shaders and shadows over the batch, as the JIT
/// path computes them) and the same compositing, Rust for the surface.
#[allow(clippy::too_many_arguments)]
fn shade_native(
    frame: &Frame,
    native: &dyn NativeSurface,
    group: &GroupRows,
    geoms: &[Option<HitGeometry>],
    (color, opacity): (Vec3A, Vec3A),
    depth: u32,
    out: &mut ShadedRows,
    budgets: &mut [RayBudget],
) {
    let (mut points, mut mask, mut times) = (Vec::new(), Vec::new(), Vec::new());
    let hits = GroupHits::Each(geoms, None);
    extend_batch_lanes(group, hits, (&mut points, &mut mask, &mut times));
    let front: Vec<Vec3A> = front_normals(group, hits).collect();
    let mut table = BatchLights::compute(frame, None, &points, &mask, &times, Some(&front), depth, budgets);
    // The hand-written plastic sums the lights in front of its normal faced forward by itself.
    let faced = |(k, g): (usize, &Option<HitGeometry>)| {
        let g = g.as_ref()?;
        Some((k, faced_against(g.n, g.p - group.origin(k)).to_array(), 0.0))
    };
    table.resolve(frame, &points, &times, geoms.iter().enumerate().filter_map(faced));
    let mut seen = Vec::new();
    for (k, g) in geoms.iter().enumerate() {
        let Some(g) = g else { continue };
        seen.clear();
        seen.extend((0..table.count_of(k) as usize).map(|j| {
            let h = table.light(k, j);
            LightSeen { l: Vec3A::from(h.l), cl: Vec3A::from(h.cl), ambient: h.ambient != 0 }
        }));
        let i = g.p - group.origin(k);
        let (ci, oi) = native.shade(g.n, i, g.cs.unwrap_or(color), g.os.unwrap_or(opacity), &seen);
        out.set(k, [ci, oi, g.p, g.ng]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mirror (its rays traced ahead), plastic, a checker and a transparent matte (a second
    /// layer of hits), over the middle of a view from (0, 0, -4).
    const FOREGROUND: &str = r#"
            AttributeBegin
              Surface "mirror" "Kr" [0.7]
              Color [0.3 0.3 0.4]
              Polygon "P" [-3 -1 -3  3 -1 -3  3 -1 3  -3 -1 3]
            AttributeEnd
            AttributeBegin
              Surface "plastic" "Ks" [0.5] "roughness" [0.1]
              Color [0.8 0.3 0.2]
              Polygon "P" [-1.5 -1 0.5  0.1 -1 0.5  0.1 0.6 0.5  -1.5 0.6 0.5]
            AttributeEnd
            AttributeBegin
              Surface "checker"
              Polygon "P" [-0.2 -0.8 -0.5  1.4 -0.8 -0.5  1.4 0.9 -0.5  -0.2 0.9 -0.5]
            AttributeEnd
            AttributeBegin
              Surface "matte"
              Opacity [0.5 0.5 0.5]
              Color [0.2 0.7 0.3]
              Polygon "P" [-0.6 -0.3 -1  0.7 -0.3 -1  0.7 0.4 -1  -0.6 0.4 -1]
            AttributeEnd
    "#;

    /// A packet is told whole from its instance ids only where keying it lane by lane would find
    /// every lane active, hit, no holdout and of one key, and then with that key.
    #[test]
    fn a_whole_packet_is_told_from_its_instance_ids_as_its_lanes_keys_would_tell_it() {
        let rib = r#"
            Format 16 16 1
            WorldBegin
            Surface "matte"
            Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
            AttributeBegin
              Matte 1
              Polygon "P" [-1 -1 1  1 -1 1  1 1 1  -1 1 1]
            AttributeEnd
            WorldEnd
        "#;
        let mut rt = crate::api::Context::new();
        crate::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        let on = |instance: u32| {
            let mut hits = HitPacket::default();
            hits.instance.0 = [instance; PACKET_SIZE];
            hits.primitive.0 = std::array::from_fn(|l| (l % 2) as u32);
            hits.t.0 = [1.0; PACKET_SIZE];
            hits
        };
        let (front, holdout) = (on(0), on(1));
        assert!(!world.is_holdout(&front.get(0)) && world.is_holdout(&holdout.get(0)));
        let key = super::super::group::group_key(&world, &front.get(0));
        assert!((0..PACKET_SIZE).all(|l| super::super::group::group_key(&world, &front.get(l)) == key));
        assert_eq!(whole_packet_key(&world, u64::MAX, &front), Some(key));
        // An inactive lane, a holdout, a miss, a lane on another instance: keyed lane by lane.
        assert_eq!(whole_packet_key(&world, u64::MAX >> 1, &front), None);
        assert_eq!(whole_packet_key(&world, u64::MAX, &holdout), None);
        assert_eq!(whole_packet_key(&world, u64::MAX, &on(INVALID_ID)), None);
        let mut mixed = on(0);
        mixed.instance.0[37] = 1;
        assert_eq!(whole_packet_key(&world, u64::MAX, &mixed), None);
    }

    /// Bucketing a packet's group keys orders them exactly as a comparison sort: with one to eight
    /// distinct keys (bucketed) and with more (sorted), in any order.
    #[test]
    fn shaders_that_read_dpdu_and_the_normals_derivatives_get_them() {
        let probe =
            "surface probe() { Ci = color(length(Du(N)) + length(Dv(N)), length(dPdu), length(dPdv)); Oi = 1; }";
        let rib = r#"
            Format 16 16 1
            Projection "perspective" "fov" 40
            Translate 0 0 4
            WorldBegin
            Surface "probe"
            PointsPolygons [4] [0 1 2 3] "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
                "N" [-0.5 -0.5 1  0.5 -0.5 1  0.5 0.5 1  -0.5 0.5 1]
            WorldEnd
        "#;
        let mut rt = crate::api::Context::new();
        rt.compile_shader("probe", probe).expect("the probe compiles");
        crate::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        let (fb, _) = super::super::render_frame(&world, None);
        let centre = (8 * 16 + 8) * 4;
        let rgb = &fb.rgba[centre..centre + 3];
        assert!(rgb.iter().all(|v| v.is_finite() && *v > 1e-3), "dN, dPdu, dPdv at the centre: {rgb:?}");
    }

    /// A surface batch read from the hits' rows alone (`GroupHits::Rows`, its lane globals four
    /// lanes at a time) gets the globals that one read hit by hit does (`GroupHits::Each`, which a
    /// displacement shader that leaves the surface alone forces): the same image, bit for bit.
    #[test]
    fn globals_from_the_rows_alone_are_those_read_hit_by_hit() {
        let probe = "surface probe() {
            Ci = color(xcomp(I), ycomp(I), zcomp(I)) + 0.25 * color(xcomp(E), ycomp(E), zcomp(E))
                + Cs * Os + time + ncomps + color(s, t, 0);
            Oi = 1;
        }";
        let render = |displaced: bool| {
            let rib = format!(
                r#"
                Format 16 16 1
                Projection "perspective" "fov" 40
                Translate 0.3 0.2 4
                WorldBegin
                Color [0.2 0.5 0.7]
                Opacity [0.9 0.8 0.6]
                Surface "probe"
                {}
                Polygon "P" [-1 -1 0  1 -1 0.5  1 1 0  -1 1 -0.5]
                WorldEnd
            "#,
                if displaced { r#"Displacement "unmoved""# } else { "" }
            );
            let mut rt = crate::api::Context::new();
            rt.compile_shader("probe", probe).expect("the probe compiles");
            rt.compile_shader("unmoved", "displacement unmoved() { }").expect("the displacement compiles");
            crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
            let world = rt.build_world().expect("the test scene builds");
            super::super::render_frame(&world, None).0.rgba
        };
        let (rows, each) = (render(false), render(true));
        let lit = rows.chunks(4).filter(|px| px[..3].iter().any(|v| *v != 0.0)).count();
        assert!(lit > 64 && lit < 256, "{lit} of 256 pixels see the quad");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&rows), bits(&each));
    }

    /// Light queries that a surface batch's chunks answer from the batch's lights in place
    /// (`HostTable::batch_lights`: every light, at the batch's points) get what the renderer's
    /// answers chunk by chunk give (a category every light belongs to, which the view does not
    /// serve): the same image, bit for bit. Lights in front of the surface and behind it (whose
    /// shadows are traced only once a loop's cone takes them in), each partly shadowed.
    #[test]
    fn lights_read_in_place_are_those_asked_chunk_by_chunk() {
        let light = r#"light keyed(float intensity = 1; point from = point "shader" (0, 0, 0);
            string __category = "key";) { illuminate(from) Cl = intensity * color(1, 0.8, 0.6) / (L . L); }"#;
        let render = |category: &str| {
            let surface = format!(
                r#"surface lit() {{
                    normal Nf = faceforward(normalize(N), I);
                    color front = 0, back = 0;
                    illuminance("{category}", P, Nf, PI / 2) {{ front += Cl * (Nf . normalize(L)); }}
                    illuminance("{category}", P, -Nf, PI / 2) {{ back += Cl; }}
                    Ci = front + 0.5 * back + 0.01 * diffuse(Nf);
                    Oi = 1;
                }}"#
            );
            let rib = r#"
                Format 24 24 1
                Projection "perspective" "fov" 45
                Translate 0 0 4
                WorldBegin
                Attribute "light" "shadows" "on"
                LightSource "keyed" 1 "intensity" [4] "from" [0.5 1.5 -1.5]
                LightSource "keyed" 2 "intensity" [3] "from" [-0.4 -0.3 1.5]
                Surface "lit"
                Polygon "P" [-1.5 -1.5 0  1.5 -1.5 0  1.5 1.5 0  -1.5 1.5 0]
                Polygon "P" [-0.2 0.2 -0.6  0.6 0.2 -0.6  0.6 0.9 -0.6  -0.2 0.9 -0.6]
                Polygon "P" [-0.9 -0.8 0.7  0.1 -0.8 0.7  0.1 0.1 0.7  -0.9 0.1 0.7]
                WorldEnd
            "#;
            let mut rt = crate::api::Context::new();
            rt.compile_shader("keyed", light).expect("the light compiles");
            rt.compile_shader("lit", &surface).expect("the surface compiles");
            crate::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>")).expect("the test scene loads");
            let world = rt.build_world().expect("the test scene builds");
            super::super::render_frame(&world, None).0.rgba
        };
        let (in_place, asked) = (render(""), render("key"));
        // The scene is what the test is about: light from both sides, and a shadow.
        let lit = in_place.chunks(4).filter(|px| px[..3].iter().any(|v| *v > 0.0)).count();
        assert!(lit > 200, "{lit} pixels lit");
        let levels: std::collections::HashSet<u32> = in_place.iter().map(|v| v.to_bits()).collect();
        assert!(levels.len() > 100, "{} distinct values", levels.len());
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&in_place), bits(&asked));
    }

    /// A tile's first hits shaded by rows (`shade_primary_layer`: packets whose every lane hit one
    /// material read in place, the others' hits gathered from the packets' rows) get what their
    /// jobs shaded one by one get (`shade_pending`, the path of scenes with volume shaders, here
    /// taken without any): colour, alpha, depth, ids, normal and outputs, bit for bit. A backdrop
    /// whose shader sets an output variable the frame keeps fills whole packets; in front of it
    /// stand the mirror, plastic, checker and transparent matte of [`FOREGROUND`].
    #[test]
    fn primary_hits_by_rows_get_what_their_jobs_get() {
        let rib = format!(
            r#"
            Format 32 32 1
            Projection "perspective" "fov" 50
            Display "+glow.exr" "file" "float glow"
            Translate 0 0 4
            WorldBegin
            LightSource "ambientlight" 1 "intensity" [0.1]
            LightSource "pointlight" 2 "intensity" [6] "from" [1 2 -3]
            Attribute "light" "shadows" "on"
            AttributeBegin
              Surface "glowing"
              Polygon "P" [-9 -9 3  9 -9 3  9 9 3  -9 9 3]
            AttributeEnd
            {FOREGROUND}
            WorldEnd
        "#
        );
        let glowing = "surface glowing(output varying float glow = 0;) {
            glow = s + 2 * t;
            Ci = color(s, t, 0.5) * diffuse(faceforward(normalize(N), I));
            Oi = 1;
        }";
        let mut rt = crate::api::Context::new();
        rt.compile_shader("glowing", glowing).expect("the backdrop's shader compiles");
        crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        assert!(!world.has_volumes());
        let corners: Vec<(u32, u32)> = (0..4).flat_map(|y| (0..4).map(move |x| (8 * x, 8 * y))).collect();
        let [rows, jobs] = by_rows_and_by_jobs(&world, &corners);
        // The scene is what the test is about: packets wholly on the backdrop and packets of
        // several materials, a transparent surface, the output kept.
        let whole = rows.iter().filter(|p| p.iter().all(|s| s.shader_id == p[0].shader_id)).count();
        assert!(whole >= 4 && whole < rows.len(), "{whole} of {} packets on one material", rows.len());
        let materials: std::collections::HashSet<u32> = rows.iter().flatten().map(|s| s.shader_id).collect();
        assert!(materials.len() >= 4, "materials seen: {materials:?}");
        assert!(rows.iter().flatten().any(|s| s.outputs[0][0] > 0.5), "the output variable is kept");
        assert_eq!(sample_bits(&rows), sample_bits(&jobs));
    }

    /// Whole packets whose first hits are on a semi-transparent veil over the view, composited a
    /// row at a time, get what their jobs shaded one by one get, bit for bit: the rays going on
    /// through it, their depths with RenderMan's depth threshold (the veil's opacity falls short
    /// of it) and without one, and with the farthest surface kept.
    #[test]
    fn whole_packets_through_a_veil_get_what_their_jobs_get() {
        let rib = format!(
            r#"
            Format 16 16 1
            Projection "perspective" "fov" 50
            Translate 0 0 4
            WorldBegin
            LightSource "ambientlight" 1 "intensity" [0.1]
            LightSource "pointlight" 2 "intensity" [6] "from" [1 2 -3]
            AttributeBegin
              Surface "matte"
              Opacity [0.6 0.5 0.4]
              Polygon "P" [-3 -3 -3.3  3 -3 -3.3  3 3 -3.3  -3 3 -3.3]
            AttributeEnd
            {FOREGROUND}
            WorldEnd
        "#
        );
        let thresholds = [None, Some([0.0; 3]), Some([0.3; 3])];
        for (case, (threshold, farthest)) in thresholds.into_iter().flat_map(|t| [(t, false), (t, true)]).enumerate() {
            let mut rt = crate::api::Context::new();
            crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
            if let Some(t) = threshold {
                rt.options.depth_threshold = t;
            }
            if farthest {
                rt.options.depth_filter = super::super::DepthFilter::Max;
            }
            let world = rt.build_world().expect("the test scene builds");
            let [rows, jobs] = by_rows_and_by_jobs(&world, &[(0, 0), (8, 0), (0, 8), (8, 8)]);
            // Every packet lies wholly on the veil, and sees what is behind it.
            let veil = rows[0][0].shader_id;
            assert!(rows.iter().flatten().all(|s| s.shader_id == veil), "case {case}");
            assert!(rows.iter().flatten().any(|s| s.alpha > 0.9), "case {case}: surfaces behind the veil");
            if threshold == Some([0.3; 3]) && !farthest {
                assert!(rows.iter().flatten().all(|s| s.depth < 1.0), "case {case}: the veil's depth");
            }
            assert_eq!(sample_bits(&rows), sample_bits(&jobs), "case {case}");
        }
    }

    /// The packets at `corners` shaded by rows (`shade_primary_layer`) and by jobs
    /// (`shade_pending`, the path of scenes with volume shaders), lane by lane.
    fn by_rows_and_by_jobs(world: &World, corners: &[(u32, u32)]) -> [Vec<[Sample; PACKET_SIZE]>; 2] {
        let by_rows = Frame::new(world);
        let mut by_jobs = Frame::new(world);
        by_jobs.volumes = true;
        let (rays, hits) = traced_packets(&by_rows, corners);
        let packets: Vec<(&PrimaryRays, &HitPacket)> = rays.iter().zip(&hits).collect();
        [by_rows, by_jobs].map(|frame| {
            let mut out = vec![SampleRows::default(); packets.len()];
            shade_packets(&frame, &packets, &mut out);
            lanes_of(&out)
        })
    }

    /// Packets' samples lane by lane.
    fn lanes_of(rows: &[SampleRows]) -> Vec<[Sample; PACKET_SIZE]> {
        rows.iter().map(|r| std::array::from_fn(|l| r.lane(l))).collect()
    }

    /// The primary packets of sample (0, 0) at each 8x8 corner, and their hits.
    fn traced_packets(frame: &Frame, corners: &[(u32, u32)]) -> (Vec<PrimaryRays>, Vec<HitPacket>) {
        let rays: Vec<PrimaryRays> =
            corners.iter().map(|&(x, y)| super::super::frame::primary_packet(frame, x, y, (0, 0))).collect();
        let hits = rays
            .iter()
            .map(|r| {
                let mut hits = HitPacket::default();
                frame.world.scene.intersect_packet(&r.packet, &mut hits);
                hits
            })
            .collect();
        (rays, hits)
    }

    /// Every field of each sample, as bits.
    fn sample_bits(samples: &[[Sample; PACKET_SIZE]]) -> Vec<Vec<u32>> {
        let bits = |s: &Sample| {
            let floats = [s.color.to_array(), s.normal.to_array()].into_iter().chain(s.outputs).flatten();
            let mut v: Vec<u32> = floats.chain([s.alpha, s.depth]).map(f32::to_bits).collect();
            v.extend([s.object_id, s.shader_id]);
            v
        };
        samples.iter().flatten().map(bits).collect()
    }

    /// Shading a tile's packets together (`shade_packets`, whose batches mix the packets' hits)
    /// gives every sample what shading each packet alone gives it, bit for bit: in a scene of
    /// several materials over the packets' seams, shadows (an opaque and a transparent blocker),
    /// a mirror (rays traced ahead) and a transparent surface (a second layer of hits).
    #[test]
    fn packets_shaded_together_get_what_each_gets_alone() {
        let rib = format!(
            r#"
            Format 16 16 1
            Projection "perspective" "fov" 50
            Translate 0 0 4
            WorldBegin
            LightSource "ambientlight" 1 "intensity" [0.1]
            LightSource "pointlight" 2 "intensity" [6] "from" [1 2 -3]
            {FOREGROUND}
            WorldEnd
        "#
        );
        let mut rt = crate::api::Context::new();
        crate::rib::load::load_str(&mut rt, &rib, std::path::Path::new("<test>")).expect("the test scene loads");
        let world = rt.build_world().expect("the test scene builds");
        let frame = Frame::new(&world);
        let corners = [(0, 0), (8, 0), (0, 8), (8, 8)];
        let (rays, hits) = traced_packets(&frame, &corners);
        let mut alone = vec![[Sample::default(); PACKET_SIZE]; corners.len()];
        for ((r, h), out) in rays.iter().zip(&hits).zip(&mut alone) {
            shade_packet(&frame, r, h, out);
        }
        let packets: Vec<(&PrimaryRays, &HitPacket)> = rays.iter().zip(&hits).collect();
        let mut together = vec![SampleRows::default(); corners.len()];
        shade_packets(&frame, &packets, &mut together);
        let together = lanes_of(&together);
        // The scene is what the test is about: several materials, some lanes in shadow.
        let materials: std::collections::HashSet<u32> = alone.iter().flatten().map(|s| s.shader_id).collect();
        assert!(materials.len() >= 4, "materials seen: {materials:?}");
        assert_eq!(sample_bits(&alone), sample_bits(&together));
    }
}

//! Lights on a batch: every light shader run over the batch's points (area lights sampled, one
//! light per sample), shadow rays traced as packets (or walked through transparent surfaces), and
//! the per-lane table the shader's light queries are served from.

use super::differential::RayDifferential;
use super::host::{ray_relevance, ShadeCall};
use super::lanes::Lanes3;
use super::ray_budget::RayBudget;
use super::ray_params::samples_for_relevance;
use super::sampling::{mix, point_seed, unit};
use super::stats::{tracing, Stats};
use super::work::{epsilon, launch_bias, launch_epsilon, BatchLights, Frame, Pending, Shaded};
use super::world::{InstanceShadows, LightSource, Material, RayKind, ShadowKind, World, DEFAULT_MATERIAL};
use crate::ray::{HitCandidate, HitPacket, Ray, RayPacket, PACKET_SIZE};
use crate::shading::{fill1, fill3, get_row, put3, put_row, varying_rows, with_filled_batch, LightKind};
use glam::{IVec4, Vec3A, Vec4};
use rtsl_compiler::abi::{light_in_cone, HostLight, LightLanes, MAX_LIGHTS};
use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// Runs one light's shader for the active lanes of a chunk and appends what reaches each lane, with
/// shadows traced.
#[allow(clippy::too_many_arguments)] // a chunk's lanes: mask, points, times, and where the lights go
pub(super) fn eval_light(
    frame: &Frame,
    light: &LightSource,
    material: Option<u32>,
    mask: &[i32; 4],
    points: &[Vec3A; 4],
    times: &[f32; 4],
    depth: u32,
    budgets: &mut [RayBudget; 4],
    out: &mut [LightLanes],
    counts: &mut [u32; 4],
) {
    let lanes = LightLanesIn { mask, points, times, front: None, budgets };
    eval_light_lanes(frame, light, material, depth, lanes, |_, fill, lanes, _| {
        let appended = append_row(out, counts, fill, lanes);
        count_dropped(frame, lanes & !appended);
    });
}

/// The lanes a light shader runs over: `mask` nonzero where a point asks, each point's ray time,
/// its front normal when known, and what its ray tree may still spawn (the rays the light's
/// shader spawns at a point are charged to it).
struct LightLanesIn<'a> {
    mask: &'a [i32],
    points: &'a [Vec3A],
    times: &'a [f32],
    front: Option<&'a [Vec3A]>,
    budgets: &'a mut [RayBudget],
}

/// Counts the lights of the lanes in `dropped` that found no room ([`MAX_LIGHTS`] reached them
/// already), for the frame's warning.
fn count_dropped(frame: &Frame, dropped: u32) {
    if dropped != 0 {
        Stats::add(&frame.stats.lights_dropped, dropped.count_ones() as usize);
    }
}

/// Appends lane `l`'s light in the row `fill` writes to `lights` (lane `l`'s `counts[l]`-th, while
/// there is room) for the lanes whose bit is set in `lanes`; returns the lanes appended.
/// When the four lanes have as many lights so far, `fill` writes the row in place: what it holds
/// for the other lanes lies past their counts, where nothing reads and their next light overwrites
/// it. (In place, because a row is 208 bytes: built apart, each costs a copy.)
fn append_row(lights: &mut [LightLanes], counts: &mut [u32; 4], fill: &dyn Fn(&mut LightLanes), lanes: u32) -> u32 {
    let k = counts[0];
    if counts.iter().all(|&c| c == k) {
        let Some(slot) = lights.get_mut(k as usize) else { return 0 };
        fill(slot);
        for (l, c) in counts.iter_mut().enumerate() {
            *c += lanes >> l & 1;
        }
        return lanes;
    }
    let mut row = LightLanes::default();
    fill(&mut row);
    let mut appended = 0;
    for (l, c) in counts.iter_mut().enumerate() {
        if lanes >> l & 1 == 0 {
            continue;
        }
        let Some(slot) = lights.get_mut(*c as usize) else { continue };
        slot.set_lane(l, &row.lane(l));
        *c += 1;
        appended |= 1 << l;
    }
    appended
}

/// Runs one light's shader over `points` (up to a packet of lanes, `mask` nonzero where a point
/// asks; shadow rays at the lanes' `times`) and hands the lights to `sink` a chunk at a time:
/// `sink(chunk, fill, lanes, pending)` gets a function `fill` that writes the chunk's four lanes
/// as a row wherever the sink wants it, with bit `j` of `lanes` set where lane `4 * chunk + j` is
/// lit (elsewhere the row holds whatever), each colour attenuated by the shadow rays traced as one
/// packet (`transmission_packet`). Area lights give one light per sample. `material` is the lit
/// surface's (for `surface()` messages).
/// With `front`, a lane's shadow ray is traced now only toward a light within 90 degrees of its
/// `front` normal ([`traced_lanes`]); elsewhere the light is unshadowed and its bit set in
/// `pending` (see [`BatchLights::resolve`]).
fn eval_light_lanes(
    frame: &Frame,
    light: &LightSource,
    material: Option<u32>,
    depth: u32,
    LightLanesIn { mask, points, times, front, budgets }: LightLanesIn,
    mut sink: impl FnMut(usize, &dyn Fn(&mut LightLanes), u32, u32),
) {
    let n = points.len().min(PACKET_SIZE);
    let instance = &light.shader;
    let program = &instance.program;
    let slots = &program.slots;
    let samples = light.area.as_ref().map_or(1, |a| a.samples);
    let eye = frame.world.camera.eye();
    let ambient = light.kind == LightKind::Ambient;
    let id = light_id(frame, light);
    if ambient && program.lane_invariant && light.area.is_none() {
        eval_invariant_light_lanes(frame, (id, light), material, mask, points, times, depth, sink);
        return;
    }
    // Under relevance (`ray_params.rs`), each lane takes its share of an area light's samples, at
    // least one, each weighed by one over the lane's own count.
    let takes: [u32; PACKET_SIZE] = std::array::from_fn(|l| match budgets.get(l) {
        Some(b) if samples > 1 && l < n => samples_for_relevance(samples, ray_relevance(frame, b.origin)),
        _ => samples,
    });
    let scales: [f32; PACKET_SIZE] = std::array::from_fn(|l| 1.0 / takes[l].max(1) as f32);
    let mut sample_mask = [0i32; PACKET_SIZE];
    let mut scratch = super::scratch::take(&LIGHT_LANE_ROWS);
    let LightLaneRows { ps, lane_times, rows, flags, attenuation, packet, .. } = scratch.fresh(n);
    // The lanes' points and times as rows, written into each batch a row at a time; the points
    // four at a time, transposed in registers.
    let whole = n / 4 * 4;
    for c in 0..whole / 4 {
        let Some(four) = chunk_of_four(points, c) else { break };
        let p = Lanes3::of_four(four);
        for (row, v) in ps.iter_mut().zip([p.x, p.y, p.z]) {
            v.write_to_slice(&mut row[4 * c..4 * c + 4]);
        }
    }
    for (l, p) in points.iter().enumerate().take(n).skip(whole) {
        (ps[0][l], ps[1][l], ps[2][l]) = (p.x, p.y, p.z);
    }
    match times.get(..n) {
        Some(times) => lane_times[..n].copy_from_slice(times),
        None => {
            for (l, t) in lane_times.iter_mut().enumerate().take(n) {
                *t = time_of(times, l);
            }
        }
    }
    // What the light shader left, L, Cl and Ol, a row per component, in `rows`; in `flags`,
    // RenderMan's light flags: `diffuse()` and `specular()` skip (weigh by 1 minus) a light whose
    // `__nondiffuse` / `__nonspecular` output is set, as the shader left it for each lane.
    let flag_slots = program.light_flags;
    // Every lane of these is written below, for every sample.
    let filled =
        varying_rows([(slots.e, 3), (slots.ncomps, 1), (slots.p, 3), (slots.n, 3), (slots.ps, 3), (slots.time, 1)]);
    // Pixie's `I` and `Ns` of light shaders, where one reads them: the lit point seen from the
    // eye, and the lit surface's normal faced toward it (zero where no normal is known).
    let pixie = slots.i.is_some() || slots.ns.is_some();
    for sample in 0..samples {
        for (l, m) in sample_mask.iter_mut().enumerate().take(n) {
            *m = if sample < takes[l] { mask[l] } else { 0 };
        }
        let mask = &sample_mask[..n];
        if mask.iter().all(|&m| m == 0) {
            continue;
        }
        Stats::add(&frame.stats.light_evaluations, 1);
        with_filled_batch(program, n, &filled, |batch| {
            {
                let mut raw = batch.raw_mut();
                instance.write_params(&mut raw);
                raw.mask[..n].copy_from_slice(mask);
                // What every lane shares is written a row at a time.
                fill3(&mut raw, slots.e, eye);
                fill1(&mut raw, slots.ncomps, 3.0);
                match &light.area {
                    None => {
                        fill3(&mut raw, slots.p, instance.world_from_shader.translation);
                        fill3(&mut raw, slots.n, Vec3A::ZERO);
                    }
                    Some(area) => {
                        for (l, &point) in points.iter().enumerate().take(n) {
                            // The emitting point: a sample of the light's geometry.
                            let h = mix(point_seed(point) ^ u64::from(sample).wrapping_mul(0x2545_F491_4F6C_DD1D));
                            let (origin, normal) = area
                                .sample(unit(h), unit(mix(h)), unit(mix(h ^ 1)))
                                .unwrap_or((instance.world_from_shader.translation, Vec3A::ZERO));
                            put3(&mut raw, slots.p, l, origin);
                            put3(&mut raw, slots.n, l, normal);
                        }
                    }
                }
                for (k, row) in ps.iter().enumerate() {
                    put_row(&mut raw, slots.ps, k, &row[..n]);
                }
                put_row(&mut raw, slots.time, 0, &lane_times[..n]);
                if pixie {
                    for (l, &point) in points.iter().enumerate().take(n) {
                        put3(&mut raw, slots.i, l, point - eye);
                        let normal = front.and_then(|f| f.get(l)).copied().unwrap_or(Vec3A::ZERO);
                        put3(&mut raw, slots.ns, l, normal);
                    }
                }
            }
            let mut call = ShadeCall::new(frame, instance, instance.world_from_shader, depth, &mut *budgets);
            call.material = material;
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for (k, row) in rows.iter_mut().enumerate() {
                let slot = [slots.l, slots.cl, slots.ol][k / 3];
                get_row(&raw, slot, k % 3, 0.0, &mut row[..n]);
            }
            for (flag, slot) in flags.iter_mut().zip(&flag_slots) {
                let Some(slot) = slot else { continue };
                for (l, f) in flag.iter_mut().enumerate().take(n) {
                    let v =
                        if slot.varying { raw.varying[slot.offset * raw.stride + l] } else { raw.uniform[slot.offset] };
                    *f = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
                }
            }
        });
        // Shadows: which lanes need a ray, then one packet (or a walk per ray).
        fill_attenuation(attenuation, n.div_ceil(4) * 4, Vec3A::ONE);
        let mut pending = 0u64;
        if !ambient && light.shadows {
            // As `RayPacket::new()` in the lanes this batch writes (no other lane is active or read).
            reset_packet_lanes(packet, n.div_ceil(4) * 4);
            let distant = light.kind == LightKind::Distant;
            let rays = shadow_packet_rows(rows, ps, lane_times, points, mask, distant, packet);
            let traced = traced_lanes(front, rows, rays, n);
            packet.active |= traced;
            pending |= rays & !traced;
            transmission_packet(frame, packet, &mut attenuation[..n]);
        }
        for c in 0..n.div_ceil(4) {
            let at = 4 * c..4 * c + 4;
            let lanes4 =
                |first: usize| -> [Vec4; 3] { std::array::from_fn(|k| Vec4::from_slice(&rows[first + k][at.clone()])) };
            // `finite_or_zero` of each lane's triple: zero unless all three components are finite.
            let finite_or_zero = |v: [Vec4; 3]| {
                let finite = v[0].is_finite_mask() & v[1].is_finite_mask() & v[2].is_finite_mask();
                v.map(|x| Vec4::select(finite, x, Vec4::ZERO))
            };
            let (to_surface, cl, ol) = (lanes4(0), finite_or_zero(lanes4(3)), finite_or_zero(lanes4(6)));
            // (A packet's worth of rows: every chunk has its four, the `ONE`s never serve.)
            let shadow = chunk_of_four(&attenuation[..], c).map_or([Vec4::ONE; 3], |four| {
                let a = Lanes3::of_four(four);
                [a.x, a.y, a.z]
            });
            // `illuminate` leaves L at zero where the point is outside its cone: no light there.
            let unlit =
                to_surface[0].cmpeq(Vec4::ZERO) & to_surface[1].cmpeq(Vec4::ZERO) & to_surface[2].cmpeq(Vec4::ZERO);
            let mut lanes = 0u32;
            for j in 0..4 {
                let l = 4 * c + j;
                if l < n && mask[l] != 0 && (ambient || !unlit.test(j)) {
                    lanes |= 1 << j;
                }
            }
            if lanes == 0 {
                continue;
            }
            let scale = Vec4::from_slice(&scales[at.clone()]);
            let fill = |row: &mut LightLanes| {
                for k in 0..3 {
                    row.l[k] = if ambient { [0.0; 4] } else { (-to_surface[k]).to_array() };
                    row.cl[k] = (cl[k] * scale * shadow[k]).to_array();
                    row.ol[k] = ol[k].to_array();
                }
                row.ambient = [u32::from(ambient); 4];
                row.nondiffuse.copy_from_slice(&flags[0][at.clone()]);
                row.nonspecular.copy_from_slice(&flags[1][at.clone()]);
                row.id = [id; 4];
            };
            sink(c, &fill, lanes, (pending >> (4 * c)) as u32 & lanes);
        }
    }
    super::scratch::give(&LIGHT_LANE_ROWS, scratch);
}

/// [`eval_light_lanes`] for an ambient light whose shader gives every lane the same values
/// ([`ShaderProgram::lane_invariant`](crate::shading::ShaderProgram::lane_invariant)): the shader
/// runs on one lane, once a frame (`Frame::invariant_light_rows`), and every asking lane gets its
/// row. The same rows as running it on all: an ambient light casts no shadows and has no
/// direction, and every lane of every batch would compute the same from the same parameters.
/// (Scenes with an ambient light have it in every lane's list: running it over whole batches and
/// taking their rows apart lane by lane would repeat that work for every batch.)
#[allow(clippy::too_many_arguments)]
fn eval_invariant_light_lanes(
    frame: &Frame,
    (id, light): (u32, &LightSource),
    material: Option<u32>,
    mask: &[i32],
    points: &[Vec3A],
    times: &[f32],
    depth: u32,
    mut sink: impl FnMut(usize, &dyn Fn(&mut LightLanes), u32, u32),
) {
    let n = points.len().min(PACKET_SIZE);
    Stats::add(&frame.stats.light_evaluations, 1);
    // Kept for the frame: run with what it reaches, never without what a unit rendering ahead
    // has not fetched yet.
    let row =
        || crate::accel::ask_ahead::waiting(|| invariant_light_row(frame, (id, light), material, points, times, depth));
    let template = match frame.invariant_light_rows.get(id as usize) {
        Some(cached) => *cached.get_or_init(row),
        None => row(),
    };
    let fill = |row: &mut LightLanes| *row = template;
    for c in 0..n.div_ceil(4) {
        let lanes = match mask.get(4 * c..4 * c + 4).filter(|_| 4 * c + 4 <= n) {
            Some(four) => IVec4::from_slice(four).cmpne(IVec4::ZERO).bitmask(),
            None => (0..4)
                .filter(|&j| 4 * c + j < n && mask.get(4 * c + j).is_some_and(|&m| m != 0))
                .fold(0, |a, j| a | 1 << j),
        };
        if lanes != 0 {
            sink(c, &fill, lanes, 0);
        }
    }
}

/// The row every lane gets from a lane-invariant ambient light ([`eval_invariant_light_lanes`]):
/// its shader run on one lane.
fn invariant_light_row(
    frame: &Frame,
    (id, light): (u32, &LightSource),
    material: Option<u32>,
    points: &[Vec3A],
    times: &[f32],
    depth: u32,
) -> LightLanes {
    let instance = &light.shader;
    let program = &instance.program;
    let slots = &program.slots;
    let flag_slots = program.light_flags;
    let filled =
        varying_rows([(slots.e, 3), (slots.ncomps, 1), (slots.p, 3), (slots.n, 3), (slots.ps, 3), (slots.time, 1)]);
    // Cl and Ol (an ambient light has no L).
    let mut values = [[0.0f32; 3]; 2];
    let mut flags = [0.0f32; 2];
    with_filled_batch(program, 1, &filled, |batch| {
        {
            let mut raw = batch.raw_mut();
            instance.write_params(&mut raw);
            raw.mask[0] = -1;
            fill3(&mut raw, slots.e, frame.world.camera.eye());
            fill1(&mut raw, slots.ncomps, 3.0);
            fill3(&mut raw, slots.p, instance.world_from_shader.translation);
            fill3(&mut raw, slots.n, Vec3A::ZERO);
            // Not read (the shader reads no global on entry), but written as everywhere.
            fill3(&mut raw, slots.ps, points.first().copied().unwrap_or(Vec3A::ZERO));
            fill1(&mut raw, slots.time, time_of(times, 0));
        }
        // Run once a frame for every point that asks: its rays are a tree of their own.
        let mut budget = [RayBudget::FULL];
        let mut call = ShadeCall::new(frame, instance, instance.world_from_shader, depth, &mut budget);
        call.material = material;
        let table = call.table();
        program.code.shade_with_table(batch, &table);
        let raw = batch.raw_mut();
        for (k, slot) in [slots.cl, slots.ol].into_iter().enumerate() {
            for (c, value) in values[k].iter_mut().enumerate() {
                let mut one = [0.0f32];
                get_row(&raw, slot, c, 0.0, &mut one);
                *value = one[0];
            }
        }
        for (flag, slot) in flags.iter_mut().zip(&flag_slots) {
            let Some(slot) = slot else { continue };
            let v = if slot.varying { raw.varying[slot.offset * raw.stride] } else { raw.uniform[slot.offset] };
            *flag = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
        }
    });
    // As `eval_light_lanes` makes a row of an ambient light: `finite_or_zero` colours, L zero,
    // and `Cl` times a sample weight and a shadow that are both one (so exactly `Cl`).
    let finite_or_zero = |v: [f32; 3]| if v.iter().all(|x| x.is_finite()) { v } else { [0.0; 3] };
    let (cl, ol) = (finite_or_zero(values[0]), finite_or_zero(values[1]));
    let mut template = LightLanes::default();
    for k in 0..3 {
        template.l[k] = [0.0; 4];
        template.cl[k] = [cl[k]; 4];
        template.ol[k] = [ol[k]; 4];
    }
    template.ambient = [1; 4];
    template.nondiffuse = [flags[0]; 4];
    template.nonspecular = [flags[1]; 4];
    template.id = [id; 4];
    template
}

/// `light`'s index among the world's lights (`u32::MAX` if it is not one of them).
fn light_id(frame: &Frame, light: &LightSource) -> u32 {
    frame.world.lights.iter().position(|x| std::ptr::eq(x, light)).map_or(u32::MAX, |i| i as u32)
}

thread_local! {
    /// [`LightLaneRows`] for the next light evaluation (`scratch`: shadows recurse into shading).
    static LIGHT_LANE_ROWS: std::cell::RefCell<Vec<Box<LightLaneRows>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The rows [`eval_light_lanes`] works in, kept from call to call. Made afresh they would be 6 KB
/// zeroed for every light and sample of every batch however few its lanes, which dominates
/// where incoherent rays make small batches. A batch of `n` lanes reads only the chunks of four that hold them, and writes every lane below
/// `n` before it reads it (`fresh` zeroes the padding lanes and the flags); lanes past its chunks
/// hold whatever an earlier batch left.
struct LightLaneRows {
    ps: [[f32; PACKET_SIZE]; 3],
    lane_times: [f32; PACKET_SIZE],
    rows: [[f32; PACKET_SIZE]; 9],
    flags: [[f32; PACKET_SIZE]; 2],
    attenuation: [Vec3A; PACKET_SIZE],
    packet: RayPacket,
}

/// `packet` as `RayPacket::new()` in its first `lanes` lanes, and no lane active.
fn reset_packet_lanes(packet: &mut RayPacket, lanes: usize) {
    let p = packet;
    for row in [&mut p.ox, &mut p.oy, &mut p.oz, &mut p.dx, &mut p.dy, &mut p.dz, &mut p.tmin, &mut p.tmax, &mut p.time]
    {
        fill_lanes(&mut row.0, lanes, 0.0);
    }
    p.active = 0;
}

/// Sets the first `lanes` lanes of `row` to `value`, and the rest of their chunk of 8 (lanes the
/// caller does not read), a 32-byte store a chunk. A small batch's rows are a few lanes long, and a
/// `memset` call for each costs more than the stores (a light's evaluation resets a dozen rows); the value is hidden from the optimiser, which would otherwise make those
/// stores the very `memset` calls again.
#[inline(always)]
fn fill_lanes(row: &mut [f32; PACKET_SIZE], lanes: usize, value: f32) {
    let chunks: &mut [wide::f32x8; PACKET_SIZE / 8] = bytemuck::cast_mut(row);
    let value = std::hint::black_box(wide::f32x8::splat(value));
    for chunk in &mut chunks[..lanes.div_ceil(8).min(PACKET_SIZE / 8)] {
        *chunk = value;
    }
}

/// [`fill_lanes`] for the attenuation, a 16-byte store a lane.
#[inline(always)]
fn fill_attenuation(row: &mut [Vec3A; PACKET_SIZE], lanes: usize, value: Vec3A) {
    let value = std::hint::black_box(value);
    for lane in &mut row[..lanes.min(PACKET_SIZE)] {
        *lane = value;
    }
}

impl Default for LightLaneRows {
    fn default() -> LightLaneRows {
        LightLaneRows {
            ps: [[0.0; PACKET_SIZE]; 3],
            lane_times: [0.0; PACKET_SIZE],
            rows: [[0.0; PACKET_SIZE]; 9],
            flags: [[0.0; PACKET_SIZE]; 2],
            attenuation: [Vec3A::ONE; PACKET_SIZE],
            packet: RayPacket::new(),
        }
    }
}

impl LightLaneRows {
    /// These rows for a batch of `n` lanes: in every row the padding lanes of its last chunk of
    /// four are zero, and so are the flags in all its lanes (a light shader without them leaves
    /// them). Each evaluation writes the other lanes below `n` before reading them (the points and
    /// times once, the light's rows and flags every sample), and the attenuation and the packet
    /// are reset every sample.
    fn fresh(&mut self, n: usize) -> &mut LightLaneRows {
        let n = n.min(PACKET_SIZE);
        let chunked = n.div_ceil(4) * 4;
        let zero = std::hint::black_box(0.0f32);
        for row in self.ps.iter_mut().chain([&mut self.lane_times]).chain(&mut self.rows) {
            for lane in &mut row[n..chunked] {
                *lane = zero;
            }
        }
        for row in &mut self.flags {
            fill_lanes(row, chunked, 0.0);
        }
        self
    }
}

/// The shadow rays of a light shader's lanes, four at a time: from each lane's point (`ps`, a
/// row per coordinate) toward the light (`-L`: `rows` 0-2; `Cl` in rows 3-5) at its time, written
/// into `packet`'s rows for every lane (without marking any active). Returns the lanes that have a
/// ray: asking (`mask`), `L` and `Cl` nonzero, `Cl` finite, and [`light_shadow_ray`] giving one.
/// Lane for lane the same operations as `light_shadow_ray`, so the same rays.
fn shadow_packet_rows(
    rows: &[[f32; PACKET_SIZE]; 9],
    ps: &[[f32; PACKET_SIZE]; 3],
    times: &[f32; PACKET_SIZE],
    points: &[Vec3A],
    mask: &[i32],
    distant: bool,
    packet: &mut RayPacket,
) -> u64 {
    let n = points.len().min(mask.len()).min(PACKET_SIZE);
    let mut lanes = 0u64;
    // The rays start past the lit surface's trace bias (`launch_epsilon`).
    let bias = Vec4::splat(launch_bias());
    for c in 0..n.div_ceil(4) {
        let at = 4 * c..4 * c + 4;
        let row = |r: &[f32; PACKET_SIZE]| Vec4::from_slice(&r[at.clone()]);
        let (lx, ly, lz) = (row(&rows[0]), row(&rows[1]), row(&rows[2]));
        let (cx, cy, cz) = (row(&rows[3]), row(&rows[4]), row(&rows[5]));
        let zero = Vec4::ZERO;
        // Lanes where a vector, a row per component, is zero (as `Vec3A == ZERO`).
        let all_zero = |x: Vec4, y: Vec4, z: Vec4| x.cmpeq(zero) & y.cmpeq(zero) & z.cmpeq(zero);
        let (l_zero, cl_zero) = (all_zero(lx, ly, lz), all_zero(cx, cy, cz));
        let cl_finite = cx.is_finite_mask() & cy.is_finite_mask() & cz.is_finite_mask();
        // `-L`, its length and `normalize_or_zero` as glam computes them for a `Vec3A`.
        let (tx, ty, tz) = (-lx, -ly, -lz);
        let dot = (tx * tx + ty * ty) + tz * tz;
        let length = dot.sqrt();
        let recip = Vec4::ONE / length;
        let normalisable = recip.is_finite_mask() & recip.cmpgt(zero);
        let (dx, dy, dz) = (
            Vec4::select(normalisable, tx * recip, zero),
            Vec4::select(normalisable, ty * recip, zero),
            Vec4::select(normalisable, tz * recip, zero),
        );
        let no_direction = all_zero(dx, dy, dz);
        let eps = Vec4::from_array(std::array::from_fn(|j| points.get(4 * c + j).map_or(0.0, |&p| epsilon(p))));
        let near = eps.max(bias);
        let tmax = if distant { Vec4::INFINITY } else { length - Vec4::splat(2.0) * eps };
        // (`light_shadow_ray` leaves the segment open for a non-finite length; here an infinite
        // length gives an infinite `tmax` anyway, and a NaN one no direction.)
        let long_enough = tmax.cmpgt(near);
        let ok = !l_zero & !cl_zero & cl_finite & !no_direction & long_enough;
        for (dst, v) in [
            (&mut packet.ox, row(&ps[0])),
            (&mut packet.oy, row(&ps[1])),
            (&mut packet.oz, row(&ps[2])),
            (&mut packet.dx, dx),
            (&mut packet.dy, dy),
            (&mut packet.dz, dz),
            (&mut packet.tmin, near),
            (&mut packet.tmax, tmax),
            (&mut packet.time, row(times)),
        ] {
            v.write_to_slice(&mut dst.0[at.clone()]);
        }
        for j in 0..4 {
            let l = 4 * c + j;
            if l < n && mask[l] != 0 && ok.test(j) {
                lanes |= 1 << l;
            }
        }
    }
    lanes
}

/// The lanes of `lanes` (lanes with a shadow ray, of the first `n`) whose shadow ray is traced at
/// once: all without `front`, else those whose direction toward the light (`-L`, rows 0-2 of
/// `rows`) is within 90 degrees of their `front` normal, or that have none. Only a guess (a query
/// that needs more resolves it), so no normalisation or slack. Four lanes at a time, each dot
/// product summed in `Vec3A::dot`'s order, so the same signs.
fn traced_lanes(front: Option<&[Vec3A]>, rows: &[[f32; PACKET_SIZE]; 9], lanes: u64, n: usize) -> u64 {
    let Some(front) = front else { return lanes };
    let mut traced = 0u64;
    for c in 0..n.min(PACKET_SIZE).div_ceil(4) {
        let four = (lanes >> (4 * c)) & 0xF;
        if four == 0 {
            continue;
        }
        let at = 4 * c..4 * c + 4;
        let toward = |l: usize| -Vec3A::new(rows[0][l], rows[1][l], rows[2][l]);
        let facing = match chunk_of_four(front, c) {
            Some(f) => {
                let f = Lanes3::of_four(f);
                let row = |k: usize| -Vec4::from_slice(&rows[k][at.clone()]);
                let dot = (row(0) * f.x + row(1) * f.y) + row(2) * f.z;
                u64::from(dot.cmpge(Vec4::ZERO).bitmask())
            }
            None => (0..4)
                .filter(|&j| front.get(4 * c + j).is_none_or(|f| toward(4 * c + j).dot(*f) >= 0.0))
                .fold(0, |a, j| a | 1 << j),
        };
        traced |= (four & facing) << (4 * c);
    }
    traced
}

/// Chunk `c` of `v`: its four vectors, if it has them all.
fn chunk_of_four(v: &[Vec3A], c: usize) -> Option<&[Vec3A; 4]> {
    v.get(4 * c..4 * c + 4)?.try_into().ok()
}

/// Lane `l`'s time (0 where no times are given).
fn time_of(times: &[f32], l: usize) -> f32 {
    times.get(l).copied().unwrap_or(0.0)
}

/// The shadow ray of `light` from the lit point `from` toward it along `to_light` (its `L`, reversed)
/// at `time`: to the light's point, or unbounded for a distant light.
fn light_shadow_ray(light: &LightSource, from: Vec3A, to_light: Vec3A, time: f32) -> Option<Ray> {
    shadow_ray_toward(light.kind == LightKind::Distant, from, to_light, time)
}

/// [`light_shadow_ray`] of a distant light (an unbounded ray) or not (a segment to the light).
fn shadow_ray_toward(distant: bool, from: Vec3A, to_light: Vec3A, time: f32) -> Option<Ray> {
    let distance = if distant { f32::INFINITY } else { to_light.length() };
    Some(shadow_ray(from, to_light.normalize_or_zero(), distance)?.at_time(time))
}

/// The shadow ray from `from` along unit `dir` for `distance`, kept off both ends; `None` when the
/// segment is too short to hold anything.
fn shadow_ray(from: Vec3A, dir: Vec3A, distance: f32) -> Option<Ray> {
    if dir == Vec3A::ZERO {
        return None;
    }
    let (eps, near) = (epsilon(from), launch_epsilon(from));
    let tmax = if distance.is_finite() { distance - 2.0 * eps } else { f32::INFINITY };
    (tmax > near).then(|| Ray::segment(from, dir, near, tmax))
}

/// The buffers of a [`BatchLights`]: counts, lights, pending.
type BatchLightBuffers = (Vec<[u32; 4]>, Vec<LightLanes>, Vec<[u32; 4]>);

thread_local! {
    /// Buffers of dropped [`BatchLights`], for the next batch (`scratch`).
    static BATCH_LIGHT_BUFFERS: std::cell::RefCell<Vec<BatchLightBuffers>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl Drop for BatchLights {
    fn drop(&mut self) {
        let buffers =
            (std::mem::take(&mut self.counts), std::mem::take(&mut self.lights), std::mem::take(&mut self.pending));
        super::scratch::give(&BATCH_LIGHT_BUFFERS, buffers);
    }
}

impl BatchLights {
    /// Runs the lights over the batch's lanes. With `front`, lane `l`'s shadows are traced only
    /// for the lights within 90 degrees of `front[l]` (the side a shader facing its normal
    /// forward lights: `faceforward(N, I)`); without, for all.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn compute(
        frame: &Frame,
        material: Option<u32>,
        points: &[Vec3A],
        mask: &[i32],
        times: &[f32],
        front: Option<&[Vec3A]>,
        depth: u32,
        budgets: &mut [RayBudget],
    ) -> BatchLights {
        let n = points.len();
        let slots: usize = frame.world.lights.iter().map(|l| l.area.as_ref().map_or(1, |a| a.samples as usize)).sum();
        let slots = slots.min(MAX_LIGHTS);
        let (mut counts, mut lights, mut pending) = super::scratch::take(&BATCH_LIGHT_BUFFERS);
        let chunks = n.div_ceil(4);
        counts.clear();
        counts.resize(chunks, [0; 4]);
        // Not cleared: a row is read only below its lanes' counts, where an append wrote it (the
        // host ABI leaves lanes past their count undefined), and zeroing a batch's rows was most
        // of the stores here.
        lights.resize(slots * chunks, LightLanes::default());
        pending.clear();
        pending.resize(chunks, [0; 4]);
        for light in &frame.world.lights {
            if light.in_category("") {
                let lanes = LightLanesIn { mask, points, times, front, budgets: &mut *budgets };
                eval_light_lanes(frame, light, material, depth, lanes, |c, fill, lanes, later| {
                    let (Some(chunk_counts), Some(chunk_pending), Some(chunk_lights)) =
                        (counts.get_mut(c), pending.get_mut(c), lights.get_mut(c * slots..(c + 1) * slots))
                    else {
                        return;
                    };
                    let before = *chunk_counts;
                    let appended = append_row(chunk_lights, chunk_counts, fill, lanes);
                    count_dropped(frame, lanes & !appended);
                    for j in 0..4 {
                        if appended >> j & 1 != 0 {
                            chunk_pending[j] |= (later >> j & 1) << before[j];
                        }
                    }
                });
            }
        }
        BatchLights { n, slots, counts, lights, pending }
    }

    /// Lane `lane`'s light `k` (`k` below the lane's count).
    pub(super) fn light(&self, lane: usize, k: usize) -> HostLight {
        self.lights.get((lane / 4) * self.slots + k).map_or_else(HostLight::default, |row| row.lane(lane % 4))
    }

    /// Lights `0..count` of chunk `chunk`, every lane's, as rows.
    pub(super) fn chunk_lights(&self, chunk: usize, count: usize) -> &[LightLanes] {
        let start = (chunk * self.slots).min(self.lights.len());
        &self.lights[start..(start + count.min(self.slots)).min(self.lights.len())]
    }

    /// Which of `lane`'s lights (bit `k`: light `k`) still have their shadows untraced.
    pub(super) fn pending_of(&self, lane: usize) -> u32 {
        self.pending.get(lane / 4).map_or(0, |p| p[lane % 4])
    }

    /// How many lights lane `lane` has (0 past the batch).
    pub(super) fn count_of(&self, lane: usize) -> u32 {
        self.counts.get(lane / 4).map_or(0, |c| c[lane % 4])
    }

    /// Traces the pending shadows that queries need: for each `(lane, axis, cos)`, those of the
    /// lane's lights within the cone (`light_in_cone`), all together as packets.
    pub(super) fn resolve(
        &mut self,
        frame: &Frame,
        points: &[Vec3A],
        times: &[f32],
        queries: impl IntoIterator<Item = (usize, [f32; 3], f32)>,
    ) {
        let mut wanted: Vec<(usize, usize)> = Vec::new();
        for (lane, axis, cos) in queries {
            if lane >= self.n {
                continue;
            }
            let pending = self.pending_of(lane);
            if cos > 1.0 {
                // `ambient()`: no non-ambient light counts.
                continue;
            }
            let mut m = pending;
            while m != 0 {
                let k = m.trailing_zeros() as usize;
                m &= m - 1;
                if light_in_cone(self.light(lane, k).l, axis, cos) {
                    wanted.push((k, lane));
                    if let Some(p) = self.pending.get_mut(lane / 4) {
                        p[lane % 4] &= !(1 << k);
                    }
                }
            }
        }
        for group in wanted.chunks(PACKET_SIZE) {
            let mut packet = RayPacket::new();
            for (slot, &(k, lane)) in group.iter().enumerate() {
                let h = self.light(lane, k);
                let Some(light) = frame.world.lights.get(h.id as usize) else { continue };
                let (Some(&from), time) = (points.get(lane), time_of(times, lane)) else { continue };
                if let Some(ray) = light_shadow_ray(light, from, Vec3A::from(h.l), time) {
                    packet.set(slot, &ray);
                }
            }
            let mut attenuation = [Vec3A::ONE; PACKET_SIZE];
            transmission_packet(frame, &mut packet, &mut attenuation[..group.len()]);
            for (&(k, lane), a) in group.iter().zip(attenuation) {
                if let Some(row) = self.lights.get_mut((lane / 4) * self.slots + k) {
                    row.scale_cl(lane % 4, a.to_array());
                }
            }
        }
    }
}

/// How much light gets along each segment `from -> to` at its time (white where nothing blocks, and
/// for `None`): opaque blockers stop it, transparent ones filter it by their opacity. The segments
/// (at most a packet) are traced together; `through[l]` receives segment `l`'s.
pub(super) fn transmission_between(frame: &Frame, segments: &[Option<(Vec3A, Vec3A, f32)>], through: &mut [Vec3A]) {
    let mut packet = RayPacket::new();
    for (l, (from, to, time)) in segments.iter().enumerate().take(PACKET_SIZE).filter_map(|(l, s)| Some((l, (*s)?))) {
        let d = to - from;
        if let Some(ray) = shadow_ray(from, d.normalize_or_zero(), d.length()) {
            packet.set(l, &ray.at_time(time));
        }
    }
    through.fill(Vec3A::ONE);
    transmission_packet(frame, &mut packet, through);
}

/// Multiplies `through[l]` by how much light passes along the active shadow rays of `packet` (whose
/// lanes' `active` and `tmin` it uses as scratch):
/// zero where an opaque surface blocks, the product of `1 - opacity` of the transparent surfaces
/// crossed otherwise (the nearest `max_transparent_layers` of them; their order does not matter).
///
/// One packet occlusion query finds the opaque blockers. Its hit filter passes over transparent
/// surfaces and notes each crossing; the crossings of surfaces with a fixed opacity are multiplied
/// in afterwards ([`resolve_crossings`]). Only rays that cross a surface whose shader sets the
/// shadow's opacity (`transmissionhitmode "shader"`) walk through their surfaces again, together,
/// layer by layer, each layer's hits shaded in batches. (Walking every crossing ray that way takes a
/// closest-hit packet query per layer, costly in scenes where most shadow rays cross a window.)
fn transmission_packet(frame: &Frame, packet: &mut RayPacket, through: &mut [Vec3A]) {
    let active = packet.active & lane_mask(through.len());
    if active == 0 {
        return;
    }
    Stats::add(&frame.stats.shadow_rays, active.count_ones() as usize);
    let world = frame.world;
    packet.active = active;
    if !frame.transparent_shadows {
        let blocked = tracing(|| world.occluded_packet(RayKind::Shadow, packet));
        clear_lanes(through, blocked);
        return;
    }
    let material_of = |instance: u32, primitive: u32| material_at(world, instance, primitive);
    // Transparent candidates are passed over (the traversal goes on) but noted: in this thread's
    // log, where the filter runs on this thread (the traversal does not spread over threads),
    // else under a lock. A lock for every crossing would dominate the filter's time where most
    // candidates are crossings (a city with glass windows).
    let here = NOTED_HERE.with(|log| std::ptr::from_ref(log) as usize);
    let start = NOTED_HERE.with(|log| log.borrow().len());
    let elsewhere = Mutex::new(Vec::new());
    let note = |crossing: Crossing| {
        let noted = NOTED_HERE.with(|log| {
            std::ptr::from_ref(log) as usize == here && log.try_borrow_mut().map(|mut log| log.push(crossing)).is_ok()
        });
        if !noted {
            elsewhere.lock().unwrap_or_else(PoisonError::into_inner).push(crossing);
        }
    };
    let by_shader = AtomicU64::new(0);
    // Inside the shading of a shadow's own surfaces, their shaders are not run again for the
    // shadows their lights cast (see `SHADING_FOR_SHADOWS`): such surfaces pass light by their
    // opacity.
    let nested = SHADING_FOR_SHADOWS.with(Cell::get);
    let kind_of = |instance: u32, primitive: u32| {
        let i = instance as usize;
        // An instance out of range is shaded with the default material, which blocks.
        match (frame.instance_shadows.get(i), world.instances.get(i)) {
            (Some(InstanceShadows::Opaque), _) | (_, None) => ShadowKind::Blocked,
            (Some(shadows), Some(inst)) => shadows.kind(inst, primitive),
            (None, Some(inst)) => world.shadow_kind(inst.material_at(primitive)),
        }
    };
    let opaque = |c: &HitCandidate| {
        match kind_of(c.instance, c.primitive) {
            ShadowKind::Blocked => {
                LAST_BLOCKER.with(|b| b.set(Some((c.instance, c.primitive))));
                return true;
            }
            ShadowKind::ByShader if !nested => {
                by_shader.fetch_or(1u64 << (c.lane & 63), Ordering::Relaxed);
            }
            ShadowKind::ByShader | ShadowKind::Crossed => {
                note(Crossing { lane: c.lane & 63, t: c.t, instance: c.instance, primitive: c.primitive });
            }
        }
        false
    };
    // The triangle that blocked this thread's last shadow ray most often blocks the next packet's
    // too (a wall between a light and the points a batch shades): lanes it blocks need no
    // traversal. It is tested as the traversal tests it, and blocks whichever triangle it has
    // become since, if that is opaque: the lanes found are exactly blocked lanes.
    let known = LAST_BLOCKER
        .with(Cell::get)
        .filter(|&(instance, primitive)| kind_of(instance, primitive) == ShadowKind::Blocked)
        .map_or(0, |(instance, primitive)| world.lanes_hitting_triangle(packet, active, instance, primitive));
    packet.active = active & !known;
    let traced = if packet.active != 0 {
        tracing(|| world.occluded_packet_filtered(RayKind::Shadow, packet, Some(&opaque)))
    } else {
        0
    };
    packet.active = active;
    let blocked = traced | known;
    clear_lanes(through, blocked);
    let walking = by_shader.into_inner() & active & !blocked;
    let mut crossings = super::scratch::take(&CROSSING_BUFFERS);
    crossings.clear();
    NOTED_HERE.with(|log| crossings.extend(log.borrow_mut().drain(start..)));
    crossings.extend(elsewhere.into_inner().unwrap_or_else(PoisonError::into_inner));
    let layers = world.options.max_transparent_layers as usize;
    let passes = |c: &Crossing| {
        let opacity = Vec3A::from(material_of(c.instance, c.primitive).opacity);
        Vec3A::ONE - opacity.clamp(Vec3A::ZERO, Vec3A::ONE)
    };
    // Where the walk would start again after a layer at `t` (`walk_transparent_layers`).
    let past = |c: &Crossing| {
        let ray = packet.get(c.lane as usize);
        c.t + epsilon(ray.origin + ray.direction * c.t)
    };
    resolve_crossings(&mut crossings, active & !blocked & !walking, layers, passes, past).for_each(|(lane, passed)| {
        if let Some(t) = through.get_mut(lane) {
            *t *= passed;
            if t.max_element() < 1.0 / 256.0 {
                *t = Vec3A::ZERO;
            }
        }
    });
    super::scratch::give(&CROSSING_BUFFERS, crossings);
    walk_transparent_layers(frame, packet, walking, through);
}

thread_local! {
    /// The crossings' lists, reused from packet to packet (rather than one allocated afresh for
    /// each shadow packet that crosses a transparent surface).
    static CROSSING_BUFFERS: RefCell<Vec<Vec<Crossing>>> = const { RefCell::new(Vec::new()) };
    /// The crossings that shadow filters running on this thread note during a traversal; each
    /// `transmission_packet` takes those past where the log stood when it began.
    static NOTED_HERE: RefCell<Vec<Crossing>> = const { RefCell::new(Vec::new()) };
    /// The triangle (instance, primitive) that last blocked a shadow ray this thread traced.
    static LAST_BLOCKER: Cell<Option<(u32, u32)>> = const { Cell::new(None) };
    /// Set while this thread runs the shaders of surfaces a shadow ray crosses, to find their
    /// opacity (`walk_transparent_layers`). Those shaders' own light queries trace shadows too,
    /// and if those ran the shaders of the surfaces they cross in turn, the shading would recurse
    /// without end (each level at the ray depth, which bounds only the rays shaders spawn): a
    /// wooden cylinder under `transmissionhitmode "shader"` and two shadowed lights overflowed the
    /// stack. Their shadows take those surfaces' opacity instead.
    static SHADING_FOR_SHADOWS: Cell<bool> = const { Cell::new(false) };
}

/// Marks this thread as shading for shadows until dropped, then restores what it was.
struct ShadingForShadows(bool);

impl ShadingForShadows {
    fn begin() -> ShadingForShadows {
        ShadingForShadows(SHADING_FOR_SHADOWS.with(|s| s.replace(true)))
    }
}

impl Drop for ShadingForShadows {
    fn drop(&mut self) {
        SHADING_FOR_SHADOWS.with(|s| s.set(self.0));
    }
}

/// The material of triangle `primitive` of instance `instance` (the default for ids out of range).
fn material_at(world: &World, instance: u32, primitive: u32) -> &Material {
    let inst = world.instances.get(instance as usize);
    inst.and_then(|i| world.materials.get(i.material_at(primitive) as usize)).unwrap_or(&DEFAULT_MATERIAL)
}

/// A transparent surface a shadow ray crosses: the ray's lane, where along it, and which triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Crossing {
    lane: u32,
    t: f32,
    instance: u32,
    primitive: u32,
}

/// What gets through each lane of `lanes` with crossings: the product of `passes(c)` over the lane's
/// nearest `layers` layers, as walking them would find them: a crossing counts when it lies
/// beyond `past(c)` of the last one counted (a start offset), so the two triangles of a shared edge
/// are one layer, and so is a triangle the traversal reported twice (a packet that leaves its last
/// few lanes to single rays reports their crossings again). Sorts `crossings`.
fn resolve_crossings<'c>(
    crossings: &'c mut [Crossing],
    lanes: u64,
    layers: usize,
    passes: impl Fn(&Crossing) -> Vec3A + 'c,
    past: impl Fn(&Crossing) -> f32 + 'c,
) -> impl Iterator<Item = (usize, Vec3A)> + 'c {
    crossings.sort_unstable_by(|a, b| a.lane.cmp(&b.lane).then(a.t.total_cmp(&b.t)));
    crossings.chunk_by(|a, b| a.lane == b.lane).filter(move |run| lanes >> (run[0].lane & 63) & 1 != 0).map(
        move |run| {
            let (mut passed, mut counted, mut beyond) = (Vec3A::ONE, 0, f32::NEG_INFINITY);
            for c in run {
                if counted == layers {
                    break;
                }
                if c.t > beyond {
                    passed *= passes(c);
                    counted += 1;
                    beyond = past(c);
                }
            }
            (run[0].lane as usize, passed)
        },
    )
}

/// The transparent-shadow walk of the lanes `walking`, which cross surfaces whose shaders set the
/// shadow's opacity: layer by layer, each layer's hits shaded together, up to
/// `max_transparent_layers`.
fn walk_transparent_layers(frame: &Frame, packet: &mut RayPacket, mut walking: u64, through: &mut [Vec3A]) {
    let world = frame.world;
    let material_of = |instance: u32, primitive: u32| material_at(world, instance, primitive);
    let mut hits = HitPacket::default();
    for _ in 0..world.options.max_transparent_layers {
        if walking == 0 {
            return;
        }
        packet.active = walking;
        tracing(|| world.intersect_packet(RayKind::Shadow, packet, &mut hits));
        let mut shaded_by_shader = Vec::new();
        for l in lanes(walking) {
            let hit = hits.get(l);
            if !hit.is_hit() {
                walking &= !(1u64 << l);
                continue;
            }
            let material = material_of(hit.instance, hit.primitive);
            if material.is_opaque_for_shadows() {
                through[l] = Vec3A::ZERO;
            } else if material.shadow_by_shader {
                let ray = packet.get(l);
                let diff = RayDifferential::cone(ray.direction, 0.0, frame.pixel_spread);
                // Shaded at the ray depth, where shaders spawn no rays.
                shaded_by_shader.push(Pending { index: l, start: 0.0, ray, diff, hit, budget: RayBudget::NONE });
            } else {
                through[l] *= Vec3A::ONE - Vec3A::from(material.opacity).clamp(Vec3A::ZERO, Vec3A::ONE);
            }
        }
        if !shaded_by_shader.is_empty() {
            let mut shaded = vec![Shaded::default(); shaded_by_shader.len()];
            let _marked = ShadingForShadows::begin();
            (frame.stages.shade_in_groups)(frame, &mut shaded_by_shader, world.options.max_ray_depth, &mut shaded);
            for (p, s) in shaded_by_shader.iter().zip(&shaded) {
                through[p.index] *= Vec3A::ONE - s.oi.clamp(Vec3A::ZERO, Vec3A::ONE);
            }
        }
        for l in lanes(walking) {
            if through[l].max_element() < 1.0 / 256.0 {
                through[l] = Vec3A::ZERO;
                walking &= !(1u64 << l);
            } else {
                let t = hits.t.0[l];
                let from = packet.get(l).origin;
                packet.tmin.0[l] = t + epsilon(from + packet.get(l).direction * t);
            }
        }
    }
}

/// The first `n` lanes of a packet (all of them from `PACKET_SIZE` on).
fn lane_mask(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}

/// The lanes set in `mask`, lowest first.
fn lanes(mask: u64) -> impl Iterator<Item = usize> {
    (0..64).filter(move |l| mask >> l & 1 != 0)
}

fn clear_lanes(through: &mut [Vec3A], mask: u64) {
    for (l, t) in through.iter_mut().enumerate() {
        if mask >> l & 1 != 0 {
            *t = Vec3A::ZERO;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes a row whose lane `j` carries `tag` in its light's id and colour.
    fn tagged(tag: u32) -> impl Fn(&mut LightLanes) {
        move |row| *row = tagged_row(tag)
    }

    fn tagged_row(tag: u32) -> LightLanes {
        let mut row = LightLanes::default();
        for j in 0..4 {
            let h = HostLight { cl: [tag as f32, j as f32, 0.0], id: tag * 10 + j as u32, ..HostLight::default() };
            row.set_lane(j, &h);
        }
        row
    }

    /// Appending rows gives each lane its lights in order, whether the row goes in whole (equal
    /// counts) or lane by lane (counts apart), and stops at the room there is.
    #[test]
    fn appended_rows_give_each_lane_its_own_lights_in_order() {
        let mut lights = vec![LightLanes::default(); 3];
        let mut counts = [0u32; 4];
        // Equal counts: whole rows. Lane 1 unlit by the first light, lane 3 by the second.
        assert_eq!(append_row(&mut lights, &mut counts, &tagged(1), 0b1101), 0b1101);
        assert_eq!(counts, [1, 0, 1, 1]);
        // Counts apart now: lane by lane.
        assert_eq!(append_row(&mut lights, &mut counts, &tagged(2), 0b0111), 0b0111);
        assert_eq!(counts, [2, 1, 2, 1]);
        assert_eq!(append_row(&mut lights, &mut counts, &tagged(3), 0b1111), 0b1111);
        assert_eq!(counts, [3, 2, 3, 2]);
        // No room left for lanes 0 and 2.
        assert_eq!(append_row(&mut lights, &mut counts, &tagged(4), 0b1111), 0b1010);
        assert_eq!(counts, [3, 3, 3, 3]);
        let ids = |l: usize| (0..counts[l] as usize).map(|k| lights[k].lane(l).id).collect::<Vec<_>>();
        assert_eq!(ids(0), [10, 20, 30]);
        assert_eq!(ids(1), [21, 31, 41]);
        assert_eq!(ids(2), [12, 22, 32]);
        assert_eq!(ids(3), [13, 33, 43]);
        assert_eq!(lights[1].lane(3).cl, [3.0, 3.0, 0.0]);
    }

    /// A small deterministic generator (xorshift), so that failures reproduce.
    fn xorshift(mut state: u32) -> impl FnMut() -> u32 {
        move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        }
    }

    /// Four lanes at a time, `traced_lanes` picks the lanes that the one-lane test picks: a lane
    /// with a ray whose direction toward the light (`-L`) has a non-negative dot product with its
    /// front normal (as `Vec3A::dot` sums it), or that has no front normal; random and special
    /// values (zeros of both signs, tiny, huge, infinite, NaN), front lists shorter than the batch,
    /// and none.
    #[test]
    fn four_lane_shadow_choice_is_the_per_lane_one() {
        let mut next = xorshift(0x9e37_79b9);
        let specials = [0.0, -0.0, 1e-30, -1e-30, 1e30, -f32::INFINITY, f32::NAN, 1.0, -1.0];
        for round in 0..2000 {
            let n = 1 + (next() % 64) as usize;
            let mut value = || {
                let bits = next();
                if bits % 7 == 0 {
                    specials[(bits >> 8) as usize % specials.len()]
                } else {
                    bits as f32 / u32::MAX as f32 - 0.5
                }
            };
            let mut rows = [[0.0f32; PACKET_SIZE]; 9];
            for row in rows.iter_mut().take(3) {
                for v in row.iter_mut().take(n) {
                    *v = value();
                }
            }
            let front: Vec<Vec3A> = (0..n).map(|_| Vec3A::new(value(), value(), value())).collect();
            let lanes = (u64::from(next()) << 32 | u64::from(next())) & if n == 64 { u64::MAX } else { (1 << n) - 1 };
            let cut = match round % 4 {
                0 => n,
                _ => (next() as usize) % (n + 1),
            };
            let front = &front[..cut];
            let one_lane = |l: usize| {
                let toward = -Vec3A::new(rows[0][l], rows[1][l], rows[2][l]);
                front.get(l).is_none_or(|f| toward.dot(*f) >= 0.0)
            };
            let expected = (0..n).filter(|&l| lanes >> l & 1 != 0 && one_lane(l)).fold(0u64, |a, l| a | 1 << l);
            assert_eq!(traced_lanes(Some(front), &rows, lanes, n), expected, "round {round}, {n} lanes, {cut} fronts");
            assert_eq!(traced_lanes(None, &rows, lanes, n), lanes);
        }
    }

    /// The four-lane shadow rays are `shadow_ray_toward`'s, lane for lane and bit for bit, and only
    /// the lanes that ask and have light get one: random and special directions (zero, tiny,
    /// huge, infinite, NaN), colours (zero, infinite, NaN), points, masks and batch sizes, for
    /// point and distant lights.
    #[test]
    fn four_lane_shadow_rays_are_the_per_lane_ones() {
        let mut next = xorshift(0x2545_f491);
        let specials = [0.0, -0.0, 1e-30, -1e-20, 1e30, f32::INFINITY, f32::NAN, 3.0, -0.5];
        for round in 0..400 {
            let n = 1 + (next() % 64) as usize;
            let distant = round % 3 == 0;
            let mut value = |scale: f32| {
                let bits = next();
                if bits % 11 == 0 {
                    specials[(bits >> 8) as usize % specials.len()]
                } else {
                    (bits as f32 / u32::MAX as f32 - 0.5) * scale
                }
            };
            let mut rows = [[0.0f32; PACKET_SIZE]; 9];
            let mut ps = [[0.0f32; PACKET_SIZE]; 3];
            let mut times = [0.0f32; PACKET_SIZE];
            let mut points = Vec::new();
            let mut mask = Vec::new();
            for l in 0..n {
                for row in rows.iter_mut().take(6) {
                    row[l] = value(20.0);
                }
                if l % 7 == 3 {
                    // Nonzero, but its length underflows to zero: no direction.
                    (rows[0][l], rows[1][l], rows[2][l]) = (1e-30, -1e-25, 0.0);
                }
                let p = Vec3A::new(value(2000.0), value(2.0), value(1e5));
                (ps[0][l], ps[1][l], ps[2][l]) = (p.x, p.y, p.z);
                times[l] = value(1.0);
                points.push(p);
                mask.push(if value(1.0) < -0.3 { 0 } else { -1 });
            }
            let mut packet = RayPacket::new();
            let lanes = shadow_packet_rows(&rows, &ps, &times, &points, &mask, distant, &mut packet);
            for l in 0..n {
                let to_surface = Vec3A::new(rows[0][l], rows[1][l], rows[2][l]);
                let cl = Vec3A::new(rows[3][l], rows[4][l], rows[5][l]);
                let asks = mask[l] != 0 && to_surface != Vec3A::ZERO && cl != Vec3A::ZERO && cl.is_finite();
                let expected = if asks { shadow_ray_toward(distant, points[l], -to_surface, times[l]) } else { None };
                let case = format!("round {round}, lane {l} of {n}, L {to_surface}, Cl {cl}, from {}", points[l]);
                assert_eq!(lanes >> l & 1 != 0, expected.is_some(), "{case}");
                if let Some(ray) = expected {
                    let got = packet.get(l);
                    let bits = |r: &Ray| {
                        [r.origin.x, r.origin.y, r.origin.z, r.direction.x, r.direction.y, r.direction.z]
                            .into_iter()
                            .chain([r.tmin, r.tmax, r.time])
                            .map(f32::to_bits)
                            .collect::<Vec<_>>()
                    };
                    assert_eq!(bits(&got), bits(&ray), "{case}");
                }
            }
            assert_eq!(lanes & !lane_mask(n), 0, "no lane past the batch");
        }
    }

    /// Each lane's crossings multiply once per layer, nearest first up to the layer limit, and
    /// only for the lanes asked about.
    #[test]
    fn crossings_count_each_layer_once_nearest_first() {
        let at = |lane: u32, t: f32, primitive: u32| Crossing { lane, t, instance: 7, primitive };
        // Lane 2 crosses triangles 1, 2, 3 at t = 1, 2, 3; triangle 2 reported three times (a
        // packet's traversal, then single rays, with a slightly different t), and triangle 4 at
        // the same place (the other half of triangle 2's quad, met on their shared edge). Lane 5
        // crosses triangle 1 only; lane 9 is not asked about.
        let mut crossings = vec![
            at(5, 4.0, 1),
            at(2, 3.0, 3),
            at(2, 2.0, 2),
            at(9, 1.0, 1),
            at(2, 1.0, 1),
            at(2, 2.0001, 2),
            at(2, 2.0, 4),
            at(2, 2.0, 2),
        ];
        // Triangle k lets 1 / (k + 1) through; the walk starts again 0.01 past a layer.
        let passes = |c: &Crossing| Vec3A::splat(1.0 / (c.primitive + 1) as f32);
        let past = |c: &Crossing| c.t + 0.01;
        let lanes = (1u64 << 2) | (1 << 5);
        let all: Vec<_> = resolve_crossings(&mut crossings, lanes, 16, passes, past).collect();
        assert_eq!(all, vec![(2, Vec3A::splat(1.0 / 24.0)), (5, Vec3A::splat(0.5))]);
        // With two layers, lane 2 counts its two nearest layers (triangles 1 and 2).
        let two: Vec<_> = resolve_crossings(&mut crossings, lanes, 2, passes, past).collect();
        assert_eq!(two, vec![(2, Vec3A::splat(1.0 / 6.0)), (5, Vec3A::splat(0.5))]);
    }
}

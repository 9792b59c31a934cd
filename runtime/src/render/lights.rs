//! Lights on a batch: every light shader run over the batch's points (area lights sampled, one
//! light per sample), shadow rays traced as packets (or walked through transparent surfaces), and
//! the per-lane table the shader's light queries are served from.

use super::differential::RayDifferential;
use super::host::ShadeCall;
use super::shade::{finite_or_zero, mix, point_seed, shade_group, unit, Frame, Pending, Shaded};
use super::stats::{tracing, Stats};
use super::world::{LightSource, DEFAULT_MATERIAL};
use crate::ray::{Ray, RayPacket, PACKET_SIZE};
use crate::shading::{get3, put1, put3, with_batch, LightKind};
use glam::Vec3A;
use rtsl_compiler::back::jit::{HostLight, MAX_LIGHTS};

/// Runs one light's shader for the active lanes of a chunk and appends what reaches each lane, with
/// shadows traced.
#[allow(clippy::too_many_arguments)] // a chunk's lanes: mask, points, times, and where the lights go
pub(super) fn eval_light(
    frame: &Frame,
    light: &LightSource,
    mask: &[i32; 4],
    points: &[Vec3A; 4],
    times: &[f32; 4],
    depth: u32,
    out: &mut [HostLight],
    counts: &mut [u32; 4],
) {
    eval_light_lanes(frame, light, mask, points, times, depth, |l, h| {
        if (counts[l] as usize) < MAX_LIGHTS {
            out[4 * counts[l] as usize + l] = h;
            counts[l] += 1;
        }
    });
}

/// Runs one light's shader over `points` (up to a packet of lanes, `mask` nonzero where a point
/// asks; shadow rays at the lanes' `times`) and hands each lane's light to `sink`, its colour attenuated by traced shadows: a packet
/// of shadow rays when nothing in the scene is transparent, one transmission walk per ray
/// otherwise. Area lights give one light per sample.
fn eval_light_lanes(
    frame: &Frame,
    light: &LightSource,
    mask: &[i32],
    points: &[Vec3A],
    times: &[f32],
    depth: u32,
    mut sink: impl FnMut(usize, HostLight),
) {
    let n = points.len().min(PACKET_SIZE);
    let instance = &light.shader;
    let program = &instance.program;
    let slots = &program.slots;
    let samples = light.area.as_ref().map_or(1, |a| a.samples);
    let eye = frame.world.camera.eye();
    let ambient = light.kind == LightKind::Ambient;
    let scale = 1.0 / samples as f32;
    let mut results = vec![(Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO); n];
    for sample in 0..samples {
        Stats::add(&frame.stats.light_evaluations, 1);
        with_batch(program, n, |batch| {
            {
                let mut raw = batch.raw_mut();
                instance.write_params(&mut raw);
                raw.mask[..n].copy_from_slice(&mask[..n]);
                for (l, &point) in points.iter().enumerate().take(n) {
                    // The emitting point: the light's origin, or a sample of its geometry.
                    let (mut origin, mut normal) = (instance.world_from_shader.translation, Vec3A::ZERO);
                    if let Some(area) = &light.area {
                        let h = mix(point_seed(point) ^ u64::from(sample).wrapping_mul(0x2545_F491_4F6C_DD1D));
                        if let Some((q, nn)) = area.sample(unit(h), unit(mix(h)), unit(mix(h ^ 1))) {
                            (origin, normal) = (q, nn);
                        }
                    }
                    put3(&mut raw, slots.ps, l, point);
                    put3(&mut raw, slots.p, l, origin);
                    put3(&mut raw, slots.n, l, normal);
                    put3(&mut raw, slots.e, l, eye);
                    put1(&mut raw, slots.ncomps, l, 3.0);
                    put1(&mut raw, slots.time, l, time_of(times, l));
                }
            }
            let mut call = ShadeCall::new(frame, instance, instance.world_from_shader, depth);
            let table = call.table();
            program.code.shade_with_table(batch, &table);
            let raw = batch.raw_mut();
            for (l, r) in results.iter_mut().enumerate() {
                *r = (
                    get3(&raw, slots.l, l, Vec3A::ZERO),
                    get3(&raw, slots.cl, l, Vec3A::ZERO),
                    get3(&raw, slots.ol, l, Vec3A::ZERO),
                );
            }
        });
        // Shadows: which lanes need a ray, then one packet (or a walk per ray).
        let mut attenuation = vec![Vec3A::ONE; n];
        if !ambient && light.shadows {
            let mut packet = RayPacket::new();
            for l in 0..n {
                let (to_surface, cl, _) = results[l];
                if mask[l] == 0 || to_surface == Vec3A::ZERO || cl == Vec3A::ZERO || !cl.is_finite() {
                    continue;
                }
                let to_light = -to_surface;
                let distance = if light.kind == LightKind::Distant { f32::INFINITY } else { to_light.length() };
                let dir = to_light.normalize_or_zero();
                if frame.transparent_shadows {
                    attenuation[l] = transmission_along(frame, points[l], dir, distance, time_of(times, l));
                } else if let Some(ray) = shadow_ray(points[l], dir, distance) {
                    packet.set(l, &ray.at_time(time_of(times, l)));
                }
            }
            if packet.active != 0 {
                Stats::add(&frame.stats.shadow_rays, packet.active.count_ones() as usize);
                let blocked = tracing(|| frame.world.scene.occluded_packet(&packet));
                for (l, a) in attenuation.iter_mut().enumerate() {
                    if blocked >> l & 1 != 0 {
                        *a = Vec3A::ZERO;
                    }
                }
            }
        }
        for l in 0..n {
            let (to_surface, cl, ol) = results[l];
            // `illuminate` leaves L at zero where the point is outside its cone: no light there.
            if mask[l] == 0 || (!ambient && to_surface == Vec3A::ZERO) {
                continue;
            }
            let cl = finite_or_zero(cl) * scale * attenuation[l];
            sink(
                l,
                HostLight {
                    l: if ambient { [0.0; 3] } else { (-to_surface).to_array() },
                    cl: cl.to_array(),
                    ol: finite_or_zero(ol).to_array(),
                    ambient: u32::from(ambient),
                },
            );
        }
    }
}

/// Lane `l`'s time (0 where no times are given).
fn time_of(times: &[f32], l: usize) -> f32 {
    times.get(l).copied().unwrap_or(0.0)
}

/// The shadow ray from `from` along unit `dir` for `distance`, kept off both ends; `None` when the
/// segment is too short to hold anything.
fn shadow_ray(from: Vec3A, dir: Vec3A, distance: f32) -> Option<Ray> {
    if dir == Vec3A::ZERO {
        return None;
    }
    let eps = epsilon(from);
    let tmax = if distance.is_finite() { distance - 2.0 * eps } else { f32::INFINITY };
    (tmax > eps).then(|| Ray::segment(from, dir, eps, tmax))
}

/// The lights of every point of a surface batch, computed once for the whole batch when the shader
/// first asks (light shaders run over the batch, shadow rays go as packets): lane `l`'s light `k`
/// at `lights[k * n + l]`.
pub(super) struct BatchLights {
    pub(super) n: usize,
    pub(super) counts: Vec<u32>,
    pub(super) lights: Vec<HostLight>,
}

impl BatchLights {
    pub(super) fn compute(frame: &Frame, points: &[Vec3A], mask: &[i32], times: &[f32], depth: u32) -> BatchLights {
        let n = points.len();
        let slots: usize = frame.world.lights.iter().map(|l| l.area.as_ref().map_or(1, |a| a.samples as usize)).sum();
        let slots = slots.min(MAX_LIGHTS);
        let mut counts = vec![0u32; n];
        let mut lights = vec![HostLight::default(); slots * n];
        for light in &frame.world.lights {
            if light.in_category("") {
                eval_light_lanes(frame, light, mask, points, times, depth, |l, h| {
                    let k = counts[l] as usize;
                    if k < slots {
                        lights[k * n + l] = h;
                        counts[l] += 1;
                    }
                });
            }
        }
        BatchLights { n, counts, lights }
    }
}

/// A start offset for rays leaving `p` (its scale grows with the coordinates' magnitude).
pub(super) fn epsilon(p: Vec3A) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

/// How much light gets from `from` along unit `dir` for `distance` (white where nothing blocks):
/// opaque blockers stop it, transparent ones filter it by their opacity. Rays are at `time`.
pub(super) fn transmission_along(frame: &Frame, from: Vec3A, dir: Vec3A, distance: f32, time: f32) -> Vec3A {
    let Some(ray) = shadow_ray(from, dir, distance) else { return Vec3A::ONE };
    let ray = ray.at_time(time);
    let (eps, tmax) = (ray.tmin, ray.tmax);
    let world = frame.world;
    Stats::add(&frame.stats.shadow_rays, 1);
    if !frame.transparent_shadows {
        return if tracing(|| world.scene.occluded(&ray)) { Vec3A::ZERO } else { Vec3A::ONE };
    }
    let mut through = Vec3A::ONE;
    let mut start = eps;
    for _ in 0..world.options.max_transparent_layers {
        let hit = tracing(|| world.scene.intersect(&Ray::segment(from, dir, start, tmax).at_time(time)));
        if !hit.is_hit() {
            return through;
        }
        let Some(inst) = world.instances.get(hit.instance as usize) else { return through };
        let material = world.materials.get(inst.material as usize).unwrap_or(&DEFAULT_MATERIAL);
        if material.is_opaque_for_shadows() {
            return Vec3A::ZERO;
        }
        let opacity = if material.shadow_by_shader {
            let ray = Ray::segment(from, dir, start, tmax).at_time(time);
            let mut shaded = [Shaded::default()];
            let diff = RayDifferential::cone(dir, 0.0, frame.pixel_spread);
            shade_group(frame, &[Pending { index: 0, ray, diff, hit }], world.options.max_ray_depth, &mut shaded);
            shaded[0].oi
        } else {
            Vec3A::from(material.opacity)
        };
        through *= Vec3A::ONE - opacity.clamp(Vec3A::ZERO, Vec3A::ONE);
        if through.max_element() < 1.0 / 256.0 {
            return Vec3A::ZERO;
        }
        start = hit.t + epsilon(from + dir * hit.t);
    }
    through
}

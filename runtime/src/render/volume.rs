//! Volume shaders along ray segments (`docs/volumes.md`): the world's atmosphere, and the interior
//! shader of an object a segment ends inside.
//!
//! Every segment of a camera, `trace` or transparency ray that ends on a surface (the ray's origin
//! `E` to its hit `P`) is handed to one volume shader after the surface was shaded:
//! - the **interior** shader of the hit object's material when the segment reaches the surface
//!   from behind (the geometric normal faces along the ray: the segment ran inside the object);
//! - otherwise the world's **atmosphere** shader, if any.
//!
//! The shader sees RISpec's volume globals, `P` the hit, `E` the segment's start, `I = P - E`, and
//! `Ci`/`Oi` the surface's (premultiplied) colour and opacity, which it changes into what arrives
//! at `E`: a volume in front of the surface is composited *over* it (`Ci = emission + T Ci`,
//! `Oi = 1 - T (1 - Oi)` for transmittance `T`), so what lies behind a transparent surface is
//! attenuated by the renderer's front-to-back compositing. Rays that hit nothing and shadow rays
//! run no volume shader (as in RenderMan).
//!
//! Invariant: volume shaders run over batches of up to 64 lanes (one call per batch through the
//! packet ABI), lanes grouped by shader, never one lane at a time.

use super::host::ShadeCall;
use super::ray_budget::RayBudget;
use super::stats::ShadingTimer;
use super::work::{finite_or_zero, Frame, Pending, Shaded};
use super::world::DEFAULT_MATERIAL;
use crate::ray::PACKET_SIZE;
use crate::shading::{get3, put1, put3, with_batch, ShaderInstance};
use glam::{Affine3A, Vec3A};
use std::sync::Arc;

/// The volume shader for the segment that ended at `shaded` (see the module doc), if any.
fn segment_volume<'w>(frame: &Frame<'w>, p: &Pending, shaded: &Shaded) -> Option<&'w Arc<ShaderInstance>> {
    let world = frame.world;
    if shaded.ng == Vec3A::ZERO {
        // The hit's geometry could not be read: nothing was shaded there.
        return None;
    }
    if shaded.ng.dot(p.ray.direction) > 0.0 {
        let inst = world.instances.get(p.hit.instance as usize);
        let material = inst
            .and_then(|i| world.materials.get(i.material_at(p.hit.primitive) as usize))
            .unwrap_or(&DEFAULT_MATERIAL);
        if let Some(interior) = &material.interior {
            return Some(interior);
        }
    }
    world.atmosphere.as_ref()
}

/// Runs the volume shaders of a layer of shaded hits, changing their `ci`/`oi` in place.
pub(super) fn shade_segments(frame: &Frame, current: &[Pending], results: &mut [Shaded], depth: u32) {
    if !frame.volumes {
        return;
    }
    // Lanes grouped by shader instance (by address: one instance per binding).
    let mut lanes: Vec<(usize, usize)> = current
        .iter()
        .zip(results.iter())
        .enumerate()
        .filter_map(|(k, (p, r))| segment_volume(frame, p, r).map(|v| (Arc::as_ptr(v) as usize, k)))
        .collect();
    if lanes.is_empty() {
        return;
    }
    lanes.sort_unstable();
    let mut start = 0;
    while start < lanes.len() {
        let key = lanes[start].0;
        let mut end = start + 1;
        while end < lanes.len() && end - start < PACKET_SIZE && lanes[end].0 == key {
            end += 1;
        }
        let members: Vec<usize> = lanes[start..end].iter().map(|&(_, k)| k).collect();
        if let Some(volume) = segment_volume(frame, &current[members[0]], &results[members[0]]) {
            shade_batch(frame, volume, current, results, &members, depth);
        }
        start = end;
    }
}

/// One batch of segments through `volume`: `members` index `current` and `results`.
fn shade_batch(
    frame: &Frame,
    volume: &ShaderInstance,
    current: &[Pending],
    results: &mut [Shaded],
    members: &[usize],
    depth: u32,
) {
    let _timer = ShadingTimer::start(&frame.stats);
    let program = &volume.program;
    let slots = &program.slots;
    with_batch(program, members.len(), |batch| {
        {
            let mut raw = batch.raw_mut();
            volume.write_params(&mut raw);
            for (lane, &k) in members.iter().enumerate() {
                let (p, r) = (&current[k], &results[k]);
                let e = p.ray.origin;
                put3(&mut raw, slots.p, lane, r.p);
                put3(&mut raw, slots.e, lane, e);
                put3(&mut raw, slots.i, lane, r.p - e);
                put3(&mut raw, slots.ci, lane, r.ci);
                put3(&mut raw, slots.oi, lane, r.oi);
                put1(&mut raw, slots.ncomps, lane, 3.0);
            }
        }
        // What each segment's ray has left once its surface is shaded.
        let mut budgets: Vec<RayBudget> = members
            .iter()
            .map(|&k| {
                let (p, r) = (&current[k], &results[k]);
                RayBudget { left: p.budget.left.saturating_sub(r.spent), cut: false, ..p.budget }
            })
            .collect();
        let before = budgets.clone();
        let mut call = ShadeCall::new(frame, volume, Affine3A::IDENTITY, depth, &mut budgets);
        // Light loops in the volume shader are served for the whole batch at once.
        call.batch_points = members.iter().map(|&k| results[k].p).collect();
        call.batch_mask = vec![-1; members.len()];
        let table = call.table();
        program.code.shade_with_table(batch, &table);
        drop(call);
        let raw = batch.raw_mut();
        for (lane, &k) in members.iter().enumerate() {
            let r = &mut results[k];
            r.ci = finite_or_zero(get3(&raw, slots.ci, lane, r.ci));
            r.oi = finite_or_zero(get3(&raw, slots.oi, lane, r.oi));
            r.spent += before[lane].left.saturating_sub(budgets[lane].left);
            r.cut |= budgets[lane].cut;
        }
    });
}

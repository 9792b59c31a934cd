//! Filling a batch's globals from its hits: positions, normals, surface coordinates and their
//! derivatives, `I`, `E`, colours and time, as rows of the packet ABI's batch, four lanes at a
//! time where the hits' rows allow.

use super::hit_geometry::{derivs_four, GroupHits, HitRows, HitSurface};
use super::jobs::GroupRows;
use super::lanes::Lanes3;
use super::sampling::point_seed;
use crate::ray::PACKET_SIZE;
use crate::shading::{put1, varying_rows, Slot};
use glam::{BVec4A, Vec3A, Vec4};
use rtsl_compiler::abi::RawBatch;

/// Writes the globals of a batch of hits on one material and instance (lanes without geometry are
/// masked off), with their screen-space derivatives when `program` uses them, and the seed of its
/// random numbers.
pub(super) fn fill_hit_globals(
    raw: &mut RawBatch<'_>,
    program: &crate::shading::ShaderProgram,
    group: &GroupRows,
    hits: GroupHits,
    (color, opacity): (Vec3A, Vec3A),
) {
    let slots = &program.slots;
    let needs_derivs = needs_derivs(program);
    match hits {
        GroupHits::Rows(rows, len) => {
            fill_lane_globals_by_chunks(raw, program, group, (hits, rows, len), (color, opacity))
        }
        GroupHits::Each(..) => {
            for (m, g) in raw.mask.iter_mut().zip(hits.iter()) {
                if g.is_none() {
                    *m = 0;
                }
            }
            put3_rows(raw, slots.i, hits, |g, lane| g.p - group.origin(lane));
            put3_rows(raw, slots.e, hits, |_, lane| group.origin(lane));
            put3_rows(raw, slots.cs, hits, |g, _| g.cs.unwrap_or(color));
            put3_rows(raw, slots.os, hits, |g, _| g.os.unwrap_or(opacity));
            put3_rows(raw, slots.oi, hits, |g, _| g.os.unwrap_or(opacity));
            put1_rows(raw, slots.ncomps, hits, |_, _| 3.0);
            put1_rows(raw, slots.time, hits, |_, lane| group.time(lane));
        }
    }
    let rows = hits.rows();
    // A global at a time, a row per component: the shader reads few of them, and a row is written
    // without looking up its slot again for every lane.
    // The hit's own geometry is copied from its rows where `hit_geometries` wrote them.
    put3_hit_rows(raw, slots.p, rows.map(|r| &r.p), hits, |g| g.p);
    put3_hit_rows(raw, slots.n, rows.map(|r| &r.n), hits, |g| g.n);
    put3_hit_rows(raw, slots.ng, rows.map(|r| &r.ng), hits, |g| g.ng);
    put1_hit_rows(raw, slots.u, rows.map(|r| &r.uv[0]), hits, |g| g.uv[0]);
    put1_hit_rows(raw, slots.v, rows.map(|r| &r.uv[1]), hits, |g| g.uv[1]);
    put1_hit_rows(raw, slots.s, rows.map(|r| &r.uv[0]), hits, |g| g.st[0]);
    put1_hit_rows(raw, slots.t, rows.map(|r| &r.uv[1]), hits, |g| g.st[1]);
    put3_hit_rows(raw, slots.dpdu, rows.map(|r| &r.dpdu), hits, |g| g.dpdu);
    put3_hit_rows(raw, slots.dpdv, rows.map(|r| &r.dpdv), hits, |g| g.dpdv);
    // The derivatives only for shaders that use them (they cost a few solves per hit).
    if needs_derivs {
        fill_hit_derivs(raw, program, group, hits);
    }
    if let Some(seed) = program.layout().seed {
        for (lane, g) in hits.iter().enumerate() {
            let h = g.as_ref().map_or(0, |g| point_seed(g.p));
            raw.varying[seed * raw.stride + lane] = f32::from_bits(h as u32);
            raw.varying[(seed + 1) * raw.stride + lane] = f32::from_bits((h >> 32) as u32);
        }
    }
}

/// [`fill_hit_globals`]' mask and the globals that are not the hits' own rows (`I E Cs Os Oi
/// ncomps time`), for a group read from its rows alone (`hits`, whose rows are `rows`, `len`
/// lanes): four lanes at a time, zeros where a lane has no geometry (and in the lanes past `len` up
/// to a whole chunk, which the batch's rows hold). Lane by lane, each lane's `GroupHits::get` and
/// its row stores cost more than the values.
pub(super) fn fill_lane_globals_by_chunks(
    raw: &mut RawBatch<'_>,
    program: &crate::shading::ShaderProgram,
    group: &GroupRows,
    (hits, rows, len): (GroupHits, &HitRows, usize),
    (color, opacity): (Vec3A, Vec3A),
) {
    let slots = &program.slots;
    let len = len.min(group.len()).min(PACKET_SIZE);
    let first_row = |slot: Option<Slot>| slot.filter(|s| s.varying).map(|s| s.offset);
    let (i, e, ncomps, time) = (first_row(slots.i), first_row(slots.e), first_row(slots.ncomps), first_row(slots.time));
    let constants = [(first_row(slots.cs), color), (first_row(slots.os), opacity), (first_row(slots.oi), opacity)];
    let st = raw.stride;
    let rays = &group.rays;
    for chunk in 0..len.div_ceil(4) {
        let (at, lanes) = (4 * chunk, (len - 4 * chunk).min(4));
        let bits = (rows.valid >> at) as u32 & ((1 << lanes) - 1);
        let valid = BVec4A::from_array(std::array::from_fn(|j| bits >> j & 1 != 0));
        for (j, m) in raw.mask.iter_mut().skip(at).take(lanes).enumerate() {
            if bits >> j & 1 == 0 {
                *m = 0;
            }
        }
        let varying = &mut *raw.varying;
        let mut put = |row: usize, v: Vec4| {
            if let Some(out) = varying.get_mut(row * st + at..row * st + at + 4) {
                out.copy_from_slice(&Vec4::select(valid, v, Vec4::ZERO).to_array());
            }
        };
        if i.is_some() || e.is_some() {
            let origin = [&rays.ox.0, &rays.oy.0, &rays.oz.0].map(|row| Vec4::from_slice(&row[at..at + 4]));
            for (k, origin) in origin.into_iter().enumerate() {
                if let Some(i) = i {
                    // `g.p - origin` of each lane, as `Vec3A` subtracts.
                    put(i + k, Vec4::from_slice(&rows.p[k][at..at + 4]) - origin);
                }
                if let Some(e) = e {
                    put(e + k, origin);
                }
            }
        }
        for (first, value) in constants {
            let Some(first) = first else { continue };
            for k in 0..3 {
                put(first + k, Vec4::splat(value[k]));
            }
        }
        if let Some(ncomps) = ncomps {
            put(ncomps, Vec4::splat(3.0));
        }
        if let Some(time) = time {
            put(time, Vec4::from_slice(&rays.time.0[at..at + 4]));
        }
    }
    // Uniform globals (a shader's own choice, rare) take the last lane's value, as lane by lane.
    let uniform = |slot: Option<Slot>| slot.filter(|s| !s.varying);
    put3_rows(raw, uniform(slots.i), hits, |g, lane| g.p - group.origin(lane));
    put3_rows(raw, uniform(slots.e), hits, |_, lane| group.origin(lane));
    put3_rows(raw, uniform(slots.cs), hits, |_, _| color);
    put3_rows(raw, uniform(slots.os), hits, |_, _| opacity);
    put3_rows(raw, uniform(slots.oi), hits, |_, _| opacity);
    put1_rows(raw, uniform(slots.ncomps), hits, |_, _| 3.0);
    put1_rows(raw, uniform(slots.time), hits, |_, lane| group.time(lane));
}

/// Writes the screen-space derivatives of the globals `program` reads them of, and `du`, `dv`,
/// four hits at a time: from `rows` where `hit_geometries` worked them out with the geometry,
/// else by [`derivs_four`]. Lanes without geometry get zeros, as the batch's reset left them.
pub(super) fn fill_hit_derivs(
    raw: &mut RawBatch<'_>,
    program: &crate::shading::ShaderProgram,
    group: &GroupRows,
    hits: GroupHits,
) {
    let slots = &program.slots;
    let deriv_slots = program.layout().deriv_slots;
    // The rows each derivative goes to, found once for the batch.
    let (d1, d3) = (|slot| deriv_row(slot, 1, deriv_slots), |slot| deriv_row(slot, 3, deriv_slots));
    let (dp, di, dn) = (d3(slots.p), d3(slots.i), d3(slots.n));
    let (du, dv, ds, dt) = (d1(slots.u), d1(slots.v), d1(slots.s), d1(slots.t));
    let st = raw.stride;
    let len = hits.len().min(group.len());
    for chunk in 0..len.div_ceil(4) {
        let lanes = (len - 4 * chunk).min(4);
        let has = BVec4A::from_array(std::array::from_fn(|j| j < lanes && hits.get(4 * chunk + j).is_some()));
        let d = match hits {
            GroupHits::Each(_, Some(rows)) | GroupHits::Rows(rows, _) => rows.derivs(chunk),
            GroupHits::Each(geoms, None) => {
                let at = |j: usize| if j < lanes { geoms.get(4 * chunk + j).and_then(Option::as_ref) } else { None };
                derivs_four(group, 4 * chunk, std::array::from_fn(at))
            }
        };
        let derivs = &mut *raw.derivs;
        // Rows `first` (along x) and `first + 1` (along y) of this chunk's lanes; the batch's
        // rows hold whole chunks (`stride` is a multiple of four).
        let mut put = |first: Option<usize>, [x, y]: [Vec4; 2]| {
            let Some(row) = first else { return };
            for (k, v) in [x, y].into_iter().enumerate() {
                let at = (row + k) * st + 4 * chunk;
                if let Some(out) = derivs.get_mut(at..at + 4) {
                    out.copy_from_slice(&Vec4::select(has, v, Vec4::ZERO).to_array());
                }
            }
        };
        let components = |v: [Lanes3; 2]| [[v[0].x, v[1].x], [v[0].y, v[1].y], [v[0].z, v[1].z]];
        for (first, v) in [(dp, d.dp), (di, d.dp), (dn, d.dn)] {
            for (k, xy) in components(v).into_iter().enumerate() {
                put(first.map(|row| row + 2 * k), xy);
            }
        }
        for (first, xy) in [(du, d.du), (dv, d.dv), (ds, d.ds), (dt, d.dt)] {
            put(first, xy);
        }
        let widest = |[x, y]: [Vec4; 2]| -> [f32; 4] { std::array::from_fn(|j| x[j].abs().max(y[j].abs())) };
        for (slot, change) in [(slots.du, widest(d.du)), (slots.dv, widest(d.dv))] {
            for (j, v) in change.into_iter().enumerate().take(lanes).filter(|&(j, _)| has.test(j)) {
                put1(raw, slot, 4 * chunk + j, v);
            }
        }
    }
}

/// The varying slots [`fill_hit_globals`] writes in every lane (zeros where a lane has no
/// geometry): a batch need not zero them first.
pub(super) fn hit_global_rows(program: &crate::shading::ShaderProgram) -> [std::ops::Range<usize>; 17] {
    let s = &program.slots;
    // The random numbers' seed: two slots, written for every lane.
    let seed = program.layout().seed.map(|offset| Slot {
        varying: true,
        offset,
        written: false,
        entry_unused: false,
        derivs: false,
    });
    varying_rows([
        (s.p, 3),
        (s.n, 3),
        (s.ng, 3),
        (s.i, 3),
        (s.e, 3),
        (s.u, 1),
        (s.v, 1),
        (s.s, 1),
        (s.t, 1),
        (s.dpdu, 3),
        (s.dpdv, 3),
        (s.cs, 3),
        (s.os, 3),
        (s.oi, 3),
        (s.ncomps, 1),
        (s.time, 1),
        (seed, 2),
    ])
}

/// Whether `program` reads screen-space derivatives of its globals (or `du`, `dv`).
pub(super) fn needs_derivs(program: &crate::shading::ShaderProgram) -> bool {
    program.layout().deriv_slots > 0 || program.slots.du.is_some() || program.slots.dv.is_some()
}

/// The first derivative row of a varying global of `components` values, when the shader reads
/// its screen-space derivatives (`Slot::derivs`: a material that only filters a texture reads
/// those of `s` and `t`, and the others are not written for it).
/// Only globals below `deriv_slots` have them; see `docs/packet-abi.md`. Component `k`'s
/// derivative along x is row `first + 2k`, along y the row after it.
pub(super) fn deriv_row(slot: Option<Slot>, components: usize, deriv_slots: usize) -> Option<usize> {
    slot.filter(|s| s.derivs && s.varying && s.offset + components <= deriv_slots).map(|s| 2 * s.offset)
}

/// [`put3_rows`] of a hit's own geometry, copied from the group's [`HitRows`] `from` where there
/// are rows.
pub(super) fn put3_hit_rows(
    raw: &mut RawBatch<'_>,
    slot: Option<Slot>,
    from: Option<&[[f32; PACKET_SIZE]; 3]>,
    hits: GroupHits,
    value: impl Fn(&HitSurface) -> Vec3A,
) {
    let lanes = hits.len().min(PACKET_SIZE);
    if !copy_rows(raw, slot, from.map(|rows| rows.iter().map(|r| &r[..lanes]))) {
        put3_rows(raw, slot, hits, |g, _| value(g));
    }
}

/// [`put3_hit_rows`] for a float global.
pub(super) fn put1_hit_rows(
    raw: &mut RawBatch<'_>,
    slot: Option<Slot>,
    from: Option<&[f32; PACKET_SIZE]>,
    hits: GroupHits,
    value: impl Fn(&HitSurface) -> f32,
) {
    let lanes = hits.len().min(PACKET_SIZE);
    if !copy_rows(raw, slot, from.map(|row| std::iter::once(&row[..lanes]))) {
        put1_rows(raw, slot, hits, |g, _| value(g));
    }
}

/// Copies `from` (a row per component of a varying global, a lane per hit) into the batch's rows
/// of `slot`; `false`, with nothing written, where the slot is uniform or there are no rows (the
/// caller then gathers the global hit by hit).
pub(super) fn copy_rows<'r>(
    raw: &mut RawBatch<'_>,
    slot: Option<Slot>,
    from: Option<impl Iterator<Item = &'r [f32]>>,
) -> bool {
    let (Some(s), Some(from)) = (slot, from) else { return slot.is_none() };
    if !s.varying {
        return false;
    }
    let st = raw.stride;
    for (k, row) in from.enumerate() {
        let at = (s.offset + k) * st;
        match raw.varying.get_mut(at..at + row.len()) {
            Some(out) if row.len() <= st => out.copy_from_slice(row),
            _ => return false,
        }
    }
    true
}

/// Writes a triple global for every lane, `value(hit, lane)` where the lane has geometry and zero
/// where not, a row per component (a uniform global takes the last such lane's value, as [`put3`]
/// lane by lane would).
pub(super) fn put3_rows(
    raw: &mut RawBatch<'_>,
    slot: Option<Slot>,
    hits: GroupHits,
    value: impl Fn(&HitSurface, usize) -> Vec3A,
) {
    let Some(s) = slot else { return };
    let st = raw.stride;
    if !s.varying {
        let last = (0..hits.len()).rev().find_map(|lane| Some(value(&hits.get(lane)?, lane)));
        if let Some(v) = last {
            raw.uniform[s.offset..s.offset + 3].copy_from_slice(&v.to_array());
        }
        return;
    }
    let rows = &mut raw.varying[s.offset * st..(s.offset + 3) * st];
    let (x, rest) = rows.split_at_mut(st);
    let (y, z) = rest.split_at_mut(st);
    for (lane, ((g, x), (y, z))) in hits.iter().zip(x).zip(y.iter_mut().zip(z)).enumerate() {
        let v = g.map_or(Vec3A::ZERO, |g| value(&g, lane));
        (*x, *y, *z) = (v.x, v.y, v.z);
    }
}

/// [`put3_rows`] for a float global. (Not one generic `put_rows::<N>` indexing `rows[c * stride + lane]`:
/// the zipped rows here need no bounds checks.)
pub(super) fn put1_rows(
    raw: &mut RawBatch<'_>,
    slot: Option<Slot>,
    hits: GroupHits,
    value: impl Fn(&HitSurface, usize) -> f32,
) {
    let Some(s) = slot else { return };
    let st = raw.stride;
    if !s.varying {
        let last = (0..hits.len()).rev().find_map(|lane| Some(value(&hits.get(lane)?, lane)));
        if let Some(v) = last {
            raw.uniform[s.offset] = v;
        }
        return;
    }
    let row = &mut raw.varying[s.offset * st..(s.offset + 1) * st];
    for (lane, (g, x)) in hits.iter().zip(row).enumerate() {
        *x = g.map_or(0.0, |g| value(&g, lane));
    }
}

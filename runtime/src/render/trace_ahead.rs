//! A batch's `trace` rays traced and shaded together.
//!
//! The JIT runs a shader a chunk of four lanes at a time, and a chunk's `trace` needs its answer
//! before the chunk goes on. Answered there, each chunk's rays were traced and shaded as a batch
//! of at most four, and every such batch evaluated each light for its few points: the BART
//! kitchen, whose glass and chrome reflect, spent two thirds of its frame on such batches.
//!
//! So a batch whose shader calls `trace` (and no costlier ray built-in) runs twice
//! (`shade::shade_group`):
//! 1. **Recording.** Every `trace` call notes its rays ([`RayLog::Record`]) and answers as if
//!    nothing were hit (black, at infinity); `printf` says nothing.
//! 2. The rays of all calls are traced and shaded together ([`Recorded::trace`]): their hits form
//!    batches as large as those of primary rays.
//! 3. **Replay.** The batch's values are put back as they were before the first run, and the
//!    shader runs again. Its `trace` calls come in the same order; a lane whose ray is the one
//!    noted, bit for bit, gets that ray's answer ([`RayLog::Replay`]). Any other lane (a ray that
//!    depended on an earlier placeholder answer) is traced there and then, as without this.
//!
//! A lane's noted rays share what its ray tree has left (`ray_budget.rs`) equally; a replayed
//! answer whose tree was lent more than the lane has left when the second run asks for it is
//! traced again there, with what is left.
//!
//! A first run notes at most [`MAX_NOTED_CALLS`] calls: a shader that calls `trace` in a long
//! loop would otherwise hold every call's rays, and then all their answers, at once. The calls
//! past it answer black in the first run, as noted calls do, and are traced call by call in the
//! second, which finds no note for them.
//!
//! Each lane's answer is the same either way: a ray's shading does not depend on the other rays
//! shaded beside it. The cost is a second run of the shader itself, which for a reflecting or
//! refracting surface is small beside the shading of what its rays meet.
//!
//! `occlusion` is noted and answered the same way: the first run notes each lane's point, normal,
//! ray count and time (and answers unoccluded), the hemisphere rays of all calls are traced
//! together, and the second run takes each lane's share of blocked rays where its inputs are the
//! noted ones, bit for bit (a chunk's rays over four hemispheres made packets of a few rays each
//! octant). Under instant radiosity (`virtual_lights.rs`) `indirectdiffuse` is noted alike: the first run notes each lane's point, normal and time (and answers black), the points
//! of all calls gather their virtual lights together, and the second run takes each lane's sum
//! where its point, normal and time are the ones noted, bit for bit. A chunk's four points have
//! a few dozen shadow rays each, spread over the eight direction octants: gathered chunk by
//! chunk, they made packets of a dozen rays, each paying a whole packet's set-up; a batch's
//! points fill them. A point's sum is its own rays' alone, whichever points gather beside it.

use super::ray_budget::{Bounce, RayBudget};
use super::stats::Stats;
use super::virtual_lights::{self, Gatherer};
use super::work::{Frame, Sample};
use crate::ray::Ray;
use glam::Vec3A;

/// What a `trace` call does with its rays.
#[derive(Default)]
pub(super) enum RayLog {
    /// Traces and shades them at once.
    #[default]
    Direct,
    /// Notes them (the first run of a batch).
    Record(Recorded),
    /// Answers those noted (the second run).
    Replay(Replayed),
}

/// The most `trace` calls a batch's first run notes (each up to four rays): enough for every chunk
/// of a batch to trace several times, and few enough that the notes and their answers stay small
/// however many times a shader's loop calls `trace`.
pub(super) const MAX_NOTED_CALLS: usize = 4096;

/// The rays of a first run's `trace` calls, call by call, with the chunk that made each.
#[derive(Default)]
pub(super) struct Recorded {
    calls: Vec<(u32, [Option<Ray>; 4])>,
    /// The points of the run's `indirectdiffuse` calls that gather virtual lights, call by call.
    gathers: Vec<[Option<GatherAt>; 4]>,
    /// The points of the run's `occlusion` calls, call by call.
    occlusions: Vec<[Option<OcclusionAt>; 4]>,
    /// Whether the run had output it did not write (`printf`).
    pub(super) silenced: bool,
}

/// Where a lane asks `occlusion`: its point, unit normal (zero: no rays), the number of rays and
/// its ray time.
#[derive(Clone, Copy, Debug)]
pub(super) struct OcclusionAt {
    pub(super) p: Vec3A,
    pub(super) n: Vec3A,
    pub(super) count: u32,
    pub(super) time: f32,
}

impl OcclusionAt {
    /// Whether two are the same bit for bit (a NaN is never the same).
    fn same(&self, o: &OcclusionAt) -> bool {
        let g = |a: &OcclusionAt| GatherAt { p: a.p, n: a.n, time: a.time };
        self.count == o.count && g(self).same(&g(o))
    }
}

/// Where a lane gathers virtual lights: its point, unit normal and ray time.
#[derive(Clone, Copy, Debug)]
pub(super) struct GatherAt {
    pub(super) p: Vec3A,
    pub(super) n: Vec3A,
    pub(super) time: f32,
}

impl GatherAt {
    /// Whether two are the same bit for bit (a NaN is never the same).
    fn same(&self, o: &GatherAt) -> bool {
        let bits = |g: &GatherAt| {
            let (p, n) = (g.p.to_array(), g.n.to_array());
            [p[0], p[1], p[2], n[0], n[1], n[2], g.time].map(f32::to_bits)
        };
        self.p.is_finite() && self.n.is_finite() && bits(self) == bits(o)
    }
}

/// The answers to a first run's rays.
pub(super) struct Replayed {
    /// Each noted ray, and where its answer is in `seen` and `budgets`.
    calls: Vec<[Option<(Ray, usize)>; 4]>,
    seen: Vec<Sample>,
    /// What each ray's tree was lent, and what it left.
    lent: Vec<RayBudget>,
    budgets: Vec<RayBudget>,
    next: usize,
    /// Each noted gathering point with the light it gathered, call by call.
    gathers: Vec<[Option<(GatherAt, Vec3A)>; 4]>,
    next_gather: usize,
    /// Each noted `occlusion` point with the share of its rays that were blocked, call by call.
    occlusions: Vec<[Option<(OcclusionAt, f32)>; 4]>,
    next_occlusion: usize,
}

impl Recorded {
    /// Notes one call's rays (by lane of chunk `chunk`), unless [`MAX_NOTED_CALLS`] are noted
    /// already.
    pub(super) fn note(&mut self, chunk: u32, rays: [Option<Ray>; 4]) {
        if self.calls.len() < MAX_NOTED_CALLS {
            self.calls.push((chunk, rays));
        }
    }

    /// Notes one call's gathering points (by lane), unless [`MAX_NOTED_CALLS`] are noted already.
    pub(super) fn note_gathers(&mut self, at: [Option<GatherAt>; 4]) {
        if self.gathers.len() < MAX_NOTED_CALLS {
            self.gathers.push(at);
        }
    }

    /// Notes one call's `occlusion` points (by lane), unless [`MAX_NOTED_CALLS`] are noted already.
    pub(super) fn note_occlusions(&mut self, at: [Option<OcclusionAt>; 4]) {
        if self.occlusions.len() < MAX_NOTED_CALLS {
            self.occlusions.push(at);
        }
    }

    /// Whether the run must be made again: it traced or gathered, or kept output back.
    pub(super) fn needs_replay(&self) -> bool {
        self.silenced
            || self.calls.iter().any(|(_, c)| c.iter().any(Option::is_some))
            || self.gathers.iter().any(|g| g.iter().any(Option::is_some))
            || self.occlusions.iter().any(|g| g.iter().any(Option::is_some))
    }

    /// Traces and shades every noted ray together, `depth` deep: each costs its lane one, and a
    /// lane's rays share what it has left, as `budgets` (the batch's lanes') has it. A lane with
    /// fewer left than it noted rays has none traced here.
    pub(super) fn trace(mut self, frame: &Frame, depth: u32, budgets: &[RayBudget]) -> Replayed {
        let gathers = gather_all(frame, std::mem::take(&mut self.gathers));
        let occlusions = occlude_all(frame, std::mem::take(&mut self.occlusions));
        let lane_of = |chunk: u32, l: usize| (chunk as usize).checked_mul(4).and_then(|c| c.checked_add(l));
        let mut noted = vec![0u32; budgets.len()];
        for (chunk, call) in &self.calls {
            for l in (0..4).filter(|&l| call[l].is_some()) {
                if let Some(n) = lane_of(*chunk, l).and_then(|k| noted.get_mut(k)) {
                    *n += 1;
                }
            }
        }
        let share = |lane: usize| {
            let (budget, n) = (budgets.get(lane)?, *noted.get(lane)?);
            let mut share = budget.share(n).bounced(Bounce::Specular);
            share.take(1).then_some(share)
        };
        let (mut rays, mut lent) = (Vec::new(), Vec::new());
        let calls = self
            .calls
            .into_iter()
            .map(|(chunk, call)| {
                std::array::from_fn(|l| {
                    let r = call[l]?;
                    lent.push(share(lane_of(chunk, l)?)?);
                    rays.push(r);
                    Some((r, rays.len() - 1))
                })
            })
            .collect();
        let mut budgets = lent.clone();
        let seen = if rays.is_empty() {
            Vec::new()
        } else {
            Stats::add(&frame.stats.secondary_rays, rays.len());
            (frame.stages.trace_rays)(frame, &rays, &mut budgets, depth)
        };
        Replayed { calls, seen, lent, budgets, next: 0, gathers, next_gather: 0, occlusions, next_occlusion: 0 }
    }
}

/// Gathers the frame's virtual lights at every noted point, all points together
/// (`virtual_lights::gather`, which packs their shadow rays by octant), each point's sum beside it.
fn gather_all(frame: &Frame, noted: Vec<[Option<GatherAt>; 4]>) -> Vec<[Option<(GatherAt, Vec3A)>; 4]> {
    if noted.iter().all(|g| g.iter().all(Option::is_none)) {
        return Vec::new();
    }
    let lights = virtual_lights::of_frame(frame);
    let start = frame.stats.timed.then(std::time::Instant::now);
    let points: Vec<Gatherer> = noted
        .iter()
        .flatten()
        .flatten()
        .map(|g| Gatherer { p: g.p, n: g.n, time: g.time, set: virtual_lights::set_of(lights, frame, g.p) })
        .collect();
    let mut light = vec![Vec3A::ZERO; points.len()];
    virtual_lights::gather(lights, frame, &points, &mut light);
    if let Some(start) = start {
        let ns = start.elapsed().as_nanos() as u64;
        frame.stats.gathering_ns.add(ns as usize);
    }
    let mut sums = light.into_iter();
    noted.into_iter().map(|call| call.map(|g| Some((g?, sums.next()?)))).collect()
}

impl Replayed {
    /// The answers noted for the next call's rays, lane by lane, with the rays their trees spent
    /// and whether they refused one: `None` for a lane whose ray is not the one noted in its place
    /// (bit for bit), or whose tree was lent more than `lent` (what the lane has for it now), to
    /// be traced anew.
    pub(super) fn answers(
        &mut self,
        rays: &[Option<Ray>; 4],
        lent: &[RayBudget; 4],
    ) -> [Option<(Sample, u32, bool)>; 4] {
        let noted = self.calls.get(self.next).copied().unwrap_or([None; 4]);
        self.next += 1;
        std::array::from_fn(|l| match (rays[l], noted[l]) {
            (Some(ray), Some((was, k))) if same_ray(&ray, &was) => {
                let (given, after) = (self.lent.get(k)?, self.budgets.get(k)?);
                (given.left <= lent[l].left)
                    .then(|| Some((*self.seen.get(k)?, given.left - after.left.min(given.left), after.cut)))?
            }
            _ => None,
        })
    }
}

/// The share of each noted `occlusion` point's hemisphere rays that are blocked, all points' rays
/// traced together (as packets of one direction octant, `World::occluded_rays`), each share beside
/// its point.
fn occlude_all(frame: &Frame, noted: Vec<[Option<OcclusionAt>; 4]>) -> Vec<[Option<(OcclusionAt, f32)>; 4]> {
    if noted.iter().all(|g| g.iter().all(Option::is_none)) {
        return Vec::new();
    }
    let mut rays = Vec::new();
    // Each point's rays: those before its end and after the last point's.
    let ends: Vec<usize> = noted
        .iter()
        .flatten()
        .flatten()
        .map(|o| {
            if o.n != Vec3A::ZERO {
                super::hemisphere::hemisphere_rays(o.p, o.n, o.count, o.time, &mut rays);
            }
            rays.len()
        })
        .collect();
    Stats::add(&frame.stats.secondary_rays, rays.len());
    let mut blocked = Vec::new();
    super::stats::tracing(|| frame.world.occluded_rays(super::RayKind::Trace, &rays, &mut blocked));
    let mut start = 0;
    let mut shares = ends.into_iter().map(|end| {
        let hit = blocked[start..end].iter().filter(|&&b| b).count();
        let share = if end > start { hit as f32 / (end - start) as f32 } else { 0.0 };
        start = end;
        share
    });
    noted.into_iter().map(|call| call.map(|o| Some((o?, shares.next()?)))).collect()
}

impl Replayed {
    /// The share of its rays blocked for the next `occlusion` call's points, lane by lane: `None`
    /// for a lane whose point, normal, ray count or time is not the one noted in its place (bit
    /// for bit), to be traced anew.
    pub(super) fn occluded(&mut self, at: &[Option<OcclusionAt>; 4]) -> [Option<f32>; 4] {
        next_answers(&self.occlusions, &mut self.next_occlusion, at, OcclusionAt::same)
    }

    /// The light gathered for the next `indirectdiffuse` call's points, lane by lane: `None` for a
    /// lane whose point, normal or time is not the one noted in its place (bit for bit), to be
    /// gathered anew.
    pub(super) fn gathered(&mut self, at: &[Option<GatherAt>; 4]) -> [Option<Vec3A>; 4] {
        next_answers(&self.gathers, &mut self.next_gather, at, GatherAt::same)
    }
}

/// The answers noted for the next call (`noted[*next]`, then `next` moves on), lane by lane: a
/// lane's answer where its query is `same` as the one noted in its place, else `None`.
fn next_answers<Q: Copy, A: Copy>(
    noted: &[[Option<(Q, A)>; 4]],
    next: &mut usize,
    at: &[Option<Q>; 4],
    same: impl Fn(&Q, &Q) -> bool,
) -> [Option<A>; 4] {
    let call = noted.get(*next).copied().unwrap_or([None; 4]);
    *next += 1;
    std::array::from_fn(|l| match (at[l], call[l]) {
        (Some(q), Some((was, answer))) if same(&q, &was) => Some(answer),
        _ => None,
    })
}

/// Whether two rays are the same bit for bit (`-0` is not `+0`; a NaN is never the same).
fn same_ray(a: &Ray, b: &Ray) -> bool {
    let bits = |r: &Ray| {
        let (o, d) = (r.origin.to_array(), r.direction.to_array());
        [o[0], o[1], o[2], d[0], d[1], d[2], r.tmin, r.tmax, r.time].map(f32::to_bits)
    };
    let finite = |r: &Ray| r.origin.is_finite() && r.direction.is_finite();
    finite(a) && bits(a) == bits(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    #[test]
    fn a_first_run_notes_a_bounded_number_of_calls() {
        let ray = Ray::segment(Vec3A::ZERO, Vec3A::Z, 1e-4, f32::INFINITY);
        let mut noted = Recorded::default();
        for _ in 0..3 * MAX_NOTED_CALLS {
            noted.note(0, [Some(ray); 4]);
        }
        assert_eq!(noted.calls.len(), MAX_NOTED_CALLS);
        assert!(noted.needs_replay());
    }

    #[test]
    fn rays_are_the_same_only_bit_for_bit() {
        let ray = Ray::segment(Vec3A::new(1.0, 2.0, 3.0), Vec3A::new(0.0, 0.0, 1.0), 1e-4, f32::INFINITY);
        assert!(same_ray(&ray, &ray));
        let mut signed = ray;
        signed.direction.x = -0.0;
        assert!(!same_ray(&ray, &signed), "-0 and +0 differ");
        let mut later = ray;
        later.time = 0.5;
        assert!(!same_ray(&ray, &later));
        let mut nan = ray;
        nan.origin.y = f32::NAN;
        assert!(!same_ray(&nan, &nan));
    }
}

//! A group's hits to shade by rows (structure of arrays, a lane per hit, a packet at most): each
//! hit's ray, its differential, the hit itself and the budget its shading spends from
//! ([`GroupRows`]). Shading reads them a row at a time (four or eight lanes in a vector), the hit
//! geometry and the batch's globals from the same rows. A primary packet whose every lane hit one
//! material and instance is its own group, read where the packet is (no copy); other hits are
//! gathered into rows of their own ([`JobRows`]): a tile's other primary hits straight from their
//! packets' rows, hits that arrive one by one (secondary rays, as [`Pending`] jobs) from those.
//!
//! Invariants: the lanes' hits share one instance (a group is of one material and instance); the
//! lanes from `len` up to the next multiple of eight hold real hits' values (rows gathered repeat
//! their last hit there, [`JobRows::finish`]), so that arithmetic over a group's last chunk of
//! four or eight reads values it may drop.

use super::differential::{DifferentialRows, RayDifferential};
use super::ray_budget::RayBudget;
use crate::ray::{Hit, HitPacket, Ray, RayPacket, PACKET_SIZE};
use glam::Vec3A;

/// A hit to shade, one by one: the ray's index among those its caller shades (where its result
/// goes), the ray, its differential and hit, and what the ray's tree may still spawn
/// (`ray_budget.rs`).
pub(crate) struct Pending {
    pub(crate) index: usize,
    /// How far along the ray that began its sample `ray` starts: 0 for a first hit, the
    /// distance of the surfaces crossed before for a ray going on through transparent ones.
    pub(crate) start: f32,
    pub(crate) ray: Ray,
    pub(crate) diff: RayDifferential,
    pub(crate) hit: Hit,
    pub(crate) budget: RayBudget,
}

/// A group's hits by rows, where they lie (see the module documentation).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GroupRows<'a> {
    len: usize,
    pub(crate) rays: &'a RayPacket,
    pub(crate) diffs: &'a DifferentialRows,
    pub(crate) hits: &'a HitPacket,
    /// Each lane's budget (`len` of them).
    pub(crate) budgets: &'a [RayBudget],
}

impl<'a> GroupRows<'a> {
    /// A whole packet's hits (every lane's, all on one material and instance), read in place,
    /// with their budgets.
    pub(crate) fn whole_packet(
        (rays, diffs, hits): (&'a RayPacket, &'a DifferentialRows, &'a HitPacket),
        budgets: &'a [RayBudget; PACKET_SIZE],
    ) -> GroupRows<'a> {
        GroupRows { len: PACKET_SIZE, rays, diffs, hits, budgets }
    }

    /// The hits held.
    #[inline(always)]
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// Whether no hit is held.
    pub(crate) fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The group's instance (that of its first hit).
    #[inline(always)]
    pub(crate) fn instance(&self) -> u32 {
        self.hits.instance.0[0]
    }

    /// Lane `l`'s ray.
    #[inline(always)]
    pub(crate) fn ray(&self, l: usize) -> Ray {
        self.rays.get(l)
    }

    /// Lane `l`'s ray's origin.
    #[inline(always)]
    pub(crate) fn origin(&self, l: usize) -> Vec3A {
        let r = self.rays;
        Vec3A::new(r.ox.0[l], r.oy.0[l], r.oz.0[l])
    }

    /// Lane `l`'s ray's direction.
    #[inline(always)]
    pub(crate) fn direction(&self, l: usize) -> Vec3A {
        let r = self.rays;
        Vec3A::new(r.dx.0[l], r.dy.0[l], r.dz.0[l])
    }

    /// Lane `l`'s ray's time.
    #[inline(always)]
    pub(crate) fn time(&self, l: usize) -> f32 {
        self.rays.time.0[l]
    }

    /// Lane `l`'s ray differential.
    #[inline(always)]
    pub(crate) fn diff(&self, l: usize) -> RayDifferential {
        self.diffs.lane(l)
    }

    /// Lane `l`'s hit.
    #[inline(always)]
    pub(crate) fn hit(&self, l: usize) -> Hit {
        self.hits.get(l)
    }
}

/// A group's hits gathered into rows of their own (see the module documentation).
#[derive(Clone, Debug)]
pub(crate) struct JobRows {
    len: usize,
    pub(crate) rays: RayPacket,
    pub(crate) diffs: DifferentialRows,
    pub(crate) hits: HitPacket,
    pub(crate) budgets: [RayBudget; PACKET_SIZE],
}

impl Default for JobRows {
    fn default() -> Self {
        JobRows {
            len: 0,
            rays: RayPacket::new(),
            diffs: DifferentialRows::default(),
            hits: HitPacket::default(),
            budgets: [RayBudget::NONE; PACKET_SIZE],
        }
    }
}

impl JobRows {
    /// The hits held, by rows.
    #[inline(always)]
    pub(crate) fn rows(&self) -> GroupRows<'_> {
        GroupRows {
            len: self.len,
            rays: &self.rays,
            diffs: &self.diffs,
            hits: &self.hits,
            budgets: &self.budgets[..self.len],
        }
    }

    /// Holds no hit (the rows keep their values, to be written over).
    #[inline(always)]
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds the hit of `pending`, with `budget`; `false` when the rows are full.
    #[inline(always)]
    pub(crate) fn push(&mut self, pending: &Pending, budget: RayBudget) -> bool {
        let l = self.len;
        if l >= PACKET_SIZE {
            return false;
        }
        let Pending { ray, diff, hit, .. } = pending;
        let rays = &mut self.rays;
        let (o, d) = (ray.origin.to_array(), ray.direction.to_array());
        for (k, row) in [&mut rays.ox, &mut rays.oy, &mut rays.oz].into_iter().enumerate() {
            row.0[l] = o[k];
        }
        for (k, row) in [&mut rays.dx, &mut rays.dy, &mut rays.dz].into_iter().enumerate() {
            row.0[l] = d[k];
        }
        (rays.tmin.0[l], rays.tmax.0[l], rays.time.0[l]) = (ray.tmin, ray.tmax, ray.time);
        self.diffs.set_lane(l, *diff);
        self.put_hit(l, hit);
        self.budgets[l] = budget;
        self.len += 1;
        true
    }

    /// Adds the hit of lane `lane` of a packet (`rays`, `diffs`, `hits`), with `budget`; `false`
    /// when the rows are full. Row to row, without building the lane's ray, differential and hit.
    #[inline(always)]
    pub(crate) fn push_lane(
        &mut self,
        (rays, diffs, hits): (&RayPacket, &DifferentialRows, &HitPacket),
        lane: usize,
        budget: RayBudget,
    ) -> bool {
        let l = self.len;
        if l >= PACKET_SIZE || lane >= PACKET_SIZE {
            return false;
        }
        let to = &mut self.rays;
        for (to, from) in [
            (&mut to.ox, &rays.ox),
            (&mut to.oy, &rays.oy),
            (&mut to.oz, &rays.oz),
            (&mut to.dx, &rays.dx),
            (&mut to.dy, &rays.dy),
            (&mut to.dz, &rays.dz),
            (&mut to.tmin, &rays.tmin),
            (&mut to.tmax, &rays.tmax),
            (&mut to.time, &rays.time),
        ] {
            to.0[l] = from.0[lane];
        }
        let d = &mut self.diffs;
        for (to, from) in [(&mut d.dodx, &diffs.dodx), (&mut d.dody, &diffs.dody), (&mut d.dddx, &diffs.dddx)]
            .into_iter()
            .chain([(&mut d.dddy, &diffs.dddy)])
        {
            for k in 0..3 {
                to[k][l] = from[k][lane];
            }
        }
        let h = &mut self.hits;
        (h.t.0[l], h.u.0[l], h.v.0[l]) = (hits.t.0[lane], hits.u.0[lane], hits.v.0[lane]);
        (h.instance.0[l], h.primitive.0[l]) = (hits.instance.0[lane], hits.primitive.0[lane]);
        self.budgets[l] = budget;
        self.len += 1;
        true
    }

    /// Copies the last hit into the lanes after it up to the next multiple of eight (the module's
    /// invariant); call once the hits are in.
    pub(crate) fn finish(&mut self) {
        let Some(last) = self.len.checked_sub(1) else { return };
        let end = self.len.next_multiple_of(8).min(PACKET_SIZE);
        let rays = &mut self.rays;
        for row in [
            &mut rays.ox,
            &mut rays.oy,
            &mut rays.oz,
            &mut rays.dx,
            &mut rays.dy,
            &mut rays.dz,
            &mut rays.tmin,
            &mut rays.tmax,
            &mut rays.time,
        ] {
            let v = row.0[last];
            row.0[self.len..end].fill(v);
        }
        let d = &mut self.diffs;
        for rows in [&mut d.dodx, &mut d.dody, &mut d.dddx, &mut d.dddy] {
            for row in rows.iter_mut() {
                let v = row[last];
                row[self.len..end].fill(v);
            }
        }
        let h = &mut self.hits;
        for row in [&mut h.t, &mut h.u, &mut h.v] {
            let v = row.0[last];
            row.0[self.len..end].fill(v);
        }
        for row in [&mut h.instance, &mut h.primitive] {
            let v = row.0[last];
            row.0[self.len..end].fill(v);
        }
    }

    #[inline(always)]
    fn put_hit(&mut self, l: usize, hit: &Hit) {
        let h = &mut self.hits;
        (h.t.0[l], h.u.0[l], h.v.0[l]) = (hit.t, hit.u, hit.v);
        (h.instance.0[l], h.primitive.0[l]) = (hit.instance, hit.primitive);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(k: usize) -> Pending {
        let f = k as f32;
        let ray = Ray::new(Vec3A::new(f, 1.0, 2.0), Vec3A::new(0.0, 0.6, 0.8)).at_time(0.25 * f);
        let v = |s: f32| Vec3A::new(s * f, -s, s + f);
        let diff = RayDifferential { dodx: v(1.0), dody: v(2.0), dddx: v(3.0), dddy: v(4.0) };
        let hit = Hit { t: 2.0 + f, u: 0.125 * f, v: 0.5, instance: 3, primitive: 7 * k as u32 };
        Pending { index: k, start: 0.0, ray, diff, hit, budget: RayBudget::NONE }
    }

    /// A hit goes in from a job or from a packet's rows and comes out the same, and the lanes
    /// after the last up to a chunk of eight repeat it.
    #[test]
    fn hits_pushed_from_jobs_or_packets_read_back_and_pad_their_last_chunk() {
        let given: Vec<Pending> = (0..11).map(job).collect();
        let mut from_jobs = JobRows::default();
        let mut packet = (RayPacket::new(), DifferentialRows::default(), HitPacket::default());
        for (k, p) in given.iter().enumerate() {
            assert!(from_jobs.push(p, RayBudget::from_pixel(k as u32)));
            let (rays, diffs, hits) = &mut packet;
            let r = p.ray;
            for (row, v) in [&mut rays.ox, &mut rays.oy, &mut rays.oz].into_iter().zip(r.origin.to_array()) {
                row.0[k] = v;
            }
            for (row, v) in [&mut rays.dx, &mut rays.dy, &mut rays.dz].into_iter().zip(r.direction.to_array()) {
                row.0[k] = v;
            }
            (rays.tmin.0[k], rays.tmax.0[k], rays.time.0[k]) = (r.tmin, r.tmax, r.time);
            diffs.set_lane(k, p.diff);
            (hits.t.0[k], hits.u.0[k], hits.v.0[k]) = (p.hit.t, p.hit.u, p.hit.v);
            (hits.instance.0[k], hits.primitive.0[k]) = (p.hit.instance, p.hit.primitive);
        }
        let mut from_packet = JobRows::default();
        for k in 0..given.len() {
            let packet = (&packet.0, &packet.1, &packet.2);
            assert!(from_packet.push_lane(packet, k, RayBudget::from_pixel(k as u32)));
        }
        for jobs in [&mut from_jobs, &mut from_packet] {
            jobs.finish();
            let rows = jobs.rows();
            assert_eq!(rows.len(), 11);
            assert_eq!(rows.instance(), 3);
            for l in 0..16 {
                let p = &given[l.min(10)];
                assert_eq!(rows.ray(l), p.ray, "lane {l}");
                assert_eq!(rows.diff(l), p.diff, "lane {l}");
                assert_eq!(rows.hit(l), p.hit, "lane {l}");
                assert_eq!(
                    (rows.origin(l), rows.direction(l), rows.time(l)),
                    (p.ray.origin, p.ray.direction, p.ray.time)
                );
            }
            assert_eq!(rows.budgets[4], RayBudget::from_pixel(4));
        }
        let mut full = JobRows::default();
        assert!((0..PACKET_SIZE).all(|k| full.push(&given[k % 11], RayBudget::NONE)));
        assert!(!full.push(&given[0], RayBudget::NONE), "a packet's worth at most");
        full.clear();
        assert!(full.rows().is_empty());
    }
}

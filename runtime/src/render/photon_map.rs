//! A photon map (Jensen 1996): photons where light paths ended, in a balanced kd-tree, and the
//! density estimate of the irradiance they carry to a point: the power of its `k` nearest photons
//! over the disc they cover.
//!
//! The tree is implicit: the photons are reordered so that the photons of a subtree `[lo, hi)`
//! have their splitting photon at `(lo + hi) / 2`, the lower half before it and the upper after;
//! `axes[i]` is the axis photon `i` splits.

use glam::Vec3A;
use std::collections::BinaryHeap;

/// Where a light path ended, the power it carried there, and the direction it arrived from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    pub p: Vec3A,
    pub power: Vec3A,
    /// Unit direction of travel as it arrived.
    pub direction: Vec3A,
}

/// Photons in a balanced kd-tree.
#[derive(Clone, Debug, Default)]
pub struct PhotonMap {
    photons: Vec<Photon>,
    axes: Vec<u8>,
    /// The box of each subtree's photons, at its splitting photon's index: a search skips a
    /// subtree whose box lies beyond its reach (most searches, away from a caustic, find none).
    bounds: Vec<[Vec3A; 2]>,
}

/// The most photons one estimate gathers.
pub const MAX_ESTIMATOR: usize = 1024;

impl PhotonMap {
    pub fn new(mut photons: Vec<Photon>) -> PhotonMap {
        photons.retain(|p| p.p.is_finite() && p.power.is_finite() && p.direction.is_finite());
        let mut axes = vec![0u8; photons.len()];
        build(&mut photons, &mut axes, 0);
        PhotonMap::with_bounds(photons, axes)
    }

    /// The map of photons in tree order, with its subtrees' boxes worked out.
    fn with_bounds(photons: Vec<Photon>, axes: Vec<u8>) -> PhotonMap {
        let mut bounds = vec![[Vec3A::ZERO; 2]; photons.len()];
        subtree_bounds(&photons, &mut bounds, 0, photons.len());
        PhotonMap { photons, axes, bounds }
    }

    /// How many photons the map holds.
    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// The photons, in the tree's order.
    pub fn photons(&self) -> &[Photon] {
        &self.photons
    }

    /// Appends the map to `out` as it lies in memory, tree order kept: a count, then each photon's
    /// position, power and direction (nine floats) and its splitting axis.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.photons.len() as u64).to_le_bytes());
        for (photon, axis) in self.photons.iter().zip(&self.axes) {
            for v in [photon.p, photon.power, photon.direction] {
                for c in v.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            out.push(*axis);
        }
    }

    /// The map [`PhotonMap::encode`] wrote at the start of `bytes`, and the bytes after it; an
    /// error for bytes that are short, a count they cannot hold, a value that is not finite or an
    /// axis that is not 0, 1 or 2. (Any order of valid photons is a safe tree to search: a wrong
    /// order finds the wrong photons, never reads outside the map.)
    pub fn decode(bytes: &[u8]) -> Result<(PhotonMap, &[u8]), String> {
        const PHOTON_BYTES: usize = 9 * 4 + 1;
        let (count, rest) = bytes.split_first_chunk::<8>().ok_or("a photon map without its count")?;
        let count = u64::from_le_bytes(*count);
        let size = usize::try_from(count).ok().and_then(|n| n.checked_mul(PHOTON_BYTES));
        let Some((body, rest)) = size.and_then(|size| rest.split_at_checked(size)) else {
            return Err(format!("a photon map of {count} photons in {} bytes", rest.len()));
        };
        let mut photons = Vec::with_capacity(body.len() / PHOTON_BYTES);
        let mut axes = Vec::with_capacity(body.len() / PHOTON_BYTES);
        for chunk in body.chunks_exact(PHOTON_BYTES) {
            let f = |i: usize| f32::from_le_bytes([chunk[4 * i], chunk[4 * i + 1], chunk[4 * i + 2], chunk[4 * i + 3]]);
            let v = |i: usize| Vec3A::new(f(i), f(i + 1), f(i + 2));
            let photon = Photon { p: v(0), power: v(3), direction: v(6) };
            let axis = chunk[36];
            if !(photon.p.is_finite() && photon.power.is_finite() && photon.direction.is_finite()) || axis > 2 {
                return Err(format!("photon {} of the map is damaged", photons.len()));
            }
            photons.push(photon);
            axes.push(axis);
        }
        Ok((PhotonMap::with_bounds(photons, axes), rest))
    }

    /// The irradiance at `p` on a surface facing `n` (unit; zero: any way) from the `k` nearest
    /// photons within `max_radius` that arrived from the side `n` faces: their power over the area of the disc
    /// that holds them. Black where none are near.
    pub fn irradiance(&self, p: Vec3A, n: Vec3A, k: usize, max_radius: f32) -> Vec3A {
        let k = k.clamp(1, MAX_ESTIMATOR);
        let mut nearest = BinaryHeap::with_capacity(k + 1);
        let mut reach = max_radius * max_radius;
        self.gather(0, self.photons.len(), p, n, k, &mut reach, &mut nearest);
        if nearest.is_empty() {
            return Vec3A::ZERO;
        }
        // With k found, the disc reaches the farthest of them; with fewer, the whole search disc.
        let r2 = if nearest.len() == k { nearest.peek().map_or(reach, |n: &Near| n.distance2) } else { reach };
        let power = nearest.iter().fold(Vec3A::ZERO, |sum, near| sum + self.photons[near.index].power);
        power / (std::f32::consts::PI * r2.max(1e-12))
    }

    #[allow(clippy::too_many_arguments)]
    fn gather(
        &self,
        lo: usize,
        hi: usize,
        p: Vec3A,
        n: Vec3A,
        k: usize,
        reach: &mut f32,
        nearest: &mut BinaryHeap<Near>,
    ) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        // No photon of the subtree is nearer than its box: a photon is taken only nearer than
        // `reach`. (`length_squared` of the gaps, each at most the photon's own distance along its
        // axis, rounds no larger than the photon's distance does.)
        if let Some(&[min, max]) = self.bounds.get(mid) {
            let gap = (min - p).max(p - max).max(Vec3A::ZERO);
            if gap.length_squared() >= *reach {
                return;
            }
        }
        let photon = &self.photons[mid];
        let axis = self.axes[mid] as usize;
        let delta = p[axis] - photon.p[axis];
        let (near_side, far_side) = if delta < 0.0 { ((lo, mid), (mid + 1, hi)) } else { ((mid + 1, hi), (lo, mid)) };
        self.gather(near_side.0, near_side.1, p, n, k, reach, nearest);
        let d2 = (photon.p - p).length_squared();
        if d2 < *reach && (n == Vec3A::ZERO || n.dot(photon.direction) < 0.0) {
            nearest.push(Near { distance2: d2, index: mid });
            if nearest.len() > k {
                nearest.pop();
            }
            if nearest.len() == k {
                *reach = nearest.peek().map_or(*reach, |n| n.distance2);
            }
        }
        if delta * delta < *reach {
            self.gather(far_side.0, far_side.1, p, n, k, reach, nearest);
        }
    }
}

/// Writes the box of the photons of subtree `[lo, hi)` at its splitting photon's index in
/// `bounds`, and those of its subtrees, and returns it (empty, min above max, for no photons).
/// The tree is balanced by its index ranges, whatever order the photons are in: the recursion is
/// as deep as the map's size has bits.
fn subtree_bounds(photons: &[Photon], bounds: &mut [[Vec3A; 2]], lo: usize, hi: usize) -> [Vec3A; 2] {
    if lo >= hi {
        return [Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)];
    }
    let mid = (lo + hi) / 2;
    let [lmin, lmax] = subtree_bounds(photons, bounds, lo, mid);
    let [rmin, rmax] = subtree_bounds(photons, bounds, mid + 1, hi);
    let p = photons[mid].p;
    let b = [p.min(lmin).min(rmin), p.max(lmax).max(rmax)];
    bounds[mid] = b;
    b
}

/// Orders `photons` into the implicit tree, splitting each subtree at its median along its widest
/// axis.
fn build(photons: &mut [Photon], axes: &mut [u8], depth: u32) {
    if photons.len() <= 1 || depth > 64 {
        return;
    }
    let (lo, hi) = photons
        .iter()
        .fold((Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)), |(lo, hi), p| (lo.min(p.p), hi.max(p.p)));
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = photons.len() / 2;
    photons.select_nth_unstable_by(mid, |a, b| a.p[axis].total_cmp(&b.p[axis]));
    axes[mid] = axis as u8;
    let (left, right) = photons.split_at_mut(mid);
    let (left_axes, right_axes) = axes.split_at_mut(mid);
    build(left, left_axes, depth + 1);
    build(&mut right[1..], &mut right_axes[1..], depth + 1);
}

/// A photon found, by its squared distance (the heap keeps the farthest on top).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Near {
    distance2: f32,
    index: usize,
}

impl Eq for Near {}

impl PartialOrd for Near {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Near {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.distance2.total_cmp(&other.distance2).then(self.index.cmp(&other.index))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_photons(n: usize) -> Vec<Photon> {
        // A square grid of photons on the plane y = 0, each of power 1, arriving from above.
        (0..n * n)
            .map(|i| Photon {
                p: Vec3A::new((i % n) as f32 / n as f32, 0.0, (i / n) as f32 / n as f32),
                power: Vec3A::ONE,
                direction: -Vec3A::Y,
            })
            .collect()
    }

    #[test]
    fn the_estimate_is_the_density_of_power() {
        // n^2 photons of power 1 on the unit square: irradiance n^2 in the middle.
        let map = PhotonMap::new(grid_photons(100));
        let e = map.irradiance(Vec3A::new(0.5, 0.0, 0.5), Vec3A::Y, 200, 1.0);
        assert!((e.x / 10_000.0 - 1.0).abs() < 0.1, "{e}");
        // Photons arriving at the other side do not count.
        assert_eq!(map.irradiance(Vec3A::new(0.5, 0.0, 0.5), -Vec3A::Y, 200, 1.0), Vec3A::ZERO);
        // Nothing within reach: black.
        assert_eq!(map.irradiance(Vec3A::new(5.0, 0.0, 5.0), Vec3A::Y, 10, 0.5), Vec3A::ZERO);
    }

    #[test]
    fn the_tree_finds_the_same_neighbours_as_a_scan() {
        let mut photons = grid_photons(37);
        for (i, p) in photons.iter_mut().enumerate() {
            p.p.y = ((i * 7919) % 101) as f32 / 300.0;
            p.power = Vec3A::splat(1.0 + (i % 5) as f32);
        }
        let map = PhotonMap::new(photons.clone());
        for q in [Vec3A::new(0.3, 0.1, 0.7), Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(0.9, 0.3, 0.2)] {
            let k = 25;
            let mut by_distance: Vec<&Photon> = photons.iter().collect();
            by_distance.sort_by(|a, b| (a.p - q).length_squared().total_cmp(&(b.p - q).length_squared()));
            let r2 = (by_distance[k - 1].p - q).length_squared();
            let power = by_distance[..k].iter().fold(Vec3A::ZERO, |s, p| s + p.power);
            let want = power / (std::f32::consts::PI * r2);
            let got = map.irradiance(q, Vec3A::Y, k, 10.0);
            assert!((got - want).abs().max_element() < 1e-3 * want.max_element(), "{q}: {got} against {want}");
        }
    }
}

//! Grouping: the hits waiting to be shaded sorted by (material, instance), and shaded a group of
//! one material and instance at a time, a packet at most each (through the frame's stages:
//! `shade::shade_group`). Each hit's key is found once; a packet's few distinct keys are bucketed
//! rather than sorted, and the hits moved once, by the sorted keys.
//!
//! Invariant: the order is that of a stable sort by key, so that groups, and the images, do not
//! depend on how the hits arrived beyond their order.

use super::jobs::JobRows;
use super::work::{Frame, Pending, Shaded};
use super::world::World;
use crate::ray::Hit;
use std::cell::RefCell;

/// Sorts `pending` by (material, instance) and shades it in groups of one material and instance,
/// a packet at most each: `out[i]` is what the sorted `pending[i]` produced.
pub(super) fn shade_in_groups(frame: &Frame, pending: &mut [Pending], depth: u32, out: &mut [Shaded]) {
    let world = frame.world;
    // Each key once: finding a hit's material reads its instance's per-primitive table, a cache
    // miss, which comparisons would repeat.
    let mut keys = take_keys();
    keys.extend(pending.iter().enumerate().map(|(i, p)| (group_key(world, &p.hit), i as u32)));
    // Coherent rays mostly arrive in order already; sorting moves whole jobs, so it sorts their
    // keys and then moves each job once.
    if sort_stably(&mut keys) {
        permute(pending, &mut keys);
    }
    shade_sorted_groups(frame, pending, &keys, depth, out);
    give_keys(keys);
}

/// The (material, instance) key a hit is grouped by.
#[inline(always)]
pub(super) fn group_key(world: &World, hit: &Hit) -> (u32, u32) {
    let inst = world.instances.get(hit.instance as usize);
    (inst.map_or(0, |i| i.material_at(hit.primitive)), hit.instance)
}

/// Puts `keys` (each index once) in the order of a stable sort by key (the index breaks ties);
/// `false` when they were in that order already.
pub(super) fn sort_stably(keys: &mut Vec<GroupKey>) -> bool {
    if keys.is_sorted() {
        return false;
    }
    let mut spare = take_keys();
    sort_group_keys(keys, &mut spare);
    give_keys(spare);
    true
}

/// Shades `pending`, already in the order of `keys` (its jobs' keys, sorted), in groups of one
/// key, a packet at most each: `out[i]` is what `pending[i]` produced.
pub(super) fn shade_sorted_groups(
    frame: &Frame,
    pending: &[Pending],
    keys: &[GroupKey],
    depth: u32,
    out: &mut [Shaded],
) {
    debug_assert_eq!(pending.len(), keys.len());
    let len = pending.len().min(keys.len()).min(out.len());
    let mut jobs = super::scratch::take(&GROUP_JOBS);
    let mut start = 0;
    while start < len {
        let k = keys[start].0;
        jobs.clear();
        let mut end = start;
        while end < len && keys[end].0 == k && jobs.push(&pending[end], pending[end].budget) {
            end += 1;
        }
        jobs.finish();
        (frame.stages.shade_group)(frame, &jobs.rows(), depth, &mut out[start..end]);
        start = end;
    }
    super::scratch::give(&GROUP_JOBS, jobs);
}

thread_local! {
    /// Groups' hits by rows (`shade_sorted_groups`).
    static GROUP_JOBS: RefCell<Vec<Box<JobRows>>> = const { RefCell::new(Vec::new()) };
}

/// A buffer of group keys from this thread's stack of them; hand it back with [`give_keys`].
pub(super) fn take_keys() -> Vec<GroupKey> {
    let mut keys = super::scratch::take(&GROUP_KEYS);
    keys.clear();
    keys
}

pub(super) fn give_keys(keys: Vec<GroupKey>) {
    super::scratch::give(&GROUP_KEYS, keys);
}

/// Puts `items[order[i].1]` at `i`, for every `i` (`order` a permutation of the indices, its
/// indices changed on the way).
fn permute<K, T>(items: &mut [T], order: &mut [(K, u32)]) {
    for i in 0..items.len().min(order.len()) {
        // Where the item that belongs at `i` is now: earlier swaps moved it from `order[i].1`
        // along the chain of places they put things.
        let mut from = order[i].1 as usize;
        while from < i {
            from = order[from].1 as usize;
        }
        order[i].1 = from as u32;
        items.swap(i, from);
    }
}

/// A job's (material, instance) and its index among the jobs.
pub(super) type GroupKey = ((u32, u32), u32);

/// The most distinct keys [`sort_group_keys`] buckets; with more it sorts.
const MAX_BUCKETED_KEYS: usize = 8;

/// Sorts `keys` (each index once) as `sort_unstable` would, `spare` a buffer to use. A packet's
/// hits mostly have one to three distinct (material, instance) keys, so they are bucketed by key
/// in two passes, cheaper than a comparison sort of the 64.
fn sort_group_keys(keys: &mut Vec<GroupKey>, spare: &mut Vec<GroupKey>) {
    let mut distinct = [(0u32, 0u32); MAX_BUCKETED_KEYS];
    let mut count = 0;
    for (k, _) in keys.iter() {
        if distinct[..count].contains(k) {
            continue;
        }
        if count == MAX_BUCKETED_KEYS {
            keys.sort_unstable();
            return;
        }
        distinct[count] = *k;
        count += 1;
    }
    let distinct = &mut distinct[..count];
    distinct.sort_unstable();
    let bucket = |k: &(u32, u32)| distinct.iter().position(|d| d == k).unwrap_or(0);
    // Where each bucket starts: the sizes of the buckets before it.
    let mut starts = [0usize; MAX_BUCKETED_KEYS + 1];
    for (k, _) in keys.iter() {
        starts[bucket(k) + 1] += 1;
    }
    for b in 1..=MAX_BUCKETED_KEYS {
        starts[b] += starts[b - 1];
    }
    // Scattered in index order, the indices ascend within each bucket.
    spare.clear();
    spare.resize(keys.len(), ((0, 0), 0));
    for key in keys.iter() {
        let b = bucket(&key.0);
        spare[starts[b]] = *key;
        starts[b] += 1;
    }
    std::mem::swap(keys, spare);
}

thread_local! {
    /// The (material, instance) keys of the jobs `shade_in_groups` sorts, with their indices.
    static GROUP_KEYS: RefCell<Vec<Vec<GroupKey>>> = const { RefCell::new(Vec::new()) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::mix;

    #[test]
    fn group_keys_bucket_into_the_order_of_a_sort() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n) as u32
        };
        let mut spare = Vec::new();
        for distinct in [1u64, 2, 3, 8, 9, 40] {
            for len in [1usize, 2, 17, 64, 150] {
                let mut keys: Vec<GroupKey> =
                    (0..len).map(|i| ((next(distinct) * 7, next(2) * distinct as u32), i as u32)).collect();
                let mut sorted = keys.clone();
                sorted.sort_unstable();
                sort_group_keys(&mut keys, &mut spare);
                assert_eq!(keys, sorted, "{distinct} distinct keys, {len} hits");
            }
        }
    }

    /// The hit geometry works out `dPdu`, `dPdv` and the normal's derivatives only for shaders that
    /// read them: a shader that does gets them (not zero, on a quad whose normals vary).
    #[test]
    fn permuting_by_sorted_keys_orders_the_items_as_a_stable_sort() {
        let mut state = 7u64;
        for n in [0usize, 1, 2, 5, 64, 200] {
            // Few distinct keys, so ties are common and the order among them shows.
            let keys: Vec<u32> = (0..n)
                .map(|_| {
                    state = mix(state);
                    (state % 5) as u32
                })
                .collect();
            let mut items: Vec<(u32, usize)> = keys.iter().copied().zip(0..).collect();
            let mut expected = items.clone();
            expected.sort_by_key(|&(k, _)| k);
            let mut order: Vec<(u32, u32)> = keys.iter().copied().zip(0..).collect();
            order.sort_unstable();
            permute(&mut items, &mut order);
            assert_eq!(items, expected, "{n} items");
        }
    }
}

//! An object's BVH in parts: a small tree over the top of the object's BVH whose leaves are
//! **parts**, subtrees of at most [`PART_TRIANGLES`] triangles, each an object BVH of its own
//! (`object::Parts`; this module cuts the 4-wide trees).
//! A distributed worker fetches an object's mesh and small tree first and a part when a ray first
//! reaches it (the paper's demand loading, in units finer than the object), so that the parts of
//! a large object that no ray of the worker reaches never travel. A single process keeps whole
//! trees.
//!
//! Invariants:
//! - The small tree is the whole tree's 4-wide nodes above the cut, in pre-order, with the same
//!   boxes; a child that is cut off is a leaf reference `leaf_ref(p, 1)` naming part `p`
//!   (`prim_order` is `0..parts`). A part is the whole tree's subtree under that child, its nodes
//!   in pre-order and its leaves blocks, with the leaf order naming the **mesh's** triangles (no
//!   triangle is renumbered, no mesh is copied).
//! - A part's root is a leaf of the whole tree or a 4-wide node that heads an 8-wide node
//!   ([`Bvh8::heads`]). So the small tree's and the parts' 8-wide forms are exactly the whole
//!   tree's 8-wide nodes, and a single ray visits the same nodes in the same order in parts as
//!   whole: a part is finished before traversal returns above it, as the whole tree's stack
//!   finishes a subtree before it pops the subtree's siblings. Packets, which read the 4-wide
//!   nodes, likewise. Hits are therefore the same, ties included. (A part that is one leaf adds a
//!   test of that leaf's box, which cannot cull a hit the leaf would give: box tests are
//!   conservative.)

use super::bvh4::{leaf_range, leaf_ref, Bvh4, Node4, EMPTY_CHILD, LEAF_BIT};
use super::bvh8::Bvh8;
use crate::geometry::triangle::BLOCK_WIDTH;
use glam::Vec3A;

/// The most triangles in one part.
pub const PART_TRIANGLES: u32 = 1 << 14;

/// Objects of more triangles than this travel in parts; smaller ones whole.
pub const PARTED_ABOVE: usize = 1 << 16;

/// A box's corners.
pub type Bounds = (Vec3A, Vec3A);

/// A 4-wide object BVH cut into a small tree and parts (4-wide trees, leaves blocks).
#[derive(Clone, Debug, Default)]
pub struct Cut {
    pub small: Bvh4,
    pub parts: Vec<CutPart>,
}

/// A part of a [`Cut`].
#[derive(Clone, Debug, Default)]
pub struct CutPart {
    pub bvh: Bvh4,
    pub triangles: u32,
}

impl CutPart {
    /// The part's box.
    pub fn bounds(&self) -> Bounds {
        self.bvh.bounds.unwrap_or((Vec3A::INFINITY, Vec3A::NEG_INFINITY))
    }
}

/// Cuts `whole`, an object BVH whose leaves are blocks, into parts of at most `part_triangles`
/// triangles (or one leaf, or one 8-wide head's subtree where no smaller cut keeps the 8-wide
/// nodes: see the module documentation). The root is never a part.
pub fn cut(whole: &Bvh4, part_triangles: u32) -> Cut {
    if whole.nodes.is_empty() {
        return Cut::default();
    }
    let heads = Bvh8::heads(whole);
    // Triangles under each node; children follow their parents (pre-order).
    let mut under = vec![0u32; whole.nodes.len()];
    for i in (0..whole.nodes.len()).rev() {
        under[i] = whole.nodes[i]
            .child
            .iter()
            .filter(|&&r| r != EMPTY_CHILD)
            .map(|&r| if r & LEAF_BIT != 0 { leaf_range(r).1 } else { under[r as usize] })
            .sum();
    }
    let mut cutter = Cutter { whole, heads, under, limit: part_triangles, small: Vec::new(), parts: Vec::new() };
    let depth = cutter.visit(0, 1);
    let parts = cutter.parts.len() as u32;
    let small = Bvh4 { nodes: cutter.small, prim_order: (0..parts).collect(), bounds: whole.bounds, depth };
    Cut { small, parts: cutter.parts }
}

struct Cutter<'a> {
    whole: &'a Bvh4,
    heads: Vec<bool>,
    under: Vec<u32>,
    limit: u32,
    small: Vec<Node4>,
    parts: Vec<CutPart>,
}

impl Cutter<'_> {
    /// Copies node `i` (at level `level`) into the small tree, cutting off its children that are
    /// parts; returns the depth of its subtree in the small tree.
    fn visit(&mut self, i: usize, level: usize) -> usize {
        let at = self.small.len();
        self.small.push(self.whole.nodes[i]);
        let mut depth = level;
        for k in 0..4 {
            let r = self.whole.nodes[i].child[k];
            if r == EMPTY_CHILD {
                continue;
            }
            let is_part = r & LEAF_BIT != 0 || (self.under[r as usize] <= self.limit && self.heads[r as usize]);
            let reference = if is_part {
                let p = self.parts.len() as u32;
                let part = self.part(i, k);
                self.parts.push(part);
                leaf_ref(p, 1)
            } else {
                let child = self.small.len() as u32;
                depth = depth.max(self.visit(r as usize, level + 1));
                child
            };
            self.small[at].child[k] = reference;
        }
        depth
    }

    /// The part under child `k` of node `i`.
    fn part(&self, i: usize, k: usize) -> CutPart {
        let parent = &self.whole.nodes[i];
        let r = parent.child[k];
        let bounds = (
            Vec3A::new(parent.min_x[k], parent.min_y[k], parent.min_z[k]),
            Vec3A::new(parent.max_x[k], parent.max_y[k], parent.max_z[k]),
        );
        let mut bvh = Bvh4 { bounds: Some(bounds), ..Bvh4::default() };
        if r & LEAF_BIT != 0 {
            // A leaf alone: a root of one child, the leaf's box.
            let mut root = Node4::default();
            for (row, v) in [
                (&mut root.min_x, bounds.0.x),
                (&mut root.min_y, bounds.0.y),
                (&mut root.min_z, bounds.0.z),
                (&mut root.max_x, bounds.1.x),
                (&mut root.max_y, bounds.1.y),
                (&mut root.max_z, bounds.1.z),
            ] {
                row[0] = v;
            }
            let (block, count) = leaf_range(r);
            root.child[0] = leaf_ref(0, count);
            bvh.nodes.push(root);
            bvh.prim_order.extend_from_slice(self.block(block));
            bvh.depth = 1;
            return CutPart { bvh, triangles: count };
        }
        bvh.depth = self.copy(r as usize, &mut bvh, 1);
        CutPart { bvh, triangles: self.under[r as usize] }
    }

    /// The leaf slots of block `b` of the whole tree.
    fn block(&self, b: u32) -> &[u32] {
        &self.whole.prim_order[BLOCK_WIDTH * b as usize..BLOCK_WIDTH * (b as usize + 1)]
    }

    /// Copies the subtree of node `i` into `out` in pre-order, its blocks renumbered in the order
    /// met; returns its depth.
    fn copy(&self, i: usize, out: &mut Bvh4, level: usize) -> usize {
        let at = out.nodes.len();
        out.nodes.push(self.whole.nodes[i]);
        let mut depth = level;
        for k in 0..4 {
            let r = self.whole.nodes[i].child[k];
            if r == EMPTY_CHILD {
                continue;
            }
            let reference = if r & LEAF_BIT != 0 {
                let (block, count) = leaf_range(r);
                let renumbered = (out.prim_order.len() / BLOCK_WIDTH) as u32;
                out.prim_order.extend_from_slice(self.block(block));
                leaf_ref(renumbered, count)
            } else {
                let child = out.nodes.len() as u32;
                depth = depth.max(self.copy(r as usize, out, level + 1));
                child
            };
            out.nodes[at].child[k] = reference;
        }
        depth
    }
}

/// The whole tree that [`cut`] cut into `small` and `parts` (part `p` the tree of `parts[p]`),
/// with the parts in the order their blocks take in it (each part's blocks follow the last's):
/// the inverse of [`cut`], node for node and slot for slot. `None` if the small tree names a part
/// not given.
pub fn join(small: &Bvh4, parts: &[&Bvh4]) -> Option<(Bvh4, Vec<u32>)> {
    if small.nodes.is_empty() {
        return Some((Bvh4::default(), Vec::new()));
    }
    let mut joiner = Joiner { small, parts, out: Bvh4 { bounds: small.bounds, ..Bvh4::default() }, order: Vec::new() };
    joiner.out.depth = joiner.visit(0, 1)?;
    Some((joiner.out, joiner.order))
}

struct Joiner<'a> {
    small: &'a Bvh4,
    parts: &'a [&'a Bvh4],
    out: Bvh4,
    /// The parts in the order met.
    order: Vec<u32>,
}

impl Joiner<'_> {
    /// Copies small node `i` (at level `level`) into the whole tree, its parts put back under it
    /// (as [`Cutter::visit`] took them out); returns the depth of its subtree.
    fn visit(&mut self, i: usize, level: usize) -> Option<usize> {
        let at = self.out.nodes.len();
        let node = *self.small.nodes.get(i)?;
        self.out.nodes.push(node);
        let mut depth = level;
        for k in 0..4 {
            let r = node.child[k];
            if r == EMPTY_CHILD {
                continue;
            }
            let reference = if r & LEAF_BIT != 0 {
                let p = leaf_range(r).0;
                let part = *self.parts.get(p as usize)?;
                self.order.push(p);
                let (reference, part_depth) = self.put_back(part)?;
                depth = depth.max(level + part_depth);
                reference
            } else {
                let child = self.out.nodes.len() as u32;
                depth = depth.max(self.visit(r as usize, level + 1)?);
                child
            };
            self.out.nodes[at].child[k] = reference;
        }
        Some(depth)
    }

    /// Appends `part` (its nodes in pre-order, its blocks in the order met, as [`Cutter::copy`]
    /// made them) to the whole tree: returns the reference its parent takes and the levels it
    /// adds below the parent.
    fn put_back(&mut self, part: &Bvh4) -> Option<(u32, usize)> {
        let block_base = (self.out.prim_order.len() / BLOCK_WIDTH) as u32;
        let root = part.nodes.first()?;
        if part.nodes.len() == 1 && root.child[0] & LEAF_BIT != 0 && root.child[1..].iter().all(|&c| c == EMPTY_CHILD) {
            // A leaf alone ([`Cutter::part`]): the parent takes the leaf, not the root around it.
            let (block, count) = leaf_range(root.child[0]);
            let slots = part.prim_order.get(BLOCK_WIDTH * block as usize..BLOCK_WIDTH * (block as usize + 1))?;
            self.out.prim_order.extend_from_slice(slots);
            return Some((leaf_ref(block_base, count), 0));
        }
        let node_base = self.out.nodes.len() as u32;
        for node in &part.nodes {
            let mut node = *node;
            for r in node.child.iter_mut().filter(|r| **r != EMPTY_CHILD) {
                *r = if *r & LEAF_BIT != 0 {
                    let (block, count) = leaf_range(*r);
                    leaf_ref(block_base + block, count)
                } else {
                    node_base + *r
                };
            }
            self.out.nodes.push(node);
        }
        self.out.prim_order.extend_from_slice(&part.prim_order);
        Some((node_base, part.depth))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh4::BuildQuality;
    use crate::accel::object::{Object, ObjectBvh, NO_TRIANGLE};
    use crate::geometry::Deformation;
    use crate::geometry::Mesh;
    use crate::ray::{Hit, HitPacket, Ray, RayPacket, INVALID_ID};
    use crate::scene::Scene;
    use glam::Affine3A;
    use std::sync::Arc;

    /// A crumpled sheet of `n` pseudo-random triangles.
    pub(crate) fn scattered(n: u32) -> Mesh {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut positions = Vec::new();
        for _ in 0..n {
            let c = glam::Vec3::new(next() * 10.0, next() * 10.0, next() * 10.0);
            for _ in 0..3 {
                positions.push(c + glam::Vec3::new(next(), next(), next()) * 0.6);
            }
        }
        Mesh::from_triangles(positions, (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect()).expect("a mesh")
    }

    /// A scene of `mesh` twice (one instance turned and moved), its object a whole tree or in
    /// parts of at most `limit` triangles.
    fn scene(mesh: &Arc<Mesh>, limit: Option<u32>) -> Scene {
        let mut scene = Scene::new();
        let id = scene.add_object(mesh.clone());
        if let Some(limit) = limit {
            let whole = scene.objects()[0].data().bvh.clone();
            scene.objects_mut()[0] = Object::with_bvh(mesh.clone(), Arc::new(whole.in_parts(mesh, limit)));
        }
        scene.add_instance(id, Affine3A::IDENTITY).expect("an instance");
        let turned =
            Affine3A::from_rotation_translation(glam::Quat::from_rotation_y(0.7), glam::Vec3::new(3.0, 1.0, -2.0));
        scene.add_instance(id, turned).expect("an instance");
        scene.commit();
        scene
    }

    fn same(a: Hit, b: Hit) -> bool {
        (a.t.to_bits(), a.u.to_bits(), a.v.to_bits(), a.instance, a.primitive)
            == (b.t.to_bits(), b.u.to_bits(), b.v.to_bits(), b.instance, b.primitive)
    }

    /// Every answer of a BVH in parts is the whole tree's, to the bit: closest hits and occlusion,
    /// single rays and packets (coherent and not), standing and deforming meshes.
    #[test]
    fn parts_answer_every_ray_as_the_whole_tree_does() {
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 40) as f32 / (1u64 << 24) as f32
        };
        let standing = scattered(3000);
        let mut deforming = standing.clone();
        let close = deforming.positions.iter().map(|p| *p + glam::Vec3::new(0.3, -0.2, 0.1)).collect();
        deforming.deformation = Some(Deformation { positions: close, normals: None, open: 0.0, close: 1.0 });
        for mesh in [standing, deforming] {
            let mesh = Arc::new(mesh);
            let whole = scene(&mesh, None);
            for limit in [64, 700] {
                let parted = scene(&mesh, Some(limit));
                let (mut hits, mut blocked) = (0, 0);
                for round in 0..100 {
                    // A bundle from one point towards a small window (coherent), or rays from
                    // anywhere to anywhere (not).
                    let coherent = round % 2 == 0;
                    let eye = Vec3A::new(next() * 30.0 - 10.0, next() * 30.0 - 10.0, next() * 30.0 - 10.0);
                    let aim = Vec3A::new(next() * 10.0, next() * 10.0, next() * 10.0);
                    let mut packet = RayPacket::new();
                    for i in 0..64 {
                        let (o, target) = if coherent {
                            let offset = Vec3A::new((i % 8) as f32, (i / 8) as f32, 0.0) * 0.15;
                            (eye, aim + offset)
                        } else {
                            let o = Vec3A::new(next() * 12.0 - 1.0, next() * 12.0 - 1.0, next() * 12.0 - 1.0);
                            (o, Vec3A::new(next() * 10.0, next() * 10.0, next() * 10.0))
                        };
                        let mut ray = Ray::new(o, target - o);
                        ray.time = next();
                        if i % 3 == 0 {
                            ray.tmax = 0.5 + next();
                        }
                        packet.set(i, &ray);
                        let (a, b) = (whole.intersect(&ray), parted.intersect(&ray));
                        assert!(same(a, b), "limit {limit}, round {round}, ray {i}: {a:?} against {b:?}");
                        if i % 16 == 0 {
                            // The reference reads the parts too (ties at equal t may differ).
                            assert_eq!(parted.intersect_brute_force(&ray, None).t, a.t);
                        }
                        assert_eq!(
                            whole.occluded(&ray),
                            parted.occluded(&ray),
                            "limit {limit}, round {round}, ray {i}"
                        );
                        hits += (a.instance != INVALID_ID) as u32;
                    }
                    let (mut a, mut b) = (HitPacket::default(), HitPacket::default());
                    whole.intersect_packet(&packet, &mut a);
                    parted.intersect_packet(&packet, &mut b);
                    for i in 0..64 {
                        assert!(
                            same(a.get(i), b.get(i)),
                            "limit {limit}, round {round}, lane {i}: {:?} against {:?}",
                            a.get(i),
                            b.get(i)
                        );
                    }
                    let occluded = whole.occluded_packet(&packet);
                    assert_eq!(occluded, parted.occluded_packet(&packet), "limit {limit}, round {round}");
                    blocked += occluded.count_ones();
                }
                // The rays hit and miss, are blocked and pass.
                assert!(hits > 1000 && hits < 6000 && blocked > 700 && blocked < 6000, "{hits} {blocked}");
            }
        }
    }

    /// A worker keeps a small tree across scenes only for the same mesh under a tree of the same
    /// shape: the summary's digest tells trees of other build qualities apart.
    #[test]
    fn a_summary_tells_trees_of_other_shapes_apart() {
        use crate::accel::object::MeshSummary;
        let mesh = scattered(3000);
        let digest = |quality| MeshSummary::of_tree(&mesh, &ObjectBvh::build(&mesh, quality).bvh).digest;
        assert_eq!(digest(BuildQuality::High), digest(BuildQuality::High));
        assert_ne!(digest(BuildQuality::High), digest(BuildQuality::Fast));
        assert_ne!(digest(BuildQuality::High), MeshSummary::of(&mesh, None).digest);
    }

    /// Joined, the parts give back the tree they were cut from, node for node and slot for slot,
    /// with its prepared triangles (at both ends of a deformation) and its 8-wide nodes; a BVH in
    /// parts with a part missing stays in parts.
    #[test]
    fn joined_parts_are_the_whole_tree_they_were_cut_from() {
        let standing = scattered(3000);
        let mut deforming = standing.clone();
        let close = deforming.positions.iter().map(|p| *p + glam::Vec3::new(0.3, -0.2, 0.1)).collect();
        deforming.deformation = Some(Deformation { positions: close, normals: None, open: 0.0, close: 1.0 });
        for mesh in [standing, deforming] {
            let whole = ObjectBvh::build(&mesh, BuildQuality::High);
            for limit in [1, 16, 64, 500, 5000] {
                let parted = whole.in_parts(&mesh, limit);
                let held = parted.parts.as_ref().expect("parts").parts.len();
                assert!(held > 1, "limit {limit}: {held} parts");
                let joined = parted.joined().expect("every part is here");
                assert!(joined.parts.is_none());
                assert_eq!(joined.bvh.nodes, whole.bvh.nodes, "limit {limit}");
                assert_eq!(joined.bvh.prim_order, whole.bvh.prim_order, "limit {limit}");
                assert_eq!(joined.bvh.depth, whole.bvh.depth, "limit {limit}");
                assert_eq!(joined.bvh.bounds, whole.bvh.bounds, "limit {limit}");
                assert_eq!(joined.blocks, whole.blocks, "limit {limit}");
                assert_eq!(joined.wide.nodes, whole.wide.nodes, "limit {limit}");
                let close = |b: &ObjectBvh| b.deformed.as_ref().map(|d| (d.close.clone(), d.open_time, d.close_time));
                assert_eq!(close(&joined), close(&whole), "limit {limit}");

                let mut missing = parted.clone();
                if let Some(parts) = missing.parts.as_deref_mut() {
                    parts.parts[held / 2].bvh = std::sync::OnceLock::new();
                }
                assert!(missing.joined().is_none(), "limit {limit}: a part is missing");
            }
        }
    }

    #[test]
    fn parts_hold_every_triangle_once_under_their_boxes_and_the_8_wide_nodes_of_the_whole() {
        let mesh = scattered(3000);
        let whole = ObjectBvh::build(&mesh, BuildQuality::High);
        for limit in [1, 16, 64, 500, 5000] {
            let Cut { small, parts } = cut(&whole.bvh, limit);
            assert_eq!(small.prim_order.len(), parts.len());
            let mut seen = vec![0u32; 3000];
            for p in &parts {
                let tris: Vec<u32> = p.bvh.prim_order.iter().copied().filter(|&t| t != NO_TRIANGLE).collect();
                assert_eq!(tris.len() as u32, p.triangles);
                // A part is a leaf or no bigger than the limit, unless no head below fits.
                assert!(p.triangles <= limit.max(4) || p.bvh.nodes.len() > 1);
                for t in tris {
                    seen[t as usize] += 1;
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "limit {limit}: every triangle in one part");
            // The small tree's and the parts' 8-wide nodes are the whole tree's: as many, and the
            // same boxes in the same order.
            let wide = Bvh8::from_bvh4(&small);
            let part_nodes: usize = parts.iter().map(|p| Bvh8::from_bvh4(&p.bvh).nodes.len()).sum();
            let leaf_parts = parts
                .iter()
                .filter(|p| p.bvh.nodes.len() == 1 && p.bvh.nodes[0].child[1..].iter().all(|&c| c == EMPTY_CHILD))
                .count();
            assert_eq!(wide.nodes.len() + part_nodes - leaf_parts, whole.wide.nodes.len(), "limit {limit}");
            assert_eq!(wide.nodes[0].min_x, whole.wide.nodes[0].min_x, "limit {limit}");
        }
    }
}

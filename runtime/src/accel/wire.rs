//! An object's 4-wide BVH as it travels between processes: a distributed master sends the BVH it
//! built with each mesh a worker fetches, so that the worker does not build it again (it still
//! prepares the triangles and the 8-wide form, which take a fraction of the build).
//!
//! Layout: the node count and the leaf-slot count (`u32` each), then each node's six box rows,
//! four child references and shape code (29 little-endian 32-bit values), then the leaf order
//! (`u32` each). A shape code that does not fit its node is not an error: the 8-wide conversion
//! then takes the node's children as they are. The
//! leaves are blocks, as in [`ObjectBvh`](super::object::ObjectBvh): a leaf reference names its
//! block, and the leaf order has four slots a block, the unused ones [`NO_TRIANGLE`].
//!
//! A large object travels in parts ([`super::parts`]): its small tree ([`encode_small_tree`]:
//! the tree as above, its leaf order the parts `0..n`, then each part's triangle count) with the
//! mesh, then each part a ray reaches as a tree of its own whose leaf order names the mesh's
//! triangles ([`decode_part`]).
//!
//! Decoding checks the tree against the mesh it is for, so that damaged bytes are an error and
//! never a traversal out of bounds, a loop, or a triangle no ray can reach: every inner reference
//! points past its parent (pre-order) and is reached once, every block lies in one leaf, which
//! holds its used slots and no other, the leaf order names each of the mesh's triangles once, each
//! child box contains its subtree (a leaf's triangles, at both ends of a deformation; an inner
//! node's child boxes), and the tree is at most [`MAX_WIRE_DEPTH`] levels deep (the 8-wide
//! conversion recurses over it).

use super::bvh4::{leaf_range, Bvh4, Node4, EMPTY_CHILD, LEAF_BIT};
use super::object::NO_TRIANGLE;
use super::parts::Bounds;
use crate::geometry::triangle::BLOCK_WIDTH;
use crate::geometry::Mesh;
use glam::{Vec3, Vec3A};

/// The deepest tree a worker accepts. Trees the builder makes from meshes of up to 2^27
/// triangles stay far shallower.
pub const MAX_WIRE_DEPTH: usize = 256;

/// The values of one node as it travels.
const NODE_VALUES: usize = 29;

/// Appends `bvh` to `out`.
pub fn encode_bvh4(bvh: &Bvh4, out: &mut Vec<u8>) {
    out.reserve(8 + 4 * NODE_VALUES * bvh.nodes.len() + 4 * bvh.prim_order.len());
    out.extend_from_slice(&(bvh.nodes.len() as u32).to_le_bytes());
    out.extend_from_slice(&(bvh.prim_order.len() as u32).to_le_bytes());
    for n in &bvh.nodes {
        for row in [n.min_x, n.max_x, n.min_y, n.max_y, n.min_z, n.max_z] {
            for v in row {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        for c in n.child {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&n.shape.to_le_bytes());
    }
    for &p in &bvh.prim_order {
        out.extend_from_slice(&p.to_le_bytes());
    }
}

/// The BVH that [`encode_bvh4`] wrote to `bytes`, for `mesh`: an error unless it is a whole tree
/// over exactly the mesh's triangles whose boxes contain them (see the module documentation).
pub fn decode_bvh4(bytes: &[u8], mesh: &Mesh) -> Result<Bvh4, String> {
    decode_tree(bytes, mesh, None)
}

/// A part of an object's BVH ([`super::parts`]) that [`encode_bvh4`] wrote: as [`decode_bvh4`],
/// but over `triangles` of the mesh's triangles (each once) rather than all of them, its boxes
/// inside `bounds`, the part's box in the small tree.
pub fn decode_part(bytes: &[u8], mesh: &Mesh, triangles: u32, bounds: Bounds) -> Result<Bvh4, String> {
    decode_tree(bytes, mesh, Some((triangles, bounds)))
}

/// The nodes and leaf order at the start of `bytes`, and the bytes they took.
fn read_nodes(bytes: &[u8]) -> Result<(Vec<Node4>, Vec<u32>, usize), String> {
    let word = |k: usize| -> Option<u32> { Some(u32::from_le_bytes(bytes.get(4 * k..4 * k + 4)?.try_into().ok()?)) };
    let (Some(node_count), Some(slot_count)) = (word(0), word(1)) else {
        return Err("a BVH shorter than its header".into());
    };
    let (node_count, slot_count) = (node_count as usize, slot_count as usize);
    let length = (node_count.checked_mul(NODE_VALUES))
        .and_then(|v| v.checked_add(slot_count))
        .and_then(|v| v.checked_add(2))
        .and_then(|v| v.checked_mul(4))
        .filter(|&length| length <= bytes.len());
    let Some(length) = length else {
        return Err(format!("a BVH of {} bytes for {node_count} nodes and {slot_count} leaf slots", bytes.len()));
    };
    let nodes: Vec<Node4> = (0..node_count)
        .map(|i| {
            let v = |k: usize| word(2 + NODE_VALUES * i + k).unwrap_or(0);
            let row = |r: usize| [0, 1, 2, 3].map(|k| f32::from_bits(v(4 * r + k)));
            Node4 {
                min_x: row(0),
                max_x: row(1),
                min_y: row(2),
                max_y: row(3),
                min_z: row(4),
                max_z: row(5),
                child: [0, 1, 2, 3].map(|k| v(24 + k)),
                shape: v(28),
            }
        })
        .collect();
    let prim_order: Vec<u32> = (0..slot_count).map(|s| word(2 + NODE_VALUES * node_count + s).unwrap_or(0)).collect();
    Ok((nodes, prim_order, length))
}

/// [`decode_bvh4`] (`part`: `None`) or [`decode_part`] (the part's triangle count and box).
fn decode_tree(bytes: &[u8], mesh: &Mesh, part: Option<(u32, Bounds)>) -> Result<Bvh4, String> {
    let (nodes, prim_order, length) = read_nodes(bytes)?;
    if length != bytes.len() {
        return Err(format!("a BVH of {} bytes where its header says {length}", bytes.len()));
    }
    let triangles = match part {
        None => mesh.triangle_count(),
        Some((triangles, _)) if triangles as usize <= mesh.triangle_count() => triangles as usize,
        Some((triangles, _)) => return Err(format!("a part of {triangles} triangles of a mesh of fewer")),
    };
    let slot_count = prim_order.len();
    // Every block holds a triangle at least.
    if slot_count % BLOCK_WIDTH != 0 || slot_count / BLOCK_WIDTH > triangles || slot_count < triangles {
        return Err(format!("a BVH of {slot_count} leaf slots for {triangles} triangles"));
    }
    if nodes.is_empty() != (triangles == 0) {
        return Err(format!("a BVH of {} nodes for {triangles} triangles", nodes.len()));
    }
    let named: Vec<u32> = prim_order.iter().copied().filter(|&p| p != NO_TRIANGLE).collect();
    match part {
        None => {
            let mut placed = vec![false; triangles];
            for &p in &named {
                match placed.get_mut(p as usize) {
                    Some(seen @ false) => *seen = true,
                    _ => return Err(format!("the BVH's leaf order names triangle {p} twice or out of range")),
                }
            }
            if let Some(t) = placed.iter().position(|&p| !p) {
                return Err(format!("the BVH's leaf order leaves out triangle {t}"));
            }
        }
        Some(_) => {
            let mut sorted = named;
            sorted.sort_unstable();
            if sorted.windows(2).any(|w| w[0] == w[1])
                || sorted.last().is_some_and(|&p| p as usize >= mesh.triangle_count())
            {
                return Err("the part's leaf order names a triangle twice or out of range".into());
            }
            if sorted.len() != triangles {
                return Err(format!("a part of {} triangles where {triangles} were announced", sorted.len()));
            }
        }
    }
    if nodes.is_empty() {
        return Ok(Bvh4::default());
    }
    let mut block_taken = vec![false; prim_order.len() / BLOCK_WIDTH];
    let depth = check_nodes(&nodes, part.map(|p| p.1), |i, block, count, child| {
        let (block, count) = (block as usize, count as usize);
        if count > BLOCK_WIDTH || block >= block_taken.len() {
            return Err(format!("BVH node {i} has a leaf of {count} in block {block} of {}", block_taken.len()));
        }
        if std::mem::replace(&mut block_taken[block], true) {
            return Err(format!("block {block} lies in two leaves of the BVH"));
        }
        let lanes = &prim_order[BLOCK_WIDTH * block..BLOCK_WIDTH * (block + 1)];
        if lanes.iter().enumerate().any(|(j, &p)| (j < count) == (p == NO_TRIANGLE)) {
            return Err(format!("block {block} of the BVH holds other slots than its leaf's {count}"));
        }
        for &t in &lanes[..count] {
            let t = t as usize;
            let [a, b, c] = mesh.corners(t);
            let close = mesh.deformation.as_ref().map(|d| mesh.triangles[t].map(|v| d.positions[v as usize]));
            if ![a, b, c].into_iter().chain(close.into_iter().flatten()).all(|p| inside(child, p)) {
                return Err(format!("triangle {t} lies outside its leaf's box in the BVH"));
            }
        }
        Ok(())
    })?;
    if let Some(b) = block_taken.iter().position(|&t| !t) {
        return Err(format!("block {b} of the BVH is in no leaf"));
    }
    Ok(Bvh4 { bounds: Some(nodes[0].children_bounds()), nodes, prim_order, depth })
}

/// Appends an object's small tree ([`super::parts`]) to `out`: the tree as [`encode_bvh4`]
/// writes it, then each part's triangle count.
pub fn encode_small_tree(small: &Bvh4, triangles: &[u32], out: &mut Vec<u8>) {
    encode_bvh4(small, out);
    for &t in triangles {
        out.extend_from_slice(&t.to_le_bytes());
    }
}

/// The small tree that [`encode_small_tree`] wrote, for `mesh`, with each part's triangle count
/// and box: an error unless it is a tree whose leaves name each part once (leaf slot `p` naming
/// part `p`), with nested boxes, and parts that share out the mesh's triangles.
pub fn decode_small_tree(bytes: &[u8], mesh: &Mesh) -> Result<(Bvh4, Vec<(u32, Bounds)>), String> {
    let (nodes, prim_order, length) = read_nodes(bytes)?;
    let parts = prim_order.len();
    if bytes.len() - length != 4 * parts {
        return Err(format!("a small tree of {parts} parts in {} bytes", bytes.len()));
    }
    if parts == 0 || nodes.is_empty() || prim_order.iter().enumerate().any(|(s, &p)| p as usize != s) {
        return Err("a small tree whose leaf order is not its parts in order".into());
    }
    let triangles: Vec<u32> =
        bytes[length..].chunks_exact(4).map(|w| u32::from_le_bytes(w.try_into().unwrap_or_default())).collect();
    let total = triangles.iter().map(|&t| t as u64).sum::<u64>();
    if triangles.contains(&0) || total != mesh.triangle_count() as u64 {
        return Err(format!("parts of {total} triangles in all for a mesh of {}", mesh.triangle_count()));
    }
    let mut boxes: Vec<Option<Bounds>> = vec![None; parts];
    let depth = check_nodes(&nodes, None, |i, part, count, child| {
        match boxes.get_mut(part as usize) {
            Some(slot @ None) if count == 1 => *slot = Some(child),
            _ => return Err(format!("small tree node {i} names part {part} again, out of range, or {count} times")),
        }
        Ok(())
    })?;
    let known: Option<Vec<(u32, Bounds)>> = triangles.into_iter().zip(boxes).map(|(t, b)| Some((t, b?))).collect();
    let known = known.ok_or("a part that no leaf of the small tree names")?;
    Ok((Bvh4 { bounds: Some(nodes[0].children_bounds()), nodes, prim_order, depth }, known))
}

/// Child `k`'s box in `node`.
fn child_box(node: &Node4, k: usize) -> Bounds {
    (Vec3A::new(node.min_x[k], node.min_y[k], node.min_z[k]), Vec3A::new(node.max_x[k], node.max_y[k], node.max_z[k]))
}

/// Whether `p` lies in the box (a `NaN` anywhere is outside).
fn inside((lo, hi): Bounds, p: Vec3) -> bool {
    let p = Vec3A::from(p);
    lo.cmple(p).all() && p.cmple(hi).all()
}

/// Checks the tree under node 0 (see the module documentation), its root's child boxes inside
/// `root_box` when given; `leaf(node, first, count, box)` checks each non-empty leaf. Returns the
/// depth in inner-node levels, as [`Bvh4::depth`] counts them.
fn check_nodes(
    nodes: &[Node4],
    root_box: Option<Bounds>,
    mut leaf: impl FnMut(usize, u32, u32, Bounds) -> Result<(), String>,
) -> Result<usize, String> {
    let mut reached = vec![false; nodes.len()];
    let mut deepest = 0;
    // Inner nodes to check: index, level (the root's is 1), and the box its parent gives it.
    let mut stack: Vec<(usize, usize, Option<Bounds>)> = vec![(0, 1, root_box)];
    while let Some((i, level, parent_box)) = stack.pop() {
        if level > MAX_WIRE_DEPTH {
            return Err(format!("the BVH is deeper than {MAX_WIRE_DEPTH} levels"));
        }
        deepest = deepest.max(level);
        reached[i] = true;
        let node = &nodes[i];
        for k in 0..4 {
            let r = node.child[k];
            let child = child_box(node, k);
            if r & LEAF_BIT == 0 {
                let j = r as usize;
                if j <= i || j >= nodes.len() || reached[j] {
                    return Err(format!("BVH node {i} refers to node {r}, which is no child of its"));
                }
                // Marked now, so that a second reference to it is refused before it is visited.
                reached[j] = true;
                stack.push((j, level + 1, Some(child)));
            } else {
                let (first, count) = leaf_range(r);
                if count == 0 {
                    continue;
                }
                leaf(i, first, count, child)?;
            }
            if let Some(parent) = parent_box {
                if r != EMPTY_CHILD && !(inside(parent, child.0.into()) && inside(parent, child.1.into())) {
                    return Err(format!("a child box of BVH node {i} reaches outside its own box"));
                }
            }
        }
    }
    if let Some(i) = reached.iter().position(|&r| !r) {
        return Err(format!("BVH node {i} is in no tree"));
    }
    Ok(deepest)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::accel::bvh4::BuildQuality;
    use crate::accel::object::ObjectBvh;

    /// A grid of `n x n` quads, two triangles each, rippled so that boxes differ.
    pub(crate) fn grid(n: u32) -> Mesh {
        let mut positions = Vec::new();
        for y in 0..=n {
            for x in 0..=n {
                positions.push(Vec3::new(x as f32, y as f32, ((x * 7 + y * 3) % 5) as f32 * 0.1));
            }
        }
        let mut triangles = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let k = y * (n + 1) + x;
                triangles.push([k, k + 1, k + n + 1]);
                triangles.push([k + 1, k + n + 2, k + n + 1]);
            }
        }
        Mesh::from_triangles(positions, triangles).expect("a grid")
    }

    #[test]
    fn a_bvh_travels_whole() {
        for n in [1, 2, 40] {
            let mesh = grid(n);
            let built = ObjectBvh::build(&mesh, BuildQuality::High).bvh;
            let mut bytes = Vec::new();
            encode_bvh4(&built, &mut bytes);
            let decoded = decode_bvh4(&bytes, &mesh).expect("a whole BVH");
            assert_eq!(decoded.nodes, built.nodes);
            assert_eq!(decoded.prim_order, built.prim_order);
            assert_eq!((decoded.depth, decoded.bounds), (built.depth, built.bounds));
        }
        let empty = Mesh::from_triangles(Vec::new(), Vec::new()).expect("an empty mesh");
        let mut bytes = Vec::new();
        encode_bvh4(&Bvh4::default(), &mut bytes);
        assert!(decode_bvh4(&bytes, &empty).expect("an empty BVH").nodes.is_empty());
    }

    #[test]
    fn an_object_travels_in_parts_and_damaged_parts_are_errors() {
        let mesh = grid(60);
        let whole = ObjectBvh::build(&mesh, BuildQuality::High);
        let cut = crate::accel::parts::cut(&whole.bvh, 500);
        assert!(cut.parts.len() > 8);
        let counts: Vec<u32> = cut.parts.iter().map(|p| p.triangles).collect();
        let mut bytes = Vec::new();
        encode_small_tree(&cut.small, &counts, &mut bytes);
        let (small, parts) = decode_small_tree(&bytes, &mesh).expect("a small tree");
        assert_eq!((small.nodes, small.prim_order), (cut.small.nodes.clone(), cut.small.prim_order.clone()));
        assert_eq!(parts.len(), cut.parts.len());
        for ((triangles, bounds), part) in parts.iter().zip(&cut.parts) {
            assert_eq!((*triangles, *bounds), (part.triangles, part.bounds()));
            let mut encoded = Vec::new();
            encode_bvh4(&part.bvh, &mut encoded);
            let decoded = decode_part(&encoded, &mesh, *triangles, *bounds).expect("a part");
            assert_eq!((decoded.nodes, decoded.prim_order), (part.bvh.nodes.clone(), part.bvh.prim_order.clone()));
            // Another count, a box that does not hold it, or another mesh.
            assert!(decode_part(&encoded, &mesh, triangles + 1, *bounds).is_err());
            assert!(decode_part(&encoded, &mesh, *triangles, (bounds.0, bounds.0)).is_err());
            assert!(decode_part(&encoded, &grid(3), *triangles, *bounds).is_err());
        }
        // A part that names a triangle twice.
        let mut encoded = Vec::new();
        encode_bvh4(&cut.parts[0].bvh, &mut encoded);
        let order = 4 * (2 + NODE_VALUES * cut.parts[0].bvh.nodes.len());
        encoded[order + 4..order + 8].copy_from_slice(&cut.parts[0].bvh.prim_order[0].to_le_bytes());
        assert!(decode_part(&encoded, &mesh, cut.parts[0].triangles, cut.parts[0].bounds()).is_err());
        // Small trees cut short, with counts that do not add up to the mesh, or a part named twice.
        for cut_at in [0, 8, bytes.len() / 2, bytes.len() - 1] {
            assert!(decode_small_tree(&bytes[..cut_at], &mesh).is_err(), "cut at {cut_at}");
        }
        assert!(decode_small_tree(&bytes, &grid(59)).is_err());
        let mut other = counts.clone();
        other[0] += 1;
        other[1] -= 1;
        let mut moved = Vec::new();
        encode_small_tree(&cut.small, &other, &mut moved);
        assert!(decode_small_tree(&moved, &mesh).is_ok(), "counts are checked in sum; each part on arrival");
        other[1] += 1;
        let mut wrong = Vec::new();
        encode_small_tree(&cut.small, &other, &mut wrong);
        assert!(decode_small_tree(&wrong, &mesh).is_err());
        let mut twice = cut.small.clone();
        let (i, k) = (0..twice.nodes.len())
            .flat_map(|i| (0..4).map(move |k| (i, k)))
            .find(|&(i, k)| twice.nodes[i].child[k] == crate::accel::bvh4::leaf_ref(1, 1))
            .expect("part 1's leaf");
        twice.nodes[i].child[k] = crate::accel::bvh4::leaf_ref(0, 1);
        let mut named_twice = Vec::new();
        encode_small_tree(&twice, &counts, &mut named_twice);
        assert!(decode_small_tree(&named_twice, &mesh).is_err());
    }

    /// Trees damaged at random either fail to decode or decode to trees that every traversal
    /// reads safely: the checks on arrival are all a traversal relies on.
    #[test]
    fn damaged_trees_that_decode_are_traversed_safely() {
        use crate::accel::object::Object;
        use crate::ray::{HitPacket, Ray, RayPacket};
        let mesh = std::sync::Arc::new(grid(24));
        let whole = ObjectBvh::build(&mesh, BuildQuality::High);
        let cut = crate::accel::parts::cut(&whole.bvh, 100);
        let counts: Vec<u32> = cut.parts.iter().map(|p| p.triangles).collect();
        let (mut whole_bytes, mut small_bytes, mut part_bytes) = (Vec::new(), Vec::new(), Vec::new());
        encode_bvh4(&whole.bvh, &mut whole_bytes);
        encode_small_tree(&cut.small, &counts, &mut small_bytes);
        encode_bvh4(&cut.parts[1].bvh, &mut part_bytes);
        let part_box = cut.parts[1].bounds();
        let mut rng = 0x853c_49e6_748f_ea9bu64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let mut decoded = [0u32; 3];
        for round in 0..1500 {
            let kind = round % 3;
            let mut bytes = [&whole_bytes, &small_bytes, &part_bytes][kind].clone();
            for _ in 0..1 + next() % 3 {
                let at = 4 * (next() as usize % (bytes.len() / 4));
                let old = u32::from_le_bytes(bytes[at..at + 4].try_into().expect("a word"));
                let value = match next() % 4 {
                    0 => next() as u32,
                    1 => old.wrapping_add(next() as u32 % 5).wrapping_sub(2),
                    2 => old ^ 1 << (next() % 32),
                    _ => (next() as f32 / u64::MAX as f32 * 30.0 - 5.0).to_bits(),
                };
                bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            }
            let bvh = match kind {
                0 => decode_bvh4(&bytes, &mesh).ok().map(|b| ObjectBvh::from_bvh4(&mesh, b)),
                1 => decode_small_tree(&bytes, &mesh).ok().map(|(small, parts)| {
                    let mut bvh = ObjectBvh::parted(&mesh, small, parts);
                    // The parts as the master cut them, here from the start.
                    if let Some(held) = bvh.parts.as_deref_mut() {
                        for (part, cut) in held.parts.iter_mut().zip(&cut.parts) {
                            part.bvh = std::sync::OnceLock::from(ObjectBvh::from_bvh4(&mesh, cut.bvh.clone()));
                        }
                    }
                    bvh
                }),
                _ => decode_part(&bytes, &mesh, counts[1], part_box).ok().map(|b| ObjectBvh::from_bvh4(&mesh, b)),
            };
            let Some(bvh) = bvh else { continue };
            decoded[kind] += 1;
            let mut scene = crate::scene::Scene::new();
            let id = scene.add_object(mesh.clone());
            scene.objects_mut()[0] = Object::with_bvh(mesh.clone(), std::sync::Arc::new(bvh));
            scene.add_instance(id, glam::Affine3A::IDENTITY).expect("an instance");
            scene.commit();
            let mut packet = RayPacket::new();
            for i in 0..64 {
                let o = glam::Vec3A::new(i as f32 * 0.37, (i * 7 % 24) as f32, 6.0);
                let ray = Ray::new(o, glam::Vec3A::new(0.1, -0.05, -1.0));
                let _ = (scene.intersect(&ray), scene.occluded(&ray));
                packet.set(i, &ray);
            }
            let mut hits = HitPacket::default();
            scene.intersect_packet(&packet, &mut hits);
            let _ = scene.occluded_packet(&packet);
        }
        // Some damage decodes (boxes grown, for one), so the traversals above did run.
        assert!(decoded.iter().all(|&n| n > 20), "{decoded:?}");
    }

    #[test]
    fn damaged_bvhs_are_errors() {
        // 882 triangles: not a whole number of blocks, so some leaf does not fill its block.
        let mesh = grid(21);
        let built = ObjectBvh::build(&mesh, BuildQuality::High).bvh;
        let mut bytes = Vec::new();
        encode_bvh4(&built, &mut bytes);
        // Cut, lengthened, or for another mesh.
        for cut in [0, 3, 8, bytes.len() / 2, bytes.len() - 1] {
            assert!(decode_bvh4(&bytes[..cut], &mesh).is_err(), "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.extend_from_slice(&[0; 4]);
        assert!(decode_bvh4(&longer, &mesh).is_err());
        assert!(decode_bvh4(&bytes, &grid(20)).is_err());
        let node = |i: usize, k: usize| 4 * (2 + NODE_VALUES * i + k);
        let damage = |at: usize, value: u32| {
            let mut damaged = bytes.clone();
            damaged[at..at + 4].copy_from_slice(&value.to_le_bytes());
            decode_bvh4(&damaged, &mesh)
        };
        let root_child = built.nodes[0].child[0];
        assert_eq!(root_child & LEAF_BIT, 0, "the root of 882 triangles has inner children");
        // A reference back to the root (a loop), past the end, or to a node already reached.
        assert!(damage(node(0, 24), 0).is_err());
        assert!(damage(node(0, 24), built.nodes.len() as u32).is_err());
        assert!(damage(node(0, 25), root_child).is_err());
        // A box that no longer holds its subtree: the root's first child box shrunk to a point.
        let min_x = built.nodes[0].max_x[0];
        assert!(damage(node(0, 0), min_x.to_bits()).is_err());
        assert!(damage(node(0, 0), f32::NAN.to_bits()).is_err());
        // A leaf order that names a triangle twice.
        let order = 4 * (2 + NODE_VALUES * built.nodes.len());
        assert!(damage(order, built.prim_order[1]).is_err());
        // A leaf slot emptied (its triangle then in no leaf), a leaf that claims its block's empty
        // lane or a block it does not own, or that does not fit a block.
        let (at, leaf) = (0..built.nodes.len())
            .flat_map(|i| (0..4).map(move |k| (i, k)))
            .map(|(i, k)| ((i, k), built.nodes[i].child[k]))
            .find(|&(_, r)| r & LEAF_BIT != 0 && (1..4).contains(&leaf_range(r).1))
            .expect("a leaf that does not fill its block");
        let (block, count) = leaf_range(leaf);
        assert!(damage(order + 16 * block as usize, NO_TRIANGLE).is_err());
        assert!(damage(node(at.0, 24 + at.1), leaf + 1).is_err());
        let other = crate::accel::bvh4::leaf_ref((block + 1) % (built.prim_order.len() / 4) as u32, count);
        assert!(damage(node(at.0, 24 + at.1), other).is_err());
        assert!(damage(node(at.0, 24 + at.1), crate::accel::bvh4::leaf_ref(block, 5)).is_err());
        // The same bytes decode again: nothing above changed them.
        assert!(decode_bvh4(&bytes, &mesh).is_ok());
    }
}

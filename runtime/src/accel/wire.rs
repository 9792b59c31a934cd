//! An object's 4-wide BVH as it travels between processes: a distributed master sends the BVH it
//! built with each mesh a worker fetches, so that the worker does not build it again (it still
//! prepares the triangles and the 8-wide form, which take a fraction of the build).
//!
//! Layout: the node count and the leaf-slot count (`u32` each), then each node's six box rows and
//! four child references (28 little-endian 32-bit values), then the leaf order (`u32` each). The
//! leaves are blocks, as in [`ObjectBvh`](super::object::ObjectBvh): a leaf reference names its
//! block, and the leaf order has four slots a block, the unused ones [`NO_TRIANGLE`].
//!
//! Decoding checks the tree against the mesh it is for, so that damaged bytes are an error and
//! never a traversal out of bounds, a loop, or a triangle no ray can reach: every inner reference
//! points past its parent (pre-order) and is reached once, every block lies in one leaf, which
//! holds its used slots and no other, the leaf order names each of the mesh's triangles once, each
//! child box contains its subtree (a leaf's triangles, at both ends of a deformation; an inner
//! node's child boxes), and the tree is at most [`MAX_WIRE_DEPTH`] levels deep (the 8-wide
//! conversion recurses over it).

use super::bvh4::{leaf_range, Bvh4, Node4, LEAF_BIT};
use super::object::NO_TRIANGLE;
use crate::geometry::triangle::BLOCK_WIDTH;
use crate::geometry::Mesh;
use glam::{Vec3, Vec3A};

/// The deepest tree a worker accepts. Trees the builder makes from meshes of up to 2^27
/// triangles stay far shallower.
pub const MAX_WIRE_DEPTH: usize = 256;

/// The values of one node as it travels.
const NODE_VALUES: usize = 28;

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
    }
    for &p in &bvh.prim_order {
        out.extend_from_slice(&p.to_le_bytes());
    }
}

/// The BVH that [`encode_bvh4`] wrote to `bytes`, for `mesh`: an error unless it is a whole tree
/// over exactly the mesh's triangles whose boxes contain them (see the module documentation).
pub fn decode_bvh4(bytes: &[u8], mesh: &Mesh) -> Result<Bvh4, String> {
    let word = |k: usize| -> Option<u32> { Some(u32::from_le_bytes(bytes.get(4 * k..4 * k + 4)?.try_into().ok()?)) };
    let (Some(node_count), Some(slot_count)) = (word(0), word(1)) else {
        return Err("a BVH shorter than its header".into());
    };
    let (node_count, slot_count) = (node_count as usize, slot_count as usize);
    let expected = (node_count.checked_mul(NODE_VALUES))
        .and_then(|v| v.checked_add(slot_count))
        .and_then(|v| v.checked_add(2))
        .and_then(|v| v.checked_mul(4));
    if expected != Some(bytes.len()) {
        return Err(format!("a BVH of {} bytes for {node_count} nodes and {slot_count} leaf slots", bytes.len()));
    }
    let triangles = mesh.triangle_count();
    // Every block holds a triangle at least.
    if slot_count % BLOCK_WIDTH != 0 || slot_count / BLOCK_WIDTH > triangles || slot_count < triangles {
        return Err(format!("a BVH of {slot_count} leaf slots for a mesh of {triangles} triangles"));
    }
    if (node_count == 0) != (triangles == 0) {
        return Err(format!("a BVH of {node_count} nodes for a mesh of {triangles} triangles"));
    }
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
            }
        })
        .collect();
    let prim_order: Vec<u32> = (0..slot_count).map(|s| word(2 + NODE_VALUES * node_count + s).unwrap_or(0)).collect();
    let mut placed = vec![false; triangles];
    for &p in prim_order.iter().filter(|&&p| p != NO_TRIANGLE) {
        match placed.get_mut(p as usize) {
            Some(seen @ false) => *seen = true,
            _ => return Err(format!("the BVH's leaf order names triangle {p} twice or out of range")),
        }
    }
    if let Some(t) = placed.iter().position(|&p| !p) {
        return Err(format!("the BVH's leaf order leaves out triangle {t}"));
    }
    if nodes.is_empty() {
        return Ok(Bvh4::default());
    }
    let depth = check_tree(&nodes, &prim_order, mesh)?;
    let mut lo = Vec3A::INFINITY;
    let mut hi = Vec3A::NEG_INFINITY;
    for k in 0..4 {
        if nodes[0].child[k] != super::bvh4::EMPTY_CHILD {
            let (a, b) = child_box(&nodes[0], k);
            (lo, hi) = (lo.min(a), hi.max(b));
        }
    }
    Ok(Bvh4 { nodes, prim_order, bounds: Some((lo, hi)), depth })
}

/// A box's corners.
type Bounds = (Vec3A, Vec3A);

/// Child `k`'s box in `node`.
fn child_box(node: &Node4, k: usize) -> Bounds {
    (Vec3A::new(node.min_x[k], node.min_y[k], node.min_z[k]), Vec3A::new(node.max_x[k], node.max_y[k], node.max_z[k]))
}

/// Whether `p` lies in the box (a `NaN` anywhere is outside).
fn inside((lo, hi): Bounds, p: Vec3) -> bool {
    let p = Vec3A::from(p);
    lo.cmple(p).all() && p.cmple(hi).all()
}

/// Checks the tree under node 0 (see the module documentation); returns its depth in inner-node
/// levels, as [`Bvh4::depth`] counts them.
fn check_tree(nodes: &[Node4], prim_order: &[u32], mesh: &Mesh) -> Result<usize, String> {
    let mut reached = vec![false; nodes.len()];
    let mut block_taken = vec![false; prim_order.len() / BLOCK_WIDTH];
    let mut deepest = 0;
    // Inner nodes to check: index, level (the root's is 1), and the box its parent gives it.
    let mut stack: Vec<(usize, usize, Option<Bounds>)> = vec![(0, 1, None)];
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
                let (block, count) = leaf_range(r);
                if count == 0 {
                    continue;
                }
                let (block, count) = (block as usize, count as usize);
                if count > BLOCK_WIDTH || block >= block_taken.len() {
                    return Err(format!(
                        "BVH node {i} has a leaf of {count} in block {block} of {}",
                        block_taken.len()
                    ));
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
            }
            if let Some(parent) = parent_box {
                if r != super::bvh4::EMPTY_CHILD && !(inside(parent, child.0.into()) && inside(parent, child.1.into()))
                {
                    return Err(format!("a child box of BVH node {i} reaches outside its own box"));
                }
            }
        }
    }
    if let Some(i) = reached.iter().position(|&r| !r) {
        return Err(format!("BVH node {i} is in no tree"));
    }
    if let Some(b) = block_taken.iter().position(|&t| !t) {
        return Err(format!("block {b} of the BVH is in no leaf"));
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
    fn damaged_bvhs_are_errors() {
        let mesh = grid(20);
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
        assert!(decode_bvh4(&bytes, &grid(21)).is_err());
        let node = |i: usize, k: usize| 4 * (2 + NODE_VALUES * i + k);
        let damage = |at: usize, value: u32| {
            let mut damaged = bytes.clone();
            damaged[at..at + 4].copy_from_slice(&value.to_le_bytes());
            decode_bvh4(&damaged, &mesh)
        };
        let root_child = built.nodes[0].child[0];
        assert_eq!(root_child & LEAF_BIT, 0, "the root of 800 triangles has inner children");
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

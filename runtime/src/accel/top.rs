//! The top-level BVH over instances, rebuilt every frame from the instance list.
//!
//! Invariants: `instances[i]` is instance `i` of the list the level was built from;
//! `object_from_world` is the exact inverse used to move rays into object space, and `identity`
//! is set only when the transform is exactly the identity (rays are then used unchanged).

use super::bvh4::{BuildQuality, Bvh4};
use super::object::Object;
use glam::{Affine3A, Vec3A};
use obvhs::aabb::Aabb;

/// Leaf size of the top-level BVH.
const TOP_LEAF_SIZE: u32 = 2;

/// One instance as the tracer sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceData {
    /// The object instanced.
    pub object: u32,
    /// Object to world.
    pub world_from_object: Affine3A,
    /// World to object (applied to rays).
    pub object_from_world: Affine3A,
    /// Whether the transform is the identity.
    pub identity: bool,
}

impl InstanceData {
    /// Instance data for `object` placed by `world_from_object`.
    pub fn new(object: u32, world_from_object: Affine3A) -> Self {
        InstanceData {
            object,
            world_from_object,
            object_from_world: world_from_object.inverse(),
            identity: world_from_object == Affine3A::IDENTITY,
        }
    }
}

/// The top level of the two-level BVH.
#[derive(Clone, Debug, Default)]
pub struct TopLevel {
    /// BVH over instance world bounds; leaf slots are instance ids.
    pub bvh: Bvh4,
    /// The instances.
    pub instances: Vec<InstanceData>,
}

impl TopLevel {
    /// The instance, when the BVH holds exactly one (single rays then skip the top level: the
    /// object BVH's root test culls the same rays).
    #[inline(always)]
    pub fn sole_instance(&self) -> Option<u32> {
        match self.bvh.prim_order.as_slice() {
            [only] => Some(*only),
            _ => None,
        }
    }

    /// Builds the top level over `instances` of `objects`. Instances of empty objects are kept in
    /// the list but left out of the BVH.
    pub fn build(instances: Vec<InstanceData>, objects: &[Object]) -> Self {
        let mut boxes = Vec::with_capacity(instances.len());
        let mut ids = Vec::with_capacity(instances.len());
        for (i, inst) in instances.iter().enumerate() {
            let Some((lo, hi)) = objects.get(inst.object as usize).and_then(|o| o.bvh.bvh.bounds) else {
                continue;
            };
            let mut b = Aabb::empty();
            for k in 0..8 {
                let c = Vec3A::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                b.extend(inst.world_from_object.transform_point3a(c));
            }
            // Widen by a relative epsilon: the transformed corners are rounded.
            let pad = (b.max - b.min).abs().max((b.min.abs()).max(b.max.abs())) * 1e-6;
            boxes.push(Aabb::new(b.min - pad, b.max + pad));
            ids.push(i as u32);
        }
        let mut bvh = Bvh4::build(&boxes, BuildQuality::Fast, TOP_LEAF_SIZE);
        for slot in &mut bvh.prim_order {
            *slot = ids[*slot as usize];
        }
        TopLevel { bvh, instances }
    }
}

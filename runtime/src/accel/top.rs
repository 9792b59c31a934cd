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

/// Top levels over at most this many instances are built at [`BuildQuality::High`], larger ones at
/// [`BuildQuality::Fast`]. A few hundred instances build in tens of microseconds either way, and
/// the better tree saves more traversal in a frame than its build adds (an animation's rigid
/// parts, rebuilt every frame, are this case). Thousands of instances keep the fast build, for the per-frame rebuild targets (1,000 under 1 ms).
const TOP_HIGH_QUALITY_UP_TO: usize = 512;

/// One instance as the tracer sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceData {
    /// The object instanced.
    pub object: u32,
    /// Object to world (at the shutter's opening, for a moving instance).
    pub world_from_object: Affine3A,
    /// World to object (applied to rays).
    pub object_from_world: Affine3A,
    /// Whether the transform is the identity (never for a moving instance).
    pub identity: bool,
    /// How a moving instance's transform changes over the shutter interval.
    pub motion: Option<Motion>,
}

/// A moving instance: its transform goes from `world_from_object` at `open` to `close_transform`
/// at `close`, interpolated linearly, matrix element by matrix element (so every point of the
/// object moves on a straight line, and the boxes of the two end positions bound the whole motion).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub close_transform: Affine3A,
    pub open: f32,
    pub close: f32,
}

impl InstanceData {
    /// The instance's world box, over its motion (from its object's root bounds, without
    /// fetching a demand-loaded object), widened by a relative epsilon (the transformed corners
    /// are rounded); `None` for an empty or unknown object.
    pub fn world_bounds(&self, objects: &[Object]) -> Option<Aabb> {
        let (lo, hi) = objects.get(self.object as usize).and_then(Object::bounds)?;
        let mut b = Aabb::empty();
        for k in 0..8 {
            let c = Vec3A::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            b.extend(self.world_from_object.transform_point3a(c));
            if let Some(m) = &self.motion {
                b.extend(m.close_transform.transform_point3a(c));
            }
        }
        let pad = (b.max - b.min).abs().max((b.min.abs()).max(b.max.abs())) * 1e-6;
        Some(Aabb::new(b.min - pad, b.max + pad))
    }

    /// Instance data for `object` placed by `world_from_object`.
    pub fn new(object: u32, world_from_object: Affine3A) -> Self {
        InstanceData {
            object,
            world_from_object,
            object_from_world: world_from_object.inverse(),
            identity: world_from_object == Affine3A::IDENTITY,
            motion: None,
        }
    }

    /// A moving instance: placed by `open_transform` at time `open` and `close_transform` at `close`.
    pub fn moving(object: u32, open_transform: Affine3A, close_transform: Affine3A, open: f32, close: f32) -> Self {
        if open_transform == close_transform || close.partial_cmp(&open) != Some(std::cmp::Ordering::Greater) {
            return InstanceData::new(object, open_transform);
        }
        InstanceData {
            identity: false,
            motion: Some(Motion { close_transform, open, close }),
            ..InstanceData::new(object, open_transform)
        }
    }

    /// Object to world at `time` (clamped to the shutter interval).
    #[inline]
    pub fn world_from_object_at(&self, time: f32) -> Affine3A {
        match &self.motion {
            None => self.world_from_object,
            Some(m) => {
                let s = ((time - m.open) / (m.close - m.open)).clamp(0.0, 1.0);
                let (a, b) = (&self.world_from_object, &m.close_transform);
                Affine3A {
                    matrix3: a.matrix3 * (1.0 - s) + b.matrix3 * s,
                    translation: a.translation * (1.0 - s) + b.translation * s,
                }
            }
        }
    }

    /// World to object at `time`.
    #[inline]
    pub fn object_from_world_at(&self, time: f32) -> Affine3A {
        match &self.motion {
            None => self.object_from_world,
            Some(_) => self.world_from_object_at(time).inverse(),
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
    /// Whether any object may be in parts ([`super::parts`]: a demand-loaded object, or one
    /// given a BVH in parts): single rays then take the traversal that looks for parts, other
    /// scenes a copy without that test.
    pub may_have_parts: bool,
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
            let Some(b) = inst.world_bounds(objects) else { continue };
            boxes.push(b);
            ids.push(i as u32);
        }
        let quality = if boxes.len() <= TOP_HIGH_QUALITY_UP_TO { BuildQuality::High } else { BuildQuality::Fast };
        let mut bvh = Bvh4::build(&boxes, quality, TOP_LEAF_SIZE);
        for slot in &mut bvh.prim_order {
            *slot = ids[*slot as usize];
        }
        TopLevel { bvh, instances, may_have_parts: objects.iter().any(Object::may_be_in_parts) }
    }
}

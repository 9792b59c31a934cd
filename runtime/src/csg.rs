//! Solids and their spatial set operations (RISpec 3.2, "Solids and Spatial Set Operations"; RIB
//! `SolidBegin`/`SolidEnd`), ray traced exactly at the level of hits.
//!
//! A [`Solid`] is a tree of set operations (union, intersection, difference) over primitive
//! solids, each primitive a set of instances whose triangles close a volume. The tree is kept
//! flat, in postfix order, so that neither building, checking, serialising nor evaluating it
//! recurses, however deep a file nests its blocks.
//!
//! How a ray sees a solid: every candidate hit the traversal finds on a primitive's triangle is
//! asked whether it lies on the boundary of the whole solid. That is a property of the point
//! alone: the solid's membership function changes across the primitive's surface there, given
//! whether the point is inside each of the other primitives. Whether a point is inside a
//! primitive is found along the same ray: the primitive's nearest surface beyond the point is met
//! from inside (the ray leaves through it) exactly when the point is inside. That query runs the
//! ordinary traversal over a top level of the primitive's own instances, so the core kernels are
//! not changed and every path (packets, single rays, occlusion) takes the same filter. The nearest
//! accepted candidate is then the first boundary of the solid along the ray, whatever the order the
//! traversal met candidates in. Its shading is that of the primitive it belongs to; a subtracted
//! part faces into the part it was subtracted from because the RIB loader built it reversed.
//!
//! Inside and outside come from the triangles' orientation, not from counting crossings: the
//! triangle test is not watertight (a ray through a shared edge may count two hits or none), and a
//! nearest surface is found reliably where a parity is not. A primitive's surfaces must therefore
//! close it with their outsides facing out, as RISpec asks ("when specifying a volume it is
//! important that boundary surfaces completely enclose the interior"); surfaces that do not close
//! a volume give whatever the nearest surface says.

use crate::accel::object::Object;
use crate::accel::single;
use crate::accel::top::{InstanceData, TopLevel};
use crate::ray::{HitCandidate, Ray, INVALID_ID};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Primitive solids at most in one solid: whether a point is inside each is one bit of a `u64`.
pub const MAX_SOLID_PRIMITIVES: usize = 64;

/// A set operation of a solid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SolidOp {
    /// Inside any operand.
    Union,
    /// Inside every operand.
    Intersection,
    /// Inside the first operand and outside every other.
    Difference,
}

impl SolidOp {
    /// The operation a RIB `SolidBegin` names (`"primitive"` is not one).
    pub fn from_name(name: &str) -> Option<SolidOp> {
        match name {
            "union" => Some(SolidOp::Union),
            "intersection" => Some(SolidOp::Intersection),
            "difference" => Some(SolidOp::Difference),
            _ => None,
        }
    }
}

/// One instance of a primitive solid's surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SolidPart<L> {
    /// The instance.
    pub instance: L,
    /// Its triangles face into the primitive (the RIB loader reverses the surfaces of a subtracted
    /// part, RISpec: "the sense of the orientation of the surfaces being subtracted is
    /// automatically reversed"), rather than out of it.
    pub inward: bool,
}

/// A node of a solid in postfix order: a primitive, or an operation on the values of the last
/// `operands` nodes' subtrees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SolidNode<L> {
    Primitive(Vec<SolidPart<L>>),
    Op(SolidOp, u32),
}

/// A solid: its nodes in postfix order (operands before their operation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Solid<L> {
    pub nodes: Vec<SolidNode<L>>,
}

/// Why a solid is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SolidError {
    #[error("a solid of {0} primitives (at most {MAX_SOLID_PRIMITIVES})")]
    TooManyPrimitives(usize),
    #[error("a solid's operations do not form one tree")]
    Malformed,
}

impl<L: Copy> Solid<L> {
    /// Checks that the nodes form one tree of at most [`MAX_SOLID_PRIMITIVES`] primitives, every
    /// operation taking at least one operand.
    pub fn check(&self) -> Result<(), SolidError> {
        let primitives = self.nodes.iter().filter(|n| matches!(n, SolidNode::Primitive(_))).count();
        if primitives > MAX_SOLID_PRIMITIVES {
            return Err(SolidError::TooManyPrimitives(primitives));
        }
        let mut depth = 0usize;
        for node in &self.nodes {
            match node {
                SolidNode::Primitive(_) => depth += 1,
                SolidNode::Op(_, n) => {
                    let n = *n as usize;
                    if n == 0 || n > depth {
                        return Err(SolidError::Malformed);
                    }
                    depth -= n - 1;
                }
            }
        }
        if depth == 1 {
            Ok(())
        } else {
            Err(SolidError::Malformed)
        }
    }

    /// The same solid over other instance names; parts `map` gives `None` are left out.
    pub fn filter_map<M>(&self, mut map: impl FnMut(L) -> Option<M>) -> Solid<M> {
        let nodes = self
            .nodes
            .iter()
            .map(|n| match n {
                SolidNode::Primitive(parts) => SolidNode::Primitive(
                    parts
                        .iter()
                        .filter_map(|p| Some(SolidPart { instance: map(p.instance)?, inward: p.inward }))
                        .collect(),
                ),
                SolidNode::Op(op, n) => SolidNode::Op(*op, *n),
            })
            .collect();
        Solid { nodes }
    }

    /// Every instance of every primitive.
    pub fn instances(&self) -> impl Iterator<Item = L> + '_ {
        self.nodes
            .iter()
            .flat_map(|n| match n {
                SolidNode::Primitive(parts) => parts.as_slice(),
                SolidNode::Op(..) => &[],
            })
            .map(|p| p.instance)
    }
}

/// A step of a compiled solid's program.
#[derive(Clone, Copy, Debug)]
enum Step {
    Leaf(u8),
    Op(SolidOp, u8),
}

/// A primitive solid as the tracer asks it: a top level over its instances.
#[derive(Clone, Debug)]
struct Leaf {
    top: TopLevel,
    /// Per instance of `top`, whether its triangles face into the primitive.
    inward: Vec<bool>,
}

/// A checked solid: its program and its primitives.
#[derive(Clone, Debug)]
struct Tree {
    program: Vec<Step>,
    leaves: Vec<Leaf>,
}

/// The solids of a scene, compiled against its instance list ([`crate::Scene::commit`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct Csg {
    trees: Vec<Tree>,
    /// Per scene instance, its solid and primitive (`INVALID_ID` for none).
    member: Vec<(u32, u32)>,
}

impl Csg {
    /// Compiles `solids` over the scene's instances (indices into `instances`); a solid that fails
    /// [`Solid::check`] is left out (its parts are then plain surfaces), and so is an instance out
    /// of range or already in a solid.
    pub(crate) fn build(solids: &[Solid<u32>], instances: &[InstanceData], objects: &[Object]) -> Csg {
        let mut member = vec![(INVALID_ID, INVALID_ID); instances.len()];
        let mut trees = Vec::new();
        for solid in solids {
            if solid.check().is_err() {
                continue;
            }
            let tree_index = trees.len() as u32;
            let mut program = Vec::with_capacity(solid.nodes.len());
            let mut leaves = Vec::new();
            for node in &solid.nodes {
                match node {
                    SolidNode::Primitive(parts) => {
                        let leaf_index = leaves.len() as u32;
                        let mut data = Vec::new();
                        let mut inward = Vec::new();
                        for part in parts {
                            let Some(slot) = member.get_mut(part.instance as usize) else { continue };
                            if slot.0 != INVALID_ID {
                                continue;
                            }
                            *slot = (tree_index, leaf_index);
                            data.push(instances[part.instance as usize]);
                            inward.push(part.inward);
                        }
                        program.push(Step::Leaf(leaf_index as u8));
                        leaves.push(Leaf { top: TopLevel::build(data, objects), inward });
                    }
                    // An operation of one operand is that operand: left out, so that a chain of
                    // them costs nothing, and a program holds at most 64 leaves and 63
                    // operations. At most 64 operands: they are on a stack of at most 64.
                    SolidNode::Op(_, 1) => {}
                    SolidNode::Op(op, n) => program.push(Step::Op(*op, (*n).min(64) as u8)),
                }
            }
            trees.push(Tree { program, leaves });
        }
        Csg { trees, member }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.trees.is_empty()
    }

    /// Whether instance `instance` is part of a solid.
    pub(crate) fn is_member(&self, instance: u32) -> bool {
        self.member.get(instance as usize).is_some_and(|m| m.0 != INVALID_ID)
    }

    /// Whether candidate `c` of `ray` lies on the boundary of the solid its instance belongs to
    /// (always, for an instance in no solid).
    pub(crate) fn accepts(&self, objects: &[Object], ray: &Ray, c: &HitCandidate) -> bool {
        let Some(&(tree, leaf)) = self.member.get(c.instance as usize) else { return true };
        let Some(tree) = self.trees.get(tree as usize) else { return true };
        let mut inside = 0u64;
        for (j, other) in tree.leaves.iter().enumerate() {
            if j as u32 != leaf && other.contains(objects, ray, c.t) {
                inside |= 1 << j;
            }
        }
        let bit = 1u64 << leaf;
        tree.eval(inside | bit) != tree.eval(inside & !bit)
    }
}

impl Tree {
    /// Whether a point inside the primitives of `inside`'s bits is inside the solid. The values
    /// wait on a stack of bits: there are never more on it than primitives, at most 64.
    fn eval(&self, inside: u64) -> bool {
        let (mut stack, mut len) = (0u64, 0u32);
        for step in &self.program {
            match *step {
                Step::Leaf(j) => {
                    stack |= (inside >> j & 1) << len;
                    len += 1;
                }
                Step::Op(op, n) => {
                    let n = u32::from(n).min(len);
                    if n == 0 {
                        continue;
                    }
                    let base = len - n;
                    let operands = (stack >> base) & (u64::MAX >> (64 - n));
                    let value = match op {
                        SolidOp::Union => operands != 0,
                        SolidOp::Intersection => operands == u64::MAX >> (64 - n),
                        SolidOp::Difference => operands == 1,
                    };
                    stack &= !(u64::MAX << base);
                    stack |= u64::from(value) << base;
                    len = base + 1;
                }
            }
        }
        len >= 1 && stack & 1 == 1
    }
}

impl Leaf {
    /// Whether the point at `t` along `ray` is inside the primitive: the ray leaves through the
    /// primitive's nearest surface beyond it.
    fn contains(&self, objects: &[Object], ray: &Ray, t: f32) -> bool {
        let probe = Ray { tmin: t, tmax: f32::INFINITY, ..*ray };
        let hit = single::intersect_scene(&self.top, objects, &probe, None, 0);
        if !hit.is_hit() {
            return false;
        }
        let (Some(inst), Some(&inward)) =
            (self.top.instances.get(hit.instance as usize), self.inward.get(hit.instance as usize))
        else {
            return false;
        };
        let Some(object) = objects.get(inst.object as usize) else { return false };
        let mesh = &object.data().mesh;
        if hit.primitive as usize >= mesh.triangle_count() {
            return false;
        }
        let [a, b, c] = mesh.corners_at(hit.primitive as usize, ray.time);
        // In object space: a direction and a normal moved by a matrix and its inverse transpose
        // keep their dot product, so a mirroring instance keeps its outside.
        let d = Vec3::from(inst.object_from_world_at(ray.time).transform_vector3a(ray.direction));
        let leaves_outward = (b - a).cross(c - a).dot(d) > 0.0;
        leaves_outward != inward
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(nodes: &[SolidNode<u32>]) -> Tree {
        let leaves = nodes.iter().filter(|n| matches!(n, SolidNode::Primitive(_))).count();
        let csg = Csg::build(&[Solid { nodes: nodes.to_vec() }], &[], &[]);
        assert_eq!(csg.trees[0].leaves.len(), leaves);
        csg.trees[0].clone()
    }

    fn p() -> SolidNode<u32> {
        SolidNode::Primitive(Vec::new())
    }

    #[test]
    fn operations_combine_their_operands() {
        let diff = tree(&[p(), p(), p(), SolidNode::Op(SolidOp::Difference, 3)]);
        assert!(diff.eval(0b001));
        assert!(!diff.eval(0b011));
        assert!(!diff.eval(0b101));
        assert!(!diff.eval(0b110));
        let inter = tree(&[p(), p(), SolidNode::Op(SolidOp::Intersection, 2)]);
        assert!(inter.eval(0b11) && !inter.eval(0b01) && !inter.eval(0b10));
        let union = tree(&[p(), p(), SolidNode::Op(SolidOp::Union, 2)]);
        assert!(union.eval(0b01) && union.eval(0b10) && !union.eval(0));
        // (A - (B - C)): a point in A, B and C is in the solid.
        let nested =
            tree(&[p(), p(), p(), SolidNode::Op(SolidOp::Difference, 2), SolidNode::Op(SolidOp::Difference, 2)]);
        assert!(nested.eval(0b111) && !nested.eval(0b011) && nested.eval(0b001));
    }

    #[test]
    fn operations_of_one_operand_are_left_out() {
        let chain: Vec<_> = [p()].into_iter().chain((0..1000).map(|_| SolidNode::Op(SolidOp::Difference, 1))).collect();
        let t = tree(&chain);
        assert_eq!(t.program.len(), 1);
        assert!(t.eval(1) && !t.eval(0));
    }

    #[test]
    fn malformed_trees_are_refused() {
        let s = |nodes: Vec<SolidNode<u32>>| Solid { nodes }.check();
        assert_eq!(s(vec![]), Err(SolidError::Malformed));
        assert_eq!(s(vec![p(), p()]), Err(SolidError::Malformed));
        assert_eq!(s(vec![p(), SolidNode::Op(SolidOp::Union, 2)]), Err(SolidError::Malformed));
        assert_eq!(s(vec![p(), SolidNode::Op(SolidOp::Union, 0)]), Err(SolidError::Malformed));
        assert_eq!(s(vec![p(), SolidNode::Op(SolidOp::Union, 1)]), Ok(()));
        let many = (0..65).map(|_| p()).chain([SolidNode::Op(SolidOp::Union, 65)]).collect();
        assert_eq!(s(many), Err(SolidError::TooManyPrimitives(65)));
    }
}

//! The budget of one camera sample's tree of rays.
//!
//! The ray depth bounds how deep the rays shaders spawn nest, not how many there are: a surface
//! that traces two rays a hit (glass: a reflection and a refraction) makes 2^depth rays per camera
//! ray, and at `Option "trace" "maxdepth"` 64 a frame would not end. So each camera sample's tree
//! may spawn at most [`RAY_TREE_BUDGET`] rays, counted wherever in the tree they start; past it a
//! shader's `trace` sees nothing (black, at infinity, as past the ray depth), a `gather` ray
//! misses and `indirectdiffuse` goes unshaded, and the frame counts the rays refused
//! ([`super::FrameReport::rays_cut`]).
//!
//! The count goes with the rays as their depth does: each shaded ray carries what its tree may
//! still spend ([`RayBudget`]), and a shader call keeps one for each of its lanes. A ray a lane
//! spawns costs one and is lent everything the lane has left; what its own tree spent is taken
//! from the lane when its answer comes back, so a sample's rays spend its budget in the order
//! they are traced, whatever other samples are shaded beside them. Two exceptions, both cut only
//! where the budget runs out: the rays of one `indirectdiffuse` call, traced together, share what
//! their lane has left equally; so do a lane's `trace` rays when its batch traces them ahead
//! together (`trace_ahead.rs`), so that past the budget which rays are cut may depend on how the
//! frame's rays were batched. A tree none of whose rays is refused is shaded exactly as without a
//! budget, so a frame that cuts nothing is the image it was before there was one.
//!
//! The budget also carries where its tree comes from ([`RayOrigin`]): the pixel of its camera
//! sample and the nearest object on its path that sets ray parameters, which every ray of the tree
//! inherits (`ray_params.rs`).
//!
//! Only rays that are shaded count (and `gather` rays that could be): shadow, `transmission` and
//! `occlusion` rays end where they hit, and are bounded by the loop budget of the shader that
//! sends them.

/// The rays one camera sample's shaders may spawn (`trace`, `gather`, `indirectdiffuse`), at
/// every depth together: a tree of reflection and refraction 16 levels deep, or a `gather` at its
/// largest sample count 32 times over.
pub const RAY_TREE_BUDGET: u32 = 1 << 17;

/// Where a tree of rays comes from, for its rays' parameters (`ray_params.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RayOrigin {
    /// The camera sample's pixel, `y * width + x` ([`RayOrigin::NO_PIXEL`] for rays of no
    /// pixel: light paths, rays an application traces).
    pub(crate) pixel: u32,
    /// The material of the nearest surface on the path that sets ray parameters
    /// ([`RayOrigin::NO_MATERIAL`]: none).
    pub(crate) material: u32,
}

impl RayOrigin {
    pub(crate) const NO_PIXEL: u32 = u32::MAX;
    pub(crate) const NO_MATERIAL: u32 = u32::MAX;
    pub(crate) const NONE: RayOrigin = RayOrigin { pixel: Self::NO_PIXEL, material: Self::NO_MATERIAL };
}

/// What a ray's tree may still spawn, whether a ray of it was refused, and where it comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RayBudget {
    pub(crate) left: u32,
    pub(crate) cut: bool,
    pub(crate) origin: RayOrigin,
}

impl RayBudget {
    /// A camera sample's (of no pixel: [`RayBudget::from_pixel`] gives it one).
    pub(crate) const FULL: RayBudget = RayBudget { left: RAY_TREE_BUDGET, cut: false, origin: RayOrigin::NONE };
    /// Nothing to spend: for rays that cannot spawn any (at the ray depth).
    pub(crate) const NONE: RayBudget = RayBudget { left: 0, cut: false, origin: RayOrigin::NONE };

    /// The full budget of the camera sample of pixel `pixel` (`y * width + x`).
    pub(crate) const fn from_pixel(pixel: u32) -> RayBudget {
        RayBudget { origin: RayOrigin { pixel, material: RayOrigin::NO_MATERIAL }, ..RayBudget::FULL }
    }

    /// This budget where a ray reaches a surface of material `material`: its rays inherit the
    /// material's ray parameters if it sets any (`sets_parameters`).
    pub(crate) fn through(self, material: u32, sets_parameters: bool) -> RayBudget {
        if sets_parameters {
            RayBudget { origin: RayOrigin { material, ..self.origin }, ..self }
        } else {
            self
        }
    }

    /// Takes `rays` from what is left; false, with nothing taken and the tree marked cut, when
    /// fewer are left.
    pub(crate) fn take(&mut self, rays: u32) -> bool {
        if self.left < rays {
            self.cut = true;
            return false;
        }
        self.left -= rays;
        true
    }

    /// What a spawned ray is lent: all that is left.
    pub(crate) fn lend(self) -> RayBudget {
        RayBudget { left: self.left, cut: false, origin: self.origin }
    }

    /// A share of what is left, for one of `n` rays spawned together.
    pub(crate) fn share(self, n: u32) -> RayBudget {
        RayBudget { left: self.left / n.max(1), cut: false, origin: self.origin }
    }

    /// Takes back what a spawned ray's tree spent of `lent`, ending with `after`.
    pub(crate) fn settle(&mut self, lent: RayBudget, after: RayBudget) {
        self.charge(lent.left.saturating_sub(after.left), after.cut);
    }

    /// Takes `spent` rays (at most what is left: a tree never spends more than it was lent).
    pub(crate) fn charge(&mut self, spent: u32, cut: bool) {
        self.left = self.left.saturating_sub(spent);
        self.cut |= cut;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tree_spends_what_it_was_lent_and_no_more() {
        let mut lane = RayBudget { left: 10, cut: false, origin: RayOrigin { pixel: 7, material: 2 } };
        assert!(lane.take(1));
        let lent = lane.lend();
        assert_eq!(lent.left, 9);
        let mut child = lent;
        assert!(child.take(4));
        assert!(!child.take(6), "5 left");
        assert!(child.cut);
        lane.settle(lent, child);
        assert_eq!(lane, RayBudget { left: 5, cut: true, origin: RayOrigin { pixel: 7, material: 2 } });
        assert_eq!(lane.share(2).left, 2);
        assert_eq!(lane.share(2).origin, lane.origin, "the rays of a tree keep its origin");
        assert_eq!(lent.origin, lane.origin);
        assert_eq!(lane.through(5, false).origin.material, 2);
        assert_eq!(lane.through(5, true).origin, RayOrigin { pixel: 7, material: 5 });
        assert_eq!(lane.share(0).left, 5);
    }
}

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
//!
//! The budget carries the bounces its ray's path took, diffuse and specular, and the most it may
//! take ([`Bounces`], RenderMan's `maxdiffusedepth` and `maxspeculardepth`: see
//! [`super::TraceDepths`]), as it carries its origin: the rays of a tree inherit them, and each
//! `indirectdiffuse()` or `trace()` ray adds its own bounce.

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

/// A kind of bounce a spawned ray takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bounce {
    /// `indirectdiffuse()`.
    Diffuse,
    /// `trace()`: reflections and refractions.
    Specular,
}

/// The bounces a ray's path took, and the most it may take (see [`super::TraceDepths`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Bounces {
    pub(crate) diffuse: u32,
    pub(crate) specular: u32,
    diffuse_limit: u32,
    specular_limit: u32,
}

impl Bounces {
    /// A camera ray's: none taken, none bounded.
    pub(crate) const NONE: Bounces =
        Bounces { diffuse: 0, specular: 0, diffuse_limit: u32::MAX, specular_limit: u32::MAX };

    /// These bounces where the ray reaches a surface whose rays may take `depths` more: each limit
    /// becomes the smaller of the one carried and the bounces so far plus the surface's (PRMan's
    /// rule).
    pub(crate) fn at(self, depths: super::TraceDepths) -> Bounces {
        Bounces {
            diffuse_limit: self.diffuse_limit.min(self.diffuse.saturating_add(depths.diffuse)),
            specular_limit: self.specular_limit.min(self.specular.saturating_add(depths.specular)),
            ..self
        }
    }

    /// Whether a ray spawned here may take a bounce of `kind`.
    pub(crate) fn allow(self, kind: Bounce) -> bool {
        match kind {
            Bounce::Diffuse => self.diffuse < self.diffuse_limit,
            Bounce::Specular => self.specular < self.specular_limit,
        }
    }

    /// A spawned ray's: these with a bounce of `kind` more.
    fn after(self, kind: Bounce) -> Bounces {
        match kind {
            Bounce::Diffuse => Bounces { diffuse: self.diffuse.saturating_add(1), ..self },
            Bounce::Specular => Bounces { specular: self.specular.saturating_add(1), ..self },
        }
    }
}

/// What a ray's tree may still spawn, whether a ray of it was refused, where it comes from, and
/// the bounces its path took.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RayBudget {
    pub(crate) left: u32,
    pub(crate) cut: bool,
    pub(crate) origin: RayOrigin,
    pub(crate) bounces: Bounces,
}

impl RayBudget {
    /// A camera sample's (of no pixel: [`RayBudget::from_pixel`] gives it one).
    pub(crate) const FULL: RayBudget =
        RayBudget { left: RAY_TREE_BUDGET, cut: false, origin: RayOrigin::NONE, bounces: Bounces::NONE };
    /// Nothing to spend: for rays that cannot spawn any (at the ray depth).
    pub(crate) const NONE: RayBudget =
        RayBudget { left: 0, cut: false, origin: RayOrigin::NONE, bounces: Bounces::NONE };

    /// The full budget of the camera sample of pixel `pixel` (`y * width + x`).
    pub(crate) const fn from_pixel(pixel: u32) -> RayBudget {
        RayBudget { origin: RayOrigin { pixel, material: RayOrigin::NO_MATERIAL }, ..RayBudget::FULL }
    }

    /// This budget where a ray reaches a surface of material `material`: its rays inherit the
    /// material's ray parameters if it sets any (`sets_parameters`), and take at most the bounces
    /// `depths` allows beyond it ([`Bounces::at`]).
    pub(crate) fn through(self, material: u32, sets_parameters: bool, depths: super::TraceDepths) -> RayBudget {
        let bounces = self.bounces.at(depths);
        if sets_parameters {
            RayBudget { origin: RayOrigin { material, ..self.origin }, bounces, ..self }
        } else {
            RayBudget { bounces, ..self }
        }
    }

    /// This budget for a ray that takes a bounce of `kind`.
    pub(crate) fn bounced(self, kind: Bounce) -> RayBudget {
        RayBudget { bounces: self.bounces.after(kind), ..self }
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
        RayBudget { left: self.left, cut: false, ..self }
    }

    /// A share of what is left, for one of `n` rays spawned together.
    pub(crate) fn share(self, n: u32) -> RayBudget {
        RayBudget { left: self.left / n.max(1), cut: false, ..self }
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
        let origin = RayOrigin { pixel: 7, material: 2 };
        let mut lane = RayBudget { left: 10, cut: false, origin, bounces: Bounces::NONE };
        assert!(lane.take(1));
        let lent = lane.lend();
        assert_eq!(lent.left, 9);
        let mut child = lent;
        assert!(child.take(4));
        assert!(!child.take(6), "5 left");
        assert!(child.cut);
        lane.settle(lent, child);
        assert_eq!(lane, RayBudget { left: 5, cut: true, origin, bounces: Bounces::NONE });
        assert_eq!(lane.share(2).left, 2);
        assert_eq!(lane.share(2).origin, lane.origin, "the rays of a tree keep its origin");
        assert_eq!(lent.origin, lane.origin);
        let depths = crate::render::TraceDepths::UNBOUNDED;
        assert_eq!(lane.through(5, false, depths).origin.material, 2);
        assert_eq!(lane.through(5, true, depths).origin, RayOrigin { pixel: 7, material: 5 });
        assert_eq!(lane.share(0).left, 5);
    }

    /// PRMan's rule, with its defaults (one diffuse bounce, two specular ones): a diffuse ray's
    /// hit spawns no diffuse ray; a glass ball refracts in and out, but a reflection of it in a
    /// mirror does not get out again; and a surface lowers, never raises, what an earlier one
    /// allowed.
    #[test]
    fn bounces_follow_the_smallest_bound_on_the_path() {
        use crate::render::TraceDepths;
        let prman = TraceDepths::RENDERMAN;
        let camera = RayBudget::FULL.through(0, false, prman);
        assert!(camera.bounces.allow(Bounce::Diffuse) && camera.bounces.allow(Bounce::Specular));
        let diffuse = camera.lend().bounced(Bounce::Diffuse).through(0, false, prman);
        assert!(!diffuse.bounces.allow(Bounce::Diffuse), "one diffuse bounce");
        assert!(diffuse.bounces.allow(Bounce::Specular), "the specular bounces are apart");
        let inside = camera.bounced(Bounce::Specular).through(0, false, prman);
        assert!(inside.bounces.allow(Bounce::Specular), "out of the ball again");
        let mirrored = camera.bounced(Bounce::Specular).through(0, false, prman);
        let in_ball = mirrored.bounced(Bounce::Specular).through(0, false, prman);
        assert!(!in_ball.bounces.allow(Bounce::Specular), "the mirror took one of the two");
        // A surface allowing more does not lift the bound an earlier one set.
        let generous = TraceDepths { diffuse: 5, specular: 5 };
        let later = diffuse.bounced(Bounce::Specular).through(0, false, generous);
        assert!(!later.bounces.allow(Bounce::Diffuse));
        // Unbounded surfaces leave every bounce to the ray depth.
        let free = RayBudget::FULL.through(0, false, TraceDepths::UNBOUNDED).bounced(Bounce::Diffuse);
        assert!(free.through(0, false, TraceDepths::UNBOUNDED).bounces.allow(Bounce::Diffuse));
        // A surface with no bounces stops its own rays at once.
        let none = RayBudget::FULL.through(0, false, TraceDepths { diffuse: 0, specular: 0 });
        assert!(!none.bounces.allow(Bounce::Diffuse) && !none.bounces.allow(Bounce::Specular));
    }
}

//! When a refitted tree is rebuilt: the rule every tree here that follows moving boxes
//! shares (the instance BVH, the BVH over a scene's clusters, the ray caster's top level).
//!
//! Refit keeps the topology and recomputes boxes bottom-up: cheap, but a tree refitted after
//! large motions has overlapping, bloated nodes. The rule measures the SAH cost after each
//! refit and rebuilds when it exceeds [`REBUILD_RATIO`] × the cost right after the last full
//! build (a common heuristic, e.g. Kopta et al., "Fast, Effective BVH Updates for Animated
//! Scenes", I3D 2012, rebuild on measured degradation). Where the rebuild runs is the
//! `background` module's business.

/// Rebuild when the refitted tree's SAH cost exceeds this multiple of the fresh build's.
pub const REBUILD_RATIO: f32 = 1.5;

/// What an update of a refitted tree did ([`InstanceBvh::update`](crate::InstanceBvh::update),
/// [`ClusteredScene`](crate::ClusteredScene)'s and the ray caster's top level's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RefitOutcome {
    /// Boxes refitted; the SAH cost is now `cost_ratio` × the fresh build's.
    Refitted {
        /// SAH cost after refit over SAH cost after the last build.
        cost_ratio: f32,
    },
    /// Refitted, with the SAH cost beyond [`REBUILD_RATIO`] × the fresh build's: a fresh
    /// tree is being built off the frame, started by this update or one of the previous
    /// [`rebuild_lag`](crate::rebuild_lag), and put in place by the update that many after
    /// the one that started it (the trees that rebuild in the background:
    /// [`InstanceBvh`](crate::InstanceBvh)'s and the
    /// [`ClusteredScene`](crate::ClusteredScene)'s).
    Rebuilding {
        /// SAH cost after refit over SAH cost after the last build.
        cost_ratio: f32,
    },
    /// Rebuilt from scratch: refit degraded too much (`cost_ratio` is the refit's ratio) or
    /// the set of valid boxes changed (ratio infinite); or a tree built in the background
    /// was put in place and refitted to the current boxes (`cost_ratio` is the ratio that
    /// started its build).
    Rebuilt {
        /// The ratio that triggered the rebuild.
        cost_ratio: f32,
    },
}

impl RefitOutcome {
    /// The rule every refitted tree here follows: `ratio` is the refitted tree's SAH cost
    /// over its last build's (`None`: the refit failed, the boxes no longer fit the tree).
    /// At most [`REBUILD_RATIO`] the refit stands; otherwise `rebuild` runs.
    pub(crate) fn decide(ratio: Option<f32>, rebuild: impl FnOnce()) -> RefitOutcome {
        match ratio {
            Some(r) if r <= REBUILD_RATIO => RefitOutcome::Refitted { cost_ratio: r },
            other => {
                rebuild();
                RefitOutcome::Rebuilt { cost_ratio: other.unwrap_or(f32::INFINITY) }
            }
        }
    }
}

/// A tree's SAH cost over its cost right after the last build (1 when that was 0).
pub(crate) fn cost_ratio(cost: f32, build_cost: f32) -> f32 {
    if build_cost > 0.0 {
        cost / build_cost
    } else {
        1.0
    }
}

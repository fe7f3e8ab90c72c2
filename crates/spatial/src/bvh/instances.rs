//! The BVH over a scene's instances (one item per [`Instance`], its world box), for culling,
//! refitted after instances move and rebuilt when the refit has degraded it past
//! [`REBUILD_RATIO`](crate::REBUILD_RATIO) (the rule of [`RefitOutcome`]). The rebuild runs
//! off the frame, as the cluster BVH's does (see [`crate::rebuild_lag`]): the updates in
//! between refit the old tree. (The ray caster's top level is the 4-wide
//! [`crate::bvh::wide::WideTlas`].)

use glam::Vec3;
use sightline_scene::{Aabb, Instance};

use super::background::Background;
use super::policy::{cost_ratio, RefitOutcome};
use super::traverse::CoherencyCache;
use super::{Bvh, BvhPreset};
use crate::{CullCounters, CullOptions, FrontToBack, Frustum, FrustumCull, Visible, Visit};

/// Instances per leaf: small leaves cull finely; items of bigger leaves are tested one by one.
const INSTANCE_LEAF: u32 = 4;

/// A BVH over instances: item `i` is instance `i` of the slice it was built from.
#[derive(Debug, Clone, Default)]
pub struct InstanceBvh {
    bvh: Bvh,
    preset: BvhPreset,
    build_cost: f32,
    background: Background<Bvh>,
}

impl InstanceBvh {
    /// Builds over the world boxes of `instances` (the fast preset).
    pub fn from_instances(instances: &[Instance]) -> InstanceBvh {
        let boxes: Vec<Aabb> = instances.iter().map(|i| i.world_aabb).collect();
        Self::build(&boxes, BvhPreset::Fast)
    }

    /// Builds over `boxes` (item `i` is `boxes[i]`).
    pub fn build(boxes: &[Aabb], preset: BvhPreset) -> InstanceBvh {
        let (bvh, build_cost) = Bvh::build_costed(boxes, preset, INSTANCE_LEAF);
        InstanceBvh { bvh, preset, build_cost, background: Background::default() }
    }

    /// The underlying BVH (for custom traversals).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// SAH cost of the tree right after its last full build.
    pub fn build_cost(&self) -> f32 {
        self.build_cost
    }

    /// Refits to new boxes (same count and order as the build) without the rebuild policy.
    /// Returns the SAH cost ratio, or `None` when the boxes no longer fit the tree (an item's
    /// box became empty, NaN or infinite, or the count changed): rebuild then.
    pub fn refit(&mut self, boxes: &[Aabb]) -> Option<f32> {
        let cost = self.bvh.refit_cost(boxes)?;
        Some(cost_ratio(cost, self.build_cost))
    }

    /// Current SAH cost over the fresh build's.
    pub fn cost_ratio(&self) -> f32 {
        cost_ratio(self.bvh.sah_cost(), self.build_cost)
    }

    /// Refits to new boxes (same count and order as the build). When the SAH cost has grown
    /// beyond [`REBUILD_RATIO`](crate::REBUILD_RATIO) × the fresh build's, a new tree is
    /// built on a background thread from these boxes, and the update
    /// [`rebuild_lag`](crate::rebuild_lag) updates later puts it in place, refitted to the
    /// boxes of then (waiting for it if it is not done); the updates between refit the old
    /// tree. When the boxes no longer fit the tree (an item's box changed kind, or the count
    /// changed) it is rebuilt here and now.
    pub fn update(&mut self, boxes: &[Aabb]) -> RefitOutcome {
        let preset = self.preset;
        let tree = (&mut self.bvh, &mut self.build_cost);
        self.background.update(
            tree,
            boxes,
            Bvh::refit_cost,
            |bvh| bvh.refit_cost(boxes),
            move |b| Bvh::build_costed(b, preset, INSTANCE_LEAF),
        )
    }

    /// [`InstanceBvh::update`] from instances (their world boxes).
    pub fn update_instances(&mut self, instances: &[Instance]) -> RefitOutcome {
        let boxes: Vec<Aabb> = instances.iter().map(|i| i.world_aabb).collect();
        self.update(&boxes)
    }

    /// Frustum culling with options; see [`Bvh::cull_with`].
    pub fn cull_with(&self, frustum: &Frustum, opts: CullOptions, out: &mut Vec<Visible>) -> CullCounters {
        self.bvh.cull_with(frustum, opts, out)
    }

    /// Frustum culling with plane coherency; see [`Bvh::cull_coherent`].
    pub fn cull_coherent(&self, frustum: &Frustum, cache: &mut CoherencyCache, out: &mut Vec<Visible>) -> CullCounters {
        self.bvh.cull_coherent(frustum, cache, out)
    }

    /// Front-to-back traversal with callbacks; see [`Bvh::traverse_front_to_back`].
    pub fn traverse_front_to_back(
        &self,
        frustum: Option<&Frustum>,
        eye: Vec3,
        node_visit: impl FnMut(&Aabb) -> Visit,
        item_visit: impl FnMut(Visible) -> Visit,
    ) {
        self.bvh.traverse_front_to_back(frustum, eye, node_visit, item_visit)
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes()
    }
}

impl FrustumCull for InstanceBvh {
    fn cull(&self, frustum: &Frustum, out: &mut Vec<Visible>) {
        self.bvh.cull_with(frustum, CullOptions::default(), out);
    }
}

impl FrontToBack for InstanceBvh {
    fn order(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.bvh.order_front_to_back(eye, out);
    }
}

impl FrustumCull for Bvh {
    fn cull(&self, frustum: &Frustum, out: &mut Vec<Visible>) {
        self.cull_with(frustum, CullOptions::default(), out);
    }
}

impl FrontToBack for Bvh {
    fn order(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.order_front_to_back(eye, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::REBUILD_RATIO;

    #[test]
    fn big_moves_rebuild_in_the_background_small_ones_refit() {
        let mut rng = sightline_scene::rng::Rng::new(4);
        let mut boxes: Vec<Aabb> = (0..2000)
            .map(|_| {
                let c = Vec3::new(rng.range(-100.0, 100.0), 0.0, rng.range(-100.0, 100.0));
                Aabb::new(c, c + Vec3::ONE)
            })
            .collect();
        let mut tree = InstanceBvh::build(&boxes, BvhPreset::Medium);
        // Small jitter: refit.
        for b in &mut boxes {
            let d = Vec3::new(rng.range(-0.1, 0.1), 0.0, rng.range(-0.1, 0.1));
            *b = Aabb::new(b.min + d, b.max + d);
        }
        assert!(matches!(tree.update(&boxes), RefitOutcome::Refitted { .. }));
        // Shuffle everything across the world: the refitted tree degrades, so a rebuild
        // starts, and the lag's last update puts in place the tree of the boxes it started
        // from, built with the tree's own preset.
        for b in &mut boxes {
            let c = Vec3::new(rng.range(-100.0, 100.0), 0.0, rng.range(-100.0, 100.0));
            *b = Aabb::new(c, c + Vec3::ONE);
        }
        let trigger = match tree.update(&boxes) {
            RefitOutcome::Rebuilding { cost_ratio } => cost_ratio,
            o => panic!("expected a background rebuild, got {o:?}"),
        };
        assert!(trigger > REBUILD_RATIO);
        for _ in 1..crate::rebuild_lag(boxes.len()) {
            assert!(matches!(tree.update(&boxes), RefitOutcome::Rebuilding { .. }));
        }
        assert_eq!(tree.update(&boxes), RefitOutcome::Rebuilt { cost_ratio: trigger });
        tree.bvh().validate().unwrap();
        assert!((tree.cost_ratio() - 1.0).abs() < 1e-6);
        let mut expected = Bvh::build(&boxes, BvhPreset::Medium, INSTANCE_LEAF);
        assert!(expected.refit(&boxes));
        assert!(tree.bvh().nodes() == expected.nodes() && tree.bvh().items() == expected.items());
        // A box turning NaN forces a rebuild now, and the item stays visible.
        boxes[5] = Aabb::new(Vec3::NAN, Vec3::NAN);
        assert!(matches!(tree.update(&boxes), RefitOutcome::Rebuilt { .. }));
        assert_eq!(tree.bvh().unbounded(), &[5]);
    }
}

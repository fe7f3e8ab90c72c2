//! Refitting a wide BVH to moved primitives, and the surface-area cost that says when a
//! refitted tree has degraded enough to rebuild (Wald, Boulos & Shirley 2007, "Ray tracing
//! deformable scenes using dynamic bounding volume hierarchies").
//!
//! Inner nodes are laid out parents first, so a node's inner children always have larger
//! indices than the node: one sweep from the last node to the first sees every child
//! before its parent. The sweep keeps each node's union for its parent to read, and sums
//! the surface-area cost as it goes, so deciding whether to rebuild costs no second pass.

use obvhs::aabb::Aabb as ObAabb;

use super::{WideBvh, EMPTY_LINK, WIDTH};

/// Half the surface area of a box given by its corners (0 for an inverted box).
fn half_area(lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]].map(|x| x.max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

impl WideBvh {
    /// Refits every box to `boxes` (primitive `i`'s new box, as in the build). Returns false,
    /// leaving the tree unchanged, when the count differs from the build's or a box is not
    /// finite: the caller must rebuild then.
    pub fn refit(&mut self, boxes: &[ObAabb]) -> bool {
        self.refit_cost(boxes).is_some()
    }

    /// [`WideBvh::refit`], returning the refitted tree's [SAH cost](WideBvh::sah_cost), summed
    /// in the same sweep (in the sweep's order, so equal to it up to rounding); `None` where
    /// `refit` fails.
    pub fn refit_cost(&mut self, boxes: &[ObAabb]) -> Option<f32> {
        if boxes.len() != self.order.len() || !boxes.iter().all(|b| b.min.is_finite() && b.max.is_finite()) {
            return None;
        }
        // Each node's union, written when the node is refitted: its parent, earlier in the
        // array, reads it instead of re-reducing the node's four slots.
        let mut union = vec![ObAabb::INVALID; self.nodes.len()];
        let mut cost = 0.0f64;
        let order = &self.order;
        // A slot's new box: a leaf's primitives, or the union of an inner child's node.
        let fit = |link: u32, count: u32, union: &[ObAabb]| -> ObAabb {
            if count == 0 {
                union[link as usize]
            } else {
                let run = &order[link as usize..(link + count) as usize];
                run.iter().fold(ObAabb::INVALID, |acc, &i| acc.union(&boxes[i as usize]))
            }
        };
        for i in (0..self.nodes.len()).rev() {
            let mut node = self.nodes[i];
            let mut all = ObAabb::INVALID;
            for k in 0..WIDTH {
                if node.link[k] == EMPTY_LINK {
                    continue;
                }
                let b = fit(node.link[k], node.count[k], &union);
                for a in 0..3 {
                    node.lo[a][k] = b.min[a];
                    node.hi[a][k] = b.max[a];
                }
                // The cost as `sah_cost` weighs a slot: its area, times its count for a leaf.
                cost += half_area(b.min.to_array(), b.max.to_array()) as f64 * node.count[k].max(1) as f64;
                all = all.union(&b);
            }
            self.nodes[i] = node;
            union[i] = all;
        }
        if self.root.is_empty() {
            return Some(0.0);
        }
        // The root's own box has no weight: the cost is relative to it.
        let b = fit(self.root.link, self.root.count, &union);
        self.root.lo = b.min.to_array();
        self.root.hi = b.max.to_array();
        let root = half_area(self.root.lo, self.root.hi);
        Some(if !(root > 0.0) { self.order.len() as f32 } else { (cost / root as f64) as f32 })
    }

    /// The tree's surface-area cost: the expected number of box and primitive tests for a
    /// random ray through the root's box (each used slot weighs its half area, a leaf's times
    /// its primitive count, relative to the root's). Only ratios of it mean anything.
    pub fn sah_cost(&self) -> f32 {
        if self.root.is_empty() {
            return 0.0;
        }
        let root = half_area(self.root.lo, self.root.hi);
        if !(root > 0.0) {
            return self.order.len() as f32;
        }
        let mut cost = 0.0f64;
        for n in &self.nodes {
            for k in 0..WIDTH {
                let c = n.child(k);
                if !c.is_empty() {
                    cost += half_area(c.lo, c.hi) as f64 * if c.is_leaf() { c.count as f64 } else { 1.0 };
                }
            }
        }
        (cost / root as f64) as f32
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;
    use crate::bvh::wide::WideBuildParams;

    fn boxes(n: usize, shift: f32) -> Vec<ObAabb> {
        (0..n)
            .map(|i| {
                let c = Vec3A::new((i % 17) as f32 * 3.0 + shift * (i % 3) as f32, (i / 17) as f32 * 2.0, 0.0);
                ObAabb::new(c - Vec3A::splat(0.5), c + Vec3A::splat(0.5))
            })
            .collect()
    }

    #[test]
    fn a_refitted_tree_is_valid_and_tight_and_its_cost_grows_with_motion() {
        for n in [1usize, 2, 5, 100, 1000] {
            let mut bvh = WideBvh::build_obvhs(&boxes(n, 0.0), WideBuildParams::TLAS);
            let built = bvh.sah_cost();
            let swept = bvh.refit_cost(&boxes(n, 0.0)).unwrap();
            assert!((swept - built).abs() <= 1e-5 * built, "the sweep's cost {swept} is the tree's {built}");
            assert!(bvh.refit(&boxes(n, 0.0)));
            assert_eq!(bvh.sah_cost(), built, "refitting to the same boxes changes nothing");
            let moved = boxes(n, 40.0);
            assert!(bvh.refit(&moved));
            bvh.validate(n).unwrap();
            // The root is exactly the union of the moved boxes.
            let all = moved.iter().fold(ObAabb::INVALID, |a, b| a.union(b));
            assert_eq!((bvh.root().lo, bvh.root().hi), (all.min.to_array(), all.max.to_array()));
            if n >= 100 {
                let fresh = WideBvh::build_obvhs(&moved, WideBuildParams::TLAS).sah_cost();
                assert!(bvh.sah_cost() > fresh, "scattering the leaves degrades the refitted tree");
            }
        }
    }

    #[test]
    fn wrong_counts_and_non_finite_boxes_are_refused() {
        let mut bvh = WideBvh::build_obvhs(&boxes(10, 0.0), WideBuildParams::TLAS);
        assert!(!bvh.refit(&boxes(9, 0.0)));
        let mut bad = boxes(10, 0.0);
        bad[3].max.x = f32::NAN;
        assert!(!bvh.refit(&bad));
        bvh.validate(10).unwrap();
    }
}

//! Bounding volume hierarchies: a flat binary BVH over boxes ([`Bvh`], this module), built
//! by locally-ordered clustering (module `ploc`), optimized with `obvhs` and re-laid out for
//! culling, and what is built on it: the BVH
//! over instances ([`instances`]), over one mesh's triangles ([`triangles`]), triangle
//! clusters ([`cluster`], [`scene`]), the traversals (frustum culling in [`traverse`],
//! front to back in [`front_to_back`]), and the ray caster's 4-wide two-level BVH
//! ([`wide`]).
//!
//! Construction: D. Meister and J. Bittner, "Parallel Locally-Ordered Clustering for Bounding
//! Volume Hierarchy Construction" (PLOC, IEEE TVCG 2018), in our own version whose build
//! time stays O(n log n) on coincident or evenly spaced boxes (module `ploc`), followed by obvhs's
//! reinsertion (D. Meister and J. Bittner, "Parallel Reinsertion for Bounding Volume
//! Hierarchy Optimization", Eurographics 2018) and SAH leaf collapsing (then, with the
//! medium preset, reinsertion again), with obvhs's presets.
//!
//! Layout: nodes are 32 bytes (`min`, `count`, `max`, `index`) in depth-first order of sibling
//! pairs: the root is node 0, an inner node's children are `index` and `index + 1`, and every
//! child comes after its parent (so refit is one reverse sweep). Every pair sits on one
//! 64-byte cache line (module `nodes`). A leaf holds the items
//! `items[index .. index + count]`; items are stored in depth-first leaf order, so every
//! subtree's items are one contiguous range (clusters rely on this). Each item's box is kept
//! in `item_boxes` in the same order, so leaves with several items can test them one by one.
//!
//! Bad input: items with empty boxes are left out; items with NaN/infinite boxes are kept in
//! [`Bvh::unbounded`] and reported by every traversal as visible (see the crate docs).

pub(crate) mod background;
pub mod cluster;
pub mod front_to_back;
pub mod instances;
pub mod node_set;
mod nodes;
mod ploc;
pub mod policy;
mod refit;
pub mod scene;
pub mod traverse;
pub mod triangles;
pub mod wide;

pub use nodes::BvhNode;

use obvhs::bvh2::{leaf_collapser::collapse, reinsertion::ReinsertionOptimizer};
use obvhs::BvhBuildParams;
use sightline_scene::Aabb;

use crate::{AabbExt, BoxKind};

/// Build quality/speed presets (obvhs's `BvhBuildParams`), fastest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BvhPreset {
    /// PLOC with search distance 1, no reinsertion, one item per leaf.
    Fastest,
    /// Search distance 1, a little reinsertion, up to 8 items per leaf.
    VeryFast,
    /// Search distance 6 (the default: "fast preset").
    #[default]
    Fast,
    /// Search distance 14, more reinsertion (slower build, better trees).
    Medium,
}

impl BvhPreset {
    /// The obvhs parameters, with the leaf size capped at `max_leaf`.
    pub fn params(self, max_leaf: u32) -> BvhBuildParams {
        let mut p = match self {
            BvhPreset::Fastest => BvhBuildParams::fastest_build(),
            BvhPreset::VeryFast => BvhBuildParams::very_fast_build(),
            BvhPreset::Fast => BvhBuildParams::fast_build(),
            BvhPreset::Medium => BvhBuildParams::medium_build(),
        };
        p.max_prims_per_leaf = p.max_prims_per_leaf.min(max_leaf.max(1));
        p
    }
}

/// A flat binary BVH over a list of boxes (item `i` is `boxes[i]` of the build).
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    pub(crate) nodes: nodes::NodeArray,
    pub(crate) items: Vec<u32>,
    pub(crate) item_boxes: Vec<Aabb>,
    pub(crate) unbounded: Vec<u32>,
    pub(crate) item_count: usize,
    pub(crate) depth: u32,
    /// Per node, the items in its subtree, saturated at 255 (a byte a node): what
    /// [`crate::FrontToBackCursor::whole_subtrees`] decides by. A refit leaves it as it is.
    pub(crate) sizes: Vec<u8>,
    /// Item → its place in `items` (`u32::MAX`: empty or unbounded), made on the first
    /// [`Bvh::refit_changed`].
    pub(crate) slot_of: Vec<u32>,
    /// How a refit splits the tree into subtrees refitted in parallel, made on the first
    /// refit (see the `refit` module).
    pub(crate) parts: Option<refit::Parts>,
    /// What a refit along the paths of a few changed items reads (each node's parent, each
    /// item slot's leaf), made on the first such refit (see the `refit` module).
    pub(crate) paths: Option<refit::Paths>,
}

impl Bvh {
    /// [`Bvh::build`], with the new tree's SAH cost: what a rebuild policy holds refits
    /// against (see [`RefitOutcome`](crate::RefitOutcome)).
    pub(crate) fn build_costed(boxes: &[Aabb], preset: BvhPreset, max_leaf: u32) -> (Bvh, f32) {
        let bvh = Bvh::build(boxes, preset, max_leaf);
        let cost = bvh.sah_cost();
        (bvh, cost)
    }

    /// Builds a BVH over `boxes` with `preset`, at most `max_leaf` items per leaf.
    /// Empty boxes are left out; NaN/infinite ones go to [`Bvh::unbounded`].
    pub fn build(boxes: &[Aabb], preset: BvhPreset, max_leaf: u32) -> Bvh {
        let mut ids = Vec::with_capacity(boxes.len());
        let mut unbounded = Vec::new();
        for (i, b) in boxes.iter().enumerate() {
            match b.kind() {
                BoxKind::Finite => ids.push(i as u32),
                BoxKind::Unbounded => unbounded.push(i as u32),
                BoxKind::Empty => {}
            }
        }
        let mut bvh = Self::build_ids(boxes, ids, preset, max_leaf);
        bvh.unbounded = unbounded;
        bvh.item_count = boxes.len();
        bvh
    }

    /// Builds over the items `ids` (all with finite boxes) of `boxes`.
    fn build_ids(boxes: &[Aabb], ids: Vec<u32>, preset: BvhPreset, max_leaf: u32) -> Bvh {
        let mut out = Bvh { item_count: boxes.len(), ..Default::default() };
        match ids.len() {
            0 => return out,
            1 => {
                let b = boxes[ids[0] as usize];
                out.nodes.push(BvhNode { min: b.min, count: 1, max: b.max, index: 0 });
                out.items = ids;
                out.item_boxes = vec![b];
                out.depth = 1;
                out.sizes = vec![1];
                return out;
            }
            _ => {}
        }
        let params = preset.params(max_leaf);
        let obv: Vec<obvhs::aabb::Aabb> = ids.iter().map(|&i| boxes[i as usize].to_obvhs()).collect();
        let (mut bvh2, _) = ploc::build(&obv, params.ploc_search_distance, params.search_depth_threshold);
        let mut reinsertion = ReinsertionOptimizer::default();
        reinsertion.run(&mut bvh2, params.reinsertion_batch_ratio, None);
        collapse(&mut bvh2, params.max_prims_per_leaf.clamp(1, 255), params.collapse_traversal_cost);
        reinsertion.run(
            &mut bvh2,
            params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
            None,
        );
        out.relayout(&bvh2, &ids, boxes);
        out
    }

    /// Copies an obvhs tree into the depth-first pair layout with contiguous leaf items.
    fn relayout(&mut self, src: &obvhs::bvh2::Bvh2, ids: &[u32], boxes: &[Aabb]) {
        let cap = src.nodes.len();
        self.nodes = nodes::NodeArray::with_capacity(cap);
        self.items = Vec::with_capacity(ids.len());
        self.item_boxes = Vec::with_capacity(ids.len());
        let root = &src.nodes[0];
        self.nodes.push(BvhNode { min: root.aabb().min.into(), count: 0, max: root.aabb().max.into(), index: 0 });
        // (source node, destination slot, depth)
        let mut stack: Vec<(u32, u32, u32)> = vec![(0, 0, 1)];
        let mut max_depth = 1;
        while let Some((s, d, depth)) = stack.pop() {
            max_depth = max_depth.max(depth);
            let sn = &src.nodes[s as usize];
            if sn.is_leaf() {
                let first = self.items.len() as u32;
                let range = sn.first_index as usize..(sn.first_index + sn.prim_count) as usize;
                for &p in &src.primitive_indices[range] {
                    let id = ids[p as usize];
                    self.items.push(id);
                    self.item_boxes.push(boxes[id as usize]);
                }
                let dn = &mut self.nodes[d as usize];
                dn.count = sn.prim_count;
                dn.index = first;
            } else {
                let pair = self.nodes.len() as u32;
                for k in 0..2 {
                    let c = &src.nodes[sn.first_index as usize + k];
                    self.nodes.push(BvhNode { min: c.aabb().min.into(), count: 0, max: c.aabb().max.into(), index: 0 });
                }
                self.nodes[d as usize].index = pair;
                // Right first so the left subtree is laid out (and its items listed) first.
                stack.push((sn.first_index + 1, pair + 1, depth + 1));
                stack.push((sn.first_index, pair, depth + 1));
            }
        }
        self.depth = max_depth;
        self.sizes = subtree_sizes(&self.nodes);
    }

    /// The nodes (root first; empty for a tree with no finite item).
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// Item ids in leaf order (a leaf's `index..index + count` slice of this).
    pub fn items(&self) -> &[u32] {
        &self.items
    }

    /// Item boxes in leaf order (parallel to [`Bvh::items`]).
    pub fn item_boxes(&self) -> &[Aabb] {
        &self.item_boxes
    }

    /// Items whose boxes are NaN or infinite: not in the tree, always reported visible.
    pub fn unbounded(&self) -> &[u32] {
        &self.unbounded
    }

    /// Number of boxes the tree was built from (including empty and unbounded ones).
    pub fn item_count(&self) -> usize {
        self.item_count
    }

    /// Depth of the tree (1 for a single leaf, 0 for an empty tree).
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// The root box (empty when the tree has no finite item).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.aabb())
    }

    /// The SAH cost relative to the root's area: `Σ_inner A(n) + Σ_leaf A(n)·count`, over
    /// `A(root)` (traversal and intersection cost 1). 0 for an empty tree.
    pub fn sah_cost(&self) -> f32 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        refit::normalized_cost(refit::unnormalized_cost(&self.nodes), &self.nodes)
    }

    /// Heap bytes held (nodes, items, item boxes, and the parents and leaves a refit along
    /// paths reads once one has run).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.memory_bytes()
            + self.sizes.capacity()
            + self.items.capacity() * 4
            + self.item_boxes.capacity() * std::mem::size_of::<Aabb>()
            + self.unbounded.capacity() * 4
            + self.paths.as_ref().map_or(0, refit::Paths::memory_bytes)
    }

    /// Checks the structure: every child inside its parent, every finite item exactly once,
    /// children after parents. Returns a description of the first problem.
    pub fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.item_count];
        for (i, n) in self.nodes.iter().enumerate() {
            let b = n.aabb();
            if n.is_leaf() {
                let r = n.index as usize..(n.index + n.count) as usize;
                if r.end > self.items.len() {
                    return Err(format!("leaf {i} range {r:?} out of bounds"));
                }
                for s in r {
                    let id = self.items[s] as usize;
                    if id >= seen.len() || std::mem::replace(&mut seen[id], true) {
                        return Err(format!("item {id} missing or listed twice"));
                    }
                    if !b.contains(&self.item_boxes[s]) {
                        return Err(format!("leaf {i} does not contain item {id}"));
                    }
                }
            } else {
                let c = n.index as usize;
                if c <= i || c + 1 >= self.nodes.len() {
                    return Err(format!("node {i} has children at {c}"));
                }
                for k in [c, c + 1] {
                    if !b.contains(&self.nodes[k].aabb()) {
                        return Err(format!("node {i} does not contain child {k}"));
                    }
                }
            }
        }
        for &u in &self.unbounded {
            if std::mem::replace(&mut seen[u as usize], true) {
                return Err(format!("unbounded item {u} also in the tree"));
            }
        }
        // Every subtree's items are contiguous (what counting and whole subtrees rely on),
        // and the sizes are their counts.
        let mut span = vec![(0u32, 0u32); self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            span[i] = if n.is_leaf() {
                (n.index, n.count)
            } else {
                let (a, b) = (span[n.index as usize], span[n.index as usize + 1]);
                if b.0 != a.0 + a.1 {
                    return Err(format!("node {i}: its children's items are not contiguous"));
                }
                (a.0, a.1 + b.1)
            };
        }
        if self.sizes.len() != self.nodes.len() || self.sizes.iter().zip(&span).any(|(&s, t)| s as u32 != t.1.min(255))
        {
            return Err("subtree sizes do not match the tree".into());
        }
        Ok(())
    }
}

/// Per node, the items in its subtree, saturated at 255: children come after their parent
/// in the layout, so one pass from the last node back sums each pair into its parent.
fn subtree_sizes(nodes: &[BvhNode]) -> Vec<u8> {
    let mut sizes = vec![0u8; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        let k = n.index as usize;
        sizes[i] = if n.is_leaf() { n.count.min(255) as u8 } else { sizes[k].saturating_add(sizes[k + 1]) };
    }
    sizes
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// `n` random boxes over a 100 × 10 × 100 area (also the refit tests' input).
    pub(super) fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = sightline_scene::rng::Rng::new(seed);
        (0..n)
            .map(|_| {
                let c = Vec3::new(rng.range(-50.0, 50.0), rng.range(0.0, 10.0), rng.range(-50.0, 50.0));
                let e = Vec3::new(rng.range(0.1, 2.0), rng.range(0.1, 2.0), rng.range(0.1, 2.0));
                Aabb::new(c - e, c + e)
            })
            .collect()
    }

    #[test]
    fn builds_valid_trees_for_every_preset_and_size() {
        for preset in [BvhPreset::Fastest, BvhPreset::VeryFast, BvhPreset::Fast, BvhPreset::Medium] {
            for n in [0, 1, 2, 3, 17, 1000] {
                let boxes = random_boxes(n, n as u64);
                let bvh = Bvh::build(&boxes, preset, 4);
                bvh.validate().unwrap();
                assert_eq!(bvh.items().len(), n);
                assert!(bvh.sah_cost() >= 0.0);
            }
        }
    }

    /// obvhs reinserts and collapses on every worker: the tree must not depend on how many
    /// there are (culling counters and ray-cast ties follow the tree).
    #[test]
    fn trees_are_the_same_on_one_and_two_threads() {
        let boxes = random_boxes(60_000, 7);
        let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        for preset in [BvhPreset::Fast, BvhPreset::Medium] {
            let one = pool(1).install(|| Bvh::build(&boxes, preset, 4));
            let two = pool(2).install(|| Bvh::build(&boxes, preset, 4));
            one.validate().unwrap();
            assert!(one.nodes() == two.nodes() && one.items() == two.items(), "{preset:?}");
        }
    }

    #[test]
    fn bad_boxes_are_sorted_out() {
        let mut boxes = random_boxes(50, 1);
        boxes[3] = Aabb::EMPTY;
        boxes[7] = Aabb::new(Vec3::NAN, Vec3::ONE);
        boxes[9] = Aabb::new(Vec3::NEG_INFINITY, Vec3::ONE);
        let mut bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
        bvh.validate().unwrap();
        assert_eq!(bvh.items().len(), 47);
        assert_eq!(bvh.unbounded(), &[7, 9]);
        assert!(bvh.refit(&boxes));
        boxes[3] = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert!(!bvh.refit(&boxes));
    }

    #[test]
    fn refit_contains_moved_boxes() {
        let mut boxes = random_boxes(300, 2);
        let mut bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
        let fresh = bvh.sah_cost();
        for (i, b) in boxes.iter_mut().enumerate() {
            let d = Vec3::new((i % 7) as f32 * 3.0, 0.0, -((i % 5) as f32) * 4.0);
            *b = Aabb::new(b.min + d, b.max + d);
        }
        assert!(bvh.refit(&boxes));
        bvh.validate().unwrap();
        assert!(bvh.sah_cost() > fresh * 0.5);
    }

    #[test]
    fn refitting_the_changed_items_equals_refitting_all() {
        let mut boxes = random_boxes(500, 3);
        boxes[11] = Aabb::EMPTY;
        boxes[12] = Aabb::new(Vec3::NAN, Vec3::ONE);
        let mut all = Bvh::build(&boxes, BvhPreset::Fast, 4);
        let mut some = all.clone();
        for round in 0..3u32 {
            let changed: Vec<u32> = (0..500).filter(|i| (i + round) % 7 == 0 && *i != 11 && *i != 12).collect();
            for &i in &changed {
                let d = Vec3::new(round as f32 + 1.0, 0.5, -2.0);
                let b = boxes[i as usize];
                boxes[i as usize] = Aabb::new(b.min + d, b.max + d);
            }
            assert!(all.refit(&boxes));
            assert!(some.refit_changed(&boxes, &changed));
            some.validate().unwrap();
            assert_eq!(some.nodes, all.nodes, "round {round}");
        }
        // A changed item whose box changes kind needs a rebuild, as with `refit`.
        boxes[11] = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert!(!some.refit_changed(&boxes, &[11]));
        assert!(!some.refit_changed(&boxes[..10], &[]));
    }
}

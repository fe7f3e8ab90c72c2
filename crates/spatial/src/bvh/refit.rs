//! Refitting a [`Bvh`] to moved items: node boxes recomputed bottom-up with the topology
//! kept, and the tree's SAH cost measured in the same sweep (the rebuild rule of
//! [`RefitOutcome`](crate::RefitOutcome) reads it every frame).
//!
//! In the depth-first pair layout the descendants of a node form one contiguous range of
//! nodes (its children's pair, then the left child's descendants, then the right child's),
//! and every child comes after its parent. So the tree splits into a few subtrees whose
//! ranges are disjoint: each is refitted by one reverse sweep over its own range, the
//! subtrees in parallel, and then the few nodes above them. The split depends on the tree
//! alone, never on the thread count, so the boxes and the summed cost are the same however
//! many threads run it (the boxes are unions, exact in any order anyway).
//!
//! When only a few items moved in a large tree, sweeping every node costs far more than the
//! motion: one vehicle driving through a 10^8-triangle city would have its million nodes
//! swept every frame. So a refit whose changed items, and then the nodes on their paths to
//! the root, come to a small share of the nodes ([`PATH_SHARE`]; paths that turn out longer
//! give up for the sweep) refits only those nodes, children before parents (a child's index
//! is above its parent's), and keeps the SAH cost up to date by each refitted node's change.
//! The boxes are unions, so both ways give the same tree, bit for bit.
//!
//! Refitting after motion is the dynamic-BVH scheme of Wald, Boulos and Shirley (2007),
//! "Ray tracing deformable scenes using dynamic bounding volume hierarchies".

use rayon::prelude::*;
use sightline_scene::Aabb;

use super::{Bvh, BvhNode};
use crate::{AabbExt, BoxKind};

/// Trees with fewer nodes are refitted in one sequential sweep (a parallel split costs more
/// than it saves there).
const PARALLEL_NODES: usize = 8192;

/// Subtrees a large tree is split into for refitting.
const PARTS: usize = 8;

/// A refit goes along the paths of the changed items when they, and then the nodes on their
/// paths, are at most the node count over this: a node on a path is a scattered read (a
/// cache miss), where the sweep streams through the nodes in order.
const PATH_SHARE: usize = 32;

/// What refitting along paths reads: each node's parent and each item slot's leaf, and the
/// tree's SAH cost as of the last refit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Paths {
    /// Each node's parent (`u32::MAX` for the root).
    up: Vec<u32>,
    /// Each item slot's leaf.
    leaf: Vec<u32>,
    /// The unnormalized SAH cost of the tree as it stands (see [`node_cost`]).
    cost: f64,
    /// Scratch: the nodes to refit, and a bit per node for those listed.
    list: Vec<u32>,
    listed: Vec<u64>,
}

impl Paths {
    /// The parents, leaves and cost of the tree `nodes` over `slots` item slots.
    fn of(nodes: &[BvhNode], slots: usize) -> Paths {
        let mut up = vec![u32::MAX; nodes.len()];
        let mut leaf = vec![u32::MAX; slots];
        for (i, n) in nodes.iter().enumerate() {
            if n.is_leaf() {
                leaf[n.index as usize..(n.index + n.count) as usize].fill(i as u32);
            } else {
                up[n.index as usize..n.index as usize + 2].fill(i as u32);
            }
        }
        let cost = unnormalized_cost(nodes);
        Paths { up, leaf, cost, list: Vec::new(), listed: vec![0; nodes.len().div_ceil(64)] }
    }

    pub(crate) fn memory_bytes(&self) -> usize {
        (self.up.capacity() + self.leaf.capacity() + self.list.capacity()) * 4 + self.listed.capacity() * 8
    }
}

/// The SAH cost of the tree `nodes` before [`normalized_cost`]: its nodes' [`node_cost`]s
/// summed in order.
pub(crate) fn unnormalized_cost(nodes: &[BvhNode]) -> f64 {
    nodes.iter().map(node_cost).sum()
}

/// A node's share of the unnormalized SAH cost: its half area, times its item count for a
/// leaf.
#[inline]
fn node_cost(n: &BvhNode) -> f64 {
    let a = n.aabb().half_area() as f64;
    if n.is_leaf() {
        a * n.count as f64
    } else {
        a
    }
}

/// How a refit splits the tree (see the module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct Parts {
    /// Each part's descendant range of nodes (`start..end`), by increasing start.
    ranges: Vec<(u32, u32)>,
    /// The nodes outside every part's range (the parts' roots and their ancestors), by
    /// decreasing index: refitted after the parts, children first.
    top: Vec<u32>,
}

impl Parts {
    /// Splits the tree greedily: the part with the most descendants is replaced by its two
    /// children until there are [`PARTS`] parts or only leaves are left to split.
    fn of(nodes: &[BvhNode]) -> Parts {
        // last[n]: the largest node index in n's subtree (children follow their parents, so
        // a reverse sweep has both children's before the node's).
        let mut last: Vec<u32> = (0..nodes.len() as u32).collect();
        for i in (0..nodes.len()).rev() {
            let n = &nodes[i];
            if !n.is_leaf() {
                last[i] = last[n.index as usize].max(last[n.index as usize + 1]);
            }
        }
        // A part: its root, whose descendants are `root.index ..= last[root]`.
        let descendants = |r: u32| last[r as usize] + 1 - nodes[r as usize].index;
        let mut parts: Vec<u32> = vec![0];
        let mut top: Vec<u32> = Vec::new();
        while parts.len() < PARTS {
            let Some((k, _)) = parts
                .iter()
                .enumerate()
                .filter(|(_, &r)| !nodes[r as usize].is_leaf())
                .max_by_key(|(_, &r)| descendants(r))
            else {
                break;
            };
            let r = parts.swap_remove(k);
            top.push(r);
            let c = nodes[r as usize].index;
            for child in [c, c + 1] {
                if nodes[child as usize].is_leaf() {
                    top.push(child);
                } else {
                    parts.push(child);
                }
            }
        }
        // Part roots are refitted with the top nodes, after their descendants.
        top.extend(&parts);
        top.sort_unstable_by(|a, b| b.cmp(a));
        let mut ranges: Vec<(u32, u32)> =
            parts.iter().map(|&r| (nodes[r as usize].index, last[r as usize] + 1)).collect();
        ranges.sort_unstable();
        Parts { ranges, top }
    }
}

/// Refits the nodes of one range (`nodes` is the range, `base` the index of its first
/// node) from `item_boxes`; every child of a node in the range is in the range. Returns the
/// range's unnormalized SAH cost (see [`Bvh::sah_cost`]).
fn refit_range(nodes: &mut [BvhNode], base: usize, item_boxes: &[Aabb]) -> f64 {
    let mut cost = 0.0f64;
    for i in (0..nodes.len()).rev() {
        cost += refit_node(nodes, i, base, item_boxes);
    }
    cost
}

/// Refits node `i` of `nodes` (whose first node has index `base`) from its children or
/// items; returns its share of the SAH cost.
#[inline(always)]
fn refit_node(nodes: &mut [BvhNode], i: usize, base: usize, item_boxes: &[Aabb]) -> f64 {
    let n = nodes[i];
    let b = if n.is_leaf() {
        let r = n.index as usize..(n.index + n.count) as usize;
        item_boxes[r].iter().fold(Aabb::EMPTY, |acc, b| acc.union(b))
    } else {
        let c = n.index as usize - base;
        nodes[c].aabb().union(&nodes[c + 1].aabb())
    };
    nodes[i].min = b.min;
    nodes[i].max = b.max;
    node_cost(&nodes[i])
}

impl Bvh {
    /// Refits every node to new item boxes (`boxes[i]` is item `i`'s box, as in the build).
    ///
    /// Returns false (and leaves the tree unusable until rebuilt) when the boxes no longer
    /// fit the tree: a different count, or an item whose box kind changed (became empty,
    /// NaN or infinite, or the reverse) — the caller must rebuild then.
    pub fn refit(&mut self, boxes: &[Aabb]) -> bool {
        self.refit_cost(boxes).is_some()
    }

    /// [`Bvh::refit`], returning the refitted tree's [SAH cost](Bvh::sah_cost) (summed in
    /// the refit's own order, so equal to it up to rounding), or `None` where `refit` fails.
    pub(crate) fn refit_cost(&mut self, boxes: &[Aabb]) -> Option<f32> {
        if boxes.len() != self.item_count {
            return None;
        }
        for (slot, &id) in self.items.iter().enumerate() {
            let b = boxes[id as usize];
            if b.kind() != BoxKind::Finite {
                return None;
            }
            self.item_boxes[slot] = b;
        }
        if self.unbounded.iter().any(|&id| boxes[id as usize].kind() != BoxKind::Unbounded) {
            return None;
        }
        // Items that were empty must still be empty.
        let in_tree = self.items.len() + self.unbounded.len();
        let empty_now = boxes.iter().filter(|b| b.kind() == BoxKind::Empty).count();
        if in_tree + empty_now != boxes.len() {
            return None;
        }
        Some(self.refit_nodes())
    }

    /// [`Bvh::refit`] when only the items `changed` have new boxes (the others are as at the
    /// last build or refit): the cost is the changed items plus one sweep over the nodes,
    /// not a pass over every item. Returns false, as `refit` does, when a changed item's box
    /// changed kind (or an index is out of range): the caller must rebuild then.
    pub fn refit_changed(&mut self, boxes: &[Aabb], changed: &[u32]) -> bool {
        self.refit_changed_cost(boxes, changed).is_some()
    }

    /// [`Bvh::refit_changed`], returning the cost as [`Bvh::refit_cost`] does.
    pub(crate) fn refit_changed_cost(&mut self, boxes: &[Aabb], changed: &[u32]) -> Option<f32> {
        if boxes.len() != self.item_count {
            return None;
        }
        if self.slot_of.len() != self.item_count {
            self.slot_of = vec![u32::MAX; self.item_count];
            for (slot, &id) in self.items.iter().enumerate() {
                self.slot_of[id as usize] = slot as u32;
            }
        }
        for &id in changed {
            let &b = boxes.get(id as usize)?;
            match self.slot_of[id as usize] {
                u32::MAX => {
                    let was_unbounded = self.unbounded.contains(&id);
                    if b.kind() == BoxKind::Finite || was_unbounded != (b.kind() == BoxKind::Unbounded) {
                        return None;
                    }
                }
                slot => {
                    if b.kind() != BoxKind::Finite {
                        return None;
                    }
                    self.item_boxes[slot as usize] = b;
                }
            }
        }
        let budget = self.nodes.len() / PATH_SHARE;
        if changed.len() <= budget {
            if let Some(cost) = self.refit_paths(changed, budget) {
                return Some(cost);
            }
        }
        Some(self.refit_nodes())
    }

    /// Refits the nodes on the paths from the leaves of the items `changed` (whose boxes in
    /// `item_boxes` are new) to the root, children first; returns the SAH cost, updated by
    /// each refitted node's change in cost. `None`, with nothing refitted, when the paths
    /// hold more than `budget` nodes (the sweep is then cheaper).
    fn refit_paths(&mut self, changed: &[u32], budget: usize) -> Option<f32> {
        let paths = match &mut self.paths {
            Some(p) => p,
            none => none.insert(Paths::of(&self.nodes, self.items.len())),
        };
        let Paths { up, leaf, cost, list, listed } = paths;
        for &id in changed {
            let slot = self.slot_of[id as usize];
            if slot == u32::MAX {
                continue; // empty or unbounded: in no leaf
            }
            // Up to the root, or to a node another path listed (its ancestors are listed).
            let mut n = leaf[slot as usize];
            while n != u32::MAX && listed[n as usize / 64] >> (n % 64) & 1 == 0 {
                listed[n as usize / 64] |= 1 << (n % 64);
                list.push(n);
                n = up[n as usize];
            }
            if list.len() > budget {
                for n in list.drain(..) {
                    listed[n as usize / 64] &= !(1 << (n % 64));
                }
                return None;
            }
        }
        // Children have larger indices than their parents.
        list.sort_unstable_by(|a, b| b.cmp(a));
        for &n in list.iter() {
            let before = node_cost(&self.nodes[n as usize]);
            *cost += refit_node(&mut self.nodes, n as usize, 0, &self.item_boxes) - before;
            listed[n as usize / 64] &= !(1 << (n % 64));
        }
        list.clear();
        Some(normalized_cost(*cost, &self.nodes))
    }

    /// Recomputes node boxes from `item_boxes`, children before parents (large trees by
    /// subtrees in parallel, see the module docs); returns the SAH cost.
    pub(crate) fn refit_nodes(&mut self) -> f32 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let cost = if self.nodes.len() < PARALLEL_NODES {
            refit_range(&mut self.nodes, 0, &self.item_boxes)
        } else {
            let parts = self.parts.get_or_insert_with(|| Parts::of(&self.nodes));
            // Carve the parts' disjoint ranges out of the node array.
            let mut jobs: Vec<(usize, &mut [BvhNode])> = Vec::with_capacity(parts.ranges.len());
            let mut rest: &mut [BvhNode] = &mut self.nodes;
            let mut at = 0usize;
            for &(start, end) in &parts.ranges {
                let (_, tail) = std::mem::take(&mut rest).split_at_mut(start as usize - at);
                let (mine, tail) = tail.split_at_mut((end - start) as usize);
                jobs.push((start as usize, mine));
                rest = tail;
                at = end as usize;
            }
            let boxes = &self.item_boxes;
            let costs: Vec<f64> = jobs.into_par_iter().map(|(base, nodes)| refit_range(nodes, base, boxes)).collect();
            let mut cost: f64 = costs.iter().sum();
            for &i in &parts.top {
                cost += refit_node(&mut self.nodes, i as usize, 0, &self.item_boxes);
            }
            cost
        };
        if let Some(p) = &mut self.paths {
            p.cost = cost;
        }
        normalized_cost(cost, &self.nodes)
    }
}

/// An unnormalized SAH cost of the non-empty tree `nodes` over its root's half area, as
/// [`Bvh::sah_cost`] gives it (the node count for a flat root).
pub(crate) fn normalized_cost(cost: f64, nodes: &[BvhNode]) -> f32 {
    let root = nodes[0].aabb().half_area() as f64;
    if root > 0.0 {
        (cost / root) as f32
    } else {
        nodes.len() as f32
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::bvh::tests::random_boxes;
    use crate::BvhPreset;

    #[test]
    fn the_parts_cover_every_node_once() {
        let bvh = Bvh::build(&random_boxes(40_000, 5), BvhPreset::Fast, 4);
        assert!(bvh.nodes.len() >= PARALLEL_NODES);
        let parts = Parts::of(&bvh.nodes);
        assert_eq!(parts.ranges.len(), PARTS);
        let mut seen = vec![0u32; bvh.nodes.len()];
        for &(a, b) in &parts.ranges {
            (a..b).for_each(|i| seen[i as usize] += 1);
        }
        parts.top.iter().for_each(|&i| seen[i as usize] += 1);
        assert!(seen.iter().all(|&k| k == 1), "every node in exactly one part or the top");
        assert!(parts.top.windows(2).all(|w| w[0] > w[1]) && parts.top.last() == Some(&0));
        // Every part holds a sizeable share of the tree (the split is balanced).
        assert!(parts.ranges.iter().all(|&(a, b)| (b - a) as usize > bvh.nodes.len() / (4 * PARTS)));
    }

    /// A few items moved, round after round: refitting along their paths gives the full
    /// sweep's tree bit for bit and its cost (the cost kept up to date across rounds, and
    /// across a round with so many changes that the sweep runs instead).
    #[test]
    fn refitting_along_paths_equals_the_full_sweep() {
        let mut boxes = random_boxes(40_000, 7);
        let mut paths = Bvh::build(&boxes, BvhPreset::Fast, 4);
        let mut swept = paths.clone();
        for round in 0..12u32 {
            // Round 5 moves a third of the items: too many for the paths. Round 8 moves few
            // enough to try them, scattered so that their paths hold too many nodes.
            let moved: Vec<u32> = if round == 5 {
                (0..boxes.len() as u32).step_by(3).collect()
            } else if round == 8 {
                let budget = (paths.nodes.len() / PATH_SHARE) as u32;
                (0..budget).map(|k| k * 97 % boxes.len() as u32).collect()
            } else {
                (0..1 + round % 4).map(|k| (round * 7919 + k * 104_729) % boxes.len() as u32).collect()
            };
            for &i in &moved {
                let d = Vec3::new(round as f32 * 5.0 - 20.0, (i % 11) as f32, 3.0 - (i % 5) as f32 * 2.0);
                let b = &mut boxes[i as usize];
                *b = Aabb::new(b.min + d, b.max + d + Vec3::splat(0.25 * round as f32));
            }
            let cost = paths.refit_changed_cost(&boxes, &moved).unwrap();
            assert_eq!(paths.paths.is_some(), round > 0 || moved.len() < 100, "round {round}: paths taken when few");
            let full = swept.refit_cost(&boxes).unwrap();
            assert_eq!(paths.nodes, swept.nodes, "round {round}");
            paths.validate().unwrap();
            assert!((cost - full).abs() <= 1e-6 * full, "round {round}: cost {cost} against the sweep's {full}");
        }
        assert!(paths.paths.as_ref().is_some_and(|p| p.list.is_empty() && p.listed.iter().all(|&w| w == 0)));
    }

    #[test]
    fn a_parallel_refit_equals_a_sequential_one_on_any_thread_count() {
        let mut boxes = random_boxes(40_000, 6);
        let built = Bvh::build(&boxes, BvhPreset::Fast, 4);
        for (i, b) in boxes.iter_mut().enumerate() {
            let d = Vec3::new((i % 7) as f32 * 3.0, (i % 3) as f32, -((i % 5) as f32) * 4.0);
            *b = Aabb::new(b.min + d, b.max + d);
        }
        // The sequential sweep over all nodes, by hand.
        let mut sequential = built.clone();
        for (slot, &id) in built.items.iter().enumerate() {
            sequential.item_boxes[slot] = boxes[id as usize];
        }
        refit_range(&mut sequential.nodes, 0, &sequential.item_boxes);
        sequential.validate().unwrap();
        let mut costs = Vec::new();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut bvh = built.clone();
            let cost = pool.install(|| bvh.refit_cost(&boxes)).unwrap();
            assert_eq!(bvh.nodes, sequential.nodes, "{threads} threads");
            let full = bvh.sah_cost();
            assert!((cost - full).abs() <= 1e-5 * full, "the sweep's cost {cost} is the tree's {full}");
            costs.push(cost.to_bits());
        }
        assert!(costs.windows(2).all(|w| w[0] == w[1]), "the same cost bits on every thread count");
    }
}

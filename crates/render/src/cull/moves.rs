//! Moving instances in the culling state: the per-instance half of a sync after rigid
//! motion (see the `update` module for the whole).
//!
//! Each moved instance takes its node's world transform and box; each of its clusters gets
//! a new world box, octree entry (pending), draw record and, when its normal cone can cull,
//! a new cone. The clusters of one instance are one contiguous range of items, so splitting
//! the instances into ranges splits every per-cluster array too: the moved instances are
//! cut into ranges of about equal counts (quantiles of their indices), and each range is
//! written by one task on the rayon pool, with no locks. What a range asks of the shared
//! state (clusters whose cone can no longer cull, octree entries to move) is joined after.
//! Every value written depends on the instance alone, so the state is the same for any
//! number of threads.

use rayon::prelude::*;
use sightline_scene::{Aabb, Instance, NodeId, Scene};
use sightline_spatial::{ClusteredScene, RefitOutcome};

use super::{cone, ClusterDraw, Clusters, SceneMeshlets};

/// Moves below this count are done in one task (splitting costs more than it saves).
const PARALLEL_MOVES: usize = 512;

/// One range of instances and the per-cluster records of their items.
struct Range<'a> {
    /// The first instance and the first item of the range.
    first_instance: u32,
    first_item: u32,
    instances: &'a mut [Instance],
    draws: &'a mut [ClusterDraw],
    item_boxes: &'a mut [Aabb],
    cones: &'a mut [cone::Cone],
}

/// What a range leaves for the shared state.
#[derive(Default)]
struct Moved {
    /// Some instance of the range moved.
    any: bool,
    /// Items with new boxes.
    changed: Vec<u32>,
    /// Items whose cone can no longer cull.
    uncull: Vec<u32>,
    /// The largest reach of a moved instance ([`super::update::instance_reach`]).
    reach: f32,
}

/// What a range reads.
struct Shared<'a> {
    scene: &'a Scene,
    clustered: &'a ClusteredScene,
    cone_can_cull: &'a [u64],
    meshlets: &'a SceneMeshlets,
    local_cones: &'a [Vec<cone::LocalCone>],
}

impl Range<'_> {
    /// Moves the instances of `moves` (instance, node) that fall in the range.
    fn apply(self, moves: &[(u32, NodeId)], sh: &Shared) -> Moved {
        let mut out = Moved::default();
        let end = self.first_instance + self.instances.len() as u32;
        for &(i, id) in moves {
            if i < self.first_instance || i >= end {
                continue;
            }
            let Some(node) = sh.scene.node(id) else { continue };
            let inst = &mut self.instances[(i - self.first_instance) as usize];
            inst.world_from_local = node.world_matrix();
            inst.world_aabb = node.world_aabb();
            out.any = true;
            out.reach = out.reach.max(super::update::instance_reach(sh.scene, inst));
            let cols = inst.world_from_local.to_cols_array();
            for item in sh.clustered.instance_items(i) {
                out.changed.push(item);
                let k = (item - self.first_item) as usize;
                self.item_boxes[k] = sh.clustered.item_box_of(item, inst);
                self.draws[k].world_from_local = cols;
                // A cone that can cull is recomputed for the new pose; one that cannot stays
                // unable to (conservative: at worst a cluster that could be dropped is drawn).
                if sh.cone_can_cull[item as usize / 64] >> (item % 64) & 1 != 0 {
                    let it = sh.clustered.item(item);
                    let local =
                        sh.local_cones.get(sh.meshlets.slot(i) as usize).and_then(|v| v.get(it.cluster as usize));
                    let c = local.map_or(cone::Cone::NEVER, |l| l.to_world(&inst.world_from_local));
                    self.cones[k] = c;
                    if !c.can_cull() {
                        out.uncull.push(item);
                    }
                }
            }
        }
        out
    }
}

impl Clusters {
    /// Moves the instances drawn by `nodes` to their nodes' current world transforms (nodes
    /// that draw nothing here are passed over) and refits the cluster BVH. Returns what
    /// became of the BVH, or `None` when nothing moved.
    pub(super) fn move_nodes(&mut self, scene: &Scene, nodes: &[NodeId]) -> Option<RefitOutcome> {
        let mut moves = std::mem::take(&mut self.moves);
        moves.clear();
        moves.extend(nodes.iter().filter_map(|id| self.node_instance.get(*id).map(|&i| (i, *id))));
        let bounds = split_points(&moves, rayon::current_num_threads());
        let ranges = ranges(
            &bounds,
            &self.clustered,
            &mut self.instances,
            &mut self.draws,
            &mut self.item_boxes,
            &mut self.cones,
        );
        let sh = Shared {
            scene,
            clustered: &self.clustered,
            cone_can_cull: &self.cone_can_cull,
            meshlets: &self.meshlets,
            local_cones: &self.local_cones,
        };
        let parts: Vec<Moved> = if ranges.len() == 1 {
            ranges.into_iter().map(|r| r.apply(&moves, &sh)).collect()
        } else {
            ranges.into_par_iter().map(|r| r.apply(&moves, &sh)).collect()
        };
        self.moves = moves;
        let mut any = false;
        let mut changed = std::mem::take(&mut self.changed);
        changed.clear();
        for p in &parts {
            any |= p.any;
            self.reach = self.reach.max(p.reach);
            changed.extend(&p.changed);
            for &k in &p.uncull {
                self.cone_can_cull[k as usize / 64] &= !(1u64 << (k % 64));
            }
        }
        // The octree serves one method only: its entries move when that method draws next
        // (`settle_octree`), not on every frame of the others.
        if !self.octree_rebuild {
            self.octree_pending.extend(&changed);
            if self.octree_pending.len() > self.item_boxes.len() {
                // More moves than clusters: rebuilding is cheaper than the list.
                self.octree_pending.clear();
                self.octree_rebuild = true;
            }
        }
        let outcome = any.then(|| self.clustered.refit_changed(&self.item_boxes, &changed));
        self.changed = changed;
        outcome
    }
}

/// Instance indices where the ranges of [`Clusters::move_nodes`] start, after the first
/// (which starts at 0): quantiles of the moved instances, at most one range per thread and
/// one per `PARALLEL_MOVES / 2` moves, estimated from [`QUANTILE_SAMPLES`] moves spread
/// evenly over the list (exact for a list in instance order, as animations mostly give
/// it; a selection over a copy of 10^4 moves took a tenth of the sync's parallel step).
/// Any increasing points give the same state (`ranges` clamps them); only how evenly the
/// work splits depends on them.
fn split_points(moves: &[(u32, NodeId)], threads: usize) -> Vec<u32> {
    let ranges = threads.min(moves.len() / (PARALLEL_MOVES / 2)).max(1);
    if ranges == 1 {
        return Vec::new();
    }
    let n = moves.len().min(QUANTILE_SAMPLES);
    let mut samples: Vec<u32> = (0..n).map(|k| moves[k * moves.len() / n].0).collect();
    samples.sort_unstable();
    (1..ranges).map(|r| samples[r * n / ranges]).collect()
}

/// Moves sampled to place the split points.
const QUANTILE_SAMPLES: usize = 256;

/// The per-instance and per-cluster arrays cut at the instances `bounds` (increasing).
fn ranges<'a>(
    bounds: &[u32],
    clustered: &ClusteredScene,
    mut instances: &'a mut [Instance],
    mut draws: &'a mut [ClusterDraw],
    mut item_boxes: &'a mut [Aabb],
    mut cones: &'a mut [cone::Cone],
) -> Vec<Range<'a>> {
    let n = instances.len() as u32;
    let mut out = Vec::with_capacity(bounds.len() + 1);
    let (mut first_instance, mut first_item) = (0u32, 0u32);
    for &b in bounds.iter().chain(std::iter::once(&n)) {
        let b = b.clamp(first_instance, n);
        let item = clustered.first_item(b);
        let (ni, ki) = ((b - first_instance) as usize, (item - first_item) as usize);
        let (i_now, i_rest) = std::mem::take(&mut instances).split_at_mut(ni);
        let (d_now, d_rest) = std::mem::take(&mut draws).split_at_mut(ki);
        let (b_now, b_rest) = std::mem::take(&mut item_boxes).split_at_mut(ki);
        let (c_now, c_rest) = std::mem::take(&mut cones).split_at_mut(ki);
        out.push(Range { first_instance, first_item, instances: i_now, draws: d_now, item_boxes: b_now, cones: c_now });
        (instances, draws, item_boxes, cones) = (i_rest, d_rest, b_rest, c_rest);
        (first_instance, first_item) = (b, item);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sampled split points cut a list in instance order exactly at its quantiles, and
    /// one in any order (here shuffled, and two sorted halves swapped) about evenly.
    #[test]
    fn split_points_split_the_moves_about_evenly() {
        let id = NodeId::default();
        let sorted: Vec<(u32, NodeId)> = (0..10_000u32).map(|i| (3 * i, id)).collect();
        assert_eq!(split_points(&sorted, 2), vec![15_000]);
        assert_eq!(split_points(&sorted, 4), vec![7_500, 15_000, 22_500]);
        assert!(split_points(&sorted, 1).is_empty());
        assert!(split_points(&sorted[..PARALLEL_MOVES - 1], 2).is_empty(), "too few to split");
        let mut shuffled = sorted.clone();
        let mut x = 12345u64;
        for k in (1..shuffled.len()).rev() {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            shuffled.swap(k, (x >> 33) as usize % (k + 1));
        }
        let mut swapped = sorted[5_000..].to_vec();
        swapped.extend_from_slice(&sorted[..5_000]);
        for moves in [shuffled, swapped] {
            let p = split_points(&moves, 2);
            let below = moves.iter().filter(|m| m.0 < p[0]).count();
            assert!((4_000..=6_000).contains(&below), "{below} of 10,000 moves before the split");
        }
    }
}

//! The two-pass form of the `hzb` walk (Bittner, Wimmer, Piringer & Purgathofer,
//! "Coherent Hierarchical Culling", Eurographics 2004): the clusters found visible in the
//! last frame are drawn first, in one batch, front to back; the front-to-back walk then
//! tests the rest against their pyramid; finally last frame's clusters are tested against
//! the finished pyramid to make the next frame's set. A first pass of thousands of
//! clusters (a view over a whole scene) is prepared on every worker.

use std::time::Instant;

use rayon::prelude::*;
use sightline_scene::Aabb;
use sightline_spatial::{prefetch, AabbExt, Containment, Frustum};

use super::walk::{retain_ahead, Batching, Frame, Source, TwoPass, Walk};
use super::{BoxVisibility, Clusters, OcclusionQueries};
use crate::stats::ms_since;
use crate::{Result, Session};

/// A first pass drawing at least one cluster in this many has the BVH nodes holding its
/// clusters found, so that the walk does not test them ([`TwoPass::holding`]).
const HOLDING_SHARE: usize = 8;

/// Clusters of the first pass kept, ordered and gathered for the re-test per task: a pass
/// of thousands (a view over a whole scene) is prepared on every worker, a small one stays
/// one task.
const FIRST_CHUNK: usize = 1024;

impl Clusters {
    /// [`super::Method::Hzb`]: last frame's visible clusters (those still in the frustum and
    /// not facing away) are drawn first, in one batch; the front-to-back walk then tests the
    /// rest against their pyramid, starting with big batches; finally last frame's clusters
    /// are tested against the finished pyramid, and the ones not occluded join this frame's
    /// newly drawn ones as the next frame's set.
    pub(super) fn hzb_two_pass(
        &self,
        s: &mut Session,
        f: &mut Frame,
        frustum: &Frustum,
        batching: Batching,
        two: &mut TwoPass,
    ) -> Result<()> {
        let n = self.clustered.item_count();
        two.frame = two.frame.wrapping_add(1);
        if two.frame == 0 || two.drawn_in.len() != n {
            two.drawn_in.clear();
            two.drawn_in.resize(n, 0);
            two.frame = 1;
        }
        let frame = two.frame;
        let t = Instant::now();
        // Last frame's set, kept where still in the frustum and facing us. Each cluster's box
        // is tested as the frustum walk would test it (a box inside a node inside the frustum
        // is itself inside), so the set is the one the walk would find, at a cost that grows
        // with last frame's visible clusters, not with those in view.
        let eye = f.camera.view.eye;
        let boxes = &self.item_boxes;
        let backface = f.opts.backface_culling;
        // (key, cluster): the key is set for the clusters kept.
        let mut first: Vec<(u32, u32)> = two.last_visible.drain(..).map(|i| (0, i)).collect();
        // Each cluster's box and cone, which the test below reads, and its frame number,
        // which the marking after the sort writes.
        let ahead = |&(_, i): &(u32, u32)| {
            if let (Some(b), Some(d)) = (boxes.get(i as usize), two.drawn_in.get(i as usize)) {
                prefetch(b);
                prefetch(d);
                if backface && self.can_cull(i) {
                    prefetch(&self.cones[i as usize]);
                }
            }
        };
        let keep = |(key, i): &mut (u32, u32)| {
            let Some(b) = boxes.get(*i as usize) else { return false };
            // Not counted here when facing away: the walk meets them again and counts them once.
            if frustum.classify(b) == Containment::Outside || backface && self.faces_away(*i, eye) {
                return false;
            }
            // Front to back (by the distance from the eye to each box): the rasterizer's
            // coarse depth then skips the 8×8 blocks that nearer clusters of the same batch
            // already hide. The set keeps the order it was found in otherwise, which goes
            // stale as the camera moves. (A distance is ≥ 0, so its bits order like it; NaN
            // sorts last.) The example `culling_bound` orders its reference frame by the same
            // key.
            *key = b.distance_squared(eye).to_bits();
            true
        };
        // The order of (key, cluster) pairs, compared as one number (each cluster comes once,
        // so the order is the same however it is sorted).
        let order = |&(key, i): &(u32, u32)| (key as u64) << 32 | i as u64;
        // In chunks on whichever worker is free (a view over a whole scene keeps tens of
        // thousands), in order; a small set is one chunk.
        first = first
            .par_chunks(FIRST_CHUNK)
            .flat_map_iter(|c| {
                let mut c = c.to_vec();
                retain_ahead(&mut c, ahead, keep);
                c
            })
            .collect();
        first.par_sort_unstable_by_key(order);
        for &(_, i) in &first {
            two.drawn_in[i as usize] = frame;
        }
        two.holding.clear();
        // The sweep reads every node: worth it only when the first pass drew a fair share of
        // the clusters (it then saves a test for most nodes the walk reaches).
        if first.len() * HOLDING_SHARE >= n {
            let drawn_in = &two.drawn_in;
            self.clustered.bvh().nodes_holding(|i| drawn_in[i as usize] == frame, &mut two.holding);
        }
        f.cs.ms_cull += ms_since(t);
        let mut result = Ok(());
        if !first.is_empty() {
            let t = Instant::now();
            result = self.draw(s, &first, |&(_, i)| i, f);
            f.cs.ms_draw += ms_since(t);
            f.cs.batches += 1;
        }
        if result.is_ok() {
            // With last frame's occluders in place the pyramid is mostly complete: big batches.
            let first_batch = if first.is_empty() { batching.first } else { (batching.cap / 4).max(batching.first) };
            let walk = Walk { first_batch, skip: Some(&mut *two) };
            result = self.hzb_walk(s, f, frustum, Source::Bvh, walk, batching);
        }
        // Re-test last frame's clusters against the finished pyramid: the occluded ones leave
        // the set (their pixels went to nearer clusters). The tests are independent: one
        // batch, in parallel and eight boxes at a time.
        let t = Instant::now();
        let pyramid = s.pyramid();
        let projector = self.projector(f.camera, pyramid.width(), pyramid.height());
        let q = OcclusionQueries::with_projector(projector, pyramid);
        let boxes: Vec<Aabb> =
            first.par_iter().with_min_len(FIRST_CHUNK).map(|&(_, i)| self.item_boxes[i as usize]).collect();
        let mut verdicts = Vec::new();
        q.test_batch(&boxes, &mut verdicts);
        let visible = |v: &&BoxVisibility| **v == BoxVisibility::Visible;
        two.last_visible.extend(first.iter().zip(&verdicts).filter(|(_, v)| visible(v)).map(|(&(_, i), _)| i));
        f.cs.occlusion_tests += first.len() as u64;
        f.cs.occluded_boxes += verdicts.iter().filter(|v| !visible(v)).count() as u64;
        f.cs.ms_cull += ms_since(t);
        if result.is_err() {
            two.last_visible.clear();
        }
        result
    }
}

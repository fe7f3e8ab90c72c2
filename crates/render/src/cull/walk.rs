//! The culling walks of one frame, drawing through a renderer [`Session`]: the
//! front-to-back walk over the cluster BVH or the loose octree in growing batches, with
//! occlusion tests against the session's z-pyramid between batches (Greene, Kass & Miller
//! 1993), each batch found on every worker ([`FrontToBackCursor::next_batch_parallel`]);
//! its two-pass form, which draws last frame's visible set first, is in [`super::two_pass`].

use std::time::Instant;

use glam::Affine3A;
use sightline_scene::{Aabb, Camera};
use sightline_spatial::{prefetch, CullOptions, FrontToBackCursor, Frustum, NodeSet, OctreeCursor, SimdLevel, Visible};

use super::drawn::ClusterList;
use super::{ClusterDraw, Clusters, CullStats, OcclusionQueries, PREFETCH_AHEAD};
use crate::awake::join_helping;
use crate::stats::ms_since;
use crate::{DrawSource, FrameStats, RenderOptions, Result, Session};

/// One culled frame in progress: the camera and options it draws with, and its counters.
pub(super) struct Frame<'a> {
    pub camera: &'a Camera,
    pub opts: &'a RenderOptions,
    pub cs: CullStats,
    pub fs: FrameStats,
}

/// Batch sizes of a walk.
#[derive(Debug, Clone, Copy)]
pub(super) struct Batching {
    /// Clusters in the first batch of a walk that starts from an empty pyramid.
    pub first: usize,
    /// Largest batch (batches double up to it).
    pub cap: usize,
    /// Clusters nearest the eye that a BVH walk takes before its depth-first order
    /// ([`FrontToBackCursor::nearest_first`]).
    pub nearest_first: usize,
    /// Clusters of a subtree inside the frustum that the walk that tests nothing takes
    /// whole ([`FrontToBackCursor::whole_subtrees`]).
    pub whole_subtree: u32,
}

/// How [`Clusters::hzb_walk`] walks.
#[derive(Debug)]
pub(super) struct Walk<'t> {
    /// Clusters in the first draw batch (batches then double up to the batch cap).
    pub first_batch: usize,
    /// `Some(state)`: clusters already drawn in the state's frame are passed over, and the
    /// ones drawn get marked and join its `last_visible`.
    pub skip: Option<&'t mut TwoPass>,
}

/// What [`super::Method::Hzb`] keeps from frame to frame.
#[derive(Debug, Default)]
pub(super) struct TwoPass {
    /// The clusters found visible in the last frame drawn with it.
    pub(super) last_visible: Vec<u32>,
    /// Per cluster, the number of the frame that last drew it.
    pub(super) drawn_in: Vec<u32>,
    /// The current frame's number, matched against `drawn_in` (it restarts at 1 when it
    /// wraps or the cluster count changes; never 0 once started).
    pub(super) frame: u32,
    /// The BVH nodes holding a cluster of the first pass, when it drew many.
    pub(super) holding: NodeSet,
}

/// Which structure the front-to-back walk runs over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Source {
    /// The BVH over (instance, cluster) boxes.
    Bvh,
    /// The loose octree over the same boxes (Greene's original walk).
    Octree,
}

/// A resumable walk over either structure.
enum Cursor {
    Bvh(FrontToBackCursor),
    Octree(OctreeCursor),
}

impl Clusters {
    /// Starts a culled frame: the clusters in `frustum` go to `self.visible` (BVH order) and
    /// their counts to `cs`.
    pub(super) fn frustum_cull(&mut self, frustum: &Frustum, cs: &mut CullStats) {
        self.visible.clear();
        self.clustered.cull_with(frustum, CullOptions::default(), &mut self.visible);
        cs.set_in_frustum(self.visible.len() as u64);
    }

    /// True when cluster `i`'s cone can cull at all (one bit in a small array that stays in
    /// cache, so closed meshes' clusters cost no load of their cone).
    #[inline]
    pub(super) fn can_cull(&self, i: u32) -> bool {
        self.cone_can_cull[i as usize / 64] >> (i % 64) & 1 != 0
    }

    /// True when every triangle of cluster `i` faces away from `eye`, by its normal cone.
    #[inline]
    pub(super) fn faces_away(&self, i: u32, eye: glam::Vec3) -> bool {
        self.can_cull(i) && self.cones[i as usize].backfacing(eye)
    }

    /// Drops clusters whose triangles all face away from the eye (normal cones), counting them.
    fn drop_backfacing(&self, items: &mut Vec<Visible>, eye: glam::Vec3, cs: &mut CullStats) {
        let n = items.len();
        // Ask for the cones ahead, and for the draw records that `sources` reads next.
        let ahead = |v: &Visible| {
            if self.can_cull(v.index) {
                prefetch(&self.cones[v.index as usize]);
            }
        };
        retain_ahead(items, ahead, |v| {
            let keep = !self.faces_away(v.index, eye);
            if keep {
                prefetch(&self.draws[v.index as usize]);
            }
            keep
        });
        cs.culled_by_backface += (n - items.len()) as u64;
    }

    /// The draw sources of the given items (cluster indices, `index` of each element), in
    /// order, counted into `cs`.
    pub(super) fn sources<T>(&self, items: &[T], index: impl Fn(&T) -> u32, cs: &mut CullStats) -> Vec<DrawSource<'_>> {
        let mut sources: Vec<DrawSource> = Vec::with_capacity(items.len());
        self.for_each_drawn(items, index, cs, |_, d| sources.push(self.draw_source(d)));
        sources
    }

    /// Calls `f` with the index and record of each of the given clusters that draws
    /// something, in order, counting them into `cs`.
    fn for_each_drawn<T>(
        &self,
        items: &[T],
        index: impl Fn(&T) -> u32,
        cs: &mut CullStats,
        mut f: impl FnMut(u32, &ClusterDraw),
    ) {
        for (k, v) in items.iter().enumerate() {
            if let Some(a) = items.get(k + PREFETCH_AHEAD) {
                prefetch(&self.draws[index(a) as usize]);
            }
            let i = index(v);
            let d = &self.draws[i as usize];
            if d.count == 0 {
                continue;
            }
            f(i, d);
            cs.clusters_drawn += 1;
            cs.triangles_drawn += d.count as u64;
        }
    }

    /// The draw of one cluster record: its meshlet range under its instance's transform.
    pub(super) fn draw_source(&self, d: &ClusterDraw) -> DrawSource<'_> {
        let ml = self.meshlets.by_slot(d.meshlets);
        DrawSource {
            positions: &ml.positions,
            indices: &ml.indices,
            triangle_ids: Some(&ml.triangle_ids),
            world_from_local: Affine3A::from_cols_array(&d.world_from_local),
            first_triangle: d.first_triangle,
            first: d.first,
            count: d.count,
        }
    }

    /// Draws the given items into the session, counting into `f`.
    pub(super) fn draw<T>(&self, s: &mut Session, items: &[T], index: impl Fn(&T) -> u32, f: &mut Frame) -> Result<()> {
        f.fs.add(&self.draw_batch(s, items, index, f.camera, &mut f.cs)?);
        Ok(())
    }

    /// Draws the given items (cluster indices, `index` of each element) into the session
    /// under `camera`, counting them into `cs`: the clusters that draw something and their
    /// triangle ranges are listed here, and the chunks of the geometry step make them into
    /// items ([`ClusterList`]); meshlet indices point into their own positions by
    /// construction.
    pub(super) fn draw_batch<T>(
        &self,
        s: &mut Session,
        items: &[T],
        index: impl Fn(&T) -> u32,
        camera: &Camera,
        cs: &mut CullStats,
    ) -> Result<FrameStats> {
        let (mut picked, mut ranges) = (Vec::with_capacity(items.len()), Vec::with_capacity(items.len()));
        self.for_each_drawn(items, index, cs, |i, d| {
            ranges.push((picked.len() as u32, d.first, d.count));
            picked.push(i);
        });
        let simd = SimdLevel::Auto.resolve();
        let list = ClusterList { clusters: self, picked: &picked, clip_from_world: camera.clip_from_world_f64(), simd };
        s.draw_list(&list, &ranges, camera)
    }

    /// The front-to-back walk of [`super::Method::HzbOnePass`] and
    /// [`super::Method::OctreeHzb`] (and of the occluder pass that skips hidden occluders)
    /// over `source`, testing nodes and clusters against the pyramid as it fills, in batches
    /// growing from `walk.first_batch` clusters; see [`Walk`] for the rest.
    pub(super) fn hzb_walk(
        &self,
        s: &mut Session,
        f: &mut Frame,
        frustum: &Frustum,
        source: Source,
        mut walk: Walk,
        batching: Batching,
    ) -> Result<()> {
        let pyramid = s.pyramid();
        let projector = self.projector(f.camera, pyramid.width(), pyramid.height());
        let eye = f.camera.view.eye;
        let mut cursor = match source {
            Source::Bvh => Cursor::Bvh(
                self.clustered.cursor(Some(frustum), eye).nearest_first(self.clustered.bvh(), batching.nearest_first),
            ),
            Source::Octree => Cursor::Octree(OctreeCursor::new(&self.octree, Some(frustum), eye)),
        };
        let mut batch = walk.first_batch.max(1);
        let mut out: Vec<Visible> = Vec::new();
        let no_nodes = NodeSet::default();
        loop {
            let t = Instant::now();
            out.clear();
            let more = {
                let q = OcclusionQueries::with_projector(projector, s.pyramid());
                // Clusters drawn already this frame (by the two-pass form's first pass, which
                // walks the BVH) are passed over untested, and the nodes holding them too when
                // it found them.
                let skip = walk.skip.as_deref();
                let drawn = |i: u32| skip.is_some_and(|two| two.drawn_in[i as usize] == two.frame);
                let known = skip.map_or(&no_nodes, |two| &two.holding);
                match &mut cursor {
                    // On every worker (the others are kept awake by the caller, `join_helping`),
                    // each walk of the batch counting its own tests.
                    Cursor::Bvh(c) => {
                        let tests = (CullStats::default, |cs: &mut CullStats, b: &Aabb| q.counted_visible(b, cs));
                        let mut counted = Vec::new();
                        let more = c.next_batch_parallel(
                            self.clustered.bvh(),
                            tests,
                            (drawn, known),
                            batch,
                            &mut out,
                            &mut counted,
                        );
                        for cs in counted {
                            f.cs.occlusion_tests += cs.occlusion_tests;
                            f.cs.occluded_boxes += cs.occluded_boxes;
                        }
                        more
                    }
                    Cursor::Octree(c) => {
                        debug_assert!(walk.skip.is_none(), "the two-pass form walks the BVH");
                        c.next_batch(&self.octree, |b| q.counted_visible(b, &mut f.cs), batch, &mut out)
                    }
                }
            };
            debug_assert!(walk
                .skip
                .as_ref()
                .is_none_or(|two| out.iter().all(|v| two.drawn_in[v.index as usize] != two.frame)));
            // Clusters facing away would only be dropped triangle by triangle.
            if f.opts.backface_culling {
                self.drop_backfacing(&mut out, eye, &mut f.cs);
            }
            f.cs.ms_cull += ms_since(t);
            if !out.is_empty() {
                let t = Instant::now();
                self.draw(s, &out, |v| v.index, f)?;
                if let Some(two) = &mut walk.skip {
                    for v in &out {
                        two.drawn_in[v.index as usize] = two.frame;
                    }
                    two.last_visible.extend(out.iter().map(|v| v.index));
                }
                f.cs.ms_draw += ms_since(t);
                f.cs.batches += 1;
            }
            if !more {
                return Ok(());
            }
            batch = (batch * 2).min(batching.cap);
        }
    }

    /// The occluder pass's walk when nothing is tested: every cluster in the frustum, front
    /// to back in batches growing from `batching.first` clusters, with no pyramid tests. No
    /// batch depends on the pyramid here, so the walk is pipelined: the next batch is found
    /// (BVH walk, back-facing clusters dropped) on one worker while the current one is drawn
    /// on the others ([`join_helping`]: the finder then joins the drawing), so that the
    /// serial traversal and the parallel drawing overlap. The batches, and so the frame, are
    /// the same. The walk lists every cluster in the frustum, so it counts them too
    /// (`clusters_in_frustum`, the number a [`sightline_spatial::FrustumCount`] gives).
    pub(super) fn draw_front_to_back(
        &self,
        s: &mut Session,
        f: &mut Frame,
        frustum: &Frustum,
        batching: Batching,
    ) -> Result<()> {
        let eye = f.camera.view.eye;
        let backface = f.opts.backface_culling;
        let mut cursor = self
            .clustered
            .cursor(Some(frustum), eye)
            .nearest_first(self.clustered.bvh(), batching.nearest_first)
            .whole_subtrees(batching.whole_subtree);
        // One batch: the clusters, whether more may follow, and what dropping back faces counted.
        let find = |cursor: &mut FrontToBackCursor, batch: usize| {
            let t = Instant::now();
            let mut out = Vec::new();
            let mut cs = CullStats::default();
            let more = cursor.next_batch(self.clustered.bvh(), |_| true, batch, &mut out);
            cs.clusters_in_frustum = out.len() as u64;
            if backface {
                self.drop_backfacing(&mut out, eye, &mut cs);
            }
            cs.ms_cull = ms_since(t);
            (out, more, cs)
        };
        let mut batch = batching.first;
        let mut found = Some(find(&mut cursor, batch));
        while let Some((out, more, cs)) = found.take() {
            f.cs.clusters_in_frustum += cs.clusters_in_frustum;
            f.cs.culled_by_backface += cs.culled_by_backface;
            f.cs.ms_cull += cs.ms_cull;
            batch = (batch * 2).min(batching.cap);
            let draw = |s: &mut Session, f: &mut Frame| -> Result<()> {
                if out.is_empty() {
                    return Ok(());
                }
                let t = Instant::now();
                self.draw(s, &out, |v| v.index, f)?;
                f.cs.ms_draw += ms_since(t);
                f.cs.batches += 1;
                Ok(())
            };
            if more {
                // The worker that finds the next batch then helps draw this one.
                let (drawn, next) = join_helping(|| draw(s, f), |_| find(&mut cursor, batch));
                drawn?;
                found = Some(next);
            } else {
                draw(s, f)?;
            }
        }
        f.cs.set_in_frustum(f.cs.clusters_in_frustum);
        Ok(())
    }
}

/// `items.retain_mut(keep)` over items whose data lies scattered in memory: `ahead(item)`,
/// which asks for what `keep` (or the caller, soon after) will read of an item, runs
/// [`PREFETCH_AHEAD`] items before `keep`, so that the waits on memory overlap instead of
/// following one another. In a big
/// scene a frame's few thousand clusters each have their box, cone and frame number in
/// arrays of hundreds of megabytes.
pub(super) fn retain_ahead<T: Copy>(items: &mut Vec<T>, ahead: impl Fn(&T), mut keep: impl FnMut(&mut T) -> bool) {
    items.iter().take(PREFETCH_AHEAD).for_each(&ahead);
    let mut kept = 0;
    for k in 0..items.len() {
        if let Some(a) = items.get(k + PREFETCH_AHEAD) {
            ahead(a);
        }
        let mut v = items[k];
        if keep(&mut v) {
            items[kept] = v;
            kept += 1;
        }
    }
    items.truncate(kept);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In an `hzb` frame whose camera is the last frame's, the walk passes over the clusters
    /// the first pass drew (last frame's visible set) instead of testing them again, and
    /// when that set is a fair share of the clusters, over the BVH nodes holding them too:
    /// the frame makes no more tests than a first frame, which tests every box it reaches,
    /// and a quarter fewer when the nodes are passed over. Seen from above the row: 196
    /// tests in the first frame, 135 in the second (188 without the nodes passed over, 237
    /// without the clusters either); from the side, where the set is 12 clusters of 122, 56
    /// and 56. The frame itself is the first one's.
    #[test]
    fn the_walk_passes_over_the_clusters_drawn_first() {
        use crate::cull::ranges::tests::{camera, row};
        use glam::Vec3;
        let scene = row();
        let views = [(Vec3::new(12.0, 20.0, 40.0), 3), (Vec3::new(-6.0, 1.0, 1.0), 4), (Vec3::new(12.0, 3.0, 9.0), 3)];
        for (eye, quarters) in views {
            let camera = camera(eye, Vec3::new(12.0, 1.0, 1.0), 60.0);
            let mut culler = crate::Culler::new(&scene);
            let opts = RenderOptions::ids_only();
            let mut frame = || {
                let mut fb = crate::Framebuffer::new(160, 96).unwrap();
                let (cs, _) = culler.render(&scene, &camera, super::super::Method::Hzb, &mut fb, &opts).unwrap();
                (cs, fb.ids.iter().copied().collect::<Vec<u32>>())
            };
            let (first, ids) = frame();
            let (second, again) = frame();
            assert_eq!(again, ids);
            assert!(second.clusters_drawn > 10, "{eye}: {} clusters drawn", second.clusters_drawn);
            let bound = first.occlusion_tests * quarters / 4;
            assert!(second.occlusion_tests <= bound, "{eye}: {second:?} against {first:?}");
        }
    }

    /// A batch drawn as a cluster list (each chunk making its clusters into items) draws what
    /// the same clusters' draw sources, resolved beforehand, draw: over instances of two
    /// meshes, runs of one instance's clusters (one matrix) and changes between instances.
    #[test]
    fn a_cluster_list_draws_as_its_draw_sources() {
        use crate::cull::ranges::tests::{camera, row};
        use glam::Vec3;
        let scene = row();
        let camera = camera(Vec3::new(12.0, 20.0, 40.0), Vec3::new(12.0, 1.0, 1.0), 60.0);
        let culler = crate::Culler::new(&scene);
        let c = &culler.c;
        let every: Vec<u32> = (0..c.draws.len() as u32).collect();
        let opts = RenderOptions::ids_only();
        let mut renderer = crate::Renderer::new();
        let mut draw = |listed: bool| {
            let mut fb = crate::Framebuffer::new(160, 96).unwrap();
            let mut s = renderer.begin(&mut fb, &opts);
            let mut cs = CullStats::default();
            if listed {
                c.draw_batch(&mut s, &every, |&i| i, &camera, &mut cs).unwrap();
            } else {
                let sources = c.sources(&every, |&i| i, &mut cs);
                s.draw_sources_checked(&sources, &camera, false).unwrap();
            }
            s.finish();
            (fb.ids.to_vec(), fb.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>(), cs.clusters_drawn)
        };
        let (listed, sourced) = (draw(true), draw(false));
        assert_eq!(listed, sourced);
        // Clusters of several instances of both meshes show.
        let instances: std::collections::BTreeSet<_> = listed
            .0
            .iter()
            .filter(|&&id| id != 0)
            .map(|&id| scene.instances().iter().rposition(|i| i.first_triangle < id).unwrap())
            .collect();
        assert!(instances.len() >= 4, "{instances:?}");
        assert!(listed.2 > 20, "{}", listed.2);
    }

    /// `retain_ahead` keeps what `retain_mut` keeps, in order, with the changes `keep` made,
    /// and asks ahead for every item once, before `keep` sees it, for any length.
    #[test]
    fn retain_ahead_is_retain_mut_with_every_item_asked_for_first() {
        for n in 0..40u32 {
            let items: Vec<u32> = (0..n).map(|i| i * 7 % 13).collect();
            let keep = |v: &mut u32| {
                *v += 100;
                !v.is_multiple_of(3)
            };
            let mut want = items.clone();
            want.retain_mut(keep);
            let log = std::cell::RefCell::new(Vec::new());
            let mut got: Vec<(u32, u32)> = items.iter().copied().enumerate().map(|(k, v)| (k as u32, v)).collect();
            retain_ahead(
                &mut got,
                |&(k, _)| log.borrow_mut().push(('a', k)),
                |(k, v)| {
                    log.borrow_mut().push(('k', *k));
                    keep(v)
                },
            );
            assert_eq!(got.iter().map(|p| p.1).collect::<Vec<_>>(), want, "n = {n}");
            let log = log.into_inner();
            for k in 0..n {
                let at = |c| log.iter().position(|&e| e == (c, k));
                assert_eq!(log.iter().filter(|&&e| e == ('a', k)).count(), 1, "n = {n}: item {k} asked for once");
                assert!(at('a') < at('k'), "n = {n}: item {k} asked for before it is tested");
                if k >= PREFETCH_AHEAD as u32 {
                    let early = at('k').zip(log.iter().position(|&e| e == ('k', k - PREFETCH_AHEAD as u32)));
                    assert!(
                        early.is_some_and(|(_, before)| at('a').unwrap() < before),
                        "n = {n}: item {k} asked for ahead"
                    );
                }
            }
        }
    }
}

//! The occluder pass on its own: every cluster in the frustum drawn front to back into a
//! frame session, then box queries against the pyramid it leaves (the interface of a
//! culling library such as Masked Occlusion Culling: render occluders, then test boxes).

use std::time::Instant;

use sightline_scene::{Aabb, Camera};
use sightline_spatial::{BoxProjector, Frustum, FrustumCount};

use super::walk::{Frame, Source, Walk};
use super::{BoxVisibility, CullStats, Culler, OcclusionQueries, TilePyramid};
use crate::awake::join_helping;
use crate::stats::ms_since;
use crate::{FrameStats, Framebuffer, RenderOptions, Result, Session};

impl Culler {
    /// Draws every cluster in the view frustum as occluders (depth and IDs; back faces as
    /// `opts` says) into a frame session, and returns it as an [`OccluderPass`] that
    /// answers box queries against the resulting pyramid. The pass draws into `fb` (its
    /// depth and IDs, and depth-test counts when `fb` counts them), which stays borrowed
    /// while the pass lives; [`OccluderPass::finish`] writes the pixels no occluder reached
    /// as cleared. Dropped without `finish`, those pixels keep what `fb` held before.
    pub fn occluder_pass<'c>(
        &'c mut self,
        camera: &Camera,
        fb: &'c mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<(CullStats, FrameStats, OccluderPass<'c>)> {
        self.occluder_pass_with(camera, fb, opts, false)
    }

    /// [`Culler::occluder_pass`]; with `skip_hidden`, occluders are themselves tested against
    /// the pyramid as it fills (BVH nodes and clusters, as in [`Method::HzbOnePass`](super::Method::HzbOnePass)) and the
    /// hidden ones skipped. Hidden occluders cannot change a depth, so the z-buffer, IDs and
    /// pyramid are the same bit for bit, for far less work in deep scenes.
    pub fn occluder_pass_with<'c>(
        &'c mut self,
        camera: &Camera,
        fb: &'c mut Framebuffer,
        opts: &RenderOptions,
        skip_hidden: bool,
    ) -> Result<(CullStats, FrameStats, OccluderPass<'c>)> {
        let t0 = Instant::now();
        let cs = CullStats { clusters: self.c.clustered.item_count() as u64, ..Default::default() };
        let frustum = Frustum::from_camera(camera);
        let batching = self.batching(skip_hidden);
        let projector = self.c.projector(camera, fb.width(), fb.height());
        let c = &self.c;
        let mut session = self.renderer.begin(fb, opts);
        // Front to back in growing batches, so that the coarse depth test of the rasterizer
        // rejects whole triangles hidden behind earlier ones.
        let mut f = Frame { camera, opts, cs, fs: FrameStats::default() };
        if skip_hidden {
            // The tested walk does not list every cluster in the frustum: the other worker
            // counts them whenever the walk leaves it free.
            let mut count = FrustumCount::new(c.clustered.bvh(), &frustum);
            let walk = Walk { first_batch: batching.first, skip: None };
            let (r, ()) = join_helping(
                || c.hzb_walk(&mut session, &mut f, &frustum, Source::Bvh, walk, batching),
                |poll| {
                    count.run(c.clustered.bvh(), poll);
                },
            );
            r?;
            f.cs.set_in_frustum(count.finish(c.clustered.bvh()));
        } else {
            // The walk without tests lists (and counts) every cluster in the frustum.
            c.draw_front_to_back(&mut session, &mut f, &frustum, batching)?;
        }
        let Frame { mut cs, fs, .. } = f;
        // The walk's split into culling and drawing is not reported for the pass.
        cs.ms_cull = 0.0;
        cs.ms_draw = ms_since(t0);
        cs.ms_total = cs.ms_draw;
        cs.culled_by_occlusion = cs.clusters_in_frustum.saturating_sub(cs.clusters_drawn + cs.culled_by_backface);
        Ok((cs, fs, OccluderPass { session, projector }))
    }
}

/// The occluders of one frame drawn into an open frame session, and box queries against
/// their z-pyramid (see [`Culler::occluder_pass`]).
#[derive(Debug)]
pub struct OccluderPass<'c> {
    session: Session<'c>,
    projector: BoxProjector,
}

impl OccluderPass<'_> {
    /// Queries against the pyramid of the occluders.
    pub fn queries(&self) -> OcclusionQueries<'_> {
        OcclusionQueries::with_projector(self.projector, self.session.pyramid())
    }

    /// The pyramid of the occluders.
    pub fn pyramid(&self) -> TilePyramid<'_> {
        self.session.pyramid()
    }

    /// [`OcclusionQueries::test`].
    pub fn test(&self, b: &Aabb) -> BoxVisibility {
        self.queries().test(b)
    }

    /// [`OcclusionQueries::test_many`].
    pub fn test_many(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        self.queries().test_many(boxes, out)
    }

    /// [`OcclusionQueries::test_batch`].
    pub fn test_batch(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        self.queries().test_batch(boxes, out)
    }

    /// Ends the pass: the framebuffer holds the occluders' depth and IDs (and depth-test
    /// counts when it counts them; its colors are left as they were). Returns the pixels
    /// covered.
    pub fn finish(self) -> u64 {
        self.session.finish()
    }
}

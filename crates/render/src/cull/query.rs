//! Occlusion queries against the z-pyramid of drawn occluders, with a three-way answer like
//! Intel's Masked Occlusion Culling (`TestRect`: visible / occluded / outside the view), but
//! exact: a box is occluded only when no point of it could pass the depth test.
//!
//! Use: [`Culler::occluder_pass`](super::Culler::occluder_pass) draws the occluders
//! (frustum- and back-face-culled, depth and IDs only) into a frame session it returns as
//! an [`OccluderPass`](super::OccluderPass); [`OcclusionQueries::test`],
//! [`OcclusionQueries::test_many`] (one thread) or [`OcclusionQueries::test_batch`] (all
//! threads) answer box queries; then
//! [`OccluderPass::finish`](super::OccluderPass::finish) completes the frame.
//!
//! A query is two steps: [`BoxProjector`] turns the box into a conservative pixel rectangle
//! and nearest depth (or "outside", or "crosses the near plane": visible), then
//! [`TilePyramid::is_occluded`] compares that depth with the farthest depth stored over the
//! rectangle. `test_many` projects eight boxes at a time
//! ([`BoxProjector::classify_many`]) and tests each rectangle in the same loop; all three
//! entry points give the same answers.

use rayon::prelude::*;
use serde::Serialize;
use sightline_scene::{Aabb, Camera};

use sightline_spatial::{BoxImage, BoxProjector};

use super::{Rect, TilePyramid};

/// The answer to one box query.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum BoxVisibility {
    /// Some point of the box may be visible (or the box crosses the near plane).
    Visible,
    /// Every point of the box lies behind what is drawn.
    Occluded,
    /// The box lies outside the view frustum.
    OutsideView,
}

/// Box queries against one frame's pyramid.
#[derive(Debug, Clone, Copy)]
pub struct OcclusionQueries<'a> {
    projector: BoxProjector,
    pyramid: TilePyramid<'a>,
}

impl<'a> OcclusionQueries<'a> {
    /// Queries for `camera` against `pyramid`, for boxes drawn by instances whose vertex
    /// transforms reach at most `reach` world units per axis from their origins
    /// ([`BoxProjector::for_camera`]; a culler's own is [`Culler::reach`](super::Culler::reach)).
    pub fn new(camera: &Camera, pyramid: TilePyramid<'a>, reach: f32) -> Self {
        let projector = BoxProjector::for_camera(camera, pyramid.width(), pyramid.height(), reach);
        Self::with_projector(projector, pyramid)
    }

    /// Queries with a projector made once for many pyramids (one per draw batch).
    pub(crate) fn with_projector(projector: BoxProjector, pyramid: TilePyramid<'a>) -> Self {
        Self { projector, pyramid }
    }

    /// One box test of a culling walk, counted in `cs`: false only when the box is certainly
    /// hidden or off screen, i.e. nothing of it can be drawn.
    #[inline]
    pub(crate) fn counted_visible(&self, b: &Aabb, cs: &mut super::CullStats) -> bool {
        cs.occlusion_tests += 1;
        let vis = self.test(b) == BoxVisibility::Visible;
        cs.occluded_boxes += !vis as u64;
        vis
    }

    /// Tests one world-space box. Empty boxes are outside; NaN boxes are visible.
    ///
    /// [`BoxProjector::classify`] decides outside / across the near plane / a screen
    /// rectangle with nearest depth; only rectangles are tested against the pyramid
    /// ([`TilePyramid::is_occluded`]).
    #[inline]
    pub fn test(&self, b: &Aabb) -> BoxVisibility {
        self.projector.classify_with(b, |image| self.verdict(image))
    }

    /// The answer for a box's image.
    #[inline(always)]
    fn verdict(&self, image: BoxImage) -> BoxVisibility {
        match image {
            BoxImage::Rect(r) => {
                // `classify` never gives an empty rectangle (it answers `Outside` instead).
                debug_assert!(!r.is_empty());
                let rect = Rect { x0: r.x0, y0: r.y0, x1: r.x1 - 1, y1: r.y1 - 1 };
                if self.pyramid.is_occluded(rect, r.depth) {
                    BoxVisibility::Occluded
                } else {
                    BoxVisibility::Visible
                }
            }
            BoxImage::Outside => BoxVisibility::OutsideView,
            BoxImage::CrossesNear => BoxVisibility::Visible,
        }
    }

    /// Tests many boxes on the calling thread; `out[i]` answers `boxes[i]` (`out` is cleared
    /// first). The same answers as [`OcclusionQueries::test`] box by box, but the boxes are
    /// projected eight at a time ([`BoxProjector::classify_many`]).
    pub fn test_many(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.reserve(boxes.len());
        self.projector.classify_many(boxes, |_, image| out.push(self.verdict(image)));
    }

    /// Tests many boxes, in parallel (chunks of [`OcclusionQueries::test_many`]); `out[i]`
    /// answers `boxes[i]`.
    pub fn test_batch(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.resize(boxes.len(), BoxVisibility::Visible);
        out.par_chunks_mut(1024).zip(boxes.par_chunks(1024)).for_each(|(out, boxes)| {
            self.projector.classify_many(boxes, |i, image| out[i] = self.verdict(image));
        });
    }
}

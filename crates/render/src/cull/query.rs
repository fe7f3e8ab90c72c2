//! Occlusion queries against the z-pyramid of drawn occluders, with a three-way answer like
//! Intel's Masked Occlusion Culling (`TestRect`: visible / occluded / outside the view), but
//! exact: a box is occluded only when no point of it could pass the depth test.
//!
//! Use: [`Culler::occluder_pass`](super::Culler::occluder_pass) draws the occluders
//! (frustum- and back-face-culled, depth and IDs only) and leaves the frame session open;
//! [`OcclusionQueries::test`] or [`OcclusionQueries::test_batch`] answer box queries; then
//! [`Culler::end_occluder_pass`](super::Culler::end_occluder_pass) writes the frame out.

use rayon::prelude::*;
use serde::Serialize;
use sightline_scene::{Aabb, Camera};

use sightline_spatial::{BoxImage, BoxProjector};

use super::{to_rect, TilePyramid};

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
    /// Queries for `camera` against `pyramid`.
    pub fn new(camera: &Camera, pyramid: TilePyramid<'a>) -> Self {
        Self { projector: BoxProjector::new(camera.clip_from_world(), pyramid.width(), pyramid.height()), pyramid }
    }

    /// Tests one world-space box. Empty boxes are outside; NaN boxes are visible.
    ///
    /// [`BoxProjector::classify`] decides outside / across the near plane / a screen
    /// rectangle with nearest depth; only rectangles are tested against the pyramid
    /// ([`TilePyramid::is_occluded`]).
    #[inline]
    pub fn test(&self, b: &Aabb) -> BoxVisibility {
        self.projector.classify_with(b, |image| match image {
            BoxImage::Rect(r) => match to_rect(&r) {
                Some(rect) if self.pyramid.is_occluded(rect, r.depth) => BoxVisibility::Occluded,
                Some(_) => BoxVisibility::Visible,
                None => BoxVisibility::OutsideView,
            },
            BoxImage::Outside => BoxVisibility::OutsideView,
            BoxImage::CrossesNear => BoxVisibility::Visible,
        })
    }

    /// Tests many boxes on the calling thread; `out[i]` answers `boxes[i]` (`out` is cleared
    /// first). One tight loop, with the camera matrix and the pyramid's fields in registers.
    pub fn test_many(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.extend(boxes.iter().map(|b| self.test(b)));
    }

    /// Tests many boxes, in parallel; `out[i]` answers `boxes[i]`.
    pub fn test_batch(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.par_extend(boxes.par_iter().with_min_len(1024).map(|b| self.test(b)));
    }
}

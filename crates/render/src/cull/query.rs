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
use sightline_spatial::BoxProjector;

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
    clip_from_world: glam::Mat4,
    projector: BoxProjector,
    pyramid: TilePyramid<'a>,
}

impl<'a> OcclusionQueries<'a> {
    /// Queries for `camera` against `pyramid`.
    pub fn new(camera: &Camera, pyramid: TilePyramid<'a>) -> Self {
        Self {
            clip_from_world: camera.clip_from_world(),
            projector: BoxProjector::new(camera.clip_from_world(), pyramid.width(), pyramid.height()),
            pyramid,
        }
    }

    /// Tests one world-space box. Empty boxes are outside; NaN boxes are visible.
    ///
    /// The eight corners are formed once in clip space (a corner plus multiples of the
    /// matrix columns); a box is outside the view when all eight lie beyond one clip plane —
    /// exact for the box, and cheaper than six plane tests. Only boxes that remain are
    /// projected to a rectangle and tested against the pyramid.
    pub fn test(&self, b: &Aabb) -> BoxVisibility {
        if b.is_empty() {
            return if b.min.is_nan() || b.max.is_nan() { BoxVisibility::Visible } else { BoxVisibility::OutsideView };
        }
        if self.outside_clip(b) {
            return BoxVisibility::OutsideView;
        }
        let r = self.projector.project(b);
        if r.crosses_near {
            return BoxVisibility::Visible;
        }
        match to_rect(&r) {
            None => BoxVisibility::OutsideView,
            Some(rect) if self.pyramid.is_occluded(rect, r.depth) => BoxVisibility::Occluded,
            Some(_) => BoxVisibility::Visible,
        }
    }

    /// True when all eight corners lie outside one of the six clip planes.
    #[inline]
    fn outside_clip(&self, b: &Aabb) -> bool {
        let m = &self.clip_from_world;
        let base = *m * b.min.extend(1.0);
        let e = b.max - b.min;
        let (dx, dy, dz) = (m.x_axis * e.x, m.y_axis * e.y, m.z_axis * e.z);
        let mut all = 0b11_1111u32;
        for i in 0..8u32 {
            let c = base + dx * (i & 1) as f32 + dy * ((i >> 1) & 1) as f32 + dz * ((i >> 2) & 1) as f32;
            let o = (c.x > c.w) as u32
                | ((c.x < -c.w) as u32) << 1
                | ((c.y > c.w) as u32) << 2
                | ((c.y < -c.w) as u32) << 3
                | ((c.z > c.w) as u32) << 4
                | ((c.z < -c.w) as u32) << 5;
            all &= o;
        }
        all != 0
    }

    /// Tests many boxes, in parallel; `out[i]` answers `boxes[i]`.
    pub fn test_batch(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.par_extend(boxes.par_iter().with_min_len(1024).map(|b| self.test(b)));
    }
}

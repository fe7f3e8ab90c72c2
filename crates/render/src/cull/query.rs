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

use super::TilePyramid;

/// Clip-space w below which a corner counts as at or behind the eye.
const W_EPS: f32 = 1e-6;
/// Pixels added around the projected corners (1/256-pixel snapping plus float error).
const PIXEL_MARGIN: f32 = 1.0 / 128.0;
/// Subtracted from the nearest window depth (float error of the projection).
const DEPTH_MARGIN: f32 = 1e-6;

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
    pyramid: TilePyramid<'a>,
}

impl<'a> OcclusionQueries<'a> {
    /// Queries for `camera` against `pyramid`.
    pub fn new(camera: &Camera, pyramid: TilePyramid<'a>) -> Self {
        Self { clip_from_world: camera.clip_from_world(), pyramid }
    }

    /// Tests one world-space box. Empty boxes are outside; NaN boxes are visible.
    ///
    /// The eight corners are formed once in clip space (a corner plus multiples of the
    /// matrix columns), as eight-wide arrays the compiler vectorizes. A box is outside the
    /// view when all eight lie beyond one clip plane (exact for the box, cheaper than six
    /// plane tests); it is visible when a corner is behind the near plane; otherwise its
    /// conservative screen rectangle and nearest depth (the margins of
    /// `sightline_spatial::BoxProjector`) are tested against the pyramid.
    pub fn test(&self, b: &Aabb) -> BoxVisibility {
        if b.is_empty() {
            return if b.min.is_nan() || b.max.is_nan() { BoxVisibility::Visible } else { BoxVisibility::OutsideView };
        }
        if !(b.min.is_finite() && b.max.is_finite()) {
            return BoxVisibility::Visible;
        }
        let m = &self.clip_from_world;
        let base = *m * b.min.extend(1.0);
        let e = b.max - b.min;
        let (dx, dy, dz) = (m.x_axis * e.x, m.y_axis * e.y, m.z_axis * e.z);
        let (mut cx, mut cy, mut cz, mut cw) = ([0f32; 8], [0f32; 8], [0f32; 8], [0f32; 8]);
        for i in 0..8 {
            let (fx, fy, fz) = ((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32);
            cx[i] = base.x + dx.x * fx + dy.x * fy + dz.x * fz;
            cy[i] = base.y + dx.y * fx + dy.y * fy + dz.y * fz;
            cz[i] = base.z + dx.z * fx + dy.z * fy + dz.z * fz;
            cw[i] = base.w + dx.w * fx + dy.w * fy + dz.w * fz;
        }
        let all = |f: &dyn Fn(usize) -> bool| (0..8).all(f);
        if all(&|i| cx[i] > cw[i])
            || all(&|i| cx[i] < -cw[i])
            || all(&|i| cy[i] > cw[i])
            || all(&|i| cy[i] < -cw[i])
            || all(&|i| cz[i] > cw[i])
            || all(&|i| cz[i] < -cw[i])
        {
            return BoxVisibility::OutsideView;
        }
        // A corner behind the near plane (or at the eye): the box may cover anything.
        if !all(&|i| cw[i] > W_EPS && cz[i] >= -cw[i]) {
            return BoxVisibility::Visible;
        }
        let (mut x0, mut x1, mut y0, mut y1, mut z0) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN, f32::MAX);
        for i in 0..8 {
            let inv = 1.0 / cw[i];
            let (x, y, z) = (cx[i] * inv, cy[i] * inv, cz[i] * inv);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
            z0 = z0.min(z);
        }
        let (w, h) = (self.pyramid.width(), self.pyramid.height());
        let (wf, hf) = (w as f32, h as f32);
        // Pixel space, y down; pixel i spans [i, i + 1). Truncation stands in for floor since
        // everything at or below 0 clamps to 0.
        let clamp = |v: f32, hi: u32| {
            if v <= 0.0 {
                0
            } else if v >= hi as f32 {
                hi
            } else {
                v as u32
            }
        };
        let px0 = clamp((x0 + 1.0) * 0.5 * wf - PIXEL_MARGIN, w);
        let px1 = clamp((x1 + 1.0) * 0.5 * wf + PIXEL_MARGIN + 1.0, w);
        let py0 = clamp((1.0 - y1) * 0.5 * hf - PIXEL_MARGIN, h);
        let py1 = clamp((1.0 - y0) * 0.5 * hf + PIXEL_MARGIN + 1.0, h);
        if px0 >= px1 || py0 >= py1 {
            return BoxVisibility::OutsideView;
        }
        let depth = ((z0 + 1.0) * 0.5 - DEPTH_MARGIN).clamp(0.0, 1.0);
        let rect = super::Rect { x0: px0, y0: py0, x1: px1 - 1, y1: py1 - 1 };
        if self.pyramid.is_occluded(rect, depth) {
            BoxVisibility::Occluded
        } else {
            BoxVisibility::Visible
        }
    }

    /// Tests many boxes, in parallel; `out[i]` answers `boxes[i]`.
    pub fn test_batch(&self, boxes: &[Aabb], out: &mut Vec<BoxVisibility>) {
        out.clear();
        out.par_extend(boxes.par_iter().with_min_len(1024).map(|b| self.test(b)));
    }
}

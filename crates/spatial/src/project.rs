//! Projection of a world box to a conservative screen rectangle and nearest window depth —
//! the query shape of hierarchical z-buffer tests (Greene, Kass & Miller 1993; the
//! rectangle-instead-of-box idea of Intel's Masked Occlusion Culling `TestRect`).
//!
//! Window conventions (DESIGN.md): `x_w = (x_ndc + 1)/2 · W`, `y_w = (1 − y_ndc)/2 · H`,
//! `z_w = (z_ndc + 1)/2`. The eight corners are projected; when any corner has `w ≤ ε` or lies
//! in front of the near plane (`z < −w`), the box crosses the near plane (or the eye plane) and
//! the answer is "covers the whole screen, nearest depth 0". Otherwise the rectangle is the
//! pixel-space bounds of the corners grown by a small margin (vertex snapping to 1/256 pixel
//! and float error), rounded outwards and clamped to the viewport, and the depth is the
//! smallest corner window z minus a small margin. Since the view depth is linear over a box
//! and window z is monotonic in it, the box's nearest point is one of its corners.

use glam::Mat4;
use sightline_scene::Aabb;

use crate::{AabbExt, BoxKind};

/// Smallest clip `w` accepted as "in front of the eye".
const W_EPS: f32 = 1e-6;
/// Margin in pixels added around the projected corners (1/256-pixel snapping plus float error).
const PIXEL_MARGIN: f32 = 1.0 / 128.0;
/// Margin subtracted from the nearest window depth.
const DEPTH_MARGIN: f32 = 1e-6;

/// A pixel rectangle `[x0, x1) × [y0, y1)` (row 0 at the top) with the nearest window depth of
/// the box that made it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
    /// Nearest window depth in [0, 1] (0 when the box crosses the near plane).
    pub depth: f32,
    /// True when the box crosses the near plane (or lies partly behind the eye): the rect is
    /// the whole viewport and the depth 0, so an occlusion test must report it visible.
    pub crosses_near: bool,
}

impl ScreenRect {
    /// The rectangle of a box that projects to nothing (empty box, or off screen).
    pub const EMPTY: ScreenRect = ScreenRect { x0: 0, y0: 0, x1: 0, y1: 0, depth: 1.0, crosses_near: false };

    /// True when no pixel is covered.
    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    /// The whole `width × height` viewport at depth 0.
    pub fn full(width: u32, height: u32) -> ScreenRect {
        ScreenRect { x0: 0, y0: 0, x1: width, y1: height, depth: 0.0, crosses_near: true }
    }

    /// Number of pixels covered.
    pub fn area(&self) -> u64 {
        if self.is_empty() {
            0
        } else {
            (self.x1 - self.x0) as u64 * (self.y1 - self.y0) as u64
        }
    }
}

/// Where a box lands on the screen ([`BoxProjector::classify`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoxImage {
    /// Outside the view frustum (or covering no pixel): nothing of it can be drawn.
    Outside,
    /// At or behind the near plane (or unbounded): it may cover any pixel at any depth.
    CrossesNear,
    /// In front of the near plane: a conservative rectangle and its nearest depth.
    Rect(ScreenRect),
}

/// Projects boxes with one `clip_from_world` onto a `width × height` viewport.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxProjector {
    clip_from_world: Mat4,
    width: u32,
    height: u32,
}

impl BoxProjector {
    /// A projector for `clip_from_world` and a `width × height` viewport.
    pub fn new(clip_from_world: Mat4, width: u32, height: u32) -> BoxProjector {
        BoxProjector { clip_from_world, width, height }
    }

    /// The box's conservative screen rectangle and nearest depth (see the module docs).
    /// Empty boxes and boxes outside the view give [`ScreenRect::EMPTY`]; NaN/infinite boxes
    /// and boxes crossing the near plane give the full screen.
    #[inline]
    pub fn project(&self, b: &Aabb) -> ScreenRect {
        match self.classify(b) {
            BoxImage::Outside => ScreenRect::EMPTY,
            BoxImage::CrossesNear => ScreenRect::full(self.width, self.height),
            BoxImage::Rect(r) => r,
        }
    }

    /// Where the box lands: outside the view (all eight corners beyond one clip plane, or no
    /// pixel covered), across the near plane (a corner at or behind it: it may cover
    /// anything), or a conservative rectangle with its nearest depth.
    ///
    /// The corners are formed once in clip space (one corner plus multiples of the matrix
    /// columns) as eight-wide arrays that the compiler vectorizes.
    #[inline]
    pub fn classify(&self, b: &Aabb) -> BoxImage {
        match b.kind() {
            BoxKind::Empty => return BoxImage::Outside,
            BoxKind::Unbounded => return BoxImage::CrossesNear,
            BoxKind::Finite => {}
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
            return BoxImage::Outside;
        }
        // NaN-safe: a NaN w or z fails this test and takes the "crosses" path.
        if !all(&|i| cw[i] > W_EPS && cz[i] >= -cw[i]) {
            return BoxImage::CrossesNear;
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
        if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
            return BoxImage::CrossesNear;
        }
        let (w, h) = (self.width, self.height);
        let (wf, hf) = (w as f32, h as f32);
        // Pixel space, y down; pixel i spans [i, i + 1): covered columns are floor(px0) ..=
        // floor(px1). `clamp` sends everything ≤ 0 to 0, so truncation stands in for floor
        // (for values in (−1, 0) the end bound grows by one pixel: still conservative).
        let clamp = |v: f32, hi: u32| -> u32 {
            if v <= 0.0 {
                0
            } else if v >= hi as f32 {
                hi
            } else {
                v as u32
            }
        };
        let rx0 = clamp((x0 + 1.0) * 0.5 * wf - PIXEL_MARGIN, w);
        let rx1 = clamp((x1 + 1.0) * 0.5 * wf + PIXEL_MARGIN + 1.0, w);
        let ry0 = clamp((1.0 - y1) * 0.5 * hf - PIXEL_MARGIN, h);
        let ry1 = clamp((1.0 - y0) * 0.5 * hf + PIXEL_MARGIN + 1.0, h);
        if rx0 >= rx1 || ry0 >= ry1 {
            return BoxImage::Outside;
        }
        let depth = ((z0 + 1.0) * 0.5 - DEPTH_MARGIN).clamp(0.0, 1.0);
        BoxImage::Rect(ScreenRect { x0: rx0, y0: ry0, x1: rx1, y1: ry1, depth, crosses_near: false })
    }
}

/// Projects one box: see [`BoxProjector::project`].
pub fn project_box(b: &Aabb, clip_from_world: &Mat4, width: u32, height: u32) -> ScreenRect {
    BoxProjector::new(*clip_from_world, width, height).project(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sightline_scene::Camera;

    fn cam() -> Camera {
        Camera::perspective_look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 60.0, 1.5, 0.5, 100.0).unwrap()
    }

    #[test]
    fn box_crossing_near_plane_covers_screen_at_depth_zero() {
        let c = cam();
        let m = c.clip_from_world();
        // Straddles the near plane at z = 4.5.
        let b = Aabb::new(Vec3::new(-0.1, -0.1, 4.3), Vec3::new(0.1, 0.1, 4.7));
        let r = project_box(&b, &m, 96, 64);
        assert!(r.crosses_near);
        assert_eq!((r.x0, r.y0, r.x1, r.y1, r.depth), (0, 0, 96, 64, 0.0));
        // Entirely behind the eye: all corners lie beyond the near plane, so nothing of it
        // can be drawn.
        let b = Aabb::new(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0));
        assert!(project_box(&b, &m, 96, 64).is_empty());
        // NaN box: full screen.
        assert!(project_box(&Aabb::new(Vec3::NAN, Vec3::ONE), &m, 96, 64).crosses_near);
        assert!(project_box(&Aabb::EMPTY, &m, 96, 64).is_empty());
    }

    #[test]
    fn rect_contains_every_projected_corner() {
        let c = cam();
        let m = c.clip_from_world();
        let (w, h) = (96u32, 64u32);
        let mut rng = sightline_scene::rng::Rng::new(5);
        let mut tested = 0;
        for _ in 0..500 {
            let lo = Vec3::new(rng.range(-3.0, 3.0), rng.range(-2.0, 2.0), rng.range(-10.0, 3.0));
            let b = Aabb::new(lo, lo + Vec3::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0)));
            let r = project_box(&b, &m, w, h);
            assert!(!r.crosses_near);
            let mut any_on = false;
            for p in b.corners() {
                let cl = m * p.extend(1.0);
                let ndc = cl.truncate() / cl.w;
                let (xw, yw, zw) =
                    ((ndc.x + 1.0) * 0.5 * w as f32, (1.0 - ndc.y) * 0.5 * h as f32, (ndc.z + 1.0) * 0.5);
                assert!(r.is_empty() || r.depth <= zw, "depth {} > corner {zw}", r.depth);
                // Corners on screen lie in the rect.
                if (0.0..w as f32).contains(&xw) && (0.0..h as f32).contains(&yw) {
                    any_on = true;
                    assert!(!r.is_empty());
                    assert!(
                        r.x0 as f32 <= xw && xw < r.x1 as f32 && r.y0 as f32 <= yw && yw < r.y1 as f32,
                        "corner ({xw}, {yw}) outside {r:?}"
                    );
                }
            }
            tested += any_on as u32;
        }
        assert!(tested > 100, "{tested}");
    }

    #[test]
    fn offscreen_box_is_empty() {
        let c = cam();
        let m = c.clip_from_world();
        let b = Aabb::new(Vec3::new(30.0, -0.5, -1.0), Vec3::new(31.0, 0.5, 0.0));
        assert!(project_box(&b, &m, 96, 64).is_empty());
    }
}

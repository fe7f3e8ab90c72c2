//! View frusta: six planes extracted from any `clip_from_world` matrix, and conservative
//! box–frustum classification.
//!
//! * Plane extraction: G. Gribb and K. Hartmann, "Fast Extraction of Viewing Frustum Planes
//!   from the World-View-Projection Matrix" (2001). With rows `r0..r3` of `clip_from_world`
//!   and OpenGL clip space (`−w ≤ x, y, z ≤ w`): left `r3 + r0`, right `r3 − r0`, bottom
//!   `r3 + r1`, top `r3 − r1`, near `r3 + r2`, far `r3 − r2`. It needs no knowledge of the
//!   projection, so perspective, orthographic and oblique matrices all work. Planes point
//!   inwards and are normalized (in f64 when the matrix is given in f64).
//! * Classification: the n/p-vertex test per plane, with plane masking and plane coherency
//!   from U. Assarsson and T. Möller, "Optimized View Frustum Culling Algorithms for Bounding
//!   Boxes", Journal of Graphics Tools 5(1), 2000. A mask bit set means "this plane still has
//!   to be tested"; a box fully inside a plane clears its bit so the box's children skip it.
//!   Coherency starts with the plane that rejected the box in the previous frame.
//!
//! Conservative: a box is `Outside` only when its p-vertex is behind some plane by more than a
//! small relative tolerance (float error of the distance itself), so a box touching the
//! frustum is never `Outside`; `Inside` likewise requires a margin.

use glam::{DMat4, Mat4, Vec3};
use sightline_scene::{Aabb, Camera};

use crate::{Plane, Sphere};

/// Bitmask of frustum planes still to test (bit `i` = plane `i`).
pub type PlaneMask = u8;
/// All six planes.
pub const ALL_PLANES: PlaneMask = 0b11_1111;

/// Relative float tolerance of a box–plane distance (a few ulps of the summed magnitudes).
const REL_TOL: f32 = 4e-6;

/// Result of classifying a volume against a frustum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Containment {
    /// Entirely outside (behind at least one plane).
    Outside,
    /// Possibly crossing the boundary (conservative default).
    Intersecting,
    /// Entirely inside all planes tested.
    Inside,
}

/// Six inward-facing planes: left, right, bottom, top, near, far (indices 0..6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    planes: [Plane; 6],
    abs_normals: [Vec3; 6],
}

impl Frustum {
    /// Index of the left plane.
    pub const LEFT: usize = 0;
    /// Index of the right plane.
    pub const RIGHT: usize = 1;
    /// Index of the bottom plane.
    pub const BOTTOM: usize = 2;
    /// Index of the top plane.
    pub const TOP: usize = 3;
    /// Index of the near plane.
    pub const NEAR: usize = 4;
    /// Index of the far plane.
    pub const FAR: usize = 5;

    /// The frustum of a `clip_from_world` matrix (Gribb–Hartmann, OpenGL z in [−w, w]).
    pub fn from_clip_from_world(m: &Mat4) -> Frustum {
        Self::from_clip_from_world_f64(&m.as_dmat4())
    }

    /// Like [`Frustum::from_clip_from_world`], with the plane sums formed in f64 (less
    /// cancellation for far-away far planes).
    ///
    /// A non-finite or degenerate row combination yields [`Plane::DEGENERATE`], which never
    /// rejects and never accepts, so a bad matrix culls less, never more, and reports nothing
    /// as fully inside.
    pub fn from_clip_from_world_f64(m: &DMat4) -> Frustum {
        let (r0, r1, r2, r3) = (m.row(0), m.row(1), m.row(2), m.row(3));
        let planes = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 + r2, r3 - r2].map(Plane::from_dvec4);
        Self::from_planes(planes)
    }

    /// The frustum of a camera (its f64 `clip_from_world`).
    pub fn from_camera(camera: &Camera) -> Frustum {
        Self::from_clip_from_world_f64(&camera.clip_from_world_f64())
    }

    /// A frustum from six inward-facing planes (any convex region bounded by six planes).
    pub fn from_planes(planes: [Plane; 6]) -> Frustum {
        Frustum { planes, abs_normals: planes.map(|p| p.normal.abs()) }
    }

    /// The six planes: left, right, bottom, top, near, far.
    pub fn planes(&self) -> &[Plane; 6] {
        &self.planes
    }

    /// True when `p` is inside or on every plane.
    pub fn contains_point(&self, p: Vec3) -> bool {
        self.planes.iter().all(|pl| pl.distance(p) >= 0.0)
    }

    /// Classifies a box against all six planes. Empty boxes are `Outside`; boxes with NaN or
    /// infinite coordinates are `Intersecting`.
    pub fn classify(&self, b: &Aabb) -> Containment {
        let mut mask = ALL_PLANES;
        self.classify_masked(b, &mut mask)
    }

    /// The frustum test of a culling walk: true when `b` lies outside `frustum` (never
    /// without one, or once `mask` holds no plane left to test), testing only the planes in
    /// `mask` and clearing those `b` is fully inside of, for its children.
    #[inline]
    pub(crate) fn excludes(frustum: Option<&Frustum>, b: &Aabb, mask: &mut PlaneMask) -> bool {
        match frustum {
            Some(f) => *mask != 0 && f.classify_masked(b, mask) == Containment::Outside,
            None => false,
        }
    }

    /// Classifies a box against the planes in `mask`, clearing the bits of planes the box is
    /// fully inside (so that children of this box may skip them). `Inside` means inside every
    /// plane of the original mask.
    #[inline]
    pub fn classify_masked(&self, b: &Aabb, mask: &mut PlaneMask) -> Containment {
        let mut start = 0u8;
        self.classify_coherent(b, mask, &mut start)
    }

    /// Like [`Frustum::classify_masked`], testing plane `*start` first (plane coherency); when a
    /// plane rejects the box, its index is stored in `*start` for next time.
    #[inline]
    pub fn classify_coherent(&self, b: &Aabb, mask: &mut PlaneMask, start: &mut u8) -> Containment {
        let mut tests = 0u32;
        self.classify_counted(b, mask, start, &mut tests)
    }

    /// The classification kernel; also counts single plane tests in `tests`.
    #[inline]
    pub(crate) fn classify_counted(
        &self,
        b: &Aabb,
        mask: &mut PlaneMask,
        start: &mut u8,
        tests: &mut u32,
    ) -> Containment {
        if !b.min.cmple(b.max).all() {
            // Empty, or NaN somewhere.
            if b.min.is_nan() || b.max.is_nan() {
                return Containment::Intersecting;
            }
            return Containment::Outside;
        }
        if *mask == 0 {
            return Containment::Inside;
        }
        let c = (b.min + b.max) * 0.5;
        let e = (b.max - b.min) * 0.5;
        let ca = c.abs();
        let s = (*start as usize).min(5);
        for k in 0..6 {
            let i = if k == 0 {
                s
            } else if k <= s {
                k - 1
            } else {
                k
            };
            if *mask & (1 << i) == 0 {
                continue;
            }
            *tests += 1;
            let pl = &self.planes[i];
            let an = self.abs_normals[i];
            let dc = pl.normal.dot(c) + pl.d;
            let r = an.dot(e);
            let tol = REL_TOL * (an.dot(ca) + r + pl.d.abs());
            if dc + r < -tol {
                *start = i as u8;
                return Containment::Outside;
            }
            if dc - r > tol {
                *mask &= !(1 << i);
            }
        }
        if *mask == 0 {
            Containment::Inside
        } else {
            Containment::Intersecting
        }
    }

    /// Classifies a sphere against all six planes (conservative like boxes).
    pub fn classify_sphere(&self, s: &Sphere) -> Containment {
        if s.radius < 0.0 {
            return Containment::Outside;
        }
        if !s.radius.is_finite() || !s.center.is_finite() {
            return Containment::Intersecting; // NaN too
        }
        let mut all_inside = true;
        for pl in &self.planes {
            let d = pl.distance(s.center);
            let tol = REL_TOL * (pl.normal.abs().dot(s.center.abs()) + pl.d.abs() + s.radius);
            if d < -s.radius - tol {
                return Containment::Outside;
            }
            if d <= s.radius + tol {
                all_inside = false;
            }
        }
        if all_inside {
            Containment::Inside
        } else {
            Containment::Intersecting
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec3, Vec4};
    use sightline_scene::{Projection, View};

    fn cams() -> Vec<Camera> {
        let view = View::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        vec![
            Camera::new(view, Projection::perspective(sightline_scene::Angle::radians(1.0), 1.5, 0.5, 40.0).unwrap())
                .unwrap(),
            Camera::new(view, Projection::frustum(-0.1, 0.4, -0.3, 0.2, 0.5, 40.0).unwrap()).unwrap(),
            Camera::new(view, Projection::orthographic(-2.0, 3.0, -1.0, 2.0, 0.5, 20.0).unwrap()).unwrap(),
            Camera::new(view, Projection::cabinet(-2.0, 2.0, -2.0, 2.0, 0.5, 20.0, 0.5).unwrap()).unwrap(),
        ]
    }

    fn inside_clip(m: &Mat4, p: Vec3) -> Option<bool> {
        let c = *m * p.extend(1.0);
        let margin = 1e-3 * c.w.abs().max(1e-3);
        let lim = [c.x, c.y, c.z].map(|v| c.w - v.abs());
        if lim.iter().all(|&l| l > margin) {
            Some(true)
        } else if lim.iter().any(|&l| l < -margin) {
            Some(false)
        } else {
            None // too close to the boundary to call
        }
    }

    #[test]
    fn points_classify_like_clip_space() {
        let mut rng = sightline_scene::rng::Rng::new(3);
        for cam in cams() {
            let m = cam.clip_from_world();
            let f = Frustum::from_camera(&cam);
            let inv = cam.clip_from_world_f64().inverse();
            let mut counts = [0, 0];
            for k in 0..4000 {
                let p = if k % 2 == 0 {
                    Vec3::new(rng.range(-15.0, 15.0), rng.range(-15.0, 15.0), rng.range(-15.0, 15.0))
                } else {
                    // Around the frustum: unprojected NDC points in [−1.3, 1.3]³.
                    let n = glam::DVec4::new(
                        rng.range(-1.3, 1.3) as f64,
                        rng.range(-1.3, 1.3) as f64,
                        rng.range(-1.3, 1.3) as f64,
                        1.0,
                    );
                    let h = inv * n;
                    (h.truncate() / h.w).as_vec3()
                };
                if let Some(inside) = inside_clip(&m, p) {
                    assert_eq!(f.contains_point(p), inside, "{p} {cam:?}");
                    counts[inside as usize] += 1;
                }
            }
            assert!(counts[0] > 100 && counts[1] > 100, "{counts:?}");
        }
    }

    #[test]
    fn boxes_touching_the_frustum_are_not_outside() {
        for cam in cams() {
            let f = Frustum::from_camera(&cam);
            let inv = cam.clip_from_world_f64().inverse();
            let unproject = |ndc: Vec3| {
                let h = inv * Vec4::new(ndc.x, ndc.y, ndc.z, 1.0).as_dvec4();
                (h.truncate() / h.w).as_vec3()
            };
            // Boxes whose corner is a point on a face, edge or corner of the frustum.
            for ndc in [
                Vec3::new(1.0, 0.3, 0.2),
                Vec3::new(-1.0, -1.0, -1.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(0.2, -0.1, -1.0),
            ] {
                let p = unproject(ndc);
                // A box with p as its min corner, one with p as its max corner, a point box.
                for b in [Aabb::new(p, p + Vec3::splat(0.5)), Aabb::new(p - Vec3::splat(0.5), p), Aabb::new(p, p)] {
                    assert_ne!(f.classify(&b), Containment::Outside, "{b:?} {ndc}");
                }
            }
            // The box behind the camera is outside; a tiny box at the center is inside.
            let eye = cam.view.eye;
            let back = eye + cam.view.w * 5.0;
            assert_eq!(f.classify(&Aabb::new(back - Vec3::splat(0.1), back + Vec3::splat(0.1))), Containment::Outside);
            let mid = unproject(Vec3::ZERO);
            assert_eq!(f.classify(&Aabb::new(mid - Vec3::splat(0.01), mid + Vec3::splat(0.01))), Containment::Inside);
        }
    }

    #[test]
    fn masking_and_coherency_agree_with_plain_classification() {
        let cam = &cams()[0];
        let f = Frustum::from_camera(cam);
        let mut rng = sightline_scene::rng::Rng::new(9);
        for _ in 0..2000 {
            let c = Vec3::new(rng.range(-20.0, 20.0), rng.range(-20.0, 20.0), rng.range(-20.0, 20.0));
            let b = Aabb::new(c, c + Vec3::splat(rng.range(0.0, 6.0)));
            let plain = f.classify(&b);
            let mut mask = ALL_PLANES;
            let mut start = rng.below(6) as u8;
            assert_eq!(f.classify_coherent(&b, &mut mask, &mut start), plain);
            if plain == Containment::Outside {
                // The rejecting plane is remembered and rejects again.
                let mut m2 = 1 << start;
                assert_eq!(f.classify_masked(&b, &mut m2), Containment::Outside);
            }
        }
    }

    #[test]
    fn bad_input_is_conservative() {
        let f = Frustum::from_clip_from_world(&Mat4::NAN);
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(f.classify(&b), Containment::Intersecting);
        let f = Frustum::from_camera(&cams()[0]);
        assert_eq!(f.classify(&Aabb::EMPTY), Containment::Outside);
        assert_eq!(f.classify(&Aabb::new(Vec3::NAN, Vec3::ONE)), Containment::Intersecting);
        assert_eq!(f.classify_sphere(&Sphere::new(Vec3::NAN, 1.0)), Containment::Intersecting);
    }
}

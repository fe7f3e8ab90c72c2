//! Planes `n·x + d = 0` with a unit normal; the positive side (`n·x + d > 0`) is "in front".
//!
//! Box–plane tests use the center/extent form of the n/p-vertex test (Haines & Wallace 1994;
//! Assarsson & Möller 2000): the signed distance of the box's p-vertex (the corner farthest
//! along `n`) is `n·c + d + |n|·e`, of its n-vertex `n·c + d − |n|·e`, where `c` is the center
//! and `e` the half extent.

use glam::{DVec4, Vec3, Vec4};
use sightline_scene::Aabb;

/// A plane `normal · x + d = 0` with a unit normal (or a zero normal for the "everything is
/// in front" plane made from degenerate input).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Unit normal, pointing to the front (positive) side.
    pub normal: Vec3,
    /// Offset: the signed distance of the origin.
    pub d: f32,
}

impl Plane {
    /// The degenerate plane (zero normal and offset): every point lies on it (distance 0), so
    /// a classification against it never rejects and never reports "fully inside". Stands in
    /// for planes made from degenerate or non-finite input, so culling stays conservative.
    pub const DEGENERATE: Plane = Plane { normal: Vec3::ZERO, d: 0.0 };

    /// A plane from any (non-zero) normal and offset; normalizes both.
    /// A zero or non-finite normal gives [`Plane::DEGENERATE`].
    pub fn new(normal: Vec3, d: f32) -> Plane {
        Self::from_vec4(normal.extend(d))
    }

    /// A plane from `(a, b, c, d)` meaning `a·x + b·y + c·z + d = 0`; normalized.
    /// A zero or non-finite normal gives [`Plane::DEGENERATE`].
    pub fn from_vec4(v: Vec4) -> Plane {
        Self::from_dvec4(v.as_dvec4())
    }

    /// Like [`Plane::from_vec4`], normalizing in f64 (used by the frustum extraction).
    pub fn from_dvec4(v: DVec4) -> Plane {
        let len = v.truncate().length();
        if !v.is_finite() || len.is_nan() || len <= 0.0 {
            return Plane::DEGENERATE;
        }
        let p = v / len;
        Plane { normal: p.truncate().as_vec3(), d: p.w as f32 }
    }

    /// The plane through `point` with the given normal (normalized).
    pub fn from_point_normal(point: Vec3, normal: Vec3) -> Plane {
        let n = normal.normalize_or_zero();
        if n == Vec3::ZERO || !point.is_finite() {
            return Plane::DEGENERATE;
        }
        Plane { normal: n, d: -n.dot(point) }
    }

    /// The plane of a counter-clockwise triangle (normal `(b − a) × (c − a)`), or `None` when
    /// the triangle has zero area.
    pub fn from_triangle(a: Vec3, b: Vec3, c: Vec3) -> Option<Plane> {
        let n = (b - a).cross(c - a);
        let len = n.length();
        if !len.is_finite() || len <= 0.0 {
            return None;
        }
        let n = n / len;
        // Offset from the centroid: less cancellation than from one corner.
        let centroid = (a + b + c) / 3.0;
        Some(Plane { normal: n, d: -n.dot(centroid) })
    }

    /// Signed distance of `p` (positive in front).
    #[inline]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.normal.dot(p) + self.d
    }

    /// The plane facing the other way.
    pub fn flipped(&self) -> Plane {
        Plane { normal: -self.normal, d: -self.d }
    }

    /// Signed distances of a box's n-vertex and p-vertex: `(min, max)` of the distance over
    /// the box. Degenerate (empty) boxes give `(+∞, −∞)`-like values; check the kind first.
    #[inline]
    pub fn box_distance_range(&self, b: &Aabb) -> (f32, f32) {
        let c = (b.min + b.max) * 0.5;
        let e = (b.max - b.min) * 0.5;
        let dc = self.distance(c);
        let r = self.normal.abs().dot(e);
        (dc - r, dc + r)
    }

    /// The parameter `t` in `[0, 1]` where the segment `a → b` crosses the plane, from the
    /// signed distances `da`, `db` of its ends (which must have opposite signs):
    /// `t = da / (da − db)`, which is `t = (d − n·a) / (n·(b − a))` for a plane written
    /// `n·x = d` (Ericson, *Real-Time Collision Detection*, §5.3.1).
    #[inline]
    pub fn crossing(da: f32, db: f32) -> f32 {
        let t = da / (da - db);
        if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.5
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalizes_and_measures() {
        let p = Plane::new(Vec3::new(0.0, 2.0, 0.0), -4.0); // y = 2
        assert!((p.normal - Vec3::Y).length() < 1e-7);
        assert!((p.distance(Vec3::new(5.0, 3.0, -1.0)) - 1.0).abs() < 1e-6);
        assert_eq!(Plane::new(Vec3::ZERO, 1.0), Plane::DEGENERATE);
        assert_eq!(Plane::new(Vec3::NAN, 1.0), Plane::DEGENERATE);
    }

    #[test]
    fn triangle_plane_faces_ccw_side() {
        let p = Plane::from_triangle(Vec3::ZERO, Vec3::X, Vec3::Y).unwrap();
        assert!(p.distance(Vec3::Z) > 0.0);
        assert!(Plane::from_triangle(Vec3::ZERO, Vec3::X, Vec3::X * 2.0).is_none());
    }

    #[test]
    fn box_range_is_exact_over_corners() {
        let p = Plane::new(Vec3::new(0.3, -0.8, 0.5), 0.7);
        let b = Aabb::new(Vec3::new(-1.0, 0.5, 2.0), Vec3::new(3.0, 1.5, 4.0));
        let ds = b.corners().map(|c| p.distance(c));
        let lo = ds.iter().cloned().fold(f32::INFINITY, f32::min);
        let hi = ds.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
        let (a, bb) = p.box_distance_range(&b);
        assert!((a - lo).abs() < 1e-5 && (bb - hi).abs() < 1e-5);
    }
}

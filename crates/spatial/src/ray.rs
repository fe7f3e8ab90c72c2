//! Rays with a `[t_min, t_max]` interval: slab test against boxes (Kay & Kajiya 1986) and
//! the Möller–Trumbore triangle test (T. Möller and B. Trumbore, "Fast, Minimum Storage
//! Ray/Triangle Intersection", JGT 1997).

use glam::{Vec3, Vec3A};
use sightline_scene::Aabb;

/// A ray `origin + t · direction`, `t ∈ [t_min, t_max]`; the direction need not be unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Direction (any non-zero length; `t` is measured in its units).
    pub direction: Vec3,
    /// Smallest accepted `t`.
    pub t_min: f32,
    /// Largest accepted `t`.
    pub t_max: f32,
}

impl Ray {
    /// A ray with `t ∈ [0, ∞)`.
    pub fn new(origin: Vec3, direction: Vec3) -> Ray {
        Ray { origin, direction, t_min: 0.0, t_max: f32::INFINITY }
    }

    /// The same ray restricted to `[t_min, t_max]`.
    pub fn with_interval(mut self, t_min: f32, t_max: f32) -> Ray {
        self.t_min = t_min;
        self.t_max = t_max;
        self
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }

    /// The entry and exit parameters of the box, clipped to the ray's interval, or `None` on a
    /// miss. Rays parallel to a slab are handled through IEEE infinities.
    #[inline]
    pub fn intersect_aabb(&self, b: &Aabb) -> Option<(f32, f32)> {
        let inv = Vec3::ONE / self.direction;
        let t0 = (b.min - self.origin) * inv;
        let t1 = (b.max - self.origin) * inv;
        // NaN (0 · ∞: a parallel ray on a slab's boundary plane) constrains nothing.
        let lo = |t: Vec3| Vec3::select(t.is_nan_mask(), Vec3::NEG_INFINITY, t);
        let hi = |t: Vec3| Vec3::select(t.is_nan_mask(), Vec3::INFINITY, t);
        let tn = lo(t0).min(lo(t1));
        let tf = hi(t0).max(hi(t1));
        let enter = tn.max_element().max(self.t_min);
        let exit = tf.min_element().min(self.t_max);
        (enter <= exit).then_some((enter, exit))
    }

    /// Möller–Trumbore: the hit parameter `t` and barycentrics `(u, v)` (weights of `b` and
    /// `c`) for a hit inside the interval, either facing; `None` for misses and for
    /// zero-area triangles.
    #[inline]
    pub fn intersect_triangle(&self, a: Vec3, b: Vec3, c: Vec3) -> Option<(f32, f32, f32)> {
        let (a, b, c) = (Vec3A::from(a), Vec3A::from(b), Vec3A::from(c));
        let (o, d) = (Vec3A::from(self.origin), Vec3A::from(self.direction));
        let e1 = b - a;
        let e2 = c - a;
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let s = o - a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        (t >= self.t_min && t <= self.t_max).then_some((t, u, v))
    }

    /// The ray as an `obvhs` ray.
    pub fn to_obvhs(&self) -> obvhs::ray::Ray {
        obvhs::ray::Ray::new(self.origin.into(), self.direction.into(), self.t_min, self.t_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_and_misses() {
        let r = Ray::new(Vec3::new(0.2, 0.2, 5.0), Vec3::NEG_Z);
        let (t, u, v) = r.intersect_triangle(Vec3::ZERO, Vec3::X, Vec3::Y).expect("hit");
        assert!((t - 5.0).abs() < 1e-6 && (u - 0.2).abs() < 1e-6 && (v - 0.2).abs() < 1e-6);
        assert!(r.intersect_triangle(Vec3::ONE, Vec3::ONE * 2.0, Vec3::ONE * 3.0).is_none());
        assert!(r.with_interval(0.0, 4.0).intersect_triangle(Vec3::ZERO, Vec3::X, Vec3::Y).is_none());
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let (t0, t1) = r.intersect_aabb(&b).unwrap();
        assert!((t0 - 4.0).abs() < 1e-6 && (t1 - 5.0).abs() < 1e-6);
        // Parallel ray in a slab plane.
        let r = Ray::new(Vec3::new(0.0, 0.5, 5.0), Vec3::NEG_Z);
        assert!(r.intersect_aabb(&b).is_some());
        let r = Ray::new(Vec3::new(2.0, 0.5, 5.0), Vec3::NEG_Z);
        assert!(r.intersect_aabb(&b).is_none());
    }
}

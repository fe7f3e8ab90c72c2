//! Bounding spheres: from a box, from points (Ritter 1990, "An Efficient Bounding Sphere",
//! Graphics Gems), under an affine transform.

use glam::{Affine3A, Vec3};
use sightline_scene::Aabb;

use crate::{AabbExt, BoxKind};

/// A sphere; a negative radius marks the empty sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Center.
    pub center: Vec3,
    /// Radius (negative: empty).
    pub radius: f32,
}

impl Sphere {
    /// The empty sphere.
    pub const EMPTY: Sphere = Sphere { center: Vec3::ZERO, radius: -1.0 };

    /// A sphere from center and radius.
    pub const fn new(center: Vec3, radius: f32) -> Sphere {
        Sphere { center, radius }
    }

    /// The sphere circumscribing a box (empty for the empty box; NaN stays NaN).
    pub fn from_aabb(b: &Aabb) -> Sphere {
        match b.kind() {
            BoxKind::Empty => Sphere::EMPTY,
            _ => Sphere::new(b.center(), (b.max - b.min).length() * 0.5),
        }
    }

    /// A bounding sphere of the points (Ritter's two-pass approximation, at most ~5% larger
    /// than optimal); empty for no points.
    pub fn from_points(points: &[Vec3]) -> Sphere {
        let Some(&first) = points.first() else {
            return Sphere::EMPTY;
        };
        let farthest = |from: Vec3| {
            points
                .iter()
                .copied()
                .max_by(|a, b| a.distance_squared(from).total_cmp(&b.distance_squared(from)))
                .unwrap_or(from)
        };
        let a = farthest(first);
        let b = farthest(a);
        let mut s = Sphere::new((a + b) * 0.5, a.distance(b) * 0.5);
        for &p in points {
            let d = p.distance(s.center);
            if d > s.radius {
                let r = (s.radius + d) * 0.5;
                s.center += (p - s.center) * ((r - s.radius) / d);
                s.radius = r;
            }
        }
        s
    }

    /// True when `p` is inside or on the sphere.
    pub fn contains_point(&self, p: Vec3) -> bool {
        p.distance_squared(self.center) <= self.radius * self.radius && self.radius >= 0.0
    }

    /// The sphere bounding this one after `m` (radius scaled by the largest axis scale).
    pub fn transformed(&self, m: &Affine3A) -> Sphere {
        if self.radius < 0.0 {
            return *self;
        }
        let s = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis]
            .map(|c| c.length())
            .into_iter()
            .fold(0.0f32, f32::max);
        Sphere::new(m.transform_point3(self.center), self.radius * s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn ritter_bounds_all_points() {
        let mut rng = sightline_scene::rng::Rng::new(1);
        let pts: Vec<Vec3> =
            (0..500).map(|_| Vec3::new(rng.range(-1.0, 3.0), rng.range(0.0, 1.0), rng.range(-2.0, 2.0))).collect();
        let s = Sphere::from_points(&pts);
        assert!(pts.iter().all(|&p| p.distance(s.center) <= s.radius * 1.0001));
        assert_eq!(Sphere::from_points(&[]).radius, -1.0);
    }

    #[test]
    fn transformed_sphere_contains_transformed_points() {
        let b = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0));
        let s = Sphere::from_aabb(&b);
        let m =
            Affine3A::from_scale_rotation_translation(Vec3::new(2.0, 0.5, 1.0), Quat::from_rotation_y(0.7), Vec3::X);
        let t = s.transformed(&m);
        for c in b.corners() {
            assert!(m.transform_point3(c).distance(t.center) <= t.radius * 1.0001);
        }
    }
}

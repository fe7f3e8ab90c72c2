//! Extra operations on the scene crate's [`Aabb`]: the empty / finite / unbounded rule that
//! every structure follows, distances for front-to-back ordering, and conversions to the
//! `obvhs` box type.

use glam::{Vec3, Vec3A};
use sightline_scene::Aabb;

/// What kind of box an item has; decides how structures treat it (see the crate docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BoxKind {
    /// Contains nothing (`min > max` on some axis, no NaN): never visible.
    Empty,
    /// Finite corners, `min ≤ max`.
    Finite,
    /// Some coordinate is NaN or infinite: could be anywhere, always visible.
    Unbounded,
}

/// Operations on [`Aabb`] that the spatial crate needs.
pub trait AabbExt {
    /// The box's kind (empty, finite or unbounded); NaN anywhere makes it unbounded.
    fn kind(&self) -> BoxKind;
    /// Squared distance from `p` to the nearest point of the box (0 inside).
    fn distance_squared(&self, p: Vec3) -> f32;
    /// The box of a triangle.
    fn of_triangle(a: Vec3, b: Vec3, c: Vec3) -> Aabb;
    /// Index of the longest axis (0 = x, 1 = y, 2 = z).
    fn longest_axis(&self) -> usize;
    /// The box as an `obvhs` box.
    fn to_obvhs(&self) -> obvhs::aabb::Aabb;
    /// A box from an `obvhs` box.
    fn from_obvhs(b: &obvhs::aabb::Aabb) -> Aabb;
    /// The box grown by `margin` on every side.
    fn expanded(&self, margin: f32) -> Aabb;
}

impl AabbExt for Aabb {
    #[inline]
    fn kind(&self) -> BoxKind {
        if self.min.is_nan() || self.max.is_nan() {
            BoxKind::Unbounded
        } else if !(self.min.cmple(self.max).all()) {
            BoxKind::Empty
        } else if self.min.is_finite() && self.max.is_finite() {
            BoxKind::Finite
        } else {
            BoxKind::Unbounded
        }
    }

    #[inline]
    fn distance_squared(&self, p: Vec3) -> f32 {
        let d = (self.min - p).max(p - self.max).max(Vec3::ZERO);
        d.length_squared()
    }

    #[inline]
    fn of_triangle(a: Vec3, b: Vec3, c: Vec3) -> Aabb {
        Aabb::new(a.min(b).min(c), a.max(b).max(c))
    }

    fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    #[inline]
    fn to_obvhs(&self) -> obvhs::aabb::Aabb {
        obvhs::aabb::Aabb::new(Vec3A::from(self.min), Vec3A::from(self.max))
    }

    #[inline]
    fn from_obvhs(b: &obvhs::aabb::Aabb) -> Aabb {
        Aabb::new(b.min.into(), b.max.into())
    }

    fn expanded(&self, margin: f32) -> Aabb {
        Aabb::new(self.min - Vec3::splat(margin), self.max + Vec3::splat(margin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds() {
        assert_eq!(Aabb::EMPTY.kind(), BoxKind::Empty);
        assert_eq!(Aabb::new(Vec3::ZERO, Vec3::ONE).kind(), BoxKind::Finite);
        assert_eq!(Aabb::new(Vec3::NAN, Vec3::ONE).kind(), BoxKind::Unbounded);
        assert_eq!(Aabb::new(Vec3::ONE, Vec3::new(0.0, f32::NAN, 0.0)).kind(), BoxKind::Unbounded);
        assert_eq!(Aabb::new(Vec3::NEG_INFINITY, Vec3::ONE).kind(), BoxKind::Unbounded);
        // A point box is finite (it can hold a degenerate triangle).
        assert_eq!(Aabb::new(Vec3::ONE, Vec3::ONE).kind(), BoxKind::Finite);
    }

    #[test]
    fn distances() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(b.distance_squared(Vec3::splat(0.5)), 0.0);
        assert_eq!(b.distance_squared(Vec3::new(3.0, 0.5, 0.5)), 4.0);
        assert_eq!(b.distance_squared(Vec3::new(-1.0, -1.0, 0.5)), 2.0);
    }
}

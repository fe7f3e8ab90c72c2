//! Axis-aligned bounding boxes, shared by every crate (the spatial crate builds on this type).
//!
//! The empty box has `min = +inf`, `max = -inf`, so that growing it by any point gives that
//! point's box and a union with it is the identity. Transforming a box uses Arvo's method
//! (J. Arvo, "Transforming Axis-Aligned Bounding Boxes", Graphics Gems, 1990): each output
//! extent sums the per-axis min/max of the matrix column products, which is exact for the
//! transformed corners and costs a fraction of transforming all eight.

use glam::{Affine3A, Vec3};

/// An axis-aligned box `[min, max]`; empty when any `min > max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: contains nothing, and is the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    /// A box from its corners (not reordered).
    pub const fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box containing all `points` (empty for no points).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> Self {
        let mut b = Self::EMPTY;
        for p in points {
            b.grow(*p);
        }
        b
    }

    /// True when the box contains no point (also when a coordinate is NaN).
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// True when both corners are finite and the box is not empty.
    pub fn is_finite(&self) -> bool {
        !self.is_empty() && self.min.is_finite() && self.max.is_finite()
    }

    /// Grows the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Center point (meaningless for the empty box).
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Size along each axis (zero for the empty box).
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Half the surface area (the SAH cost measure); zero for the empty box.
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// True when `p` lies inside or on the boundary.
    pub fn contains_point(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// True when `o` lies entirely inside `self`.
    pub fn contains(&self, o: &Aabb) -> bool {
        o.min.cmpge(self.min).all() && o.max.cmple(self.max).all()
    }

    /// True when the two boxes share at least one point.
    pub fn intersects(&self, o: &Aabb) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }

    /// The eight corners (bit 0 = x, bit 1 = y, bit 2 = z pick `max`).
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 != 0 { self.max.x } else { self.min.x },
                if i & 2 != 0 { self.max.y } else { self.min.y },
                if i & 4 != 0 { self.max.z } else { self.min.z },
            )
        })
    }

    /// The box of this box transformed by `m` (Arvo's method); empty stays empty.
    ///
    /// Summed in f32 and widened by a bound on the rounding (2^-21 of the magnitudes summed,
    /// about 0.5 mm at 10^3 units from the origin), so that the box holds every transformed
    /// point exactly: far from the origin an f32 sum rounded to nearest can land a
    /// millimetre inside (at 3·10^4 units), which box tests of culling cannot allow. (Summed
    /// in f64 and rounded outward, the tightest such box, it made moving instances cost
    /// more: 10,000 moving vehicles' frames 1.56–1.58× the parked ones against 1.41× now,
    /// `examples/moving_cost`, alternated.)
    pub fn transformed(&self, m: &Affine3A) -> Aabb {
        if self.is_empty() {
            return Aabb::EMPTY;
        }
        let t = m.translation;
        let (mut lo, mut hi, mut size) = (t, t, t.abs());
        let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        for (i, c) in cols.iter().enumerate() {
            let (a, b) = (*c * self.min[i], *c * self.max[i]);
            lo += a.min(b);
            hi += a.max(b);
            size += a.abs().max(b.abs());
        }
        // Each product rounds by at most 2^-24 of itself and each of the three sums by 2^-24
        // of the running total, all below `size`: widened by 2^-21 · size the box holds the
        // exact one (and every transformed point).
        let e = size * (1.0 / (1u32 << 21) as f32);
        Aabb { min: (lo - e).into(), max: (hi + e).into() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// Far from the origin the transformed box still holds every transformed corner, as
    /// computed in f64 (rounded to nearest in f32 it missed them by up to a millimetre).
    #[test]
    fn transformed_box_holds_its_corners_far_from_the_origin() {
        let mut rng = crate::rng::Rng::new(4);
        for _ in 0..2000 {
            let far = Vec3::new(rng.range(-3e4, 3e4), rng.range(-50.0, 50.0), rng.range(-3e4, 3e4));
            let axis =
                Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or(Vec3::Y);
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(rng.range(0.5, 2.0)),
                Quat::from_axis_angle(axis, rng.range(0.0, 6.3)),
                far,
            );
            let lo = Vec3::new(rng.range(-20.0, 20.0), rng.range(-20.0, 20.0), rng.range(-20.0, 20.0));
            let b = Aabb::new(lo, lo + Vec3::new(rng.range(0.0, 9.0), rng.range(0.0, 9.0), rng.range(0.0, 9.0)));
            let t = b.transformed(&m);
            let m64 = glam::DAffine3::from_mat3_translation(
                glam::Mat3::from(m.matrix3).as_dmat3(),
                Vec3::from(m.translation).as_dvec3(),
            );
            for c in b.corners() {
                let p = m64.transform_point3(c.as_dvec3());
                for k in 0..3 {
                    assert!(t.min[k] as f64 <= p[k] && p[k] <= t.max[k] as f64, "{p} outside {t:?}");
                }
            }
        }
    }

    #[test]
    fn empty_box_is_union_identity() {
        let b = Aabb::new(Vec3::ONE, Vec3::splat(2.0));
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.union(&b), b);
        assert!(Aabb::EMPTY.transformed(&Affine3A::IDENTITY).is_empty());
        let nan = Aabb::new(Vec3::NAN, Vec3::ONE);
        assert!(nan.is_empty());
    }

    #[test]
    fn arvo_equals_eight_corners() {
        let b = Aabb::new(Vec3::new(-1.0, 0.5, 2.0), Vec3::new(3.0, 1.5, 4.0));
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, -0.5, 1.0),
            Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.7),
            Vec3::new(5.0, -2.0, 0.25),
        );
        let by_corners = Aabb::from_points(b.corners().map(|c| m.transform_point3(c)).iter());
        let arvo = b.transformed(&m);
        assert!((arvo.min - by_corners.min).abs().max_element() < 1e-5);
        assert!((arvo.max - by_corners.max).abs().max_element() < 1e-5);
    }
}

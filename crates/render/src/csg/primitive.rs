//! The solid primitives of CSG in canonical form, and where a ray meets each.
//!
//! Every primitive is convex, so a ray meets it in at most one span; node transforms place,
//! scale and rotate it. Canonical shapes (all inside [−1, 1]³):
//!
//! * sphere: radius 1 around the origin;
//! * cube: [−1, 1]³ (slab test, Kay & Kajiya 1986);
//! * cylinder: radius 1 around the y axis, y in [−1, 1], capped;
//! * cone: apex (0, 1, 0), base of radius 1 at y = −1, capped.
//!
//! Intersections run in f64 on rays with unnormalized directions; a ray parallel to a face
//! or tangent to a curved surface gives an empty or zero-length span, never a NaN, and a
//! degenerate ray gives nothing.

use glam::DVec3;

use super::interval::{Crossing, Span};

/// A canonical solid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shape {
    /// Unit sphere.
    Sphere,
    /// The cube [−1, 1]³.
    Cube,
    /// Capped cylinder of radius 1 along y, y ∈ [−1, 1].
    Cylinder,
    /// Capped cone along y: base radius 1 at y = −1, apex at y = 1.
    Cone,
}

/// The interval of t where `lo ≤ o + t·d ≤ hi` along one axis, with entry/exit normals
/// along that axis; `None` when the ray runs parallel outside the slab.
#[inline]
fn slab(o: f64, d: f64, lo: f64, hi: f64) -> Option<(f64, f64, f64)> {
    if d == 0.0 {
        return (o >= lo && o <= hi).then_some((f64::NEG_INFINITY, f64::INFINITY, 0.0));
    }
    let (t0, t1) = ((lo - o) / d, (hi - o) / d);
    // Entering through the low face (normal −axis) when moving up.
    let sign = if d > 0.0 { -1.0 } else { 1.0 };
    Some((t0.min(t1), t0.max(t1), sign))
}

/// Roots of a·t² + 2·b·t + c = 0, ascending; `None` without real roots.
#[inline]
fn roots(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    let disc = b * b - a * c;
    if disc.is_nan() || disc < 0.0 || a == 0.0 {
        return None;
    }
    let s = disc.sqrt();
    // Numerically stable form.
    let q = -(b + if b >= 0.0 { s } else { -s });
    let (r0, r1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    Some((r0.min(r1), r0.max(r1)))
}

impl Shape {
    /// The span where the ray `o + t·d` is inside the shape, in the shape's own space.
    /// Degenerate rays (zero, NaN or infinite) give `None`.
    pub fn span(self, o: DVec3, d: DVec3) -> Option<Span> {
        if !o.is_finite() || !d.is_finite() || d == DVec3::ZERO {
            return None;
        }
        let span = match self {
            Shape::Sphere => {
                let (t0, t1) = roots(d.dot(d), o.dot(d), o.dot(o) - 1.0)?;
                Span::new(
                    Crossing::new(t0, (o + d * t0).normalize_or_zero()),
                    Crossing::new(t1, (o + d * t1).normalize_or_zero()),
                )
            }
            Shape::Cube => {
                let mut enter = Crossing::new(f64::NEG_INFINITY, DVec3::ZERO);
                let mut exit = Crossing::new(f64::INFINITY, DVec3::ZERO);
                for a in 0..3 {
                    let (t0, t1, s) = slab(o[a], d[a], -1.0, 1.0)?;
                    let mut n = DVec3::ZERO;
                    n[a] = s;
                    if t0 > enter.t {
                        enter = Crossing::new(t0, n);
                    }
                    if t1 < exit.t {
                        exit = Crossing::new(t1, -n);
                    }
                }
                Span::new(enter, exit)
            }
            Shape::Cylinder => {
                let (s0, s1, s) = slab(o.y, d.y, -1.0, 1.0)?;
                let a = d.x * d.x + d.z * d.z;
                let c = o.x * o.x + o.z * o.z - 1.0;
                let (r0, r1) = if a == 0.0 {
                    if c > 0.0 {
                        return None;
                    }
                    (f64::NEG_INFINITY, f64::INFINITY)
                } else {
                    roots(a, o.x * d.x + o.z * d.z, c)?
                };
                let side = |t: f64| {
                    let p = o + d * t;
                    DVec3::new(p.x, 0.0, p.z).normalize_or_zero()
                };
                let enter =
                    if s0 > r0 { Crossing::new(s0, DVec3::new(0.0, s, 0.0)) } else { Crossing::new(r0, side(r0)) };
                let exit =
                    if s1 < r1 { Crossing::new(s1, DVec3::new(0.0, -s, 0.0)) } else { Crossing::new(r1, side(r1)) };
                Span::new(enter, exit)
            }
            Shape::Cone => {
                // x² + z² = k²(1 − y)², k = ½, kept to y ∈ [−1, 1] (the lower nappe).
                let (s0, s1, s) = slab(o.y, d.y, -1.0, 1.0)?;
                let k2 = 0.25;
                let h = 1.0 - o.y;
                let a = d.x * d.x + d.z * d.z - k2 * d.y * d.y;
                let b = o.x * d.x + o.z * d.z + k2 * h * d.y;
                let c = o.x * o.x + o.z * o.z - k2 * h * h;
                let side = |t: f64| {
                    let p = o + d * t;
                    DVec3::new(p.x, k2 * (1.0 - p.y), p.z).normalize_or_zero()
                };
                // Where the quadratic is negative (inside the double cone), as up to two
                // intervals; clipped to the slab only the lower nappe's one survives.
                let inside: [(f64, f64); 2] = if a == 0.0 {
                    if b == 0.0 {
                        if c <= 0.0 {
                            [(f64::NEG_INFINITY, f64::INFINITY), (1.0, 0.0)]
                        } else {
                            return None;
                        }
                    } else {
                        // 2bt + c < 0.
                        let t = -c / (2.0 * b);
                        if b > 0.0 {
                            [(f64::NEG_INFINITY, t), (1.0, 0.0)]
                        } else {
                            [(t, f64::INFINITY), (1.0, 0.0)]
                        }
                    }
                } else {
                    match roots(a, b, c) {
                        Some((r0, r1)) if a > 0.0 => [(r0, r1), (1.0, 0.0)],
                        Some((r0, r1)) => [(f64::NEG_INFINITY, r0), (r1, f64::INFINITY)],
                        None if a < 0.0 => [(f64::NEG_INFINITY, f64::INFINITY), (1.0, 0.0)],
                        None => return None,
                    }
                };
                let mut best: Option<Span> = None;
                for (r0, r1) in inside {
                    let (t0, t1) = (r0.max(s0), r1.min(s1));
                    if t0 > t1 || (t0 == t1 && best.is_some()) {
                        continue;
                    }
                    let enter =
                        if s0 >= r0 { Crossing::new(t0, DVec3::new(0.0, s, 0.0)) } else { Crossing::new(t0, side(t0)) };
                    let exit = if s1 <= r1 {
                        Crossing::new(t1, DVec3::new(0.0, -s, 0.0))
                    } else {
                        Crossing::new(t1, side(t1))
                    };
                    // The slab can still leave a piece at the apex's height or above it
                    // numerically: keep the longer piece.
                    if best.is_none_or(|b| b.exit.t - b.enter.t < t1 - t0) {
                        best = Some(Span::new(enter, exit));
                    }
                }
                best?
            }
        };
        (span.enter.t <= span.exit.t).then_some(span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(shape: Shape, o: DVec3, d: DVec3, t0: f64, t1: f64, n0: DVec3, n1: DVec3) {
        let s = shape.span(o, d).unwrap_or_else(|| panic!("{shape:?} missed"));
        assert!((s.enter.t - t0).abs() < 1e-9 && (s.exit.t - t1).abs() < 1e-9, "{shape:?} {s:?}");
        assert!((s.enter.normal - n0).length() < 1e-9 && (s.exit.normal - n1).length() < 1e-9, "{shape:?} {s:?}");
    }

    #[test]
    fn rays_along_axes() {
        let o = DVec3::new(0.0, 0.0, 5.0);
        let d = DVec3::new(0.0, 0.0, -2.0); // unnormalized on purpose
        check(Shape::Sphere, o, d, 2.0, 3.0, DVec3::Z, DVec3::NEG_Z);
        check(Shape::Cube, o, d, 2.0, 3.0, DVec3::Z, DVec3::NEG_Z);
        check(Shape::Cylinder, o, d, 2.0, 3.0, DVec3::Z, DVec3::NEG_Z);
        // Down the cylinder's axis: through both caps.
        check(Shape::Cylinder, DVec3::new(0.2, 4.0, 0.1), DVec3::NEG_Y, 3.0, 5.0, DVec3::Y, DVec3::NEG_Y);
        // Cone at y = 0 has radius 0.5.
        check(
            Shape::Cone,
            o,
            d,
            2.25,
            2.75,
            DVec3::new(0.0, 0.5, 1.0).normalize(),
            DVec3::new(0.0, 0.5, -1.0).normalize(),
        );
        // Up the cone's axis: base cap, then out through the apex.
        let s = Shape::Cone.span(DVec3::new(0.0, -3.0, 0.0), DVec3::Y).unwrap();
        assert!((s.enter.t - 2.0).abs() < 1e-9 && (s.exit.t - 4.0).abs() < 1e-6);
        assert_eq!(s.enter.normal, DVec3::NEG_Y);
    }

    #[test]
    fn misses_and_degenerate_rays() {
        for shape in [Shape::Sphere, Shape::Cube, Shape::Cylinder, Shape::Cone] {
            assert!(shape.span(DVec3::new(3.0, 0.0, 5.0), DVec3::NEG_Z).is_none());
            assert!(shape.span(DVec3::new(0.0, 5.0, 5.0), DVec3::ZERO).is_none());
            assert!(shape.span(DVec3::new(0.0, 0.0, 5.0), DVec3::NAN).is_none());
            // Above the cone's apex, parallel to the base: outside.
            assert!(shape.span(DVec3::new(-5.0, 1.5, 0.0), DVec3::X).is_none());
        }
        // A zero direction from inside is degenerate too.
        assert!(Shape::Cube.span(DVec3::ZERO, DVec3::ZERO).is_none());
    }
}

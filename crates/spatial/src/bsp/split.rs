//! Classifying a triangle against a plane and splitting it, winding preserved.
//!
//! The triangle is clipped as a polygon against both half-spaces (one Sutherland–Hodgman step
//! per side): vertices on the plane (|distance| ≤ ε) go to both sides, and each edge whose ends
//! lie strictly on opposite sides contributes its crossing point `a + t (b − a)`,
//! `t = d_a / (d_a − d_b)` (the segment–plane intersection `t = (d − n·a) / (n·(b − a))` of
//! Ericson, *Real-Time Collision Detection*, §5.3.1, with the plane written `n·x = d`). Each
//! side's polygon keeps the input's cyclic order and is fanned into triangles, so every piece
//! has the input's orientation: 1 + 2 = three triangles when one vertex is alone on its side,
//! 1 + 1 = two when a vertex lies on the plane.
//!
//! The crossing point of an edge is always computed from its end in front of the plane, so
//! the two triangles sharing an edge get bit-identical points: no cracks between pieces.

use glam::Vec3;

use crate::Plane;

/// Where a triangle lies relative to a plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// In the plane (every vertex within ε).
    On,
    /// In front (no vertex behind).
    Front,
    /// Behind (no vertex in front).
    Back,
    /// Vertices strictly on both sides.
    Spanning,
}

#[inline]
fn side_of(d: f32, eps: f32) -> i8 {
    if d > eps {
        1
    } else if d < -eps {
        -1
    } else {
        0 // also NaN: treated as on the plane
    }
}

/// Classifies a triangle against `plane` with thickness `eps`.
#[inline]
pub fn classify_triangle(plane: &Plane, v: &[Vec3; 3], eps: f32) -> Side {
    let s = v.map(|p| side_of(plane.distance(p), eps));
    let pos = s.iter().any(|&x| x > 0);
    let neg = s.iter().any(|&x| x < 0);
    match (pos, neg) {
        (false, false) => Side::On,
        (true, false) => Side::Front,
        (false, true) => Side::Back,
        (true, true) => Side::Spanning,
    }
}

/// Up to two triangles (the pieces of a split on one side of the plane), no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pieces {
    tris: [[Vec3; 3]; 2],
    len: usize,
}

impl Pieces {
    /// The pieces.
    pub fn as_slice(&self) -> &[[Vec3; 3]] {
        &self.tris[..self.len]
    }
}

/// Splits a spanning triangle into its front pieces and back pieces (each 1 or 2 triangles),
/// all with the input's winding.
pub fn split_triangle(plane: &Plane, v: &[Vec3; 3], eps: f32) -> (Pieces, Pieces) {
    let d = v.map(|p| plane.distance(p));
    let s = d.map(|x| side_of(x, eps));
    let mut front: [Vec3; 4] = [Vec3::ZERO; 4];
    let mut back: [Vec3; 4] = [Vec3::ZERO; 4];
    let (mut nf, mut nb) = (0usize, 0usize);
    for i in 0..3 {
        let j = (i + 1) % 3;
        if s[i] >= 0 && nf < 4 {
            front[nf] = v[i];
            nf += 1;
        }
        if s[i] <= 0 && nb < 4 {
            back[nb] = v[i];
            nb += 1;
        }
        if s[i] * s[j] < 0 {
            // Compute from the end in front so shared edges get identical points.
            let (p, q, dp, dq) = if s[i] > 0 { (v[i], v[j], d[i], d[j]) } else { (v[j], v[i], d[j], d[i]) };
            let t = Plane::crossing(dp, dq);
            let x = p + (q - p) * t;
            if nf < 4 {
                front[nf] = x;
                nf += 1;
            }
            if nb < 4 {
                back[nb] = x;
                nb += 1;
            }
        }
    }
    (fan(&front[..nf]), fan(&back[..nb]))
}

/// Fans a convex polygon of at most 4 corners (in order) into triangles.
fn fan(p: &[Vec3]) -> Pieces {
    let mut out = Pieces { tris: [[Vec3::ZERO; 3]; 2], len: 0 };
    for k in 1..p.len().saturating_sub(1) {
        out.tris[out.len] = [p[0], p[k], p[k + 1]];
        out.len += 1;
    }
    out
}

//! Outcodes and homogeneous clipping.
//!
//! * Trivial accept/reject: 6-bit outcodes, i.e. 3D Cohen–Sutherland
//!   (Newman & Sproull, *Principles of Interactive Computer Graphics*, 1979): one bit per
//!   frustum plane `−w ≤ x, y, z ≤ w`. All three vertices outside one plane (AND ≠ 0) →
//!   the triangle is invisible; no bit set (OR = 0) → no clipping needed.
//! * Clipping: Sutherland & Hodgman, "Reentrant Polygon Clipping" (CACM 1974), run in
//!   homogeneous clip space *before* the perspective divide (Blinn & Newell, "Clipping using
//!   homogeneous coordinates", SIGGRAPH 1978), so vertices behind the eye are handled
//!   correctly. Planes are `dot(plane, v) ≥ 0`. Attributes are carried as barycentric weights
//!   of the original triangle; they interpolate linearly in clip space, which is what makes
//!   the later perspective-correct interpolation of any attribute exact.
//!
//! Watertightness: an intersection is always computed from the inside end of an edge towards
//! the outside end, so two triangles sharing an edge get bit-identical new vertices.

use glam::{Vec3, Vec4};

/// Outcode bit: `x < −w`.
pub const LEFT: u8 = 1;
/// Outcode bit: `x > w`.
pub const RIGHT: u8 = 2;
/// Outcode bit: `y < −w`.
pub const BOTTOM: u8 = 4;
/// Outcode bit: `y > w`.
pub const TOP: u8 = 8;
/// Outcode bit: `z < −w` (in front of the near plane).
pub const NEAR: u8 = 16;
/// Outcode bit: `z > w` (beyond the far plane).
pub const FAR: u8 = 32;
/// The six frustum bits.
pub const VIEW_BITS: u8 = 63;
/// Not a frustum plane: the vertex lies outside the guard band, beyond the near or far
/// plane, or has `w ≤ 0`, so the triangle must be clipped before rasterization.
pub const GUARD: u8 = 64;
/// Not a frustum plane: a coordinate is NaN or infinite; such triangles are dropped.
pub const BAD: u8 = 128;

/// The outcode of a clip-space vertex against the frustum and a guard band `|x| ≤ gx·w`,
/// `|y| ≤ gy·w` (`gx = gy = 1` gives plain frustum clipping).
#[inline]
pub fn outcode(c: Vec4, gx: f32, gy: f32) -> u8 {
    if !c.is_finite() {
        return BAD | GUARD;
    }
    let w = c.w;
    let mut code = 0;
    code |= (c.x < -w) as u8 * LEFT;
    code |= (c.x > w) as u8 * RIGHT;
    code |= (c.y < -w) as u8 * BOTTOM;
    code |= (c.y > w) as u8 * TOP;
    code |= (c.z < -w) as u8 * NEAR;
    code |= (c.z > w) as u8 * FAR;
    let outside_guard = c.x.abs() > gx * w || c.y.abs() > gy * w || w <= 0.0;
    if outside_guard || code & (NEAR | FAR) != 0 {
        code |= GUARD;
    }
    code
}

/// A clipped vertex: clip-space position and barycentric weights of the source triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClipVertex {
    /// Clip-space position.
    pub pos: Vec4,
    /// Weights of the source triangle's three vertices (sum to 1).
    pub bary: Vec3,
}

/// Most vertices a triangle clipped by six planes can have.
pub const MAX_POLYGON: usize = 9;

/// A convex polygon with a fixed capacity (no heap allocation per triangle).
#[derive(Debug, Clone, Copy)]
pub struct Polygon {
    verts: [ClipVertex; MAX_POLYGON],
    len: usize,
}

impl Polygon {
    /// The triangle `v` with weights (1,0,0), (0,1,0), (0,0,1).
    pub fn triangle(v: [Vec4; 3]) -> Self {
        let z = ClipVertex { pos: Vec4::ZERO, bary: Vec3::ZERO };
        let mut verts = [z; MAX_POLYGON];
        for (i, (p, b)) in v.iter().zip([Vec3::X, Vec3::Y, Vec3::Z]).enumerate() {
            verts[i] = ClipVertex { pos: *p, bary: b };
        }
        Self { verts, len: 3 }
    }
    /// The vertices.
    pub fn vertices(&self) -> &[ClipVertex] {
        &self.verts[..self.len]
    }
    /// Number of vertices (0 when clipped away).
    pub fn len(&self) -> usize {
        self.len
    }
    /// True when nothing is left.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Clips against the half-space `dot(plane, v) ≥ 0` (one Sutherland–Hodgman stage).
    pub fn clip(&mut self, plane: Vec4) {
        if self.len == 0 {
            return;
        }
        let src = *self;
        let n = src.len;
        self.len = 0;
        for i in 0..n {
            let a = src.verts[i];
            let b = src.verts[(i + 1) % n];
            let (da, db) = (plane.dot(a.pos), plane.dot(b.pos));
            let (ina, inb) = (da >= 0.0, db >= 0.0);
            if ina {
                self.push(a);
            }
            if ina != inb {
                // Always from the inside end: bit-identical for both triangles of an edge.
                let (i_v, o_v, di, d_o) = if ina { (a, b, da, db) } else { (b, a, db, da) };
                let t = di / (di - d_o);
                self.push(ClipVertex {
                    pos: i_v.pos + (o_v.pos - i_v.pos) * t,
                    bary: i_v.bary + (o_v.bary - i_v.bary) * t,
                });
            }
        }
    }

    fn push(&mut self, v: ClipVertex) {
        // A convex polygon gains at most one vertex per plane; the guard keeps bad input
        // (NaN distances) from writing past the end.
        if self.len < MAX_POLYGON {
            self.verts[self.len] = v;
            self.len += 1;
        }
    }
}

/// The clip planes `dot(p, v) ≥ 0`: near, far, then x and y at `±gx·w`, `±gy·w`.
pub fn planes(gx: f32, gy: f32) -> [Vec4; 6] {
    [
        Vec4::new(0.0, 0.0, 1.0, 1.0),
        Vec4::new(0.0, 0.0, -1.0, 1.0),
        Vec4::new(1.0, 0.0, 0.0, gx),
        Vec4::new(-1.0, 0.0, 0.0, gx),
        Vec4::new(0.0, 1.0, 0.0, gy),
        Vec4::new(0.0, -1.0, 0.0, gy),
    ]
}

/// Clips a triangle against those of [`planes`] that some vertex violates.
pub fn clip_triangle(v: [Vec4; 3], gx: f32, gy: f32) -> Polygon {
    let mut poly = Polygon::triangle(v);
    for p in planes(gx, gy) {
        if v.iter().any(|c| p.dot(*c) < 0.0) {
            poly.clip(p);
        }
    }
    poly
}

/// Twice the signed area of the triangle's image, up to a positive factor, computed
/// without dividing by w: `det[x y w]` (Olano & Greer 1997). Positive for front faces
/// (counter-clockwise in NDC), whatever the signs of the w's, so facing can be decided
/// before clipping.
pub fn facing_det(v: [Vec4; 3]) -> f64 {
    let r = v.map(|c| glam::DVec3::new(c.x as f64, c.y as f64, c.w as f64));
    r[0].dot(r[1].cross(r[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcodes() {
        assert_eq!(outcode(Vec4::new(0.0, 0.0, 0.0, 1.0), 1.0, 1.0), 0);
        assert_eq!(outcode(Vec4::new(2.0, 0.0, 0.0, 1.0), 1.0, 1.0), RIGHT | GUARD);
        assert_eq!(outcode(Vec4::new(2.0, 0.0, 0.0, 1.0), 4.0, 4.0), RIGHT);
        assert_eq!(outcode(Vec4::new(0.0, 0.0, -2.0, 1.0), 4.0, 4.0), NEAR | GUARD);
        assert_eq!(outcode(Vec4::new(f32::NAN, 0.0, 0.0, 1.0), 1.0, 1.0) & BAD, BAD);
        assert_eq!(outcode(Vec4::ZERO, 1.0, 1.0) & GUARD, GUARD);
    }

    #[test]
    fn near_clip_of_one_vertex_behind_gives_a_quad() {
        let v = [
            Vec4::new(-0.5, -0.5, 0.0, 1.0),
            Vec4::new(0.5, -0.5, 0.0, 1.0),
            Vec4::new(0.0, 0.5, -3.0, 1.0), // z < −w
        ];
        let p = clip_triangle(v, 1.0, 1.0);
        assert_eq!(p.len(), 4);
        for c in p.vertices() {
            assert!(c.pos.z >= -c.pos.w - 1e-6);
            assert!((c.bary.element_sum() - 1.0).abs() < 1e-6);
            // Position and weights agree.
            let q = v[0] * c.bary.x + v[1] * c.bary.y + v[2] * c.bary.z;
            assert!((q - c.pos).abs().max_element() < 1e-5);
        }
    }

    #[test]
    fn shared_edges_clip_identically() {
        let a = Vec4::new(-0.3, 0.2, -5.0, 1.0);
        let b = Vec4::new(0.4, -0.1, 0.5, 1.0);
        let t1 = clip_triangle([a, b, Vec4::new(0.9, 0.9, 0.1, 1.0)], 1.0, 1.0);
        let t2 = clip_triangle([b, a, Vec4::new(-0.9, -0.9, 0.2, 1.0)], 1.0, 1.0);
        // The vertex made on edge ab (third weight 0, neither end) is the same in both.
        let on_ab = |p: &Polygon| -> Vec<Vec4> {
            p.vertices().iter().filter(|v| v.bary.z == 0.0 && v.pos != a && v.pos != b).map(|v| v.pos).collect()
        };
        let (n1, n2) = (on_ab(&t1), on_ab(&t2));
        assert_eq!(n1.len(), 1);
        assert_eq!(n1, n2);
    }

    #[test]
    fn facing_is_positive_for_counter_clockwise_and_survives_w_flips() {
        let ccw = [Vec4::new(0.0, 0.0, 0.0, 1.0), Vec4::new(1.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 1.0)];
        assert!(facing_det(ccw) > 0.0);
        assert!(facing_det([ccw[0], ccw[2], ccw[1]]) < 0.0);
        // Scaling a vertex by a positive factor (same point) keeps the sign.
        assert!(facing_det([ccw[0] * 3.0, ccw[1], ccw[2] * 0.2]) > 0.0);
    }

    /// For triangles with one or two vertices behind the eye (w < 0), the sign of
    /// `facing_det` is the sign of the area of what is seen: the clipped polygon in NDC.
    #[test]
    fn facing_matches_the_visible_part_when_vertices_lie_behind_the_eye() {
        let mut rng = sightline_scene::rng::Rng::new(21);
        let mut checked = [0usize; 2];
        for _ in 0..4000 {
            let mut v = [Vec4::ZERO; 3];
            for c in &mut v {
                let w = rng.range(-2.0, 2.0);
                *c = Vec4::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-0.9, 0.9) * w.abs(), w);
            }
            let behind = v.iter().filter(|c| c.w < 0.0).count();
            if behind == 0 || behind == 3 {
                continue;
            }
            let poly = clip_triangle(v, 1e4, 1e4);
            let ndc: Vec<glam::DVec2> = poly
                .vertices()
                .iter()
                .map(|c| glam::DVec2::new(c.pos.x as f64 / c.pos.w as f64, c.pos.y as f64 / c.pos.w as f64))
                .collect();
            let area: f64 = (0..ndc.len()).map(|i| ndc[i].perp_dot(ndc[(i + 1) % ndc.len()])).sum();
            if ndc.len() < 3 || area.abs() < 1e-6 {
                continue;
            }
            assert_eq!(area > 0.0, facing_det(v) > 0.0, "{v:?}: area {area}");
            checked[behind - 1] += 1;
        }
        assert!(checked[0] > 200 && checked[1] > 200, "cases with one and two vertices behind: {checked:?}");
    }
}

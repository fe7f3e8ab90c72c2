//! Convex polygons in normalized device coordinates: the geometry of the depth-sort tests.
//!
//! After the perspective divide the projection is parallel: the viewer looks along +z from
//! z = −∞ (GL's NDC, near at −1), x and y are screen positions and z is depth. Planes stay
//! planes under the projective map (the scene is clipped to the frustum first, so nothing
//! crosses w = 0), which is why Newell, Newell & Sancha ("A Solution to the Hidden Surface
//! Problem", ACM National Conference 1972) and Foley, van Dam, Feiner & Hughes (*Computer
//! Graphics: Principles and Practice*, 2nd ed., 1990, §15.5) run their tests here: extents
//! are screen boxes and depth ranges, "on the viewer's side of a plane" is the side its
//! normal points to when the normal has negative z.
//!
//! * A polygon's plane is found by Newell's method (the normal as the sum over edges of
//!   `(y_i − y_j)(z_i + z_j)`, … — exact for planar polygons, a best fit otherwise).
//! * Projection overlap is the separating axis test for two convex polygons: they are
//!   disjoint on screen exactly when the edge normal of one of them separates them
//!   (touching counts as disjoint: the fill rule gives a shared edge's centres to one side).
//! * Splitting by a plane is one Sutherland–Hodgman step per side (Sutherland & Hodgman,
//!   "Reentrant Polygon Clipping", CACM 1974): vertices within [`EPS`] of the plane go to
//!   both pieces, and an edge whose ends lie strictly on opposite sides contributes one
//!   crossing point, computed from its front end, to both pieces, so the pieces share the
//!   split line bit for bit.
//!
//! Coordinates are f64: NDC depth crowds towards 1 with distance (`z_ndc` changes by about
//! `2·near/d²` per unit of distance `d`), and f64 keeps surfaces a millimetre apart
//! hundreds of metres away distinct.

use glam::{DVec2, DVec3, DVec4};

/// Plane thickness in NDC: a vertex this close to a plane counts as on it. Far below the
/// ~1e-7 an f32 depth buffer resolves, far above f64 rounding on coordinates of size 1.
pub(crate) const EPS: f64 = 1e-10;

/// Smallest |normal.z| of a plane the viewer-side tests use: a plane closer to edge-on
/// has no usable "viewer side" (its polygon covers almost no area on screen).
const EDGE_ON: f64 = 1e-9;

/// The bounding box of a polygon's vertices: screen extents (x, y) and depth range (z).
pub(crate) fn extents(p: &[DVec3]) -> (DVec3, DVec3) {
    p.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

/// The plane `n·p + d = 0` of a polygon by Newell's method, normalized and oriented with
/// its normal toward the viewer (`n.z < 0`); `None` when the polygon has no area or is
/// seen edge-on.
pub(crate) fn plane_of(p: &[DVec3]) -> Option<DVec4> {
    let mut n = DVec3::ZERO;
    let mut c = DVec3::ZERO;
    for (i, &a) in p.iter().enumerate() {
        let b = p[(i + 1) % p.len()];
        n += DVec3::new((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
        c += a;
    }
    let len = n.length();
    if !(len > 0.0) || !len.is_finite() {
        return None;
    }
    let mut n = n / len;
    if n.z.abs() < EDGE_ON {
        return None;
    }
    if n.z > 0.0 {
        n = -n;
    }
    let c = c / p.len() as f64;
    Some(n.extend(-n.dot(c)))
}

/// Lowest and highest signed distance of the polygon's vertices from `plane` (positive on
/// the viewer's side).
#[inline]
pub(crate) fn reach(plane: DVec4, p: &[DVec3]) -> (f64, f64) {
    p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        let d = plane.truncate().dot(*v) + plane.w;
        (lo.min(d), hi.max(d))
    })
}

/// True when the polygon has vertices strictly on both sides of `plane` (beyond [`EPS`]).
pub(crate) fn spans(plane: Option<DVec4>, p: &[DVec3]) -> bool {
    plane.is_some_and(|pl| {
        let (lo, hi) = reach(pl, p);
        lo < -EPS && hi > EPS
    })
}

/// True when the screen projections of two convex polygons share interior points
/// (separating axis test on the edge normals of both; zero-length edges are skipped).
pub(crate) fn overlap_2d(a: &[DVec3], b: &[DVec3]) -> bool {
    !(separated_by_edges_of(a, a, b) || separated_by_edges_of(b, a, b))
}

fn separated_by_edges_of(edges: &[DVec3], a: &[DVec3], b: &[DVec3]) -> bool {
    let span = |axis: DVec2, p: &[DVec3]| {
        p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            let d = axis.dot(v.truncate());
            (lo.min(d), hi.max(d))
        })
    };
    (0..edges.len()).any(|i| {
        let (p, q) = (edges[i].truncate(), edges[(i + 1) % edges.len()].truncate());
        let axis = (q - p).perp();
        if axis == DVec2::ZERO {
            return false;
        }
        let ((alo, ahi), (blo, bhi)) = (span(axis, a), span(axis, b));
        ahi <= blo || bhi <= alo
    })
}

/// Splits a convex polygon by `plane` into the part on the viewer's side (`front`) and the
/// rest (`back`), appended to the two lists (see the module doc).
pub(crate) fn split(p: &[DVec3], plane: DVec4, front: &mut Vec<DVec3>, back: &mut Vec<DVec3>) {
    let dist = |v: DVec3| plane.truncate().dot(v) + plane.w;
    let side = |d: f64| {
        if d > EPS {
            1
        } else if d < -EPS {
            -1
        } else {
            0
        }
    };
    for (i, &a) in p.iter().enumerate() {
        let b = p[(i + 1) % p.len()];
        let (da, db) = (dist(a), dist(b));
        let (sa, sb) = (side(da), side(db));
        if sa >= 0 {
            front.push(a);
        }
        if sa <= 0 {
            back.push(a);
        }
        if sa * sb < 0 {
            let (f, r, df, dr) = if sa > 0 { (a, b, da, db) } else { (b, a, db, da) };
            let x = f + (r - f) * (df / (df - dr));
            front.push(x);
            back.push(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z0: f64, z1: f64) -> Vec<DVec3> {
        vec![DVec3::new(-0.5, -0.5, z0), DVec3::new(0.5, -0.5, z0), DVec3::new(0.5, 0.5, z1), DVec3::new(-0.5, 0.5, z1)]
    }

    #[test]
    fn planes_face_the_viewer_and_split_keeps_area() {
        let q = quad(0.2, 0.6);
        let pl = plane_of(&q).unwrap();
        assert!(pl.z < 0.0);
        let (lo, hi) = reach(pl, &q);
        assert!(lo.abs() < 1e-15 && hi.abs() < 1e-15);
        // A point nearer the viewer (smaller z) is on the positive side.
        assert!(pl.truncate().dot(DVec3::new(0.0, 0.0, 0.0)) + pl.w > 0.0);
        // Reversed winding: the same oriented plane.
        let r: Vec<DVec3> = q.iter().rev().copied().collect();
        assert!((plane_of(&r).unwrap() - pl).abs().max_element() < 1e-15);
        let cut = DVec4::new(1.0, 0.0, 0.0, -0.1);
        assert!(spans(Some(cut), &q));
        let (mut f, mut b) = (Vec::new(), Vec::new());
        split(&q, cut, &mut f, &mut b);
        let area = |p: &[DVec3]| {
            (0..p.len()).map(|i| p[i].truncate().perp_dot(p[(i + 1) % p.len()].truncate())).sum::<f64>().abs() / 2.0
        };
        assert_eq!((f.len(), b.len()), (4, 4));
        assert!((area(&f) + area(&b) - area(&q)).abs() < 1e-12);
        assert!(f.iter().all(|v| v.x >= 0.1 - 1e-12) && b.iter().all(|v| v.x <= 0.1 + 1e-12));
        // Edge-on and zero-area polygons have no plane.
        assert!(plane_of(&[DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0)]).is_none());
        assert!(plane_of(&[DVec3::ZERO, DVec3::X, DVec3::X * 2.0]).is_none());
    }

    #[test]
    fn projection_overlap_is_strict() {
        let a = quad(0.0, 0.0);
        let shifted = |dx: f64| a.iter().map(|v| *v + DVec3::new(dx, 0.0, 0.3)).collect::<Vec<_>>();
        assert!(overlap_2d(&a, &shifted(0.9)));
        assert!(!overlap_2d(&a, &shifted(1.0)), "touching is not overlapping");
        assert!(!overlap_2d(&a, &shifted(1.5)));
        // A triangle beside the quad's corner.
        let t = [DVec3::new(0.6, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, 0.4, 0.0)];
        assert!(!overlap_2d(&a, &t));
        // A diamond (the quad turned 45°) and a triangle in the corner of its bounding box:
        // only the diamond's slanted edge separates them; moved in a little, they overlap.
        let diamond = [
            DVec3::new(0.0, -0.5, 0.0),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(0.0, 0.5, 0.0),
            DVec3::new(-0.5, 0.0, 0.0),
        ];
        let corner = |c: f64| [DVec3::new(c, c, 0.0), DVec3::new(0.5, c, 0.0), DVec3::new(0.5, 0.5, 0.0)];
        assert!(!overlap_2d(&diamond, &corner(0.3)) && !overlap_2d(&corner(0.3), &diamond));
        assert!(overlap_2d(&diamond, &corner(0.2)) && overlap_2d(&corner(0.2), &diamond));
        // Zero-length edges do not separate.
        let d = [DVec3::ZERO, DVec3::ZERO, DVec3::new(0.2, 0.1, 0.0), DVec3::new(0.1, 0.3, 0.0)];
        assert!(overlap_2d(&a, &d));
    }
}

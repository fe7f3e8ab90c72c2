//! Back-facing cluster culling with normal cones (the meshlet technique of Wihlidal,
//! "Optimizing the Graphics Pipeline with Compute", GDC 2016, and meshoptimizer's
//! `meshopt_computeMeshletBounds`): when every triangle of a cluster faces away from the eye,
//! the rasterizer would drop all of them one by one; the cone drops the cluster at once.
//!
//! A cone bounds the world-space face normals of a cluster: axis `a`, half-angle θ. For a
//! cluster inside the sphere (c, r) and the eye e at distance d = |c − e|, every point p of
//! every triangle with normal n satisfies (p − e)·n ≥ d·cos(φ + θ) − r, where φ is the angle
//! between c − e and a. So all triangles face away when cos(φ + θ) > r/d + m. The margin m
//! keeps triangles seen almost edge-on out of the test: the rasterizer decides facing from
//! the snapped screen-space area, which can flip for such slivers.

use glam::{Affine3A, Vec3};
use rayon::prelude::*;

/// Margin on the cosine: clusters within about 3° of edge-on are never culled.
const MARGIN: f32 = 0.05;

/// A normal cone with the bounding sphere of its cluster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cone {
    /// Unit cone axis (mean facing direction).
    pub axis: Vec3,
    /// Half-angle θ in radians (≥ π/2: the cone never culls).
    pub half_angle: f32,
    /// Bounding sphere center.
    pub center: Vec3,
    /// Bounding sphere radius.
    pub radius: f32,
}

impl Cone {
    /// A cone that never culls.
    pub const NEVER: Cone =
        Cone { axis: Vec3::Z, half_angle: std::f32::consts::PI, center: Vec3::ZERO, radius: f32::INFINITY };

    /// The cone of triangles `tris` (indices into `indices`) of a mesh under `world_from_local`.
    pub fn of_cluster(positions: &[Vec3], indices: &[u32], tris: &[u32], world_from_local: &Affine3A) -> Cone {
        let corner =
            |t: u32, k: usize| world_from_local.transform_point3(positions[indices[3 * t as usize + k] as usize]);
        let mut sum = Vec3::ZERO;
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let mut normals = Vec::with_capacity(tris.len());
        for &t in tris {
            let [a, b, c] = [corner(t, 0), corner(t, 1), corner(t, 2)];
            lo = lo.min(a).min(b).min(c);
            hi = hi.max(a).max(b).max(c);
            // Degenerate triangles are never drawn, whatever their normal.
            if let Some(n) = (b - a).cross(c - a).try_normalize() {
                sum += n;
                normals.push(n);
            }
        }
        let Some(axis) = sum.try_normalize() else { return Cone::NEVER };
        if !lo.is_finite() || !hi.is_finite() {
            return Cone::NEVER;
        }
        let min_dot = normals.iter().map(|n| n.dot(axis)).fold(1.0f32, f32::min);
        let center = (lo + hi) * 0.5;
        // Slightly widened against rounding in the normals.
        let half_angle = min_dot.clamp(-1.0, 1.0).acos() + 1e-3;
        Cone { axis, half_angle, center, radius: (hi - lo).length() * 0.5 * (1.0 + 1e-5) + 1e-6 }
    }

    /// False when the cone is wide enough (half-angle ≥ π/2) that no eye position makes it
    /// cull, e.g. the cone of a closed box.
    #[inline]
    pub fn can_cull(&self) -> bool {
        self.half_angle < std::f32::consts::FRAC_PI_2
    }

    /// True when every triangle of the cluster faces away from `eye` (with margin).
    #[inline]
    pub fn backfacing(&self, eye: Vec3) -> bool {
        if !self.can_cull() {
            return false;
        }
        let v = self.center - eye;
        let d = v.length();
        if !(d > self.radius) {
            return false;
        }
        let phi = (v.dot(self.axis) / d).clamp(-1.0, 1.0).acos();
        let limit = self.radius / d + MARGIN;
        limit < 1.0 && (phi + self.half_angle) < limit.acos()
    }
}

/// One cluster to make a cone of: mesh positions, mesh indices, the cluster's triangles, and
/// the instance's `world_from_local`.
pub type ClusterRef<'a> = (&'a [Vec3], &'a [u32], &'a [u32], Affine3A);

/// Cones of many clusters, computed in parallel.
pub fn cones(clusters: &[ClusterRef]) -> Vec<Cone> {
    clusters.par_iter().map(|(p, i, t, m)| Cone::of_cluster(p, i, t, m)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_is_backfacing_only_from_behind() {
        // A wall in the plane z = 0 facing +z.
        let p = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let idx = [0, 1, 2, 0, 2, 3];
        let c = Cone::of_cluster(&p, &idx, &[0, 1], &Affine3A::IDENTITY);
        assert!((c.axis - Vec3::Z).length() < 1e-6);
        assert!(c.backfacing(Vec3::new(0.0, 0.0, -10.0)), "seen from behind");
        assert!(!c.backfacing(Vec3::new(0.0, 0.0, 10.0)), "seen from the front");
        assert!(!c.backfacing(Vec3::new(10.0, 0.0, -0.1)), "nearly edge-on: never culled");
        assert!(!c.backfacing(Vec3::new(0.0, 0.0, -0.5)), "eye inside the bounding sphere");
        // Rotated by the instance transform.
        let m = Affine3A::from_rotation_y(std::f32::consts::PI);
        let c = Cone::of_cluster(&p, &idx, &[0, 1], &m);
        assert!(c.backfacing(Vec3::new(0.0, 0.0, 10.0)));
    }

    #[test]
    fn a_box_never_culls() {
        let m = sightline_scene::shapes::cube("c").unwrap();
        let all: Vec<u32> = (0..12).collect();
        let c = Cone::of_cluster(m.positions(), m.indices(), &all, &Affine3A::IDENTITY);
        for e in [Vec3::X * 5.0, Vec3::NEG_Y * 7.0, Vec3::new(3.0, 4.0, -5.0)] {
            assert!(!c.backfacing(e));
        }
    }
}

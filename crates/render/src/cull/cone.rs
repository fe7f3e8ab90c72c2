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

use glam::{Affine3A, Mat3, Vec3};

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
        match bound(corner, tris) {
            Some(b) => Cone { axis: b.axis, half_angle: b.half_angle, center: b.center(), radius: b.radius() },
            None => Cone::NEVER,
        }
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

/// A cluster's normal cone and box in its mesh's own space: made once per mesh cluster and
/// carried to each instance by [`LocalCone::to_world`], so that placing or moving an
/// instance costs a few matrix products per cluster instead of a pass over its triangles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalCone {
    axis: Vec3,
    half_angle: f32,
    lo: Vec3,
    hi: Vec3,
}

impl LocalCone {
    /// A local cone that never culls.
    pub const NEVER: LocalCone =
        LocalCone { axis: Vec3::Z, half_angle: std::f32::consts::PI, lo: Vec3::ZERO, hi: Vec3::ZERO };

    /// The cone of triangles `tris` (indices into `indices`) of a mesh, in the mesh's space.
    pub fn of_cluster(positions: &[Vec3], indices: &[u32], tris: &[u32]) -> LocalCone {
        let corner = |t: u32, k: usize| positions[indices[3 * t as usize + k] as usize];
        bound(corner, tris).map_or(LocalCone::NEVER, |b| LocalCone {
            axis: b.axis,
            half_angle: b.half_angle,
            lo: b.lo,
            hi: b.hi,
        })
    }

    /// The cone under `world_from_local` (any invertible linear part: rotation, mirror,
    /// non-uniform scale, shear).
    ///
    /// A triangle's edges map by the linear part L, so its normal maps by the cofactor
    /// matrix C = det(L)·L⁻ᵀ: (La)×(Lb) = C(a×b). With σ₁ ≥ σ₂ ≥ σ₃ the singular values of
    /// C, two unit normals n, a at angle φ map to directions at an angle φ′ with
    /// |Cn × Ca| = |cof(C)(n × a)| ≤ σ₁σ₂ sin φ and |Cn||Ca| ≥ σ₃², so sin φ′ ≤ k sin φ with
    /// k = σ₁σ₂/σ₃²; and φ′ stays acute while tan φ < 2σ₃²/(σ₁² − σ₃²) (the part of Cn
    /// along Ca is at least σ₃² cos φ − (σ₁² − σ₃²)/2 · sin φ). So the local half-angle θ
    /// becomes asin(k sin θ), or no cone when that bound fails. For a rotation with uniform
    /// scale k = 1 and θ is kept. The sphere is that of the transformed local box, which
    /// holds the transformed triangles.
    pub fn to_world(&self, world_from_local: &Affine3A) -> Cone {
        let theta = self.half_angle;
        if theta >= std::f32::consts::FRAC_PI_2 {
            return Cone::NEVER;
        }
        let l = world_from_local.matrix3;
        let (l0, l1, l2) = (Vec3::from(l.x_axis), Vec3::from(l.y_axis), Vec3::from(l.z_axis));
        let c = Mat3::from_cols(l1.cross(l2), l2.cross(l0), l0.cross(l1));
        let Some(axis) = (c * self.axis).try_normalize() else { return Cone::NEVER };
        let Some([s1, s2, s3]) = singular_values(&c) else { return Cone::NEVER };
        let (s1, s2, s3) = (s1 * (1.0 + 1e-6), s2 * (1.0 + 1e-6), s3 * (1.0 - 1e-6));
        let (theta, k) = (theta as f64, s1 * s2 / (s3 * s3));
        let spread = s1 * s1 - s3 * s3;
        let acute = spread <= 0.0 || theta.tan() < 2.0 * s3 * s3 / spread;
        let sin = k * theta.sin();
        if !acute || !(sin < 1.0) {
            return Cone::NEVER;
        }
        // Widened against rounding, as a cone made in world space is.
        let half_angle = (sin.asin() + 1e-3) as f32;
        let center = world_from_local.transform_point3((self.lo + self.hi) * 0.5);
        let m = Mat3::from(l);
        let abs = Mat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let extent = abs * ((self.hi - self.lo) * 0.5);
        let radius = extent.length() * (1.0 + 1e-5) + 1e-6;
        if !center.is_finite() || !radius.is_finite() {
            return Cone::NEVER;
        }
        Cone { axis, half_angle, center, radius }
    }
}

/// The singular values of `c`, largest first (square roots of the eigenvalues of cᵀc, by
/// the closed form for symmetric 3 × 3 matrices: Smith, "Eigenvalues of a symmetric 3 × 3
/// matrix", CACM 1961), in f64; `None` when `c` is singular or not finite.
fn singular_values(c: &Mat3) -> Option<[f64; 3]> {
    let d = c.as_dmat3();
    let s = d.transpose() * d;
    let (a00, a11, a22, a01, a02, a12) = (s.x_axis.x, s.y_axis.y, s.z_axis.z, s.y_axis.x, s.z_axis.x, s.z_axis.y);
    let q = (a00 + a11 + a22) / 3.0;
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let [e1, e2, e3] = if p <= q * 1e-12 {
        [q; 3]
    } else {
        let b = (s - glam::DMat3::from_diagonal(glam::DVec3::splat(q))) * (1.0 / p);
        let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        let e1 = q + 2.0 * p * phi.cos();
        let e3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
        [e1, 3.0 * q - e1 - e3, e3]
    };
    // Rounding of the closed form, relative to the largest eigenvalue.
    let slack = e1.abs() * 1e-9;
    let e3 = e3 - slack;
    (e3 > 0.0 && e1.is_finite()).then(|| [(e1 + slack).sqrt(), (e2.max(e3) + slack).sqrt(), e3.sqrt()])
}

/// A cluster's normals and box, from its triangles' corners.
struct Bound {
    axis: Vec3,
    half_angle: f32,
    lo: Vec3,
    hi: Vec3,
}

impl Bound {
    fn center(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }

    fn radius(&self) -> f32 {
        (self.hi - self.lo).length() * 0.5 * (1.0 + 1e-5) + 1e-6
    }
}

/// The normal cone (mean normal, widest angle to it) and box of triangles `tris`, whose
/// corner k is `corner(t, k)`; `None` when no triangle has a normal or a corner is not finite.
/// Two passes over the triangles, so that nothing is allocated.
fn bound(corner: impl Fn(u32, usize) -> Vec3, tris: &[u32]) -> Option<Bound> {
    let normal = |t: u32| {
        let [a, b, c] = [corner(t, 0), corner(t, 1), corner(t, 2)];
        (b - a).cross(c - a).try_normalize()
    };
    let mut sum = Vec3::ZERO;
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &t in tris {
        let [a, b, c] = [corner(t, 0), corner(t, 1), corner(t, 2)];
        lo = lo.min(a).min(b).min(c);
        hi = hi.max(a).max(b).max(c);
        // Degenerate triangles are never drawn, whatever their normal.
        if let Some(n) = normal(t) {
            sum += n;
        }
    }
    let axis = sum.try_normalize()?;
    if !lo.is_finite() || !hi.is_finite() {
        return None;
    }
    let min_dot = tris.iter().filter_map(|&t| normal(t)).map(|n| n.dot(axis)).fold(1.0f32, f32::min);
    // Slightly widened against rounding in the normals.
    let half_angle = min_dot.clamp(-1.0, 1.0).acos() + 1e-3;
    Some(Bound { axis, half_angle, lo, hi })
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

    /// Local cones carried to the world bound what a cone made in world space bounds: every
    /// world normal within the half-angle, every corner inside the sphere; under rotation
    /// and uniform scale they are as tight as the world-space cone.
    #[test]
    fn local_cones_carried_to_the_world_bound_the_world_normals() {
        use glam::Quat;
        // A curved strip: normals spread over about 40 degrees.
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for k in 0..8u32 {
            let a = k as f32 * 0.1;
            p.push(Vec3::new(a.sin() * 3.0, 0.0, a.cos() * 3.0));
            p.push(Vec3::new(a.sin() * 3.0, 2.0, a.cos() * 3.0));
            if k > 0 {
                let b = 2 * k;
                idx.extend([b - 2, b, b + 1, b - 2, b + 1, b - 1]);
            }
        }
        let tris: Vec<u32> = (0..idx.len() as u32 / 3).collect();
        let local = LocalCone::of_cluster(&p, &idx, &tris);
        let rot = Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.2);
        let cases = [
            (Affine3A::from_rotation_translation(rot, Vec3::new(5.0, 1.0, -2.0)), true),
            (Affine3A::from_scale_rotation_translation(Vec3::splat(2.5), rot, Vec3::X), true),
            (Affine3A::from_scale_rotation_translation(Vec3::new(1.0, 0.97, 1.03), rot, Vec3::Z), false),
            (Affine3A::from_scale_rotation_translation(Vec3::new(-1.0, 1.0, 1.0), rot, Vec3::Y), true),
            (Affine3A::from_scale_rotation_translation(Vec3::new(4.0, 0.5, 1.0), rot, Vec3::ZERO), false),
            (Affine3A::from_mat3(glam::Mat3::from_cols(Vec3::X, Vec3::new(0.3, 1.0, 0.0), Vec3::Z)), false),
        ];
        for (m, similar) in cases {
            let c = local.to_world(&m);
            let w = Cone::of_cluster(&p, &idx, &tris, &m);
            for t in &tris {
                let q = |k: usize| m.transform_point3(p[idx[3 * *t as usize + k] as usize]);
                let n = (q(1) - q(0)).cross(q(2) - q(0)).normalize();
                assert!(n.dot(c.axis).clamp(-1.0, 1.0).acos() <= c.half_angle, "{m:?}");
                for k in 0..3 {
                    assert!((q(k) - c.center).length() <= c.radius, "{m:?}");
                }
            }
            if similar {
                assert!(c.can_cull() && (c.half_angle - w.half_angle).abs() < 2e-3, "{m:?}: {c:?} vs {w:?}");
            }
            assert!(c.half_angle >= w.half_angle - 2e-3 || !c.can_cull(), "{m:?}");
        }
        // A vehicle's ±3% sizes keep a cone that culls.
        assert!(local.to_world(&cases[2].0).can_cull());
        // Singular or not finite: never culls.
        assert!(!local.to_world(&Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))).can_cull());
        assert!(!local.to_world(&Affine3A::from_translation(Vec3::NAN)).can_cull());
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

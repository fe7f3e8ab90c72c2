//! Ray–triangle intersection over packet lanes with watertight edge functions.
//!
//! The test is the edge-function (Plücker) form of Möller & Trumbore 1997 ("Fast, Minimum
//! Storage Ray/Triangle Intersection"): with a = v0 − o, b = v1 − o, c = v2 − o, the three
//! signed volumes e0 = d·(b × c), e1 = d·(c × a), e2 = d·(a × b) have one sign exactly when the
//! ray passes through the triangle, their sum is det = d·((v1 − v0) × (v2 − v0)), the
//! barycentric weights are e_i / det and t = ((v1 − v0) × (v2 − v0))·a / det.
//!
//! Two properties make it the right test here:
//! * For rays sharing an origin (a perspective packet), the three cross products belong to
//!   the triangle, not the ray: they are computed once per triangle and packet, leaving three
//!   dot products and a division per lane (the shared-origin trick of Benthin's and Wald's
//!   packet tracers).
//! * A shared edge is evaluated by both of its triangles as `cross(p − o, q − o)` and
//!   `cross(q − o, p − o)`, which are exact negations in floating point, so a ray can never
//!   slip between two triangles of a mesh (watertight within one instance).
//!
//! Facing: a triangle is front-facing (counter-clockwise as seen by the ray) when
//! det < 0. `cull` selects what is kept: 0 keeps both sides, +1 keeps det < 0 (front faces),
//! −1 keeps det > 0 (front faces of an instance whose transform mirrors). Degenerate
//! triangles (det = 0) are never hit.

use glam::Vec3A;

use super::packet::{Hits, Rays, CHUNK, NO_GID};
use super::{mn, mx};

/// The cross product written out, so that `cross(a, b)` and `cross(b, a)` are exact
/// negations of each other.
#[inline(always)]
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

#[inline(always)]
fn sub(a: Vec3A, o: Vec3A) -> [f32; 3] {
    (a - o).to_array()
}

/// A triangle prepared for rays from one shared origin.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shared {
    /// b × c: e0 = d·n0 weights vertex 0.
    n0: [f32; 3],
    /// c × a: weights vertex 1.
    n1: [f32; 3],
    /// a × b: weights vertex 2.
    n2: [f32; 3],
    /// (n0 + n1 + n2)·a: t = tnum / det.
    tnum: f32,
}

/// Prepares `tri` for rays starting at `o`.
#[inline(always)]
pub(crate) fn shared_setup(tri: &[Vec3A; 3], o: Vec3A) -> Shared {
    let (a, b, c) = (sub(tri[0], o), sub(tri[1], o), sub(tri[2], o));
    let (n0, n1, n2) = (cross(b, c), cross(c, a), cross(a, b));
    let n = [n0[0] + n1[0] + n2[0], n0[1] + n1[1] + n2[1], n0[2] + n1[2] + n2[2]];
    Shared { n0, n1, n2, tnum: n[0] * a[0] + n[1] * a[1] + n[2] * a[2] }
}

/// Relative depth window inside which two hits count as equally near (2⁻²¹): coplanar
/// triangles computed from different vertices differ by a few ulps.
pub(crate) const TIE: f32 = 1.0 / (1u32 << 21) as f32;

/// Does a candidate at `t` with global ID `gid` beat the lane's record (`best`, `best_gid`)?
/// Nearer wins; within the tie window the smaller global ID wins, which is what the
/// rasterizer's LESS depth test does with triangles submitted in ID order.
#[inline(always)]
fn beats(t: f32, gid: u32, best: f32, best_gid: u32) -> bool {
    let tie = (best_gid != NO_GID) & (t <= best * (1.0 + TIE)) & (t >= best * (1.0 - TIE));
    (tie & (gid < best_gid)) | (!tie & (t < best))
}

/// The inside, facing and interval part of the accept test, shared by both kernels.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn inside(e0: f32, e1: f32, e2: f32, det: f32, t: f32, tmin: f32, cull: f32, on: bool) -> bool {
    let lo = mn(mn(e0, e1), e2);
    let hi = mx(mx(e0, e1), e2);
    ((lo >= 0.0) | (hi <= 0.0)) & (det != 0.0) & (det * cull <= 0.0) & (t >= tmin) & on
}

/// Tests a candidate in lane `j` of chunk `c` and records it when it wins; returns the lane
/// bit when it does. With `ANY`, a hit closes the lane (t = −∞) instead.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn resolve<const ANY: bool>(hits: &mut Hits, j: usize, job: &Job, e0: f32, e1: f32, e2: f32, det: f32, t: f32) -> u64 {
    let c = job.c;
    let on = (job.bits >> j) & 1 != 0;
    let best = hits.t[c][j];
    let ok = inside(e0, e1, e2, det, t, hits.tmin[c][j], job.cull, on)
        & if ANY { t < best } else { beats(t, job.gid, best, hits.gid[c][j]) };
    let ht = &mut hits.t[c][j];
    *ht = if ok {
        if ANY {
            f32::NEG_INFINITY
        } else {
            t
        }
    } else {
        *ht
    };
    let hi = &mut hits.inst[c][j];
    *hi = if ok { job.inst } else { *hi };
    let hp = &mut hits.prim[c][j];
    *hp = if ok { job.prim } else { *hp };
    if !ANY {
        let hg = &mut hits.gid[c][j];
        *hg = if ok { job.gid } else { *hg };
        let h1 = &mut hits.e1[c][j];
        *h1 = if ok { e1 } else { *h1 };
        let h2 = &mut hits.e2[c][j];
        *h2 = if ok { e2 } else { *h2 };
        let hd = &mut hits.det[c][j];
        *hd = if ok { det } else { *hd };
    }
    (ok as u64) << j
}

/// What a kernel call is about: which lanes, which triangle, which facing to keep.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Job {
    /// Chunk index.
    pub c: usize,
    /// Lanes of the chunk to test.
    pub bits: u64,
    /// Instance to record.
    pub inst: u32,
    /// Leaf-order triangle to record.
    pub prim: u32,
    /// Global triangle ID (orders hits at equal depth).
    pub gid: u32,
    /// Facing selector (see the module docs).
    pub cull: f32,
}

/// Intersects a prepared triangle with the lanes of a chunk (shared origin); closer hits
/// replace the lanes' records. Returns the lanes hit. With `ANY`, a hit closes the lane
/// (t = −∞) instead.
#[inline(always)]
pub(crate) fn intersect_shared<const ANY: bool>(s: &Shared, rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let c = job.c;
    let (dx, dy, dz) = (&rays.d[0][c], &rays.d[1][c], &rays.d[2][c]);
    let mut m = 0u64;
    for j in 0..CHUNK {
        let (x, y, z) = (dx[j], dy[j], dz[j]);
        let e0 = x * s.n0[0] + y * s.n0[1] + z * s.n0[2];
        let e1 = x * s.n1[0] + y * s.n1[1] + z * s.n1[2];
        let e2 = x * s.n2[0] + y * s.n2[1] + z * s.n2[2];
        let det = e0 + e1 + e2;
        let t = s.tnum / det;
        m |= resolve::<ANY>(hits, j, &job, e0, e1, e2, det, t);
    }
    m
}

/// Intersects a triangle with the lanes of a chunk, each lane with its own origin.
#[inline(always)]
pub(crate) fn intersect_general<const ANY: bool>(tri: &[Vec3A; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let c = job.c;
    let v = [tri[0].to_array(), tri[1].to_array(), tri[2].to_array()];
    let mut m = 0u64;
    for j in 0..CHUNK {
        let o = [rays.o[0][c][j], rays.o[1][c][j], rays.o[2][c][j]];
        let d = [rays.d[0][c][j], rays.d[1][c][j], rays.d[2][c][j]];
        let a = [v[0][0] - o[0], v[0][1] - o[1], v[0][2] - o[2]];
        let b = [v[1][0] - o[0], v[1][1] - o[1], v[1][2] - o[2]];
        let cc = [v[2][0] - o[0], v[2][1] - o[1], v[2][2] - o[2]];
        let (n0, n1, n2) = (cross(b, cc), cross(cc, a), cross(a, b));
        let dot = |n: [f32; 3]| d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
        let (e0, e1, e2) = (dot(n0), dot(n1), dot(n2));
        let det = e0 + e1 + e2;
        let tnum = (n0[0] + n1[0] + n2[0]) * a[0] + (n0[1] + n1[1] + n2[1]) * a[1] + (n0[2] + n1[2] + n2[2]) * a[2];
        let t = tnum / det;
        m |= resolve::<ANY>(hits, j, &job, e0, e1, e2, det, t);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raycast::packet::NO_HIT;

    fn job(inst: u32, prim: u32) -> Job {
        Job { c: 0, bits: 1, inst, prim, gid: prim, cull: 0.0 }
    }

    fn one_ray(o: Vec3A, d: Vec3A) -> (Rays, Hits) {
        let mut r = Rays::new();
        let mut h = Hits::new();
        for i in 0..CHUNK {
            r.set(i, o, d);
            h.open(i, 0.0, f32::INFINITY);
        }
        (r, h)
    }

    #[test]
    fn both_kernels_agree_on_t_and_barycentrics() {
        let tri = [Vec3A::new(0.0, 0.0, -2.0), Vec3A::new(2.0, 0.0, -2.0), Vec3A::new(0.0, 2.0, -2.0)];
        let o = Vec3A::new(0.5, 0.25, 1.0);
        let d = Vec3A::new(0.0, 0.0, -1.0);
        let (mut r, mut h) = one_ray(o, d);
        let s = shared_setup(&tri, o);
        assert_eq!(intersect_shared::<false>(&s, &r, &mut h, job(7, 3)), 1);
        let (t, l1, l2) = (h.t[0][0], h.e1[0][0] / h.det[0][0], h.e2[0][0] / h.det[0][0]);
        assert!((t - 3.0).abs() < 1e-6 && (l1 - 0.25).abs() < 1e-6 && (l2 - 0.125).abs() < 1e-6);
        assert_eq!((h.inst[0][0], h.prim[0][0]), (7, 3));
        r.shared = None;
        let mut h2 = Hits::new();
        h2.open(0, 0.0, f32::INFINITY);
        assert_eq!(intersect_general::<false>(&tri, &r, &mut h2, job(7, 3)), 1);
        assert!((h2.t[0][0] - 3.0).abs() < 1e-6);
        // A ray that passes beside it.
        let (r, mut h) = one_ray(Vec3A::new(1.5, 1.5, 1.0), d);
        assert_eq!(intersect_general::<false>(&tri, &r, &mut h, job(0, 0)), 0);
        assert_eq!(h.inst[0][0], NO_HIT);
    }

    #[test]
    fn shared_edges_are_watertight() {
        // Two triangles sharing the diagonal of a square; rays swept across the diagonal.
        let q = [
            Vec3A::new(-1.0, -1.0, -3.0),
            Vec3A::new(1.3, -0.7, -3.5),
            Vec3A::new(0.9, 1.1, -2.5),
            Vec3A::new(-1.2, 0.8, -3.1),
        ];
        let t0 = [q[0], q[1], q[2]];
        let t1 = [q[0], q[2], q[3]];
        let o = Vec3A::new(0.01, 0.02, 0.5);
        let (s0, s1) = (shared_setup(&t0, o), shared_setup(&t1, o));
        let mut misses = 0;
        for k in 1..4000 {
            let a = k as f32 / 4000.0;
            let p = q[0].lerp(q[2], a) + Vec3A::new(1e-7, -1e-7, 0.0) * (k % 3) as f32;
            let (r, mut h) = one_ray(o, p - o);
            let m = intersect_shared::<false>(&s0, &r, &mut h, job(0, 0))
                | intersect_shared::<false>(&s1, &r, &mut h, job(0, 1));
            misses += (m == 0) as u32;
        }
        assert_eq!(misses, 0);
    }

    #[test]
    fn degenerate_triangles_and_rays_miss() {
        let flat = [Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0];
        let point = [Vec3A::ONE; 3];
        for (o, d) in [
            (Vec3A::new(0.5, 0.0, 1.0), Vec3A::NEG_Z),
            (Vec3A::ZERO, Vec3A::ZERO),
            (Vec3A::ZERO, Vec3A::NAN),
            (Vec3A::NAN, Vec3A::NEG_Z),
        ] {
            for tri in [flat, point] {
                let (r, mut h) = one_ray(o, d);
                assert_eq!(intersect_general::<false>(&tri, &r, &mut h, job(0, 0)), 0);
                let s = shared_setup(&tri, o);
                assert_eq!(intersect_shared::<false>(&s, &r, &mut h, job(0, 0)), 0);
            }
        }
    }
}

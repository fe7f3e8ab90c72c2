//! The watertight ray–triangle test over packet lanes.
//!
//! The test is Woop, Benthin & Wald 2013 ("Watertight Ray/Triangle Intersection", JCGT
//! 2(1)). Each lane carries the shear of [`super::shear`], which makes its ray the positive
//! z axis from the origin. The triangle's vertices, taken relative to the ray origin
//! (`a = v0 − o`, `b = v1 − o`, `c = v2 − o`), are permuted and sheared into that space;
//! the ray then pierces the triangle exactly when the origin of the x'y' plane lies inside
//! the projected triangle, which three 2D edge functions decide:
//!
//! ```text
//! e0 = c'y·b'x − c'x·b'y   (the edge b c, weighting vertex 0)
//! e1 = a'y·c'x − a'x·c'y   (the edge c a, weighting vertex 1)
//! e2 = b'y·a'x − b'x·a'y   (the edge a b, weighting vertex 2)
//! ```
//!
//! The ray hits when the three have one sign (an exact zero counts as either). Their sum is
//! `det`, the barycentric weights are `e_i / det`, and `t = (e0·a'z + e1·b'z + e2·c'z) / det`.
//! (These are the paper's U, V, W negated, so that `det` has the sign of `d·((v1 − v0) ×
//! (v2 − v0))`: negative for a front face, counter-clockwise as the ray sees it.)
//!
//! Why it is watertight. A vertex's sheared coordinates depend only on the vertex and the
//! ray, so every triangle around a shared edge or vertex sees that vertex at the same
//! rounded 2D point. An edge function is `fl(fl(p·q) − fl(r·s))`: rounding is monotonic,
//! so a rounded product never changes order with another, and the result can be wrong only
//! by being zero. When an edge function is exactly zero, it is recomputed in f64, where the
//! products of f32 values are exact and the sign is right. The signs are thus the exact
//! signs of an exact 2D point-in-triangle test on one consistent set of projected
//! vertices, and the projection of a closed mesh covers the plane: a ray through a shared
//! edge or vertex hits at least one of the triangles there, never none (two or more only
//! when it is exactly on the edge; the nearest then wins). The rounding that remains is in
//! the sheared coordinates, a few ulps (2⁻²⁴ relative) of the vertex-to-origin distance
//! along each axis; the box test's margin of 2⁻²⁰ of the ray parameter (see `traverse`) is
//! many times that, so the traversal does not skip the box of a triangle the test accepts.
//!
//! The earlier edge-function (Plücker) form of Möller & Trumbore 1997 ("Fast, Minimum
//! Storage Ray/Triangle Intersection") had consistent signs on shared edges too, but its
//! 3D cross products of vertex-to-origin vectors lost about 10⁻³ of a triangle's size to
//! cancellation far from the origin: a ray that truly passed near an edge could be given
//! to the triangle on the other side, whose box the traversal had (rightly) skipped.
//!
//! Packets: for a perspective packet the relative vertices `a`, `b`, `c` are the same for
//! every lane and computed once per triangle ([`shared_setup`]); when all the lanes of a
//! chunk share one axis permutation (the common case), the triangle is permuted once (once
//! per packet when every chunk shares the same one), and the lanes run the same
//! straight-line arithmetic that LLVM vectorizes. Mixed chunks
//! permute per lane. A chunk with only one or two active lanes (divergent rays) tests them
//! one at a time in scalar code (`sparse`), the idea of switching from packets to single
//! rays where packets diverge of Benthin, Wald, Woop, Ernst & Mark 2012 ("Combining Single
//! and Packet-Ray Tracing for Arbitrary Ray Distributions on the Intel MIC Architecture").
//! Every way a lane computes the same values, bit for bit.
//!
//! Quads: a BLAS of a mesh made of quads stores each pair of triangles `(0, 1, 2)`,
//! `(0, 2, 3)` as one record (`sightline_spatial::bvh::wide::BlasQuad`), and
//! [`intersect_quad_shared`] / [`intersect_quad_general`] test the two at once: four corners
//! are sheared instead of six, the diagonal's edge function is computed once (the second
//! triangle's is its exact negation: the same two products, subtracted the other way), and
//! each lane's record is read and written once for both, the two offers decided in
//! registers. Each triangle's values are bit for bit those of the triangle kernels, and the
//! records those of the two triangles tested in a row. On the exported 10^6-triangle city
//! (every triangle in a quad; 1280 × 720, two threads, runs alternated), quad records took
//! the aerial path from 14.66–15.25 ms to 12.54–13.48 ms a frame and the street path from
//! 5.62–5.77 ms to 5.38–5.52 ms. The kernel is written as short passes over the lanes
//! (shear, edge functions, the early exit, depths, records): written as one loop, LLVM kept
//! it scalar and the aerial path took 21 ms.
//!
//! Facing: `cull` selects what is kept: 0 keeps both sides, +1 keeps det < 0 (front faces),
//! −1 keeps det > 0 (front faces of an instance whose transform mirrors). Degenerate
//! triangles (det = 0) are never hit.

use glam::{Vec3, Vec3A};

use super::packet::{Hits, Rays, CHUNK, MIXED, NO_GID};
use super::shear::AXES;
use super::{mn, mx};

mod quad;
pub(crate) use quad::{intersect_quad_general, intersect_quad_shared};

/// A triangle's vertices relative to a ray origin: `[v0 − o, v1 − o, v2 − o]`.
pub(crate) type Rel = [[f32; 3]; 3];

/// A quad's four corners relative to a ray origin (triangles `(0, 1, 2)` and `(0, 2, 3)`).
pub(crate) type Rel4 = [[f32; 3]; 4];

/// A triangle (`N = 3`) or quad (`N = 4`) prepared for the rays of a packet from one shared
/// origin.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shared<const N: usize = 3> {
    /// The vertices relative to the origin.
    rel: [[f32; 3]; N],
    /// The permutation `permuted` was made for ([`MIXED`]: none).
    p: u8,
    /// `rel` permuted by `p`, for the chunks whose lanes all use `p`.
    permuted: [[f32; 3]; N],
}

/// Prepares corners `v` for rays starting at `o`, permuted once for permutation `p` (the
/// one the packet's chunks are expected to share; [`MIXED`] for none).
#[inline(always)]
pub(crate) fn shared_setup<const N: usize>(v: &[Vec3; N], o: Vec3A, p: u8) -> Shared<N> {
    let o = Vec3::from(o);
    let rel = v.map(|v| (v - o).to_array());
    let permuted = AXES.get(p as usize).map_or(rel, |&k| permute(&rel, k));
    Shared { rel, p, permuted }
}

/// `rel` with each vertex's axes in the order `[kx, ky, kz]`.
#[inline(always)]
fn permute<const N: usize>(rel: &[[f32; 3]; N], k: [usize; 3]) -> [[f32; 3]; N] {
    rel.map(|v| [v[k[0]], v[k[1]], v[k[2]]])
}

/// The x' and y' of the permuted vertices under the shear `Sx`, `Sy` (z' is `Sz` times the
/// third coordinate, needed only for a hit's t).
#[inline(always)]
fn shear_xy(p: &Rel, sx: f32, sy: f32) -> [[f32; 2]; 3] {
    p.map(|v| [v[0] - sx * v[2], v[1] - sy * v[2]])
}

/// The three edge functions of sheared vertices (see the module docs).
#[inline(always)]
fn edges(q: &[[f32; 2]; 3]) -> [f32; 3] {
    let [a, b, c] = q;
    [c[1] * b[0] - c[0] * b[1], a[1] * c[0] - a[0] * c[1], b[1] * a[0] - b[0] * a[1]]
}

/// [`edges`] with exact products (f64), rounded once to f32: the sign is exact.
#[inline(never)]
#[cold]
fn edges_exact(q: &[[f32; 2]; 3]) -> [f32; 3] {
    let f = |x: f32| x as f64;
    let [a, b, c] = q;
    [
        (f(c[1]) * f(b[0]) - f(c[0]) * f(b[1])) as f32,
        (f(a[1]) * f(c[0]) - f(a[0]) * f(c[1])) as f32,
        (f(b[1]) * f(a[0]) - f(b[0]) * f(a[1])) as f32,
    ]
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

/// True when the three edge functions have one sign (zeros count as either).
#[inline(always)]
fn same_signs(e: [f32; 3]) -> bool {
    (mn(mn(e[0], e[1]), e[2]) >= 0.0) | (mx(mx(e[0], e[1]), e[2]) <= 0.0)
}

/// The inside, facing and interval part of the accept test, shared by both kernels.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn inside(e0: f32, e1: f32, e2: f32, det: f32, t: f32, tmin: f32, cull: f32, on: bool) -> bool {
    same_signs([e0, e1, e2]) & (det != 0.0) & (det * cull <= 0.0) & (t >= tmin) & on
}

/// Tests a candidate in lane `j` of chunk `c` and records it when it wins; returns the lane
/// bit when it does. With `ANY`, a hit closes the lane (t = −∞) instead. (The same rule as
/// [`Record::offer`], written on the record in place: through a `Record` loaded and stored
/// around it, lone-triangle leaves took 4–5% longer on an aerial city path.)
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

/// The lanes of a chunk against one triangle: `fetch(j)` gives lane `j`'s permuted relative
/// vertices. Closer hits replace the lanes' records; returns the lanes hit.
///
/// Three passes: the edge functions of every lane (straight-line code, vectorized) and an
/// exit when no active lane's signs agree on a triangle facing the way `cull` keeps (most
/// calls); the exact recomputation of lanes with a zero edge function (rare); then depth,
/// facing and the record update.
#[inline(always)]
fn lanes<const ANY: bool>(fetch: impl Fn(usize) -> Rel, rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    if (job.bits & 0xFFFF).count_ones() <= SPARSE {
        return sparse::<ANY>(fetch, rays, hits, job);
    }
    let c = job.c;
    let (sx, sy, sz) = (&rays.s[0][c], &rays.s[1][c], &rays.s[2][c]);
    let mut e = [[0f32; CHUNK]; 3];
    let (mut zero, mut any) = (false, false);
    for j in 0..CHUNK {
        let ej = edges(&shear_xy(&fetch(j), sx[j], sy[j]));
        for (ek, v) in e.iter_mut().zip(ej) {
            ek[j] = v;
        }
        let on = (job.bits >> j) & 1 != 0;
        let z = (ej[0] == 0.0) | (ej[1] == 0.0) | (ej[2] == 0.0);
        zero |= z;
        // The facing test of `inside`, final unless an edge function is zero (its exact
        // value moves det).
        let det = ej[0] + ej[1] + ej[2];
        let facing = z | ((det != 0.0) & (det * job.cull <= 0.0));
        // Zeros pass here; the exact signs below can only turn a zero into a sign, so a
        // lane that fails now fails for good.
        any |= same_signs(ej) & facing & on;
    }
    if !any {
        return 0;
    }
    if zero {
        // Rare: an edge function rounded to zero; decide its sign exactly.
        let mut bits = job.bits;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if e[0][j] == 0.0 || e[1][j] == 0.0 || e[2][j] == 0.0 {
                let ej = edges_exact(&shear_xy(&fetch(j), sx[j], sy[j]));
                for (ek, v) in e.iter_mut().zip(ej) {
                    ek[j] = v;
                }
            }
        }
    }
    let mut m = 0u64;
    for j in 0..CHUNK {
        let (e0, e1, e2) = (e[0][j], e[1][j], e[2][j]);
        let det = e0 + e1 + e2;
        let p = fetch(j);
        let t = (e0 * (sz[j] * p[0][2]) + e1 * (sz[j] * p[1][2]) + e2 * (sz[j] * p[2][2])) / det;
        m |= resolve::<ANY>(hits, j, &job, e0, e1, e2, det, t);
    }
    m
}

/// Lane `j`'s three edge functions.
#[inline(always)]
fn lane(e: &[[f32; CHUNK]; 3], j: usize) -> [f32; 3] {
    [e[0][j], e[1][j], e[2][j]]
}

/// One lane's hit record, in registers.
struct Record {
    t: f32,
    inst: u32,
    prim: u32,
    gid: u32,
    e1: f32,
    e2: f32,
    det: f32,
}

impl Record {
    /// The record of lane `j` of chunk `c`.
    #[inline(always)]
    fn load(hits: &Hits, c: usize, j: usize) -> Record {
        Record {
            t: hits.t[c][j],
            inst: hits.inst[c][j],
            prim: hits.prim[c][j],
            gid: hits.gid[c][j],
            e1: hits.e1[c][j],
            e2: hits.e2[c][j],
            det: hits.det[c][j],
        }
    }

    /// Writes the record back to lane `j` of chunk `c` (with `ANY`, only what any-hit
    /// queries keep: t, closed at −∞, and the hit).
    #[inline(always)]
    fn store<const ANY: bool>(&self, hits: &mut Hits, c: usize, j: usize) {
        hits.t[c][j] = self.t;
        hits.inst[c][j] = self.inst;
        hits.prim[c][j] = self.prim;
        if !ANY {
            hits.gid[c][j] = self.gid;
            hits.e1[c][j] = self.e1;
            hits.e2[c][j] = self.e2;
            hits.det[c][j] = self.det;
        }
    }

    /// Offers a candidate to the record of lane `j` (interval start `tmin`): it wins when
    /// it is inside, faces the way `job.cull` keeps, and beats the record; returns the lane
    /// bit when it does. With `ANY`, a win closes the lane (t = −∞) instead.
    #[inline(always)]
    fn offer<const ANY: bool>(&mut self, j: usize, tmin: f32, job: &Job, e: [f32; 3], det: f32, t: f32) -> u64 {
        let on = (job.bits >> j) & 1 != 0;
        let ok = inside(e[0], e[1], e[2], det, t, tmin, job.cull, on)
            & if ANY { t < self.t } else { beats(t, job.gid, self.t, self.gid) };
        self.t = if ok {
            if ANY {
                f32::NEG_INFINITY
            } else {
                t
            }
        } else {
            self.t
        };
        self.inst = if ok { job.inst } else { self.inst };
        self.prim = if ok { job.prim } else { self.prim };
        self.gid = if ok { job.gid } else { self.gid };
        self.e1 = if ok { e[1] } else { self.e1 };
        self.e2 = if ok { e[2] } else { self.e2 };
        self.det = if ok { det } else { self.det };
        (ok as u64) << j
    }
}

/// The early rejection of [`lanes`] over a chunk's edge functions `e`: whether an active
/// lane has a zero edge function, and whether an active lane may hit (signs agree on a
/// triangle facing the way `job.cull` keeps; final unless an edge function is zero, whose
/// exact sign can only turn a zero into a sign).
#[inline(always)]
fn screen(e: &[[f32; CHUNK]; 3], job: &Job) -> (bool, bool) {
    let (mut zero, mut any) = (false, false);
    for j in 0..CHUNK {
        let ej = lane(e, j);
        let on = (job.bits >> j) & 1 != 0;
        let z = (ej[0] == 0.0) | (ej[1] == 0.0) | (ej[2] == 0.0);
        let det = ej[0] + ej[1] + ej[2];
        let facing = z | ((det != 0.0) & (det * job.cull <= 0.0));
        zero |= z & on;
        any |= same_signs(ej) & facing & on;
    }
    (zero, any)
}

/// Active lanes at or below which a chunk is tested lane by lane ([`sparse`]). Divergent
/// packets (an aerial view of a city) reach many leaves with one or two lanes of a chunk;
/// there the scalar test of those lanes beats the 16-lane kernel (measured with AVX-512,
/// frames interleaved in one process: about 2 % faster on an aerial city view, 1 % on a
/// street view; thresholds 1 and 2 alike, 2 also suits AVX2's two halves).
const SPARSE: u32 = 2;

/// [`lanes`] for a chunk with few active lanes: each active lane alone, in scalar code, with
/// the same arithmetic in the same order, so it records the same bits.
#[inline(always)]
fn sparse<const ANY: bool>(fetch: impl Fn(usize) -> Rel, rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let c = job.c;
    let (sx, sy, sz) = (&rays.s[0][c], &rays.s[1][c], &rays.s[2][c]);
    let mut m = 0u64;
    let mut bits = job.bits & 0xFFFF;
    while bits != 0 {
        let j = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let p = fetch(j);
        let q = shear_xy(&p, sx[j], sy[j]);
        let mut e = edges(&q);
        let z = (e[0] == 0.0) | (e[1] == 0.0) | (e[2] == 0.0);
        let det = e[0] + e[1] + e[2];
        // The early rejection of `lanes`: final unless an edge function is zero.
        if !(same_signs(e) & (z | ((det != 0.0) & (det * job.cull <= 0.0)))) {
            continue;
        }
        if z {
            e = edges_exact(&q);
        }
        let [e0, e1, e2] = e;
        let det = e0 + e1 + e2;
        let t = (e0 * (sz[j] * p[0][2]) + e1 * (sz[j] * p[1][2]) + e2 * (sz[j] * p[2][2])) / det;
        m |= resolve::<ANY>(hits, j, &job, e0, e1, e2, det, t);
    }
    m
}

/// The permutation all lanes of `job`'s chunk share, if they share one.
#[inline(always)]
fn uniform(rays: &Rays, job: &Job) -> Option<[usize; 3]> {
    AXES.get(rays.uniform[job.c] as usize).copied()
}

/// Intersects a prepared triangle with the lanes of a chunk (shared origin); closer hits
/// replace the lanes' records. Returns the lanes hit. With `ANY`, a hit closes the lane
/// (t = −∞) instead.
#[inline(always)]
pub(crate) fn intersect_shared<const ANY: bool>(s: &Shared, rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    if rays.uniform[job.c] == s.p && s.p != MIXED {
        return lanes::<ANY>(|_| s.permuted, rays, hits, job);
    }
    let rel = &s.rel;
    match uniform(rays, &job) {
        Some(k) => {
            let p = permute(rel, k);
            lanes::<ANY>(|_| p, rays, hits, job)
        }
        None => {
            let perm = &rays.perm[job.c];
            lanes::<ANY>(|j| permute(rel, AXES[perm[j] as usize % AXES.len()]), rays, hits, job)
        }
    }
}

/// Intersects a triangle with the lanes of a chunk, each lane with its own origin.
#[inline(always)]
pub(crate) fn intersect_general<const ANY: bool>(tri: &[Vec3; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let c = job.c;
    let v = [tri[0].to_array(), tri[1].to_array(), tri[2].to_array()];
    let o = [&rays.o[0][c], &rays.o[1][c], &rays.o[2][c]];
    match uniform(rays, &job) {
        Some([kx, ky, kz]) => {
            let (ox, oy, oz) = (o[kx], o[ky], o[kz]);
            let p = permute(&v, [kx, ky, kz]);
            lanes::<ANY>(|j| p.map(|w| [w[0] - ox[j], w[1] - oy[j], w[2] - oz[j]]), rays, hits, job)
        }
        None => {
            let perm = &rays.perm[c];
            let fetch = |j: usize| {
                let k = AXES[perm[j] as usize % AXES.len()];
                let rel = v.map(|w| [w[0] - o[0][j], w[1] - o[1][j], w[2] - o[2][j]]);
                permute(&rel, k)
            };
            lanes::<ANY>(fetch, rays, hits, job)
        }
    }
}

#[cfg(test)]
mod tests;

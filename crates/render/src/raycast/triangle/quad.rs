//! Both triangles of a quad record, `(0, 1, 2)` and `(0, 2, 3)`, against a chunk of lanes
//! at once: the parent module's test with the work of the shared edge done once.

use glam::Vec3;

use super::super::packet::{Hits, Rays, CHUNK, MIXED};
use super::super::shear::AXES;
use super::{
    edges, edges_exact, lane, permute, screen, shear_xy, sparse, uniform, Job, Record, Rel, Rel4, Shared, SPARSE,
};

/// Triangle `half` (0 or 1) of a quad's corners.
#[inline(always)]
fn half_of(q: &Rel4, half: usize) -> Rel {
    if half == 0 {
        [q[0], q[1], q[2]]
    } else {
        [q[0], q[2], q[3]]
    }
}

/// The lanes of a chunk against the two triangles of a quad, `jobs[0]` for `(0, 1, 2)` and
/// `jobs[1]` for `(0, 2, 3)`; `fetch(j)` gives lane `j`'s permuted relative corners.
///
/// [`lanes`](super::lanes) for both triangles at once, sharing the work of their shared corners: four
/// corners are sheared instead of six, and the edge from corner 2 to corner 0 is computed
/// once (the second triangle's edge from 0 to 2 is its exact negation: the same two
/// products, subtracted the other way). Each triangle's edge functions, depth and record are
/// bit for bit those of [`lanes`](super::lanes) on it, and the lanes' records see the first triangle, then
/// the second, as a leaf with the two in a row. Each pass is a short loop over the lanes,
/// which LLVM unrolls and vectorizes (one loop doing all of it stays scalar).
#[inline(always)]
fn quad_lanes<const ANY: bool>(fetch: impl Fn(usize) -> Rel4, rays: &Rays, hits: &mut Hits, jobs: [Job; 2]) -> u64 {
    let [ja, jb] = jobs;
    if (ja.bits & 0xFFFF).count_ones() <= SPARSE {
        return sparse::<ANY>(|j| half_of(&fetch(j), 0), rays, hits, ja)
            | sparse::<ANY>(|j| half_of(&fetch(j), 1), rays, hits, jb);
    }
    let c = ja.c;
    let (sx, sy, sz) = (&rays.s[0][c], &rays.s[1][c], &rays.s[2][c]);
    // The corners sheared (x', y').
    let (mut qx, mut qy) = ([[0f32; CHUNK]; 4], [[0f32; CHUNK]; 4]);
    for j in 0..CHUNK {
        let p = fetch(j);
        for v in 0..4 {
            qx[v][j] = p[v][0] - sx[j] * p[v][2];
            qy[v][j] = p[v][1] - sy[j] * p[v][2];
        }
    }
    // The edge functions of both triangles: `edges` of (q0, q1, q2) and of (q0, q2, q3),
    // whose last (the edge q0 q2) is the negated second of the first.
    let (mut ea, mut eb) = ([[0f32; CHUNK]; 3], [[0f32; CHUNK]; 3]);
    for j in 0..CHUNK {
        let q = |v: usize| [qx[v][j], qy[v][j]];
        let a = edges(&[q(0), q(1), q(2)]);
        let (q0, q2, q3) = (q(0), q(2), q(3));
        let b = [q3[1] * q2[0] - q3[0] * q2[1], q0[1] * q3[0] - q0[0] * q3[1], -a[1]];
        for k in 0..3 {
            ea[k][j] = a[k];
            eb[k][j] = b[k];
        }
    }
    let (za, pa) = screen(&ea, &ja);
    let (zb, pb) = screen(&eb, &jb);
    if !(pa | pb) {
        return 0;
    }
    if za | zb {
        // Rare: an edge function rounded to zero; decide its sign exactly.
        for (e, job, half) in [(&mut ea, &ja, 0), (&mut eb, &jb, 1)] {
            let mut bits = job.bits;
            while bits != 0 {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if e[0][j] == 0.0 || e[1][j] == 0.0 || e[2][j] == 0.0 {
                    let ej = edges_exact(&shear_xy(&half_of(&fetch(j), half), sx[j], sy[j]));
                    for (ek, v) in e.iter_mut().zip(ej) {
                        ek[j] = v;
                    }
                }
            }
        }
    }
    // Depths of both triangles, then one record update per lane for the two.
    let (mut da, mut ta, mut db, mut tb) = ([0f32; CHUNK], [0f32; CHUNK], [0f32; CHUNK], [0f32; CHUNK]);
    for j in 0..CHUNK {
        let p = fetch(j);
        let (a, b) = (lane(&ea, j), lane(&eb, j));
        da[j] = a[0] + a[1] + a[2];
        ta[j] = (a[0] * (sz[j] * p[0][2]) + a[1] * (sz[j] * p[1][2]) + a[2] * (sz[j] * p[2][2])) / da[j];
        db[j] = b[0] + b[1] + b[2];
        tb[j] = (b[0] * (sz[j] * p[0][2]) + b[1] * (sz[j] * p[2][2]) + b[2] * (sz[j] * p[3][2])) / db[j];
    }
    let mut m = 0u64;
    for j in 0..CHUNK {
        let mut r = Record::load(hits, c, j);
        let tmin = hits.tmin[c][j];
        m |= r.offer::<ANY>(j, tmin, &ja, lane(&ea, j), da[j], ta[j]);
        m |= r.offer::<ANY>(j, tmin, &jb, lane(&eb, j), db[j], tb[j]);
        r.store::<ANY>(hits, c, j);
    }
    m
}

/// [`intersect_shared`](super::intersect_shared) for the two triangles of a prepared quad
/// (a pair: the record of a lone triangle goes to the triangle kernels).
#[inline(always)]
pub(crate) fn intersect_quad_shared<const ANY: bool>(
    s: &Shared<4>,
    rays: &Rays,
    hits: &mut Hits,
    jobs: [Job; 2],
) -> u64 {
    if rays.uniform[jobs[0].c] == s.p && s.p != MIXED {
        return quad_lanes::<ANY>(|_| s.permuted, rays, hits, jobs);
    }
    let rel = &s.rel;
    match uniform(rays, &jobs[0]) {
        Some(k) => {
            let p = permute(rel, k);
            quad_lanes::<ANY>(|_| p, rays, hits, jobs)
        }
        None => {
            let perm = &rays.perm[jobs[0].c];
            quad_lanes::<ANY>(|j| permute(rel, AXES[perm[j] as usize % AXES.len()]), rays, hits, jobs)
        }
    }
}

/// [`intersect_general`](super::intersect_general) for the two triangles of a quad's corners (see
/// [`intersect_quad_shared`]).
#[inline(always)]
pub(crate) fn intersect_quad_general<const ANY: bool>(
    quad: &[Vec3; 4],
    rays: &Rays,
    hits: &mut Hits,
    jobs: [Job; 2],
) -> u64 {
    let c = jobs[0].c;
    let v = quad.map(|w| w.to_array());
    let o = [&rays.o[0][c], &rays.o[1][c], &rays.o[2][c]];
    match uniform(rays, &jobs[0]) {
        Some([kx, ky, kz]) => {
            let (ox, oy, oz) = (o[kx], o[ky], o[kz]);
            let p = permute(&v, [kx, ky, kz]);
            quad_lanes::<ANY>(|j| p.map(|w| [w[0] - ox[j], w[1] - oy[j], w[2] - oz[j]]), rays, hits, jobs)
        }
        None => {
            let perm = &rays.perm[c];
            let fetch = |j: usize| {
                let k = AXES[perm[j] as usize % AXES.len()];
                permute(&v.map(|w| [w[0] - o[0][j], w[1] - o[1][j], w[2] - o[2][j]]), k)
            };
            quad_lanes::<ANY>(fetch, rays, hits, jobs)
        }
    }
}

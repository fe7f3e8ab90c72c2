//! The triangle kernels: hits, barycentrics, watertightness and bit parity.

use sightline_scene::rng::Rng;

use super::*;
use crate::raycast::packet::{Lf, CHUNKS, LANES, MIXED, NO_HIT};

mod quad;

// The fixtures are `Vec3A` triangles; the kernels read the BLAS's packed `Vec3` ones.
fn shared_setup(tri: &[Vec3A; 3], o: Vec3A, p: u8) -> Shared {
    super::shared_setup(&tri.map(Vec3::from), o, p)
}

fn intersect_general<const ANY: bool>(tri: &[Vec3A; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    super::intersect_general::<ANY>(&tri.map(Vec3::from), rays, hits, job)
}

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
    let s = shared_setup(&tri, o, r.uniform[0]);
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
    let (s0, s1) = (shared_setup(&t0, o, MIXED), shared_setup(&t1, o, MIXED));
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
            let s = shared_setup(&tri, o, r.uniform[0]);
            assert_eq!(intersect_shared::<false>(&s, &r, &mut h, job(0, 0)), 0);
        }
    }
}

/// A closed UV sphere: `lat` bands of `lon` segments, the poles fans of `lon` triangles
/// (cones), every vertex shared by all its triangles; faces wound counter-clockwise seen
/// from outside. Convex, so a ray from outside at a point that faces it hits there first.
fn uv_sphere(center: Vec3A, r: f32, lat: u32, lon: u32) -> (Vec<Vec3A>, Vec<[u32; 3]>) {
    let mut v = vec![center + Vec3A::Y * r];
    for i in 1..lat {
        let th = std::f32::consts::PI * i as f32 / lat as f32;
        for k in 0..lon {
            let ph = std::f32::consts::TAU * k as f32 / lon as f32;
            let dir = Vec3A::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin());
            v.push(center + dir * r);
        }
    }
    v.push(center - Vec3A::Y * r);
    let ring = |i: u32, k: u32| 1 + (i - 1) * lon + k % lon;
    let south = v.len() as u32 - 1;
    let mut t = Vec::new();
    for k in 0..lon {
        t.push([0, ring(1, k), ring(1, k + 1)]);
        t.push([south, ring(lat - 1, k), ring(lat - 1, k + 1)]);
        for i in 1..lat - 1 {
            t.push([ring(i, k), ring(i + 1, k), ring(i + 1, k + 1)]);
            t.push([ring(i, k), ring(i + 1, k + 1), ring(i, k + 1)]);
        }
    }
    for f in &mut t {
        let p = f.map(|i| v[i as usize]);
        if (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2] - center * 3.0) < 0.0 {
            f.swap(1, 2);
        }
    }
    (v, t)
}

/// A kernel under test: (triangle, rays, hits, job) → lanes hit.
type Kernel<'k> = &'k dyn Fn(&[Vec3A; 3], &Rays, &mut Hits, Job) -> u64;

/// The shared-origin kernel (prepares the triangle for the packet's origin).
fn shared_kernel(tri: &[Vec3A; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let o = rays.shared.expect("a shared origin");
    intersect_shared::<false>(&shared_setup(tri, o, rays.uniform[0]), rays, hits, job)
}

/// The per-lane-origin kernel.
fn general_kernel(tri: &[Vec3A; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    intersect_general::<false>(tri, rays, hits, job)
}

/// Casts packets of rays from far-away origins at features of the mesh that face them
/// (vertices, points on edges, points inside triangles), every triangle tested (no BVH).
/// Returns (rays cast, rays that slipped through: no hit, or a first hit past the target) per kernel;
/// with two kernels, also checks that they record the same hits bit for bit.
fn shoot(
    verts: &[Vec3A],
    tris: &[[u32; 3]],
    center: Vec3A,
    packets: usize,
    cull: f32,
    kernels: &[Kernel],
) -> (usize, Vec<usize>) {
    let mut rng = Rng::new(99);
    let mut misses = vec![0; kernels.len()];
    let faces: Vec<[Vec3A; 3]> = tris.iter().map(|t| t.map(|i| verts[i as usize])).collect();
    for _ in 0..packets {
        let dir = Vec3A::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize();
        let o = center + dir * rng.range(300.0, 600.0);
        let facing = |p: Vec3A| (p - center).normalize().dot(dir) > 0.4;
        let mut rays = Rays::new();
        let mut i = 0;
        while i < LANES {
            let t = tris[rng.below(tris.len() as u32) as usize].map(|k| verts[k as usize]);
            let (a, b) = (rng.f32(), rng.f32());
            let p = match rng.below(4) {
                0 => t[0],
                1 => t[0].lerp(t[1], 0.5),
                2 => t[1].lerp(t[2], a),
                _ => t[0] + (t[1] - t[0]) * a.min(b) + (t[2] - t[0]) * (a.max(b) - a.min(b)),
            };
            if facing(p) {
                rays.set(i, o, p - o);
                i += 1;
            }
        }
        rays.shared = Some(o);
        let mut records = Vec::new();
        for (k, kernel) in kernels.iter().enumerate() {
            let mut hits = Hits::new();
            for lane in 0..LANES {
                hits.open(lane, 0.0, f32::INFINITY);
            }
            for (prim, f) in faces.iter().enumerate() {
                for c in 0..CHUNKS {
                    let job = Job { c, bits: 0xFFFF, inst: 0, prim: prim as u32, gid: prim as u32, cull };
                    kernel(f, &rays, &mut hits, job);
                }
            }
            // Each ray reaches its target at t = 1; a first hit beyond (the far side, at least
            // 1.6 units further), or none, means it slipped through the surface there.
            misses[k] += hits.t.iter().flatten().filter(|&&t| !(t <= 1.0 + 1e-4)).count();
            let bits = |x: &Lf| x.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
            records.push((bits(&hits.t), hits.prim, bits(&hits.e1), bits(&hits.e2), bits(&hits.det)));
        }
        assert!(records.windows(2).all(|w| w[0] == w[1]), "the kernels record different hits");
    }
    (packets * LANES, misses)
}

/// Rays aimed at the vertices, edges and faces of a closed mesh far from their origin (the
/// distance about a thousand times a triangle's size, as across a city) all hit, with
/// either facing kept and with back faces dropped, in both kernels.
#[test]
fn a_closed_mesh_far_away_has_no_pinholes() {
    let center = Vec3A::new(317.3, -141.7, 523.9);
    let (v, t) = uv_sphere(center, 2.0, 12, 20);
    for cull in [0.0, 1.0] {
        let (n, misses) = shoot(&v, &t, center, 800, cull, &[&shared_kernel, &general_kernel]);
        assert_eq!(misses, [0, 0], "{misses:?} of {n} rays slipped through (cull {cull})");
    }
}

/// Rays from above at the apex of five triangles around it and along their shared edges
/// (`fan_of_five` below): (rays cast, rays that hit none of them) for `kernel`.
fn fan_of_five(kernel: Kernel) -> (usize, usize) {
    let apex = Vec3A::new(-211.7, 93.1, 407.3);
    let mut v = vec![apex];
    for k in 0..5 {
        let ph = std::f32::consts::TAU * k as f32 / 5.0 + 0.1;
        v.push(apex + Vec3A::new(3.0 * ph.cos(), -1.3 - 0.2 * k as f32, 3.0 * ph.sin()));
    }
    let mut tris: Vec<[u32; 3]> = (0..5).map(|k| [0, 1 + (k + 1) % 5, 1 + k]).collect();
    for f in &mut tris {
        let p = f.map(|i| v[i as usize]);
        if (p[1] - p[0]).cross(p[2] - p[0]).y < 0.0 {
            f.swap(1, 2);
        }
    }
    let faces: Vec<[Vec3A; 3]> = tris.iter().map(|t| t.map(|i| v[i as usize])).collect();
    let mut rng = Rng::new(8);
    let (mut cast, mut misses) = (0, 0);
    for _ in 0..400 {
        // Origins above, 200 to 500 away, up to 30 degrees off the vertical: every face is
        // seen from the front (the steepest slopes 35 degrees), so nothing is a silhouette.
        let (ph, th) = (rng.range(0.0, std::f32::consts::TAU), rng.range(0.0, 0.52));
        let o = apex + Vec3A::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * rng.range(200.0, 500.0);
        let mut rays = Rays::new();
        for i in 0..LANES {
            let p = if i % 2 == 0 { apex } else { apex.lerp(v[1 + (i / 2) % 5], rng.f32()) };
            rays.set(i, o, p - o);
        }
        rays.shared = Some(o);
        let mut hits = Hits::new();
        for lane in 0..LANES {
            hits.open(lane, 0.0, f32::INFINITY);
        }
        for (prim, f) in faces.iter().enumerate() {
            for c in 0..CHUNKS {
                kernel(f, &rays, &mut hits, Job { c, bits: 0xFFFF, inst: 0, prim: prim as u32, gid: 0, cull: 1.0 });
            }
        }
        misses += hits.inst.iter().flatten().filter(|&&h| h == NO_HIT).count();
        cast += LANES;
    }
    (cast, misses)
}

/// Five triangles around a raised apex (a pyramid roof, as in the city): rays aimed at the
/// apex and along the five shared edges from every side above all hit.
#[test]
fn a_fan_of_five_has_no_hole_at_its_apex() {
    for kernel in [&shared_kernel as Kernel, &general_kernel] {
        let (cast, misses) = fan_of_five(kernel);
        assert_eq!(misses, 0, "{misses} of {cast} rays slipped through the fan");
    }
}

/// An edge function that rounds to zero in f32 but not in exact arithmetic is decided in
/// f64: of two triangles sharing that edge, exactly one is hit. (Counting the f32 zero as
/// inside would hit both.)
#[test]
fn a_zero_edge_function_is_decided_exactly() {
    // Looking down −z from the origin, the sheared coordinates of a vertex are its (y, x),
    // so the shared edge's function is c.x·b.y − c.y·b.x = −(1 + 2⁻¹²)² + (1 + 2⁻¹¹) = −2⁻²⁴,
    // whose products round to the same f32. The edge runs from (1, 1) to (−1, −1), nearly
    // through the origin; the two apexes lie on either side.
    let u = 1.0 + 1.0 / 4096.0;
    let (b, c) = (Vec3A::new(1.0, u, -5.0), Vec3A::new(-u, -(1.0 + 1.0 / 2048.0), -5.0));
    assert_eq!(c.x * b.y, c.y * b.x, "the products must round to the same f32");
    let sides = [Vec3A::new(-3.0, 3.0, -5.0), Vec3A::new(3.0, -3.0, -5.0)];
    let mut hit = Vec::new();
    for a in sides {
        let tri = [a, b, c];
        let (r, mut h) = one_ray(Vec3A::ZERO, Vec3A::NEG_Z);
        let m = intersect_shared::<false>(&shared_setup(&tri, Vec3A::ZERO, MIXED), &r, &mut h, job(0, 0));
        let (r, mut h2) = one_ray(Vec3A::ZERO, Vec3A::NEG_Z);
        assert_eq!(m, intersect_general::<false>(&tri, &r, &mut h2, job(0, 0)));
        hit.push(m == 1);
    }
    // Exactly: the origin is on the side of the line b c where the first apex lies.
    let orient = |p: Vec3A, q: Vec3A, s: Vec3A| {
        let f = |v: f32| v as f64;
        (f(q.x) - f(p.x)) * (f(s.y) - f(p.y)) - (f(q.y) - f(p.y)) * (f(s.x) - f(p.x))
    };
    let first = orient(b, c, Vec3A::ZERO).signum() == orient(b, c, sides[0]).signum();
    assert_eq!(hit, [first, !first]);
}

/// One kernel call's output: the lanes hit and every record field, as bits.
type Record = (u64, Vec<u32>);

/// Packets that exercise every path: random triangles and rays (every axis permutation,
/// chunks of one permutation and mixed ones), rays through vertices and along edges, and
/// integer geometry whose edge functions are exactly zero (the f64 path).
fn parity_cases() -> Vec<([Vec3A; 3], Rays)> {
    let mut rng = Rng::new(4242);
    let mut cases = Vec::new();
    for k in 0..300 {
        let o = if k % 3 == 0 {
            Vec3A::new(rng.below(5) as f32, rng.below(5) as f32, rng.below(5) as f32)
        } else {
            Vec3A::new(rng.range(-500.0, 500.0), rng.range(-500.0, 500.0), rng.range(-500.0, 500.0))
        };
        let tri = if k % 3 == 0 {
            let (x, y, z) = (rng.below(9) as f32 - 4.0, rng.below(9) as f32 - 4.0, -(rng.below(20) as f32) - 8.0);
            [Vec3A::new(x, y, z), Vec3A::new(x + 3.0, y, z), Vec3A::new(x, y + 2.0, z + (k % 2) as f32)]
        } else {
            let c = o + Vec3A::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * 300.0;
            [0; 3].map(|_| c + Vec3A::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)))
        };
        let mut rays = Rays::new();
        let spread = [0.0, 0.05, 2.0][k % 3];
        for i in 0..LANES {
            let (a, b) = (rng.f32(), rng.f32());
            let target = match i % 4 {
                0 => tri[i / 4 % 3],
                1 => tri[0].lerp(tri[1], a),
                2 => tri[0] + (tri[1] - tri[0]) * a.min(b) + (tri[2] - tri[0]) * (a.max(b) - a.min(b)),
                _ => tri[0] + Vec3A::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * spread,
            };
            rays.set(i, o, target - o);
        }
        rays.shared = Some(o);
        cases.push((tri, rays));
    }
    cases
}

/// Hits open on every lane, every fifth lane's interval ending at t = 1.
fn open_hits() -> Hits {
    let mut hits = Hits::new();
    for i in 0..LANES {
        hits.open(i, 0.0, if i % 5 == 0 { 1.0 } else { f32::INFINITY });
    }
    hits
}

/// The lane masks of the calls on chunk `c`: every lane but the `c`-th in one call, or with
/// `split`, one call per lane (the sparse path).
fn chunk_calls(c: usize, split: bool) -> Vec<u64> {
    let all = 0xFFFF ^ (1u64 << c);
    match split {
        false => vec![all],
        true => (0..CHUNK).map(|j| 1u64 << j).filter(|b| all & b != 0).collect(),
    }
}

/// The lanes hit and every field of the records, as bits.
fn record(lanes: u64, hits: &Hits) -> Record {
    let mut bits: Vec<u32> = Vec::new();
    for f in [&hits.t, &hits.e1, &hits.e2, &hits.det] {
        bits.extend(f.iter().flatten().map(|v| v.to_bits()));
    }
    for f in [&hits.inst, &hits.prim, &hits.gid] {
        bits.extend(f.iter().flatten());
    }
    (lanes, bits)
}

/// Kernel `kernel` on one triangle: 0 and 1 the shared-origin (prepared for the chunk's
/// permutation) and per-lane-origin closest-hit kernels, 2 and 3 the same as any-hit
/// queries (2 prepared for no permutation).
#[inline(always)]
fn triangle_kernel(kernel: usize, tri: &[Vec3A; 3], rays: &Rays, hits: &mut Hits, job: Job) -> u64 {
    let prep = |p| shared_setup(tri, rays.shared.unwrap(), p);
    match kernel {
        0 => intersect_shared::<false>(&prep(rays.uniform[0]), rays, hits, job),
        1 => intersect_general::<false>(tri, rays, hits, job),
        2 => intersect_shared::<true>(&prep(MIXED), rays, hits, job),
        _ => intersect_general::<true>(tri, rays, hits, job),
    }
}

/// `call(case, rays, kernel, hits, job)` for each of the four kernels, each facing rule and
/// every case, on each chunk's lanes (with `split`, one call per lane: the sparse path),
/// from freshly opened hits: the records.
#[inline(always)]
fn run_cases<C>(
    cases: &[(C, Rays)],
    split: bool,
    mut call: impl FnMut(&C, &Rays, usize, &mut Hits, Job) -> u64,
) -> Vec<Record> {
    let mut out = Vec::new();
    for (case, rays) in cases {
        for cull in [0.0, 1.0, -1.0] {
            for kernel in 0..4 {
                let mut hits = open_hits();
                let mut lanes = 0u64;
                for c in 0..CHUNKS {
                    for bits in chunk_calls(c, split) {
                        let job = Job { c, bits, inst: 3, prim: 9, gid: 5, cull };
                        lanes |= call(case, rays, kernel, &mut hits, job) << (c * CHUNK);
                    }
                }
                out.push(record(lanes, &hits));
            }
        }
    }
    out
}

/// Every kernel (shared origin and per-lane origin, closest and any hit, each facing rule)
/// on every case; with `split`, each chunk's lanes one call per lane (the sparse path).
#[inline(always)]
fn run_kernels(cases: &[([Vec3A; 3], Rays)], split: bool) -> Vec<Record> {
    run_cases(
        cases,
        split,
        #[inline(always)]
        |tri, rays, kernel, hits, job| triangle_kernel(kernel, tri, rays, hits, job),
    )
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_kernels_avx2(cases: &[([Vec3A; 3], Rays)], split: bool) -> Vec<Record> {
    run_kernels(cases, split)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_kernels_avx512(cases: &[([Vec3A; 3], Rays)], split: bool) -> Vec<Record> {
    run_kernels(cases, split)
}

/// The kernels compiled for AVX2 and AVX-512 (the ray caster's packet step enables those
/// features) record exactly what the portable build records, on every SIMD level this
/// process has (`SIGHTLINE_SIMD` may cap them); a chunk tested lane by lane (the sparse
/// path for chunks with few active lanes) records what the whole chunk does.
#[test]
fn kernels_are_bit_identical_on_every_simd_level() {
    // One-lane calls must take the sparse path for `split` to test it.
    const _: () = assert!(SPARSE >= 1);
    use sightline_spatial::simd::SimdLevel;
    let cases = parity_cases();
    let reference = run_kernels(&cases, false);
    assert!(reference.iter().any(|r| r.0 != 0) && reference.iter().any(|r| r.0 == 0));
    for level in SimdLevel::all_available() {
        for split in [false, true] {
            let got = match level {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `all_available` lists AVX2 only when the CPU has these features.
                SimdLevel::Avx2 => unsafe { run_kernels_avx2(&cases, split) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: as above, for AVX-512.
                SimdLevel::Avx512 => unsafe { run_kernels_avx512(&cases, split) },
                _ => run_kernels(&cases, split),
            };
            assert!(got == reference, "{level:?} (split: {split}) differs from the portable kernels");
        }
    }
}

/// A chunk whose lanes share one axis permutation takes the uniform path (with the triangle
/// permuted ahead for the packet or not); the same lanes in a chunk with one odd lane take
/// the per-lane path; all record the same bits.
#[test]
fn uniform_and_mixed_chunks_agree() {
    let mut mixed_seen = 0;
    for (tri, rays) in parity_cases() {
        if rays.uniform[0] == MIXED {
            continue;
        }
        // Lane 15 turned to another axis: the chunk is mixed, lanes 0..15 are unchanged.
        let mut odd = rays.clone();
        let d = rays.dir(15);
        odd.set(15, rays.origin(15), Vec3A::new(d.z, d.x, d.y) * 7.0 + Vec3A::new(1.0, -3.0, 2.0) * d.length());
        if odd.uniform[0] != MIXED {
            continue;
        }
        mixed_seen += 1;
        for any in [false, true] {
            let mut out = Vec::new();
            // Uniform, prepared for its permutation; uniform, not prepared; mixed.
            for (r, p) in [(&rays, rays.uniform[0]), (&rays, MIXED), (&odd, rays.uniform[0])] {
                let mut hits = Hits::new();
                for i in 0..LANES {
                    hits.open(i, 0.0, f32::INFINITY);
                }
                let job = Job { c: 0, bits: 0x7FFF, inst: 1, prim: 2, gid: 3, cull: 0.0 };
                let rel = shared_setup(&tri, r.shared.unwrap(), p);
                let m = match any {
                    false => {
                        intersect_shared::<false>(&rel, r, &mut hits, job)
                            | intersect_general::<false>(&tri, r, &mut hits, job) << 16
                    }
                    true => intersect_shared::<true>(&rel, r, &mut hits, job),
                };
                let first = |f: &Lf| f[0][..15].iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                out.push((m, first(&hits.t), first(&hits.e1), first(&hits.e2), first(&hits.det)));
            }
            assert_eq!(out[0], out[1]);
            assert_eq!(out[0], out[2]);
        }
    }
    assert!(mixed_seen > 50, "only {mixed_seen} cases made a mixed chunk");
}

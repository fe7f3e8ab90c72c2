//! The quad kernels against their two triangles run one after the other.

use super::*;

/// Quads made from the parity cases: the fourth corner completes a parallelogram (bent out
/// of its plane in two cases of three, by whole units in the integer ones), and a quarter
/// of the lanes are re-aimed at the shared diagonal.
fn quad_cases() -> Vec<([Vec3A; 4], Rays)> {
    let mut rng = Rng::new(77);
    let mut cases = Vec::new();
    for (k, (t, mut rays)) in parity_cases().into_iter().enumerate() {
        let bend = match k % 3 {
            0 => Vec3A::new(0.0, 0.0, (k % 2) as f32),
            1 => Vec3A::ZERO,
            _ => Vec3A::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)),
        };
        let o = rays.shared.unwrap();
        for i in (3..LANES).step_by(4) {
            rays.set(i, o, t[0].lerp(t[2], rng.f32()) - o);
        }
        cases.push(([t[0], t[1], t[2], t[0] + t[2] - t[1] + bend], rays));
    }
    cases
}

/// Every quad kernel (shared and per-lane origin, closest and any hit, each facing rule) on
/// every case, or with `as_pairs` the triangle kernels on its two triangles one after the
/// other; with `split`, one call per lane (the sparse path). The second triangle's ID is
/// above the first's in even chunks and below it in odd ones, so that ties go both ways.
#[inline(always)]
fn run_quads(cases: &[([Vec3A; 4], Rays)], split: bool, as_pairs: bool) -> Vec<Record> {
    run_cases(
        cases,
        split,
        #[inline(always)]
        |q, rays, kernel, hits, job| {
            let a = Job { prim: 8, ..job };
            let ab = [a, Job { prim: 9, gid: if a.c.is_multiple_of(2) { 6 } else { 4 }, ..a }];
            if as_pairs {
                let halves = [[q[0], q[1], q[2]], [q[0], q[2], q[3]]];
                return (0..2).fold(0, |m, h| m | triangle_kernel(kernel, &halves[h], rays, hits, ab[h]));
            }
            let q3 = q.map(Vec3::from);
            let prep = |p| super::super::shared_setup(&q3, rays.shared.unwrap(), p);
            match kernel {
                0 => intersect_quad_shared::<false>(&prep(rays.uniform[0]), rays, hits, ab),
                1 => intersect_quad_general::<false>(&q3, rays, hits, ab),
                2 => intersect_quad_shared::<true>(&prep(MIXED), rays, hits, ab),
                _ => intersect_quad_general::<true>(&q3, rays, hits, ab),
            }
        },
    )
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_quads_avx2(cases: &[([Vec3A; 4], Rays)], split: bool) -> Vec<Record> {
    run_quads(cases, split, false)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_quads_avx512(cases: &[([Vec3A; 4], Rays)], split: bool) -> Vec<Record> {
    run_quads(cases, split, false)
}

/// A quad kernel records, bit for bit, what the triangle kernels record on its two
/// triangles in a row, on every SIMD level, whole chunks or lane by lane; both triangles
/// win lanes, and ties on the diagonal go to the smaller ID either way.
#[test]
fn quad_kernels_record_what_their_two_triangles_do() {
    use sightline_spatial::simd::SimdLevel;
    let cases = quad_cases();
    let reference = run_quads(&cases, false, true);
    let prims: Vec<u32> =
        reference.iter().flat_map(|r| r.1[r.1.len() - 2 * LANES..r.1.len() - LANES].to_vec()).collect();
    assert!(prims.contains(&8) && prims.contains(&9), "both triangles must win lanes");
    for level in SimdLevel::all_available() {
        for split in [false, true] {
            let got = match level {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `all_available` lists AVX2 only when the CPU has these features.
                SimdLevel::Avx2 => unsafe { run_quads_avx2(&cases, split) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: as above, for AVX-512.
                SimdLevel::Avx512 => unsafe { run_quads_avx512(&cases, split) },
                _ => run_quads(&cases, split, false),
            };
            let first = got.iter().zip(&reference).position(|(g, r)| g != r);
            assert!(first.is_none(), "{level:?} (split: {split}): record {first:?} differs from the triangles'");
        }
    }
}

/// The zero-edge case of `a_zero_edge_function_is_decided_exactly`, on a quad's diagonal:
/// exactly one of its two triangles is hit, and the quad kernels agree with the triangles'.
#[test]
fn a_zero_edge_on_the_diagonal_is_decided_exactly() {
    let u = 1.0 + 1.0 / 4096.0;
    let (b, c) = (Vec3A::new(1.0, u, -5.0), Vec3A::new(-u, -(1.0 + 1.0 / 2048.0), -5.0));
    let q = [b, Vec3A::new(-3.0, 3.0, -5.0), c, Vec3A::new(3.0, -3.0, -5.0)].map(Vec3::from);
    let (r, mut h) = one_ray(Vec3A::ZERO, Vec3A::NEG_Z);
    let a = Job { c: 0, bits: 1, inst: 0, prim: 0, gid: 0, cull: 0.0 };
    let ab = [a, Job { prim: 1, gid: 1, ..a }];
    assert_eq!(intersect_quad_shared::<false>(&super::super::shared_setup(&q, Vec3A::ZERO, MIXED), &r, &mut h, ab), 1);
    let winner = h.prim[0][0];
    let (r, mut h) = one_ray(Vec3A::ZERO, Vec3A::NEG_Z);
    assert_eq!(intersect_quad_general::<false>(&q, &r, &mut h, ab), 1);
    assert_eq!(h.prim[0][0], winner);
    // The triangle kernels: only the winner is hit.
    for (half, tri) in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]].iter().enumerate() {
        let (r, mut h) = one_ray(Vec3A::ZERO, Vec3A::NEG_Z);
        assert_eq!(super::super::intersect_general::<false>(tri, &r, &mut h, ab[half]), (half as u32 == winner) as u64);
    }
}

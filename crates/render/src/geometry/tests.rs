//! The geometry stage against its scalar reference, at every SIMD level the CPU has.

use super::*;

/// The levels this process has (`SIGHTLINE_SIMD` may cap them) that run the eight-wide
/// kernels.
#[cfg(target_arch = "x86_64")]
fn wide_levels() -> Vec<SimdLevel> {
    SimdLevel::all_available().into_iter().filter(|&l| l >= SimdLevel::Avx2).collect()
}

/// The eight-wide kernels' results as arrays (a test-only entry point with their
/// features).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn transform8_lanes(p: &[Vec3], m: &Mat4) -> [[f32; 8]; 4] {
    transform8(p, m).map(|v| {
        let mut a = [0f32; 8];
        // SAFETY: stores eight floats into `a`; the function's features include AVX.
        unsafe { std::arch::x86_64::_mm256_storeu_ps(a.as_mut_ptr(), v) };
        a
    })
}

/// [`classify8`] of eight clip-space positions into `vc[0..8]`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn classify8_at(c: &[Vec4], vp: &Viewport, vc: &mut VertexCache) {
    classify8(load8(c), vp, vc, 0);
}

/// The eight-wide classification equals the scalar one (codes; snapped positions inside
/// the guard band) on every available level from AVX2 up.
#[test]
fn eight_wide_classification_equals_scalar() {
    #[cfg(target_arch = "x86_64")]
    for level in wide_levels() {
        eight_wide_classification_at(level);
    }
}

#[cfg(target_arch = "x86_64")]
fn eight_wide_classification_at(level: SimdLevel) {
    let mut rng = sightline_scene::rng::Rng::new(3);
    let specials = [f32::NAN, f32::INFINITY, -f32::INFINITY, 0.0, -0.0, 1e30, -1e30, 1e-30];
    for vp in [Viewport::new(1280, 720, true), Viewport::new(7, 3, false)] {
        for _ in 0..5000 {
            let c: Vec<Vec4> = (0..8)
                .map(|_| {
                    let mut v = [0f32; 4].map(|_| rng.range(-3.0, 3.0));
                    v[3] = rng.range(-0.5, 3.0);
                    if rng.below(8) == 0 {
                        v[rng.below(4) as usize] = specials[rng.below(8) as usize];
                    }
                    if rng.below(8) == 0 {
                        v[0] = v[3]; // exactly on a plane
                    }
                    Vec4::from(v)
                })
                .collect();
            let mut vc = VertexCache::default();
            vc.resize(8);
            assert!(level >= SimdLevel::Avx2 && level <= SimdLevel::best());
            // SAFETY: `level` is available (asserted), so the CPU has AVX2.
            unsafe { classify8_at(&c, &vp, &mut vc) };
            for (k, ck) in c.iter().enumerate() {
                let (want_code, want) = Chunk::classify(*ck, &vp);
                assert_eq!(vc.code[k], want_code, "{level:?}: {ck:?}");
                if want_code & GUARD == 0 {
                    assert_eq!((vc.sx[k], vc.sy[k], vc.sz[k]), (want.x, want.y, want.z), "{level:?}: {ck:?}");
                }
            }
        }
    }
}

/// Where the eight-wide transform runs (every available level from AVX2 up), it equals
/// glam's `Mat4 * Vec4` bit for bit.
#[test]
fn eight_wide_transform_equals_glam() {
    #[cfg(target_arch = "x86_64")]
    for level in wide_levels() {
        let mut rng = sightline_scene::rng::Rng::new(5);
        for _ in 0..2000 {
            let m = Mat4::from_cols_array(&[0.0; 16].map(|_| rng.range(-4.0, 4.0)));
            let p: Vec<Vec3> =
                (0..8).map(|_| Vec3::new(rng.range(-9.0, 9.0), rng.range(-9.0, 9.0), rng.range(-9.0, 9.0))).collect();
            assert!(level <= SimdLevel::best());
            // SAFETY: `level` is available (asserted) and at least AVX2.
            let [x, y, z, w] = unsafe { transform8_lanes(&p, &m) };
            for k in 0..8 {
                let want = m * p[k].extend(1.0);
                let got = Vec4::new(x[k], y[k], z[k], w[k]);
                let (got, want) = (got.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits));
                assert_eq!(got, want, "{level:?}: {m:?} {:?}", p[k]);
            }
        }
    }
}

/// A random position: mostly in a box around the view, sometimes far, huge or not finite.
fn random_position(rng: &mut sightline_scene::rng::Rng) -> Vec3 {
    let mut v = || rng.range(-6.0, 6.0);
    let p = Vec3::new(v(), v(), v());
    match rng.below(64) {
        0 => Vec3::new(f32::NAN, p.y, p.z),
        1 => Vec3::new(p.x, f32::INFINITY, p.z),
        2 => p * 1e30,
        3 => p * 1e4,
        _ => p,
    }
}

/// A perspective camera looking at the origin from `eye` (aspect 1.5, far plane at 100).
fn camera(eye: Vec3, fovy_degrees: f32, near: f32) -> sightline_scene::Camera {
    let at = sightline_scene::LookAt {
        eye,
        target: Vec3::ZERO,
        up: Vec3::Y,
        fovy: sightline_scene::Angle::degrees(fovy_degrees),
        near,
        far: 100.0,
    };
    sightline_scene::Camera::perspective(&at, 1.5).unwrap()
}

/// The vertex cache filled at every available level equals the portable one bit for bit
/// (codes, snapped positions and depths), for spans of every length modulo 8.
#[test]
fn transform_is_the_same_on_every_level() {
    let mut rng = sightline_scene::rng::Rng::new(11);
    let cam = camera(Vec3::new(0.5, 1.0, 8.0), 60.0, 0.5);
    for round in 0..300 {
        let m = if round % 3 == 2 {
            Mat4::from_cols_array(&[0.0; 16].map(|_| rng.range(-2.0, 2.0)))
        } else {
            cam.clip_from_world()
        };
        let vp = [Viewport::new(1280, 720, true), Viewport::new(7, 3, false)][round % 2];
        let n = rng.below(70) as usize;
        let positions: Vec<Vec3> = (0..n).map(|_| random_position(&mut rng)).collect();
        let mut portable = VertexCache::default();
        transform_portable(&mut portable, &positions, &m, &vp);
        #[cfg(target_arch = "x86_64")]
        for level in wide_levels() {
            let mut vc = VertexCache::default();
            assert!(level <= SimdLevel::best());
            // SAFETY: `level` is available (asserted) and at least AVX2.
            unsafe { transform_avx2(&mut vc, &positions, &m, &vp) };
            assert_eq!(vc.code[..n], portable.code[..n], "{level:?} {m:?}");
            assert_eq!(vc.sx[..n], portable.sx[..n], "{level:?} {m:?}");
            assert_eq!(vc.sy[..n], portable.sy[..n], "{level:?} {m:?}");
            let bits = |z: &[f32]| z[..n].iter().map(|z| z.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&vc.sz), bits(&portable.sz), "{level:?} {m:?}");
        }
    }
}

/// A set-up triangle's fields, depths as bits.
type TriBits = ([i32; 3], [i32; 3], [u32; 3], u32, [u16; 4], u32);

/// [`TriBits`] of `t`.
fn tri_bits(t: &Tri) -> TriBits {
    (t.x, t.y, [t.z0.to_bits(), t.zx.to_bits(), t.zy.to_bits()], t.id, t.bbox, t.multi)
}

/// The whole stage (transform, trivial reject, clipping, setup) gives the same triangles
/// and counters at every available level, over whole meshes, partial pieces and raw
/// clip-space triangles.
#[test]
fn process_is_the_same_on_every_level() {
    let mut rng = sightline_scene::rng::Rng::new(12);
    let cam = camera(Vec3::new(0.0, 0.5, 5.0), 70.0, 1.0);
    let vp = Viewport::new(320, 200, true);
    let mut kinds = FrameStats::default();
    for _ in 0..20 {
        let n = 8 + rng.below(300) as usize;
        let positions: Vec<Vec3> = (0..n).map(|_| random_position(&mut rng)).collect();
        let tris = 1 + rng.below(400);
        let indices: Vec<u32> = (0..3 * tris).map(|_| rng.below(n as u32)).collect();
        let clip: Vec<[Vec4; 3]> =
            (0..50).map(|_| [0; 3].map(|_| cam.clip_from_world() * random_position(&mut rng).extend(1.0))).collect();
        let mesh = Source::Mesh {
            positions: &positions,
            indices: &indices,
            clip_from_local: cam.clip_from_world(),
            ids: None,
        };
        let items = [
            Item { src: mesh, first_id: 1, source_triangles: tris },
            Item { src: Source::Clip(&clip), first_id: 5000, source_triangles: clip.len() as u32 },
        ];
        let half = tris / 2;
        let pieces = [
            Piece { item: 0, start: 0, count: tris },
            Piece { item: 0, start: half, count: tris - half },
            Piece { item: 1, start: 3, count: 40 },
        ];
        let run = |level: SimdLevel| {
            let mut chunk = Chunk { simd: level, ..Chunk::default() };
            chunk.process(&items[..], &pieces, &vp, true);
            (chunk.tris.iter().map(tri_bits).collect::<Vec<_>>(), chunk.stats)
        };
        let portable = run(SimdLevel::Portable);
        for level in SimdLevel::all_available() {
            let got = run(level);
            assert_eq!(got.1, portable.1, "{level:?}");
            assert_eq!(got.0, portable.0, "{level:?}");
        }
        kinds.add(&portable.1);
    }
    let k = &kinds;
    assert!(k.trivially_rejected > 100 && k.clipped > 100 && k.backface_culled > 100 && k.triangles_in > 5000, "{k:?}");
}

/// Draw sources resolved by the chunks that draw them ([`Placed`]: each matrix computed
/// when a chunk reaches its item, or taken from the item before when both are placed alike)
/// give the triangles and counters of items resolved beforehand, each with its own product.
#[test]
fn placed_sources_draw_as_items_resolved_beforehand() {
    use crate::clip_matrix::clip_from_local;
    use crate::options::DrawSource;
    use glam::Affine3A;
    let mut rng = sightline_scene::rng::Rng::new(5);
    let cam = camera(Vec3::new(0.0, 0.5, 6.0), 70.0, 0.5);
    let vp = Viewport::new(320, 200, true);
    let positions: Vec<Vec3> = (0..40).map(|_| random_position(&mut rng)).collect();
    let indices: Vec<u32> = (0..3 * 30).map(|_| rng.below(40)).collect();
    let ids: Vec<u32> = (0..30).rev().collect();
    // Runs of one placement and changes between them, an equal copy of one included.
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 0.0, 0.0));
    let placements = [at(0.0), at(0.0), at(0.7), at(0.0), at(0.7), at(0.7)];
    let sources: Vec<DrawSource> = placements
        .iter()
        .enumerate()
        .map(|(k, &world_from_local)| DrawSource {
            positions: &positions,
            indices: &indices,
            triangle_ids: (k % 2 == 0).then_some(&ids[..]),
            world_from_local,
            first_triangle: 100 * k as u32,
            first: 0,
            count: 30,
        })
        .collect();
    let (clip_from_world, simd) = (cam.clip_from_world_f64(), SimdLevel::Auto.resolve());
    let items: Vec<Item> = sources
        .iter()
        .map(|d| Item {
            src: Source::Mesh {
                positions: d.positions,
                indices: d.indices,
                clip_from_local: clip_from_local(&clip_from_world, &d.world_from_local, simd),
                ids: d.triangle_ids,
            },
            first_id: d.first_triangle + 1,
            source_triangles: 30,
        })
        .collect();
    let placed = Placed { sources: &sources, clip_from_world, simd };
    // Whole items, and one split in two pieces.
    let mut pieces: Vec<Piece> = (0..6).map(|k| Piece { item: k, start: 0, count: 30 }).collect();
    pieces.splice(2..3, [Piece { item: 2, start: 0, count: 11 }, Piece { item: 2, start: 11, count: 19 }]);
    fn run<L: DrawList + ?Sized>(list: &L, pieces: &[Piece], vp: &Viewport) -> (Vec<TriBits>, FrameStats) {
        let mut chunk = Chunk::default();
        chunk.process(list, pieces, vp, true);
        (chunk.tris.iter().map(tri_bits).collect(), chunk.stats)
    }
    let want = run(&items[..], &pieces, &vp);
    assert_eq!(run(&placed, &pieces, &vp), want);
    // The placements draw differently, so a matrix taken from the wrong item would show.
    let first = |k: usize| run(&items[..], &[Piece { item: k as u32, start: 0, count: 30 }], &vp).0;
    let ready = |t: &[TriBits]| t.iter().map(|b| (b.0, b.1)).collect::<Vec<_>>();
    assert!(!want.0.is_empty());
    assert_ne!(ready(&first(0)), ready(&first(2)));
}

#[test]
fn split_keeps_order_and_balances() {
    let items = [(0, 0, 10), (0, 5, 3), (0, 0, 0), (0, 2, 7)];
    let mut out = Vec::new();
    split(&items, 4, &mut out);
    assert_eq!(out.len(), 4);
    let flat: Vec<_> = out.iter().flatten().map(|p| (p.item, p.start, p.count)).collect();
    let total: u32 = flat.iter().map(|p| p.2).sum();
    assert_eq!(total, 20);
    for c in &out {
        assert!(c.iter().map(|p| p.count).sum::<u32>() <= 5);
    }
    // Contiguous, in submission order.
    assert_eq!(flat[0], (0, 0, 5));
    assert_eq!(flat[1], (0, 5, 5));
    assert_eq!(flat[2], (1, 5, 3));
}

/// Two pieces draw the same data (and the prefetches for the later one are skipped) only
/// when they are the same triangles of one mesh: instances of a cluster under two matrices,
/// not another range of the mesh, another mesh with equal contents, or raw triangles.
#[test]
fn pieces_share_data_only_for_the_same_triangles_of_one_mesh() {
    let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    let indices: Vec<u32> = vec![0, 1, 2, 0, 2, 3];
    let copy = indices.clone();
    let clip = [[Vec4::ZERO; 3]];
    let src = |idx| Source::Mesh { positions: &positions, indices: idx, clip_from_local: Mat4::IDENTITY, ids: None };
    let moved = Source::Mesh {
        positions: &positions,
        indices: &indices,
        clip_from_local: Mat4::from_scale(Vec3::splat(2.0)),
        ids: None,
    };
    let items = [
        Item { src: src(&indices), first_id: 1, source_triangles: 2 },
        Item { src: moved, first_id: 10, source_triangles: 2 },
        Item { src: src(&copy), first_id: 20, source_triangles: 2 },
        Item { src: Source::Clip(&clip), first_id: 30, source_triangles: 1 },
    ];
    let piece = |item, start| Piece { item, start, count: 1 };
    assert!(same_data(&items[..], &piece(0, 1), &piece(1, 1)), "one cluster, two instances");
    assert!(!same_data(&items[..], &piece(0, 0), &piece(1, 1)), "another range");
    assert!(!same_data(&items[..], &piece(0, 1), &piece(2, 1)), "another mesh with equal contents");
    assert!(!same_data(&items[..], &piece(3, 0), &piece(3, 0)), "raw triangles");
}

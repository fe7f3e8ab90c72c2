//! The rasterizer against per-pixel references, for every kernel the CPU has.

use super::kernel::{fragment, Row};
#[cfg(target_arch = "x86_64")]
use super::kernel::{row_scalar, row_sse2};
use super::*;
use crate::depth::{Unorm16, Unorm24, F32};
use crate::hzb::tile::OFFSETS;
use crate::setup::{setup, Setup, SnappedVertex, Viewport};
use crate::tiling::{TileRect, TILE};

/// The best kernel the CPU has (and `SIGHTLINE_SIMD` allows).
fn best() -> SimdLevel {
    SimdLevel::Auto.resolve()
}

/// `raster_tri` with the kernel of instruction set `simd` (the row kernel below AVX2).
fn draw_tri<D: DepthCodec, const C: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    simd: SimdLevel,
) -> TriRaster {
    // SAFETY: `kernels()` and `best()` give only levels the CPU has.
    unsafe {
        match simd {
            SimdLevel::Avx512 => raster_tri::<D, C, Avx512>(t, tile, lv),
            SimdLevel::Avx2 => raster_tri::<D, C, Avx2>(t, tile, lv),
            _ => raster_tri::<D, C, Rows>(t, tile, lv),
        }
    }
}

/// The kernels to test: rows always, AVX2 and AVX-512 when available.
fn kernels() -> Vec<SimdLevel> {
    [SimdLevel::Portable, SimdLevel::Avx2, SimdLevel::Avx512].into_iter().filter(|&l| l <= best()).collect()
}

fn levels_of(tile: &TileBuf) -> TileLevels {
    TileLevels::new(tile.rect)
}

fn tri(pts: [(f32, f32); 3], id: u32, vp: &Viewport) -> Option<Tri> {
    let v = pts.map(|(x, y)| SnappedVertex { x: crate::setup::snap(x), y: crate::setup::snap(y), z: 0.5 });
    match setup(v, id, false, vp) {
        Setup::Ready(t) => Some(t),
        _ => None,
    }
}

fn draw(tris: &[Tri], w: u32, h: u32) -> (Vec<u32>, Vec<u32>) {
    let mut result = None;
    for simd in kernels() {
        let mut tile = TileBuf::new(TileRect { x0: 0, y0: 0, w, h });
        let mut lv = levels_of(&tile);
        tile.depth.fill(F32::key(1.0));
        for t in tris {
            draw_tri::<F32, true>(t, &mut tile, &mut lv, simd);
        }
        let pick = |v: &Vec<u32>| -> Vec<u32> {
            (0..h).flat_map(|y| (0..w).map(move |x| (y * TILE + x) as usize)).map(|i| v[i]).collect()
        };
        let r = (pick(&tile.ids), pick(&tile.counts));
        if let Some(first) = &result {
            assert_eq!(first, &r, "the {simd:?} kernel draws what the row kernel draws");
        }
        result = Some(r);
    }
    result.expect("at least the row kernel")
}

/// llvmpipe's fill rule probed in image coordinates (y down): which triangle owns centers
/// on a shared horizontal and a shared vertical edge.
#[test]
fn llvmpipe_tie_rule_probe() {
    let vp = Viewport::new(8, 8, true);
    let flip = |(x, y): (f32, f32)| (x, 8.0 - y); // the probe gives GL window coords
    let case = |p: [(f32, f32); 6]| {
        let p = p.map(flip);
        let a = tri([p[0], p[1], p[2]], 1, &vp).unwrap();
        let b = tri([p[3], p[4], p[5]], 2, &vp).unwrap();
        draw(&[a, b], 8, 8)
    };
    // Horizontal edge at GL y 4.5 = image row 3: goes to the triangle visually above.
    let (ids, counts) = case([(0.0, 4.5), (4.0, 0.0), (8.0, 4.5), (0.0, 4.5), (8.0, 4.5), (4.0, 9.0)]);
    assert_eq!(&ids[3 * 8 + 2..3 * 8 + 6], &[2, 2, 2, 2]);
    assert!(counts[3 * 8 + 2..3 * 8 + 6].iter().all(|&c| c == 1));
    // Vertical edge at x 4.5 = column 4: goes to the triangle on the right.
    let (ids, _) = case([(4.5, 0.0), (4.5, 8.0), (0.0, 4.0), (4.5, 8.0), (4.5, 0.0), (9.0, 4.0)]);
    for row in 2..6 {
        assert_eq!(ids[row * 8 + 4], 2, "row {row}");
        assert_eq!(ids[row * 8 + 3], 1, "row {row}");
    }
}

#[cfg(target_arch = "x86_64")]
#[test]
fn sse2_rows_equal_scalar_rows() {
    let mut rng = sightline_scene::rng::Rng::new(5);
    for _ in 0..2000 {
        let n = 1 + rng.below(40) as i32;
        let r = Row {
            e: [0; 3].map(|_| rng.below(4000) as i32 - 2000),
            a: [0; 3].map(|_| (rng.below(600) as i32 - 300) * 256),
            n,
            zrow: rng.range(-0.1, 1.1),
            zx: rng.range(-1e-3, 1e-3),
            zmin: rng.range(-0.2, 0.8),
            dx0: rng.below(512) as i32 - 256,
            id: 1 + rng.below(100),
        };
        let len = ((n + 7) & !7) as usize + 4;
        let init: Vec<u32> = (0..len).map(|_| F32::key(rng.f32())).collect();
        for fmt in [0u8, 16, 24] {
            let (mut d1, mut i1, mut c1) = (init.clone(), vec![7u32; len], vec![0u32; len]);
            let (mut d2, mut i2, mut c2) = (init.clone(), vec![7u32; len], vec![0u32; len]);
            let (mut o1, mut o2) = (TriRaster::default(), TriRaster::default());
            let n4 = ((n + 3) & !3) as usize;
            match fmt {
                16 => {
                    row_scalar::<Unorm16, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                    row_sse2::<Unorm16, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                }
                24 => {
                    row_scalar::<Unorm24, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                    row_sse2::<Unorm24, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                }
                _ => {
                    row_scalar::<F32, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                    row_sse2::<F32, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                }
            }
            assert_eq!((d1, i1, c1), (d2, i2, c2));
            assert_eq!((o1.covered, o1.written), (o2.covered, o2.written));
        }
    }
}

/// Per pixel on i64 edges, the textbook loop: what every fast path must equal.
fn reference<D: DepthCodec>(t: &Tri, tile: &mut TileBuf) -> TriRaster {
    let e = edges(t);
    let mut out = TriRaster::default();
    let x1 = (t.bbox[2] as u32).min(tile.rect.x0 + tile.rect.w - 1);
    let y1 = (t.bbox[3] as u32).min(tile.rect.y0 + tile.rect.h - 1);
    for py in (t.bbox[1] as u32).max(tile.rect.y0)..=y1 {
        for px in (t.bbox[0] as u32).max(tile.rect.x0)..=x1 {
            let (x, y) = (px as i64, py as i64);
            if e.iter().all(|e| e.a * x + e.b * y + e.c >= 0) {
                let z = t.depth_at(t.depth_row(py as i32), px as i32);
                let idx = (((py - tile.rect.y0) << TILE_SHIFT) + px - tile.rect.x0) as usize;
                fragment::<D, true>(tile, idx, z, t.id, &mut out);
            }
        }
    }
    out
}

/// The block walk and kernel give the reference's depths, IDs, counts and counters bit
/// for bit, for overlapping random triangles of every size and all depth formats.
#[test]
fn block_kernel_equals_per_pixel_reference() {
    let vp = Viewport::new(200, 150, true);
    let mut rng = sightline_scene::rng::Rng::new(21);
    for (fmt, simd) in [0u8, 16, 24].into_iter().flat_map(|f| kernels().into_iter().map(move |k| (f, k))) {
        let mut a = TileBuf::new(TileRect { x0: 64, y0: 64, w: 64, h: 64 });
        let mut lv = levels_of(&a);
        a.depth.fill(F32::key(1.0));
        let mut b = a.clone();
        for n in 0..3000 {
            let s = [0.5f32, 4.0, 30.0, 300.0][n % 4];
            let (cx, cy) = (rng.range(40.0, 150.0), rng.range(40.0, 150.0));
            let mut p = || (cx + rng.range(-s, s), cy + rng.range(-s, s));
            let pts = [p(), p(), p()];
            let v = pts.map(|(x, y)| SnappedVertex {
                x: crate::setup::snap(x),
                y: crate::setup::snap(y),
                z: rng.range(0.0, 1.0),
            });
            let Setup::Ready(t) = setup(v, 1 + rng.below(50), false, &vp) else { continue };
            let (ra, rb) = match fmt {
                16 => (draw_tri::<Unorm16, true>(&t, &mut a, &mut lv, simd), reference::<Unorm16>(&t, &mut b)),
                24 => (draw_tri::<Unorm24, true>(&t, &mut a, &mut lv, simd), reference::<Unorm24>(&t, &mut b)),
                _ => (draw_tri::<F32, true>(&t, &mut a, &mut lv, simd), reference::<F32>(&t, &mut b)),
            };
            assert_eq!((ra.covered, ra.written), (rb.covered, rb.written), "triangle {n} {pts:?}");
        }
        assert_eq!(a.depth, b.depth);
        assert_eq!(a.ids, b.ids);
        assert_eq!(a.counts, b.counts);
        assert!(a.ids.iter().filter(|&&i| i != 0).count() > 3000, "the tile got drawn");
    }
}

/// With coarse depth on (frame sessions), skipping blocks behind the pyramid changes no
/// pixel, and every block written gets its level-3 texel refreshed at once, exactly the
/// max of its depths, before any later triangle is tested against it.
#[test]
fn coarse_blocks_skip_nothing_visible_and_refresh_their_texel() {
    let vp = Viewport::new(64, 64, true);
    for simd in kernels() {
        let mut rng = sightline_scene::rng::Rng::new(9);
        let mut a = TileBuf::new(TileRect { x0: 0, y0: 0, w: 64, h: 64 });
        a.clear_for_session::<F32>(false);
        let mut lv = levels_of(&a);
        lv.clear::<F32>();
        lv.coarse = true;
        let mut b = a.clone();
        let mut skipped = 0;
        for n in 0..2000 {
            let s = [3.0f32, 12.0, 40.0][n % 3];
            let (cx, cy) = (rng.range(0.0, 64.0), rng.range(0.0, 64.0));
            let z = rng.range(0.0, 1.0);
            let mut p = || SnappedVertex {
                x: crate::setup::snap(cx + rng.range(-s, s)),
                y: crate::setup::snap(cy + rng.range(-s, s)),
                z: (z + rng.range(-0.05, 0.05)).clamp(0.0, 1.0),
            };
            let v = [p(), p(), p()];
            let Setup::Ready(t) = setup(v, 1 + n as u32, false, &vp) else { continue };
            let (ra, rb) = (draw_tri::<F32, false>(&t, &mut a, &mut lv, simd), reference::<F32>(&t, &mut b));
            assert_eq!(ra.written, rb.written, "triangle {n}");
            skipped += (ra.covered < rb.covered) as u32;
            let mut stale = lv.stale_blocks;
            while stale != 0 {
                let k = stale.trailing_zeros() as usize;
                stale &= stale - 1;
                let (bx, by) = ((k % 8) * 8, (k / 8) * 8);
                let max = (by..by + 8).flat_map(|y| (bx..bx + 8).map(move |x| y * 64 + x)).map(|i| a.depth[i]).max();
                assert_eq!(lv.mips[OFFSETS[2] + k], f32::from_bits(max.unwrap()), "block {k} after triangle {n}");
            }
        }
        assert_eq!((&a.depth, &a.ids), (&b.depth, &b.ids));
        assert!(skipped > 100, "coarse depth skipped blocks of only {skipped} triangles");
    }
}

/// A tile made larger than its buffers (only possible inside the crate) is caught in
/// checked builds, never written out of bounds: by the AVX2 kernel's debug check, by the
/// row loops' slice bounds. (Release builds leave the kernel's check out: there the
/// misuse is not caught, so the test runs only where it is.)
#[cfg(debug_assertions)]
#[test]
#[should_panic]
fn oversized_hand_built_tile_panics() {
    let vp = Viewport::new(200, 200, true);
    let t = tri([(0.5, 0.5), (199.5, 0.5), (0.5, 199.5)], 1, &vp).unwrap();
    let mut tile = TileBuf::new(TileRect { x0: 0, y0: 0, w: 200, h: 200 });
    let mut lv = levels_of(&tile);
    draw_tri::<F32, false>(&t, &mut tile, &mut lv, best());
}

#[test]
fn big_and_sliver_triangles_cover_exactly() {
    let vp = Viewport::new(64, 64, true);
    let t = tri([(0.3, 0.7), (63.2, 20.1), (10.4, 63.9)], 1, &vp).unwrap();
    covers_exactly_its_pixels(&t, "first");
    // A long steep edge: its step per pixel times a block offset leaves i32 although
    // every edge value over the box fits (found in review; checked builds overflowed).
    let steep = tri([(9.36, -514.5), (60.3, 534.0), (16.7, -178.9)], 1, &vp)
        .or_else(|| tri([(9.36, -514.5), (16.7, -178.9), (60.3, 534.0)], 1, &vp))
        .expect("the steep triangle covers pixels of the tile");
    assert!(covers_exactly_its_pixels(&steep, "steep") > 0);
    // Many like it: edges a few hundred to a thousand pixels long across the tile.
    let mut rng = sightline_scene::rng::Rng::new(17);
    for _ in 0..500 {
        let mut p = |r: f32| (rng.range(-40.0, 104.0), rng.range(-r, r));
        let pts = [p(1200.0), p(1200.0), p(100.0)];
        if let Some(t) = tri(pts, 1, &vp) {
            covers_exactly_its_pixels(&t, "long edge");
        }
    }
    // Huge triangles (vertices thousands of pixels away, as near-plane-hugging geometry
    // gives): partly covered blocks run on i32 when their edge values fit, else on i64.
    let mut rng = sightline_scene::rng::Rng::new(11);
    let (mut checked, mut partly) = (0, 0);
    while checked < 300 {
        let mut far = || (rng.range(-16000.0, 16064.0), rng.range(-16000.0, 16064.0));
        let pts = [far(), far(), (rng.range(-40.0, 104.0), rng.range(-40.0, 104.0))];
        let Some(t) = tri(pts, 1, &vp) else { continue };
        let e = edges(&t);
        let (ids, _) = draw(&[t], 64, 64);
        partly += (ids.contains(&0) && ids.contains(&1)) as u32;
        for py in t.bbox[1] as i64..=t.bbox[3] as i64 {
            for px in t.bbox[0] as i64..=t.bbox[2] as i64 {
                let inside = e.iter().all(|e| e.a * px + e.b * py + e.c >= 0);
                assert_eq!(ids[(py * 64 + px) as usize] == 1, inside, "{pts:?} at {px},{py}");
            }
        }
        checked += 1;
    }
    assert!(partly >= 50, "only {partly} triangles cross the tile");
    // A sliver one block wide with a steep edge: its values over the box fit i32, but
    // an edge's spread over a whole block does not (found in review; it overflowed).
    let sliver = tri([(4.0, -3000.0), (4.0, 3000.0), (5.0, 0.0)], 1, &vp)
        .or_else(|| tri([(4.0, -3000.0), (5.0, 0.0), (4.0, 3000.0)], 1, &vp))
        .expect("the sliver covers column 4");
    assert!(covers_exactly_its_pixels(&sliver, "sliver") > 0, "the sliver draws column 4");
    let mut big = t;
    big.x = t.x.map(|v| v * 2);
    big.y = t.y.map(|v| v * 2);
    big.bbox = [0, 0, 63, 63];
    covers_exactly_its_pixels(&big, "doubled");
}

/// Draws `t` alone into a 64 × 64 tile and checks every pixel against the i64 edge
/// functions; returns the pixels covered.
fn covers_exactly_its_pixels(t: &Tri, label: &str) -> usize {
    let (ids, _) = draw(&[*t], 64, 64);
    let e = edges(t);
    for py in 0..64i64 {
        for px in 0..64i64 {
            let inside = e.iter().all(|e| e.a * px + e.b * py + e.c >= 0);
            assert_eq!(ids[(py * 64 + px) as usize] == 1, inside, "{label} at {px},{py}");
        }
    }
    ids.iter().filter(|&&i| i == 1).count()
}

/// A fragment whose depth is NaN is never written, in every depth format and with every
/// kernel (on GPUs every comparison with NaN fails); its pixels still count as covered. The
/// vector kernels never see such a plane (see [`Tri::depths_are_numbers`]).
#[test]
fn nan_depth_is_never_written() {
    fn check<D: DepthCodec>(simd: SimdLevel) {
        let vp = Viewport::new(64, 64, true);
        let mut t = tri([(1.0, 1.0), (60.0, 3.0), (5.0, 62.0)], 9, &vp).unwrap();
        let mut tile = TileBuf::new(TileRect { x0: 0, y0: 0, w: 64, h: 64 });
        let mut lv = levels_of(&tile);
        tile.depth.fill(D::key(1.0));
        for (z0, zx) in [(f32::NAN, 0.0), (0.5, f32::NAN), (-f32::NAN, 0.0)] {
            (t.z0, t.zx) = (z0, zx);
            let r = draw_tri::<D, true>(&t, &mut tile, &mut lv, simd);
            assert!(r.covered > 1000, "{:?}: the triangle covers its pixels", D::FORMAT);
            assert_eq!(r.written, 0, "{:?} {simd:?}: a NaN depth was written", D::FORMAT);
        }
        assert!(tile.ids.iter().all(|&i| i == 0));
        assert!(tile.depth[..(TILE * TILE) as usize].iter().all(|&k| k == D::key(1.0)));
        // Coefficients that are numbers yet so large that the plane is −∞ on every row and
        // ±∞ along them, on either side of vertex 0: NaN (∞ − ∞) left of it, never
        // written, and −∞ right of it, raised to the nearest vertex, as in the reference.
        let mut u = tri([(32.0, 1.0), (62.0, 60.0), (2.0, 50.0)], 9, &vp).unwrap();
        (u.z0, u.zx, u.zy) = (0.5, -1e38, -1e38);
        let mut reached = tile.clone();
        let drawn = draw_tri::<D, true>(&u, &mut tile, &mut lv, simd);
        let expected = reference::<D>(&u, &mut reached);
        assert_eq!((drawn.covered, drawn.written), (expected.covered, expected.written));
        assert!(expected.written > 500 && expected.written + 500 < expected.covered, "{:?}", D::FORMAT);
        assert_eq!((tile.depth, tile.ids), (reached.depth, reached.ids), "{:?} {simd:?}", D::FORMAT);
    }
    for simd in kernels() {
        check::<F32>(simd);
        check::<Unorm24>(simd);
        check::<Unorm16>(simd);
    }
}

/// No pixel is written nearer than the triangle's nearest vertex, with every kernel: the
/// depth plane of a sliver reaching thousands of pixels off screen, evaluated in f32 far from
/// its vertices, comes out below them by more than the box tests of culling allow for, and
/// the rasterizer clamps it (`Tri::depth_at`).
#[test]
fn no_pixel_is_nearer_than_the_nearest_vertex() {
    let vp = Viewport::new(64, 64, true);
    let mut rng = sightline_scene::rng::Rng::new(23);
    let (mut drawn, mut plane_below, mut far_below) = (0, 0, 0);
    while drawn < 400 {
        // Two vertices far off on either side of the tile, the third a few pixels off the
        // line between them: a sliver across the tile, its depth changing fast across it
        // and not along it (the long edge at one depth, so that pixels along it are,
        // exactly, at that depth). Half of the long edges run diagonally through pixel
        // centers, which then lie exactly on them.
        let p = (rng.below(64) as f32 + 0.5, rng.below(64) as f32 + 0.5);
        let (dx, dy) = match rng.below(4) {
            0 => (1.0, 1.0),
            1 => (1.0, -1.0),
            _ => {
                let angle = rng.range(-3.1f32, 3.1);
                (angle.cos(), angle.sin())
            }
        };
        let (la, lb) = (rng.below(14000) as f32 + 2000.0, rng.below(14000) as f32 + 2000.0);
        let a = (p.0 - la * dx, p.1 - la * dy);
        let b = (p.0 + lb * dx, p.1 + lb * dy);
        let off = rng.range(1.0, 4.0) * if rng.below(2) == 0 { 1.0 } else { -1.0 };
        let mid = (p.0 - off * dy, p.1 + off * dx);
        let near = rng.range(0.98, 0.99);
        let far_z = near + [1e-2, 1e-4, 1e-6][rng.below(3) as usize];
        let z = [near, near, far_z];
        let v = [a, b, mid].map(|(x, y)| (crate::setup::snap(x), crate::setup::snap(y)));
        let verts = std::array::from_fn(|k| SnappedVertex { x: v[k].0, y: v[k].1, z: z[k] });
        let Setup::Ready(t) = setup(verts, 5, false, &vp) else { continue };
        drawn += 1;
        let zmin = z[0].min(z[1]).min(z[2]);
        for simd in kernels() {
            let mut tile = TileBuf::new(TileRect { x0: 0, y0: 0, w: 64, h: 64 });
            let mut lv = levels_of(&tile);
            tile.depth.fill(F32::key(1.0));
            draw_tri::<F32, false>(&t, &mut tile, &mut lv, simd);
            for py in 0..64u32 {
                for px in 0..64u32 {
                    let i = ((py << TILE_SHIFT) + px) as usize;
                    if tile.ids[i] == 5 {
                        assert!(tile.depth[i] >= F32::key(zmin), "{simd:?}: pixel ({px}, {py}) of {t:?}");
                        // The plane itself, unclamped, as the kernels evaluate it.
                        let x = ((px as i32) << crate::edge::SUBPIXEL_BITS) + crate::edge::ONE / 2 - t.x[0];
                        let plane = t.depth_row(py as i32) + t.zx * (x as f32);
                        plane_below += (plane < zmin) as u32;
                        far_below += (plane < zmin - 8.0 * f32::EPSILON) as u32;
                    }
                }
            }
        }
    }
    // The test meets the case it is about, also by more than 8ε (twice the box
    // projector's fixed depth margin, 8u = 4ε).
    assert!(
        plane_below > 500 && far_below > 50,
        "the plane fell below the nearest vertex at {plane_below} pixels, by more than 8ε at {far_below}"
    );
}

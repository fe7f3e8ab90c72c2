//! Every projection path against the portable one, on random cameras, matrices and boxes.

use super::*;
use glam::Vec3;
use sightline_scene::{Angle, Camera, LookAt};

fn cam() -> Camera {
    Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.5,
            far: 100.0,
        },
        1.5,
    )
    .unwrap()
}

#[test]
fn box_crossing_near_plane_covers_screen_at_depth_zero() {
    let c = cam();
    let m = c.clip_from_world();
    // Straddles the near plane at z = 4.5.
    let b = Aabb::new(Vec3::new(-0.1, -0.1, 4.3), Vec3::new(0.1, 0.1, 4.7));
    let r = project_box(&b, &m, 96, 64);
    assert!(r.crosses_near);
    assert_eq!((r.x0, r.y0, r.x1, r.y1, r.depth), (0, 0, 96, 64, 0.0));
    // Entirely behind the eye: all corners lie beyond the near plane, so nothing of it
    // can be drawn.
    let b = Aabb::new(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0));
    assert!(project_box(&b, &m, 96, 64).is_empty());
    // NaN box: full screen.
    assert!(project_box(&Aabb::new(Vec3::NAN, Vec3::ONE), &m, 96, 64).crosses_near);
    assert!(project_box(&Aabb::EMPTY, &m, 96, 64).is_empty());
}

#[test]
fn rect_holds_the_pixel_centers_the_corners_span_and_no_others() {
    let c = cam();
    let m = c.clip_from_world();
    let (w, h) = (96u32, 64u32);
    let mut rng = sightline_scene::rng::Rng::new(5);
    let (mut tested, mut between_centers) = (0, 0);
    for k in 0..2000 {
        let lo = Vec3::new(rng.range(-3.0, 3.0), rng.range(-2.0, 2.0), rng.range(-10.0, 3.0));
        // Every fourth box tiny: most of those fall between pixel centers.
        let reach = if k % 4 == 0 { 0.02 } else { 1.0 };
        let e = Vec3::new(rng.range(0.0, reach), rng.range(0.0, reach), rng.range(0.0, reach));
        let b = Aabb::new(lo, lo + e);
        let r = project_box(&b, &m, w, h);
        assert!(!r.crosses_near);
        // The corners' window bounds, in f64.
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in b.corners() {
            let cl = m.as_dmat4() * p.as_dvec3().extend(1.0);
            let ndc = cl.truncate() / cl.w;
            let (xw, yw) = ((ndc.x + 1.0) * 0.5 * w as f64, (1.0 - ndc.y) * 0.5 * h as f64);
            let zw = ((ndc.z + 1.0) * 0.5) as f32;
            assert!(r.is_empty() || r.depth <= zw, "depth {} > corner {zw}", r.depth);
            (x0, x1, y0, y1) = (x0.min(xw), x1.max(xw), y0.min(yw), y1.max(yw));
        }
        // Every pixel whose center the corners span is in the rectangle...
        let centers = |a: f64, b: f64, n: u32| (0..n).filter(move |&i| (a..=b).contains(&(i as f64 + 0.5)));
        let any = centers(x0, x1, w).next().is_some() && centers(y0, y1, h).next().is_some();
        for (i, j) in centers(x0, x1, w).flat_map(|i| centers(y0, y1, h).map(move |j| (i, j))) {
            assert!(r.x0 <= i && i < r.x1 && r.y0 <= j && j < r.y1, "center of ({i}, {j}) outside {r:?}");
        }
        tested += any as u32;
        // ... and none farther than the margin (and float error) outside them.
        let slack = 2.0 / 128.0;
        if !r.is_empty() {
            let (cx0, cx1) = (r.x0 as f64 + 0.5, r.x1 as f64 - 0.5);
            let (cy0, cy1) = (r.y0 as f64 + 0.5, r.y1 as f64 - 0.5);
            assert!(cx0 >= x0 - slack && cx1 <= x1 + slack && cy0 >= y0 - slack && cy1 <= y1 + slack, "{r:?}");
        } else if x1 > 0.0 && x0 < w as f64 && y1 > 0.0 && y0 < h as f64 {
            between_centers += 1;
        }
    }
    assert!(tested > 400 && between_centers > 50, "{tested} {between_centers}");
}

/// A random box: mostly ordinary, sometimes flat, huge, empty, NaN or infinite.
fn random_box(rng: &mut sightline_scene::rng::Rng, reach: f32) -> Aabb {
    let mut v = || Vec3::new(rng.range(-reach, reach), rng.range(-reach, reach), rng.range(-reach, reach));
    let (lo, d) = (v(), v().abs() * 0.2);
    match rng.below(40) {
        0 => Aabb::new(lo, lo),
        1 => Aabb::new(lo + d, lo),
        2 => Aabb::new(Vec3::new(f32::NAN, lo.y, lo.z), lo + d),
        3 => Aabb::new(lo, Vec3::new(lo.x, f32::INFINITY, lo.z)),
        4 => Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38)),
        5 => Aabb::new(lo * 1e30, lo * 1e30 + d * 1e30),
        6 => Aabb::new(lo * 1e-30, lo * 1e-30 + d * 1e-30),
        _ => Aabb::new(lo, lo + d),
    }
}

/// A clip-from-world matrix of kind `k`: 3 arbitrary (some entries NaN, huge or
/// infinite), 4 orthographic (w = 1 everywhere; view volume [−5, 5] × [−3, 3] ×
/// [−25, 25]), otherwise a random perspective camera (`None` when it is invalid).
fn random_matrix(rng: &mut sightline_scene::rng::Rng, k: u32) -> Option<Mat4> {
    match k {
        3 => Some(Mat4::from_cols_array(&std::array::from_fn(|_| match rng.below(60) {
            0 => f32::NAN,
            1 => 1e30,
            2 => f32::INFINITY,
            _ => rng.range(-2.0, 2.0),
        }))),
        4 => Some(
            Mat4::from_scale(Vec3::new(0.2, 1.0 / 3.0, -0.04))
                * Mat4::from_translation(Vec3::new(rng.range(-5.0, 5.0), rng.range(-1.0, 1.0), 0.0)),
        ),
        _ => {
            let eye = Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
            let target = eye + Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let near = [1e-4, 0.1, 1.0][rng.below(3) as usize];
            let c = Camera::perspective(
                &LookAt { eye, target, up: Vec3::Y, fovy: Angle::degrees(rng.range(10.0, 120.0)), near, far: 500.0 },
                1.7,
            );
            c.ok().map(|c| c.clip_from_world())
        }
    }
}

/// A projector on each SIMD level this process has (`SIGHTLINE_SIMD` may cap them), the
/// portable one first.
fn on_every_level(m: Mat4, w: u32, h: u32) -> Vec<BoxProjector> {
    let levels = SimdLevel::all_available();
    assert_eq!(levels[0], SimdLevel::Portable);
    levels.into_iter().map(|l| BoxProjector::with_simd(m, w, h, l)).collect()
}

#[test]
fn projector_runs_on_the_level_it_resolved() {
    let m = cam().clip_from_world();
    for level in SimdLevel::all_available() {
        assert_eq!(BoxProjector::with_simd(m, 96, 64, level).simd(), level);
    }
    assert_eq!(BoxProjector::new(m, 96, 64).simd(), SimdLevel::best());
    assert_eq!(BoxProjector::with_simd(m, 96, 64, SimdLevel::Avx512).simd(), SimdLevel::Avx512.resolve());
    // Too large for the SIMD path's exact float clamp.
    assert_eq!(BoxProjector::new(m, 1 << 25, 8).simd(), SimdLevel::Portable);
}

/// `classify` gives exactly the answers of the portable path, at every SIMD level this
/// process has, on perspective and orthographic cameras, arbitrary matrices and every
/// kind of box.
#[test]
fn classify_equals_the_portable_path() {
    let mut rng = sightline_scene::rng::Rng::new(77);
    let mut kinds = [0usize; 3];
    for cam_i in 0..300 {
        let Some(m) = random_matrix(&mut rng, cam_i % 5) else { continue };
        let (w, h) = [(1280, 720), (97, 33), (1, 1), (0, 0), (4096, 3000)][rng.below(5) as usize];
        let levels = on_every_level(m, w, h);
        for _ in 0..400 {
            let reach = [1.0, 10.0, 100.0][rng.below(3) as usize];
            let b = random_box(&mut rng, reach);
            let portable = levels[0].classify_portable(&b);
            for p in &levels {
                let (fast, with) = (p.classify(&b), p.classify_with(&b, |i| bits(&i)));
                assert_eq!(bits(&fast), bits(&portable), "{:?}: {b:?} {m:?} {w}x{h}", p.simd());
                assert_eq!(with, bits(&portable), "{:?}: {b:?} {m:?} {w}x{h}", p.simd());
            }
            kinds[bits(&portable).0 as usize] += 1;
        }
    }
    assert!(kinds.iter().all(|&k| k > 2000), "{kinds:?}");
}

/// A [`BoxImage`] as its kind (0 outside, 1 crossing, 2 rectangle) and the rectangle's
/// x0, y0, x1, y1, depth bits (so that NaN would show as a mismatch) and crossing flag.
fn bits(i: &BoxImage) -> (u8, [u32; 6]) {
    match i {
        BoxImage::Outside => (0, [0; 6]),
        BoxImage::CrossesNear => (1, [0; 6]),
        BoxImage::Rect(r) => (2, [r.x0, r.y0, r.x1, r.y1, r.depth.to_bits(), r.crosses_near as u32]),
    }
}

/// `classify_many` (eight boxes per SIMD batch, the rest one by one) answers every box
/// exactly like the portable path, in order, whatever lane an unusual box lands in, at
/// every SIMD level this process has.
#[test]
fn classify_many_equals_the_portable_path() {
    let mut rng = sightline_scene::rng::Rng::new(78);
    let mut kinds = [0usize; 3];
    for cam_i in 0..200 {
        let Some(m) = random_matrix(&mut rng, if cam_i % 4 == 3 { 3 } else { 0 }) else { continue };
        let (w, h) = [(1280, 720), (97, 33), (1, 1), (0, 0), (4096, 3000), (1 << 25, 8)][rng.below(6) as usize];
        let reach = [1.0, 10.0, 100.0][rng.below(3) as usize];
        let n = rng.below(300) as usize;
        let boxes: Vec<Aabb> = (0..n).map(|_| random_box(&mut rng, reach)).collect();
        for p in on_every_level(m, w, h) {
            let mut next = 0;
            p.classify_many(&boxes, |i, image| {
                assert_eq!(i, next, "in order");
                next += 1;
                let portable = p.classify_portable(&boxes[i]);
                assert_eq!(bits(&image), bits(&portable), "{:?}: box {i} {:?} {m:?} {w}x{h}", p.simd(), boxes[i]);
                kinds[bits(&image).0 as usize] += 1;
            });
            assert_eq!(next, n);
        }
    }
    assert!(kinds.iter().all(|&k| k > 1000), "{kinds:?}");
}

#[test]
fn boxes_behind_the_eye_across_near_nan_and_empty() {
    let c = cam();
    for p in on_every_level(c.clip_from_world(), 96, 64) {
        for classify in [BoxProjector::classify, BoxProjector::classify_portable] {
            // Behind the eye (all corners beyond the near plane): outside.
            let b = Aabb::new(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0));
            assert_eq!(classify(&p, &b), BoxImage::Outside);
            // Around the eye, and across the near plane (z = 4.5).
            let b = Aabb::new(Vec3::new(-1.0, -1.0, 4.0), Vec3::new(1.0, 1.0, 6.0));
            assert_eq!(classify(&p, &b), BoxImage::CrossesNear);
            let b = Aabb::new(Vec3::new(-0.1, -0.1, 4.3), Vec3::new(0.1, 0.1, 4.7));
            assert_eq!(classify(&p, &b), BoxImage::CrossesNear);
            assert_eq!(classify(&p, &Aabb::new(Vec3::NAN, Vec3::ONE)), BoxImage::CrossesNear);
            assert_eq!(classify(&p, &Aabb::new(Vec3::ZERO, Vec3::INFINITY)), BoxImage::CrossesNear);
            assert_eq!(classify(&p, &Aabb::EMPTY), BoxImage::Outside);
            // Overflowing corners: no rectangle.
            assert_eq!(classify(&p, &Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38))), BoxImage::CrossesNear);
            // A point box on a pixel center is a rectangle of that one pixel; one on a pixel
            // corner (the origin lands on (48, 32)) covers no center.
            let center = Vec3::new(4.33 / 96.0, -4.33 / 96.0, 0.0) * (30f32.to_radians().tan() / 0.57735);
            let BoxImage::Rect(r) = classify(&p, &Aabb::new(center, center)) else { panic!() };
            assert!((r.x0, r.y0, r.x1, r.y1) == (48, 32, 49, 33) && r.depth > 0.0 && r.depth < 1.0, "{r:?}");
            assert_eq!(classify(&p, &Aabb::new(Vec3::ZERO, Vec3::ZERO)), BoxImage::Outside);
        }
    }
}

/// Finite clip terms whose projection overflows (x/w or z/w) or whose w sums to +∞ at
/// some corners, while the box stays in front of the near plane: no rectangle
/// (crossing), on every path and in every lane of a batch.
#[test]
fn overflowing_projections_cross_near() {
    let m = |x: Vec4, z: Vec4, w: Vec4| Mat4::from_cols(x, Vec4::Y, z, w);
    let tiny_w = Vec4::new(0.0, 0.0, 0.0, 1e-5);
    let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
    let cases = [
        // x/w = 1e38 / 1e-5 at the corners with x = 1.
        m(Vec4::new(1e38, 0.0, 0.0, 0.0), Vec4::ZERO, tiny_w),
        // z/w = 1e38 / 1e-5 at the corners with z = 1.
        m(Vec4::X, Vec4::new(0.0, 0.0, 1e38, 0.0), tiny_w),
        // w = 3e38 + 3e38 at the corners with z = 1.
        m(Vec4::X, Vec4::new(0.0, 0.0, 0.0, 3e38), Vec4::new(0.0, 0.0, 0.0, 3e38)),
    ];
    for m in cases {
        // Odd sizes, so that NDC x = 0 and y = 0 land on pixel centers.
        for p in on_every_level(m, 63, 47) {
            assert_eq!(p.classify_portable(&unit), BoxImage::CrossesNear, "{:?}: {m:?}", p.simd());
            assert_eq!(p.classify(&unit), BoxImage::CrossesNear, "{:?}: {m:?}", p.simd());
            let ordinary = Aabb::new(Vec3::ZERO, Vec3::new(0.0, 0.2, 0.0));
            assert!(matches!(p.classify_portable(&ordinary), BoxImage::Rect(_)), "{:?}: {m:?}", p.simd());
            // Every lane of a call's four batches, and of a shorter last group.
            for lane in 0..BATCH + 7 {
                let mut boxes = [ordinary; BATCH + 7];
                boxes[lane] = unit;
                p.classify_many(&boxes, |i, image| {
                    assert_eq!(image, p.classify_portable(&boxes[i]), "{:?}: lane {lane}, box {i}, {m:?}", p.simd());
                });
            }
        }
    }
}

#[test]
fn offscreen_box_is_empty() {
    let c = cam();
    let m = c.clip_from_world();
    let b = Aabb::new(Vec3::new(30.0, -0.5, -1.0), Vec3::new(31.0, 0.5, 0.0));
    assert!(project_box(&b, &m, 96, 64).is_empty());
}

/// A perspective camera `distance` from the world's origin, looking in a random direction
/// (`None` when the random choice is invalid).
fn far_camera(rng: &mut sightline_scene::rng::Rng, distance: f32) -> Option<Camera> {
    let dir = |rng: &mut sightline_scene::rng::Rng| {
        Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize_or(Vec3::X)
    };
    let eye = dir(rng) * distance;
    let target = eye + dir(rng);
    let near = [0.05, 0.5][rng.below(2) as usize];
    let fovy = Angle::degrees(rng.range(20.0, 100.0));
    Camera::perspective(&LookAt { eye, target, up: Vec3::Y, fovy, near, far: 5000.0 }, 16.0 / 9.0).ok()
}

/// A box in front of `cam` at 0.3 to 2000 units, sometimes flat (a facade seen head on or
/// edge on).
fn box_in_view(rng: &mut sightline_scene::rng::Rng, cam: &Camera) -> Aabb {
    let v = &cam.view;
    let ahead = -v.w * rng.range(0.3, 1.0) + v.u * rng.range(-0.8, 0.8) + v.v * rng.range(-0.5, 0.5);
    let center = v.eye + ahead.normalize() * rng.range(0.3f32, 2000.0).powf(rng.range(0.5, 1.0));
    let mut half = Vec3::new(rng.range(0.0, 3.0), rng.range(0.0, 3.0), rng.range(0.0, 3.0));
    if rng.below(3) == 0 {
        half[rng.below(3) as usize] = 0.0;
    }
    Aabb::new(center - half, center + half)
}

/// Far from the world's origin f32 coordinates are coarse: at 3·10^4 units one step is
/// 0.002. The depth and rectangle of a box must still bound the exact (f64) projection of
/// its corners with the camera's own f64 matrix, whether it is projected from the world's
/// origin ([`BoxProjector::new`]) or from the eye ([`BoxProjector::for_camera`]); from the
/// eye the margin stays small.
#[test]
fn margins_cover_the_rounding_far_from_the_origin() {
    let (w, h) = (1280u32, 720u32);
    let mut rng = sightline_scene::rng::Rng::new(91);
    let (mut rects, mut loosest) = (0, 0f64);
    for cam_i in 0..120 {
        let Some(cam) = far_camera(&mut rng, [0.0, 1e3, 3e4][cam_i % 3]) else { continue };
        let exact = cam.clip_from_world_f64();
        let projectors = [BoxProjector::new(cam.clip_from_world(), w, h), BoxProjector::for_camera(&cam, w, h, 0.0)];
        for _ in 0..200 {
            let b = box_in_view(&mut rng, &cam);
            let corners: Vec<_> = b.corners().iter().map(|p| exact * p.as_dvec3().extend(1.0)).collect();
            // Only boxes clearly in front of the near plane: at it the answer may go either way.
            if corners.iter().any(|c| c.w <= 0.0 || c.z < -c.w * 0.999) {
                continue;
            }
            let ndc: Vec<_> = corners.iter().map(|c| c.truncate() / c.w).collect();
            let z = ndc.iter().map(|n| (n.z + 1.0) * 0.5).fold(f64::MAX, f64::min);
            let xs = ndc.iter().map(|n| (n.x + 1.0) * 0.5 * w as f64);
            let ys = ndc.iter().map(|n| (1.0 - n.y) * 0.5 * h as f64);
            let (x0, x1) = (xs.clone().fold(f64::MAX, f64::min), xs.fold(f64::MIN, f64::max));
            let (y0, y1) = (ys.clone().fold(f64::MAX, f64::min), ys.fold(f64::MIN, f64::max));
            // The pixels whose centers the exact corners span, within the viewport.
            let first = |a: f64, n: u32| (a - 0.5).ceil().clamp(0.0, n as f64) as u32;
            let end = |b: f64, n: u32| ((b - 0.5).floor() + 1.0).clamp(0.0, n as f64) as u32;
            let (px0, px1, py0, py1) = (first(x0, w), end(x1, w), first(y0, h), end(y1, h));
            let covers_some = px0 < px1 && py0 < py1;
            for (k, p) in projectors.iter().enumerate() {
                match p.classify(&b) {
                    BoxImage::Rect(r) => {
                        assert!(
                            r.depth as f64 <= z,
                            "projector {k}: depth {} > exact {z} for {b:?}, eye {}",
                            r.depth,
                            cam.view.eye
                        );
                        if covers_some {
                            assert!(
                                r.x0 <= px0 && px1 <= r.x1 && r.y0 <= py0 && py1 <= r.y1,
                                "projector {k}: {r:?} misses pixels {px0}..{px1} × {py0}..{py1} of {b:?}"
                            );
                        }
                        if k == 1 {
                            rects += 1;
                            // The margin against what moving the box 10^-3 of its distance
                            // nearer changes its depth by (window z = f/(f − n)·(1 − n/d),
                            // so about n/d·10^-3), plus a few times the fixed 10^-6 the
                            // margin replaced.
                            let w_min = corners.iter().map(|c| c.w).fold(f64::MAX, f64::min);
                            let p = cam.projection.clip_from_view_f64();
                            let near = p.w_axis.z / (p.z_axis.z - 1.0);
                            loosest = loosest.max((z - r.depth as f64) / (4e-6 + 1e-3 * near / w_min));
                        }
                    }
                    BoxImage::Outside => assert!(!covers_some, "projector {k}: {b:?} called outside"),
                    BoxImage::CrossesNear => {}
                }
            }
        }
    }
    assert!(rects > 5000, "{rects} rectangles");
    assert!(loosest < 1.0, "a margin reached {loosest} of its allowance");
}

/// [`BoxProjector::for_camera`] answers every box alike at every SIMD level, one box at a
/// time and eight at a time, for cameras far from the origin and any reach.
#[test]
fn camera_relative_projectors_agree_on_every_level() {
    let mut rng = sightline_scene::rng::Rng::new(92);
    let mut kinds = [0usize; 3];
    for cam_i in 0..120 {
        let Some(cam) = far_camera(&mut rng, [0.0, 1e3, 3e4][cam_i % 3]) else { continue };
        let reach = [0.0, 10.0, 1e4, f32::INFINITY][rng.below(4) as usize];
        let (w, h) = [(1280, 720), (97, 33), (1, 1)][rng.below(3) as usize];
        let boxes: Vec<Aabb> = (0..rng.below(200) as usize)
            .map(|_| match rng.below(4) {
                0 => random_box(&mut rng, 50.0),
                _ => box_in_view(&mut rng, &cam),
            })
            .collect();
        let levels: Vec<_> = SimdLevel::all_available()
            .into_iter()
            .map(|l| BoxProjector::for_camera_with_simd(&cam, w, h, reach, l))
            .collect();
        for p in &levels {
            p.classify_many(&boxes, |i, image| {
                let portable = levels[0].classify_portable(&boxes[i]);
                assert_eq!(bits(&image), bits(&portable), "{:?}: box {i} {:?}", p.simd(), boxes[i]);
                assert_eq!(bits(&p.classify(&boxes[i])), bits(&portable), "{:?}: {:?}", p.simd(), boxes[i]);
                kinds[bits(&image).0 as usize] += 1;
            });
        }
    }
    assert!(kinds.iter().all(|&k| k > 200), "{kinds:?}");
}

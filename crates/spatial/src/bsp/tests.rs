use super::*;
use glam::{Mat4, Vec4};
use sightline_scene::rng::Rng;
use sightline_scene::{Angle, Camera, LookAt};
use std::ops::ControlFlow;

/// A tiny reference rasterizer: pixel-center coverage (either facing), window depth
/// interpolated in screen space. `depth_test = false` is the painter's algorithm.
fn raster(tris: &[([Vec3; 3], u32)], m: &Mat4, w: usize, h: usize, depth_test: bool) -> Vec<u32> {
    let mut ids = vec![0u32; w * h];
    let mut depth = vec![1.0f32; w * h];
    for (v, id) in tris {
        let p = v.map(|p| {
            let c = *m * p.extend(1.0);
            let n = c.truncate() / c.w;
            Vec3::new((n.x + 1.0) * 0.5 * w as f32, (1.0 - n.y) * 0.5 * h as f32, (n.z + 1.0) * 0.5)
        });
        let area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
        if area == 0.0 {
            continue;
        }
        for j in 0..h {
            for i in 0..w {
                let (x, y) = (i as f32 + 0.5, j as f32 + 0.5);
                let e = |a: Vec3, b: Vec3| (b.x - a.x) * (y - a.y) - (x - a.x) * (b.y - a.y);
                let (w0, w1, w2) = (e(p[1], p[2]) / area, e(p[2], p[0]) / area, e(p[0], p[1]) / area);
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * p[0].z + w1 * p[1].z + w2 * p[2].z;
                let k = j * w + i;
                if !depth_test || z < depth[k] {
                    depth[k] = z;
                    ids[k] = *id;
                }
            }
        }
    }
    ids
}

/// Three sticks overlapping in a cycle (each above the next at one crossing) plus two
/// triangles piercing each other: no order of whole triangles is right.
fn cyclic_scene() -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    let r = 1.0f32;
    let len = 2.0 * r * 3f32.sqrt();
    for k in 0..3 {
        let th = std::f32::consts::TAU * k as f32 / 3.0;
        let d = Vec3::new(th.cos(), th.sin(), 0.0);
        let n = Vec3::new(-th.sin(), th.cos(), 0.0);
        let p = -n * r;
        let at = |s: f32| p + d * s + Vec3::Z * (0.25 * s);
        let wid = 1.0;
        tris.push([at(-len) - n * wid, at(-len) + n * wid, at(len)]);
    }
    // Two intersecting triangles to the side.
    let o = Vec3::new(3.5, 0.0, 0.0);
    tris.push([o + Vec3::new(-1.0, -1.0, 0.0), o + Vec3::new(1.0, -1.0, 0.0), o + Vec3::new(0.0, 1.2, 0.0)]);
    tris.push([o + Vec3::new(-1.0, 0.0, -1.0), o + Vec3::new(1.0, 0.2, 1.0), o + Vec3::new(0.0, 0.9, 1.0)]);
    tris
}

#[test]
fn bsp_painter_matches_z_buffer_and_centroid_sort_does_not() {
    let tris = cyclic_scene();
    let tree = BspTree::build(&tris, &BspParams::default());
    let s = tree.stats();
    assert!(s.splits >= 2, "{s:?}");
    assert_eq!(s.triangles_in, 5);
    assert!(s.triangles_out >= 5 + s.splits);
    let (w, h) = (128usize, 128usize);
    for eye in [Vec3::new(1.0, 0.3, 9.0), Vec3::new(0.5, -1.5, 7.0), Vec3::new(1.2, 0.0, -8.0)] {
        let cam = Camera::perspective(
            &LookAt {
                eye,
                target: Vec3::new(1.2, 0.0, 0.0),
                up: Vec3::Y,
                fovy: Angle::degrees(40.0),
                near: 0.5,
                far: 50.0,
            },
            1.0,
        )
        .unwrap();
        let m = cam.clip_from_world();
        let refs: Vec<([Vec3; 3], u32)> = tris.iter().enumerate().map(|(i, t)| (*t, i as u32 + 1)).collect();
        let zbuf = raster(&refs, &m, w, h, true);
        let covered = zbuf.iter().filter(|&&i| i != 0).count();
        assert!(covered > 2000, "{covered}");
        // BSP painter's: back to front, no depth test.
        let mut order = Vec::new();
        tree.back_to_front(eye, &mut order);
        assert_eq!(order.len(), s.triangles_out);
        let painted: Vec<([Vec3; 3], u32)> = order
            .iter()
            .map(|&i| {
                let t = tree.triangles()[i as usize];
                (t.v, t.source + 1)
            })
            .collect();
        let bsp = raster(&painted, &m, w, h, false);
        let diff = bsp.iter().zip(&zbuf).filter(|(a, b)| a != b).count();
        assert!(diff * 1000 <= w * h, "BSP painter differs on {diff} pixels");
        // Front-to-back is the exact reverse.
        let mut ftb = Vec::new();
        tree.front_to_back(eye, &mut ftb);
        ftb.reverse();
        assert_eq!(ftb, order);
        // Centroid-sort painter's: farthest centroid first.
        let mut by_centroid = refs.clone();
        by_centroid.sort_by(|a, b| {
            let da = ((a.0[0] + a.0[1] + a.0[2]) / 3.0).distance(eye);
            let db = ((b.0[0] + b.0[1] + b.0[2]) / 3.0).distance(eye);
            db.total_cmp(&da)
        });
        let centroid = raster(&by_centroid, &m, w, h, false);
        let bad = centroid.iter().zip(&zbuf).filter(|(a, b)| a != b).count();
        println!("eye {eye}: covered {covered}, BSP differs {diff}, centroid sort differs {bad}");
        assert!(bad >= 100 && bad * 100 >= covered, "centroid sort differs on only {bad} of {covered} pixels");
    }
}

fn area(t: &[Vec3; 3]) -> f32 {
    (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5
}

#[test]
fn split_pieces_keep_orientation_and_area() {
    let mut rng = Rng::new(11);
    let mut rv = || Vec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
    let mut spans = 0;
    for it in 0..2000 {
        let t = [rv(), rv(), rv()];
        let mut plane = Plane::from_point_normal(rv() * 0.3, rv());
        if it % 4 == 0 {
            // Through a vertex: two pieces.
            plane = Plane::from_point_normal(t[it % 3], (t[(it + 1) % 3] - t[(it + 2) % 3]).cross(rv()));
        }
        if classify_triangle(&plane, &t, 1e-6) != Side::Spanning {
            continue;
        }
        spans += 1;
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let (f, b) = split_triangle(&plane, &t, 1e-6);
        let pieces = f.as_slice().len() + b.as_slice().len();
        assert!(pieces == 2 || pieces == 3, "{pieces}");
        let mut sum = 0.0;
        for (side, list) in [(1.0f32, f.as_slice()), (-1.0, b.as_slice())] {
            for p in list {
                let pn = (p[1] - p[0]).cross(p[2] - p[0]);
                if pn.length() > 1e-5 * n.length() {
                    assert!(pn.dot(n) > 0.0, "piece flipped");
                }
                for v in p {
                    assert!(side * plane.distance(*v) >= -1e-4, "piece on the wrong side");
                }
                sum += area(p);
            }
        }
        assert!((sum - area(&t)).abs() <= 1e-4 * area(&t).max(1e-3), "{sum} vs {}", area(&t));
    }
    assert!(spans > 500, "{spans}");
}

#[test]
fn vertex_on_plane_gives_two_pieces() {
    let t = [Vec3::new(0.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    let plane = Plane::from_point_normal(Vec3::ZERO, Vec3::X);
    let (f, b) = split_triangle(&plane, &t, 1e-6);
    assert_eq!((f.as_slice().len(), b.as_slice().len()), (1, 1));
    let (f, b) = split_triangle(&Plane::from_point_normal(Vec3::ZERO, Vec3::Y), &t, 1e-6);
    assert_eq!(f.as_slice().len() + b.as_slice().len(), 3);
}

#[test]
fn every_input_area_survives_the_build() {
    let mut rng = Rng::new(5);
    let tris: Vec<[Vec3; 3]> = (0..400)
        .map(|_| {
            let c = Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
            [0, 1, 2].map(|_| c + Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)))
        })
        .collect();
    let tree = BspTree::build(&tris, &BspParams::default());
    let s = tree.stats();
    assert!(s.splits > 0 && s.nodes > 10 && s.depth > 3);
    let mut sums = vec![0.0f64; tris.len()];
    for t in tree.triangles() {
        sums[t.source as usize] += area(&t.v) as f64;
        let n = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
        let src = &tris[t.source as usize];
        let sn = (src[1] - src[0]).cross(src[2] - src[0]);
        if n.length() > 1e-4 * sn.length() {
            assert!(n.dot(sn) > 0.0);
        }
    }
    for (i, t) in tris.iter().enumerate() {
        assert!((sums[i] - area(t) as f64).abs() <= 1e-3 * area(t) as f64 + 1e-6, "triangle {i}");
    }
}

/// `n` copies of one triangle facing +z, stacked `dz` apart in order of increasing z.
fn stack(n: usize, dz: f32) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|i| {
            let z = i as f32 * dz;
            [Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(0.0, 1.0, z)]
        })
        .collect()
}

#[test]
fn deep_trees_and_bad_input_do_not_overflow_or_panic() {
    // One candidate, stacked parallel triangles in order: a chain 5000 nodes deep.
    let tris = stack(5000, 0.01);
    let params = BspParams { candidates: 1, ..Default::default() };
    let tree = BspTree::build(&tris, &params);
    assert!(tree.stats().depth >= 2500, "{:?}", tree.stats());
    let mut out = Vec::new();
    tree.back_to_front(Vec3::new(0.2, 0.2, 100.0), &mut out);
    assert_eq!(out.len(), 5000);
    // Far triangles (small z) come first when the eye is above.
    assert!(tree.triangles()[out[0] as usize].v[0].z < tree.triangles()[out[4999] as usize].v[0].z);
    // Zero-area, NaN and empty inputs.
    let bad = vec![
        [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        [Vec3::ONE; 3],
        [Vec3::NAN, Vec3::X, Vec3::Y],
        [Vec3::ZERO, Vec3::X, Vec3::Y],
    ];
    let tree = BspTree::build(&bad, &BspParams::default());
    out.clear();
    tree.back_to_front(Vec3::Z, &mut out);
    assert_eq!(out.len(), tree.stats().triangles_out);
    let only_degenerate = BspTree::build(&bad[..2], &BspParams::default());
    assert_eq!(only_degenerate.stats().triangles_out, 2);
    let empty = BspTree::build(&[], &BspParams::default());
    out.clear();
    empty.back_to_front(Vec3::ZERO, &mut out);
    assert!(out.is_empty());
    let _ = Vec4::ZERO;
}

#[test]
fn visits_from_a_direction_and_stop_early() {
    // Parallel triangles stacked along z: seen from +z far away, or from the direction +z
    // (a parallel projection), the back-to-front order is by increasing z either way.
    let tris = stack(50, 0.1);
    let tree = BspTree::build(&tris, &BspParams::default());
    let mut by_point = Vec::new();
    tree.back_to_front(Vec3::new(0.3, 0.3, 1e4), &mut by_point);
    let mut by_direction = Vec::new();
    let nodes = tree.visit(Vec4::new(0.0, 0.0, 1.0, 0.0), BspOrder::BackToFront, |r| {
        by_direction.extend(r);
        ControlFlow::Continue(())
    });
    assert_eq!(by_direction, by_point);
    assert_eq!(nodes, tree.stats().nodes);
    let z = |i: u32| tree.triangles()[i as usize].v[0].z;
    assert!(by_direction.windows(2).all(|w| z(w[0]) <= z(w[1])));
    // From −z the order flips.
    let mut from_below = Vec::new();
    tree.visit(Vec4::new(0.0, 0.0, -1.0, 0.0), BspOrder::BackToFront, |r| {
        from_below.extend(r);
        ControlFlow::Continue(())
    });
    assert!(from_below.windows(2).all(|w| z(w[0]) >= z(w[1])));
    // Front to back, stopping after three nodes' triangles.
    let mut seen = 0;
    let visited = tree.visit(Vec4::new(0.0, 0.0, 1.0, 0.0), BspOrder::FrontToBack, |r| {
        seen += r.len();
        if seen >= 3 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    assert_eq!(seen, 3);
    assert!(visited < tree.stats().nodes, "{visited}");
}

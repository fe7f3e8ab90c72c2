//! Occlusion queries against the z-pyramid of drawn occluders, and the pyramid's exactness.

use glam::Vec3;
use sightline::render::cull::Rect;
use sightline::render::{BoxVisibility, Culler, Framebuffer, RenderOptions};
use sightline::scene::rng::Rng;
use sightline::scene::shapes::MeshBuilder;
use sightline::scene::{Aabb, Camera, NodeDesc, Scene};

use crate::support::camera_key;

/// A 20 × 10 wall in the plane z = −10, facing +z, and a camera at the origin looking down −z.
fn wall() -> (Scene, Camera) {
    let mut s = Scene::new();
    let mut b = MeshBuilder::default();
    b.grid(Vec3::new(-10.0, -5.0, -10.0), Vec3::X * 20.0, Vec3::Y * 10.0, 4, 2);
    let m = s.add_mesh(b.build("wall").unwrap());
    s.add_node(None, NodeDesc::new("wall").mesh(m)).unwrap();
    s.update_transforms();
    (s, camera_key([0.0; 3], [0.0, 0.0, -1.0], 60.0, 0.1, 100.0).camera(16.0 / 9.0).unwrap())
}

fn cube_at(center: Vec3, half: f32) -> Aabb {
    Aabb::new(center - Vec3::splat(half), center + Vec3::splat(half))
}

#[test]
fn boxes_behind_beside_and_across_the_near_plane() {
    let (scene, cam) = wall();
    let mut culler = Culler::new(&scene);
    let mut fb = Framebuffer::new(320, 180).unwrap();
    let opts = RenderOptions::ids_only();
    {
        let (_, _, q) = culler.occluder_pass(&cam, &mut fb, &opts).unwrap();
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, -12.0), 0.5)), BoxVisibility::Occluded, "right behind the wall");
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, -30.0), 2.0)), BoxVisibility::Occluded, "far behind the wall");
        // Beside the wall: x beyond its edge at x = 10, still in view at z = −12.
        assert_eq!(q.test(&cube_at(Vec3::new(12.5, 0.0, -12.0), 0.5)), BoxVisibility::Visible, "beside the wall");
        // Straddling the wall's plane: partly in front of it.
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, -10.0), 0.5)), BoxVisibility::Visible, "through the wall");
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, -5.0), 0.5)), BoxVisibility::Visible, "in front of the wall");
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, 0.0), 0.5)), BoxVisibility::Visible, "crossing the near plane");
        assert_eq!(q.test(&cube_at(Vec3::new(0.0, 0.0, 5.0), 0.5)), BoxVisibility::OutsideView, "behind the eye");
        assert_eq!(q.test(&Aabb::new(Vec3::NAN, Vec3::NAN)), BoxVisibility::Visible, "NaN box");
        q.finish();
    }
    // The occluders were really drawn: the wall covers the middle of the image.
    assert_ne!(fb.ids[(90 * 320 + 160) as usize], 0);
}

#[test]
fn a_depth_cleared_buffer_occludes_nothing() {
    let (scene, cam) = wall();
    let mut culler = Culler::new(&scene);
    let mut fb = Framebuffer::new(160, 90).unwrap();
    // Looking away from the wall: nothing is drawn.
    let away = camera_key([0.0; 3], [0.0, 0.0, 1.0], 60.0, 0.1, 100.0).camera(16.0 / 9.0).unwrap();
    let (_, _, q) = culler.occluder_pass(&away, &mut fb, &RenderOptions::ids_only()).unwrap();
    let mut rng = Rng::new(4);
    let boxes: Vec<Aabb> = (0..2000)
        .map(|_| {
            cube_at(
                Vec3::new(rng.range(-30.0, 30.0), rng.range(-10.0, 10.0), rng.range(0.5, 90.0)),
                rng.range(0.01, 2.0),
            )
        })
        .collect();
    let mut out = Vec::new();
    q.test_batch(&boxes, &mut out);
    assert!(out.iter().all(|&v| v != BoxVisibility::Occluded));
    assert!(out.iter().filter(|&&v| v == BoxVisibility::Visible).count() > 500);
    let _ = cam;
}

/// The tiled pyramid never calls a rectangle occluded unless every pixel in it is nearer
/// than the query depth (checked against the depth buffer itself).
#[test]
fn session_pyramid_is_conservative_against_the_depth_buffer() {
    let c = sightline::scene::builders::city(&sightline::scene::builders::CityParams::for_triangles(100_000)).unwrap();
    let mut culler = Culler::new(&c.scene);
    let (w, h) = (300u32, 170u32); // not a multiple of the 64-pixel tile
    let mut fb = Framebuffer::new(w, h).unwrap();
    let mut rng = Rng::new(8);
    for key in c.layout.street_path(4, 2) {
        let cam = key.camera(w as f32 / h as f32).unwrap();
        // Draw once to get the finished depth buffer, then again to read its pyramid.
        let (_, _, pass) = culler.occluder_pass(&cam, &mut fb, &RenderOptions::ids_only()).unwrap();
        pass.finish();
        let depth = fb.depth.clone();
        let (_, _, pass) = culler.occluder_pass(&cam, &mut fb, &RenderOptions::ids_only()).unwrap();
        let pyramid = pass.pyramid();
        let mut occluded = 0;
        for _ in 0..3000 {
            let (xa, xb, ya, yb) = (rng.below(w), rng.below(w), rng.below(h), rng.below(h));
            let r = Rect { x0: xa.min(xb), x1: xa.max(xb), y0: ya.min(yb), y1: ya.max(yb) };
            let z = rng.range(0.9, 1.0);
            let truth_max = (r.y0..=r.y1)
                .flat_map(|y| (r.x0..=r.x1).map(move |x| (x, y)))
                .map(|(x, y)| depth[(y * w + x) as usize])
                .fold(0.0f32, f32::max);
            let occ = pyramid.is_occluded(r, z);
            if occ {
                occluded += 1;
                assert!(z > truth_max, "rect {r:?} at {z} called occluded but a pixel has depth {truth_max}");
            }
        }
        assert!(occluded > 0, "street views must occlude something");
        pass.finish();
    }
}

/// A small boxfield: no box reported occluded has a pixel that passes the depth test against
/// the occluders (checked by drawing all of them onto the occluder frame), and the queries
/// do occlude most boxes at eye height.
#[test]
fn boxfield_queries_are_exact() {
    use sightline::boxfield::{check_occluded, count, run_queries, Boxfield};
    use sightline::scene::builders::{boxfield, boxfield_queries, BoxfieldParams};
    let scene = boxfield(&BoxfieldParams { boxes: 8000, half_size: 40.0, seed: 3, ..Default::default() }).unwrap();
    let camera = sightline::boxfield::camera(16.0 / 9.0, 200.0);
    let queries = boxfield_queries(6000, 60f32.to_radians(), 16.0 / 9.0, 9);
    let bf = Boxfield { scene, camera, queries };
    let mut culler = Culler::new(&bf.scene);
    let mut fb = Framebuffer::new(320, 180).unwrap();
    let answers = run_queries(&mut culler, &bf, &mut fb);
    let c = count(&answers);
    assert!(c.occluded > 1000 && c.visible > 10, "{c:?}");
    assert_eq!(check_occluded(&bf, &answers, &fb), 0, "a box reported occluded has a visible pixel");
}

/// `test_many` (eight boxes per SIMD batch) and `test_batch` (parallel) answer every box
/// like `test`, in order, on ordinary boxes mixed with empty, NaN, infinite, flat, huge and
/// eye-crossing ones, for slices of every length modulo 8.
#[test]
fn many_and_batch_answer_like_test() {
    let (scene, cam) = wall();
    let mut culler = Culler::new(&scene);
    let mut fb = Framebuffer::new(320, 180).unwrap();
    let (_, _, q) = culler.occluder_pass(&cam, &mut fb, &RenderOptions::ids_only()).unwrap();
    let mut rng = Rng::new(21);
    let boxes: Vec<Aabb> = (0..5000)
        .map(|_| {
            let c = Vec3::new(rng.range(-20.0, 20.0), rng.range(-10.0, 10.0), rng.range(-40.0, 5.0));
            let half = Vec3::new(rng.range(0.0, 2.0), rng.range(0.0, 2.0), rng.range(0.0, 2.0));
            match rng.below(30) {
                0 => Aabb::EMPTY,
                1 => Aabb::new(Vec3::NAN, c),
                2 => Aabb::new(c, Vec3::new(c.x, f32::INFINITY, c.z)),
                3 => Aabb::new(c, c),
                4 => Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38)),
                5 => cube_at(Vec3::ZERO, rng.range(0.05, 1.0)),
                _ => Aabb::new(c - half, c + half),
            }
        })
        .collect();
    let (mut many, mut batch) = (Vec::new(), Vec::new());
    let mut counts = [0usize; 3];
    for len in [0, 1, 7, 8, 9, 4999, 5000] {
        let boxes = &boxes[..len];
        let one: Vec<BoxVisibility> = boxes.iter().map(|b| q.test(b)).collect();
        q.test_many(boxes, &mut many);
        q.test_batch(boxes, &mut batch);
        assert_eq!(many, one, "test_many, {len} boxes");
        assert_eq!(batch, one, "test_batch, {len} boxes");
        if len == 5000 {
            for v in one {
                counts[v as usize] += 1;
            }
        }
    }
    assert!(counts.iter().all(|&c| c > 300), "visible / occluded / outside: {counts:?}");
    q.finish();
}

/// Skipping occluders hidden by the pyramid as it fills leaves the z-buffer, the IDs and the
/// query answers exactly as drawing every occluder does, in both boxfield layouts.
#[test]
fn skipping_hidden_occluders_changes_nothing() {
    use sightline::scene::builders::{boxfield, boxfield_queries, BoxfieldLayout, BoxfieldParams};
    let camera = sightline::boxfield::camera(16.0 / 9.0, 200.0);
    let queries = boxfield_queries(3000, 60f32.to_radians(), 16.0 / 9.0, 5);
    for layout in [BoxfieldLayout::Instanced, BoxfieldLayout::OneMesh] {
        let scene = boxfield(&BoxfieldParams { boxes: 6000, half_size: 40.0, seed: 9, layout }).unwrap();
        let mut culler = Culler::new(&scene);
        let opts = RenderOptions::ids_only();
        let mut results = Vec::new();
        for skip_hidden in [false, true] {
            let mut fb = Framebuffer::new(320, 180).unwrap();
            let (cs, _, q) = culler.occluder_pass_with(&camera, &mut fb, &opts, skip_hidden).unwrap();
            let answers: Vec<_> = queries.iter().map(|b| q.test(b)).collect();
            q.finish();
            results.push((fb.depth, fb.ids, answers, cs.triangles_drawn, (cs.clusters_in_frustum, cs.clusters)));
        }
        let (all, skipped) = (&results[0], &results[1]);
        // The pass that draws every occluder counts the clusters in the frustum as its walk
        // lists them; the other counts them in a traversal of its own.
        assert!(all.4 .0 > 0 && all.4 .0 < all.4 .1, "{layout:?}: {:?} clusters in the frustum, of all", all.4);
        assert_eq!(all.4, skipped.4, "{layout:?}: clusters in the frustum");
        assert!(skipped.3 * 2 < all.3, "{layout:?}: {} of {} triangles drawn", skipped.3, all.3);
        assert!(all.1.iter().any(|&i| i != 0));
        assert_eq!(all.0, skipped.0, "{layout:?}: depth");
        assert_eq!(all.1, skipped.1, "{layout:?}: IDs");
        assert_eq!(all.2, skipped.2, "{layout:?}: query answers");
    }
}

/// The occluder pass that draws every occluder finds each batch while the last one is drawn,
/// and takes small subtrees inside the frustum whole: its depth and IDs are the same on one,
/// two and three threads, with no subtree, the default ones and the largest taken whole, and
/// its IDs are brute force's.
#[test]
fn the_pipelined_occluder_pass_is_the_same_on_any_thread_count() {
    use sightline::render::Method;
    use sightline::scene::builders::{boxfield, BoxfieldLayout, BoxfieldParams};
    let camera = sightline::boxfield::camera(16.0 / 9.0, 200.0);
    let scene =
        boxfield(&BoxfieldParams { boxes: 6000, half_size: 40.0, seed: 9, layout: BoxfieldLayout::Instanced }).unwrap();
    let opts = RenderOptions::ids_only();
    let (mut frames, mut counts) = (Vec::new(), Vec::new());
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        for whole in [0, Culler::DEFAULT_WHOLE_SUBTREE, 254] {
            let mut culler = Culler::new(&scene);
            culler.whole_subtree = whole;
            let mut fb = Framebuffer::new(320, 180).unwrap();
            pool.install(|| {
                let (cs, _, pass) = culler.occluder_pass(&camera, &mut fb, &opts).unwrap();
                assert!(cs.batches > 3, "{threads} threads, whole {whole}: {} batches", cs.batches);
                counts.push((cs.clusters_in_frustum, cs.clusters_drawn, cs.triangles_drawn));
                pass.finish();
            });
            frames.push((fb.depth, fb.ids));
        }
    }
    // Every occluder in the frustum is drawn, whatever the order.
    assert!(counts.iter().all(|c| *c == counts[0]), "{counts:?}");
    assert!(frames[0].1.iter().any(|&i| i != 0));
    assert!(frames.iter().all(|f| *f == frames[0]), "the frame depends on the thread count");
    let mut brute = Framebuffer::new(320, 180).unwrap();
    Culler::new(&scene).render(&scene, &camera, Method::Brute, &mut brute, &opts).unwrap();
    assert_eq!(frames[0].1, brute.ids, "the occluder pass's IDs are brute force's");
}

/// The occlusion walks find each batch on every worker: `hzb` (its walk and its first pass),
/// `hzb-one-pass` and the occluder pass that skips hidden occluders draw the same batches,
/// test as many boxes and give the same depth and IDs on one, two and three threads, frame
/// after frame as the camera turns (the two-pass form carrying its set from frame to
/// frame), and their IDs are brute force's.
#[test]
fn the_occlusion_walks_are_the_same_on_any_thread_count() {
    use sightline::render::Method;
    use sightline::scene::builders::{boxfield, BoxfieldLayout, BoxfieldParams};
    let scene =
        boxfield(&BoxfieldParams { boxes: 6000, half_size: 40.0, seed: 5, layout: BoxfieldLayout::Instanced }).unwrap();
    let cameras: Vec<Camera> = (0..4)
        .map(|k| {
            let a = k as f32 * 0.6;
            let key =
                camera_key([45.0 * a.sin(), 2.0 + 3.0 * k as f32, 45.0 * a.cos()], [0.0, 0.0, 0.0], 60.0, 0.1, 200.0);
            key.camera(16.0 / 9.0).unwrap()
        })
        .collect();
    let opts = RenderOptions::ids_only();
    let mut runs = Vec::new();
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut run = Vec::new();
        for method in [Method::Hzb, Method::HzbOnePass] {
            let mut culler = Culler::new(&scene);
            for camera in &cameras {
                let mut fb = Framebuffer::new(320, 180).unwrap();
                let (cs, _) = pool.install(|| culler.render(&scene, camera, method, &mut fb, &opts)).unwrap();
                let counts = (cs.batches, cs.clusters_drawn, cs.triangles_drawn, cs.occlusion_tests, cs.occluded_boxes);
                run.push((counts, fb.depth, fb.ids));
            }
        }
        let mut fb = Framebuffer::new(320, 180).unwrap();
        let mut culler = Culler::new(&scene);
        let pass = pool.install(|| {
            let (cs, _, pass) = culler.occluder_pass_with(&cameras[0], &mut fb, &opts, true).unwrap();
            pass.finish();
            cs
        });
        let counts =
            (pass.batches, pass.clusters_drawn, pass.triangles_drawn, pass.occlusion_tests, pass.occluded_boxes);
        run.push((counts, fb.depth, fb.ids));
        runs.push(run);
    }
    let tested: u64 = runs[0].iter().map(|r| r.0 .3).sum();
    let batches: u64 = runs[0].iter().map(|r| r.0 .0).sum();
    assert!(tested > 10_000 && batches > 20, "{tested} boxes tested in {batches} batches");
    for (t, run) in runs.iter().enumerate().skip(1) {
        for (k, (a, b)) in runs[0].iter().zip(run).enumerate() {
            assert_eq!(a.0, b.0, "frame {k}: counts on {} threads", t + 1);
            assert!(a.1 == b.1 && a.2 == b.2, "frame {k}: the frame depends on the thread count");
        }
    }
    let mut culler = Culler::new(&scene);
    for (k, camera) in cameras.iter().enumerate() {
        let mut brute = Framebuffer::new(320, 180).unwrap();
        culler.render(&scene, camera, Method::Brute, &mut brute, &opts).unwrap();
        assert_eq!(runs[0][k].2, brute.ids, "hzb frame {k}");
        assert_eq!(runs[0][cameras.len() + k].2, brute.ids, "hzb-one-pass frame {k}");
    }
}

/// The walks' counters of occlusion tests and occluded boxes: with nothing behind the wall no
/// box is found occluded, though boxes are tested (and `hzb`'s later frames re-test the
/// wall they drew first); with cubes behind it, boxes are found occluded, no more than were
/// tested, and once the wall alone is drawn first every cube is culled by occlusion.
#[test]
fn occluded_boxes_count_the_boxes_found_hidden() {
    use sightline::render::Method;
    for cubes in [0usize, 16] {
        let (mut scene, cam) = wall();
        let cube = scene.add_mesh(sightline::scene::shapes::cube("cube").unwrap());
        for k in 0..cubes {
            let at = Vec3::new(-6.0 + 4.0 * (k % 4) as f32, -3.0 + 2.0 * (k / 4) as f32, -30.0);
            scene
                .add_node(
                    None,
                    NodeDesc::new(format!("cube{k}")).mesh(cube).matrix(glam::Affine3A::from_translation(at)),
                )
                .unwrap();
        }
        scene.update_transforms();
        let mut culler = Culler::new(&scene);
        let mut fb = Framebuffer::new(320, 180).unwrap();
        let opts = RenderOptions::ids_only();
        for (method, frame) in [(Method::HzbOnePass, 1), (Method::Hzb, 1), (Method::Hzb, 2), (Method::Hzb, 3)] {
            let (cs, _) = culler.render(&scene, &cam, method, &mut fb, &opts).unwrap();
            let what = format!("{cubes} cubes, {} frame {frame}", method.name());
            assert!(cs.occlusion_tests > 0, "{what}: {cs:?}");
            if cubes == 0 {
                assert_eq!(cs.occluded_boxes, 0, "{what}: {cs:?}");
            } else {
                assert!(cs.occluded_boxes > 0 && cs.occluded_boxes <= cs.occlusion_tests, "{what}: {cs:?}");
                // The first batch of a walk from an empty pyramid draws some cubes, which
                // `hzb` draws first again in its second frame, re-tests and drops: its third
                // frame starts from the wall alone.
                let hidden = if frame == 3 { cubes as u64 } else { 1 };
                assert!(cs.culled_by_occlusion >= hidden, "{what}: {cs:?}");
            }
        }
    }
}

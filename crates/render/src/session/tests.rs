//! Frame sessions against plain draws, and the tile pyramid they keep.

use glam::Vec4;
use sightline_scene::rng::Rng;
use sightline_scene::{Camera, Scene};

use crate::options::{draw_all, DrawItem};
use crate::{DepthFormat, Error, Framebuffer, RenderOptions, Renderer};

/// Random clip-space triangles centered at NDC x in `[-1, x1]` on a 200 × 150 screen
/// (tiles cut by its edges; with `x1` well below 1, tiles no batch draws into).
fn batch_of_triangles(rng: &mut Rng, x1: f32) -> Vec<[Vec4; 3]> {
    (0..40)
        .map(|_| {
            let (cx, cy, s) = (rng.range(-1.0, x1), rng.range(-1.0, 1.0), rng.range(0.01, 0.4));
            let z = rng.range(-0.9, 0.9);
            let mut p = || Vec4::new(cx + rng.range(-s, s), cy + rng.range(-s, s), z + rng.range(-0.1, 0.1), 1.0);
            [p(), p(), p()]
        })
        .collect()
}

/// A session writes its tiles through as it draws and the untouched ones as cleared at
/// the end: over a framebuffer full of stale values, the frame equals plain draws of the
/// same batches into a cleared one, in every depth format.
#[test]
fn a_session_over_a_stale_framebuffer_equals_plain_draws() {
    for format in [DepthFormat::F32, DepthFormat::Unorm24, DepthFormat::Unorm16] {
        let opts = RenderOptions { backface_culling: false, depth_format: format, ..RenderOptions::ids_only() };
        let mut rng = Rng::new(11);
        let batches: Vec<_> = (0..5).map(|_| batch_of_triangles(&mut rng, 0.2)).collect();
        // Cleared as the renderer clears: the depth of the far plane's key.
        let mut plain = Framebuffer::new(200, 150).unwrap();
        plain.depth.fill(format.depth(format.key(1.0)));
        let mut r = Renderer::new();
        for (k, b) in batches.iter().enumerate() {
            r.draw_clip_triangles(b, 1 + 100 * k as u32, &mut plain, &opts);
        }
        let mut fb = Framebuffer::new(200, 150).unwrap();
        fb.depth.fill(0.25);
        fb.ids.fill(7);
        let mut session = r.begin(&mut fb, &opts);
        for (k, b) in batches.iter().enumerate() {
            session.draw_clip_triangles(b, 1 + 100 * k as u32);
        }
        let covered = session.finish();
        assert!(fb.ids == plain.ids, "{format:?}: IDs differ");
        assert!(fb.depth == plain.depth, "{format:?}: depths differ");
        assert_eq!(covered, fb.ids.iter().filter(|&&i| i != 0).count() as u64, "{format:?}");
        assert!(fb.ids.contains(&0) && covered > 0, "{format:?}: some tiles drawn, some not");
        // Counting depth tests over stale counts: the same frame, and the counts left in
        // the framebuffer are every test the batches made (a re-drawn tile loads and stores
        // its counts under its span), none on pixels no triangle reached.
        let mut counted = Framebuffer::new(200, 150).unwrap();
        counted.count_depth_tests(true);
        counted.depth.fill(0.25);
        if let Some(c) = &mut counted.depth_tests {
            c.fill(9);
        }
        let mut session = r.begin(&mut counted, &opts);
        let mut tests = 0;
        for (k, b) in batches.iter().enumerate() {
            tests += session.draw_clip_triangles(b, 1 + 100 * k as u32).fragments_tested;
        }
        session.finish();
        assert!(counted.ids == plain.ids && counted.depth == plain.depth, "{format:?}: counting changed the frame");
        let c = counted.depth_tests.as_ref().unwrap();
        assert_eq!(c.iter().map(|&n| n as u64).sum::<u64>(), tests, "{format:?}: depth tests lost or stale");
        assert!(c.iter().zip(&counted.ids).all(|(&n, &id)| id != 0 || n == 0), "{format:?}: stale counts");
    }
}

/// Items drawn in a session, batch after batch, give the frame one plain draw of them
/// all gives.
#[test]
fn session_draws_of_scene_items_equal_a_plain_frame() {
    use glam::Vec3;
    use sightline_scene::{shapes, Angle, LookAt, NodeDesc, Transform};
    let mut scene = Scene::new();
    let cube = scene.add_mesh(shapes::cube("cube").unwrap());
    for k in 0..12 {
        let at = Vec3::new((k % 4) as f32 * 1.5 - 2.0, (k / 4) as f32 * 1.2 - 1.0, -(k as f32) * 0.7);
        scene.add_node(None, NodeDesc::new("box").mesh(cube).transform(Transform::from_translation(at))).unwrap();
    }
    scene.update_transforms();
    let instances = scene.instances();
    let items = draw_all(&instances);
    let look = LookAt { eye: Vec3::new(0.5, 0.8, 6.0), fovy: Angle::degrees(60.0), far: 100.0, ..LookAt::default() };
    let camera = Camera::perspective(&look, 200.0 / 150.0).unwrap();
    let opts = RenderOptions::ids_only();
    let mut r = Renderer::new();
    let mut plain = Framebuffer::new(200, 150).unwrap();
    r.render(&scene, &instances, &items, &camera, &mut plain, &opts).unwrap();
    let mut fb = Framebuffer::new(200, 150).unwrap();
    fb.depth.fill(0.25);
    fb.ids.fill(7);
    let mut session = r.begin(&mut fb, &opts);
    for batch in items.chunks(5) {
        session.draw(&scene, &instances, batch, &camera).unwrap();
    }
    let covered = session.finish();
    assert!(fb.ids == plain.ids && fb.depth == plain.depth, "a session of batches differs from one draw");
    assert_eq!(covered, fb.ids.iter().filter(|&&i| i != 0).count() as u64);
    assert!(covered > 1000, "the boxes are in view");
    // Bad items and depth formats that cannot resolve the camera are refused, as by a
    // plain draw.
    let mut session = r.begin(&mut fb, &opts);
    let bad = [DrawItem { instance: 99, first: 0, count: 1 }];
    assert!(matches!(session.draw(&scene, &instances, &bad, &camera), Err(Error::InvalidDraw(_))));
    session.finish();
    let near = LookAt { near: 1e-6, far: 1e6, ..look };
    let close = Camera::perspective(&near, 200.0 / 150.0).unwrap();
    let coarse = RenderOptions { depth_format: DepthFormat::Unorm16, ..opts };
    let mut session = r.begin(&mut fb, &coarse);
    assert!(matches!(session.draw(&scene, &instances, &items, &close), Err(Error::DepthRange { .. })));
}

/// The pyramid levels kept up to date block by block during a session equal levels
/// computed from scratch, on tiles cut by the screen edge too, and in a second session over
/// the records the first one left (whose levels a new session starts from cleared).
#[test]
fn incremental_tile_pyramid_equals_a_full_rebuild() {
    let (w, h) = (200, 150);
    let mut fb = Framebuffer::new(w, h).unwrap();
    let opts = RenderOptions::ids_only();
    let mut r = Renderer::new();
    let mut rng = Rng::new(3);
    for (frame, batches) in [6u32, 2].into_iter().enumerate() {
        let mut session = r.begin(&mut fb, &opts);
        for batch in 0..batches {
            let tris = batch_of_triangles(&mut rng, 1.0);
            session.draw_clip_triangles(&tris, 1 + batch * 100);
            let (r, fb) = (session.renderer(), session.framebuffer());
            for lv in r.tile_levels().iter().filter(|lv| lv.touched) {
                let t = lv.rect;
                // The tile's keys from the framebuffer it wrote through to, 0 off the screen.
                let mut keys = vec![0; (crate::tiling::TILE * crate::tiling::TILE) as usize];
                for (y, x) in (0..t.h).flat_map(|y| (0..t.w).map(move |x| (y, x))) {
                    let d = fb.depth[fb.index(t.x0 + x, t.y0 + y)];
                    keys[(y * crate::tiling::TILE + x) as usize] = DepthFormat::F32.key(d);
                }
                let mut full = lv.clone();
                full.compute::<crate::depth::F32>(&keys);
                let at = format!("tile at {},{}, frame {frame}, batch {batch}", t.x0, t.y0);
                assert_eq!(lv.mips, full.mips, "{at}");
            }
        }
        session.finish();
    }
}

/// Binning leaves out a triangle wholly behind the depths drawn in its tile in earlier
/// batches (the tile's farthest depth, read from the compact per-tile array), and only
/// there: the same triangle in front of them, or in a tile no batch has drawn into, is
/// drawn, and the frame equals plain draws of the same batches.
#[test]
fn binning_skips_triangles_behind_drawn_tiles_only() {
    let opts = RenderOptions { backface_culling: false, ..RenderOptions::ids_only() };
    // A 128 × 64 screen: tile 0 on the left, tile 1 on the right.
    let quad = |x0: f32, x1: f32, z: f32| {
        let p = |x: f32, y: f32| Vec4::new(x, y, z, 1.0);
        [[p(x0, -1.0), p(x1, -1.0), p(x1, 1.0)], [p(x0, -1.0), p(x1, 1.0), p(x0, 1.0)]]
    };
    // A small triangle inside the tile whose NDC x range starts at `x0`, at depth `z`.
    let small = |x0: f32, z: f32| {
        let p = |x: f32, y: f32| Vec4::new(x0 + x, y, z, 1.0);
        [[p(0.2, -0.3), p(0.6, -0.3), p(0.4, 0.3)]]
    };
    let cover_left = quad(-1.0, 0.0, -0.5);
    let later: Vec<[[Vec4; 3]; 1]> = vec![small(-1.0, 0.5), small(-1.0, -0.9), small(0.0, 0.5)];
    let mut plain = Framebuffer::new(128, 64).unwrap();
    let mut r = Renderer::new();
    r.draw_clip_triangles(&cover_left, 1, &mut plain, &opts);
    for (k, t) in later.iter().enumerate() {
        r.draw_clip_triangles(t, 10 + k as u32, &mut plain, &opts);
    }
    let mut fb = Framebuffer::new(128, 64).unwrap();
    let mut session = r.begin(&mut fb, &opts);
    session.draw_clip_triangles(&cover_left, 1);
    let st: Vec<_> = later.iter().enumerate().map(|(k, t)| session.draw_clip_triangles(t, 10 + k as u32)).collect();
    session.finish();
    assert_eq!((st[0].coarse_rejected, st[0].rasterized), (1, 0), "behind the drawn tile: left out");
    assert_eq!((st[1].coarse_rejected, st[1].rasterized), (0, 1), "in front of it: drawn");
    assert_eq!((st[2].coarse_rejected, st[2].rasterized), (0, 1), "in a tile not drawn into: drawn");
    assert!(fb.ids == plain.ids && fb.depth == plain.depth, "the frame equals plain draws");
}

/// A triangle behind one drawn in an earlier batch by less than half a step of an integer
/// depth format gets the same depth key and so ties, and with the smaller ID wins: the
/// session's coarse tests (at binning, per triangle and per 8×8 block in the rasterizer)
/// leave that margin and give the frame plain draws give.
#[test]
fn coarse_tests_leave_integer_depth_ties_to_the_smaller_id() {
    let opts = RenderOptions { backface_culling: false, ..RenderOptions::ids_only() };
    // A quad over the whole 200 × 150 screen at window depth `d` (NDC z = 2d − 1).
    let quad = |d: f32| {
        let p = |x: f32, y: f32| Vec4::new(x, y, 2.0 * d - 1.0, 1.0);
        [[p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0)], [p(-1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)]]
    };
    for format in [DepthFormat::Unorm16, DepthFormat::Unorm24] {
        let opts = RenderOptions { depth_format: format, ..opts };
        // Depths near 0.015, tenths of a step apart for Unorm16; for Unorm24 the rounding of
        // NDC depth (about a step there) may put both quads at one depth, a tie all the same.
        let step = 1.0 / format.max_value().unwrap() as f32;
        let k = (0.015 / step).round();
        for frac in [0.1f32, 0.2, 0.3, 0.4] {
            let (near, far) = (quad(k * step), quad((k + frac) * step));
            let mut plain = Framebuffer::new(200, 150).unwrap();
            let mut r = Renderer::new();
            r.draw_clip_triangles(&near, 10, &mut plain, &opts);
            r.draw_clip_triangles(&far, 1, &mut plain, &opts);
            let at = format!("{format:?}, {frac} of a step behind");
            assert!(plain.ids.iter().all(|&id| id == 1 || id == 2), "{at}: the farther quad ties and wins");
            let mut fb = Framebuffer::new(200, 150).unwrap();
            let mut session = r.begin(&mut fb, &opts);
            session.draw_clip_triangles(&near, 10);
            session.draw_clip_triangles(&far, 1);
            session.finish();
            assert!(fb.ids == plain.ids && fb.depth == plain.depth, "{at}: the session differs");
        }
    }
}

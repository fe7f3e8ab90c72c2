//! Bad input never panics: NaN and infinite vertices, zero-area triangles, huge
//! coordinates, w = 0, a 1×1 framebuffer, invalid draw items.

use glam::{Affine3A, Vec3, Vec4};
use sightline_render::{render_scene, DrawItem, Framebuffer, RenderOptions, Renderer};
use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene};

use crate::support::one_node_scene;

fn v(x: f32, y: f32, z: f32, w: f32) -> Vec4 {
    Vec4::new(x, y, z, w)
}

fn ok() -> [Vec4; 3] {
    [v(-0.5, -0.5, 0.0, 1.0), v(0.5, -0.5, 0.0, 1.0), v(0.0, 0.5, 0.0, 1.0)]
}

fn nasty() -> Vec<[Vec4; 3]> {
    let ok = ok();
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    vec![
        [v(nan, 0.0, 0.0, 1.0), ok[1], ok[2]],
        [v(0.0, 0.0, 0.0, nan), ok[1], ok[2]],
        [v(inf, 0.0, 0.0, 1.0), ok[1], ok[2]],
        [v(0.0, 0.0, 0.0, -inf), ok[1], ok[2]],
        [v(-inf, -inf, -inf, inf), v(inf, inf, inf, inf), ok[2]],
        [ok[0], ok[0], ok[0]],                  // a point
        [ok[0], ok[1], v(1.5, -0.5, 0.0, 1.0)], // collinear
        [v(-1e30, -1e30, 0.0, 1.0), v(1e30, -1e30, 0.0, 1.0), v(0.0, 1e30, 0.0, 1.0)],
        [v(-1e30, -1e30, 0.5, 1e-30), v(1e30, -1e30, 0.5, 1.0), v(0.0, 1e30, -1e30, 1e30)],
        [v(0.0, 0.0, 0.0, 0.0), v(0.0, 0.0, 0.0, 0.0), v(0.0, 0.0, 0.0, 0.0)], // w = 0
        [v(0.0, 0.0, 0.0, 0.0), ok[1], ok[2]],
        [v(1e-38, 1e-38, 0.0, 1e-38), ok[1], v(0.0, 0.0, 0.0, -1e-38)],
        [v(-3.0, -3.0, 0.0, -1.0), v(3.0, -3.0, 0.0, -1.0), v(0.0, 3.0, 0.0, 1.0)],
        ok,
    ]
}

#[test]
fn raw_triangles_with_nan_inf_huge_and_degenerate_vertices() {
    for (w, h) in [(1, 1), (2, 3), (67, 45), (130, 70)] {
        for cull in [false, true] {
            let mut fb = Framebuffer::new(w, h).unwrap();
            fb.count_depth_tests(true);
            let opts = RenderOptions { backface_culling: cull, ..RenderOptions::default() };
            let tris = nasty();
            let st = Renderer::new().draw_clip_triangles(&tris, 1, &mut fb, &opts);
            assert_eq!(st.triangles_in, tris.len() as u64);
            assert!(st.trivially_rejected >= 5, "{st:?}");
            assert!(fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
            assert!(fb.ids.iter().all(|&i| (i as usize) <= tris.len()));
            // Each triangle alone, too; the ordinary one still draws after all that.
            for t in &tris {
                let mut fb = Framebuffer::new(w, h).unwrap();
                let st = Renderer::new().draw_clip_triangles(std::slice::from_ref(t), 1, &mut fb, &opts);
                if t == &ok() && w > 10 {
                    assert!(st.fragments_written > 0 && fb.ids.contains(&1));
                }
            }
        }
    }
}

#[test]
fn huge_transforms_and_tiny_framebuffers_through_the_scene() {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("c").unwrap());
    for (k, scale) in [1.0f32, 1e30, 1e-30, 1e15].into_iter().enumerate() {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(scale),
            glam::Quat::IDENTITY,
            Vec3::new(0.0, 0.0, -5.0 * k as f32),
        );
        s.add_node(None, NodeDesc::new(format!("n{k}")).matrix(m).mesh(cube)).unwrap();
    }
    s.update_transforms();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.3, 0.2, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.0,
    )
    .unwrap();
    for (w, h) in [(1, 1), (1, 7), (33, 1), (40, 30)] {
        let mut fb = Framebuffer::new(w, h).unwrap();
        fb.count_depth_tests(true);
        for aa in [sightline_render::Antialias::Off, sightline_render::Antialias::Ssaa4x4] {
            let opts = RenderOptions {
                antialias: aa,
                wireframe: sightline_render::Wireframe::Overlay,
                ..RenderOptions::default()
            };
            render_scene(&s, &cam, &mut fb, &opts).unwrap();
            assert!(fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
        }
    }
}

#[test]
fn invalid_draw_items_are_errors() {
    let s = one_node_scene("n", shapes::cube("c").unwrap());
    let inst = s.instances();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 0.0, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.0,
    )
    .unwrap();
    let mut fb = Framebuffer::new(8, 8).unwrap();
    let mut r = Renderer::new();
    let opts = RenderOptions::default();
    let bad = [
        DrawItem { instance: 1, first: 0, count: 1 },
        DrawItem { instance: 0, first: 10, count: 3 },
        DrawItem { instance: 0, first: u32::MAX, count: u32::MAX },
    ];
    for b in bad {
        let e = r.draw(&s, &inst, &[b], &cam, &mut fb, &opts).unwrap_err().to_string();
        assert!(e.contains("item 0"), "{e}");
    }
    assert!(r.render(&s, &inst, &[], &cam, &mut fb, &opts).is_ok());
}

/// A failed `render` must not leave the renderer believing the next target is freshly
/// cleared: a later `draw` batch keeps what the framebuffer already holds.
#[test]
fn a_failed_render_does_not_spoil_later_batches() {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("c").unwrap());
    s.add_node(None, NodeDesc::new("near").mesh(cube)).unwrap();
    let far = Affine3A::from_translation(Vec3::new(0.3, 0.0, -4.0)) * Affine3A::from_scale(Vec3::splat(3.0));
    s.add_node(None, NodeDesc::new("far").matrix(far).mesh(cube)).unwrap();
    s.update_transforms();
    let inst = s.instances();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.5, 0.7, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.0,
    )
    .unwrap();
    let opts = RenderOptions::ids_only();
    let mut r = Renderer::new();
    let near = [DrawItem::whole(0, &inst[0])];
    let far = [DrawItem::whole(1, &inst[1])];
    // Reference: both batches through one renderer, no failure in between.
    let mut want = Framebuffer::new(32, 32).unwrap();
    r.render(&s, &inst, &near, &cam, &mut want, &opts).unwrap();
    r.draw(&s, &inst, &far, &cam, &mut want, &opts).unwrap();
    // The same with a failed render in between.
    let mut fb = Framebuffer::new(32, 32).unwrap();
    r.render(&s, &inst, &near, &cam, &mut fb, &opts).unwrap();
    let mut scratch = Framebuffer::new(32, 32).unwrap();
    let bad = [DrawItem { instance: 9, first: 0, count: 1 }];
    assert!(r.render(&s, &inst, &bad, &cam, &mut scratch, &opts).is_err());
    r.draw(&s, &inst, &far, &cam, &mut fb, &opts).unwrap();
    assert!(fb.ids.iter().any(|&i| (1..=12).contains(&i)), "the near cube is still there");
    assert_eq!(fb.ids, want.ids);
}

/// A camera made by hand (its fields are public) with near = 0, an empty window or NaN
/// planes is refused by every way of drawing a frame, naming what is wrong, instead of a
/// blank frame and `Ok`.
#[test]
fn a_hand_made_invalid_camera_is_an_error_not_a_blank_frame() {
    use sightline_render::{Culler, Method, RayCaster, RaycastOptions};
    use sightline_scene::Projection;
    let scene = one_node_scene("cube", shapes::cube("cube").unwrap());
    let look = LookAt { eye: Vec3::new(2.0, 1.5, 3.0), fovy: Angle::degrees(50.0), far: 100.0, ..LookAt::default() };
    let good = Camera::perspective(&look, 1.0).unwrap();
    let window = |near: f32, far: f32, right: f32| Projection::Perspective {
        left: -0.05,
        right,
        bottom: -0.05,
        top: 0.05,
        near,
        far,
    };
    let cases = [
        (window(0.0, 100.0, 0.05), "near = 0"),
        (window(0.1, 100.0, -0.05), "empty window"),
        (window(0.1, f32::NAN, 0.05), "finite"),
        (window(10.0, 1.0, 0.05), "smaller than far"),
    ];
    let opts = RenderOptions::default();
    for (projection, says) in cases {
        let camera = Camera { projection, ..good };
        let mut fb = Framebuffer::new(32, 32).unwrap();
        let e = render_scene(&scene, &camera, &mut fb, &opts).unwrap_err().to_string();
        assert!(e.contains(says), "render_scene: {e}");
        for method in [Method::Frustum, Method::Hzb] {
            let e = Culler::new(&scene).render(&scene, &camera, method, &mut fb, &opts).unwrap_err().to_string();
            assert!(e.contains(says), "{method:?}: {e}");
        }
        let caster = RayCaster::build(&scene).unwrap();
        let e = caster.render(&scene, &camera, &mut fb, &RaycastOptions::default()).unwrap_err().to_string();
        assert!(e.contains(says), "ray casting: {e}");
    }
}

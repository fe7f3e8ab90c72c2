//! Bad input never panics the ray caster: degenerate rays miss, degenerate triangles are
//! never hit, singular transforms, empty scenes and tiny framebuffers work.

use glam::{Affine3A, Vec3};
use sightline_render::csg::{Csg, CsgObject};
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::{shapes, Angle, Camera, LookAt, Mesh, NodeDesc, Projection, Scene, Transform, View};

use crate::support::one_node_scene;

fn degenerate_scene() -> Scene {
    let mut scene = Scene::new();
    let p = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::X * 2.0, // collinear with the first two
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(1e30, -1e30, 1e30), // huge
        Vec3::new(-1e30, 1e30, 1e-30),
    ];
    let idx = vec![0, 1, 2, 3, 3, 3, 0, 0, 0, 0, 1, 3, 4, 5, 0, 1, 1, 2];
    let m = scene.add_mesh(Mesh::new("degenerate", p, None, None, idx).unwrap());
    scene.add_node(None, NodeDesc::new("d").mesh(m)).unwrap();
    // A flattened instance (zero scale): its transform cannot be inverted.
    let cube = scene.add_mesh(shapes::cube("c").unwrap());
    scene
        .add_node(None, NodeDesc::new("flat").transform(Transform::from_scale(Vec3::new(1.0, 0.0, 1.0))).mesh(cube))
        .unwrap();
    // An empty mesh.
    let e = scene.add_mesh(Mesh::new("empty", vec![], None, None, vec![]).unwrap());
    scene.add_node(None, NodeDesc::new("e").mesh(e)).unwrap();
    scene.update_transforms();
    scene
}

#[test]
fn raycast_degenerate_rays_miss() {
    let scene = degenerate_scene();
    let solid = CsgObject::new("s", &Csg::sphere(Vec3::ZERO, 1.0), Affine3A::IDENTITY, [1.0; 4]).unwrap();
    let caster = RayCaster::build(&scene).unwrap().with_csg(vec![solid]);
    let o = Vec3::new(0.2, 0.3, 5.0);
    for (origin, dir) in [
        (o, Vec3::ZERO),
        (o, Vec3::NAN),
        (o, Vec3::new(0.0, f32::NAN, -1.0)),
        (o, Vec3::new(f32::INFINITY, 0.0, -1.0)),
        (Vec3::NAN, Vec3::NEG_Z),
        (Vec3::INFINITY, Vec3::NEG_Z),
    ] {
        assert!(caster.intersect(origin, dir, 0.0, f32::INFINITY).is_none(), "{origin} {dir}");
        assert!(!caster.occluded(origin, dir, 0.0, f32::INFINITY));
    }
    // NaN or reversed intervals.
    assert!(caster.intersect(o, Vec3::NEG_Z, f32::NAN, 10.0).is_none());
    assert!(caster.intersect(o, Vec3::NEG_Z, 10.0, 1.0).is_none());
    // A good ray still hits (the triangle 0, 1, 3 or the sphere).
    assert!(caster.intersect(o, Vec3::NEG_Z, 0.0, f32::INFINITY).is_some());
}

#[test]
fn raycast_degenerate_triangles_are_never_hit() {
    // Only zero-area triangles.
    let p = vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::Y];
    let scene = one_node_scene("z", Mesh::new("zero", p, None, None, vec![0, 1, 2, 3, 3, 3, 0, 3, 0]).unwrap());
    let caster = RayCaster::build(&scene).unwrap();
    for x in [-0.5f32, 0.0, 0.5, 1.0, 1.5, 2.0] {
        for y in [-0.5f32, 0.0, 0.5, 1.0] {
            assert!(caster.intersect(Vec3::new(x, y, 3.0), Vec3::NEG_Z, 0.0, f32::INFINITY).is_none());
        }
    }
    // And the renderer draws nothing.
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.5, 0.5, 4.0),
            target: Vec3::new(0.5, 0.5, 0.0),
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 10.0,
        },
        1.0,
    )
    .unwrap();
    let mut fb = Framebuffer::new(32, 32).unwrap();
    caster
        .render(&scene, &cam, &mut fb, &RaycastOptions { backface_culling: false, ..RaycastOptions::default() })
        .unwrap();
    assert!(fb.ids.iter().all(|&i| i == 0));
}

#[test]
fn raycast_odd_scenes_and_frames_do_not_panic() {
    let scene = degenerate_scene();
    let caster = RayCaster::build(&scene).unwrap();
    let empty = Scene::new();
    let nothing = RayCaster::build(&empty).unwrap();
    assert_eq!(nothing.instance_count(), 0);
    let view = View::look_at(Vec3::new(0.3, 2.0, 3.0), Vec3::ZERO, Vec3::Y).unwrap();
    let cams = [
        Camera::new(view, Projection::perspective(Angle::radians(1.2), 1.0, 1e-4, 1e7).unwrap()).unwrap(),
        Camera::new(view, Projection::orthographic(-2.0, 2.0, -2.0, 2.0, 0.0, 10.0).unwrap()).unwrap(),
        Camera::new(view, Projection::cavalier(-2.0, 2.0, -2.0, 2.0, 0.0, 10.0, 0.4).unwrap()).unwrap(),
        // Inside the flattened cube's plane, looking along it.
        Camera::perspective(
            &LookAt { eye: Vec3::ZERO, target: Vec3::X, up: Vec3::Y, fovy: Angle::degrees(90.0), near: 0.1, far: 10.0 },
            1.0,
        )
        .unwrap(),
    ];
    for (w, h) in [(1, 1), (1, 17), (9, 1), (13, 11)] {
        for cam in &cams {
            for (c, scene) in [(&caster, &scene), (&nothing, &empty)] {
                // Shaded hit by hit (shadows), and from the ID buffer.
                for shadows in [true, false] {
                    let mut fb = Framebuffer::new(w, h).unwrap();
                    let opts = RaycastOptions { shadows, ..RaycastOptions::default() };
                    let s = c.render(scene, cam, &mut fb, &opts).unwrap();
                    assert_eq!(s.primary_rays, (w * h) as u64);
                    assert!(fb.depth.iter().all(|d| (0.0..=1.0).contains(d)));
                }
            }
        }
    }
    // The flattened cube is drawn from above (a square at y = 0).
    let top = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 3.0, 0.01),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(40.0),
            near: 0.1,
            far: 10.0,
        },
        1.0,
    )
    .unwrap();
    let mut fb = Framebuffer::new(16, 16).unwrap();
    caster.render(&scene, &top, &mut fb, &RaycastOptions::default()).unwrap();
    assert!(fb.ids.iter().any(|&i| i != 0));
}

#[test]
fn raycast_bad_csg_transforms_are_errors() {
    let sphere = Csg::sphere(Vec3::ZERO, 1.0);
    assert!(CsgObject::new("flat", &sphere, Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)), [1.0; 4]).is_err());
    assert!(CsgObject::new("nan", &sphere, Affine3A::from_translation(Vec3::NAN), [1.0; 4]).is_err());
    let bad = sphere.clone().scaled(Vec3::ZERO);
    let e = CsgObject::new("zero scale", &bad, Affine3A::IDENTITY, [1.0; 4]).unwrap_err().to_string();
    assert!(e.contains("zero scale"), "{e}");
}

/// The planes are public: one replaced by a plane of another length is caught before the
/// cast, which would otherwise stop its bands where the plane ends and leave stale pixels.
#[test]
#[should_panic(expected = "does not hold")]
fn a_replaced_depth_plane_of_the_wrong_length_is_caught_before_casting() {
    let scene = Scene::new();
    let caster = RayCaster::build(&scene).unwrap();
    let look = LookAt { target: Vec3::NEG_Z, ..LookAt::default() };
    let camera = Camera::perspective(&look, 1.0).unwrap();
    let mut fb = Framebuffer::new(64, 64).unwrap();
    fb.depth = sightline_render::Plane::filled(64, 1.0);
    let _ = caster.render(&scene, &camera, &mut fb, &RaycastOptions::default());
}

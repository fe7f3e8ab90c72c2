//! CSG by ray casting: visible surfaces and normals of differences, intersections and
//! unions of transformed primitives, and CSG solids drawn with meshes in one image.

use glam::{Affine3A, Quat, Vec3};
use sightline_render::csg::{classic_demo, Csg, CsgObject, CsgScratch, Shape};
use sightline_render::raycast::HitTarget;
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene, Transform};

use crate::support::pixel_ndc;

fn object(csg: &Csg) -> CsgObject {
    CsgObject::new("test", csg, Affine3A::IDENTITY, [1.0; 4]).unwrap()
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-5
}

#[test]
fn csg_hollow_sphere_outer_shell_and_far_inner_wall() {
    let hollow = object(&Csg::sphere(Vec3::ZERO, 2.0).subtract(Csg::sphere(Vec3::ZERO, 1.0)));
    // Through the middle from outside: the outer shell at distance 5 − 2.
    let h = hollow.intersect(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 3.0), "{h:?}");
    assert!((h.normal - Vec3::Z).length() < 1e-5);
    // Unnormalized direction: t scales.
    let h = hollow.intersect(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z * 2.0, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 1.5));
    // From inside the hole: the inner wall on the far side, its normal facing the center
    // (the subtracted sphere's normal, flipped).
    let h = hollow.intersect(Vec3::new(0.0, 0.5, 0.0), Vec3::X, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 0.75f32.sqrt()), "{h:?}");
    assert!(h.normal.x < -0.8 && h.normal.y < 0.0, "{:?}", h.normal);
    // Starting inside the shell material: the first entry after t_min is the far shell's
    // inner wall... entered from the hole at t = 1 + 1.5.
    let h = hollow.intersect(Vec3::new(-1.5, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 2.5), "{h:?}");
    assert!((h.normal - Vec3::NEG_X).length() < 1e-5);
    // Beside everything: a miss.
    assert!(hollow.intersect(Vec3::new(3.0, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).is_none());
}

#[test]
fn csg_hole_through_a_box_hits_the_far_wall() {
    // A cube with a cylindrical hole along z, radius 0.5.
    let holed = object(&Csg::cuboid(Vec3::splat(-1.0), Vec3::ONE).subtract(Csg::cylinder(
        Vec3::new(0.0, 0.0, -2.0),
        Vec3::new(0.0, 0.0, 2.0),
        0.5,
    )));
    // Down the hole: nothing.
    assert!(holed.intersect(Vec3::new(0.1, 0.1, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).is_none());
    // Across the hole from inside it: the far wall at x = 0.5, normal pointing back into the hole.
    let h = holed.intersect(Vec3::new(0.0, 0.0, 0.3), Vec3::X, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 0.5), "{h:?}");
    assert!((h.normal - Vec3::NEG_X).length() < 1e-5, "{:?}", h.normal);
    // From outside, through the box and across the hole: the box face first.
    let h = holed.intersect(Vec3::new(-3.0, 0.0, 0.3), Vec3::X, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 2.0) && (h.normal - Vec3::NEG_X).length() < 1e-5);
    // Beyond the near material (t_min past it): the hole's far wall.
    let h = holed.intersect(Vec3::new(-3.0, 0.0, 0.3), Vec3::X, 2.7, f32::INFINITY).unwrap();
    assert!(close(h.t, 3.5), "{h:?}");
}

#[test]
fn csg_empty_intersections_miss() {
    let apart =
        object(&Csg::sphere(Vec3::new(-2.0, 0.0, 0.0), 1.0).intersect(Csg::sphere(Vec3::new(2.0, 0.0, 0.0), 1.0)));
    for x in [-2.0f32, -1.0, 0.0, 1.0, 2.0] {
        assert!(apart.intersect(Vec3::new(x, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).is_none());
    }
    // Touching spheres intersect in a point: still nothing to see.
    let touching =
        object(&Csg::sphere(Vec3::new(-1.0, 0.0, 0.0), 1.0).intersect(Csg::sphere(Vec3::new(1.0, 0.0, 0.0), 1.0)));
    assert!(touching.intersect(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY).is_none());
    // A solid minus a bigger one is empty.
    let gone = object(&Csg::sphere(Vec3::ZERO, 1.0).subtract(Csg::cuboid(Vec3::splat(-2.0), Vec3::splat(2.0))));
    assert!(gone.intersect(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).is_none());
}

#[test]
fn csg_lens_and_union_with_transformed_inner_nodes() {
    // Intersection of two unit spheres 1 apart: the lens between x = 0 and 0... seen along x.
    let lens =
        object(&Csg::sphere(Vec3::new(-0.5, 0.0, 0.0), 1.0).intersect(Csg::sphere(Vec3::new(0.5, 0.0, 0.0), 1.0)));
    let h = lens.intersect(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 4.5) && (h.normal - Vec3::NEG_X).length() < 1e-5, "{h:?}");
    // A union placed by a transform on the inner node: rotated 90° about z and moved up 3.
    let pair = Csg::cuboid(Vec3::new(0.0, -0.5, -0.5), Vec3::new(2.0, 0.5, 0.5))
        .union(Csg::sphere(Vec3::ZERO, 0.75))
        .rotated(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2))
        .translated(Vec3::new(0.0, 3.0, 0.0));
    let o = object(&pair);
    // The box now points up from (0, 3, 0) to (0, 5, 0): a ray down the y axis meets its top.
    let h = o.intersect(Vec3::new(0.0, 10.0, 0.0), Vec3::NEG_Y, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 5.0) && (h.normal - Vec3::Y).length() < 1e-4, "{h:?}");
    // From below: the sphere's bottom at y = 2.25.
    let h = o.intersect(Vec3::new(0.0, -10.0, 0.0), Vec3::Y, 0.0, f32::INFINITY).unwrap();
    assert!(close(h.t, 12.25) && (h.normal - Vec3::NEG_Y).length() < 1e-4, "{h:?}");
    // Non-uniform scale: normals stay perpendicular to the surface (an ellipsoid 2 × 1 × 1).
    let e = object(&Csg::primitive(Shape::Sphere).scaled(Vec3::new(2.0, 1.0, 1.0)));
    let p = Vec3::new(2.0f32.sqrt(), 0.5f32.sqrt(), 0.0);
    let h = e.intersect(p + Vec3::Z * 3.0, Vec3::NEG_Z, 0.0, f32::INFINITY);
    assert!(h.is_some());
    let hp = Vec3::new(1.0, 0.6, 0.0);
    let h = e.intersect(hp * 3.0, -hp, 0.0, f32::INFINITY).unwrap();
    let q = hp * 3.0 - hp * h.t;
    let want = Vec3::new(q.x / 4.0, q.y, q.z).normalize();
    assert!((h.normal - want).length() < 1e-4, "{:?} vs {want:?}", h.normal);
}

#[test]
fn csg_spans_are_sorted_disjoint_and_reused() {
    let t = classic_demo().compile().unwrap();
    assert_eq!(t.primitive_count(), 5);
    let mut scratch = CsgScratch::default();
    let (mut total, mut several) = (0, 0);
    for k in 0..200 {
        let a = k as f64 * 0.031;
        let o = glam::DVec3::new(3.0 * a.cos(), 0.7 * (a * 1.7).sin(), 3.0 * a.sin());
        let d = -o + glam::DVec3::new(0.1, 0.2, -0.05);
        // Reused scratch answers as a fresh one does.
        let fresh: Vec<_> = t.spans(o, d, &mut CsgScratch::default()).iter().map(|s| (s.enter.t, s.exit.t)).collect();
        let spans = t.spans(o, d, &mut scratch);
        assert_eq!(spans.iter().map(|s| (s.enter.t, s.exit.t)).collect::<Vec<_>>(), fresh, "ray {k}");
        total += spans.len();
        several += (spans.len() > 1) as usize;
        for s in spans {
            assert!(s.enter.t <= s.exit.t);
            assert!((s.enter.normal.length() - 1.0).abs() < 1e-9 && (s.exit.normal.length() - 1.0).abs() < 1e-9);
        }
        for w in spans.windows(2) {
            assert!(w[0].exit.t < w[1].enter.t);
        }
    }
    // Most rays pass through the solid (178 spans), some of them through its holes (66 with
    // several spans).
    assert!(total > 100 && several > 10, "{total} spans, {several} rays with more than one");
}

#[test]
fn csg_solids_render_with_meshes_with_ids_above_the_triangles() {
    let mut scene = Scene::new();
    let cube = scene.add_mesh(shapes::cube("cube").unwrap());
    // A unit cube at x = −1.5 and a CSG solid at x = +1.5, a cube half inside the solid.
    scene
        .add_node(
            None,
            NodeDesc::new("left").transform(Transform::from_translation(Vec3::new(-1.5, 0.0, 0.0))).mesh(cube),
        )
        .unwrap();
    scene
        .add_node(
            None,
            NodeDesc::new("mid").transform(Transform::from_translation(Vec3::new(1.0, 0.0, 0.0))).mesh(cube),
        )
        .unwrap();
    scene.update_transforms();
    let solid = CsgObject::new(
        "demo",
        &classic_demo(),
        Affine3A::from_translation(Vec3::new(1.5, 0.0, 0.0)),
        [0.9, 0.4, 0.1, 1.0],
    )
    .unwrap();
    let caster = RayCaster::build(&scene).unwrap().with_csg(vec![solid]);
    assert_eq!(caster.csg_id(0), 25);
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 1.5, 6.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(50.0),
            near: 0.1,
            far: 50.0,
        },
        1.5,
    )
    .unwrap();
    let mut fb = Framebuffer::new(96, 64).unwrap();
    caster.render(&scene, &cam, &mut fb, &RaycastOptions { shadows: true, ..RaycastOptions::default() }).unwrap();
    let csg_px = fb.ids.iter().filter(|&&i| i == 25).count();
    let tri_px = fb.ids.iter().filter(|&&i| (1..=24).contains(&i)).count();
    assert!(csg_px > 200 && tri_px > 200, "{csg_px} CSG and {tri_px} triangle pixels");
    assert!(fb.ids.iter().all(|&i| i <= 25));
    // Depth of CSG pixels is consistent with the single-ray query.
    let (w, h) = (96usize, 64usize);
    let i = (0..w * h).find(|&i| fb.ids[i] == 25).unwrap();
    let ndc = pixel_ndc((i % w) as u32, (i / w) as u32, w as u32, h as u32);
    let (o, d) = cam.ray_through_ndc(ndc);
    let hit = caster.intersect(o, d, 0.0, f32::INFINITY).unwrap();
    assert_eq!(hit.id, 25);
    assert!(matches!(hit.target, HitTarget::Csg { object: 0, .. }));
}

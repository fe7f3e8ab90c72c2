//! Bad input never panics: NaN boxes (the rule: unbounded items are always visible), empty
//! scenes, zero-area triangles, stale meshes.

use glam::{Affine3A, Vec3};
use sightline_scene::{shapes, Aabb, Angle, Camera, LookAt, Mesh, NodeDesc, Scene, Transform};
use sightline_spatial::*;

fn cam() -> Camera {
    Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 2.0, 10.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.5,
    )
    .unwrap()
}

#[test]
fn empty_scene_everywhere() {
    let scene = Scene::new();
    let inst = scene.instances();
    let f = Frustum::from_camera(&cam());
    let mut out = Vec::new();
    let tlas = InstanceBvh::from_instances(&inst);
    tlas.cull(&f, &mut out);
    LooseOctree::from_instances(&inst, 5).cull(&f, &mut out);
    let cs = ClusteredScene::build(&scene);
    cs.cull(&f, &mut out);
    assert!(out.is_empty());
    let mut order = Vec::new();
    tlas.order(Vec3::ZERO, &mut order);
    cs.order(Vec3::ZERO, &mut order);
    assert!(order.is_empty());
    let mut cursor = cs.cursor(Some(&f), Vec3::ZERO);
    assert!(!cursor.next_batch(cs.bvh(), |_| true, 10, &mut out));
    assert!(cursor.is_done());
    let mut tlas = tlas;
    assert!(matches!(tlas.update(&[]), RefitOutcome::Refitted { .. }));
    assert_eq!(tlas.memory_bytes(), 0);
}

#[test]
fn nan_boxes_are_always_visible_and_empty_boxes_never() {
    let mut scene = Scene::new();
    let cube = scene.add_mesh(shapes::cube("c").unwrap());
    let big = scene.add_mesh(shapes::subdivided_box("b", Vec3::ZERO, Vec3::ONE, [12, 12, 12], true).unwrap());
    let empty = scene.add_mesh(Mesh::new("e", vec![], None, None, vec![]).unwrap());
    for (i, m) in [cube, big, empty, cube].into_iter().enumerate() {
        let t = Transform::from_translation(Vec3::new(i as f32 * 2.0, 0.0, 0.0));
        scene.add_node(None, NodeDesc::new("n").transform(t).mesh(m)).unwrap();
    }
    scene.update_transforms();
    let mut inst = scene.instances();
    assert_eq!(inst.len(), 4);
    // Instance 0 gets a NaN box and a NaN transform (the scene refuses those, other code may not).
    inst[0].world_aabb = Aabb::new(Vec3::NAN, Vec3::NAN);
    inst[1].world_from_local = Affine3A::from_translation(Vec3::NAN);
    inst[1].world_aabb = Aabb::new(Vec3::new(f32::NEG_INFINITY, 0.0, 0.0), Vec3::INFINITY);
    let away = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 2.0, 10.0),
            target: Vec3::new(0.0, 2.0, 20.0),
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.5,
    )
    .unwrap();
    for c in [cam(), away] {
        let f = Frustum::from_camera(&c);
        let mut a = Vec::new();
        InstanceBvh::from_instances(&inst).cull(&f, &mut a);
        let mut b = Vec::new();
        LooseOctree::from_instances(&inst, 5).cull(&f, &mut b);
        for v in [&a, &b] {
            let ids: Vec<u32> = v.iter().map(|x| x.index).collect();
            assert!(ids.contains(&0) && ids.contains(&1), "{ids:?}");
            assert!(!ids.contains(&2), "the empty mesh is never visible");
            assert!(v.iter().filter(|x| x.index < 2).all(|x| !x.inside));
        }
        let cs = ClusteredScene::from_instances(&scene, &inst);
        let mut items = Vec::new();
        cs.cull(&f, &mut items);
        let insts: std::collections::HashSet<u32> = items.iter().map(|v| cs.item(v.index).instance).collect();
        assert!(insts.contains(&0) && insts.contains(&1) && !insts.contains(&2));
        // Every cluster of the NaN-transformed instance is reported.
        let n1 = cs.instance_items(1).len();
        assert_eq!(items.iter().filter(|v| cs.item(v.index).instance == 1).count(), n1);
        // The box projection of an unbounded box covers the screen.
        assert!(project_box(&inst[0].world_aabb, &c.clip_from_world(), 64, 48).crosses_near);
    }
}

#[test]
fn degenerate_triangles_and_bad_matrices() {
    let m = Mesh::new(
        "flat",
        vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::ONE],
        None,
        None,
        (0..300).flat_map(|i| [0, 1 + (i % 2), 3 * (i % 2)]).collect(),
    )
    .unwrap();
    assert!(m.degenerate_triangles() > 0);
    let mc = MeshClusters::build(&m);
    assert_eq!(mc.permutation().len(), 300);
    let blas = TriangleBvh::build(&m, BvhPreset::Fast);
    let _ = blas.intersect(&m, &Ray::new(Vec3::new(0.5, 1.0, 0.0), Vec3::NEG_Y));
    let tris: Vec<[Vec3; 3]> = (0..m.triangle_count()).map(|t| m.triangle_positions(t)).collect();
    let bsp = BspTree::build(&tris, &BspParams::default());
    let mut out = Vec::new();
    bsp.back_to_front(Vec3::new(f32::NAN, 0.0, 0.0), &mut out);
    assert_eq!(out.len(), bsp.stats().triangles_out);
    // A NaN matrix culls nothing away.
    let f = Frustum::from_clip_from_world(&glam::Mat4::NAN);
    let boxes = [Aabb::new(Vec3::ZERO, Vec3::ONE)];
    let mut v = Vec::new();
    InstanceBvh::build(&boxes, BvhPreset::Fast).cull(&f, &mut v);
    assert_eq!(v.len(), 1);
    // Zero-size viewport in box projection.
    assert!(project_box(&boxes[0], &cam().clip_from_world(), 0, 0).is_empty());
}

//! Conservative frustum culling, property-tested: for random scenes and cameras, every
//! instance (and every cluster) that owns a pixel of a brute-force triangle-ID buffer is in the
//! culled set, for the TLAS, the loose octree and the clustered scene, with and without plane
//! masking. The reference casts one ray per pixel center (`Camera::ray_through_ndc`) against
//! every triangle (Möller–Trumbore) and keeps the nearest hit between the near and far planes.

use glam::{EulerRot, Quat, Vec2, Vec3};
use proptest::prelude::*;
use sightline_scene::{shapes, Angle, Camera, Instance, NodeDesc, Projection, Scene, Transform, View};
use sightline_spatial::*;

const W: usize = 48;
const H: usize = 32;

type InstanceParams = ([f32; 3], [f32; 3], [f32; 3], bool);

fn build_scene(params: &[InstanceParams]) -> Scene {
    let mut scene = Scene::new();
    let cube = scene.add_mesh(shapes::cube("cube").unwrap());
    // ~600 triangles: several clusters per instance.
    let slab = scene.add_mesh(
        shapes::subdivided_box("slab", Vec3::new(-1.0, -0.2, -1.0), Vec3::new(1.0, 0.2, 1.0), [10, 2, 10], true)
            .unwrap(),
    );
    for (i, (t, r, s, big)) in params.iter().enumerate() {
        let tr = Transform {
            translation: Vec3::from(*t),
            rotation: Quat::from_euler(EulerRot::XYZ, r[0], r[1], r[2]),
            scale: Vec3::from(*s),
        };
        let mesh = if *big { slab } else { cube };
        scene.add_node(None, NodeDesc::new(format!("n{i}")).transform(tr).mesh(mesh)).unwrap();
    }
    scene.update_transforms();
    scene
}

/// (instance, triangle) of the nearest hit per pixel, if any.
fn reference_hits(scene: &Scene, instances: &[Instance], cam: &Camera) -> Vec<Option<(u32, u32)>> {
    // World-space triangles once.
    let mut tris: Vec<([Vec3; 3], u32, u32)> = Vec::new();
    for (k, inst) in instances.iter().enumerate() {
        let mesh = scene.mesh(inst.mesh).unwrap();
        for t in 0..mesh.triangle_count() {
            let v = mesh.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p));
            tris.push((v, k as u32, t as u32));
        }
    }
    let fwd = cam.view.forward();
    let (near, far) = (cam.projection.near(), cam.projection.far());
    let mut out = Vec::with_capacity(W * H);
    for j in 0..H {
        for i in 0..W {
            let ndc = Vec2::new((i as f32 + 0.5) / W as f32 * 2.0 - 1.0, 1.0 - (j as f32 + 0.5) / H as f32 * 2.0);
            let (o, d) = cam.ray_through_ndc(ndc);
            let ray = Ray::new(o, d).with_interval(f32::NEG_INFINITY, f32::INFINITY);
            let mut best: Option<(f32, u32, u32)> = None;
            for (v, inst, t) in &tris {
                if let Some((th, _, _)) = ray.intersect_triangle(v[0], v[1], v[2]) {
                    let depth = (ray.at(th) - cam.view.eye).dot(fwd);
                    if depth >= near && depth <= far && best.is_none_or(|b| th < b.0) {
                        best = Some((th, *inst, *t));
                    }
                }
            }
            out.push(best.map(|b| (b.1, b.2)));
        }
    }
    out
}

fn camera(eye: [f32; 3], target: [f32; 3], fov: f32, near: f32, depth: f32, kind: u8) -> Option<Camera> {
    let view = View::look_at(Vec3::from(eye), Vec3::from(target), Vec3::Y).ok()?;
    let aspect = W as f32 / H as f32;
    let far = near + depth;
    let projection = match kind {
        0 | 1 => Projection::perspective(Angle::degrees(fov), aspect, near, far).ok()?,
        2 => Projection::orthographic(-6.0 * aspect, 6.0 * aspect, -6.0, 6.0, near, far).ok()?,
        _ => Projection::cabinet(-6.0 * aspect, 6.0 * aspect, -6.0, 6.0, near, far, 0.6).ok()?,
    };
    Camera::new(view, projection).ok()
}

fn instance_strategy() -> impl Strategy<Value = InstanceParams> {
    (
        prop::array::uniform3(-6.0f32..6.0),
        prop::array::uniform3(-3.2f32..3.2),
        prop::array::uniform3(0.2f32..3.0),
        prop::bool::weighted(0.15),
    )
}

fn ids(v: &[Visible]) -> std::collections::HashSet<u32> {
    v.iter().map(|x| x.index).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn every_visible_instance_and_cluster_survives_culling(
        params in prop::collection::vec(instance_strategy(), 1..40),
        eye in prop::array::uniform3(-14.0f32..14.0),
        target in prop::array::uniform3(-3.0f32..3.0),
        fov in 20.0f32..100.0,
        near in 0.05f32..1.0,
        depth in 3.0f32..40.0,
        kind in 0u8..4,
        max_depth in 1u32..9,
    ) {
        let Some(cam) = camera(eye, target, fov, near, depth, kind) else { return Ok(()); };
        let scene = build_scene(&params);
        let instances = scene.instances();
        let frustum = Frustum::from_camera(&cam);
        let hits = reference_hits(&scene, &instances, &cam);

        let tlas = InstanceBvh::from_instances(&instances);
        let octree = LooseOctree::from_instances(&instances, max_depth);
        let clustered = ClusteredScene::from_instances(&scene, &instances);
        let mut sets = Vec::new();
        for masking in [true, false] {
            let opts = CullOptions { plane_masking: masking };
            let mut v = Vec::new();
            tlas.cull_with(&frustum, opts, &mut v);
            sets.push(("tlas", masking, ids(&v)));
            let mut v = Vec::new();
            octree.cull_with(&frustum, opts, &mut v);
            sets.push(("octree", masking, ids(&v)));
        }
        let mut v = Vec::new();
        tlas.cull_coherent(&frustum, &mut CoherencyCache::new(), &mut v);
        sets.push(("tlas coherent", true, ids(&v)));
        let mut f2b = Vec::new();
        tlas.traverse_front_to_back(Some(&frustum), cam.view.eye, |_| Visit::Continue, |v| { f2b.push(v); Visit::Continue });
        sets.push(("tlas front-to-back", true, ids(&f2b)));
        let mut f2b = Vec::new();
        octree.traverse_front_to_back(Some(&frustum), cam.view.eye, |_| Visit::Continue, |v| { f2b.push(v); Visit::Continue });
        sets.push(("octree front-to-back", true, ids(&f2b)));

        // Clusters: (instance, cluster) items, culled plainly and by the batched cursor.
        let mut items = Vec::new();
        clustered.cull_with(&frustum, CullOptions { plane_masking: true }, &mut items);
        let cluster_set: std::collections::HashSet<ClusterItem> = items.iter().map(|v| clustered.item(v.index)).collect();
        let mut cursor = clustered.cursor(Some(&frustum), cam.view.eye);
        let mut batch = Vec::new();
        while cursor.next_batch(clustered.bvh(), |_| true, 7, &mut batch) {}
        let cursor_set: std::collections::HashSet<ClusterItem> = batch.iter().map(|v| clustered.item(v.index)).collect();
        prop_assert_eq!(&cursor_set, &cluster_set);

        for (p, hit) in hits.iter().enumerate() {
            let Some((inst, tri)) = *hit else { continue };
            for (name, masking, set) in &sets {
                prop_assert!(set.contains(&inst), "{} (masking {}) culled instance {} visible at pixel {}", name, masking, inst, p);
            }
            let mc = clustered.mesh_clusters(inst).unwrap();
            let c = (0..mc.clusters().len()).find(|&c| mc.triangles(c).contains(&tri)).unwrap();
            let item = ClusterItem { instance: inst, cluster: c as u32 };
            prop_assert!(cluster_set.contains(&item), "cluster {:?} visible at pixel {} was culled", item, p);
        }

        // `inside` really means inside.
        let mut v = Vec::new();
        tlas.cull(&frustum, &mut v);
        for x in &v {
            if x.inside {
                prop_assert_eq!(frustum.classify(&instances[x.index as usize].world_aabb), Containment::Inside);
            }
        }
    }
}

#[test]
fn a_camera_looking_away_sees_nothing() {
    let params: Vec<InstanceParams> = (0..40)
        .map(|i| {
            let x = (i % 8) as f32 * 2.0 - 8.0;
            let z = (i / 8) as f32 * 2.0 - 4.0;
            ([x, 0.0, z], [0.1 * i as f32, 0.0, 0.0], [0.5, 1.0, 0.5], i % 5 == 0)
        })
        .collect();
    let scene = build_scene(&params);
    let instances = scene.instances();
    let tlas = InstanceBvh::from_instances(&instances);
    let octree = LooseOctree::from_instances(&instances, 6);
    let clustered = ClusteredScene::build(&scene);
    // Looking at the scene: most things are visible, and culling keeps them.
    let toward = camera([0.0, 8.0, 20.0], [0.0, 0.0, 0.0], 60.0, 0.1, 100.0, 0).unwrap();
    let away = camera([0.0, 8.0, 20.0], [0.0, 8.0, 40.0], 60.0, 0.1, 100.0, 0).unwrap();
    let mut v = Vec::new();
    tlas.cull(&Frustum::from_camera(&toward), &mut v);
    assert_eq!(v.len(), 40);
    {
        let cam = away;
        let f = Frustum::from_camera(&cam);
        let mut out = Vec::new();
        tlas.cull(&f, &mut out);
        octree.cull(&f, &mut out);
        clustered.cull(&f, &mut out);
        assert!(out.is_empty(), "{out:?}");
        tlas.traverse_front_to_back(Some(&f), cam.view.eye, |_| Visit::Continue, |_| panic!("nothing is visible"));
    }
    // A narrow camera sees part of the scene only.
    let narrow = camera([0.0, 8.0, 20.0], [-8.0, 0.0, -4.0], 10.0, 0.1, 100.0, 0).unwrap();
    let mut out = Vec::new();
    tlas.cull(&Frustum::from_camera(&narrow), &mut out);
    assert!(!out.is_empty() && out.len() < 20, "{}", out.len());
}

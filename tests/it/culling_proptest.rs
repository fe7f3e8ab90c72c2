//! Conservative frustum culling, property-tested against the real rasterizer: for random
//! scenes and cameras, every instance that owns at least one pixel of the brute-force
//! triangle-ID buffer is in the culled set of the instance BVH and of the loose octree, with
//! and without plane masking; and a camera looking away from everything culls everything.

use glam::{Quat, Vec3};
use proptest::prelude::*;
use sightline::render::{render_scene, Framebuffer, RenderOptions};
use sightline::scene::path::CameraKey;
use sightline::scene::{shapes, Instance, NodeDesc, Scene, Transform};
use sightline::spatial::{CullOptions, Frustum, InstanceBvh, LooseOctree, Visible};

use crate::support::camera_key;

const W: u32 = 96;
const H: u32 = 64;

#[derive(Debug, Clone)]
struct Placed {
    pos: [f32; 3],
    scale: [f32; 3],
    angle: f32,
    slab: bool,
}

fn placed() -> impl Strategy<Value = Placed> {
    (
        prop::array::uniform3(-20.0f32..20.0),
        prop::array::uniform3(0.05f32..6.0),
        0.0f32..std::f32::consts::TAU,
        any::<bool>(),
    )
        .prop_map(|(pos, scale, angle, slab)| Placed { pos, scale, angle, slab })
}

fn build(objects: &[Placed]) -> Scene {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("cube").unwrap());
    let slab =
        s.add_mesh(shapes::subdivided_box("slab", Vec3::splat(-0.5), Vec3::splat(0.5), [6, 2, 6], true).unwrap());
    for (i, o) in objects.iter().enumerate() {
        let t = Transform::from_translation(o.pos.into())
            .with_rotation(Quat::from_rotation_y(o.angle) * Quat::from_rotation_x(0.3 * o.angle))
            .with_scale(o.scale.into());
        s.add_node(None, NodeDesc::new(format!("o{i}")).transform(t).mesh(if o.slab { slab } else { cube })).unwrap();
    }
    s.update_transforms();
    s
}

/// Instances owning at least one pixel of the brute-force ID buffer.
fn owners(scene: &Scene, instances: &[Instance], key: &CameraKey) -> Vec<bool> {
    let cam = key.camera(W as f32 / H as f32).unwrap();
    let mut fb = Framebuffer::new(W, H).unwrap();
    let opts = RenderOptions { backface_culling: false, ..RenderOptions::ids_only() };
    render_scene(scene, &cam, &mut fb, &opts).unwrap();
    let mut own = vec![false; instances.len()];
    for &id in fb.ids.iter().filter(|&&i| i != 0) {
        let t = id - 1;
        let k = instances.partition_point(|i| i.first_triangle + i.triangle_count <= t);
        own[k] = true;
    }
    own
}

fn culled_sets(instances: &[Instance], frustum: &Frustum) -> Vec<(String, Vec<bool>)> {
    let tlas = InstanceBvh::from_instances(instances);
    let octree = LooseOctree::from_instances(instances, 5);
    let mut sets = Vec::new();
    for masking in [true, false] {
        let opts = CullOptions { plane_masking: masking };
        let mut v: Vec<Visible> = Vec::new();
        tlas.cull_with(frustum, opts, &mut v);
        sets.push((format!("bvh, masking {masking}"), v.clone()));
        v.clear();
        octree.cull_with(frustum, opts, &mut v);
        sets.push((format!("octree, masking {masking}"), v));
    }
    sets.into_iter()
        .map(|(name, v)| {
            let mut s = vec![false; instances.len()];
            for x in v {
                s[x.index as usize] = true;
            }
            (name, s)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn every_instance_with_a_pixel_survives_culling(
        objects in prop::collection::vec(placed(), 1..40),
        eye in prop::array::uniform3(-30.0f32..30.0),
        target in prop::array::uniform3(-10.0f32..10.0),
        fovy in 20.0f32..100.0,
        near in 0.05f32..2.0,
    ) {
        prop_assume!(Vec3::from(eye).distance(Vec3::from(target)) > 0.5);
        let scene = build(&objects);
        let instances = scene.instances();
        let key = camera_key(eye, target, fovy, near, 200.0);
        prop_assume!(key.camera(1.5).is_ok());
        let own = owners(&scene, &instances, &key);
        let frustum = Frustum::from_camera(&key.camera(W as f32 / H as f32).unwrap());
        for (name, set) in culled_sets(&instances, &frustum) {
            for (i, (&o, &s)) in own.iter().zip(&set).enumerate() {
                prop_assert!(!o || s, "{name}: instance {i} owns pixels but was culled");
            }
        }
    }
}

#[test]
fn looking_away_culls_everything() {
    let objects: Vec<Placed> = (0..50)
        .map(|i| Placed {
            pos: [i as f32 % 10.0, 0.0, -(i as f32)],
            scale: [1.0; 3],
            angle: i as f32,
            slab: i % 2 == 0,
        })
        .collect();
    let scene = build(&objects);
    let instances = scene.instances();
    let key = camera_key([0.0, 0.0, 10.0], [0.0, 0.0, 20.0], 60.0, 0.1, 100.0);
    let frustum = Frustum::from_camera(&key.camera(1.5).unwrap());
    for (name, set) in culled_sets(&instances, &frustum) {
        assert!(set.iter().all(|&s| !s), "{name} kept something behind the camera");
    }
    assert!(owners(&scene, &instances, &key).iter().all(|&o| !o));
}

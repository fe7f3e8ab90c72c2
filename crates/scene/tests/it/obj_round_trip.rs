//! The OBJ exporter and loader on a scene whose coordinates use all their digits: a round trip
//! keeps every triangle, in ID order, at the same place. 10^5 triangles here; the 10^6
//! round trip is timed by `cargo bench --bench scene` (group `obj`).

use glam::{Quat, Vec3};
use sightline_scene::export::export_obj;
use sightline_scene::obj_loader::load_obj;
use sightline_scene::*;

/// About 1000-triangle meshes instanced under rotated, scaled nodes until `triangles`, so
/// coordinates use all their digits.
fn tiled_scene(mesh: Mesh, triangles: u64) -> Scene {
    let mut scene = Scene::new();
    let mesh = scene.add_mesh(mesh);
    let root = scene.add_node(None, NodeDesc::new("root")).unwrap();
    let mut n = 0;
    while scene.stats().triangles < triangles {
        let t =
            Transform::from_translation(Vec3::new((n % 37) as f32 * 1.37, (n / 37) as f32 * 0.71, n as f32 * 0.013))
                .with_rotation(Quat::from_rotation_y(n as f32 * 0.31) * Quat::from_rotation_x(0.2))
                .with_scale(Vec3::new(1.1, 0.9, 1.3));
        let desc = NodeDesc::new(format!("tile {n}")).transform(t).mesh(mesh);
        scene.add_node(Some(root), desc).unwrap();
        n += 1;
    }
    scene.update_transforms();
    scene
}

/// A mesh of `n` separate triangles (no shared vertices: 3 vertices per triangle).
fn soup(n: usize) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..n {
        let o = Vec3::new((i % 31) as f32 * 0.37, (i / 31) as f32 * 0.21, (i % 7) as f32 * 0.11);
        positions.extend([o, o + Vec3::new(0.3, 0.01, 0.0), o + Vec3::new(0.02, 0.3, 0.05)]);
    }
    Mesh::new("soup", positions, None, None, (0..3 * n as u32).collect()).unwrap()
}

fn round_trip(scene: &Scene, what: &str) {
    let triangles = scene.stats().triangles;
    let path = std::env::temp_dir().join(format!("sightline-round-trip-{}.obj", std::process::id()));
    export_obj(scene, &path).unwrap();
    let back = load_obj(&path);
    let _ = std::fs::remove_file(&path);
    let mut back = back.unwrap();
    back.update_transforms();
    assert_eq!(back.meshes().count(), 1, "{what}");
    assert_eq!(back.stats().triangles, triangles, "{what}");
    // Every triangle: same corners, bit for bit, at its place in ID order.
    let flat = back.mesh(back.instances()[0].mesh).unwrap();
    for inst in scene.instances() {
        let m = scene.mesh(inst.mesh).unwrap();
        for t in 0..m.triangle_count() {
            let want = m.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p));
            assert_eq!(flat.triangle_positions(inst.first_triangle as usize + t), want, "{what}: triangle {t}");
        }
    }
}

#[test]
fn obj_round_trip_keeps_every_triangle_in_place() {
    round_trip(&tiled_scene(shapes::ground_quad("tile", 22).unwrap(), 100_000), "shared vertices");
    round_trip(&tiled_scene(soup(1000), 100_000), "triangle soup");
}

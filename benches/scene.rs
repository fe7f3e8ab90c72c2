//! Scene benchmarks: world-transform propagation over 10^6 nodes (flat and deep, and flat
//! with every node drawing a mesh, so that the change report lists each moved node), full and
//! after changing 1% of the nodes (on a fresh clone, and edited in place frame after frame as an
//! animation would), building the 10^6-triangle city, and its OBJ round trip (export, load).

#![forbid(unsafe_code)]

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use glam::Vec3;
use sightline_scene::builders::{city, CityParams};
use sightline_scene::export::export_obj;
use sightline_scene::obj_loader::load_obj;
use sightline_scene::rng::Rng;
use sightline_scene::{shapes, NodeDesc, NodeId, Scene, Transform};

const NODES: usize = 1_000_000;

/// One root with 10^6 children.
fn flat() -> (Scene, Vec<NodeId>) {
    let mut s = Scene::new();
    let root = s.add_node(None, NodeDesc::new("root")).unwrap();
    let ids = (0..NODES)
        .map(|i| {
            s.add_node(Some(root), NodeDesc::new("n").transform(Transform::from_translation(Vec3::X * i as f32)))
                .unwrap()
        })
        .collect();
    s.update_transforms();
    (s, ids)
}

/// One root with 10^6 children, each drawing the same cube.
fn flat_drawn() -> (Scene, Vec<NodeId>) {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("cube").unwrap());
    let root = s.add_node(None, NodeDesc::new("root")).unwrap();
    let ids = (0..NODES)
        .map(|i| {
            let t = Transform::from_translation(Vec3::X * i as f32);
            s.add_node(Some(root), NodeDesc::new("n").transform(t).mesh(cube)).unwrap()
        })
        .collect();
    s.update_transforms();
    (s, ids)
}

/// 1000 chains of 1000 nodes.
fn deep() -> (Scene, Vec<NodeId>) {
    let mut s = Scene::new();
    let mut ids = Vec::with_capacity(NODES);
    for _ in 0..1000 {
        let mut parent = None;
        for _ in 0..1000 {
            let id =
                s.add_node(parent, NodeDesc::new("n").transform(Transform::from_translation(Vec3::Y * 0.01))).unwrap();
            ids.push(id);
            parent = Some(id);
        }
    }
    s.update_transforms();
    (s, ids)
}

fn propagate(c: &mut Criterion) {
    let mut g = c.benchmark_group("propagate_1e6");
    g.sample_size(10);
    for (name, (mut scene, ids)) in [("flat", flat()), ("deep", deep()), ("flat_drawn", flat_drawn())] {
        let roots: Vec<NodeId> = scene.roots().collect();
        let mut rng = Rng::new(5);
        let some: Vec<NodeId> = (0..NODES / 100).map(|_| ids[rng.below(ids.len() as u32) as usize]).collect();
        g.bench_function(format!("{name}/full"), |b| {
            b.iter_batched_ref(
                || {
                    let mut s = scene.clone();
                    for &r in &roots {
                        s.set_local_transform(r, Transform::from_translation(Vec3::Z)).unwrap();
                    }
                    s
                },
                |s| s.update_transforms(),
                BatchSize::LargeInput,
            )
        });
        g.bench_function(format!("{name}/one_percent_changed"), |b| {
            b.iter_batched_ref(
                || {
                    let mut s = scene.clone();
                    for &n in &some {
                        s.set_local_transform(n, Transform::from_translation(Vec3::ONE)).unwrap();
                    }
                    s
                },
                |s| {
                    s.update_transforms();
                    s.changes().moved.len()
                },
                BatchSize::LargeInput,
            )
        });
        // As in a frame loop: the same scene edited in place (an animation setting 1% of
        // the local transforms), only the propagation timed.
        let mut frame = 0u32;
        g.bench_function(format!("{name}/one_percent_per_frame"), |b| {
            b.iter_custom(|n| {
                let mut spent = Duration::ZERO;
                for _ in 0..n {
                    frame += 1;
                    let t = Transform::from_translation(Vec3::splat(frame as f32));
                    for &id in &some {
                        scene.set_local_transform(id, t).unwrap();
                    }
                    let start = Instant::now();
                    scene.update_transforms();
                    spent += start.elapsed();
                }
                spent
            })
        });
    }
    g.finish();
}

fn build_city(c: &mut Criterion) {
    let mut g = c.benchmark_group("city");
    g.sample_size(10);
    let p = CityParams::for_triangles(1_000_000);
    g.bench_function("build_1e6", |b| b.iter(|| city(&p).unwrap()));
    g.finish();
}

/// Exporting the 10^6-triangle city as one OBJ mesh and loading it back.
fn obj_round_trip(c: &mut Criterion) {
    let mut g = c.benchmark_group("obj");
    g.sample_size(10);
    let scene = city(&CityParams::for_triangles(1_000_000)).unwrap().scene;
    let dir = std::env::temp_dir().join(format!("sightline-bench-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("city.obj");
    // Written once before timing, so that `load_1e6` has its file when run alone.
    export_obj(&scene, &path).unwrap();
    g.bench_function("export_1e6", |b| b.iter(|| export_obj(&scene, &path).unwrap()));
    g.bench_function("load_1e6", |b| b.iter(|| load_obj(&path).unwrap()));
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, propagate, build_city, obj_round_trip);
criterion_main!(benches);

//! Spatial structures on the default 10^6-triangle city, on the same city flattened into one
//! 10^6-triangle mesh (what loading its OBJ export gives), and on 10^5 instances of a cube:
//! build time of each structure (TLAS, BLAS, clusters, clustered scene, loose octree; BSP on a
//! 10^5-triangle subset), frustum query time per frame (street and aerial frames), refit vs
//! rebuild, octree moves. Bytes per structure and per-frame counts are printed first.

#![forbid(unsafe_code)]

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::Vec3;
use sightline_scene::builders::{city, scatter, CityParams, ScatterParams};
use sightline_scene::{shapes, Aabb, Angle, Camera, Instance, LookAt, Mesh, NodeDesc, Scene};
use sightline_spatial::{
    BspParams, BspTree, BvhPreset, ClusteredScene, CoherencyCache, CullOptions, Frustum, InstanceBvh, LooseOctree,
    MeshClusters, TriangleBvh, Visible, Visit,
};

/// Octree depth: for 10^5 small objects, 8 levels make ~4.5 nodes per object; 6 suits them.
const OCTREE_DEPTH: u32 = 6;

/// The scene flattened into one world-space mesh (the OBJ export's triangle order).
fn flatten(scene: &Scene) -> Mesh {
    let (mut pos, mut idx) = (Vec::new(), Vec::new());
    for inst in scene.instances() {
        let m = scene.mesh(inst.mesh).expect("mesh");
        let base = pos.len() as u32;
        pos.extend(m.positions().iter().map(|&p| inst.world_from_local.transform_point3(p)));
        idx.extend(m.indices().iter().map(|&i| base + i));
    }
    Mesh::new("flattened city", pos, None, None, idx).expect("flattened mesh")
}

fn one_mesh_scene(mesh: Mesh) -> Scene {
    let mut s = Scene::new();
    let m = s.add_mesh(mesh);
    s.add_node(None, NodeDesc::new("city").mesh(m)).expect("node");
    s.update_transforms();
    s
}

fn cubes(count: u32) -> Scene {
    let mut s = Scene::new();
    let cube = s.add_mesh(shapes::cube("cube").expect("cube"));
    let params = ScatterParams {
        count,
        region: Aabb::new(Vec3::new(-500.0, 0.0, -500.0), Vec3::new(500.0, 20.0, 500.0)),
        scale: (0.5, 2.0),
        upright: false,
        seed: 7,
    };
    scatter(&mut s, None, "cubes", cube, &params).expect("scatter");
    s.update_transforms();
    s
}

fn moved(instances: &[Instance], step: f32, k: u32) -> Vec<Aabb> {
    instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let a = (i as f32 * 0.618 + k as f32) * std::f32::consts::TAU;
            let d = Vec3::new(a.cos(), 0.0, a.sin()) * step;
            Aabb::new(inst.world_aabb.min + d, inst.world_aabb.max + d)
        })
        .collect()
}

fn mib(b: usize) -> String {
    format!("{:.2} MiB", b as f64 / (1024.0 * 1024.0))
}

fn bench(c: &mut Criterion) {
    let t = Instant::now();
    let city = city(&CityParams::default()).expect("city");
    let flat = one_mesh_scene(flatten(&city.scene));
    let cubes = cubes(100_000);
    let aspect = 1280.0 / 720.0;
    let street: Camera = city.layout.street_path(100, 11)[40].camera(aspect).expect("camera");
    let aerial: Camera = city.layout.aerial_path(100)[40].camera(aspect).expect("camera");
    let cube_cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 10.0, -520.0),
            target: Vec3::new(0.0, 0.0, 0.0),
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 600.0,
        },
        aspect,
    )
    .expect("camera");
    eprintln!("setup {:.1} s", t.elapsed().as_secs_f64());

    let city_inst = city.scene.instances();
    let flat_inst = flat.instances();
    let cube_inst = cubes.instances();
    let flat_mesh = flat.mesh(flat_inst[0].mesh).expect("mesh").clone();
    let tris: Vec<[Vec3; 3]> = (0..100_000).map(|t| flat_mesh.triangle_positions(t * 10)).collect();

    // ---- one-off numbers: sizes, counts ---------------------------------------------------
    let tlas_city = InstanceBvh::from_instances(&city_inst);
    let tlas_cubes = InstanceBvh::from_instances(&cube_inst);
    let oct_city = LooseOctree::from_instances(&city_inst, OCTREE_DEPTH);
    let oct_cubes = LooseOctree::from_instances(&cube_inst, OCTREE_DEPTH);
    let cs_city = ClusteredScene::build(&city.scene);
    let cs_flat = ClusteredScene::build(&flat);
    let cs_cubes = ClusteredScene::build(&cubes);
    let blas = TriangleBvh::build(&flat_mesh, BvhPreset::Fast);
    let clusters = MeshClusters::build(&flat_mesh);
    let bsp = BspTree::build(&tris, &BspParams::default());
    eprintln!(
        "city: {} instances, {} triangles; flattened: 1 mesh, {} triangles; cubes: {} instances",
        city_inst.len(),
        city_inst.iter().map(|i| i.triangle_count as u64).sum::<u64>(),
        flat_mesh.triangle_count(),
        cube_inst.len()
    );
    eprintln!("bytes: TLAS city {} | TLAS cubes {}", mib(tlas_city.memory_bytes()), mib(tlas_cubes.memory_bytes()));
    eprintln!(
        "bytes: octree city {} ({} nodes) | octree cubes {} ({} nodes)",
        mib(oct_city.memory_bytes()),
        oct_city.node_count(),
        mib(oct_cubes.memory_bytes()),
        oct_cubes.node_count()
    );
    eprintln!(
        "bytes: clustered city {} ({} items) | clustered flat {} ({} items) | clustered cubes {} ({} items)",
        mib(cs_city.memory_bytes()),
        cs_city.item_count(),
        mib(cs_flat.memory_bytes()),
        cs_flat.item_count(),
        mib(cs_cubes.memory_bytes()),
        cs_cubes.item_count()
    );
    eprintln!(
        "bytes: BLAS 10^6 tris {} (depth {}) | clusters 10^6 tris {} ({} clusters)",
        mib(blas.memory_bytes()),
        blas.bvh().depth(),
        mib(clusters.memory_bytes()),
        clusters.clusters().len()
    );
    let s = bsp.stats();
    eprintln!(
        "bytes: BSP 10^5 tris {} ({} nodes, depth {}, {} splits, {} -> {} triangles)",
        mib(bsp.memory_bytes()),
        s.nodes,
        s.depth,
        s.splits,
        s.triangles_in,
        s.triangles_out
    );
    for (name, cam) in [("street", &street), ("aerial", &aerial)] {
        let f = Frustum::from_camera(cam);
        let mut v = Vec::new();
        tlas_city.cull_with(&f, CullOptions::default(), &mut v);
        let tlas_n = v.len();
        let inside = v.iter().filter(|x| x.inside).count();
        v.clear();
        oct_city.cull_with(&f, CullOptions::default(), &mut v);
        let oct_n = v.len();
        v.clear();
        cs_flat.cull_with(&f, CullOptions::default(), &mut v);
        let flat_tris: usize = v.iter().map(|x| cs_flat.triangles(x.index).len()).sum();
        eprintln!(
            "{name}: TLAS keeps {tlas_n} of {} instances ({inside} inside), octree {oct_n}; \
             flat clusters keep {} of {} ({flat_tris} triangles)",
            city_inst.len(),
            v.len(),
            cs_flat.item_count()
        );
    }
    {
        let boxes = moved(&cube_inst, 1.0, 1);
        let mut t = tlas_cubes.clone();
        let r = t.refit(&boxes);
        let boxes = moved(&cube_inst, 60.0, 2);
        let mut t2 = tlas_cubes.clone();
        let r2 = t2.refit(&boxes);
        eprintln!("refit cubes: SAH ratio {r:?} after 1-unit moves, {r2:?} after 60-unit moves (rebuild above 1.5)");
    }

    // ---- builds ---------------------------------------------------------------------------
    let mut g = c.benchmark_group("spatial_build");
    g.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2));
    g.bench_function("tlas/city", |b| b.iter(|| InstanceBvh::from_instances(&city_inst)));
    g.bench_function("tlas/cubes_1e5", |b| b.iter(|| InstanceBvh::from_instances(&cube_inst)));
    g.bench_function("octree/city", |b| b.iter(|| LooseOctree::from_instances(&city_inst, OCTREE_DEPTH)));
    g.bench_function("octree/cubes_1e5", |b| b.iter(|| LooseOctree::from_instances(&cube_inst, OCTREE_DEPTH)));
    g.bench_function("clusters/mesh_1e6", |b| b.iter(|| MeshClusters::build(&flat_mesh)));
    g.bench_function("blas/mesh_1e6_fast", |b| b.iter(|| TriangleBvh::build(&flat_mesh, BvhPreset::Fast)));
    g.bench_function("clustered_scene/city", |b| b.iter(|| ClusteredScene::build(&city.scene)));
    g.bench_function("clustered_scene/flat_1e6", |b| b.iter(|| ClusteredScene::build(&flat)));
    g.bench_function("clustered_scene/cubes_1e5", |b| b.iter(|| ClusteredScene::build(&cubes)));
    g.bench_function("bsp/tris_1e5", |b| b.iter(|| BspTree::build(&tris, &BspParams::default())));
    g.finish();

    // ---- frustum queries per frame ---------------------------------------------------------
    let mut g = c.benchmark_group("spatial_query");
    g.sample_size(20).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(1));
    let mut out: Vec<Visible> = Vec::with_capacity(200_000);
    let frames = [("street", Frustum::from_camera(&street)), ("aerial", Frustum::from_camera(&aerial))];
    for ((name, f), eye) in frames.iter().zip([street.view.eye, aerial.view.eye]) {
        for masking in [true, false] {
            let opts = CullOptions { plane_masking: masking };
            let m = if masking { "mask" } else { "nomask" };
            g.bench_function(BenchmarkId::new(format!("tlas_city/{m}"), name), |b| {
                b.iter(|| {
                    out.clear();
                    tlas_city.cull_with(f, opts, &mut out)
                })
            });
            g.bench_function(BenchmarkId::new(format!("octree_city/{m}"), name), |b| {
                b.iter(|| {
                    out.clear();
                    oct_city.cull_with(f, opts, &mut out)
                })
            });
        }
        g.bench_function(BenchmarkId::new("clustered_flat", name), |b| {
            b.iter(|| {
                out.clear();
                cs_flat.cull_with(f, CullOptions::default(), &mut out)
            })
        });
        g.bench_function(BenchmarkId::new("clustered_flat_front_to_back", name), |b| {
            b.iter(|| {
                out.clear();
                cs_flat.traverse_front_to_back(
                    Some(f),
                    eye,
                    |_| Visit::Continue,
                    |v| {
                        out.push(v);
                        Visit::Continue
                    },
                )
            })
        });
    }
    let fc = Frustum::from_camera(&cube_cam);
    {
        let mut v = Vec::new();
        tlas_cubes.cull_with(&fc, CullOptions::default(), &mut v);
        eprintln!("cubes frame: {} of {} instances visible", v.len(), cube_inst.len());
    }
    let mut cache = CoherencyCache::new();
    g.bench_function("tlas_cubes_1e5/mask", |b| {
        b.iter(|| {
            out.clear();
            tlas_cubes.cull_with(&fc, CullOptions::default(), &mut out)
        })
    });
    g.bench_function("tlas_cubes_1e5/mask_coherent", |b| {
        b.iter(|| {
            out.clear();
            tlas_cubes.cull_coherent(&fc, &mut cache, &mut out)
        })
    });
    g.bench_function("tlas_cubes_1e5/nomask", |b| {
        b.iter(|| {
            out.clear();
            tlas_cubes.cull_with(&fc, CullOptions { plane_masking: false }, &mut out)
        })
    });
    g.bench_function("octree_cubes_1e5/mask", |b| {
        b.iter(|| {
            out.clear();
            oct_cubes.cull_with(&fc, CullOptions::default(), &mut out)
        })
    });
    let oct_cubes8 = LooseOctree::from_instances(&cube_inst, 8);
    eprintln!("octree cubes depth 8: {} nodes, {}", oct_cubes8.node_count(), mib(oct_cubes8.memory_bytes()));
    g.bench_function("octree_cubes_1e5_depth8/mask", |b| {
        b.iter(|| {
            out.clear();
            oct_cubes8.cull_with(&fc, CullOptions::default(), &mut out)
        })
    });
    g.bench_function("clustered_cubes_1e5/mask", |b| {
        b.iter(|| {
            out.clear();
            cs_cubes.cull_with(&fc, CullOptions::default(), &mut out)
        })
    });
    g.finish();

    // ---- refit / rebuild / moves ------------------------------------------------------------
    let mut g = c.benchmark_group("spatial_update");
    g.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2));
    let small = moved(&cube_inst, 1.0, 1);
    let mut t = tlas_cubes.clone();
    g.bench_function("tlas_cubes_1e5/refit", |b| b.iter(|| t.refit(&small)));
    g.bench_function("tlas_cubes_1e5/rebuild", |b| b.iter(|| InstanceBvh::build(&small, BvhPreset::Fast)));
    let mut cs = cs_flat.clone();
    let flat_moved: Vec<Instance> = flat_inst
        .iter()
        .map(|i| {
            let mut i = *i;
            i.world_from_local = glam::Affine3A::from_translation(Vec3::X) * i.world_from_local;
            i.world_aabb = Aabb::new(i.world_aabb.min + Vec3::X, i.world_aabb.max + Vec3::X);
            i
        })
        .collect();
    g.bench_function("clustered_flat/update", |b| b.iter(|| cs.update(&flat_moved)));
    let mut oct = oct_cubes.clone();
    let mut k = 0u32;
    g.bench_function("octree_cubes_1e5/update_all", |b| {
        b.iter(|| {
            k += 1;
            let d = Vec3::new((k % 3) as f32 - 1.0, 0.0, 0.5);
            for (i, inst) in cube_inst.iter().enumerate() {
                oct.update(i as u32, Aabb::new(inst.world_aabb.min + d, inst.world_aabb.max + d));
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

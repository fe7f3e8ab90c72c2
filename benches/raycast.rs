//! Ray casting the default 10^6-triangle city at 1280×720: BLAS + TLAS build time, and
//! primary rays per second for a street frame (eye at 1.7 m looking along a street) and an
//! aerial frame, with 1 and 2 threads.
//!
//! * `raycast_build/city/<threads>t`: the caster over the instanced city (one BLAS per distinct
//!   building mesh, shared by its instances, plus the TLAS).
//! * `raycast_build/flat/<threads>t`: the same triangles flattened into one world-space mesh (what a
//!   ray tracer that reads the exported OBJ, such as Embree, builds).
//! * `raycast_build/flat_shuffled/<threads>t`: the flattened mesh with its triangles in a scrambled
//!   order, so that no two halves of a square are neighbours in the mesh (as in a mesh
//!   reordered for the vertex cache): its triangles pair into quads across shared edges.
//! * `raycast_city_1280x720/<frame>/<ids|shaded>/<threads>t`: one frame; the throughput
//!   line (Melem/s) is million primary rays per second. `ids` writes IDs and depth only (as
//!   the Embree reference does); `shaded` adds flat shading.
//! * `raycast_mesh_order_1280x720/<flat|flat_shuffled>/<frame>`: IDs and depth of the two
//!   one-mesh scenes on two threads: what the order of a mesh's triangles costs. Criterion
//!   runs the two one after the other, so on a noisy machine a gap between them can be the
//!   machine's: one measured 6–18% on the street frame, where frames of the two meshes
//!   taken in turns in one process differed by under 1%.

#![forbid(unsafe_code)]

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use glam::Vec3;
use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
use sightline_scene::builders::{city, CityParams};
use sightline_scene::{Camera, Mesh, NodeDesc, Scene};

const W: u32 = 1280;
const H: u32 = 720;

/// The scene's triangles in world space, as one mesh; `scrambled`: triangle t moved to place
/// (p·t) mod n for a large prime p, so that neighbours in the mesh lie far apart.
fn flattened(scene: &Scene, scrambled: bool) -> Scene {
    let mut positions: Vec<Vec3> = Vec::new();
    for inst in scene.instances() {
        let Some(m) = scene.mesh(inst.mesh) else { continue };
        for t in 0..m.triangle_count() {
            positions.extend(m.triangle_positions(t).map(|p| inst.world_from_local.transform_point3(p)));
        }
    }
    let n = positions.len() as u64 / 3;
    const P: u64 = 1_000_003;
    assert!(!scrambled || !n.is_multiple_of(P), "the stride is a prime that does not divide the triangle count");
    let mut indices = vec![0u32; positions.len()];
    for t in 0..n {
        let to = if scrambled { P * t % n } else { t } as usize;
        for k in 0..3 {
            indices[3 * to + k] = (3 * t) as u32 + k as u32;
        }
    }
    let mut flat = Scene::new();
    let mesh = flat.add_mesh(Mesh::new("flat", positions, None, None, indices).expect("mesh"));
    flat.add_node(None, NodeDesc::new("flat").mesh(mesh)).expect("node");
    flat.update_transforms();
    flat
}

/// A group of whole frames, its throughput in primary rays.
fn frame_group<'a>(c: &'a mut Criterion, name: &str) -> BenchmarkGroup<'a, WallTime> {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .throughput(Throughput::Elements(W as u64 * H as u64));
    group
}

fn bench(c: &mut Criterion) {
    let city = city(&CityParams::default()).expect("city");
    let scene = &city.scene;
    let flat = flattened(scene, false);
    let shuffled = flattened(scene, true);
    let aspect = W as f32 / H as f32;
    let cam = |k: sightline_scene::path::CameraKey| -> Camera { k.camera(aspect).expect("camera") };
    let frames =
        [("street", cam(city.layout.street_path(100, 11)[40])), ("aerial", cam(city.layout.aerial_path(100)[40]))];

    let mut group = c.benchmark_group("raycast_build");
    group.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2));
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
        for (name, s) in [("city", scene), ("flat", &flat), ("flat_shuffled", &shuffled)] {
            pool.install(|| {
                let rc = RayCaster::build(s).expect("build");
                eprintln!(
                    "{name}/{threads}t: {} BLASes, {} stored triangles ({} paired), {} instances, {:.1} ms",
                    rc.blas_count(),
                    rc.stored_triangles(),
                    rc.paired_triangles(),
                    rc.instance_count(),
                    rc.build_ms()
                );
            });
            group.bench_function(format!("{name}/{threads}t"), |b| {
                pool.install(|| b.iter(|| RayCaster::build(s).expect("build").instance_count()))
            });
        }
    }
    group.finish();

    let caster = RayCaster::build(scene).expect("build");
    let mut group = frame_group(c, "raycast_city_1280x720");
    let mut fb = Framebuffer::new(W, H).expect("framebuffer");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
        for (name, camera) in &frames {
            for (mode, opts) in [("ids", RaycastOptions::ids_only()), ("shaded", RaycastOptions::default())] {
                let label = format!("{name}/{mode}/{threads}t");
                pool.install(|| {
                    let s = caster.render(scene, camera, &mut fb, &opts).expect("render");
                    eprintln!(
                        "{label}: {} hits of {} rays, {:.1} ms, {:.2} Mrays/s",
                        s.hits,
                        s.primary_rays,
                        s.ms_total,
                        s.primary_rays as f64 / s.ms_total / 1e3
                    );
                });
                group.bench_function(&label, |b| {
                    pool.install(|| b.iter(|| caster.render(scene, camera, &mut fb, &opts).expect("render").hits))
                });
            }
        }
    }
    group.finish();

    let mut group = frame_group(c, "raycast_mesh_order_1280x720");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("thread pool");
    let opts = RaycastOptions::ids_only();
    for (name, s) in [("flat", &flat), ("flat_shuffled", &shuffled)] {
        let caster = pool.install(|| RayCaster::build(s).expect("build"));
        for (frame, camera) in &frames {
            group.bench_function(format!("{name}/{frame}"), |b| {
                pool.install(|| b.iter(|| caster.render(s, camera, &mut fb, &opts).expect("render").hits))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

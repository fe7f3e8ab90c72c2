//! Culling benchmarks on 10^6-triangle scenes.
//!
//! * `city_street/METHOD`: one street frame of the default city at 1280×720 per iteration,
//!   drawn through the `World` facade as a program draws it, walking the 120 frames of the
//!   street path in order (as `sightline walk` does, so `hzb` sees the last frame of a
//!   walk), flat shading, all threads.
//! * `city_orbit/METHOD`: the same along the orbit path (`sightline path --kind orbit`), one
//!   turn around the whole city seen from outside: everything is in view and little is
//!   hidden, the case where culling has the least to gain (`frustum` removes nothing).
//! * `boxfield_1thread/occluders` and `/queries`: the occlusion benchmark of record on one
//!   thread: (a) depth-only rasterization of the frustum- and back-face-culled occluders into
//!   the z-buffer and pyramid, (b) 100,000 box queries against it. `occluders_skip_hidden`:
//!   (a) with occluders hidden by the pyramid as it fills skipped (an identical z-buffer and
//!   IDs: Greene's hierarchical test applied to the occluders themselves).
//!   `occluders_one_mesh`: (a)
//!   with the boxes stored as one mesh; `occluders_one_mesh_skip_hidden`: the same with
//!   occluders hidden by the pyramid as it fills skipped (an identical z-buffer). Only the
//!   pass is timed, as in the `boxfield` example: it draws the z-buffer and IDs into the
//!   framebuffer (tiles write through as they are drawn) and the pyramid the queries read;
//!   writing the untouched tiles as cleared afterwards (`OccluderPass::finish`) is not part
//!   of (a).

#![forbid(unsafe_code)]

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use sightline::boxfield::{Boxfield, QUERIES, SIZE};
use sightline::render::{Culler, Framebuffer, Method, RenderOptions, World};
use sightline::scene::builders::{boxfield, city, BoxfieldLayout, BoxfieldParams, CityParams};
use sightline::scene::path::{orbit_path, CameraKey};
use sightline::scene::Scene;

fn city_street(c: &mut Criterion) {
    let city = city(&CityParams::for_triangles(1_000_000)).unwrap();
    let keys = city.layout.street_path(120, 11);
    city_walk(c, "city_street", city.scene, &keys, Duration::from_secs(4));
}

fn city_orbit(c: &mut Criterion) {
    let city = city(&CityParams::for_triangles(1_000_000)).unwrap();
    let keys = orbit_path(&city.scene.world_aabb(), 120).unwrap();
    city_walk(c, "city_orbit", city.scene, &keys, Duration::from_secs(8));
}

/// Every culling method along the camera path `keys` through `scene`, one frame an iteration.
fn city_walk(c: &mut Criterion, group: &str, scene: Scene, keys: &[CameraKey], time: Duration) {
    let cams: Vec<_> = keys.iter().map(|k| k.camera(1280.0 / 720.0).unwrap()).collect();
    let mut world = World::new(scene);
    world.prepare(Method::Hzb).unwrap();
    let mut fb = Framebuffer::new(1280, 720).unwrap();
    let opts = RenderOptions::default();
    let mut g = c.benchmark_group(group);
    g.sample_size(20).measurement_time(time).warm_up_time(Duration::from_secs(1));
    // Each frame runs on a pool worker, as in the CLI: from outside the pool every parallel
    // call of a frame would hand its work over and wait (one handover per frame instead).
    let pool = rayon::ThreadPoolBuilder::new().build().unwrap();
    for m in Method::ALL {
        let mut k = 0;
        g.bench_function(m.name(), |b| {
            b.iter(|| {
                k = (k + 1) % cams.len();
                pool.install(|| world.render(&cams[k], m, &mut fb, &opts).unwrap())
            })
        });
    }
    g.finish();
}

fn boxfield_1thread(c: &mut Criterion) {
    let bf = Boxfield::new(QUERIES);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut culler = Culler::new(&bf.scene);
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1).unwrap();
    let opts = RenderOptions::ids_only();
    let mut g = c.benchmark_group("boxfield_1thread");
    g.sample_size(20).measurement_time(Duration::from_secs(4)).warm_up_time(Duration::from_secs(1));
    // Times the occluder pass of `culler` alone (finishing it, which writes the tiles no
    // batch drew into as cleared, is not part of it).
    let mut time_pass = |name: &str, culler: &mut Culler, skip_hidden: bool| {
        g.bench_function(name, |b| {
            b.iter_custom(|n| {
                pool.install(|| {
                    let mut spent = Duration::ZERO;
                    for _ in 0..n {
                        let t = Instant::now();
                        let (_, _, pass) = culler.occluder_pass_with(&bf.camera, &mut fb, &opts, skip_hidden).unwrap();
                        spent += t.elapsed();
                        pass.finish();
                    }
                    spent
                })
            })
        });
    };
    // Every occluder (the benchmark of record), then the same pass with the occluders the
    // pyramid already hides skipped as it fills (the same z-buffer and IDs).
    time_pass("occluders", &mut culler, false);
    time_pass("occluders_skip_hidden", &mut culler, true);
    // The same boxes as one mesh (the flat triangle list MOC takes): every occluder, then
    // with hidden occluders skipped (the same z-buffer).
    let one_mesh = boxfield(&BoxfieldParams { layout: BoxfieldLayout::OneMesh, ..Default::default() }).unwrap();
    let mut flat = Culler::new(&one_mesh);
    time_pass("occluders_one_mesh", &mut flat, false);
    time_pass("occluders_one_mesh_skip_hidden", &mut flat, true);
    // The queries run on the calling thread; only the occluder pass uses the pool.
    let (_, _, q) = pool.install(|| culler.occluder_pass(&bf.camera, &mut fb, &opts)).unwrap();
    let mut answers = Vec::with_capacity(bf.queries.len());
    g.bench_function("queries", |b| {
        b.iter(|| {
            q.test_many(&bf.queries, &mut answers);
            answers.len()
        })
    });
    q.finish();
    g.finish();
}

criterion_group!(benches, city_street, city_orbit, boxfield_1thread);
criterion_main!(benches);

//! Brute-force rasterization of the default 10^6-triangle city at 1280×720: every triangle
//! goes through the pipeline (no scene-level culling). One street frame and one aerial
//! frame, back-face culling off and on, 1 and 2 threads; criterion reports ms/frame, and
//! the throughput line gives triangles/s (Melem/s = million triangles per second).
//!
//! Before timing, the per-stage counters of each configuration are printed once.

#![forbid(unsafe_code)]

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use sightline_render::{draw_all, Framebuffer, RenderOptions, Renderer};
use sightline_scene::builders::{city, CityParams};
use sightline_scene::Camera;

const W: u32 = 1280;
const H: u32 = 720;

fn bench(c: &mut Criterion) {
    let city = city(&CityParams::default()).expect("city");
    let scene = &city.scene;
    let instances = scene.instances();
    let items = draw_all(&instances);
    let tris: u64 = instances.iter().map(|i| i.triangle_count as u64).sum();
    let aspect = W as f32 / H as f32;
    let cam = |k: sightline_scene::path::CameraKey| -> Camera { k.camera(aspect).expect("camera") };
    let frames =
        [("street", cam(city.layout.street_path(100, 11)[40])), ("aerial", cam(city.layout.aerial_path(100)[40]))];
    let mut group = c.benchmark_group("raster_city_1280x720");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .throughput(Throughput::Elements(tris));
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
        for (name, camera) in &frames {
            for cull in [false, true] {
                let opts = RenderOptions { backface_culling: cull, ..RenderOptions::default() };
                let mut r = Renderer::new();
                let mut fb = Framebuffer::new(W, H).expect("framebuffer");
                let label = format!("{name}/cull_{}/{threads}t", if cull { "on" } else { "off" });
                pool.install(|| {
                    r.render(scene, &instances, &items, camera, &mut fb, &opts).expect("render");
                    let s = r.render(scene, &instances, &items, camera, &mut fb, &opts).expect("render");
                    eprintln!(
                        "{label}: {tris} tris, rejected {}, culled {}, clipped {}, small {}, rasterized {}, \
                         written {} / tested {}, overdraw {:.2}; ms geometry {:.1}, binning {:.1}, raster {:.1}, \
                         shading {:.1}, total {:.1}",
                        s.trivially_rejected,
                        s.backface_culled,
                        s.clipped,
                        s.too_small,
                        s.rasterized,
                        s.fragments_written,
                        s.fragments_tested,
                        s.overdraw,
                        s.ms_geometry,
                        s.ms_binning,
                        s.ms_raster,
                        s.ms_shading,
                        s.ms_total
                    );
                });
                group.bench_function(&label, |b| {
                    pool.install(|| {
                        b.iter(|| r.render(scene, &instances, &items, camera, &mut fb, &opts).expect("render"))
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

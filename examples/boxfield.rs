//! The occlusion benchmark of record on one thread: depth-only rasterization of the boxfield's
//! occluders into the z-buffer and pyramid, then 100,000 box queries; prints medians, the
//! visible / occluded counts, and checks that no box reported occluded has a visible pixel.
//!
//! `cargo run --release --example boxfield`

use std::time::Instant;

use sightline::boxfield::{check_occluded, count, Boxfield, QUERIES, SIZE};
use sightline::render::{Culler, Framebuffer, RenderOptions};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let bf = Boxfield::new(QUERIES);
    println!("boxfield: {} triangles, {} queries, {}x{}", bf.scene.stats().triangles, bf.queries.len(), SIZE.0, SIZE.1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("thread pool");
    pool.install(|| {
        let mut culler = Culler::new(&bf.scene);
        culler.first_batch = std::env::var("FIRST_BATCH").ok().and_then(|v| v.parse().ok()).unwrap_or(culler.first_batch);
        let mut fb = Framebuffer::new(SIZE.0, SIZE.1).expect("framebuffer");
        let opts = RenderOptions::ids_only();
        let (mut raster, mut query) = (Vec::new(), Vec::new());
        let mut answers = Vec::new();
        let mut stats = None;
        for _ in 0..15 {
            let t = Instant::now();
            let (cs, fs, q) = culler.occluder_pass(&bf.camera, &mut fb, &opts).expect("occluders");
            stats = Some((cs, fs));
            raster.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            q.test_many(&bf.queries, &mut answers);
            query.push(t.elapsed().as_secs_f64() * 1e3);
            culler.end_occluder_pass(&mut fb);
        }
        if std::env::var("QUERY_PROFILE").is_ok() {
            // Profiling aid: the queries alone, many times.
            let (_, _, q) = culler.occluder_pass(&bf.camera, &mut fb, &opts).expect("occluders");
            for _ in 0..200 {
                q.test_many(&bf.queries, &mut answers);
            }
            culler.end_occluder_pass(&mut fb);
        }
        let c = count(&answers);
        if let Some((cs, fs)) = stats {
            println!(
                "occluders: {} clusters in the frustum, {} back-facing, {} triangles sent, {} back faces, {} rasterized, {} coarse-rejected (triangle x tile), {} fragments tested, {} batches",
                cs.clusters_in_frustum, cs.culled_by_backface, cs.triangles_drawn, fs.backface_culled, fs.rasterized, fs.coarse_rejected, fs.fragments_tested, cs.batches
            );
        }
        println!("(a) occluders into z-buffer + pyramid: median {:.2} ms (1 thread)", median(raster));
        println!("(b) {} box queries:                  median {:.2} ms (1 thread)", bf.queries.len(), median(query));
        println!("visible {}, occluded {}, outside the view {}", c.visible, c.occluded, c.outside);
        let bad = check_occluded(&bf, &answers, &fb);
        println!("brute-force check: {bad} pixels won by boxes reported occluded (must be 0)");
        assert_eq!(bad, 0, "occlusion queries were not conservative");
    });
}

//! The occlusion benchmark of record (on one thread unless `--threads N` says otherwise):
//! depth-only rasterization of the boxfield's
//! occluders into the z-buffer and pyramid, then 100,000 box queries; prints medians, the
//! visible / occluded counts, and checks that no box reported occluded has a visible pixel.
//!
//! Step (a) is timed four ways: every frustum- and back-face-culled occluder of the
//! instanced boxfield (the benchmark as stated), the same with hidden occluders skipped by
//! the pyramid as it fills (checked to give identical buffers), the same boxes stored as one
//! mesh (the flat triangle list Masked Occlusion Culling takes), and the one mesh with hidden
//! occluders skipped. The two one-mesh z-buffers are checked to be
//! identical; the instanced layout rounds vertices differently (`P·V·M` applied to the unit
//! cube instead of `P·V` to world positions), so its depths differ in the last bits.
//!
//! `cargo run --release --example boxfield [-- --threads N]` (`-j N` alike; default one
//! thread, the benchmark as stated; `--threads 2` shows how the passes scale, and the
//! queries then run in parallel, `test_batch`). With `--scaling`, the occluder passes of
//! both layouts run on one thread and on N (at least two) in turn, pass by pass in one
//! process, so that the speed-up is read from interleaved runs rather than from two
//! processes that a noisy machine may run at different speeds.

#![forbid(unsafe_code)]

use std::time::Instant;

use sightline::boxfield::{check_occluded, count, Boxfield, QUERIES, SIZE};
use sightline::render::{BoxVisibility, Culler, Framebuffer, OccluderPass, RenderOptions};
use sightline::scene::builders::{boxfield, BoxfieldLayout, BoxfieldParams};
use sightline::scene::Aabb;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The command line.
#[derive(clap::Parser)]
#[command(about = "The boxfield occlusion benchmark: occluder passes and box queries, checked")]
struct Args {
    /// Worker threads (1: the benchmark as stated; 2 shows how the passes scale, and the
    /// queries then run in parallel)
    #[arg(short = 'j', long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=256))]
    threads: u16,
    /// Time the occluder passes on one thread and on --threads (at least two) in turn, pass
    /// by pass, and print each one's speed-up instead of the benchmark
    #[arg(long)]
    scaling: bool,
}

/// The box queries: on one thread the serial form (the benchmark as stated), on more the
/// parallel one.
fn test(q: &OccluderPass, boxes: &[Aabb], out: &mut Vec<BoxVisibility>, threads: usize) {
    if threads == 1 {
        q.test_many(boxes, out)
    } else {
        q.test_batch(boxes, out)
    }
}

/// `--scaling`: every occluder pass of both layouts (all occluders, and hidden ones
/// skipped) on one thread and on `threads`, alternated pass by pass, with the medians'
/// ratio.
fn scaling(bf: &Boxfield, threads: usize) {
    let one_mesh = boxfield(&BoxfieldParams { layout: BoxfieldLayout::OneMesh, ..Default::default() })
        .expect("the one-mesh boxfield is valid");
    let pools = [1, threads].map(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build().expect("thread pool"));
    let opts = RenderOptions::ids_only();
    println!("occluder passes, 1 thread against {threads}, alternated pass by pass (medians of {ROUNDS}):");
    for (layout, scene) in [("instanced", &bf.scene), ("one mesh", &one_mesh)] {
        // Each pool's culler is built in it, as a program on that many threads would.
        let mut cullers = [0, 1].map(|k| pools[k].install(|| Culler::new(scene)));
        let mut fb = Framebuffer::new(SIZE.0, SIZE.1).expect("framebuffer");
        for skip_hidden in [false, true] {
            let mut times = [Vec::new(), Vec::new()];
            for _ in 0..ROUNDS {
                for (k, pool) in pools.iter().enumerate() {
                    pool.install(|| {
                        let t = Instant::now();
                        let (_, _, pass) =
                            cullers[k].occluder_pass_with(&bf.camera, &mut fb, &opts, skip_hidden).expect("occluders");
                        times[k].push(t.elapsed().as_secs_f64() * 1e3);
                        pass.finish();
                    });
                }
            }
            let [one, many] = times.map(median);
            let which = if skip_hidden { "hidden occluders skipped" } else { "every occluder" };
            println!("  {layout}, {which}: {one:.2} ms against {many:.2} ms ({:.2}x)", one / many);
        }
    }
}

/// Passes per pool in `--scaling`.
const ROUNDS: usize = 25;

fn main() {
    let args = <Args as clap::Parser>::parse();
    let threads = usize::from(args.threads);
    let th = if threads == 1 { "1 thread".to_string() } else { format!("{threads} threads") };
    let bf = Boxfield::new(QUERIES);
    println!("boxfield: {} triangles, {} queries, {}x{}", bf.scene.stats().triangles, bf.queries.len(), SIZE.0, SIZE.1);
    if args.scaling {
        return scaling(&bf, threads.max(2));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
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
            test(&q, &bf.queries, &mut answers, threads);
            query.push(t.elapsed().as_secs_f64() * 1e3);
            q.finish();
        }
        if std::env::var("QUERY_PROFILE").is_ok() {
            // Profiling aid: the queries alone, many times.
            let (_, _, q) = culler.occluder_pass(&bf.camera, &mut fb, &opts).expect("occluders");
            for _ in 0..200 {
                test(&q, &bf.queries, &mut answers, threads);
            }
            q.finish();
        }
        // (a) with hidden occluders skipped: the buffers must be the instanced pass's own.
        let every = (fb.depth.clone(), fb.ids.clone());
        let mut skipped = Vec::new();
        for _ in 0..15 {
            let t = Instant::now();
            let (_, _, pass) = culler.occluder_pass_with(&bf.camera, &mut fb, &opts, true).expect("occluders");
            skipped.push(t.elapsed().as_secs_f64() * 1e3);
            pass.finish();
        }
        let same = fb.depth == every.0 && fb.ids == every.1;
        println!(
            "(a) instanced, hidden occluders skipped: median {:.2} ms ({th}); z-buffer and IDs {} to every occluder's",
            median(skipped),
            if same { "identical" } else { "DIFFERENT" }
        );
        assert!(same, "skipping hidden occluders must not change the buffers");
        // The other two ways of (a): one mesh, all occluders; one mesh, hidden ones skipped.
        let one_mesh = boxfield(&BoxfieldParams { layout: BoxfieldLayout::OneMesh, ..Default::default() })
            .expect("the one-mesh boxfield is valid");
        let mut flat = Culler::new(&one_mesh);
        let mut other = Framebuffer::new(SIZE.0, SIZE.1).expect("framebuffer");
        let mut strict: Option<(Vec<f32>, Vec<u32>)> = None;
        for skip_hidden in [false, true] {
            let mut times = Vec::new();
            let mut drawn = 0;
            for _ in 0..15 {
                let t = Instant::now();
                let (cs, _, pass) = flat.occluder_pass_with(&bf.camera, &mut other, &opts, skip_hidden).expect("occluders");
                times.push(t.elapsed().as_secs_f64() * 1e3);
                drawn = cs.triangles_drawn;
                pass.finish();
            }
            let label = if skip_hidden { "hidden occluders skipped" } else { "every occluder" };
            println!("(a) one mesh, {label}: median {:.2} ms ({th}), {drawn} triangles sent", median(times));
            match &strict {
                None => {
                    // Vertices transformed in another order round differently, so depths (and
                    // rarely IDs) may differ from the instanced layout's buffer in the last bits.
                    let ids = other.ids.iter().zip(&fb.ids).filter(|(a, b)| a != b).count();
                    let depths = other.depth.iter().zip(&fb.depth).filter(|(a, b)| a != b).count();
                    println!("    vs the instanced layout (other vertex rounding): {ids} IDs and {depths} depths differ");
                    strict = Some((other.depth.to_vec(), other.ids.to_vec()));
                }
                Some((d, i)) => {
                    let same = &other.depth == d && &other.ids == i;
                    println!("    z-buffer and IDs {} to every occluder's", if same { "identical" } else { "DIFFERENT" });
                    assert!(same, "skipping hidden occluders must not change the buffers");
                }
            }
        }
        let c = count(&answers);
        if let Some((cs, fs)) = stats {
            println!(
                "occluders: {} clusters in the frustum, {} back-facing, {} triangles sent, {} back faces, {} rasterized, {} coarse-rejected (triangle x tile), {} fragments tested, {} batches",
                cs.clusters_in_frustum, cs.culled_by_backface, cs.triangles_drawn, fs.backface_culled, fs.rasterized, fs.coarse_rejected, fs.fragments_tested, cs.batches
            );
        }
        println!("(a) occluders into z-buffer + pyramid: median {:.2} ms ({th}, instanced boxes)", median(raster));
        println!("(b) {} box queries:                  median {:.2} ms ({th})", bf.queries.len(), median(query));
        println!("visible {}, occluded {}, outside the view {}", c.visible, c.occluded, c.outside);
        let bad = check_occluded(&bf, &answers, &fb);
        println!("brute-force check: {bad} pixels won by boxes reported occluded (must be 0)");
        assert_eq!(bad, 0, "occlusion queries were not conservative");
    });
}

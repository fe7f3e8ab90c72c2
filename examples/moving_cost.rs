//! What moving costs: `hzb` street frames of the traffic city with its vehicles and cranes
//! moving, against the same frames with everything parked, measured interleaved.
//!
//! Two worlds are built from one scene: one is animated (1/30 s per frame; posing,
//! propagating and the culler's sync are part of its frame), the other never changes. They
//! take turns in blocks of 12 frames over the same cameras, and the first 2 frames of each
//! block are not counted, so each world is timed with its own data in the caches (as a
//! program drawing only that world would be) while machine noise falls on both alike.
//! Prints the medians, means, 99th percentiles and maxima of both and their ratio (issue
//! target: moving ≤ 1.3× parked).
//!
//! ```text
//! cargo run --release --example moving_cost [VEHICLES] [ROUNDS]
//! ```

use std::time::Instant;

use sightline::render::{Framebuffer, Method, RenderOptions, World};
use sightline::scene::builders::{city_with_traffic, TrafficParams};

const BLOCK: usize = 12;
const SKIPPED: usize = 2;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let vehicles: u32 = args.next().map_or(Ok(10_000), |a| a.parse())?;
    let rounds: usize = args.next().map_or(Ok(8), |a| a.parse())?;
    let traffic = city_with_traffic(&TrafficParams::new(vehicles))?;
    let cameras =
        traffic.layout.street_path(120, 11).iter().map(|k| k.camera(1280.0 / 720.0)).collect::<Result<Vec<_>, _>>()?;
    let mut moving = World::new(traffic.scene.clone());
    let mut parked = World::new(traffic.scene);
    moving.prepare(Method::Hzb)?;
    parked.prepare(Method::Hzb)?;
    let mut fb = Framebuffer::new(1280, 720)?;
    let opts = RenderOptions::default();
    // Every frame runs on one pool, as a program's frames do.
    let pool = rayon::ThreadPoolBuilder::new().build()?;
    let (mut moving_ms, mut parked_ms) = (Vec::new(), Vec::new());
    let mut frame = 0u32;
    // Round 0 warms both worlds up and is not counted.
    for round in 0..=rounds {
        for block in cameras.chunks(BLOCK) {
            for (k, camera) in block.iter().enumerate() {
                frame += 1;
                let t = Instant::now();
                pool.install(|| -> sightline::render::Result<()> {
                    moving.animate(frame as f32 / 30.0)?;
                    moving.render(camera, Method::Hzb, &mut fb, &opts)?;
                    Ok(())
                })?;
                if round > 0 && k >= SKIPPED {
                    moving_ms.push(t.elapsed().as_secs_f64() * 1e3);
                }
            }
            for (k, camera) in block.iter().enumerate() {
                let t = Instant::now();
                pool.install(|| parked.render(camera, Method::Hzb, &mut fb, &opts))?;
                if round > 0 && k >= SKIPPED {
                    parked_ms.push(t.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
    }
    let (m, p) = (summary(&mut moving_ms), summary(&mut parked_ms));
    println!("{vehicles} vehicles, {} frames each, {} threads", moving_ms.len(), pool.current_num_threads());
    for (name, s) in [("moving", m), ("parked", p)] {
        println!("{name}: median {:.3} ms, mean {:.3} ms, p99 {:.3} ms, max {:.3} ms", s.0, s.1, s.2, s.3);
    }
    println!("moving / parked: {:.3} (medians), {:.3} (means)", m.0 / p.0, m.1 / p.1);
    Ok(())
}

/// Median, mean, 99th percentile (nearest rank) and maximum: a frame that stalls (a tree
/// rebuilt on the frame, say) shows in the last two.
fn summary(ms: &mut [f64]) -> (f64, f64, f64, f64) {
    ms.sort_by(f64::total_cmp);
    let n = ms.len();
    (ms[n / 2], ms.iter().sum::<f64>() / n as f64, ms[(n - 1) * 99 / 100], ms[n - 1])
}

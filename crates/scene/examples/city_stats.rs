//! Builds a city of the given triangle count (default 10^6) and prints its statistics.
//!
//! `cargo run --release -p sightline-scene --example city_stats -- 10000000`

#![forbid(unsafe_code)]

fn main() -> Result<(), sightline_scene::Error> {
    let n: u64 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(1_000_000);
    let t = std::time::Instant::now();
    let params = sightline_scene::builders::CityParams::for_triangles(n);
    let city = sightline_scene::builders::city(&params)?;
    println!("{params:?}");
    println!("{:#?}", city.scene.stats());
    println!("built in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    Ok(())
}

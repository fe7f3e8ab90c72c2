//! A headless walkthrough of any scene: every frame as a PNG, the walk as an animated GIF
//! with the readout burned in, and one CSV row of counters per frame.
//!
//! The path is the city's street walk for the built-in city, and for anything else one
//! orbit around the scene at the distance that fits its bounding sphere in the view (the
//! viewer's start camera, turned about the vertical). Rendering goes through the viewer's
//! `engine` module, the one place both programs call sightline.
//!
//! ```sh
//! cargo run --release --example walkthrough -- --frames 60 --out walkthrough-out
//! cargo run --release --example walkthrough -- --scene assets/some-model.glb --method raycast
//! ```

#![forbid(unsafe_code)]

// The viewer's link to the library; the walkthrough uses a part of it.
#[allow(dead_code, unused_imports)]
#[path = "../viewer/engine.rs"]
mod engine;

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Parser;
use sightline::gif_out;
use sightline::render::Antialias;
use sightline::SceneSpec;

use engine::{Engine, FrameInfo, Framebuffer, Method};

/// Render a walkthrough of a scene to PNG frames, an animated GIF and a CSV of counters.
#[derive(Debug, Parser)]
#[command(name = "walkthrough")]
struct Args {
    /// Scene: a .gltf/.glb/.obj file, `city` (default, ≥ 10^6 triangles), `city:TRIS`,
    /// `city+traffic:N` (N vehicles and tower cranes, animated), or `boxfield`
    #[arg(short, long, default_value = "city", value_name = "SCENE")]
    scene: SceneSpec,
    /// Play the scene's animations along the walk: frame f shows time f / 30 s (always on
    /// for `city+traffic:N`)
    #[arg(long)]
    animate: bool,
    /// Let a scene file read from DIR too (repeatable)
    #[arg(long = "allow-asset-root", value_name = "DIR")]
    allow_asset_roots: Vec<PathBuf>,
    /// Frames of the walk (1 to 100000)
    #[arg(short = 'n', long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frame size
    #[arg(long, default_value = "1280x720", value_parser = sightline::args::parse_size)]
    size: (u32, u32),
    /// Output folder
    #[arg(short, long, value_name = "DIR", default_value = "walkthrough-out")]
    out: PathBuf,
    /// Visibility method
    #[arg(short, long, value_enum, default_value = "hzb")]
    method: Method,
    /// Write every k-th frame as PNG (0: none)
    #[arg(long, default_value_t = 1)]
    png_every: u32,
    /// Widest the GIF gets (frames are shrunk to fit)
    #[arg(long, default_value_t = 480, value_parser = clap::value_parser!(u32).range(16..=4096))]
    gif_width: u32,
    /// Put every k-th frame into the GIF (0: as many as keep it near 60 frames)
    #[arg(long, default_value_t = 0)]
    gif_every: u32,
    /// Supersampling of the PNG frames (1 = off): each pixel the average of s×s samples,
    /// drawn apart from the timed frame (the GIF is shrunk, which filters it enough)
    /// (off, 2x2, 4x4; or 1, 2, 4)
    #[arg(long, visible_alias = "supersample", value_name = "off|2x2|4x4", value_parser = sightline::args::parse_aa, default_value = "2x2")]
    aa: Antialias,
    /// Worker threads (default: all cores)
    #[arg(short = 'j', long, value_parser = clap::value_parser!(u16).range(1..=256))]
    threads: Option<u16>,
}

fn main() {
    let args = Args::parse();
    if let Err(e) = run(&args) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// One frame's row of `frames.csv`.
struct Row {
    frame: usize,
    info: FrameInfo,
    eye: glam::Vec3,
}

fn run(a: &Args) -> Result<()> {
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create output folder {}", a.out.display()))?;
    let probe = a.out.join(".walkthrough-write-check");
    std::fs::write(&probe, b"").with_context(|| format!("cannot write into output folder {}", a.out.display()))?;
    let _ = std::fs::remove_file(&probe);

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.map_or(0, usize::from))
        .build()
        .context("starting the thread pool")?;
    eprintln!("loading {} ...", engine::describe(&a.scene));
    let mut engine = Engine::load(&a.scene, &a.allow_asset_roots)?;
    let (w, h) = a.size;
    let aspect = w as f32 / h as f32;
    let path = engine.walk_path(a.frames as usize, aspect)?;
    if path.is_empty() {
        bail!("the scene's camera path has no frames");
    }
    let gif_every = match a.gif_every {
        0 => gif_out::every_for(path.len()),
        k => k as usize,
    };
    // 30 frames a second along the path, whatever the GIF keeps of them.
    let delay = gif_out::delay_for(gif_every);
    let gif_path = a.out.join("walk.gif");
    let mut gif = gif_out::GifOut::create(&gif_path, w, h, a.gif_width, delay)?;
    let rows = pool.install(|| walk(a, &mut engine, &path, &mut gif, gif_every))?;
    let csv = a.out.join("frames.csv");
    write_csv(&csv, a.method, &rows)?;
    let gif_frames = gif.frames;
    drop(gif); // writes the GIF's trailer
    summary(a, &engine, &rows, (&gif_path, gif_frames), &csv)
}

fn walk(
    a: &Args,
    engine: &mut Engine,
    path: &[engine::Pose],
    gif: &mut gif_out::GifOut,
    gif_every: usize,
) -> Result<Vec<Row>> {
    let (w, h) = a.size;
    let mut fb = Framebuffer::new(w, h)?;
    let bar = indicatif::ProgressBar::new(path.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames {msg} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut rows = Vec::with_capacity(path.len());
    let animate = a.animate || matches!(a.scene, SceneSpec::CityTraffic(_));
    for (f, pose) in path.iter().enumerate() {
        if animate {
            engine.animate(f as f32 / 30.0).with_context(|| format!("posing frame {f}"))?;
        }
        let camera = engine.camera(pose, w as f32 / h as f32).with_context(|| format!("frame {f} of the path"))?;
        let info = engine.render(&camera, a.method, &mut fb).with_context(|| format!("frame {f}"))?;
        if a.png_every > 0 && f % a.png_every as usize == 0 {
            let p = a.out.join(format!("frame_{f:04}.png"));
            let sharp = match a.aa {
                Antialias::Off => None,
                aa => Some(engine.picture(&camera, a.method, w, h, aa.factor()).with_context(|| format!("frame {f}"))?),
            };
            let color = sharp.as_ref().map_or(&fb.color, |s| &s.color);
            image::save_buffer(&p, color.as_flattened(), w, h, image::ExtendedColorType::Rgba8)
                .with_context(|| format!("writing {}", p.display()))?;
        }
        if f % gif_every == 0 {
            let lines = readout(a.method, f, path.len(), &info, engine.triangles());
            gif.push(&fb.color, w, h, |px, gw, gh| {
                sightline::hud::draw(px, gw, gh, &lines, 1);
            })?;
        }
        bar.set_message(format!("{:.1} ms", info.ms));
        bar.inc(1);
        rows.push(Row { frame: f, info, eye: pose.eye });
    }
    bar.finish_and_clear();
    Ok(rows)
}

fn readout(method: Method, f: usize, n: usize, i: &FrameInfo, triangles: u64) -> Vec<String> {
    let mut lines = vec![format!("{}  frame {}/{}  {:.1} ms", method.name(), f + 1, n, i.ms)];
    match i.triangles_drawn {
        Some(t) => lines.push(format!("drawn {t} tris, culled {}", triangles.saturating_sub(t))),
        None => lines.push(format!("ray cast, {triangles} tris")),
    }
    lines
}

fn write_csv(p: &Path, method: Method, rows: &[Row]) -> Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?);
    writeln!(
        f,
        "frame,method,ms,triangles_drawn,clusters_drawn,clusters,culled_by_frustum,culled_by_backface,culled_by_occlusion,eye_x,eye_y,eye_z,ms_cull,ms_draw,ms_shading"
    )?;
    for r in rows {
        let i = &r.info;
        let opt = |v: Option<u64>| v.map_or(String::new(), |v| v.to_string());
        let (drawn, all) = (i.clusters.map(|c| c.0), i.clusters.map(|c| c.1));
        let culled = |v: u64| if i.clusters.is_some() { v.to_string() } else { String::new() };
        let stage = |k: usize| i.stages.map_or(String::new(), |s| format!("{:.3}", s[k]));
        writeln!(
            f,
            "{},{},{:.3},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.frame,
            method.name(),
            i.ms,
            opt(i.triangles_drawn),
            opt(drawn),
            opt(all),
            culled(i.culled.0),
            culled(i.culled.1),
            culled(i.culled.2),
            r.eye.x,
            r.eye.y,
            r.eye.z,
            stage(0),
            stage(1),
            stage(2)
        )?;
    }
    f.flush().with_context(|| format!("writing {}", p.display()))
}

fn summary(a: &Args, engine: &Engine, rows: &[Row], (gif, gif_frames): (&Path, usize), csv: &Path) -> Result<()> {
    let mut ms: Vec<f64> = rows.iter().map(|r| r.info.ms).collect();
    ms.sort_by(f64::total_cmp);
    let pick = |p: f64| ms[((ms.len() - 1) as f64 * p).round() as usize];
    println!(
        "{} frames of {} ({} triangles) with {}: median {:.2} ms, p95 {:.2} ms per frame",
        rows.len(),
        engine::describe(&a.scene),
        engine.triangles(),
        a.method.name(),
        pick(0.5),
        pick(0.95)
    );
    let pngs = if a.png_every == 0 { 0 } else { rows.len().div_ceil(a.png_every as usize) };
    if pngs > 0 {
        let last = (rows.len() - 1) / a.png_every as usize * a.png_every as usize;
        println!("  {pngs} PNG frames   {}", a.out.join(format!("frame_0000.png … frame_{last:04}.png")).display());
    }
    let gif_bytes = std::fs::metadata(gif).map(|m| m.len()).unwrap_or(0);
    let (gw, gh) = gif_out::fit(a.size.0, a.size.1, a.gif_width);
    println!(
        "  animated GIF     {} ({gif_frames} frames of {gw}x{gh}, {:.1} MB)",
        gif.display(),
        gif_bytes as f64 / 1e6
    );
    println!("  counters         {}", csv.display());
    Ok(())
}

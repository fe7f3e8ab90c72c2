//! Command-line parsing (clap) and dispatch. Scripts rely on the names of the commands and
//! flags (the README lists them); keep them.

mod bench;
mod chart;
mod common;
mod csg;
mod info;
mod lab;
mod merge;
mod path;
mod pictures;
mod render;
mod report;
mod walk;

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};
use sightline::SceneSpec;

/// Decide what is visible in large 3D scenes and draw it on the CPU.
#[derive(Debug, Parser)]
#[command(name = "sightline", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The scene option shared by every command.
#[derive(Debug, Clone, clap::Args)]
pub struct SceneArg {
    /// Scene: a .gltf/.glb/.obj file, `city` (default, ≥ 10^6 triangles), `city:TRIS` (10^3 to 10^9),
    /// `city+traffic:N` (the city with N vehicles and tower cranes, animated: frame f is time
    /// f/30 s), or `boxfield`
    #[arg(short, long, default_value = "city", value_name = "SCENE")]
    pub scene: SceneSpec,
    /// Let a scene file read buffers, images and material libraries under DIR too (by default
    /// only files inside the scene file's own folder are read); repeatable
    #[arg(long = "allow-asset-root", value_name = "DIR")]
    pub allow_asset_roots: Vec<PathBuf>,
}

/// A scene and the camera path through it, shared by `walk` and `bench`.
#[derive(Debug, Clone, clap::Args)]
pub struct PathArgs {
    #[command(flatten)]
    pub scene: SceneArg,
    /// Camera path JSON (default: the scene's street path)
    #[arg(short, long, value_name = "FILE")]
    pub path: Option<std::path::PathBuf>,
    /// Frames to render, at most 1,000,000 (default: the whole path; 120 for the built-in path)
    #[arg(short = 'n', long, value_parser = common::frames_arg)]
    pub frames: Option<usize>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print scene statistics
    Info {
        #[command(flatten)]
        scene: SceneArg,
        /// Write the statistics as one JSON object to FILE instead of a table (no FILE or
        /// `-`: to standard output)
        #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
        json: Option<PathBuf>,
    },
    /// Write the flattened world-space scene as one OBJ (triangle order = triangle IDs)
    ExportObj {
        #[command(flatten)]
        scene: SceneArg,
        /// Output OBJ file
        #[arg(short, long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a camera path as JSON
    Path {
        #[command(flatten)]
        scene: SceneArg,
        /// Street walk at eye height, a flight above the roofs, an orbit around the scene, or a
        /// flight through it
        #[arg(long, value_enum, default_value = "street")]
        kind: path::PathKind,
        /// Number of frames, at most 1,000,000
        #[arg(short = 'n', long, default_value_t = 120, value_parser = common::frames_arg)]
        frames: usize,
        /// Output JSON file
        #[arg(short, long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Render one frame to PNGs (color, depth, IDs, depth complexity), .npy and JSON
    Render(Box<render::RenderArgs>),
    /// Render a camera path with a progress bar; per-method timing, culling counters, verification
    Walk(Box<walk::WalkArgs>),
    /// Every method over a path, verified, as a Markdown table and charts
    Bench(Box<bench::BenchArgs>),
    /// Join the --out folders of the shards of a walk (`walk --frame-range A..B`) into the
    /// report one run would have written
    Merge(Box<merge::MergeArgs>),
    /// Every visibility method on one view (z-buffer, HZB, ray casting, Warnock, …): a labelled
    /// contact sheet, difference images against the z-buffer, a Markdown table and JSON; or,
    /// with --scaling, time against triangle count for every method
    Lab(Box<lab::LabArgs>),
    /// Render the built-in CSG demo (box ∩ sphere − three cylinders) by ray casting, to PNG
    Csg {
        /// Output PNG file
        #[arg(short, long, value_name = "FILE.png", default_value = "csg.png")]
        out: PathBuf,
        /// Image size
        #[arg(long, default_value = "1024x768")]
        size: common::Size,
    },
}

/// The pictures of `--out` are drawn at `size` times the `--aa` factor: a usage error when
/// that is over the largest framebuffer.
fn too_large_to_supersample(size: common::Size, look: &common::Look) -> Option<String> {
    let k = look.aa.factor();
    let side = size.width.max(size.height) as u64 * k as u64;
    (side > sightline::render::MAX_SIZE as u64).then(|| {
        format!(
            "--size {size} with --aa {k}x{k} draws the --out pictures {k} times larger, over the {} pixels a side allows: give a smaller --size or a lower --aa",
            sightline::render::MAX_SIZE
        )
    })
}

impl Cli {
    /// Options that parse but cannot mean anything together: a usage error (exit 2) before
    /// any work, instead of being ignored.
    pub fn usage_error(&self) -> Option<String> {
        match &self.command {
            Command::Render(a) if a.shadows && a.method == render::FrameMethod::Raster => {
                Some("--shadows needs --method raycast: the rasterizer draws no shadows".into())
            }
            Command::Render(a)
                if a.projection != render::ProjectionArg::Perspective
                    && (a.camera.given() || a.camera.near.is_some() || a.camera.far.is_some()) =>
            {
                Some(format!(
                    "--projection {:?} frames the whole scene itself: --eye, --path, --fov, --near, --far and --camera go with --projection perspective",
                    a.projection
                ).to_lowercase())
            }
            Command::Render(a)
                if a.projection == render::ProjectionArg::Multiview && (a.size.width < 2 || a.size.height < 2) =>
            {
                Some(format!("--size {}: multiview draws four views in a 2×2 grid and needs at least 2x2", a.size))
            }
            Command::Render(a) if a.out.is_some() => {
                // Multiview draws each of its four pictures at a quarter of the image.
                let quarter = a.projection == render::ProjectionArg::Multiview;
                let size = if quarter { common::Size { width: a.size.width / 2, height: a.size.height / 2 } } else { a.size };
                too_large_to_supersample(size, &a.look)
            }
            // Only the PNG frames of a walk are drawn supersampled.
            Command::Walk(a) if a.out.is_some() && a.png_every != Some(0) => too_large_to_supersample(a.size, &a.look),
            Command::Csg { out, .. } if !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) => {
                Some(format!("--out {}: csg writes a PNG image; give a .png file", out.display()))
            }
            _ => None,
        }
    }
}

/// Runs one command.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { scene, json } => info::run(&scene, json.as_deref()),
        Command::ExportObj { scene, out } => path::export_obj(&scene, &out),
        Command::Path { scene, kind, frames, out } => path::run(&scene, kind, frames, &out),
        Command::Render(a) => render::run(&a),
        Command::Walk(a) => walk::run(&a),
        Command::Bench(a) => bench::run(&a),
        Command::Merge(a) => merge::run(&a),
        Command::Lab(a) => lab::run(&a),
        Command::Csg { out, size } => {
            csg::write_classic_demo_png(&out, size.width, size.height)?;
            println!("wrote {}", out.display());
            Ok(())
        }
    }
}

/// Loads a scene with a spinner on the terminal; each loader warning (a skipped primitive,
/// a missing texture, …) is printed as one line on standard error.
pub fn load_scene(arg: &SceneArg) -> Result<sightline::LoadedScene> {
    let spec = &arg.scene;
    let options = sightline::scene::LoadOptions { allowed_roots: arg.allow_asset_roots.clone(), ..Default::default() };
    let bar = indicatif::ProgressBar::new_spinner().with_message(format!("loading {}", describe(spec)));
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    let s = spec.load_with(&options);
    bar.finish_and_clear();
    match s {
        Err(sightline::scene::Error::Load { path, why }) if why.contains("outside the asset folder") => {
            anyhow::bail!("{}: {why} (--allow-asset-root DIR allows another folder)", path.display())
        }
        s => {
            let s = s?;
            for w in &s.scene.warnings {
                eprintln!("warning: {w}");
            }
            Ok(s)
        }
    }
}

/// Runs `work` under a spinner naming it on the terminal (BVH builds over 10^6 primitives take
/// a second or two).
pub fn with_spinner<T>(what: &str, work: impl FnOnce() -> T) -> T {
    let bar = indicatif::ProgressBar::new_spinner().with_message(what.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    let out = work();
    bar.finish_and_clear();
    out
}

fn describe(spec: &SceneSpec) -> String {
    match spec {
        SceneSpec::City(n) => format!("city ({n} triangles)"),
        SceneSpec::CityTraffic(n) => format!("city with {n} vehicles"),
        SceneSpec::Boxfield => "boxfield".into(),
        SceneSpec::File(p) => p.display().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roots(args: &[&str]) -> Vec<PathBuf> {
        let cli = Cli::try_parse_from(args).unwrap();
        match cli.command {
            Command::Info { scene, .. } | Command::ExportObj { scene, .. } | Command::Path { scene, .. } => {
                scene.allow_asset_roots
            }
            Command::Render(a) => a.scene.allow_asset_roots,
            Command::Walk(a) => a.walk.scene.allow_asset_roots,
            Command::Bench(a) => a.walk.scene.allow_asset_roots,
            Command::Lab(a) => a.scene.allow_asset_roots,
            Command::Csg { .. } | Command::Merge(_) => unreachable!(),
        }
    }

    #[test]
    fn every_scene_command_takes_repeatable_asset_roots() {
        assert!(roots(&["sightline", "info", "--scene", "a.gltf"]).is_empty());
        let two = [PathBuf::from("x"), PathBuf::from("y")];
        for cmd in [
            &["info"][..],
            &["export-obj", "--out", "o.obj"],
            &["path", "--out", "p.json"],
            &["render"],
            &["walk"],
            &["bench"],
            &["lab", "--out", "lab"],
        ] {
            let mut args = vec!["sightline"];
            args.extend_from_slice(cmd);
            args.extend(["--scene", "a.gltf", "--allow-asset-root", "x", "--allow-asset-root", "y"]);
            assert_eq!(roots(&args), two, "{cmd:?}");
        }
    }
}

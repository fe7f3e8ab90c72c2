//! `sightline render`: one frame, by rasterization or ray casting, to PNGs, .npy and JSON.

use std::path::PathBuf;

use anyhow::{Context, Result};
use glam::Vec3;
use sightline::render::{output, Framebuffer, RayCaster, RaycastOptions, Renderer};

use super::common::{self, CameraChoice, Look, OnOff, Size};

/// Visibility method of a single frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameMethod {
    /// Object order: clip, rasterize, z-buffer
    Raster,
    /// Image order: one ray per pixel through the BVHs
    Raycast,
}

#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: super::SceneArg,
    /// Camera path JSON (see `sightline path`); with --frame
    #[arg(short, long, value_name = "FILE", conflicts_with_all = ["eye", "target"])]
    pub path: Option<PathBuf>,
    /// Frame of the path to render
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Eye position x,y,z (with --target)
    #[arg(long, value_parser = common::parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point looked at x,y,z (with --eye)
    #[arg(long, value_parser = common::parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Up direction x,y,z (with --eye; default 0,1,0)
    #[arg(long, value_parser = common::parse_vec3, allow_hyphen_values = true, requires = "eye")]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees (with --eye; default 60)
    #[arg(long, requires = "eye")]
    pub fov: Option<f32>,
    /// Near plane distance (default: the path's, or 0.1)
    #[arg(long)]
    pub near: Option<f32>,
    /// Far plane distance (default: the path's, or beyond the scene)
    #[arg(long)]
    pub far: Option<f32>,
    /// Image size
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Animation time in seconds: the scene's animations (glTF animations, the traffic and
    /// cranes of `city+traffic:N`) are posed at this time before the frame is drawn
    #[arg(long, value_name = "SECONDS", value_parser = common::time_arg)]
    pub time: Option<f32>,
    /// Visibility method
    #[arg(short, long, value_enum, default_value = "raster")]
    pub method: FrameMethod,
    /// Drop triangles facing away from the camera
    #[arg(long, value_enum, default_value = "on")]
    pub backface_culling: OnOff,
    /// Hard shadows from the light (ray casting only)
    #[arg(long)]
    pub shadows: bool,
    /// Worker threads, 1 to 256 (default: all cores)
    #[arg(short = 'j', long, value_parser = super::common::threads_arg)]
    pub threads: Option<usize>,
    /// Output folder for color.png, depth.png, ids.png, complexity.png
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Raw triangle-ID buffer as .npy (uint32, H×W, row 0 = top, 0 = background)
    #[arg(long, value_name = "FILE.npy")]
    pub id_out: Option<PathBuf>,
    /// Window depth as .npy (float32, H×W)
    #[arg(long, value_name = "FILE.npy")]
    pub depth_out: Option<PathBuf>,
    /// Counters as JSON into FILE (`-`: standard output)
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    #[command(flatten)]
    pub look: Look,
}

pub fn run(a: &RenderArgs) -> Result<()> {
    let files: Vec<&std::path::Path> =
        [&a.id_out, &a.depth_out, &a.json].into_iter().flatten().map(|p| p.as_path()).collect();
    common::check_outputs(a.out.as_deref().as_slice(), &files)?;
    let mut loaded = super::load_scene(&a.scene)?;
    if let Some(t) = a.time {
        common::pose(&mut loaded.scene, t)?;
    }
    let choice = CameraChoice {
        eye: a.eye,
        target: a.target,
        up: a.up.unwrap_or(Vec3::Y),
        fov: a.fov.unwrap_or(60.0),
        near: a.near,
        far: a.far,
        path: a.path.as_ref(),
        frame: a.frame,
    };
    let camera = choice.camera(&loaded, a.size)?;
    let opts = a.look.options(a.backface_culling);
    let mut fb = Framebuffer::new(a.size.width, a.size.height)?;
    fb.count_depth_tests(a.out.is_some() && a.method == FrameMethod::Raster);
    let counters = common::with_threads(a.threads, || -> Result<serde_json::Value> {
        match a.method {
            FrameMethod::Raster => {
                let instances = loaded.scene.instances();
                let items = sightline::render::draw_all(&instances);
                let stats = Renderer::new().render(&loaded.scene, &instances, &items, &camera, &mut fb, &opts)?;
                print_raster(&stats);
                Ok(serde_json::to_value(stats)?)
            }
            FrameMethod::Raycast => {
                let caster = super::with_spinner("building BVHs", || RayCaster::build(&loaded.scene))?;
                let mut ro = RaycastOptions::from_render(&opts);
                ro.shadows = a.shadows;
                let st = caster.render(&loaded.scene, &camera, &mut fb, &ro)?;
                println!("BVH build        {:>10.1} ms", caster.build_ms());
                println!("primary rays     {:>10}", st.primary_rays);
                println!("shadow rays      {:>10}", st.shadow_rays);
                println!("hits             {:>10}", st.hits);
                println!("frame            {:>10.2} ms", st.ms_total);
                println!("Mrays/s          {:>10.2}", st.primary_rays as f64 / st.ms_total / 1e3);
                Ok(serde_json::json!({
                    "build_ms": caster.build_ms(), "primary_rays": st.primary_rays, "shadow_rays": st.shadow_rays,
                    "hits": st.hits, "ms_total": st.ms_total,
                }))
            }
        }
    })??;
    write_outputs(&fb, a, &counters)
}

fn print_raster(s: &sightline::render::FrameStats) {
    println!("triangles in        {:>10}", s.triangles_in);
    println!("trivially rejected  {:>10}", s.trivially_rejected);
    println!("clipped             {:>10} (-> {} triangles)", s.clipped, s.clip_output);
    println!("back-face culled    {:>10}", s.backface_culled);
    println!("degenerate          {:>10}", s.degenerate);
    println!("too small           {:>10}", s.too_small);
    println!("rasterized          {:>10}", s.rasterized);
    println!("fragments tested    {:>10}", s.fragments_tested);
    println!("fragments written   {:>10}", s.fragments_written);
    println!("covered pixels      {:>10}", s.covered_pixels);
    println!("overdraw            {:>10.2}", s.overdraw);
    println!(
        "ms: geometry {:.2}, binning {:.2}, raster {:.2}, shading {:.2}, total {:.2}",
        s.ms_geometry, s.ms_binning, s.ms_raster, s.ms_shading, s.ms_total
    );
}

fn write_outputs(fb: &Framebuffer, a: &RenderArgs, counters: &serde_json::Value) -> Result<()> {
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        output::write_color_png(fb, &dir.join("color.png"))?;
        output::write_depth_png(fb, &dir.join("depth.png"))?;
        output::write_id_png(fb, &dir.join("ids.png"))?;
        if fb.depth_tests.is_some() {
            output::write_heatmap_png(fb, &dir.join("complexity.png"))?;
        }
        println!("pictures in {}", dir.display());
    }
    if let Some(p) = &a.id_out {
        output::write_ids_npy(fb, p)?;
    }
    if let Some(p) = &a.depth_out {
        output::write_depth_npy(fb, p)?;
    }
    if let Some(p) = &a.json {
        common::write_json(p, counters, true)?;
    }
    Ok(())
}

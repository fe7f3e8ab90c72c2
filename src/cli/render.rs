//! `sightline render`: one frame, by rasterization or ray casting, to PNGs, .npy and JSON.

use std::path::PathBuf;

use anyhow::{Context, Result};
use glam::Vec3;
use sightline::render::{output, Framebuffer, RayCaster, RaycastOptions, Renderer};

use super::common::{self, Look, OnOff, Size};
use super::pictures::{self, Painter};

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
    #[command(flatten)]
    pub camera: common::CameraArgs,
    /// Image size
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Projection. Without --eye or --path every projection frames the whole scene:
    /// perspective from a three-quarter view, orthographic along that direction, cavalier and
    /// cabinet from the front, the axonometric presets, and multiview (top, front, side and
    /// perspective in a 2×2 grid). Only perspective takes --eye or --path
    #[arg(long, value_enum, default_value = "perspective")]
    pub projection: ProjectionArg,
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
    /// Output folder for color.png (supersampled as --aa says), depth.png, ids.png, and
    /// complexity.png (depth tests per pixel; rasterizer only)
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

/// `render --projection`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ProjectionArg {
    Perspective,
    Orthographic,
    Cavalier,
    Cabinet,
    Isometric,
    Dimetric,
    Trimetric,
    Multiview,
}

/// The cameras of a parallel `--projection` framing `bounds` (four for multiview, each for
/// a quarter of the image).
fn parallel_cameras(
    p: ProjectionArg,
    bounds: &sightline::scene::Aabb,
    aspect: f32,
) -> Result<Vec<sightline::scene::Camera>> {
    use sightline::scene::views::{self, Axonometric, Multiview};
    let axo = |kind: Axonometric| kind.camera(bounds, aspect);
    let cams = match p {
        ProjectionArg::Perspective => Vec::new(),
        ProjectionArg::Orthographic => {
            vec![views::parallel_camera(bounds, views::three_quarter_direction(), Vec3::Y, aspect)?]
        }
        ProjectionArg::Cavalier => vec![views::oblique_camera(bounds, 1.0, aspect)?],
        ProjectionArg::Cabinet => vec![views::oblique_camera(bounds, 0.5, aspect)?],
        ProjectionArg::Isometric => vec![axo(Axonometric::Isometric)?],
        ProjectionArg::Dimetric => vec![axo(Axonometric::Dimetric { fy: 0.5 })?],
        ProjectionArg::Trimetric => {
            vec![axo(Axonometric::Trimetric { fx: 0.9, fy: 0.8, fz: (2.0f32 - 0.81 - 0.64).sqrt() })?]
        }
        ProjectionArg::Multiview => {
            let m = Multiview::new(bounds, aspect)?;
            vec![m.top, m.perspective, m.front, m.side]
        }
    };
    Ok(cams)
}

/// Copies `part` into quadrant `q` (0 top left, 1 top right, 2 bottom left, 3 bottom right)
/// of `fb`, whose sides are at least twice `part`'s.
fn blit_quadrant(part: &Framebuffer, q: usize, fb: &mut Framebuffer) {
    let (pw, ph, w) = (part.width() as usize, part.height() as usize, fb.width() as usize);
    let (x0, y0) = ((q % 2) * pw, (q / 2) * ph);
    for y in 0..ph {
        let (src, dst) = (y * pw..(y + 1) * pw, (y0 + y) * w + x0..(y0 + y) * w + x0 + pw);
        fb.color[dst.clone()].copy_from_slice(&part.color[src.clone()]);
        fb.depth[dst.clone()].copy_from_slice(&part.depth[src.clone()]);
        fb.ids[dst.clone()].copy_from_slice(&part.ids[src.clone()]);
        if let (Some(d), Some(s)) = (&mut fb.depth_tests, &part.depth_tests) {
            d[dst].copy_from_slice(&s[src]);
        }
    }
}

pub fn run(a: &RenderArgs) -> Result<()> {
    let files: Vec<&std::path::Path> =
        [&a.id_out, &a.depth_out, &a.json].into_iter().flatten().map(|p| p.as_path()).collect();
    common::check_outputs(a.out.as_deref().as_slice(), &files)?;
    let mut loaded = super::load_scene(&a.scene)?;
    if let Some(t) = a.time {
        common::pose(&mut loaded.scene, t)?;
    }
    let choice = a.camera.choice(super::describe(&a.scene.scene));
    let parallel = parallel_cameras(a.projection, &loaded.scene.world_aabb(), a.size.aspect())
        .context("framing the scene for --projection")?;
    let camera = match parallel.first() {
        Some(&c) if a.projection != ProjectionArg::Multiview => c,
        _ => choice.camera(&loaded, a.size)?,
    };
    // IDs, depth and counters come from one sample per pixel (what the references compare);
    // the colour picture, when one is written, is drawn apart, supersampled.
    let opts = a.look.frame_options(a.backface_culling);
    let pic_opts = a.look.options(a.backface_culling);
    let supersample = a.out.is_some() && pic_opts.antialias.factor() > 1;
    let mut fb = Framebuffer::new(a.size.width, a.size.height)?;
    let counting = a.out.is_some() && a.method == FrameMethod::Raster;
    let caster = (a.method == FrameMethod::Raycast)
        .then(|| {
            super::with_spinner("building BVHs", || common::with_threads(a.threads, || RayCaster::build(&loaded.scene)))
        })
        .transpose()?
        .transpose()?;
    let mut ro = RaycastOptions::from_render(&opts);
    ro.shadows = a.shadows;
    let picture = |cam: &sightline::scene::Camera, size: (u32, u32)| -> Result<sightline::render::Plane<[u8; 4]>> {
        let painter = caster.as_ref().map_or(Painter::Plain, |c| Painter::Rays(c, &ro));
        common::with_threads(a.threads, || pictures::picture(&loaded.scene, painter, cam, &pic_opts, size))?
    };
    fb.count_depth_tests(counting);
    if a.projection == ProjectionArg::Multiview {
        // Four views, each framed for a quarter of the image.
        let (qw, qh) = ((a.size.width / 2).max(1), (a.size.height / 2).max(1));
        let cams = parallel_cameras(a.projection, &loaded.scene.world_aabb(), qw as f32 / qh as f32)?;
        fb.clear(opts.background);
        let mut part = Framebuffer::new(qw, qh)?;
        part.count_depth_tests(counting);
        let mut views = Vec::new();
        for (q, cam) in cams.iter().enumerate() {
            let v =
                common::with_threads(a.threads, || draw(&loaded.scene, caster.as_ref(), cam, &mut part, &ro, &opts))??;
            if supersample {
                part.color = picture(cam, (qw, qh))?;
            }
            blit_quadrant(&part, q, &mut fb);
            views.push(v);
        }
        return write_outputs(&fb, a, &serde_json::json!({ "views": views }));
    }
    let counters =
        common::with_threads(a.threads, || draw(&loaded.scene, caster.as_ref(), &camera, &mut fb, &ro, &opts))??;
    if supersample {
        fb.color = picture(&camera, (a.size.width, a.size.height))?;
    }
    write_outputs(&fb, a, &counters)
}

/// One frame of `scene`: rasterized, or ray cast with `caster` (built once per run, even
/// for the four views of multiview); its counters as JSON.
fn draw(
    scene: &sightline::scene::Scene,
    caster: Option<&RayCaster>,
    camera: &sightline::scene::Camera,
    fb: &mut Framebuffer,
    ro: &RaycastOptions,
    opts: &sightline::render::RenderOptions,
) -> Result<serde_json::Value> {
    let Some(caster) = caster else {
        let instances = scene.instances();
        let items = sightline::render::draw_all(&instances);
        let stats = Renderer::new().render(scene, &instances, &items, camera, fb, opts)?;
        print_raster(&stats);
        return Ok(serde_json::to_value(stats)?);
    };
    let st = caster.render(scene, camera, fb, ro)?;
    println!("BVH build        {:>10.1} ms", caster.build_ms());
    println!("paired into quads{:>10} of {} triangles", caster.paired_triangles(), caster.stored_triangles());
    println!("primary rays     {:>10}", st.primary_rays);
    println!("shadow rays      {:>10}", st.shadow_rays);
    println!("hits             {:>10}", st.hits);
    println!("frame            {:>10.2} ms", st.ms_total);
    println!("Mrays/s          {:>10.2}", st.primary_rays as f64 / st.ms_total / 1e3);
    Ok(serde_json::json!({
        "build_ms": caster.build_ms(), "stored_triangles": caster.stored_triangles(),
        "paired_triangles": caster.paired_triangles(), "primary_rays": st.primary_rays, "shadow_rays": st.shadow_rays,
        "hits": st.hits, "ms_total": st.ms_total,
    }))
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
    if let Some(t) = &s.transparency {
        println!(
            "masked triangles    {:>10} ({} fragments kept, {} discarded)",
            t.masked_triangles, t.masked_fragments_kept, t.masked_fragments_discarded
        );
        println!("blended triangles   {:>10} ({:?})", t.blended_triangles, t.method);
        println!(
            "blended fragments   {:>10} (max {} and mean {:.2} per pixel over {} pixels; {} drawn)",
            t.fragments, t.max_fragments_per_pixel, t.mean_fragments_per_pixel, t.pixels, t.fragments_drawn
        );
    }
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

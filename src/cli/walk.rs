//! `sightline walk`: render a camera path with one or all visibility methods, verify against
//! brute force, summarize per method (median / p95 ms, triangles drawn, culled shares).
//!
//! `--frame-range A..B` renders a shard of the path: frames A to B−1, numbered as in the
//! whole path (animation time, PNG names and records keep the path's frame numbers). A shard
//! first renders frame A−1 with every method, untimed and unrecorded, so that the state a
//! method carries from frame to frame (the `hzb` method's last visible set) and the caches
//! are warm as they are in one run; `sightline merge` then joins the shards.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use sightline::render::{
    compare_ids, CullStats, Culler, Framebuffer, Method, RaycastOptions, RenderOptions, Renderer, Visibility, World,
};
use sightline::scene::Scene;

use super::common::{self, Look, OnOff, Size};
use super::pictures::{self, Painter, Pictures};
use super::report::{self, FrameRecord, RunInfo, WalkReport};

/// Methods `walk` can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum WalkMethod {
    /// Every triangle through the pipeline
    Brute,
    /// View-frustum culling of instances and clusters (BVH)
    Frustum,
    /// Frustum culling plus occlusion culling with a z-pyramid: last frame's visible clusters first, then a front-to-back walk over the rest
    Hzb,
    /// Greene's octree walk with z-pyramid tests on octants
    OctreeHzb,
    /// The hzb walk in one pass, front to back, without using the last frame
    HzbOnePass,
    /// Ray casting through the two-level BVH
    Raycast,
    /// All of the above, interleaved frame by frame
    All,
}

#[derive(Debug, clap::Args)]
pub struct WalkArgs {
    #[command(flatten)]
    pub walk: super::PathArgs,
    /// Visibility method
    #[arg(short, long, value_enum, default_value = "hzb")]
    pub method: WalkMethod,
    /// Also render every frame with brute force and compare triangle IDs; a mismatch fails the run
    #[arg(long)]
    pub verify: bool,
    /// Play the scene's animations along the walk: frame f shows time f / 30 s (always on
    /// for `city+traffic:N`)
    #[arg(long)]
    pub animate: bool,
    /// With --verify: the least share of pixels (percent) on which ray casting must give the
    /// rasterizer's triangle ID on every frame; a frame below it fails the run
    #[arg(long, value_name = "PERCENT", default_value_t = 99.5, value_parser = common::percent_arg)]
    pub min_agreement: f64,
    /// Image size
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Drop triangles facing away from the camera
    #[arg(long, value_enum, default_value = "on")]
    pub backface_culling: OnOff,
    /// Worker threads, 1 to 256 (default: all cores)
    #[arg(short = 'j', long, value_parser = super::common::threads_arg)]
    pub threads: Option<usize>,
    /// Output folder: per-frame counters (frames.csv, frames.json), the summary (walk.json),
    /// a few PNG frames, the walk as a GIF (walk.gif) and the frame-time chart
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Render frames A to B-1 of the path only (a shard: `sightline merge` joins the
    /// shards' --out folders into the report of one run); frames keep the path's numbers
    #[arg(long, value_name = "A..B", value_parser = frame_range_arg)]
    pub frame_range: Option<std::ops::Range<usize>>,
    /// Write every k-th frame of the path as PNG into --out (0: none; default: about four)
    #[arg(long, requires = "out")]
    pub png_every: Option<usize>,
    /// Put every k-th frame of the path into --out's walk.gif (0: no GIF; default: about 60
    /// frames)
    #[arg(long, requires = "out")]
    pub gif_every: Option<usize>,
    /// Summary as JSON into FILE (`-`: standard output)
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Occlusion culling: clusters in the first front-to-back batch (later batches double)
    #[arg(long, default_value_t = Culler::DEFAULT_FIRST_BATCH)]
    pub first_batch: usize,
    #[command(flatten)]
    pub look: Look,
}

/// Parses `--frame-range A..B`: whole numbers, A < B ≤ the most frames a command renders.
fn frame_range_arg(s: &str) -> std::result::Result<std::ops::Range<usize>, String> {
    let bad = || format!("'{s}' is not a frame range A..B (frames A to B-1 of the path, A < B, e.g. 0..60)");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let a = common::frame_number_arg(a).map_err(|_| bad())?;
    let b = common::frame_number_arg(b).map_err(|_| bad())?;
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

/// The methods a walk runs on each frame, in order.
fn methods(m: WalkMethod) -> Vec<Visibility> {
    match m {
        WalkMethod::Brute => vec![Method::Brute.into()],
        WalkMethod::Frustum => vec![Method::Frustum.into()],
        WalkMethod::Hzb => vec![Method::Hzb.into()],
        WalkMethod::OctreeHzb => vec![Method::OctreeHzb.into()],
        WalkMethod::HzbOnePass => vec![Method::HzbOnePass.into()],
        WalkMethod::Raycast => vec![Visibility::RayCast],
        WalkMethod::All => Visibility::all(),
    }
}

pub fn run(a: &WalkArgs) -> Result<()> {
    common::check_outputs(a.out.as_deref().as_slice(), a.json.as_deref().as_slice())?;
    let loaded = super::load_scene(&a.walk.scene)?;
    let keys = common::path_keys(&loaded, a.walk.path.as_deref(), a.walk.frames)?;
    let range = a.frame_range.clone().unwrap_or(0..keys.len());
    if range.end > keys.len() {
        bail!("--frame-range {}..{}, but the path has {} frames", range.start, range.end, keys.len());
    }
    let run = RunInfo {
        scene: format!("{:?}", a.walk.scene.scene),
        size: [a.size.width, a.size.height],
        method_set: methods(a.method).iter().map(|m| m.name().to_string()).collect(),
        verify: a.verify,
        animate: a.animate || matches!(a.walk.scene.scene, sightline::SceneSpec::CityTraffic(_)),
        backface_culling: a.backface_culling.on(),
        path_frames: keys.len(),
        png_every: a.out.as_ref().map_or(0, |_| a.png_every.unwrap_or(pictures::default_png_every(keys.len()))),
        gif_every: a.out.as_ref().map_or(0, |_| a.gif_every.unwrap_or(sightline::gif_out::every_for(keys.len()))),
    };
    let mut pics = match &a.out {
        Some(dir) => {
            let size = (a.size.width, a.size.height);
            Some(Pictures::new(dir, size, keys.len(), run.png_every, run.gif_every)?)
        }
        None => None,
    };
    // Timed frames take one sample per pixel; the PNG frames are drawn apart, supersampled.
    let opts = a.look.frame_options(a.backface_culling);
    let pic_opts = a.look.options(a.backface_culling);
    let scene = loaded.scene;
    let records = common::with_threads(a.threads, || {
        walk(scene, &keys, range.clone(), a, &run, (&opts, &pic_opts), pics.as_mut())
    })??;
    let gif_frames = pics.and_then(Pictures::finish);
    let report = WalkReport {
        methods: report::summarize(&records, &run.method_set),
        scene_update: report::summarize_updates(&records),
        run,
        frame_range: [range.start, range.end],
        missing_frames: Vec::new(),
    };
    finish(&report, &records, a.out.as_deref(), a.json.as_deref(), gif_frames, a.min_agreement)
}

/// The end of a walk or a merge: the table, the report files, the JSON summary, where they
/// went; then the verdict (frames that differ from brute force, too little ray-casting
/// agreement) as the error that fails the run.
pub fn finish(
    report: &WalkReport,
    records: &[FrameRecord],
    out: Option<&std::path::Path>,
    json: Option<&std::path::Path>,
    gif_frames: Option<usize>,
    min_agreement: f64,
) -> Result<()> {
    report::print_summary(report, json)?;
    if let Some(dir) = out {
        report::write_report(dir, report, records)?;
    }
    if let Some(p) = json {
        common::write_json(p, &serde_json::to_value(report)?, true)?;
    }
    if let Some(dir) = out {
        report::print_outputs(dir, gif_frames, json)?;
    }
    let bad: usize = report.methods.iter().map(|s| s.mismatched_frames).sum();
    if bad > 0 {
        bail!("{bad} frames differ from brute force");
    }
    if let Some(why) = agreement_shortfall(records, min_agreement) {
        bail!(why);
    }
    Ok(())
}

/// Why the run fails `--min-agreement` (a percentage), if it does: the worst frame, and how
/// many frames fell short. Only frames judged by agreement count (ray casting's); culled
/// frames are verified exactly instead.
fn agreement_shortfall(records: &[FrameRecord], min_percent: f64) -> Option<String> {
    let compared = records.iter().filter(|r| r.verified.is_none() && r.agreement.is_some()).count();
    let short: Vec<&FrameRecord> = records
        .iter()
        .filter(|r| r.verified.is_none() && r.agreement.is_some_and(|x| 100.0 * x < min_percent))
        .collect();
    let worst = short.iter().min_by(|x, y| x.agreement.unwrap_or(0.0).total_cmp(&y.agreement.unwrap_or(0.0)))?;
    Some(format!(
        "{} gave the rasterizer's triangle IDs on only {:.2}% of the pixels of frame {}, below --min-agreement {}% ({} of {} compared frames fell short)",
        worst.method,
        100.0 * worst.agreement.unwrap_or(0.0),
        worst.frame,
        min_percent,
        short.len(),
        compared
    ))
}

#[allow(clippy::too_many_arguments)]
fn walk(
    scene: Scene,
    keys: &[sightline::scene::path::CameraKey],
    range: std::ops::Range<usize>,
    a: &WalkArgs,
    run: &RunInfo,
    (opts, pic_opts): (&RenderOptions, &RenderOptions),
    mut pics: Option<&mut Pictures>,
) -> Result<Vec<FrameRecord>> {
    let mut world = World::new(scene);
    // A shard warms up on the frame before its first (see the module docs).
    let first = range.start.saturating_sub(1);
    if run.animate {
        pose(&mut world, first)?;
    }
    let list = methods(a.method);
    super::with_spinner("building BVHs", || -> Result<()> {
        if list.iter().any(|m| matches!(m, Visibility::Cull(_))) || a.verify {
            world.culler()?.first_batch = a.first_batch.max(1);
        }
        for &m in &list {
            world.prepare(m)?;
        }
        Ok(())
    })?;
    let mut fb = Framebuffer::new(a.size.width, a.size.height)?;
    let mut reference = Framebuffer::new(a.size.width, a.size.height)?;
    let mut picture: Vec<[u8; 4]> = Vec::new();
    // Pictures are drawn larger than the frames: with a renderer of their own.
    let mut picture_renderer = Renderer::new();
    let bar = indicatif::ProgressBar::new((range.len() * list.len()) as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames·methods {msg} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut out = Vec::new();
    for (f, key) in keys.iter().enumerate().take(range.end).skip(first) {
        let recorded = f >= range.start;
        let scene_update_ms = if run.animate {
            let t = Instant::now();
            pose(&mut world, f)?;
            Some(t.elapsed().as_secs_f64() * 1e3)
        } else {
            None
        };
        let cam = key.camera(a.size.aspect()).with_context(|| format!("frame {f} of the path"))?;
        let mut have_reference = false;
        if a.verify {
            // The reference is rendered apart from the timed frames.
            world.render(&cam, Method::Brute, &mut reference, opts)?;
            have_reference = true;
        }
        let frame_start = out.len();
        for (k, &method) in list.iter().enumerate() {
            let t = Instant::now();
            let report = world.render(&cam, method, &mut fb, opts)?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            if !recorded {
                continue;
            }
            // Ray casting has no culling counters; its frame time stands in their total.
            let cs = report.cull.unwrap_or_else(|| CullStats {
                ms_total: report.rays.map_or(0.0, |r| r.ms_total),
                ..Default::default()
            });
            let diff = have_reference.then(|| compare_ids(&reference.ids, &fb.ids, fb.width()));
            let agreement = diff.map(|d| 1.0 - d.map_or(0, |m| m.pixels) as f64 / fb.len() as f64);
            // Culling methods must equal brute force exactly; ray casting is reported as agreement.
            let verified = if method == Visibility::RayCast { None } else { diff };
            if let Some(Some(m)) = &verified {
                bar.println(format!(
                    "frame {f}, {}: {} pixels differ from brute force, first at {:?} (expected ID {}, got {})",
                    method.name(),
                    m.pixels,
                    m.first,
                    m.ids.0,
                    m.ids.1
                ));
            }
            if k == 0 && pics.as_ref().is_some_and(|p| p.wants(f)) {
                picture.clear();
                picture.extend_from_slice(&fb.color);
            }
            out.push(FrameRecord {
                frame: f,
                method: method.name().to_string(),
                ms,
                triangles_drawn: cs.triangles_drawn,
                cull: cs,
                raster: report.raster.unwrap_or_default(),
                verified: verified.map(|m| m.is_none()),
                agreement,
                scene_update_ms,
            });
            bar.inc(1);
        }
        if let Some(p) = pics.as_mut().filter(|p| recorded && p.wants(f)) {
            // The PNG supersampled, by the first method's renderer (untimed).
            let sharp = (p.wants_png(f) && pic_opts.antialias.factor() > 1)
                .then(|| {
                    let size = (a.size.width, a.size.height);
                    match list[0] {
                        Visibility::RayCast => {
                            let (caster, scene) = world.caster_and_scene()?;
                            let rc_opts = RaycastOptions::from_render(opts);
                            pictures::picture(scene, Painter::Rays(caster, &rc_opts), &cam, pic_opts, size)
                        }
                        Visibility::Cull(Method::Brute) => {
                            pictures::picture(world.scene(), Painter::Plain, &cam, pic_opts, size)
                        }
                        Visibility::Cull(_) => {
                            let (culler, scene) = world.culler_and_scene()?;
                            let painter = Painter::Culler(culler, &mut picture_renderer);
                            pictures::picture(scene, painter, &cam, pic_opts, size)
                        }
                    }
                })
                .transpose()?;
            p.add(f, &picture, sharp.as_deref(), &out[frame_start..])?;
        }
        bar.set_message(format!("frame {f}"));
    }
    bar.finish_and_clear();
    Ok(out)
}

/// Poses the world's animations at frame `f` of the walk (time f / 30 s) and brings the
/// culler and the ray caster up to date before any frame is timed: a walk times how each
/// method draws the frame apart from the scene's change, which every method shares (a moved
/// vehicle costs a refit of the culler's and the ray caster's trees, never a BLAS) and
/// which is reported on its own line.
fn pose(world: &mut World, f: usize) -> Result<()> {
    let t = f as f32 / 30.0;
    world.animate(t).with_context(|| format!("playing the animations at {t} s"))?;
    world.update().with_context(|| format!("following the scene's changes at {t} s"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline::render::FrameStats;

    fn record(frame: usize, method: &'static str, agreement: Option<f64>) -> FrameRecord {
        FrameRecord {
            frame,
            method: method.to_string(),
            ms: 1.0,
            triangles_drawn: 0,
            cull: CullStats::default(),
            raster: FrameStats::default(),
            verified: None,
            agreement,
            scene_update_ms: None,
        }
    }

    /// The scene's update counts once per frame, however many methods drew it; a static
    /// walk has none.
    #[test]
    fn the_scene_update_is_summed_up_once_per_frame() {
        let mut rs = Vec::new();
        for (f, ms) in [(0, 1.0), (1, 3.0), (2, 2.0), (3, 10.0)] {
            for m in ["hzb", "raycast"] {
                rs.push(FrameRecord { scene_update_ms: Some(ms), ..record(f, m, None) });
            }
        }
        let u = report::summarize_updates(&rs).expect("an animated walk");
        assert_eq!((u.frames, u.median_ms, u.p95_ms, u.max_ms, u.mean_ms), (4, 3.0, 10.0, 10.0, 4.0));
        assert!(report::summarize_updates(&[record(0, "hzb", None)]).is_none());
    }

    /// Each rasterizing method's summary holds the medians of its cull, draw and shading
    /// times (each part's own median); ray casting, which has no such parts, holds none.
    #[test]
    fn the_summary_holds_each_rasterizing_method_s_stage_medians() {
        let mut rs = Vec::new();
        for (f, (cull, draw, shading)) in [(0.1, 5.0, 1.0), (0.3, 2.0, 0.5), (0.2, 3.0, 9.0)].into_iter().enumerate() {
            let cull = CullStats { ms_cull: cull, ms_draw: draw, ms_shading: shading, ..Default::default() };
            rs.push(FrameRecord { cull, ..record(f, "hzb", None) });
            rs.push(record(f, "raycast", None));
        }
        let s = report::summarize(&rs, &["hzb".into(), "raycast".into()]);
        assert_eq!(s[0].stages_median_ms, Some(report::Stages { cull: 0.2, draw: 3.0, shading: 1.0 }));
        assert_eq!(s[1].stages_median_ms, None);
        let mut table = Vec::new();
        report::print_table(&mut table, &s).unwrap();
        let table = String::from_utf8(table).unwrap();
        let row = table.lines().last().unwrap();
        assert!(row.starts_with("hzb") && row.ends_with("0.20       3.00       1.00"), "{table}");
    }

    #[test]
    fn verify_fails_a_walk_whose_ray_casting_agrees_too_little() {
        let rs = [
            // Culled methods are checked exactly, not by agreement.
            FrameRecord { verified: Some(true), ..record(0, "hzb", Some(0.2)) },
            record(0, "raycast", Some(0.999)),
            record(1, "raycast", Some(0.9949)),
            record(2, "raycast", Some(0.98)),
        ];
        let why = agreement_shortfall(&rs, 99.5).expect("frames 1 and 2 are below 99.5%");
        assert!(why.contains("98.00%") && why.contains("frame 2") && why.contains("2 of 3"), "{why}");
        assert!(agreement_shortfall(&rs, 98.0).is_none());
        assert!(agreement_shortfall(&[record(0, "raycast", None)], 100.0).is_none(), "no comparison, no failure");
        assert!(
            common::percent_arg("99.5").is_ok()
                && common::percent_arg("100.1").is_err()
                && common::percent_arg("x").is_err()
        );
    }
}

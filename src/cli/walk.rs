//! `sightline walk`: render a camera path with one or all visibility methods, verify against
//! brute force, summarize per method (median / p95 ms, triangles drawn, culled shares).

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde::Serialize;
use sightline::render::{
    compare_ids, output, CullStats, Culler, FrameStats, Framebuffer, Method, RayCaster, RaycastOptions, RenderOptions,
};

use super::common::{self, Look, OnOff, Size};

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
    #[arg(long, value_name = "PERCENT", default_value_t = 99.5, value_parser = percent_arg)]
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
    /// Output folder for per-frame counters (frames.csv) and PNG frames
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Write every k-th frame as PNG into --out (0: none)
    #[arg(long, default_value_t = 0, requires = "out")]
    pub png_every: usize,
    /// Summary as JSON into FILE (`-`: standard output)
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Occlusion culling: clusters in the first front-to-back batch (later batches double)
    #[arg(long, default_value_t = Culler::DEFAULT_FIRST_BATCH)]
    pub first_batch: usize,
    #[command(flatten)]
    pub look: Look,
}

/// One rendered frame of one method.
#[derive(Debug, Clone, Serialize)]
pub struct FrameRecord {
    pub frame: usize,
    pub method: &'static str,
    pub ms: f64,
    pub triangles_drawn: u64,
    pub cull: CullStats,
    pub raster: FrameStats,
    pub verified: Option<bool>,
    /// Share of pixels whose ID equals brute force's (ray casting is checked this way: it
    /// decides visibility differently, so it agrees on ≥ 99.5% rather than exactly).
    pub agreement: Option<f64>,
}

/// One method's summary: what scripts read.
#[derive(Debug, Clone, Serialize)]
pub struct MethodSummary {
    pub method: &'static str,
    pub frames: usize,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub mean_ms: f64,
    pub triangles_drawn_median: u64,
    pub culled_by_frustum_share: f64,
    pub culled_by_occlusion_share: f64,
    pub verified_frames: usize,
    pub mismatched_frames: usize,
    /// Lowest per-frame ID agreement with brute force (ray casting with --verify).
    pub min_id_agreement: Option<f64>,
}

fn methods(m: WalkMethod) -> Vec<(&'static str, Option<Method>)> {
    let one = |x: Method| (x.name(), Some(x));
    match m {
        WalkMethod::Brute => vec![one(Method::Brute)],
        WalkMethod::Frustum => vec![one(Method::Frustum)],
        WalkMethod::Hzb => vec![one(Method::Hzb)],
        WalkMethod::OctreeHzb => vec![one(Method::OctreeHzb)],
        WalkMethod::HzbOnePass => vec![one(Method::HzbOnePass)],
        WalkMethod::Raycast => vec![("raycast", None)],
        WalkMethod::All => {
            let mut v: Vec<_> = Method::ALL.iter().map(|&x| one(x)).collect();
            v.push(("raycast", None));
            v
        }
    }
}

pub fn run(a: &WalkArgs) -> Result<()> {
    common::check_outputs(a.out.as_deref().as_slice(), a.json.as_deref().as_slice())?;
    let mut loaded = super::load_scene(&a.walk.scene)?;
    let keys = common::path_keys(&loaded, a.walk.path.as_deref(), a.walk.frames)?;
    let opts = a.look.options(a.backface_culling);
    let records = common::with_threads(a.threads, || walk(&mut loaded, &keys, a, &opts))??;
    let summaries = summarize(&records, a);
    // With the summary on standard output, the table goes to standard error.
    if a.json.as_deref().is_some_and(common::is_stdout) {
        print_table(&mut std::io::stderr(), &summaries)?;
    } else {
        print_table(&mut std::io::stdout(), &summaries)?;
    }
    if let Some(dir) = &a.out {
        write_frames(dir, &records)?;
    }
    if let Some(p) = &a.json {
        let v = serde_json::json!({ "scene": format!("{:?}", a.walk.scene.scene), "size": [a.size.width, a.size.height], "methods": summaries });
        common::write_json(p, &v, true)?;
    }
    let bad: usize = summaries.iter().map(|s| s.mismatched_frames).sum();
    if bad > 0 {
        bail!("{bad} frames differ from brute force");
    }
    if let Some(why) = agreement_shortfall(&records, a.min_agreement) {
        bail!(why);
    }
    Ok(())
}

/// Why the run fails `--min-agreement` (a percentage), if it does: the worst frame, and how
/// many frames fell short.
fn agreement_shortfall(records: &[FrameRecord], min_percent: f64) -> Option<String> {
    let short: Vec<&FrameRecord> =
        records.iter().filter(|r| r.agreement.is_some_and(|x| 100.0 * x < min_percent)).collect();
    let worst = short.iter().min_by(|x, y| x.agreement.unwrap_or(0.0).total_cmp(&y.agreement.unwrap_or(0.0)))?;
    Some(format!(
        "{} gave the rasterizer's triangle IDs on only {:.2}% of the pixels of frame {}, below --min-agreement {}% ({} of {} compared frames fell short)",
        worst.method,
        100.0 * worst.agreement.unwrap_or(0.0),
        worst.frame,
        min_percent,
        short.len(),
        records.iter().filter(|r| r.agreement.is_some()).count()
    ))
}

/// A percentage in [0, 100].
fn percent_arg(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(p) if (0.0..=100.0).contains(&p) => Ok(p),
        _ => Err(format!("'{s}' is not a percentage between 0 and 100")),
    }
}

fn walk(
    loaded: &mut sightline::LoadedScene,
    keys: &[sightline::scene::path::CameraKey],
    a: &WalkArgs,
    opts: &RenderOptions,
) -> Result<Vec<FrameRecord>> {
    let animate = a.animate || matches!(a.walk.scene.scene, sightline::SceneSpec::CityTraffic(_));
    if animate {
        common::pose(&mut loaded.scene, 0.0)?;
    }
    let scene = &mut loaded.scene;
    let list = methods(a.method);
    let needs_raster = list.iter().any(|m| m.1.is_some()) || a.verify;
    let (mut culler, mut caster) = super::with_spinner("building BVHs", || -> Result<_> {
        let culler = needs_raster.then(|| {
            let mut c = Culler::new(scene);
            c.first_batch = a.first_batch.max(1);
            c
        });
        let caster = list.iter().any(|m| m.1.is_none()).then(|| RayCaster::build(scene)).transpose()?;
        Ok((culler, caster))
    })?;
    let mut fb = Framebuffer::new(a.size.width, a.size.height)?;
    let mut reference = Framebuffer::new(a.size.width, a.size.height)?;
    let bar = indicatif::ProgressBar::new((keys.len() * list.len()) as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames·methods {msg} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut out = Vec::new();
    let mut rc_opts = RaycastOptions::from_render(opts);
    rc_opts.shadows = false;
    for (f, key) in keys.iter().enumerate() {
        if animate {
            // Frame f shows time f / 30 s; the culler follows in its render call, the ray
            // caster here (a moved vehicle costs a TLAS rebuild, never a BLAS).
            common::pose(scene, f as f32 / 30.0)?;
            if let Some(c) = &mut caster {
                c.sync(scene)?;
            }
        }
        let scene = &*scene;
        let cam = key.camera(a.size.aspect()).with_context(|| format!("frame {f} of the path"))?;
        let mut have_reference = false;
        if a.verify {
            // The reference is rendered apart from the timed frames.
            culler.as_mut().unwrap().render(scene, &cam, Method::Brute, &mut reference, opts)?;
            have_reference = true;
        }
        for (name, method) in &list {
            let t = Instant::now();
            let (cs, rs) = match method {
                Some(m) => culler.as_mut().unwrap().render(scene, &cam, *m, &mut fb, opts)?,
                None => {
                    let st = caster.as_ref().unwrap().render(scene, &cam, &mut fb, &rc_opts)?;
                    let cs = CullStats { ms_total: st.ms_total, ..Default::default() };
                    (cs, FrameStats::default())
                }
            };
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let diff = have_reference.then(|| compare_ids(&reference.ids, &fb.ids, fb.width()));
            let agreement = diff.map(|d| 1.0 - d.map_or(0, |m| m.pixels) as f64 / fb.len() as f64);
            // Culling methods must equal brute force exactly; ray casting is reported as agreement.
            let verified = if method.is_some() { diff } else { None };
            if let Some(Some(m)) = &verified {
                bar.println(format!(
                    "frame {f}, {name}: {} pixels differ from brute force, first at {:?} (expected ID {}, got {})",
                    m.pixels, m.first, m.ids.0, m.ids.1
                ));
            }
            if let (Some(dir), true) = (&a.out, a.png_every > 0 && f % a.png_every == 0) {
                std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
                output::write_color_png(&fb, &dir.join(format!("{name}_{f:04}.png")))?;
            }
            out.push(FrameRecord {
                frame: f,
                method: name,
                ms,
                triangles_drawn: cs.triangles_drawn,
                cull: cs,
                raster: rs,
                verified: verified.map(|m| m.is_none()),
                agreement,
            });
            bar.inc(1);
        }
        bar.set_message(format!("frame {f}"));
    }
    bar.finish_and_clear();
    Ok(out)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

fn summarize(records: &[FrameRecord], a: &WalkArgs) -> Vec<MethodSummary> {
    methods(a.method)
        .iter()
        .map(|(name, _)| {
            let rs: Vec<&FrameRecord> = records.iter().filter(|r| r.method == *name).collect();
            let mut ms: Vec<f64> = rs.iter().map(|r| r.ms).collect();
            ms.sort_by(f64::total_cmp);
            let mut tris: Vec<u64> = rs.iter().map(|r| r.triangles_drawn).collect();
            tris.sort_unstable();
            let share = |f: &dyn Fn(&CullStats) -> u64| {
                let total: u64 = rs.iter().map(|r| r.cull.clusters).sum();
                if total == 0 {
                    0.0
                } else {
                    rs.iter().map(|r| f(&r.cull)).sum::<u64>() as f64 / total as f64
                }
            };
            MethodSummary {
                method: name,
                frames: rs.len(),
                median_ms: percentile(&ms, 0.5),
                p95_ms: percentile(&ms, 0.95),
                mean_ms: ms.iter().sum::<f64>() / ms.len().max(1) as f64,
                triangles_drawn_median: tris.get(tris.len() / 2).copied().unwrap_or(0),
                culled_by_frustum_share: share(&|c| c.culled_by_frustum),
                culled_by_occlusion_share: share(&|c| c.culled_by_occlusion),
                verified_frames: rs.iter().filter(|r| r.verified.is_some()).count(),
                mismatched_frames: rs.iter().filter(|r| r.verified == Some(false)).count(),
                min_id_agreement: rs.iter().filter_map(|r| r.agreement).reduce(f64::min),
            }
        })
        .collect()
}

fn print_table(w: &mut dyn Write, s: &[MethodSummary]) -> std::io::Result<()> {
    let brute = s.iter().find(|m| m.method == "brute").map(|m| m.median_ms);
    writeln!(
        w,
        "{:<13} {:>6} {:>10} {:>10} {:>9} {:>14} {:>9} {:>9} {:>9}",
        "method", "frames", "median ms", "p95 ms", "vs brute", "tris drawn", "frustum%", "occl%", "verified"
    )?;
    for m in s {
        let ratio = brute.map_or("-".into(), |b| format!("{:.1}x", b / m.median_ms.max(1e-9)));
        let ver = if let (0, Some(a)) = (m.verified_frames, m.min_id_agreement) {
            format!("{:.2}%", 100.0 * a)
        } else if m.verified_frames == 0 {
            "-".to_string()
        } else {
            format!("{}/{}", m.verified_frames - m.mismatched_frames, m.verified_frames)
        };
        writeln!(
            w,
            "{:<13} {:>6} {:>10.2} {:>10.2} {:>9} {:>14} {:>8.1}% {:>8.1}% {:>9}",
            m.method,
            m.frames,
            m.median_ms,
            m.p95_ms,
            ratio,
            m.triangles_drawn_median,
            100.0 * m.culled_by_frustum_share,
            100.0 * m.culled_by_occlusion_share,
            ver
        )?;
    }
    Ok(())
}

fn write_frames(dir: &std::path::Path, records: &[FrameRecord]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let csv = dir.join("frames.csv");
    let mut f =
        std::io::BufWriter::new(std::fs::File::create(&csv).with_context(|| format!("creating {}", csv.display()))?);
    writeln!(
        f,
        "frame,method,ms,triangles_drawn,clusters_in_frustum,clusters_drawn,culled_by_frustum,culled_by_occlusion,occlusion_tests,batches,ms_cull,ms_draw,ms_shading,ms_geometry,ms_binning,ms_raster,fragments_written,verified"
    )?;
    for r in records {
        let c = &r.cull;
        writeln!(
            f,
            "{},{},{:.3},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{}",
            r.frame,
            r.method,
            r.ms,
            r.triangles_drawn,
            c.clusters_in_frustum,
            c.clusters_drawn,
            c.culled_by_frustum,
            c.culled_by_occlusion,
            c.occlusion_tests,
            c.batches,
            c.ms_cull,
            c.ms_draw,
            c.ms_shading,
            r.raster.ms_geometry,
            r.raster.ms_binning,
            r.raster.ms_raster,
            r.raster.fragments_written,
            r.verified.map_or("".into(), |v| v.to_string())
        )?;
    }
    let json = dir.join("frames.json");
    std::fs::write(&json, serde_json::to_string(records)?).with_context(|| format!("writing {}", json.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(frame: usize, method: &'static str, agreement: Option<f64>) -> FrameRecord {
        FrameRecord {
            frame,
            method,
            ms: 1.0,
            triangles_drawn: 0,
            cull: CullStats::default(),
            raster: FrameStats::default(),
            verified: None,
            agreement,
        }
    }

    #[test]
    fn verify_fails_a_walk_whose_ray_casting_agrees_too_little() {
        let rs = [
            record(0, "hzb", Some(0.2)), // culled methods are checked exactly, not by agreement
            record(0, "raycast", Some(0.999)),
            record(1, "raycast", Some(0.9949)),
            record(2, "raycast", Some(0.98)),
        ];
        let why = agreement_shortfall(&rs[1..], 99.5).expect("frames 1 and 2 are below 99.5%");
        assert!(why.contains("98.00%") && why.contains("frame 2") && why.contains("2 of 3"), "{why}");
        assert!(agreement_shortfall(&rs[1..], 98.0).is_none());
        assert!(agreement_shortfall(&[record(0, "raycast", None)], 100.0).is_none(), "no comparison, no failure");
        assert!(percent_arg("99.5").is_ok() && percent_arg("100.1").is_err() && percent_arg("x").is_err());
    }
}

//! What a walk leaves in its `--out` folder, written the same way by `walk` and by `merge`:
//! the per-frame counters (`frames.csv`, `frames.json`), the run and its per-method summary
//! (`walk.json`, the object `--json` writes too), and the frame-time chart
//! (`frame_times.png`). The summary is computed from the per-frame records alone (median
//! and p95 by nearest rank over the sorted frame times), so a merge of shards recomputes
//! exactly what one run over all their frames prints.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sightline::render::{CullStats, FrameStats, Visibility};

/// Per-frame counters, CSV.
pub const FRAMES_CSV: &str = "frames.csv";
/// Per-frame counters, JSON (what `merge` reads back).
pub const FRAMES_JSON: &str = "frames.json";
/// The run and its summary.
pub const WALK_JSON: &str = "walk.json";
/// The frame-time chart.
pub const CHART_PNG: &str = "frame_times.png";
/// The walk as an animated GIF.
pub const WALK_GIF: &str = "walk.gif";

/// One rendered frame of one method.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrameRecord {
    /// The frame's number in the camera path (a shard keeps the path's numbers).
    pub frame: usize,
    pub method: String,
    pub ms: f64,
    pub triangles_drawn: u64,
    pub cull: CullStats,
    pub raster: FrameStats,
    pub verified: Option<bool>,
    /// Share of pixels whose ID equals brute force's (ray casting is checked this way: it
    /// decides visibility differently, so it agrees on ≥ 99.5% rather than exactly).
    pub agreement: Option<f64>,
    /// Milliseconds posing the frame's animations and bringing the scene, the culler and the
    /// ray caster up to date (animated walks): shared by every method of the frame, so
    /// outside `ms`, and the same in each of the frame's records.
    #[serde(default)]
    pub scene_update_ms: Option<f64>,
}

/// The scene's update per frame of an animated walk (see [`FrameRecord::scene_update_ms`]).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct UpdateSummary {
    pub frames: usize,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
    pub mean_ms: f64,
}

/// One method's summary: what scripts read.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MethodSummary {
    pub method: String,
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
    /// Where a rasterizing method's frame time goes (medians); `None` for ray casting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stages_median_ms: Option<Stages>,
}

/// Medians over a method's frames of the parts of its frame time, in milliseconds: walking
/// the culling structures and testing occlusion, drawing (geometry, binning, rasterizing,
/// writing out), shading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stages {
    pub cull: f64,
    pub draw: f64,
    pub shading: f64,
}

/// How a walk was run: shards of one walk must agree on all of it but the frame range.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The scene spec.
    pub scene: String,
    /// Image width and height.
    pub size: [u32; 2],
    /// The methods, in the order they ran on each frame.
    pub method_set: Vec<String>,
    pub verify: bool,
    pub animate: bool,
    pub backface_culling: bool,
    /// Frames in the whole camera path.
    pub path_frames: usize,
    /// Every k-th frame of the path is written as PNG (0: none).
    pub png_every: usize,
    /// Every k-th frame of the path goes into the GIF (0: no GIF).
    pub gif_every: usize,
}

/// `walk.json`, and what `--json` writes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WalkReport {
    #[serde(flatten)]
    pub run: RunInfo,
    /// The frames rendered: `[A, B)` of the path.
    pub frame_range: [usize; 2],
    /// Ranges `[A, B)` of the path that no shard rendered (a merge with gaps).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub missing_frames: Vec<[usize; 2]>,
    pub methods: Vec<MethodSummary>,
    /// The scene's update per frame, for animated walks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_update: Option<UpdateSummary>,
}

/// `values` in ascending order (NaN last), as [`percentile`] takes them.
fn sorted(values: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.into_iter().collect();
    v.sort_by(f64::total_cmp);
    v
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// Per-method summaries of `records`, in the order of `methods`.
pub fn summarize(records: &[FrameRecord], methods: &[String]) -> Vec<MethodSummary> {
    methods
        .iter()
        .map(|name| {
            let rs: Vec<&FrameRecord> = records.iter().filter(|r| r.method == *name).collect();
            let ms = sorted(rs.iter().map(|r| r.ms));
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
                method: name.clone(),
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
                stages_median_ms: (*name != Visibility::RayCast.name() && !rs.is_empty()).then(|| {
                    let median = |f: fn(&CullStats) -> f64| percentile(&sorted(rs.iter().map(|r| f(&r.cull))), 0.5);
                    Stages {
                        cull: median(|c| c.ms_cull),
                        draw: median(|c| c.ms_draw),
                        shading: median(|c| c.ms_shading),
                    }
                }),
            }
        })
        .collect()
}

/// The scene's update per frame over `records` (one value per frame: the frame's first
/// record's), `None` when no frame was updated (a static walk).
pub fn summarize_updates(records: &[FrameRecord]) -> Option<UpdateSummary> {
    let ms = sorted(records.chunk_by(|a, b| a.frame == b.frame).filter_map(|frame| frame[0].scene_update_ms));
    let max_ms = *ms.last()?;
    Some(UpdateSummary {
        frames: ms.len(),
        median_ms: percentile(&ms, 0.5),
        p95_ms: percentile(&ms, 0.95),
        max_ms,
        mean_ms: ms.iter().sum::<f64>() / ms.len() as f64,
    })
}

/// The summary table, one row per method.
pub fn print_table(w: &mut dyn Write, s: &[MethodSummary]) -> std::io::Result<()> {
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
    // Where each rasterizing method's time goes.
    if s.iter().any(|m| m.stages_median_ms.is_some()) {
        writeln!(w, "\nwhere the time goes (medians)")?;
        writeln!(w, "{:<13} {:>10} {:>10} {:>10}", "method", "cull ms", "draw ms", "shading ms")?;
        for m in s {
            if let Some(st) = &m.stages_median_ms {
                writeln!(w, "{:<13} {:>10.2} {:>10.2} {:>10.2}", m.method, st.cull, st.draw, st.shading)?;
            }
        }
    }
    Ok(())
}

/// The line under the table of an animated walk: what updating the scene cost per frame.
fn print_update(w: &mut dyn Write, u: &UpdateSummary) -> std::io::Result<()> {
    writeln!(
        w,
        "scene update per frame (posing, propagating, syncing the culler and ray caster; not in the times above): \
         median {:.2} ms, p95 {:.2} ms, max {:.2} ms, mean {:.2} ms over {} frames",
        u.median_ms, u.p95_ms, u.max_ms, u.mean_ms, u.frames
    )
}

/// Prints the table (and the scene update of an animated walk) on standard output, or on
/// standard error when the JSON summary goes to standard output.
pub fn print_summary(report: &WalkReport, json: Option<&Path>) -> Result<()> {
    let mut out: Box<dyn Write> = if json.is_some_and(super::common::is_stdout) {
        Box::new(std::io::stderr())
    } else {
        Box::new(std::io::stdout())
    };
    print_table(&mut out, &report.methods)?;
    if let Some(u) = &report.scene_update {
        print_update(&mut out, u)?;
    }
    Ok(())
}

/// Writes `frames.csv`, `frames.json`, `walk.json` and the chart into `dir`.
pub fn write_report(dir: &Path, report: &WalkReport, records: &[FrameRecord]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    write_csv(&dir.join(FRAMES_CSV), records)?;
    let json = dir.join(FRAMES_JSON);
    std::fs::write(&json, serde_json::to_string(records)?).with_context(|| format!("writing {}", json.display()))?;
    super::common::write_json(&dir.join(WALK_JSON), &serde_json::to_value(report)?, true)?;
    let mut series: Vec<(String, Vec<(f64, f64)>)> = report
        .run
        .method_set
        .iter()
        .map(|m| {
            let pts = records.iter().filter(|r| r.method == *m).map(|r| (r.frame as f64, r.ms)).collect();
            (m.clone(), pts)
        })
        .collect();
    // An animated walk's scene update beside the methods' frames (once per frame: the
    // first method's records carry it like every other's).
    if let Some(first) = report.run.method_set.first().filter(|_| report.scene_update.is_some()) {
        let pts =
            records.iter().filter(|r| r.method == *first).filter_map(|r| Some((r.frame as f64, r.scene_update_ms?)));
        series.push(("scene update".to_string(), pts.collect()));
    }
    super::chart::line_chart(&dir.join(CHART_PNG), "frame time per frame", "frame", "ms", &series)
}

/// The largest report file `merge` reads (16 GiB: a million frames of every method).
const MAX_REPORT_BYTES: u64 = 16 << 30;

/// Reads `frames.json` and `walk.json` back from a walk's output folder.
pub fn read_report(dir: &Path) -> Result<(WalkReport, Vec<FrameRecord>)> {
    let read = |name: &str| -> Result<String> {
        let p = dir.join(name);
        // A regular file only: a FIFO in a shard folder must not block the merge.
        let bytes = sightline::scene::assets::read_regular_file(&p, MAX_REPORT_BYTES).map_err(|why| {
            anyhow::anyhow!("{}: {why} (is {} the --out folder of a walk?)", p.display(), dir.display())
        })?;
        String::from_utf8(bytes).with_context(|| format!("{}: not UTF-8 text", p.display()))
    };
    let report: WalkReport =
        serde_json::from_str(&read(WALK_JSON)?).with_context(|| format!("{}", dir.join(WALK_JSON).display()))?;
    let records: Vec<FrameRecord> =
        serde_json::from_str(&read(FRAMES_JSON)?).with_context(|| format!("{}", dir.join(FRAMES_JSON).display()))?;
    Ok((report, records))
}

fn write_csv(csv: &Path, records: &[FrameRecord]) -> Result<()> {
    let mut f =
        std::io::BufWriter::new(std::fs::File::create(csv).with_context(|| format!("creating {}", csv.display()))?);
    writeln!(
        f,
        "frame,method,ms,triangles_drawn,clusters_in_frustum,clusters_drawn,culled_by_frustum,culled_by_occlusion,occlusion_tests,batches,ms_cull,ms_draw,ms_shading,ms_geometry,ms_binning,ms_raster,fragments_written,verified,scene_update_ms"
    )?;
    for r in records {
        let c = &r.cull;
        writeln!(
            f,
            "{},{},{:.3},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{}",
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
            r.verified.map_or("".into(), |v| v.to_string()),
            r.scene_update_ms.map_or("".into(), |v| format!("{v:.3}"))
        )?;
    }
    f.flush().with_context(|| format!("writing {}", csv.display()))
}

/// Names of the PNG frames in `dir` (`frame_NNNN.png`), sorted.
pub fn png_frames(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_prefix("frame_")?.strip_suffix(".png"))
                .is_some_and(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()))
        })
        .collect();
    // Zero-padded numbers: a longer name is a larger number.
    v.sort_by_key(|p| (p.as_os_str().len(), p.clone()));
    v
}

/// The last lines of a walk or a merge: where everything went (on standard error when the
/// JSON summary goes to standard output).
pub fn print_outputs(dir: &Path, gif_frames: Option<usize>, json: Option<&Path>) -> Result<()> {
    let mut text = String::new();
    list_outputs(&mut text, dir, gif_frames)?;
    if json.is_some_and(super::common::is_stdout) {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    Ok(())
}

fn list_outputs(w: &mut String, dir: &Path, gif_frames: Option<usize>) -> std::fmt::Result {
    use std::fmt::Write as _;
    writeln!(w, "outputs in {}:", dir.display())?;
    writeln!(w, "  {:<28} per-frame counters", format!("{FRAMES_CSV}, {FRAMES_JSON}"))?;
    writeln!(w, "  {:<28} the run and its summary per method", WALK_JSON)?;
    let pngs = png_frames(dir);
    if let (Some(first), Some(last)) = (pngs.first(), pngs.last()) {
        let name = |p: &PathBuf| p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let span = if pngs.len() == 1 { name(first) } else { format!("{} … {}", name(first), name(last)) };
        writeln!(w, "  {span:<28} {} PNG frames", pngs.len())?;
    }
    if let Some(n) = gif_frames {
        writeln!(w, "  {:<28} the walk as an animated GIF ({n} frames)", WALK_GIF)?;
    }
    writeln!(w, "  {:<28} frame-time chart", CHART_PNG)
}

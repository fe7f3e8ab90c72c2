//! `sightline merge`: joins the `--out` folders of the shards of one walk (`walk
//! --frame-range`) into the folder one run over all their frames would have written.
//!
//! The shards must agree on everything but their frame ranges (scene, image size, the
//! methods and their order, verification, animation, back-face culling, the path's length
//! and which frames become pictures) and their ranges must not overlap; a shard that breaks
//! either is refused, naming both folders. A report whose frame size no walk draws, or whose
//! range leaves the path, is refused too, and only regular files are read from the shards.
//! Frames no shard rendered are reported (on standard error and as `missing_frames` in
//! `walk.json`), not refused. The per-frame records are concatenated in path order and the
//! summary recomputed from them; the PNG frames and any other per-frame files are copied; the
//! shards' GIFs are joined frame by frame, as encoded (nothing re-quantized).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::report::{self, FrameRecord, WalkReport, CHART_PNG, FRAMES_CSV, FRAMES_JSON, WALK_GIF, WALK_JSON};

#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// Output folder: the merged frames.csv, frames.json, walk.json, PNG frames, walk.gif and
    /// frame-time chart
    #[arg(short, long, value_name = "DIR")]
    pub out: PathBuf,
    /// The --out folders of the shards (`sightline walk --frame-range A..B --out DIR`)
    #[arg(value_name = "SHARD_DIR", required = true)]
    pub shards: Vec<PathBuf>,
    /// The merged summary as JSON into FILE too (`-`: standard output)
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// The least share of pixels (percent) on which ray casting must have agreed with the
    /// rasterizer on every verified frame, as `walk --min-agreement`
    #[arg(long, value_name = "PERCENT", default_value_t = 99.5, value_parser = super::common::percent_arg)]
    pub min_agreement: f64,
}

/// One shard read back.
struct Shard {
    dir: PathBuf,
    report: WalkReport,
    records: Vec<FrameRecord>,
}

/// Files of a walk's folder that the merge writes itself rather than copies.
const REPORT_FILES: [&str; 5] = [FRAMES_CSV, FRAMES_JSON, WALK_JSON, WALK_GIF, CHART_PNG];

pub fn run(a: &MergeArgs) -> Result<()> {
    super::common::check_outputs(&[&a.out], a.json.as_deref().as_slice())?;
    let mut shards = Vec::with_capacity(a.shards.len());
    for dir in &a.shards {
        if same_folder(dir, &a.out) {
            bail!("--out {} is also a shard folder: merge into a folder of its own", a.out.display());
        }
        let (report, records) = report::read_report(dir)?;
        shards.push(Shard { dir: dir.clone(), report, records });
    }
    check_consistent(&shards)?;
    shards.sort_by_key(|s| s.report.frame_range[0]);
    check_disjoint(&shards)?;
    let run = shards[0].report.run.clone();
    let covered: Vec<[usize; 2]> = shards.iter().map(|s| s.report.frame_range).collect();
    let (lo, hi) = (covered[0][0], covered.iter().map(|r| r[1]).max().unwrap_or(0));
    let missing = gaps(&covered, run.path_frames);
    if !missing.is_empty() {
        let list: Vec<String> = missing.iter().map(|[a, b]| format!("{a}..{b}")).collect();
        eprintln!(
            "warning: no shard rendered frames {} of the path's {} (the merged report covers the rest)",
            list.join(", "),
            run.path_frames
        );
    }
    let records: Vec<FrameRecord> = shards.iter().flat_map(|s| s.records.iter().cloned()).collect();
    copy_frame_files(&shards, &a.out)?;
    let gif_frames = join_gifs(&shards, &a.out, &run)?;
    let merged = WalkReport {
        methods: report::summarize(&records, &run.method_set),
        scene_update: report::summarize_updates(&records),
        run,
        frame_range: [lo.min(hi), hi],
        missing_frames: missing,
    };
    println!("merged {} shards: frames {lo}..{hi} of {}", shards.len(), merged.run.path_frames);
    super::walk::finish(&merged, &records, Some(&a.out), a.json.as_deref(), gif_frames, a.min_agreement)
}

fn same_folder(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Every shard ran the walk the first one ran, but for its frames.
fn check_consistent(shards: &[Shard]) -> Result<()> {
    for s in shards {
        check_report(s)?;
    }
    let first = &shards[0];
    let r0 = &first.report.run;
    for s in &shards[1..] {
        let r = &s.report.run;
        let differs: Vec<String> = [
            ("scene", r0.scene != r.scene, format!("{} vs {}", r0.scene, r.scene)),
            ("size", r0.size != r.size, format!("{:?} vs {:?}", r0.size, r.size)),
            ("methods", r0.method_set != r.method_set, format!("{:?} vs {:?}", r0.method_set, r.method_set)),
            ("--verify", r0.verify != r.verify, format!("{} vs {}", r0.verify, r.verify)),
            ("--animate", r0.animate != r.animate, format!("{} vs {}", r0.animate, r.animate)),
            (
                "--backface-culling",
                r0.backface_culling != r.backface_culling,
                format!("{} vs {}", r0.backface_culling, r.backface_culling),
            ),
            ("path length", r0.path_frames != r.path_frames, format!("{} vs {}", r0.path_frames, r.path_frames)),
            ("--png-every", r0.png_every != r.png_every, format!("{} vs {}", r0.png_every, r.png_every)),
            ("--gif-every", r0.gif_every != r.gif_every, format!("{} vs {}", r0.gif_every, r.gif_every)),
        ]
        .into_iter()
        .filter(|d| d.1)
        .map(|(what, _, how)| format!("{what} ({how})"))
        .collect();
        if !differs.is_empty() {
            bail!(
                "shards {} and {} are not parts of one walk: they differ in {}",
                first.dir.display(),
                s.dir.display(),
                differs.join(", ")
            );
        }
    }
    Ok(())
}

/// A shard's report describes a walk this program could have run: a frame size it draws, a
/// frame range inside the path, and records of frames in that range only. (A report is read
/// from a folder that anyone may have written; its size sizes the merged GIF, and its range
/// says which frames are missing.)
fn check_report(s: &Shard) -> Result<()> {
    let r = &s.report;
    let [w, h] = r.run.size;
    let max = sightline::render::MAX_SIZE;
    if !(1..=max).contains(&w) || !(1..=max).contains(&h) {
        bail!("{}: walk.json gives the frame size {w}x{h}; a walk draws 1 to {max} pixels a side", s.dir.display());
    }
    let [a, b] = r.frame_range;
    if a > b || b > r.run.path_frames {
        bail!(
            "{}: walk.json gives the frame range {a}..{b}, not a range of the path's {} frames",
            s.dir.display(),
            r.run.path_frames
        );
    }
    if s.records.iter().any(|rec| !(a..b).contains(&rec.frame)) {
        bail!("{}: frames.json holds frames outside the shard's range in walk.json", s.dir.display());
    }
    Ok(())
}

/// No frame is in two shards (`shards` sorted by the start of their ranges).
fn check_disjoint(shards: &[Shard]) -> Result<()> {
    for w in shards.windows(2) {
        let ([a0, a1], [b0, b1]) = (w[0].report.frame_range, w[1].report.frame_range);
        if b0 < a1 {
            bail!(
                "shards {} (frames {a0}..{a1}) and {} (frames {b0}..{b1}) overlap in frames {b0}..{}",
                w[0].dir.display(),
                w[1].dir.display(),
                a1.min(b1)
            );
        }
    }
    Ok(())
}

/// The ranges of `0..frames` that none of the sorted, disjoint `covered` ranges holds.
fn gaps(covered: &[[usize; 2]], frames: usize) -> Vec<[usize; 2]> {
    let mut out = Vec::new();
    let mut at = 0;
    for &[a, b] in covered {
        if a > at {
            out.push([at, a]);
        }
        at = at.max(b);
    }
    if at < frames {
        out.push([at, frames]);
    }
    out
}

/// Copies every file of the shards but their reports (the PNG frames, and whatever else a
/// walk writes per frame); a name in two shards is an overlap.
fn copy_frame_files(shards: &[Shard], out: &Path) -> Result<()> {
    let mut seen: HashMap<std::ffi::OsString, &Path> = HashMap::new();
    for s in shards {
        let entries = std::fs::read_dir(&s.dir).with_context(|| format!("reading {}", s.dir.display()))?;
        for e in entries {
            let e = e.with_context(|| format!("reading {}", s.dir.display()))?;
            let name = e.file_name();
            if REPORT_FILES.iter().any(|r| name == *r) || !e.file_type().is_ok_and(|t| t.is_file()) {
                continue;
            }
            if let Some(other) = seen.insert(name.clone(), &s.dir) {
                bail!(
                    "shards {} and {} both hold {}: their frames overlap",
                    other.display(),
                    s.dir.display(),
                    name.to_string_lossy()
                );
            }
            // Opened as a regular file (checked on the open handle): a file swapped for a FIFO
            // since the listing must not block the merge.
            let (src, dest) = (e.path(), out.join(&name));
            let copy = || -> Result<u64> {
                let mut from = sightline::scene::assets::open_regular_file(&src).map_err(anyhow::Error::msg)?;
                let mut to = std::fs::File::create(&dest)?;
                Ok(std::io::copy(&mut from, &mut to)?)
            };
            copy().with_context(|| format!("copying {} to {}", src.display(), dest.display()))?;
        }
    }
    Ok(())
}

/// Joins the shards' GIFs in path order; `None` when the walk wrote none.
fn join_gifs(shards: &[Shard], out: &Path, run: &report::RunInfo) -> Result<Option<usize>> {
    if run.gif_every == 0 {
        return Ok(None);
    }
    let [w, h] = run.size;
    let delay = sightline::gif_out::delay_for(run.gif_every);
    let mut gif = sightline::gif_out::GifOut::create(&out.join(WALK_GIF), w, h, super::pictures::GIF_WIDTH, delay)?;
    for s in shards {
        let p = s.dir.join(WALK_GIF);
        // A shard none of whose frames went into the GIF may hold an empty one. Only a
        // regular file is opened (`append_gif`): a FIFO must not block the merge.
        if p.exists() {
            gif.append_gif(&p)?;
        } else if holds_a_multiple(s.report.frame_range, run.gif_every) {
            bail!("{}: missing; the shard's frames belong in the GIF", p.display());
        }
    }
    Ok(Some(gif.frames))
}

/// Whether frames `a..b` hold a multiple of `every` (counted, not searched: the range comes
/// from a file and may be huge).
fn holds_a_multiple([a, b]: [usize; 2], every: usize) -> bool {
    let first = a.div_ceil(every.max(1)).saturating_mul(every.max(1));
    first < b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_the_frames_no_shard_holds() {
        assert_eq!(gaps(&[[0, 10], [10, 20]], 20), Vec::<[usize; 2]>::new());
        assert_eq!(gaps(&[[5, 10], [12, 20]], 25), vec![[0, 5], [10, 12], [20, 25]]);
    }

    #[test]
    fn a_multiple_in_a_range_is_counted_not_searched() {
        assert!(holds_a_multiple([0, 1], 5) && holds_a_multiple([3, 6], 5));
        assert!(!holds_a_multiple([1, 5], 5) && !holds_a_multiple([6, 10], 5) && !holds_a_multiple([7, 7], 1));
        // A range read from a crafted report answers at once.
        assert!(!holds_a_multiple([1, 1 << 60], usize::MAX / 2));
        assert!(holds_a_multiple([1, usize::MAX], 1 << 40));
    }
}

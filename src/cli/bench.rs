//! `sightline bench`: every method over the path, verified against brute force, as a
//! Markdown table and charts.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};

use super::chart::{bar_chart, stacked_bar_chart, Bar, Stack};
use super::walk::{self, WalkArgs, WalkMethod};

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub walk: super::PathArgs,
    /// Output folder for bench.md, bench.json, frames.csv and the charts
    #[arg(short, long, value_name = "DIR", default_value = "bench-out")]
    pub out: PathBuf,
    /// Image size
    #[arg(long, default_value = "1280x720")]
    pub size: super::common::Size,
    /// Worker threads, 1 to 256 (default: all cores)
    #[arg(short = 'j', long, value_parser = super::common::threads_arg)]
    pub threads: Option<usize>,
}

pub fn run(a: &BenchArgs) -> Result<()> {
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let json = a.out.join("bench.json");
    let w = WalkArgs {
        walk: a.walk.clone(),
        method: WalkMethod::All,
        verify: true,
        animate: false,
        min_agreement: 99.5,
        size: a.size,
        backface_culling: super::common::OnOff::On,
        threads: a.threads,
        out: Some(a.out.clone()),
        frame_range: None,
        png_every: None,
        gif_every: None,
        json: Some(json.clone()),
        first_batch: sightline::render::Culler::DEFAULT_FIRST_BATCH,
        look: super::common::Look::pictures(),
    };
    // A summary left by an earlier run must not pass for this one's.
    if json.exists() {
        std::fs::remove_file(&json).with_context(|| format!("removing the old {}", json.display()))?;
    }
    let result = walk::run(&w);
    let text = match std::fs::read_to_string(&json) {
        Ok(t) => t,
        Err(e) => {
            result?;
            return Err(e).with_context(|| format!("the walk wrote no {}", json.display()));
        }
    };
    let summary: serde_json::Value = serde_json::from_str(&text)?;
    let methods = summary["methods"].as_array().cloned().unwrap_or_default();
    let brute = methods.iter().find(|m| m["method"] == "brute").and_then(|m| m["median_ms"].as_f64());
    let mut md = String::new();
    writeln!(md, "# sightline bench\n")?;
    writeln!(
        md,
        "scene `{}`, {}×{}, {} frames, threads: {}\n",
        summary["scene"].as_str().unwrap_or("?"),
        a.size.width,
        a.size.height,
        methods.first().and_then(|m| m["frames"].as_u64()).unwrap_or(0),
        a.threads.map_or("all".into(), |t| t.to_string())
    )?;
    writeln!(
        md,
        "| method | median ms | p95 ms | × faster than brute | triangles drawn (median) | cull / draw / shading ms (medians) | verified |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|---|")?;
    let mut bars = Vec::new();
    let mut tri_bars = Vec::new();
    let mut stacks = Vec::new();
    for m in &methods {
        let name = m["method"].as_str().unwrap_or("?");
        let med = m["median_ms"].as_f64().unwrap_or(0.0);
        let p95 = m["p95_ms"].as_f64().unwrap_or(0.0);
        let tris = m["triangles_drawn_median"].as_u64().unwrap_or(0);
        let verified =
            match (m["verified_frames"].as_u64(), m["mismatched_frames"].as_u64(), m["min_id_agreement"].as_f64()) {
                (Some(0), _, Some(a)) => format!("{:.2}% ID agreement (min)", 100.0 * a),
                (Some(v), Some(bad), _) => format!("{}/{v} identical", v - bad),
                _ => "-".into(),
            };
        let ratio = brute.map_or("-".into(), |b| format!("{:.1}", b / med.max(1e-9)));
        let st = &m["stages_median_ms"];
        let stages = match (st["cull"].as_f64(), st["draw"].as_f64(), st["shading"].as_f64()) {
            (Some(c), Some(d), Some(s)) => {
                stacks.push(Stack { label: name.into(), parts: vec![c, d, s] });
                format!("{c:.2} / {d:.2} / {s:.2}")
            }
            _ => "-".into(),
        };
        writeln!(md, "| {name} | {med:.2} | {p95:.2} | {ratio} | {tris} | {stages} | {verified} |")?;
        bars.push(Bar { label: name.into(), value: med, high: Some(p95) });
        if name != "raycast" {
            tri_bars.push(Bar { label: name.into(), value: tris as f64, high: None });
        }
    }
    writeln!(
        md,
        "\n![frame times](bench.png)\n\n![where the time goes](stages.png)\n\n![triangles drawn](triangles.png)"
    )?;
    std::fs::write(a.out.join("bench.md"), &md)?;
    bar_chart(&a.out.join("bench.png"), "median frame time (bar) and p95 (line)", "ms", &bars)?;
    bar_chart(&a.out.join("triangles.png"), "triangles drawn per frame (median)", "triangles", &tri_bars)?;
    stacked_bar_chart(
        &a.out.join("stages.png"),
        "where the frame time goes (medians of each part)",
        "ms",
        &["cull", "draw", "shading"],
        &stacks,
    )?;
    println!("\n{md}");
    println!("wrote {}", a.out.join("bench.md").display());
    result
}

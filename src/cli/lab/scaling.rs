//! `sightline lab --scaling`: every method's time on a family of cities from 10^3 to 10^5
//! triangles, as a CSV and a log–log chart (one line per method; a method stops where its
//! size limit refuses the scene).

use std::fmt::Write as _;

use anyhow::{Context, Result};
use sightline::SceneSpec;

use super::report::Row;
use super::{common, draw_view, progress, scene_triangles, LabArgs};
use crate::cli::chart;

/// The family: cities of at least this many triangles, about half a decade apart.
pub const FAMILY: [u64; 5] = [1_000, 3_000, 10_000, 30_000, 100_000];

pub fn run(a: &LabArgs) -> Result<()> {
    let bar = progress((FAMILY.len() * super::METHODS.len()) as u64);
    let mut runs: Vec<(usize, Vec<Row>)> = Vec::new();
    for n in FAMILY {
        let arg = crate::cli::SceneArg { scene: SceneSpec::City(n), allow_asset_roots: Vec::new() };
        let loaded = bar.suspend(|| crate::cli::load_scene(&arg))?;
        let camera = a.camera.choice(super::super::describe(&a.scene.scene)).camera(&loaded, a.size)?;
        let scene = &loaded.scene;
        let rows = common::with_threads(a.threads, || draw_view(scene, &camera, a.size, a.repeat, false, &bar))??;
        runs.push((scene_triangles(scene), rows));
    }
    bar.finish_and_clear();
    let csv = csv(&runs);
    let path = a.out.join("scaling.csv");
    std::fs::write(&path, &csv).with_context(|| format!("writing {}", path.display()))?;
    let mut series: Vec<chart::Series> = Vec::new();
    for (tris, rows) in &runs {
        for r in rows {
            let Some(ms) = r.ms() else { continue };
            match series.iter_mut().find(|s| s.label == r.method) {
                Some(s) => s.points.push((*tris as f64, ms)),
                None => series.push(chart::Series { label: r.method.to_string(), points: vec![(*tris as f64, ms)] }),
            }
        }
    }
    let title = format!("visibility methods at {}x{}: time against triangles", a.size.width, a.size.height);
    chart::log_log_chart(&a.out.join("scaling.png"), &title, "triangles", "ms", &series)?;
    let json = serde_json::json!({ "size": [a.size.width, a.size.height], "runs": runs.iter().map(|(t, rows)| {
        serde_json::json!({ "triangles": t, "methods": rows.iter().map(|r| serde_json::json!({
            "method": r.method, "ms": r.ms(), "agreement_vs_zbuffer": r.agreement(),
        })).collect::<Vec<_>>() })
    }).collect::<Vec<_>>() });
    if let Some(p) = &a.json {
        common::write_json(p, &json, true)?;
    }
    if !a.json.as_deref().is_some_and(common::is_stdout) {
        print!("{csv}");
    }
    eprintln!("scaling chart written to {}", a.out.display());
    Ok(())
}

/// `triangles,method,ms,agreement_vs_zbuffer,status`, one line per scene and method.
fn csv(runs: &[(usize, Vec<Row>)]) -> String {
    let mut s = String::from("triangles,method,ms,agreement_vs_zbuffer,status\n");
    for (tris, rows) in runs {
        for r in rows {
            let (ms, agree) = (r.ms().map_or(String::new(), |v| format!("{v:.3}")), r.agreement());
            let status = match (r.ms(), r.limit) {
                (Some(_), _) => "ran",
                (None, Some(limit)) if limit < *tris => "refused",
                (None, _) => "failed",
            };
            let _ =
                writeln!(s, "{tris},{},{ms},{},{status}", r.method, agree.map_or(String::new(), |v| format!("{v:.4}")));
        }
    }
    s
}

//! What the lab writes for one view: the Markdown table, the JSON summary, the labelled
//! contact sheet and a difference image per method against the z-buffer.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use sightline::hud;
use sightline::render::Framebuffer;

use super::methods::{Ran, REFEREE};

/// How a method fared on the view.
pub enum Outcome {
    /// It drew the view.
    Ran {
        /// Its time and counters.
        ran: Ran,
        /// Its frame, shaded.
        fb: Box<Framebuffer>,
        /// Pixels whose triangle ID differs from the z-buffer's.
        differing: usize,
    },
    /// It was not run (over its size limit) or could not draw the view: why.
    NotRun(String),
}

/// One method's line of the report.
pub struct Row {
    pub method: &'static str,
    /// The most triangles the method takes.
    pub limit: Option<usize>,
    pub outcome: Outcome,
}

impl Row {
    /// Percentage of pixels whose triangle ID equals the z-buffer's.
    pub fn agreement(&self) -> Option<f64> {
        match &self.outcome {
            Outcome::Ran { fb, differing, .. } => Some(100.0 * (1.0 - *differing as f64 / fb.len() as f64)),
            Outcome::NotRun(_) => None,
        }
    }

    /// Milliseconds, when it ran.
    pub fn ms(&self) -> Option<f64> {
        match &self.outcome {
            Outcome::Ran { ran, .. } => Some(ran.ms),
            Outcome::NotRun(_) => None,
        }
    }
}

/// The view: scene, size, camera.
pub struct ViewInfo {
    pub scene: String,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub eye: [f32; 3],
    pub forward: [f32; 3],
}

/// Writes `lab.md`, `lab.json`, `contact_sheet.png` and `diff_<method>.png` into `dir`;
/// returns the Markdown and the JSON.
pub fn write_all(dir: &Path, info: &ViewInfo, rows: &[Row]) -> Result<(String, serde_json::Value)> {
    let md = markdown(info, rows);
    std::fs::write(dir.join("lab.md"), &md).with_context(|| format!("writing {}", dir.join("lab.md").display()))?;
    let json = json(info, rows);
    super::super::common::write_json(&dir.join("lab.json"), &json, true)?;
    let referee = rows.iter().find_map(|r| match &r.outcome {
        Outcome::Ran { fb, .. } if r.method == REFEREE => Some(fb),
        _ => None,
    });
    if let Some(z) = referee {
        for r in rows.iter().filter(|r| r.method != REFEREE) {
            if let Outcome::Ran { fb, .. } = &r.outcome {
                save(&dir.join(format!("diff_{}.png", r.method)), z.width(), z.height(), difference(z, fb))?;
            }
        }
    }
    let (w, h, sheet) = contact_sheet(info, rows);
    save(&dir.join("contact_sheet.png"), w, h, sheet)?;
    Ok((md, json))
}

fn save(path: &Path, w: u32, h: u32, rgba: Vec<[u8; 4]>) -> Result<()> {
    let img = image::RgbaImage::from_raw(w, h, rgba.into_flattened()).context("image size")?;
    img.save_with_format(path, image::ImageFormat::Png).with_context(|| format!("writing {}", path.display()))
}

/// The counters of a run as `name=value, …`.
fn counters_text(ran: &Ran) -> String {
    ran.counters.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(", ")
}

/// The Markdown report: the view, then one table row per method.
pub fn markdown(info: &ViewInfo, rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Visibility lab\n");
    let _ = writeln!(
        s,
        "Scene `{}` ({} triangles), {}×{} pixels, eye ({:.2}, {:.2}, {:.2}) looking along ({:.3}, {:.3}, {:.3}). \
         Every method draws the same view; `agreement_vs_zbuffer` is the share of pixels whose triangle ID equals \
         the z-buffer's; `diff_<method>.png` shows the pixels that differ in red, ringed in orange.\n",
        info.scene,
        info.triangles,
        info.width,
        info.height,
        info.eye[0],
        info.eye[1],
        info.eye[2],
        info.forward[0],
        info.forward[1],
        info.forward[2]
    );
    let _ = writeln!(s, "| method | triangles | ms | agreement_vs_zbuffer % | differing pixels | counters |");
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---|");
    for r in rows {
        match &r.outcome {
            Outcome::Ran { ran, differing, .. } => {
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.2} | {:.3} | {} | {} |",
                    r.method,
                    info.triangles,
                    ran.ms,
                    r.agreement().unwrap_or(0.0),
                    differing,
                    counters_text(ran)
                );
            }
            Outcome::NotRun(why) => {
                let limit = r.limit.map_or("-".to_string(), |l| format!("refused (takes ≤ {l})"));
                let _ = writeln!(s, "| {} | {limit} | - | - | - | {} |", r.method, why.replace('|', "/"));
            }
        }
    }
    s
}

/// `{"scene", "triangles", "size", "eye", "forward", "methods": [...], "refused": [...]}`.
pub fn json(info: &ViewInfo, rows: &[Row]) -> serde_json::Value {
    let mut methods = Vec::new();
    let mut refused = Vec::new();
    for r in rows {
        match &r.outcome {
            Outcome::Ran { ran, differing, .. } => {
                let mut m = serde_json::Map::new();
                m.insert("method".into(), r.method.into());
                m.insert("triangles".into(), info.triangles.into());
                m.insert("ms".into(), ran.ms.into());
                m.insert("agreement_vs_zbuffer".into(), r.agreement().unwrap_or(0.0).into());
                m.insert("differing_pixels".into(), (*differing).into());
                for (k, v) in ran.counters.iter() {
                    m.insert(k.into(), v.into());
                }
                methods.push(serde_json::Value::Object(m));
            }
            Outcome::NotRun(why) => {
                refused.push(serde_json::json!({ "method": r.method, "limit": r.limit, "reason": why }));
            }
        }
    }
    serde_json::json!({
        "scene": info.scene, "triangles": info.triangles, "size": [info.width, info.height],
        "eye": info.eye, "forward": info.forward, "methods": methods, "refused": refused,
    })
}

/// The z-buffer's image in dim grey, the pixels whose ID differs in red, and a ring of
/// orange around them so that single pixels show at a glance.
pub fn difference(z: &Framebuffer, other: &Framebuffer) -> Vec<[u8; 4]> {
    let (w, h) = (z.width() as usize, z.height() as usize);
    let differs = |i: usize| z.ids[i] != other.ids[i];
    let mut out: Vec<[u8; 4]> = z
        .color
        .iter()
        .map(|c| {
            let luma = (c[0] as u32 * 3 + c[1] as u32 * 6 + c[2] as u32) / 10;
            let g = (24 + luma / 4) as u8;
            [g, g, g, 255]
        })
        .collect();
    for y in 0..h {
        for x in 0..w {
            if !differs(y * w + x) {
                continue;
            }
            for ny in y.saturating_sub(2)..(y + 3).min(h) {
                for nx in x.saturating_sub(2)..(x + 3).min(w) {
                    if !differs(ny * w + nx) {
                        out[ny * w + nx] = [255, 160, 0, 255];
                    }
                }
            }
            out[y * w + x] = [255, 0, 0, 255];
        }
    }
    out
}

/// Widest tile of the contact sheet: larger frames are shrunk by a whole factor.
const TILE_MAX: u32 = 480;
/// Tiles per row.
const COLUMNS: usize = 3;
/// Space between and around tiles.
const GAP: u32 = 4;

/// Every method's frame side by side, shrunk to at most [`TILE_MAX`] pixels wide, each
/// labelled with its name, time and agreement (or why it did not run).
pub fn contact_sheet(info: &ViewInfo, rows: &[Row]) -> (u32, u32, Vec<[u8; 4]>) {
    let k = info.width.div_ceil(TILE_MAX).max(1);
    let (tw, th) = ((info.width / k).max(1), (info.height / k).max(1));
    let cols = rows.len().clamp(1, COLUMNS);
    let nrows = rows.len().div_ceil(cols).max(1);
    let (sw, sh) = (cols as u32 * (tw + GAP) + GAP, nrows as u32 * (th + GAP) + GAP);
    let mut sheet = vec![[24u8, 24, 24, 255]; (sw * sh) as usize];
    let scale = if tw >= 400 { 2 } else { 1 };
    let chars = (tw / (8 * scale)).saturating_sub(1).max(4) as usize;
    for (i, r) in rows.iter().enumerate() {
        let (mut tile, lines) = match &r.outcome {
            Outcome::Ran { ran, fb, differing } => {
                let agree = match r.agreement() {
                    Some(a) if r.method != REFEREE => format!("{a:.3}% ({differing} px)"),
                    _ => "referee".to_string(),
                };
                (shrink(fb, k, tw, th), vec![r.method.to_string(), format!("{:.1} ms", ran.ms), agree])
            }
            Outcome::NotRun(why) => {
                let mut lines = vec![r.method.to_string(), "not run:".to_string()];
                lines.extend(wrap(why, chars));
                (vec![[70u8, 70, 70, 255]; (tw * th) as usize], lines)
            }
        };
        hud::draw(&mut tile, tw, th, &lines, scale);
        let (x0, y0) = (GAP + (i % cols) as u32 * (tw + GAP), GAP + (i / cols) as u32 * (th + GAP));
        for y in 0..th {
            let dst = ((y0 + y) * sw + x0) as usize;
            sheet[dst..dst + tw as usize].copy_from_slice(&tile[(y * tw) as usize..((y + 1) * tw) as usize]);
        }
    }
    (sw, sh, sheet)
}

/// The frame's colours shrunk by `k` (box filter over k × k pixels) to `tw × th`.
fn shrink(fb: &Framebuffer, k: u32, tw: u32, th: u32) -> Vec<[u8; 4]> {
    let (w, h) = (fb.width(), fb.height());
    let mut out = Vec::with_capacity((tw * th) as usize);
    for ty in 0..th {
        for tx in 0..tw {
            let (mut sum, mut n) = ([0u32; 3], 0u32);
            for y in ty * k..((ty + 1) * k).min(h) {
                for x in tx * k..((tx + 1) * k).min(w) {
                    let c = fb.color[fb.index(x, y)];
                    (0..3).for_each(|j| sum[j] += c[j] as u32);
                    n += 1;
                }
            }
            let n = n.max(1);
            out.push([(sum[0] / n) as u8, (sum[1] / n) as u8, (sum[2] / n) as u8, 255]);
        }
    }
    out
}

/// `text` broken into lines of at most `width` characters, at spaces where it can be.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let last = lines.last_mut().expect("never empty");
        if !last.is_empty() && last.chars().count() + 1 + word.chars().count() > width {
            lines.push(String::new());
        }
        let last = lines.last_mut().expect("never empty");
        if !last.is_empty() {
            last.push(' ');
        }
        last.push_str(word);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reasons_wrap_at_spaces() {
        assert_eq!(
            wrap("warnock takes at most 131072 triangles", 12),
            ["warnock", "takes at", "most 131072", "triangles"]
        );
        assert_eq!(wrap("", 5), [""]);
        assert_eq!(wrap("averyveryverylongword x", 5), ["averyveryverylongword", "x"]);
    }
}

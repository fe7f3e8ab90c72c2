//! `sightline lab`: one view drawn by every visibility method, side by side, with the
//! z-buffer as referee; or, with `--scaling`, every method's time over a family of cities.

mod methods;
mod report;
mod scaling;

use std::path::PathBuf;

use anyhow::Result;
use sightline::render::{shade_pass, Framebuffer};
use sightline::scene::{Camera, Scene};

use super::common::{self, CameraArgs, Size};
use methods::{Lab, METHODS, REFEREE};
use report::{Outcome, Row, ViewInfo};

#[derive(Debug, clap::Args)]
#[command(after_help = "Writes into DIR: contact_sheet.png (every method's image, labelled with its name, time and \
    agreement), diff_<method>.png (pixels whose triangle ID differs from the z-buffer's, in red), lab.md (the table) \
    and lab.json. Methods that take fewer triangles than the scene has are listed as refused, with their limit. \
    With --scaling: scaling.png (time against triangle count, log-log, a line per method) and scaling.csv, over \
    city:1000, city:3000, city:10000, city:30000 and city:100000, each framed whole.")]
pub struct LabArgs {
    #[command(flatten)]
    pub scene: super::SceneArg,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Image size
    #[arg(long, default_value = "1280x720")]
    pub size: Size,
    /// Output folder
    #[arg(short, long, value_name = "DIR")]
    pub out: PathBuf,
    /// Also write the summary (lab.json's content) to FILE (`-`: standard output)
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Run each method N times and report the median time (1 to 100)
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
    /// Instead of one view: time every method on a family of cities from 10^3 to 10^5
    /// triangles (each framed whole) and chart time against triangle count
    #[arg(long, conflicts_with_all = ["scene", "path", "eye", "target"])]
    pub scaling: bool,
    /// Worker threads, 1 to 256 (default: all cores)
    #[arg(short = 'j', long, value_parser = common::threads_arg)]
    pub threads: Option<usize>,
}

pub fn run(a: &LabArgs) -> Result<()> {
    common::check_outputs(&[&a.out], a.json.as_deref().as_slice())?;
    if a.scaling {
        return scaling::run(a);
    }
    let loaded = super::load_scene(&a.scene)?;
    let camera = a.camera.choice(super::describe(&a.scene.scene)).camera(&loaded, a.size)?;
    let scene = &loaded.scene;
    let bar = progress(METHODS.len() as u64);
    let rows = common::with_threads(a.threads, || draw_view(scene, &camera, a.size, a.repeat, true, &bar))??;
    bar.finish_and_clear();
    let info = ViewInfo {
        scene: super::describe(&a.scene.scene),
        triangles: scene_triangles(scene),
        width: a.size.width,
        height: a.size.height,
        eye: camera.view.eye.into(),
        forward: camera.view.forward().into(),
    };
    let (md, json) = report::write_all(&a.out, &info, &rows)?;
    match &a.json {
        Some(p) if common::is_stdout(p) => {
            eprint!("{md}");
            common::write_json(p, &json, true)?;
        }
        Some(p) => {
            print!("{md}");
            common::write_json(p, &json, true)?;
        }
        None => print!("{md}"),
    }
    eprintln!("lab written to {}", a.out.display());
    Ok(())
}

/// Triangles in the flattened scene (the soup every method draws from).
fn scene_triangles(scene: &Scene) -> usize {
    scene.instances().iter().map(|i| i.triangle_count as usize).sum()
}

/// A progress bar over `n` method runs, on standard error.
fn progress(n: u64) -> indicatif::ProgressBar {
    indicatif::ProgressBar::new(n).with_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} methods {msg} [{elapsed}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    )
}

/// Draws the view with every method that applies, the referee first; a method whose limit
/// is below the scene's size is refused, one that fails is reported with its error. With
/// `shade`, every frame is shaded from its IDs the same way (for the pictures).
fn draw_view(
    scene: &Scene,
    camera: &Camera,
    size: Size,
    repeat: u32,
    shade: bool,
    bar: &indicatif::ProgressBar,
) -> Result<Vec<Row>> {
    let mut lab = Lab::new(scene)?;
    let instances = scene.instances();
    // The contact sheet shrinks each frame by a box filter, which antialiases it as well.
    let look = methods::look();
    let mut rows: Vec<Row> = Vec::new();
    for m in METHODS.iter().filter(|m| (m.applies)(scene)) {
        bar.set_message(m.name);
        let refused = m.limit.and_then(|l| lab.soup.check_size(m.name, l).err());
        let outcome = match refused {
            Some(e) => Outcome::NotRun(e.to_string()),
            None => {
                let mut fb = Box::new(Framebuffer::new(size.width, size.height)?);
                match draw_repeated(m, &mut lab, camera, &mut fb, repeat) {
                    Err(e) if m.name == REFEREE => return Err(e),
                    Err(e) => Outcome::NotRun(format!("{e:#}")),
                    Ok(ran) => {
                        if shade && !ran.shaded {
                            shade_pass(scene, &instances, camera, &mut fb, &look.shading, look.background);
                        }
                        let differing = rows
                            .first()
                            .and_then(|r| match &r.outcome {
                                Outcome::Ran { fb: z, .. } => {
                                    Some(z.ids.iter().zip(&fb.ids).filter(|(x, y)| x != y).count())
                                }
                                Outcome::NotRun(_) => None,
                            })
                            .unwrap_or(0);
                        Outcome::Ran { ran, fb, differing }
                    }
                }
            }
        };
        rows.push(Row { method: m.name, limit: m.limit, outcome });
        bar.inc(1);
    }
    Ok(rows)
}

/// Runs a method `repeat` times: the last frame, the median time.
fn draw_repeated(
    m: &methods::LabMethod,
    lab: &mut Lab,
    camera: &Camera,
    fb: &mut Framebuffer,
    repeat: u32,
) -> Result<methods::Ran> {
    let mut times = Vec::with_capacity(repeat as usize);
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let ran = m.draw(lab, camera, fb)?;
        times.push(ran.ms);
        last = Some(ran);
    }
    times.sort_by(f64::total_cmp);
    let mut ran = last.expect("at least one run");
    ran.ms = times[times.len() / 2];
    Ok(ran)
}

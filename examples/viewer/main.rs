//! An interactive window onto any scene: fly or walk through it, switch the visibility
//! method and the picture live, and read what each frame cost.
//!
//! The window is winit's, its pixels go through softbuffer (no GPU anywhere): each frame is
//! rendered by the engine into its framebuffer, then written once into the window's buffer —
//! converted from RGBA to the window's 0RGB words, or mapped from depth, IDs, depth-test
//! counts or a z-pyramid level, in the same pass — with the readout drawn over it
//! (`sightline::hud`). The modules: `engine` (every call into sightline), `fly` (the camera
//! controller), `views` (the pictures), `app` (the window and its events).
//!
//! The start camera takes `sightline render`'s options: `--path FILE --frame N`, `--eye
//! --target [--up] [--fov]`, `--near`/`--far`, or the file's own `--camera N`. That camera is
//! drawn exactly until the first move (R returns to it); flying keeps +y up.
//!
//! `--screenshot FILE --after-frames N` draws N frames, reads the window's pixels back from
//! the X server and saves them as PNG, then exits: what a test compares with
//! `sightline render` of the same camera.

#![forbid(unsafe_code)]

mod app;
mod engine;
mod fly;
mod views;

use std::path::PathBuf;

use clap::Parser;
use glam::Vec3;
use sightline::SceneSpec;

use engine::Method;
use views::View;

/// The keys, for `--help` and the README.
pub const KEYS: &str = "\
Keys:
  W A S D          move forward / left / back / right
  Q E              down / up (fly mode)
  mouse drag       look around (left or right button held)
  arrow keys       look around
  C                capture the mouse for looking (C or Esc releases it)
  Shift / Ctrl     move 5x faster / 5x slower; mouse wheel: change the speed
  G                walk mode on/off (eye height above the ground, moves stay level)
  1 2 3 4 5        method: brute, frustum, hzb, octree-hzb, raycast
  V / Shift+V      next / previous view: color, depth, ids, complexity, culling, hzb
  + / -            z-pyramid level shown in the hzb view
  K                culling view: freeze the classifying camera (fly out to see its frustum)
  L                wireframe: edges of the triangles the frame shows, over the color view
  H                readout on/off
  F12 or P         save a screenshot (viewer-NNNN.png in the current folder)
  Space            pause / play the scene's animations (city+traffic:N, animated glTF)
  R or Home        back to the start camera
  Esc              release the mouse, or quit";

/// An interactive window onto a scene (winit + softbuffer, drawn on the CPU).
#[derive(Debug, Parser)]
#[command(name = "viewer", after_help = KEYS)]
pub struct Args {
    /// Scene: a .gltf/.glb/.obj file, `city` (default, ≥ 10^6 triangles), `city:TRIS` (10^3 to 10^9),
    /// `city+traffic:N` (N vehicles and tower cranes, animated), or `boxfield`
    #[arg(short, long, default_value = "city", value_name = "SCENE")]
    pub scene: SceneSpec,
    /// Animation time at the start, in seconds (animated scenes play on from it)
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0, value_parser = sightline::args::parse_time)]
    pub time: f32,
    /// Start with the animations paused (Space plays them)
    #[arg(long)]
    pub paused: bool,
    /// Let a scene file read from DIR too (repeatable)
    #[arg(long = "allow-asset-root", value_name = "DIR")]
    pub allow_asset_roots: Vec<PathBuf>,
    /// Visibility method at the start (keys 1–5 switch it)
    #[arg(short, long, value_enum, default_value = "hzb")]
    pub method: Method,
    /// Picture at the start (V switches it)
    #[arg(long, value_enum, default_value = "color")]
    pub view: View,
    /// Camera path JSON (see `sightline path`): start from its frame --frame, as `sightline
    /// render --path FILE --frame N` draws it
    #[arg(short, long, value_name = "FILE", conflicts_with_all = ["eye", "target"])]
    pub path: Option<PathBuf>,
    /// Frame of --path to start from
    #[arg(long, default_value_t = 0, requires = "path")]
    pub frame: usize,
    /// Eye position x,y,z (with --target; default: the street walk's start in a city, a
    /// three-quarter view of anything else)
    #[arg(long, value_parser = sightline::args::parse_vec3, allow_hyphen_values = true, requires = "target")]
    pub eye: Option<Vec3>,
    /// Point looked at x,y,z (with --eye)
    #[arg(long, value_parser = sightline::args::parse_vec3, allow_hyphen_values = true, requires = "eye")]
    pub target: Option<Vec3>,
    /// Up direction x,y,z (with --eye; default 0,1,0). The start view uses it exactly; flying
    /// keeps +y up
    #[arg(long, value_parser = sightline::args::parse_vec3, allow_hyphen_values = true, requires = "eye")]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees (with --eye)
    #[arg(long, default_value_t = 60.0, requires = "eye")]
    pub fov: f32,
    /// Near plane distance (default: the path's, or 0.1)
    #[arg(long)]
    pub near: Option<f32>,
    /// Far plane distance (default: the path's, or past the scene)
    #[arg(long)]
    pub far: Option<f32>,
    /// Start from the scene file's own camera N (glTF cameras, numbered from 0 in the order
    /// the file's nodes place them; `sightline info` counts them), as `sightline render
    /// --camera N` does: its position, orientation, field of view, near and far, the width
    /// fitted to the window
    #[arg(long = "camera", value_name = "N", conflicts_with_all = ["path", "eye", "target", "near", "far"])]
    pub file_camera: Option<usize>,
    /// Initial window size (inner, in pixels)
    #[arg(long, default_value = "1280x720", value_parser = sightline::args::parse_size)]
    pub size: (u32, u32),
    /// Save the window's pixels to this PNG after --after-frames frames, then exit
    #[arg(long, value_name = "FILE.png")]
    pub screenshot: Option<PathBuf>,
    /// Frames to draw before --screenshot is taken
    #[arg(long, value_name = "N", default_value_t = 3, requires = "screenshot")]
    pub after_frames: u32,
    /// No readout over the picture
    #[arg(long)]
    pub no_hud: bool,
    /// Start with the wireframe on
    #[arg(long)]
    pub wireframe: bool,
    /// Worker threads (default: all cores)
    #[arg(short = 'j', long, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub threads: Option<u16>,
}

fn main() {
    let args = Args::parse();
    if let Some(p) = &args.screenshot {
        if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            eprintln!("error: --screenshot {}: give a .png file", p.display());
            std::process::exit(2);
        }
    }
    if let Err(e) = app::run(args) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

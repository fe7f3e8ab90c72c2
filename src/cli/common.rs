//! Options shared by `render`, `walk` and `bench`: image size, threads, camera choice,
//! shading switches.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::Vec3;
use sightline::render::{Antialias, DepthFormat, RenderOptions, ShadeOptions, ShadingMode, Sky, Wireframe};
use sightline::scene::path::CameraKey;
use sightline::scene::Camera;
use sightline::LoadedScene;

/// `WIDTHxHEIGHT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl std::str::FromStr for Size {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (width, height) = sightline::args::parse_size(s)?;
        Ok(Size { width, height })
    }
}

impl std::fmt::Display for Size {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

impl Size {
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }
}

pub use sightline::args::parse_vec3;

/// `on|off`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

impl OnOff {
    pub fn on(self) -> bool {
        self == OnOff::On
    }
}

/// Shading switches for pictures.
#[derive(Debug, Clone, clap::Args)]
pub struct Look {
    /// Shading: none (depth and IDs only), flat, gouraud, per-pixel
    #[arg(long, value_enum, default_value = "flat")]
    pub shading: ShadingArg,
    /// Supersampling of the pictures written (PNG frames and images; 1 = off): each pixel is
    /// the average of s×s samples. Triangle IDs, depth, counters and timed frames always
    /// take one sample per pixel, at its centre
    /// (off, 2x2, 4x4; or 1, 2, 4)
    #[arg(long, visible_alias = "supersample", value_name = "off|2x2|4x4", value_parser = sightline::args::parse_aa, default_value = "2x2")]
    pub aa: Antialias,
    /// The background of the pictures: a gradient sky, or the flat clear colour
    #[arg(long, value_enum, default_value = "on")]
    pub sky: OnOff,
    /// Wireframe drawing (Bresenham lines); hidden-line: only the edges the depth buffer shows
    #[arg(long, value_enum, default_value = "off")]
    pub wireframe: WireArg,
    /// Depth buffer format
    #[arg(long, value_enum, default_value = "f32")]
    pub depth_format: DepthArg,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ShadingArg {
    None,
    Flat,
    Gouraud,
    PerPixel,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum WireArg {
    Off,
    Overlay,
    Only,
    HiddenLine,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DepthArg {
    F32,
    #[value(name = "24")]
    U24,
    #[value(name = "16")]
    U16,
}

impl Look {
    /// The look of the pictures: flat shading in the pictures' light
    /// ([`ShadeOptions::picture`]) in front of the sky, 2×2 supersampled.
    pub fn pictures() -> Self {
        Look {
            shading: ShadingArg::Flat,
            aa: Antialias::Ssaa2x2,
            sky: OnOff::On,
            wireframe: WireArg::Off,
            depth_format: DepthArg::F32,
        }
    }

    /// The options of a picture (`antialias` is the supersampling the pictures get; a frame
    /// whose IDs or time count is drawn with it off, see [`Look::frame_options`]).
    pub fn options(&self, backface: OnOff) -> RenderOptions {
        let shading = ShadeOptions { sky: self.sky.on().then(Sky::default), ..ShadeOptions::picture() };
        let mut o = RenderOptions { backface_culling: backface.on(), shading, ..Default::default() };
        o.shading.mode = match self.shading {
            ShadingArg::None => ShadingMode::None,
            ShadingArg::Flat => ShadingMode::Flat,
            ShadingArg::Gouraud => ShadingMode::Gouraud,
            ShadingArg::PerPixel => ShadingMode::PerPixel,
        };
        o.antialias = self.aa;
        o.wireframe = match self.wireframe {
            WireArg::Off => Wireframe::Off,
            WireArg::Overlay => Wireframe::Overlay,
            WireArg::Only => Wireframe::Only,
            WireArg::HiddenLine => Wireframe::HiddenLine,
        };
        o.depth_format = match self.depth_format {
            DepthArg::F32 => DepthFormat::F32,
            DepthArg::U24 => DepthFormat::Unorm24,
            DepthArg::U16 => DepthFormat::Unorm16,
        };
        o
    }

    /// The options of a frame whose IDs, depth, counters or time are reported: as
    /// [`Look::options`] with one sample per pixel (the pictures are drawn apart).
    pub fn frame_options(&self, backface: OnOff) -> RenderOptions {
        RenderOptions { antialias: Antialias::Off, ..self.options(backface) }
    }
}

/// The most frames a command renders or a path holds: ten hours at 30 frames a second. A
/// frame count is checked against it before any work (a path of 2^64 frames would try to
/// allocate its keys up front).
pub const MAX_FRAMES: usize = 1_000_000;

/// The most worker threads a command starts (far more than any CPU this runs on has; each
/// thread costs a stack and a share of every frame's synchronization).
pub const MAX_THREADS: usize = 256;

/// Parses `--frames`: a whole number from 1 to [`MAX_FRAMES`].
pub fn frames_arg(s: &str) -> std::result::Result<usize, String> {
    match frame_number_arg(s)? {
        0 => Err("give at least 1 frame".into()),
        n => Ok(n),
    }
}

/// Parses a frame number or count from 0 to [`MAX_FRAMES`] (the ends of `--frame-range`).
pub fn frame_number_arg(s: &str) -> std::result::Result<usize, String> {
    let n: u128 = s.trim().parse().map_err(|_| format!("`{s}` is not a whole number of frames"))?;
    if n > MAX_FRAMES as u128 {
        return Err(format!("{n} frames is more than the {MAX_FRAMES} a command renders"));
    }
    Ok(n as usize)
}

/// Parses a percentage in [0, 100] (`--min-agreement`).
pub fn percent_arg(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(p) if (0.0..=100.0).contains(&p) => Ok(p),
        _ => Err(format!("'{s}' is not a percentage between 0 and 100")),
    }
}

/// Parses `--threads`: a whole number from 1 to [`MAX_THREADS`].
pub fn threads_arg(s: &str) -> std::result::Result<usize, String> {
    let n: u128 = s.trim().parse().map_err(|_| format!("`{s}` is not a whole number of threads"))?;
    if n == 0 || n > MAX_THREADS as u128 {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        return Err(format!("{n} threads: give 1 to {MAX_THREADS} (this machine has {cores} cores)"));
    }
    Ok(n as usize)
}

/// Checks, before any work, that output can be written where the user asked: `dirs` are
/// created (and written to and cleaned up once), each of `files` must be creatable in an
/// existing folder. A long walk then never renders every frame only to fail at the end.
pub fn check_outputs(dirs: &[&Path], files: &[&Path]) -> Result<()> {
    let files: Vec<&Path> = files.iter().copied().filter(|f| !is_stdout(f)).collect();
    for dir in dirs {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let probe = dir.join(".sightline-write-check");
        std::fs::write(&probe, b"").with_context(|| format!("cannot write into output folder {}", dir.display()))?;
        let _ = std::fs::remove_file(&probe);
    }
    for file in &files {
        if file.is_dir() {
            bail!("output file {} is a folder", file.display());
        }
        let parent = file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !parent.is_dir() {
            bail!("cannot write {}: folder {} does not exist", file.display(), parent.display());
        }
        let existed = file.exists();
        std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(file)
            .with_context(|| format!("cannot write output file {}", file.display()))?;
        if !existed {
            let _ = std::fs::remove_file(file);
        }
    }
    Ok(())
}

/// Runs `f` on a rayon pool of `threads` threads (all cores when `None`).
///
/// `f` itself runs on one of the pool's workers, not on the calling thread: a frame makes
/// dozens of parallel calls, and from outside the pool each would hand its work over and
/// sleep until it is done, a context switch per call that cost more than the work itself.
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    match threads {
        None => {}
        Some(0) => bail!("--threads must be at least 1"),
        Some(n) => builder = builder.num_threads(n),
    }
    let pool = builder.build().context("starting the thread pool")?;
    Ok(pool.install(f))
}

/// Reads a camera path file, or makes the scene's street path when none is given.
pub fn path_keys(loaded: &LoadedScene, path: Option<&Path>, frames: Option<usize>) -> Result<Vec<CameraKey>> {
    let mut keys = match path {
        Some(p) => sightline::scene::path::read_path(p)?,
        None => loaded.path(true, frames.unwrap_or(120))?,
    };
    if let Some(n) = frames {
        keys.truncate(n);
    }
    Ok(keys)
}

/// The camera options of `render` and `lab`: a frame of a path, or an eye and a target; with
/// neither, the whole scene framed from its three-quarter view.
#[derive(Debug, Clone, clap::Args)]
pub struct CameraArgs {
    /// Camera path JSON (see `sightline path`); with --frame
    #[arg(short, long, value_name = "FILE", conflicts_with_all = ["eye", "target"])]
    pub path: Option<PathBuf>,
    /// Frame of the path to render (with --path)
    #[arg(long, default_value_t = 0, requires = "path")]
    pub frame: usize,
    /// Eye position x,y,z (with --target)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "target")]
    pub eye: Option<Vec3>,
    /// Point looked at x,y,z (with --eye)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "eye")]
    pub target: Option<Vec3>,
    /// Up direction x,y,z (with --eye; default 0,1,0)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "eye")]
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees (with --eye; default 60)
    #[arg(long, requires = "eye")]
    pub fov: Option<f32>,
    /// Near plane distance (default: the path's, or 0.1)
    #[arg(long)]
    pub near: Option<f32>,
    /// Far plane distance (default: the path's, or beyond the scene)
    #[arg(long)]
    pub far: Option<f32>,
    /// Render through the scene file's own camera N (glTF cameras, numbered from 0 in the
    /// order the file's nodes place them; `sightline info` counts them): its position, field
    /// of view, near and far, the width fitted to --size
    #[arg(long = "camera", value_name = "N", conflicts_with_all = ["path", "eye", "target", "fov", "near", "far"])]
    pub file_camera: Option<usize>,
}

impl CameraArgs {
    /// The camera these options choose (resolved against a scene by [`CameraChoice::camera`]);
    /// `scene_name` is the scene as the user named it, for messages.
    pub fn choice(&self, scene_name: String) -> CameraChoice<'_> {
        CameraChoice {
            eye: self.eye,
            target: self.target,
            up: self.up.unwrap_or(Vec3::Y),
            fov: self.fov.unwrap_or(60.0),
            near: self.near,
            far: self.far,
            path: self.path.as_ref(),
            frame: self.frame,
            file_camera: self.file_camera,
            scene_name,
        }
    }

    /// True when some option picks the view (a path, an eye, a field of view, a file's camera).
    pub fn given(&self) -> bool {
        self.path.is_some()
            || self.eye.is_some()
            || self.target.is_some()
            || self.fov.is_some()
            || self.file_camera.is_some()
    }
}

/// The camera of `render`: `--eye/--target` when given, else frame `frame` of `--path`, else
/// the whole scene framed from its three-quarter view.
pub struct CameraChoice<'a> {
    pub eye: Option<Vec3>,
    pub target: Option<Vec3>,
    pub up: Vec3,
    pub fov: f32,
    pub near: Option<f32>,
    pub far: Option<f32>,
    pub path: Option<&'a PathBuf>,
    pub frame: usize,
    /// `--camera N`: the scene file's own camera N.
    pub file_camera: Option<usize>,
    /// The scene as the user named it, for messages.
    pub scene_name: String,
}

impl CameraChoice<'_> {
    pub fn camera(&self, loaded: &LoadedScene, size: Size) -> Result<Camera> {
        if let Some(n) = self.file_camera {
            return match loaded.scene.camera(n, size.aspect()) {
                Err(sightline::scene::Error::NoSuchCamera { count, .. }) => {
                    let has = match count {
                        0 => "no cameras".to_string(),
                        1 => "1 camera (--camera 0)".to_string(),
                        c => format!("{c} cameras (--camera 0 to {})", c - 1),
                    };
                    bail!("--camera {n}, but {} has {has}", self.scene_name)
                }
                c => c.with_context(|| format!("--camera {n} of {}", self.scene_name)),
            };
        }
        match (self.eye, self.target) {
            (Some(eye), Some(target)) => {
                let b = loaded.scene.world_aabb();
                let reach = if b.is_finite() { (b.center() - eye).length() + b.extent().length() } else { 1000.0 };
                let key = CameraKey {
                    eye: eye.into(),
                    target: target.into(),
                    up: self.up.into(),
                    fovy_deg: self.fov,
                    near: self.near.unwrap_or(0.1),
                    far: self.far.unwrap_or(reach.max(1.0) * 1.5),
                };
                Ok(key.camera(size.aspect())?)
            }
            (None, None) if self.path.is_none() => {
                // No camera given: the whole scene from its three-quarter view.
                let b = loaded.scene.world_aabb();
                let fovy = sightline::scene::Angle::degrees(self.fov);
                let mut cam = sightline::scene::views::framing_camera(&b, fovy, size.aspect())?;
                if self.near.is_some() || self.far.is_some() {
                    let (near, far) =
                        (self.near.unwrap_or(cam.projection.near()), self.far.unwrap_or(cam.projection.far()));
                    cam.projection = sightline::scene::Projection::perspective(fovy, size.aspect(), near, far)?;
                }
                Ok(cam)
            }
            (None, None) => {
                let keys = path_keys(loaded, self.path.map(|p| p.as_path()), None)?;
                let key = keys
                    .get(self.frame)
                    .with_context(|| format!("--frame {} but the path has {} frames", self.frame, keys.len()))?;
                let mut key = *key;
                if let Some(n) = self.near {
                    key.near = n;
                }
                if let Some(f) = self.far {
                    key.far = f;
                }
                Ok(key.camera(size.aspect())?)
            }
            _ => bail!("--eye and --target go together"),
        }
    }
}

pub use sightline::args::parse_time as time_arg;

/// Poses the scene's animations at time `t` (seconds) and propagates the transforms.
pub fn pose(scene: &mut sightline::scene::Scene, t: f32) -> Result<()> {
    scene.animate(t).with_context(|| format!("playing the animations at {t} s"))?;
    scene.update_transforms();
    Ok(())
}

/// `-` as an output file: standard output.
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Writes a JSON value to `dest` (`-`: standard output), pretty-printed or on one line.
pub fn write_json(dest: &Path, v: &serde_json::Value, pretty: bool) -> Result<()> {
    let text = if pretty { serde_json::to_string_pretty(v)? } else { v.to_string() };
    if is_stdout(dest) {
        println!("{text}");
        return Ok(());
    }
    std::fs::write(dest, text + "\n").with_context(|| format!("writing {}", dest.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_and_thread_counts_are_checked_before_any_work() {
        assert_eq!(frames_arg("120"), Ok(120));
        assert!(frames_arg("0").unwrap_err().contains("at least 1"));
        assert!(frames_arg("18446744073709551615").unwrap_err().contains("more than"));
        assert!(frames_arg("3000000000").unwrap_err().contains("more than"));
        assert!(frames_arg("99999999999999999999999999999999999999999").unwrap_err().contains("not a whole number"));
        assert!(frames_arg("-1").is_err() && frames_arg("ten").is_err());
        assert_eq!(threads_arg("2"), Ok(2));
        assert!(threads_arg("0").unwrap_err().contains("give 1 to"));
        assert!(threads_arg("10000").unwrap_err().contains("give 1 to"));
    }
}

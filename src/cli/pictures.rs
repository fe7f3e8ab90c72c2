//! The pictures a walk leaves besides its counters: a few frames as PNG and the walk as an
//! animated GIF with the readout (frame number, each method's time and triangles drawn)
//! burned in. Which frames are kept depends only on the frame's number in the camera path
//! and the path's length, so the shards of a walk keep exactly the frames one run keeps.
//!
//! Pictures are supersampled ([`picture`]): drawn apart from the timed frame at s × s
//! samples per pixel and box-filtered down (Crow, "A Comparison of Antialiasing
//! Techniques", 1981), so a walk's times and a frame's IDs never pay for, or change with,
//! the picture.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use sightline::gif_out::{self, GifOut};
use sightline::render::{aa, draw_all, Framebuffer, RayCaster, RaycastOptions, RenderOptions, Renderer};
use sightline::scene::{Camera, Scene};

use super::report::{FrameRecord, WALK_GIF};

/// Every k-th frame of a path of `frames` frames written as PNG by default: about four.
pub fn default_png_every(frames: usize) -> usize {
    frames.div_ceil(4).max(1)
}

/// Widest the GIF gets (frames are shrunk to fit).
pub const GIF_WIDTH: u32 = 480;

/// The PNG frames and the GIF of one walk being written.
pub struct Pictures {
    dir: PathBuf,
    png_every: usize,
    gif_every: usize,
    gif: Option<GifOut>,
    size: (u32, u32),
    path_frames: usize,
}

impl Pictures {
    /// Pictures of a walk of `size` over a path of `path_frames` frames into `dir`: every
    /// `png_every`-th frame as PNG, every `gif_every`-th into `walk.gif` (0: none).
    pub fn new(dir: &Path, size: (u32, u32), path_frames: usize, png_every: usize, gif_every: usize) -> Result<Self> {
        let gif = (gif_every > 0)
            .then(|| GifOut::create(&dir.join(WALK_GIF), size.0, size.1, GIF_WIDTH, gif_out::delay_for(gif_every)))
            .transpose()?;
        Ok(Pictures { dir: dir.to_path_buf(), png_every, gif_every, gif, size, path_frames })
    }

    /// True when frame `f` of the path is kept as a picture.
    pub fn wants(&self, f: usize) -> bool {
        self.wants_png(f) || (self.gif_every > 0 && f.is_multiple_of(self.gif_every))
    }

    /// True when frame `f` of the path is written as PNG.
    pub fn wants_png(&self, f: usize) -> bool {
        self.png_every > 0 && f.is_multiple_of(self.png_every)
    }

    /// Writes frame `f` (its colour, RGBA, and what each method did on it); the PNG gets
    /// `sharp` when given (the frame supersampled: the GIF's shrinking filters enough).
    pub fn add(
        &mut self,
        f: usize,
        color: &[[u8; 4]],
        sharp: Option<&[[u8; 4]]>,
        records: &[FrameRecord],
    ) -> Result<()> {
        let (w, h) = self.size;
        if self.wants_png(f) {
            let p = self.dir.join(format!("frame_{f:04}.png"));
            let png = sharp.unwrap_or(color);
            image::save_buffer(&p, png.as_flattened(), w, h, image::ExtendedColorType::Rgba8)
                .with_context(|| format!("writing {}", p.display()))?;
        }
        if let Some(gif) = self.gif.as_mut().filter(|_| f.is_multiple_of(self.gif_every)) {
            let mut lines = vec![format!("frame {}/{}", f + 1, self.path_frames)];
            for r in records {
                let drawn = if r.method == "raycast" { String::new() } else { format!("  {} tris", r.triangles_drawn) };
                lines.push(format!("{:<12}{:>6.1} ms{drawn}", r.method, r.ms));
            }
            gif.push(color, w, h, |px, gw, gh| {
                sightline::hud::draw(px, gw, gh, &lines, 1);
            })?;
        }
        Ok(())
    }

    /// Finishes the GIF; returns how many frames it holds (`None`: no GIF).
    pub fn finish(self) -> Option<usize> {
        // Dropping the encoder writes the GIF's trailer.
        self.gif.map(|g| g.frames)
    }
}

/// A picture of `scene` seen by `camera`: ray cast with `caster` and its options when
/// given (their shading and background replaced by `opts`'), else rasterized (every
/// instance), supersampled as `opts.antialias` says.
pub fn picture(
    scene: &Scene,
    caster: Option<(&RayCaster, &RaycastOptions)>,
    camera: &Camera,
    opts: &RenderOptions,
    size: (u32, u32),
) -> Result<Vec<[u8; 4]>> {
    let s = opts.antialias.factor();
    let fb = match caster {
        // The ray caster takes one sample per pixel: the picture is cast s times larger and
        // box-filtered down.
        Some((c, ro)) => {
            let ro = RaycastOptions { shading: opts.shading, background: opts.background, ..*ro };
            aa::supersample(size.0, size.1, s, |fb| -> Result<()> {
                c.render(scene, camera, fb, &ro)?;
                Ok(())
            })
        }
        None => raster_picture(scene, camera, opts, size),
    }
    .with_context(|| format!("a {}x{} picture at {s}x{s} samples per pixel", size.0, size.1))?;
    Ok(fb.color.into())
}

/// Every instance rasterized: the renderer supersamples by itself (`opts.antialias`), as it
/// does every frame it draws, the wireframe over the resolved picture.
fn raster_picture(scene: &Scene, camera: &Camera, opts: &RenderOptions, size: (u32, u32)) -> Result<Framebuffer> {
    let mut fb = Framebuffer::new(size.0, size.1)?;
    let instances = scene.instances();
    Renderer::new().render(scene, &instances, &draw_all(&instances), camera, &mut fb, opts)?;
    Ok(fb)
}

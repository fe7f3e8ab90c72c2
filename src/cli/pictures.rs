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
use sightline::render::{
    aa, draw_all, Culler, Framebuffer, Method, RayCaster, RaycastOptions, RenderOptions, Renderer, Wireframe,
};
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

/// [`picture`] rasterized, drawn by `culler` (`hzb-one-pass`, at s × s the size, then
/// box-filtered down as the renderer's own supersampling does) when that draws the same
/// picture: a culled frame's IDs are brute force's, so for a scene whose materials are all
/// opaque and a picture without a wireframe (the culler draws every material opaque, and no
/// wireframe) the colors are too. In big scenes it is far faster: a street picture of the
/// 10^9-triangle city at 2 × 2 samples took about 2.5 s drawing every instance. The one-pass
/// method keeps no state from frame to frame, so the next timed frame is not touched.
pub fn culled_picture(
    culler: &mut Culler,
    scene: &Scene,
    camera: &Camera,
    opts: &RenderOptions,
    size: (u32, u32),
) -> Result<Vec<[u8; 4]>> {
    let opaque = scene.materials().all(|(_, m)| m.alpha_mode.is_opaque());
    if !opaque || opts.wireframe != Wireframe::Off {
        return picture(scene, None, camera, opts, size);
    }
    let s = opts.antialias.factor();
    let fb = aa::supersample(size.0, size.1, s, |fb| -> Result<()> {
        culler.render(scene, camera, Method::HzbOnePass, fb, opts)?;
        Ok(())
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use sightline::render::Antialias;
    use sightline::scene::builders::{city, CityParams};
    use sightline::scene::Material;

    fn street_camera(c: &sightline::scene::builders::City, k: usize) -> Camera {
        c.layout.street_path(4, 3)[k].camera(16.0 / 9.0).unwrap()
    }

    /// The culled picture is the plain one, pixel for pixel, at every supersampling factor.
    #[test]
    fn culled_pictures_equal_the_plain_ones() {
        let c = city(&CityParams::for_triangles(30_000)).unwrap();
        let mut culler = Culler::new(&c.scene);
        for (k, aa) in [(0, Antialias::Off), (1, Antialias::Ssaa2x2), (2, Antialias::Ssaa4x4)] {
            let opts = RenderOptions { antialias: aa, ..RenderOptions::default() };
            let cam = street_camera(&c, k);
            let plain = picture(&c.scene, None, &cam, &opts, (96, 54)).unwrap();
            let culled = culled_picture(&mut culler, &c.scene, &cam, &opts, (96, 54)).unwrap();
            assert!(plain.iter().collect::<std::collections::HashSet<_>>().len() > 10, "{aa:?}: a picture of nothing");
            assert!(plain == culled, "{aa:?}: the culled picture differs");
        }
    }

    /// What the culler would draw otherwise (a see-through material, a wireframe) is drawn by
    /// the plain renderer.
    #[test]
    fn pictures_the_culler_would_draw_otherwise_are_drawn_plainly() {
        let mut c = city(&CityParams::for_triangles(30_000)).unwrap();
        let mut culler = Culler::new(&c.scene);
        let cam = street_camera(&c, 0);
        let wire = RenderOptions { wireframe: Wireframe::Overlay, ..RenderOptions::default() };
        let plain = picture(&c.scene, None, &cam, &wire, (96, 54)).unwrap();
        assert!(plain == culled_picture(&mut culler, &c.scene, &cam, &wire, (96, 54)).unwrap(), "wireframe");
        // Every instance see-through: the culler would draw it opaque.
        let glass = c.scene.add_material(Material::translucent("glass", [0.2, 0.5, 0.9], 0.4));
        // Every other instance, so that the glass has something behind it.
        for inst in c.scene.instances().into_iter().step_by(2) {
            c.scene.set_material(inst.node, Some(glass)).unwrap();
        }
        c.scene.update_transforms();
        let opts = RenderOptions::default();
        let plain = picture(&c.scene, None, &cam, &opts, (96, 54)).unwrap();
        let mut culler = Culler::new(&c.scene);
        assert!(plain == culled_picture(&mut culler, &c.scene, &cam, &opts, (96, 54)).unwrap(), "blended");
    }
}

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
    aa, draw_all, Culler, Framebuffer, Method, Plane, RayCaster, RaycastOptions, RenderOptions, Renderer,
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

/// What draws a picture.
pub enum Painter<'a> {
    /// The plain renderer, every instance.
    Plain,
    /// A culler (`hzb-one-pass`), drawing with a renderer kept for pictures
    /// ([`Culler::with_renderer`]: the culler's own buffers stay sized for the timed frames),
    /// when its frames show what the plain renderer's show
    /// ([`Culler::draws_like_renderer`]); else the plain renderer. A culled frame has brute
    /// force's IDs, so the picture is the same, far faster in big scenes: a street picture of
    /// the 10^9-triangle city at 2 × 2 samples took about 2.5 s drawing every instance.
    /// One-pass culling keeps no state from frame to frame.
    Culler(&'a mut Culler, &'a mut Renderer),
    /// The ray caster and its options (their shading and background replaced by the
    /// picture's).
    Rays(&'a RayCaster, &'a RaycastOptions),
}

/// A picture of `scene` seen by `camera`, drawn by `painter`, supersampled as
/// `opts.antialias` says: the color plane of the drawn frame.
pub fn picture(
    scene: &Scene,
    painter: Painter,
    camera: &Camera,
    opts: &RenderOptions,
    size: (u32, u32),
) -> Result<Plane<[u8; 4]>> {
    let s = opts.antialias.factor();
    let fb = match painter {
        // The ray caster and the culler take one sample per pixel: the picture is drawn s
        // times larger and box-filtered down.
        Painter::Rays(c, ro) => {
            let ro = RaycastOptions { shading: opts.shading, background: opts.background, ..*ro };
            aa::supersample(size.0, size.1, s, |fb| -> Result<()> {
                c.render(scene, camera, fb, &ro)?;
                Ok(())
            })
        }
        Painter::Culler(culler, renderer) if Culler::draws_like_renderer(scene, opts) => {
            culled_picture(culler, renderer, scene, camera, opts, size)
        }
        Painter::Culler(..) | Painter::Plain => raster_picture(scene, camera, opts, size),
    }
    .with_context(|| format!("a {}x{} picture at {s}x{s} samples per pixel", size.0, size.1))?;
    Ok(fb.color)
}

/// The culler's frame (`hzb-one-pass`, drawn with `renderer`) at s × s the size,
/// box-filtered down, s as `opts.antialias` says: what the culler paints.
fn culled_picture(
    culler: &mut Culler,
    renderer: &mut Renderer,
    scene: &Scene,
    camera: &Camera,
    opts: &RenderOptions,
    size: (u32, u32),
) -> Result<Framebuffer> {
    aa::supersample(size.0, size.1, opts.antialias.factor(), |fb| -> Result<()> {
        culler.with_renderer(renderer, |c| c.render(scene, camera, Method::HzbOnePass, fb, opts))?;
        Ok(())
    })
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
    use sightline::render::{Antialias, Wireframe};
    use sightline::scene::builders::{city, CityParams};
    use sightline::scene::Material;

    const SIZE: (u32, u32) = (96, 54);

    fn street_camera(c: &sightline::scene::builders::City, k: usize) -> Camera {
        c.layout.street_path(4, 3)[k].camera(16.0 / 9.0).unwrap()
    }

    /// What the culler would paint, whether or not `picture` lets it.
    fn culler_alone(culler: &mut Culler, scene: &Scene, cam: &Camera, opts: &RenderOptions) -> Vec<[u8; 4]> {
        culled_picture(culler, &mut Renderer::new(), scene, cam, opts, SIZE).unwrap().color.into()
    }

    /// For an opaque city the culler paints (`draws_like_renderer`), and its picture is the
    /// plain one, pixel for pixel, at every supersampling factor.
    #[test]
    fn culled_pictures_equal_the_plain_ones() {
        let c = city(&CityParams::for_triangles(30_000)).unwrap();
        let (mut culler, mut renderer) = (Culler::new(&c.scene), Renderer::new());
        for (k, aa) in [(0, Antialias::Off), (1, Antialias::Ssaa2x2), (2, Antialias::Ssaa4x4)] {
            let opts = RenderOptions { antialias: aa, ..RenderOptions::default() };
            assert!(Culler::draws_like_renderer(&c.scene, &opts), "{aa:?}");
            let cam = street_camera(&c, k);
            let plain = picture(&c.scene, Painter::Plain, &cam, &opts, SIZE).unwrap();
            let culled = picture(&c.scene, Painter::Culler(&mut culler, &mut renderer), &cam, &opts, SIZE).unwrap();
            assert!(plain.iter().collect::<std::collections::HashSet<_>>().len() > 10, "{aa:?}: a picture of nothing");
            assert!(plain == culled, "{aa:?}: the culled picture differs");
            assert!(culled == culler_alone(&mut culler, &c.scene, &cam, &opts), "{aa:?}: not the culler's");
        }
    }

    /// What the culler would paint otherwise (a wireframe, see-through materials) is painted
    /// by the plain renderer, and the culler's own frame would indeed differ.
    #[test]
    fn pictures_the_culler_would_draw_otherwise_are_drawn_plainly() {
        let mut c = city(&CityParams::for_triangles(30_000)).unwrap();
        let mut renderer = Renderer::new();
        let cam = street_camera(&c, 0);
        // Transparency ignored, so that the wireframe alone keeps the culler from painting.
        let wire = RenderOptions {
            wireframe: Wireframe::Overlay,
            transparency: sightline::render::Transparency::Ignore,
            ..RenderOptions::default()
        };
        // Every other instance see-through, so that the glass has something behind it.
        let glass = c.scene.add_material(Material::translucent("glass", [0.2, 0.5, 0.9], 0.4));
        for inst in c.scene.instances().into_iter().step_by(2) {
            c.scene.set_material(inst.node, Some(glass)).unwrap();
        }
        c.scene.update_transforms();
        let opts = RenderOptions::default();
        let mut culler = Culler::new(&c.scene);
        for (what, o) in [("wireframe", &wire), ("glass", &opts)] {
            assert!(!Culler::draws_like_renderer(&c.scene, o), "{what}");
            let plain = picture(&c.scene, Painter::Plain, &cam, o, SIZE).unwrap();
            let painted = picture(&c.scene, Painter::Culler(&mut culler, &mut renderer), &cam, o, SIZE).unwrap();
            assert!(plain == painted, "{what}: not drawn plainly");
            assert!(plain != culler_alone(&mut culler, &c.scene, &cam, o), "{what}: the culler would paint it alike");
        }
        // Transparency ignored: the plain renderer draws the glass opaque too.
        let ignored = RenderOptions { transparency: sightline::render::Transparency::Ignore, ..opts };
        assert!(Culler::draws_like_renderer(&c.scene, &ignored));
        let plain = picture(&c.scene, Painter::Plain, &cam, &ignored, SIZE).unwrap();
        assert!(plain == culler_alone(&mut culler, &c.scene, &cam, &ignored), "transparency ignored");
    }
}

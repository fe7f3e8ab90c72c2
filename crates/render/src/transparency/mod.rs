//! Transparency: alpha-masked and blended materials (glTF's `alphaMode`), drawn by an
//! A-buffer or by depth peeling, around the unchanged z-buffer path for opaque surfaces.
//!
//! A frame whose draw list holds only opaque materials (or drawn with
//! [`Transparency::Ignore`]) takes the plain z-buffer path, pixel for pixel and step for
//! step what it always was. Otherwise the draw list is split by material
//! ([`sightline_scene::AlphaMode`]):
//!
//! 1. **Opaque** items: drawn by the tile rasterizer into depth and IDs, as always.
//! 2. **Masked** items (`MASK`): their triangles are set up by the same geometry stage and
//!    their fragments walked with the rasterizer's coverage and depth (`walk.rs`); each
//!    fragment that passes the depth test is alpha-tested (base color factor × texture alpha
//!    at its perspective-correct texture coordinates) before it writes depth and ID
//!    (`mask.rs`). Then the frame is shaded (deferred, from the IDs) like any other.
//! 3. **Blended** items (`BLEND`), over the shaded opaque frame, one of:
//!    * [`Transparency::ABuffer`] (the default, and the reference): per-pixel fragment lists,
//!      sorted by depth and composited back to front with Porter & Duff's "over" (Carpenter,
//!      "The A-buffer, an antialiased hidden surface method", SIGGRAPH 1984; here without
//!      its subpixel coverage masks, see `abuffer.rs`);
//!    * [`Transparency::DepthPeeling`]: k z-buffer passes, each keeping the nearest
//!      fragment behind the previous layer, composited front to back (Everitt,
//!      "Interactive Order-Independent Transparency", 2001; see `peel.rs`).
//!
//! Both blend methods order fragments as the z-buffer does (depth key, then triangle ID),
//! so with enough layers depth peeling reproduces the A-buffer, and coplanar surfaces are
//! neither lost nor doubled. Afterwards the ID and depth planes hold the **nearest surface
//! of any kind**, blended or opaque: the triangle a ray through the pixel center meets
//! first, as the ray caster reports it (masked surfaces only where their alpha passed).
//! Compositing is in the 8-bit color space the shading writes, like a GPU blending into an
//! RGBA8 target without sRGB conversion.
//!
//! [`render_abuffer`] and [`render_depth_peeling`] draw a whole scene one way or the other;
//! [`crate::Renderer::render`] follows [`crate::RenderOptions::transparency`]. The occlusion
//! culler ([`crate::Culler`]) draws every material opaque.

mod abuffer;
mod blend;
mod mask;
mod peel;
mod surface;
mod walk;

use std::sync::atomic::AtomicU64;
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sightline_scene::{AlphaMode, Camera, Instance, Material, Scene};

use crate::geometry::Chunk;
use crate::options::{draw_all, DrawItem, RenderOptions};
use crate::pipeline::{Renderer, Target};
use crate::stats::{ms_since, FrameStats};
use crate::{deferred, Error, Framebuffer, Result};

pub use abuffer::MAX_ABUFFER_FRAGMENTS;
use surface::Surfaces;
use walk::{bands, triangles};

/// How blended (`BLEND`) materials are drawn, and whether alpha modes count at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Transparency {
    /// Alpha modes are ignored: every material is drawn opaque by the z-buffer (the
    /// engine's behaviour before alpha modes, and what the occlusion culler draws).
    Ignore,
    /// Masked materials alpha-tested, blended ones resolved by the A-buffer (the reference).
    #[default]
    ABuffer,
    /// Masked materials alpha-tested, blended ones by depth peeling with at most `layers`
    /// passes (at least 1); fewer layers than the scene's transparent depth complexity drop
    /// the farthest layers.
    DepthPeeling {
        /// The most layers (z-buffer passes) peeled.
        layers: u32,
    },
}

/// Counters of the masked and blended part of a frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TransparencyStats {
    /// How blended materials were drawn.
    pub method: Transparency,
    /// Triangles of masked (`MASK`) instances submitted.
    pub masked_triangles: u64,
    /// Triangles of blended (`BLEND`) instances submitted.
    pub blended_triangles: u64,
    /// Masked fragments that passed the depth test and then the alpha test (and were
    /// written).
    pub masked_fragments_kept: u64,
    /// Masked fragments that passed the depth test but not the alpha test.
    pub masked_fragments_discarded: u64,
    /// Blended fragments in front of the opaque surface: the A-buffer's list entries.
    pub fragments: u64,
    /// Blended fragments rasterized, over every walk (the A-buffer walks once, depth
    /// peeling once to count and once per pass).
    pub fragments_drawn: u64,
    /// Pixels with at least one blended fragment in front of the opaque surface.
    pub pixels: u64,
    /// The most blended fragments in front of the opaque surface at one pixel: the depth
    /// peeling layers the frame needs.
    pub max_fragments_per_pixel: u32,
    /// `fragments / pixels` (0 without blended pixels).
    pub mean_fragments_per_pixel: f64,
    /// Layers composited: the deepest list (A-buffer) or the passes that found a layer
    /// (depth peeling).
    pub layers: u32,
    /// Pixels that had more blended fragments than the layers peeled (depth peeling only):
    /// where the image lacks its farthest layers.
    pub pixels_missing_layers: u64,
    /// Milliseconds of the mask pass.
    pub ms_mask: f64,
    /// Milliseconds of the blend pass (setup, fragments, sort or passes, compositing).
    pub ms_blend: f64,
    /// Milliseconds of the whole frame, opaque part and shading included (set by
    /// [`render_abuffer`] and [`render_depth_peeling`]; 0 inside [`FrameStats`]).
    pub ms_total: f64,
}

impl TransparencyStats {
    /// Adds the counters and timings of another batch (the method is kept).
    pub fn add(&mut self, o: &TransparencyStats) {
        self.masked_triangles += o.masked_triangles;
        self.blended_triangles += o.blended_triangles;
        self.masked_fragments_kept += o.masked_fragments_kept;
        self.masked_fragments_discarded += o.masked_fragments_discarded;
        self.fragments += o.fragments;
        self.fragments_drawn += o.fragments_drawn;
        self.pixels += o.pixels;
        self.max_fragments_per_pixel = self.max_fragments_per_pixel.max(o.max_fragments_per_pixel);
        self.layers = self.layers.max(o.layers);
        self.pixels_missing_layers += o.pixels_missing_layers;
        self.ms_mask += o.ms_mask;
        self.ms_blend += o.ms_blend;
        self.ms_total += o.ms_total;
        self.update_mean();
    }

    fn update_mean(&mut self) {
        self.mean_fragments_per_pixel = if self.pixels > 0 { self.fragments as f64 / self.pixels as f64 } else { 0.0 };
    }

    fn take(&mut self, c: &LayerCounts) {
        self.add(&TransparencyStats {
            fragments: c.fragments,
            fragments_drawn: c.drawn,
            pixels: c.pixels,
            max_fragments_per_pixel: c.max,
            layers: c.layers,
            pixels_missing_layers: c.short,
            ..Default::default()
        });
    }
}

/// Counters of one band of a blend pass.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LayerCounts {
    /// Fragments rasterized.
    pub drawn: u64,
    /// Fragments in front of the opaque surface.
    pub fragments: u64,
    /// Pixels with at least one.
    pub pixels: u64,
    /// The most at one pixel.
    pub max: u32,
    /// Layers composited.
    pub layers: u32,
    /// Pixels with more fragments than layers composited.
    pub short: u64,
}

impl LayerCounts {
    /// Counts a pixel with `n > 0` fragments (and, for the A-buffer, `n` layers).
    fn pixel(&mut self, n: u32) {
        self.fragments += n as u64;
        self.pixels += 1;
        self.max = self.max.max(n);
    }

    fn sum(a: Self, b: Self) -> Self {
        Self {
            drawn: a.drawn + b.drawn,
            fragments: a.fragments + b.fragments,
            pixels: a.pixels + b.pixels,
            max: a.max.max(b.max),
            layers: a.layers.max(b.layers),
            short: a.short + b.short,
        }
    }
}

/// True when some instance of `scene` draws with a blended (`BLEND`) material: when the
/// A-buffer and depth peeling have something to show.
pub fn scene_has_transparency(scene: &Scene) -> bool {
    if scene.materials().all(|(_, m)| m.alpha_mode != AlphaMode::Blend) {
        return false;
    }
    scene.instances().iter().any(|i| mode_of(scene, i) == AlphaMode::Blend)
}

/// Renders every instance of `scene` (world transforms up to date) into `fb`, blended
/// materials by the A-buffer, masked ones alpha-tested; every plane is written (the ID and
/// depth planes hold the nearest surface, blended or opaque). The counters are those of
/// [`TransparencyStats`] (all zero but `ms_total` for a scene without masked or blended
/// materials).
pub fn render_abuffer(
    scene: &Scene,
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &RenderOptions,
) -> Result<TransparencyStats> {
    render_with(scene, camera, fb, opts, Transparency::ABuffer)
}

/// Like [`render_abuffer`], with blended materials drawn by depth peeling of at most
/// `layers` layers (at least 1). With `layers` ≥ the frame's
/// [`TransparencyStats::max_fragments_per_pixel`] the colors equal the A-buffer's within
/// 1/255 per channel; with fewer, the farthest layers are missing (1, 2, 4, … show how the
/// image degrades). `layers = 0` is an error.
pub fn render_depth_peeling(
    scene: &Scene,
    camera: &Camera,
    fb: &mut Framebuffer,
    layers: u32,
    opts: &RenderOptions,
) -> Result<TransparencyStats> {
    render_with(scene, camera, fb, opts, Transparency::DepthPeeling { layers })
}

fn render_with(
    scene: &Scene,
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &RenderOptions,
    method: Transparency,
) -> Result<TransparencyStats> {
    let instances = scene.instances();
    let items = draw_all(&instances);
    let opts = RenderOptions { transparency: method, ..*opts };
    let st = Renderer::new().render(scene, &instances, &items, camera, fb, &opts)?;
    let mut t = st.transparency.unwrap_or(TransparencyStats { method, ..Default::default() });
    t.ms_total = st.ms_total;
    Ok(t)
}

fn mode_of(scene: &Scene, inst: &Instance) -> AlphaMode {
    inst.material.and_then(|m| scene.material(m)).map_or(AlphaMode::Opaque, |m| m.alpha_mode)
}

/// A draw list split by alpha mode.
pub(crate) struct Routes {
    opaque: Vec<DrawItem>,
    masked: Vec<DrawItem>,
    blended: Vec<DrawItem>,
}

impl Routes {
    /// The split of `items`, or `None` when every item is opaque (or `how` ignores alpha
    /// modes): the plain z-buffer path then draws the frame. A depth peeling of 0 layers is
    /// an error.
    pub(crate) fn of(
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        how: Transparency,
    ) -> Result<Option<Self>> {
        match how {
            Transparency::Ignore => return Ok(None),
            Transparency::DepthPeeling { layers: 0 } => {
                return Err(Error::InvalidOptions("depth peeling needs at least 1 layer, got 0".into()))
            }
            _ => {}
        }
        // The common case costs a look at the materials, not at the draw list.
        if scene.materials().all(|(_, m)| m.alpha_mode.is_opaque()) {
            return Ok(None);
        }
        let mut r = Routes { opaque: Vec::new(), masked: Vec::new(), blended: Vec::new() };
        for d in items {
            // An item naming no instance stays in the opaque list, whose resolution reports it.
            let mode = instances.get(d.instance as usize).map_or(AlphaMode::Opaque, |i| mode_of(scene, i));
            match mode {
                AlphaMode::Opaque => r.opaque.push(*d),
                AlphaMode::Mask { .. } => r.masked.push(*d),
                AlphaMode::Blend => r.blended.push(*d),
            }
        }
        Ok((!r.masked.is_empty() || !r.blended.is_empty()).then_some(r))
    }
}

/// Adds the geometry stage's counters of `chunks` to `st` (their set-up triangles count as
/// rasterized).
fn count_set_up(chunks: &[Chunk], st: &mut FrameStats) {
    for c in chunks {
        st.add(&c.stats);
        st.rasterized += c.tris.len() as u64;
    }
}

fn triangles_of(items: &[DrawItem]) -> u64 {
    items.iter().map(|d| d.count as u64).sum()
}

/// The filled part of a frame with masked or blended items: opaque items by the z-buffer,
/// masked ones alpha-tested into it, deferred shading, then the blended ones by the method
/// `opts.transparency` names. Every plane of `fb` is written.
pub(crate) fn draw_frame(
    renderer: &mut Renderer,
    scene: &Scene,
    instances: &[Instance],
    routes: &Routes,
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &RenderOptions,
) -> Result<FrameStats> {
    let t0 = Instant::now();
    let size = (fb.width(), fb.height());
    let fmt = opts.depth_format;
    let mut ts = TransparencyStats {
        method: opts.transparency,
        masked_triangles: triangles_of(&routes.masked),
        blended_triangles: triangles_of(&routes.blended),
        ..Default::default()
    };
    let fresh = Target::Frame { fb: &mut *fb, fresh: true };
    let mut st = renderer.draw_items(scene, instances, &routes.opaque, camera, fresh, opts)?;
    let default = Material::default();
    let surfaces = Surfaces::new(scene, instances, camera, &default, &opts.shading, size);

    if !routes.masked.is_empty() {
        let t = Instant::now();
        let chunks = renderer.set_up(scene, instances, &routes.masked, camera, size, opts)?;
        count_set_up(chunks, &mut st);
        let tris = triangles(chunks);
        let n = bands(fb).into_par_iter().map(|mut b| mask::draw_masked(&mut b, tris.clone(), &surfaces, fmt)).reduce(
            mask::MaskCount::default,
            |a, b| mask::MaskCount {
                tested: a.tested + b.tested,
                passed: a.passed + b.passed,
                written: a.written + b.written,
            },
        );
        st.fragments_tested += n.tested;
        st.fragments_written += n.written;
        ts.masked_fragments_kept = n.written;
        ts.masked_fragments_discarded = n.passed - n.written;
        ts.ms_mask = ms_since(t);
    }

    let t = Instant::now();
    deferred::shade_pass(scene, instances, camera, fb, &opts.shading, opts.background);
    st.ms_shading = ms_since(t);

    if !routes.blended.is_empty() {
        let t = Instant::now();
        let chunks = renderer.set_up(scene, instances, &routes.blended, camera, size, opts)?;
        count_set_up(chunks, &mut st);
        let tris = triangles(chunks);
        let counts = match opts.transparency {
            Transparency::DepthPeeling { layers } => bands(fb)
                .into_par_iter()
                .map(|mut b| peel::peel_band(&mut b, tris.clone(), layers, &surfaces, fmt))
                .reduce(LayerCounts::default, LayerCounts::sum),
            _ => {
                let kept = AtomicU64::new(0);
                bands(fb)
                    .into_par_iter()
                    .map(|mut b| abuffer::resolve_band(&mut b, tris.clone(), &surfaces, fmt, &kept))
                    .reduce(|| Some(LayerCounts::default()), |a, b| Some(LayerCounts::sum(a?, b?)))
                    .ok_or(Error::TooManyFragments { method: "the A-buffer", limit: MAX_ABUFFER_FRAGMENTS })?
            }
        };
        ts.take(&counts);
        ts.ms_blend = ms_since(t);
    }
    st.transparency = Some(ts);
    st.covered_pixels = fb.ids.par_iter().filter(|&&id| id != 0).count() as u64;
    st.update_overdraw();
    st.ms_total = ms_since(t0);
    Ok(st)
}

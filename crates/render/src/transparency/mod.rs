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
mod frame;
mod mask;
mod peel;
pub(crate) mod stats;
mod surface;
mod walk;

use sightline_scene::{AlphaMode, Camera, Scene};

use crate::options::{draw_all, RenderOptions};
use crate::pipeline::Renderer;
use crate::{Framebuffer, Result};

pub use abuffer::MAX_ABUFFER_FRAGMENTS;
use frame::mode_of;
pub(crate) use stats::LayerCounts;
pub use stats::{Transparency, TransparencyStats};

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

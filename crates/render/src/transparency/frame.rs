//! The frame driver for scenes with masked or blended materials: the draw list split by
//! alpha mode ([`Routes`]), then opaque, masked and blended items drawn in that order (see the
//! parent module). It is a [`Renderer`] method, so that the pipeline reaches it without
//! importing this module.

use std::sync::atomic::AtomicU64;
use std::time::Instant;

use rayon::prelude::*;
use sightline_scene::{AlphaMode, Camera, Instance, Scene};

use super::abuffer::{self, MAX_ABUFFER_FRAGMENTS};
use super::stats::{LayerCounts, Transparency, TransparencyStats};
use super::surface::Surfaces;
use super::walk::{bands, triangles};
use super::{mask, peel};
use crate::geometry::Chunk;
use crate::options::{DrawItem, RenderOptions};
use crate::pipeline::{Renderer, Target};
use crate::stats::{ms_since, FrameStats};
use crate::{deferred, Error, Framebuffer, Result};

impl Renderer {
    /// Draws the filled part of a frame whose draw list has masked or blended items (and
    /// `opts.transparency` does not ignore them); `None`, drawing nothing, when the plain
    /// z-buffer path should draw it.
    pub(crate) fn draw_with_transparency(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<Option<FrameStats>> {
        match Routes::of(scene, instances, items, opts.transparency)? {
            Some(routes) => draw_frame(self, scene, instances, &routes, camera, fb, opts).map(Some),
            None => Ok(None),
        }
    }
}

pub(super) fn mode_of(scene: &Scene, inst: &Instance) -> AlphaMode {
    scene.instance_material(inst).alpha_mode
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
    let surfaces = Surfaces::new(scene, instances, camera, &opts.shading, size);

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

//! The scene-order experiment: the same visible set drawn front to back, back to front and
//! in random order, with and without coarse depth (hierarchical z), to show what ordering
//! buys a z-buffer (front-to-back order is what makes early depth rejection pay, Greene,
//! Kass & Miller 1993); [`Culler::render_ordered`] renders one such frame.

use std::time::Instant;

use serde::Serialize;
use sightline_scene::rng::Rng;
use sightline_scene::Camera;
use sightline_spatial::Frustum;

use super::{CullStats, Culler, Frame};
use crate::pipeline::Target;
use crate::stats::ms_since;
use crate::{FrameStats, Framebuffer, RenderOptions, Result};

/// The order clusters are drawn in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DrawOrder {
    /// Nearest cluster box first.
    FrontToBack,
    /// Farthest first (the painter's order).
    BackToFront,
    /// A seeded shuffle.
    Random(u64),
}

impl DrawOrder {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            DrawOrder::FrontToBack => "front-to-back",
            DrawOrder::BackToFront => "back-to-front",
            DrawOrder::Random(_) => "random",
        }
    }
}

impl Culler {
    /// Draws every cluster in the view frustum in `order`. With `coarse`, it draws in
    /// batches of `batch` clusters inside a frame session, so the rasterizer's coarse depth
    /// test (tile pyramid refreshed after each batch) can reject hidden triangles and blocks;
    /// without, it draws everything in one plain z-buffer pass. The image is the same either
    /// way (the depth test's tie rule makes it independent of order). After an error `fb`
    /// may hold part of the frame.
    #[allow(clippy::too_many_arguments)] // an experiment's knobs
    pub fn render_ordered(
        &mut self,
        camera: &Camera,
        order: DrawOrder,
        coarse: bool,
        batch: usize,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<(CullStats, FrameStats)> {
        let t0 = Instant::now();
        let mut cs = CullStats { clusters: self.c.clustered.item_count() as u64, ..Default::default() };
        fb.clear(opts.background);
        self.c.frustum_cull(&Frustum::from_camera(camera), &mut cs);
        let eye = camera.view.eye;
        let mut items: Vec<(f32, u32)> = self
            .c
            .visible
            .iter()
            .map(|v| {
                let b = &self.c.item_boxes[v.index as usize];
                (eye.clamp(b.min, b.max).distance_squared(eye), v.index)
            })
            .collect();
        match order {
            DrawOrder::FrontToBack => items.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))),
            DrawOrder::BackToFront => items.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1))),
            DrawOrder::Random(seed) => {
                let mut rng = Rng::new(seed);
                for i in (1..items.len()).rev() {
                    items.swap(i, rng.below(i as u32 + 1) as usize);
                }
            }
        }
        cs.ms_cull = ms_since(t0);
        let t = Instant::now();
        let mut f = Frame { camera, opts, cs, fs: FrameStats::default() };
        if coarse {
            let mut session = self.renderer.begin(fb, opts);
            for chunk in items.chunks(batch.max(1)) {
                let sources = self.c.sources(chunk, |x| x.1, &mut f.cs);
                f.fs.add(&session.draw_sources_checked(&sources, camera, false)?);
                f.cs.batches += 1;
            }
            f.fs.covered_pixels = session.finish();
        } else {
            let sources = self.c.sources(&items, |x| x.1, &mut f.cs);
            let target = Target::Frame { fb: &mut *fb, fresh: false };
            f.fs.add(&self.renderer.draw_sources_to(&sources, camera, target, opts, false)?);
            f.cs.batches = 1;
        }
        let Frame { mut cs, mut fs, .. } = f;
        cs.ms_draw = ms_since(t);
        cs.ms_total = ms_since(t0);
        fs.ms_total = cs.ms_total;
        Ok((cs, fs))
    }
}

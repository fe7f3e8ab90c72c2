//! What blended materials are drawn with, and what the transparent part of a frame did: the
//! types that the render options and the frame statistics carry, kept apart from the drawing
//! so that those modules depend on nothing else of transparency.

use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::{render_abuffer, render_depth_peeling};
#[cfg(doc)]
use crate::FrameStats;

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

    pub(super) fn take(&mut self, c: &LayerCounts) {
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
    pub(super) fn pixel(&mut self, n: u32) {
        self.fragments += n as u64;
        self.pixels += 1;
        self.max = self.max.max(n);
    }

    pub(super) fn sum(a: Self, b: Self) -> Self {
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

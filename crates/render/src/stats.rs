//! Per-frame counters and stage timings.
//!
//! Triangle accounting: every submitted triangle is trivially rejected, back-face culled,
//! degenerate, or goes on either unclipped or through the clipper; the triangles that reach
//! setup (unclipped ones plus clipper output) end up degenerate, too small (no pixel center
//! covered) or rasterized.

use serde::{Deserialize, Serialize};

use crate::transparency::stats::TransparencyStats;

/// Counters of one frame (or of one `draw` batch; [`FrameStats::add`] sums batches).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameStats {
    /// Triangles submitted.
    pub triangles_in: u64,
    /// Dropped by the outcode test (all vertices outside one frustum plane) or because a
    /// vertex was NaN or infinite.
    pub trivially_rejected: u64,
    /// Triangles that crossed the near/far planes or the guard band and were clipped.
    pub clipped: u64,
    /// Triangles the clipper produced (fan triangles).
    pub clip_output: u64,
    /// Back faces removed.
    pub backface_culled: u64,
    /// Zero area (after snapping).
    pub degenerate: u64,
    /// Covered no pixel center, or was rejected whole by coarse depth (per tile at binning
    /// or in every 8×8 block it touches).
    pub too_small: u64,
    /// Covered at least one pixel center.
    pub rasterized: u64,
    /// Fragments (covered pixel centers or samples) that were depth-tested.
    pub fragments_tested: u64,
    /// Fragments that passed the depth test and were written.
    pub fragments_written: u64,
    /// Triangle–tile pairs skipped by coarse depth: the triangle's nearest depth lies behind
    /// the farthest depth drawn under its bounding box in the tile (frame sessions only).
    pub coarse_rejected: u64,
    /// Pixels (or samples) holding a triangle at the end of the frame.
    pub covered_pixels: u64,
    /// `fragments_written / covered_pixels`.
    pub overdraw: f64,
    /// Milliseconds in the geometry stage (transform, outcodes, clipping, setup). Each
    /// chunk of triangles is binned right after its setup, in one parallel step; the step's
    /// time is split between this and [`FrameStats::ms_binning`] in proportion to the time
    /// the chunks spent in each.
    pub ms_geometry: f64,
    /// Milliseconds binning triangles to tiles (see [`FrameStats::ms_geometry`]).
    pub ms_binning: f64,
    /// Milliseconds rasterizing tiles (edge functions, depth test).
    pub ms_raster: f64,
    /// Milliseconds in the shading pass (and antialiasing resolve).
    pub ms_shading: f64,
    /// Milliseconds drawing the wireframe.
    pub ms_wireframe: f64,
    /// Whole frame, milliseconds.
    pub ms_total: f64,
    /// Counters of masked and blended materials, when the frame drew some.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub transparency: Option<TransparencyStats>,
}

impl FrameStats {
    /// Adds the counters and timings of another batch (derived ratios are recomputed).
    pub fn add(&mut self, o: &FrameStats) {
        self.triangles_in += o.triangles_in;
        self.trivially_rejected += o.trivially_rejected;
        self.clipped += o.clipped;
        self.clip_output += o.clip_output;
        self.backface_culled += o.backface_culled;
        self.degenerate += o.degenerate;
        self.too_small += o.too_small;
        self.rasterized += o.rasterized;
        self.fragments_tested += o.fragments_tested;
        self.fragments_written += o.fragments_written;
        self.coarse_rejected += o.coarse_rejected;
        self.covered_pixels += o.covered_pixels;
        self.ms_geometry += o.ms_geometry;
        self.ms_binning += o.ms_binning;
        self.ms_raster += o.ms_raster;
        self.ms_shading += o.ms_shading;
        self.ms_wireframe += o.ms_wireframe;
        self.ms_total += o.ms_total;
        match (&mut self.transparency, &o.transparency) {
            (Some(a), Some(b)) => a.add(b),
            (a, b) => *a = a.or(*b),
        }
        self.update_overdraw();
    }

    /// Recomputes `overdraw` from the counters.
    pub fn update_overdraw(&mut self) {
        self.overdraw =
            if self.covered_pixels > 0 { self.fragments_written as f64 / self.covered_pixels as f64 } else { 0.0 };
    }
}

/// Milliseconds since `t`.
pub(crate) fn ms_since(t: std::time::Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn add_sums_and_recomputes_overdraw() {
        let mut a = FrameStats { fragments_written: 30, covered_pixels: 10, ..Default::default() };
        a.update_overdraw();
        assert_eq!(a.overdraw, 3.0);
        let b = FrameStats { fragments_written: 10, triangles_in: 4, ..Default::default() };
        a.add(&b);
        assert_eq!((a.triangles_in, a.overdraw), (4, 4.0));
    }
}

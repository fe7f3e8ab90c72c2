//! [`DepthPyramid`]: Greene's z-pyramid over a whole-screen depth buffer.
//!
//! Queries pick the finest level where the rectangle spans at most 4 texel widths per axis
//! (`span >> level ≤ 3`, so up to 5 × 5 texels are read: a finer level than Greene's 2 × 2,
//! which rejects more for a few more reads). After drawing, only the
//! rectangle that changed is propagated up ([`DepthPyramid::update`]).

use super::{Level, Rect};

/// The max-depth pyramid above a whole-screen depth buffer, e.g. a finished
/// [`Framebuffer`](crate::Framebuffer)'s: to test boxes against a frame after the fact, or
/// to look at its levels. Culled frames use the per-tile [`TilePyramid`](super::TilePyramid)
/// instead, which is built while the tiles are drawn.
#[derive(Debug, Clone, Default)]
pub struct DepthPyramid {
    width: u32,
    height: u32,
    /// Levels 1.. (level 0 is the depth buffer).
    levels: Vec<Level>,
}

impl DepthPyramid {
    /// An empty pyramid for a `width × height` depth buffer (all levels cleared to 1.0, the
    /// cleared depth, so nothing is occluded).
    pub fn new(width: u32, height: u32) -> Self {
        let mut levels: Vec<Level> = Vec::new();
        let mut below = Level { width, height, texels: Vec::new() };
        while below.width > 1 || below.height > 1 {
            let l = below.coarser(1.0);
            below = Level { width: l.width, height: l.height, texels: Vec::new() };
            levels.push(l);
        }
        Self { width, height, levels }
    }

    /// Screen width.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Screen height.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Number of levels including level 0.
    pub fn level_count(&self) -> usize {
        self.levels.len() + 1
    }
    /// Level `k`, for 1 ≤ k < [`level_count`]; `None` for level 0 (the depth buffer
    /// itself, not held here) and past the top.
    ///
    /// [`level_count`]: DepthPyramid::level_count
    pub fn level(&self, k: usize) -> Option<&Level> {
        self.levels.get(k.checked_sub(1)?)
    }

    /// Bytes held (levels ≥ 1).
    pub fn memory_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.texels.len() * 4).sum()
    }

    /// Resets every level to 1.0 (a cleared depth buffer).
    pub fn clear(&mut self) {
        for l in &mut self.levels {
            l.texels.fill(1.0);
        }
    }

    /// Rebuilds every level from `depth` (row-major, `width × height`), one pass per level.
    ///
    /// # Panics
    ///
    /// When `depth` does not hold `width × height` values.
    pub fn build(&mut self, depth: &[f32]) {
        let full = Rect { x0: 0, y0: 0, x1: self.width.saturating_sub(1), y1: self.height.saturating_sub(1) };
        self.update(depth, full);
    }

    /// Re-propagates the texels above the pixel rectangle `r` after it was drawn into (the
    /// part of it on the screen; nothing for an empty or inverted rectangle).
    ///
    /// # Panics
    ///
    /// When `depth` does not hold `width × height` values.
    pub fn update(&mut self, depth: &[f32], r: Rect) {
        assert_eq!(depth.len(), self.width as usize * self.height as usize, "depth buffer size");
        if self.width == 0 || self.height == 0 {
            return;
        }
        let mut r = Rect { x1: r.x1.min(self.width - 1), y1: r.y1.min(self.height - 1), ..r };
        if r.x0 > r.x1 || r.y0 > r.y1 {
            return;
        }
        let (mut sw, mut sh) = (self.width, self.height);
        for k in 0..self.levels.len() {
            let (below, rest) = self.levels.split_at_mut(k);
            let src: &[f32] = if k == 0 { depth } else { &below[k - 1].texels };
            let dst = &mut rest[0];
            let (x0, y0) = (r.x0 / 2, r.y0 / 2);
            let (x1, y1) = ((r.x1 / 2).min(dst.width - 1), (r.y1 / 2).min(dst.height - 1));
            r = Rect { x0, y0, x1, y1 };
            super::reduce_2x2(src, sw, sh, &mut dst.texels, dst.width, r);
            (sw, sh) = (dst.width, dst.height);
        }
    }

    /// The max depth of texel (x, y) of `level` (level 0 reads `depth`).
    #[inline]
    fn texel(&self, depth: &[f32], level: usize, x: u32, y: u32) -> f32 {
        if level == 0 {
            depth[(y * self.width + x) as usize]
        } else {
            self.levels[level - 1].at(x, y)
        }
    }

    /// True when nothing inside the pixel rectangle `r` at window depth ≥ `nearest` can pass
    /// a LESS test against `depth`, judged from the pyramid.
    ///
    /// # Panics
    ///
    /// When `r` reaches outside the screen (a [`BoxProjector`](sightline_spatial::BoxProjector)'s
    /// rectangles never do).
    pub fn is_occluded(&self, depth: &[f32], r: Rect, nearest: f32) -> bool {
        // NaN nearest: not occluded (be conservative).
        if !(nearest <= 1.0) {
            return nearest > 1.0;
        }
        let span = (r.x1 - r.x0).max(r.y1 - r.y0) + 1;
        // Finest level at which the rectangle spans at most 4 texel widths per axis.
        let mut level = 0usize;
        while (span >> level) > 3 && level + 1 < self.level_count() {
            level += 1;
        }
        let (x0, y0, x1, y1) = (r.x0 >> level, r.y0 >> level, r.x1 >> level, r.y1 >> level);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if nearest <= self.texel(depth, level, x, y) {
                    return false;
                }
            }
        }
        true
    }

    /// The max depth over the whole screen (the top texel).
    pub fn farthest(&self, depth: &[f32]) -> f32 {
        match self.levels.last() {
            Some(l) => l.texels[0],
            None => depth[0],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hzb::{brute_max, Rect};

    /// A pyramid over an empty screen, and updates of rectangles that are inverted or reach
    /// past the screen, do nothing rather than panic.
    #[test]
    fn empty_screens_and_odd_rectangles_are_no_ops() {
        let mut empty = DepthPyramid::new(0, 5);
        empty.build(&[]);
        let (w, h) = (10u32, 6u32);
        let depth = vec![0.5f32; (w * h) as usize];
        let mut p = DepthPyramid::new(w, h);
        p.update(&depth, Rect { x0: 5, y0: 0, x1: 2, y1: 3 });
        assert_eq!(p.farthest(&depth), 1.0, "an inverted rectangle changes nothing");
        p.update(&depth, Rect { x0: 0, y0: 0, x1: 100, y1: 100 });
        assert_eq!(p.farthest(&depth), 0.5, "a rectangle past the screen updates the screen");
    }

    #[test]
    fn pyramid_is_exactly_conservative_on_odd_sizes() {
        let (w, h) = (37u32, 23u32);
        let mut rng = sightline_scene::rng::Rng::new(9);
        let depth: Vec<f32> = (0..w * h).map(|_| rng.f32()).collect();
        let mut p = DepthPyramid::new(w, h);
        p.build(&depth);
        assert_eq!(p.level_count(), 7);
        for _ in 0..2000 {
            let (xa, xb) = (rng.below(w), rng.below(w));
            let (ya, yb) = (rng.below(h), rng.below(h));
            let r = Rect { x0: xa.min(xb), x1: xa.max(xb), y0: ya.min(yb), y1: ya.max(yb) };
            let m = brute_max(&depth, w, r);
            // Anything nearer than or at the true max is never called occluded.
            assert!(!p.is_occluded(&depth, r, m));
            assert!(!p.is_occluded(&depth, r, m - 1e-3));
            // Something behind everything drawn (every depth is below 1) is occluded.
            assert!(p.is_occluded(&depth, r, 1.0));
            // Exactly so: the texels read (at the level where the rectangle spans at most 4
            // texel widths) hold the max of the pixels they cover, and a box just behind that
            // max is occluded.
            let span = (r.x1 - r.x0).max(r.y1 - r.y0) + 1;
            let level = (0..p.level_count() as u32).find(|&l| span >> l <= 3).unwrap_or(p.level_count() as u32 - 1);
            let cover = Rect {
                x0: r.x0 >> level << level,
                y0: r.y0 >> level << level,
                x1: (((r.x1 >> level) + 1) << level).min(w) - 1,
                y1: (((r.y1 >> level) + 1) << level).min(h) - 1,
            };
            let mc = brute_max(&depth, w, cover);
            assert!(!p.is_occluded(&depth, r, mc), "{r:?} at level {level}");
            assert!(p.is_occluded(&depth, r, mc.next_up()), "{r:?} at level {level}");
        }
        assert_eq!(p.farthest(&depth), brute_max(&depth, w, Rect { x0: 0, y0: 0, x1: w - 1, y1: h - 1 }));
        // Levels: 0 is the depth buffer (not held), then sizes halve rounding up, each texel
        // the max of the texels below it that exist.
        assert!(p.level(0).is_none() && p.level(p.level_count()).is_none());
        let (mut lw, mut lh, mut below) = (w, h, depth.clone());
        for k in 1..p.level_count() {
            let l = p.level(k).expect("a level below the top");
            let (kw, kh, texels) = (l.width, l.height, &l.texels);
            assert_eq!((kw, kh), (lw.div_ceil(2), lh.div_ceil(2)));
            for y in 0..kh {
                for x in 0..kw {
                    let r = Rect { x0: 2 * x, y0: 2 * y, x1: (2 * x + 1).min(lw - 1), y1: (2 * y + 1).min(lh - 1) };
                    assert_eq!(texels[(y * kw + x) as usize], brute_max(&below, lw, r), "level {k} at {x},{y}");
                }
            }
            (lw, lh, below) = (kw, kh, texels.to_vec());
        }
    }

    #[test]
    fn incremental_update_equals_rebuild() {
        let (w, h) = (64u32, 40u32);
        let mut depth = vec![1.0f32; (w * h) as usize];
        let mut p = DepthPyramid::new(w, h);
        p.build(&depth);
        // Draw a rectangle of depth 0.3 and update only it.
        let r = Rect { x0: 5, y0: 7, x1: 30, y1: 20 };
        for y in r.y0..=r.y1 {
            for x in r.x0..=r.x1 {
                depth[(y * w + x) as usize] = 0.3;
            }
        }
        p.update(&depth, r);
        let mut q = DepthPyramid::new(w, h);
        q.build(&depth);
        assert_eq!(p.levels, q.levels);
        assert!(p.is_occluded(&depth, Rect { x0: 10, y0: 10, x1: 20, y1: 15 }, 0.5));
        assert!(!p.is_occluded(&depth, Rect { x0: 10, y0: 10, x1: 40, y1: 15 }, 0.5));
    }

    #[test]
    fn cleared_buffer_occludes_nothing() {
        let depth = vec![1.0f32; 100];
        let p = DepthPyramid::new(10, 10);
        assert!(!p.is_occluded(&depth, Rect { x0: 0, y0: 0, x1: 9, y1: 9 }, 0.999));
        assert!(!p.is_occluded(&depth, Rect { x0: 2, y0: 2, x1: 3, y1: 3 }, f32::NAN));
    }
}

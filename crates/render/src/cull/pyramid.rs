//! The hierarchical z-buffer: Greene's z-pyramid (N. Greene, M. Kass, G. Miller,
//! "Hierarchical Z-Buffer Visibility", SIGGRAPH 1993).
//!
//! Level 0 is the depth buffer itself (read in place, never copied); level k + 1 stores for
//! each texel the FARTHEST (max) window depth of the up to 2 × 2 texels below it. Odd sizes
//! round up (`ceil(w / 2)`), and an edge texel takes the max of the children that exist:
//! those are the only pixels it stands for, so the bound stays exact.
//!
//! A screen rectangle whose nearest possible depth is farther than the max stored over
//! every texel it touches cannot pass a LESS depth test anywhere: it is occluded. Queries
//! pick the level where the rectangle touches at most 4 × 4 texels (a finer level than
//! Greene's 2 × 2, which rejects more for a few more reads). After drawing, only the
//! rectangle that changed is propagated up ([`DepthPyramid::update`]).
//!
//! The frame session's pyramid ([`TilePyramid`]) gives the answers of the same rule (from
//! level 1 up) but first tries Greene's 2 × 2 test on the small grid of levels ≥ 6 over the
//! tiles: a coarser texel is the max of the finer ones below it, so when that test says
//! occluded the finer one would too, and it settles nearly every query of a dense scene
//! with four reads.

/// A pixel rectangle, inclusive bounds, inside the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// Last column (inclusive).
    pub x1: u32,
    /// Last row (inclusive).
    pub y1: u32,
}

impl Rect {
    /// The smallest rectangle containing both.
    pub fn union(&self, o: &Rect) -> Rect {
        Rect { x0: self.x0.min(o.x0), y0: self.y0.min(o.y0), x1: self.x1.max(o.x1), y1: self.y1.max(o.y1) }
    }
}

/// The max-depth pyramid above a whole-screen depth buffer, e.g. a finished
/// [`Framebuffer`](crate::Framebuffer)'s: to test boxes against a frame after the fact, or
/// to look at (`examples/depth_complexity.rs` draws its levels). Culled frames use the
/// per-tile [`TilePyramid`] instead, which is built while the tiles are drawn.
#[derive(Debug, Clone, Default)]
pub struct DepthPyramid {
    width: u32,
    height: u32,
    /// Levels 1.. (level 0 is the depth buffer): (width, height, texels).
    levels: Vec<(u32, u32, Vec<f32>)>,
}

impl DepthPyramid {
    /// An empty pyramid for a `width × height` depth buffer (all levels cleared to 1.0, the
    /// cleared depth, so nothing is occluded).
    pub fn new(width: u32, height: u32) -> Self {
        let mut levels = Vec::new();
        let (mut w, mut h) = (width, height);
        while w > 1 || h > 1 {
            w = w.div_ceil(2);
            h = h.div_ceil(2);
            levels.push((w, h, vec![1.0; w as usize * h as usize]));
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
    /// Level `k` as (width, height, texels, row-major), for 1 ≤ k < [`level_count`]; `None`
    /// for level 0 (the depth buffer itself, not held here) and past the top.
    ///
    /// [`level_count`]: DepthPyramid::level_count
    pub fn level(&self, k: usize) -> Option<(u32, u32, &[f32])> {
        let (w, h, t) = self.levels.get(k.checked_sub(1)?)?;
        Some((*w, *h, t))
    }

    /// Bytes held (levels ≥ 1).
    pub fn memory_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.2.len() * 4).sum()
    }

    /// Resets every level to 1.0 (a cleared depth buffer).
    pub fn clear(&mut self) {
        for l in &mut self.levels {
            l.2.fill(1.0);
        }
    }

    /// Rebuilds every level from `depth` (row-major, `width × height`), one pass per level.
    pub fn build(&mut self, depth: &[f32]) {
        let full = Rect { x0: 0, y0: 0, x1: self.width - 1, y1: self.height - 1 };
        self.update(depth, full);
    }

    /// Re-propagates the texels above the pixel rectangle `r` after it was drawn into.
    pub fn update(&mut self, depth: &[f32], r: Rect) {
        assert_eq!(depth.len(), self.width as usize * self.height as usize, "depth buffer size");
        let (mut sw, mut sh) = (self.width, self.height);
        let mut r = r;
        for k in 0..self.levels.len() {
            let (below, rest) = self.levels.split_at_mut(k);
            let src: &[f32] = if k == 0 { depth } else { &below[k - 1].2 };
            let (dw, dh, dst) = &mut rest[0];
            let (x0, y0, x1, y1) = (r.x0 / 2, r.y0 / 2, (r.x1 / 2).min(*dw - 1), (r.y1 / 2).min(*dh - 1));
            reduce(src, sw, sh, dst, *dw, Rect { x0, y0, x1, y1 });
            r = Rect { x0, y0, x1, y1 };
            sw = *dw;
            sh = *dh;
        }
    }

    /// The max depth of texel (x, y) of `level` (level 0 reads `depth`).
    #[inline]
    fn texel(&self, depth: &[f32], level: usize, x: u32, y: u32) -> f32 {
        if level == 0 {
            depth[(y * self.width + x) as usize]
        } else {
            let (w, _, d) = &self.levels[level - 1];
            d[(y * w + x) as usize]
        }
    }

    /// True when nothing inside the pixel rectangle `r` at window depth ≥ `nearest` can pass
    /// a LESS test against `depth`, judged from the pyramid.
    pub fn is_occluded(&self, depth: &[f32], r: Rect, nearest: f32) -> bool {
        // NaN nearest: not occluded (be conservative).
        if !(nearest <= 1.0) {
            return nearest > 1.0;
        }
        let span = (r.x1 - r.x0).max(r.y1 - r.y0) + 1;
        // Finest level at which the rectangle touches at most 4 × 4 texels.
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
            Some(l) => l.2[0],
            None => depth[0],
        }
    }
}

/// dst texels in `r` (destination coordinates) = max of their 2 × 2 source children.
fn reduce(src: &[f32], sw: u32, sh: u32, dst: &mut [f32], dw: u32, r: Rect) {
    let (sw, sh, dw) = (sw as usize, sh as usize, dw as usize);
    for y in r.y0 as usize..=r.y1 as usize {
        let s0 = 2 * y;
        let s1 = (2 * y + 1).min(sh - 1);
        let (row0, row1) = (&src[s0 * sw..(s0 + 1) * sw], &src[s1 * sw..(s1 + 1) * sw]);
        let out = &mut dst[y * dw..(y + 1) * dw];
        for (x, o) in out.iter_mut().enumerate().take(r.x1 as usize + 1).skip(r.x0 as usize) {
            let a = 2 * x;
            let b = (2 * x + 1).min(sw - 1);
            *o = row0[a].max(row0[b]).max(row1[a]).max(row1[b]);
        }
    }
}

/// The pyramid levels of a tile not drawn into in this session: cleared.
static CLEARED_MIPS: [f32; crate::raster::MIP_OFFSETS[6]] = [1.0; crate::raster::MIP_OFFSETS[6]];

/// The z-pyramid of a frame session, read straight from the renderer's tiles: levels 1..=6
/// live in each 64 × 64 tile (computed in the tile's own raster task, right after it drew),
/// levels 6 and up over the tile grid. Same answers as [`DepthPyramid`] on the same depth,
/// except that it never reads level 0 (its finest level is 2 × 2 pixels).
#[derive(Debug, Clone, Copy)]
pub struct TilePyramid<'a> {
    tiles: &'a [crate::raster::TileBuf],
    tiles_x: u32,
    width: u32,
    height: u32,
    upper: &'a [(u32, u32, Vec<f32>)],
    /// Added to stored depths before comparing: integer depth formats round window depth
    /// to their grid, so a fragment up to half a step farther can still tie.
    margin: f32,
}

impl<'a> TilePyramid<'a> {
    pub(crate) fn new(
        tiles: &'a [crate::raster::TileBuf],
        tiles_x: u32,
        width: u32,
        height: u32,
        upper: &'a [(u32, u32, Vec<f32>)],
        fmt: crate::DepthFormat,
    ) -> Self {
        Self { tiles, tiles_x, width, height, upper, margin: fmt.tie_margin() }
    }

    /// Screen width.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Screen height.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The top level (one texel over the whole screen).
    #[inline]
    fn top(&self) -> u32 {
        5 + self.upper.len() as u32
    }

    /// The max depth of texel (x, y) of `level` (1 ..= [`TilePyramid::top`]). Levels below 6
    /// live in the tiles: texel (x, y) is in tile (x, y) >> (6 − level), at the position
    /// given by the low bits; a tile not drawn into this session is still clear (1.0).
    #[inline(always)]
    fn texel(&self, level: u32, x: u32, y: u32) -> f32 {
        if level < 6 {
            self.tile_texel(level, x, y)
        } else {
            let (w, _, d) = &self.upper[(level - 6) as usize];
            d[(y * w + x) as usize]
        }
    }

    /// [`TilePyramid::texel`] for a level below 6. Branch-free: the texel of an untouched
    /// tile is read from a cleared array instead.
    #[inline(always)]
    fn tile_texel(&self, level: u32, x: u32, y: u32) -> f32 {
        let sh = 6 - level;
        let tile = &self.tiles[((y >> sh) * self.tiles_x + (x >> sh)) as usize];
        let mips: &[f32] = if tile.touched { &tile.mips } else { &CLEARED_MIPS };
        let low = (1 << sh) - 1;
        mips[crate::raster::MIP_OFFSETS[level as usize - 1] + (((y & low) << sh) | (x & low)) as usize]
    }

    /// True when nothing inside the pixel rectangle `r` at window depth ≥ `nearest` can pass
    /// the depth test against what is drawn so far.
    ///
    /// The answer is that of the finest level ≥ 1 where the rectangle spans at most 4 texels
    /// per axis (span >> level ≤ 3, up to 5 × 5 texels read), reached in two steps:
    /// 1. Greene's 2 × 2 test on the grid over the tiles, at the finest level ≥ 6 where
    ///    2^level is at least the rectangle's span in pixels (so it touches at most 2 × 2
    ///    texels): four reads from one small flat array, no tile lookup, no loop. Each of
    ///    these texels is the max of the finer texels below it, so when this test says
    ///    occluded the finer one would too. In the boxfield benchmark it settles nearly
    ///    every occluded query.
    /// 2. Otherwise the finer level itself, texel by texel.
    ///
    /// A texel t occludes when `nearest > t + margin`; a NaN texel does not.
    #[inline(always)]
    pub fn is_occluded(&self, r: Rect, nearest: f32) -> bool {
        if !(nearest <= 1.0) {
            return nearest > 1.0; // NaN: not occluded
        }
        let top = self.top();
        // 2^level ≥ the span in pixels: each axis touches texels a and a + 1 at most.
        let d = (r.x1 - r.x0).max(r.y1 - r.y0);
        let level = (32 - d.leading_zeros()).clamp(6, top);
        let (x0, y0, x1, y1) = (r.x0 >> level, r.y0 >> level, r.x1 >> level, r.y1 >> level);
        let (w, _, g) = &self.upper[(level - 6) as usize];
        let (row0, row1) = ((y0 * w) as usize, (y1 * w) as usize);
        let far = [g[row0 + x0 as usize], g[row0 + x1 as usize], g[row1 + x0 as usize], g[row1 + x1 as usize]];
        if far.iter().fold(true, |all, &t| all & (nearest > t + self.margin)) {
            return true;
        }
        self.is_occluded_fine(r, nearest, top)
    }

    /// The finer level of [`TilePyramid::is_occluded`] (span >> level ≤ 3), texel by texel.
    #[inline(never)]
    fn is_occluded_fine(&self, r: Rect, nearest: f32, top: u32) -> bool {
        let span = (r.x1 - r.x0).max(r.y1 - r.y0) + 1;
        // The finest level ≥ 1 where the span covers at most 4 texels: span >> level ≤ 3.
        let level = (32 - (span >> 2).leading_zeros()).clamp(1, top);
        let (x0, y0, x1, y1) = (r.x0 >> level, r.y0 >> level, r.x1 >> level, r.y1 >> level);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if !(nearest > self.texel(level, x, y) + self.margin) {
                    return false;
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_max(depth: &[f32], w: u32, r: Rect) -> f32 {
        let mut m = f32::MIN;
        for y in r.y0..=r.y1 {
            for x in r.x0..=r.x1 {
                m = m.max(depth[(y * w + x) as usize]);
            }
        }
        m
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
            // Something behind everything is occluded.
            assert!(p.is_occluded(&depth, r, 1.5) || m >= 1.5);
        }
        assert_eq!(p.farthest(&depth), brute_max(&depth, w, Rect { x0: 0, y0: 0, x1: w - 1, y1: h - 1 }));
        // Levels: 0 is the depth buffer (not held), then sizes halve rounding up, each texel
        // the max of the texels below it that exist.
        assert!(p.level(0).is_none() && p.level(p.level_count()).is_none());
        let (mut lw, mut lh, mut below) = (w, h, depth.clone());
        for k in 1..p.level_count() {
            let (kw, kh, texels) = p.level(k).expect("a level below the top");
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

    /// The session pyramid's two-step test gives exactly the answers of its finer level alone
    /// (the grid test only ever settles queries the finer level would call occluded too), and
    /// never calls occluded a rectangle with a pixel at or behind the query depth; on every
    /// depth format, with tiles never drawn into, and on a screen that is not a multiple of
    /// the tile size.
    #[test]
    fn tile_pyramid_grid_test_keeps_the_fine_answers() {
        use crate::{DepthFormat, Framebuffer, RenderOptions, Renderer};
        use glam::Vec4;
        let (w, h) = (300u32, 170u32);
        let opts = RenderOptions { backface_culling: false, ..RenderOptions::ids_only() };
        let mut rng = sightline_scene::rng::Rng::new(11);
        for fmt in [DepthFormat::F32, DepthFormat::Unorm16, DepthFormat::Unorm24] {
            let mut fb = Framebuffer::new(w, h).unwrap();
            let mut renderer = Renderer::new();
            renderer.begin_session(&fb, fmt);
            // Triangles of all sizes at all depths, over the left 80% of the screen only, so
            // that some tiles are never drawn into.
            let tris: Vec<[Vec4; 3]> = (0..400)
                .map(|_| {
                    let (cx, cy, size) = (rng.range(-1.2, 0.5), rng.range(-1.2, 1.2), rng.range(0.01, 0.6));
                    let (z, dz) = (rng.range(-0.95, 0.95), [rng.range(-0.05, 0.05), rng.range(-0.05, 0.05)]);
                    let (s1, s2) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                    let v = |dx: f32, dy: f32, dz: f32| Vec4::new(cx + dx * size, cy + dy * size, z + dz, 1.0);
                    [v(0.0, 0.0, 0.0), v(1.0, s1, dz[0]), v(s2, 1.0, dz[1])]
                })
                .collect();
            renderer.draw_clip_triangles(&tris, 1, &mut fb, &opts);
            let pyramid = renderer.session_pyramid().unwrap();
            let top = pyramid.top();
            let mut queries = Vec::new();
            let mut occluded = 0;
            for _ in 0..20_000 {
                // Sizes from one pixel to the whole screen, roughly log-uniform.
                let side = |n: u32, rng: &mut sightline_scene::rng::Rng| {
                    let len = (2f32.powf(rng.range(0.0, (n as f32).log2())) as u32).clamp(1, n);
                    let a = rng.below(n - len + 1);
                    (a, a + len - 1)
                };
                let ((x0, x1), (y0, y1)) = (side(w, &mut rng), side(h, &mut rng));
                let r = Rect { x0, y0, x1, y1 };
                let z = rng.range(0.0, 1.0);
                let occ = pyramid.is_occluded(r, z);
                assert_eq!(occ, pyramid.is_occluded_fine(r, z, top), "{fmt:?} {r:?} at {z}");
                occluded += occ as u32;
                queries.push((r, z, occ));
            }
            assert!(occluded > 1000 && occluded < 19_000, "{fmt:?}: {occluded}");
            renderer.end_session(&mut fb);
            for (r, z, occ) in queries {
                if occ {
                    let m = brute_max(&fb.depth, w, r);
                    assert!(z > m, "{fmt:?}: {r:?} at {z} called occluded, but a pixel has depth {m}");
                }
            }
        }
    }

    #[test]
    fn cleared_buffer_occludes_nothing() {
        let depth = vec![1.0f32; 100];
        let p = DepthPyramid::new(10, 10);
        assert!(!p.is_occluded(&depth, Rect { x0: 0, y0: 0, x1: 9, y1: 9 }, 0.999));
        assert!(!p.is_occluded(&depth, Rect { x0: 2, y0: 2, x1: 3, y1: 3 }, f32::NAN));
    }
}

//! [`TilePyramid`]: box queries against a frame session's z-pyramid, read straight from
//! the rasterizer's tiles ([`TileLevels`]) and the levels above them ([`UpperLevels`]).
//!
//! Same answers as [`DepthPyramid`](super::DepthPyramid) on the same depth (from level 1
//! up), but first Greene's 2 × 2 test on the small grid of levels ≥ 6 over the tiles: a
//! coarser texel is the max of the finer ones below it, so when that test says occluded the
//! finer one would too, and it settles nearly every query of a dense scene with four reads.

use super::tile::{CLEARED, OFFSETS};
use super::{Level, Rect, TileLevels, UpperLevels};

/// The z-pyramid of a frame session, read straight from the renderer's tiles: levels 1..=6
/// live in each 64 × 64 tile (computed in the tile's own raster task, right after it drew),
/// levels 6 and up over the tile grid. Same answers as [`DepthPyramid`](super::DepthPyramid)
/// on the same depth, except that it never reads level 0 (its finest level is 2 × 2 pixels).
#[derive(Debug, Clone, Copy)]
pub struct TilePyramid<'a> {
    tiles: &'a [TileLevels],
    tiles_x: u32,
    width: u32,
    height: u32,
    upper: &'a [Level],
    /// Added to stored depths before comparing: integer depth formats round window depth
    /// to their grid, so a fragment up to half a step farther can still tie.
    margin: f32,
}

impl<'a> TilePyramid<'a> {
    pub(crate) fn new(
        tiles: &'a [TileLevels],
        tiles_x: u32,
        (width, height): (u32, u32),
        upper: &'a UpperLevels,
        fmt: crate::DepthFormat,
    ) -> Self {
        Self { tiles, tiles_x, width, height, upper: &upper.levels, margin: fmt.tie_margin() }
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
            self.upper[(level - 6) as usize].at(x, y)
        }
    }

    /// [`TilePyramid::texel`] for a level below 6. Branch-free: the texel of an untouched
    /// tile is read from a cleared array instead.
    #[inline(always)]
    fn tile_texel(&self, level: u32, x: u32, y: u32) -> f32 {
        let sh = 6 - level;
        let tile = &self.tiles[((y >> sh) * self.tiles_x + (x >> sh)) as usize];
        let mips: &[f32] = if tile.touched { &tile.mips } else { &CLEARED };
        let low = (1 << sh) - 1;
        mips[OFFSETS[level as usize - 1] + (((y & low) << sh) | (x & low)) as usize]
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
        let l = &self.upper[(level - 6) as usize];
        let (g, w) = (&l.texels, l.width);
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
    use crate::hzb::brute_max;

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
            let mut session = renderer.begin(&fb, &RenderOptions { depth_format: fmt, ..opts });
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
            session.draw_clip_triangles(&tris, 1);
            let pyramid = session.pyramid();
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
            session.finish(&mut fb).unwrap();
            for (r, z, occ) in queries {
                if occ {
                    let m = brute_max(&fb.depth, w, r);
                    assert!(z > m, "{fmt:?}: {r:?} at {z} called occluded, but a pixel has depth {m}");
                }
            }
        }
    }
}

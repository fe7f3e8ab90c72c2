//! Levels 1–6 of the z-pyramid inside one 64 × 64 rasterizer tile, and the coarse depth
//! tests made against them while drawing.
//!
//! The levels are 32², 16², …, 1² texels stored one after the other ([`OFFSETS`]). During a
//! frame session the rasterizer keeps them up to date: right after a triangle writes into an
//! 8 × 8 block, that block's level-3 texel is recomputed ([`TileLevels::refresh_block`]), so
//! the next triangles of the same batch are tested against it (Masked Occlusion Culling's
//! sequential updates; Hasselgren, Andersson, Akenine-Möller 2016); levels 1–2 under the
//! written blocks and levels 4–6 follow after the batch ([`TileLevels::update`]). Three tests
//! read them: a whole triangle against the tile at binning ([`TileLevels::occludes`]: the
//! per-tile z-max of "HyperZ", then Greene's pyramid test per triangle); in the rasterizer,
//! the triangle against the level-3 texels of every block it reaches before its block walk
//! ([`TileLevels::blocks_hidden`]: binning ran before the batch's earlier triangles refreshed
//! them, and on the street path this settles half the triangle–tile pairs a culled frame
//! rasterizes); and each 8 × 8 block in the walk ([`TileLevels::block_hidden`]).

#[cfg(test)]
use super::{reduce_2x2, Rect};
use crate::depth::DepthCodec;
use crate::edge::Tri;
use crate::tiling::{TileRect, BLOCK, TILE, TILE_SHIFT};

/// Offsets of levels 1..=6 in [`TileLevels::mips`] (index = level − 1), and the total length.
pub(crate) const OFFSETS: [usize; 7] = [0, 1024, 1280, 1344, 1360, 1364, 1365];

/// The pyramid levels of a tile not drawn into in this session: cleared.
pub(crate) static CLEARED: [f32; OFFSETS[6]] = [1.0; OFFSETS[6]];

/// One screen tile's record: its rectangle, its z-pyramid levels 1..=6 and the state of
/// their incremental update, and its state in a frame session.
#[derive(Debug, Clone)]
pub(crate) struct TileLevels {
    /// The tile on the screen.
    pub rect: TileRect,
    /// In a frame session: whether the tile has been drawn into (else it is still clear and
    /// the levels are stale).
    pub touched: bool,
    /// Whether the rasterizer may skip 8×8 blocks behind these levels and keeps the level
    /// of the blocks it writes up to date; set per pass, on in frame sessions.
    pub coarse: bool,
    /// Levels 1..=6, see [`OFFSETS`].
    pub mips: Vec<f32>,
    /// The 8×8-pixel blocks (bit `8·by + bx`) written since levels 1–2 were last updated.
    pub stale_blocks: u64,
    /// The depth format's tie margin, added to texels before a test says "hidden".
    pub tie_margin: f32,
    /// In a frame session: the tile's covered pixels (ID ≠ 0) in the framebuffer, kept up
    /// to date as passes store into it; reset on the tile's first use in a session and
    /// meaningful only while `touched`.
    pub covered: u64,
}

impl TileLevels {
    /// Cleared levels for the tile `rect`.
    pub(crate) fn new(rect: TileRect) -> Self {
        Self {
            rect,
            touched: false,
            coarse: false,
            mips: vec![1.0; OFFSETS[6]],
            stale_blocks: 0,
            tie_margin: 0.0,
            covered: 0,
        }
    }

    /// Clears the levels when the tile is first drawn into in a session of format `D`.
    pub(crate) fn clear<D: DepthCodec>(&mut self) {
        self.tie_margin = D::tie_margin();
        self.mips.fill(1.0);
        // A tile cut by the screen edge: its first update computes every level, so that
        // texels over pixels that do not exist take their depth 0 (no pixel written there
        // would ever mark them).
        self.stale_blocks = if self.rect.w < TILE || self.rect.h < TILE { !0 } else { 0 };
        self.touched = true;
    }

    /// True when triangle `t` cannot pass the depth test anywhere in this tile, judged from
    /// the levels. They may lag behind the pixels (refreshed after each draw batch), but
    /// depths only decrease, so a stale max is a safe bound. First the whole tile: `far` is
    /// its farthest depth as binning reads it from the compact level 6 of the upper pyramid
    /// (where a tile not drawn into holds the clear depth, which no fragment beats), and a
    /// triangle behind it by more than the format's tie `margin` is hidden. Where nearer
    /// surfaces cover the tile, that one load settles every triangle behind them (the
    /// boxfield's occluder pass on one thread, 11.2 → 9.7 ms), without reading this record,
    /// which the core that drew the tile last wrote. Then, on a tile drawn into in this
    /// session, [`TileLevels::occludes_below_tile`].
    #[inline]
    pub(crate) fn occludes(&self, far: f32, margin: f32, t: &Tri) -> bool {
        t.zmin > far + margin || (self.touched && self.occludes_below_tile(t))
    }

    /// True when the texels of the level by the triangle's size, under the part of `t`
    /// inside this tile, all lie nearer than `t` (by more than the tie margin): the test
    /// after the whole tile's in [`TileLevels::occludes`]. Only meaningful on a tile drawn
    /// into in this session. Out of line: binning's loop then stays short, and most of its
    /// triangles are settled by the tile's level 6 before this (inlined into the loop, the
    /// boxfield's occluder pass took 1.02–1.06× as long).
    #[inline(never)]
    pub(crate) fn occludes_below_tile(&self, t: &Tri) -> bool {
        // The triangle's pixels in this tile, in tile coordinates.
        let x0 = (t.bbox[0] as u32).max(self.rect.x0) - self.rect.x0;
        let y0 = (t.bbox[1] as u32).max(self.rect.y0) - self.rect.y0;
        let x1 = (t.bbox[2] as u32).min(self.rect.x0 + self.rect.w - 1).saturating_sub(self.rect.x0);
        let y1 = (t.bbox[3] as u32).min(self.rect.y0 + self.rect.h - 1).saturating_sub(self.rect.y0);
        if x0 > x1 || y0 > y1 {
            return false;
        }
        // The triangle's nearest depth: its nearest vertex's, to which the rasterizer clamps
        // every pixel's depth (`Tri::depth_at`).
        let near = t.zmin;
        // The texels of the smallest level whose texels are at least half the rectangle's
        // longer side: at most 3 × 3 of them.
        let span = (x1 - x0).max(y1 - y0) + 1;
        let level = (31 - span.leading_zeros()).clamp(1, 6) as usize;
        let behind = |near: f32| self.texels_behind(level, [x0, y0, x1, y1], near);
        if near > 0.0 && behind(near) {
            return true;
        }
        // Depth is affine in the window: over the pixel centers of this rectangle it is at
        // least its value at the nearest corner. For a big triangle reaching far behind
        // this tile, that bound is much tighter than its nearest vertex; it is only worth
        // computing when the vertex bound did not already hide the triangle, and small
        // triangles (most of them) are not worth it at all.
        if t.bbox[2] - t.bbox[0] < 8 && t.bbox[3] - t.bbox[1] < 8 {
            return false;
        }
        let (sx, sy) = (self.rect.x0 as i32, self.rect.y0 as i32);
        let plane = t.plane_min([x0 as i32 + sx, y0 as i32 + sy, x1 as i32 + sx, y1 as i32 + sy]);
        plane > near && plane > 0.0 && behind(plane)
    }

    /// True when depth `near` lies behind every texel of level `level` over the tile pixels
    /// `[x0, y0, x1, y1]` (by more than the tie margin).
    #[inline(always)]
    fn texels_behind(&self, level: usize, [x0, y0, x1, y1]: [u32; 4], near: f32) -> bool {
        let s = (TILE >> level) as usize;
        let off = OFFSETS[level - 1];
        // Half-open ranges: inclusive ones cost a check per step.
        let (tx0, tx1) = ((x0 >> level) as usize, (x1 >> level) as usize + 1);
        for y in (y0 >> level) as usize..(y1 >> level) as usize + 1 {
            for &texel in &self.mips[off + y * s..][tx0..tx1] {
                if !self.behind_texel(near, texel) {
                    return false;
                }
            }
        }
        true
    }

    /// [`TileLevels::block_hidden`] for every 8×8 block under the screen rectangle `rect`
    /// (inside this tile) at once, from the triangle's plane over the whole rectangle: no
    /// nearer than over any block's part of it, so a true answer here is a true answer for
    /// each block.
    #[inline(always)]
    pub(crate) fn blocks_hidden(&self, t: &Tri, rect: [i32; 4]) -> bool {
        let near = t.plane_min(rect);
        let (sx, sy) = (self.rect.x0 as i32, self.rect.y0 as i32);
        let level3 = &self.mips[OFFSETS[2]..OFFSETS[3]];
        let (bx0, bx1) = (((rect[0] - sx) >> 3) as usize, ((rect[2] - sx) >> 3) as usize + 1);
        for by in ((rect[1] - sy) >> 3) as usize..((rect[3] - sy) >> 3) as usize + 1 {
            for &max in &level3[by * 8..][bx0..bx1] {
                if !self.behind_texel(near, max) {
                    return false;
                }
            }
        }
        true
    }

    /// Coarse depth per 8×8 block: true when the triangle's plane over the block's pixel
    /// centers `rect` (screen) lies behind the farthest depth drawn in the block (level 3;
    /// `[bx, by]` is the block's corner in the tile).
    #[inline(always)]
    pub(crate) fn block_hidden(&self, t: &Tri, rect: [i32; 4], [bx, by]: [i32; 2]) -> bool {
        let max = self.mips[OFFSETS[2] + ((by >> 3) * 8 + (bx >> 3)) as usize];
        // The plane's nearest depth only where the block is drawn over.
        max < 1.0 && self.behind_texel(t.plane_min(rect), max)
    }

    /// The pyramid's one depth comparison: true when depth `near` lies behind a texel whose
    /// farthest drawn depth is `max`, by more than the tie margin; never for a texel
    /// something is still clear in (`max` 1), nor for a `near` that is not a number.
    #[inline(always)]
    fn behind_texel(&self, near: f32, max: f32) -> bool {
        max < 1.0 && near > max + self.tie_margin
    }

    /// Brings the level-3 texel of one 8×8 block (`[bx, by]`: any of its pixels, in tile
    /// pixels) up to date from
    /// the tile's depth keys right after a triangle wrote into it, and marks the block stale
    /// for levels 1–2.
    #[inline(always)]
    pub(crate) fn refresh_block<D: DepthCodec>(&mut self, depth: &[u32], [bx, by]: [i32; 2]) {
        let (bx, by) = ((bx & !(BLOCK - 1)) as usize, (by & !(BLOCK - 1)) as usize);
        let mut m = [0u32; BLOCK as usize];
        for r in 0..BLOCK as usize {
            let row = &depth[((by + r) << TILE_SHIFT) + bx..][..BLOCK as usize];
            for (m, &k) in m.iter_mut().zip(row) {
                *m = (*m).max(k);
            }
        }
        let k = m.into_iter().max().unwrap_or(0);
        self.mips[OFFSETS[2] + (by / 8) * 8 + bx / 8] = D::decode(k);
        self.stale_blocks |= 1 << ((by / 8) * 8 + bx / 8);
    }

    /// Brings the levels up to date after writes: levels 1–3 only under the stale 8×8
    /// blocks (one level-3 texel each), levels 4–6 (21 texels) whole. Keys order like
    /// depths, so a stale block's 16 + 4 + 1 texels are reduced from its 64 keys held in
    /// registers and each decoded once; levels 4–6 have fixed sizes, written out. (Through
    /// the general 2 × 2 reduction, rectangle by rectangle, the boxfield's occluder pass took
    /// 1.03× as long and the street path's `hzb` frame 1.03–1.05×.) Inlined into the tile
    /// stage, so that it is compiled for the stage's instruction set.
    #[inline(always)]
    pub(crate) fn update<D: DepthCodec>(&mut self, depth: &[u32]) {
        let mut stale = std::mem::take(&mut self.stale_blocks);
        if stale == 0 {
            return;
        }
        const T: usize = TILE as usize;
        let (l1, rest) = self.mips.split_at_mut(OFFSETS[1]);
        let (l2, rest) = rest.split_at_mut(OFFSETS[2] - OFFSETS[1]);
        let (l3, upper) = rest.split_at_mut(OFFSETS[3] - OFFSETS[2]);
        while stale != 0 {
            let b = stale.trailing_zeros() as usize;
            stale &= stale - 1;
            let (bx, by) = (b & 7, b >> 3);
            // Plain loops, not `std::array::from_fn`: its closures run inside the library's
            // generic function, which is compiled without this stage's target features
            // (SSE2: no unsigned 32-bit max, each emulated in several operations).
            let mut k1 = [[0u32; 4]; 4];
            for (y, row) in k1.iter_mut().enumerate() {
                let at = (8 * by + 2 * y) * T + 8 * bx;
                let (r0, r1) = (&depth[at..at + 8], &depth[at + T..at + T + 8]);
                for (x, k) in row.iter_mut().enumerate() {
                    *k = r0[2 * x].max(r1[2 * x]).max(r0[2 * x + 1].max(r1[2 * x + 1]));
                }
            }
            for (y, row) in k1.iter().enumerate() {
                let at = (4 * by + y) * 32 + 4 * bx;
                for (t, &k) in l1[at..at + 4].iter_mut().zip(row) {
                    *t = D::decode(k);
                }
            }
            let mut k2 = [[0u32; 2]; 2];
            for (y, row) in k2.iter_mut().enumerate() {
                let (a, b) = (&k1[2 * y], &k1[2 * y + 1]);
                for (x, k) in row.iter_mut().enumerate() {
                    *k = a[2 * x].max(a[2 * x + 1]).max(b[2 * x]).max(b[2 * x + 1]);
                }
            }
            for (y, row) in k2.iter().enumerate() {
                let at = (2 * by + y) * 16 + 2 * bx;
                l2[at] = D::decode(row[0]);
                l2[at + 1] = D::decode(row[1]);
            }
            l3[8 * by + bx] = D::decode(k2[0][0].max(k2[0][1]).max(k2[1][0]).max(k2[1][1]));
        }
        // Levels 4–6: 4 × 4, 2 × 2 and 1 texels (depths, never NaN: one `maxss` each).
        use crate::edge::max;
        let (l4, rest) = upper.split_at_mut(16);
        let (l5, l6) = rest.split_at_mut(4);
        for y in 0..4 {
            for x in 0..4 {
                let at = 16 * y + 2 * x;
                l4[4 * y + x] = max(max(l3[at], l3[at + 1]), max(l3[at + 8], l3[at + 9]));
            }
        }
        for y in 0..2 {
            for x in 0..2 {
                let at = 8 * y + 2 * x;
                l5[2 * y + x] = max(max(l4[at], l4[at + 1]), max(l4[at + 4], l4[at + 5]));
            }
        }
        l6[0] = max(max(l5[0], l5[1]), max(l5[2], l5[3]));
    }

    /// Texels `r` of level `level` (≥ 2) from the level below.
    #[cfg(test)]
    fn reduce_level(&mut self, level: usize, r: Rect) {
        let (below, above) = self.mips.split_at_mut(OFFSETS[level - 1]);
        let src = &below[OFFSETS[level - 2]..];
        let s = TILE >> level; // this level's side
        reduce_2x2(src, 2 * s, 2 * s, above, s, r);
    }

    /// Recomputes every level from the depth keys: the reference the incremental
    /// [`TileLevels::update`] is tested against.
    #[cfg(test)]
    pub(crate) fn compute<D: DepthCodec>(&mut self, depth: &[u32]) {
        let t = TILE as usize;
        let first = &mut self.mips[..OFFSETS[1]];
        // Level 1 from the keys: keys order like depths, so take the max key, decode once.
        for y in 0..t / 2 {
            let (r0, r1) = (&depth[(2 * y) * t..(2 * y + 1) * t], &depth[(2 * y + 1) * t..(2 * y + 2) * t]);
            for x in 0..t / 2 {
                let k = r0[2 * x].max(r0[2 * x + 1]).max(r1[2 * x]).max(r1[2 * x + 1]);
                first[y * (t / 2) + x] = D::decode(k);
            }
        }
        for level in 2..=6 {
            let s = TILE >> level;
            self.reduce_level(level, Rect { x0: 0, y0: 0, x1: s - 1, y1: s - 1 });
        }
        self.stale_blocks = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::Unorm16;
    use crate::setup::{setup, Setup, SnappedVertex, Viewport};

    /// A triangle of depth `z` over the screen points `pts` (a 128 × 64 screen).
    fn flat(pts: [(f32, f32); 3], z: f32) -> Tri {
        let v = pts.map(|(x, y)| SnappedVertex { x: crate::setup::snap(x), y: crate::setup::snap(y), z });
        match setup(v, 1, false, &Viewport::new(128, 64, true)) {
            Setup::Ready(t) => t,
            other => panic!("{other:?}"),
        }
    }

    /// A triangle is occluded in a tile only when it lies behind every depth drawn where it
    /// reaches, by more than the format's tie margin: the whole-tile test first, then the
    /// texels under it. The tile (the right one of a 128 × 64 screen) is drawn at 0.25 on
    /// its left half and 0.75 on its right half.
    #[test]
    fn a_triangle_is_occluded_only_behind_the_depths_where_it_reaches() {
        let mut lv = TileLevels::new(TileRect { x0: 64, y0: 0, w: 64, h: 64 });
        lv.clear::<Unorm16>();
        let depth: Vec<u32> = (0..64 * 64).map(|i| Unorm16::key(if i % 64 < 32 { 0.25 } else { 0.75 })).collect();
        lv.compute::<Unorm16>(&depth);
        let far = lv.mips[OFFSETS[5]];
        assert!((far - 0.75).abs() < 1e-4, "{far}");
        let whole = [(60.0, -4.0), (140.0, -4.0), (100.0, 80.0)];
        let (left, right) = ([(70.0, 10.0), (90.0, 10.0), (80.0, 30.0)], [(100.0, 10.0), (120.0, 10.0), (110.0, 30.0)]);
        let m = lv.tie_margin;
        assert!(lv.occludes(far, m, &flat(whole, 0.8)), "behind the whole tile");
        assert!(
            !lv.occludes(far, m, &flat(whole, far + 0.5 * lv.tie_margin)),
            "within the tie margin of the farthest depth"
        );
        assert!(!lv.occludes(far, m, &flat(whole, 0.5)), "in front of the right half");
        assert!(lv.occludes(far, m, &flat(left, 0.5)), "behind the left half, where it lies");
        assert!(!lv.occludes(far, m, &flat(right, 0.5)), "in front of the right half, where it lies");
        assert!(
            !lv.occludes(far, m, &flat(whole, 0.0)) && !lv.occludes(far, m, &flat(whole, -0.5)),
            "at or before the near plane"
        );
    }
}

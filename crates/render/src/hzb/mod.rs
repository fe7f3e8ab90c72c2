//! The hierarchical z-buffer: Greene's z-pyramid (N. Greene, M. Kass, G. Miller,
//! "Hierarchical Z-Buffer Visibility", SIGGRAPH 1993), every level of it in one place.
//!
//! Level 0 is the depth buffer itself; level k + 1 stores for each texel the FARTHEST (max)
//! window depth of the up to 2 × 2 texels below it (`reduce_2x2`). Odd sizes round up
//! (`ceil(w / 2)`), and an edge texel takes the max of the children that exist: those are
//! the only pixels it stands for, so the bound stays exact. A screen rectangle whose
//! nearest possible depth is farther than the max stored over every texel it touches cannot
//! pass a LESS depth test anywhere: it is occluded. Depths only ever decrease while a frame
//! is drawn, so a level that lags behind the pixels is still a safe (conservative) bound.
//!
//! The pyramid lives in three parts, finest first:
//! * `tile`: levels 1–6 inside each 64 × 64 rasterizer tile (`TileLevels`), kept up to
//!   date by the rasterizer block by block as it draws (the texel of an 8 × 8 block is
//!   refreshed right after a triangle writes into it, so the next triangles of the same
//!   batch are tested against it, as Masked Occlusion Culling does), and the coarse tests
//!   that skip hidden triangles at binning and hidden 8 × 8 blocks in the rasterizer;
//! * `upper`: the levels from one texel per tile up to one texel over the screen;
//! * `session`: [`TilePyramid`], box queries against both, during a frame session.
//!
//! [`DepthPyramid`] (`screen`) is the same pyramid over a finished whole-screen depth
//! buffer, for tests against a frame after the fact and for pictures of the levels.

pub(crate) mod screen;
pub(crate) mod session;
pub(crate) mod tile;
pub(crate) mod upper;

pub use screen::DepthPyramid;
pub use session::TilePyramid;
pub(crate) use tile::TileLevels;
pub(crate) use upper::UpperLevels;

/// A pixel (or texel) rectangle, inclusive bounds.
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

/// One level of a pyramid: `width × height` texels, row-major, each the max window depth of
/// the texels below it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Level {
    /// Texels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The texels, row-major (`width × height`).
    pub texels: Vec<f32>,
}

impl Level {
    /// A `width × height` level with every texel at `value`.
    pub fn filled(width: u32, height: u32, value: f32) -> Self {
        Self { width, height, texels: vec![value; width as usize * height as usize] }
    }

    /// The texel at (x, y).
    #[inline(always)]
    pub fn at(&self, x: u32, y: u32) -> f32 {
        self.texels[(y * self.width + x) as usize]
    }

    /// The level above this one, every texel at `value`.
    pub fn coarser(&self, value: f32) -> Self {
        Self::filled(self.width.div_ceil(2), self.height.div_ceil(2), value)
    }

    /// Recomputes the texels of this level inside `r` (this level's coordinates) from
    /// `below`, the next finer level.
    #[inline]
    pub fn reduce_from(&mut self, below: &Level, r: Rect) {
        reduce_2x2(&below.texels, below.width, below.height, &mut self.texels, self.width, r);
    }
}

/// The one 2 × 2 max reduction: texels of `dst` (row stride `dw`) inside `r` become the max
/// of their up to 2 × 2 children in `src` (`sw × sh`; a child past an odd edge is the edge
/// texel itself, which leaves the max unchanged).
#[inline(always)]
pub(crate) fn reduce_2x2(src: &[f32], sw: u32, sh: u32, dst: &mut [f32], dw: u32, r: Rect) {
    let (sw, sh, dw) = (sw as usize, sh as usize, dw as usize);
    let (x0, x1) = (r.x0 as usize, r.x1 as usize);
    // Texels x < sw / 2 have both children in their row: a straight loop over pairs that
    // vectorizes; at most one texel (an odd width's last) takes the clamped form.
    let full = (sw / 2).clamp(x0, x1 + 1);
    for y in r.y0 as usize..=r.y1 as usize {
        let s0 = 2 * y;
        let s1 = (2 * y + 1).min(sh - 1);
        let (row0, row1) = (&src[s0 * sw..(s0 + 1) * sw], &src[s1 * sw..(s1 + 1) * sw]);
        let out = &mut dst[y * dw..(y + 1) * dw];
        let pairs = row0[2 * x0..2 * full].chunks_exact(2).zip(row1[2 * x0..2 * full].chunks_exact(2));
        for (o, (p, q)) in out[x0..full].iter_mut().zip(pairs) {
            *o = p[0].max(p[1]).max(q[0]).max(q[1]);
        }
        for (x, o) in out.iter_mut().enumerate().take(x1 + 1).skip(full) {
            let a = 2 * x;
            let b = (2 * x + 1).min(sw - 1);
            *o = row0[a].max(row0[b]).max(row1[a]).max(row1[b]);
        }
    }
}

/// The max of `depth` (row stride `w`) over `r`: the brute-force answer pyramid tests are
/// checked against.
#[cfg(test)]
pub(crate) fn brute_max(depth: &[f32], w: u32, r: Rect) -> f32 {
    let mut m = f32::MIN;
    for y in r.y0..=r.y1 {
        for x in r.x0..=r.x1 {
            m = m.max(depth[(y * w + x) as usize]);
        }
    }
    m
}

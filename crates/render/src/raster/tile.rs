//! One tile's pixel buffers: depth keys, triangle IDs and depth-test counts, row stride
//! [`TILE`], with padding after the last row for the eight-lane kernels.

use crate::depth::DepthCodec;
use crate::tiling::{TileRect, TILE};

/// Padding after a tile's last row: the kernels work in groups of four or eight pixels and
/// may read and rewrite (unchanged) entries past a row's end.
pub(crate) const PAD: usize = 8;

/// One tile's depth keys, IDs and depth-test counts (row stride [`TILE`]): the scratch
/// buffer a worker draws tiles in, set to the rectangle of the tile it draws.
#[derive(Debug, Clone)]
pub(crate) struct TileBuf {
    /// The tile being drawn.
    pub rect: TileRect,
    /// Depth keys ([`DepthCodec::key`]).
    pub depth: Vec<u32>,
    /// Triangle IDs.
    pub ids: Vec<u32>,
    /// Depth tests per pixel (only used when counting).
    pub counts: Vec<u32>,
}

impl TileBuf {
    /// A scratch buffer drawing the tile `rect`.
    pub(crate) fn new(rect: TileRect) -> Self {
        let n = (TILE * TILE) as usize + PAD;
        Self { rect, depth: vec![0; n], ids: vec![0; n], counts: vec![0; n] }
    }

    /// Clears the tile for a frame session in depth format `D`: the far plane's key inside
    /// the screen and 0 (nearest) outside it, so that the pyramid's max ignores pixels that
    /// do not exist; IDs to 0, depth-test counts too when `counting`.
    pub(crate) fn clear_for_session<D: DepthCodec>(&mut self, counting: bool) {
        let clear = D::FORMAT.key(1.0);
        let (w, h) = (self.rect.w as usize, self.rect.h as usize);
        let t = TILE as usize;
        for row in self.depth[..h * t].chunks_exact_mut(t) {
            row[..w].fill(clear);
        }
        self.zero_outside();
        self.ids.fill(0);
        if counting {
            self.counts.fill(0);
        }
    }

    /// Sets the depth keys of the buffer's pixels off the screen (right of `w`, below `h`)
    /// to 0, so that the pyramid's max ignores them: a tile cut by the screen edge drawn
    /// again in a session, whose pixels on the screen are loaded.
    pub(crate) fn zero_outside(&mut self) {
        let (w, h) = (self.rect.w as usize, self.rect.h as usize);
        let t = TILE as usize;
        if w == t && h == t {
            return;
        }
        for (r, row) in self.depth[..t * t].chunks_exact_mut(t).enumerate() {
            row[if r < h { w } else { 0 }..].fill(0);
        }
    }
}

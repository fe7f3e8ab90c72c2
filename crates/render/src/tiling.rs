//! How the screen is cut for the rasterizer: 64 × 64-pixel tiles (the unit of binning,
//! parallelism and of the per-tile z-pyramid levels), each made of 8 × 8-pixel blocks (the
//! unit of the block walk and of coarse depth).

/// Tile side in pixels (a power of two).
pub(crate) const TILE: u32 = 64;
/// log2 of [`TILE`].
pub(crate) const TILE_SHIFT: u32 = 6;
/// Block side in pixels.
pub(crate) const BLOCK: i32 = 8;

/// A tile's pixel rectangle on the target: left column, top row, width and height (≤
/// [`TILE`] at the right and bottom borders).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct TileRect {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
}

/// The tile grid of a framebuffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Grid {
    pub tiles_x: u32,
    pub tiles_y: u32,
    pub width: u32,
    pub height: u32,
}

impl Grid {
    pub fn new(width: u32, height: u32) -> Self {
        Self { tiles_x: width.div_ceil(TILE), tiles_y: height.div_ceil(TILE), width, height }
    }

    pub fn len(&self) -> usize {
        (self.tiles_x * self.tiles_y) as usize
    }

    /// Tile `k`'s pixel rectangle.
    pub fn tile_rect(&self, k: usize) -> TileRect {
        let (tx, ty) = (k as u32 % self.tiles_x, k as u32 / self.tiles_x);
        let (x0, y0) = (tx * TILE, ty * TILE);
        TileRect { x0, y0, w: TILE.min(self.width - x0), h: TILE.min(self.height - y0) }
    }
}

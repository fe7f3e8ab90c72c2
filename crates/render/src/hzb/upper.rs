//! The z-pyramid levels above the tiles of a frame session: level 6 holds one texel per
//! 64 × 64 tile (the max of the tile's own top level), each level above it the max of 2 × 2
//! texels below, up to one texel over the whole screen.

use super::{Level, Rect, TileLevels};

/// Levels 6 and up of a frame session's pyramid.
#[derive(Debug, Clone, Default)]
pub(crate) struct UpperLevels {
    /// Level 6 first, up to the 1 × 1 top.
    pub levels: Vec<Level>,
}

impl UpperLevels {
    /// Clears the levels for a grid of `tiles_x × tiles_y` tiles (allocated only when the
    /// grid changes).
    pub(crate) fn clear(&mut self, tiles_x: u32, tiles_y: u32) {
        if self.levels.first().is_some_and(|l| (l.width, l.height) == (tiles_x, tiles_y)) {
            for l in &mut self.levels {
                l.texels.fill(1.0);
            }
            return;
        }
        self.levels.clear();
        let mut l = Level::filled(tiles_x, tiles_y, 1.0);
        while l.width > 1 || l.height > 1 {
            let up = l.coarser(1.0);
            self.levels.push(l);
            l = up;
        }
        self.levels.push(l);
    }

    /// Recomputes every level from the tiles' own levels (untouched tiles count as clear).
    pub(crate) fn update(&mut self, tiles: &[TileLevels]) {
        let Some(l6) = self.levels.first_mut() else { return };
        for (v, t) in l6.texels.iter_mut().zip(tiles) {
            *v = if t.touched { t.mips[super::tile::OFFSETS[5]] } else { 1.0 };
        }
        for k in 1..self.levels.len() {
            let (below, above) = self.levels.split_at_mut(k);
            let dst = &mut above[0];
            let r = Rect { x0: 0, y0: 0, x1: dst.width - 1, y1: dst.height - 1 };
            dst.reduce_from(&below[k - 1], r);
        }
    }
}

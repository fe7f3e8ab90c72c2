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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::{DepthCodec, Unorm16};
    use crate::tiling::TileRect;

    /// Level 6, which binning tests every triangle against first: the clear depth for every
    /// tile of a new session, and after an update each drawn tile's farthest depth, the
    /// others still clear.
    #[test]
    fn level_6_follows_the_drawn_tiles() {
        let mut upper = UpperLevels::default();
        upper.clear(2, 1);
        assert_eq!(upper.levels[0].texels, [1.0; 2]);
        let mut tiles: Vec<TileLevels> =
            (0..2).map(|k| TileLevels::new(TileRect { x0: 64 * k, y0: 0, w: 64, h: 64 })).collect();
        tiles[1].clear::<Unorm16>();
        tiles[1].compute::<Unorm16>(&vec![Unorm16::key(0.5); 64 * 64]);
        upper.update(&tiles);
        let l6 = &upper.levels[0].texels;
        assert_eq!(l6[0], 1.0, "a tile not drawn into");
        assert!((l6[1] - 0.5).abs() < 1e-4, "{}", l6[1]);
        assert_eq!(l6[1], tiles[1].mips[super::super::tile::OFFSETS[5]]);
        upper.clear(2, 1);
        assert_eq!(upper.levels[0].texels, [1.0; 2], "a new session");
    }
}

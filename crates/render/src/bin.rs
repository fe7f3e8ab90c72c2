//! Binning: which screen tiles each set-up triangle touches.
//!
//! Sort-middle parallel rendering (Molnar et al., "A Sorting Classification of Parallel
//! Rendering", 1994): triangles are set up once, then appended to compact per-tile index
//! lists; tiles are rasterized independently, each owning its pixels. A triangle whose
//! bounding box spans several tiles is tested against each tile rectangle with its edge
//! functions, so long thin triangles are not sent to tiles they only pass by. Lists keep
//! submission order, which makes the image independent of the thread count.

use std::sync::atomic::AtomicBool;

use crate::edge::{misses_rect, Tri};
use crate::geometry::Chunk;
use crate::hzb::TileLevels;
use crate::tiling::{Grid, TILE, TILE_SHIFT};

/// Bins all triangles of a chunk (also assigns their multi-tile flags).
///
/// With `session` (the tiles of a frame session, the pyramid's level 6 over them and the
/// depth format's tie margin), the coarse depth test runs here, while the triangle is still
/// in cache from setup: a triangle behind a tile's pyramid (as of the last draw batch) is not
/// sent to that tile (the per-tile z-max of ATI's "HyperZ", then Greene's test per triangle;
/// [`TileLevels::occludes`]). The whole tile's farthest depth is read from level 6, one
/// compact array that stays in every core's cache (the boxfield's occluder pass binned in
/// 0.98 ms instead of 1.18 ms on one thread, and 2–4% faster on two): the tile records hold
/// it too, but the core that drew the tile last wrote them.
#[inline(never)] // a stage of its own in profiles
pub(crate) fn bin_chunk(chunk: &mut Chunk, grid: &Grid, session: Option<(&[TileLevels], &[f32], f32)>) {
    let n = grid.len();
    chunk.bins.resize_with(n, Vec::new);
    chunk.bins.truncate(n);
    for b in &mut chunk.bins {
        b.clear();
    }
    chunk.multi.clear();
    chunk.hidden_at_binning = 0;
    let tx = grid.tiles_x as usize;
    let hidden = |k: usize, t: &Tri| session.is_some_and(|(levels, l6, margin)| levels[k].occludes(l6[k], margin, t));
    for (i, t) in chunk.tris.iter_mut().enumerate() {
        let [x0, y0, x1, y1] = t.bbox.map(|v| v as u32);
        let (tx0, ty0) = (x0 >> TILE_SHIFT, y0 >> TILE_SHIFT);
        let (tx1, ty1) = (x1 >> TILE_SHIFT, y1 >> TILE_SHIFT);
        if tx0 == tx1 && ty0 == ty1 {
            let k = ty0 as usize * tx + tx0 as usize;
            if hidden(k, t) {
                chunk.stats.coarse_rejected += 1;
                chunk.hidden_at_binning += 1;
            } else {
                chunk.bins[k].push(i as u32);
            }
            continue;
        }
        t.multi = chunk.multi.len() as u32;
        chunk.multi.push(AtomicBool::new(false));
        bin_across(t, i as u32, tx, &mut chunk.bins, &mut chunk.stats.coarse_rejected, hidden);
    }
}

/// Bins triangle `t` (number `i` of its chunk) that spans several tiles: each tile of its box
/// that it covers some pixel center of, unless `hidden` says the tile's pyramid hides it there
/// (counted into `rejected`). Out of line, so that the loop over the chunk's triangles, most of
/// them in one tile, stays short.
#[inline(never)]
fn bin_across(
    t: &Tri,
    i: u32,
    tiles_x: usize,
    bins: &mut [Vec<u32>],
    rejected: &mut u64,
    hidden: impl Fn(usize, &Tri) -> bool,
) {
    let [x0, y0, x1, y1] = t.bbox.map(|v| v as u32);
    for ty in y0 >> TILE_SHIFT..=y1 >> TILE_SHIFT {
        for txi in x0 >> TILE_SHIFT..=x1 >> TILE_SHIFT {
            let r = [
                (txi * TILE).max(x0) as i32,
                (ty * TILE).max(y0) as i32,
                (txi * TILE + TILE - 1).min(x1) as i32,
                (ty * TILE + TILE - 1).min(y1) as i32,
            ];
            let k = ty as usize * tiles_x + txi as usize;
            if misses_rect(t, r) {
                continue;
            }
            if hidden(k, t) {
                *rejected += 1;
            } else {
                bins[k].push(i);
            }
        }
    }
}

//! Edge-function rasterization of set-up triangles into screen tiles: the block walk and
//! the tile stage of the pipeline.
//!
//! Every triangle walks the 8×8 blocks of its bounding box (clipped to the tile), with the
//! block-level trivial reject/accept of Greene ("Hierarchical Polygon Tiling with Coverage
//! Masks", SIGGRAPH 1996) and Intel's Masked Occlusion Culling (Hasselgren, Andersson,
//! Akenine-Möller 2016): blocks outside an edge are skipped, and an edge the whole block is
//! inside of is dropped from the per-pixel test. In a frame session a block whose pyramid
//! texel lies nearer than the triangle's plane over it is skipped too (coarse depth,
//! [`TileLevels::block_hidden`]), and a triangle behind every block it reaches is settled
//! before its edges are formed ([`TileLevels::blocks_hidden`]). The rest go through one
//! [`Kernel`]. Edge values run on i32 where they fit ([`FastEdges`]), per pixel on i64 in
//! the rare blocks where they do not (vertices thousands of pixels away), and so do the
//! blocks of a triangle whose depth plane could give NaN ([`Tri::depths_are_numbers`]; never
//! one set-up makes). After a triangle writes into a block, the block's pyramid texel is
//! refreshed at once, so the next triangles of the same batch are tested against it.
//!
//! The edge functions and the fill rule are in [`crate::edge`]; the per-pixel kernels in
//! [`kernel`]; the tile buffers in [`tile`].
//!
//! # Instruction sets
//!
//! The tile stage ([`raster_tiles`]) is compiled three times: as plain Rust with the
//! [`Rows`] kernel, inside an AVX2 `#[target_feature]` function with the [`Avx2`] kernel,
//! and inside an AVX-512 one with the [`Avx512`] kernel, every function on the way
//! `#[inline(always)]` so that the whole walk gets the wider code. The run-time
//! [`SimdLevel`] picks one per frame; the images are identical.

pub(crate) mod kernel;
pub(crate) mod store;
pub(crate) mod tile;

use std::sync::atomic::Ordering;
use std::sync::Mutex;

use sightline_spatial::SimdLevel;

use crate::claim::{for_each_claimed, Claim};
use crate::depth::{with_codec, DepthCodec, DepthFormat};
use crate::edge::{edges, wide_block, BlockSetup, Edge, FastEdges, Tri};
use crate::geometry::Chunk;
use crate::hzb::TileLevels;
use crate::tiling::{TileRect, BLOCK, TILE_SHIFT};
pub(crate) use kernel::{Avx2, Avx512, Kernel, Rows};
pub(crate) use store::{Planes, Span};
pub(crate) use tile::TileBuf;

/// Per-triangle result of rasterizing into one tile.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TriRaster {
    /// Pixel centers covered (= fragments depth-tested).
    pub covered: u32,
    /// Fragments that passed the depth test.
    pub written: u32,
}

/// Rasterizes one triangle into `tile` (depth test LESS, exact ties to the smaller ID; IDs
/// written with depth), with the
/// block kernel `K`; `lv` holds the tile's pyramid levels (read and refreshed when
/// `lv.coarse`).
///
/// # Safety
/// The CPU must support `K`'s instruction set.
#[inline(always)]
pub(crate) unsafe fn raster_tri<D: DepthCodec, const COUNT: bool, K: Kernel>(
    t: &Tri,
    tile: &mut TileBuf,
    lv: &mut TileLevels,
) -> TriRaster {
    let x0 = (t.bbox[0] as i32).max(tile.rect.x0 as i32);
    let y0 = (t.bbox[1] as i32).max(tile.rect.y0 as i32);
    let x1 = (t.bbox[2] as i32).min((tile.rect.x0 + tile.rect.w) as i32 - 1);
    let y1 = (t.bbox[3] as i32).min((tile.rect.y0 + tile.rect.h) as i32 - 1);
    if x0 > x1 || y0 > y1 {
        return TriRaster::default();
    }
    let rect = [x0, y0, x1, y1];
    // In a frame session, a triangle behind every 8×8 block it reaches is settled before its
    // edges and block walk (the walk would skip each block by the same test): binning tested
    // it before the batch's earlier triangles refreshed those blocks.
    if lv.coarse && lv.blocks_hidden(t, rect) {
        return TriRaster::default();
    }
    let e = edges(t);
    // The kernels take every depth to be a number: a plane that could give NaN (never one
    // set-up makes) is drawn pixel by pixel with scalar keys.
    let numbers = t.depths_are_numbers();
    let fast = if numbers { FastEdges::new(&e, rect) } else { None };
    // SAFETY (both): forwarded from the caller.
    match fast {
        Some(f) => unsafe { walk_blocks::<D, COUNT, K>(t, tile, lv, rect, &e, |r, c| f.block(r, c)) },
        None => unsafe { walk_blocks::<D, COUNT, K>(t, tile, lv, rect, &e, |r, _| wide_block(&e, r, numbers)) },
    }
}

/// Walks the 8×8 blocks (aligned in the tile) of the triangle's bounding box `[x0, y0, x1,
/// y1]` (clipped to the tile); `setup(rect, block corner)` (screen pixels) says how each
/// block runs. Blocks outside an edge are skipped, blocks behind the tile's pyramid (coarse
/// depth) too, and the rest go through the kernel. A block the triangle wrote into gets its
/// pyramid texel refreshed at once and is marked stale for the levels below it (frame
/// sessions only).
///
/// # Safety
/// The CPU must support `K`'s instruction set.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // edge k of several arrays
unsafe fn walk_blocks<D: DepthCodec, const COUNT: bool, K: Kernel>(
    t: &Tri,
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    [x0, y0, x1, y1]: [i32; 4],
    e: &[Edge; 3],
    mut setup: impl FnMut([i32; 4], [i32; 2]) -> BlockSetup,
) -> TriRaster {
    let mut out = TriRaster::default();
    let (tx, ty) = (tile.rect.x0 as i32, tile.rect.y0 as i32);
    // Block corners are aligned to the tile (whose corner is a multiple of 8).
    let mut by = y0 & !(BLOCK - 1);
    while by <= y1 {
        let (ry0, ry1) = (by.max(y0), (by + BLOCK - 1).min(y1));
        let mut bx = x0 & !(BLOCK - 1);
        while bx <= x1 {
            let (rx0, rx1) = (bx.max(x0), (bx + BLOCK - 1).min(x1));
            let rect = [rx0, ry0, rx1, ry1];
            let corner = [bx - tx, by - ty];
            let how = setup(rect, [bx, by]);
            bx += BLOCK;
            if matches!(how, BlockSetup::Outside) || (lv.coarse && lv.block_hidden(t, rect, corner)) {
                continue;
            }
            let before = out.written;
            match how {
                BlockSetup::Outside => {}
                // SAFETY: forwarded from the caller.
                BlockSetup::Narrow(k32) => unsafe { K::block::<D, COUNT>(t, tile, rect, &k32, &mut out) },
                BlockSetup::Wide(e00) => {
                    for py in ry0..=ry1 {
                        let zrow = t.depth_row(py);
                        let row = ((py - ty) as usize) << TILE_SHIFT;
                        let dy = (py - ry0) as i64;
                        let mut ev = [0i64; 3];
                        for k in 0..3 {
                            ev[k] = e00[k] + e[k].b * dy;
                        }
                        for px in rx0..=rx1 {
                            if (ev[0] | ev[1] | ev[2]) >= 0 {
                                let z = t.depth_at(zrow, px);
                                kernel::fragment::<D, COUNT>(tile, row + (px - tx) as usize, z, t.id, &mut out);
                            }
                            for k in 0..3 {
                                ev[k] += e[k].a;
                            }
                        }
                    }
                }
            }
            if lv.coarse && out.written != before {
                lv.refresh_block::<D>(&tile.depth, corner);
            }
        }
        by += BLOCK;
    }
    out
}

/// Counters of one tile's rasterization.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct TileStats {
    pub tested: u64,
    pub written: u64,
    pub empty: u64,
    /// Pixels with an ID after the pass, counted on a fresh frame only (0 otherwise; a
    /// session keeps its tiles' counts in their records).
    pub covered: u64,
}

impl TileStats {
    fn sum(a: Self, b: Self) -> Self {
        Self {
            tested: a.tested + b.tested,
            written: a.written + b.written,
            empty: a.empty + b.empty,
            covered: a.covered + b.covered,
        }
    }
}

/// What the tile stage draws and how.
#[derive(Clone, Copy)]
pub(crate) struct TilePass<'a> {
    /// The binned chunks, in submission order.
    pub chunks: &'a [Chunk],
    /// The target: outside sessions each tile loads its pixels from it before drawing
    /// (unless `fresh`) and stores them to it right after; in a session each tile drawn
    /// into is stored to it right after drawing (written through).
    pub target: &'a Planes<'a>,
    /// The target is overwritten whole: tiles start from the clear values, and tiles with
    /// nothing to draw are stored as cleared.
    pub fresh: bool,
    /// Depth tests are counted per pixel.
    pub counting: bool,
    /// Inside a frame session: tiles start cleared on their first use in the session and
    /// keep their pyramid levels.
    pub session: bool,
}

/// The tile stage: every tile rasterizes its binned triangles, in parallel over tiles, on
/// the instruction set `simd` resolves to. Each worker draws in a scratch tile taken from
/// `scratch` (made when there is none) and given back after the pass, so that the many
/// passes of a frame session allocate none.
pub(crate) fn raster_tiles(
    levels: &mut [TileLevels],
    scratch: &mut Vec<TileBuf>,
    pass: &TilePass,
    fmt: DepthFormat,
    simd: SimdLevel,
) -> TileStats {
    with_codec!(fmt, tiles_in::<_>(levels, scratch, pass, simd))
}

type TileFn = fn(&mut TileBuf, &mut TileLevels, usize, bool, &TilePass) -> TileStats;

/// The AVX2 build of the tile function.
///
/// # Safety
/// The CPU must have AVX2 and the other features enabled here.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn raster_tile_avx2<D: DepthCodec, const C: bool>(
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    index: usize,
    binned: bool,
    pass: &TilePass,
) -> TileStats {
    // SAFETY: the CPU has AVX2 (this function's contract).
    unsafe { raster_tile::<D, C, Avx2>(tile, lv, index, binned, pass) }
}

/// The AVX-512 build of the tile function (the walk as AVX2's, the [`Avx512`] kernel).
///
/// # Safety
/// The CPU must have AVX-512 F, BW, DQ and VL and the other features enabled here.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::incompatible_msrv)]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn raster_tile_avx512<D: DepthCodec, const C: bool>(
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    index: usize,
    binned: bool,
    pass: &TilePass,
) -> TileStats {
    // SAFETY: the CPU has AVX-512 (this function's contract).
    unsafe { raster_tile::<D, C, Avx512>(tile, lv, index, binned, pass) }
}

fn tiles_in<D: DepthCodec>(
    levels: &mut [TileLevels],
    scratch: &mut Vec<TileBuf>,
    pass: &TilePass,
    simd: SimdLevel,
) -> TileStats {
    let count = pass.counting;
    // SAFETY (every `unsafe` below): `Rows` needs nothing beyond the baseline, and the
    // AVX2 and AVX-512 functions are chosen only when the resolved level says the CPU has
    // every feature they enable.
    let f: TileFn = match (simd.resolve(), count) {
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx512, false) => |t, l, i, b, p| unsafe { raster_tile_avx512::<D, false>(t, l, i, b, p) },
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx512, true) => |t, l, i, b, p| unsafe { raster_tile_avx512::<D, true>(t, l, i, b, p) },
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx2, false) => |t, l, i, b, p| unsafe { raster_tile_avx2::<D, false>(t, l, i, b, p) },
        #[cfg(target_arch = "x86_64")]
        (SimdLevel::Avx2, true) => |t, l, i, b, p| unsafe { raster_tile_avx2::<D, true>(t, l, i, b, p) },
        (_, false) => |t, l, i, b, p| unsafe { raster_tile::<D, false, Rows>(t, l, i, b, p) },
        (_, true) => |t, l, i, b, p| unsafe { raster_tile::<D, true, Rows>(t, l, i, b, p) },
    };
    // Tiles are claimed one at a time, costliest (most binned triangles) first; see
    // [`crate::claim`]. A tile with nothing binned needs work only when a fresh target is
    // cleared through it; otherwise it is settled here, so that the many small batches of
    // an occlusion pass hand out only the few tiles they touch.
    let mut order: Vec<(usize, usize, &mut TileLevels)> = Vec::with_capacity(levels.len());
    for (i, lv) in levels.iter_mut().enumerate() {
        let cost = pass.chunks.iter().map(|c| c.bins[i].len()).sum::<usize>();
        if cost > 0 || pass.fresh {
            order.push((cost, i, lv));
        }
    }
    order.sort_unstable_by_key(|&(c, i, _)| (std::cmp::Reverse(c), i));
    // A tile's pixels live in the target between passes (in a session too: tiles write
    // through), so every tile is drawn in one scratch buffer per worker: it stays in the
    // core's cache, where the 240 tile buffers of a frame would be cleared and read back
    // from the shared cache.
    let pool = Mutex::new(std::mem::take(scratch));
    let take = || pool.lock().ok().and_then(|mut p| p.pop()).unwrap_or_else(|| TileBuf::new(TileRect::default()));
    let workers = for_each_claimed(
        order,
        Claim::InOrder,
        || (TileStats::default(), take()),
        |(sum, s), (cost, i, lv)| {
            s.rect = lv.rect;
            *sum = TileStats::sum(*sum, f(s, lv, i, cost > 0, pass));
        },
    );
    *scratch = pool.into_inner().unwrap_or_default();
    workers.into_iter().fold(TileStats::default(), |a, (b, buf)| {
        scratch.push(buf);
        TileStats::sum(a, b)
    })
}

/// One tile of the tile stage, drawn in the scratch buffer `tile`: start from the clear
/// values (a fresh target, or a session's first use of the tile) or load the target's
/// pixels, draw, store back. In a session the tile also keeps its pyramid levels.
/// `binned` says whether any triangle is binned to it.
///
/// # Safety
/// The CPU must support `K`'s instruction set.
#[inline(always)]
unsafe fn raster_tile<D: DepthCodec, const C: bool, K: Kernel>(
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    index: usize,
    binned: bool,
    pass: &TilePass,
) -> TileStats {
    let mut st = TileStats::default();
    let out = pass.target;
    if !binned {
        if pass.fresh {
            // SAFETY: this task is the only one on tile `index`, whose rectangle no other
            // tile shares.
            unsafe { out.clear(tile.rect, D::decode(D::FORMAT.key(1.0))) };
        }
        return st;
    }
    if pass.session {
        // A tile drawn into before in this session is loaded and stored only under the 8×8
        // blocks its binned triangles reach: the later batches of an occlusion walk touch a
        // few blocks of many tiles. Its first use clears and stores it whole.
        let first = !lv.touched;
        let span = if first { Span::whole(tile) } else { binned_span(tile, index, pass.chunks) };
        // Only a span that is loaded is asked for ahead: the planes are written without
        // reading them (`crate::stream`).
        if !first {
            out.prefetch(tile, span);
        }
        // The pyramid's max reads whole 8×8 blocks: pixels off the screen hold 0 (the
        // scratch buffer last held another tile).
        if first {
            tile.clear_for_session::<D>(C);
        } else {
            tile.zero_outside();
        }
        let covered_before = if first {
            lv.clear::<D>();
            lv.covered = 0;
            0
        } else {
            // SAFETY: as above, the tile's rectangle is this task's alone.
            unsafe { out.load::<D, true>(tile, C, span) }
        };
        // SAFETY: forwarded from the caller.
        unsafe { raster_bins::<D, C, true, K>(tile, lv, index, pass.chunks, &mut st) };
        lv.update::<D>(&tile.depth);
        // SAFETY: as above.
        let covered_after = unsafe { out.store::<D, true>(tile, span) };
        // The tile's covered pixels: those outside the span are unchanged.
        lv.covered = lv.covered + covered_after - covered_before;
        return st;
    }
    let span = Span::whole(tile);
    // Start from the clear values on a fresh target; otherwise load the tile's pixels
    // (earlier batches may have drawn here).
    if pass.fresh {
        tile.depth.fill(D::FORMAT.key(1.0));
        tile.ids.fill(0);
        if C {
            tile.counts.fill(0); // only read and written when counting
        }
    } else {
        out.prefetch(tile, span);
        // SAFETY: as above.
        unsafe { out.load::<D, false>(tile, C, span) };
    }
    // SAFETY: forwarded from the caller.
    unsafe { raster_bins::<D, C, false, K>(tile, lv, index, pass.chunks, &mut st) };
    // Only a fresh frame's count is used (a plain batch's would include earlier batches').
    st.covered = if pass.fresh {
        // SAFETY: as above.
        unsafe { out.store::<D, true>(tile, span) }
    } else {
        // SAFETY: as above.
        unsafe { out.store::<D, false>(tile, span) }
    };
    st
}

/// The 8×8 blocks of `tile` (tile `index`) that the triangles binned to it reach, as a
/// span: the union of their bounding boxes, widened to whole blocks and cut to the tile.
fn binned_span(tile: &TileBuf, index: usize, chunks: &[Chunk]) -> Span {
    let (tx, ty) = (tile.rect.x0 as i32, tile.rect.y0 as i32);
    let mut b = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
    for c in chunks {
        for &i in &c.bins[index] {
            let t = &c.tris[i as usize].bbox;
            b = [b[0].min(t[0] as i32), b[1].min(t[1] as i32), b[2].max(t[2] as i32), b[3].max(t[3] as i32)];
        }
    }
    let (w, h) = (tile.rect.w as i32, tile.rect.h as i32);
    let lo = |v: i32, o: i32| ((v - o).max(0) & !(BLOCK - 1)) as usize;
    let hi = |v: i32, o: i32, n: i32| (((v - o + BLOCK) & !(BLOCK - 1)).clamp(0, n)) as usize;
    let (x0, y0) = (lo(b[0], tx), lo(b[1], ty));
    let (x1, y1) = (hi(b[2], tx, w), hi(b[3], ty, h));
    if b[0] > b[2] || x0 >= x1 || y0 >= y1 {
        return Span { x0: 0, x1: 0, y0: 0, y1: 0 };
    }
    Span { x0, x1, y0, y1 }
}

/// Rasterizes the tile's binned triangles, chunk after chunk, in submission order.
/// With `COARSE` (frame sessions), 8×8 blocks behind the tile's pyramid are skipped (on a
/// tile's first use in the session only blocks refreshed in this batch can hide anything);
/// whole triangles behind it were left out at binning.
///
/// # Safety
/// The CPU must support `K`'s instruction set.
#[inline(always)]
unsafe fn raster_bins<D: DepthCodec, const C: bool, const COARSE: bool, K: Kernel>(
    tile: &mut TileBuf,
    lv: &mut TileLevels,
    index: usize,
    chunks: &[Chunk],
    st: &mut TileStats,
) {
    // With depth-test counting on, coarse rejection stays on: the heat map then counts
    // the tests actually made.
    lv.coarse = COARSE && lv.touched;
    for c in chunks {
        for &i in &c.bins[index] {
            let t = &c.tris[i as usize];
            // SAFETY: forwarded from the caller.
            let r = unsafe { raster_tri::<D, C, K>(t, tile, lv) };
            st.tested += r.covered as u64;
            st.written += r.written as u64;
            if t.multi == u32::MAX {
                st.empty += (r.covered == 0) as u64;
            } else if r.covered > 0 {
                c.multi[t.multi as usize].store(true, Ordering::Relaxed);
            }
        }
    }
}

#[cfg(test)]
mod tests;

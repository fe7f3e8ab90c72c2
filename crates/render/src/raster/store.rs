//! Tiles to the framebuffer and back, inside the tile stage.
//!
//! A tile's buffers (depth keys and IDs, 32 KiB) are loaded from the target just before
//! its triangles are drawn and stored right after, by the same task, while they are still
//! in that core's cache: one pass over the target's planes instead of a separate copy
//! stage that reads every tile buffer back in. Tasks run in parallel over tiles, and each
//! touches only its own tile's rectangle of the planes, which is what makes sharing the
//! planes between them sound.
//!
//! The depth plane is written past the cache ([`crate::stream`]): a frame's depth and IDs
//! (7.4 MB at 1280×720) would otherwise be read from memory just to be overwritten. On a
//! 2-core AMD EPYC without AVX-512, whose memory copies about 6–9 GB/s, writing both planes
//! so made the street path's oracle frame take 0.87–0.92× as long on two threads and the
//! `hzb` frame 0.88–0.92× (in one process, the two ways taking turns frame by frame). The
//! ID plane is written plainly again: the frame reads it back (a session's later batches
//! load the spans they draw into, the shading pass reads every ID), and the 3.7 MB it
//! keeps in the shared cache are worth the lines it reads first. With IDs written plainly
//! and depth past the cache, on the same kind of machine, the `hzb` frame took a median
//! 0.97× as long (eleven alternated pairs of runs, eight faster) and the oracle frame
//! 0.99×; with both planes plain, the `hzb` frame 1.00–1.08× (five pairs).
//!
//! Loading is the other way round: a tile's rectangle is 64 pieces of 256 bytes, a plane's
//! row apart, too short for the hardware's stream prefetch, so a load would wait for each
//! line in turn. A tile that is loaded therefore asks for its lines before it is drawn
//! ([`Planes::prefetch`]).
//!
//! A frame session draws the same way, batch after batch: a tile is cleared on its first
//! use and stored whole; when a later batch draws into it again, only the 8×8 blocks its
//! triangles reach are loaded and stored back (a [`Span`]; at 10^9 triangles, 60 batches a
//! street frame, the raster stage took 0.955× as long as loading and storing whole tiles,
//! median of six alternated pairs). Its pyramid levels stay with the renderer, and the
//! pyramid's level 0 is read from the depth plane. (Sessions used to keep all 240 tile
//! buffers of a 1280×720 frame and copy them out at the end: the copy read 7.5 MB back from
//! the shared cache, and clearing the buffers on first use fetched them, so the street
//! path's oracle frame took 1.42–1.45× as long in a session as in a plain frame, against
//! 1.08–1.15× when written through.)

use std::marker::PhantomData;

use super::tile::TileBuf;
use crate::depth::{DepthCodec, DepthFormat};
use crate::stream::{fill_through, write_through, written_through};
use crate::tiling::{TileRect, TILE, TILE_SHIFT};
use crate::Framebuffer;

/// A rectangle of a tile's pixels, in tile coordinates, half-open: columns `x0..x1`, rows
/// `y0..y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Span {
    pub x0: usize,
    pub x1: usize,
    pub y0: usize,
    pub y1: usize,
}

impl Span {
    /// All of `tile`'s pixels.
    pub(crate) fn whole(tile: &TileBuf) -> Self {
        Self { x0: 0, x1: tile.rect.w as usize, y0: 0, y1: tile.rect.h as usize }
    }
}

/// The depth, ID and (when counting) depth-test planes of one framebuffer, shared between
/// the tile tasks of a pass; each task reads and writes only its own tile's rectangle.
pub(crate) struct Planes<'a> {
    depth: *mut f32,
    ids: *mut u32,
    /// Null without depth-test counts.
    counts: *mut u32,
    width: usize,
    height: usize,
    _fb: PhantomData<&'a mut Framebuffer>,
}

// SAFETY: the pointers come from a framebuffer borrowed mutably for 'a, and every access
// through them is a tile's own rectangle (see the methods' contracts): tasks on different
// threads never touch the same pixel.
unsafe impl Send for Planes<'_> {}
// SAFETY: as above.
unsafe impl Sync for Planes<'_> {}

impl<'a> Planes<'a> {
    /// The planes of `fb`, for the length of its borrow.
    pub(crate) fn new(fb: &'a mut Framebuffer) -> Self {
        let (width, height) = (fb.width() as usize, fb.height() as usize);
        // The raw row accesses rely on every plane holding width × height values.
        fb.assert_planes();
        let counts = fb.depth_tests.as_mut().map_or(std::ptr::null_mut(), |c| c.as_mut_ptr());
        Self { depth: fb.depth.as_mut_ptr(), ids: fb.ids.as_mut_ptr(), counts, width, height, _fb: PhantomData }
    }

    /// Index of the first pixel of row `r` of `tile` in the planes.
    fn row_start(&self, tile: TileRect, r: usize) -> usize {
        let (x0, y0, w, h) = (tile.x0 as usize, tile.y0 as usize, tile.w as usize, tile.h as usize);
        // A real check (not debug only): it is what keeps the raw accesses inside the planes.
        assert!(x0 + w <= self.width && y0 + h <= self.height && r < h, "tile outside the framebuffer");
        (y0 + r) * self.width + x0
    }

    /// Row `r` of `tile` in the planes: (depth, IDs, counts when present).
    ///
    /// # Safety
    /// No other task may access this tile's rectangle at the same time.
    #[allow(clippy::type_complexity)] // three parallel row slices
    #[allow(clippy::mut_from_ref)] // the shared planes' rows: the caller owns the tile's rectangle
    unsafe fn row(&self, tile: TileRect, r: usize) -> (&mut [f32], &mut [u32], Option<&mut [u32]>) {
        let (at, w) = (self.row_start(tile, r), tile.w as usize);
        // SAFETY: `at..at + w` lies inside each plane (checked above; every plane holds
        // width × height entries), and the caller guarantees no other access to it.
        unsafe {
            (
                std::slice::from_raw_parts_mut(self.depth.add(at), w),
                std::slice::from_raw_parts_mut(self.ids.add(at), w),
                (!self.counts.is_null()).then(|| std::slice::from_raw_parts_mut(self.counts.add(at), w)),
            )
        }
    }

    /// Asks for the cache lines of `span` of `tile`'s rectangle in the depth and ID planes,
    /// to be loaded and written back (see the module docs); a no-op off x86-64.
    pub(crate) fn prefetch(&self, tile: &TileBuf, span: Span) {
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (tile, span);
        #[cfg(target_arch = "x86_64")]
        for r in span.y0..span.y1 {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_ET0};
            let (at, bytes) = (self.row_start(tile.rect, r) + span.x0, 4 * (span.x1 - span.x0));
            for plane in [self.depth as *const i8, self.ids as *const i8] {
                // SAFETY: prefetching never faults, and the addresses lie inside the planes
                // (`row_start` checks the rectangle).
                unsafe {
                    let row = plane.add(4 * at);
                    for off in (0..bytes).step_by(64) {
                        _mm_prefetch::<_MM_HINT_ET0>(row.add(off));
                    }
                    // The row's last line, when the row does not start on a line.
                    _mm_prefetch::<_MM_HINT_ET0>(row.add(bytes - 1));
                }
            }
        }
    }

    /// Loads `span` of `tile` from the planes (depth-test counts too when `counting`); with
    /// `COVERED`, returns the covered pixels (ID ≠ 0) of the span (else 0).
    ///
    /// # Safety
    /// No other task may access this tile's rectangle at the same time.
    pub(crate) unsafe fn load<D: DepthCodec, const COVERED: bool>(
        &self,
        tile: &mut TileBuf,
        counting: bool,
        span: Span,
    ) -> u64 {
        let (x0, x1) = (span.x0, span.x1);
        let mut covered = 0;
        for r in span.y0..span.y1 {
            // SAFETY: forwarded from the caller.
            let (depth, ids, counts) = unsafe { self.row(tile.rect, r) };
            let at = r << TILE_SHIFT;
            for (k, d) in tile.depth[at + x0..at + x1].iter_mut().zip(&depth[x0..x1]) {
                *k = D::FORMAT.key_of_stored(*d);
            }
            tile.ids[at + x0..at + x1].copy_from_slice(&ids[x0..x1]);
            if let (true, Some(c)) = (counting, counts) {
                tile.counts[at + x0..at + x1].copy_from_slice(&c[x0..x1]);
            }
            if COVERED {
                covered += count_covered(&ids[x0..x1]);
            }
        }
        covered
    }

    /// Stores `span` of `tile` into the planes (depth-test counts too when present); with
    /// `COVERED`, returns the covered pixels (ID ≠ 0) of the span (else 0).
    ///
    /// # Safety
    /// No other task may access this tile's rectangle at the same time.
    pub(crate) unsafe fn store<D: DepthCodec, const COVERED: bool>(&self, tile: &TileBuf, span: Span) -> u64 {
        let (x0, x1) = (span.x0, span.x1);
        let mut covered = 0;
        for r in span.y0..span.y1 {
            // SAFETY: forwarded from the caller.
            let (depth, ids, counts) = unsafe { self.row(tile.rect, r) };
            let at = r << TILE_SHIFT;
            let keys = &tile.depth[at + x0..at + x1];
            if D::FORMAT == DepthFormat::F32 {
                // F32 decodes a key as the float of its bits.
                write_through(&mut depth[x0..x1], keys);
            } else {
                let mut row = [0f32; TILE as usize];
                for (d, &k) in row.iter_mut().zip(keys) {
                    *d = D::decode(k);
                }
                write_through(&mut depth[x0..x1], &row[..keys.len()]);
            }
            let src = &tile.ids[at + x0..at + x1];
            // Plainly: the frame reads its IDs back (see the module docs).
            ids[x0..x1].copy_from_slice(src);
            if let Some(c) = counts {
                write_through(&mut c[x0..x1], &tile.counts[at + x0..at + x1]);
            }
            if COVERED {
                covered += count_covered(src);
            }
        }
        written_through();
        covered
    }

    /// Writes `tile` as cleared: depth `far`, ID 0, no depth tests.
    ///
    /// # Safety
    /// No other task may access this tile's rectangle at the same time.
    pub(crate) unsafe fn clear(&self, tile: TileRect, far: f32) {
        for r in 0..tile.h as usize {
            // SAFETY: forwarded from the caller.
            unsafe { self.clear_row(tile, r, far) };
        }
        written_through();
    }

    /// Row `r` of [`Planes::clear`]; the caller calls [`written_through`] once it has
    /// written its rows.
    ///
    /// # Safety
    /// No other task may access this row of the tile's rectangle at the same time.
    pub(crate) unsafe fn clear_row(&self, tile: TileRect, r: usize, far: f32) {
        // SAFETY: forwarded from the caller.
        let (depth, ids, counts) = unsafe { self.row(tile, r) };
        fill_through(depth, far);
        ids.fill(0);
        if let Some(c) = counts {
            fill_through(c, 0);
        }
    }
}

/// The covered pixels (ID ≠ 0) of a row of IDs.
fn count_covered(ids: &[u32]) -> u64 {
    ids.iter().map(|&i| (i != 0) as u32).sum::<u32>() as u64
}

//! The fragment walk of the transparency passes: the pixels a set-up triangle covers, with
//! the depth keys the z-buffer rasterizer would give them, one horizontal band of the
//! framebuffer at a time.
//!
//! The tile rasterizer ([`crate::raster`]) only writes depth and IDs. Masked and blended
//! surfaces need more per fragment (an alpha test before the depth write, or a list of
//! fragments), so they walk their triangles here instead: the same set-up triangles (the
//! geometry stage's), the same edge functions and fill rule ([`crate::edge::edges`], exact
//! on i64), and the depth plane evaluated as the kernels evaluate it
//! ([`Tri::depth_row`], [`Tri::depth_at`]). A fragment found here is one the z-buffer would
//! test, at the same key, so transparent and opaque surfaces meet exactly as two opaque ones
//! would (LESS, ties to the smaller triangle ID).
//!
//! Passes run in parallel over bands of whole rows: a band owns its pixels, so no two
//! threads write one pixel, and the result does not depend on the thread count.

use crate::depth::DepthCodec;
use crate::edge::{edges, Tri};
use crate::geometry::Chunk;
use crate::Framebuffer;

/// Bands per worker thread: several, to balance bands of uneven cost.
const BANDS_PER_THREAD: usize = 4;

/// One band of rows of a framebuffer, its planes sliced to those rows.
pub(crate) struct Band<'f> {
    /// The first row.
    pub y0: u32,
    /// Rows in the band.
    pub rows: u32,
    /// Framebuffer width.
    pub width: u32,
    /// Colors of the band's pixels.
    pub color: &'f mut [[u8; 4]],
    /// Window depths.
    pub depth: &'f mut [f32],
    /// Triangle IDs.
    pub ids: &'f mut [u32],
    /// Depth-test counts, when the framebuffer counts them.
    pub counts: Option<&'f mut [u32]>,
}

impl Band<'_> {
    /// The band's pixel index of screen pixel (x, y) (a pixel of the band).
    #[inline(always)]
    pub fn index(&self, x: i32, y: i32) -> usize {
        (y as u32 - self.y0) as usize * self.width as usize + x as usize
    }

    /// The band's rows: the first and the count.
    #[inline(always)]
    pub fn span(&self) -> (u32, u32) {
        (self.y0, self.rows)
    }
}

/// Calls `f(x, y, key)` for every pixel of the rows `span` (first, count) that `t` covers,
/// `key` being the depth key (format `D`) the z-buffer rasterizer would test there.
#[inline]
pub(crate) fn walk<D: DepthCodec>(t: &Tri, (first, rows): (u32, u32), mut f: impl FnMut(i32, i32, u32)) {
    let [bx0, by0, bx1, by1] = t.bbox.map(|v| v as i32);
    let y0 = by0.max(first as i32);
    let y1 = by1.min((first + rows) as i32 - 1);
    if y0 > y1 {
        return;
    }
    let e = edges(t);
    for py in y0..=y1 {
        let zrow = t.depth_row(py);
        let mut ev = e.map(|e| e.a * bx0 as i64 + e.b * py as i64 + e.c);
        for px in bx0..=bx1 {
            if (ev[0] | ev[1] | ev[2]) >= 0 {
                f(px, py, D::key(t.depth_at(zrow, px)));
            }
            for (v, e) in ev.iter_mut().zip(&e) {
                *v += e.a;
            }
        }
    }
}

/// Cuts `fb` into bands of whole rows, several per worker thread.
pub(crate) fn bands(fb: &mut Framebuffer) -> Vec<Band<'_>> {
    let (w, h) = (fb.width(), fb.height());
    let rows = h.div_ceil((rayon::current_num_threads().max(1) * BANDS_PER_THREAD) as u32).max(1);
    let n = (w * rows) as usize;
    let mut counts: Vec<Option<&mut [u32]>> = match &mut fb.depth_tests {
        Some(c) => c.chunks_mut(n).map(Some).collect(),
        None => Vec::new(),
    };
    counts.resize_with(h.div_ceil(rows) as usize, || None);
    fb.color
        .chunks_mut(n)
        .zip(fb.depth.chunks_mut(n))
        .zip(fb.ids.chunks_mut(n))
        .zip(counts)
        .enumerate()
        .map(|(k, (((color, depth), ids), counts))| Band {
            y0: k as u32 * rows,
            rows: (ids.len() / w as usize) as u32,
            width: w,
            color,
            depth,
            ids,
            counts,
        })
        .collect()
}

/// Every set-up triangle of the chunks, in submission order.
pub(crate) fn triangles(chunks: &[Chunk]) -> impl Iterator<Item = &Tri> + Clone {
    chunks.iter().flat_map(|c| c.tris.iter())
}

//! Edge-function rasterization of set-up triangles into one screen tile.
//!
//! Pineda, "A Parallel Algorithm for Polygon Rasterization" (SIGGRAPH 1988): each edge
//! a→b defines `E(p) = (b−a) × (p−a)`, positive on the inside of a positively oriented
//! triangle; a pixel is covered when its center gives `E ≥ 0` on all three edges, and E is
//! stepped incrementally (one add per pixel and edge). On snapped integer coordinates the
//! test is exact, so two triangles sharing an edge never both cover a center, nor miss one.
//!
//! Ties (`E = 0`): the edge belongs to the triangle for which it is a LEFT or a BOTTOM edge
//! as seen in the image (llvmpipe's rule, ../shared/anchors/fillrule_probe.py). With
//! positive area in y-down coordinates, an edge running up the screen (dy < 0) has the
//! triangle on its right: a left edge; a horizontal edge running right-to-left (dy = 0,
//! dx < 0) has the triangle above it: a bottom edge. Other edges get a bias of −1, which
//! turns `E ≥ 0` into `E > 0` on integers.
//!
//! Every triangle walks the 8×8 blocks of its bounding box (clipped to the tile), with the
//! block-level trivial reject/accept of Greene 1996 and Intel's Masked Occlusion Culling:
//! blocks outside an edge are skipped, and an edge the whole block is inside of is dropped
//! from the per-pixel test. In a frame session a block whose pyramid texel lies nearer than
//! the triangle's plane over it is skipped too (coarse depth). The rest go through one
//! kernel: eight pixels of a row per AVX2 step, everything that is constant down a column
//! set up once per block. Edge values run on i32 (exact with wrapping steps while the values
//! fit), per pixel on i64 in the rare blocks where they do not (vertices thousands of pixels
//! away). After a triangle writes into a block, the block's pyramid texel is refreshed at
//! once, so the next triangles of the same batch are tested against it.

use crate::setup::{Tri, ONE, SUBPIXEL_BITS};

/// Tile side in pixels (a power of two).
pub const TILE: u32 = 64;
/// log2 of [`TILE`].
pub const TILE_SHIFT: u32 = 6;
const BLOCK: i32 = 8;

/// Padding after a tile's last row: row loops work in groups of four or eight pixels and
/// may read and rewrite (unchanged) entries past a row's end.
const PAD: usize = 8;

/// One tile's depth keys, IDs and depth-test counts (row stride [`TILE`]).
#[derive(Debug, Clone)]
pub struct TileBuf {
    /// Left pixel column.
    pub x0: u32,
    /// Top pixel row.
    pub y0: u32,
    /// Width (≤ TILE at the right border).
    pub w: u32,
    /// Height.
    pub h: u32,
    /// Depth keys ([`crate::DepthFormat::key`]).
    pub depth: Vec<u32>,
    /// Triangle IDs.
    pub ids: Vec<u32>,
    /// Depth tests per pixel (only used when counting).
    pub counts: Vec<u32>,
    /// Whether the tile received triangles in the current pass.
    pub dirty: bool,
    /// In a frame session: whether the tile has been drawn into (else it is still clear).
    pub touched: bool,
    /// Whether the rasterizer may skip 8×8 blocks behind the tile's pyramid, and keeps the
    /// pyramid of the blocks it writes up to date (level 3 at once, the rest marked in
    /// `stale_blocks`); set per pass, on in frame sessions.
    pub coarse: bool,
    /// In a frame session: the tile's z-pyramid levels 1..=6 (32², 16², …, 1² texels, each
    /// the max window depth of the 2×2 texels below), see [`MIP_OFFSETS`].
    pub mips: Vec<f32>,
    /// In a frame session: the 8×8-pixel blocks (bit `8·by + bx`) written since the pyramid
    /// levels were last brought up to date.
    pub stale_blocks: u64,
    /// In a frame session: the depth format's [`crate::DepthFormat::tie_margin`], added to
    /// pyramid texels before a coarse test says "hidden".
    pub tie_margin: f32,
}

/// Offsets of levels 1..=6 in [`TileBuf::mips`] (index = level − 1), and the total length.
pub const MIP_OFFSETS: [usize; 7] = [0, 1024, 1280, 1344, 1360, 1364, 1365];

impl TileBuf {
    /// An empty tile at pixel (x0, y0) of size w × h.
    pub fn new(x0: u32, y0: u32, w: u32, h: u32) -> Self {
        // Padding: the block kernel's eight lanes may run 7 entries past the last row.
        let n = (TILE * TILE) as usize + PAD;
        Self {
            x0,
            y0,
            w,
            h,
            depth: vec![0; n],
            ids: vec![0; n],
            counts: vec![0; n],
            dirty: false,
            touched: false,
            coarse: false,
            mips: vec![1.0; MIP_OFFSETS[6]],
            stale_blocks: 0,
            tie_margin: 0.0,
        }
    }

    /// Clears the tile for a frame session in depth format `fmt`: the far plane's key inside
    /// the screen and 0 (nearest) outside it, so that the pyramid's max ignores pixels that
    /// do not exist; IDs to 0, depth-test counts too when `counting`.
    pub fn clear_for_session(&mut self, fmt: crate::DepthFormat, counting: bool) {
        let clear = fmt.key(1.0);
        self.tie_margin = fmt.tie_margin();
        let (w, h) = (self.w as usize, self.h as usize);
        if w == TILE as usize && h == TILE as usize {
            self.depth[..(TILE * TILE) as usize].fill(clear);
        } else {
            for r in 0..TILE as usize {
                let row = &mut self.depth[r << TILE_SHIFT..(r + 1) << TILE_SHIFT];
                if r < h {
                    row[..w].fill(clear);
                    row[w..].fill(0);
                } else {
                    row.fill(0);
                }
            }
        }
        self.ids.fill(0);
        if counting {
            self.counts.fill(0);
        }
        self.mips.fill(1.0);
        // A tile cut by the screen edge: its first update computes every level, so that
        // texels over pixels that do not exist take their depth 0 (no pixel written there
        // would ever mark them).
        self.stale_blocks = if self.w < TILE || self.h < TILE { !0 } else { 0 };
        self.touched = true;
    }

    /// Coarse depth (the seeds' per-tile Z_max, "HyperZ"; Greene's pyramid test per
    /// triangle): true when triangle `t` cannot pass the depth test anywhere in this tile,
    /// judged from the tile's pyramid levels. The levels may lag behind the pixels (they are
    /// refreshed after each draw batch), but depths only decrease, so a stale max is a safe
    /// bound. Only meaningful inside a frame session, on a tile drawn into in it (binning
    /// asks before sending a triangle to the tile).
    #[inline]
    pub fn occludes(&self, t: &Tri) -> bool {
        // The triangle's nearest depth: its plane at the three vertices, minus the rounding
        // that evaluating the plane at a pixel center may add.
        let d = |k: usize| ((t.x[k] - t.x[0]) as f32, (t.y[k] - t.y[0]) as f32);
        let ((x1, y1), (x2, y2)) = (d(1), d(2));
        let (a1, b1, a2, b2) = (t.zx * x1, t.zy * y1, t.zx * x2, t.zy * y2);
        let z1 = t.z0 + a1 + b1;
        let z2 = t.z0 + a2 + b2;
        let err = 8.0 * f32::EPSILON * (t.z0.abs() + a1.abs() + b1.abs() + a2.abs() + b2.abs()) + 1e-7;
        // The triangle's pixels in this tile, in tile coordinates.
        let x0 = (t.bbox[0] as u32).max(self.x0) - self.x0;
        let y0 = (t.bbox[1] as u32).max(self.y0) - self.y0;
        let x1 = (t.bbox[2] as u32).min(self.x0 + self.w - 1).saturating_sub(self.x0);
        let y1 = (t.bbox[3] as u32).min(self.y0 + self.h - 1).saturating_sub(self.y0);
        if x0 > x1 || y0 > y1 {
            return false;
        }
        // Depth is affine in the window: over the pixel centers of this rectangle it is at
        // least its value at the nearest corner. For a big triangle reaching far behind
        // this tile, that bound is much tighter than its nearest vertex.
        // Small triangles (most of them) are not worth the second bound; big ones keep it
        // even where only a corner of them reaches into this tile.
        let near = t.z0.min(z1).min(z2) - err;
        let near = if t.bbox[2] - t.bbox[0] < 8 && t.bbox[3] - t.bbox[1] < 8 {
            near
        } else {
            let (sx, sy) = (self.x0 as i32, self.y0 as i32);
            near.max(plane_min(t, [x0 as i32 + sx, y0 as i32 + sy, x1 as i32 + sx, y1 as i32 + sy]))
        };
        if !(near > 0.0) {
            return false;
        }
        let span = (x1 - x0).max(y1 - y0) + 1;
        let mut level = 1usize;
        while (span >> level) > 1 && level < 6 {
            level += 1;
        }
        let s = (TILE >> level) as usize;
        let off = MIP_OFFSETS[level - 1];
        for y in (y0 >> level) as usize..=(y1 >> level) as usize {
            for x in (x0 >> level) as usize..=(x1 >> level) as usize {
                if near <= self.mips[off + y * s + x] + self.tie_margin {
                    return false;
                }
            }
        }
        true
    }

    /// Brings [`TileBuf::mips`] up to date after writes: levels 1–3 only under the stale
    /// 8×8 blocks (one level-3 texel each), levels 4–6 (21 texels) whole.
    pub fn update_mips(&mut self, fmt: crate::DepthFormat) {
        let mut stale = std::mem::take(&mut self.stale_blocks);
        if stale == 0 {
            return;
        }
        const T: usize = TILE as usize;
        while stale != 0 {
            let b = stale.trailing_zeros() as usize;
            stale &= stale - 1;
            let (bx, by) = (b & 7, b >> 3);
            // Level 1 (32×32): the block's 4×4 texels from the keys (the max key, converted once).
            let l1 = &mut self.mips[..MIP_OFFSETS[1]];
            for y in 4 * by..4 * by + 4 {
                let r0 = &self.depth[(2 * y) * T..(2 * y + 1) * T];
                let r1 = &self.depth[(2 * y + 1) * T..(2 * y + 2) * T];
                for x in 4 * bx..4 * bx + 4 {
                    let k = r0[2 * x].max(r0[2 * x + 1]).max(r1[2 * x]).max(r1[2 * x + 1]);
                    l1[y * 32 + x] = fmt.depth(k);
                }
            }
            // Level 2 (16×16): 2×2 texels; level 3 (8×8): the block's own texel.
            let (below, above) = self.mips.split_at_mut(MIP_OFFSETS[1]);
            for y in 2 * by..2 * by + 2 {
                for x in 2 * bx..2 * bx + 2 {
                    let i = (2 * y) * 32 + 2 * x;
                    above[y * 16 + x] = below[i].max(below[i + 1]).max(below[i + 32]).max(below[i + 33]);
                }
            }
            let (below, above) = self.mips.split_at_mut(MIP_OFFSETS[2]);
            let l2 = &below[MIP_OFFSETS[1]..];
            let i = (2 * by) * 16 + 2 * bx;
            above[by * 8 + bx] = l2[i].max(l2[i + 1]).max(l2[i + 16]).max(l2[i + 17]);
        }
        for level in 4..=6 {
            self.reduce_level(level);
        }
    }

    /// Level `level` (≥ 2) of [`TileBuf::mips`] from the level below.
    fn reduce_level(&mut self, level: usize) {
        let (below, above) = self.mips.split_at_mut(MIP_OFFSETS[level - 1]);
        let src = &below[MIP_OFFSETS[level - 2]..];
        let s = TILE as usize >> level; // this level's side
        for y in 0..s {
            for x in 0..s {
                let i = (2 * y) * (2 * s) + 2 * x;
                above[y * s + x] = src[i].max(src[i + 1]).max(src[i + 2 * s]).max(src[i + 2 * s + 1]);
            }
        }
    }

    /// Recomputes [`TileBuf::mips`] from the depth keys (max of 2×2 per level): the reference
    /// the incremental [`TileBuf::update_mips`] is tested against.
    #[cfg(test)]
    pub(crate) fn compute_mips(&mut self, fmt: crate::DepthFormat) {
        let t = TILE as usize;
        let (first, rest) = self.mips.split_at_mut(MIP_OFFSETS[1]);
        // Level 1 from the keys: keys order like depths, so take the max key, convert once.
        for y in 0..t / 2 {
            let (r0, r1) = (&self.depth[(2 * y) * t..(2 * y + 1) * t], &self.depth[(2 * y + 1) * t..(2 * y + 2) * t]);
            for x in 0..t / 2 {
                let k = r0[2 * x].max(r0[2 * x + 1]).max(r1[2 * x]).max(r1[2 * x + 1]);
                first[y * (t / 2) + x] = fmt.depth(k);
            }
        }
        let _ = rest;
        for level in 2..=6 {
            self.reduce_level(level);
        }
        self.stale_blocks = 0;
    }
}

/// Per-triangle result of rasterizing into one tile.
#[derive(Debug, Clone, Copy, Default)]
pub struct TriRaster {
    /// Pixel centers covered (= fragments depth-tested).
    pub covered: u32,
    /// Fragments that passed the depth test.
    pub written: u32,
}

#[derive(Clone, Copy)]
struct Edge {
    /// E at pixel center (px, py) is `a·px + b·py + c` (bias included).
    a: i64,
    b: i64,
    c: i64,
}

#[inline(always)]
fn edges(t: &Tri) -> [Edge; 3] {
    let half = (ONE / 2) as i64;
    let one = ONE as i64;
    std::array::from_fn(|i| {
        let j = (i + 1) % 3;
        let (ax, ay) = (t.x[i] as i64, t.y[i] as i64);
        let (dx, dy) = (t.x[j] as i64 - ax, t.y[j] as i64 - ay);
        let inclusive = dy < 0 || (dy == 0 && dx < 0);
        Edge { a: -dy * one, b: dx * one, c: dx * (half - ay) - dy * (half - ax) - (!inclusive) as i64 }
    })
}

/// True when some pixel center of the triangle's bounding box is covered (used by setup
/// for tiny boxes).
pub fn covers_any(t: &Tri) -> bool {
    let e = edges(t);
    let [x0, y0, x1, y1] = t.bbox.map(|v| v as i64);
    (y0..=y1).any(|py| (x0..=x1).any(|px| e.iter().all(|e| e.a * px + e.b * py + e.c >= 0)))
}

/// True when the triangle covers no pixel center of the inclusive pixel rectangle (a
/// conservative test: false means "maybe").
pub fn misses_rect(t: &Tri, r: [i32; 4]) -> bool {
    let e = edges(t);
    let (w, h) = ((r[2] - r[0]) as i64, (r[3] - r[1]) as i64);
    e.iter().any(|e| {
        let e00 = e.a * r[0] as i64 + e.b * r[1] as i64 + e.c;
        e00 + e.a.max(0) * w + e.b.max(0) * h < 0
    })
}

/// Depth key of window z for a format given as a const (0 = f32, 16, 24).
#[inline(always)]
pub fn key<const FMT: u8>(z: f32) -> u32 {
    // Branch-free so row loops vectorize. Interpolated z can stray a rounding error outside
    // [0, 1]: below 0 must clamp (a negative float's bits would compare as "far"); above 1
    // fails LESS against a cleared buffer anyway. NaN gives "far" (f32) or 0 (integers;
    // setup keeps depth planes finite).
    match FMT {
        16 => (z.clamp(0.0, 1.0) * 65535.0 + 0.5) as i32 as u32,
        24 => (z.clamp(0.0, 1.0) * 16_777_215.0 + 0.5) as i32 as u32,
        _ => {
            let b = z.to_bits();
            if (b as i32) < 0 {
                0
            } else {
                b
            }
        }
    }
}

/// Rasterizes one triangle into `tile` (depth test LESS; IDs written with depth).
#[inline]
pub fn raster_tri<const FMT: u8, const COUNT: bool>(t: &Tri, tile: &mut TileBuf) -> TriRaster {
    let x0 = (t.bbox[0] as i32).max(tile.x0 as i32);
    let y0 = (t.bbox[1] as i32).max(tile.y0 as i32);
    let x1 = (t.bbox[2] as i32).min((tile.x0 + tile.w) as i32 - 1);
    let y1 = (t.bbox[3] as i32).min((tile.y0 + tile.h) as i32 - 1);
    if x0 > x1 || y0 > y1 {
        return TriRaster::default();
    }
    raster_blocks::<FMT, COUNT>(t, tile, [x0, y0, x1, y1])
}

/// Depth at fixed-point offset (dx, dy) from vertex 0.
#[inline(always)]
fn depth_row(t: &Tri, py: i32) -> f32 {
    t.z0 + t.zy * (((py << SUBPIXEL_BITS) + ONE / 2 - t.y[0]) as f32)
}

#[inline(always)]
fn depth_at(t: &Tri, zrow: f32, px: i32) -> f32 {
    zrow + t.zx * (((px << SUBPIXEL_BITS) + ONE / 2 - t.x[0]) as f32)
}

/// The depth test: a fragment wins when it is nearer (LESS), or exactly as near and of a
/// smaller triangle ID. Drawing in ID order with a plain LESS test keeps the first (smallest
/// ID) of equal depths, so this gives the same image for ANY draw order: what lets culled,
/// front-to-back and clustered frames equal the brute-force frame pixel for pixel.
#[inline(always)]
pub(crate) fn wins(key: u32, id: u32, stored_key: u32, stored_id: u32) -> bool {
    key < stored_key || (key == stored_key && id < stored_id)
}

#[inline(always)]
fn fragment<const FMT: u8, const COUNT: bool>(tile: &mut TileBuf, idx: usize, z: f32, id: u32, r: &mut TriRaster) {
    let k = key::<FMT>(z);
    r.covered += 1;
    if COUNT {
        tile.counts[idx] += 1;
    }
    // LESS, with exact ties going to the smaller ID: what in-order drawing gives, but
    // independent of draw order, so culled and reordered frames equal brute force.
    if wins(k, id, tile.depth[idx], tile.ids[idx]) {
        tile.depth[idx] = k;
        tile.ids[idx] = id;
        r.written += 1;
    }
}

/// One row of a block for the row loops: edge values at its first pixel and their steps,
/// the depth plane along the row, the pixel count.
#[derive(Clone, Copy)]
struct Row {
    e: [i32; 3],
    a: [i32; 3],
    n: i32,
    zrow: f32,
    zx: f32,
    dx0: i32,
    id: u32,
}

/// Scalar form of a row (the reference; used where SSE2 is not available).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn row_scalar<const FMT: u8, const COUNT: bool>(
    r: &Row,
    depth: &mut [u32],
    ids: &mut [u32],
    counts: &mut [u32],
    out: &mut TriRaster,
) {
    let [mut e0, mut e1, mut e2] = r.e;
    for k in 0..r.n {
        let inside = (e0 | e1 | e2) >= 0;
        e0 = e0.wrapping_add(r.a[0]);
        e1 = e1.wrapping_add(r.a[1]);
        e2 = e2.wrapping_add(r.a[2]);
        let z = r.zrow + r.zx * (r.dx0 + (k << SUBPIXEL_BITS)) as f32;
        let key = key::<FMT>(z);
        let i = k as usize;
        let pass = inside & wins(key, r.id, depth[i], ids[i]);
        if pass {
            depth[i] = key;
            ids[i] = r.id;
        }
        if COUNT {
            counts[i] += inside as u32;
        }
        out.covered += inside as u32;
        out.written += pass as u32;
    }
}

/// The value unchanged, but opaque to the optimizer (an empty inline-asm barrier).
#[cfg(target_arch = "x86_64")]
#[cfg_attr(target_feature = "avx2", allow(dead_code))]
#[inline(always)]
fn opaque(mut v: std::arch::x86_64::__m128i) -> std::arch::x86_64::__m128i {
    // SAFETY: the assembly is empty; it only pins `v` to a register.
    unsafe { std::arch::asm!("/* {0} */", inout(xmm_reg) v, options(pure, nomem, nostack, preserves_flags)) };
    v
}

/// The lane sums of two vectors, in registers with SSE2 only (a store and four scalar loads
/// per row were a measurable share of the row loops' time).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn sum2(a: std::arch::x86_64::__m128i, b: std::arch::x86_64::__m128i) -> (u32, u32) {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of the x86_64 baseline.
    unsafe {
        // (a0+a2, a1+a3, b0+b2, b1+b3), then pairwise: lane 0 = Σa, lane 2 = Σb.
        let s = _mm_add_epi32(_mm_unpacklo_epi64(a, b), _mm_unpackhi_epi64(a, b));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0b10_11_00_01));
        (_mm_cvtsi128_si32(s) as u32, _mm_cvtsi128_si32(_mm_shuffle_epi32(s, 0b10)) as u32)
    }
}

/// A row in groups of four pixels with SSE2, branch-free (coverage and the depth test are
/// unpredictable along the edges of triangles). Same arithmetic as [`row_scalar`], so the same
/// result bit for bit. Lanes past the row are masked; they read and rewrite unchanged
/// values of the next row or of the buffer's padding.
#[cfg(target_arch = "x86_64")]
#[cfg_attr(target_feature = "avx2", allow(dead_code))]
#[inline(always)]
fn row_sse2<const FMT: u8, const COUNT: bool>(
    r: &Row,
    depth: &mut [u32],
    ids: &mut [u32],
    counts: &mut [u32],
    out: &mut TriRaster,
) {
    use std::arch::x86_64::*;
    let lanes = |a: i32| [0, a, a.wrapping_mul(2), a.wrapping_mul(3)];
    let (l0, l1, l2) = (lanes(r.a[0]), lanes(r.a[1]), lanes(r.a[2]));
    // SAFETY: SSE2 is part of the x86_64 baseline, so the intrinsics are always available;
    // memory is only touched through 4-element chunks of the slices (unaligned loads and
    // stores).
    unsafe {
        let v = |l: [i32; 4], base: i32| _mm_add_epi32(_mm_set1_epi32(base), _mm_setr_epi32(l[0], l[1], l[2], l[3]));
        let mut e0 = v(l0, r.e[0]);
        let mut e1 = v(l1, r.e[1]);
        let mut e2 = v(l2, r.e[2]);
        let s0 = _mm_set1_epi32(r.a[0].wrapping_mul(4));
        let s1 = _mm_set1_epi32(r.a[1].wrapping_mul(4));
        let s2 = _mm_set1_epi32(r.a[2].wrapping_mul(4));
        let mut k = _mm_setr_epi32(0, 1, 2, 3);
        let four = _mm_set1_epi32(4);
        let n = _mm_set1_epi32(r.n);
        let minus1 = _mm_set1_epi32(-1);
        let dx0 = _mm_set1_epi32(r.dx0);
        let (zrow, zx) = (_mm_set1_ps(r.zrow), _mm_set1_ps(r.zx));
        let id = _mm_set1_epi32(r.id as i32);
        let (mut cov, mut wr) = (_mm_setzero_si128(), _mm_setzero_si128());
        for ((dq, iq), cq) in depth.chunks_exact_mut(4).zip(ids.chunks_exact_mut(4)).zip(counts.chunks_exact_mut(4)) {
            let inside =
                _mm_and_si128(_mm_cmpgt_epi32(_mm_or_si128(_mm_or_si128(e0, e1), e2), minus1), _mm_cmplt_epi32(k, n));
            let dx = _mm_add_epi32(dx0, _mm_slli_epi32(k, SUBPIXEL_BITS as i32));
            let z = _mm_add_ps(zrow, _mm_mul_ps(zx, _mm_cvtepi32_ps(dx)));
            let key = match FMT {
                16 | 24 => {
                    let m = if FMT == 16 { 65535.0 } else { 16_777_215.0 };
                    let c = _mm_min_ps(_mm_max_ps(z, _mm_setzero_ps()), _mm_set1_ps(1.0));
                    _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(c, _mm_set1_ps(m)), _mm_set1_ps(0.5)))
                }
                _ => {
                    let bits = _mm_castps_si128(z);
                    _mm_andnot_si128(_mm_srai_epi32(bits, 31), bits)
                }
            };
            let dp = dq.as_mut_ptr() as *mut __m128i;
            let ip = iq.as_mut_ptr() as *mut __m128i;
            let d = _mm_loadu_si128(dp);
            let old = _mm_loadu_si128(ip);
            // Keys and IDs are below 2^31, so signed compares order them. Ties in depth go to
            // the smaller ID (see `wins`).
            let tie = _mm_and_si128(_mm_cmpeq_epi32(key, d), _mm_cmplt_epi32(id, old));
            let pass = _mm_and_si128(inside, _mm_or_si128(_mm_cmplt_epi32(key, d), tie));
            // Plain stores of the blended vectors. `opaque` hides that they are selects of
            // the loaded values: with AVX enabled LLVM would otherwise emit masked stores
            // (vpmaskmovd), several times slower on AMD Zen.
            _mm_storeu_si128(dp, opaque(_mm_or_si128(_mm_and_si128(pass, key), _mm_andnot_si128(pass, d))));
            _mm_storeu_si128(ip, opaque(_mm_or_si128(_mm_and_si128(pass, id), _mm_andnot_si128(pass, old))));
            if COUNT {
                let cp = cq.as_mut_ptr() as *mut __m128i;
                _mm_storeu_si128(cp, _mm_sub_epi32(_mm_loadu_si128(cp), inside));
            }
            cov = _mm_sub_epi32(cov, inside);
            wr = _mm_sub_epi32(wr, pass);
            e0 = _mm_add_epi32(e0, s0);
            e1 = _mm_add_epi32(e1, s1);
            e2 = _mm_add_epi32(e2, s2);
            k = _mm_add_epi32(k, four);
        }
        let (c, w) = sum2(cov, wr);
        out.covered += c;
        out.written += w;
    }
}

/// The value unchanged, but opaque to the optimizer (see [`opaque`]).
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn opaque256(mut v: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    // SAFETY: the assembly is empty; it only pins `v` to a register.
    unsafe { std::arch::asm!("/* {0} */", inout(ymm_reg) v, options(pure, nomem, nostack, preserves_flags)) };
    v
}

/// Runs one row starting at tile buffer index `base`, four pixels per step with SSE2 (the
/// block kernel of builds without AVX2).
#[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2"), allow(dead_code))]
#[inline(always)]
fn run_row<const FMT: u8, const COUNT: bool>(r: &Row, tile: &mut TileBuf, base: usize, out: &mut TriRaster) {
    let n4 = ((r.n + 3) & !3) as usize;
    let depth = &mut tile.depth[base..base + n4];
    let ids = &mut tile.ids[base..base + n4];
    let counts = &mut tile.counts[base..base + n4];
    #[cfg(target_arch = "x86_64")]
    row_sse2::<FMT, COUNT>(r, depth, ids, counts, out);
    #[cfg(not(target_arch = "x86_64"))]
    row_scalar::<FMT, COUNT>(r, depth, ids, counts, out);
}

/// Coarse depth per 8×8 block: true when the triangle's plane over the block's pixel
/// centers `[x0, y0, x1, y1]` (screen) lies behind the farthest depth drawn in the block
/// (the tile's pyramid level 3; `[bx, by]` is the block's corner in the tile).
#[inline]
fn block_hidden(t: &Tri, tile: &TileBuf, [x0, y0, x1, y1]: [i32; 4], [bx, by]: [i32; 2]) -> bool {
    let max = tile.mips[MIP_OFFSETS[2] + ((by >> 3) * 8 + (bx >> 3)) as usize];
    if max >= 1.0 {
        return false; // something is still clear here
    }
    plane_min(t, [x0, y0, x1, y1]) > max + tile.tie_margin
}

/// A lower bound of the triangle's depth plane over the pixel centers of the screen
/// rectangle `[x0, y0, x1, y1]` (inclusive): the plane is affine, so its minimum is at a
/// corner; the rounding that evaluating it at a pixel may add is subtracted.
#[inline]
fn plane_min(t: &Tri, [x0, y0, x1, y1]: [i32; 4]) -> f32 {
    let cx = |px: i32| t.zx * ((px << SUBPIXEL_BITS) + ONE / 2 - t.x[0]) as f32;
    let cy = |py: i32| t.zy * ((py << SUBPIXEL_BITS) + ONE / 2 - t.y[0]) as f32;
    let (a0, a1, b0, b1) = (cx(x0), cx(x1), cy(y0), cy(y1));
    let err = 8.0 * f32::EPSILON * (t.z0.abs() + a0.abs().max(a1.abs()) + b0.abs().max(b1.abs())) + 1e-7;
    t.z0 + a0.min(a1) + b0.min(b1) - err
}

/// Walks the 8×8 blocks (aligned in the tile) of the triangle's bounding box `[x0, y0, x1,
/// y1]` (clipped to the tile): blocks outside an edge are skipped, blocks behind the tile's
/// pyramid (coarse depth) too, and the rest go through the block kernel, edges the whole
/// block is inside of dropped from its test (Greene 1996; the block-level trivial
/// reject/accept of Intel's Masked Occlusion Culling). Edge values are set up per block in
/// i32 when they fit over the whole box ([`FastEdges`], nearly every triangle), else from
/// the i64 edge functions.
fn raster_blocks<const FMT: u8, const COUNT: bool>(t: &Tri, tile: &mut TileBuf, rect: [i32; 4]) -> TriRaster {
    let e = edges(t);
    match FastEdges::new(&e, rect) {
        Some(f) => walk_blocks::<FMT, COUNT>(t, tile, rect, &e, |r, c| f.block(r, c)),
        None => walk_blocks::<FMT, COUNT>(t, tile, rect, &e, |r, _| wide_block(&e, r)),
    }
}

/// How the kernel is to run one block.
enum BlockSetup {
    /// Outside an edge: nothing to do.
    Outside,
    /// Edge values in i32 (an edge the block is inside of is all zeros).
    Narrow(BlockEdges),
    /// Values too big for i32: per pixel on i64, from these values at the rectangle's first
    /// pixel (rare: vertices thousands of pixels away).
    Wide([i64; 3]),
}

/// Block setup from the i64 edge functions over the rectangle `[rx0, ry0, rx1, ry1]`.
#[allow(clippy::needless_range_loop)] // edge k of several arrays
fn wide_block(e: &[Edge; 3], [rx0, ry0, rx1, ry1]: [i32; 4]) -> BlockSetup {
    let (w, h) = ((rx1 - rx0) as i64, (ry1 - ry0) as i64);
    let mut fits = true;
    let mut k32 = BlockEdges { e: [0; 3], a: [0; 3], b: [0; 3] };
    let mut e00 = [0i64; 3];
    for k in 0..3 {
        let v = e[k].a * rx0 as i64 + e[k].b * ry0 as i64 + e[k].c;
        e00[k] = v;
        let lo = v + e[k].a.min(0) * w + e[k].b.min(0) * h;
        let hi = v + e[k].a.max(0) * w + e[k].b.max(0) * h;
        if hi < 0 {
            return BlockSetup::Outside;
        }
        if lo < 0 {
            // The edge crosses the block: tested per pixel. Wrapping i32 steps are exact
            // modulo 2^32, so values that fit i32 come out exact.
            fits &= lo >= i32::MIN as i64 && hi <= i32::MAX as i64;
            (k32.e[k], k32.a[k], k32.b[k]) = (v as i32, e[k].a as i32, e[k].b as i32);
        }
    }
    if fits {
        BlockSetup::Narrow(k32)
    } else {
        BlockSetup::Wide(e00)
    }
}

/// The block loop of [`raster_blocks`]; `setup(rect, block corner)` (screen pixels) says
/// how each block runs. A block the triangle wrote into gets its pyramid texel refreshed
/// at once and is marked stale for the levels below it (frame sessions only).
#[allow(clippy::needless_range_loop)] // edge k of several arrays
fn walk_blocks<const FMT: u8, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [x0, y0, x1, y1]: [i32; 4],
    e: &[Edge; 3],
    mut setup: impl FnMut([i32; 4], [i32; 2]) -> BlockSetup,
) -> TriRaster {
    let mut out = TriRaster::default();
    let (tx, ty) = (tile.x0 as i32, tile.y0 as i32);
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
            if matches!(how, BlockSetup::Outside) || (tile.coarse && block_hidden(t, tile, rect, corner)) {
                continue;
            }
            let before = out.written;
            match how {
                BlockSetup::Outside => {}
                BlockSetup::Narrow(k32) => block::<FMT, COUNT>(t, tile, rect, &k32, &mut out),
                BlockSetup::Wide(e00) => {
                    for py in ry0..=ry1 {
                        let zrow = depth_row(t, py);
                        let row = ((py - ty) as usize) << TILE_SHIFT;
                        let dy = (py - ry0) as i64;
                        let mut ev = [0i64; 3];
                        for k in 0..3 {
                            ev[k] = e00[k] + e[k].b * dy;
                        }
                        for px in rx0..=rx1 {
                            if (ev[0] | ev[1] | ev[2]) >= 0 {
                                let z = depth_at(t, zrow, px);
                                fragment::<FMT, COUNT>(tile, row + (px - tx) as usize, z, t.id, &mut out);
                            }
                            for k in 0..3 {
                                ev[k] += e[k].a;
                            }
                        }
                    }
                }
            }
            if tile.coarse && out.written != before {
                refresh_block_max::<FMT>(tile, corner);
                tile.stale_blocks |= 1 << ((corner[1] >> 3) * 8 + (corner[0] >> 3));
            }
        }
        by += BLOCK;
    }
    out
}

/// The edge functions of a triangle whose values fit i32 over every 8×8 block its
/// bounding box (clipped to the tile) touches: the common case, triangles up to about a
/// hundred pixels across.
struct FastEdges {
    /// The first block's corner (screen pixels).
    corner: [i32; 2],
    /// Values at the first block's corner.
    e: [i32; 3],
    /// Steps per pixel along x and y.
    a: [i32; 3],
    b: [i32; 3],
    /// Lowest and highest offset from a block corner's value over the block's 8×8 pixels.
    lo: [i32; 3],
    hi: [i32; 3],
}

impl FastEdges {
    /// `None` when some value over the block-aligned box of `[x0, y0, x1, y1]`, or the
    /// spread of an edge's values over one block, leaves i32 (long slivers: a steep edge
    /// over a box one block wide), so that every edge value over the box fits i32.
    #[inline]
    #[allow(clippy::needless_range_loop)] // edge k of several arrays
    fn new(e: &[Edge; 3], [x0, y0, x1, y1]: [i32; 4]) -> Option<Self> {
        let (ax0, ay0) = ((x0 & !(BLOCK - 1)) as i64, (y0 & !(BLOCK - 1)) as i64);
        let (w, h) = ((x1 | (BLOCK - 1)) as i64 - ax0, (y1 | (BLOCK - 1)) as i64 - ay0);
        let corner = [ax0 as i32, ay0 as i32];
        let mut f = FastEdges { corner, e: [0; 3], a: [0; 3], b: [0; 3], lo: [0; 3], hi: [0; 3] };
        let m = (BLOCK - 1) as i64;
        for k in 0..3 {
            // Affine: the extremes over the box are at its corners.
            let v = e[k].a * ax0 + e[k].b * ay0 + e[k].c;
            let lo = v + e[k].a.min(0) * w + e[k].b.min(0) * h;
            let hi = v + e[k].a.max(0) * w + e[k].b.max(0) * h;
            let (block_lo, block_hi) = (e[k].a.min(0) * m + e[k].b.min(0) * m, e[k].a.max(0) * m + e[k].b.max(0) * m);
            let fits = |x: i64| x >= i32::MIN as i64 && x <= i32::MAX as i64;
            if !(fits(lo) && fits(hi) && fits(block_lo) && fits(block_hi)) {
                return None;
            }
            f.e[k] = v as i32;
            f.a[k] = e[k].a as i32;
            f.b[k] = e[k].b as i32;
            (f.lo[k], f.hi[k]) = (block_lo as i32, block_hi as i32);
        }
        Some(f)
    }

    /// Setup of the block with corner `[bx, by]` and rectangle `[rx0, ry0, ...]` inside
    /// it: whole blocks (not their parts inside the box) decide "outside" and "inside an
    /// edge"; a block skipped or an edge dropped that way is so for its part inside the box
    /// too, so the pixels drawn are the same. Every result is a value over the box, so it
    /// fits i32 (a product on the way may wrap; see below).
    #[inline]
    #[allow(clippy::needless_range_loop)] // edge k of several arrays
    fn block(&self, [rx0, ry0, _, _]: [i32; 4], [bx, by]: [i32; 2]) -> BlockSetup {
        let mut k32 = BlockEdges { e: [0; 3], a: [0; 3], b: [0; 3] };
        let (dx, dy) = (bx - self.corner[0], by - self.corner[1]);
        // A step times an offset can leave i32 (a long steep edge) while the value it leads to
        // cannot: wrapping arithmetic is exact modulo 2^32, so every result that fits is exact.
        let value = |k: usize, x: i32, y: i32, from: i32| {
            from.wrapping_add(self.a[k].wrapping_mul(x)).wrapping_add(self.b[k].wrapping_mul(y))
        };
        for k in 0..3 {
            let at = value(k, dx, dy, self.e[k]);
            if at + self.hi[k] < 0 {
                return BlockSetup::Outside;
            }
            if at + self.lo[k] < 0 {
                // The edge crosses the block: tested per pixel, from the rectangle's first
                // pixel.
                let e = value(k, rx0 - bx, ry0 - by, at);
                (k32.e[k], k32.a[k], k32.b[k]) = (e, self.a[k], self.b[k]);
            }
        }
        BlockSetup::Narrow(k32)
    }
}

/// Brings the pyramid texel of one 8×8 block (level 3; `corner` in tile pixels) up to date
/// right after a triangle wrote into it, so that the next triangles of the same draw batch
/// are tested against it (Masked Occlusion Culling's sequential updates); levels 1–2 wait
/// for [`TileBuf::update_mips`], the block staying marked stale.
#[inline]
fn refresh_block_max<const FMT: u8>(tile: &mut TileBuf, [bx, by]: [i32; 2]) {
    let (bx, by) = ((bx & !(BLOCK - 1)) as usize, (by & !(BLOCK - 1)) as usize);
    let mut m = [0u32; BLOCK as usize];
    for r in 0..BLOCK as usize {
        let row = &tile.depth[((by + r) << TILE_SHIFT) + bx..][..BLOCK as usize];
        for (m, &k) in m.iter_mut().zip(row) {
            *m = (*m).max(k);
        }
    }
    let k = m.into_iter().max().unwrap_or(0);
    tile.mips[MIP_OFFSETS[2] + (by / 8) * 8 + bx / 8] = match FMT {
        16 => k as f32 / 65535.0,
        24 => k as f32 / 16_777_215.0,
        _ => f32::from_bits(k),
    };
}

/// Edge values at a block's first pixel and their steps along x and y, as i32; an edge the
/// block is entirely inside of is all zeros (inside everywhere).
struct BlockEdges {
    e: [i32; 3],
    a: [i32; 3],
    b: [i32; 3],
}

/// One block of at most 8×8 pixels (`rect`, inclusive, in screen pixels): eight pixels per
/// row in AVX2 registers, with everything that does not change along a column (edge lane
/// offsets, the depth plane's x part, the column mask) set up once per block instead of once
/// per row. Same arithmetic per pixel as the row loops, so the same result bit for bit.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn block<const FMT: u8, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [rx0, ry0, rx1, ry1]: [i32; 4],
    k: &BlockEdges,
    out: &mut TriRaster,
) {
    use std::arch::x86_64::*;
    let (tx, ty) = (tile.x0 as i32, tile.y0 as i32);
    let mut base = (((ry0 - ty) as usize) << TILE_SHIFT) + (rx0 - tx) as usize;
    // Eight lanes from a row's first pixel overrun the row by at most 7 entries, into the
    // next row or the padding after the last one. Checked for real: tiles can be built by
    // hand through the public API, and the loads and stores below are unchecked.
    let end = base + ((ry1 - ry0) as usize) * TILE as usize + 8;
    assert!(
        rx0 >= tx
            && ry0 >= ty
            && end <= tile.depth.len()
            && end <= tile.ids.len()
            && (!COUNT || end <= tile.counts.len()),
        "block outside the tile buffers"
    );
    // SAFETY: AVX2 is enabled for the whole build (cfg above); every load and store covers
    // eight u32 at `base` for rows ry0..=ry1, all inside the buffers (asserted above); lanes
    // past the block rewrite the values they read (masked by `cols`).
    unsafe {
        let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let cols = _mm256_cmpgt_epi32(_mm256_set1_epi32(rx1 - rx0 + 1), lanes);
        let ev = |i: usize| {
            _mm256_add_epi32(_mm256_set1_epi32(k.e[i]), _mm256_mullo_epi32(lanes, _mm256_set1_epi32(k.a[i])))
        };
        let (mut e0, mut e1, mut e2) = (ev(0), ev(1), ev(2));
        let (b0, b1, b2) = (_mm256_set1_epi32(k.b[0]), _mm256_set1_epi32(k.b[1]), _mm256_set1_epi32(k.b[2]));
        let dx0 = (rx0 << SUBPIXEL_BITS) + ONE / 2 - t.x[0];
        let dx = _mm256_add_epi32(_mm256_set1_epi32(dx0), _mm256_slli_epi32(lanes, SUBPIXEL_BITS as i32));
        // The x part of the depth plane, as the row loops compute it (multiply, then add).
        let zx = _mm256_mul_ps(_mm256_set1_ps(t.zx), _mm256_cvtepi32_ps(dx));
        let minus1 = _mm256_set1_epi32(-1);
        let id = _mm256_set1_epi32(t.id as i32);
        let (mut cov, mut wr) = (_mm256_setzero_si256(), _mm256_setzero_si256());
        let dp = tile.depth.as_mut_ptr();
        let ip = tile.ids.as_mut_ptr();
        let cp = tile.counts.as_mut_ptr();
        for py in ry0..=ry1 {
            let z = _mm256_add_ps(_mm256_set1_ps(depth_row(t, py)), zx);
            let inside =
                _mm256_and_si256(_mm256_cmpgt_epi32(_mm256_or_si256(_mm256_or_si256(e0, e1), e2), minus1), cols);
            let key = match FMT {
                16 | 24 => {
                    let m = if FMT == 16 { 65535.0 } else { 16_777_215.0 };
                    let c = _mm256_min_ps(_mm256_max_ps(z, _mm256_setzero_ps()), _mm256_set1_ps(1.0));
                    _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(c, _mm256_set1_ps(m)), _mm256_set1_ps(0.5)))
                }
                _ => {
                    let bits = _mm256_castps_si256(z);
                    _mm256_andnot_si256(_mm256_srai_epi32(bits, 31), bits)
                }
            };
            let (d_at, i_at) = (dp.add(base) as *mut __m256i, ip.add(base) as *mut __m256i);
            let (d, old) = (_mm256_loadu_si256(d_at), _mm256_loadu_si256(i_at));
            // Keys and IDs are below 2^31, so signed compares order them; depth ties go to the
            // smaller ID (see `wins`).
            let tie = _mm256_and_si256(_mm256_cmpeq_epi32(key, d), _mm256_cmpgt_epi32(old, id));
            let pass = _mm256_and_si256(inside, _mm256_or_si256(_mm256_cmpgt_epi32(d, key), tie));
            let nd = opaque256(_mm256_or_si256(_mm256_and_si256(pass, key), _mm256_andnot_si256(pass, d)));
            let ni = opaque256(_mm256_or_si256(_mm256_and_si256(pass, id), _mm256_andnot_si256(pass, old)));
            _mm256_storeu_si256(d_at, nd);
            _mm256_storeu_si256(i_at, ni);
            if COUNT {
                let c_at = cp.add(base) as *mut __m256i;
                _mm256_storeu_si256(c_at, opaque256(_mm256_sub_epi32(_mm256_loadu_si256(c_at), inside)));
            }
            cov = _mm256_sub_epi32(cov, inside);
            wr = _mm256_sub_epi32(wr, pass);
            e0 = _mm256_add_epi32(e0, b0);
            e1 = _mm256_add_epi32(e1, b1);
            e2 = _mm256_add_epi32(e2, b2);
            base += TILE as usize;
        }
        let c = _mm_add_epi32(_mm256_castsi256_si128(cov), _mm256_extracti128_si256(cov, 1));
        let w = _mm_add_epi32(_mm256_castsi256_si128(wr), _mm256_extracti128_si256(wr, 1));
        let (c, w) = sum2(c, w);
        out.covered += c;
        out.written += w;
    }
}

/// [`block`] without AVX2: row by row through the SSE2 (or scalar) row loop.
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
#[inline(always)]
fn block<const FMT: u8, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [rx0, ry0, rx1, ry1]: [i32; 4],
    k: &BlockEdges,
    out: &mut TriRaster,
) {
    let (tx, ty) = (tile.x0 as i32, tile.y0 as i32);
    let mut r = Row {
        e: k.e,
        a: k.a,
        n: rx1 - rx0 + 1,
        zrow: 0.0,
        zx: t.zx,
        dx0: (rx0 << SUBPIXEL_BITS) + ONE / 2 - t.x[0],
        id: t.id,
    };
    for py in ry0..=ry1 {
        r.zrow = depth_row(t, py);
        let base = (((py - ty) as usize) << TILE_SHIFT) + (rx0 - tx) as usize;
        run_row::<FMT, COUNT>(&r, tile, base, out);
        for (e, b) in r.e.iter_mut().zip(k.b) {
            *e = e.wrapping_add(b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::{setup, Setup, SnappedVertex, Viewport};

    fn tri(pts: [(f32, f32); 3], id: u32, vp: &Viewport) -> Option<Tri> {
        let v = pts.map(|(x, y)| SnappedVertex { x: crate::setup::snap(x), y: crate::setup::snap(y), z: 0.5 });
        match setup(v, id, false, vp) {
            Setup::Ready(t) => Some(t),
            _ => None,
        }
    }

    fn draw(tris: &[Tri], w: u32, h: u32) -> (Vec<u32>, Vec<u32>) {
        let mut tile = TileBuf::new(0, 0, w, h);
        tile.depth.fill(key::<0>(1.0));
        for t in tris {
            raster_tri::<0, true>(t, &mut tile);
        }
        let pick =
            |v: &Vec<u32>| (0..h).flat_map(|y| (0..w).map(move |x| (y * TILE + x) as usize)).map(|i| v[i]).collect();
        (pick(&tile.ids), pick(&tile.counts))
    }

    /// fillrule_probe.py in image coordinates (y down): which triangle owns centers on a
    /// shared horizontal and a shared vertical edge.
    #[test]
    fn llvmpipe_tie_rule_probe() {
        let vp = Viewport::new(8, 8, true);
        let flip = |(x, y): (f32, f32)| (x, 8.0 - y); // the probe gives GL window coords
        let case = |p: [(f32, f32); 6]| {
            let p = p.map(flip);
            let a = tri([p[0], p[1], p[2]], 1, &vp).unwrap();
            let b = tri([p[3], p[4], p[5]], 2, &vp).unwrap();
            draw(&[a, b], 8, 8)
        };
        // Horizontal edge at GL y 4.5 = image row 3: goes to the triangle visually above.
        let (ids, counts) = case([(0.0, 4.5), (4.0, 0.0), (8.0, 4.5), (0.0, 4.5), (8.0, 4.5), (4.0, 9.0)]);
        assert_eq!(&ids[3 * 8 + 2..3 * 8 + 6], &[2, 2, 2, 2]);
        assert!(counts[3 * 8 + 2..3 * 8 + 6].iter().all(|&c| c == 1));
        // Vertical edge at x 4.5 = column 4: goes to the triangle on the right.
        let (ids, _) = case([(4.5, 0.0), (4.5, 8.0), (0.0, 4.0), (4.5, 8.0), (4.5, 0.0), (9.0, 4.0)]);
        for row in 2..6 {
            assert_eq!(ids[row * 8 + 4], 2, "row {row}");
            assert_eq!(ids[row * 8 + 3], 1, "row {row}");
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sse2_rows_equal_scalar_rows() {
        let mut rng = sightline_scene::rng::Rng::new(5);
        for _ in 0..2000 {
            let n = 1 + rng.below(40) as i32;
            let r = Row {
                e: [0; 3].map(|_| rng.below(4000) as i32 - 2000),
                a: [0; 3].map(|_| (rng.below(600) as i32 - 300) * 256),
                n,
                zrow: rng.range(-0.1, 1.1),
                zx: rng.range(-1e-3, 1e-3),
                dx0: rng.below(512) as i32 - 256,
                id: 1 + rng.below(100),
            };
            let len = ((n + 7) & !7) as usize + 4;
            let init: Vec<u32> = (0..len).map(|_| key::<0>(rng.f32())).collect();
            for fmt in [0u8, 16, 24] {
                let (mut d1, mut i1, mut c1) = (init.clone(), vec![7u32; len], vec![0u32; len]);
                let (mut d2, mut i2, mut c2) = (init.clone(), vec![7u32; len], vec![0u32; len]);
                let (mut o1, mut o2) = (TriRaster::default(), TriRaster::default());
                let n4 = ((n + 3) & !3) as usize;
                match fmt {
                    16 => {
                        row_scalar::<16, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                        row_sse2::<16, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                    }
                    24 => {
                        row_scalar::<24, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                        row_sse2::<24, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                    }
                    _ => {
                        row_scalar::<0, true>(&r, &mut d1, &mut i1, &mut c1, &mut o1);
                        row_sse2::<0, true>(&r, &mut d2[..n4], &mut i2[..n4], &mut c2[..n4], &mut o2);
                    }
                }
                assert_eq!((d1, i1, c1), (d2, i2, c2));
                assert_eq!((o1.covered, o1.written), (o2.covered, o2.written));
            }
        }
    }

    /// Per pixel on i64 edges, the textbook loop: what every fast path must equal.
    fn reference<const FMT: u8>(t: &Tri, tile: &mut TileBuf) -> TriRaster {
        let e = edges(t);
        let mut out = TriRaster::default();
        let x1 = (t.bbox[2] as u32).min(tile.x0 + tile.w - 1);
        let y1 = (t.bbox[3] as u32).min(tile.y0 + tile.h - 1);
        for py in (t.bbox[1] as u32).max(tile.y0)..=y1 {
            for px in (t.bbox[0] as u32).max(tile.x0)..=x1 {
                let (x, y) = (px as i64, py as i64);
                if e.iter().all(|e| e.a * x + e.b * y + e.c >= 0) {
                    let z = depth_at(t, depth_row(t, py as i32), px as i32);
                    let idx = (((py - tile.y0) << TILE_SHIFT) + px - tile.x0) as usize;
                    fragment::<FMT, true>(tile, idx, z, t.id, &mut out);
                }
            }
        }
        out
    }

    /// The block walk and kernel give the reference's depths, IDs, counts and counters bit
    /// for bit, for overlapping random triangles of every size and all depth formats.
    #[test]
    fn block_kernel_equals_per_pixel_reference() {
        let vp = Viewport::new(200, 150, true);
        let mut rng = sightline_scene::rng::Rng::new(21);
        for fmt in [0u8, 16, 24] {
            let mut a = TileBuf::new(64, 64, 64, 64);
            a.depth.fill(key::<0>(1.0));
            let mut b = a.clone();
            for n in 0..3000 {
                let s = [0.5f32, 4.0, 30.0, 300.0][n % 4];
                let (cx, cy) = (rng.range(40.0, 150.0), rng.range(40.0, 150.0));
                let mut p = || (cx + rng.range(-s, s), cy + rng.range(-s, s));
                let pts = [p(), p(), p()];
                let v = pts.map(|(x, y)| SnappedVertex {
                    x: crate::setup::snap(x),
                    y: crate::setup::snap(y),
                    z: rng.range(0.0, 1.0),
                });
                let Setup::Ready(t) = setup(v, 1 + rng.below(50), false, &vp) else { continue };
                let (ra, rb) = match fmt {
                    16 => (raster_tri::<16, true>(&t, &mut a), reference::<16>(&t, &mut b)),
                    24 => (raster_tri::<24, true>(&t, &mut a), reference::<24>(&t, &mut b)),
                    _ => (raster_tri::<0, true>(&t, &mut a), reference::<0>(&t, &mut b)),
                };
                assert_eq!((ra.covered, ra.written), (rb.covered, rb.written), "triangle {n} {pts:?}");
            }
            assert_eq!(a.depth, b.depth);
            assert_eq!(a.ids, b.ids);
            assert_eq!(a.counts, b.counts);
            assert!(a.ids.iter().filter(|&&i| i != 0).count() > 3000, "the tile got drawn");
        }
    }

    /// With coarse depth on (frame sessions), skipping blocks behind the pyramid changes no
    /// pixel, and every block written gets its level-3 texel refreshed at once, exactly the
    /// max of its depths, before any later triangle is tested against it.
    #[test]
    fn coarse_blocks_skip_nothing_visible_and_refresh_their_texel() {
        let vp = Viewport::new(64, 64, true);
        let mut rng = sightline_scene::rng::Rng::new(9);
        let mut a = TileBuf::new(0, 0, 64, 64);
        a.clear_for_session(crate::DepthFormat::F32, false);
        a.coarse = true;
        let mut b = a.clone();
        b.coarse = false;
        let mut skipped = 0;
        for n in 0..2000 {
            let s = [3.0f32, 12.0, 40.0][n % 3];
            let (cx, cy) = (rng.range(0.0, 64.0), rng.range(0.0, 64.0));
            let z = rng.range(0.0, 1.0);
            let mut p = || SnappedVertex {
                x: crate::setup::snap(cx + rng.range(-s, s)),
                y: crate::setup::snap(cy + rng.range(-s, s)),
                z: (z + rng.range(-0.05, 0.05)).clamp(0.0, 1.0),
            };
            let v = [p(), p(), p()];
            let Setup::Ready(t) = setup(v, 1 + n as u32, false, &vp) else { continue };
            let (ra, rb) = (raster_tri::<0, false>(&t, &mut a), reference::<0>(&t, &mut b));
            assert_eq!(ra.written, rb.written, "triangle {n}");
            skipped += (ra.covered < rb.covered) as u32;
            let mut stale = a.stale_blocks;
            while stale != 0 {
                let k = stale.trailing_zeros() as usize;
                stale &= stale - 1;
                let (bx, by) = ((k % 8) * 8, (k / 8) * 8);
                let max = (by..by + 8).flat_map(|y| (bx..bx + 8).map(move |x| y * 64 + x)).map(|i| a.depth[i]).max();
                assert_eq!(a.mips[MIP_OFFSETS[2] + k], f32::from_bits(max.unwrap()), "block {k} after triangle {n}");
            }
        }
        assert_eq!((&a.depth, &a.ids), (&b.depth, &b.ids));
        assert!(skipped > 100, "coarse depth skipped blocks of only {skipped} triangles");
    }

    /// A tile built by hand larger than the buffers allow is refused with a panic, never
    /// written out of bounds (with AVX2, by the block kernel's check; without, by the row
    /// loops' slice bounds).
    #[test]
    #[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2"), should_panic(expected = "block outside the tile"))]
    #[cfg_attr(not(all(target_arch = "x86_64", target_feature = "avx2")), should_panic)]
    fn oversized_hand_built_tile_panics() {
        let vp = Viewport::new(200, 200, true);
        let t = tri([(0.5, 0.5), (199.5, 0.5), (0.5, 199.5)], 1, &vp).unwrap();
        let mut tile = TileBuf::new(0, 0, 200, 200);
        raster_tri::<0, false>(&t, &mut tile);
    }

    /// Big triangles, slivers and triangles reaching thousands of pixels past the tile cover
    /// exactly the pixel centers their i64 edge functions say, whichever block path
    /// (i32 steps or i64 per pixel) draws them.
    #[test]
    fn big_and_sliver_triangles_cover_exactly() {
        let vp = Viewport::new(64, 64, true);
        let t = tri([(0.3, 0.7), (63.2, 20.1), (10.4, 63.9)], 1, &vp).unwrap();
        covers_exactly_its_pixels(&t, "first");
        // A long steep edge: its step per pixel times a block offset leaves i32 although
        // every edge value over the box fits (found in review; checked builds overflowed).
        let steep = tri([(9.36, -514.5), (60.3, 534.0), (16.7, -178.9)], 1, &vp)
            .or_else(|| tri([(9.36, -514.5), (16.7, -178.9), (60.3, 534.0)], 1, &vp))
            .expect("the steep triangle covers pixels of the tile");
        assert!(covers_exactly_its_pixels(&steep, "steep") > 0);
        // Many like it: edges a few hundred to a thousand pixels long across the tile.
        let mut rng = sightline_scene::rng::Rng::new(17);
        for _ in 0..500 {
            let mut p = |r: f32| (rng.range(-40.0, 104.0), rng.range(-r, r));
            let pts = [p(1200.0), p(1200.0), p(100.0)];
            if let Some(t) = tri(pts, 1, &vp) {
                covers_exactly_its_pixels(&t, "long edge");
            }
        }
        // Huge triangles (vertices thousands of pixels away, as near-plane-hugging geometry
        // gives): partly covered blocks run on i32 when their edge values fit, else on i64.
        let mut rng = sightline_scene::rng::Rng::new(11);
        let (mut checked, mut partly) = (0, 0);
        while checked < 300 {
            let mut far = || (rng.range(-16000.0, 16064.0), rng.range(-16000.0, 16064.0));
            let pts = [far(), far(), (rng.range(-40.0, 104.0), rng.range(-40.0, 104.0))];
            let Some(t) = tri(pts, 1, &vp) else { continue };
            let e = edges(&t);
            let (ids, _) = draw(&[t], 64, 64);
            partly += (ids.contains(&0) && ids.contains(&1)) as u32;
            for py in t.bbox[1] as i64..=t.bbox[3] as i64 {
                for px in t.bbox[0] as i64..=t.bbox[2] as i64 {
                    let inside = e.iter().all(|e| e.a * px + e.b * py + e.c >= 0);
                    assert_eq!(ids[(py * 64 + px) as usize] == 1, inside, "{pts:?} at {px},{py}");
                }
            }
            checked += 1;
        }
        assert!(partly >= 50, "only {partly} triangles cross the tile");
        // A sliver one block wide with a steep edge: its values over the box fit i32, but
        // an edge's spread over a whole block does not (found in review; it overflowed).
        let sliver = tri([(4.0, -3000.0), (4.0, 3000.0), (5.0, 0.0)], 1, &vp)
            .or_else(|| tri([(4.0, -3000.0), (5.0, 0.0), (4.0, 3000.0)], 1, &vp))
            .expect("the sliver covers column 4");
        assert!(covers_exactly_its_pixels(&sliver, "sliver") > 0, "the sliver draws column 4");
        let mut big = t;
        big.x = t.x.map(|v| v * 2);
        big.y = t.y.map(|v| v * 2);
        big.bbox = [0, 0, 63, 63];
        covers_exactly_its_pixels(&big, "doubled");
    }

    /// Draws `t` alone into a 64 × 64 tile and checks every pixel against the i64 edge
    /// functions; returns the pixels covered.
    fn covers_exactly_its_pixels(t: &Tri, label: &str) -> usize {
        let (ids, _) = draw(&[*t], 64, 64);
        let e = edges(t);
        for py in 0..64i64 {
            for px in 0..64i64 {
                let inside = e.iter().all(|e| e.a * px + e.b * py + e.c >= 0);
                assert_eq!(ids[(py * 64 + px) as usize] == 1, inside, "{label} at {px},{py}");
            }
        }
        ids.iter().filter(|&&i| i == 1).count()
    }
}

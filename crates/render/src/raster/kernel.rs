//! The per-pixel kernels: depth test (LESS, exact ties to the smaller triangle ID), depth,
//! ID and count writes, for one block of up to 8 × 8 pixels.
//!
//! Four forms of the same arithmetic, bit for bit: a scalar row loop (the reference, and
//! the kernel off x86-64), an SSE2 row loop (four pixels per step; every x86-64 CPU), an
//! AVX2 block kernel (eight pixels of a row per step, everything constant down a column
//! set up once per block), and an AVX-512 block kernel that takes two rows per step in one
//! 16-lane register, with the coverage and depth tests compared into mask registers and the
//! writes as mask blends. Its first form (one row per step) cut the street path's oracle
//! frame's raster stage from 1.20 to 1.09 ms on two threads; AVX2's tie compare, row depths
//! at once and counters in vectors took the street path's `hzb` frames a further 0.96× on
//! an AMD Zen 5, and two rows per step 0.95–0.97× more (frames alternated in one process).
//! Which one runs is the
//! [`Kernel`] type parameter of the block walk, chosen once per frame from the run-time
//! [`SimdLevel`](sightline_spatial::SimdLevel).
//! All are branch-free per pixel: coverage and the depth test are unpredictable along the
//! edges of triangles. Every depth they compute is a number: a triangle whose plane could
//! give NaN never reaches them ([`Tri::depths_are_numbers`]), so their keys skip the NaN
//! test.

use super::tile::{TileBuf, PAD};
use super::TriRaster;
use crate::depth::DepthCodec;
use crate::edge::{BlockEdges, Tri, ONE, SUBPIXEL_BITS};
#[cfg(target_arch = "x86_64")]
use crate::forward::read_alone;
use crate::tiling::{TILE, TILE_SHIFT};

/// A block kernel for one instruction set.
pub(crate) trait Kernel: Copy + Send + Sync + 'static {
    /// Draws triangle `t` over the block rectangle `rect` (inclusive, screen pixels) with
    /// the edge values `k`, adding to `out`.
    ///
    /// # Safety
    /// The CPU must support the kernel's instruction set.
    unsafe fn block<D: DepthCodec, const COUNT: bool>(
        t: &Tri,
        tile: &mut TileBuf,
        rect: [i32; 4],
        k: &BlockEdges,
        out: &mut TriRaster,
    );
}

/// Row by row: SSE2 on x86-64, scalar elsewhere.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rows;

/// AVX2, eight pixels per step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx2;

/// AVX-512 (VL), eight pixels per step with mask registers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx512;

impl Kernel for Rows {
    #[inline(always)]
    unsafe fn block<D: DepthCodec, const COUNT: bool>(
        t: &Tri,
        tile: &mut TileBuf,
        rect: [i32; 4],
        k: &BlockEdges,
        out: &mut TriRaster,
    ) {
        block_rows::<D, COUNT>(t, tile, rect, k, out)
    }
}

/// `impl Kernel` for an x86-64 block kernel `$block` (the row loops elsewhere).
macro_rules! x86_kernel {
    ($kernel:ident, $block:ident) => {
        impl Kernel for $kernel {
            #[inline(always)]
            unsafe fn block<D: DepthCodec, const COUNT: bool>(
                t: &Tri,
                tile: &mut TileBuf,
                rect: [i32; 4],
                k: &BlockEdges,
                out: &mut TriRaster,
            ) {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: forwarded from the caller (the CPU has the kernel's instruction set).
                unsafe {
                    $block::<D, COUNT>(t, tile, rect, k, out)
                }
                #[cfg(not(target_arch = "x86_64"))]
                block_rows::<D, COUNT>(t, tile, rect, k, out)
            }
        }
    };
}

x86_kernel!(Avx2, block_avx2);
x86_kernel!(Avx512, block_avx512);

/// The depth test: a fragment wins when it is nearer (LESS), or exactly as near and of a
/// smaller triangle ID. Drawing in ID order with a plain LESS test keeps the first (smallest
/// ID) of equal depths, so this gives the same image for ANY draw order: what lets culled,
/// front-to-back and clustered frames equal the brute-force frame pixel for pixel.
#[inline(always)]
pub(crate) fn wins(key: u32, id: u32, stored_key: u32, stored_id: u32) -> bool {
    key < stored_key || (key == stored_key && id < stored_id)
}

#[inline(always)]
pub(super) fn fragment<D: DepthCodec, const COUNT: bool>(
    tile: &mut TileBuf,
    idx: usize,
    z: f32,
    id: u32,
    r: &mut TriRaster,
) {
    let k = D::key(z);
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
pub(super) struct Row {
    pub(super) e: [i32; 3],
    pub(super) a: [i32; 3],
    pub(super) n: i32,
    pub(super) zrow: f32,
    pub(super) zx: f32,
    /// The triangle's nearest vertex depth ([`Tri::depth_at`]'s clamp).
    pub(super) zmin: f32,
    pub(super) dx0: i32,
    pub(super) id: u32,
}

/// Scalar form of a row (the reference; used where SSE2 is not available).
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
pub(super) fn row_scalar<D: DepthCodec, const COUNT: bool>(
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
        let z = crate::edge::no_nearer(r.zmin, r.zrow + r.zx * (r.dx0 + (k << SUBPIXEL_BITS)) as f32);
        let key = D::key(z);
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
/// unpredictable along the edges of triangles). Same arithmetic as `row_scalar`, so the same
/// result bit for bit. Lanes past the row are masked; they read and rewrite unchanged
/// values of the next row or of the buffer's padding.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn row_sse2<D: DepthCodec, const COUNT: bool>(
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
        let (zrow, zx, zmin) = (_mm_set1_ps(r.zrow), _mm_set1_ps(r.zx), _mm_set1_ps(r.zmin));
        let id = _mm_set1_epi32(r.id as i32);
        let (mut cov, mut wr) = (_mm_setzero_si128(), _mm_setzero_si128());
        for ((dq, iq), cq) in depth.chunks_exact_mut(4).zip(ids.chunks_exact_mut(4)).zip(counts.chunks_exact_mut(4)) {
            let inside =
                _mm_and_si128(_mm_cmpgt_epi32(_mm_or_si128(_mm_or_si128(e0, e1), e2), minus1), _mm_cmplt_epi32(k, n));
            let dx = _mm_add_epi32(dx0, _mm_slli_epi32(k, SUBPIXEL_BITS as i32));
            // maxps(zmin, z) is `no_nearer`: z when either is NaN.
            let z = _mm_max_ps(zmin, _mm_add_ps(zrow, _mm_mul_ps(zx, _mm_cvtepi32_ps(dx))));
            let key = D::key4(z);
            let dp = dq.as_mut_ptr() as *mut __m128i;
            let ip = iq.as_mut_ptr() as *mut __m128i;
            let d = _mm_loadu_si128(dp);
            let old = _mm_loadu_si128(ip);
            // Keys and IDs are below 2^31, so signed compares order them. Ties in depth go to
            // the smaller ID (see `wins`), as one compare: `d > key − 1` (that is, `d ≥ key`)
            // where the stored ID is larger, `d > key` elsewhere (keys are at least 0).
            let bar = _mm_add_epi32(key, _mm_cmpgt_epi32(old, id));
            let pass = _mm_and_si128(inside, _mm_cmpgt_epi32(d, bar));
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

/// `k`'s nine values, each read with a load of its own ([`read_alone`]). The block setup
/// stores them as nine scalars just before the kernel runs; read as the compiler would (256-bit
/// loads to broadcast from, each spanning several of those stores), they waited for the stores
/// to reach the cache: the AVX2 tile stage's hottest spot on a Zen 3, 9% of its samples on the
/// oracle frame.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn edges_one_by_one(k: &BlockEdges) -> BlockEdges {
    BlockEdges {
        e: k.e.each_ref().map(read_alone),
        a: k.a.each_ref().map(read_alone),
        b: k.b.each_ref().map(read_alone),
    }
}

/// The value unchanged, but opaque to the optimizer (see [`opaque`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn opaque256(mut v: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    // SAFETY: the assembly is empty; it only pins `v` to a register.
    unsafe { std::arch::asm!("/* {0} */", inout(ymm_reg) v, options(pure, nomem, nostack, preserves_flags)) };
    v
}

/// Runs one row starting at tile buffer index `base`, four pixels per step with SSE2 (the
/// block kernel without AVX2).
#[inline(always)]
fn run_row<D: DepthCodec, const COUNT: bool>(r: &Row, tile: &mut TileBuf, base: usize, out: &mut TriRaster) {
    let n4 = ((r.n + 3) & !3) as usize;
    let depth = &mut tile.depth[base..base + n4];
    let ids = &mut tile.ids[base..base + n4];
    let counts = &mut tile.counts[base..base + n4];
    #[cfg(target_arch = "x86_64")]
    row_sse2::<D, COUNT>(r, depth, ids, counts, out);
    #[cfg(not(target_arch = "x86_64"))]
    row_scalar::<D, COUNT>(r, depth, ids, counts, out);
}

/// The tile buffer index of block `rect`'s first pixel, for the 8-lane block kernels.
///
/// Eight lanes from a row's first pixel overrun the row by at most 7 entries, into the next
/// row or the padding after the last one ([`PAD`]). Tiles are made only by the renderer, and
/// the walk clips every block to its tile, so the rows' lanes stay inside the buffers by
/// construction (checked in debug builds).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn block_base<const COUNT: bool>(tile: &TileBuf, [rx0, ry0, _, ry1]: [i32; 4]) -> usize {
    let (tx, ty) = (tile.rect.x0 as i32, tile.rect.y0 as i32);
    let base = (((ry0 - ty) as usize) << TILE_SHIFT) + (rx0 - tx) as usize;
    let end = base + ((ry1 - ry0) as usize) * TILE as usize + PAD;
    debug_assert!(
        rx0 >= tx
            && ry0 >= ty
            && end <= tile.depth.len()
            && end <= tile.ids.len()
            && (!COUNT || end <= tile.counts.len()),
        "block outside the tile buffers"
    );
    base
}

/// [`Tri::depth_row`] of the eight pixel rows from `ry0` (a block's, at most eight), the same
/// operations per lane at once.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn block_row_depths(t: &Tri, ry0: i32) -> [f32; 8] {
    use std::arch::x86_64::*;
    let rows = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let dy = _mm256_add_epi32(
        _mm256_set1_epi32((ry0 << SUBPIXEL_BITS) + ONE / 2 - t.y[0]),
        _mm256_slli_epi32(rows, SUBPIXEL_BITS as i32),
    );
    let zy = _mm256_mul_ps(_mm256_set1_ps(t.zy), _mm256_cvtepi32_ps(dy));
    let mut zrow = [0f32; 8];
    // SAFETY: an unaligned store of eight f32 into an array of eight.
    unsafe { _mm256_storeu_ps(zrow.as_mut_ptr(), _mm256_add_ps(_mm256_set1_ps(t.z0), zy)) };
    zrow
}

/// One block of at most 8×8 pixels (`rect`, inclusive, in screen pixels): eight pixels per
/// row in AVX2 registers, with everything that does not change along a column (edge lane
/// offsets, the depth plane's x part, the column mask) and the plane's row depths set up
/// once per block instead of once per row. Same arithmetic per pixel as the row loops, so
/// the same result bit for bit.
///
/// # Safety
/// The CPU must have AVX2 (the caller resolved [`SimdLevel`](sightline_spatial::SimdLevel)).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
unsafe fn block_avx2<D: DepthCodec, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [rx0, ry0, rx1, ry1]: [i32; 4],
    k: &BlockEdges,
    out: &mut TriRaster,
) {
    use std::arch::x86_64::*;
    let mut base = block_base::<COUNT>(tile, [rx0, ry0, rx1, ry1]);
    let k = &edges_one_by_one(k);
    // SAFETY: the caller guarantees AVX2; every load and store covers eight u32 at `base`
    // for rows ry0..=ry1, all inside the buffers (see above); lanes past the block rewrite
    // the values they read (masked by `cols`).
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
        let zmin = _mm256_set1_ps(t.zmin);
        let minus1 = _mm256_set1_epi32(-1);
        let id = _mm256_set1_epi32(t.id as i32);
        let (mut cov, mut wr) = (_mm256_setzero_si256(), _mm256_setzero_si256());
        let dp = tile.depth.as_mut_ptr();
        let ip = tile.ids.as_mut_ptr();
        let cp = tile.counts.as_mut_ptr();
        for &zr in &block_row_depths(t, ry0)[..(ry1 - ry0 + 1) as usize] {
            let z = _mm256_max_ps(zmin, _mm256_add_ps(_mm256_set1_ps(zr), zx));
            let inside =
                _mm256_and_si256(_mm256_cmpgt_epi32(_mm256_or_si256(_mm256_or_si256(e0, e1), e2), minus1), cols);
            let key = D::key8(z);
            let (d_at, i_at) = (dp.add(base) as *mut __m256i, ip.add(base) as *mut __m256i);
            let (d, old) = (_mm256_loadu_si256(d_at), _mm256_loadu_si256(i_at));
            // Keys and IDs are below 2^31, so signed compares order them; depth ties go to the
            // smaller ID (see `wins`), as in `row_sse2`: one compare against the key less one
            // where the stored ID is larger.
            let bar = _mm256_add_epi32(key, _mm256_cmpgt_epi32(old, id));
            let pass = _mm256_and_si256(inside, _mm256_cmpgt_epi32(d, bar));
            // One blend each (`row_sse2` has none in SSE2 and takes three operations).
            let nd = opaque256(_mm256_blendv_epi8(d, key, pass));
            let ni = opaque256(_mm256_blendv_epi8(old, id, pass));
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

/// [`block_avx2`] with AVX-512: two rows of eight pixels per step in one 16-lane register,
/// so that a block's arithmetic takes half the steps. Coverage compares straight into a
/// mask, the depth test (its tie rule as one compare, as in `block_avx2`) is a compare under
/// that mask, the new depth and IDs are mask blends, and the counters add one under the
/// masks. Each row is loaded and stored as eight lanes of its own (the rows of a tile
/// buffer are [`TILE`] apart); a block's last row of an odd count is a step with the upper
/// lanes masked off, neither read nor written. Same arithmetic per pixel, so the same result
/// bit for bit.
///
/// # Safety
/// The CPU must have AVX-512 F, BW, DQ and VL (and the other features enabled here).
#[cfg(target_arch = "x86_64")]
#[allow(clippy::incompatible_msrv)]
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
unsafe fn block_avx512<D: DepthCodec, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [rx0, ry0, rx1, ry1]: [i32; 4],
    k: &BlockEdges,
    out: &mut TriRaster,
) {
    use std::arch::x86_64::*;
    let mut base = block_base::<COUNT>(tile, [rx0, ry0, rx1, ry1]);
    let k = &edges_one_by_one(k);
    // SAFETY: the caller guarantees AVX-512; every load and store covers eight u32 at
    // `base` (the step's first row) or `base + TILE` (its second, only when that row is in
    // the block), all inside the buffers (see `block_base`); lanes past the block rewrite
    // the values they read (masked by `cols`).
    unsafe {
        // Lane i: column i % 8 of the step's row i / 8.
        let x = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7);
        let r = _mm512_setr_epi32(0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1);
        let cols8 = 0xFFu32 >> (7 - (rx1 - rx0).clamp(0, 7));
        let cols: __mmask16 = (cols8 | cols8 << 8) as u16;
        let ev = |i: usize| {
            _mm512_add_epi32(
                _mm512_add_epi32(_mm512_set1_epi32(k.e[i]), _mm512_mullo_epi32(x, _mm512_set1_epi32(k.a[i]))),
                _mm512_mullo_epi32(r, _mm512_set1_epi32(k.b[i])),
            )
        };
        let (mut e0, mut e1, mut e2) = (ev(0), ev(1), ev(2));
        let down2 = |i: usize| _mm512_set1_epi32(k.b[i].wrapping_mul(2));
        let (b0, b1, b2) = (down2(0), down2(1), down2(2));
        let dx0 = (rx0 << SUBPIXEL_BITS) + ONE / 2 - t.x[0];
        let dx = _mm512_add_epi32(_mm512_set1_epi32(dx0), _mm512_slli_epi32::<{ SUBPIXEL_BITS }>(x));
        let zx = _mm512_mul_ps(_mm512_set1_ps(t.zx), _mm512_cvtepi32_ps(dx));
        let zmin = _mm512_set1_ps(t.zmin);
        let zero = _mm512_setzero_si512();
        let one = _mm512_set1_epi32(1);
        let id = _mm512_set1_epi32(t.id as i32);
        // `Tri::depth_row` of the step's rows, the same operations per lane.
        let mut dy = _mm512_add_epi32(
            _mm512_set1_epi32((ry0 << SUBPIXEL_BITS) + ONE / 2 - t.y[0]),
            _mm512_slli_epi32::<{ SUBPIXEL_BITS }>(r),
        );
        let dy2 = _mm512_set1_epi32(2 << SUBPIXEL_BITS);
        let (zy, z0) = (_mm512_set1_ps(t.zy), _mm512_set1_ps(t.z0));
        let (mut cov, mut wr) = (zero, zero);
        let dp = tile.depth.as_mut_ptr();
        let ip = tile.ids.as_mut_ptr();
        let cp = tile.counts.as_mut_ptr();
        // A step's rows from the buffer at `p` (the second only when `both`), and back.
        let load = |p: *mut u32, both: bool| {
            let lo = _mm512_castsi256_si512(_mm256_loadu_si256(p as *const __m256i));
            if both {
                _mm512_inserti64x4::<1>(lo, _mm256_loadu_si256(p.add(TILE as usize) as *const __m256i))
            } else {
                lo
            }
        };
        let store = |p: *mut u32, v: __m512i, both: bool| {
            _mm256_storeu_si256(p as *mut __m256i, _mm512_castsi512_si256(v));
            if both {
                _mm256_storeu_si256(p.add(TILE as usize) as *mut __m256i, _mm512_extracti64x4_epi64::<1>(v));
            }
        };
        let rows = ry1 - ry0 + 1;
        for step in 0..(rows + 1) / 2 {
            let both = 2 * step + 1 < rows;
            let z =
                _mm512_max_ps(zmin, _mm512_add_ps(_mm512_add_ps(z0, _mm512_mul_ps(zy, _mm512_cvtepi32_ps(dy))), zx));
            let m = if both { cols } else { cols & 0xFF };
            let inside = _mm512_mask_cmpge_epi32_mask(m, _mm512_or_si512(_mm512_or_si512(e0, e1), e2), zero);
            let key = D::key16(z);
            let (d_at, i_at) = (dp.add(base), ip.add(base));
            let (d, old) = (load(d_at, both), load(i_at, both));
            // Signed compares, as in `block_avx2`: the key less one where the stored ID is larger.
            let bar = _mm512_mask_sub_epi32(key, _mm512_cmpgt_epi32_mask(old, id), key, one);
            let pass = _mm512_mask_cmpgt_epi32_mask(inside, d, bar);
            store(d_at, _mm512_mask_blend_epi32(pass, d, key), both);
            store(i_at, _mm512_mask_blend_epi32(pass, old, id), both);
            if COUNT {
                let c_at = cp.add(base);
                let c = load(c_at, both);
                store(c_at, _mm512_mask_add_epi32(c, inside, c, one), both);
            }
            cov = _mm512_mask_add_epi32(cov, inside, cov, one);
            wr = _mm512_mask_add_epi32(wr, pass, wr, one);
            e0 = _mm512_add_epi32(e0, b0);
            e1 = _mm512_add_epi32(e1, b1);
            e2 = _mm512_add_epi32(e2, b2);
            dy = _mm512_add_epi32(dy, dy2);
            base += 2 * TILE as usize;
        }
        out.covered += _mm512_reduce_add_epi32(cov) as u32;
        out.written += _mm512_reduce_add_epi32(wr) as u32;
    }
}

/// [`block_avx2`] without AVX2: row by row through the SSE2 (or scalar) row loop.
#[inline(always)]
fn block_rows<D: DepthCodec, const COUNT: bool>(
    t: &Tri,
    tile: &mut TileBuf,
    [rx0, ry0, rx1, ry1]: [i32; 4],
    k: &BlockEdges,
    out: &mut TriRaster,
) {
    let (tx, ty) = (tile.rect.x0 as i32, tile.rect.y0 as i32);
    let mut r = Row {
        e: k.e,
        a: k.a,
        n: rx1 - rx0 + 1,
        zrow: 0.0,
        zx: t.zx,
        zmin: t.zmin,
        dx0: (rx0 << SUBPIXEL_BITS) + ONE / 2 - t.x[0],
        id: t.id,
    };
    for py in ry0..=ry1 {
        r.zrow = t.depth_row(py);
        let base = (((py - ty) as usize) << TILE_SHIFT) + (rx0 - tx) as usize;
        run_row::<D, COUNT>(&r, tile, base, out);
        for (e, b) in r.e.iter_mut().zip(k.b) {
            *e = e.wrapping_add(b);
        }
    }
}

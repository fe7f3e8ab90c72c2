//! Projection of a world box to a conservative screen rectangle and nearest window depth —
//! the query shape of hierarchical z-buffer tests (Greene, Kass & Miller 1993; the
//! rectangle-instead-of-box idea of Intel's Masked Occlusion Culling `TestRect`).
//!
//! Window conventions (OpenGL's viewport transform with row 0 at the top):
//! `x_w = (x_ndc + 1)/2 · W`, `y_w = (1 − y_ndc)/2 · H`, `z_w = (z_ndc + 1)/2`. The eight
//! corners are projected; when any corner has `w ≤ ε` or lies in front of the near plane
//! (`z < −w`), the box crosses the near plane (or the eye plane) and the answer is "covers the
//! whole screen, nearest depth 0". Otherwise the rectangle is the pixel-space bounds of the
//! corners grown by a small margin (vertex snapping to 1/256 pixel and float error), rounded
//! outwards and clamped to the viewport, and the depth is the smallest corner window z minus
//! a small margin. Since the view depth is linear over a box and window z is monotonic in
//! it, the box's nearest point is one of its corners.
//!
//! ## One computation, three implementations
//!
//! The corners are formed in clip space from four terms: `base = M·(min, 1)` and the matrix
//! columns scaled by the box extent, `dx`, `dy`, `dz`; corner `i` adds `dx`, `dy`, `dz` to
//! `base` (in that order) for the bits of `i` that are set. Each corner's x, y and z are
//! multiplied by `1/w`, and the rectangle comes from the min and max over the corners.
//! [`BoxProjector::classify_portable`] does this in scalar code. With AVX2, chosen when the
//! program runs ([`SimdLevel`]: the level is resolved once, when the projector is made, and
//! each call branches on it to `#[target_feature]` functions, so that a build without
//! `-C target-cpu` still runs the 256-bit code):
//! * [`BoxProjector::classify`] keeps two corners per 256-bit register (four registers per
//!   box; one division gives the eight reciprocals);
//! * [`BoxProjector::classify_many`] runs eight boxes side by side, one per lane, so that the
//!   long chain of dependent operations of one box overlaps with seven others. A box whose
//!   clip terms are all finite has no NaN corner (a sum of finite terms is finite or an
//!   infinity of one sign), so its answer needs no per-corner NaN checks; other boxes (empty,
//!   unbounded, or overflowing terms) take the one-box path.
//!
//! At the AVX-512 level the AVX2 code runs (there is no 16-lane version).
//!
//! All three perform the same IEEE operations on the same operands (min and max see no NaN,
//! so their order does not matter), so they agree bit for bit on every input; the tests check
//! it on random cameras, matrices and boxes.

use glam::{Mat4, Vec3A, Vec4};
use sightline_scene::Aabb;

use crate::simd::SimdLevel;
use crate::{AabbExt, BoxKind};

/// Smallest clip `w` accepted as "in front of the eye".
const W_EPS: f32 = 1e-6;
/// Margin in pixels added around the projected corners (1/256-pixel snapping plus float error).
const PIXEL_MARGIN: f32 = 1.0 / 128.0;
/// Margin subtracted from the nearest window depth.
const DEPTH_MARGIN: f32 = 1e-6;

/// A pixel rectangle `[x0, x1) × [y0, y1)` (row 0 at the top) with the nearest window depth of
/// the box that made it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
    /// Nearest window depth in [0, 1] (0 when the box crosses the near plane).
    pub depth: f32,
    /// True when the box crosses the near plane (or lies partly behind the eye): the rect is
    /// the whole viewport and the depth 0, so an occlusion test must report it visible.
    pub crosses_near: bool,
}

impl ScreenRect {
    /// The rectangle of a box that projects to nothing (empty box, or off screen).
    pub const EMPTY: ScreenRect = ScreenRect { x0: 0, y0: 0, x1: 0, y1: 0, depth: 1.0, crosses_near: false };

    /// True when no pixel is covered.
    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    /// The whole `width × height` viewport at depth 0.
    pub fn full(width: u32, height: u32) -> ScreenRect {
        ScreenRect { x0: 0, y0: 0, x1: width, y1: height, depth: 0.0, crosses_near: true }
    }

    /// Number of pixels covered.
    pub fn area(&self) -> u64 {
        if self.is_empty() {
            0
        } else {
            (self.x1 - self.x0) as u64 * (self.y1 - self.y0) as u64
        }
    }
}

/// Where a box lands on the screen ([`BoxProjector::classify`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoxImage {
    /// Outside the view frustum (or covering no pixel): nothing of it can be drawn.
    Outside,
    /// At or behind the near plane (or unbounded): it may cover any pixel at any depth.
    CrossesNear,
    /// In front of the near plane: a conservative rectangle (never empty: a box covering no
    /// pixel is [`BoxImage::Outside`]) and its nearest depth.
    Rect(ScreenRect),
}

/// Projects boxes with one `clip_from_world` onto a `width × height` viewport.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxProjector {
    clip_from_world: Mat4,
    width: u32,
    height: u32,
    /// The instruction set the calls run on: resolved (never `Auto`), and `Portable` for
    /// viewports too large for the SIMD path.
    simd: SimdLevel,
}

impl BoxProjector {
    /// A projector for `clip_from_world` and a `width × height` viewport, on the best
    /// instruction set available ([`SimdLevel::best`]).
    pub fn new(clip_from_world: Mat4, width: u32, height: u32) -> BoxProjector {
        BoxProjector::with_simd(clip_from_world, width, height, SimdLevel::Auto)
    }

    /// [`BoxProjector::new`] on the instruction set `simd` (resolved: a level the CPU lacks
    /// falls back to the best it has). Every level gives the same answers bit for bit; this
    /// is for parity tests and measurements.
    pub fn with_simd(clip_from_world: Mat4, width: u32, height: u32, simd: SimdLevel) -> BoxProjector {
        let simd = if width <= SIMD_MAX_SIZE && height <= SIMD_MAX_SIZE { simd.resolve() } else { SimdLevel::Portable };
        BoxProjector { clip_from_world, width, height, simd }
    }

    /// The instruction set the calls run on (never [`SimdLevel::Auto`]).
    pub fn simd(&self) -> SimdLevel {
        self.simd
    }

    /// The box's conservative screen rectangle and nearest depth (see the module docs).
    /// Empty boxes and boxes outside the view give [`ScreenRect::EMPTY`]; NaN/infinite boxes
    /// and boxes crossing the near plane give the full screen.
    #[inline]
    pub fn project(&self, b: &Aabb) -> ScreenRect {
        match self.classify(b) {
            BoxImage::Outside => ScreenRect::EMPTY,
            BoxImage::CrossesNear => ScreenRect::full(self.width, self.height),
            BoxImage::Rect(r) => r,
        }
    }

    /// Where the box lands: outside the view (all eight corners beyond one clip plane, or no
    /// pixel covered), across the near plane (a corner at or behind it, or a corner whose
    /// projection is not finite: it may cover anything), or a conservative rectangle with its
    /// nearest depth.
    ///
    /// With AVX2 (at the projector's [`SimdLevel`]) this runs the eight corners as four
    /// 256-bit registers of two corners each; otherwise
    /// [`BoxProjector::classify_portable`]. Both do the same IEEE operations in the same order
    /// on every corner, so they give the same answer bit for bit, on every input.
    #[inline]
    pub fn classify(&self, b: &Aabb) -> BoxImage {
        self.classify_with(b, |image| image)
    }

    /// `then(self.classify(b))`, with `then` inlined into the caller (it has one call site,
    /// after the branch on the level), so that a caller that only needs a small answer (a
    /// query's three-way verdict) does not go through a call for it.
    #[inline(always)]
    pub fn classify_with<R>(&self, b: &Aabb, then: impl FnOnce(BoxImage) -> R) -> R {
        let image = match self.simd {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `self.simd` comes from `SimdLevel::resolve`, which gives AVX2 or AVX-512
            // only when the CPU has every feature of `simd::AVX2_FEATURES`, the features
            // `classify_avx2` enables.
            SimdLevel::Avx2 | SimdLevel::Avx512 => unsafe { self.classify_avx2(b) },
            _ => self.classify_portable(b),
        };
        then(image)
    }

    /// Classifies every box of `boxes`: calls `f(i, self.classify(&boxes[i]))` for each `i`,
    /// in increasing order.
    ///
    /// With AVX2 (at the projector's [`SimdLevel`]: a predictable branch per 32 boxes to a
    /// `#[target_feature]` function; `f` keeps one call site, inlined here) this projects
    /// eight boxes at a time, one box per lane
    /// ([`BoxProjector::classify_portable`]'s operations, lane by lane, so the answers are the
    /// same bit for bit): the corners' clip coordinates, the clip-plane and near-plane tests,
    /// the reciprocals of w and the min/max over the corners are each a few 256-bit
    /// operations for eight boxes, and the boxes run side by side instead of one long chain
    /// of dependent operations each. Boxes that need care (empty, unbounded, or with clip
    /// terms that are not finite) are handed to the scalar path.
    #[inline]
    pub fn classify_many(&self, boxes: &[Aabb], mut f: impl FnMut(usize, BoxImage)) {
        #[cfg(target_arch = "x86_64")]
        let lanes = match self.simd {
            // SAFETY: as in `classify_with`: the resolved level guarantees the features of
            // `Lanes::new`.
            SimdLevel::Avx2 | SimdLevel::Avx512 => Some(unsafe { Lanes::new(self) }),
            _ => None,
        };
        let mut batch = Batch::default();
        for (c, chunk) in boxes.chunks(BATCH).enumerate() {
            #[cfg(target_arch = "x86_64")]
            match &lanes {
                // SAFETY: `lanes` exists only at a level with the features of `chunk_avx2`.
                Some(lanes) => unsafe { chunk_avx2(self, lanes, chunk, &mut batch) },
                None => self.chunk_portable(chunk, &mut batch),
            }
            #[cfg(not(target_arch = "x86_64"))]
            self.chunk_portable(chunk, &mut batch);
            // One call site for `f`, so that it is inlined.
            for k in 0..chunk.len() {
                f(BATCH * c + k, batch.image(k));
            }
        }
    }

    /// Answers up to [`BATCH`] boxes into lanes `0..chunk.len()` of `out`, one by one.
    #[inline]
    fn chunk_portable(&self, chunk: &[Aabb], out: &mut Batch) {
        for (k, b) in chunk.iter().enumerate() {
            out.set(k, self.classify_portable(b));
        }
    }

    /// [`BoxProjector::classify`] in plain scalar code: the reference the SIMD path is tested
    /// against, and the path on CPUs (and targets) without AVX2.
    ///
    /// The corners are formed once in clip space: corner `i` is `base` (the clip position of
    /// `b.min`) plus, in this order, the scaled matrix columns `dx` (if bit 0 of `i` is set),
    /// `dy` (bit 1) and `dz` (bit 2).
    pub fn classify_portable(&self, b: &Aabb) -> BoxImage {
        let Some((base, dx, dy, dz)) = self.corner_terms(b) else {
            return self.unbounded_or_empty(b);
        };
        let mut c = [Vec4::ZERO; 8];
        for (i, c) in c.iter_mut().enumerate() {
            let mut v = base;
            if i & 1 != 0 {
                v += dx;
            }
            if i & 2 != 0 {
                v += dy;
            }
            if i & 4 != 0 {
                v += dz;
            }
            *c = v;
        }
        let all = |f: &dyn Fn(&Vec4) -> bool| c.iter().all(f);
        if all(&|c| c.x > c.w)
            || all(&|c| c.x < -c.w)
            || all(&|c| c.y > c.w)
            || all(&|c| c.y < -c.w)
            || all(&|c| c.z > c.w)
            || all(&|c| c.z < -c.w)
        {
            return BoxImage::Outside;
        }
        // NaN-safe: a NaN w or z fails this test and takes the "crosses" path.
        if !all(&|c| c.w > W_EPS && c.z >= -c.w) {
            return BoxImage::CrossesNear;
        }
        let (mut x0, mut x1, mut y0, mut y1, mut z0) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN, f32::MAX);
        for c in &c {
            let inv = 1.0 / c.w;
            let (x, y, z) = (c.x * inv, c.y * inv, c.z * inv);
            // Overflow (a huge box, or a huge x over a tiny w): no rectangle to trust.
            if !(x.is_finite() && y.is_finite() && z.is_finite() && c.w.is_finite()) {
                return BoxImage::CrossesNear;
            }
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
            z0 = z0.min(z);
        }
        let (w, h) = (self.width, self.height);
        let (wf, hf) = (w as f32, h as f32);
        // Pixel space, y down; pixel i spans [i, i + 1): covered columns are floor(px0) ..=
        // floor(px1). `clamp` sends everything ≤ 0 to 0, so truncation stands in for floor
        // (for values in (−1, 0) the end bound grows by one pixel: still conservative).
        let clamp = |v: f32, hi: u32| -> u32 {
            if v <= 0.0 {
                0
            } else if v >= hi as f32 {
                hi
            } else {
                v as u32
            }
        };
        let rx0 = clamp((x0 + 1.0) * 0.5 * wf - PIXEL_MARGIN, w);
        let rx1 = clamp((x1 + 1.0) * 0.5 * wf + PIXEL_MARGIN + 1.0, w);
        let ry0 = clamp((1.0 - y1) * 0.5 * hf - PIXEL_MARGIN, h);
        let ry1 = clamp((1.0 - y0) * 0.5 * hf + PIXEL_MARGIN + 1.0, h);
        self.rect(rx0, ry0, rx1, ry1, z0)
    }

    /// `base` (clip position of `b.min`) and the matrix columns scaled by the box extent, for
    /// a finite box; `None` for empty and unbounded boxes.
    #[inline(always)]
    fn corner_terms(&self, b: &Aabb) -> Option<(Vec4, Vec4, Vec4, Vec4)> {
        // `b.kind() == BoxKind::Finite` as three lane-wise compares: min ≤ max, min > −∞ and
        // max < +∞ on every axis (any NaN fails the first).
        let (lo, hi) = (Vec3A::from(b.min), Vec3A::from(b.max));
        if !(lo.cmple(hi) & lo.cmpgt(Vec3A::NEG_INFINITY) & hi.cmplt(Vec3A::INFINITY)).all() {
            return None;
        }
        let m = &self.clip_from_world;
        // m · (min, 1), spelled out in the order of the eight-box path.
        let base = ((m.x_axis * b.min.x + m.y_axis * b.min.y) + m.z_axis * b.min.z) + m.w_axis;
        let e = b.max - b.min;
        Some((base, m.x_axis * e.x, m.y_axis * e.y, m.z_axis * e.z))
    }

    /// The answer for a box that is not finite.
    #[cold]
    fn unbounded_or_empty(&self, b: &Aabb) -> BoxImage {
        match b.kind() {
            BoxKind::Empty => BoxImage::Outside,
            _ => BoxImage::CrossesNear,
        }
    }

    /// The rectangle of pixel bounds and nearest NDC z (shared tail of both paths).
    #[inline(always)]
    fn rect(&self, x0: u32, y0: u32, x1: u32, y1: u32, z0: f32) -> BoxImage {
        if x0 >= x1 || y0 >= y1 {
            return BoxImage::Outside;
        }
        let depth = ((z0 + 1.0) * 0.5 - DEPTH_MARGIN).clamp(0.0, 1.0);
        BoxImage::Rect(ScreenRect { x0, y0, x1, y1, depth, crosses_near: false })
    }

    /// Lanes k (x, y, z, w) of the corner registers `a` (two corners each) for which the
    /// compare `P` against `b` holds at all eight corners: bit k of the result.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    fn all_corners<const P: i32>(a: [std::arch::x86_64::__m256; 4], b: [std::arch::x86_64::__m256; 4]) -> i32 {
        use std::arch::x86_64::*;
        let m = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<P>(a[0], b[0]), _mm256_cmp_ps::<P>(a[1], b[1])),
            _mm256_and_ps(_mm256_cmp_ps::<P>(a[2], b[2]), _mm256_cmp_ps::<P>(a[3], b[3])),
        );
        let m = _mm256_movemask_ps(m);
        m & (m >> 4)
    }

    /// [`BoxProjector::classify_portable`] with AVX2: corners 2k and 2k + 1 share a 256-bit
    /// register as (x, y, z, w, x, y, z, w), so that forming them takes four additions, the
    /// clip tests are lane-wise compares reduced across registers, one division gives the
    /// eight reciprocals, and the min/max over the corners are six lane-wise operations.
    /// Every arithmetic operation is the one the portable path does, on the same operands,
    /// so every value (and so the answer) is the same bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    fn classify_avx2(&self, b: &Aabb) -> BoxImage {
        use std::arch::x86_64::*;
        let Some((base, dx, dy, dz)) = self.corner_terms(b) else {
            return self.unbounded_or_empty(b);
        };
        // The intrinsics work on values only (no memory is accessed through pointers).
        let (x0, y0, x1, y1, z0) = {
            let (base, dx, dy, dz) = (__m128::from(base), __m128::from(dx), __m128::from(dy), __m128::from(dz));
            // Corners (0, 1), (2, 3), (4, 5), (6, 7): the additions of the portable path, in its
            // order (base + dx, then + dy, then + dz).
            let c01 = _mm256_set_m128(_mm_add_ps(base, dx), base);
            let dy = _mm256_set_m128(dy, dy);
            let dz = _mm256_set_m128(dz, dz);
            let c23 = _mm256_add_ps(c01, dy);
            let c45 = _mm256_add_ps(c01, dz);
            let c67 = _mm256_add_ps(c23, dz);
            let sign = _mm256_set1_ps(-0.0);
            let w01 = _mm256_permute_ps::<0xFF>(c01);
            let w23 = _mm256_permute_ps::<0xFF>(c23);
            let w45 = _mm256_permute_ps::<0xFF>(c45);
            let w67 = _mm256_permute_ps::<0xFF>(c67);
            let (n01, n23) = (_mm256_xor_ps(w01, sign), _mm256_xor_ps(w23, sign));
            let (n45, n67) = (_mm256_xor_ps(w45, sign), _mm256_xor_ps(w67, sign));
            let (c, w, n) = ([c01, c23, c45, c67], [w01, w23, w45, w67], [n01, n23, n45, n67]);
            let beyond = Self::all_corners::<_CMP_GT_OQ>(c, w);
            let below = Self::all_corners::<_CMP_LT_OQ>(c, n);
            if (beyond | below) & 0b0111 != 0 {
                return BoxImage::Outside;
            }
            // In front of the near plane: z ≥ −w (lane 2) and w > W_EPS (lane 3) at every corner.
            let front = Self::all_corners::<_CMP_GE_OQ>(c, n);
            let ahead = Self::all_corners::<_CMP_GT_OQ>(w, [_mm256_set1_ps(W_EPS); 4]);
            if front & 0b0100 == 0 || ahead & 0b1000 == 0 {
                return BoxImage::CrossesNear;
            }
            // The eight w in one register (corner k in lane k / 2 + 4 (k mod 2)), one division.
            let w = _mm256_blend_ps::<0xCC>(_mm256_blend_ps::<0x22>(w01, w23), _mm256_blend_ps::<0x88>(w45, w67));
            let inv = _mm256_div_ps(_mm256_set1_ps(1.0), w);
            let p01 = _mm256_mul_ps(c01, _mm256_permute_ps::<0x00>(inv));
            let p23 = _mm256_mul_ps(c23, _mm256_permute_ps::<0x55>(inv));
            let p45 = _mm256_mul_ps(c45, _mm256_permute_ps::<0xAA>(inv));
            let p67 = _mm256_mul_ps(c67, _mm256_permute_ps::<0xFF>(inv));
            // x/w, y/w, z/w and w/w all finite (v − v is NaN exactly for ±∞ and NaN).
            let z = |v: __m256| _mm256_sub_ps(v, v);
            let nan = _mm256_add_ps(_mm256_add_ps(z(p01), z(p23)), _mm256_add_ps(z(p45), z(p67)));
            if _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_UNORD_Q>(nan, nan)) != 0 {
                return BoxImage::CrossesNear;
            }
            // No NaN is left, so min and max are the portable path's whatever the order.
            let lo = _mm256_min_ps(_mm256_min_ps(p01, p23), _mm256_min_ps(p45, p67));
            let hi = _mm256_max_ps(_mm256_max_ps(p01, p23), _mm256_max_ps(p45, p67));
            let lo = _mm_min_ps(_mm256_castps256_ps128(lo), _mm256_extractf128_ps::<1>(lo));
            let hi = _mm_max_ps(_mm256_castps256_ps128(hi), _mm256_extractf128_ps::<1>(hi));
            // (x0, x1, −y1, −y0): 1 − y is −y + 1 exactly.
            let v = _mm_permute_ps::<0b10_11_01_00>(_mm_unpacklo_ps(lo, hi));
            let v = _mm_xor_ps(v, _mm_set_ps(-0.0, -0.0, 0.0, 0.0));
            let (wf, hf) = (self.width as f32, self.height as f32);
            let size = _mm_set_ps(hf, hf, wf, wf);
            let v = _mm_mul_ps(_mm_mul_ps(_mm_add_ps(v, _mm_set1_ps(1.0)), _mm_set1_ps(0.5)), size);
            let v = _mm_add_ps(v, _mm_set_ps(PIXEL_MARGIN, -PIXEL_MARGIN, PIXEL_MARGIN, -PIXEL_MARGIN));
            let v = _mm_add_ps(v, _mm_set_ps(1.0, 0.0, 1.0, 0.0));
            // The portable clamp: ≤ 0 → 0, ≥ size → size, else truncation (sizes ≤ 2^24 are exact).
            let r = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(v, _mm_setzero_ps()), size));
            let (x0, x1) = (_mm_cvtsi128_si32(r) as u32, _mm_extract_epi32::<1>(r) as u32);
            let (y0, y1) = (_mm_extract_epi32::<2>(r) as u32, _mm_extract_epi32::<3>(r) as u32);
            let z0 = f32::from_bits(_mm_extract_ps::<2>(lo) as u32);
            (x0, y0, x1, y1, z0)
        };
        self.rect(x0, y0, x1, y1, z0)
    }
}

/// Boxes answered per call of the AVX2 path (four batches of eight lanes), so that the call
/// costs little per box.
const BATCH: usize = 32;

/// The answers of up to [`BATCH`] boxes, lane k for box k (filled eight lanes at a time by
/// `Lanes::classify8`).
#[derive(Debug)]
#[repr(C, align(32))]
struct Batch {
    /// [`Batch::RECT`], [`Batch::OUTSIDE`] or [`Batch::CROSSES`].
    kind: [i32; BATCH],
    x0: [i32; BATCH],
    y0: [i32; BATCH],
    x1: [i32; BATCH],
    y1: [i32; BATCH],
    depth: [f32; BATCH],
}

impl Default for Batch {
    fn default() -> Batch {
        Batch { kind: [0; BATCH], x0: [0; BATCH], y0: [0; BATCH], x1: [0; BATCH], y1: [0; BATCH], depth: [0.0; BATCH] }
    }
}

impl Batch {
    const RECT: i32 = 0;
    const OUTSIDE: i32 = 1;
    const CROSSES: i32 = 2;

    /// Lane `k` as a [`BoxImage`].
    #[inline(always)]
    fn image(&self, k: usize) -> BoxImage {
        match self.kind[k] {
            Batch::RECT => BoxImage::Rect(ScreenRect {
                x0: self.x0[k] as u32,
                y0: self.y0[k] as u32,
                x1: self.x1[k] as u32,
                y1: self.y1[k] as u32,
                depth: self.depth[k],
                crosses_near: false,
            }),
            Batch::OUTSIDE => BoxImage::Outside,
            _ => BoxImage::CrossesNear,
        }
    }

    /// Stores `image` in lane `k`.
    #[inline]
    fn set(&mut self, k: usize, image: BoxImage) {
        self.kind[k] = match image {
            BoxImage::Rect(r) => {
                (self.x0[k], self.y0[k], self.x1[k], self.y1[k]) = (r.x0 as i32, r.y0 as i32, r.x1 as i32, r.y1 as i32);
                self.depth[k] = r.depth;
                Batch::RECT
            }
            BoxImage::Outside => Batch::OUTSIDE,
            BoxImage::CrossesNear => Batch::CROSSES,
        }
    }
}

/// A projector's constants broadcast to eight lanes.
#[cfg(target_arch = "x86_64")]
struct Lanes {
    /// Matrix entry (column c, row r) at `4c + r`.
    m: [std::arch::x86_64::__m256; 16],
    /// Viewport width and height as floats.
    size: [std::arch::x86_64::__m256; 2],
}

// The eight-box path reads each box as floats: min at 0..3, max at 3..6.
#[cfg(target_arch = "x86_64")]
const _: () = assert!(
    std::mem::size_of::<Aabb>() == 24
        && std::mem::size_of::<glam::Vec3>() == 12
        && std::mem::offset_of!(Aabb, min) == 0
        && std::mem::offset_of!(Aabb, max) == 12
        && std::mem::offset_of!(glam::Vec3, x) == 0
        && std::mem::offset_of!(glam::Vec3, y) == 4
        && std::mem::offset_of!(glam::Vec3, z) == 8
);

#[cfg(target_arch = "x86_64")]
impl Lanes {
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    fn new(p: &BoxProjector) -> Lanes {
        use std::arch::x86_64::*;
        let cols = p.clip_from_world.to_cols_array();
        Lanes {
            m: std::array::from_fn(|i| _mm256_set1_ps(cols[i])),
            size: [_mm256_set1_ps(p.width as f32), _mm256_set1_ps(p.height as f32)],
        }
    }

    /// [`BoxProjector::classify_portable`] for eight boxes, one per lane, into lanes
    /// `at..at + 8` of `out` (`at` a multiple of eight). Lanes
    /// whose box is not finite, or whose clip terms (`base`, `dx`, `dy`, `dz`) are not all
    /// finite, are left for the one-box path (their lanes hold anything); the returned mask
    /// has bit k set for such a lane k. For the others no corner coordinate is NaN (sums of
    /// finite terms are finite or ±∞ of one sign), so the comparisons, and the min/max over
    /// the corners, are those of the portable path; a non-finite projection shows up in the
    /// min or max over the corners (or, for w = +∞, in the max of w).
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    fn classify8(&self, boxes: &[Aabb; 8], out: &mut Batch, at: usize) -> u32 {
        use std::arch::x86_64::*;
        assert!(at.is_multiple_of(8) && at + 8 <= BATCH);
        // SAFETY: the function's features include AVX2, so the intrinsics may run. Box k is
        // read as floats at its address: 16 bytes at offsets 0 and 8 of its 24 (layout
        // asserted above). The stores write lanes `at..at + 8` (asserted in bounds) of `out`'s
        // arrays, which are 32-byte aligned there (`Batch` is, each array is 4 · BATCH bytes
        // long and `at` is a multiple of eight).
        unsafe {
            let p = |k: usize| &boxes[k] as *const Aabb as *const f32;
            // Rows (min.x, min.y, min.z, max.x) and (min.z, max.x, max.y, max.z) of boxes k
            // and k + 4 in the two halves, then 4 × 4 transposes within each half.
            let lo = |k: usize| _mm256_loadu2_m128(p(k + 4), p(k));
            let hi = |k: usize| _mm256_loadu2_m128(p(k + 4).add(2), p(k).add(2));
            let (l0, l1, l2, l3) = (lo(0), lo(1), lo(2), lo(3));
            let (t0, t1) = (_mm256_unpacklo_ps(l0, l1), _mm256_unpackhi_ps(l0, l1));
            let (t2, t3) = (_mm256_unpacklo_ps(l2, l3), _mm256_unpackhi_ps(l2, l3));
            let min_x = _mm256_shuffle_ps::<0x44>(t0, t2);
            let min_y = _mm256_shuffle_ps::<0xEE>(t0, t2);
            let min_z = _mm256_shuffle_ps::<0x44>(t1, t3);
            let max_x = _mm256_shuffle_ps::<0xEE>(t1, t3);
            let u1 = _mm256_unpackhi_ps(hi(0), hi(1));
            let u3 = _mm256_unpackhi_ps(hi(2), hi(3));
            let max_y = _mm256_shuffle_ps::<0x44>(u1, u3);
            let max_z = _mm256_shuffle_ps::<0xEE>(u1, u3);

            let (inf, ninf) = (_mm256_set1_ps(f32::INFINITY), _mm256_set1_ps(f32::NEG_INFINITY));
            let and = |a: __m256, b: __m256| _mm256_and_ps(a, b);
            let finite_box = and(
                and(
                    and(_mm256_cmp_ps::<_CMP_LE_OQ>(min_x, max_x), _mm256_cmp_ps::<_CMP_LE_OQ>(min_y, max_y)),
                    and(_mm256_cmp_ps::<_CMP_LE_OQ>(min_z, max_z), _mm256_cmp_ps::<_CMP_GT_OQ>(min_x, ninf)),
                ),
                and(
                    and(_mm256_cmp_ps::<_CMP_GT_OQ>(min_y, ninf), _mm256_cmp_ps::<_CMP_GT_OQ>(min_z, ninf)),
                    and(
                        _mm256_cmp_ps::<_CMP_LT_OQ>(max_x, inf),
                        and(_mm256_cmp_ps::<_CMP_LT_OQ>(max_y, inf), _mm256_cmp_ps::<_CMP_LT_OQ>(max_z, inf)),
                    ),
                ),
            );

            let m = &self.m;
            let (add, mul) = (|a, b| _mm256_add_ps(a, b), |a, b| _mm256_mul_ps(a, b));
            // Component r of base = ((x_axis·min.x + y_axis·min.y) + z_axis·min.z) + w_axis.
            let base =
                |r: usize| add(add(add(mul(m[r], min_x), mul(m[4 + r], min_y)), mul(m[8 + r], min_z)), m[12 + r]);
            let (ex, ey, ez) = (_mm256_sub_ps(max_x, min_x), _mm256_sub_ps(max_y, min_y), _mm256_sub_ps(max_z, min_z));
            let b = [base(0), base(1), base(2), base(3)];
            let dx = [mul(m[0], ex), mul(m[1], ex), mul(m[2], ex), mul(m[3], ex)];
            let dy = [mul(m[4], ey), mul(m[5], ey), mul(m[6], ey), mul(m[7], ey)];
            let dz = [mul(m[8], ez), mul(m[9], ez), mul(m[10], ez), mul(m[11], ez)];
            // All sixteen terms finite: v − v is 0 for finite v and NaN otherwise.
            let z = |v: [__m256; 4]| {
                add(
                    add(_mm256_sub_ps(v[0], v[0]), _mm256_sub_ps(v[1], v[1])),
                    add(_mm256_sub_ps(v[2], v[2]), _mm256_sub_ps(v[3], v[3])),
                )
            };
            let zs = add(add(z(b), z(dx)), add(z(dy), z(dz)));
            let simd = and(finite_box, _mm256_cmp_ps::<_CMP_ORD_Q>(zs, zs));

            let v4 =
                |a: [__m256; 4], d: [__m256; 4]| [add(a[0], d[0]), add(a[1], d[1]), add(a[2], d[2]), add(a[3], d[3])];
            let sign = _mm256_set1_ps(-0.0);
            let eps = _mm256_set1_ps(W_EPS);
            let one = _mm256_set1_ps(1.0);
            // Corner 0 starts every accumulator.
            let nw = _mm256_xor_ps(b[3], sign);
            let mut beyond = [
                _mm256_cmp_ps::<_CMP_GT_OQ>(b[0], b[3]),
                _mm256_cmp_ps::<_CMP_LT_OQ>(b[0], nw),
                _mm256_cmp_ps::<_CMP_GT_OQ>(b[1], b[3]),
                _mm256_cmp_ps::<_CMP_LT_OQ>(b[1], nw),
                _mm256_cmp_ps::<_CMP_GT_OQ>(b[2], b[3]),
                _mm256_cmp_ps::<_CMP_LT_OQ>(b[2], nw),
            ];
            let mut front = and(_mm256_cmp_ps::<_CMP_GT_OQ>(b[3], eps), _mm256_cmp_ps::<_CMP_GE_OQ>(b[2], nw));
            let mut max_w = b[3];
            let inv = _mm256_div_ps(one, b[3]);
            let (px, py, pz) = (mul(b[0], inv), mul(b[1], inv), mul(b[2], inv));
            let (mut x0, mut x1, mut y0, mut y1, mut z0, mut z1) = (px, px, py, py, pz, pz);
            let mut corner = |c: [__m256; 4]| {
                let nw = _mm256_xor_ps(c[3], sign);
                beyond[0] = and(beyond[0], _mm256_cmp_ps::<_CMP_GT_OQ>(c[0], c[3]));
                beyond[1] = and(beyond[1], _mm256_cmp_ps::<_CMP_LT_OQ>(c[0], nw));
                beyond[2] = and(beyond[2], _mm256_cmp_ps::<_CMP_GT_OQ>(c[1], c[3]));
                beyond[3] = and(beyond[3], _mm256_cmp_ps::<_CMP_LT_OQ>(c[1], nw));
                beyond[4] = and(beyond[4], _mm256_cmp_ps::<_CMP_GT_OQ>(c[2], c[3]));
                beyond[5] = and(beyond[5], _mm256_cmp_ps::<_CMP_LT_OQ>(c[2], nw));
                front = and(front, and(_mm256_cmp_ps::<_CMP_GT_OQ>(c[3], eps), _mm256_cmp_ps::<_CMP_GE_OQ>(c[2], nw)));
                max_w = _mm256_max_ps(max_w, c[3]);
                let inv = _mm256_div_ps(one, c[3]);
                let (px, py, pz) = (mul(c[0], inv), mul(c[1], inv), mul(c[2], inv));
                x0 = _mm256_min_ps(x0, px);
                x1 = _mm256_max_ps(x1, px);
                y0 = _mm256_min_ps(y0, py);
                y1 = _mm256_max_ps(y1, py);
                z0 = _mm256_min_ps(z0, pz);
                z1 = _mm256_max_ps(z1, pz);
            };
            // Corners 1..8 in the order of the portable path's additions.
            let c1 = v4(b, dx);
            corner(c1);
            let c2 = v4(b, dy);
            corner(c2);
            let c3 = v4(c1, dy);
            corner(c3);
            corner(v4(b, dz));
            corner(v4(c1, dz));
            corner(v4(c2, dz));
            corner(v4(c3, dz));

            let or = |a: __m256, b: __m256| _mm256_or_ps(a, b);
            let outside_planes = or(or(beyond[0], beyond[1]), or(or(beyond[2], beyond[3]), or(beyond[4], beyond[5])));
            // A non-finite min or max (no NaN can be among them here), or w = +∞.
            let fz = |v: __m256| _mm256_sub_ps(v, v);
            let f = add(add(add(fz(x0), fz(x1)), add(fz(y0), fz(y1))), add(add(fz(z0), fz(z1)), fz(max_w)));
            let crosses = or(
                _mm256_xor_ps(front, _mm256_castsi256_ps(_mm256_set1_epi32(-1))),
                _mm256_cmp_ps::<_CMP_UNORD_Q>(f, f),
            );

            // Pixel bounds: the portable path's formulas, lane-wise.
            let (wf, hf) = (self.size[0], self.size[1]);
            let (half, margin, zero) = (_mm256_set1_ps(0.5), _mm256_set1_ps(PIXEL_MARGIN), _mm256_setzero_ps());
            let clamp = |v: __m256, hi: __m256| _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(v, zero), hi));
            let rx0 = clamp(_mm256_sub_ps(mul(mul(add(x0, one), half), wf), margin), wf);
            let rx1 = clamp(add(add(mul(mul(add(x1, one), half), wf), margin), one), wf);
            let ry0 = clamp(_mm256_sub_ps(mul(mul(_mm256_sub_ps(one, y1), half), hf), margin), hf);
            let ry1 = clamp(add(add(mul(mul(_mm256_sub_ps(one, y0), half), hf), margin), one), hf);
            let depth = _mm256_min_ps(
                _mm256_max_ps(_mm256_sub_ps(mul(add(z0, one), half), _mm256_set1_ps(DEPTH_MARGIN)), zero),
                one,
            );
            // x0 ≥ x1 or y0 ≥ y1 (values in 0 ..= 2^24, so signed compares do).
            let empty = _mm256_castsi256_ps(_mm256_xor_si256(
                _mm256_and_si256(_mm256_cmpgt_epi32(rx1, rx0), _mm256_cmpgt_epi32(ry1, ry0)),
                _mm256_set1_epi32(-1),
            ));

            // The portable path's order: planes, then near plane / non-finite, then empty.
            let k = |v: i32| _mm256_castsi256_ps(_mm256_set1_epi32(v));
            let mut kind = _mm256_blendv_ps(k(Batch::RECT), k(Batch::OUTSIDE), empty);
            kind = _mm256_blendv_ps(kind, k(Batch::CROSSES), crosses);
            kind = _mm256_blendv_ps(kind, k(Batch::OUTSIDE), outside_planes);
            _mm256_store_si256(out.kind.as_mut_ptr().add(at) as *mut __m256i, _mm256_castps_si256(kind));
            _mm256_store_si256(out.x0.as_mut_ptr().add(at) as *mut __m256i, rx0);
            _mm256_store_si256(out.y0.as_mut_ptr().add(at) as *mut __m256i, ry0);
            _mm256_store_si256(out.x1.as_mut_ptr().add(at) as *mut __m256i, rx1);
            _mm256_store_si256(out.y1.as_mut_ptr().add(at) as *mut __m256i, ry1);
            _mm256_store_ps(out.depth.as_mut_ptr().add(at), depth);
            (_mm256_movemask_ps(simd) ^ 0xFF) as u32
        }
    }
}

/// Largest viewport side for which the SIMD path's float clamp and truncation are exact.
const SIMD_MAX_SIZE: u32 = 1 << 24;

/// [`BoxProjector::chunk_portable`] with AVX2: each eight boxes as one batch of eight lanes,
/// then the lanes it left out (and the boxes of a shorter group) one by one on the AVX2
/// one-box path.
///
/// It and the kernels it calls are `#[target_feature]` functions with the features of
/// [`crate::simd::AVX2_FEATURES`] (closures inside inherit them), so that the 256-bit code is
/// compiled whatever the build's target CPU. They may be called from code with these
/// features, elsewhere only once [`SimdLevel::resolve`] has given AVX2 or AVX-512. They
/// return their answers: a caller's closure called in one of them would have two call sites
/// (one per level) and would no longer be inlined.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn chunk_avx2(p: &BoxProjector, lanes: &Lanes, chunk: &[Aabb], out: &mut Batch) {
    for (g, group) in chunk.chunks(8).enumerate() {
        let at = 8 * g;
        let mut scalar = match <&[Aabb; 8]>::try_from(group) {
            Ok(group) => lanes.classify8(group, out, at),
            Err(_) => (1 << group.len()) - 1,
        };
        // The lanes the batch left out (the tail, unusual boxes), one box at a time.
        while scalar != 0 {
            let k = scalar.trailing_zeros() as usize;
            scalar &= scalar - 1;
            out.set(at + k, p.classify_avx2(&group[k]));
        }
    }
}

/// Projects one box: see [`BoxProjector::project`].
pub fn project_box(b: &Aabb, clip_from_world: &Mat4, width: u32, height: u32) -> ScreenRect {
    BoxProjector::new(*clip_from_world, width, height).project(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use sightline_scene::Camera;

    fn cam() -> Camera {
        Camera::perspective_look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 60.0, 1.5, 0.5, 100.0).unwrap()
    }

    #[test]
    fn box_crossing_near_plane_covers_screen_at_depth_zero() {
        let c = cam();
        let m = c.clip_from_world();
        // Straddles the near plane at z = 4.5.
        let b = Aabb::new(Vec3::new(-0.1, -0.1, 4.3), Vec3::new(0.1, 0.1, 4.7));
        let r = project_box(&b, &m, 96, 64);
        assert!(r.crosses_near);
        assert_eq!((r.x0, r.y0, r.x1, r.y1, r.depth), (0, 0, 96, 64, 0.0));
        // Entirely behind the eye: all corners lie beyond the near plane, so nothing of it
        // can be drawn.
        let b = Aabb::new(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0));
        assert!(project_box(&b, &m, 96, 64).is_empty());
        // NaN box: full screen.
        assert!(project_box(&Aabb::new(Vec3::NAN, Vec3::ONE), &m, 96, 64).crosses_near);
        assert!(project_box(&Aabb::EMPTY, &m, 96, 64).is_empty());
    }

    #[test]
    fn rect_contains_every_projected_corner() {
        let c = cam();
        let m = c.clip_from_world();
        let (w, h) = (96u32, 64u32);
        let mut rng = sightline_scene::rng::Rng::new(5);
        let mut tested = 0;
        for _ in 0..500 {
            let lo = Vec3::new(rng.range(-3.0, 3.0), rng.range(-2.0, 2.0), rng.range(-10.0, 3.0));
            let b = Aabb::new(lo, lo + Vec3::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0)));
            let r = project_box(&b, &m, w, h);
            assert!(!r.crosses_near);
            let mut any_on = false;
            for p in b.corners() {
                let cl = m * p.extend(1.0);
                let ndc = cl.truncate() / cl.w;
                let (xw, yw, zw) =
                    ((ndc.x + 1.0) * 0.5 * w as f32, (1.0 - ndc.y) * 0.5 * h as f32, (ndc.z + 1.0) * 0.5);
                assert!(r.is_empty() || r.depth <= zw, "depth {} > corner {zw}", r.depth);
                // Corners on screen lie in the rect.
                if (0.0..w as f32).contains(&xw) && (0.0..h as f32).contains(&yw) {
                    any_on = true;
                    assert!(!r.is_empty());
                    assert!(
                        r.x0 as f32 <= xw && xw < r.x1 as f32 && r.y0 as f32 <= yw && yw < r.y1 as f32,
                        "corner ({xw}, {yw}) outside {r:?}"
                    );
                }
            }
            tested += any_on as u32;
        }
        assert!(tested > 100, "{tested}");
    }

    /// A random box: mostly ordinary, sometimes flat, huge, empty, NaN or infinite.
    fn random_box(rng: &mut sightline_scene::rng::Rng, reach: f32) -> Aabb {
        let mut v = || Vec3::new(rng.range(-reach, reach), rng.range(-reach, reach), rng.range(-reach, reach));
        let (lo, d) = (v(), v().abs() * 0.2);
        match rng.below(40) {
            0 => Aabb::new(lo, lo),
            1 => Aabb::new(lo + d, lo),
            2 => Aabb::new(Vec3::new(f32::NAN, lo.y, lo.z), lo + d),
            3 => Aabb::new(lo, Vec3::new(lo.x, f32::INFINITY, lo.z)),
            4 => Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38)),
            5 => Aabb::new(lo * 1e30, lo * 1e30 + d * 1e30),
            6 => Aabb::new(lo * 1e-30, lo * 1e-30 + d * 1e-30),
            _ => Aabb::new(lo, lo + d),
        }
    }

    /// A clip-from-world matrix of kind `k`: 3 arbitrary (some entries NaN, huge or
    /// infinite), 4 orthographic (w = 1 everywhere; view volume [−5, 5] × [−3, 3] ×
    /// [−25, 25]), otherwise a random perspective camera (`None` when it is invalid).
    fn random_matrix(rng: &mut sightline_scene::rng::Rng, k: u32) -> Option<Mat4> {
        match k {
            3 => Some(Mat4::from_cols_array(&std::array::from_fn(|_| match rng.below(60) {
                0 => f32::NAN,
                1 => 1e30,
                2 => f32::INFINITY,
                _ => rng.range(-2.0, 2.0),
            }))),
            4 => Some(
                Mat4::from_scale(Vec3::new(0.2, 1.0 / 3.0, -0.04))
                    * Mat4::from_translation(Vec3::new(rng.range(-5.0, 5.0), rng.range(-1.0, 1.0), 0.0)),
            ),
            _ => {
                let eye = Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
                let target = eye + Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                let near = [1e-4, 0.1, 1.0][rng.below(3) as usize];
                let c = Camera::perspective_look_at(eye, target, Vec3::Y, rng.range(10.0, 120.0), 1.7, near, 500.0);
                c.ok().map(|c| c.clip_from_world())
            }
        }
    }

    /// A projector on each SIMD level this process has (`SIGHTLINE_SIMD` may cap them), the
    /// portable one first.
    fn on_every_level(m: Mat4, w: u32, h: u32) -> Vec<BoxProjector> {
        let levels = SimdLevel::all_available();
        assert_eq!(levels[0], SimdLevel::Portable);
        levels.into_iter().map(|l| BoxProjector::with_simd(m, w, h, l)).collect()
    }

    #[test]
    fn projector_runs_on_the_level_it_resolved() {
        let m = cam().clip_from_world();
        for level in SimdLevel::all_available() {
            assert_eq!(BoxProjector::with_simd(m, 96, 64, level).simd(), level);
        }
        assert_eq!(BoxProjector::new(m, 96, 64).simd(), SimdLevel::best());
        assert_eq!(BoxProjector::with_simd(m, 96, 64, SimdLevel::Avx512).simd(), SimdLevel::Avx512.resolve());
        // Too large for the SIMD path's exact float clamp.
        assert_eq!(BoxProjector::new(m, 1 << 25, 8).simd(), SimdLevel::Portable);
    }

    /// `classify` gives exactly the answers of the portable path, at every SIMD level this
    /// process has, on perspective and orthographic cameras, arbitrary matrices and every
    /// kind of box.
    #[test]
    fn classify_equals_the_portable_path() {
        let mut rng = sightline_scene::rng::Rng::new(77);
        let mut kinds = [0usize; 3];
        for cam_i in 0..300 {
            let Some(m) = random_matrix(&mut rng, cam_i % 5) else { continue };
            let (w, h) = [(1280, 720), (97, 33), (1, 1), (0, 0), (4096, 3000)][rng.below(5) as usize];
            let levels = on_every_level(m, w, h);
            for _ in 0..400 {
                let reach = [1.0, 10.0, 100.0][rng.below(3) as usize];
                let b = random_box(&mut rng, reach);
                let portable = levels[0].classify_portable(&b);
                for p in &levels {
                    let (fast, with) = (p.classify(&b), p.classify_with(&b, |i| bits(&i)));
                    assert_eq!(bits(&fast), bits(&portable), "{:?}: {b:?} {m:?} {w}x{h}", p.simd());
                    assert_eq!(with, bits(&portable), "{:?}: {b:?} {m:?} {w}x{h}", p.simd());
                }
                kinds[bits(&portable).0 as usize] += 1;
            }
        }
        assert!(kinds.iter().all(|&k| k > 2000), "{kinds:?}");
    }

    /// A [`BoxImage`] as its kind (0 outside, 1 crossing, 2 rectangle) and the rectangle's
    /// x0, y0, x1, y1, depth bits (so that NaN would show as a mismatch) and crossing flag.
    fn bits(i: &BoxImage) -> (u8, [u32; 6]) {
        match i {
            BoxImage::Outside => (0, [0; 6]),
            BoxImage::CrossesNear => (1, [0; 6]),
            BoxImage::Rect(r) => (2, [r.x0, r.y0, r.x1, r.y1, r.depth.to_bits(), r.crosses_near as u32]),
        }
    }

    /// `classify_many` (eight boxes per SIMD batch, the rest one by one) answers every box
    /// exactly like the portable path, in order, whatever lane an unusual box lands in, at
    /// every SIMD level this process has.
    #[test]
    fn classify_many_equals_the_portable_path() {
        let mut rng = sightline_scene::rng::Rng::new(78);
        let mut kinds = [0usize; 3];
        for cam_i in 0..200 {
            let Some(m) = random_matrix(&mut rng, if cam_i % 4 == 3 { 3 } else { 0 }) else { continue };
            let (w, h) = [(1280, 720), (97, 33), (1, 1), (0, 0), (4096, 3000), (1 << 25, 8)][rng.below(6) as usize];
            let reach = [1.0, 10.0, 100.0][rng.below(3) as usize];
            let n = rng.below(300) as usize;
            let boxes: Vec<Aabb> = (0..n).map(|_| random_box(&mut rng, reach)).collect();
            for p in on_every_level(m, w, h) {
                let mut next = 0;
                p.classify_many(&boxes, |i, image| {
                    assert_eq!(i, next, "in order");
                    next += 1;
                    let portable = p.classify_portable(&boxes[i]);
                    assert_eq!(bits(&image), bits(&portable), "{:?}: box {i} {:?} {m:?} {w}x{h}", p.simd(), boxes[i]);
                    kinds[bits(&image).0 as usize] += 1;
                });
                assert_eq!(next, n);
            }
        }
        assert!(kinds.iter().all(|&k| k > 1000), "{kinds:?}");
    }

    #[test]
    fn boxes_behind_the_eye_across_near_nan_and_empty() {
        let c = cam();
        for p in on_every_level(c.clip_from_world(), 96, 64) {
            for classify in [BoxProjector::classify, BoxProjector::classify_portable] {
                // Behind the eye (all corners beyond the near plane): outside.
                let b = Aabb::new(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0));
                assert_eq!(classify(&p, &b), BoxImage::Outside);
                // Around the eye, and across the near plane (z = 4.5).
                let b = Aabb::new(Vec3::new(-1.0, -1.0, 4.0), Vec3::new(1.0, 1.0, 6.0));
                assert_eq!(classify(&p, &b), BoxImage::CrossesNear);
                let b = Aabb::new(Vec3::new(-0.1, -0.1, 4.3), Vec3::new(0.1, 0.1, 4.7));
                assert_eq!(classify(&p, &b), BoxImage::CrossesNear);
                assert_eq!(classify(&p, &Aabb::new(Vec3::NAN, Vec3::ONE)), BoxImage::CrossesNear);
                assert_eq!(classify(&p, &Aabb::new(Vec3::ZERO, Vec3::INFINITY)), BoxImage::CrossesNear);
                assert_eq!(classify(&p, &Aabb::EMPTY), BoxImage::Outside);
                // Overflowing corners: no rectangle.
                assert_eq!(classify(&p, &Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38))), BoxImage::CrossesNear);
                // A point box in view is a rectangle of at least one pixel.
                let BoxImage::Rect(r) = classify(&p, &Aabb::new(Vec3::ZERO, Vec3::ZERO)) else { panic!() };
                assert!(r.x1 > r.x0 && r.y1 > r.y0 && r.depth > 0.0 && r.depth < 1.0, "{r:?}");
            }
        }
    }

    /// Finite clip terms whose projection overflows (x/w or z/w) or whose w sums to +∞ at
    /// some corners, while the box stays in front of the near plane: no rectangle
    /// (crossing), on every path and in every lane of a batch.
    #[test]
    fn overflowing_projections_cross_near() {
        let m = |x: Vec4, z: Vec4, w: Vec4| Mat4::from_cols(x, Vec4::Y, z, w);
        let tiny_w = Vec4::new(0.0, 0.0, 0.0, 1e-5);
        let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let cases = [
            // x/w = 1e38 / 1e-5 at the corners with x = 1.
            m(Vec4::new(1e38, 0.0, 0.0, 0.0), Vec4::ZERO, tiny_w),
            // z/w = 1e38 / 1e-5 at the corners with z = 1.
            m(Vec4::X, Vec4::new(0.0, 0.0, 1e38, 0.0), tiny_w),
            // w = 3e38 + 3e38 at the corners with z = 1.
            m(Vec4::X, Vec4::new(0.0, 0.0, 0.0, 3e38), Vec4::new(0.0, 0.0, 0.0, 3e38)),
        ];
        for m in cases {
            for p in on_every_level(m, 64, 48) {
                assert_eq!(p.classify_portable(&unit), BoxImage::CrossesNear, "{:?}: {m:?}", p.simd());
                assert_eq!(p.classify(&unit), BoxImage::CrossesNear, "{:?}: {m:?}", p.simd());
                let ordinary = Aabb::new(Vec3::ZERO, Vec3::new(0.0, 0.2, 0.0));
                assert!(matches!(p.classify_portable(&ordinary), BoxImage::Rect(_)), "{:?}: {m:?}", p.simd());
                // Every lane of a call's four batches, and of a shorter last group.
                for lane in 0..BATCH + 7 {
                    let mut boxes = [ordinary; BATCH + 7];
                    boxes[lane] = unit;
                    p.classify_many(&boxes, |i, image| {
                        assert_eq!(
                            image,
                            p.classify_portable(&boxes[i]),
                            "{:?}: lane {lane}, box {i}, {m:?}",
                            p.simd()
                        );
                    });
                }
            }
        }
    }

    #[test]
    fn offscreen_box_is_empty() {
        let c = cam();
        let m = c.clip_from_world();
        let b = Aabb::new(Vec3::new(30.0, -0.5, -1.0), Vec3::new(31.0, 0.5, 0.0));
        assert!(project_box(&b, &m, 96, 64).is_empty());
    }
}

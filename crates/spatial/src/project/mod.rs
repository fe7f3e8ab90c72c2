//! Projection of a world box to a conservative screen rectangle and nearest window depth —
//! the query shape of hierarchical z-buffer tests (Greene, Kass & Miller 1993; the
//! rectangle-instead-of-box idea of Intel's Masked Occlusion Culling `TestRect`).
//!
//! Window conventions (OpenGL's viewport transform with row 0 at the top):
//! `x_w = (x_ndc + 1)/2 · W`, `y_w = (1 − y_ndc)/2 · H`, `z_w = (z_ndc + 1)/2`. The eight
//! corners are projected; a box whose eight corners all lie beyond one clip plane is outside.
//! Otherwise, when any corner has `w ≤ ε` or lies in front of the near plane (`z < −w`), the
//! box crosses the near plane (or the eye plane) and the answer is "covers the whole screen,
//! nearest depth 0". Otherwise the rectangle holds the pixels whose centers
//! lie within the pixel-space bounds of the corners grown by a margin, clamped to the
//! viewport, and the depth is the smallest corner window z less a margin; the margins bound
//! the f32 rounding of this projection and of the rasterizer's (see [`BoxProjector`]'s
//! "Rounding"). Since the view depth is linear over a box and window z is monotonic in it,
//! the box's nearest point is one of its corners.
//!
//! Boxes are projected relative to an origin, the eye for [`BoxProjector::for_camera`]:
//! `clip_from_world · translate(eye)` is formed in f64 and rounded once, and each box is
//! moved by `−eye` before the product, so that the terms summed are as large as the box's
//! distance, not as the world's coordinates (the camera-relative rendering of large worlds).
//!
//! Pixel centers, not pixel areas: the rasterizer samples each pixel at its center, so a
//! triangle inside the box can write only the pixels whose centers its snapped vertices'
//! bounds hold. A box far away that falls between pixel centers therefore draws nothing
//! and is [`BoxImage::Outside`]. In the street view of a city of 10^9 triangles two thirds
//! of the clusters that pass the occlusion test are such boxes.
//!
//! ## One computation, three implementations
//!
//! The corners are formed in clip space from four terms: `base = M·(min − origin, 1)` and the
//! matrix columns scaled by the box extent, `dx`, `dy`, `dz`; corner `i` adds `dx`, `dy`,
//! `dz` to `base` (in that order) for the bits of `i` that are set. Each corner's x, y and z
//! are multiplied by `1/w`, and the rectangle comes from the min and max over the corners,
//! widened by the margins of the box's reach and smallest `w`.
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

use glam::{DMat4, Mat4, Vec3, Vec3A, Vec4};
use sightline_scene::{Aabb, Camera};

use crate::simd::SimdLevel;
use crate::{AabbExt, BoxKind};
use batch::{Batch, BATCH};

mod batch;
#[cfg(target_arch = "x86_64")]
mod lanes;
#[cfg(target_arch = "x86_64")]
use lanes::{chunk_avx2, Lanes};

/// Smallest clip `w` accepted as "in front of the eye".
const W_EPS: f32 = 1e-6;
/// Part of the margin in pixels added around the projected corners that does not depend on
/// the scene's scale: the rasterizer's 1/256-pixel snapping, with room to spare. A pixel
/// bound `a` with margin `m` starts at the first pixel center at or above `a − m`:
/// `ceil(a − (m + 1/2))`; a high bound `b` ends at the last at or below `b + m`:
/// `floor(b + (m − 1/2))`.
const PIXEL_MARGIN: f32 = 1.0 / 128.0;
/// Unit roundoff of f32: every rounding of a result `x` moves it by at most `U·|x|`.
const U: f32 = f32::EPSILON / 2.0;
/// Part of the depth margin independent of the scene's scale: the roundings of the divide
/// and the viewport transform, here and for the rasterizer's vertices.
const DEPTH_FLOOR: f32 = 8.0 * U;
/// Bound on the relative rounding of a clip coordinate, per unit of the magnitudes summed
/// into it (see [`BoxProjector`]'s "Rounding" section), halved for window coordinates.
const CLIP_ROUNDING: f32 = 8.0 * U;

/// A pixel rectangle `[x0, x1) × [y0, y1)` (row 0 at the top): the pixels whose centers the
/// box that made it may cover, with its nearest window depth.
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
    /// Outside the view frustum (or covering no pixel center): nothing of it can be drawn.
    Outside,
    /// At or behind the near plane (or unbounded, or too large for its rounding to be
    /// bounded): it may cover any pixel at any depth.
    CrossesNear,
    /// In front of the near plane: a conservative rectangle (never empty: a box covering no
    /// pixel center is [`BoxImage::Outside`]) and its nearest depth.
    Rect(ScreenRect),
}

/// Projects boxes with one `clip_from_world` onto a `width × height` viewport.
///
/// ## Rounding
///
/// A box's corners and the rasterizer's vertices are projected in f32 by different
/// operations, so the box's nearest depth and pixel bounds are widened by a bound on both
/// roundings, per box. A clip coordinate summed from terms whose magnitudes add up to `S` is
/// off by at most a few `u·S` (`u = 2^−24`, Higham, *Accuracy and Stability of Numerical
/// Algorithms*, §3.1), and its NDC value `c/w` by about that over `w`. For a box the terms
/// are the matrix rows times the corners' coordinates, so `S ≤ n·R + t` with `n` a row's
/// absolute sum, `t` its translation and `R` the box's reach: its largest coordinate
/// magnitude plus extent, measured from the projector's origin. For a vertex drawn by
/// `clip_from_local`, `S` is at most `n·(R + 2L) + t` when the terms of its instance's
/// transform, `Σ_j |B_kj|·|v_j|` on each axis `k`, stay below `L` (the `reach` of
/// [`BoxProjector::for_camera`]): the instance's origin lies within `R + L` of the eye and
/// the local product adds up to `L`. Each box's depth is lowered by
/// `8u·((n_z + n_w)·(R + 2L) + t_z + t_w) / w_min` (`w_min` its smallest corner `w`) plus a
/// fixed `8u`, and its pixel bounds grown by the same form in x and y scaled to pixels, plus
/// 1/128 px for the rasterizer's 1/256-pixel snapping. A box whose margins are not finite
/// (an infinite reach, a corner `w` next to zero with a huge box) may cover anything: it is
/// [`BoxImage::CrossesNear`]. Vertices the rasterizer makes by clipping at the guard band
/// add a few more roundings of the same terms, left to the factor 8's slack. Projecting from
/// the eye ([`BoxProjector::for_camera`]) keeps `R` the distance to the box rather than the
/// world's size (from the origin, the f32 projection itself of a box 9 m from the eye in a
/// city 700 m across was off by 1.1·10^−6 in depth).
///
/// The rasterizer does its part: a triangle's depth plane, evaluated far from its vertices,
/// is clamped from below to its nearest vertex's depth, so no pixel of a triangle is nearer
/// than that vertex. World boxes made by transforming local boxes are rounded outward
/// (`Aabb::transformed`).
///
/// The bound is first-order and assumes transforms without extreme shear; the tests check
/// it against f64 projections far from the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxProjector {
    /// `clip_from_world · translate(origin)`: boxes are projected relative to `origin`.
    clip: Mat4,
    origin: Vec3,
    /// The rounding bound of each box (see "Rounding"): the margin of pixel x, pixel y and
    /// depth is `(err_a[k]·R + err_b[k]) / w_min` plus a fixed part.
    err_a: [f32; 3],
    err_b: [f32; 3],
    width: u32,
    height: u32,
    /// The instruction set the calls run on: resolved (never `Auto`), and `Portable` for
    /// viewports too large for the SIMD path.
    simd: SimdLevel,
}

impl BoxProjector {
    /// A projector for `clip_from_world` and a `width × height` viewport, on the best
    /// instruction set available ([`SimdLevel::best`]).
    ///
    /// The boxes are projected from the world's origin, so the margins (see "Rounding")
    /// grow with the world coordinates' magnitude; [`BoxProjector::for_camera`] measures them
    /// from the eye.
    pub fn new(clip_from_world: Mat4, width: u32, height: u32) -> BoxProjector {
        BoxProjector::with_simd(clip_from_world, width, height, SimdLevel::Auto)
    }

    /// A projector for `camera` that projects boxes relative to the eye, so that its
    /// rounding margins follow the boxes' distance rather than the world's size.
    /// `reach` bounds the terms of the drawn instances' vertex transforms, `Σ_j |B_kj|·|v_j|`
    /// per world axis (`B` the linear part, `v` local positions; see "Rounding"): the
    /// rasterizer's own rounding grows with it (0 for boxes not drawn through instances, the
    /// world's size for meshes in world coordinates).
    pub fn for_camera(camera: &Camera, width: u32, height: u32, reach: f32) -> BoxProjector {
        BoxProjector::for_camera_with_simd(camera, width, height, reach, SimdLevel::Auto)
    }

    /// [`BoxProjector::for_camera`] on the instruction set `simd` (see
    /// [`BoxProjector::with_simd`]).
    pub fn for_camera_with_simd(camera: &Camera, width: u32, height: u32, reach: f32, simd: SimdLevel) -> BoxProjector {
        let eye = camera.view.eye;
        let clip = (camera.clip_from_world_f64() * DMat4::from_translation(eye.as_dvec3())).as_mat4();
        BoxProjector::make(clip, eye, reach, width, height, simd)
    }

    /// [`BoxProjector::new`] on the instruction set `simd` (resolved: a level the CPU lacks
    /// falls back to the best it has). Every level gives the same answers bit for bit; this
    /// is for parity tests and measurements.
    pub fn with_simd(clip_from_world: Mat4, width: u32, height: u32, simd: SimdLevel) -> BoxProjector {
        BoxProjector::make(clip_from_world, Vec3::ZERO, 0.0, width, height, simd)
    }

    /// The projector of `clip` (clip from coordinates relative to `origin`), with the
    /// rounding bounds of its rows (see "Rounding").
    fn make(clip: Mat4, origin: Vec3, reach: f32, width: u32, height: u32, simd: SimdLevel) -> BoxProjector {
        let simd = if width <= SIMD_MAX_SIZE && height <= SIMD_MAX_SIZE { simd.resolve() } else { SimdLevel::Portable };
        let row = |r: usize| {
            let n = clip.x_axis[r].abs() + clip.y_axis[r].abs() + clip.z_axis[r].abs();
            (n, clip.w_axis[r].abs())
        };
        let (nw, tw) = row(3);
        let reach = if reach.is_nan() { f32::INFINITY } else { reach.abs() };
        // x and y in pixels (half the viewport per NDC unit), z in window depth (half).
        let scale = [width as f32, height as f32, 1.0].map(|s| s * CLIP_ROUNDING);
        let err_a = std::array::from_fn(|k| scale[k] * (row(k).0 + nw));
        let err_b = std::array::from_fn(|k| scale[k] * ((row(k).0 + nw) * (2.0 * reach) + row(k).1 + tw));
        BoxProjector { clip, origin, err_a, err_b, width, height, simd }
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

    /// [`BoxProjector::classify`] in plain scalar code: the reference the SIMD path is tested
    /// against, and the path on CPUs (and targets) without AVX2.
    ///
    /// The corners are formed once in clip space: corner `i` is `base` (the clip position of
    /// `b.min`) plus, in this order, the scaled matrix columns `dx` (if bit 0 of `i` is set),
    /// `dy` (bit 1) and `dz` (bit 2).
    pub fn classify_portable(&self, b: &Aabb) -> BoxImage {
        let Some((base, dx, dy, dz, reach)) = self.corner_terms(b) else {
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
        let mut w_min = f32::MAX;
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
            w_min = w_min.min(c.w);
        }
        let Some([mx, my, mz]) = self.margins(reach, w_min) else {
            return BoxImage::CrossesNear;
        };
        let (w, h) = (self.width, self.height);
        let (wf, hf) = (w as f32, h as f32);
        // Pixel space, y down; pixel i has its center at i + 1/2. The columns whose centers
        // lie in [a − m, b + m] are ceil(a − m − 1/2) ..= floor(b + m − 1/2). The bounds are
        // integers, so the clamp's truncation is exact.
        let clamp = |v: f32, hi: u32| -> u32 {
            if v <= 0.0 {
                0
            } else if v >= hi as f32 {
                hi
            } else {
                v as u32
            }
        };
        let rx0 = clamp(((x0 + 1.0) * 0.5 * wf - (mx + 0.5)).ceil(), w);
        let rx1 = clamp(((x1 + 1.0) * 0.5 * wf + (mx - 0.5)).floor() + 1.0, w);
        let ry0 = clamp(((1.0 - y1) * 0.5 * hf - (my + 0.5)).ceil(), h);
        let ry1 = clamp(((1.0 - y0) * 0.5 * hf + (my - 0.5)).floor() + 1.0, h);
        self.rect(rx0, ry0, rx1, ry1, z0, mz)
    }

    /// The margins of a box of reach `reach` whose nearest corner `w` is `w_min` (see
    /// "Rounding"): pixels in x and y, window depth. `None` when one is not finite (a box
    /// too large for its rounding to be bounded: it may cover anything).
    #[inline(always)]
    fn margins(&self, reach: f32, w_min: f32) -> Option<[f32; 3]> {
        let g = 1.0 / w_min;
        let m = |k: usize| (self.err_a[k] * reach + self.err_b[k]) * g;
        let (mx, my, mz) = (m(0) + PIXEL_MARGIN, m(1) + PIXEL_MARGIN, m(2) + DEPTH_FLOOR);
        // All three are ≥ 0 or NaN, so a finite sum means all are finite; a sum that
        // overflows with finite parts also answers "crosses" (conservative, in every path).
        (mx + my + mz).is_finite().then_some([mx, my, mz])
    }

    /// `base` (clip position of `b.min`, relative to the origin), the matrix columns scaled
    /// by the box extent and the box's reach (see "Rounding"), for a finite box; `None` for
    /// empty and unbounded boxes.
    #[inline(always)]
    fn corner_terms(&self, b: &Aabb) -> Option<(Vec4, Vec4, Vec4, Vec4, f32)> {
        // `b.kind() == BoxKind::Finite` as three lane-wise compares: min ≤ max, min > −∞ and
        // max < +∞ on every axis (any NaN fails the first).
        let (lo, hi) = (Vec3A::from(b.min), Vec3A::from(b.max));
        if !(lo.cmple(hi) & lo.cmpgt(Vec3A::NEG_INFINITY) & hi.cmplt(Vec3A::INFINITY)).all() {
            return None;
        }
        let m = &self.clip;
        // m · (min − origin, 1), spelled out in the order of the eight-box path.
        let q = b.min - self.origin;
        let base = ((m.x_axis * q.x + m.y_axis * q.y) + m.z_axis * q.z) + m.w_axis;
        let e = b.max - b.min;
        let r = q.abs() + e;
        let reach = r.x.max(r.y).max(r.z);
        Some((base, m.x_axis * e.x, m.y_axis * e.y, m.z_axis * e.z, reach))
    }

    /// The answer for a box that is not finite.
    #[cold]
    fn unbounded_or_empty(&self, b: &Aabb) -> BoxImage {
        match b.kind() {
            BoxKind::Empty => BoxImage::Outside,
            _ => BoxImage::CrossesNear,
        }
    }

    /// The rectangle of pixel bounds and nearest NDC z, less the depth margin `mz` (shared
    /// tail of both paths).
    #[inline(always)]
    fn rect(&self, x0: u32, y0: u32, x1: u32, y1: u32, z0: f32, mz: f32) -> BoxImage {
        if x0 >= x1 || y0 >= y1 {
            return BoxImage::Outside;
        }
        let depth = ((z0 + 1.0) * 0.5 - mz).clamp(0.0, 1.0);
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
        let Some((base, dx, dy, dz, reach)) = self.corner_terms(b) else {
            return self.unbounded_or_empty(b);
        };
        // The intrinsics work on values only (no memory is accessed through pointers).
        let (x0, y0, x1, y1, z0, mz) = {
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
            let w_min = _mm256_min_ps(w, _mm256_permute2f128_ps::<1>(w, w));
            let w_min = _mm256_min_ps(w_min, _mm256_permute_ps::<0b01_00_11_10>(w_min));
            let w_min = _mm256_min_ps(w_min, _mm256_permute_ps::<0b10_11_00_01>(w_min));
            let Some([mx, my, mz]) = self.margins(reach, _mm256_cvtss_f32(w_min)) else {
                return BoxImage::CrossesNear;
            };
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
            // Low bounds (lanes 0, 2) − (margin + 1/2) rounded up, high bounds + (margin − 1/2)
            // rounded down, plus one.
            let v = _mm_add_ps(v, _mm_set_ps(my - 0.5, -(my + 0.5), mx - 0.5, -(mx + 0.5)));
            let v = _mm_blend_ps::<0b1010>(_mm_ceil_ps(v), _mm_floor_ps(v));
            let v = _mm_add_ps(v, _mm_set_ps(1.0, 0.0, 1.0, 0.0));
            // The portable clamp: ≤ 0 → 0, ≥ size → size, else truncation (exact: the values
            // are integers, and sizes ≤ 2^24).
            let r = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(v, _mm_setzero_ps()), size));
            let (x0, x1) = (_mm_cvtsi128_si32(r) as u32, _mm_extract_epi32::<1>(r) as u32);
            let (y0, y1) = (_mm_extract_epi32::<2>(r) as u32, _mm_extract_epi32::<3>(r) as u32);
            let z0 = f32::from_bits(_mm_extract_ps::<2>(lo) as u32);
            (x0, y0, x1, y1, z0, mz)
        };
        self.rect(x0, y0, x1, y1, z0, mz)
    }
}

/// Largest viewport side for which the SIMD path's float clamp and truncation are exact.
const SIMD_MAX_SIZE: u32 = 1 << 24;

/// Projects one box: see [`BoxProjector::project`].
pub fn project_box(b: &Aabb, clip_from_world: &Mat4, width: u32, height: u32) -> ScreenRect {
    BoxProjector::new(*clip_from_world, width, height).project(b)
}

#[cfg(test)]
mod tests;

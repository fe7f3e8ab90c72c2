//! Projection of a world box to a conservative screen rectangle and nearest window depth —
//! the query shape of hierarchical z-buffer tests (Greene, Kass & Miller 1993; the
//! rectangle-instead-of-box idea of Intel's Masked Occlusion Culling `TestRect`).
//!
//! Window conventions (DESIGN.md): `x_w = (x_ndc + 1)/2 · W`, `y_w = (1 − y_ndc)/2 · H`,
//! `z_w = (z_ndc + 1)/2`. The eight corners are projected; when any corner has `w ≤ ε` or lies
//! in front of the near plane (`z < −w`), the box crosses the near plane (or the eye plane) and
//! the answer is "covers the whole screen, nearest depth 0". Otherwise the rectangle is the
//! pixel-space bounds of the corners grown by a small margin (vertex snapping to 1/256 pixel
//! and float error), rounded outwards and clamped to the viewport, and the depth is the
//! smallest corner window z minus a small margin. Since the view depth is linear over a box
//! and window z is monotonic in it, the box's nearest point is one of its corners.

use glam::{Mat4, Vec3A, Vec4};
use sightline_scene::Aabb;

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
    /// In front of the near plane: a conservative rectangle and its nearest depth.
    Rect(ScreenRect),
}

/// Projects boxes with one `clip_from_world` onto a `width × height` viewport.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxProjector {
    clip_from_world: Mat4,
    width: u32,
    height: u32,
}

impl BoxProjector {
    /// A projector for `clip_from_world` and a `width × height` viewport.
    pub fn new(clip_from_world: Mat4, width: u32, height: u32) -> BoxProjector {
        BoxProjector { clip_from_world, width, height }
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
    /// With AVX2 enabled at build time (the workspace builds for x86-64-v3) this runs the
    /// eight corners as four 256-bit registers of two corners each; otherwise
    /// [`BoxProjector::classify_portable`]. Both do the same IEEE operations in the same order
    /// on every corner, so they give the same answer bit for bit, on every input.
    #[inline]
    pub fn classify(&self, b: &Aabb) -> BoxImage {
        self.classify_with(b, |image| image)
    }

    /// `then(self.classify(b))`, with `then` inlined into each path, so that a caller that
    /// only needs a small answer (a query's three-way verdict) gets it without the
    /// [`BoxImage`] passing through memory.
    #[inline(always)]
    pub fn classify_with<R>(&self, b: &Aabb, then: impl FnOnce(BoxImage) -> R) -> R {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if self.width <= SIMD_MAX_SIZE && self.height <= SIMD_MAX_SIZE {
            return then(self.classify_avx2(b));
        }
        then(self.classify_portable(b))
    }

    /// [`BoxProjector::classify`] in plain scalar code: the reference the SIMD path is tested
    /// against, and the path on targets without AVX2.
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
        let base = *m * b.min.extend(1.0);
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

    /// [`BoxProjector::classify_portable`] with AVX2: corners 2k and 2k + 1 share a 256-bit
    /// register as (x, y, z, w, x, y, z, w), so that forming them takes four additions, the
    /// clip tests are lane-wise compares reduced across registers, one division gives the
    /// eight reciprocals, and the min/max over the corners are six lane-wise operations.
    /// Every arithmetic operation is the one the portable path does, on the same operands,
    /// so every value (and so the answer) is the same bit for bit.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    #[inline(always)]
    fn classify_avx2(&self, b: &Aabb) -> BoxImage {
        use std::arch::x86_64::*;
        let Some((base, dx, dy, dz)) = self.corner_terms(b) else {
            return self.unbounded_or_empty(b);
        };
        // SAFETY: compiled only when the whole build enables AVX2 (and so AVX, SSE4.1); the
        // intrinsics work on values only, no memory is accessed through pointers.
        let (x0, y0, x1, y1, z0) = unsafe {
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
            // Lane k (x, y, z) of `all4` holds for all eight corners when it holds in both halves.
            let all4 = |a: __m256, b: __m256, c: __m256, d: __m256| {
                let m = _mm256_movemask_ps(_mm256_and_ps(_mm256_and_ps(a, b), _mm256_and_ps(c, d)));
                m & (m >> 4)
            };
            let beyond = all4(
                _mm256_cmp_ps::<_CMP_GT_OQ>(c01, w01),
                _mm256_cmp_ps::<_CMP_GT_OQ>(c23, w23),
                _mm256_cmp_ps::<_CMP_GT_OQ>(c45, w45),
                _mm256_cmp_ps::<_CMP_GT_OQ>(c67, w67),
            );
            let below = all4(
                _mm256_cmp_ps::<_CMP_LT_OQ>(c01, n01),
                _mm256_cmp_ps::<_CMP_LT_OQ>(c23, n23),
                _mm256_cmp_ps::<_CMP_LT_OQ>(c45, n45),
                _mm256_cmp_ps::<_CMP_LT_OQ>(c67, n67),
            );
            if (beyond | below) & 0b0111 != 0 {
                return BoxImage::Outside;
            }
            // In front of the near plane: z ≥ −w (lane 2) and w > W_EPS (lane 3) at every corner.
            let eps = _mm256_set1_ps(W_EPS);
            let front = all4(
                _mm256_cmp_ps::<_CMP_GE_OQ>(c01, n01),
                _mm256_cmp_ps::<_CMP_GE_OQ>(c23, n23),
                _mm256_cmp_ps::<_CMP_GE_OQ>(c45, n45),
                _mm256_cmp_ps::<_CMP_GE_OQ>(c67, n67),
            );
            let ahead = all4(
                _mm256_cmp_ps::<_CMP_GT_OQ>(w01, eps),
                _mm256_cmp_ps::<_CMP_GT_OQ>(w23, eps),
                _mm256_cmp_ps::<_CMP_GT_OQ>(w45, eps),
                _mm256_cmp_ps::<_CMP_GT_OQ>(w67, eps),
            );
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

/// Largest viewport side for which the SIMD path's float clamp and truncation are exact.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
const SIMD_MAX_SIZE: u32 = 1 << 24;

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

    /// The SIMD path of `classify` gives exactly the answers of the portable path, on
    /// perspective and orthographic cameras, arbitrary matrices and every kind of box.
    #[test]
    fn classify_equals_the_portable_path() {
        let mut rng = sightline_scene::rng::Rng::new(77);
        let mut kinds = [0usize; 3];
        for cam_i in 0..300 {
            let m = match cam_i % 5 {
                // Arbitrary matrices, some with NaN or huge entries.
                3 => Mat4::from_cols_array(&std::array::from_fn(|_| match rng.below(50) {
                    0 => f32::NAN,
                    1 => 1e30,
                    _ => rng.range(-2.0, 2.0),
                })),
                // Orthographic (w = 1 everywhere): view volume [−5, 5] × [−3, 3] × [−25, 25].
                4 => {
                    Mat4::from_scale(Vec3::new(0.2, 1.0 / 3.0, -0.04))
                        * Mat4::from_translation(Vec3::new(rng.range(-5.0, 5.0), rng.range(-1.0, 1.0), 0.0))
                }
                _ => {
                    let eye = Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0));
                    let target = eye + Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                    let near = [1e-4, 0.1, 1.0][rng.below(3) as usize];
                    match Camera::perspective_look_at(eye, target, Vec3::Y, rng.range(10.0, 120.0), 1.7, near, 500.0) {
                        Ok(c) => c.clip_from_world(),
                        Err(_) => continue,
                    }
                }
            };
            let (w, h) = [(1280, 720), (97, 33), (1, 1), (0, 0), (4096, 3000)][rng.below(5) as usize];
            let p = BoxProjector::new(m, w, h);
            for _ in 0..400 {
                let reach = [1.0, 10.0, 100.0][rng.below(3) as usize];
                let b = random_box(&mut rng, reach);
                let (fast, portable) = (p.classify(&b), p.classify_portable(&b));
                // Compared through the bits of the depth, so NaN would show as a mismatch.
                let key = |i: &BoxImage| match i {
                    BoxImage::Rect(r) => Some((r.x0, r.y0, r.x1, r.y1, r.depth.to_bits(), r.crosses_near)),
                    _ => None,
                };
                assert_eq!(std::mem::discriminant(&fast), std::mem::discriminant(&portable), "{b:?} {m:?} {w}x{h}");
                assert_eq!(key(&fast), key(&portable), "{b:?} {m:?} {w}x{h}");
                kinds[match fast {
                    BoxImage::Outside => 0,
                    BoxImage::CrossesNear => 1,
                    BoxImage::Rect(_) => 2,
                }] += 1;
            }
        }
        assert!(kinds.iter().all(|&k| k > 2000), "{kinds:?}");
    }

    #[test]
    fn boxes_behind_the_eye_across_near_nan_and_empty() {
        let c = cam();
        let p = BoxProjector::new(c.clip_from_world(), 96, 64);
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

    #[test]
    fn offscreen_box_is_empty() {
        let c = cam();
        let m = c.clip_from_world();
        let b = Aabb::new(Vec3::new(30.0, -0.5, -1.0), Vec3::new(31.0, 0.5, 0.0));
        assert!(project_box(&b, &m, 96, 64).is_empty());
    }
}

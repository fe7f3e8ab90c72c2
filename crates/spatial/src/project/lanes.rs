//! Eight boxes side by side, one per AVX2 lane ([`BoxProjector::classify_many`]): the long
//! chain of dependent operations of one box overlaps with seven others. Same IEEE operations
//! in the same order as the one-box paths of the parent module.

#![cfg(target_arch = "x86_64")]

use super::*;

/// A projector's constants broadcast to eight lanes.
pub(super) struct Lanes {
    /// Matrix entry (column c, row r) at `4c + r`.
    m: [std::arch::x86_64::__m256; 16],
    /// Viewport width and height as floats.
    size: [std::arch::x86_64::__m256; 2],
    /// The projector's origin, x, y, z.
    origin: [std::arch::x86_64::__m256; 3],
    /// The rounding bound's coefficients (pixel x, pixel y, depth).
    err_a: [std::arch::x86_64::__m256; 3],
    err_b: [std::arch::x86_64::__m256; 3],
}

// The eight-box path reads each box as floats: min at 0..3, max at 3..6.
const _: () = assert!(
    std::mem::size_of::<Aabb>() == 24
        && std::mem::size_of::<glam::Vec3>() == 12
        && std::mem::offset_of!(Aabb, min) == 0
        && std::mem::offset_of!(Aabb, max) == 12
        && std::mem::offset_of!(glam::Vec3, x) == 0
        && std::mem::offset_of!(glam::Vec3, y) == 4
        && std::mem::offset_of!(glam::Vec3, z) == 8
);

impl Lanes {
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    pub(super) fn new(p: &BoxProjector) -> Lanes {
        use std::arch::x86_64::*;
        let cols = p.clip.to_cols_array();
        let splat = |v: [f32; 3]| v.map(|x| _mm256_set1_ps(x));
        Lanes {
            m: std::array::from_fn(|i| _mm256_set1_ps(cols[i])),
            size: [_mm256_set1_ps(p.width as f32), _mm256_set1_ps(p.height as f32)],
            origin: splat(p.origin.to_array()),
            err_a: splat(p.err_a),
            err_b: splat(p.err_b),
        }
    }

    /// [`BoxProjector::classify_portable`] for eight boxes, one per lane, into lanes
    /// `at..at + 8` of `out` (`at` a multiple of eight). Lanes
    /// whose box is not finite, or whose clip terms (`base`, `dx`, `dy`, `dz`) are not all
    /// finite, are left for the one-box path (their lanes hold anything); the returned mask
    /// has bit k set for such a lane k. For the others no corner coordinate is NaN (sums of
    /// finite terms are finite or ±∞ of one sign), so the comparisons, and the min/max over
    /// the corners, are those of the portable path; a non-finite projection shows up in the
    /// min or max over the corners (or, for w = +∞, in the max of w); a lane whose margins
    /// are not finite answers "crosses", as the portable path does.
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
            // Component r of base = ((x_axis·q.x + y_axis·q.y) + z_axis·q.z) + w_axis, q = min − origin.
            let o = &self.origin;
            let (qx, qy, qz) = (_mm256_sub_ps(min_x, o[0]), _mm256_sub_ps(min_y, o[1]), _mm256_sub_ps(min_z, o[2]));
            let base = |r: usize| add(add(add(mul(m[r], qx), mul(m[4 + r], qy)), mul(m[8 + r], qz)), m[12 + r]);
            let (ex, ey, ez) = (_mm256_sub_ps(max_x, min_x), _mm256_sub_ps(max_y, min_y), _mm256_sub_ps(max_z, min_z));
            // The reach: max over the axes of |q| + extent.
            let sign = _mm256_set1_ps(-0.0);
            let reach = |q: __m256, e: __m256| add(_mm256_andnot_ps(sign, q), e);
            let reach = _mm256_max_ps(_mm256_max_ps(reach(qx, ex), reach(qy, ey)), reach(qz, ez));
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
            let (mut max_w, mut min_w) = (b[3], b[3]);
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
                min_w = _mm256_min_ps(min_w, c[3]);
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
            // The margins (`BoxProjector::margins`): pixels in x and y, window depth.
            let g = _mm256_div_ps(one, min_w);
            let margin = |k: usize| mul(add(mul(self.err_a[k], reach), self.err_b[k]), g);
            let pixel = _mm256_set1_ps(PIXEL_MARGIN);
            let (mx, my) = (add(margin(0), pixel), add(margin(1), pixel));
            let mz = add(margin(2), _mm256_set1_ps(DEPTH_FLOOR));
            // A non-finite min or max (no NaN can be among them here), w = +∞, or a margin
            // that is not finite (`margins` tests their sum).
            let fz = |v: __m256| _mm256_sub_ps(v, v);
            let f = add(add(add(fz(x0), fz(x1)), add(fz(y0), fz(y1))), add(add(fz(z0), fz(z1)), fz(max_w)));
            let f = add(f, fz(add(add(mx, my), mz)));
            let crosses = or(
                _mm256_xor_ps(front, _mm256_castsi256_ps(_mm256_set1_epi32(-1))),
                _mm256_cmp_ps::<_CMP_UNORD_Q>(f, f),
            );

            // Pixel bounds: the portable path's formulas, lane-wise.
            let (wf, hf) = (self.size[0], self.size[1]);
            let (half, zero) = (_mm256_set1_ps(0.5), _mm256_setzero_ps());
            let clamp = |v: __m256, hi: __m256| _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(v, zero), hi));
            let first = |v: __m256, m: __m256| _mm256_ceil_ps(_mm256_sub_ps(v, add(m, half)));
            let end = |v: __m256, m: __m256| add(_mm256_floor_ps(add(v, _mm256_sub_ps(m, half))), one);
            let rx0 = clamp(first(mul(mul(add(x0, one), half), wf), mx), wf);
            let rx1 = clamp(end(mul(mul(add(x1, one), half), wf), mx), wf);
            let ry0 = clamp(first(mul(mul(_mm256_sub_ps(one, y1), half), hf), my), hf);
            let ry1 = clamp(end(mul(mul(_mm256_sub_ps(one, y0), half), hf), my), hf);
            let depth = _mm256_min_ps(_mm256_max_ps(_mm256_sub_ps(mul(add(z0, one), half), mz), zero), one);
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
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
pub(super) fn chunk_avx2(p: &BoxProjector, lanes: &Lanes, chunk: &[Aabb], out: &mut Batch) {
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

//! The kernels written per instruction set, each returning a bit mask: the slab test of 16
//! packet lanes against a box, lane comparisons (`le16`, `ne16`), and the beam test of a node's
//! four boxes against a packet's four planes (`culls4`).
//!
//! Everything else is plain Rust that LLVM vectorizes for whichever target features the
//! calling function enables. These are the exceptions: building a bit mask from vectorized
//! comparisons is exactly what auto-vectorization does badly (it OR-reduces shifted bits
//! across the vector instead of one `vcmpps → k-mask` or `movmskps`), and the beam test's
//! sixteen plane–box pairs fill one AVX-512 register (two AVX2 ones) where the portable
//! form takes four 4-wide passes (a street view of the city: 8.9 → 8.3 ms a frame).
//!
//! Every version performs the same IEEE operations in the same order, without fused
//! multiply-adds — for the slab test `(lo − o)·r`, then `min`/`max` with the semantics of
//! `if a < b { a } else { b }` (which is what `minps` / `maxps` do with NaNs), then
//! `near ≤ far·(1 + 2⁻²⁰)` as an ordered comparison — so every instruction set returns the
//! same bits.

use super::packet::{BeamPlanes, CHUNK};
use super::{mn, mx};

/// 1 + 2⁻²⁰: above 1 + 2γ₃ (Ize 2013) and the triangle tie window.
pub(crate) const ROBUST: f32 = 1.0 + 1.0 / (1u32 << 20) as f32;

/// The operands of one 16-lane slab test.
pub(crate) struct Slab<'a> {
    /// Lane origins per axis.
    pub o: [&'a [f32; CHUNK]; 3],
    /// Lane direction reciprocals per axis.
    pub r: [&'a [f32; CHUNK]; 3],
    /// Lane interval starts.
    pub tmin: &'a [f32; CHUNK],
    /// Lane interval ends.
    pub tmax: &'a [f32; CHUNK],
}

/// An instruction set for the lane-mask kernels.
pub(crate) trait Isa: Copy {
    /// Bit `j` set when lane `j` meets the box `[lo, hi]`.
    ///
    /// # Safety
    /// The CPU must support the instruction set (checked once by `SimdLevel::resolve`).
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64;

    /// [`Isa::slab16`] for lanes that all start at one origin, given the box's corners
    /// relative to it (`lo − o`, `hi − o`, computed once for every chunk): the same bits,
    /// since each lane's `(lo − o)` was that same difference. `s.o` is not read.
    ///
    /// # Safety
    /// As for [`Isa::slab16`].
    unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64;

    /// Bit `j` set when `a[j] ≤ b[j]` (false for NaN).
    ///
    /// # Safety
    /// As for [`Isa::slab16`].
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64;

    /// Bit `j` set when `a[j] ≠ v`.
    ///
    /// # Safety
    /// As for [`Isa::slab16`].
    unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64;

    /// [`BeamPlanes::culls4`]: bit `k` set when child `k`'s box is outside one of the beam's
    /// planes, with the same IEEE operations in the same order.
    ///
    /// # Safety
    /// As for [`Isa::slab16`].
    #[inline(always)]
    unsafe fn culls4(f: &BeamPlanes, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
        f.culls4(lo, hi)
    }
}

/// Scalar code (LLVM may vectorize the arithmetic; the mask is built bit by bit).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

/// The portable slab test of a chunk given `rel(axis, lane)`: the box's corners relative to
/// the lane's origin, `(lo − o, hi − o)`.
#[inline(always)]
fn slab_portable(s: &Slab<'_>, rel: impl Fn(usize, usize) -> (f32, f32)) -> u64 {
    let mut m = 0u64;
    for j in 0..CHUNK {
        let mut near = s.tmin[j];
        let mut far = s.tmax[j];
        for a in 0..3 {
            let (dlo, dhi) = rel(a, j);
            let t0 = dlo * s.r[a][j];
            let t1 = dhi * s.r[a][j];
            near = mx(mn(t0, t1), near);
            far = mn(mx(t0, t1), far);
        }
        m |= ((near <= far * ROBUST) as u64) << j;
    }
    m
}

impl Isa for Portable {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        slab_portable(s, |a, j| (lo[a] - s.o[a][j], hi[a] - s.o[a][j]))
    }

    #[inline(always)]
    unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
        slab_portable(s, |a, _| (dlo[a], dhi[a]))
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        let mut m = 0u64;
        for j in 0..CHUNK {
            m |= ((a[j] <= b[j]) as u64) << j;
        }
        m
    }

    #[inline(always)]
    unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64 {
        let mut m = 0u64;
        for (j, &x) in a.iter().enumerate() {
            m |= ((x != v) as u64) << j;
        }
        m
    }
}

/// AVX2: two 8-lane halves, `movmskps`.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct Avx2;

/// AVX-512: one 16-lane register, compare into a mask register.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct Avx512;

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::*;
    use std::arch::x86_64::*;

    /// The slab test of eight lanes (from lane `at`) given, per axis, the box's corners
    /// relative to each lane's origin (`dlo`, `dhi`): the part both forms share.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn half_from(s: &Slab<'_>, dlo: [__m256; 3], dhi: [__m256; 3], at: usize) -> u32 {
        // SAFETY (all loads): `at` is 0 or 8 and every array has 16 lanes.
        let mut near = _mm256_loadu_ps(s.tmin.as_ptr().add(at));
        let mut far = _mm256_loadu_ps(s.tmax.as_ptr().add(at));
        for a in 0..3 {
            let r = _mm256_loadu_ps(s.r[a].as_ptr().add(at));
            let t0 = _mm256_mul_ps(dlo[a], r);
            let t1 = _mm256_mul_ps(dhi[a], r);
            // min(t0, t1) as `t0 < t1 ? t0 : t1` is minps(t0, t1); max likewise. Then
            // near = t > near ? t : near is maxps(t, near).
            near = _mm256_max_ps(_mm256_min_ps(t0, t1), near);
            far = _mm256_min_ps(_mm256_max_ps(t0, t1), far);
        }
        let ok = _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_mul_ps(far, _mm256_set1_ps(ROBUST)));
        _mm256_movemask_ps(ok) as u32
    }

    /// [`half_from`] with each lane's own origin.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn half(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3], at: usize) -> u32 {
        // SAFETY (loads): `at` is 0 or 8 and every array has 16 lanes.
        let load = |a: usize| _mm256_loadu_ps(s.o[a].as_ptr().add(at));
        let (o0, o1, o2) = (load(0), load(1), load(2));
        let rel = |v: &[f32; 3]| {
            [
                _mm256_sub_ps(_mm256_set1_ps(v[0]), o0),
                _mm256_sub_ps(_mm256_set1_ps(v[1]), o1),
                _mm256_sub_ps(_mm256_set1_ps(v[2]), o2),
            ]
        };
        half_from(s, rel(lo), rel(hi), at)
    }

    /// [`half_from`] with one origin for every lane, the corners relative to it given.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn half_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3], at: usize) -> u32 {
        let splat = |v: &[f32; 3]| [_mm256_set1_ps(v[0]), _mm256_set1_ps(v[1]), _mm256_set1_ps(v[2])];
        half_from(s, splat(dlo), splat(dhi), at)
    }

    impl Isa for Avx2 {
        #[inline(always)]
        unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
            (half(s, lo, hi, 0) | half(s, lo, hi, 8) << 8) as u64
        }

        #[inline(always)]
        unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
            (half_shared(s, dlo, dhi, 0) | half_shared(s, dlo, dhi, 8) << 8) as u64
        }

        #[inline(always)]
        unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
            le_avx2(a, b)
        }

        #[inline(always)]
        unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64 {
            ne_avx2(a, v)
        }

        #[inline(always)]
        unsafe fn culls4(f: &BeamPlanes, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
            culls_avx2(f, lo, hi)
        }
    }

    /// Two planes against the four boxes per 8-lane register: lane `4k + b` is plane
    /// `2h + k` against box `b` in half `h`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn culls_avx2(f: &BeamPlanes, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
        if !f.on {
            return 0;
        }
        let boxes = |v: &[f32; 4]| {
            let x = _mm_loadu_ps(v.as_ptr());
            _mm256_set_m128(x, x)
        };
        let half = _mm256_set1_ps(0.5);
        let sign = _mm256_set1_ps(-0.0);
        let abs = |v: __m256| _mm256_andnot_ps(sign, v);
        let (mul, add) = (|a, b| _mm256_mul_ps(a, b), |a, b| _mm256_add_ps(a, b));
        let mut c = [_mm256_setzero_ps(); 3];
        let mut e = [_mm256_setzero_ps(); 3];
        let mut ca = [_mm256_setzero_ps(); 3];
        for a in 0..3 {
            let (l, h) = (boxes(&lo[a]), boxes(&hi[a]));
            c[a] = mul(_mm256_add_ps(l, h), half);
            e[a] = mul(_mm256_sub_ps(h, l), half);
            ca[a] = add(abs(c[a]), e[a]);
        }
        let mut m = 0u32;
        for h in 0..2 {
            let spread = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1);
            let spread = _mm256_add_epi32(spread, _mm256_set1_epi32(2 * h));
            let planes =
                |v: &[f32; 4]| _mm256_permutevar8x32_ps(_mm256_castps128_ps256(_mm_loadu_ps(v.as_ptr())), spread);
            let n = [planes(&f.n[0]), planes(&f.n[1]), planes(&f.n[2])];
            let na = [abs(n[0]), abs(n[1]), abs(n[2])];
            let d = planes(&f.c);
            let centre = add(add(mul(c[0], n[0]), mul(c[1], n[1])), mul(c[2], n[2]));
            let reach = add(add(mul(e[0], na[0]), mul(e[1], na[1])), mul(e[2], na[2]));
            let dist = add(add(centre, reach), d);
            let mag = add(add(add(mul(ca[0], na[0]), mul(ca[1], na[1])), mul(ca[2], na[2])), abs(d));
            let out = _mm256_cmp_ps::<_CMP_LT_OQ>(dist, mul(mag, _mm256_set1_ps(-1e-6)));
            m |= _mm256_movemask_ps(out) as u32;
        }
        (m | m >> 4) & 0xF
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn le_avx2(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        let mut m = 0u64;
        for at in [0, 8] {
            // SAFETY: `at` is 0 or 8 and both arrays have 16 lanes.
            let ok =
                _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_loadu_ps(a.as_ptr().add(at)), _mm256_loadu_ps(b.as_ptr().add(at)));
            m |= (_mm256_movemask_ps(ok) as u32 as u64) << at;
        }
        m
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn ne_avx2(a: &[u32; CHUNK], v: u32) -> u64 {
        let v = _mm256_set1_epi32(v as i32);
        let mut m = 0u64;
        for at in [0, 8] {
            // SAFETY: `at` is 0 or 8 and the array has 16 lanes.
            let eq = _mm256_cmpeq_epi32(_mm256_loadu_si256(a.as_ptr().add(at).cast()), v);
            m |= (!_mm256_movemask_ps(_mm256_castsi256_ps(eq)) as u32 as u64 & 0xFF) << at;
        }
        m
    }

    // AVX-512 intrinsics and target features are stable since Rust 1.89 (the workspace
    // declares an older rust-version; this path needs 1.89).
    /// The slab test of 16 lanes given, per axis, the box's corners relative to each lane's
    /// origin (`dlo`, `dhi`): the part both forms share.
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn full_from(s: &Slab<'_>, dlo: [__m512; 3], dhi: [__m512; 3]) -> u64 {
        let mut near = _mm512_loadu_ps(s.tmin.as_ptr());
        let mut far = _mm512_loadu_ps(s.tmax.as_ptr());
        for a in 0..3 {
            let r = _mm512_loadu_ps(s.r[a].as_ptr());
            let t0 = _mm512_mul_ps(dlo[a], r);
            let t1 = _mm512_mul_ps(dhi[a], r);
            near = _mm512_max_ps(_mm512_min_ps(t0, t1), near);
            far = _mm512_min_ps(_mm512_max_ps(t0, t1), far);
        }
        _mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, _mm512_mul_ps(far, _mm512_set1_ps(ROBUST))) as u64
    }

    /// [`full_from`] with each lane's own origin.
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn full(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        let (o0, o1, o2) =
            (_mm512_loadu_ps(s.o[0].as_ptr()), _mm512_loadu_ps(s.o[1].as_ptr()), _mm512_loadu_ps(s.o[2].as_ptr()));
        let rel = |v: &[f32; 3]| {
            [
                _mm512_sub_ps(_mm512_set1_ps(v[0]), o0),
                _mm512_sub_ps(_mm512_set1_ps(v[1]), o1),
                _mm512_sub_ps(_mm512_set1_ps(v[2]), o2),
            ]
        };
        full_from(s, rel(lo), rel(hi))
    }

    /// [`full_from`] with one origin for every lane, the corners relative to it given.
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn full_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
        let splat = |v: &[f32; 3]| [_mm512_set1_ps(v[0]), _mm512_set1_ps(v[1]), _mm512_set1_ps(v[2])];
        full_from(s, splat(dlo), splat(dhi))
    }

    impl Isa for Avx512 {
        #[inline(always)]
        unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
            full(s, lo, hi)
        }

        #[inline(always)]
        unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
            full_shared(s, dlo, dhi)
        }

        #[inline(always)]
        unsafe fn culls4(f: &BeamPlanes, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
            culls_avx512(f, lo, hi)
        }

        #[inline(always)]
        unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
            le_avx512(a, b)
        }

        #[inline(always)]
        unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64 {
            ne_avx512(a, v)
        }
    }

    /// The four planes against the four boxes in one 16-lane register: lane `4k + b` is
    /// plane `k` against box `b`.
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn culls_avx512(f: &BeamPlanes, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
        if !f.on {
            return 0;
        }
        // Boxes repeated in each 128-bit quarter; planes spread, one per quarter.
        let boxes = |v: &[f32; 4]| _mm512_broadcast_f32x4(_mm_loadu_ps(v.as_ptr()));
        let spread = _mm512_set_epi32(3, 3, 3, 3, 2, 2, 2, 2, 1, 1, 1, 1, 0, 0, 0, 0);
        let planes = |v: &[f32; 4]| _mm512_permutexvar_ps(spread, _mm512_castps128_ps512(_mm_loadu_ps(v.as_ptr())));
        let half = _mm512_set1_ps(0.5);
        let mut c = [_mm512_setzero_ps(); 3];
        let mut e = [_mm512_setzero_ps(); 3];
        let mut ca = [_mm512_setzero_ps(); 3];
        let mut n = [_mm512_setzero_ps(); 3];
        let mut na = [_mm512_setzero_ps(); 3];
        for a in 0..3 {
            let (l, h) = (boxes(&lo[a]), boxes(&hi[a]));
            c[a] = _mm512_mul_ps(_mm512_add_ps(l, h), half);
            e[a] = _mm512_mul_ps(_mm512_sub_ps(h, l), half);
            ca[a] = _mm512_add_ps(_mm512_abs_ps(c[a]), e[a]);
            n[a] = planes(&f.n[a]);
            na[a] = _mm512_abs_ps(n[a]);
        }
        let d = planes(&f.c);
        let mul = _mm512_mul_ps;
        let add = _mm512_add_ps;
        let centre = add(add(mul(c[0], n[0]), mul(c[1], n[1])), mul(c[2], n[2]));
        let reach = add(add(mul(e[0], na[0]), mul(e[1], na[1])), mul(e[2], na[2]));
        let dist = add(add(centre, reach), d);
        let mag = add(add(add(mul(ca[0], na[0]), mul(ca[1], na[1])), mul(ca[2], na[2])), _mm512_abs_ps(d));
        let m = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(dist, mul(mag, _mm512_set1_ps(-1e-6))) as u32;
        (m | m >> 4 | m >> 8 | m >> 12) & 0xF
    }

    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn le_avx512(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_loadu_ps(a.as_ptr()), _mm512_loadu_ps(b.as_ptr())) as u64
    }

    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn ne_avx512(a: &[u32; CHUNK], v: u32) -> u64 {
        _mm512_cmpneq_epu32_mask(_mm512_loadu_si512(a.as_ptr().cast()), _mm512_set1_epi32(v as i32)) as u64
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Isa for Avx2 {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        Portable::slab16(s, lo, hi)
    }

    #[inline(always)]
    unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
        Portable::slab16_shared(s, dlo, dhi)
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        Portable::le16(a, b)
    }

    #[inline(always)]
    unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64 {
        Portable::ne16(a, v)
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Isa for Avx512 {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        Portable::slab16(s, lo, hi)
    }

    #[inline(always)]
    unsafe fn slab16_shared(s: &Slab<'_>, dlo: &[f32; 3], dhi: &[f32; 3]) -> u64 {
        Portable::slab16_shared(s, dlo, dhi)
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        Portable::le16(a, b)
    }

    #[inline(always)]
    unsafe fn ne16(a: &[u32; CHUNK], v: u32) -> u64 {
        Portable::ne16(a, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform values in [−4, 4) from a xorshift generator seeded with `seed`.
    fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32 * 8.0 - 4.0
        }
    }

    /// Every instruction set's beam test gives the portable bits: boxes inside, outside,
    /// straddling and on a plane, empty and infinite ones, and culling switched off.
    #[test]
    fn beam_tests_agree_across_instruction_sets() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
        let special = [0.0f32, -0.0, 1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut culled = 0;
        for round in 0..4000 {
            let mut f = BeamPlanes { on: round % 97 != 0, n: [[0.0; 4]; 3], c: [0.0; 4] };
            for k in 0..4 {
                for a in 0..3 {
                    f.n[a][k] = next();
                }
                f.c[k] = next();
            }
            let (mut lo, mut hi) = ([[0f32; 4]; 3], [[0f32; 4]; 3]);
            for b in 0..4 {
                for a in 0..3 {
                    let (p, q) = (next(), next());
                    (lo[a][b], hi[a][b]) = (p.min(q), p.max(q));
                }
            }
            if round % 5 == 0 {
                let b = round / 5 % 4;
                lo[round % 3][b] = special[round % special.len()];
                hi[(round + 1) % 3][b] = special[(round / 7) % special.len()];
            }
            // A box touching plane 0 exactly: the margin decides.
            if round % 11 == 0 {
                f.n = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
                f.c[0] = 2.0;
                (lo[0][1], hi[0][1]) = (-3.0, -2.0);
            }
            let want = f.culls4(&lo, &hi);
            culled += want.count_ones();
            // SAFETY: the portable kernel needs nothing; the others run only when detected.
            assert_eq!(unsafe { Portable::culls4(&f, &lo, &hi) }, want);
            #[cfg(target_arch = "x86_64")]
            {
                if std::is_x86_feature_detected!("avx2") {
                    assert_eq!(unsafe { Avx2::culls4(&f, &lo, &hi) }, want, "round {round}");
                }
                if std::is_x86_feature_detected!("avx512f") {
                    assert_eq!(unsafe { Avx512::culls4(&f, &lo, &hi) }, want, "round {round}");
                }
            }
        }
        // Both outcomes occur.
        assert!(culled > 1000 && culled < 15000, "{culled}");
    }

    /// Every instruction set's lane comparison gives the portable bits, on signed zeros,
    /// infinities, NaN and equal values.
    #[test]
    fn lane_comparisons_agree_across_instruction_sets() {
        let vals = [0.0f32, -0.0, 1.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-30, 3.5, 3.5];
        let mut a = [0f32; CHUNK];
        let mut b = [0f32; CHUNK];
        for k in 0..vals.len() * vals.len() / CHUNK + 1 {
            for j in 0..CHUNK {
                let n = k * CHUNK + j;
                a[j] = vals[n % vals.len()];
                b[j] = vals[(n / vals.len()) % vals.len()];
            }
            // SAFETY: the portable kernel needs nothing; the others run only when detected.
            let want = unsafe { Portable::le16(&a, &b) };
            for j in 0..CHUNK {
                assert_eq!(want >> j & 1 == 1, a[j] <= b[j]);
            }
            #[cfg(target_arch = "x86_64")]
            {
                if std::is_x86_feature_detected!("avx2") {
                    assert_eq!(unsafe { Avx2::le16(&a, &b) }, want);
                }
                if std::is_x86_feature_detected!("avx512f") {
                    assert_eq!(unsafe { Avx512::le16(&a, &b) }, want);
                }
            }
        }
    }

    /// Every instruction set's slab test gives the portable bits, and for lanes that share
    /// an origin the shared-origin form gives the same bits as the general one: random
    /// boxes and directions, with zero, infinite and NaN components mixed in, against
    /// intervals that are empty, open or cut short.
    #[test]
    fn slab_tests_agree_across_instruction_sets_and_origins() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let special = [0.0f32, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-20];
        let mut hits = 0;
        for round in 0..3000 {
            let origin = [next(), next(), next()];
            let o: [[f32; CHUNK]; 3] = origin.map(|v| [v; CHUNK]);
            let mut r = [[0f32; CHUNK]; 3];
            let (mut tmin, mut tmax) = ([0f32; CHUNK], [0f32; CHUNK]);
            for j in 0..CHUNK {
                for row in r.iter_mut() {
                    row[j] = 1.0 / next();
                }
                (tmin[j], tmax[j]) = (next().abs() * 0.1, next().abs() * 4.0);
            }
            r[round % 3][round % CHUNK] = special[round % special.len()];
            if round % 7 == 0 {
                tmax[3] = f32::INFINITY;
            }
            let (mut lo, mut hi) = ([0f32; 3], [0f32; 3]);
            for a in 0..3 {
                let (p, q) = (next(), next());
                (lo[a], hi[a]) = (p.min(q), p.max(q));
            }
            if round % 5 == 0 {
                lo[round % 3] = special[round / 5 % special.len()];
            }
            let dlo = [0, 1, 2].map(|a| lo[a] - origin[a]);
            let dhi = [0, 1, 2].map(|a| hi[a] - origin[a]);
            let s = Slab { o: [&o[0], &o[1], &o[2]], r: [&r[0], &r[1], &r[2]], tmin: &tmin, tmax: &tmax };
            // SAFETY: the portable kernel needs nothing; the others run only when detected.
            let want = unsafe { Portable::slab16(&s, &lo, &hi) };
            hits += want.count_ones();
            assert_eq!(unsafe { Portable::slab16_shared(&s, &dlo, &dhi) }, want, "round {round}");
            #[cfg(target_arch = "x86_64")]
            {
                if std::is_x86_feature_detected!("avx2") {
                    assert_eq!(unsafe { Avx2::slab16(&s, &lo, &hi) }, want, "round {round}");
                    assert_eq!(unsafe { Avx2::slab16_shared(&s, &dlo, &dhi) }, want, "round {round}");
                }
                if std::is_x86_feature_detected!("avx512f") {
                    assert_eq!(unsafe { Avx512::slab16(&s, &lo, &hi) }, want, "round {round}");
                    assert_eq!(unsafe { Avx512::slab16_shared(&s, &dlo, &dhi) }, want, "round {round}");
                }
            }
        }
        // Both outcomes occur.
        assert!(hits > 2000 && hits < 40000, "{hits}");
    }

    /// Every instruction set's inequality mask gives the portable bits, in both halves of
    /// the chunk, for values equal to the one compared against, above it and below it.
    #[test]
    fn lane_inequalities_agree_across_instruction_sets() {
        for v in [0u32, 1, 7, u32::MAX] {
            for pattern in [0u32, 0xFFFF, 0x8001, 0x00F0, 0x5A5A, 0x1234] {
                let a: [u32; CHUNK] =
                    std::array::from_fn(|j| if pattern >> j & 1 == 1 { v } else { v.wrapping_add(j as u32 + 1) });
                // SAFETY: the portable kernel needs nothing; the others run only when detected.
                let want = unsafe { Portable::ne16(&a, v) };
                assert_eq!(want, !pattern as u64 & 0xFFFF, "{v} {pattern:#x}");
                #[cfg(target_arch = "x86_64")]
                {
                    if std::is_x86_feature_detected!("avx2") {
                        assert_eq!(unsafe { Avx2::ne16(&a, v) }, want);
                    }
                    if std::is_x86_feature_detected!("avx512f") {
                        assert_eq!(unsafe { Avx512::ne16(&a, v) }, want);
                    }
                }
            }
        }
    }
}

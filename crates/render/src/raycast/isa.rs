//! The kernels written per instruction set: the slab test of 16 packet lanes against a
//! box, and a lane comparison (`le16`), each returning a lane bit mask.
//!
//! Everything else is plain Rust that LLVM vectorizes for whichever target features the
//! calling function enables; this test is the exception because building a bit mask from
//! vectorized comparisons is exactly what auto-vectorization does badly (it OR-reduces
//! shifted bits across the vector instead of one `vcmpps → k-mask` or `movmskps`); these
//! kernels are the exceptions. The
//! three versions perform the same IEEE operations in the same order — `(lo − o)·r`, then
//! `min`/`max` with the semantics of `if a < b { a } else { b }` (which is what `minps` /
//! `maxps` do with NaNs), then `near ≤ far·(1 + 2⁻²⁰)` as an ordered comparison — so every
//! instruction set returns the same bits.

use super::packet::CHUNK;
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

    /// Bit `j` set when `a[j] ≤ b[j]` (false for NaN).
    ///
    /// # Safety
    /// As for [`Isa::slab16`].
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64;
}

/// Scalar code (LLVM may vectorize the arithmetic; the mask is built bit by bit).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

impl Isa for Portable {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        let mut m = 0u64;
        for j in 0..CHUNK {
            let mut near = s.tmin[j];
            let mut far = s.tmax[j];
            for a in 0..3 {
                let t0 = (lo[a] - s.o[a][j]) * s.r[a][j];
                let t1 = (hi[a] - s.o[a][j]) * s.r[a][j];
                near = mx(mn(t0, t1), near);
                far = mn(mx(t0, t1), far);
            }
            m |= ((near <= far * ROBUST) as u64) << j;
        }
        m
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        let mut m = 0u64;
        for j in 0..CHUNK {
            m |= ((a[j] <= b[j]) as u64) << j;
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

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn half(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3], at: usize) -> u32 {
        // SAFETY (all loads): `at` is 0 or 8 and every array has 16 lanes.
        let mut near = _mm256_loadu_ps(s.tmin.as_ptr().add(at));
        let mut far = _mm256_loadu_ps(s.tmax.as_ptr().add(at));
        for a in 0..3 {
            let o = _mm256_loadu_ps(s.o[a].as_ptr().add(at));
            let r = _mm256_loadu_ps(s.r[a].as_ptr().add(at));
            let t0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(lo[a]), o), r);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(hi[a]), o), r);
            // min(t0, t1) as `t0 < t1 ? t0 : t1` is minps(t0, t1); max likewise. Then
            // near = t > near ? t : near is maxps(t, near).
            near = _mm256_max_ps(_mm256_min_ps(t0, t1), near);
            far = _mm256_min_ps(_mm256_max_ps(t0, t1), far);
        }
        let ok = _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_mul_ps(far, _mm256_set1_ps(ROBUST)));
        _mm256_movemask_ps(ok) as u32
    }

    impl Isa for Avx2 {
        #[inline(always)]
        unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
            (half(s, lo, hi, 0) | half(s, lo, hi, 8) << 8) as u64
        }

        #[inline(always)]
        unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
            le_avx2(a, b)
        }
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

    // AVX-512 intrinsics and target features are stable since Rust 1.89 (the workspace
    // declares an older rust-version; this path needs 1.89).
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn full(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        let mut near = _mm512_loadu_ps(s.tmin.as_ptr());
        let mut far = _mm512_loadu_ps(s.tmax.as_ptr());
        for a in 0..3 {
            let o = _mm512_loadu_ps(s.o[a].as_ptr());
            let r = _mm512_loadu_ps(s.r[a].as_ptr());
            let t0 = _mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(lo[a]), o), r);
            let t1 = _mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(hi[a]), o), r);
            near = _mm512_max_ps(_mm512_min_ps(t0, t1), near);
            far = _mm512_min_ps(_mm512_max_ps(t0, t1), far);
        }
        _mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, _mm512_mul_ps(far, _mm512_set1_ps(ROBUST))) as u64
    }

    impl Isa for Avx512 {
        #[inline(always)]
        unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
            full(s, lo, hi)
        }

        #[inline(always)]
        unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
            le_avx512(a, b)
        }
    }

    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn le_avx512(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_loadu_ps(a.as_ptr()), _mm512_loadu_ps(b.as_ptr())) as u64
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Isa for Avx2 {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        Portable::slab16(s, lo, hi)
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        Portable::le16(a, b)
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl Isa for Avx512 {
    #[inline(always)]
    unsafe fn slab16(s: &Slab<'_>, lo: &[f32; 3], hi: &[f32; 3]) -> u64 {
        Portable::slab16(s, lo, hi)
    }

    #[inline(always)]
    unsafe fn le16(a: &[f32; CHUNK], b: &[f32; CHUNK]) -> u64 {
        Portable::le16(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}

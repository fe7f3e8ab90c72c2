//! Depth formats and the integer keys the rasterizer compares: one codec per format.
//!
//! The z-buffer algorithm (Catmull 1974) keeps the nearest window depth per pixel and
//! accepts a fragment when its depth is LESS than the stored one. Window depth is
//! `z_w = (z_ndc + 1) / 2 ∈ [0, 1]`. Three storage formats are offered so the loss of depth
//! precision (z-fighting) can be shown: `f32`, and 16- and 24-bit unsigned integers holding
//! `round(z_w · (2^n − 1))`, like GL's fixed-point depth buffers.
//!
//! Inside the rasterizer every format is a `u32` *key* whose order equals depth order: the
//! integer value itself, or the bit pattern of a non-negative `f32` (IEEE 754 floats of one
//! sign compare like their bit patterns). One comparison serves all formats. Each format is
//! a zero-sized type implementing `DepthCodec` (scalar, four- and eight-wide keys, decode,
//! tie margin); the kernels are generic over it and the format is chosen once per frame.
//!
//! # NaN
//!
//! A fragment whose depth is NaN is never written, as on GPUs, where every comparison with
//! NaN fails: its key is `NAN_KEY`, above every key a depth can have, so it is never LESS
//! than a stored key nor equal to one. A NaN *stored* in a framebuffer handed in by a user
//! reads as the far plane ([`DepthFormat::key_of_stored`]).

use serde::Serialize;

/// How window depth is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum DepthFormat {
    /// 32-bit float (the default).
    #[default]
    F32,
    /// 16-bit unsigned normalized integer.
    Unorm16,
    /// 24-bit unsigned normalized integer (llvmpipe's default depth buffer).
    Unorm24,
}

impl DepthFormat {
    /// The largest integer value of an integer format (`None` for `F32`).
    #[inline]
    pub fn max_value(self) -> Option<u32> {
        match self {
            DepthFormat::F32 => None,
            DepthFormat::Unorm16 => Some((1 << 16) - 1),
            DepthFormat::Unorm24 => Some((1 << 24) - 1),
        }
    }

    /// The key of window depth `z` (clamped to [0, 1]); NaN gives `NAN_KEY`, which never
    /// passes a depth test.
    #[inline]
    pub fn key(self, z: f32) -> u32 {
        if z.is_nan() {
            return NAN_KEY;
        }
        // `+ 0.0` turns −0.0 into +0.0 (whose bits are 0).
        let z = if z > 0.0 { z.min(1.0) + 0.0 } else { 0.0 };
        match self.max_value() {
            None => z.to_bits(),
            Some(m) => (z * m as f32 + 0.5) as u32,
        }
    }

    /// How much farther than a stored depth a fragment may be and still get the same key
    /// (and so tie with it, and win with a smaller triangle ID): one step of an integer
    /// format (rounding moves half a step either way), 0 for f32. Coarse depth tests skip
    /// only what lies farther than a stored maximum plus this margin.
    #[inline]
    pub fn tie_margin(self) -> f32 {
        match self.max_value() {
            None => 0.0,
            Some(m) => 1.0 / m as f32,
        }
    }

    /// The key of a depth already in the framebuffer (NaN or > 1 count as the far plane).
    #[inline]
    pub fn key_of_stored(self, d: f32) -> u32 {
        if d.is_nan() {
            return self.key(1.0);
        }
        self.key(d)
    }

    /// The window depth a key stands for.
    #[inline]
    pub fn depth(self, key: u32) -> f32 {
        with_codec!(self, decode::<_>(key))
    }

    /// The window depth `z` as this format stores it (quantized for integer formats).
    #[inline]
    pub fn quantize(self, z: f32) -> f32 {
        self.depth(self.key(z))
    }

    /// The size of one depth step just below the far plane (window depth 1): 2^-24 for
    /// `f32` (the spacing of floats in [0.5, 1)), one integer step for the others.
    pub fn step_at_far(self) -> f64 {
        match self.max_value() {
            None => f64::powi(2.0, -24),
            Some(m) => 1.0 / m as f64,
        }
    }

    /// The largest `(far − near) / near` a perspective projection may have for this format
    /// to tell depths apart (see [`DepthFormat::check_resolves`]).
    pub fn max_depth_ratio(self) -> f64 {
        1.0 / self.step_at_far()
    }

    /// Refuses a perspective projection whose near plane is so close, for its far plane,
    /// that this format cannot store its depths.
    ///
    /// With OpenGL's perspective depth, window depth at eye distance `d` is
    /// `z_w(d) = f·(d − n) / (d·(f − n))`, so everything beyond `d` lies in the last
    /// `1 − z_w(d)` of the range; halfway to the far plane that is `n / (f − n)`. When it
    /// is smaller than one depth step ([`DepthFormat::step_at_far`]), the whole far half of
    /// the view rounds to the far plane and ties with the cleared buffer: a blank or torn
    /// picture (near = 10^-7 with far = 2000 blanks a street view in `f32`). Parallel
    /// projections store depth linearly and pass.
    ///
    /// An invalid projection (near = 0 in perspective, an empty window, near ≥ far,
    /// parameters that are not finite: [`Projection::validate`](sightline_scene::Projection::validate))
    /// is refused first: its fields are public, so a camera made by hand may hold one, and a
    /// frame through it would come out blank.
    pub fn check_resolves(self, projection: &sightline_scene::Projection) -> Result<(), crate::Error> {
        projection.validate()?;
        let (_, _, _, _, near, far, perspective) = projection.bounds();
        if !perspective {
            return Ok(());
        }
        let ratio = (far as f64 - near as f64) / near as f64;
        if ratio <= self.max_depth_ratio() {
            return Ok(());
        }
        Err(crate::Error::DepthRange { near, far, ratio, max_ratio: self.max_depth_ratio(), format: self })
    }
}

/// The key of a NaN depth: above every key a depth in [0, 1] (or an f32 above 1) can have,
/// and below 2^31 so that signed SIMD compares order it too. Never stored.
pub(crate) const NAN_KEY: u32 = i32::MAX as u32;

/// One depth storage format as the rasterizer's kernels use it. Every method performs the
/// same IEEE operations at every width, so the scalar, SSE2 and AVX2 kernels agree bit for
/// bit.
pub(crate) trait DepthCodec: Copy + Send + Sync + 'static {
    /// The format this codec stands for.
    const FORMAT: DepthFormat;

    /// The key of interpolated window depth `z`. Interpolation can stray a rounding error
    /// outside [0, 1]: below 0 clamps (a negative float's bits would compare as "far");
    /// above 1 fails LESS against a cleared buffer anyway. NaN gives [`NAN_KEY`].
    fn key(z: f32) -> u32;

    /// The window depth a key stands for.
    fn decode(key: u32) -> f32;

    /// [`DepthFormat::tie_margin`].
    #[inline(always)]
    fn tie_margin() -> f32 {
        Self::FORMAT.tie_margin()
    }

    /// [`DepthCodec::key`] of four lanes (SSE2), none of them NaN: the vector kernels meet
    /// only planes that give numbers ([`Tri::depths_are_numbers`]), so they leave out the
    /// NaN test (four instructions in each row of the AVX2 block kernel).
    ///
    /// # Safety
    /// None beyond SSE2, which every x86-64 CPU has.
    ///
    /// [`Tri::depths_are_numbers`]: crate::edge::Tri::depths_are_numbers
    #[cfg(target_arch = "x86_64")]
    unsafe fn key4(z: std::arch::x86_64::__m128) -> std::arch::x86_64::__m128i;

    /// [`DepthCodec::key4`] of eight lanes, none of them NaN.
    ///
    /// # Safety
    /// The CPU must have AVX2, and the caller must be compiled with it (an AVX2
    /// `#[target_feature]` function this inlines into).
    #[cfg(target_arch = "x86_64")]
    unsafe fn key8(z: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256i;

    /// [`DepthCodec::key8`] of sixteen lanes (AVX-512), none of them NaN.
    ///
    /// # Safety
    /// The CPU must have AVX-512 F and DQ, and the caller must be compiled with them.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn key16(z: std::arch::x86_64::__m512) -> std::arch::x86_64::__m512i {
        use std::arch::x86_64::*;
        unsafe {
            let lo = Self::key8(_mm512_castps512_ps256(z));
            let hi = Self::key8(_mm512_extractf32x8_ps::<1>(z));
            _mm512_inserti64x4::<1>(_mm512_castsi256_si512(lo), hi)
        }
    }
}

/// 32-bit float depth: the key is the bit pattern.
#[derive(Debug, Clone, Copy)]
pub(crate) struct F32;
/// 24-bit unsigned normalized depth.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unorm24;
/// 16-bit unsigned normalized depth.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Unorm16;

impl DepthCodec for F32 {
    const FORMAT: DepthFormat = DepthFormat::F32;

    #[inline(always)]
    fn key(z: f32) -> u32 {
        let b = z.to_bits();
        if z.is_nan() {
            NAN_KEY
        } else if (b as i32) < 0 {
            0
        } else {
            b
        }
    }

    #[inline(always)]
    fn decode(key: u32) -> f32 {
        f32::from_bits(key)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn key4(z: std::arch::x86_64::__m128) -> std::arch::x86_64::__m128i {
        use std::arch::x86_64::*;
        let bits = _mm_castps_si128(z);
        _mm_andnot_si128(_mm_srai_epi32(bits, 31), bits)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn key8(z: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256i {
        use std::arch::x86_64::*;
        let bits = _mm256_castps_si256(z);
        _mm256_andnot_si256(_mm256_srai_epi32(bits, 31), bits)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn key16(z: std::arch::x86_64::__m512) -> std::arch::x86_64::__m512i {
        use std::arch::x86_64::*;
        let bits = _mm512_castps_si512(z);
        _mm512_andnot_si512(_mm512_srai_epi32::<31>(bits), bits)
    }
}

/// The integer formats: `round(clamp(z, 0, 1) · MAX)`.
macro_rules! unorm_codec {
    ($name:ident, $format:expr, $max:expr) => {
        impl DepthCodec for $name {
            const FORMAT: DepthFormat = $format;

            #[inline(always)]
            fn key(z: f32) -> u32 {
                if z.is_nan() {
                    return NAN_KEY;
                }
                (z.clamp(0.0, 1.0) * $max + 0.5) as i32 as u32
            }

            #[inline(always)]
            fn decode(key: u32) -> f32 {
                key as f32 / $max
            }

            #[cfg(target_arch = "x86_64")]
            #[inline(always)]
            unsafe fn key4(z: std::arch::x86_64::__m128) -> std::arch::x86_64::__m128i {
                use std::arch::x86_64::*;
                let c = _mm_min_ps(_mm_max_ps(z, _mm_setzero_ps()), _mm_set1_ps(1.0));
                _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(c, _mm_set1_ps($max)), _mm_set1_ps(0.5)))
            }

            #[cfg(target_arch = "x86_64")]
            #[inline(always)]
            unsafe fn key8(z: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256i {
                use std::arch::x86_64::*;
                let c = _mm256_min_ps(_mm256_max_ps(z, _mm256_setzero_ps()), _mm256_set1_ps(1.0));
                _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(c, _mm256_set1_ps($max)), _mm256_set1_ps(0.5)))
            }
        }
    };
}

unorm_codec!(Unorm24, DepthFormat::Unorm24, 16_777_215.0);
unorm_codec!(Unorm16, DepthFormat::Unorm16, 65_535.0);

/// Calls `$f::<Codec>` ($args) for a run-time [`DepthFormat`]: the one place where a format
/// value becomes a codec type.
macro_rules! with_codec {
    ($fmt:expr, $f:ident::<_ $(, $rest:tt)*>($($args:expr),* $(,)?)) => {
        match $fmt {
            $crate::depth::DepthFormat::F32 => $f::<$crate::depth::F32 $(, $rest)*>($($args),*),
            $crate::depth::DepthFormat::Unorm24 => $f::<$crate::depth::Unorm24 $(, $rest)*>($($args),*),
            $crate::depth::DepthFormat::Unorm16 => $f::<$crate::depth::Unorm16 $(, $rest)*>($($args),*),
        }
    };
}
pub(crate) use with_codec;

/// [`DepthCodec::decode`] as a function, for [`with_codec!`].
#[inline(always)]
fn decode<D: DepthCodec>(key: u32) -> f32 {
    D::decode(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_preserve_order_and_round_trip() {
        for f in [DepthFormat::F32, DepthFormat::Unorm16, DepthFormat::Unorm24] {
            let mut last = 0;
            for i in 0..=1000 {
                let z = i as f32 / 1000.0;
                let k = f.key(z);
                assert!(k >= last, "{f:?} order broken at {z}");
                last = k;
                assert_eq!(f.key_of_stored(f.depth(k)), k, "{f:?} round trip at {z}");
            }
            assert_eq!(f.key(-0.0), f.key(0.0));
            assert_eq!(f.key(-5.0), f.key(0.0));
            assert_eq!(f.key(7.0), f.key(1.0));
            assert_eq!(f.key_of_stored(f32::NAN), f.key(1.0));
            assert_eq!(f.key(f32::NAN), NAN_KEY);
            assert!(f.key(1.0) < NAN_KEY);
        }
        assert_eq!(DepthFormat::Unorm16.key(1.0), 65535);
        assert_eq!(DepthFormat::Unorm16.key(0.5), 32768);
        // 16 bits cannot tell 1e-6 apart, f32 can.
        let (a, b) = (0.9, 0.9 + 1e-6);
        assert_eq!(DepthFormat::Unorm16.key(a), DepthFormat::Unorm16.key(b));
        assert!(DepthFormat::F32.key(a) < DepthFormat::F32.key(b));
    }

    fn codec_agrees<D: DepthCodec>() {
        let samples = [0.0, -0.0, 1e-30, 0.25, 0.5, 0.999_999_9, 1.0, 1.5, -2.0, f32::INFINITY, -f32::INFINITY];
        let nans = [f32::NAN, -f32::NAN, f32::from_bits(0x7fc0_0001), f32::from_bits(0xffff_ffff)];
        for &z in samples.iter().chain(&nans) {
            let k = D::key(z);
            if z.is_nan() {
                assert_eq!(k, NAN_KEY, "{:?} NaN {:#x}", D::FORMAT, z.to_bits());
            } else {
                assert!(k < NAN_KEY, "{:?} {z}", D::FORMAT);
            }
            if (0.0..=1.0).contains(&z) {
                assert_eq!(k, D::FORMAT.key(z), "{:?} {z}", D::FORMAT);
                assert_eq!(D::decode(k), D::FORMAT.depth(k));
            }
            // The vector keys are asked only for numbers (see `DepthCodec::key4`).
            #[cfg(target_arch = "x86_64")]
            if !z.is_nan() {
                use std::arch::x86_64::*;
                // SAFETY: SSE2 is baseline; AVX2 and AVX-512 only when detected (the
                // functions are then compiled for them).
                let k4 = unsafe {
                    let mut out = [0u32; 4];
                    _mm_storeu_si128(out.as_mut_ptr() as *mut __m128i, D::key4(_mm_set1_ps(z)));
                    out
                };
                assert_eq!(k4, [k; 4], "{:?} key4 {z}", D::FORMAT);
                if std::is_x86_feature_detected!("avx2") {
                    assert_eq!(unsafe { key8_avx2::<D>(z) }, [k; 8], "{:?} key8 {z}", D::FORMAT);
                }
                if std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512dq") {
                    assert_eq!(unsafe { key16_avx512::<D>(z) }, [k; 16], "{:?} key16 {z}", D::FORMAT);
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn key8_avx2<D: DepthCodec>(z: f32) -> [u32; 8] {
        use std::arch::x86_64::*;
        let mut out = [0u32; 8];
        _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, D::key8(_mm256_set1_ps(z)));
        out
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512dq,avx2")]
    unsafe fn key16_avx512<D: DepthCodec>(z: f32) -> [u32; 16] {
        use std::arch::x86_64::*;
        let mut out = [0u32; 16];
        _mm512_storeu_si512(out.as_mut_ptr() as *mut __m512i, D::key16(_mm512_set1_ps(z)));
        out
    }

    #[test]
    fn every_codec_gives_one_key_at_every_width_and_never_writes_nan() {
        codec_agrees::<F32>();
        codec_agrees::<Unorm24>();
        codec_agrees::<Unorm16>();
    }

    /// The refusal rule matches what the buffer does: at the largest accepted ratio (to the
    /// ulp) a point halfway to the far plane still stores below the far plane; 1% past it
    /// the projection is refused, and well past it the point does store as the far plane.
    #[test]
    fn depth_range_check_matches_what_the_format_stores() {
        use sightline_scene::Projection;
        let far = 1000.0f32;
        for f in [DepthFormat::F32, DepthFormat::Unorm24, DepthFormat::Unorm16] {
            let window_z =
                |near: f32, d: f32| (far as f64 * (d as f64 - near as f64)) / (d as f64 * (far - near) as f64);
            let persp = |near: f32| Projection::perspective(sightline_scene::Angle::degrees(60.0), 1.0, near, far);
            // The nearest plane accepted: (far − near) / near at the largest ratio, to the ulp.
            let mut edge = (far as f64 / (f.max_depth_ratio() + 1.0)) as f32;
            while f.check_resolves(&persp(edge).unwrap()).is_err() {
                edge = edge.next_up();
            }
            let ratio = (far as f64 - edge as f64) / edge as f64;
            assert!(ratio > f.max_depth_ratio() * 0.999_99, "{f:?}: accepted up to the largest ratio");
            assert!(f.key(window_z(edge, far / 2.0) as f32) < f.key(1.0), "{f:?}: halfway still resolves at the edge");
            // 1% past the largest ratio is refused.
            let past = (far as f64 / (f.max_depth_ratio() * 1.01 + 1.0)) as f32;
            assert!(matches!(f.check_resolves(&persp(past).unwrap()), Err(crate::Error::DepthRange { .. })), "{f:?}");
            let ok_near = (far as f64 / (f.max_depth_ratio() * 0.5)) as f32;
            let bad_near = ok_near / 64.0;
            let p = Projection::perspective(sightline_scene::Angle::degrees(60.0), 1.0, bad_near, far).unwrap();
            assert!(matches!(f.check_resolves(&p), Err(crate::Error::DepthRange { .. })), "{f:?} near {bad_near}");
            assert_eq!(f.key(window_z(bad_near, far / 2.0) as f32), f.key(1.0), "{f:?}: halfway rounds to far");
            let ortho = Projection::orthographic(-1.0, 1.0, -1.0, 1.0, 1e-9, far).unwrap();
            assert!(f.check_resolves(&ortho).is_ok(), "parallel depth is linear");
        }
    }
}

//! Colors as stored: linear RGBA in [0, 1] quantized to 8 bits per channel. Its own module
//! because everything that writes the color plane (shading, the sky, blending) needs it and
//! none of them should import another for it.

use glam::Vec4;

/// RGBA in [0, 1] to 8 bits per channel (clamped, rounded; NaN → 0).
#[inline]
pub fn to_rgba8(c: Vec4) -> [u8; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        to_rgba8_sse2(c)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        to_rgba8_scalar(c)
    }
}

/// [`to_rgba8`] one channel at a time: the definition.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline]
fn to_rgba8_scalar(c: Vec4) -> [u8; 4] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z), q(c.w)]
}

/// [`to_rgba8`] with the four channels in one register (SSE2, part of every x86-64): the
/// same operations, so the same bytes, without four saturating scalar conversions (a
/// quarter of flat shading's per-triangle work in a view of many small triangles). `maxps`
/// returns its second operand for a NaN first one, which maps NaN to 0 as the scalar
/// form's saturating cast does; after the clamp every value lies in [0.5, 255.5], where
/// truncation to an integer is the cast's.
#[cfg(target_arch = "x86_64")]
#[inline]
fn to_rgba8_sse2(c: Vec4) -> [u8; 4] {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of the x86-64 baseline.
    unsafe {
        let v = _mm_min_ps(_mm_max_ps(c.into(), _mm_setzero_ps()), _mm_set1_ps(1.0));
        let v = _mm_add_ps(_mm_mul_ps(v, _mm_set1_ps(255.0)), _mm_set1_ps(0.5));
        let i = _mm_cvttps_epi32(v);
        let b = _mm_packus_epi16(_mm_packs_epi32(i, i), _mm_setzero_si128());
        (_mm_cvtsi128_si32(b) as u32).to_ne_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vector form gives the scalar definition's bytes: every channel value in steps
    /// finer than a quantization level around [0, 1], the rounding boundaries, and the
    /// values outside (negative, above one, infinite, NaN, subnormal).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_vector_conversion_is_the_scalar_one() {
        let mut values: Vec<f32> = (-300..=1300).map(|k| k as f32 / 1000.0).collect();
        values.extend((0..=255).flat_map(|k| {
            let edge = (k as f32 + 0.5) / 255.0;
            [edge, f32::from_bits(edge.to_bits() - 1), f32::from_bits(edge.to_bits() + 1)]
        }));
        values.extend([0.0, -0.0, 1.0, f32::MIN_POSITIVE / 2.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e30]);
        for (k, &v) in values.iter().enumerate() {
            let w = values[(k * 7 + 3) % values.len()];
            let c = Vec4::new(v, w, 1.0 - v, 0.5 * v);
            assert_eq!(to_rgba8(c), to_rgba8_scalar(c), "{c:?}");
        }
    }

    #[test]
    fn quantizes_clamps_and_maps_nan_to_zero() {
        assert_eq!(to_rgba8(Vec4::new(0.0, 1.0, 0.5, 2.0)), [0, 255, 128, 255]);
        assert_eq!(to_rgba8(Vec4::new(-1.0, f32::NAN, 0.2, 1.0)), [0, 0, 51, 255]);
    }
}

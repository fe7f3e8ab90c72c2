//! Colors as stored: linear RGBA in [0, 1] quantized to 8 bits per channel. Its own module
//! because everything that writes the color plane (shading, the sky, blending) needs it and
//! none of them should import another for it.

use glam::Vec4;

/// RGBA in [0, 1] to 8 bits per channel (clamped, rounded; NaN → 0).
#[inline]
pub fn to_rgba8(c: Vec4) -> [u8; 4] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z), q(c.w)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantizes_clamps_and_maps_nan_to_zero() {
        assert_eq!(to_rgba8(Vec4::new(0.0, 1.0, 0.5, 2.0)), [0, 255, 128, 255]);
        assert_eq!(to_rgba8(Vec4::new(-1.0, f32::NAN, 0.2, 1.0)), [0, 0, 51, 255]);
    }
}

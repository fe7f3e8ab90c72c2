//! Depth formats and the integer keys the rasterizer compares.
//!
//! The z-buffer algorithm (Catmull 1974) keeps the nearest window depth per pixel and
//! accepts a fragment when its depth is LESS than the stored one. Window depth is
//! `z_w = (z_ndc + 1) / 2 ∈ [0, 1]`. Three storage formats are offered so the loss of depth
//! precision (z-fighting) can be shown: `f32`, and 16- and 24-bit unsigned integers holding
//! `round(z_w · (2^n − 1))`, like GL's fixed-point depth buffers.
//!
//! Inside the rasterizer every format is a `u32` *key* whose unsigned order equals depth
//! order: the integer value itself, or the bit pattern of a non-negative `f32` (IEEE 754
//! floats of one sign compare like their bit patterns). One comparison serves all formats.

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

    /// The key of window depth `z` (clamped to [0, 1]; NaN maps to the far plane).
    #[inline]
    pub fn key(self, z: f32) -> u32 {
        // `!(z > 0)` also catches NaN; `+ 0.0` turns −0.0 into +0.0 (whose bits are 0).
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
        match self.max_value() {
            None => f32::from_bits(key),
            Some(m) => key as f32 / m as f32,
        }
    }

    /// The window depth `z` as this format stores it (quantized for integer formats).
    #[inline]
    pub fn quantize(self, z: f32) -> f32 {
        self.depth(self.key(z))
    }
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
        }
        assert_eq!(DepthFormat::Unorm16.key(1.0), 65535);
        assert_eq!(DepthFormat::Unorm16.key(0.5), 32768);
        // 16 bits cannot tell 1e-6 apart, f32 can.
        let (a, b) = (0.9, 0.9 + 1e-6);
        assert_eq!(DepthFormat::Unorm16.key(a), DepthFormat::Unorm16.key(b));
        assert!(DepthFormat::F32.key(a) < DepthFormat::F32.key(b));
    }
}

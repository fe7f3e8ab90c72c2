//! Base color texture lookup: nearest and bilinear filtering, repeat and clamp addressing.
//!
//! Texel (i, j) covers `[i, i+1)/W × [j, j+1)/H` in UV space with v = 0 at the top row (the
//! glTF convention the scene's [`Texture`] uses). Bilinear filtering blends the four texels
//! whose centers surround the sample point (Heckbert, "Survey of Texture Mapping", 1986).

use glam::{Vec2, Vec4};
use serde::Serialize;
use sightline_scene::Texture;

/// Texture filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Filter {
    /// The texel containing the sample point.
    Nearest,
    /// Weighted blend of the four nearest texel centers.
    #[default]
    Bilinear,
}

/// What happens outside [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Wrap {
    /// Tile the texture.
    #[default]
    Repeat,
    /// Use the border texels.
    Clamp,
}

#[inline]
fn address(i: i64, n: u32, wrap: Wrap) -> u32 {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n as i64) as u32,
        Wrap::Clamp => i.clamp(0, n as i64 - 1) as u32,
    }
}

#[inline]
fn texel(t: &Texture, x: u32, y: u32) -> Vec4 {
    let c = t.texel(x, y);
    Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32) * (1.0 / 255.0)
}

/// Samples `t` at `uv`: RGBA in [0, 1]. Non-finite UVs read texel (0, 0). A texture that is
/// not well formed (made by hand with sizes that do not match its data) samples as white,
/// so the surface shows its base color alone.
pub fn sample(t: &Texture, uv: Vec2, filter: Filter, wrap: Wrap) -> Vec4 {
    if !t.is_well_formed() {
        return Vec4::ONE;
    }
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    // f32 → i64 casts saturate, so huge UVs cannot overflow.
    let (w, h) = (t.width, t.height);
    match filter {
        Filter::Nearest => {
            let x = address((uv.x * w as f32).floor() as i64, w, wrap);
            let y = address((uv.y * h as f32).floor() as i64, h, wrap);
            texel(t, x, y)
        }
        Filter::Bilinear => {
            let fx = uv.x * w as f32 - 0.5;
            let fy = uv.y * h as f32 - 0.5;
            let (x0, y0) = (fx.floor(), fy.floor());
            let (tx, ty) = (fx - x0, fy - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let (xa, xb) = (address(x0, w, wrap), address(x0.saturating_add(1), w, wrap));
            let (ya, yb) = (address(y0, h, wrap), address(y0.saturating_add(1), h, wrap));
            let top = texel(t, xa, ya).lerp(texel(t, xb, ya), tx);
            let bottom = texel(t, xa, yb).lerp(texel(t, xb, yb), tx);
            top.lerp(bottom, ty)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tex2x2() -> Texture {
        // Black, white / white, black.
        Texture::new(2, 2, vec![0, 0, 0, 255, 255, 255, 255, 255, 255, 255, 255, 255, 0, 0, 0, 255]).unwrap()
    }

    /// A texture made by hand with no texels, or fewer bytes than its size says, samples as
    /// white instead of panicking.
    #[test]
    fn a_malformed_texture_samples_as_white() {
        let empty = Texture { width: 0, height: 0, rgba: Vec::new() };
        let short = Texture { width: 4, height: 4, rgba: vec![0; 12] };
        // Sizes whose byte count overflows.
        let huge = Texture { width: u32::MAX, height: u32::MAX, rgba: vec![0; 16] };
        for t in [&empty, &short, &huge] {
            assert!(!t.is_well_formed());
            for f in [Filter::Nearest, Filter::Bilinear] {
                for w in [Wrap::Repeat, Wrap::Clamp] {
                    assert_eq!(sample(t, Vec2::new(0.7, 0.2), f, w), Vec4::ONE);
                }
            }
            assert_eq!(t.texel(3, 3), [0; 4]);
        }
        assert!(tex2x2().is_well_formed());
    }

    #[test]
    fn nearest_repeat_and_clamp() {
        let t = tex2x2();
        let s = |u, v, w| sample(&t, Vec2::new(u, v), Filter::Nearest, w).x;
        assert_eq!(s(0.25, 0.25, Wrap::Repeat), 0.0);
        assert_eq!(s(0.75, 0.25, Wrap::Repeat), 1.0);
        assert_eq!(s(1.25, 0.25, Wrap::Repeat), 0.0);
        assert_eq!(s(-0.25, 0.25, Wrap::Repeat), 1.0);
        assert_eq!(s(1.25, 0.25, Wrap::Clamp), 1.0);
        assert_eq!(s(-3.0, 0.25, Wrap::Clamp), 0.0);
        assert_eq!(s(f32::NAN, 1e30, Wrap::Repeat), s(0.0, 0.0, Wrap::Repeat));
    }

    #[test]
    fn bilinear_blends_between_centers() {
        let t = tex2x2();
        let s = |u, v, w| sample(&t, Vec2::new(u, v), Filter::Bilinear, w).x;
        assert!((s(0.5, 0.25, Wrap::Clamp) - 0.5).abs() < 1e-6);
        assert!((s(0.25, 0.25, Wrap::Clamp) - 0.0).abs() < 1e-6);
        assert!((s(0.5, 0.5, Wrap::Repeat) - 0.5).abs() < 1e-6);
        // Repeat blends across the border, clamp does not.
        assert!((s(0.0, 0.25, Wrap::Repeat) - 0.5).abs() < 1e-6);
        assert!((s(0.0, 0.25, Wrap::Clamp) - 0.0).abs() < 1e-6);
    }
}

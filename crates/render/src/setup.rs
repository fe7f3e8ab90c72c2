//! Viewport transform, sub-pixel snapping and triangle setup.
//!
//! After the divide, `x_w = (x_ndc + 1)/2 · W` and `y_w = (1 − y_ndc)/2 · H` (origin at the
//! top-left corner, y down). Coordinates are snapped to 8 fractional bits, round to nearest
//! even as llvmpipe's `lrintf` does; the GL-style y-up value is snapped first and flipped in
//! integers, so snapping matches a y-up rasterizer bit for bit. Pixel (i, j) has its center
//! at fixed-point `(256 i + 128, 256 j + 128)`.
//!
//! Setup computes the signed area of the snapped triangle (back faces and zero-area
//! triangles are dropped here), orients it so the edge functions of Pineda (1988) are
//! positive inside, finds the pixel-center bounding box clamped to the screen, and the depth
//! plane: window z is affine in screen space, so `z = z0 + zx·Δx + zy·Δy`.

use crate::clip;
use crate::edge::covers_any;
pub(crate) use crate::edge::{Tri, ONE, SUBPIXEL_BITS};

/// The guard band, in pixels beyond each side of the screen: triangles whose vertices stay
/// inside it are not clipped against x and y (their off-screen parts are skipped by the
/// clamped bounding box). 16384 px keeps snapped coordinates below 2^23 in magnitude and the
/// f32 window coordinates finer than 1/256 px before snapping.
pub const GUARD_BAND_PX: f32 = 16384.0;

/// Largest window coordinate magnitude [`Viewport::project`] accepts (pixels).
pub(crate) const PROJECT_LIMIT: f32 = GUARD_BAND_PX * 2.0 + 8192.0;

/// The viewport transform of one framebuffer size.
#[derive(Debug, Clone, Copy)]
pub struct Viewport {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    hw: f32,
    hh: f32,
    h_fixed: i32,
    /// Guard band in NDC x: clip against `|x| ≤ gx·w`.
    pub gx: f32,
    /// Guard band in NDC y.
    pub gy: f32,
}

impl Viewport {
    /// The viewport of a `width × height` target; `guard_band = false` clips x and y at the
    /// frustum itself.
    pub fn new(width: u32, height: u32, guard_band: bool) -> Self {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let (gx, gy) =
            if guard_band { (1.0 + 2.0 * GUARD_BAND_PX / w, 1.0 + 2.0 * GUARD_BAND_PX / h) } else { (1.0, 1.0) };
        Self { width, height, hw: w * 0.5, hh: h * 0.5, h_fixed: height as i32 * ONE, gx, gy }
    }

    /// Half width, half height and the height in fixed point (for vectorized projection).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    #[inline]
    pub(crate) fn scale(&self) -> (f32, f32, i32) {
        (self.hw, self.hh, self.h_fixed)
    }

    /// The outcode of a clip-space vertex for this viewport's guard band.
    #[inline]
    pub fn outcode(&self, c: glam::Vec4) -> u8 {
        clip::outcode(c, self.gx, self.gy)
    }

    /// Divide and viewport transform of a vertex inside the guard band (w > 0): snapped
    /// window x, y (fixed point, y down) and window z. `None` when the window position
    /// exceeds `PROJECT_LIMIT` (a margin beyond the guard band) or a result is not finite;
    /// callers treat that vertex as outside the guard band.
    #[inline]
    pub fn project(&self, c: glam::Vec4) -> Option<SnappedVertex> {
        // Same operation order as llvmpipe's draw module: x · (1/w) · scale + translate.
        let inv_w = 1.0 / c.w;
        let xw = c.x * inv_w * self.hw + self.hw;
        let yw = c.y * inv_w * self.hh + self.hh; // GL window y, up
        let zw = c.z * inv_w * 0.5 + 0.5;
        let lim = PROJECT_LIMIT;
        if !(xw.abs() <= lim && yw.abs() <= lim && zw.is_finite()) {
            return None;
        }
        Some(SnappedVertex { x: snap(xw), y: self.h_fixed - snap(yw), z: zw })
    }
}

/// A vertex after the viewport transform: fixed-point window position (y down) and depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SnappedVertex {
    /// Window x in 1/256 px.
    pub x: i32,
    /// Window y (down) in 1/256 px.
    pub y: i32,
    /// Window depth.
    pub z: f32,
}

/// Rounds `v · 256` to the nearest integer, ties to even (llvmpipe's `lrintf`).
#[inline]
pub fn snap(v: f32) -> i32 {
    let s = v * ONE as f32;
    #[cfg(target_arch = "x86_64")]
    {
        // cvtss2si rounds with the current mode, round-to-nearest-even unless changed: one
        // instruction, exactly lrintf. Out-of-range input (callers keep |s| far below 2^31)
        // gives i32::MIN, never undefined behavior.
        use std::arch::x86_64::{_mm_cvtss_si32, _mm_set_ss};
        // SAFETY: SSE is part of the x86_64 baseline.
        unsafe { _mm_cvtss_si32(_mm_set_ss(s)) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        // Adding and removing 1.5·2^52 leaves an f64 without fraction bits, rounded to
        // nearest even: exact for |s| < 2^51.
        const MAGIC: f64 = 6_755_399_441_055_744.0;
        ((s as f64 + MAGIC) - MAGIC) as i32
    }
}

/// What setup made of a triangle.
#[cfg(test)]
#[derive(Debug, Clone, Copy)]
pub(crate) enum Setup {
    /// A back face while culling is on.
    BackFace,
    /// Zero area after snapping.
    Degenerate,
    /// No pixel center inside.
    TooSmall,
    /// To be rasterized.
    Ready(Tri),
}

/// What setup made of a triangle, when a ready one went straight into the output list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// A back face while culling is on.
    BackFace,
    /// Zero area after snapping.
    Degenerate,
    /// No pixel center inside.
    TooSmall,
    /// Appended to the output.
    Ready,
}

/// Sets up a triangle from snapped vertices (see [`setup_into`]).
#[cfg(test)]
pub(crate) fn setup(v: [SnappedVertex; 3], id: u32, cull: bool, vp: &Viewport) -> Setup {
    let mut out = Vec::with_capacity(1);
    match setup_into(v, id, cull, vp, &mut out) {
        Outcome::BackFace => Setup::BackFace,
        Outcome::Degenerate => Setup::Degenerate,
        Outcome::TooSmall => Setup::TooSmall,
        Outcome::Ready => Setup::Ready(out[0]),
    }
}

/// Sets up a triangle from snapped vertices and appends it to `out` when it is to be
/// rasterized (written in place: no copy of the record per triangle). Front faces are
/// counter-clockwise in NDC, so in y-down window coordinates their signed area is
/// negative; `cull` drops the others.
#[inline(always)] // into the geometry loop: its vertices then stay in registers
pub fn setup_into(v: [SnappedVertex; 3], id: u32, cull: bool, vp: &Viewport, out: &mut Vec<Tri>) -> Outcome {
    let [a, b0, c0] = v;
    let area = (b0.x as i64 - a.x as i64) * (c0.y as i64 - a.y as i64)
        - (c0.x as i64 - a.x as i64) * (b0.y as i64 - a.y as i64);
    if area == 0 {
        return Outcome::Degenerate;
    }
    if cull && area > 0 {
        return Outcome::BackFace;
    }
    // The pixel-center box does not depend on the orientation: find it first, so that the
    // many triangles that cover no pixel center leave before the swap below.
    let (xmin, xmax) = (a.x.min(b0.x).min(c0.x), a.x.max(b0.x).max(c0.x));
    let (ymin, ymax) = (a.y.min(b0.y).min(c0.y), a.y.max(b0.y).max(c0.y));
    // Pixel centers 256 i + 128 inside [min, max].
    let half = ONE / 2;
    let px0 = ((xmin + half - 1) >> SUBPIXEL_BITS).max(0);
    let py0 = ((ymin + half - 1) >> SUBPIXEL_BITS).max(0);
    let px1 = ((xmax - half) >> SUBPIXEL_BITS).min(vp.width as i32 - 1);
    let py1 = ((ymax - half) >> SUBPIXEL_BITS).min(vp.height as i32 - 1);
    if px0 > px1 || py0 > py1 {
        return Outcome::TooSmall;
    }
    // Orient positively. Front and back faces come in random order, so swap with selects
    // (conditional moves) rather than a mispredicted branch.
    let swap = area < 0;
    let pick = |p: i32, q: i32| if swap { q } else { p };
    let pickf = |p: f32, q: f32| if swap { q } else { p };
    let b = SnappedVertex { x: pick(b0.x, c0.x), y: pick(b0.y, c0.y), z: pickf(b0.z, c0.z) };
    let c = SnappedVertex { x: pick(c0.x, b0.x), y: pick(c0.y, b0.y), z: pickf(c0.z, b0.z) };
    let area = area.abs();
    let bbox = [px0 as u16, py0 as u16, px1 as u16, py1 as u16];
    let zmin = a.z.min(b.z).min(c.z);
    let tri = |zx, zy| Tri { x: [a.x, b.x, c.x], y: [a.y, b.y, c.y], z0: a.z, zx, zy, zmin, id, bbox, multi: u32::MAX };
    // Tiny boxes: decide coverage now, before the triangle costs a depth plane, binning and
    // a tile visit.
    if (px1 - px0 + 1) * (py1 - py0 + 1) <= 4 && !covers_any(&tri(0.0, 0.0)) {
        return Outcome::TooSmall;
    }
    // Depth plane through the snapped vertices, in f64 once per triangle.
    let (dx1, dy1) = ((b.x - a.x) as f64, (b.y - a.y) as f64);
    let (dx2, dy2) = ((c.x - a.x) as f64, (c.y - a.y) as f64);
    let (dz1, dz2) = ((b.z - a.z) as f64, (c.z - a.z) as f64);
    let inv = 1.0 / area as f64;
    out.push(tri(((dz1 * dy2 - dz2 * dy1) * inv) as f32, ((dx1 * dz2 - dx2 * dz1) * inv) as f32));
    Outcome::Ready
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapping_rounds_half_to_even() {
        assert_eq!(snap(0.5 / 256.0), 0);
        assert_eq!(snap(1.5 / 256.0), 2);
        assert_eq!(snap(-0.5 / 256.0), 0);
        assert_eq!(snap(3.0), 768);
        assert_eq!(snap(0.3 / 256.0), 0);
        assert_eq!(snap(0.7 / 256.0), 1);
    }

    #[test]
    fn viewport_maps_ndc_corners_top_left() {
        let vp = Viewport::new(8, 4, true);
        let tl = vp.project(glam::Vec4::new(-1.0, 1.0, -1.0, 1.0)).unwrap();
        assert_eq!((tl.x, tl.y, tl.z), (0, 0, 0.0));
        let br = vp.project(glam::Vec4::new(2.0, -2.0, 2.0, 2.0)).unwrap();
        assert_eq!((br.x, br.y, br.z), (8 * 256, 4 * 256, 1.0));
    }

    /// The steepest plane set-up can make (depth 0 to 1 across a sliver of area one unit,
    /// vertices at the projection limit) is far inside what the vector kernels take
    /// ([`crate::edge::Tri::depths_are_numbers`]).
    #[test]
    fn set_up_planes_give_numbers_everywhere() {
        let vp = Viewport::new(1280, 720, true);
        let l = (PROJECT_LIMIT * 256.0) as i32;
        let v = |x: i32, y: i32, z: f32| SnappedVertex { x, y, z };
        let sliver = [v(-l, -l, 0.0), v(l, l - 1, 1.0), v(l - 1, l - 2, 0.0)];
        let Setup::Ready(t) = setup(sliver, 1, false, &vp) else { panic!("the sliver crosses the screen") };
        assert!(t.zx.abs().max(t.zy.abs()) > 1e7, "{t:?}");
        assert!(t.depths_are_numbers(), "{t:?}");
    }

    #[test]
    fn setup_culls_orients_and_finds_the_box() {
        let vp = Viewport::new(16, 16, true);
        let v = |x: f32, y: f32| SnappedVertex { x: (x * 256.0) as i32, y: (y * 256.0) as i32, z: 0.5 };
        // Counter-clockwise on screen with y up = clockwise in y-down numbers: a front face.
        let front = [v(1.0, 1.0), v(1.0, 9.0), v(9.0, 1.0)];
        let Setup::Ready(t) = setup(front, 7, true, &vp) else { panic!("front face must survive") };
        assert_eq!(t.bbox, [1, 1, 8, 8]);
        assert!(matches!(setup([front[0], front[2], front[1]], 7, true, &vp), Setup::BackFace));
        assert!(matches!(setup([front[0], front[2], front[1]], 7, false, &vp), Setup::Ready(_)));
        assert!(matches!(setup([v(1.0, 1.0), v(2.0, 2.0), v(3.0, 3.0)], 1, false, &vp), Setup::Degenerate));
        // Between pixel centers: nothing covered.
        assert!(matches!(setup([v(1.6, 1.6), v(1.6, 2.4), v(2.4, 1.6)], 1, false, &vp), Setup::TooSmall));
    }
}

//! Compositing: Porter & Duff's "over" (back to front) and its front-to-back form, "under".
//!
//! Porter & Duff, "Compositing Digital Images", SIGGRAPH 1984: a fragment of color `C` and
//! coverage (alpha) `α` over what lies behind it, `D`, gives `α·C + (1 − α)·D`. Applied
//! back to front over the opaque color this is the A-buffer's resolve. Front to back, the
//! same sum is accumulated as `acc += T·α·C`, `T ← T·(1 − α)` with the transmittance `T`
//! starting at 1, and the opaque color is added last as `acc + T·D` ("under", the order
//! depth peeling produces its layers in; Everitt 2001). The two orders differ only by float
//! rounding, far below one step of an 8-bit channel.
//!
//! Fragment colors are not premultiplied (what shading writes: RGB and alpha). The color
//! plane is treated as opaque color with its own alpha channel, composited by the same
//! operator (the alpha channel becomes `α + (1 − α)·A`).

use glam::Vec4;

use crate::color::to_rgba8;

/// An RGBA8 color in [0, 1].
#[inline]
pub(crate) fn unit(c: [u8; 4]) -> Vec4 {
    Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32) * (1.0 / 255.0)
}

/// The fragment `src` (RGBA8, alpha its coverage) over `dst`.
#[inline]
pub(crate) fn over(src: [u8; 4], dst: Vec4) -> Vec4 {
    let s = unit(src);
    let a = s.w;
    s.with_w(1.0) * a + dst * (1.0 - a)
}

/// Front-to-back accumulation of fragments, nearest first.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Under {
    /// The premultiplied sum so far (alpha in `w`).
    acc: Vec4,
    /// What still shows through.
    transmittance: f32,
}

impl Default for Under {
    fn default() -> Self {
        Self { acc: Vec4::ZERO, transmittance: 1.0 }
    }
}

impl Under {
    /// Adds the next fragment behind those added so far.
    #[inline]
    pub fn add(&mut self, src: [u8; 4]) {
        let s = unit(src);
        self.acc += s.with_w(1.0) * (self.transmittance * s.w);
        self.transmittance *= 1.0 - s.w;
    }

    /// The accumulated fragments over the opaque color `dst`, as RGBA8.
    #[inline]
    pub fn resolve(&self, dst: [u8; 4]) -> [u8; 4] {
        to_rgba8(self.acc + unit(dst) * self.transmittance)
    }
}

/// Fragments `back_to_front` (farthest first) over `dst`, as RGBA8.
pub(crate) fn over_all(back_to_front: impl Iterator<Item = [u8; 4]>, dst: [u8; 4]) -> [u8; 4] {
    to_rgba8(back_to_front.fold(unit(dst), |d, s| over(s, d)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn over_and_under_agree() {
        let frags = [[200, 10, 10, 51], [10, 200, 10, 102], [10, 10, 200, 204], [90, 90, 90, 255], [1, 2, 3, 0]];
        for dst in [[0, 0, 0, 255], [158, 194, 235, 255], [255, 255, 255, 0]] {
            for n in 0..=frags.len() {
                let f = &frags[..n];
                let back = over_all(f.iter().rev().copied(), dst);
                let mut u = Under::default();
                f.iter().for_each(|&c| u.add(c));
                let front = u.resolve(dst);
                for k in 0..4 {
                    assert!(back[k].abs_diff(front[k]) <= 1, "{n} fragments over {dst:?}: {back:?} vs {front:?}");
                }
            }
        }
        // By hand: half-covering red (alpha 0.4) over black.
        assert_eq!(over_all([[255, 0, 0, 102]].into_iter(), [0, 0, 0, 255]), [102, 0, 0, 255]);
        // An opaque fragment hides what lies behind it.
        assert_eq!(over_all([[9, 8, 7, 255]].into_iter(), [100, 100, 100, 255]), [9, 8, 7, 255]);
    }
}

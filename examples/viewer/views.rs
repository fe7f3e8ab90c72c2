//! The pictures the viewer shows, written straight into the window's buffer of 0RGB words
//! in one pass over the framebuffer:
//!
//! * `color`: the shaded frame (with the wireframe drawn over it when on);
//! * `depth`: window depth as gray, the range actually drawn stretched to black (near) …
//!   light gray (far), background white;
//! * `ids`: each triangle ID as its own hashed colour, background black;
//! * `complexity`: depth tests per pixel as a heat map scaled to the frame's maximum (black:
//!   none, then blue, cyan, green, yellow, red);
//! * `culling`: the frame darkened, with every cluster's box drawn in the colour of its
//!   class — outside the view, hidden by the frame's depth, visible (see
//!   `Engine::classify_clusters`);
//! * `hzb`: one level of Greene's max-depth pyramid over the frame's depth, each texel
//!   covering its 2^k × 2^k pixels, gray as in `depth`.

use crate::engine::{heat_color, id_color, Framebuffer, LevelImage};

/// A picture of the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum View {
    /// The shaded frame
    Color,
    /// Window depth as gray
    Depth,
    /// Triangle IDs in hashed colours
    Ids,
    /// Depth tests per pixel as a heat map
    Complexity,
    /// Cluster boxes: outside the view (blue), hidden (red), visible (green)
    Culling,
    /// A level of the z-pyramid (+/- choose it)
    Hzb,
}

impl View {
    const ALL: [View; 6] = [View::Color, View::Depth, View::Ids, View::Complexity, View::Culling, View::Hzb];

    pub fn name(self) -> &'static str {
        match self {
            View::Color => "color",
            View::Depth => "depth",
            View::Ids => "ids",
            View::Complexity => "complexity",
            View::Culling => "culling",
            View::Hzb => "hzb level",
        }
    }

    /// The next view (`by` = 1) or the previous one (`by` = -1).
    pub fn step(self, by: i32) -> View {
        let n = View::ALL.len() as i32;
        let i = View::ALL.iter().position(|v| *v == self).unwrap_or(0) as i32;
        View::ALL[(i + by).rem_euclid(n) as usize]
    }
}

/// An opaque colour as a 0RGB word.
#[inline]
pub fn pack(c: [u8; 4]) -> u32 {
    (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32
}

#[inline]
fn gray(g: u8) -> u32 {
    pack([g, g, g, 255])
}

/// Gray for a depth: `lo` … `hi` → 0 … 230, background (1.0) white.
#[inline]
fn depth_gray(d: f32, lo: f32, span: f32) -> u32 {
    if d < 1.0 {
        gray(((d - lo) / span * 230.0).clamp(0.0, 230.0) as u8)
    } else {
        gray(255)
    }
}

/// The range of depths below 1.0 (lo, hi − lo), or (0, 1) when nothing was drawn.
fn depth_range(depth: &[f32]) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for &d in depth.iter().filter(|d| **d < 1.0) {
        lo = lo.min(d);
        hi = hi.max(d);
    }
    if hi > lo {
        (lo, hi - lo)
    } else {
        (0.0, 1.0)
    }
}

/// Writes `view` of `fb` into `out` (the window's buffer, `fb`'s size); `level` is the
/// z-pyramid level for the hzb view.
pub fn compose(view: View, fb: &Framebuffer, level: Option<&LevelImage>, out: &mut [u32]) {
    let n = fb.len().min(out.len());
    let out = &mut out[..n];
    match view {
        View::Color | View::Culling => {
            for (o, c) in out.iter_mut().zip(&fb.color) {
                *o = pack(*c);
            }
        }
        View::Depth => {
            let (lo, span) = depth_range(&fb.depth);
            for (o, d) in out.iter_mut().zip(&fb.depth) {
                *o = depth_gray(*d, lo, span);
            }
        }
        View::Ids => {
            for (o, id) in out.iter_mut().zip(&fb.ids) {
                *o = pack(id_color(*id));
            }
        }
        View::Complexity => match &fb.depth_tests {
            Some(counts) => {
                let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
                for (o, c) in out.iter_mut().zip(counts) {
                    *o = pack(heat_color(*c as f32 / max));
                }
            }
            None => out.fill(0),
        },
        View::Hzb => match level {
            Some(l) if l.width > 0 && l.height > 0 => {
                let (lo, span) = depth_range(&l.texels);
                let w = fb.width() as usize;
                for (y, row) in out.chunks_mut(w).enumerate() {
                    let ly = (y >> l.level).min(l.height as usize - 1);
                    let texels = &l.texels[ly * l.width as usize..][..l.width as usize];
                    for (x, o) in row.iter_mut().enumerate() {
                        *o = depth_gray(texels[(x >> l.level).min(l.width as usize - 1)], lo, span);
                    }
                }
            }
            _ => out.fill(0),
        },
    }
}

/// Darkens the frame's colour to a third, under the culling view's boxes.
pub fn dim(fb: &mut Framebuffer) {
    for c in &mut fb.color {
        *c = [c[0] / 3, c[1] / 3, c[2] / 3, c[3]];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_map_the_planes() {
        let mut fb = Framebuffer::new(4, 2).unwrap();
        fb.color[1] = [10, 20, 30, 255];
        fb.depth[0] = 0.25;
        fb.depth[1] = 0.75;
        fb.ids[2] = 7;
        let mut out = vec![0u32; 8];
        compose(View::Color, &fb, None, &mut out);
        assert_eq!(out[1], 0x000a141e);
        compose(View::Depth, &fb, None, &mut out);
        assert_eq!((out[0], out[1], out[2]), (0, gray(230), gray(255)), "near black, far gray, background white");
        compose(View::Ids, &fb, None, &mut out);
        assert_eq!((out[0], out[2]), (0, pack(id_color(7))));
        assert_ne!(out[2], 0);
        let level = LevelImage { level: 1, levels: 3, width: 2, height: 1, texels: vec![0.2, 0.6] };
        compose(View::Hzb, &fb, Some(&level), &mut out);
        assert_eq!(&out[..4], &[0, 0, gray(230), gray(230)], "each texel covers 2 × 2 pixels");
        assert_eq!(&out[4..], &out[..4].to_vec()[..]);
        assert_eq!(View::Color.step(-1), View::Hzb);
        assert_eq!(View::Hzb.step(1), View::Color);
    }
}

//! Supersampling antialiasing: render at s×s samples per pixel on an ordered grid, then
//! average them with a box filter (Crow 1981; Foley et al. §14.10).
//!
//! A frame rendered at `(s·W) × (s·H)` has its sample centers exactly on the ordered grid
//! `((i + (k + 0.5)/s), (j + (l + 0.5)/s))` of the target pixels, so the ordinary
//! rasterizer does the sampling. The resolve averages colors; depth and ID come from the
//! nearest sample (the first one on ties), and depth-test counts are summed.

use rayon::prelude::*;

use crate::Framebuffer;

/// A `width × height` frame drawn at `s × s` samples per pixel: `draw` renders into a
/// framebuffer `s` times larger on each side (with the same camera, since the aspect is the
/// same), which is then box-filtered down with [`resolve`]. This is how pictures are
/// supersampled whatever draws them (rasterizer, culler, ray caster). The result's IDs and
/// depth are each pixel's nearest sample, not a one-sample frame's: count and compare on a
/// frame drawn at one sample per pixel. `s` ≤ 1 draws the frame as it is.
pub fn supersample<E: From<crate::Error>>(
    width: u32,
    height: u32,
    s: u32,
    draw: impl FnOnce(&mut Framebuffer) -> Result<(), E>,
) -> Result<Framebuffer, E> {
    let s = s.max(1);
    // An overflowing side becomes too large a framebuffer, refused by `Framebuffer::new`.
    let mut big = Framebuffer::new(width.saturating_mul(s), height.saturating_mul(s))?;
    draw(&mut big)?;
    if s == 1 {
        return Ok(big);
    }
    let mut out = Framebuffer::new(width, height)?;
    resolve(&big, s, &mut out);
    Ok(out)
}

/// Box-filters `ss` (s times larger on each side) into `out`.
pub fn resolve(ss: &Framebuffer, s: u32, out: &mut Framebuffer) {
    let (w, h) = (out.width() as usize, out.height() as usize);
    let s = s as usize;
    if ss.width() as usize != w * s || ss.height() as usize != h * s || s == 0 {
        return;
    }
    let sw = w * s;
    let n = (s * s) as u32;
    let rows = out.color.par_chunks_mut(w).zip(out.depth.par_chunks_mut(w)).zip(out.ids.par_chunks_mut(w));
    rows.enumerate().for_each(|(y, ((color, depth), ids))| {
        for x in 0..w {
            let mut sum = [0u32; 4];
            let first = y * s * sw + x * s;
            let mut best = (ss.depth[first], ss.ids[first]);
            for sy in 0..s {
                let row = (y * s + sy) * sw + x * s;
                for i in row..row + s {
                    let c = ss.color[i];
                    for k in 0..4 {
                        sum[k] += c[k] as u32;
                    }
                    let d = ss.depth[i];
                    if d < best.0 {
                        best = (d, ss.ids[i]);
                    }
                }
            }
            color[x] = sum.map(|v| ((v + n / 2) / n) as u8);
            depth[x] = best.0;
            ids[x] = best.1;
        }
    });
    if let (Some(dst), Some(src)) = (&mut out.depth_tests, &ss.depth_tests) {
        dst.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                *v = (0..s)
                    .flat_map(|sy| {
                        let base = (y * s + sy) * sw + x * s;
                        src[base..base + s].iter()
                    })
                    .sum();
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_colors_and_keeps_the_nearest_sample() {
        let mut ss = Framebuffer::new(4, 2).unwrap();
        let mut out = Framebuffer::new(2, 1).unwrap();
        ss.color = vec![[0, 0, 0, 255]; 8].into();
        ss.color[0] = [255, 255, 255, 255];
        ss.color[1] = [255, 255, 255, 255];
        ss.depth[6] = 0.25; // row 1, column 2: output pixel 1
        ss.ids[6] = 9;
        resolve(&ss, 2, &mut out);
        assert_eq!(out.color[0], [128, 128, 128, 255]);
        assert_eq!(out.color[1], [0, 0, 0, 255]);
        assert_eq!((out.depth[1], out.ids[1]), (0.25, 9));
        assert_eq!((out.depth[0], out.ids[0]), (1.0, 0));
    }

    #[test]
    fn supersample_draws_large_and_resolves() {
        let fb = supersample(3, 2, 2, |big| {
            assert_eq!((big.width(), big.height()), (6, 4));
            big.color = (0..24).map(|i| if i % 2 == 0 { [200, 0, 0, 255] } else { [0, 0, 100, 255] }).collect();
            Ok::<(), crate::Error>(())
        })
        .unwrap();
        assert_eq!((fb.width(), fb.height()), (3, 2));
        assert!(fb.color.iter().all(|&c| c == [100, 0, 50, 255]));
        assert!(supersample(8192, 8, 2, |_| Ok::<(), crate::Error>(())).is_err(), "too large is an error");
    }
}

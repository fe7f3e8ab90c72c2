//! The walk as an animated GIF: each frame shrunk to the GIF's width by averaging the
//! pixels each GIF pixel covers (a box filter: no aliasing shimmer on the facades, unlike
//! picking one pixel), the readout burned in at that size so it stays legible, then reduced
//! to its own 256-colour palette by NeuQuant (Dekker 1994, "Kohonen neural networks for
//! optimal colour quantization"; the `gif` crate's quantizer) and LZW-compressed. Frames
//! are written as they come, so the walk is never held in memory.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};

/// An animated GIF being written.
pub struct GifOut {
    encoder: gif::Encoder<BufWriter<File>>,
    width: u32,
    height: u32,
    /// Hundredths of a second per frame.
    delay: u16,
    pub frames: usize,
}

impl GifOut {
    /// Starts `path` for frames of `src_w × src_h` shrunk to at most `max_width` wide,
    /// `delay` hundredths of a second each, looping forever.
    pub fn create(path: &Path, src_w: u32, src_h: u32, max_width: u32, delay: u16) -> Result<GifOut> {
        let (width, height) = fit(src_w, src_h, max_width);
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut encoder = gif::Encoder::new(BufWriter::new(file), width as u16, height as u16, &[])
            .with_context(|| format!("writing {}", path.display()))?;
        encoder.set_repeat(gif::Repeat::Infinite).context("writing the GIF header")?;
        Ok(GifOut { encoder, width, height, delay, frames: 0 })
    }

    /// Shrinks an RGBA frame of `src_w × src_h` to the GIF's size, lets `overlay` draw on
    /// it (the readout), and appends it.
    pub fn push(
        &mut self,
        rgba: &[[u8; 4]],
        src_w: u32,
        src_h: u32,
        overlay: impl FnOnce(&mut [[u8; 4]], u32, u32),
    ) -> Result<()> {
        let mut small = shrink(rgba, src_w, src_h, self.width, self.height);
        overlay(&mut small, self.width, self.height);
        let mut bytes: Vec<u8> = small.into_iter().flatten().collect();
        // Speed 10: the quantizer's usual trade of quality for time (1 is slowest, 30 fastest).
        let mut frame = gif::Frame::from_rgba_speed(self.width as u16, self.height as u16, &mut bytes, 10);
        frame.delay = self.delay;
        self.encoder.write_frame(&frame).context("writing a GIF frame")?;
        self.frames += 1;
        Ok(())
    }
}

/// The size of a `w × h` picture shrunk to at most `max_width` wide (never enlarged).
pub fn fit(w: u32, h: u32, max_width: u32) -> (u32, u32) {
    if w <= max_width.max(1) {
        return (w.min(u16::MAX as u32), h.min(u16::MAX as u32));
    }
    let nw = max_width.max(1);
    let nh = ((h as u64 * nw as u64 + w as u64 / 2) / w as u64).max(1) as u32;
    (nw, nh)
}

/// Box-filter shrink: each output pixel is the mean of the source pixels whose index range
/// `[i·src/dst, (i+1)·src/dst)` it covers, on both axes.
pub fn shrink(src: &[[u8; 4]], sw: u32, sh: u32, dw: u32, dh: u32) -> Vec<[u8; 4]> {
    if (sw, sh) == (dw, dh) {
        return src.to_vec();
    }
    let span = |i: u32, s: u32, d: u32| {
        let a = (i as u64 * s as u64 / d as u64) as u32;
        let b = (((i + 1) as u64 * s as u64 / d as u64) as u32).max(a + 1).min(s);
        a..b
    };
    let mut out = Vec::with_capacity(dw as usize * dh as usize);
    for y in 0..dh {
        let ys = span(y, sh, dh);
        for x in 0..dw {
            let xs = span(x, sw, dw);
            let mut acc = [0u32; 4];
            for sy in ys.clone() {
                for p in &src[(sy * sw + xs.start) as usize..(sy * sw + xs.end) as usize] {
                    for (a, c) in acc.iter_mut().zip(p) {
                        *a += *c as u32;
                    }
                }
            }
            let n = ys.len() as u32 * xs.len() as u32;
            out.push(acc.map(|a| ((a + n / 2) / n) as u8));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shrinking_averages_and_keeps_the_aspect() {
        assert_eq!(fit(1280, 720, 480), (480, 270));
        assert_eq!(fit(320, 180, 480), (320, 180), "never enlarged");
        // A 4 × 2 checkerboard of black and white columns shrinks to mid-gray.
        let src: Vec<[u8; 4]> =
            (0..8).map(|i| if i % 2 == 0 { [0, 0, 0, 255] } else { [255, 255, 255, 255] }).collect();
        assert_eq!(shrink(&src, 4, 2, 2, 1), vec![[128, 128, 128, 255]; 2]);
        assert_eq!(shrink(&src, 4, 2, 4, 2), src);
    }
}

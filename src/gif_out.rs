//! Walks as animated GIFs: each frame shrunk to the GIF's width by averaging the pixels each
//! GIF pixel covers (a box filter: no aliasing shimmer on the facades, unlike picking one
//! pixel), a readout burned in at that size so it stays legible, then reduced to its own
//! 256-colour palette by NeuQuant (Dekker, "Kohonen neural networks for optimal colour
//! quantization", Network: Computation in Neural Systems, 1994; the `gif` crate's quantizer)
//! and LZW-compressed. Frames are written as they come, so a walk is never held in memory.
//!
//! [`GifOut::append_gif`] copies the frames of another GIF written here (palette, indices and
//! delay as they are, nothing re-quantized): `sightline merge` joins the GIFs of the shards of
//! a walk into the one a single run writes.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A GIF that could not be written or read.
#[derive(Debug, thiserror::Error)]
#[error("{}: {why}", path.display())]
pub struct GifError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub why: String,
}

fn err(path: &Path, why: impl std::fmt::Display) -> GifError {
    GifError { path: path.to_path_buf(), why: why.to_string() }
}

/// Frames of a walk shown at 30 frames a second: the GIF keeps every `every`-th so that it
/// holds about 60 frames.
pub fn every_for(frames: usize) -> usize {
    frames.div_ceil(60).max(1)
}

/// Hundredths of a second per GIF frame when it keeps every `every`-th frame of a walk shown
/// at 30 frames a second (at least 2: viewers slow down shorter delays).
pub fn delay_for(every: usize) -> u16 {
    ((every as f64 * 100.0 / 30.0).round().min(u16::MAX as f64) as u16).max(2)
}

/// An animated GIF being written.
pub struct GifOut {
    encoder: gif::Encoder<BufWriter<File>>,
    path: PathBuf,
    width: u32,
    height: u32,
    /// Hundredths of a second per frame.
    delay: u16,
    /// Frames written so far.
    pub frames: usize,
}

impl GifOut {
    /// Starts `path` for frames of `src_w × src_h` shrunk to at most `max_width` wide,
    /// `delay` hundredths of a second each, looping forever.
    pub fn create(path: &Path, src_w: u32, src_h: u32, max_width: u32, delay: u16) -> Result<GifOut, GifError> {
        let (width, height) = fit(src_w, src_h, max_width);
        let file = File::create(path).map_err(|e| err(path, format!("cannot create: {e}")))?;
        let mut encoder =
            gif::Encoder::new(BufWriter::new(file), width as u16, height as u16, &[]).map_err(|e| err(path, e))?;
        encoder.set_repeat(gif::Repeat::Infinite).map_err(|e| err(path, e))?;
        Ok(GifOut { encoder, path: path.to_path_buf(), width, height, delay, frames: 0 })
    }

    /// The GIF's size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Shrinks an RGBA frame of `src_w × src_h` to the GIF's size, lets `overlay` draw on
    /// it (the readout), and appends it.
    pub fn push(
        &mut self,
        rgba: &[[u8; 4]],
        src_w: u32,
        src_h: u32,
        overlay: impl FnOnce(&mut [[u8; 4]], u32, u32),
    ) -> Result<(), GifError> {
        let mut small = shrink(rgba, src_w, src_h, self.width, self.height);
        overlay(&mut small, self.width, self.height);
        let mut bytes: Vec<u8> = small.into_iter().flatten().collect();
        // Speed 10: the quantizer's usual trade of quality for time (1 is slowest, 30 fastest).
        let mut frame = gif::Frame::from_rgba_speed(self.width as u16, self.height as u16, &mut bytes, 10);
        frame.delay = self.delay;
        self.encoder.write_frame(&frame).map_err(|e| err(&self.path, e))?;
        self.frames += 1;
        Ok(())
    }

    /// Appends every frame of the GIF at `path` as it is (its own palette and delay); the
    /// frames must have this GIF's size. Returns how many were appended.
    pub fn append_gif(&mut self, path: &Path) -> Result<usize, GifError> {
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::Indexed);
        let file = sightline_scene::assets::open_regular_file(path).map_err(|why| err(path, why))?;
        let mut d = opts.read_info(std::io::BufReader::new(file)).map_err(|e| err(path, e))?;
        let mut n = 0;
        while let Some(frame) = d.read_next_frame().map_err(|e| err(path, e))? {
            if (frame.width as u32, frame.height as u32) != (self.width, self.height) || frame.palette.is_none() {
                return Err(err(
                    path,
                    format!(
                        "frame {n} is {}x{} with {} palette; {} is {}x{} with a palette per frame",
                        frame.width,
                        frame.height,
                        if frame.palette.is_some() { "its own" } else { "no" },
                        self.path.display(),
                        self.width,
                        self.height
                    ),
                ));
            }
            self.encoder.write_frame(frame).map_err(|e| err(&self.path, e))?;
            self.frames += 1;
            n += 1;
        }
        Ok(n)
    }
}

/// The size of a `w × h` picture shrunk, keeping its aspect, to at most `max_width` wide and
/// at most 65,535 pixels a side (a GIF's limit); never enlarged.
pub fn fit(w: u32, h: u32, max_width: u32) -> (u32, u32) {
    const SIDE: u64 = u16::MAX as u64;
    let (w, h) = (w as u64, h as u64);
    let nw = w.min(max_width.max(1) as u64).min(SIDE);
    let mut size = if nw == w { (w, h) } else { (nw, ((h * nw + w / 2) / w).max(1)) };
    if size.1 > SIDE {
        size = (((w * SIDE + h / 2) / h).max(1), SIDE);
    }
    (size.0 as u32, size.1 as u32)
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
        // No side past a GIF's limit, the aspect kept.
        assert_eq!(fit(100, 200_000, 480), (33, 65_535));
        assert_eq!(fit(481, u32::MAX, 480), (1, 65_535));
        assert_eq!(fit(8192, 8192, 480), (480, 480));
        // A 4 × 2 checkerboard of black and white columns shrinks to mid-gray.
        let src: Vec<[u8; 4]> =
            (0..8).map(|i| if i % 2 == 0 { [0, 0, 0, 255] } else { [255, 255, 255, 255] }).collect();
        assert_eq!(shrink(&src, 4, 2, 2, 1), vec![[128, 128, 128, 255]; 2]);
        assert_eq!(shrink(&src, 4, 2, 4, 2), src);
    }

    #[test]
    fn appended_frames_are_copied_as_they_are() {
        let dir = std::env::temp_dir().join(format!("sightline-gif-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.gif"), dir.join("b.gif"));
        let mut one = GifOut::create(&a, 8, 4, 480, 5).unwrap();
        for k in 0..3u8 {
            let px: Vec<[u8; 4]> = (0..32).map(|i| [i as u8 * 8, 40 * k, 200, 255]).collect();
            one.push(&px, 8, 4, |_, _, _| {}).unwrap();
        }
        drop(one);
        let mut two = GifOut::create(&b, 8, 4, 480, 5).unwrap();
        assert_eq!(two.append_gif(&a).unwrap(), 3);
        drop(two);
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "nothing re-quantized");
        let mut wrong = GifOut::create(&b, 4, 4, 480, 5).unwrap();
        assert!(wrong.append_gif(&a).unwrap_err().to_string().contains("8x4"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A FIFO named as a GIF to append is refused, and neither the open nor the reads block.
    #[cfg(unix)]
    #[test]
    fn a_fifo_is_not_appended() {
        let dir = std::env::temp_dir().join(format!("sightline-gif-fifo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("walk.gif");
        if !std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            eprintln!("skipped: cannot make a FIFO with mkfifo");
            return;
        }
        let out = dir.join("out.gif");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut gif = GifOut::create(&out, 8, 4, 480, 5).unwrap();
            let _ = tx.send(gif.append_gif(&fifo).map_err(|e| e.to_string()));
        });
        let why = rx.recv_timeout(std::time::Duration::from_secs(30)).expect("appending a FIFO blocked");
        let _ = std::fs::remove_dir_all(&dir);
        let why = why.unwrap_err();
        assert!(why.contains("walk.gif") && why.contains("not a regular file"), "{why}");
    }
}

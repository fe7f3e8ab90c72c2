//! Pictures and raw buffers: PNG images of color, depth (grayscale), triangle IDs (false
//! color) and depth complexity (heat map), and NumPy `.npy` files of IDs and depth.
//!
//! NPY format version 1.0 (numpy.org, "A simple file format for NumPy arrays"): magic
//! `\x93NUMPY`, version 1.0, a little-endian u16 header length, an ASCII dict header padded
//! with spaces and a newline to a multiple of 64 bytes, then the raw little-endian data in
//! C order. Arrays are H × W, row 0 at the top, like the references' ID buffers.

use std::path::Path;

use crate::{Error, Framebuffer, Result};

fn out_err(path: &Path, why: impl ToString) -> Error {
    Error::Output { path: path.display().to_string(), why: why.to_string() }
}

fn save_rgba(path: &Path, w: u32, h: u32, rgba: Vec<u8>) -> Result<()> {
    let img = image::RgbaImage::from_raw(w, h, rgba).ok_or_else(|| out_err(path, "bad size"))?;
    img.save_with_format(path, image::ImageFormat::Png).map_err(|e| out_err(path, e))
}

/// The color plane as RGBA8 bytes.
pub fn color_rgba(fb: &Framebuffer) -> Vec<u8> {
    fb.color.as_flattened().to_vec()
}

/// Depth as gray levels: the range of depths actually drawn is stretched to 0 (nearest,
/// black) … 254; background (depth 1.0, nothing drawn) is white.
pub fn depth_gray(fb: &Framebuffer) -> Vec<u8> {
    let drawn = || fb.depth.iter().copied().filter(|d| *d < 1.0);
    let lo = drawn().fold(f32::INFINITY, f32::min);
    let hi = drawn().fold(f32::NEG_INFINITY, f32::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    fb.depth
        .iter()
        .flat_map(|&d| {
            let g = if d < 1.0 { ((d - lo) / span * 254.0).clamp(0.0, 254.0) as u8 } else { 255 };
            [g, g, g, 255]
        })
        .collect()
}

/// A stable, well-spread color for an ID (0 → black).
pub fn id_color(id: u32) -> [u8; 4] {
    if id == 0 {
        return [0, 0, 0, 255];
    }
    let mut h = id.wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    // Keep colors away from black so they never look like background.
    [(h as u8) | 0x30, ((h >> 8) as u8) | 0x30, ((h >> 16) as u8) | 0x30, 255]
}

/// The heat-map ramp: 0 → black, then blue, cyan, green, yellow, red for t in (0, 1].
pub fn heat_color(t: f32) -> [u8; 4] {
    const STOPS: [[f32; 3]; 5] = [[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]];
    if t.is_nan() || t <= 0.0 {
        return [0, 0, 0, 255];
    }
    let x = t.min(1.0) * (STOPS.len() - 1) as f32;
    let i = (x as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let c: Vec<u8> = (0..3).map(|k| ((STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f) * 255.0 + 0.5) as u8).collect();
    [c[0], c[1], c[2], 255]
}

/// Writes the color plane as PNG.
pub fn write_color_png(fb: &Framebuffer, path: &Path) -> Result<()> {
    save_rgba(path, fb.width(), fb.height(), color_rgba(fb))
}

/// Writes depth as a grayscale PNG (see [`depth_gray`]).
pub fn write_depth_png(fb: &Framebuffer, path: &Path) -> Result<()> {
    save_rgba(path, fb.width(), fb.height(), depth_gray(fb))
}

/// Writes triangle IDs as false colors (see [`id_color`]).
pub fn write_id_png(fb: &Framebuffer, path: &Path) -> Result<()> {
    let rgba = fb.ids.iter().flat_map(|&i| id_color(i)).collect();
    save_rgba(path, fb.width(), fb.height(), rgba)
}

/// Writes the depth-complexity heat map (depth tests per pixel, scaled to the maximum).
/// Errors when the framebuffer did not count depth tests.
pub fn write_heatmap_png(fb: &Framebuffer, path: &Path) -> Result<()> {
    let counts = fb
        .depth_tests
        .as_ref()
        .ok_or_else(|| out_err(path, "depth tests were not counted (Framebuffer::count_depth_tests)"))?;
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    let rgba = counts.iter().flat_map(|&c| heat_color(c as f32 / max)).collect();
    save_rgba(path, fb.width(), fb.height(), rgba)
}

/// An NPY v1.0 file image of an H × W array with dtype `descr` (e.g. `<u4`, `<f4`).
pub fn npy_bytes(descr: &str, height: u32, width: u32, data: &[u8]) -> Vec<u8> {
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({height}, {width}), }}");
    // magic (6) + version (2) + length (2) + dict + padding + '\n' ≡ 0 (mod 64)
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header_len = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(10 + header_len + data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(out.len() + pad, b' ');
    out.push(b'\n');
    out.extend_from_slice(data);
    out
}

/// Writes the ID plane as `uint32` H × W `.npy`.
pub fn write_ids_npy(fb: &Framebuffer, path: &Path) -> Result<()> {
    let data: Vec<u8> = fb.ids.iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = npy_bytes("<u4", fb.height(), fb.width(), &data);
    std::fs::write(path, bytes).map_err(|e| out_err(path, e))
}

/// Writes window depth as `float32` H × W `.npy`.
pub fn write_depth_npy(fb: &Framebuffer, path: &Path) -> Result<()> {
    let data: Vec<u8> = fb.depth.iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = npy_bytes("<f4", fb.height(), fb.width(), &data);
    std::fs::write(path, bytes).map_err(|e| out_err(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_header_is_padded_to_64_bytes() {
        let b = npy_bytes("<u4", 2, 3, &[0; 24]);
        assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
        let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        let header = std::str::from_utf8(&b[10..10 + hl]).unwrap();
        assert!(header.starts_with("{'descr': '<u4', 'fortran_order': False, 'shape': (2, 3), }"));
        assert!(header.ends_with('\n'));
        assert_eq!(b.len(), 10 + hl + 24);
    }

    #[test]
    fn colors() {
        assert_eq!(id_color(0), [0, 0, 0, 255]);
        assert_ne!(id_color(1), id_color(2));
        assert!(id_color(77)[..3].iter().all(|&c| c >= 0x30));
        assert_eq!(heat_color(0.0), [0, 0, 0, 255]);
        assert_eq!(heat_color(1.0), [255, 0, 0, 255]);
        assert_eq!(heat_color(1e-9)[2], 255);
    }
}

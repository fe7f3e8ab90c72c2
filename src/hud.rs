//! An on-screen readout: a few lines of text burned into an image, for the viewer's window
//! and the walkthrough's frames.
//!
//! The glyphs are the public-domain 8 × 8 bitmap font of the `font8x8` crate (the IBM PC's
//! BIOS font as redrawn for that crate): each glyph is eight bytes, one per row from the top,
//! bit `k` of a row being column `k` from the left. Text is scaled by whole pixels (nearest
//! neighbour), drawn in one colour over a box whose pixels are darkened to a third, so it
//! reads on a bright sky and on a dark facade alike. Characters the font lacks are drawn as
//! `?`.
//!
//! The same code draws into RGBA images (`[u8; 4]`, the framebuffer's colour plane) and into
//! window buffers of packed `0x00RRGGBB` words (`u32`, what softbuffer presents): the
//! [`Pixel`] trait is all that differs.
//!
//! ```
//! use sightline::hud;
//! let (w, h) = (120, 40);
//! let mut rgba = vec![[200u8, 200, 200, 255]; w * h];
//! let r = hud::draw(&mut rgba, w as u32, h as u32, &["12.3 ms", "hzb"], 1);
//! let corner = (r.y * w as u32 + r.x) as usize;
//! assert_eq!(rgba[corner], [66, 66, 66, 255], "the box is darkened to a third");
//! assert_eq!(rgba[w * h - 1], [200, 200, 200, 255], "outside the box nothing changes");
//! ```

use font8x8::UnicodeFonts;

/// Glyph cell side in font pixels.
const CELL: u32 = 8;
/// Space around the text inside the box, and between the box and the image corner, in
/// font pixels.
const PAD: u32 = 3;
/// Extra space between lines, in font pixels.
const LEADING: u32 = 2;
/// Text colour.
const INK: [u8; 3] = [255, 255, 255];

/// A pixel the readout can draw on.
pub trait Pixel: Copy {
    /// A pixel of colour `rgb` (opaque).
    fn from_rgb(rgb: [u8; 3]) -> Self;
    /// This pixel darkened to a third (the box behind the text).
    fn darkened(self) -> Self;
}

/// RGBA, 8 bits a channel: the framebuffer's colour plane and PNG images.
impl Pixel for [u8; 4] {
    fn from_rgb([r, g, b]: [u8; 3]) -> Self {
        [r, g, b, 255]
    }
    fn darkened(self) -> Self {
        [self[0] / 3, self[1] / 3, self[2] / 3, self[3]]
    }
}

/// `0x00RRGGBB`: the packed words window systems (and softbuffer) present.
impl Pixel for u32 {
    fn from_rgb([r, g, b]: [u8; 3]) -> Self {
        (r as u32) << 16 | (g as u32) << 8 | b as u32
    }
    fn darkened(self) -> Self {
        let c = |s: u32| ((self >> s) & 0xff) / 3;
        c(16) << 16 | c(8) << 8 | c(0)
    }
}

/// A rectangle of pixels (what [`draw`] covered).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels (0: nothing drawn).
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Rect {
    /// True when pixel (x, y) lies inside.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x && y >= self.y && x - self.x < self.width && y - self.y < self.height
    }
}

/// The box [`draw`] would cover for these lines at this scale, before clipping to the image.
pub fn measure(lines: &[impl AsRef<str>], scale: u32) -> Rect {
    let s = scale.max(1);
    let cols = lines.iter().map(|l| l.as_ref().chars().count() as u32).max().unwrap_or(0);
    if cols == 0 {
        return Rect::default();
    }
    let rows = lines.len() as u32;
    Rect {
        x: PAD * s,
        y: PAD * s,
        width: (cols * CELL + 2 * PAD) * s,
        height: (rows * CELL + rows.saturating_sub(1) * LEADING + 2 * PAD) * s,
    }
}

/// Draws `lines` into the top-left corner of a `width × height` image (row 0 at the top),
/// each font pixel `scale × scale` image pixels, over a darkened box; returns the box as
/// drawn (clipped to the image). An image smaller than `pixels` says is left alone.
pub fn draw<P: Pixel>(pixels: &mut [P], width: u32, height: u32, lines: &[impl AsRef<str>], scale: u32) -> Rect {
    let s = scale.max(1);
    let r = measure(lines, s);
    if r.width == 0 || pixels.len() < width as usize * height as usize || r.x >= width || r.y >= height {
        return Rect::default();
    }
    let clipped = Rect { width: r.width.min(width - r.x), height: r.height.min(height - r.y), ..r };
    let w = width as usize;
    for y in clipped.y..clipped.y + clipped.height {
        let row = &mut pixels[y as usize * w..][..w];
        for p in &mut row[clipped.x as usize..(clipped.x + clipped.width) as usize] {
            *p = p.darkened();
        }
    }
    let ink = P::from_rgb(INK);
    for (k, line) in lines.iter().enumerate() {
        let top = r.y + (PAD + k as u32 * (CELL + LEADING)) * s;
        for (c, ch) in line.as_ref().chars().enumerate() {
            let glyph = font8x8::BASIC_FONTS.get(ch).or_else(|| font8x8::BASIC_FONTS.get('?')).unwrap_or([0; 8]);
            let left = r.x + (PAD + c as u32 * CELL) * s;
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..CELL {
                    if bits >> gx & 1 == 0 {
                        continue;
                    }
                    let (x0, y0) = (left + gx * s, top + gy as u32 * s);
                    for y in y0..y0 + s {
                        for x in x0..x0 + s {
                            if clipped.contains(x, y) {
                                pixels[y as usize * w + x as usize] = ink;
                            }
                        }
                    }
                }
            }
        }
    }
    clipped
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_drawn_inside_its_box_only_and_in_both_pixel_formats() {
        let (w, h) = (200u32, 60u32);
        let mut rgba = vec![[90u8, 120, 240, 255]; (w * h) as usize];
        let mut packed = vec![0x005a78f0u32; (w * h) as usize];
        let lines = ["ms 4.2", "hzb"];
        let r = draw(&mut rgba, w, h, &lines, 2);
        assert_eq!(draw(&mut packed, w, h, &lines, 2), r);
        assert_eq!(r, measure(&lines, 2));
        let mut ink = 0;
        for y in 0..h {
            for x in 0..w {
                let (a, b) = (rgba[(y * w + x) as usize], packed[(y * w + x) as usize]);
                assert_eq!(u32::from_rgb([a[0], a[1], a[2]]), b, "same picture at ({x}, {y})");
                if !r.contains(x, y) {
                    assert_eq!(a, [90, 120, 240, 255], "untouched outside the box at ({x}, {y})");
                } else if a == [255, 255, 255, 255] {
                    ink += 1;
                } else {
                    assert_eq!(a, [30, 40, 80, 255], "the box is the background darkened");
                }
            }
        }
        // 'm', 's', '4', '.', '2', 'h', 'z', 'b' all have ink; a 2× font pixel is 4 pixels.
        assert!(ink > 8 * 4 * 6, "{ink} ink pixels");
    }

    #[test]
    fn a_readout_larger_than_the_image_is_clipped_and_unknown_characters_show() {
        let mut px = vec![0u32; 10 * 5];
        let r = draw(&mut px, 10, 5, &["a very long line that cannot fit"], 1);
        assert_eq!((r.x, r.y, r.width, r.height), (3, 3, 7, 2));
        assert_eq!(draw(&mut px, 10, 5, &[""], 1), Rect::default());
        assert_eq!(draw(&mut px[..3], 10, 5, &["x"], 1), Rect::default(), "too short a buffer");
        let mut a = vec![0u32; 64 * 20];
        let mut b = vec![0u32; 64 * 20];
        draw(&mut a, 64, 20, &["\u{2603}"], 1);
        draw(&mut b, 64, 20, &["?"], 1);
        assert_eq!(a, b, "a glyph the font lacks is drawn as '?'");
    }
}

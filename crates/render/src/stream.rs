//! Writing rows of a framebuffer plane past the cache.
//!
//! A plain store first reads the cache line it writes into (a read for ownership). A frame
//! overwrites every pixel of its planes, at 1280×720 3.7 MB each, more than the caches keep
//! from one frame to the next, so plain stores would also read each plane from memory just
//! to overwrite it, and evict what the next stages read. Non-temporal (streaming) stores
//! write whole lines without reading them (Intel's optimization manual, "Streaming Stores";
//! Drepper, "What Every Programmer Should Know About Memory", 2007, §6.1). They are used for
//! the whole 64-byte lines of a row; the pieces of lines at either end are written plainly
//! (a partial line written by streaming stores goes to memory as several partial writes).
//! Planes start on a line ([`crate::plane`]), so at widths that are multiples of 16 pixels
//! a tile's rows are whole lines. After its rows a task fences ([`written_through`]), so
//! that whoever waits for it sees them.
//!
//! The tile stage writes depth this way, and IDs plainly (the frame reads them back; see
//! `raster::store`). The shading pass writes its colors plainly:
//! shaded into a scratch row and written through, a frame took as long or longer (0.99–1.04×
//! on the street path, on the machine where depth and IDs gained 8–13%), and streaming the
//! colors straight from the shading kernel was 5–10% slower (its runs of pixels that miss
//! the triangle cache are written plainly, so lines end up written both ways).

/// Words of 4 bytes in a 64-byte cache line.
const LINE_WORDS: usize = 16;

/// A 4-byte value of a plane or a tile buffer, copied by its bits ([`write_through`]).
pub(crate) trait Word: Copy {
    /// The value's bits.
    fn bits(self) -> u32;
    /// The value with these bits.
    fn from_bits(bits: u32) -> Self;
}

impl Word for u32 {
    #[inline(always)]
    fn bits(self) -> u32 {
        self
    }
    #[inline(always)]
    fn from_bits(bits: u32) -> Self {
        bits
    }
}

impl Word for f32 {
    #[inline(always)]
    fn bits(self) -> u32 {
        self.to_bits()
    }
    #[inline(always)]
    fn from_bits(bits: u32) -> Self {
        f32::from_bits(bits)
    }
}

/// The words of `dst` before its first cache line, and those up to the end of its last
/// whole line (`dst` is 4-byte aligned).
#[inline(always)]
fn lines<T>(dst: &[T]) -> (usize, usize) {
    let n = dst.len();
    let head = dst.as_ptr().align_offset(4 * LINE_WORDS).min(n);
    (head, head + (n - head) / LINE_WORDS * LINE_WORDS)
}

/// Copies the bits of `src` into `dst` (of the same length): the whole cache lines of
/// `dst` with non-temporal stores, which do not read the lines first, the pieces of lines
/// at either end with plain stores. Call [`written_through`] before the values are read
/// elsewhere.
#[inline(always)]
pub(crate) fn write_through<T: Word, U: Word>(dst: &mut [T], src: &[U]) {
    assert_eq!(dst.len(), src.len(), "rows of one length");
    let (head, body) = lines(dst);
    let plain = |dst: &mut [T], src: &[U]| {
        for (d, s) in dst.iter_mut().zip(src) {
            *d = T::from_bits(s.bits());
        }
    };
    plain(&mut dst[..head], &src[..head]);
    #[cfg(target_arch = "x86_64")]
    for (d, s) in dst[head..body].chunks_exact_mut(4).zip(src[head..body].chunks_exact(4)) {
        use std::arch::x86_64::{__m128i, _mm_loadu_si128, _mm_stream_si128};
        // SAFETY: SSE2 is part of the x86-64 baseline; both chunks hold four 4-byte words,
        // and `d` is 16-byte aligned (`head` starts a line, chunks are 16 bytes), as the
        // streaming store requires.
        unsafe { _mm_stream_si128(d.as_mut_ptr() as *mut __m128i, _mm_loadu_si128(s.as_ptr() as *const __m128i)) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    plain(&mut dst[head..body], &src[head..body]);
    plain(&mut dst[body..], &src[body..]);
}

/// Sets every word of `dst` to `value`, as [`write_through`] writes.
#[inline(always)]
pub(crate) fn fill_through<T: Word>(dst: &mut [T], value: T) {
    let (head, body) = lines(dst);
    dst[..head].fill(value);
    #[cfg(target_arch = "x86_64")]
    for d in dst[head..body].chunks_exact_mut(4) {
        use std::arch::x86_64::{__m128i, _mm_set1_epi32, _mm_stream_si128};
        // SAFETY: as in `write_through`.
        unsafe { _mm_stream_si128(d.as_mut_ptr() as *mut __m128i, _mm_set1_epi32(value.bits() as i32)) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    dst[head..body].fill(value);
    dst[body..].fill(value);
}

/// Orders the non-temporal stores made so far before any later store of this thread (an
/// `sfence`): the end of a task is then the end of its writes for whoever waits on it (the
/// barrier's own release store cannot pass them). A no-op off x86-64.
#[inline(always)]
pub(crate) fn written_through() {
    // SAFETY: SSE is part of the x86-64 baseline.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows written through (non-temporal stores for whole cache lines, plain stores for the
    /// pieces at either end) hold exactly the values given, wherever a row starts and however
    /// long it is, and nothing outside the row changes.
    #[test]
    fn rows_written_through_hold_their_values_at_every_alignment() {
        // 64-byte aligned storage: rows start at every word offset of a line.
        #[repr(align(64))]
        struct Lines([u32; 256]);
        let src: Vec<f32> = (0..200).map(|k| k as f32 * 0.5 - 7.0).collect();
        for start in 0..20 {
            for len in [0, 1, 3, 4, 15, 16, 17, 31, 32, 33, 47, 64, 65, 100, 150] {
                let mut buf = Lines([0xDEAD_BEEF; 256]);
                write_through(&mut buf.0[start..start + len], &src[..len]);
                written_through();
                for (k, &w) in buf.0.iter().enumerate() {
                    let want = if (start..start + len).contains(&k) { src[k - start].to_bits() } else { 0xDEAD_BEEF };
                    assert_eq!(w, want, "copy: start {start}, length {len}, word {k}");
                }
                let mut depth = [1.5f32; 256];
                let off = start + 3;
                fill_through(&mut depth[off..off + len], -0.25);
                written_through();
                for (k, &d) in depth.iter().enumerate() {
                    let want = if (off..off + len).contains(&k) { -0.25 } else { 1.5 };
                    assert_eq!(d, want, "fill: start {off}, length {len}, word {k}");
                }
            }
        }
    }
}

//! Verification: compare a culled frame's triangle IDs with the brute-force frame's.

use serde::Serialize;

/// Where two ID buffers differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Mismatch {
    /// Number of differing pixels.
    pub pixels: u64,
    /// The first differing pixel (x, y), row 0 at the top.
    pub first: (u32, u32),
    /// The IDs there: (expected, got).
    pub ids: (u32, u32),
}

/// Compares two ID buffers of width `width`; `None` when they are equal.
pub fn compare_ids(expected: &[u32], got: &[u32], width: u32) -> Option<Mismatch> {
    let mut first = None;
    let mut pixels = 0u64;
    for (i, (a, b)) in expected.iter().zip(got).enumerate() {
        if a != b {
            pixels += 1;
            first.get_or_insert(i);
        }
    }
    let extra = expected.len().abs_diff(got.len()) as u64;
    if pixels == 0 && extra == 0 {
        return None;
    }
    let i = first.unwrap_or(expected.len().min(got.len()));
    let w = width.max(1) as usize;
    Some(Mismatch {
        pixels: pixels + extra,
        first: ((i % w) as u32, (i / w) as u32),
        ids: (expected.get(i).copied().unwrap_or(0), got.get(i).copied().unwrap_or(0)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_count_and_first_pixel() {
        assert_eq!(compare_ids(&[1, 2, 3], &[1, 2, 3], 3), None);
        let m = compare_ids(&[1, 2, 3, 4, 5, 6], &[1, 2, 3, 4, 9, 7], 3).unwrap();
        assert_eq!(m, Mismatch { pixels: 2, first: (1, 1), ids: (5, 9) });
    }
}

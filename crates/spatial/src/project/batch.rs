//! The answers of a batch of boxes in [`BoxProjector::classify_many`]: one array per field,
//! so that the eight-lane path stores each field of eight boxes with one aligned write.

use sightline_scene::Aabb;

use super::{BoxImage, BoxProjector, ScreenRect};

/// Boxes answered per call of the AVX2 path (four batches of eight lanes), so that the call
/// costs little per box.
pub(super) const BATCH: usize = 32;

/// The answers of up to [`BATCH`] boxes, lane k for box k (filled eight lanes at a time by
/// `Lanes::classify8`).
#[derive(Debug)]
#[repr(C, align(32))]
pub(super) struct Batch {
    /// [`Batch::RECT`], [`Batch::OUTSIDE`] or [`Batch::CROSSES`].
    pub(super) kind: [i32; BATCH],
    pub(super) x0: [i32; BATCH],
    pub(super) y0: [i32; BATCH],
    pub(super) x1: [i32; BATCH],
    pub(super) y1: [i32; BATCH],
    pub(super) depth: [f32; BATCH],
}

impl Default for Batch {
    fn default() -> Batch {
        Batch { kind: [0; BATCH], x0: [0; BATCH], y0: [0; BATCH], x1: [0; BATCH], y1: [0; BATCH], depth: [0.0; BATCH] }
    }
}

impl Batch {
    pub(super) const RECT: i32 = 0;
    pub(super) const OUTSIDE: i32 = 1;
    pub(super) const CROSSES: i32 = 2;

    /// Lane `k` as a [`BoxImage`].
    #[inline(always)]
    pub(super) fn image(&self, k: usize) -> BoxImage {
        match self.kind[k] {
            Batch::RECT => BoxImage::Rect(ScreenRect {
                x0: self.x0[k] as u32,
                y0: self.y0[k] as u32,
                x1: self.x1[k] as u32,
                y1: self.y1[k] as u32,
                depth: self.depth[k],
                crosses_near: false,
            }),
            Batch::OUTSIDE => BoxImage::Outside,
            _ => BoxImage::CrossesNear,
        }
    }

    /// Stores `image` in lane `k`.
    #[inline]
    pub(super) fn set(&mut self, k: usize, image: BoxImage) {
        self.kind[k] = match image {
            BoxImage::Rect(r) => {
                (self.x0[k], self.y0[k], self.x1[k], self.y1[k]) = (r.x0 as i32, r.y0 as i32, r.x1 as i32, r.y1 as i32);
                self.depth[k] = r.depth;
                Batch::RECT
            }
            BoxImage::Outside => Batch::OUTSIDE,
            BoxImage::CrossesNear => Batch::CROSSES,
        }
    }
}

impl BoxProjector {
    /// Answers up to [`BATCH`] boxes into lanes `0..chunk.len()` of `out`, one by one.
    #[inline]
    pub(super) fn chunk_portable(&self, chunk: &[Aabb], out: &mut Batch) {
        for (k, b) in chunk.iter().enumerate() {
            out.set(k, self.classify_portable(b));
        }
    }
}

//! The draw list the geometry stage reads: items resolved beforehand, or draw sources
//! resolved by each chunk as it reaches them.
//!
//! Resolving a draw source (its `clip_from_local`, a 4×4 product in f64) is per-item work
//! that needs nothing from other items. Done serially before the parallel geometry step, as
//! a frame session's batches used to, it held up the other worker at every batch; done by
//! the chunk that draws the item, it runs in parallel and the item goes from registers
//! straight into the chunk's transform.

use glam::{DMat4, Mat4, Vec3};
use sightline_spatial::SimdLevel;

use super::{Item, Source};
use crate::clip_matrix::clip_from_local;
use crate::options::{same_matrix, DrawSource};

/// A mesh's data as a draw piece reads it: positions, indices and the triangle ID map.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeshData<'a> {
    pub positions: &'a [Vec3],
    pub indices: &'a [u32],
    pub ids: Option<&'a [u32]>,
}

/// The items the geometry stage's pieces point into (by index).
pub(crate) trait DrawList: Sync {
    /// Item `k`. `prev` is the last item the caller resolved (its index and matrix): a list
    /// that computes matrices reuses it when both items are placed alike.
    fn item(&self, k: usize, prev: Option<(usize, &Mat4)>) -> Item<'_>;

    /// Item `k`'s mesh data, without its matrix (`None` for raw clip-space triangles): what
    /// the stage prefetches ahead of drawing it.
    fn mesh(&self, k: usize) -> Option<MeshData<'_>>;

    /// Asks for the record item `k` is made from, ahead of [`DrawList::mesh`] reading it:
    /// nothing for lists read in order, which the hardware's prefetch follows.
    #[inline(always)]
    fn prefetch_record(&self, _k: usize) {}
}

impl DrawList for [Item<'_>] {
    #[inline(always)]
    fn item(&self, k: usize, _: Option<(usize, &Mat4)>) -> Item<'_> {
        self[k]
    }

    #[inline(always)]
    fn mesh(&self, k: usize) -> Option<MeshData<'_>> {
        match self[k].src {
            Source::Mesh { positions, indices, ids, .. } => Some(MeshData { positions, indices, ids }),
            Source::Clip(_) => None,
        }
    }
}

/// Source `d` as an item under `clip_from_world`: its `clip_from_local` is `same` when
/// given (an item placed alike), computed on `simd` otherwise.
#[inline(always)]
pub(crate) fn placed_item<'a>(
    d: &DrawSource<'a>,
    clip_from_world: &DMat4,
    simd: SimdLevel,
    same: Option<&Mat4>,
) -> Item<'a> {
    let clip_from_local = match same {
        Some(m) => *m,
        None => clip_from_local(clip_from_world, &d.world_from_local, simd),
    };
    Item {
        src: Source::Mesh { positions: d.positions, indices: d.indices, clip_from_local, ids: d.triangle_ids },
        first_id: d.first_triangle.wrapping_add(1),
        source_triangles: (d.indices.len() / 3) as u32,
    }
}

/// Draw sources, checked, under one camera: item `k` is source `k` with its
/// `clip_from_local` computed when a chunk reaches it.
pub(crate) struct Placed<'a> {
    pub sources: &'a [DrawSource<'a>],
    pub clip_from_world: DMat4,
    /// The level [`clip_from_local`] runs on (resolved).
    pub simd: SimdLevel,
}

impl DrawList for Placed<'_> {
    #[inline(always)]
    fn item(&self, k: usize, prev: Option<(usize, &Mat4)>) -> Item<'_> {
        let d = &self.sources[k];
        // Consecutive clusters of one instance share the matrix.
        let same = prev.filter(|&(j, _)| same_matrix(&self.sources[j].world_from_local, &d.world_from_local));
        placed_item(d, &self.clip_from_world, self.simd, same.map(|(_, m)| m))
    }

    #[inline(always)]
    fn mesh(&self, k: usize) -> Option<MeshData<'_>> {
        let d = &self.sources[k];
        Some(MeshData { positions: d.positions, indices: d.indices, ids: d.triangle_ids })
    }
}

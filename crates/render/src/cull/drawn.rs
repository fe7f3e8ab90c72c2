//! The clusters a walk draws, as a draw list the geometry stage resolves itself.
//!
//! A batch's draw list used to be built before the parallel geometry step: a draw source
//! per cluster (its meshlets, its instance's matrix), then each source's `clip_from_local`.
//! Here the walk only lists the clusters that draw something and their triangle ranges,
//! which the chunks need to split the batch; each chunk turns its clusters into items as it
//! reaches them ([`DrawList`]), in parallel, while their records are in its cache.

use glam::{DMat4, Mat4};
use sightline_spatial::{prefetch, SimdLevel};

use super::Clusters;
use crate::geometry::{placed_item, DrawList, Item, MeshData};

/// Clusters of one batch, under one camera: item `k` is cluster `picked[k]`.
pub(super) struct ClusterList<'a> {
    pub clusters: &'a Clusters,
    pub picked: &'a [u32],
    pub clip_from_world: DMat4,
    /// The level the matrix products run on (resolved).
    pub simd: SimdLevel,
}

impl DrawList for ClusterList<'_> {
    #[inline(always)]
    fn item(&self, k: usize, prev: Option<(usize, &Mat4)>) -> Item<'_> {
        let draws = &self.clusters.draws;
        let d = &draws[self.picked[k] as usize];
        // Consecutive clusters of one instance share the matrix.
        let same = prev.filter(|&(j, _)| draws[self.picked[j] as usize].world_from_local == d.world_from_local);
        placed_item(&self.clusters.draw_source(d), &self.clip_from_world, self.simd, same.map(|(_, m)| m))
    }

    #[inline(always)]
    fn mesh(&self, k: usize) -> Option<MeshData<'_>> {
        let d = &self.clusters.draws[self.picked[k] as usize];
        let ml = self.clusters.meshlets.by_slot(d.meshlets);
        Some(MeshData { positions: &ml.positions, indices: &ml.indices, ids: Some(&ml.triangle_ids) })
    }

    /// The walk lists clusters nearest first, so their records lie all over the array.
    #[inline(always)]
    fn prefetch_record(&self, k: usize) {
        if let Some(&i) = self.picked.get(k) {
            prefetch(&self.clusters.draws[i as usize]);
        }
    }
}

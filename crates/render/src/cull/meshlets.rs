//! Cluster geometry for drawing: each mesh's triangles reordered cluster by cluster, with
//! each cluster's vertices copied into a contiguous range of their own (meshlets), and the
//! original index of every reordered triangle, so a drawn cluster still writes the triangle
//! IDs of the scene's flattened order.
//!
//! Copying boundary vertices costs memory (≈ 1.2–1.5× the vertex count) but lets the geometry
//! stage transform exactly the vertices a cluster uses, however the mesh's vertices are laid
//! out. Clusters themselves come from `sightline_spatial::ClusteredScene`.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;
use sightline_scene::{Instance, MeshId, Scene};
use sightline_spatial::ClusteredScene;

/// One mesh, rearranged cluster by cluster.
#[derive(Debug, Clone, Default)]
pub struct Meshlets {
    /// Vertices, each cluster's in a contiguous range.
    pub positions: Vec<Vec3>,
    /// Triangles in cluster order (indices into `positions`).
    pub indices: Vec<u32>,
    /// For each reordered triangle, its index in the original mesh.
    pub triangle_ids: Vec<u32>,
    /// Per cluster: first reordered triangle and count.
    pub clusters: Vec<(u32, u32)>,
}

impl Meshlets {
    /// Rearranges `positions`/`indices` so cluster `c` holds the original triangles
    /// `clusters[c]` (original triangle indices).
    pub fn build<'a>(positions: &[Vec3], indices: &[u32], clusters: impl Iterator<Item = &'a [u32]>) -> Self {
        let mut m = Meshlets::default();
        // Vertex remap of the current cluster: `stamp[v] == cluster` marks `new[v]` as valid,
        // so nothing is cleared between clusters.
        let mut stamp = vec![u32::MAX; positions.len()];
        let mut new = vec![0u32; positions.len()];
        for (c, tris) in clusters.enumerate() {
            let first = m.triangle_ids.len() as u32;
            for &t in tris {
                for k in 0..3 {
                    let v = indices[3 * t as usize + k] as usize;
                    if stamp[v] != c as u32 {
                        stamp[v] = c as u32;
                        new[v] = m.positions.len() as u32;
                        m.positions.push(positions[v]);
                    }
                    m.indices.push(new[v]);
                }
                m.triangle_ids.push(t);
            }
            m.clusters.push((first, tris.len() as u32));
        }
        m
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.positions.capacity() * 12
            + self.indices.capacity() * 4
            + self.triangle_ids.capacity() * 4
            + self.clusters.capacity() * 8
    }
}

/// Meshlets for every mesh a scene's instances draw, built once per mesh.
#[derive(Debug, Clone, Default)]
pub struct SceneMeshlets {
    meshes: Vec<Meshlets>,
    /// The mesh of each slot.
    mesh_ids: Vec<MeshId>,
    instance_slot: Vec<u32>,
}

impl SceneMeshlets {
    /// Builds meshlets for the meshes of `instances`, with the clusters of `clustered`
    /// (which must have been built from the same instances).
    pub fn build(scene: &Scene, instances: &[Instance], clustered: &ClusteredScene) -> Self {
        Self::build_reusing(scene, instances, clustered, HashMap::new())
    }

    /// Builds anew for changed instances, keeping the meshlets of every mesh still drawn
    /// (`clustered` must have kept that mesh's clusters too, as
    /// [`ClusteredScene::rebuild`] does).
    pub fn rebuild(&mut self, scene: &Scene, instances: &[Instance], clustered: &ClusteredScene) {
        let old = std::mem::take(self);
        let known = old.mesh_ids.into_iter().zip(old.meshes).collect();
        *self = Self::build_reusing(scene, instances, clustered, known);
    }

    fn build_reusing(
        scene: &Scene,
        instances: &[Instance],
        clustered: &ClusteredScene,
        mut known: HashMap<MeshId, Meshlets>,
    ) -> Self {
        let mut slot_of: HashMap<MeshId, u32> = HashMap::new();
        let mut first_instance: Vec<u32> = Vec::new();
        let instance_slot: Vec<u32> = instances
            .iter()
            .enumerate()
            .map(|(i, inst)| {
                *slot_of.entry(inst.mesh).or_insert_with(|| {
                    first_instance.push(i as u32);
                    first_instance.len() as u32 - 1
                })
            })
            .collect();
        let mesh_ids: Vec<MeshId> = first_instance.iter().map(|&i| instances[i as usize].mesh).collect();
        let reused: Vec<Option<Meshlets>> = mesh_ids.iter().map(|id| known.remove(id)).collect();
        let meshes = first_instance
            .par_iter()
            .zip(reused)
            .map(|(&i, done)| {
                if let Some(m) = done {
                    return m;
                }
                let (Some(mesh), Some(mc)) = (scene.mesh(instances[i as usize].mesh), clustered.mesh_clusters(i))
                else {
                    return Meshlets::default();
                };
                Meshlets::build(mesh.positions(), mesh.indices(), (0..mc.clusters().len()).map(|c| mc.triangles(c)))
            })
            .collect();
        Self { meshes, mesh_ids, instance_slot }
    }

    /// The meshlets instance `i` draws.
    pub fn of_instance(&self, i: u32) -> &Meshlets {
        &self.meshes[self.instance_slot[i as usize] as usize]
    }

    /// The slot of instance `i`'s meshlets (instances of one mesh share it).
    pub fn slot(&self, i: u32) -> u32 {
        self.instance_slot[i as usize]
    }

    /// The mesh of `slot`.
    pub(crate) fn mesh_id(&self, slot: u32) -> MeshId {
        self.mesh_ids[slot as usize]
    }

    /// Number of slots (meshes drawn).
    pub fn slots(&self) -> usize {
        self.meshes.len()
    }

    /// The meshlets in `slot` (see [`SceneMeshlets::slot`]).
    pub fn by_slot(&self, slot: u32) -> &Meshlets {
        &self.meshes[slot as usize]
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.meshes.iter().map(Meshlets::memory_bytes).sum::<usize>() + self.instance_slot.capacity() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshlets_keep_triangles_and_ids() {
        let m = sightline_scene::shapes::subdivided_box("b", Vec3::ZERO, Vec3::ONE, [3, 2, 4], true).unwrap();
        let n = m.triangle_count() as u32;
        let clusters: Vec<Vec<u32>> = vec![(0..n).step_by(2).collect(), (1..n).step_by(2).rev().collect()];
        let ml = Meshlets::build(m.positions(), m.indices(), clusters.iter().map(|c| c.as_slice()));
        assert_eq!(ml.triangle_ids.len(), n as usize);
        for (k, &t) in ml.triangle_ids.iter().enumerate() {
            let ours: Vec<Vec3> = (0..3).map(|j| ml.positions[ml.indices[3 * k + j] as usize]).collect();
            assert_eq!(ours, m.triangle_positions(t as usize).to_vec());
        }
        // Each cluster's vertices are contiguous and its own.
        let (f, c) = ml.clusters[1];
        let idx = &ml.indices[3 * f as usize..3 * (f + c) as usize];
        assert!(
            *idx.iter().min().unwrap() as usize > ml.indices[..3 * f as usize].iter().copied().max().unwrap() as usize
        );
    }
}

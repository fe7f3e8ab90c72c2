//! Cluster geometry for drawing: each mesh's triangles reordered cluster by cluster, with
//! each cluster's vertices copied into a contiguous range of their own (meshlets), and the
//! original index of every reordered triangle, so a drawn cluster still writes the triangle
//! IDs of the scene's flattened order.
//!
//! Copying boundary vertices costs memory (≈ 1.2–1.5× the vertex count) but lets the geometry
//! stage transform exactly the vertices a cluster uses, however the mesh's vertices are laid
//! out. A cluster keeps one vertex per position: the vertices a mesh splits for its normals
//! or texture coordinates are welded back, since depth and IDs read positions only (the
//! boxfield's occluder pass, 10^5 instanced boxes: 10.2–10.4 → 9.5–9.7 ms on one thread).
//! Clusters themselves come from `sightline_spatial::ClusteredScene`.

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
    /// `clusters[c]` (original triangle indices). Within a cluster, vertices at bitwise-equal
    /// positions become one (see the module docs).
    pub fn build<'a>(positions: &[Vec3], indices: &[u32], clusters: impl Iterator<Item = &'a [u32]>) -> Self {
        let mut m = Meshlets::default();
        // Vertex remap of the current cluster: `stamp[v] == cluster` marks `new[v]` as valid,
        // so nothing is cleared between clusters. It answers a vertex's later uses (about six
        // triangles share one) without the weld's hashing.
        let mut stamp = vec![u32::MAX; positions.len()];
        let mut new = vec![0u32; positions.len()];
        let mut weld = Weld::default();
        for (c, tris) in clusters.enumerate() {
            let first = m.triangle_ids.len() as u32;
            weld.start(3 * tris.len());
            for &t in tris {
                for k in 0..3 {
                    let v = indices[3 * t as usize + k] as usize;
                    if stamp[v] != c as u32 {
                        stamp[v] = c as u32;
                        new[v] = weld.vertex(&mut m.positions, positions[v]);
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

/// The vertices of one cluster, by position: a mesh splits a vertex wherever its normals or
/// texture coordinates do (a box's corner is three vertices, one per face), but drawing
/// depth and IDs reads positions only, and bitwise-equal positions transform to the same
/// bits, so a cluster keeps one vertex per position and the geometry stage transforms each
/// once (a box: 8 vertices instead of 24; the exported OBJ city's mesh has 919,414 vertices
/// at 513,334 positions). An open-addressing table keyed by the position's bits, its slots
/// stamped with the cluster they belong to, so that starting a cluster clears nothing.
#[derive(Default)]
struct Weld {
    /// Per slot: the cluster stamp and the meshlet vertex stored there.
    slots: Vec<(u32, u32)>,
    /// The current cluster's stamp (slots of other stamps are empty).
    stamp: u32,
}

impl Weld {
    /// Starts a cluster of at most `vertices` vertices (the table stays at most half full).
    fn start(&mut self, vertices: usize) {
        let want = (2 * vertices).next_power_of_two().max(16);
        if self.slots.len() < want || self.stamp == u32::MAX {
            self.slots = vec![(0, 0); want.max(self.slots.len())];
            self.stamp = 0;
        }
        self.stamp += 1;
    }

    /// The current cluster's vertex at `p`, appended to `positions` on its first use.
    fn vertex(&mut self, positions: &mut Vec<Vec3>, p: Vec3) -> u32 {
        let bits = p.to_array().map(f32::to_bits);
        let mask = self.slots.len() - 1;
        let h =
            bits[0].wrapping_mul(0x9E37_79B1) ^ bits[1].wrapping_mul(0x85EB_CA77) ^ bits[2].wrapping_mul(0xC2B2_AE3D);
        let mut i = (h ^ (h >> 15)) as usize & mask;
        loop {
            let (stamp, v) = self.slots[i];
            if stamp != self.stamp {
                let v = positions.len() as u32;
                positions.push(p);
                self.slots[i] = (self.stamp, v);
                return v;
            }
            if positions[v as usize].to_array().map(f32::to_bits) == bits {
                return v;
            }
            i = (i + 1) & mask;
        }
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
        // One vertex per position in each cluster: the box's edge and corner vertices, split
        // per face in the mesh, are welded (the vertices are all used, so the ranges tile
        // the meshlet's vertices).
        let bits = |p: &Vec3| p.to_array().map(f32::to_bits);
        let mut end = 0;
        for &(f, c) in &ml.clusters {
            let idx = &ml.indices[3 * f as usize..3 * (f + c) as usize];
            let (lo, hi) = (*idx.iter().min().unwrap() as usize, *idx.iter().max().unwrap() as usize + 1);
            assert_eq!(lo, end, "each cluster's vertices follow the last's");
            end = hi;
            let distinct: std::collections::HashSet<_> = ml.positions[lo..hi].iter().map(bits).collect();
            assert_eq!(distinct.len(), hi - lo, "a position twice in one cluster");
        }
        assert_eq!(end, ml.positions.len());
        let shared: std::collections::HashSet<_> = m.positions().iter().map(bits).collect();
        assert!(shared.len() < m.positions().len(), "the box splits vertices per face");
    }

    /// Welding grows its table for big clusters and keeps apart positions that differ in
    /// any bit (zero and negative zero too).
    #[test]
    fn welding_keeps_every_distinct_position() {
        let positions: Vec<Vec3> =
            (0..3000).map(|i| Vec3::new((i % 7) as f32, (i % 11) as f32, (i % 13) as f32 * 0.5)).collect();
        // (0, 0, 0) is corner 1001 too; the last corner becomes (0, 0, −0).
        let mut signed = positions.clone();
        signed[2999] = Vec3::new(0.0, 0.0, -0.0);
        let indices: Vec<u32> = (0..signed.len() as u32).collect();
        let all: Vec<u32> = (0..(signed.len() / 3) as u32).collect();
        let ml = Meshlets::build(&signed, &indices, [&all[..10], &all[10..]].into_iter());
        let distinct = |ps: &[Vec3]| {
            ps.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<std::collections::HashSet<_>>().len()
        };
        // The first cluster's 30 corners, then the rest's (7·11·13 = 1001 combinations).
        assert_eq!(ml.positions.len(), distinct(&signed[..30]) + distinct(&signed[30..]));
        for (k, &t) in ml.triangle_ids.iter().enumerate() {
            for j in 0..3 {
                let p = ml.positions[ml.indices[3 * k + j] as usize];
                assert_eq!(p.to_array().map(f32::to_bits), signed[3 * t as usize + j].to_array().map(f32::to_bits));
            }
        }
    }
}

//! Scene statistics: what `sightline info` prints.

use serde::Serialize;

use crate::Scene;

/// Counts that describe a scene's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SceneStats {
    /// Live nodes (groups and mesh nodes).
    pub nodes: usize,
    /// Meshes in the store.
    pub meshes: usize,
    /// Mesh-carrying nodes (draws).
    pub instances: usize,
    /// Triangles drawn: each instance counts its mesh's triangles.
    pub triangles: u64,
    /// Triangles stored: each mesh counted once.
    pub unique_triangles: u64,
    /// Bytes of vertex data held by the mesh store (positions, normals, UVs).
    pub vertex_bytes: u64,
    /// Bytes of index data held by the mesh store.
    pub index_bytes: u64,
    /// Zero-area triangles among the stored ones.
    pub degenerate_triangles: u64,
    /// Materials in the store.
    pub materials: usize,
}

impl Scene {
    /// Computes the statistics.
    pub fn stats(&self) -> SceneStats {
        let mut s = SceneStats {
            nodes: self.node_count(),
            meshes: 0,
            instances: 0,
            triangles: 0,
            unique_triangles: 0,
            vertex_bytes: 0,
            index_bytes: 0,
            degenerate_triangles: 0,
            materials: self.materials().count(),
        };
        for (_, m) in self.meshes() {
            s.meshes += 1;
            s.unique_triangles += m.triangle_count() as u64;
            s.vertex_bytes += m.vertex_bytes() as u64;
            s.index_bytes += m.indices().len() as u64 * 4;
            s.degenerate_triangles += m.degenerate_triangles() as u64;
        }
        for id in self.depth_first() {
            if let Some(m) = self.node(id).and_then(|n| n.mesh()).and_then(|m| self.mesh(m)) {
                s.instances += 1;
                s.triangles += m.triangle_count() as u64;
            }
        }
        s
    }
}

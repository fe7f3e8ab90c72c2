//! Bottom-level acceleration structures: one BVH per mesh over its triangles, built once and
//! shared by every instance of the mesh.
//!
//! Triangles are copied into leaf order (exact vertex positions, so the edge test stays
//! watertight); `bvh.order` maps a leaf-order slot back to the mesh's triangle index, which
//! is what triangle IDs and shading use.

use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use sightline_scene::Mesh;

use super::bvh::{BuildParams, Bvh};

/// A triangle BVH in some local space.
#[derive(Debug, Clone)]
pub(crate) struct Blas {
    /// Vertex positions per triangle, in leaf order.
    pub tris: Vec<[Vec3A; 3]>,
    /// The tree; `bvh.order[k]` is the mesh triangle stored in slot `k`.
    pub bvh: Bvh,
}

impl Blas {
    /// Builds over `count` triangles whose corners `corners(i)` gives.
    pub fn build(count: usize, corners: impl Fn(usize) -> [Vec3; 3]) -> Blas {
        let all: Vec<[Vec3A; 3]> = (0..count).map(|i| corners(i).map(Vec3A::from)).collect();
        let boxes: Vec<ObAabb> =
            all.iter().map(|t| ObAabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))).collect();
        let bvh = Bvh::build(&boxes, BuildParams::BLAS);
        let tris = bvh.order.iter().map(|&i| all[i as usize]).collect();
        Blas { tris, bvh }
    }

    /// The BLAS of a mesh in its own coordinates.
    pub fn from_mesh(mesh: &Mesh) -> Blas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i))
    }

    /// A BLAS of the mesh already placed in the world (for instances whose transform cannot
    /// be inverted, e.g. a zero scale that flattens the mesh).
    pub fn from_mesh_placed(mesh: &Mesh, world_from_local: &Affine3A) -> Blas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i).map(|p| world_from_local.transform_point3(p)))
    }

    /// Bounds of everything in the BLAS (empty box for no triangles).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (Vec3::from(self.bvh.root.lo), Vec3::from(self.bvh.root.hi))
    }
}

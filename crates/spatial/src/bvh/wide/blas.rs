//! Bottom level: one wide BVH per mesh over its triangles, built once and shared by every
//! instance of the mesh.
//!
//! Triangles are copied into leaf order (exact vertex positions, so a watertight edge test
//! stays watertight), each with the mesh's index of the triangle, which is what triangle IDs
//! and shading use (`bvh.order()` holds the same mapping). A record takes 40 bytes (three
//! packed `Vec3`s, not 16-byte `Vec3A`s, and the index), so a leaf of four fills 2.5 cache
//! lines, and a leaf test reads its triangles' IDs from the lines it reads anyway, not from
//! a second array.

use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use rayon::prelude::*;
use sightline_scene::{Aabb, Mesh};

use super::{WideBuildParams, WideBvh};

/// One triangle of a [`WideBlas`]: its corners and its index in the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct BlasTriangle {
    /// Vertex positions.
    pub corners: [Vec3; 3],
    /// The mesh's index of the triangle.
    pub index: u32,
}

/// A wide triangle BVH in some local space, with the triangles in leaf order.
#[derive(Debug, Clone)]
pub struct WideBlas {
    /// The triangles, in leaf order.
    tris: Vec<BlasTriangle>,
    /// The tree; `bvh.order()[k]` is the mesh triangle stored in slot `k`.
    bvh: WideBvh,
}

impl WideBlas {
    /// Builds over `count` triangles whose corners `corners(i)` gives (read twice: for the
    /// boxes, and for the copy in leaf order, both made in parallel).
    pub fn build(count: usize, corners: impl Fn(usize) -> [Vec3; 3] + Sync) -> WideBlas {
        let bvh = WideBvh::build_fn(count, WideBuildParams::BLAS, |i| {
            let t = corners(i).map(Vec3A::from);
            ObAabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))
        });
        let tris = bvh.order().par_iter().map(|&i| BlasTriangle { corners: corners(i as usize), index: i }).collect();
        WideBlas { tris, bvh }
    }

    /// A BLAS with no triangles.
    pub fn empty() -> WideBlas {
        Self::build(0, |_| [Vec3::ZERO; 3])
    }

    /// The BLAS of a mesh in its own coordinates.
    pub fn from_mesh(mesh: &Mesh) -> WideBlas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i))
    }

    /// A BLAS of the mesh already placed in the world (for instances whose transform cannot
    /// be inverted, e.g. a zero scale that flattens the mesh).
    pub fn from_mesh_placed(mesh: &Mesh, world_from_local: &Affine3A) -> WideBlas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i).map(|p| world_from_local.transform_point3(p)))
    }

    /// The triangles in leaf order (slot `k` is mesh triangle `bvh().order()[k]`, which its
    /// record also holds).
    #[inline]
    pub fn tris(&self) -> &[BlasTriangle] {
        &self.tris
    }

    /// The tree over the triangles.
    #[inline]
    pub fn bvh(&self) -> &WideBvh {
        &self.bvh
    }

    /// Bounds of everything in the BLAS (an empty box for no triangles).
    pub fn bounds(&self) -> Aabb {
        let root = self.bvh.root();
        Aabb::new(Vec3::from(root.lo), Vec3::from(root.hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_are_stored_in_leaf_order() {
        let corners = |i: usize| {
            let o = Vec3::new((i % 7) as f32, (i / 7) as f32, (i % 3) as f32);
            [o, o + Vec3::X, o + Vec3::Y]
        };
        let blas = WideBlas::build(50, corners);
        blas.bvh().validate(50).unwrap();
        for (k, &i) in blas.bvh().order().iter().enumerate() {
            assert_eq!(blas.tris()[k], BlasTriangle { corners: corners(i as usize), index: i });
        }
        assert_eq!(blas.bounds(), Aabb::new(Vec3::ZERO, Vec3::new(7.0, 8.0, 2.0)));
        assert!(WideBlas::empty().tris().is_empty());
    }
}

//! A binary BVH over one mesh's triangles (mesh-local space), for single-ray casting and as
//! the source of clusters. Built as every binary BVH here ([`Bvh`]); the ray caster's
//! packet-traced BLAS is the 4-wide [`crate::bvh::wide::WideBlas`].

use glam::Vec3;
use rayon::prelude::*;
use sightline_scene::{Aabb, Mesh};

use super::{Bvh, BvhPreset};
use crate::{AabbExt, Ray};

/// Triangles per leaf.
const TRIANGLE_LEAF: u32 = 4;

/// The nearest hit of a ray cast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Index of the triangle in the mesh (original order).
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
}

/// A BVH over a mesh's triangles: item `t` is triangle `t`.
#[derive(Debug, Clone, Default)]
pub struct TriangleBvh {
    bvh: Bvh,
}

impl TriangleBvh {
    /// Builds over `mesh`'s triangles with `preset`.
    pub fn build(mesh: &Mesh, preset: BvhPreset) -> TriangleBvh {
        Self::from_triangles(mesh.positions(), mesh.indices(), preset)
    }

    /// Builds over indexed triangles (`indices.len() / 3` triangles; a trailing partial
    /// triangle and out-of-range indices are treated as empty triangles).
    pub fn from_triangles(positions: &[Vec3], indices: &[u32], preset: BvhPreset) -> TriangleBvh {
        let boxes = triangle_boxes(positions, indices);
        TriangleBvh { bvh: Bvh::build(&boxes, preset, TRIANGLE_LEAF) }
    }

    /// The underlying BVH (items are triangle indices).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The nearest hit of `ray` with the mesh's triangles (the mesh the tree was built from),
    /// either facing. Zero-area triangles are never hit.
    pub fn intersect(&self, mesh: &Mesh, ray: &Ray) -> Option<TriangleHit> {
        let nodes = &self.bvh.nodes;
        if nodes.is_empty() {
            return None;
        }
        let (pos, idx) = (mesh.positions(), mesh.indices());
        let mut best: Option<TriangleHit> = None;
        let mut r = *ray;
        let mut stack: Vec<(u32, f32)> = Vec::with_capacity(64);
        if let Some((t0, _)) = r.intersect_aabb(&nodes[0].aabb()) {
            stack.push((0, t0));
        }
        while let Some((i, t_enter)) = stack.pop() {
            if t_enter > r.t_max {
                continue;
            }
            let n = &nodes[i as usize];
            if n.is_leaf() {
                for s in n.index..n.index + n.count {
                    let t = self.bvh.items[s as usize] as usize;
                    let Some(tri) = idx.get(3 * t..3 * t + 3) else {
                        continue;
                    };
                    let [a, b, c] = [0, 1, 2].map(|k| pos.get(tri[k] as usize).copied());
                    let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                        continue;
                    };
                    if let Some((th, u, v)) = r.intersect_triangle(a, b, c) {
                        r.t_max = th;
                        best = Some(TriangleHit { t: th, triangle: t as u32, u, v });
                    }
                }
            } else {
                let (a, b) = (n.index, n.index + 1);
                let ha = r.intersect_aabb(&nodes[a as usize].aabb());
                let hb = r.intersect_aabb(&nodes[b as usize].aabb());
                match (ha, hb) {
                    (Some((ta, _)), Some((tb, _))) => {
                        // Nearer child on top.
                        if ta <= tb {
                            stack.push((b, tb));
                            stack.push((a, ta));
                        } else {
                            stack.push((a, ta));
                            stack.push((b, tb));
                        }
                    }
                    (Some((ta, _)), None) => stack.push((a, ta)),
                    (None, Some((tb, _))) => stack.push((b, tb)),
                    (None, None) => {}
                }
            }
        }
        best
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes()
    }
}

/// The box of every triangle; triangles with missing vertices get the empty box.
pub(crate) fn triangle_boxes(positions: &[Vec3], indices: &[u32]) -> Vec<Aabb> {
    indices
        .par_chunks_exact(3)
        .with_min_len(1 << 14)
        .map(|t| match (positions.get(t[0] as usize), positions.get(t[1] as usize), positions.get(t[2] as usize)) {
            (Some(&a), Some(&b), Some(&c)) => Aabb::of_triangle(a, b, c),
            _ => Aabb::EMPTY,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline_scene::shapes;

    #[test]
    fn ray_cast_matches_brute_force() {
        let mesh = shapes::subdivided_box("b", Vec3::ZERO, Vec3::new(4.0, 2.0, 3.0), [8, 4, 6], true).unwrap();
        let tree = TriangleBvh::build(&mesh, BvhPreset::Fast);
        tree.bvh().validate().unwrap();
        let mut rng = sightline_scene::rng::Rng::new(8);
        let mut hits = 0;
        for _ in 0..500 {
            let o = Vec3::new(rng.range(-5.0, 9.0), rng.range(-5.0, 7.0), rng.range(-5.0, 8.0));
            let target = Vec3::new(rng.range(0.0, 4.0), rng.range(0.0, 2.0), rng.range(0.0, 3.0));
            let ray = Ray::new(o, target - o);
            let brute = (0..mesh.triangle_count())
                .filter_map(|t| {
                    let [a, b, c] = mesh.triangle_positions(t);
                    ray.intersect_triangle(a, b, c).map(|h| h.0)
                })
                .fold(f32::INFINITY, f32::min);
            let got = tree.intersect(&mesh, &ray).map_or(f32::INFINITY, |h| h.t);
            assert_eq!(got, brute);
            hits += got.is_finite() as u32;
        }
        assert!(hits > 100);
    }

    #[test]
    fn degenerate_and_empty_meshes() {
        let m = Mesh::new("d", vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], None, None, vec![0, 1, 2]).unwrap();
        let tree = TriangleBvh::build(&m, BvhPreset::Fast);
        assert!(tree.intersect(&m, &Ray::new(Vec3::new(1.0, 1.0, 0.0), Vec3::NEG_Y)).is_none());
        let e = Mesh::new("e", vec![], None, None, vec![]).unwrap();
        let tree = TriangleBvh::build(&e, BvhPreset::Fast);
        assert!(tree.intersect(&e, &Ray::new(Vec3::ZERO, Vec3::X)).is_none());
    }
}

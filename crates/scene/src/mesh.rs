//! Triangle meshes: vertex arrays and `u32` indices, validated once at construction.
//!
//! A mesh lives in the scene's mesh store and is referenced by [`MeshId`](crate::MeshId)
//! from any number of nodes (instancing): its vertices exist once however often it is drawn.

use std::sync::OnceLock;

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

use crate::{Aabb, Error, Result};

/// Meshes of at least this many triangles are checked, and make their [`Face`] records, in
/// parallel.
const PARALLEL_FACES: usize = 1 << 14;

/// An indexed triangle mesh in its own (local) coordinates.
///
/// Fields are read-only after construction so that the cached bounds and counts stay true;
/// build a new mesh to change geometry.
#[derive(Debug, Clone)]
pub struct Mesh {
    name: String,
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    indices: Vec<u32>,
    aabb: Aabb,
    degenerate: usize,
    /// Each triangle's [`Face`], made on first use ([`Mesh::faces`]).
    faces: OnceLock<Box<[Face]>>,
}

/// What flat shading reads of a triangle, in one record: its local-space face normal
/// `(p1 − p0) × (p2 − p0)` (not normalized) and its first corner `p0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Face {
    /// `(p1 − p0) × (p2 − p0)`, in local space; zero for a degenerate triangle.
    pub normal: Vec3,
    /// The first corner, `p0`.
    pub corner: Vec3,
}

impl Mesh {
    /// Builds and validates a mesh.
    ///
    /// Errors when an index is out of range, a position, normal or UV is NaN or infinite, the
    /// index count is not a multiple of 3, or normals/UVs do not have one entry per position.
    /// Degenerate (zero-area) triangles are allowed and counted in
    /// [`Mesh::degenerate_triangles`].
    pub fn new(
        name: impl Into<String>,
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
        indices: Vec<u32>,
    ) -> Result<Self> {
        let name = name.into();
        let bad = |why: String| Error::InvalidMesh { name: name.clone(), why };
        if !indices.len().is_multiple_of(3) {
            return Err(bad(format!("{} indices is not a multiple of 3", indices.len())));
        }
        if let Some(i) = first_where(&positions, |p| !p.is_finite()) {
            return Err(bad(format!("position {i} is not finite: {:?}", positions[i])));
        }
        let n = positions.len();
        if let Some(k) = first_where(&indices, |&i| i as usize >= n) {
            return Err(bad(format!("index {} at slot {k} is out of range for {n} vertices", indices[k])));
        }
        if let Some(nr) = &normals {
            if nr.len() != n {
                return Err(bad(format!("{} normals for {n} positions", nr.len())));
            }
            if let Some(i) = first_where(nr, |v| !v.is_finite()) {
                return Err(bad(format!("normal {i} is not finite")));
            }
        }
        if let Some(uv) = &uvs {
            if uv.len() != n {
                return Err(bad(format!("{} UVs for {n} positions", uv.len())));
            }
            if let Some(i) = first_where(uv, |v| !v.is_finite()) {
                return Err(bad(format!("UV {i} is not finite")));
            }
        }
        let (aabb, degenerate) = bounds_and_degenerate(&positions, &indices);
        Ok(Self { name, positions, normals, uvs, indices, aabb, degenerate, faces: OnceLock::new() })
    }

    /// The mesh's name (from the file, or given by a builder).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Vertex positions in local space.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }
    /// Per-vertex normals, if the mesh has them.
    pub fn normals(&self) -> Option<&[Vec3]> {
        self.normals.as_deref()
    }
    /// Per-vertex texture coordinates (set 0), if the mesh has them.
    pub fn uvs(&self) -> Option<&[Vec2]> {
        self.uvs.as_deref()
    }
    /// Triangle indices, three per triangle, counter-clockwise front faces.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
    /// The three vertex indices of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [u32; 3] {
        [self.indices[3 * t], self.indices[3 * t + 1], self.indices[3 * t + 2]]
    }
    /// The three local-space corners of triangle `t`.
    #[inline]
    pub fn triangle_positions(&self, t: usize) -> [Vec3; 3] {
        self.triangle(t).map(|i| self.positions[i as usize])
    }
    /// Every triangle's [`Face`], in triangle order, made on the first call (12 bytes of
    /// normal and 12 of corner a triangle). A renderer shading whole triangles reads one
    /// record here instead of three indices and then three corners, two dependent loads
    /// that miss the caches in big scenes. Making them takes one pass over the triangles
    /// (in parallel over the triangles of a big mesh); the records are kept with the mesh
    /// and are not counted in [`Mesh::vertex_bytes`].
    pub fn faces(&self) -> &[Face] {
        self.faces.get_or_init(|| {
            let face = |t: &[u32]| {
                let corners = [0, 1, 2].map(|k| Vec3A::from(self.positions[t[k] as usize]));
                Face { normal: face_normal(corners).into(), corner: corners[0].into() }
            };
            // Each record depends on its triangle alone, so the split changes no bit.
            if self.triangle_count() >= PARALLEL_FACES {
                self.indices.par_chunks_exact(3).map(face).collect::<Vec<_>>().into_boxed_slice()
            } else {
                self.indices.chunks_exact(3).map(face).collect()
            }
        })
    }
    /// Whether [`Mesh::faces`] has made the face records yet (they take 24 bytes a
    /// triangle once made).
    pub fn has_faces(&self) -> bool {
        self.faces.get().is_some()
    }
    /// Local-space bounds of the referenced vertices.
    pub fn aabb(&self) -> Aabb {
        self.aabb
    }
    /// How many triangles have zero area.
    pub fn degenerate_triangles(&self) -> usize {
        self.degenerate
    }
    /// Bytes of vertex data (positions, normals, UVs) held by this mesh.
    pub fn vertex_bytes(&self) -> usize {
        let n = self.positions.len();
        n * 12 + self.normals.as_ref().map_or(0, |_| n * 12) + self.uvs.as_ref().map_or(0, |_| n * 8)
    }
}

/// The index of the first element of `v` that `bad` holds for (the same answer in
/// parallel over a big array: checking a 10^6-triangle mesh is a pass over 3·10^6 indices).
fn first_where<T: Sync>(v: &[T], bad: impl Fn(&T) -> bool + Sync + Send) -> Option<usize> {
    if v.len() >= 3 * PARALLEL_FACES {
        // Whole blocks in parallel, with the serial loop inside: rayon's per-item
        // `position_first` pays for every item's enumeration.
        const BLOCK: usize = 1 << 14;
        let k = v.par_chunks(BLOCK).position_first(|b| b.iter().any(&bad))?;
        v[k * BLOCK..].iter().position(bad).map(|i| k * BLOCK + i)
    } else {
        v.iter().position(bad)
    }
}

/// The bounds of the vertices `indices` reference (unreferenced ones must not inflate
/// culling boxes) and the number of zero-area triangles, in parallel over a big mesh: a
/// union of boxes and a count come out the same in any order.
fn bounds_and_degenerate(positions: &[Vec3], indices: &[u32]) -> (Aabb, usize) {
    let step = |(mut aabb, degenerate): (Aabb, usize), t: &[u32]| {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        aabb.grow(a);
        aabb.grow(b);
        aabb.grow(c);
        (aabb, degenerate + (face_normal([a, b, c].map(Vec3A::from)) == Vec3A::ZERO) as usize)
    };
    let none = (Aabb::EMPTY, 0);
    if indices.len() >= 3 * PARALLEL_FACES {
        indices.par_chunks_exact(3).fold(|| none, step).reduce(|| none, |(a, m), (b, n)| (a.union(&b), m + n))
    } else {
        indices.chunks_exact(3).fold(none, step)
    }
}

/// The unnormalized normal (b − a) × (c − a) of the triangle with corners `[a, b, c]`: zero
/// when the triangle has no area (or is so small that the products underflow). Flat shading
/// reads it from [`Mesh::faces`]; the degenerate count uses the same test.
#[inline]
fn face_normal([a, b, c]: [Vec3A; 3]) -> Vec3A {
    (b - a).cross(c - a)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Vec<Vec3> {
        vec![Vec3::ZERO, Vec3::X, Vec3::Y]
    }

    #[test]
    fn validates_indices_and_positions() {
        assert!(Mesh::new("ok", tri(), None, None, vec![0, 1, 2]).is_ok());
        let e = Mesh::new("m", tri(), None, None, vec![0, 1, 3]).unwrap_err().to_string();
        assert!(e.contains("'m'") && e.contains("out of range"), "{e}");
        let e = Mesh::new("m", tri(), None, None, vec![0, 1]).unwrap_err().to_string();
        assert!(e.contains("multiple of 3"), "{e}");
        let mut p = tri();
        p[1].y = f32::NAN;
        assert!(Mesh::new("m", p, None, None, vec![0, 1, 2]).is_err());
        assert!(Mesh::new("m", tri(), Some(vec![Vec3::Z]), None, vec![0, 1, 2]).is_err());
    }

    #[test]
    fn counts_degenerate_triangles_and_ignores_unreferenced_vertices() {
        let mut p = tri();
        p.push(Vec3::splat(100.0)); // unreferenced
        let m = Mesh::new("m", p, None, None, vec![0, 1, 2, 0, 0, 1]).unwrap();
        assert_eq!(m.degenerate_triangles(), 1);
        assert_eq!(m.triangle_count(), 2);
        assert_eq!(m.aabb().max, Vec3::new(1.0, 1.0, 0.0));
    }

    /// A face's expected normal, bit for bit what (b − a) × (c − a) gives in `Vec3A` (so that
    /// flat colors do not move), written out here rather than through `face_normal`.
    fn cross_of([a, b, c]: [Vec3; 3]) -> Vec3 {
        Vec3::from((Vec3A::from(b) - Vec3A::from(a)).cross(Vec3A::from(c) - Vec3A::from(a)))
    }

    #[test]
    fn faces_hold_each_triangles_normal_and_first_corner_in_triangle_order() {
        let p = vec![Vec3::new(0.1, 0.2, 0.3), Vec3::new(2.5, -1.0, 0.7), Vec3::new(-0.3, 4.0, 1.9), Vec3::ZERO];
        let m = Mesh::new("m", p.clone(), None, None, vec![0, 1, 2, 2, 1, 3, 3, 3, 0]).unwrap();
        assert!(!m.has_faces(), "made on first use only");
        let faces = m.faces();
        assert_eq!(faces.len(), 3);
        for (t, f) in faces.iter().enumerate() {
            let [a, b, c] = m.triangle_positions(t);
            assert_eq!(f.corner, a);
            let n = cross_of([a, b, c]);
            assert_eq!(f.normal.to_array().map(f32::to_bits), n.to_array().map(f32::to_bits));
        }
        assert_ne!(faces[0].normal, faces[1].normal);
        assert_eq!(faces[2].normal, Vec3::ZERO, "a degenerate triangle has a zero normal");
        assert!(std::ptr::eq(faces, m.faces()), "made once");
        assert_eq!(m.clone().faces(), faces);
    }

    #[test]
    fn a_big_mesh_made_in_parallel_has_its_faces_in_triangle_order() {
        // A fan of 2·PARALLEL_FACES triangles over points of a helix, each its own shape.
        let n = 2 * PARALLEL_FACES;
        let p: Vec<Vec3> =
            (0..n + 2).map(|i| Vec3::new((i as f32 * 0.37).cos(), (i as f32 * 0.37).sin(), i as f32 * 1e-3)).collect();
        let idx: Vec<u32> = (0..n as u32).flat_map(|t| [0, t + 1, t + 2]).collect();
        let m = Mesh::new("fan", p, None, None, idx).unwrap();
        let faces = m.faces();
        assert_eq!(faces.len(), n);
        for (t, f) in faces.iter().enumerate() {
            let [a, b, c] = m.triangle_positions(t);
            assert_eq!((f.corner, f.normal), (a, cross_of([a, b, c])), "triangle {t}");
        }
    }

    /// A mesh big enough to be checked in parallel reports the first bad entry (two are
    /// planted, in different blocks), and its bounds and degenerate count are those of a
    /// serial pass over its triangles.
    #[test]
    fn a_big_mesh_checked_in_parallel_reports_the_first_fault_and_the_serial_bounds() {
        let n = 3 * PARALLEL_FACES;
        let p: Vec<Vec3> =
            (0..n + 2).map(|i| Vec3::new((i as f32 * 0.37).cos(), (i as f32 * 0.37).sin(), i as f32 * 1e-3)).collect();
        // A fan, every 7th triangle degenerate (a repeated corner), and vertices past the
        // last one referenced (far away: they must not reach the bounds).
        let mut idx: Vec<u32> =
            (0..n as u32).flat_map(|t| if t % 7 == 0 { [0, t + 1, t + 1] } else { [0, t + 1, t + 2] }).collect();
        let mut far = p.clone();
        far.extend([Vec3::splat(1e6); 3]);
        let m = Mesh::new("fan", far.clone(), None, None, idx.clone()).unwrap();
        let mut aabb = Aabb::EMPTY;
        for &i in &idx {
            aabb.grow(p[i as usize]);
        }
        assert_eq!((m.aabb(), m.degenerate_triangles()), (aabb, n.div_ceil(7)));

        for (first, second) in [(70_001, 3 * n - 5), (5, 40_000)] {
            let mut bad = idx.clone();
            bad[first] = u32::MAX;
            bad[second] = u32::MAX - 1;
            let e = Mesh::new("fan", far.clone(), None, None, bad).unwrap_err().to_string();
            assert!(e.contains(&format!("index {} at slot {first} ", u32::MAX)), "{e}");
            let mut q = p.clone();
            q[first / 3].z = f32::NAN;
            q[second / 3].x = f32::INFINITY;
            let e = Mesh::new("fan", q, None, None, idx.clone()).unwrap_err().to_string();
            assert!(e.contains(&format!("position {} is not finite", first / 3)), "{e}");
            let mut normals = vec![Vec3::Z; p.len()];
            normals[first / 3] = Vec3::NAN;
            normals[second / 3] = Vec3::NAN;
            let e = Mesh::new("fan", p.clone(), Some(normals), None, idx.clone()).unwrap_err().to_string();
            assert!(e.contains(&format!("normal {} is not finite", first / 3)), "{e}");
        }
        idx.truncate(3);
        assert!(Mesh::new("small", p, None, None, idx).is_ok());
    }
}

//! Small meshes made in code: cube, quad, grid, box with subdivided faces.

use glam::{Vec2, Vec3};

use crate::{Mesh, Result};

/// Vertex and index arrays being filled, turned into a validated [`Mesh`] at the end.
#[derive(Debug, Default, Clone)]
pub struct MeshBuilder {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Normals, one per position.
    pub normals: Vec<Vec3>,
    /// UVs, one per position.
    pub uvs: Vec<Vec2>,
    /// Triangle indices.
    pub indices: Vec<u32>,
}

impl MeshBuilder {
    /// Appends a `nu × nv` grid of quads spanning `origin + [0,1]·du + [0,1]·dv` (two
    /// triangles per quad, counter-clockwise seen from the side `du × dv` points to) with
    /// flat normals.
    pub fn grid(&mut self, origin: Vec3, du: Vec3, dv: Vec3, nu: u32, nv: u32) {
        let n = du.cross(dv).normalize_or_zero();
        let base = self.positions.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                let (s, t) = (i as f32 / nu as f32, j as f32 / nv as f32);
                self.positions.push(origin + du * s + dv * t);
                self.normals.push(n);
                self.uvs.push(Vec2::new(s, 1.0 - t));
            }
        }
        let row = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                let a = base + j * row + i;
                let (b, c, d) = (a + 1, a + row + 1, a + row);
                self.indices.extend_from_slice(&[a, b, c, a, c, d]);
            }
        }
    }

    /// Appends an axis-aligned box `[min, max]` whose faces are split into grids (`cells`
    /// quads along x, y, z), faces pointing outwards; with `bottom = false` the face at
    /// `min.y` is left out.
    pub fn add_box(&mut self, min: Vec3, max: Vec3, cells: [u32; 3], bottom: bool) {
        let e = max - min;
        let [cx, cy, cz] = cells.map(|c| c.max(1));
        let (x, y, z) = (Vec3::X * e.x, Vec3::Y * e.y, Vec3::Z * e.z);
        // Each face: origin, du, dv with du × dv pointing outwards.
        self.grid(min + z, x, y, cx, cy); // +z
        self.grid(min + x + z, -z, y, cz, cy); // +x
        self.grid(min + x, -x, y, cx, cy); // −z
        self.grid(min, z, y, cz, cy); // −x
        self.grid(min + y + z, x, -z, cx, cz); // +y
        if bottom {
            self.grid(min, x, z, cx, cz); // −y
        }
    }

    /// Validates and returns the mesh.
    pub fn build(self, name: &str) -> Result<Mesh> {
        Mesh::new(name, self.positions, Some(self.normals), Some(self.uvs), self.indices)
    }
}

/// An axis-aligned box `[min, max]` whose faces are split into grids; `cells` gives the
/// number of quads along x, y, z. With `bottom = false` the face at `min.y` is left out
/// (buildings standing on the ground never show it).
pub fn subdivided_box(name: &str, min: Vec3, max: Vec3, cells: [u32; 3], bottom: bool) -> Result<Mesh> {
    let mut b = MeshBuilder::default();
    b.add_box(min, max, cells, bottom);
    b.build(name)
}

/// The unit cube [−0.5, 0.5]³, 12 triangles, outward counter-clockwise faces.
pub fn cube(name: &str) -> Result<Mesh> {
    subdivided_box(name, Vec3::splat(-0.5), Vec3::splat(0.5), [1, 1, 1], true)
}

/// A square in the xz-plane, `[−0.5, 0.5]²`, facing +y, split into `n × n` quads.
pub fn ground_quad(name: &str, n: u32) -> Result<Mesh> {
    let mut b = MeshBuilder::default();
    b.grid(Vec3::new(-0.5, 0.0, 0.5), Vec3::X, Vec3::NEG_Z, n.max(1), n.max(1));
    b.build(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_faces_point_outwards() {
        let m = subdivided_box("b", Vec3::ZERO, Vec3::new(2.0, 3.0, 1.0), [2, 3, 1], true).unwrap();
        // Two faces each of 2x3, 1x3 and 2x1 quads, two triangles per quad.
        assert_eq!(m.triangle_count(), 2 * (2 * 6 + 2 * 3 + 2 * 2));
        let c = m.aabb().center();
        for t in 0..m.triangle_count() {
            let [a, b, cc] = m.triangle_positions(t);
            let normal = (b - a).cross(cc - a);
            let centroid = (a + b + cc) / 3.0;
            assert!(normal.dot(centroid - c) > 0.0, "triangle {t} faces inwards");
        }
        assert_eq!(m.degenerate_triangles(), 0);
    }

    #[test]
    fn ground_faces_up() {
        let m = ground_quad("g", 2).unwrap();
        let [a, b, c] = m.triangle_positions(0);
        assert!((b - a).cross(c - a).y > 0.0);
    }
}

//! Building facades with windows that can be seen, at no extra triangle cost.
//!
//! A building is a box whose sides are grids of quads (`cells` along x, y and z, two
//! triangles each), as [`subdivided_box`](crate::shapes::subdivided_box) makes it. Here the
//! grid lines are not evenly spaced: along each horizontal side the columns alternate a
//! narrow pier and a wider window bay, and up the building the rows alternate a spandrel
//! (the wall between storeys) and a taller window band, starting and ending with wall. A
//! quad in a window column *and* a window row is a window pane; every other quad is wall.
//! The panes go into meshes of their own so that they get their own material (materials
//! belong to nodes): one mesh of dark glass panes and one of lit panes, the lit ones chosen
//! by a hash of the pane's place, so the same seed lights the same windows.
//!
//! The three meshes together hold exactly the quads of the evenly split box: the same
//! number of triangles. Grid coordinates are computed once per axis and shared by every
//! side and the roof, so the meshes meet edge to edge without T-junctions (watertight
//! under the fill rule, as the even box is).

use glam::{Vec2, Vec3};

use crate::rng::Rng;
use crate::shapes::MeshBuilder;
use crate::{Mesh, Result};

/// How much wider a window column is than a pier.
const BAY_RATIO: f32 = 2.2;
/// How much taller a window band is than a spandrel.
const BAND_RATIO: f32 = 1.6;

/// The three meshes of one building: walls and roof, dark panes, lit panes (either pane
/// mesh is `None` when the building has no such pane).
#[derive(Debug)]
pub(crate) struct Facade {
    pub walls: Mesh,
    pub windows: Option<Mesh>,
    pub lit: Option<Mesh>,
}

/// One axis of the grid: `n + 1` line coordinates from `lo` to `lo + len`, and for each of
/// the `n` cells whether it is an opening (odd cells, never the last one: a side starts
/// and ends with wall).
fn axis(lo: f32, len: f32, n: u32, ratio: f32) -> (Vec<f32>, Vec<bool>) {
    let n = n.max(1) as usize;
    let open: Vec<bool> = (0..n).map(|k| k % 2 == 1 && k + 1 < n).collect();
    let units: f32 = open.iter().map(|&o| if o { ratio } else { 1.0 }).sum();
    let unit = len / units;
    let mut lines = Vec::with_capacity(n + 1);
    let mut at = 0.0f32;
    lines.push(lo);
    for &o in &open {
        at += if o { ratio } else { 1.0 };
        lines.push(lo + at * unit);
    }
    // The far side exactly, whatever the rounding of the sum.
    lines[n] = lo + len;
    (lines, open)
}

/// A mesh being filled face by face, sharing each face's grid vertices between its quads.
struct Part {
    b: MeshBuilder,
    /// Index of each grid vertex of the current face in `b` (`u32::MAX`: not yet added).
    slots: Vec<u32>,
}

impl Part {
    fn new() -> Self {
        Part { b: MeshBuilder::default(), slots: Vec::new() }
    }

    fn start_face(&mut self, vertices: usize) {
        self.slots.clear();
        self.slots.resize(vertices, u32::MAX);
    }

    /// The index of grid vertex `slot` at `p` (added on first use).
    fn vertex(&mut self, slot: usize, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        if self.slots[slot] == u32::MAX {
            self.slots[slot] = self.b.positions.len() as u32;
            self.b.positions.push(p);
            self.b.normals.push(n);
            self.b.uvs.push(uv);
        }
        self.slots[slot]
    }

    fn build(self, name: &str) -> Result<Option<Mesh>> {
        if self.b.indices.is_empty() {
            return Ok(None);
        }
        self.b.build(name).map(Some)
    }
}

/// One side of the box: `nu × nv` quads; `at(i, j)` is grid vertex (i, j) (i along the
/// side's u axis, j along v, u × v pointing outwards); `pane(i, j)` tells whether quad
/// (i, j) is a window pane.
struct Face<'a> {
    nu: usize,
    nv: usize,
    at: &'a dyn Fn(usize, usize) -> Vec3,
    pane: &'a dyn Fn(usize, usize) -> bool,
}

/// Builds the facade of the box `[min, max]` (no bottom face) split into `cells` quads
/// along x, y and z; `seed` chooses the lit panes, about `lit_share` of them.
pub(crate) fn facade(name: &str, min: Vec3, max: Vec3, cells: [u32; 3], seed: u64, lit_share: f32) -> Result<Facade> {
    let e = max - min;
    let (xs, xo) = axis(min.x, e.x, cells[0], BAY_RATIO);
    let (ys, yo) = axis(min.y, e.y, cells[1], BAND_RATIO);
    let (zs, zo) = axis(min.z, e.z, cells[2], BAY_RATIO);
    let (nx, ny, nz) = (xo.len(), yo.len(), zo.len());
    let (x1, y1, z1) = (xs[nx], ys[ny], zs[nz]);
    let (x0, z0) = (xs[0], zs[0]);
    let mut parts = [Part::new(), Part::new(), Part::new()];
    // Sides in the order of `MeshBuilder::add_box`: +z, +x, −z, −x, then the roof.
    let sides: [Face; 5] = [
        Face { nu: nx, nv: ny, at: &|i, j| Vec3::new(xs[i], ys[j], z1), pane: &|i, j| xo[i] && yo[j] },
        Face { nu: nz, nv: ny, at: &|i, j| Vec3::new(x1, ys[j], zs[nz - i]), pane: &|i, j| zo[nz - 1 - i] && yo[j] },
        Face { nu: nx, nv: ny, at: &|i, j| Vec3::new(xs[nx - i], ys[j], z0), pane: &|i, j| xo[nx - 1 - i] && yo[j] },
        Face { nu: nz, nv: ny, at: &|i, j| Vec3::new(x0, ys[j], zs[i]), pane: &|i, j| zo[i] && yo[j] },
        Face { nu: nx, nv: nz, at: &|i, j| Vec3::new(xs[i], y1, zs[nz - j]), pane: &|_, _| false },
    ];
    for (f, face) in sides.iter().enumerate() {
        let row = face.nu + 1;
        let (p00, p10, p01) = ((face.at)(0, 0), (face.at)(face.nu, 0), (face.at)(0, face.nv));
        let (du, dv) = (p10 - p00, p01 - p00);
        let normal = du.cross(dv).normalize_or_zero();
        for part in &mut parts {
            part.start_face(row * (face.nv + 1));
        }
        for j in 0..face.nv {
            for i in 0..face.nu {
                let which = if !(face.pane)(i, j) {
                    0
                } else if lit(seed, f, i, j, lit_share) {
                    2
                } else {
                    1
                };
                let part = &mut parts[which];
                let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)].map(|(ci, cj)| {
                    let p = (face.at)(ci, cj);
                    let uv = Vec2::new(
                        (p - p00).dot(du) / du.length_squared(),
                        1.0 - (p - p00).dot(dv) / dv.length_squared(),
                    );
                    part.vertex(cj * row + ci, p, normal, uv)
                });
                let [a, b, c, d] = corners;
                part.b.indices.extend_from_slice(&[a, b, c, a, c, d]);
            }
        }
    }
    let [walls, windows, lit] = parts;
    let walls = walls.build(name)?;
    Ok(Facade {
        // A box always has its roof, so the walls are never empty.
        walls: walls.ok_or_else(|| crate::Error::InvalidParams(format!("{name}: a facade without walls")))?,
        windows: windows.build(&format!("{name} windows"))?,
        lit: lit.build(&format!("{name} lit windows"))?,
    })
}

/// True when pane (i, j) of side `face` is lit: a hash of its place, so a seed lights the
/// same panes every time.
fn lit(seed: u64, face: usize, i: usize, j: usize, share: f32) -> bool {
    let key = seed ^ ((face as u64) << 48) ^ ((j as u64) << 24) ^ i as u64;
    Rng::new(key).f32() < share
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::subdivided_box;

    #[test]
    fn axis_alternates_wall_and_openings_and_spans_the_side() {
        let (lines, open) = axis(-3.0, 12.0, 5, 2.0);
        assert_eq!(open, [false, true, false, true, false]);
        assert_eq!((lines[0], lines[5]), (-3.0, 9.0));
        // Walls of width w, openings 2w: 3w + 4w = 12.
        let w = 12.0 / 7.0;
        assert!((lines[2] - lines[1] - 2.0 * w).abs() < 1e-5 && (lines[1] - lines[0] - w).abs() < 1e-5);
        // An even count ends with wall as well; a single cell is wall.
        assert_eq!(axis(0.0, 1.0, 4, 2.0).1, [false, true, false, false]);
        assert_eq!(axis(0.0, 1.0, 1, 2.0).1, [false]);
    }

    #[test]
    fn the_three_meshes_hold_the_even_box_s_triangles_facing_out() {
        let (min, max, cells) = (Vec3::new(-7.0, 0.0, -6.0), Vec3::new(7.0, 30.0, 6.0), [11, 15, 9]);
        let f = facade("b", min, max, cells, 7, 0.2).unwrap();
        let even = subdivided_box("b", min, max, cells, false).unwrap();
        let (windows, lit) = (f.windows.as_ref().unwrap(), f.lit.as_ref().unwrap());
        let total = f.walls.triangle_count() + windows.triangle_count() + lit.triangle_count();
        assert_eq!(total, even.triangle_count());
        // Panes: 5 window columns on x sides, 4 on z sides, 7 window bands.
        assert_eq!(windows.triangle_count() + lit.triangle_count(), 2 * 7 * (2 * 5 + 2 * 4));
        assert!(lit.triangle_count() > 0 && lit.triangle_count() < windows.triangle_count());
        let center = (min + max) * 0.5;
        for m in [&f.walls, windows, lit] {
            assert_eq!(m.degenerate_triangles(), 0);
            assert!(m.aabb().min.cmpge(min).all() && m.aabb().max.cmple(max).all());
            for t in 0..m.triangle_count() {
                let [a, b, c] = m.triangle_positions(t);
                assert!((b - a).cross(c - a).dot((a + b + c) / 3.0 - center) > 0.0, "triangle {t} faces inwards");
            }
        }
    }

    #[test]
    fn panes_share_their_corners_with_the_walls() {
        // Every pane corner is a wall vertex too (bit for bit): no T-junctions, no cracks.
        let f = facade("b", Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 20.0, 5.0), [7, 9, 7], 3, 0.3).unwrap();
        let walls: std::collections::HashSet<[u32; 3]> =
            f.walls.positions().iter().map(|p| p.to_array().map(f32::to_bits)).collect();
        for m in [f.windows.as_ref().unwrap(), f.lit.as_ref().unwrap()] {
            for p in m.positions() {
                assert!(walls.contains(&p.to_array().map(f32::to_bits)), "pane corner {p} is not on the wall grid");
            }
        }
    }

    #[test]
    fn same_seed_same_lit_windows() {
        let make = |seed| facade("b", Vec3::ZERO, Vec3::new(10.0, 30.0, 10.0), [9, 17, 9], seed, 0.25).unwrap();
        let (a, b, c) = (make(1), make(1), make(2));
        let lit = |f: &Facade| f.lit.as_ref().unwrap().positions().to_vec();
        assert_eq!(lit(&a), lit(&b));
        assert_ne!(lit(&a), lit(&c));
    }
}

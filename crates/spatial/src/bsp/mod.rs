//! BSP trees over triangles by autopartition: H. Fuchs, Z. M. Kedem and B. F. Naylor, "On
//! Visible Surface Generation by A Priori Tree Structures", SIGGRAPH 1980.
//!
//! Every node's plane is the plane of one of its triangles. The plane is chosen among a sample
//! of candidate triangles by a cost that weighs splits against balance, `cost = k · splits +
//! |front − back|`, evaluated on a sample of the node's triangles. Triangles crossing the plane
//! are split ([`split`]) into three triangles (two when a vertex lies on the plane) with their
//! winding, and so their normal, preserved; triangles in the plane (within an epsilon relative
//! to the scene size) are stored at the node. Construction and traversal use explicit stacks,
//! so degenerate inputs that make very deep trees cannot overflow the thread stack.
//!
//! Traversal for any eye: back-to-front (the painter's order: far side, node, near side) and
//! front-to-back (near side, node, far side). The eye may be a point or, for parallel
//! projections, a direction (a homogeneous point with w = 0); a walk can stop early
//! ([`BspTree::visit`]).

pub mod split;

use std::ops::ControlFlow;

use glam::{Affine3A, Vec3, Vec4};
use sightline_scene::{Aabb, Mesh};

use crate::Plane;
use split::{classify_triangle, split_triangle, Side};

const NONE: u32 = u32::MAX;

/// A triangle stored in the tree: its corners (counter-clockwise front) and the index of the
/// input triangle it came from (pieces of a split triangle share it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BspTriangle {
    /// Corners in input winding order.
    pub v: [Vec3; 3],
    /// Index of the input triangle.
    pub source: u32,
}

/// Construction parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BspParams {
    /// Candidate planes (triangles) evaluated per node.
    pub candidates: usize,
    /// Weight `k` of one split against one triangle of imbalance.
    pub split_weight: f32,
    /// Triangles evaluated per candidate (a sample of the node's triangles).
    pub sample: usize,
    /// Plane thickness relative to the scene's size.
    pub epsilon: f32,
}

impl Default for BspParams {
    fn default() -> Self {
        Self { candidates: 12, split_weight: 8.0, sample: 256, epsilon: 1e-5 }
    }
}

/// Construction counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BspStats {
    /// Number of nodes.
    pub nodes: usize,
    /// Depth of the deepest node (1 for a single node).
    pub depth: usize,
    /// Number of triangle splits performed.
    pub splits: usize,
    /// Triangles given.
    pub triangles_in: usize,
    /// Triangles stored (inputs plus the extra pieces of splits).
    pub triangles_out: usize,
}

/// The order of a walk, as seen from the eye.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BspOrder {
    /// Far side, node, near side: the painter's order.
    BackToFront,
    /// Near side, node, far side.
    FrontToBack,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    plane: Plane,
    front: u32,
    back: u32,
    first: u32,
    count: u32,
}

/// A BSP tree over triangles.
#[derive(Debug, Clone, Default)]
pub struct BspTree {
    nodes: Vec<Node>,
    triangles: Vec<BspTriangle>,
    stats: BspStats,
}

impl BspTree {
    /// Builds a tree over triangles given by their corners (source `i` = `tris[i]`).
    pub fn build(tris: &[[Vec3; 3]], params: &BspParams) -> BspTree {
        let pool: Vec<BspTriangle> =
            tris.iter().enumerate().map(|(i, v)| BspTriangle { v: *v, source: i as u32 }).collect();
        Self::build_from(pool, params)
    }

    /// Builds over a mesh's triangles transformed by `world_from_local` (source = triangle
    /// index in the mesh).
    pub fn from_mesh(mesh: &Mesh, world_from_local: &Affine3A, params: &BspParams) -> BspTree {
        let tris: Vec<[Vec3; 3]> = (0..mesh.triangle_count())
            .map(|t| mesh.triangle_positions(t).map(|p| world_from_local.transform_point3(p)))
            .collect();
        Self::build(&tris, params)
    }

    fn build_from(mut pool: Vec<BspTriangle>, params: &BspParams) -> BspTree {
        let mut tree =
            BspTree { stats: BspStats { triangles_in: pool.len(), ..Default::default() }, ..Default::default() };
        if pool.is_empty() {
            return tree;
        }
        let bounds = pool.iter().flat_map(|t| t.v).filter(|p| p.is_finite()).fold(Aabb::EMPTY, |mut b, p| {
            b.grow(p);
            b
        });
        let size = if bounds.is_empty() { 1.0 } else { bounds.extent().max_element().max(1e-12) };
        let eps = params.epsilon.max(0.0) * size;
        tree.nodes.push(Node { plane: Plane::DEGENERATE, front: NONE, back: NONE, first: 0, count: 0 });
        // Jobs: (node slot, triangle ids in the pool, depth).
        let mut jobs: Vec<(u32, Vec<u32>, usize)> = vec![(0, (0..pool.len() as u32).collect(), 1)];
        let (mut front, mut back, mut here) = (Vec::new(), Vec::new(), Vec::new());
        while let Some((slot, list, depth)) = jobs.pop() {
            tree.stats.depth = tree.stats.depth.max(depth);
            front.clear();
            back.clear();
            here.clear();
            let chosen = choose_plane(&pool, &list, params, eps);
            let plane = chosen.map(|(p, _)| p);
            match chosen {
                None => here.extend_from_slice(&list),
                Some((plane, from)) => {
                    for (at, &t) in list.iter().enumerate() {
                        let tri = pool[t as usize];
                        // The triangle the plane comes from lies on it, whatever rounding
                        // says of a sliver: so every node keeps at least one triangle and
                        // the build ends.
                        let side = if at == from { Side::On } else { classify_triangle(&plane, &tri.v, eps) };
                        match side {
                            Side::On => here.push(t),
                            Side::Front => front.push(t),
                            Side::Back => back.push(t),
                            Side::Spanning => {
                                tree.stats.splits += 1;
                                let (f, b) = split_triangle(&plane, &tri.v, eps);
                                for (pieces, out) in [(f, &mut front), (b, &mut back)] {
                                    for &v in pieces.as_slice() {
                                        out.push(pool.len() as u32);
                                        pool.push(BspTriangle { v, source: tri.source });
                                    }
                                }
                            }
                        }
                    }
                }
            }
            // A node's triangles are listed by source, so that a renderer can break ties
            // between coincident copies as in-order drawing does (smaller source on top).
            here.sort_by_key(|&t| pool[t as usize].source);
            let first = tree.triangles.len() as u32;
            tree.triangles.extend(here.iter().map(|&t| pool[t as usize]));
            let node = &mut tree.nodes[slot as usize];
            node.plane = plane.unwrap_or(Plane::DEGENERATE);
            node.first = first;
            node.count = here.len() as u32;
            for (list, is_front) in [(&mut front, true), (&mut back, false)] {
                if list.is_empty() {
                    continue;
                }
                let child = tree.nodes.len() as u32;
                tree.nodes.push(Node { plane: Plane::DEGENERATE, front: NONE, back: NONE, first: 0, count: 0 });
                let n = &mut tree.nodes[slot as usize];
                if is_front {
                    n.front = child;
                } else {
                    n.back = child;
                }
                jobs.push((child, std::mem::take(list), depth + 1));
            }
        }
        tree.stats.nodes = tree.nodes.len();
        tree.stats.triangles_out = tree.triangles.len();
        tree
    }

    /// Construction counters.
    pub fn stats(&self) -> BspStats {
        self.stats
    }

    /// The stored triangles (indices of the traversal orders refer to these).
    pub fn triangles(&self) -> &[BspTriangle] {
        &self.triangles
    }

    /// Appends stored-triangle indices in back-to-front order for `eye` (painter's order:
    /// drawing them in this order with no depth test gives the visible surface).
    pub fn back_to_front(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.visit(eye.extend(1.0), BspOrder::BackToFront, |r| {
            out.extend(r);
            ControlFlow::Continue(())
        });
    }

    /// Appends stored-triangle indices in front-to-back order for `eye`.
    pub fn front_to_back(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.visit(eye.extend(1.0), BspOrder::FrontToBack, |r| {
            out.extend(r.rev());
            ControlFlow::Continue(())
        });
    }

    /// Walks the tree in `order` as seen from `eye`, a homogeneous point: `(x, y, z, 1)` for
    /// an eye at a point (perspective), `(d, 0)` for a viewer infinitely far along the
    /// direction `d` (parallel projections: `d` points from the scene toward the viewer).
    /// The eye is in front of a node's plane when `n·xyz + d·w > 0`.
    ///
    /// `node(range)` gets the stored-triangle indices of each node in turn (the node's
    /// triangles lie in its plane, so their order among themselves does not matter; the
    /// range is ascending); it returns [`ControlFlow::Break`] to stop the walk there, e.g.
    /// when a front-to-back renderer has covered the screen. Returns the nodes visited.
    /// An explicit stack: no recursion however deep the tree.
    pub fn visit(
        &self,
        eye: Vec4,
        order: BspOrder,
        mut node: impl FnMut(std::ops::Range<u32>) -> ControlFlow<()>,
    ) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let near_first = order == BspOrder::FrontToBack;
        let mut visited = 0;
        // (node, emit its own triangles now)
        let mut stack: Vec<(u32, bool)> = vec![(0, false)];
        while let Some((i, emit)) = stack.pop() {
            let n = &self.nodes[i as usize];
            if emit {
                if node(n.first..n.first + n.count).is_break() {
                    break;
                }
                continue;
            }
            visited += 1;
            let side = n.plane.normal.dot(eye.truncate()) + n.plane.d * eye.w;
            let (near, far) = if side > 0.0 { (n.front, n.back) } else { (n.back, n.front) };
            let (first, last) = if near_first { (near, far) } else { (far, near) };
            // Pushed in reverse: `first` pops first, then the node, then `last`.
            if last != NONE {
                stack.push((last, false));
            }
            stack.push((i, true));
            if first != NONE {
                stack.push((first, false));
            }
        }
        visited
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.triangles.capacity() * std::mem::size_of::<BspTriangle>()
    }
}

/// Picks the candidate plane with the lowest `k · splits + |front − back|` over a sample of
/// the node's triangles; `None` when no candidate triangle has a plane (all zero-area).
/// The splitting plane for a node, with the list position of the triangle it comes from.
fn choose_plane(pool: &[BspTriangle], list: &[u32], params: &BspParams, eps: f32) -> Option<(Plane, usize)> {
    let n = list.len();
    let c = params.candidates.max(1);
    let step = (n / c).max(1);
    let sample_step = (n / params.sample.max(1)).max(1);
    let mut best: Option<(f32, Plane, usize)> = None;
    let mut tried = 0;
    let mut k = 0;
    // Evenly spaced candidates; zero-area ones are skipped and replaced by the next.
    while k < n && tried < c {
        let at = k;
        let tri = &pool[list[k] as usize];
        k += step;
        let Some(plane) = Plane::from_triangle(tri.v[0], tri.v[1], tri.v[2]) else {
            continue;
        };
        tried += 1;
        if n == 1 {
            return Some((plane, at));
        }
        let (mut f, mut b, mut s) = (0i64, 0i64, 0i64);
        for &t in list.iter().step_by(sample_step) {
            match classify_triangle(&plane, &pool[t as usize].v, eps) {
                Side::Front => f += 1,
                Side::Back => b += 1,
                Side::Spanning => s += 1,
                Side::On => {}
            }
        }
        let cost = params.split_weight * s as f32 + (f - b).abs() as f32;
        if best.is_none_or(|(bc, _, _)| cost < bc) {
            best = Some((cost, plane, at));
        }
    }
    if best.is_none() {
        // Fall back to any triangle with a plane.
        return list.iter().enumerate().find_map(|(at, &t)| {
            let v = pool[t as usize].v;
            Plane::from_triangle(v[0], v[1], v[2]).map(|p| (p, at))
        });
    }
    best.map(|(_, p, at)| (p, at))
}

#[cfg(test)]
mod tests;

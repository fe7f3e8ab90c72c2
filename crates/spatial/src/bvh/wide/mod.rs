//! The ray caster's BVH: a 4-wide BVH, and the two levels built from it ([`WideBlas`]
//! over a mesh's triangles, [`WideTlas`] over placed instances).
//!
//! Two builders make it. Triangle BVHs are built top-down by binned SAH, writing four-wide
//! nodes directly, as Embree builds its triangle BVHs (the `sah` module). The instance
//! level is collapsed from a binary BVH: that tree comes from our PLOC builder (Meister &
//! Bittner 2018, "Parallel Locally-Ordered Clustering for Bounding Volume Hierarchy
//! Construction"; see the `ploc` module for why not obvhs's), then obvhs's reinsertion and
//! leaf collapsing; this module collapses it to four children per node, the way wide BVHs
//! for SIMD traversal are made (Wald, Benthin & Boulos 2008, "Getting Rid of Packets";
//! Dammertz et al. 2008, "Shallow Bounding Volume Hierarchies for Fast SIMD Ray Tracing"):
//! each node keeps an inner child's place for its two children, opening the child with the
//! largest surface area first, until four slots are used.
//!
//! A [`WideNode`] stores its children's boxes as structure of arrays (two cache lines), so
//! one ray is tested against all four boxes in one SIMD operation. A child is a leaf naming
//! a run of primitives in *leaf order*; `order[k]` maps leaf-order position `k` back to the
//! caller's primitive index, so primitive data can be stored in leaf order and read
//! sequentially.
//!
//! This module holds the data structure and its builders only; casting rays through it
//! (packets, traversal, triangle tests) is the ray caster's business in `sightline-render`.
//! Unlike [`crate::Bvh`] (binary, for culling and front-to-back order), a wide BVH has no
//! rule for unbounded boxes: every box it is built from must be finite. It can be refitted
//! to moved primitives (`refit`), which the instance level uses when instances move.

mod binning;
mod blas;
mod pairing;
mod refit;
mod sah;
mod split;
mod tlas;

pub use blas::{BlasPrims, BlasQuad, BlasTriangle, WideBlas};
pub use pairing::NO_TRIANGLE;
pub use tlas::{invertible, InstanceRecord, WideTlas};

use obvhs::aabb::Aabb as ObAabb;
use obvhs::bvh2::{leaf_collapser::collapse, reinsertion::ReinsertionOptimizer, Bvh2};
use obvhs::ploc::PlocSearchDistance;
use rayon::prelude::*;
use sightline_scene::Aabb;

use crate::AabbExt;

/// Children per node.
pub const WIDTH: usize = 4;

/// `link` of an unused child slot.
pub const EMPTY_LINK: u32 = u32::MAX;

/// One child as a box plus a link (the root, and what a node slot describes).
///
/// `count == 0`: inner node, `link` is the index of its [`WideNode`].
/// `count > 0`: leaf with primitives `link .. link + count` in leaf order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideChild {
    /// Box minimum.
    pub lo: [f32; 3],
    /// Node index (inner) or first primitive (leaf).
    pub link: u32,
    /// Box maximum.
    pub hi: [f32; 3],
    /// Primitive count (0 for an inner node).
    pub count: u32,
}

impl WideChild {
    /// No child at all.
    pub const EMPTY: WideChild =
        WideChild { lo: [f32::INFINITY; 3], link: EMPTY_LINK, hi: [f32::NEG_INFINITY; 3], count: 0 };

    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count != 0
    }

    /// True for an unused slot.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.link == EMPTY_LINK
    }
}

/// An inner node: up to four children, boxes as structure of arrays.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode {
    /// Box minima, `[axis][child]`.
    pub lo: [[f32; WIDTH]; 3],
    /// Box maxima, `[axis][child]`.
    pub hi: [[f32; WIDTH]; 3],
    /// Node index (inner child), first primitive (leaf) or `EMPTY_LINK`.
    pub link: [u32; WIDTH],
    /// Primitive count (0: inner or unused).
    pub count: [u32; WIDTH],
}

impl WideNode {
    /// A node with four unused slots.
    pub const EMPTY: WideNode = WideNode {
        lo: [[f32::INFINITY; WIDTH]; 3],
        hi: [[f32::NEG_INFINITY; WIDTH]; 3],
        link: [EMPTY_LINK; WIDTH],
        count: [0; WIDTH],
    };

    /// Slot `k` (below [`WIDTH`]) as a [`WideChild`].
    #[inline]
    pub fn child(&self, k: usize) -> WideChild {
        WideChild {
            lo: [self.lo[0][k], self.lo[1][k], self.lo[2][k]],
            link: self.link[k],
            hi: [self.hi[0][k], self.hi[1][k], self.hi[2][k]],
            count: self.count[k],
        }
    }

    /// This node with its inner links moved by `node_base` and its leaf links by
    /// `prim_base`, for a subtree appended behind others.
    fn shifted(&self, node_base: u32, prim_base: u32) -> WideNode {
        let mut n = *self;
        for k in 0..WIDTH {
            n.link[k] = shift_link(n.link[k], n.count[k], node_base, prim_base);
        }
        n
    }

    fn set(&mut self, k: usize, c: &WideChild) {
        for a in 0..3 {
            self.lo[a][k] = c.lo[a];
            self.hi[a][k] = c.hi[a];
        }
        self.link[k] = c.link;
        self.count[k] = c.count;
    }
}

/// A child link (inner node when `count` is 0, else first primitive) moved by `node_base` or
/// `prim_base`; an unused slot stays unused.
fn shift_link(link: u32, count: u32, node_base: u32, prim_base: u32) -> u32 {
    match (link, count) {
        (EMPTY_LINK, _) => EMPTY_LINK,
        (l, 0) => l + node_base,
        (l, _) => l + prim_base,
    }
}

/// Which builder runs and how hard it works. The public settings
/// ([`WideBuildParams::BLAS`], [`WideBuildParams::BLAS_QUADS`], [`WideBuildParams::TLAS`])
/// are the ones the ray caster's levels use.
#[derive(Debug, Clone, Copy)]
pub struct WideBuildParams {
    /// Largest leaf.
    max_leaf: u32,
    /// Cost of a traversal step relative to a primitive test (obvhs's leaf collapse; the
    /// SAH builder's choice between a leaf and two).
    traversal_cost: f32,
    builder: Builder,
}

/// The builder of a [`WideBvh`], with the settings only it reads.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Builder {
    /// Top-down binned SAH writing 4-wide nodes directly (`sah`).
    BinnedSah,
    /// PLOC, then obvhs's reinsertion and leaf collapse, then the 4-wide layout.
    Ploc(Ploc),
}

/// The PLOC builder's settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ploc {
    /// PLOC neighbourhood.
    search: PlocSearchDistance,
    /// Reinsertion effort (0 = none).
    reinsertion: f32,
}

impl WideBuildParams {
    /// For triangle BVHs traversed by packets: binned SAH, up to four triangles per leaf.
    pub const BLAS: WideBuildParams = WideBuildParams { max_leaf: 4, traversal_cost: 1.0, builder: Builder::BinnedSah };
    /// [`WideBuildParams::BLAS`] for BVHs over quads (pairs of triangles): one per leaf. On
    /// the exported 10^6-triangle city, runs alternated, one quad per leaf was faster than
    /// two in five of six aerial rounds and two of three street rounds (four per leaf was
    /// measured only with an earlier, slower quad kernel).
    pub const BLAS_QUADS: WideBuildParams = WideBuildParams { max_leaf: 1, ..WideBuildParams::BLAS };
    /// For the instance BVH: PLOC, one instance per leaf.
    pub const TLAS: WideBuildParams = WideBuildParams {
        max_leaf: 1,
        traversal_cost: 1.0,
        builder: Builder::Ploc(Ploc { search: PlocSearchDistance::Medium, reinsertion: 0.1 }),
    };
    /// [`WideBuildParams::BLAS`] built by PLOC (what BLASes used before the SAH builder),
    /// for tests that hold the two builders side by side.
    #[cfg(test)]
    pub(crate) const BLAS_PLOC: WideBuildParams = WideBuildParams {
        builder: Builder::Ploc(Ploc { search: PlocSearchDistance::Low, reinsertion: 0.05 }),
        ..WideBuildParams::BLAS
    };
}

/// A 4-wide BVH over a list of boxes (primitive `i` is `boxes[i]` of the build).
#[derive(Debug, Clone)]
pub struct WideBvh {
    /// The root as a child (a leaf for tiny trees; empty for no primitives).
    root: WideChild,
    /// Inner nodes; the root's is `nodes[root.link]` when the root is inner.
    nodes: Vec<WideNode>,
    /// Leaf-order position → caller's primitive index.
    order: Vec<u32>,
    /// Levels on the longest root-to-leaf path, the leaf's included (sizes traversal stacks).
    depth: usize,
}

impl WideBvh {
    /// Builds over `boxes` (all finite). Empty input gives an empty tree.
    pub fn build(boxes: &[Aabb], params: WideBuildParams) -> WideBvh {
        let boxes: Vec<ObAabb> = boxes.iter().map(|b| b.to_obvhs()).collect();
        Self::build_obvhs(&boxes, params)
    }

    /// The root as a child: a leaf for trees of one leaf, [`WideChild::EMPTY`] for an empty
    /// tree, else an inner child whose `link` indexes [`WideBvh::nodes`].
    #[inline]
    pub fn root(&self) -> &WideChild {
        &self.root
    }

    /// The inner nodes, the root's first; a node's inner children come after it (what
    /// [`WideBvh::refit`] relies on).
    #[inline]
    pub fn nodes(&self) -> &[WideNode] {
        &self.nodes
    }

    /// Leaf-order position → the caller's primitive index (a leaf's primitives are
    /// `order[link .. link + count]`).
    #[inline]
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Levels on the longest root-to-leaf path, the leaf's included (0 when empty; a
    /// traversal stack holds up to three entries per level).
    #[inline]
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Builds over obvhs boxes (all finite); what [`WideBvh::build`] does after converting.
    /// Large PLOC builds run as four Morton runs in parallel (see `split`).
    pub(crate) fn build_obvhs(boxes: &[ObAabb], params: WideBuildParams) -> WideBvh {
        match params.builder {
            Builder::BinnedSah => sah::build(boxes.len(), params.max_leaf, params.traversal_cost, |i| boxes[i]),
            Builder::Ploc(ploc) if boxes.len() >= split::SPLIT_MIN => split::build_split(boxes, params, ploc),
            Builder::Ploc(ploc) => Self::build_serial(boxes, params, ploc),
        }
    }

    /// Builds over `count` primitives whose boxes (all finite) `bounds(i)` gives, without
    /// gathering the boxes first where the builder does not need them in an array.
    pub(crate) fn build_fn(count: usize, params: WideBuildParams, bounds: impl Fn(usize) -> ObAabb + Sync) -> WideBvh {
        if let Builder::BinnedSah = params.builder {
            return sah::build(count, params.max_leaf, params.traversal_cost, bounds);
        }
        let boxes: Vec<ObAabb> = (0..count).into_par_iter().map(&bounds).collect();
        Self::build_obvhs(&boxes, params)
    }

    /// One PLOC build, reinsertion and collapse over all of `boxes`.
    fn build_serial(boxes: &[ObAabb], params: WideBuildParams, ploc: Ploc) -> WideBvh {
        if boxes.is_empty() {
            return WideBvh { root: WideChild::EMPTY, nodes: Vec::new(), order: Vec::new(), depth: 0 };
        }
        let (mut bvh2, _) = super::ploc::build(boxes, ploc.search, 2);
        let mut reinsert = ReinsertionOptimizer::default();
        reinsert.run(&mut bvh2, ploc.reinsertion, None);
        collapse(&mut bvh2, params.max_leaf.clamp(1, 255), params.traversal_cost);
        Self::from_bvh2(&bvh2)
    }

    /// Collapses an obvhs BVH2 to four children per node. A node's inner children are
    /// placed together when the node is filled, after it; their subtrees follow, first
    /// child first.
    fn from_bvh2(b: &Bvh2) -> WideBvh {
        let mut nodes: Vec<WideNode> = Vec::with_capacity(b.nodes.len() / 3 + 1);
        let mut order = Vec::with_capacity(b.primitive_indices.len());
        if b.nodes.is_empty() {
            return WideBvh { root: WideChild::EMPTY, nodes, order, depth: 0 };
        }
        let make = |idx: usize, order: &mut Vec<u32>, nodes: &mut Vec<WideNode>| -> WideChild {
            let n = &b.nodes[idx];
            let bb = n.aabb();
            let (lo, hi) = (bb.min.to_array(), bb.max.to_array());
            if n.is_leaf() {
                let first = order.len() as u32;
                let s = n.first_index as usize;
                let e = (s + n.prim_count as usize).min(b.primitive_indices.len());
                if e <= s {
                    return WideChild::EMPTY; // malformed leaf: never hit
                }
                order.extend_from_slice(&b.primitive_indices[s..e]);
                WideChild { lo, link: first, hi, count: (e - s) as u32 }
            } else {
                nodes.push(WideNode::EMPTY);
                WideChild { lo, link: nodes.len() as u32 - 1, hi, count: 0 }
            }
        };
        let inner = |i: usize| i < b.nodes.len() && !b.nodes[i].is_leaf();
        let root = make(0, &mut order, &mut nodes);
        // (obvhs node whose subtree fills node `p`, depth of `p`)
        let mut stack: Vec<(usize, u32, usize)> = Vec::new();
        if !root.is_leaf() && !root.is_empty() {
            stack.push((0, root.link, 1));
        }
        let mut depth = 1;
        while let Some((n, p, d)) = stack.pop() {
            depth = depth.max(d + 1);
            // Open inner children, largest surface area first, until four slots are used.
            let first = b.nodes[n].first_index as usize;
            let mut kids = [usize::MAX; WIDTH];
            let mut nk = 0;
            for i in [first, first + 1] {
                if i < b.nodes.len() {
                    kids[nk] = i;
                    nk += 1;
                }
            }
            while nk < WIDTH {
                let mut best: Option<(usize, f32)> = None;
                for (k, &i) in kids[..nk].iter().enumerate() {
                    let a = b.nodes[i].aabb().half_area();
                    if inner(i) && best.is_none_or(|(_, ba)| a > ba) {
                        best = Some((k, a));
                    }
                }
                let Some((k, _)) = best else { break };
                let f = b.nodes[kids[k]].first_index as usize;
                if f + 1 >= b.nodes.len() {
                    break;
                }
                kids[k] = f;
                kids[nk] = f + 1;
                nk += 1;
            }
            let mut node = WideNode::EMPTY;
            let mut pushes = [None; WIDTH];
            for (k, &i) in kids[..nk].iter().enumerate() {
                let c = make(i, &mut order, &mut nodes);
                node.set(k, &c);
                if !c.is_leaf() && !c.is_empty() {
                    pushes[k] = Some((i, c.link, d + 1));
                }
            }
            nodes[p as usize] = node;
            // Reverse, so the first child's subtree is laid out (and popped) first.
            for e in pushes.iter().rev().flatten() {
                stack.push(*e);
            }
        }
        WideBvh { root, nodes, order, depth }
    }

    /// Checks the structure: every primitive exactly once, children inside their parents'
    /// boxes, links in range. Returns a description of the first problem.
    pub fn validate(&self, prims: usize) -> Result<(), String> {
        let mut seen = vec![false; prims];
        let mut stack = vec![self.root];
        let inside = |c: &WideChild, p: &WideChild| (0..3).all(|a| c.lo[a] >= p.lo[a] && c.hi[a] <= p.hi[a]);
        while let Some(c) = stack.pop() {
            if c.is_empty() {
                continue;
            }
            if c.is_leaf() {
                for k in c.link..c.link + c.count {
                    let i = *self.order.get(k as usize).ok_or("leaf out of range")? as usize;
                    if i >= prims || std::mem::replace(&mut seen[i], true) {
                        return Err(format!("primitive {i} missing or twice"));
                    }
                }
            } else {
                let n = self.nodes.get(c.link as usize).ok_or("node out of range")?;
                for k in 0..WIDTH {
                    let ch = n.child(k);
                    if ch.is_empty() {
                        continue;
                    }
                    if !inside(&ch, &c) {
                        return Err("child box outside parent".into());
                    }
                    stack.push(ch);
                }
            }
        }
        if seen.iter().all(|&s| s) {
            Ok(())
        } else {
            Err("some primitive is in no leaf".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    #[test]
    fn layouts_are_valid_for_all_sizes() {
        for n in [0usize, 1, 2, 3, 7, 100, 1000] {
            let boxes: Vec<ObAabb> = (0..n)
                .map(|i| {
                    let p = Vec3A::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32);
                    ObAabb::new(p, p + 0.5)
                })
                .collect();
            for params in [WideBuildParams::BLAS, WideBuildParams::TLAS] {
                let b = WideBvh::build_obvhs(&boxes, params);
                b.validate(n).unwrap();
                // The public builder converts the boxes exactly: the same tree.
                let same: Vec<Aabb> = boxes.iter().map(Aabb::from_obvhs).collect();
                assert_eq!(WideBvh::build(&same, params).order(), b.order());
                assert_eq!(b.order.len(), n);
                // Wide: far fewer nodes than the n - 1 inner nodes of a binary tree. (Not n / 3:
                // collapsing two levels at a time leaves the bottom pairs of a balanced tree of
                // odd depth in nodes of their own, up to about 2n / 3 nodes.)
                if n >= 100 && params.max_leaf == 1 {
                    assert!(3 * b.nodes.len() <= 2 * n, "{} nodes for {n} leaves", b.nodes.len());
                }
            }
        }
    }
}

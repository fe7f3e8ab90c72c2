//! The ray caster's BVH layout: a binary BVH stored as sibling pairs, converted from obvhs.
//!
//! obvhs builds the tree (PLOC, Meister & Bittner 2018, "Parallel Locally-Ordered
//! Clustering for Bounding Volume Hierarchy Construction", then reinsertion and leaf
//! collapsing); this module re-lays it out for packet traversal. Each inner node is one
//! 64-byte [`Pair`] holding the boxes of its two children, so one cache line gives everything
//! a visit needs; a [`Child`] either links to the pair of its own children or is a leaf
//! naming a run of primitives in *leaf order*. `order[k]` maps leaf-order position `k` back
//! to the caller's primitive index, so the primitive data can be stored in leaf order and
//! read sequentially.

use obvhs::aabb::Aabb as ObAabb;
use obvhs::bvh2::{leaf_collapser::collapse, reinsertion::ReinsertionOptimizer, Bvh2};
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

/// One child slot of a [`Pair`]: a box plus a link.
///
/// `count == 0`: inner node, `link` is the index of the pair holding its children.
/// `count > 0`: leaf with primitives `link .. link + count` in leaf order.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub(crate) struct Child {
    /// Box minimum.
    pub lo: [f32; 3],
    /// Pair index (inner) or first primitive (leaf).
    pub link: u32,
    /// Box maximum.
    pub hi: [f32; 3],
    /// Primitive count (0 for an inner node).
    pub count: u32,
}

impl Child {
    /// A child that nothing can hit (an empty box).
    pub const EMPTY: Child = Child { lo: [f32::INFINITY; 3], link: 0, hi: [f32::NEG_INFINITY; 3], count: 0 };

    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count != 0
    }
}

/// The two children of an inner node, one cache line.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct Pair(pub [Child; 2]);

/// How hard the builder works: leaf size and PLOC search effort.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BuildParams {
    /// Largest leaf.
    pub max_leaf: u32,
    /// obvhs collapse cost of a traversal step relative to a primitive test.
    pub traversal_cost: f32,
    /// PLOC neighbourhood.
    pub search: PlocSearchDistance,
    /// Reinsertion effort (0 = none).
    pub reinsertion: f32,
}

impl BuildParams {
    /// For triangle BVHs traversed by packets.
    pub const BLAS: BuildParams =
        BuildParams { max_leaf: 4, traversal_cost: 1.0, search: PlocSearchDistance::Low, reinsertion: 0.05 };
    /// For the instance BVH: one instance per leaf.
    pub const TLAS: BuildParams =
        BuildParams { max_leaf: 1, traversal_cost: 1.0, search: PlocSearchDistance::Medium, reinsertion: 0.1 };
}

/// A binary BVH in pair layout.
#[derive(Debug, Clone)]
pub(crate) struct Bvh {
    /// The root as a child slot (a leaf for tiny trees; empty for no primitives).
    pub root: Child,
    /// Inner nodes.
    pub pairs: Vec<Pair>,
    /// Leaf-order position → caller's primitive index.
    pub order: Vec<u32>,
    /// Longest root-to-leaf path (sizes traversal stacks).
    pub depth: usize,
}

impl Bvh {
    /// Builds over the given boxes (all finite). Empty input gives an empty tree.
    pub fn build(boxes: &[ObAabb], params: BuildParams) -> Bvh {
        if boxes.is_empty() {
            return Bvh { root: Child::EMPTY, pairs: Vec::new(), order: Vec::new(), depth: 0 };
        }
        let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
            params.search,
            boxes,
            (0..boxes.len() as u32).collect(),
            SortPrecision::U64,
            2,
        );
        let mut reinsert = ReinsertionOptimizer::default();
        reinsert.run(&mut bvh2, params.reinsertion, None);
        collapse(&mut bvh2, params.max_leaf.clamp(1, 255), params.traversal_cost);
        Self::from_bvh2(&bvh2)
    }

    /// Re-lays out an obvhs BVH2 (depth first, so a subtree's pairs are contiguous).
    pub fn from_bvh2(b: &Bvh2) -> Bvh {
        let mut pairs: Vec<Pair> = Vec::with_capacity(b.nodes.len() / 2);
        let mut order = Vec::with_capacity(b.primitive_indices.len());
        if b.nodes.is_empty() {
            return Bvh { root: Child::EMPTY, pairs, order, depth: 0 };
        }
        let make = |idx: usize, order: &mut Vec<u32>, pairs: &mut Vec<Pair>| -> Child {
            let n = &b.nodes[idx];
            let bb = n.aabb();
            let (lo, hi) = (bb.min.to_array(), bb.max.to_array());
            if n.is_leaf() {
                let first = order.len() as u32;
                let s = n.first_index as usize;
                let e = (s + n.prim_count as usize).min(b.primitive_indices.len());
                if e <= s {
                    return Child::EMPTY; // malformed leaf: never hit
                }
                order.extend_from_slice(&b.primitive_indices[s..e]);
                Child { lo, link: first, hi, count: (e - s) as u32 }
            } else {
                pairs.push(Pair([Child::EMPTY; 2]));
                Child { lo, link: pairs.len() as u32 - 1, hi, count: 0 }
            }
        };
        let root = make(0, &mut order, &mut pairs);
        // (obvhs node whose children fill pair `p`, depth of the pair)
        let mut stack: Vec<(usize, u32, usize)> = Vec::new();
        if !root.is_leaf() {
            stack.push((0, root.link, 1));
        }
        let mut depth = 1;
        while let Some((node, p, d)) = stack.pop() {
            depth = depth.max(d + 1);
            let first = b.nodes[node].first_index as usize;
            let mut kids = [Child::EMPTY; 2];
            for (k, kid) in kids.iter_mut().enumerate() {
                if first + k < b.nodes.len() {
                    *kid = make(first + k, &mut order, &mut pairs);
                }
            }
            pairs[p as usize] = Pair(kids);
            // Push the right child first so the left subtree is laid out (and popped) first.
            for k in [1, 0] {
                if !kids[k].is_leaf() && kids[k].lo[0] <= kids[k].hi[0] {
                    stack.push((first + k, kids[k].link, d + 1));
                }
            }
        }
        Bvh { root, pairs, order, depth }
    }

    /// Checks the structure: every primitive exactly once, children inside their parents'
    /// boxes, links in range. Returns a description of the first problem.
    #[cfg(test)]
    pub fn validate(&self, prims: usize) -> Result<(), String> {
        let mut seen = vec![false; prims];
        let mut stack = vec![self.root];
        let inside = |c: &Child, p: &Child| (0..3).all(|a| c.lo[a] >= p.lo[a] && c.hi[a] <= p.hi[a]);
        while let Some(c) = stack.pop() {
            if c.is_leaf() {
                for k in c.link..c.link + c.count {
                    let i = *self.order.get(k as usize).ok_or("leaf out of range")? as usize;
                    if i >= prims || std::mem::replace(&mut seen[i], true) {
                        return Err(format!("primitive {i} missing or twice"));
                    }
                }
            } else if c.lo[0] <= c.hi[0] {
                let p = self.pairs.get(c.link as usize).ok_or("pair out of range")?;
                for k in p.0 {
                    if !inside(&k, &c) {
                        return Err("child box outside parent".into());
                    }
                    stack.push(k);
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
            for params in [BuildParams::BLAS, BuildParams::TLAS] {
                let b = Bvh::build(&boxes, params);
                b.validate(n).unwrap();
                assert_eq!(b.order.len(), n);
            }
        }
    }
}

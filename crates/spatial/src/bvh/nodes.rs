//! The nodes of a [`super::Bvh`], and their array, laid out so that every sibling pair is
//! one cache line.
//!
//! A node is 32 bytes and the root is alone at index 0, so the pairs are nodes `(1, 2)`,
//! `(3, 4)`, …: a pair fills 64 bytes, exactly one line when it starts on one. A `Vec` from
//! the system allocator gives no such start (a large block begins 16 bytes past a line), and
//! then every pair spans two lines, its first node across both: a walk that reads a pair
//! waited for two lines, and asked ahead for one of them only. The array here keeps one
//! node's worth of padding before the root, so that node `j` is slot `j + 1` of lines that
//! start on a boundary and pair `(2k + 1, 2k + 2)` is line `k + 1`, and derefs to the nodes.

use std::fmt;
use std::ops::{Deref, DerefMut};

use glam::Vec3;
use sightline_scene::Aabb;

/// A BVH node: a box and either two children (`count == 0`: children `index`, `index + 1`) or
/// a range of items (`count > 0`: `items[index .. index + count]`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct BvhNode {
    /// Smallest corner.
    pub min: Vec3,
    /// Number of items (0 for inner nodes).
    pub count: u32,
    /// Largest corner.
    pub max: Vec3,
    /// First child (inner) or first item slot (leaf).
    pub index: u32,
}

impl BvhNode {
    /// The node's box.
    #[inline]
    pub fn aabb(&self) -> Aabb {
        Aabb::new(self.min, self.max)
    }
    /// True for leaves.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Two nodes on one cache line.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Line([BvhNode; 2]);

/// The padding before the root, and the empty slot after an even node count.
const PAD: BvhNode = BvhNode { min: Vec3::ZERO, count: 0, max: Vec3::ZERO, index: 0 };

/// A BVH's nodes, root first, with every sibling pair on its own cache line; derefs to
/// `[BvhNode]`.
///
/// Invariant: `lines` holds `len + 1` initialized node slots at least (slot 0 is padding).
#[derive(Clone, Default)]
pub(crate) struct NodeArray {
    lines: Vec<Line>,
    len: usize,
}

impl NodeArray {
    /// An empty array with room for `n` nodes.
    pub(crate) fn with_capacity(n: usize) -> Self {
        NodeArray { lines: Vec::with_capacity((n + 1).div_ceil(2)), len: 0 }
    }

    /// Appends `node`.
    pub(crate) fn push(&mut self, node: BvhNode) {
        let slot = self.len + 1;
        if slot.is_multiple_of(2) {
            self.lines.push(Line([node, PAD]));
        } else if let Some(line) = self.lines.last_mut() {
            line.0[1] = node;
        } else {
            self.lines.push(Line([PAD, node]));
        }
        self.len += 1;
    }

    /// Heap bytes held.
    pub(crate) fn memory_bytes(&self) -> usize {
        self.lines.capacity() * size_of::<Line>()
    }
}

impl Deref for NodeArray {
    type Target = [BvhNode];

    #[inline(always)]
    fn deref(&self) -> &[BvhNode] {
        // SAFETY: `Line` is `repr(C)` around two nodes with no padding (64 bytes, 32 each),
        // so the lines are a contiguous run of nodes; by the invariant slots `1..=len` are
        // initialized. With no lines, `len` is 0 and the pointer (dangling, aligned, non-null)
        // is never read.
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast::<BvhNode>().wrapping_add(1), self.len) }
    }
}

impl DerefMut for NodeArray {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [BvhNode] {
        // SAFETY: as in `deref`; `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast::<BvhNode>().wrapping_add(1), self.len) }
    }
}

impl PartialEq for NodeArray {
    /// The same nodes (the padding aside).
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl fmt::Debug for NodeArray {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        (**self).fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(i: u32) -> BvhNode {
        BvhNode { min: Vec3::splat(i as f32), count: i, max: Vec3::splat(i as f32 + 1.0), index: 2 * i }
    }

    /// The array reads back what was pushed, for every length, and each pair after the root
    /// starts a cache line.
    #[test]
    fn pairs_start_cache_lines_and_nodes_read_back() {
        assert!(NodeArray::default().is_empty());
        for n in 0..9u32 {
            let mut a = NodeArray::with_capacity(n as usize);
            for i in 0..n {
                a.push(node(i));
            }
            let want: Vec<BvhNode> = (0..n).map(node).collect();
            assert_eq!(&*a, want.as_slice());
            for k in (1..a.len()).step_by(2) {
                assert_eq!(&a[k] as *const BvhNode as usize % 64, 0, "pair at node {k} of {n}");
            }
            a.iter_mut().for_each(|x| x.count += 1);
            assert!(a.iter().zip(&want).all(|(x, w)| x.count == w.count + 1));
            let copy = a.clone();
            assert_eq!(&*copy, &*a);
        }
    }
}

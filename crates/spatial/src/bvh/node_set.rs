//! Sets of a BVH's nodes: those holding some item of a set of items, a bit a node, found in
//! one sweep from the last node back (children come after their parents). A walk passing
//! over items drawn already ([`crate::FrontToBackCursor::next_batch_except`]) leaves these
//! nodes untested: they hold something just drawn and are rarely hidden.

use super::Bvh;

/// A set of a BVH's nodes, a bit a node: those holding some item of a set
/// ([`Bvh::nodes_holding`]), which [`crate::FrontToBackCursor::next_batch_except`] does not ask
/// about.
#[derive(Debug, Clone, Default)]
pub struct NodeSet {
    bits: Vec<u64>,
}

impl NodeSet {
    /// True when node `node` is in the set.
    #[inline(always)]
    pub fn contains(&self, node: u32) -> bool {
        self.bits.get(node as usize / 64).is_some_and(|w| w >> (node % 64) & 1 != 0)
    }

    /// Empties the set (keeping its memory).
    pub fn clear(&mut self) {
        self.bits.clear();
    }
}

impl Bvh {
    /// The nodes holding an item for which `holds(item)` is true, into `out`: one sweep from
    /// the last node back (children come after their parents), a leaf asking about its
    /// items, an inner node taking its children's answers.
    pub fn nodes_holding(&self, holds: impl Fn(u32) -> bool, out: &mut NodeSet) {
        out.bits.clear();
        out.bits.resize(self.nodes.len().div_ceil(64), 0);
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            let k = n.index as usize;
            let held = if n.is_leaf() {
                self.items[k..k + n.count as usize].iter().any(|&item| holds(item))
            } else {
                out.contains(k as u32) || out.contains(k as u32 + 1)
            };
            out.bits[i / 64] |= (held as u64) << (i % 64);
        }
    }
}

//! Front-to-back traversal of a BVH with a per-node visibility callback, whole or in
//! resumable batches.
//!
//! At each inner node the child whose box is nearer to the eye (squared distance to the
//! box, 0 when the eye is inside; ties broken by the distance to the box center) is visited
//! first, and a leaf's items are visited nearest first. This is the order an occlusion culler
//! wants (Greene, Kass & Miller 1993): near occluders are drawn before the far nodes are
//! tested against the depth pyramid. Depth first, it is only roughly front to back (a nearer
//! child's whole subtree comes before its sibling), so [`FrontToBackCursor::nearest_first`]
//! can put the k nearest items ahead of it, found best-first with a priority queue (the
//! k-nearest-neighbor search of Roussopoulos, Kelley & Vincent, SIGMOD 1995, with box
//! distances). [`FrontToBackCursor`] stops after a batch of items and resumes where it
//! stopped, so the caller can draw a batch and refresh its pyramid between batches without
//! fighting the borrow checker over callbacks. Frustum tests on the way are those of
//! [`super::traverse`] (plane masking).
//!
//! A walk that tests nothing per item (drawing every occluder) can take a small subtree
//! lying inside the frustum whole ([`FrontToBackCursor::whole_subtrees`]): the depth-first
//! layout keeps a subtree's items contiguous, so they go out as one range in slot order, at
//! the cost of a copy, instead of paying for each node, box distance and leaf sort under
//! it. The order changes only inside such a subtree, whose items lie close together.
//!
//! A walk can pass over items the caller has drawn already ([`FrontToBackCursor::next_batch_except`]):
//! they are neither asked about nor emitted, and the others come in the same order; and it
//! can leave the nodes holding them ([`Bvh::nodes_holding`]) unasked, as Coherent
//! Hierarchical Culling (Bittner, Wimmer, Piringer & Purgathofer, Eurographics 2004) leaves
//! nodes visible in the last frame untested.
//!
//! A walk asking a costly question per node (an occlusion test) can find each batch on every
//! worker ([`FrontToBackCursor::next_batch_parallel`]): the subtrees on the stack are walked
//! at once and their items put together in stack order, the same batches on any number of
//! threads.

use glam::Vec3;
use sightline_scene::Aabb;

use super::node_set::NodeSet;
use super::{Bvh, BvhNode};
use crate::hint::prefetch;
use crate::{AabbExt, Frustum, PlaneMask, Visible, Visit, ALL_PLANES};

const KIND_NODE: u8 = 0;
const KIND_ITEM: u8 = 1;
const KIND_UNBOUNDED: u8 = 2;
/// An item put ahead of the walk, already classified against the frustum (its mask is the
/// one after that test).
const KIND_SEED: u8 = 3;
/// The largest whole subtree: the tree's sizes saturate at 255, which means "255 or more".
const MAX_WHOLE: u32 = 254;
/// The rest of a whole subtree's items, in slot order: `id` is the next slot and `mask`
/// holds the count left (the subtree is inside the frustum, so it needs no planes).
const KIND_RANGE: u8 = 4;

#[derive(Debug, Clone, Copy)]
struct Entry {
    id: u32,
    mask: PlaneMask,
    kind: u8,
}

/// A front-to-back traversal that can stop after a batch of visible items and resume.
///
/// ```
/// # use sightline_spatial::*;
/// # use glam::Vec3;
/// let boxes: Vec<Aabb> = (0..100)
///     .map(|i| Aabb::new(Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32 + 0.5, 1.0, 1.0)))
///     .collect();
/// let bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
/// let mut cursor = FrontToBackCursor::new(&bvh, None, Vec3::new(-10.0, 0.5, 0.5));
/// let mut batch = Vec::new();
/// let mut all = Vec::new();
/// while cursor.next_batch(&bvh, |_node_box| true, 16, &mut batch) {
///     all.extend(batch.drain(..).map(|v| v.index)); // draw, then refresh the depth pyramid
/// }
/// all.extend(batch.drain(..).map(|v| v.index));
/// assert_eq!(all.len(), 100);
/// assert_eq!(all[0], 0); // nearest first
/// ```
#[derive(Debug, Clone)]
pub struct FrontToBackCursor {
    stack: Vec<Entry>,
    frustum: Option<Frustum>,
    eye: Vec3,
    /// The items put ahead of the walk ([`FrontToBackCursor::nearest_first`]): the walk
    /// passes over them.
    seeded: Seeds,
    /// Subtrees inside the frustum with at most this many items go out whole, in slot order
    /// ([`FrontToBackCursor::whole_subtrees`]; 0: none).
    whole: u32,
}

impl FrontToBackCursor {
    /// Starts a traversal of `bvh` for `eye`, culling against `frustum` when given.
    /// Unbounded items come first.
    pub fn new(bvh: &Bvh, frustum: Option<&Frustum>, eye: Vec3) -> Self {
        let mut stack = Vec::with_capacity(64);
        if !bvh.nodes.is_empty() {
            stack.push(Entry { id: 0, mask: ALL_PLANES, kind: KIND_NODE });
        }
        for k in (0..bvh.unbounded.len()).rev() {
            stack.push(Entry { id: k as u32, mask: ALL_PLANES, kind: KIND_UNBOUNDED });
        }
        Self { stack, frustum: frustum.copied(), eye, seeded: Seeds::default(), whole: 0 }
    }

    /// Lets a subtree that lies inside the frustum and holds at most `max_items` items (at
    /// most 254) go out whole: its items in slot order, after its own box was asked about,
    /// instead of front to back one by one. Items of one small subtree lie close together,
    /// so the order barely changes, and the walk no longer pays for their nodes, the
    /// distances to their boxes and the sorting of each leaf: a walk that tests nothing per
    /// item (drawing every occluder in the frustum) spends most of its time there when the
    /// items are many and small. A walk that tests items against a depth pyramid wants
    /// each asked about, and leaves this at 0 (the default: none).
    pub fn whole_subtrees(mut self, max_items: u32) -> Self {
        self.whole = max_items.min(MAX_WHOLE);
        self
    }

    /// Puts the `k` items nearest the eye ahead of the walk, nearest first: the items in the
    /// frustum whose boxes are nearest (squared distance to the box), found best-first with a
    /// priority queue over nodes. The depth-first walk only approximates front to back: it
    /// finishes the nearer child's whole subtree first, so a box beside the eye can wait
    /// behind thousands of farther ones in a sibling whose box holds the eye. Drawing the
    /// nearest boxes first gives the depth pyramid its best occluders at once. The walk then
    /// passes over the seeds; every item is still emitted once, and the set is the same.
    /// Unbounded items still come first. Takes effect before the first batch only (later,
    /// or a second time, it changes nothing).
    pub fn nearest_first(mut self, bvh: &Bvh, k: usize) -> Self {
        // Only before the walk has left the root (at the stack's bottom), and only once: a
        // walk under way may have emitted some of the nearest already.
        let fresh = self.stack.first().is_some_and(|e| e.kind == KIND_NODE && e.id == 0);
        if !fresh || !self.seeded.slots.is_empty() {
            return self;
        }
        let found = nearest_items(bvh, self.frustum.as_ref(), self.eye, k);
        self.seeded = Seeds::new(found.iter().map(|s| s.0));
        // Above the root, below the unbounded items; farthest first, so that the nearest
        // pops first.
        let seeds = found.iter().rev().map(|&(id, mask)| Entry { id, mask, kind: KIND_SEED });
        self.stack.splice(1..1, seeds);
        self
    }

    /// True when the traversal has finished.
    pub fn is_done(&self) -> bool {
        self.stack.is_empty()
    }

    /// Continues the traversal: `possibly_visible(box)` is asked for every node and item box
    /// that passes the frustum (false skips it and its subtree); visible items are appended to
    /// `out` until it has grown by `max_items`. Returns true when more may remain.
    pub fn next_batch(
        &mut self,
        bvh: &Bvh,
        possibly_visible: impl FnMut(&Aabb) -> bool,
        max_items: usize,
        out: &mut Vec<Visible>,
    ) -> bool {
        self.next_batch_except(bvh, possibly_visible, |_| false, &NodeSet::default(), max_items, out)
    }

    /// [`FrontToBackCursor::next_batch`], passing over the items for which `passed_over(item)`
    /// holds: they are neither asked about nor emitted; and the nodes in `known` are not
    /// asked about (taken as possibly visible). An occlusion culler that has drawn some
    /// items already this frame (last frame's visible set, say) passes them over, and
    /// saves a pyramid test per such item whose answer would change nothing; given the
    /// nodes that hold them ([`Bvh::nodes_holding`]), which hold something just drawn and
    /// are rarely found hidden, it saves their tests too.
    pub fn next_batch_except(
        &mut self,
        bvh: &Bvh,
        mut possibly_visible: impl FnMut(&Aabb) -> bool,
        passed_over: impl Fn(u32) -> bool,
        known: &NodeSet,
        max_items: usize,
        out: &mut Vec<Visible>,
    ) -> bool {
        let mut emitted = 0usize;
        let max = max_items.max(1);
        let walk = Walk { frustum: self.frustum.as_ref(), eye: self.eye, seeded: &self.seeded, whole: self.whole };
        let node_visit = |b: &Aabb| {
            if possibly_visible(b) {
                Visit::Continue
            } else {
                Visit::Skip
            }
        };
        let item_visit = |v| {
            out.push(v);
            emitted += 1;
            if emitted >= max {
                Visit::Stop
            } else {
                Visit::Continue
            }
        };
        // Two forms, so that walks without whole subtrees carry none of their tests.
        if self.whole == 0 {
            run::<false>(bvh, walk, &mut self.stack, node_visit, (passed_over, known), item_visit);
        } else {
            run::<true>(bvh, walk, &mut self.stack, node_visit, (passed_over, known), item_visit);
        }
        !self.stack.is_empty()
    }
}

/// The front-to-back core shared by the callback and cursor forms. Returns when the stack is
/// empty or a callback said `Stop` (the stack then holds the rest of the traversal). Items
/// for which `passed_over` holds are skipped before any test (it is asked through `get`, no
/// bounds check that could panic, so that a constant `false` costs no load of the item), and
/// `node_visit` is not asked about the nodes in `known`.
/// `WHOLE`: the walk may take subtrees whole (`walk.whole` > 0).
fn run<const WHOLE: bool>(
    bvh: &Bvh,
    walk: Walk,
    stack: &mut Vec<Entry>,
    mut node_visit: impl FnMut(&Aabb) -> Visit,
    (passed_over, known): (impl Fn(u32) -> bool, &NodeSet),
    mut item_visit: impl FnMut(Visible) -> Visit,
) {
    let passed_over_slot = |slot: u32| bvh.items.get(slot as usize).is_some_and(|&i| passed_over(i));
    let Walk { frustum, eye, seeded, whole } = walk;
    let mut order: Vec<(f32, u32)> = Vec::new();
    while let Some(e) = stack.pop() {
        let mut mask = e.mask;
        match e.kind {
            KIND_UNBOUNDED => {
                let id = bvh.unbounded[e.id as usize];
                if passed_over(id) {
                    continue;
                }
                let b = Aabb::new(Vec3::NAN, Vec3::NAN);
                match node_visit(&b) {
                    Visit::Stop => return,
                    Visit::Skip => continue,
                    Visit::Continue => {}
                }
                if item_visit(Visible { index: id, inside: false }) == Visit::Stop {
                    return;
                }
            }
            KIND_RANGE => {
                let range = (e.id, e.mask as u32);
                if WHOLE && visit_range(bvh, frustum.is_some(), seeded, range, stack, &passed_over, &mut item_visit) {
                    return;
                }
            }
            KIND_SEED | KIND_ITEM => {
                // A seed was classified against the frustum when it was found; the walk
                // passes over it where it meets it as an item.
                let item = e.kind == KIND_ITEM;
                if (item && seeded.contains(e.id)) || passed_over_slot(e.id) {
                    continue;
                }
                let b = &bvh.item_boxes[e.id as usize];
                if Frustum::excludes(frustum.filter(|_| item), b, &mut mask) {
                    continue;
                }
                match node_visit(b) {
                    Visit::Stop => return,
                    Visit::Skip => continue,
                    Visit::Continue => {}
                }
                let v = Visible { index: bvh.items[e.id as usize], inside: frustum.is_some() && mask == 0 };
                if item_visit(v) == Visit::Stop {
                    return;
                }
            }
            _ => {
                let n = bvh.nodes[e.id as usize];
                if n.count == 1 && (seeded.contains(n.index) || passed_over_slot(n.index)) {
                    continue;
                }
                match ask_node(frustum, known, e.id, &n, &mut mask, &mut node_visit) {
                    Visit::Stop => return,
                    Visit::Skip => continue,
                    Visit::Continue => {}
                }
                let inside = frustum.is_none() || mask == 0;
                // An inner node inside the frustum may be taken whole; its size is read once.
                let candidate = WHOLE && n.count != 1 && inside;
                let size = if candidate { bvh.sizes[e.id as usize] as u32 } else { 0 };
                if candidate && size <= whole {
                    // A small subtree inside the frustum: its items are contiguous from its
                    // leftmost leaf on.
                    let mut first = n;
                    while !first.is_leaf() {
                        first = bvh.nodes[first.index as usize];
                    }
                    let range = (first.index, size);
                    if visit_range(bvh, frustum.is_some(), seeded, range, stack, &passed_over, &mut item_visit) {
                        return;
                    }
                } else if n.count == 1 {
                    // The leaf box is the item box: no second test.
                    let v = Visible { index: bvh.items[n.index as usize], inside: frustum.is_some() && mask == 0 };
                    if item_visit(v) == Visit::Stop {
                        return;
                    }
                } else if n.is_leaf() {
                    push_items(bvh, &n, mask, eye, &mut order, stack);
                } else {
                    push_children(bvh, &n, mask, eye, stack);
                }
            }
        }
    }
}

/// Whether the walk goes into node `id` (`n`, met with plane mask `mask`, narrowed here):
/// `Skip` outside the frustum, `Continue` for a node in `known`, else `node_visit`'s answer.
#[inline(always)]
fn ask_node(
    frustum: Option<&Frustum>,
    known: &NodeSet,
    id: u32,
    n: &BvhNode,
    mask: &mut PlaneMask,
    node_visit: &mut impl FnMut(&Aabb) -> Visit,
) -> Visit {
    let b = n.aabb();
    if Frustum::excludes(frustum, &b, mask) {
        Visit::Skip
    } else if known.contains(id) {
        Visit::Continue
    } else {
        node_visit(&b)
    }
}

/// Pushes the items of leaf `n` (which passed the frustum with plane mask `mask`), the
/// nearest `eye` on top; `order` is scratch.
#[inline(always)]
fn push_items(bvh: &Bvh, n: &BvhNode, mask: PlaneMask, eye: Vec3, order: &mut Vec<(f32, u32)>, stack: &mut Vec<Entry>) {
    order.clear();
    for s in n.index..n.index + n.count {
        order.push((bvh.item_boxes[s as usize].distance_squared(eye), s));
    }
    // Farthest pushed first so the nearest pops first.
    order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    stack.extend(order.iter().map(|&(_, s)| Entry { id: s, mask, kind: KIND_ITEM }));
}

/// Pushes the two children of inner node `n` (which passed the frustum with plane mask
/// `mask`), the one nearer `eye` on top.
#[inline(always)]
fn push_children(bvh: &Bvh, n: &BvhNode, mask: PlaneMask, eye: Vec3, stack: &mut Vec<Entry>) {
    let (a, c) = (n.index, n.index + 1);
    let (na, nc) = (&bvh.nodes[a as usize], &bvh.nodes[c as usize]);
    // Both children are visited soon (unless culled): start loading what they will read,
    // their child pairs or item boxes, while this pair is ordered.
    for child in [na, nc] {
        let i = child.index as usize;
        match child.count {
            0 => bvh.nodes.get(i).map(prefetch),
            1 => bvh.items.get(i).map(prefetch),
            _ => bvh.item_boxes.get(i).map(prefetch),
        };
    }
    let (near, far) = if nearer(&na.aabb(), &nc.aabb(), eye) { (a, c) } else { (c, a) };
    stack.push(Entry { id: far, mask, kind: KIND_NODE });
    stack.push(Entry { id: near, mask, kind: KIND_NODE });
}

/// What a walk runs with besides its stack and callbacks.
#[derive(Clone, Copy)]
struct Walk<'a> {
    frustum: Option<&'a Frustum>,
    eye: Vec3,
    seeded: &'a Seeds,
    /// See [`FrontToBackCursor::whole_subtrees`].
    whole: u32,
}

/// Item slots `first..first + count` of a whole subtree in the frustum (`inside` when there
/// is one), in order, seeds and the items `passed_over` names passed over. When
/// `item_visit` says `Stop`, the slots left go on the stack as one entry, and true is
/// returned.
#[inline(always)]
fn visit_range(
    bvh: &Bvh,
    inside: bool,
    seeded: &Seeds,
    (first, count): (u32, u32),
    stack: &mut Vec<Entry>,
    passed_over: &impl Fn(u32) -> bool,
    item_visit: &mut impl FnMut(Visible) -> Visit,
) -> bool {
    let end = first + count;
    for s in first..end {
        let index = bvh.items[s as usize];
        if seeded.contains(s) || passed_over(index) {
            continue;
        }
        if item_visit(Visible { index, inside }) == Visit::Stop {
            if s + 1 < end {
                stack.push(Entry { id: s + 1, mask: (end - s - 1) as PlaneMask, kind: KIND_RANGE });
            }
            return true;
        }
    }
    false
}

/// The item slots put ahead of the walk, sorted, with a filter of 1,024 bits in front: the
/// walk asks about every item it meets, and a search of the sorted slots costs several
/// dependent loads, where the filter answers almost every "no" with one load. Both are
/// sized by the seeds, not by the items (a bit per item would be megabytes to clear per
/// frame in the largest scenes).
#[derive(Debug, Clone, Default)]
struct Seeds {
    slots: Vec<u32>,
    filter: [u64; 16],
}

impl Seeds {
    /// The seeds `slots` (none: every lookup says no).
    fn new(slots: impl IntoIterator<Item = u32>) -> Self {
        let mut s = Seeds { slots: slots.into_iter().collect(), filter: [0; 16] };
        s.slots.sort_unstable();
        for &slot in &s.slots {
            let b = Self::bit(slot);
            s.filter[b / 64] |= 1 << (b % 64);
        }
        s
    }

    /// The filter bit of `slot` (Fibonacci hashing: the top 10 bits of the product).
    #[inline(always)]
    fn bit(slot: u32) -> usize {
        (slot.wrapping_mul(0x9E37_79B9) >> 22) as usize
    }

    /// True when `slot` is a seed.
    #[inline(always)]
    fn contains(&self, slot: u32) -> bool {
        let b = Self::bit(slot);
        self.filter[b / 64] >> (b % 64) & 1 != 0 && self.slots.binary_search(&slot).is_ok()
    }
}

/// The (at most) `k` items in `frustum` whose boxes are nearest `eye`, nearest first, as
/// (slot, plane mask): best-first over the nodes (a node's box holds its items' boxes, so
/// none is nearer than its node), classified against the frustum along the same paths, with
/// the same masks, as the depth-first walk. Ties go to the lower node or slot.
fn nearest_items(bvh: &Bvh, frustum: Option<&Frustum>, eye: Vec3, k: usize) -> Vec<(u32, PlaneMask)> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let mut found = Vec::with_capacity(k);
    if k == 0 || bvh.nodes.is_empty() {
        return found;
    }
    // (distance bits, kind, id, mask): distances are ≥ 0 (or NaN, last), so their bits order
    // them as the floats.
    let mut heap = BinaryHeap::new();
    let key = |b: &Aabb| {
        let d = b.distance_squared(eye);
        if d.is_nan() {
            u32::MAX
        } else {
            d.to_bits()
        }
    };
    heap.push(Reverse((key(&bvh.nodes[0].aabb()), KIND_NODE, 0u32, ALL_PLANES)));
    while let Some(Reverse((_, kind, id, mut mask))) = heap.pop() {
        if kind == KIND_ITEM {
            if Frustum::excludes(frustum, &bvh.item_boxes[id as usize], &mut mask) {
                continue;
            }
            found.push((id, mask));
            if found.len() == k {
                break;
            }
            continue;
        }
        let n = bvh.nodes[id as usize];
        let b = n.aabb();
        if Frustum::excludes(frustum, &b, &mut mask) {
            continue;
        }
        if n.count == 1 {
            // The leaf box is the item box, tested just now.
            found.push((n.index, mask));
            if found.len() == k {
                break;
            }
        } else if n.is_leaf() {
            for s in n.index..n.index + n.count {
                heap.push(Reverse((key(&bvh.item_boxes[s as usize]), KIND_ITEM, s, mask)));
            }
        } else {
            for c in [n.index, n.index + 1] {
                heap.push(Reverse((key(&bvh.nodes[c as usize].aabb()), KIND_NODE, c, mask)));
            }
        }
    }
    found
}

/// True when box `a` should be visited before box `b` from `eye`.
#[inline]
fn nearer(a: &Aabb, b: &Aabb, eye: Vec3) -> bool {
    let (da, db) = (a.distance_squared(eye), b.distance_squared(eye));
    if da != db {
        return da < db;
    }
    a.center().distance_squared(eye) <= b.center().distance_squared(eye)
}

impl Bvh {
    /// Front-to-back traversal for `eye`, culled by `frustum` when given.
    ///
    /// `node_visit(box)` is called for every node and item box that passes the frustum, in
    /// front-to-back order: `Skip` prunes it (e.g. occluded in a depth pyramid), `Stop` ends
    /// the traversal. `item_visit` receives each surviving item (with its `inside` flag) in
    /// front-to-back order and may also return `Stop`. Unbounded items come first (their box
    /// is passed as all-NaN).
    pub fn traverse_front_to_back(
        &self,
        frustum: Option<&Frustum>,
        eye: Vec3,
        node_visit: impl FnMut(&Aabb) -> Visit,
        item_visit: impl FnMut(Visible) -> Visit,
    ) {
        let mut cursor = FrontToBackCursor::new(self, frustum, eye);
        let walk = Walk { frustum, eye, seeded: &Seeds::default(), whole: 0 };
        run::<false>(self, walk, &mut cursor.stack, node_visit, (|_| false, &NodeSet::default()), item_visit);
    }

    /// Every item (unbounded first, then the tree's) in front-to-back order for `eye`.
    pub fn order_front_to_back(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.traverse_front_to_back(None, eye, |_| Visit::Continue, crate::push_index(out));
    }
}

mod parallel;
#[cfg(test)]
mod tests;

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

use glam::Vec3;
use sightline_scene::Aabb;

use super::Bvh;
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
                let b = n.aabb();
                if Frustum::excludes(frustum, &b, &mut mask) {
                    continue;
                }
                if !known.contains(e.id) {
                    match node_visit(&b) {
                        Visit::Stop => return,
                        Visit::Skip => continue,
                        Visit::Continue => {}
                    }
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
                    order.clear();
                    for s in n.index..n.index + n.count {
                        let d = bvh.item_boxes[s as usize].distance_squared(eye);
                        order.push((d, s));
                    }
                    // Farthest pushed first so the nearest pops first.
                    order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
                    stack.extend(order.iter().map(|&(_, s)| Entry { id: s, mask, kind: KIND_ITEM }));
                } else {
                    let (a, c) = (n.index, n.index + 1);
                    let (na, nc) = (&bvh.nodes[a as usize], &bvh.nodes[c as usize]);
                    // Both children are visited soon (unless culled): start loading what they
                    // will read, their child pairs or item boxes, while this pair is ordered.
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
            }
        }
    }
}

/// A set of a BVH's nodes, a bit a node: those holding some item of a set
/// ([`Bvh::nodes_holding`]), which [`FrontToBackCursor::next_batch_except`] does not ask about.
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
        self.traverse_front_to_back(
            None,
            eye,
            |_| Visit::Continue,
            |v| {
                out.push(v.index);
                Visit::Continue
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seeds answer "yes" for exactly their slots, whatever the filter's bits share:
    /// 200 seeds (a filter a fifth full) against every slot up to 300,000 and the largest.
    #[test]
    fn seeds_contain_exactly_their_slots() {
        let slots: std::collections::HashSet<u32> = (0..200u32).map(|i| i * 1_499 + 7).chain([0, u32::MAX]).collect();
        let seeds = Seeds::new(slots.iter().copied());
        let mut false_positive_bits = 0;
        for s in (0..300_000u32).chain([u32::MAX - 1, u32::MAX]) {
            assert_eq!(seeds.contains(s), slots.contains(&s), "slot {s}");
            let b = Seeds::bit(s);
            false_positive_bits += (seeds.filter[b / 64] >> (b % 64) & 1 != 0 && !slots.contains(&s)) as u32;
        }
        assert!(false_positive_bits > 0, "the filter alone is not exact here: the search decides");
        assert!(!Seeds::default().contains(0));
    }
    use crate::bvh::traverse::tests::{grid_boxes, random_boxes};
    use crate::{BvhPreset, Containment};
    use sightline_scene::{Angle, Camera, LookAt};

    /// An eye over `random_boxes`' field and its frustum, looking at the field from a random
    /// height with a random field of view; case `c` picks the far distance (10, 60 or 400).
    fn random_view(rng: &mut sightline_scene::rng::Rng, c: usize) -> (Vec3, Frustum) {
        let eye = Vec3::new(rng.range(-70.0, 70.0), rng.range(-5.0, 10.0), rng.range(-70.0, 70.0));
        let look = LookAt {
            eye,
            target: Vec3::new(rng.range(-30.0, 30.0), 0.0, rng.range(-30.0, 30.0)),
            up: Vec3::Y,
            fovy: Angle::degrees(rng.range(20.0, 100.0)),
            near: 0.1,
            far: [10.0, 60.0, 400.0][c % 3],
        };
        (eye, Frustum::from_camera(&Camera::perspective(&look, 1.5).unwrap()))
    }

    #[test]
    fn front_to_back_is_roughly_sorted_and_callbacks_prune() {
        let boxes = grid_boxes();
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
        let eye = Vec3::new(-40.0, 0.5, -40.0);
        let mut order = Vec::new();
        bvh.order_front_to_back(eye, &mut order);
        assert_eq!(order.len(), boxes.len());
        let d = |i: u32| boxes[i as usize].distance_squared(eye).sqrt();
        // The first item is the nearest; the first tenth is nearer than the last tenth.
        assert_eq!(order[0], 0);
        let head: f32 = order[..40].iter().map(|&i| d(i)).sum::<f32>() / 40.0;
        let tail: f32 = order[360..].iter().map(|&i| d(i)).sum::<f32>() / 40.0;
        assert!(head * 1.5 < tail, "{head} {tail}");
        // A callback that rejects everything beyond x > 0 never sees items there.
        let mut got = Vec::new();
        bvh.traverse_front_to_back(
            None,
            eye,
            |b| if b.min.x > 0.0 { Visit::Skip } else { Visit::Continue },
            |v| {
                got.push(v.index);
                Visit::Continue
            },
        );
        assert!(got.iter().all(|&i| boxes[i as usize].min.x <= 0.0));
        assert_eq!(got.len(), 220);
    }

    /// A cursor that puts the k nearest items first emits them first, nearest first (the k
    /// smallest box distances among the items in the frustum), then the rest: every item
    /// the plain walk emits, once, with the same `inside` flags; unbounded items still lead.
    #[test]
    fn nearest_first_leads_with_the_nearest_and_keeps_the_set() {
        let mut rng = sightline_scene::rng::Rng::new(5);
        let mut boxes = random_boxes(&mut rng);
        boxes[11] = Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY));
        let mut led = 0;
        for leaf in [1, 4, 8] {
            let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
            for c in 0..30 {
                let (eye, frustum) = random_view(&mut rng, c);
                let f = (c % 4 != 0).then_some(&frustum);
                let walk = |k: usize| {
                    let mut cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k);
                    let mut out = Vec::new();
                    while cursor.next_batch(&bvh, |_| true, 5, &mut out) {}
                    assert!(cursor.is_done());
                    out
                };
                let plain = walk(0);
                // Seeding a walk under way, or twice, changes nothing.
                let mut late = FrontToBackCursor::new(&bvh, f, eye);
                let mut out = Vec::new();
                late.next_batch(&bvh, |_| true, 3, &mut out);
                late = late.nearest_first(&bvh, 10).nearest_first(&bvh, 10);
                while late.next_batch(&bvh, |_| true, 5, &mut out) {}
                assert_eq!(
                    out.iter().map(|v| v.index).collect::<Vec<_>>(),
                    plain.iter().map(|v| v.index).collect::<Vec<_>>()
                );
                let k = [1, 7, 32, 5000][c % 4];
                let seeded = walk(k);
                let sorted = |v: &[Visible]| {
                    let mut v: Vec<(u32, bool)> = v.iter().map(|v| (v.index, v.inside)).collect();
                    v.sort_unstable();
                    v
                };
                assert_eq!(sorted(&seeded), sorted(&plain), "leaf {leaf}, camera {c}, k {k}");
                // The unbounded item, then the k nearest by box distance.
                assert_eq!(seeded[0].index, 11);
                let d = |i: u32| boxes[i as usize].distance_squared(eye);
                let mut dist: Vec<f32> = plain.iter().filter(|v| v.index != 11).map(|v| d(v.index)).collect();
                dist.sort_unstable_by(f32::total_cmp);
                let head: Vec<f32> = seeded[1..].iter().take(k).map(|v| d(v.index)).collect();
                assert_eq!(head, dist[..head.len()], "leaf {leaf}, camera {c}, k {k}");
                assert_eq!(head.len(), k.min(dist.len()));
                led += head.len();
            }
        }
        assert!(led > 1000, "{led} items led");
    }

    /// Whole subtrees change the order only: every item the plain walk emits comes once,
    /// with the same `inside` flag, for any batch size (each batch but the last full), with
    /// or without seeds and a frustum. With 0 the order is the plain one; sizes saturate
    /// (255 is "255 or more", never taken whole, however large the limit asked for).
    #[test]
    fn whole_subtrees_change_the_order_only() {
        let mut rng = sightline_scene::rng::Rng::new(9);
        let boxes = random_boxes(&mut rng);
        let mut reordered = 0;
        for leaf in [1, 4] {
            let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
            // Each node's size is its subtree's item count, saturated (checked by
            // `validate`); the root's 3,000 items saturate.
            bvh.validate().unwrap();
            assert_eq!(bvh.sizes[0], 255);
            for c in 0..16 {
                let (eye, frustum) = random_view(&mut rng, c);
                let f = (c % 4 != 0).then_some(&frustum);
                let walk = |whole: u32, k: usize, batch: usize| {
                    let mut cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k).whole_subtrees(whole);
                    let mut out = Vec::new();
                    loop {
                        let before = out.len();
                        let more = cursor.next_batch(&bvh, |_| true, batch, &mut out);
                        if !more {
                            break;
                        }
                        assert_eq!(out.len() - before, batch, "whole {whole}, k {k}");
                    }
                    out
                };
                let sorted = |v: &[Visible]| {
                    let mut v: Vec<(u32, bool)> = v.iter().map(|v| (v.index, v.inside)).collect();
                    v.sort_unstable();
                    v
                };
                let ids = |v: &[Visible]| v.iter().map(|v| v.index).collect::<Vec<_>>();
                let plain = walk(0, 0, usize::MAX);
                for whole in [0, 1, 3, 16, 254, 255, 100_000] {
                    for (k, batch) in [(0, 1), (7, 5), (32, 64), (0, usize::MAX)] {
                        let got = walk(whole, k, batch);
                        assert_eq!(sorted(&got), sorted(&plain), "leaf {leaf}, camera {c}, whole {whole}, k {k}");
                        if whole == 0 && k == 0 {
                            assert_eq!(ids(&got), ids(&plain));
                        }
                        reordered += (k == 0 && ids(&got) != ids(&plain)) as u32;
                    }
                }
            }
        }
        assert!(reordered > 20, "{reordered} walks reordered");
    }

    /// Items passed over are neither asked about nor emitted, and the rest come in the plain
    /// walk's order: with and without a frustum, seeds, whole subtrees and an unbounded item
    /// (passed over or not), for any batch size. Every callback the plain walk makes for a
    /// passed-over item is saved (here every box is possibly visible, so the plain walk asks
    /// about exactly the items it emits, once each).
    #[test]
    fn items_passed_over_are_neither_asked_about_nor_emitted() {
        let mut rng = sightline_scene::rng::Rng::new(13);
        let mut boxes = random_boxes(&mut rng);
        boxes[11] = Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY));
        let mut saved = 0;
        for leaf in [1, 4] {
            let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
            for c in 0..16 {
                let (eye, frustum) = random_view(&mut rng, c);
                let f = (c % 4 != 0).then_some(&frustum);
                let (k, whole, batch) = [(0, 0, 1), (7, 0, 5), (0, 16, 64), (32, 16, usize::MAX)][c % 4];
                let modulus = [2, 3, 5][c % 3];
                let over = |i: u32| i % modulus == c as u32 % modulus;
                let walk = |except: bool| {
                    let mut cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k).whole_subtrees(whole);
                    let (mut out, mut asked) = (Vec::new(), 0);
                    let mut ask = |_: &Aabb| {
                        asked += 1;
                        true
                    };
                    let known = NodeSet::default();
                    while cursor.next_batch_except(&bvh, &mut ask, |i| except && over(i), &known, batch, &mut out) {}
                    (out.iter().map(|v| (v.index, v.inside)).collect::<Vec<_>>(), asked)
                };
                let (plain, plain_asked) = walk(false);
                let (got, asked) = walk(true);
                let kept: Vec<(u32, bool)> = plain.iter().copied().filter(|&(i, _)| !over(i)).collect();
                assert_eq!(got, kept, "leaf {leaf}, camera {c}");
                assert!(kept.len() < plain.len(), "leaf {leaf}, camera {c}: nothing passed over");
                let passed = plain.len() - kept.len();
                if whole == 0 {
                    assert_eq!(plain_asked - asked, passed, "leaf {leaf}, camera {c}");
                }
                saved += passed;
            }
        }
        assert!(saved > 1000, "{saved} items passed over");
    }

    /// `nodes_holding` holds exactly the nodes with an item of the set in their subtree. A
    /// walk given them asks about none it reaches and emits what it emits without them (here
    /// every box is possibly visible): each node of the set that the walk reaches (its box
    /// not outside the frustum) saves one question, except one-item leaves, whose item is
    /// passed over before anything is asked.
    #[test]
    fn nodes_holding_passed_over_items_are_not_asked_about() {
        let mut rng = sightline_scene::rng::Rng::new(17);
        let boxes = random_boxes(&mut rng);
        let mut saved = 0;
        for leaf in [1, 4] {
            let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
            fn items(bvh: &Bvh, k: usize, out: &mut Vec<u32>) {
                let n = bvh.nodes[k];
                if n.is_leaf() {
                    out.extend(&bvh.items[n.index as usize..(n.index + n.count) as usize]);
                } else {
                    items(bvh, n.index as usize, out);
                    items(bvh, n.index as usize + 1, out);
                }
            }
            for c in 0..12 {
                let (eye, frustum) = random_view(&mut rng, c);
                let f = (c % 3 != 0).then_some(&frustum);
                let modulus = [7, 40, 400][c % 3];
                let over = |i: u32| i % modulus == 1;
                let mut known = NodeSet::default();
                bvh.nodes_holding(over, &mut known);
                let mut expected = 0;
                for k in 0..bvh.nodes.len() {
                    let mut under = Vec::new();
                    items(&bvh, k, &mut under);
                    let holds = under.iter().any(|&i| over(i));
                    assert_eq!(known.contains(k as u32), holds, "leaf {leaf}, camera {c}, node {k}");
                    let outside = f.is_some_and(|f| f.classify(&bvh.nodes[k].aabb()) == Containment::Outside);
                    expected += (holds && bvh.nodes[k].count != 1 && !outside) as usize;
                }
                let walk = |known: &NodeSet| {
                    let mut cursor = FrontToBackCursor::new(&bvh, f, eye);
                    let (mut out, mut asked) = (Vec::new(), 0);
                    let mut ask = |_: &Aabb| {
                        asked += 1;
                        true
                    };
                    while cursor.next_batch_except(&bvh, &mut ask, over, known, 16, &mut out) {}
                    (out.iter().map(|v| (v.index, v.inside)).collect::<Vec<_>>(), asked)
                };
                let (plain, plain_asked) = walk(&NodeSet::default());
                let (got, asked) = walk(&known);
                assert_eq!(got, plain, "leaf {leaf}, camera {c}");
                assert_eq!(plain_asked - asked, expected, "leaf {leaf}, camera {c}");
                saved += expected;
            }
        }
        assert!(saved > 500, "{saved} questions saved");
    }
}

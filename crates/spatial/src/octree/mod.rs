//! A loose octree over boxes (instances): T. Ulrich, "Loose Octrees", Game Programming Gems,
//! 2000. Each cell's *loose* cube is its tight cube scaled by the loose factor 2 around the
//! same center, so an object whose half size is at most a quarter of the cell side always
//! fits the loose cube of the cell containing its center: the depth follows from the size
//! alone and moving objects relink in O(depth) without splitting or merging.
//!
//! Storage is flat: nodes in one `Vec` (children in blocks of 8, recycled through a free list
//! when a subtree empties), objects in one `Vec` indexed by the caller's `u32` ids, linked
//! into their node's doubly linked list. Each node counts the objects in its subtree so that
//! queries skip empty octants.
//!
//! Front-to-back order (the recursive octree traversal of Greene, Kass & Miller 1993):
//! the octant containing the eye first, then the three sharing a face with it, then the three
//! sharing an edge, then the opposite one. The renderer's `octree-hzb` uses
//! [`LooseOctree::traverse_front_to_back`] and skips a whole octant when its loose cube is
//! occluded. The rule for bad boxes is the crate's: empty boxes are stored nowhere (never
//! found), NaN/infinite boxes and boxes outside the root's loose cube live in an "outside" list
//! that every query tests one by one (unbounded ones are always visible).

mod cursor;
pub mod occupancy;
mod query;

pub use cursor::OctreeCursor;
pub use query::octant_order;

use glam::Vec3;
use sightline_scene::{Aabb, Instance};

use crate::{AabbExt, BoxKind};

const NONE: u32 = u32::MAX;
/// `Obj::node` of an object in the outside list.
const OUTSIDE: u32 = u32::MAX - 1;
/// `Obj::node` of a present object with an empty box (stored nowhere).
const NOWHERE: u32 = u32::MAX - 2;

/// Octant visiting order relative to the eye's octant `s`: child `s ^ ORDER[k]`.
pub(crate) const ORDER: [usize; 8] = [0, 1, 2, 4, 3, 5, 6, 7];

#[derive(Debug, Clone, Copy)]
struct Node {
    center: Vec3,
    /// Half side of the tight cube (the loose cube's half side is twice this).
    half: f32,
    /// First of 8 children, or NONE.
    children: u32,
    parent: u32,
    /// First object stored here.
    head: u32,
    /// Objects in this subtree (including here).
    subtree: u32,
}

#[derive(Debug, Clone, Copy)]
struct Obj {
    aabb: Aabb,
    /// Node holding it, OUTSIDE, NOWHERE, or NONE when absent.
    node: u32,
    prev: u32,
    next: u32,
}

const ABSENT: Obj = Obj { aabb: Aabb::EMPTY, node: NONE, prev: NONE, next: NONE };

/// A loose octree (loose factor 2) over objects with `u32` ids.
#[derive(Debug, Clone)]
pub struct LooseOctree {
    nodes: Vec<Node>,
    free_blocks: Vec<u32>,
    objects: Vec<Obj>,
    outside_head: u32,
    max_depth: u32,
    len: usize,
}

impl LooseOctree {
    /// An empty octree whose root cell is the cube around `bounds` (the cube [−1, 1]³ if
    /// `bounds` is empty or not finite), subdivided at most `max_depth` times (capped at 20).
    pub fn new(bounds: &Aabb, max_depth: u32) -> LooseOctree {
        let (center, half) = if bounds.kind() == BoxKind::Finite {
            let e = bounds.extent().max_element() * 0.5;
            (bounds.center(), (e * 1.001).max(1e-3))
        } else {
            (Vec3::ZERO, 1.0)
        };
        LooseOctree {
            nodes: vec![Node { center, half, children: NONE, parent: NONE, head: NONE, subtree: 0 }],
            free_blocks: Vec::new(),
            objects: Vec::new(),
            outside_head: NONE,
            max_depth: max_depth.min(20),
            len: 0,
        }
    }

    /// An octree over instances (id = index in the slice), root around their finite boxes.
    pub fn from_instances(instances: &[Instance], max_depth: u32) -> LooseOctree {
        let boxes: Vec<Aabb> = instances.iter().map(|i| i.world_aabb).collect();
        Self::from_boxes(&boxes, max_depth)
    }

    /// An octree over boxes (id = index), root around the finite ones.
    pub fn from_boxes(boxes: &[Aabb], max_depth: u32) -> LooseOctree {
        let bounds = boxes.iter().filter(|b| b.kind() == BoxKind::Finite).fold(Aabb::EMPTY, |a, b| a.union(b));
        let mut t = Self::new(&bounds, max_depth);
        t.objects.reserve(boxes.len());
        for (i, b) in boxes.iter().enumerate() {
            t.insert(i as u32, *b);
        }
        t
    }

    /// Number of objects stored.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no object is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of live nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len() - 8 * self.free_blocks.len()
    }

    /// True when object `id` is stored.
    pub fn contains(&self, id: u32) -> bool {
        self.objects.get(id as usize).is_some_and(|o| o.node != NONE)
    }

    /// The box object `id` was stored with.
    pub fn aabb(&self, id: u32) -> Option<Aabb> {
        self.objects.get(id as usize).filter(|o| o.node != NONE).map(|o| o.aabb)
    }

    /// The loose cube of node `i`.
    #[inline]
    fn loose(&self, i: u32) -> Aabb {
        let n = &self.nodes[i as usize];
        let h = Vec3::splat(2.0 * n.half);
        Aabb::new(n.center - h, n.center + h)
    }

    /// Where a box belongs: `Ok(node)` for an existing node, `Err(node)` when the path
    /// continues below `node` through children not yet allocated, OUTSIDE or NOWHERE.
    fn target(&self, b: &Aabb) -> Result<u32, u32> {
        match b.kind() {
            BoxKind::Empty => return Ok(NOWHERE),
            BoxKind::Unbounded => return Ok(OUTSIDE),
            BoxKind::Finite => {}
        }
        if !self.loose(0).contains(b) {
            return Ok(OUTSIDE);
        }
        let r = (b.max - b.min).max_element() * 0.5;
        let c = b.center();
        let mut node = 0u32;
        for _ in 0..self.max_depth {
            let n = &self.nodes[node as usize];
            let child_half = n.half * 0.5;
            if r > child_half {
                break;
            }
            let oct = octant(n.center, c);
            let cc = child_center(n.center, child_half, oct);
            let h = Vec3::splat(2.0 * child_half);
            if !Aabb::new(cc - h, cc + h).contains(b) {
                break;
            }
            if n.children == NONE {
                return Err(node);
            }
            node = n.children + oct as u32;
        }
        Ok(node)
    }

    /// Inserts object `id` with box `b` (replacing its old box if present).
    pub fn insert(&mut self, id: u32, b: Aabb) {
        if self.contains(id) {
            self.update(id, b);
            return;
        }
        let i = id as usize;
        if self.objects.len() <= i {
            self.objects.resize(i + 1, ABSENT);
        }
        self.objects[i].aabb = b;
        let node = match self.target(&b) {
            Ok(n) => n,
            Err(start) => self.descend_allocating(start, &b),
        };
        self.link(id, node);
        self.len += 1;
    }

    /// Walks down from `start`, allocating children, to the node where `b` belongs.
    fn descend_allocating(&mut self, start: u32, b: &Aabb) -> u32 {
        let r = (b.max - b.min).max_element() * 0.5;
        let c = b.center();
        let mut node = start;
        loop {
            let depth = self.depth_of(node);
            let n = self.nodes[node as usize];
            let child_half = n.half * 0.5;
            if depth >= self.max_depth || r > child_half {
                return node;
            }
            let oct = octant(n.center, c);
            let cc = child_center(n.center, child_half, oct);
            let h = Vec3::splat(2.0 * child_half);
            if !Aabb::new(cc - h, cc + h).contains(b) {
                return node;
            }
            if n.children == NONE {
                let block = self.alloc_block(node);
                self.nodes[node as usize].children = block;
            }
            node = self.nodes[node as usize].children + oct as u32;
        }
    }

    fn depth_of(&self, mut node: u32) -> u32 {
        let mut d = 0;
        while self.nodes[node as usize].parent != NONE {
            node = self.nodes[node as usize].parent;
            d += 1;
        }
        d
    }

    fn alloc_block(&mut self, parent: u32) -> u32 {
        let p = self.nodes[parent as usize];
        let child_half = p.half * 0.5;
        let make = |k: usize| Node {
            center: child_center(p.center, child_half, k),
            half: child_half,
            children: NONE,
            parent,
            head: NONE,
            subtree: 0,
        };
        match self.free_blocks.pop() {
            Some(block) => {
                for k in 0..8 {
                    self.nodes[block as usize + k] = make(k);
                }
                block
            }
            None => {
                let block = self.nodes.len() as u32;
                self.nodes.extend((0..8).map(make));
                block
            }
        }
    }

    fn link(&mut self, id: u32, node: u32) {
        let o = &mut self.objects[id as usize];
        o.node = node;
        o.prev = NONE;
        if node == NOWHERE {
            o.next = NONE;
            return;
        }
        let head = if node == OUTSIDE { &mut self.outside_head } else { &mut self.nodes[node as usize].head };
        let old = std::mem::replace(head, id);
        self.objects[id as usize].next = old;
        if old != NONE {
            self.objects[old as usize].prev = id;
        }
        if node < NOWHERE {
            let mut n = node;
            while n != NONE {
                self.nodes[n as usize].subtree += 1;
                n = self.nodes[n as usize].parent;
            }
        }
    }

    fn unlink(&mut self, id: u32) {
        let Obj { node, prev, next, .. } = self.objects[id as usize];
        if node == NOWHERE || node == NONE {
            return;
        }
        if prev != NONE {
            self.objects[prev as usize].next = next;
        } else if node == OUTSIDE {
            self.outside_head = next;
        } else {
            self.nodes[node as usize].head = next;
        }
        if next != NONE {
            self.objects[next as usize].prev = prev;
        }
        if node == OUTSIDE {
            return;
        }
        let mut n = node;
        while n != NONE {
            let nd = &mut self.nodes[n as usize];
            nd.subtree -= 1;
            if nd.subtree == 0 && nd.children != NONE {
                // Children of an empty subtree are empty and childless: recycle the block.
                let block = std::mem::replace(&mut nd.children, NONE);
                self.free_blocks.push(block);
            }
            n = self.nodes[n as usize].parent;
        }
    }

    /// Removes object `id`; false when it was not stored.
    pub fn remove(&mut self, id: u32) -> bool {
        if !self.contains(id) {
            return false;
        }
        self.unlink(id);
        self.objects[id as usize] = ABSENT;
        self.len -= 1;
        true
    }

    /// Moves object `id` to box `b` (inserts it when absent). Stays in place when the new
    /// box belongs to the same node.
    pub fn update(&mut self, id: u32, b: Aabb) {
        if !self.contains(id) {
            self.insert(id, b);
            return;
        }
        let cur = self.objects[id as usize].node;
        if self.target(&b) == Ok(cur) {
            self.objects[id as usize].aabb = b;
            return;
        }
        self.unlink(id);
        self.objects[id as usize].aabb = b;
        let node = match self.target(&b) {
            Ok(n) => n,
            Err(start) => self.descend_allocating(start, &b),
        };
        self.link(id, node);
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.objects.capacity() * std::mem::size_of::<Obj>()
            + self.free_blocks.capacity() * 4
    }

    /// Checks the invariants (every object inside its node's loose cube, counts, links).
    pub fn validate(&self) -> Result<(), String> {
        let mut count = vec![0u32; self.nodes.len()];
        let mut found = 0usize;
        for (id, o) in self.objects.iter().enumerate() {
            if o.node == NONE {
                continue;
            }
            found += 1;
            if o.node < NOWHERE {
                if !self.loose(o.node).contains(&o.aabb) {
                    return Err(format!("object {id} outside its node's loose cube"));
                }
                let mut n = o.node;
                while n != NONE {
                    count[n as usize] += 1;
                    n = self.nodes[n as usize].parent;
                }
            }
        }
        if found != self.len {
            return Err(format!("{found} objects present, len says {}", self.len));
        }
        let free: std::collections::HashSet<u32> = self.free_blocks.iter().flat_map(|&b| b..b + 8).collect();
        for (i, n) in self.nodes.iter().enumerate() {
            if free.contains(&(i as u32)) {
                continue;
            }
            if n.subtree != count[i] {
                return Err(format!("node {i} counts {} objects, has {}", n.subtree, count[i]));
            }
        }
        Ok(())
    }
}

/// The octant (bit 0 = +x, bit 1 = +y, bit 2 = +z) of `p` around `center`.
#[inline]
fn octant(center: Vec3, p: Vec3) -> usize {
    (p.x >= center.x) as usize | ((p.y >= center.y) as usize) << 1 | ((p.z >= center.z) as usize) << 2
}

#[inline]
fn child_center(center: Vec3, child_half: f32, oct: usize) -> Vec3 {
    let s = |bit: usize| if oct & bit != 0 { child_half } else { -child_half };
    center + Vec3::new(s(1), s(2), s(4))
}

#[cfg(test)]
mod tests;

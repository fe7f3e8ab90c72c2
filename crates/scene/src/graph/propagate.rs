//! Propagation: the collect / order / propagate steps described in [`super`], recording what
//! changed for drawn nodes as it goes (O(1) per visited node, see [`super::changes`]).

use glam::Affine3A;
use slotmap::{Key, SlotMap};

use super::{invalid_transform_of, Changes, MaterialId, MeshId, Node, NodeId, Scene};
use crate::{Aabb, Mesh, Result};

/// What a node passes down to its children: its world transform and its material in effect.
#[derive(Clone, Copy)]
struct Frame {
    world: Affine3A,
    material: Option<MaterialId>,
}

impl Frame {
    const ROOT: Frame = Frame { world: Affine3A::IDENTITY, material: None };
}

/// The propagation's view of a scene: the nodes it rewrites, the meshes it reads, and the
/// report it fills.
struct Walk<'a> {
    nodes: &'a mut SlotMap<NodeId, Node>,
    meshes: &'a SlotMap<MeshId, Mesh>,
    changes: &'a mut Changes,
    /// Nodes whose world matrix overflowed, less those that recovered, during this walk.
    overflowed: isize,
}

impl Scene {
    /// An error naming a node whose world transform overflowed at the last update (NaN or
    /// infinite entries: finite local matrices can multiply past `f32::MAX` down a deep
    /// chain); `Ok` when every world transform is finite. Renderers call it before drawing.
    /// Costs nothing unless a node overflowed.
    pub fn check_world_transforms(&self) -> Result<()> {
        if self.overflowed == 0 {
            return Ok(());
        }
        let name = self.nodes.values().find(|n| n.overflowed).map_or("", |n| &n.name);
        Err(invalid_transform_of(
            name,
            "its world transform overflows (NaN or infinite entries): the scales or translations of it and its ancestors multiply past the largest f32",
        ))
    }

    /// True when an edit has not been propagated yet: a node's world transform, bounds or
    /// material in effect is out of date, or a node was removed or reparented since the last
    /// [`Scene::update_transforms`]. A renderer must not draw such a scene as it stands.
    pub fn needs_update(&self) -> bool {
        !self.dirty.is_empty() || self.pending.edited
    }

    /// Recomputes the world transforms, world bounds and materials in effect of every dirty
    /// subtree and records what changed for drawn nodes in [`Scene::changes`]; returns how
    /// many nodes were recomputed. Untouched subtrees are not visited.
    ///
    /// With edits to apply, the revision goes up by one and the change report is replaced;
    /// without, both stay as they were.
    pub fn update_transforms(&mut self) -> usize {
        if !self.needs_update() {
            return 0;
        }
        let mut changes = std::mem::take(&mut self.changes);
        changes.restart(self.revision);
        changes.removed.append(&mut self.pending.removed);
        changes.order_changed = std::mem::take(&mut self.pending.order_changed);
        self.pending.edited = false;

        let mut marked = std::mem::take(&mut self.dirty);
        // Order: ancestors first, so each subtree is walked once, and nodes of one depth in
        // the order they were marked (so reports are in that order). The depths recorded
        // with the marks are used unless a reparent changed depths since; nodes removed or
        // already clean are skipped in the walk below, so ordering reads no node.
        if std::mem::take(&mut self.pending.depths_changed) {
            for (depth, id) in marked.iter_mut() {
                if let Some(n) = self.nodes.get(*id) {
                    *depth = n.depth;
                }
            }
        }
        // A stable sort keeps marking order within a depth, and runs in linear time over
        // the long runs of one depth that animations mark (every vehicle, say).
        marked.sort_by_key(|&(depth, _)| depth);
        let mut walk = Walk { nodes: &mut self.nodes, meshes: &self.meshes, changes: &mut changes, overflowed: 0 };
        let mut visited = 0;
        // The walk's stack holds one entry per level (a node, what it passes down and the
        // next child to visit), not one per pending node: a parent of 10^6 children costs
        // no 10^6-entry stack.
        let mut stack: Vec<(NodeId, Frame, usize)> = Vec::new();
        for (k, &(_, id)) in marked.iter().enumerate() {
            // Scattered edits are bound by cache misses on the nodes, and one node's visit
            // is too long for the processor to reach the next node's loads on its own: so
            // every `TOUCH_AHEAD` nodes, the next batch is read in a short loop whose loads
            // overlap.
            if k % TOUCH_AHEAD == 0 {
                walk.touch(marked[k..].iter().take(TOUCH_AHEAD).map(|&(_, id)| id));
            }
            let Some(node) = walk.nodes.get(id) else {
                continue; // removed since it was marked
            };
            if !node.dirty {
                continue; // handled with a dirty ancestor
            }
            let parent = node.parent.map_or(Frame::ROOT, |p| {
                let p = &walk.nodes[p];
                Frame { world: p.world_from_local, material: p.material_in_effect }
            });
            let (frame, _) = walk.visit(id, &parent);
            visited += 1;
            stack.push((id, frame, 0));
            // Propagate.
            while let Some(&(parent, frame, next)) = stack.last() {
                let children = &walk.nodes[parent].children;
                let Some(&child) = children.get(next) else {
                    stack.pop();
                    continue;
                };
                // The last child takes its parent's place (a chain keeps a one-entry stack).
                if next + 1 == children.len() {
                    stack.pop();
                } else if let Some(top) = stack.last_mut() {
                    top.2 += 1;
                }
                if child.is_null() {
                    continue; // the place of a removed child (see `Scene::unlink`)
                }
                let (mut frame, mut n) = walk.visit(child, &frame);
                visited += 1;
                // Down a chain of only children without the stack.
                let mut node = child;
                while n == 1 {
                    // A list of one entry holds no null place (compaction comes at half).
                    node = walk.nodes[node].children[0];
                    debug_assert!(!node.is_null());
                    (frame, n) = walk.visit(node, &frame);
                    visited += 1;
                }
                if n > 1 {
                    stack.push((node, frame, 0));
                }
            }
        }
        self.overflowed = self.overflowed.saturating_add_signed(walk.overflowed);
        marked.clear();
        self.dirty = marked; // keep the allocation for the next update
        if changes.order_changed {
            self.forget_order();
        }
        self.changes = changes;
        self.revision += 1;
        visited
    }
}

/// How many dirty nodes are read ahead at once (see the walk).
const TOUCH_AHEAD: usize = 32;

impl Walk<'_> {
    /// Reads the cache lines a visit of each node needs (its local and world matrices, its
    /// bounds and flags, its parent's world matrix), with loads independent from node to
    /// node, and returns nothing of use: a portable prefetch.
    #[inline(never)]
    fn touch(&self, ids: impl Iterator<Item = NodeId>) {
        let mut sink = 0u32;
        for id in ids {
            if let Some(n) = self.nodes.get(id) {
                // One field from each end of each wide field: whatever the layout, every
                // cache line of the node a visit uses is read.
                sink ^= n.parent_from_local.matrix3.x_axis.x.to_bits()
                    ^ n.parent_from_local.translation.x.to_bits()
                    ^ n.world_from_local.matrix3.x_axis.x.to_bits()
                    ^ n.world_from_local.translation.x.to_bits()
                    ^ n.world_aabb.min.x.to_bits()
                    ^ n.world_aabb.max.z.to_bits()
                    ^ n.children.len() as u32
                    ^ n.mesh.is_some() as u32
                    ^ n.drawn.is_some() as u32;
                if let Some(p) = n.parent.and_then(|p| self.nodes.get(p)) {
                    sink ^= p.world_from_local.translation.x.to_bits();
                }
            }
        }
        std::hint::black_box(sink);
    }

    /// Recomputes one node from what its parent passes down, records the change a consumer
    /// must hear about, and returns what the node passes down and the length of its child
    /// list (null places of removed children included).
    #[inline(always)]
    fn visit(&mut self, id: NodeId, parent: &Frame) -> (Frame, usize) {
        let node = &mut self.nodes[id];
        let world = parent.world * node.parent_from_local;
        let material = node.material.or(parent.material);
        match (node.drawn, node.mesh) {
            (None, None) => {}
            (Some(was), Some(now)) if was == now => {
                if world != node.world_from_local {
                    self.changes.moved.push(id);
                }
                if material != node.material_in_effect {
                    self.changes.restyled.push(id);
                }
            }
            (was, now) => {
                let triangles = |m: Option<MeshId>| m.and_then(|m| self.meshes.get(m)).map(|m| m.triangle_count());
                if was.is_some() {
                    self.changes.removed.push(id);
                }
                if now.is_some() {
                    self.changes.added.push(id);
                }
                // An instance appeared or disappeared, or its triangle count changed.
                if triangles(was) != triangles(now) || was.is_none() || now.is_none() {
                    self.changes.order_changed = true;
                }
            }
        }
        node.world_from_local = world;
        node.material_in_effect = material;
        node.drawn = node.mesh;
        node.dirty = false;
        let overflowed = !world.is_finite();
        self.overflowed += overflowed as isize - node.overflowed as isize;
        node.overflowed = overflowed;
        node.world_aabb = match node.mesh.and_then(|m| self.meshes.get(m)) {
            Some(mesh) => mesh.aabb().transformed(&world),
            None => Aabb::EMPTY,
        };
        (Frame { world, material }, node.children.len())
    }
}

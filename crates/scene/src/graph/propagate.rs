//! Propagation: the collect / order / propagate steps described in [`super`], recording what
//! changed for drawn nodes as it goes (O(1) per visited node, see [`super::changes`]).

use glam::Affine3A;
use slotmap::SlotMap;

use super::{Changes, MaterialId, MeshId, Node, NodeId, Scene};
use crate::{Aabb, Mesh};

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
}

impl Scene {
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
        // Collect: drop removed nodes, reading each node's depth once (a sort that looked
        // nodes up in its comparisons would cost O(n log n) cache misses); order: ancestors
        // first, so each subtree is walked once, and nodes of one depth in the order they were
        // marked (so reports are in that order).
        let mut dirty = std::mem::take(&mut self.scratch);
        dirty.clear();
        dirty.extend(
            marked
                .iter()
                .enumerate()
                .filter_map(|(seq, &id)| self.nodes.get(id).filter(|n| n.dirty).map(|n| (n.depth, seq as u32, id))),
        );
        dirty.sort_unstable_by_key(|&(depth, seq, _)| (depth, seq));
        let mut walk = Walk { nodes: &mut self.nodes, meshes: &self.meshes, changes: &mut changes };
        let mut visited = 0;
        // The walk's stack holds one entry per level (a node, what it passes down and the
        // next child to visit), not one per pending node: a parent of 10^6 children costs
        // no 10^6-entry stack.
        let mut stack: Vec<(NodeId, Frame, usize)> = Vec::new();
        for &(_, _, id) in &dirty {
            let node = &walk.nodes[id];
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
                let (mut frame, mut n) = walk.visit(child, &frame);
                visited += 1;
                // Down a chain of only children without the stack.
                let mut node = child;
                while n == 1 {
                    node = walk.nodes[node].children[0];
                    (frame, n) = walk.visit(node, &frame);
                    visited += 1;
                }
                if n > 1 {
                    stack.push((node, frame, 0));
                }
            }
        }
        marked.clear();
        self.dirty = marked; // keep the allocations for the next update
        self.scratch = dirty;
        if changes.order_changed {
            self.forget_order();
        }
        self.changes = changes;
        self.revision += 1;
        visited
    }
}

impl Walk<'_> {
    /// Recomputes one node from what its parent passes down, records the change a consumer
    /// must hear about, and returns what the node passes down and its number of children.
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
        node.world_aabb = match node.mesh.and_then(|m| self.meshes.get(m)) {
            Some(mesh) => mesh.aabb().transformed(&world),
            None => Aabb::EMPTY,
        };
        (Frame { world, material }, node.children.len())
    }
}

//! Propagation: the collect / order / propagate steps described in [`super`].

use glam::Affine3A;

use super::{NodeId, Scene};
use crate::Aabb;

impl Scene {
    /// True when some node's world transform is out of date.
    pub fn needs_update(&self) -> bool {
        !self.dirty.is_empty()
    }

    /// Recomputes the world transforms and world bounds of every dirty subtree; returns how
    /// many nodes were recomputed. Untouched subtrees are not visited.
    pub fn update_transforms(&mut self) -> usize {
        let mut dirty = std::mem::take(&mut self.dirty);
        // Collect: drop removed nodes; order: ancestors first, so each subtree is walked once.
        dirty.retain(|&id| self.nodes.get(id).is_some_and(|n| n.dirty));
        dirty.sort_unstable_by_key(|&id| self.nodes[id].depth);
        // The walk's stack holds one entry per level (a node, its world transform and the
        // next child to visit), not one per pending node: a parent of 10^6 children costs
        // no 10^6-entry stack.
        let mut stack: Vec<(NodeId, Affine3A, usize)> = Vec::new();
        let mut visited = 0;
        for id in dirty {
            let node = &self.nodes[id];
            if !node.dirty {
                continue; // handled with a dirty ancestor
            }
            let parent_world = node.parent.map_or(Affine3A::IDENTITY, |p| self.nodes[p].world_from_local);
            let (world, _) = self.update_node(id, &parent_world);
            visited += 1;
            stack.push((id, world, 0));
            // Propagate.
            while let Some(&(parent, parent_world, next)) = stack.last() {
                let children = &self.nodes[parent].children;
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
                let (mut world, mut n) = self.update_node(child, &parent_world);
                visited += 1;
                // Down a chain of only children without the stack.
                let mut node = child;
                while n == 1 {
                    node = self.nodes[node].children[0];
                    (world, n) = self.update_node(node, &world);
                    visited += 1;
                }
                if n > 1 {
                    stack.push((node, world, 0));
                }
            }
        }
        visited
    }

    /// Sets a node's world transform and bounds from its parent's world transform; returns
    /// the new world transform and the node's number of children.
    #[inline]
    fn update_node(&mut self, id: NodeId, parent_world: &Affine3A) -> (Affine3A, usize) {
        let node = &mut self.nodes[id];
        let world = *parent_world * node.parent_from_local;
        node.world_from_local = world;
        node.dirty = false;
        node.world_aabb = match node.mesh.and_then(|m| self.meshes.get(m)) {
            Some(mesh) => mesh.aabb().transformed(&world),
            None => Aabb::EMPTY,
        };
        (world, node.children.len())
    }
}

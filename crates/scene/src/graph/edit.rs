//! Edits of the hierarchy: adding nodes, setting local transforms, meshes and materials,
//! reparenting and removing subtrees. Each edit marks what it touches dirty for propagation,
//! or (a removal, a reparent) notes for the next change report what propagation cannot see:
//! until [`Scene::update_transforms`] runs, [`Scene::needs_update`] is true after any edit.

use glam::{Affine3A, Quat, Vec3};
use slotmap::Key;

use super::{invalid_transform_of, live, Keep, Node, NodeDesc, NodeId, Scene};
use crate::transform::affine_fault;
use crate::{Aabb, Error, MaterialId, MeshId, Result, SceneCamera, Transform};

/// What [`Scene::remove_node`] removed.
#[derive(Debug, Clone)]
pub struct Removed {
    /// Number of nodes removed (the node and its whole subtree).
    pub nodes: usize,
    /// The cameras that sat on removed nodes, taken out of [`Scene::cameras`] (so no camera
    /// ever refers to a dead node).
    pub cameras: Vec<SceneCamera>,
}

impl Scene {
    /// Adds a node under `parent` (or as a root), returning its handle.
    ///
    /// Errors on a stale parent, stale mesh/material handles or a non-finite transform.
    pub fn add_node(&mut self, parent: Option<NodeId>, desc: NodeDesc) -> Result<NodeId> {
        // The name is formatted only into an error: formatted up front, adding 10^6 nodes
        // took 299–306 ms against 230–233.
        if let Some(why) = affine_fault(&desc.local) {
            return Err(invalid_transform_of(&desc.name, why));
        }
        if let Some(m) = desc.mesh {
            self.try_mesh(m)?;
        }
        if let Some(m) = desc.material {
            self.materials.get(m).ok_or(Error::StaleMaterial(m))?;
        }
        let depth = match parent {
            Some(p) => self.try_node(p)?.depth + 1,
            None => 0,
        };
        let id = self.nodes.insert(Node {
            name: desc.name.into_boxed_str(),
            parent,
            children: Vec::new(),
            parent_from_local: desc.local,
            world_from_local: Affine3A::IDENTITY,
            mesh: desc.mesh,
            material: desc.material,
            world_aabb: Aabb::EMPTY,
            depth,
            dirty: true,
            overflowed: false,
            material_in_effect: None,
            drawn: None,
        });
        self.link(id, parent);
        if let Some(t) = desc.trs.filter(|t| t.matrix() == desc.local) {
            self.trs.insert(id, t);
        }
        self.dirty.push((depth, id));
        Ok(id)
    }

    pub(crate) fn mark_dirty(&mut self, id: NodeId) {
        mark(&mut self.dirty, &mut self.nodes[id], id);
    }

    /// Sets a node's local transform from translation, rotation and scale (the rotation
    /// made unit). The scene keeps the TRS beside the matrix (see [`NodeDesc::trs`]).
    pub fn set_local_transform(&mut self, id: NodeId, t: Transform) -> Result<()> {
        self.set_local_components(id, Some(t.translation), Some(t.rotation), Some(t.scale))
    }

    /// Sets the components of a node's local transform that are given, keeping the others as
    /// [`Scene::local_transform`] has them (the TRS as last set, so that a zero or negative
    /// scale keeps its rotation and mirrored axes frame after frame): what playing an
    /// animation does to each node it poses, some channels setting only some components.
    /// Errors as [`Scene::set_local_transform`].
    pub(crate) fn set_local_components(
        &mut self,
        id: NodeId,
        translation: Option<Vec3>,
        rotation: Option<Quat>,
        scale: Option<Vec3>,
    ) -> Result<()> {
        // One lookup of the node and of its TRS (animation sets thousands per frame: posing
        // 10^4 vehicles took 4–9% less than with a second lookup of each); the message names
        // the node only when there is one to write: no allocation per edit.
        let Some(n) = self.nodes.get_mut(id) else {
            return Err(Error::StaleNode(id));
        };
        let kept = self.trs.get_mut(id);
        let t = match (translation, rotation, scale) {
            (Some(translation), Some(rotation), Some(scale)) => Transform { translation, rotation, scale },
            (t, r, s) => with_kept_trs(kept.as_deref(), n, |current| Transform {
                translation: t.unwrap_or(current.translation),
                rotation: r.unwrap_or(current.rotation),
                scale: s.unwrap_or(current.scale),
            }),
        };
        // The matrix from the unit rotation in registers (see `Transform::unit_rotation`).
        let rotation = match t.unit_rotation() {
            Ok(r) => r,
            Err(why) => return Err(invalid_transform_of(&n.name, why)),
        };
        // `Transform::matrix` of the unit transform, spelled out: through a `Transform` with
        // the new rotation, posing 10^4 nodes took 0.42–0.43 ms against 0.36–0.39.
        n.parent_from_local = Affine3A::from_scale_rotation_translation(t.scale, rotation, t.translation);
        mark(&mut self.dirty, n, id);
        // Written in place, component by component, when the node keeps a TRS already (as
        // every posed node does after its first pose): an insert of a whole `Transform` built
        // on the stack waited on that copy's stores (perf).
        match kept {
            Some(kept) => {
                kept.translation = t.translation;
                kept.rotation = rotation;
                kept.scale = t.scale;
            }
            None => {
                self.trs.insert(id, Transform { rotation, ..t });
            }
        }
        Ok(())
    }

    /// A node's local transform as translation, rotation and scale: as last given so
    /// ([`NodeDesc::transform`], [`Scene::set_local_transform`], animation), else taken
    /// from its matrix ([`Transform::from_affine`]: a negative scale goes on x, and a zero
    /// scale keeps what rotation the other axes show).
    pub fn local_transform(&self, id: NodeId) -> Result<Transform> {
        Ok(with_kept_trs(self.trs.get(id), self.try_node(id)?, |t| *t))
    }

    /// Renames a node.
    pub fn set_name(&mut self, id: NodeId, name: impl Into<String>) -> Result<()> {
        self.node_mut(id)?.name = name.into().into_boxed_str();
        Ok(())
    }

    /// Sets a node's local transform from a matrix (errors on NaN/inf).
    pub fn set_local_matrix(&mut self, id: NodeId, m: Affine3A) -> Result<()> {
        let Some(n) = self.nodes.get_mut(id) else {
            return Err(Error::StaleNode(id));
        };
        if let Some(why) = affine_fault(&m) {
            return Err(invalid_transform_of(&n.name, why));
        }
        n.parent_from_local = m;
        mark(&mut self.dirty, n, id);
        self.trs.remove(id);
        Ok(())
    }

    /// Sets or clears a node's mesh. The next change report lists the node as added, removed,
    /// or both (a swap).
    pub fn set_mesh(&mut self, id: NodeId, mesh: Option<MeshId>) -> Result<()> {
        if let Some(m) = mesh {
            self.try_mesh(m)?;
        }
        self.node_mut(id)?.mesh = mesh;
        self.mark_dirty(id); // world bounds change
        Ok(())
    }

    /// Sets or clears a node's own material (its subtree inherits it). Propagation works out
    /// the material in effect below it, so the subtree is marked for the next update.
    pub fn set_material(&mut self, id: NodeId, material: Option<MaterialId>) -> Result<()> {
        if let Some(m) = material {
            self.materials.get(m).ok_or(Error::StaleMaterial(m))?;
        }
        self.node_mut(id)?.material = material;
        self.mark_dirty(id);
        Ok(())
    }

    /// `world_from_local` computed now from the local transforms of the node and its
    /// ancestors, whatever the dirty state.
    pub fn world_from_local_now(&self, id: NodeId) -> Result<Affine3A> {
        let mut m = Affine3A::IDENTITY;
        let mut cur = Some(id);
        while let Some(c) = cur {
            let n = self.try_node(c)?;
            m = n.parent_from_local * m;
            cur = n.parent;
        }
        Ok(m)
    }

    /// Moves `child` under `parent` (`None`: make it a root), keeping its local or world
    /// transform. Refuses to make a node its own ancestor.
    pub fn set_parent(&mut self, child: NodeId, parent: Option<NodeId>, keep: Keep) -> Result<()> {
        self.try_node(child)?;
        if let Some(p) = parent {
            let mut cur = Some(p);
            while let Some(c) = cur {
                if c == child {
                    let name = |id: NodeId| self.nodes.get(id).map_or_else(String::new, |n| n.name.to_string());
                    return Err(Error::Cycle { child, parent: p, child_name: name(child), parent_name: name(p) });
                }
                cur = self.try_node(c)?.parent;
            }
        }
        if keep == Keep::World {
            let world = self.world_from_local_now(child)?;
            let parent_world = match parent {
                Some(p) => self.world_from_local_now(p)?,
                None => Affine3A::IDENTITY,
            };
            // Singular relative to the matrix's own scale (a uniformly tiny parent is fine).
            let m = &parent_world.matrix3;
            let det = m.determinant();
            let scale = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
            let local = parent_world.inverse() * world;
            if !(det.is_finite() && scale.is_finite() && det.abs() > 1e-7 * scale && local.is_finite()) {
                let parent_name = parent.and_then(|p| self.nodes.get(p)).map_or("", |n| &n.name);
                return Err(Error::InvalidTransform {
                    what: format!("node '{parent_name}', the new parent of node '{}'", self.nodes[child].name),
                    why: "its world matrix is singular (or overflows), so the child's world transform cannot be kept"
                        .into(),
                });
            }
            self.nodes[child].parent_from_local = local;
            self.trs.remove(child);
        }
        // Unlink from the old place, link into the new one (last among its new siblings).
        self.unlink(child);
        let base_depth = parent.map_or(0, |p| self.nodes[p].depth + 1);
        self.nodes[child].parent = parent;
        self.link(child, parent);
        // Depths of the whole subtree change by the same amount; a drawn node in it moves in
        // the flattened order.
        let mut stack = vec![(child, base_depth)];
        let mut draws = false;
        while let Some((id, d)) = stack.pop() {
            let n = &mut self.nodes[id];
            n.depth = d;
            draws |= n.drawn.is_some();
            stack.extend(live(&n.children).map(|c| (c, d + 1)));
        }
        self.pending.depths_changed = true;
        if draws {
            self.pending.order_changed = true;
            self.forget_order();
        }
        self.mark_dirty(child);
        Ok(())
    }

    /// Removes a node and its whole subtree, and the cameras on them (returned in
    /// [`Removed::cameras`]) and the animation channels aimed at them. Their handles become
    /// stale; every other handle stays valid. The channels go before the next
    /// [`Scene::animate`], in one pass however many nodes were removed (until then
    /// [`Scene::animations`] still lists them; [`Scene::drop_dead_animation_channels`] drops
    /// them at once). Removing a node costs the size of its subtree, however many siblings it
    /// has (its place in its parent's list is left empty and the list compacted once half of
    /// it is empty), so removing all children of a parent one at a time is linear when their
    /// handles are collected first; taking `children().next()` again after each removal
    /// walks past the empty places every time.
    pub fn remove_node(&mut self, id: NodeId) -> Result<Removed> {
        self.remove_nodes(&[id])
    }

    /// [`Scene::remove_node`] for many nodes at once: the scene's cameras are scanned once
    /// for the whole batch instead of once per node. Nodes inside another removed subtree,
    /// and repeated handles, are fine. Errors on a stale handle, removing nothing.
    pub fn remove_nodes(&mut self, ids: &[NodeId]) -> Result<Removed> {
        for &id in ids {
            self.try_node(id)?;
        }
        // Each parent losing children keeps the others in order (the order sets IDs).
        for &id in ids {
            self.unlink(id);
        }
        let mut stack: Vec<NodeId> = ids.to_vec();
        let mut removed = 0;
        let drawn_before = self.pending.removed.len();
        while let Some(n) = stack.pop() {
            if let Some(node) = self.nodes.remove(n) {
                self.trs.remove(n);
                self.slots.remove(n);
                self.dead.remove(n);
                self.overflowed -= node.overflowed as usize;
                if node.drawn.is_some() {
                    self.pending.removed.push(n);
                }
                stack.extend(live(&node.children));
                removed += 1;
            }
        }
        if self.pending.removed.len() > drawn_before {
            self.pending.order_changed = true;
            self.forget_order();
        }
        self.pending.edited = true;
        let (gone, kept) =
            std::mem::take(&mut self.cameras).into_iter().partition(|c| !self.nodes.contains_key(c.node));
        self.cameras = kept;
        // Animation channels aimed into the removed subtrees go before the next `animate`,
        // in one pass over the channels however many removals come first (a pass here would
        // make removing n animated nodes one by one quadratic).
        self.dead_channels |= !self.animations.is_empty();
        Ok(Removed { nodes: removed, cameras: gone })
    }

    /// Appends `id` to `parent`'s child list (or the roots), remembering its place.
    fn link(&mut self, id: NodeId, parent: Option<NodeId>) {
        let list = match parent {
            Some(p) => &mut self.nodes[p].children,
            None => &mut self.roots,
        };
        list.push(id);
        let slot = list.len() as u32 - 1;
        self.slots.insert(id, slot);
    }

    /// Takes `id` out of its parent's child list (or the roots) in O(1): its place becomes a
    /// null handle, so the others keep their order (the order sets triangle IDs) without a
    /// shift of the list. Once nulls are half of the list it is compacted, which is linear
    /// in its length and so costs O(1) per removal over time. A node not linked (already
    /// unlinked in this batch) is left alone.
    fn unlink(&mut self, id: NodeId) {
        let Some(slot) = self.slots.remove(id) else { return };
        let parent = self.nodes[id].parent;
        let (list, dead) = match parent {
            Some(p) => {
                let dead = self.dead.entry(p).expect("a linked node's parent is live").or_insert(0);
                (&mut self.nodes[p].children, dead)
            }
            None => (&mut self.roots, &mut self.dead_roots),
        };
        debug_assert_eq!(list[slot as usize], id, "a node's slot names its place in its parent's list");
        list[slot as usize] = NodeId::null();
        *dead += 1;
        if 2 * *dead as usize >= list.len() {
            *dead = 0;
            list.retain(|c| !c.is_null());
            for (k, &c) in list.iter().enumerate() {
                self.slots.insert(c, k as u32);
            }
        }
    }
}

/// `f` of a node's TRS as the scene keeps it: `kept`, the TRS last given (the node's entry
/// in the scene's map, looked up by the caller, which may go on to write it), else taken
/// from the node's matrix ([`Node::local_transform`]). The TRS is read in place, as posing
/// reads the components it does not set (a copy of the whole `Transform` first made each
/// pose wait on the copy's stores: setting 10^4 poses took about 6% longer).
#[inline(always)]
fn with_kept_trs<R>(kept: Option<&Transform>, n: &Node, f: impl FnOnce(&Transform) -> R) -> R {
    match kept {
        Some(t) => f(t),
        None => f(&n.local_transform()),
    }
}

/// Marks node `n` (handle `id`) dirty for the next update, once: its depth goes with the mark
/// so that ordering the marks reads no node.
fn mark(dirty: &mut Vec<(u32, NodeId)>, n: &mut Node, id: NodeId) {
    if !n.dirty {
        n.dirty = true;
        dirty.push((n.depth, id));
    }
}

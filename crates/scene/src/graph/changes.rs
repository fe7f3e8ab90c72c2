//! What changed: scene identity, revisions, the change report of each propagation, and the
//! flattened view (instances in triangle-ID order) that consumers build from.
//!
//! A consumer of a scene (a culler, a ray caster's acceleration structure) copies what it needs
//! from [`Scene::instances`] once, then follows the scene from revision to revision:
//!
//! * Every [`Scene`] value has a [`SceneId`] (a clone gets a new one) and a revision counter.
//!   Each [`Scene::update_transforms`] that had edits to apply bumps the revision by one and
//!   replaces [`Scene::changes`] with the report from the old revision to the new one.
//! * The report lists drawn nodes by what happened to them ([`Changes`]). Recording costs O(1)
//!   per node the propagation visits, so a frame that moves 1% of a scene pays for that 1%.
//! * The consumer keeps the [`SceneStamp`] it last synced to, and [`Scene::delta_since`] tells
//!   it what to do: nothing, apply the one report, or rebuild.
//!
//! The flattened order (depth-first over the tree, each drawn node's triangles in order, see
//! [`Instance::first_triangle`]) is cached and kept until an edit changes it; between such
//! edits [`Scene::instance`] is a lookup, not a walk.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use slotmap::SecondaryMap;

use super::{live, Instance, NodeId, Scene};

/// Identity of one [`Scene`] value: unique per process, never reused. `Clone` on a scene gives
/// the clone a new id, so state built for one scene is never mistaken for another's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SceneId(u64);

impl SceneId {
    /// A fresh id from a process-wide counter.
    pub(crate) fn next() -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(1);
        SceneId(NEXT.fetch_add(1, Ordering::Relaxed))
    }
}

/// Where a consumer stands: the scene it copied from and the revision it copied.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SceneStamp {
    /// The scene.
    pub scene: SceneId,
    /// Its revision at the time.
    pub revision: u64,
}

/// What a consumer must do to catch up with a scene; see [`Scene::delta_since`].
#[derive(Debug, Clone, Copy)]
pub enum SceneDelta<'a> {
    /// Nothing changed since the stamp.
    UpToDate,
    /// Exactly one update happened since the stamp: apply this report.
    Apply(&'a Changes),
    /// Another scene, or more than one update behind: rebuild from [`Scene::instances`].
    Rebuild,
}

/// What one [`Scene::update_transforms`] changed in the drawn scene, from revision `from` to
/// revision `to` (= `from + 1`).
///
/// A *drawn* node is one that carries a mesh. Every list holds each node at most once, in the
/// order the propagation met them (deterministic for a given sequence of edits). A node may be
/// in two lists: `moved` and `restyled`, or `removed` and `added` (its mesh was swapped).
///
/// # How a consumer follows a scene
///
/// Remember the revision (with [`Scene::id`]: a [`SceneStamp`]) the consumer's copy reflects.
/// Before using it, make sure the scene has no pending edits ([`Scene::needs_update`] is false:
/// otherwise propagate, or refuse to draw stale data). Then:
///
/// * stamp revision == [`Scene::revision`]: nothing to do;
/// * stamp revision == `changes().from` (and the same scene id): apply this report: drop the
///   `removed` nodes, then add the `added` ones and refresh the `moved` and `restyled` ones
///   from [`Scene::instance`]; when `order_changed`, refresh every kept instance's
///   `first_triangle` too (from [`Scene::instances`]);
/// * otherwise: rebuild from [`Scene::instances`].
///
/// [`Scene::delta_since`] makes that decision.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Changes {
    /// The revision the report starts from.
    pub from: u64,
    /// The revision it leads to (the scene's revision right after the update).
    pub to: u64,
    /// Nodes drawn before and after, with the same mesh, whose world matrix changed (and so
    /// their world bounds).
    pub moved: Vec<NodeId>,
    /// Nodes that draw a mesh now and did not at `from`: new nodes, a mesh set where there was
    /// none, or the new half of a mesh swap.
    pub added: Vec<NodeId>,
    /// Nodes that drew a mesh at `from` and no longer exist or no longer draw it: removed
    /// nodes (their handles are stale now), a mesh cleared, or the old half of a mesh swap.
    pub removed: Vec<NodeId>,
    /// Nodes drawn before and after, with the same mesh, whose material in effect (their own
    /// or the inherited one) changed. Geometry and triangle IDs are untouched: a consumer that
    /// only needs visibility may ignore this list.
    pub restyled: Vec<NodeId>,
    /// The flattened triangle order changed: some instance's `first_triangle` shifted
    /// (a drawn node added, removed or reparented, or a mesh swapped for one with another
    /// triangle count). It may also be set when an edit left the order as it was, such as a
    /// reparent to the place a node already had.
    pub order_changed: bool,
}

impl Changes {
    /// True when nothing drawn changed.
    pub fn is_empty(&self) -> bool {
        self.moved.is_empty()
            && self.added.is_empty()
            && self.removed.is_empty()
            && self.restyled.is_empty()
            && !self.order_changed
    }

    /// Empties the lists (keeping their memory) for a report from `from` to `from + 1`.
    pub(crate) fn restart(&mut self, from: u64) {
        self.from = from;
        self.to = from + 1;
        self.moved.clear();
        self.added.clear();
        self.removed.clear();
        self.restyled.clear();
        self.order_changed = false;
    }
}

/// Edits made since the last propagation that it has no dirty node for.
#[derive(Debug, Clone, Default)]
pub(crate) struct Pending {
    /// Drawn nodes removed since the last update.
    pub(crate) removed: Vec<NodeId>,
    /// A removal or reparent changed the flattened order.
    pub(crate) order_changed: bool,
    /// Some edit (a removal) needs an update although no node is dirty.
    pub(crate) edited: bool,
    /// A reparent changed depths, so the depths recorded with the dirty marks may be stale.
    pub(crate) depths_changed: bool,
}

/// The flattened order: drawn nodes depth-first, with their first triangle.
#[derive(Debug, Clone, Default)]
pub(crate) struct Order {
    nodes: Vec<NodeId>,
    first: Vec<u32>,
    index: SecondaryMap<NodeId, u32>,
    /// Triangles of all drawn nodes, counted without the 32-bit cap of `first`.
    triangles: u64,
}

/// Most triangles a scene may draw: triangle IDs are 32-bit, ID 0 is the background, and
/// the ray caster numbers CSG solids after the triangles.
pub const MAX_DRAWN_TRIANGLES: u64 = u32::MAX as u64 - (1 << 16);

impl Scene {
    /// This scene value's identity (a clone has another).
    pub fn id(&self) -> SceneId {
        self.id
    }

    /// The revision: 0 for a new scene, one more after each [`Scene::update_transforms`] that
    /// had edits to apply.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// The scene id and revision, for a consumer to remember.
    pub fn stamp(&self) -> SceneStamp {
        SceneStamp { scene: self.id, revision: self.revision }
    }

    /// What the most recent [`Scene::update_transforms`] changed, from revision
    /// `changes().from` to `changes().to` (= [`Scene::revision`]). An update with nothing to
    /// do keeps the previous report. See [`Changes`] for how to use it.
    pub fn changes(&self) -> &Changes {
        &self.changes
    }

    /// What a consumer synced at `stamp` must do to catch up (the protocol on [`Changes`]).
    /// Pending edits are not considered: check [`Scene::needs_update`] first.
    pub fn delta_since(&self, stamp: SceneStamp) -> SceneDelta<'_> {
        if stamp.scene != self.id {
            SceneDelta::Rebuild
        } else if stamp.revision == self.revision {
            SceneDelta::UpToDate
        } else if stamp.revision == self.changes.from && self.changes.to == self.revision {
            SceneDelta::Apply(&self.changes)
        } else {
            SceneDelta::Rebuild
        }
    }

    /// Every drawn node in depth-first order with its world transform, bounds, material in
    /// effect and the index of its first triangle in the flattened order, all as of the last
    /// [`Scene::update_transforms`].
    ///
    /// While [`Scene::needs_update`] is true the list follows the current tree but the last
    /// update's transforms, meshes and materials: propagate first.
    pub fn instances(&self) -> Vec<Instance> {
        let order = self.order();
        order.nodes.iter().zip(&order.first).filter_map(|(&id, &first)| self.instance_at(id, first)).collect()
    }

    /// Triangles drawn by all instances as of the last update, counted in 64 bits: triangle
    /// IDs are 32-bit, so a renderer refuses a scene of more than [`MAX_DRAWN_TRIANGLES`]
    /// (whose [`Instance::first_triangle`]s would stop at `u32::MAX`).
    pub fn drawn_triangle_count(&self) -> u64 {
        self.order().triangles
    }

    /// One drawn node's [`Instance`], as [`Scene::instances`] would list it; `None` when the
    /// node is stale or drew nothing at the last update. A lookup while the flattened order is
    /// unchanged (the first call after an order change walks the tree once).
    pub fn instance(&self, node: NodeId) -> Option<Instance> {
        let order = self.order();
        let &i = order.index.get(node)?;
        self.instance_at(node, order.first[i as usize])
    }

    /// The instances the scene describes right now, pending edits included: world matrices
    /// composed from the local transforms and materials looked up as the walk goes (O(nodes),
    /// no cache). For readers that must be current without propagating (the OBJ export).
    pub(crate) fn instances_now(&self) -> Vec<Instance> {
        let mut out = Vec::new();
        let mut first = 0u32;
        let mut stack: Vec<(NodeId, glam::Affine3A, Option<crate::MaterialId>)> =
            live(&self.roots).rev().map(|r| (r, glam::Affine3A::IDENTITY, None)).collect();
        while let Some((id, parent_world, inherited)) = stack.pop() {
            let n = &self.nodes[id];
            let world = parent_world * n.parent_from_local;
            let material = n.material.or(inherited);
            if let Some((mesh, m)) = n.mesh.and_then(|m| self.meshes.get(m).map(|mm| (m, mm))) {
                let count = m.triangle_count() as u32;
                let world_aabb = m.aabb().transformed(&world);
                out.push(Instance {
                    node: id,
                    mesh,
                    world_from_local: world,
                    world_aabb,
                    material,
                    first_triangle: first,
                    triangle_count: count,
                });
                first = first.saturating_add(count);
            }
            stack.extend(live(&n.children).rev().map(|c| (c, world, material)));
        }
        out
    }

    /// Number of drawn nodes (as of the last update).
    pub fn instance_count(&self) -> usize {
        self.order().nodes.len()
    }

    fn instance_at(&self, id: NodeId, first_triangle: u32) -> Option<Instance> {
        let n = self.nodes.get(id)?;
        let mesh = n.drawn?;
        Some(Instance {
            node: id,
            mesh,
            world_from_local: n.world_from_local,
            world_aabb: n.world_aabb,
            material: n.material_in_effect,
            first_triangle,
            triangle_count: self.meshes.get(mesh).map_or(0, |m| m.triangle_count() as u32),
        })
    }

    /// The cached flattened order, built on first use after a change.
    fn order(&self) -> &Order {
        self.order.get_or_init(|| {
            let mut order = Order::default();
            let mut first = 0u32;
            for id in self.depth_first() {
                let Some(mesh) = self.nodes[id].drawn else { continue };
                let count = self.meshes.get(mesh).map_or(0, |m| m.triangle_count() as u32);
                order.index.insert(id, order.nodes.len() as u32);
                order.nodes.push(id);
                order.first.push(first);
                order.triangles += count as u64;
                first = first.saturating_add(count);
            }
            order
        })
    }

    /// Forgets the cached flattened order (an edit changed the tree).
    pub(crate) fn forget_order(&mut self) {
        self.order = OnceLock::new();
    }
}

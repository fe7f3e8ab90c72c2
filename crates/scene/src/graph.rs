//! The scene graph: nodes in a slotmap, parent/child links, incremental transform propagation.
//!
//! Propagation follows bevy_transform's shape in a few named steps: setters *mark* a node
//! dirty; [`Scene::update_transforms`] *collects* the dirty nodes, *orders* them by depth so an
//! ancestor is handled before its descendants, and *propagates* each dirty subtree with an
//! explicit stack (no recursion: a 100,000-level chain must not overflow the thread stack).
//! Subtrees with no dirty node are never visited, so static parts of a scene cost nothing.

use glam::Affine3A;
use slotmap::{new_key_type, SlotMap};

use crate::{Aabb, Error, Material, Mesh, Result, Transform};

new_key_type! {
    /// Handle of a node; stays valid across removals of other nodes.
    pub struct NodeId;
    /// Handle of a mesh in the scene's mesh store.
    pub struct MeshId;
    /// Handle of a material in the scene's material store.
    pub struct MaterialId;
}

/// What `set_parent` keeps unchanged when a node moves in the hierarchy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Keep {
    /// Keep the local transform: the node moves with its new parent.
    Local,
    /// Keep the world transform: the local transform is recomputed under the new parent.
    World,
}

/// One node of the hierarchy. Read through [`Scene::node`]; change through `Scene` methods.
#[derive(Debug, Clone)]
pub struct Node {
    name: String,
    parent: Option<NodeId>,
    children: Vec<NodeId>,
    parent_from_local: Affine3A,
    world_from_local: Affine3A,
    mesh: Option<MeshId>,
    material: Option<MaterialId>,
    world_aabb: Aabb,
    depth: u32,
    dirty: bool,
}

impl Node {
    /// The node's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The parent, or `None` for a root.
    pub fn parent(&self) -> Option<NodeId> {
        self.parent
    }
    /// Children in insertion order (this order defines triangle IDs).
    pub fn children(&self) -> &[NodeId] {
        &self.children
    }
    /// The local transform (`parent_from_local`).
    pub fn local_matrix(&self) -> Affine3A {
        self.parent_from_local
    }
    /// The local transform as translation, rotation, scale.
    pub fn local_transform(&self) -> Transform {
        Transform::from_affine(&self.parent_from_local)
    }
    /// The world transform as of the last [`Scene::update_transforms`].
    pub fn world_matrix(&self) -> Affine3A {
        self.world_from_local
    }
    /// The mesh this node draws, if any (a group node has none).
    pub fn mesh(&self) -> Option<MeshId> {
        self.mesh
    }
    /// The material set on this node itself (not the inherited one).
    pub fn material(&self) -> Option<MaterialId> {
        self.material
    }
    /// World-space bounds of the node's mesh (empty for group nodes), as of the last update.
    pub fn world_aabb(&self) -> Aabb {
        self.world_aabb
    }
    /// Distance from the root (roots have depth 0).
    pub fn depth(&self) -> u32 {
        self.depth
    }
    /// True when the node's world transform is out of date.
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }
}

/// How to create a node: name, local transform, optional mesh and material.
#[derive(Debug, Clone)]
pub struct NodeDesc {
    /// Name for messages and lookups.
    pub name: String,
    /// Local transform (`parent_from_local`).
    pub local: Affine3A,
    /// Mesh to draw.
    pub mesh: Option<MeshId>,
    /// Material for this node and (unless overridden) its subtree.
    pub material: Option<MaterialId>,
}

impl NodeDesc {
    /// A group node with an identity transform.
    pub fn new(name: impl Into<String>) -> Self {
        Self { name: name.into(), local: Affine3A::IDENTITY, mesh: None, material: None }
    }
    /// Sets the local transform from TRS (checked when the node is added).
    pub fn transform(mut self, t: Transform) -> Self {
        self.local = Affine3A::from_scale_rotation_translation(t.scale, t.rotation, t.translation);
        self
    }
    /// Sets the local transform from a matrix.
    pub fn matrix(mut self, m: Affine3A) -> Self {
        self.local = m;
        self
    }
    /// Sets the mesh.
    pub fn mesh(mut self, m: MeshId) -> Self {
        self.mesh = Some(m);
        self
    }
    /// Sets the material.
    pub fn material(mut self, m: MaterialId) -> Self {
        self.material = Some(m);
        self
    }
}

/// A camera found in a loaded file, with the node that places it.
#[derive(Debug, Clone)]
pub struct SceneCamera {
    /// Name from the file.
    pub name: String,
    /// The node carrying the camera (its world matrix is `world_from_view`).
    pub node: NodeId,
    /// The projection given by the file.
    pub projection: crate::Projection,
}

/// One drawn mesh occurrence, as the spatial and render crates consume it.
#[derive(Debug, Clone, Copy)]
pub struct Instance {
    /// The node that draws it.
    pub node: NodeId,
    /// The mesh drawn.
    pub mesh: MeshId,
    /// `world_from_local` of the node.
    pub world_from_local: Affine3A,
    /// World bounds of the mesh under that transform.
    pub world_aabb: Aabb,
    /// The inherited material (`None`: the default material).
    pub material: Option<MaterialId>,
    /// Index of this instance's first triangle in the flattened scene order.
    pub first_triangle: u32,
    /// Number of triangles (the mesh's).
    pub triangle_count: u32,
}

/// A scene: nodes, meshes, materials and the cameras a file brought.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    nodes: SlotMap<NodeId, Node>,
    roots: Vec<NodeId>,
    meshes: SlotMap<MeshId, Mesh>,
    materials: SlotMap<MaterialId, Material>,
    dirty: Vec<NodeId>,
    /// Cameras defined by a loaded file.
    pub cameras: Vec<SceneCamera>,
    /// Animations of node transforms (from a file or a builder); see [`Scene::animate`].
    pub animations: Vec<crate::animation::Animation>,
    /// Non-fatal problems met while loading (missing textures, skipped primitives, ...).
    pub warnings: Vec<String>,
}

impl Scene {
    /// An empty scene.
    pub fn new() -> Self {
        Self::default()
    }

    // ---- stores -------------------------------------------------------------------------

    /// Adds a mesh to the store.
    pub fn add_mesh(&mut self, mesh: Mesh) -> MeshId {
        self.meshes.insert(mesh)
    }
    /// A mesh by handle.
    pub fn mesh(&self, id: MeshId) -> Option<&Mesh> {
        self.meshes.get(id)
    }
    /// A mesh by handle, or a "stale handle" error.
    pub fn try_mesh(&self, id: MeshId) -> Result<&Mesh> {
        self.meshes.get(id).ok_or(Error::StaleMesh(id))
    }
    /// All meshes in the store.
    pub fn meshes(&self) -> impl Iterator<Item = (MeshId, &Mesh)> {
        self.meshes.iter()
    }
    /// Adds a material to the store.
    pub fn add_material(&mut self, m: Material) -> MaterialId {
        self.materials.insert(m)
    }
    /// A material by handle.
    pub fn material(&self, id: MaterialId) -> Option<&Material> {
        self.materials.get(id)
    }
    /// All materials in the store.
    pub fn materials(&self) -> impl Iterator<Item = (MaterialId, &Material)> {
        self.materials.iter()
    }

    // ---- nodes --------------------------------------------------------------------------

    /// Number of live nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
    /// A node by handle; `None` for a removed node.
    pub fn node(&self, id: NodeId) -> Option<&Node> {
        self.nodes.get(id)
    }
    /// A node by handle, or a "stale handle" error.
    pub fn try_node(&self, id: NodeId) -> Result<&Node> {
        self.nodes.get(id).ok_or(Error::StaleNode(id))
    }
    fn node_mut(&mut self, id: NodeId) -> Result<&mut Node> {
        self.nodes.get_mut(id).ok_or(Error::StaleNode(id))
    }
    /// Root nodes in insertion order.
    pub fn roots(&self) -> &[NodeId] {
        &self.roots
    }
    /// The first node with this name, in depth-first order.
    pub fn find(&self, name: &str) -> Option<NodeId> {
        self.depth_first().find(|&id| self.nodes[id].name == name)
    }

    /// Adds a node under `parent` (or as a root), returning its handle.
    ///
    /// Errors on a stale parent, stale mesh/material handles or a non-finite transform.
    pub fn add_node(&mut self, parent: Option<NodeId>, desc: NodeDesc) -> Result<NodeId> {
        crate::transform::validate_affine(&desc.local, &format!("node '{}'", desc.name))?;
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
            name: desc.name,
            parent,
            children: Vec::new(),
            parent_from_local: desc.local,
            world_from_local: Affine3A::IDENTITY,
            mesh: desc.mesh,
            material: desc.material,
            world_aabb: Aabb::EMPTY,
            depth,
            dirty: true,
        });
        match parent {
            Some(p) => self.nodes[p].children.push(id),
            None => self.roots.push(id),
        }
        self.dirty.push(id);
        Ok(id)
    }

    fn mark_dirty(&mut self, id: NodeId) {
        let n = &mut self.nodes[id];
        if !n.dirty {
            n.dirty = true;
            self.dirty.push(id);
        }
    }

    /// Sets a node's local transform from translation, rotation and scale.
    pub fn set_local_transform(&mut self, id: NodeId, t: Transform) -> Result<()> {
        let m = t.to_affine(&format!("node {id:?}"))?;
        self.set_local_matrix(id, m)
    }

    /// Sets a node's local transform from a matrix (errors on NaN/inf).
    pub fn set_local_matrix(&mut self, id: NodeId, m: Affine3A) -> Result<()> {
        let name = &self.try_node(id)?.name;
        crate::transform::validate_affine(&m, &format!("node '{name}'"))?;
        self.node_mut(id)?.parent_from_local = m;
        self.mark_dirty(id);
        Ok(())
    }

    /// Sets or clears a node's mesh.
    pub fn set_mesh(&mut self, id: NodeId, mesh: Option<MeshId>) -> Result<()> {
        if let Some(m) = mesh {
            self.try_mesh(m)?;
        }
        self.node_mut(id)?.mesh = mesh;
        self.mark_dirty(id); // world bounds change
        Ok(())
    }

    /// Sets or clears a node's own material (its subtree inherits it).
    pub fn set_material(&mut self, id: NodeId, material: Option<MaterialId>) -> Result<()> {
        if let Some(m) = material {
            self.materials.get(m).ok_or(Error::StaleMaterial(m))?;
        }
        self.node_mut(id)?.material = material;
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
                    return Err(Error::Cycle { child, parent: p });
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
            let det = parent_world.matrix3.determinant();
            if det.abs() < 1e-12 || !det.is_finite() {
                return Err(Error::InvalidTransform {
                    what: format!("new parent of node '{}'", self.nodes[child].name),
                    why: "its world matrix is singular, so the child's world transform cannot be kept".into(),
                });
            }
            self.nodes[child].parent_from_local = parent_world.inverse() * world;
        }
        // Unlink from the old place, link into the new one.
        match self.nodes[child].parent {
            Some(old) => self.nodes[old].children.retain(|&c| c != child),
            None => self.roots.retain(|&c| c != child),
        }
        let base_depth = match parent {
            Some(p) => {
                self.nodes[p].children.push(child);
                self.nodes[p].depth + 1
            }
            None => {
                self.roots.push(child);
                0
            }
        };
        self.nodes[child].parent = parent;
        // Depths of the whole subtree change by the same amount.
        let mut stack = vec![(child, base_depth)];
        while let Some((id, d)) = stack.pop() {
            let n = &mut self.nodes[id];
            n.depth = d;
            stack.extend(n.children.iter().map(|&c| (c, d + 1)));
        }
        self.mark_dirty(child);
        Ok(())
    }

    /// Removes a node and its whole subtree; returns how many nodes were removed.
    /// Their handles become stale; every other handle stays valid.
    pub fn remove_node(&mut self, id: NodeId) -> Result<usize> {
        let parent = self.try_node(id)?.parent;
        match parent {
            Some(p) => self.nodes[p].children.retain(|&c| c != id),
            None => self.roots.retain(|&c| c != id),
        }
        let mut stack = vec![id];
        let mut removed = 0;
        while let Some(n) = stack.pop() {
            if let Some(node) = self.nodes.remove(n) {
                stack.extend(node.children);
                removed += 1;
            }
        }
        Ok(removed)
    }

    /// Depth-first pre-order over all nodes: roots in order, children in order. This order
    /// defines the flattened triangle order (and so triangle IDs).
    pub fn depth_first(&self) -> impl Iterator<Item = NodeId> + '_ {
        let mut stack: Vec<NodeId> = self.roots.iter().rev().copied().collect();
        std::iter::from_fn(move || {
            let id = stack.pop()?;
            stack.extend(self.nodes[id].children.iter().rev());
            Some(id)
        })
    }

    // ---- propagation --------------------------------------------------------------------

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

    // ---- the flattened view -------------------------------------------------------------

    /// Every mesh-carrying node in depth-first order with its world transform, bounds,
    /// inherited material and the index of its first triangle in the flattened order.
    ///
    /// Uses the world transforms of the last [`Scene::update_transforms`]; call that first
    /// after edits.
    pub fn instances(&self) -> Vec<Instance> {
        let mut out = Vec::new();
        let mut first = 0u32;
        // (node, inherited material)
        let mut stack: Vec<(NodeId, Option<MaterialId>)> = self.roots.iter().rev().map(|&r| (r, None)).collect();
        while let Some((id, inherited)) = stack.pop() {
            let n = &self.nodes[id];
            let material = n.material.or(inherited);
            if let Some(mesh) = n.mesh.and_then(|m| self.meshes.get(m).map(|mm| (m, mm))) {
                let count = mesh.1.triangle_count() as u32;
                out.push(Instance {
                    node: id,
                    mesh: mesh.0,
                    world_from_local: n.world_from_local,
                    world_aabb: n.world_aabb,
                    material,
                    first_triangle: first,
                    triangle_count: count,
                });
                first = first.saturating_add(count);
            }
            stack.extend(n.children.iter().rev().map(|&c| (c, material)));
        }
        out
    }

    /// World bounds of everything drawn (as of the last update).
    pub fn world_aabb(&self) -> Aabb {
        self.nodes.values().fold(Aabb::EMPTY, |b, n| b.union(&n.world_aabb))
    }
}

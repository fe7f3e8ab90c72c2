//! The scene graph: nodes in a slotmap, parent/child links, incremental transform propagation.
//!
//! Propagation follows bevy_transform's shape in a few named steps: setters *mark* a node
//! dirty; [`Scene::update_transforms`] *collects* the dirty nodes, *orders* them by depth so an
//! ancestor is handled before its descendants, and *propagates* each dirty subtree with an
//! explicit stack (no recursion: a 100,000-level chain must not overflow the thread stack).
//! Subtrees with no dirty node are never visited, so static parts of a scene cost nothing.
//!
//! Propagation also records what it changed for the drawn scene (nodes moved, added, removed,
//! restyled) in a [`Changes`] report, so that consumers follow the scene incrementally
//! ([`changes`] explains the protocol).
//!
//! The module is split by idea: [`edit`] holds the edits (add, move, reparent, remove),
//! [`propagate`] the propagation, [`changes`] the change report and the flattened view,
//! [`instantiate`] shared subgraphs (a subtree or a whole scene placed many times), and this
//! file the types and the read side.

use std::sync::OnceLock;

use glam::{Affine3A, Vec3};
use slotmap::{new_key_type, Key, SecondaryMap, SlotMap};

use crate::{Aabb, Error, Material, Mesh, Result, Transform};

mod changes;
mod edit;
mod instantiate;
mod propagate;

pub use changes::{Changes, SceneDelta, SceneId, SceneStamp, MAX_DRAWN_TRIANGLES};
pub use edit::Removed;
pub use instantiate::Prefab;

new_key_type! {
    /// Handle of a node; stays valid across removals of other nodes.
    pub struct NodeId;
    /// Handle of a mesh in the scene's mesh store.
    pub struct MeshId;
    /// Handle of a material in the scene's material store.
    pub struct MaterialId;
}

/// The error for the transform of the node named `name`, invalid because of `why`.
fn invalid_transform_of(name: &str, why: impl Into<String>) -> Error {
    Error::InvalidTransform { what: format!("node '{name}'"), why: why.into() }
}

/// The handles of a child list (or the roots) that are not null: removing a node leaves a
/// null handle in its parent's list, so that removing many children of one parent one at a
/// time costs O(1) each instead of a shift of the whole list (see `Scene::unlink`).
pub(crate) fn live(list: &[NodeId]) -> impl DoubleEndedIterator<Item = NodeId> + '_ {
    list.iter().copied().filter(|c| !c.is_null())
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
    /// A boxed `str` rather than a `String`: 8 bytes less keeps a node's slot (with the slot
    /// map's version) at 256 bytes; propagation of scattered edits is bound by cache misses
    /// on nodes, so their size is their cost.
    name: Box<str>,
    parent: Option<NodeId>,
    children: Vec<NodeId>,
    parent_from_local: Affine3A,
    world_from_local: Affine3A,
    mesh: Option<MeshId>,
    material: Option<MaterialId>,
    world_aabb: Aabb,
    depth: u32,
    dirty: bool,
    /// The world matrix has NaN or infinite entries (products of finite local matrices can
    /// overflow); see [`Scene::check_world_transforms`].
    overflowed: bool,
    /// The material in effect (own or inherited), as of the last update.
    material_in_effect: Option<MaterialId>,
    /// The mesh drawn as of the last update: what the last change report told consumers.
    drawn: Option<MeshId>,
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
    pub fn children(&self) -> impl DoubleEndedIterator<Item = NodeId> + '_ {
        live(&self.children)
    }
    /// The local transform (`parent_from_local`).
    pub fn local_matrix(&self) -> Affine3A {
        self.parent_from_local
    }
    /// The local transform as translation, rotation, scale, taken from the matrix
    /// ([`Transform::from_affine`]); [`Scene::local_transform`] gives the TRS as it was set.
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
    /// True when the node's world transform, bounds or material in effect are out of date.
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }
    /// The material in effect: the node's own, else the nearest ancestor's (`None`: the
    /// default material), as of the last update.
    pub fn material_in_effect(&self) -> Option<MaterialId> {
        self.material_in_effect
    }
}

/// How to create a node: name, local transform, optional mesh and material.
#[derive(Debug, Clone)]
pub struct NodeDesc {
    /// Name for messages and lookups.
    pub name: String,
    /// Local transform (`parent_from_local`).
    pub local: Affine3A,
    /// The local transform as translation, rotation and scale, when it was given so
    /// ([`NodeDesc::transform`]). The scene keeps it beside the matrix, because a matrix
    /// cannot give back a zero scale's rotation or which axes a negative scale mirrors, and
    /// animation lays sampled components over it. Ignored unless it makes `local` exactly.
    pub trs: Option<Transform>,
    /// Mesh to draw.
    pub mesh: Option<MeshId>,
    /// Material for this node and (unless overridden) its subtree.
    pub material: Option<MaterialId>,
}

impl NodeDesc {
    /// A group node with an identity transform (kept as the matrix alone: the identity's TRS
    /// is the matrix's own, so a plain node costs no entry beside it).
    pub fn new(name: impl Into<String>) -> Self {
        Self { name: name.into(), local: Affine3A::IDENTITY, trs: None, mesh: None, material: None }
    }
    /// Sets the local transform from TRS (checked when the node is added; a rotation that
    /// is not unit is normalized there).
    pub fn transform(mut self, t: Transform) -> Self {
        // A transform `normalized` refuses is refused again, with its message, by `add_node`.
        let t = t.normalized("").unwrap_or(t);
        self.local = t.matrix();
        self.trs = Some(t);
        self
    }
    /// Sets the local transform from a matrix.
    pub fn matrix(mut self, m: Affine3A) -> Self {
        self.local = m;
        self.trs = None;
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
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    /// The node that draws it.
    pub node: NodeId,
    /// The mesh drawn.
    pub mesh: MeshId,
    /// `world_from_local` of the node.
    pub world_from_local: Affine3A,
    /// World bounds of the mesh under that transform.
    pub world_aabb: Aabb,
    /// The material in effect, own or inherited (`None`: the default material).
    pub material: Option<MaterialId>,
    /// Index of this instance's first triangle in the flattened scene order.
    pub first_triangle: u32,
    /// Number of triangles (the mesh's).
    pub triangle_count: u32,
}

/// A scene: nodes, meshes, materials and the cameras a file brought.
///
/// `Clone` copies everything but the identity: the clone gets a new [`SceneId`] (and keeps
/// the revision and the last change report). The animations' layout for playing is not
/// copied: the clone's first [`Scene::animate`] makes its own.
#[derive(Debug)]
pub struct Scene {
    nodes: SlotMap<NodeId, Node>,
    /// Root nodes in order; like child lists, may hold null handles where nodes were
    /// removed (see `Scene::unlink`).
    roots: Vec<NodeId>,
    /// Each node's place in its parent's child list (or in `roots`).
    slots: SecondaryMap<NodeId, u32>,
    /// Per parent, the null handles its child list holds; `dead_roots`: those in `roots`.
    dead: SecondaryMap<NodeId, u32>,
    dead_roots: u32,
    meshes: SlotMap<MeshId, Mesh>,
    materials: SlotMap<MaterialId, Material>,
    /// Nodes marked dirty since the last update, with their depth when marked (so that
    /// ordering them reads no node).
    dirty: Vec<(u32, NodeId)>,
    /// Cameras defined by a loaded file. Removing a camera's node removes the camera.
    pub cameras: Vec<SceneCamera>,
    /// Animations of node transforms (from a file or a builder); see [`Scene::animate`].
    animations: Vec<crate::animation::Animation>,
    /// The animations laid out for playing, made by the first [`Scene::animate`] after they
    /// change (`None` until then).
    pub(crate) playback: Option<crate::animation::Playback>,
    /// Non-fatal problems met while loading (missing textures, skipped primitives, ...).
    pub warnings: Vec<String>,
    id: SceneId,
    revision: u64,
    changes: Changes,
    pending: changes::Pending,
    order: OnceLock<changes::Order>,
    /// The local transforms given as TRS (see [`NodeDesc::trs`]), beside the matrices.
    trs: SecondaryMap<NodeId, Transform>,
    /// How many live nodes have an overflowed world matrix.
    overflowed: usize,
    /// Nodes were removed since animation channels were last checked for dead targets.
    pub(crate) dead_channels: bool,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            nodes: SlotMap::default(),
            roots: Vec::new(),
            slots: SecondaryMap::new(),
            dead: SecondaryMap::new(),
            dead_roots: 0,
            meshes: SlotMap::default(),
            materials: SlotMap::default(),
            dirty: Vec::new(),
            cameras: Vec::new(),
            animations: Vec::new(),
            playback: None,
            warnings: Vec::new(),
            id: SceneId::next(),
            revision: 0,
            changes: Changes::default(),
            pending: changes::Pending::default(),
            order: OnceLock::new(),
            trs: SecondaryMap::new(),
            overflowed: 0,
            dead_channels: false,
        }
    }
}

impl Clone for Scene {
    fn clone(&self) -> Self {
        Self {
            nodes: self.nodes.clone(),
            roots: self.roots.clone(),
            slots: self.slots.clone(),
            dead: self.dead.clone(),
            dead_roots: self.dead_roots,
            meshes: self.meshes.clone(),
            materials: self.materials.clone(),
            dirty: self.dirty.clone(),
            cameras: self.cameras.clone(),
            animations: self.animations.clone(),
            playback: None,
            warnings: self.warnings.clone(),
            id: SceneId::next(),
            revision: self.revision,
            changes: self.changes.clone(),
            pending: self.pending.clone(),
            order: self.order.clone(),
            trs: self.trs.clone(),
            overflowed: self.overflowed,
            dead_channels: self.dead_channels,
        }
    }
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
    /// The material `inst` is drawn with: its own or inherited one, or
    /// [`Material::fallback`] when it has none or its handle no longer names a material.
    pub fn instance_material(&self, inst: &Instance) -> &Material {
        inst.material.and_then(|m| self.material(m)).unwrap_or(Material::fallback())
    }
    /// All materials in the store.
    pub fn materials(&self) -> impl Iterator<Item = (MaterialId, &Material)> {
        self.materials.iter()
    }
    /// The animations [`Scene::animate`] plays, in order (a later one wins where two set the
    /// same component of one node).
    pub fn animations(&self) -> &[crate::animation::Animation] {
        &self.animations
    }
    /// The animations, to change: the next [`Scene::animate`] lays them out for playing again.
    pub fn animations_mut(&mut self) -> &mut Vec<crate::animation::Animation> {
        self.playback = None;
        &mut self.animations
    }
    /// The animations, to play them: their layout for playing stays (see `Scene::animate`).
    pub(crate) fn animations_keeping_playback(&mut self) -> &mut Vec<crate::animation::Animation> {
        &mut self.animations
    }
    /// Adds an animation, played after those already there.
    pub fn add_animation(&mut self, animation: crate::animation::Animation) {
        if let Some(p) = &mut self.playback {
            p.push(&animation);
        }
        self.animations.push(animation);
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
        // A match, not `ok_or`: the error built and dropped on every success costs a call to
        // its destructor in hot loops (animation looks nodes up ten thousand times a frame).
        match self.nodes.get(id) {
            Some(n) => Ok(n),
            None => Err(Error::StaleNode(id)),
        }
    }
    pub(crate) fn node_mut(&mut self, id: NodeId) -> Result<&mut Node> {
        match self.nodes.get_mut(id) {
            Some(n) => Ok(n),
            None => Err(Error::StaleNode(id)),
        }
    }
    /// Root nodes in insertion order.
    pub fn roots(&self) -> impl DoubleEndedIterator<Item = NodeId> + '_ {
        live(&self.roots)
    }
    /// The first node with this name, in depth-first order.
    pub fn find(&self, name: &str) -> Option<NodeId> {
        self.depth_first().find(|&id| &*self.nodes[id].name == name)
    }

    /// Depth-first pre-order over all nodes: roots in order, children in order. This order
    /// defines the flattened triangle order (and so triangle IDs).
    pub fn depth_first(&self) -> impl Iterator<Item = NodeId> + '_ {
        let mut stack: Vec<NodeId> = live(&self.roots).rev().collect();
        std::iter::from_fn(move || {
            let id = stack.pop()?;
            stack.extend(live(&self.nodes[id].children).rev());
            Some(id)
        })
    }

    /// The file's camera `index` (in [`Scene::cameras`]) as a [`Camera`](crate::Camera) for an image of
    /// `aspect` = width / height: the view from its node's world matrix as of the last
    /// update (eye at the node's origin, looking down its −z with its +y up, scale ignored),
    /// the projection the file gave with its vertical extent kept and its horizontal one
    /// fitted to `aspect` ([`crate::Projection::with_aspect`]).
    ///
    /// Errors when there is no camera `index` (saying how many there are), or its node was
    /// collapsed to a point by a zero scale.
    pub fn camera(&self, index: usize, aspect: f32) -> Result<crate::Camera> {
        let cam = self.cameras.get(index).ok_or(Error::NoSuchCamera { index, count: self.cameras.len() })?;
        let m = self.try_node(cam.node)?.world_matrix();
        let (eye, gaze, up) = (Vec3::from(m.translation), -Vec3::from(m.matrix3.z_axis), Vec3::from(m.matrix3.y_axis));
        let view = crate::View::look_along(eye, gaze, up)
            .map_err(|e| Error::InvalidCamera(format!("camera {index} ('{}'): {e}", cam.name)))?;
        crate::Camera::new(view, cam.projection.with_aspect(aspect)?)
    }

    /// World bounds of everything drawn (as of the last update).
    pub fn world_aabb(&self) -> Aabb {
        self.nodes.values().fold(Aabb::EMPTY, |b, n| b.union(&n.world_aabb))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_node_slot_stays_at_256_bytes() {
        // Propagation is bound by cache misses on nodes: keep a slot (node + version) at 256.
        assert!(std::mem::size_of::<super::Node>() <= 240, "{}", std::mem::size_of::<super::Node>());
    }

    /// A plain node is its matrix alone; a node given as TRS keeps it beside the matrix, and
    /// both read back as the same local transform.
    #[test]
    fn only_nodes_given_as_trs_keep_one() {
        use crate::{NodeDesc, Scene, Transform};
        let mut s = Scene::new();
        let plain = s.add_node(None, NodeDesc::new("plain")).unwrap();
        let t = Transform::from_translation(glam::Vec3::X).with_scale(glam::Vec3::new(2.0, -1.0, 1.0));
        let given = s.add_node(Some(plain), NodeDesc::new("given").transform(t)).unwrap();
        assert_eq!((s.trs.len(), s.trs.contains_key(given)), (1, true));
        assert_eq!(s.local_transform(plain).unwrap(), Transform::IDENTITY);
        assert_eq!(s.local_transform(given).unwrap(), t, "the mirrored axis is y, as given");
    }

    /// Finite local scales can multiply past f32's range down a chain: the update says which
    /// node overflowed, until an edit or a removal brings it back.
    #[test]
    fn an_overflowing_world_transform_is_named_until_it_is_fixed() {
        use crate::{NodeDesc, Scene, Transform};
        let mut s = Scene::new();
        let big = Transform::from_scale(glam::Vec3::splat(1e12));
        let mut parent = None;
        let mut chain = Vec::new();
        for name in ["a", "b", "c", "d", "e"] {
            let id = s.add_node(parent, NodeDesc::new(name).transform(big)).unwrap();
            chain.push(id);
            parent = Some(id);
        }
        s.update_transforms();
        // 10^48 at "d": "d" and "e" overflow.
        let e = s.check_world_transforms().unwrap_err().to_string();
        assert!(e.contains("node 'd'") || e.contains("node 'e'"), "{e}");
        s.set_local_transform(chain[0], Transform::IDENTITY).unwrap();
        s.update_transforms();
        assert!(s.check_world_transforms().is_err(), "10^48 still at 'e'");
        s.remove_node(chain[4]).unwrap();
        s.update_transforms();
        s.check_world_transforms().unwrap();
    }
}

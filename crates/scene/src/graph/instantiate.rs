//! Shared subgraphs: one subtree, or one whole scene, placed many times.
//!
//! A scene graph in the textbook sense is a directed acyclic graph: a node (a wheel, a tree, a
//! loaded model) may be referenced from many parents, each reference drawing it under another
//! transform (Foley, van Dam, Feiner & Hughes, *Computer Graphics: Principles and Practice*,
//! 2nd ed., §7.4, "hierarchical structure networks"). Here the heavy data is shared and the
//! light data is copied: each placement gets its own nodes (so each can be moved, restyled or
//! removed on its own, and has its own world matrix), while meshes and materials are handles
//! into the scene's stores, never copied per placement.
//!
//! * [`Scene::instantiate`] copies a subtree of the same scene.
//! * [`Scene::add_prefab`] brings another scene's meshes and materials in once and returns a
//!   [`Prefab`]: the other scene's node tree as a template whose handles point into this
//!   scene. [`Scene::instantiate_prefab`] then places it any number of times;
//!   [`Scene::instantiate_from`] does both for a single placement.
//!
//! Cameras on the copied nodes are copied, and so are the animation channels aimed at them
//! (aimed at the copies), so a placed animated model moves like the original. The node
//! returned by every placement has `transform` as its local transform.

use std::collections::HashMap;

use glam::Affine3A;

use super::{live, MaterialId, MeshId, NodeDesc, NodeId, Scene, SceneCamera, SceneId};
use crate::animation::{Animation, Channel};
use crate::{Error, Mesh, Projection, Result, Transform};

/// A subtree read as a template: its nodes, the cameras on them, the animations of them.
struct Template {
    nodes: Vec<TemplateNode>,
    cameras: Vec<TemplateCamera>,
    animations: Vec<TemplateAnimation>,
}

/// One node of a template: parents come before their children.
#[derive(Debug, Clone)]
struct TemplateNode {
    name: String,
    /// Index of the parent in the template (`None`: a root of the template).
    parent: Option<u32>,
    local: Affine3A,
    trs: Option<Transform>,
    mesh: Option<MeshId>,
    material: Option<MaterialId>,
}

/// A camera on a template node.
#[derive(Debug, Clone)]
struct TemplateCamera {
    node: u32,
    name: String,
    projection: Projection,
}

/// The channels of one animation aimed at template nodes: `targets[k]` is the template
/// index of channel `k`'s node (the channels' own targets are the source's nodes).
#[derive(Debug, Clone)]
struct TemplateAnimation {
    animation: Animation,
    targets: Vec<u32>,
}

impl TemplateAnimation {
    /// The animation aimed at the nodes made for the template (`node(i)`: template node `i`'s
    /// copy, if it has one).
    fn aimed(&self, node: impl Fn(u32) -> Option<NodeId>) -> Animation {
        let mut a = self.animation.clone();
        let mut targets = self.targets.iter();
        a.channels.retain_mut(|c| match targets.next().and_then(|&i| node(i)) {
            Some(n) => {
                c.target = n;
                true
            }
            None => false,
        });
        a
    }
}

/// Another scene's node tree, ready to be placed in the scene it was added to: its meshes and
/// materials already live in that scene's stores, so each placement copies nodes only.
///
/// Made by [`Scene::add_prefab`] (or [`crate::load_prefab`]); placed by
/// [`Scene::instantiate_prefab`]. A prefab belongs to the scene value it was added to (by
/// [`SceneId`]): placing it in another scene, a clone included, is an error.
#[derive(Debug, Clone)]
pub struct Prefab {
    name: String,
    scene: SceneId,
    nodes: Vec<TemplateNode>,
    cameras: Vec<TemplateCamera>,
    animations: Vec<TemplateAnimation>,
}

impl Prefab {
    /// The name each placement's new root node gets ("prefab" unless set; a loaded file's
    /// prefab is named after the file).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The same prefab with another name for the roots of its placements.
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }
    /// The scene whose stores hold its meshes and materials.
    pub fn scene(&self) -> SceneId {
        self.scene
    }
    /// Nodes each placement adds, besides its root.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

impl Scene {
    /// Copies the subtree under `source` (nodes, local transforms, the cameras on them and the
    /// animation channels aimed at them) and puts
    /// the copy under `parent` (`None`: as a root), with `transform` as the copy's local
    /// transform in place of `source`'s. Meshes and materials are shared, not copied. Returns
    /// the copy of `source`.
    ///
    /// `parent` may lie inside the copied subtree (the subtree is read before anything is
    /// added). Errors on stale handles and a non-finite transform, before changing anything.
    pub fn instantiate(&mut self, source: NodeId, parent: Option<NodeId>, transform: Transform) -> Result<NodeId> {
        let src = self.try_node(source)?;
        let local = transform.to_affine(&format!("copy of node '{}'", src.name))?;
        if let Some(p) = parent {
            self.try_node(p)?;
        }
        let Template { mut nodes, cameras, animations } = self.template(&[source], Some, Some);
        let mut root = nodes.remove(0);
        root.local = local;
        for n in &mut nodes {
            // Indices shift by one with the root taken out; the root's children become roots.
            n.parent = n.parent.and_then(|p| p.checked_sub(1));
        }
        let desc =
            NodeDesc { name: root.name, local: root.local, trs: root.trs, mesh: root.mesh, material: root.material };
        let id = self.add_node(parent, desc)?;
        let created = self.place(&nodes, id)?;
        let copy_of = |i: u32| match i {
            0 => Some(id),
            i => created.get(i as usize - 1).copied(),
        };
        for c in cameras {
            if let Some(node) = copy_of(c.node) {
                self.cameras.push(SceneCamera { name: c.name, node, projection: c.projection });
            }
        }
        for a in &animations {
            self.add_animation(a.aimed(copy_of));
        }
        Ok(id)
    }

    /// Brings `other` in as a [`Prefab`]: the meshes and materials its nodes use are added to
    /// this scene once (copied from `other`), its node tree and cameras become the template,
    /// and its warnings are appended to this scene's. Nothing is placed yet.
    pub fn add_prefab(&mut self, other: &Scene) -> Prefab {
        self.adopt(other, |m| other.meshes.get(m).cloned())
    }

    /// [`Scene::add_prefab`] for a scene that is no longer needed: its meshes are moved, not
    /// copied.
    pub fn add_prefab_owned(&mut self, mut other: Scene) -> Prefab {
        let mut store = std::mem::take(&mut other.meshes);
        self.adopt(&other, |m| store.remove(m))
    }

    /// Places `prefab` under `parent` (`None`: as a root): a new node named after the prefab,
    /// with `transform` as its local transform, holding a copy of the prefab's node tree (and
    /// of the cameras on it and of the animation channels aimed at it). Returns the new node.
    ///
    /// Errors, before changing anything, when the prefab belongs to another scene, `parent`
    /// is stale or the transform is not finite.
    pub fn instantiate_prefab(
        &mut self,
        prefab: &Prefab,
        parent: Option<NodeId>,
        transform: Transform,
    ) -> Result<NodeId> {
        if prefab.scene != self.id {
            return Err(Error::ForeignPrefab { prefab: prefab.name.clone() });
        }
        let placement = transform.normalized(&format!("placement of prefab '{}'", prefab.name))?;
        if let Some(p) = parent {
            self.try_node(p)?;
        }
        let root = self.add_node(parent, NodeDesc::new(prefab.name.clone()).transform(placement))?;
        let created = self.place(&prefab.nodes, root)?;
        for c in &prefab.cameras {
            if let Some(&node) = created.get(c.node as usize) {
                self.cameras.push(SceneCamera { name: c.name.clone(), node, projection: c.projection });
            }
        }
        for a in &prefab.animations {
            self.add_animation(a.aimed(|i| created.get(i as usize).copied()));
        }
        Ok(root)
    }

    /// Places all of `other` once under `parent`: [`Scene::add_prefab`] then
    /// [`Scene::instantiate_prefab`]. Each call adds `other`'s meshes again; to place one
    /// scene many times, add it as a prefab once.
    pub fn instantiate_from(&mut self, other: &Scene, parent: Option<NodeId>, transform: Transform) -> Result<NodeId> {
        let prefab = self.add_prefab(other);
        self.instantiate_prefab(&prefab, parent, transform)
    }

    /// Adds template nodes under `root`; returns the node made for each template node.
    fn place(&mut self, nodes: &[TemplateNode], root: NodeId) -> Result<Vec<NodeId>> {
        let mut created: Vec<NodeId> = Vec::with_capacity(nodes.len());
        for n in nodes {
            let parent = n.parent.and_then(|p| created.get(p as usize).copied()).unwrap_or(root);
            let desc =
                NodeDesc { name: n.name.clone(), local: n.local, trs: n.trs, mesh: n.mesh, material: n.material };
            created.push(self.add_node(Some(parent), desc)?);
        }
        Ok(created)
    }

    /// A prefab of `other` whose meshes (taken through `take_mesh`) and materials are added
    /// to this scene.
    fn adopt(&mut self, other: &Scene, mut take_mesh: impl FnMut(MeshId) -> Option<Mesh>) -> Prefab {
        let mut meshes: HashMap<MeshId, Option<MeshId>> = HashMap::new();
        let mut materials: HashMap<MaterialId, Option<MaterialId>> = HashMap::new();
        let Template { nodes, cameras, animations } = other.template(
            &other.roots().collect::<Vec<_>>(),
            |m| *meshes.entry(m).or_insert_with(|| take_mesh(m).map(|mesh| self.meshes.insert(mesh))),
            |m| *materials.entry(m).or_insert_with(|| other.materials.get(m).map(|x| self.materials.insert(x.clone()))),
        );
        self.warnings.extend(other.warnings.iter().cloned());
        Prefab { name: "prefab".into(), scene: self.id, nodes, cameras, animations }
    }

    /// The subtrees under `roots` as a template (depth-first, parents first) with mesh and
    /// material handles mapped through `mesh` and `material`, the cameras on them and the
    /// animation channels aimed at them.
    fn template(
        &self,
        roots: &[NodeId],
        mut mesh: impl FnMut(MeshId) -> Option<MeshId>,
        mut material: impl FnMut(MaterialId) -> Option<MaterialId>,
    ) -> Template {
        let mut nodes = Vec::new();
        let mut index: HashMap<NodeId, u32> = HashMap::new();
        let mut stack: Vec<(NodeId, Option<u32>)> = roots.iter().rev().map(|&r| (r, None)).collect();
        while let Some((id, parent)) = stack.pop() {
            let Some(n) = self.nodes.get(id) else { continue };
            let i = nodes.len() as u32;
            index.insert(id, i);
            nodes.push(TemplateNode {
                name: n.name.to_string(),
                parent,
                local: n.parent_from_local,
                trs: self.trs.get(id).copied(),
                mesh: n.mesh.and_then(&mut mesh),
                material: n.material.and_then(&mut material),
            });
            stack.extend(live(&n.children).rev().map(|c| (c, Some(i))));
        }
        let cameras = self
            .cameras
            .iter()
            .filter_map(|c| {
                let &node = index.get(&c.node)?;
                Some(TemplateCamera { node, name: c.name.clone(), projection: c.projection })
            })
            .collect();
        let animations = self
            .animations
            .iter()
            .filter_map(|a| {
                let (channels, targets): (Vec<Channel>, Vec<u32>) =
                    a.channels.iter().filter_map(|c| Some((c.clone(), *index.get(&c.target)?))).unzip();
                let animation = Animation { name: a.name.clone(), channels, wrap: a.wrap };
                (!animation.channels.is_empty()).then_some(TemplateAnimation { animation, targets })
            })
            .collect();
        Template { nodes, cameras, animations }
    }
}

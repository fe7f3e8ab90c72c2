//! The property consumers rely on: a copy of `instances()` kept up to date only through the
//! change reports (`delta_since`, then `changes()` applied with `instance(node)` lookups) is
//! always exactly the new `instances()` — same nodes, meshes, world matrices, bounds,
//! materials and first triangles — after any sequence of edits.

use std::collections::{HashMap, HashSet};

use glam::{Quat, Vec3};
use proptest::prelude::*;
use sightline_scene::*;

/// A consumer that follows a scene through its change reports.
struct Mirror {
    stamp: SceneStamp,
    items: HashMap<NodeId, Instance>,
}

impl Mirror {
    fn new(s: &Scene) -> Self {
        let mut m = Mirror { stamp: s.stamp(), items: HashMap::new() };
        m.rebuild(s);
        m
    }

    fn rebuild(&mut self, s: &Scene) {
        self.items = s.instances().into_iter().map(|i| (i.node, i)).collect();
    }

    fn sync(&mut self, s: &Scene) {
        assert!(!s.needs_update());
        match s.delta_since(self.stamp) {
            SceneDelta::UpToDate => {}
            SceneDelta::Rebuild => self.rebuild(s),
            SceneDelta::Apply(c) => {
                for list in [&c.moved, &c.added, &c.removed, &c.restyled] {
                    assert_eq!(list.iter().collect::<HashSet<_>>().len(), list.len(), "a node twice in {c:?}");
                }
                for n in &c.removed {
                    assert!(self.items.remove(n).is_some(), "removed {n:?} was not drawn");
                    assert!(s.instance(*n).is_none() || c.added.contains(n), "removed {n:?} still drawn");
                }
                for n in &c.added {
                    let i = s.instance(*n).expect("an added node is drawn");
                    assert!(self.items.insert(*n, i).is_none(), "added {n:?} was drawn already");
                }
                for n in &c.moved {
                    let (e, i) = (self.items.get_mut(n).expect("a moved node was drawn"), s.instance(*n).unwrap());
                    (e.world_from_local, e.world_aabb) = (i.world_from_local, i.world_aabb);
                }
                for n in &c.restyled {
                    let (e, i) = (self.items.get_mut(n).expect("a restyled node was drawn"), s.instance(*n).unwrap());
                    e.material = i.material;
                }
                if c.order_changed {
                    for (n, e) in &mut self.items {
                        e.first_triangle = s.instance(*n).unwrap().first_triangle;
                    }
                }
            }
        }
        self.stamp = s.stamp();
    }

    fn check(&self, s: &Scene) {
        let mut mine: Vec<Instance> = self.items.values().copied().collect();
        mine.sort_by_key(|i| i.first_triangle);
        assert_eq!(mine, s.instances());
    }
}

/// The instances worked out from scratch: depth-first mesh nodes, world matrices composed up
/// the parent chain, materials looked up the parent chain.
fn oracle(s: &Scene) {
    let list = s.instances();
    let drawn: Vec<NodeId> = s.depth_first().filter(|&n| s.node(n).unwrap().mesh().is_some()).collect();
    assert_eq!(list.iter().map(|i| i.node).collect::<Vec<_>>(), drawn);
    let mut first = 0;
    for i in &list {
        let want = s.world_from_local_now(i.node).unwrap();
        assert!(i.world_from_local.abs_diff_eq(want, 1e-3), "{:?} vs {want:?}", i.world_from_local);
        let mut material = None;
        let mut cur = Some(i.node);
        while let (None, Some(c)) = (material, cur) {
            material = s.node(c).unwrap().material();
            cur = s.node(c).unwrap().parent();
        }
        assert_eq!(i.material, material);
        assert_eq!(i.mesh, s.node(i.node).unwrap().mesh().unwrap());
        assert_eq!(i.first_triangle, first);
        first += i.triangle_count;
    }
}

#[derive(Debug, Clone)]
enum Edit {
    Move(usize, [i8; 3], i8),
    Add(Option<usize>, u8, u8),
    Remove(usize),
    Reparent(usize, Option<usize>, bool),
    SetMesh(usize, u8),
    SetMaterial(usize, u8),
    Instantiate(usize, Option<usize>),
    /// Propagate, and let the consumer catch up.
    Update,
    /// Propagate without the consumer looking (it falls two revisions behind).
    UpdateUnseen,
}

fn edit() -> impl Strategy<Value = Edit> {
    let pick = any::<usize>();
    prop_oneof![
        4 => (pick, any::<[i8; 3]>(), any::<i8>()).prop_map(|(n, t, r)| Edit::Move(n, t, r)),
        3 => (proptest::option::of(pick), 0..4u8, 0..3u8).prop_map(|(p, m, c)| Edit::Add(p, m, c)),
        1 => pick.prop_map(Edit::Remove),
        2 => (pick, proptest::option::of(pick), any::<bool>()).prop_map(|(n, p, k)| Edit::Reparent(n, p, k)),
        2 => (pick, 0..4u8).prop_map(|(n, m)| Edit::SetMesh(n, m)),
        2 => (pick, 0..3u8).prop_map(|(n, m)| Edit::SetMaterial(n, m)),
        1 => (pick, proptest::option::of(pick)).prop_map(|(n, p)| Edit::Instantiate(n, p)),
        3 => Just(Edit::Update),
        1 => Just(Edit::UpdateUnseen),
    ]
}

struct World {
    s: Scene,
    meshes: [MeshId; 3],
    materials: [MaterialId; 2],
}

impl World {
    fn new() -> Self {
        let mut s = Scene::new();
        let tri = Mesh::new("tri", vec![Vec3::ZERO, Vec3::X, Vec3::Y], None, None, vec![0, 1, 2]).unwrap();
        let meshes = [s.add_mesh(shapes::cube("a").unwrap()), s.add_mesh(shapes::cube("b").unwrap()), s.add_mesh(tri)];
        let materials = [s.add_material(Material::color("red", [1.0, 0.0, 0.0])), s.add_material(Material::default())];
        let g = s.add_node(None, NodeDesc::new("g").material(materials[0])).unwrap();
        s.add_node(Some(g), NodeDesc::new("a").mesh(meshes[0])).unwrap();
        s.add_node(None, NodeDesc::new("b").mesh(meshes[2])).unwrap();
        s.update_transforms();
        World { s, meshes, materials }
    }

    fn pick(&self, k: usize) -> Option<NodeId> {
        let all: Vec<NodeId> = self.s.depth_first().collect();
        (!all.is_empty()).then(|| all[k % all.len()])
    }

    fn mesh(&self, m: u8) -> Option<MeshId> {
        (m > 0).then(|| self.meshes[m as usize - 1])
    }

    fn material(&self, m: u8) -> Option<MaterialId> {
        (m > 0).then(|| self.materials[m as usize - 1])
    }

    /// Applies one edit; edits the scene refuses (cycles, stale handles) are fine.
    fn apply(&mut self, e: &Edit, mirror: &mut Mirror) {
        let parent = |w: &Self, p: &Option<usize>| p.and_then(|p| w.pick(p));
        match e {
            Edit::Move(n, t, r) => {
                if let Some(n) = self.pick(*n) {
                    let t = Transform::from_translation(Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32) * 0.25)
                        .with_rotation(Quat::from_rotation_y(*r as f32 * 0.05));
                    self.s.set_local_transform(n, t).unwrap();
                }
            }
            Edit::Add(p, m, c) => {
                let mut d = NodeDesc::new("new");
                (d.mesh, d.material) = (self.mesh(*m), self.material(*c));
                self.s.add_node(parent(self, p), d).unwrap();
            }
            Edit::Remove(n) => {
                if let Some(n) = self.pick(*n) {
                    self.s.remove_node(n).unwrap();
                }
            }
            Edit::Reparent(n, p, world) => {
                if let Some(n) = self.pick(*n) {
                    let keep = if *world { Keep::World } else { Keep::Local };
                    let _ = self.s.set_parent(n, parent(self, p), keep);
                }
            }
            Edit::SetMesh(n, m) => {
                if let Some(n) = self.pick(*n) {
                    self.s.set_mesh(n, self.mesh(*m)).unwrap();
                }
            }
            Edit::SetMaterial(n, m) => {
                if let Some(n) = self.pick(*n) {
                    self.s.set_material(n, self.material(*m)).unwrap();
                }
            }
            Edit::Instantiate(n, p) => {
                if let (Some(n), true) = (self.pick(*n), self.s.node_count() < 200) {
                    let t = Transform::from_translation(Vec3::Z);
                    self.s.instantiate(n, parent(self, p), t).unwrap();
                }
            }
            Edit::Update => {
                self.s.update_transforms();
                mirror.sync(&self.s);
                mirror.check(&self.s);
            }
            Edit::UpdateUnseen => {
                self.s.update_transforms();
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn change_reports_replay_to_the_new_instances(edits in proptest::collection::vec(edit(), 1..40)) {
        let mut w = World::new();
        let mut mirror = Mirror::new(&w.s);
        for e in &edits {
            w.apply(e, &mut mirror);
        }
        w.s.update_transforms();
        mirror.sync(&w.s);
        mirror.check(&w.s);
        oracle(&w.s);
        for i in w.s.instances() {
            prop_assert_eq!(w.s.instance(i.node), Some(i));
        }
    }
}

#[test]
fn the_mirror_notices_a_missed_move() {
    // The replay check itself can fail: a consumer that skips `moved` ends up wrong.
    let mut w = World::new();
    let mut mirror = Mirror::new(&w.s);
    let a = w.s.find("a").unwrap();
    w.s.set_local_transform(a, Transform::from_translation(Vec3::X)).unwrap();
    w.s.update_transforms();
    let stale = mirror.items.clone();
    mirror.sync(&w.s);
    mirror.check(&w.s);
    mirror.items = stale;
    assert!(std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| mirror.check(&w.s))).is_err());
}

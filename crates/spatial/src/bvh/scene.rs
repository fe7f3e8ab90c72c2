//! A whole scene for culling: per-mesh clusters (built once per mesh, shared by every
//! instance of it) and one BVH over the world boxes of all (instance, cluster) pairs.
//!
//! One structure serves both extremes: a city of many small instances (each instance is one
//! cluster, so the BVH is a BVH over instances) and one 10^6-triangle mesh loaded from an OBJ
//! (thousands of clusters of one instance carry the culling). An occlusion culler (the
//! renderer's `hzb` methods) walks it front to back with
//! [`ClusteredScene::traverse_front_to_back`] or, batch by batch,
//! with a [`FrontToBackCursor`] from [`ClusteredScene::cursor`]; it asks "is this box possibly
//! visible?" for every node and cluster box, and draws the surviving items' triangles
//! ([`ClusteredScene::triangles`], original mesh-local triangle indices; the global triangle
//! index is `instance.first_triangle + t`).

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;
use sightline_scene::{Aabb, Instance, MeshId, Scene};

use super::background::Background;
use super::cluster::MeshClusters;
use super::front_to_back::FrontToBackCursor;
use super::policy::RefitOutcome;
use super::{Bvh, BvhPreset};
use crate::{CullCounters, CullOptions, FrontToBack, Frustum, FrustumCull, Visible, Visit};

/// Items per BVH leaf.
const SCENE_LEAF: u32 = 4;
/// The build of the BVH over clusters: obvhs's medium preset (a wider PLOC search, and
/// reinsertion after collapsing leaves too) against its fast one, on the street path (120
/// frames) of the 10^9-triangle city: 9.8% fewer occlusion tests and 5% fewer clusters drawn
/// a frame (10^8: 5.8% and 1.5%; the default city the same), for 5.7 s of build instead of
/// 4.2 s there (10^8: 0.53 s instead of 0.41 s). The walk visits fewer boxes of a tree whose
/// boxes overlap less. Rebuilds after edits, and after refits that left the tree too costly
/// (see `RefitOutcome`), use it too: `examples/moving_cost` (10,000 vehicles and the cranes
/// moving) ran 1.574–1.576× the parked frames with it and 1.561–1.588× with the fast preset.
const SCENE_PRESET: BvhPreset = BvhPreset::Medium;

/// One BVH item: a cluster of an instance's mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClusterItem {
    /// Index of the instance in the slice the scene was built from.
    pub instance: u32,
    /// Index of the cluster in that instance's mesh's [`MeshClusters`].
    pub cluster: u32,
}

/// Per-mesh clusters plus a BVH over every (instance, cluster) world box.
#[derive(Debug, Clone, Default)]
pub struct ClusteredScene {
    meshes: Vec<MeshClusters>,
    mesh_ids: Vec<MeshId>,
    instance_mesh: Vec<u32>,
    instance_first_item: Vec<u32>,
    items: Vec<ClusterItem>,
    bvh: Bvh,
    build_cost: f32,
    /// The rebuild of `bvh` under way off the frame, if any.
    background: Background<Bvh>,
}

impl ClusteredScene {
    /// Builds for `scene.instances()` (call `scene.update_transforms()` first).
    pub fn build(scene: &Scene) -> ClusteredScene {
        Self::from_instances(scene, &scene.instances())
    }

    /// Builds for the given instances of `scene` (instances whose mesh handle is stale get no
    /// items). Meshes are clustered in parallel, once each.
    pub fn from_instances(scene: &Scene, instances: &[Instance]) -> ClusteredScene {
        Self::from_instances_reusing(scene, instances, HashMap::new())
    }

    /// Builds anew for changed instances (added, removed, reordered, other meshes), keeping
    /// the clusters of every mesh that is still drawn: only meshes new to the scene are
    /// clustered.
    pub fn rebuild(&mut self, scene: &Scene, instances: &[Instance]) {
        let old = std::mem::take(self);
        let known: HashMap<MeshId, MeshClusters> = old.mesh_ids.into_iter().zip(old.meshes).collect();
        *self = Self::from_instances_reusing(scene, instances, known);
    }

    fn from_instances_reusing(
        scene: &Scene,
        instances: &[Instance],
        mut known: HashMap<MeshId, MeshClusters>,
    ) -> ClusteredScene {
        let mut mesh_slot: HashMap<MeshId, u32> = HashMap::new();
        let mut mesh_ids: Vec<MeshId> = Vec::new();
        let instance_mesh: Vec<u32> = instances
            .iter()
            .map(|inst| {
                if scene.mesh(inst.mesh).is_none() {
                    return u32::MAX;
                }
                *mesh_slot.entry(inst.mesh).or_insert_with(|| {
                    mesh_ids.push(inst.mesh);
                    mesh_ids.len() as u32 - 1
                })
            })
            .collect();
        let reused: Vec<Option<MeshClusters>> = mesh_ids.iter().map(|id| known.remove(id)).collect();
        let meshes: Vec<MeshClusters> = mesh_ids
            .par_iter()
            .zip(reused)
            .map(|(&id, done)| done.unwrap_or_else(|| scene.mesh(id).map(MeshClusters::build).unwrap_or_default()))
            .collect();
        let mut items = Vec::new();
        let mut instance_first_item = Vec::with_capacity(instances.len() + 1);
        for (i, &m) in instance_mesh.iter().enumerate() {
            instance_first_item.push(items.len() as u32);
            if m == u32::MAX {
                continue;
            }
            let n = meshes[m as usize].clusters().len() as u32;
            items.extend((0..n).map(|c| ClusterItem { instance: i as u32, cluster: c }));
        }
        instance_first_item.push(items.len() as u32);
        let mut s =
            ClusteredScene { meshes, mesh_ids, instance_mesh, instance_first_item, items, ..Default::default() };
        (s.bvh, s.build_cost) = fresh_tree(&s.item_boxes(instances));
        s
    }

    /// World boxes of every item (index = item id) for `instances` (the build's instances,
    /// possibly moved), e.g. to put the clusters into a [`crate::LooseOctree`]. All NaN when
    /// `instances` do not [match](ClusteredScene::matches) the build.
    pub fn item_boxes(&self, instances: &[Instance]) -> Vec<Aabb> {
        if !self.matches(instances) {
            return vec![Aabb::new(Vec3::NAN, Vec3::NAN); self.items.len()];
        }
        let mut boxes = vec![Aabb::EMPTY; self.items.len()];
        boxes.par_chunks_mut(4096).enumerate().for_each(|(chunk, out)| {
            let base = chunk * 4096;
            for (k, b) in out.iter_mut().enumerate() {
                *b = self.item_box((base + k) as u32, instances);
            }
        });
        boxes
    }

    /// The world box of item `i` for `instances` (which must
    /// [match](ClusteredScene::matches) the build): its cluster's box under its instance's
    /// transform (the instance's box when the mesh is one cluster).
    #[inline]
    pub fn item_box(&self, i: u32, instances: &[Instance]) -> Aabb {
        self.item_box_of(i, &instances[self.items[i as usize].instance as usize])
    }

    /// [`ClusteredScene::item_box`] given item `i`'s instance itself (`inst` must be the
    /// build's instance [`ClusterItem::instance`] of item `i`, possibly moved).
    #[inline]
    pub fn item_box_of(&self, i: u32, inst: &Instance) -> Aabb {
        let it = self.items[i as usize];
        let mc = &self.meshes[self.instance_mesh[it.instance as usize] as usize];
        if mc.clusters().len() == 1 {
            inst.world_aabb
        } else {
            mc.clusters()[it.cluster as usize].aabb.transformed(&inst.world_from_local)
        }
    }

    /// True when `instances` are the build's instances (same count, same meshes), possibly
    /// moved.
    pub fn matches(&self, instances: &[Instance]) -> bool {
        instances.len() + 1 == self.instance_first_item.len()
            && instances
                .iter()
                .zip(&self.instance_mesh)
                .all(|(inst, &m)| m == u32::MAX || self.mesh_ids[m as usize] == inst.mesh)
    }

    /// Refits after instances moved (same instances, same order as the build); see
    /// [`ClusteredScene::refit_boxes`] for when the BVH is rebuilt. Clusters are mesh-local
    /// and never rebuilt. `None` when `instances` do not match the build (count or meshes
    /// changed): build a new `ClusteredScene` then.
    pub fn update(&mut self, instances: &[Instance]) -> Option<RefitOutcome> {
        if !self.matches(instances) {
            return None;
        }
        let boxes = self.item_boxes(instances);
        Some(self.refit_boxes(&boxes))
    }

    /// Refits the BVH to new item boxes (index = item). When its SAH cost has grown beyond
    /// [`REBUILD_RATIO`](crate::REBUILD_RATIO) × the fresh build's, a new tree is built on a
    /// background thread from these boxes, and the update [`rebuild_lag`](crate::rebuild_lag)
    /// updates later puts it in place, refitted to the boxes of then (waiting for it if it
    /// is not done); the updates between refit the old tree. When an item's box changed kind
    /// (became empty, unbounded or finite again) the BVH is rebuilt here and now.
    pub fn refit_boxes(&mut self, boxes: &[Aabb]) -> RefitOutcome {
        self.refit_by(boxes, |bvh| bvh.refit_cost(boxes))
    }

    /// [`ClusteredScene::refit_boxes`] when only the items `changed` have new boxes (see
    /// [`Bvh::refit_changed`]).
    pub fn refit_changed(&mut self, boxes: &[Aabb], changed: &[u32]) -> RefitOutcome {
        self.refit_by(boxes, |bvh| bvh.refit_changed_cost(boxes, changed))
    }

    /// One update to `boxes` by the background rule, the tree refitted by `refit`.
    fn refit_by(&mut self, boxes: &[Aabb], refit: impl FnOnce(&mut Bvh) -> Option<f32>) -> RefitOutcome {
        self.background.update((&mut self.bvh, &mut self.build_cost), boxes, Bvh::refit_cost, refit, fresh_tree)
    }

    /// Number of items ((instance, cluster) pairs).
    pub fn item_count(&self) -> usize {
        self.items.len()
    }

    /// Item `i`: which instance and which of its mesh's clusters.
    pub fn item(&self, i: u32) -> ClusterItem {
        self.items[i as usize]
    }

    /// Items of instance `instance`: a contiguous range of item indices, in the order of
    /// its mesh's clusters (item `first + c` is cluster `c`).
    pub fn instance_items(&self, instance: u32) -> std::ops::Range<u32> {
        let i = instance as usize;
        self.instance_first_item[i]..self.instance_first_item[i + 1]
    }

    /// The first item of instance `instance`, or the item count for `instance` = the number
    /// of instances: items of instances `a..b` are `first_item(a)..first_item(b)`.
    pub fn first_item(&self, instance: u32) -> u32 {
        self.instance_first_item[instance as usize]
    }

    /// The original (mesh-local) triangle indices that item `i` draws.
    pub fn triangles(&self, i: u32) -> &[u32] {
        let it = self.items[i as usize];
        self.meshes[self.instance_mesh[it.instance as usize] as usize].triangles(it.cluster as usize)
    }

    /// The clusters of the mesh instance `instance` draws.
    pub fn mesh_clusters(&self, instance: u32) -> Option<&MeshClusters> {
        self.meshes.get(*self.instance_mesh.get(instance as usize)? as usize)
    }

    /// Total number of clusters over the distinct meshes.
    pub fn cluster_count(&self) -> usize {
        self.meshes.iter().map(|m| m.clusters().len()).sum()
    }

    /// The BVH over items.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Frustum culling: appends visible items (indices into the items) to `out`.
    pub fn cull_with(&self, frustum: &Frustum, opts: CullOptions, out: &mut Vec<Visible>) -> CullCounters {
        self.bvh.cull_with(frustum, opts, out)
    }

    /// How many items [`ClusteredScene::cull_with`] (plane masking on) would list, without
    /// listing them; see [`Bvh::count_in_frustum`].
    pub fn count_in_frustum(&self, frustum: &Frustum) -> u64 {
        self.bvh.count_in_frustum(frustum)
    }

    /// Front-to-back traversal over items, culled by `frustum` when given; `node_visit`
    /// answers "is this node/cluster box possibly visible?" (`Skip` prunes it). See
    /// [`Bvh::traverse_front_to_back`].
    pub fn traverse_front_to_back(
        &self,
        frustum: Option<&Frustum>,
        eye: Vec3,
        node_visit: impl FnMut(&Aabb) -> Visit,
        item_visit: impl FnMut(Visible) -> Visit,
    ) {
        self.bvh.traverse_front_to_back(frustum, eye, node_visit, item_visit)
    }

    /// A resumable front-to-back traversal (batches of items; see [`FrontToBackCursor`]);
    /// pass [`ClusteredScene::bvh`] to its `next_batch`.
    pub fn cursor(&self, frustum: Option<&Frustum>, eye: Vec3) -> FrontToBackCursor {
        FrontToBackCursor::new(&self.bvh, frustum, eye)
    }

    /// Heap bytes held (clusters, items, BVH).
    pub fn memory_bytes(&self) -> usize {
        self.meshes.iter().map(|m| m.memory_bytes()).sum::<usize>()
            + self.instance_mesh.capacity() * 4
            + self.instance_first_item.capacity() * 4
            + self.items.capacity() * std::mem::size_of::<ClusterItem>()
            + self.bvh.memory_bytes()
    }
}

/// The BVH over item boxes `boxes`, with its SAH cost.
fn fresh_tree(boxes: &[Aabb]) -> (Bvh, f32) {
    Bvh::build_costed(boxes, SCENE_PRESET, SCENE_LEAF)
}

impl FrustumCull for ClusteredScene {
    fn cull(&self, frustum: &Frustum, out: &mut Vec<Visible>) {
        self.bvh.cull_with(frustum, CullOptions::default(), out);
    }
}

impl FrontToBack for ClusteredScene {
    fn order(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.bvh.order_front_to_back(eye, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sightline_scene::{shapes, NodeDesc, Transform};

    #[test]
    fn one_big_mesh_is_culled_in_parts_and_instances_share_clusters() {
        let mut scene = Scene::new();
        let big = scene.add_mesh(
            shapes::subdivided_box("big", Vec3::ZERO, Vec3::new(40.0, 2.0, 40.0), [80, 4, 80], false).unwrap(),
        );
        let cube = scene.add_mesh(shapes::cube("c").unwrap());
        scene.add_node(None, NodeDesc::new("big").mesh(big)).unwrap();
        for i in 0..10 {
            let t = Transform::from_translation(Vec3::new(i as f32 * 3.0, 5.0, 0.0));
            scene.add_node(None, NodeDesc::new("c").transform(t).mesh(cube)).unwrap();
        }
        scene.update_transforms();
        let cs = ClusteredScene::build(&scene);
        let big_clusters = cs.mesh_clusters(0).unwrap().clusters().len();
        assert!(big_clusters > 50);
        assert_eq!(cs.item_count(), big_clusters + 10);
        assert_eq!(cs.instance_items(3), (big_clusters as u32 + 2)..(big_clusters as u32 + 3));
        // Every triangle of the big mesh is drawn by exactly one of its items.
        let mut seen = vec![0u8; scene.mesh(big).unwrap().triangle_count()];
        for it in cs.instance_items(0) {
            for &t in cs.triangles(it) {
                seen[t as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        // Item `first + c` of an instance is its mesh's cluster `c`.
        for it in cs.instance_items(0).chain(cs.instance_items(3)) {
            let first = cs.first_item(cs.item(it).instance);
            assert_eq!(cs.item(it).cluster, it - first);
        }
        // A camera close to a corner of the big mesh sees only part of it.
        let cam = sightline_scene::Camera::perspective(
            &sightline_scene::LookAt {
                eye: Vec3::new(1.0, 3.0, 1.0),
                target: Vec3::new(5.0, 2.0, 5.0),
                up: Vec3::Y,
                fovy: sightline_scene::Angle::degrees(40.0),
                near: 0.1,
                far: 10.0,
            },
            1.0,
        )
        .unwrap();
        let mut out = Vec::new();
        cs.cull(&Frustum::from_camera(&cam), &mut out);
        let big_visible = out.iter().filter(|v| cs.item(v.index).instance == 0).count();
        assert!(big_visible > 0 && big_visible * 4 < big_clusters, "{big_visible} of {big_clusters}");
        // Moving instances: refit keeps everything findable.
        let mut inst = scene.instances();
        for i in inst.iter_mut().skip(1) {
            i.world_aabb = Aabb::new(i.world_aabb.min + Vec3::Y, i.world_aabb.max + Vec3::Y);
        }
        assert!(matches!(cs.clone().update(&inst), Some(RefitOutcome::Refitted { .. })));
        assert!(cs.clone().update(&inst[1..]).is_none());
        assert_eq!(cs.item_boxes(&inst).len(), cs.item_count());
    }

    /// Moves every instance by `d` (plus its index's share of `spread`, scattering them).
    fn shift(inst: &mut [Instance], d: Vec3, spread: f32) {
        for (k, i) in inst.iter_mut().enumerate() {
            let o = d + Vec3::new(((k * 37) % 101) as f32 - 50.0, 0.0, ((k * 53) % 97) as f32 - 48.0) * spread;
            i.world_aabb = Aabb::new(i.world_aabb.min + o, i.world_aabb.max + o);
        }
    }

    /// `n` cubes over a 100 × 100 area, scattered after the build so that a background
    /// rebuild starts: the instances, the scene, the boxes the build starts from and the
    /// cost ratio that started it.
    fn rebuild_started(n: usize) -> (Vec<Instance>, ClusteredScene, Vec<Aabb>, f32) {
        let mut scene = Scene::new();
        let cube = scene.add_mesh(shapes::cube("c").unwrap());
        let mut rng = sightline_scene::rng::Rng::new(9);
        for _ in 0..n {
            let t = Transform::from_translation(Vec3::new(rng.range(-50.0, 50.0), 0.0, rng.range(-50.0, 50.0)));
            scene.add_node(None, NodeDesc::new("c").transform(t).mesh(cube)).unwrap();
        }
        scene.update_transforms();
        let mut inst = scene.instances();
        let mut cs = ClusteredScene::build(&scene);
        shift(&mut inst, Vec3::ZERO, 1.0);
        let started_from = cs.item_boxes(&inst);
        match cs.update(&inst) {
            Some(RefitOutcome::Rebuilding { cost_ratio }) => (inst, cs, started_from, cost_ratio),
            o => panic!("expected a background rebuild, got {o:?}"),
        }
    }

    /// A tree of up to `LAG_ITEMS` items waits `REBUILD_LAG` updates for its new tree, a
    /// larger one one more per `LAG_ITEMS`.
    #[test]
    fn the_lag_grows_with_the_items() {
        use crate::{rebuild_lag, LAG_ITEMS, REBUILD_LAG};
        assert_eq!([0, LAG_ITEMS - 1, LAG_ITEMS, 1_140_000].map(rebuild_lag), [8, 8, 9, 147]);
        assert_eq!(rebuild_lag(usize::MAX), u32::MAX);
        // Put in place at the lag of the tree's size.
        let (mut inst, mut cs, _, trigger) = rebuild_started(LAG_ITEMS + 10);
        for _ in 1..REBUILD_LAG + 1 {
            assert!(matches!(cs.update(&inst), Some(RefitOutcome::Rebuilding { .. })));
        }
        shift(&mut inst, Vec3::new(0.5, 0.0, 0.0), 0.0);
        assert_eq!(cs.update(&inst), Some(RefitOutcome::Rebuilt { cost_ratio: trigger }));
    }

    #[test]
    fn a_degraded_tree_is_rebuilt_in_the_background_and_put_in_place_lag_updates_later() {
        let (mut inst, mut cs, started_from, trigger) = rebuild_started(300);
        assert!(trigger > crate::REBUILD_RATIO);
        // Until it is due the old tree is refitted (and stays as degraded).
        for _ in 1..crate::REBUILD_LAG {
            shift(&mut inst, Vec3::new(0.5, 0.0, 0.0), 0.0);
            assert!(matches!(cs.update(&inst), Some(RefitOutcome::Rebuilding { .. })));
            cs.bvh().validate().unwrap();
        }
        // The due update puts in place the tree of the boxes it started from, refitted to
        // the boxes of now.
        shift(&mut inst, Vec3::new(0.5, 0.0, 0.0), 0.0);
        assert_eq!(cs.update(&inst), Some(RefitOutcome::Rebuilt { cost_ratio: trigger }));
        let mut expected = Bvh::build(&started_from, SCENE_PRESET, SCENE_LEAF);
        assert!(expected.refit(&cs.item_boxes(&inst)));
        assert!(cs.bvh().nodes() == expected.nodes() && cs.bvh().items() == expected.items());
        shift(&mut inst, Vec3::new(0.5, 0.0, 0.0), 0.0);
        match cs.update(&inst) {
            Some(RefitOutcome::Refitted { cost_ratio }) => assert!(cost_ratio < 1.01, "{cost_ratio}"),
            o => panic!("expected a refit of the new tree, got {o:?}"),
        }
    }

    /// A box changing kind while a build is under way rebuilds at once, and the build from
    /// the boxes of before is never put in place.
    #[test]
    fn a_box_changing_kind_rebuilds_now_and_drops_the_background_build() {
        let (mut inst, mut cs, _, _) = rebuild_started(300);
        inst[7].world_aabb = Aabb::new(Vec3::NAN, Vec3::NAN);
        assert!(matches!(cs.update(&inst), Some(RefitOutcome::Rebuilt { cost_ratio }) if cost_ratio.is_infinite()));
        assert_eq!(cs.bvh().unbounded(), &[7]);
        for _ in 0..2 * crate::REBUILD_LAG {
            shift(&mut inst, Vec3::new(0.1, 0.0, 0.0), 0.0);
            assert!(matches!(cs.update(&inst), Some(RefitOutcome::Refitted { .. })));
        }
        assert_eq!(cs.bvh().unbounded(), &[7]);
    }
}

//! Keeping the culling state in step with a scene that changes.
//!
//! Rigid motion is the common change (vehicles drive, a crane turns): clusters and meshlets
//! are mesh-local and stay; what moves is the world side — each moved instance's transform
//! in its per-cluster draw records, its clusters' world boxes, their entries in the loose
//! octree (built and moved when the octree walk next runs, so that the other methods do not
//! pay for it) and their normal cones — and the BVH over all cluster boxes is refitted bottom-up,
//! or rebuilt once refitting has let its SAH cost grow past `REBUILD_RATIO` times that of a
//! fresh build (the rule of Wald, Boulos and Shirley 2007, "Ray tracing deformable scenes
//! using dynamic bounding volume hierarchies": refit while the tree stays good, rebuild when
//! it has degraded; the rebuild runs on a background thread and its tree is put in place
//! `rebuild_lag` syncs later, so that it costs no frame a hitch). A material change only
//! updates the instance records (shading reads them). A change of what is drawn (instances
//! added, removed or reordered, a mesh swapped) rebuilds the world side but keeps the
//! clusters and meshlets of every mesh that is still drawn, so a mesh is clustered once,
//! however the scene changes.
//!
//! Two-pass culling needs nothing here: last frame's visible clusters are drawn at their
//! new place as this frame's first occluders (drawing more than needed never changes the
//! picture), and every other cluster is tested against the pyramid as usual.

use rayon::prelude::*;
use sightline_scene::{Aabb, Instance, NodeId, Scene, SceneDelta};
use sightline_spatial::{BoxProjector, ClusteredScene, LooseOctree, RefitOutcome};
use slotmap::SecondaryMap;

use super::{cone, ClusterDraw, Clusters, SceneMeshlets, TwoPass, OCTREE_DEPTH};

impl Clusters {
    /// Builds the culling state for `scene.instances()` (world transforms must be up to date),
    /// keeping the per-mesh clusters and meshlets of `reuse` for meshes still drawn.
    pub(super) fn build(scene: &Scene, reuse: Option<(ClusteredScene, SceneMeshlets)>) -> Clusters {
        Self::build_for(scene, scene.instances(), reuse)
    }

    /// A state that draws nothing, for a scene it must not draw (see [`super::Culler::new`]).
    /// Its stamp names a revision the scene has not reached, so the first sync that gets
    /// through builds the whole state instead of following a change report.
    pub(super) fn empty(scene: &Scene) -> Clusters {
        let mut c = Self::build_for(scene, Vec::new(), None);
        c.stamp.revision = u64::MAX;
        c
    }

    fn build_for(scene: &Scene, instances: Vec<Instance>, reuse: Option<(ClusteredScene, SceneMeshlets)>) -> Clusters {
        let (clustered, meshlets) = match reuse {
            Some((mut clustered, mut meshlets)) => {
                clustered.rebuild(scene, &instances);
                meshlets.rebuild(scene, &instances, &clustered);
                (clustered, meshlets)
            }
            None => {
                let clustered = ClusteredScene::from_instances(scene, &instances);
                let meshlets = SceneMeshlets::build(scene, &instances, &clustered);
                (clustered, meshlets)
            }
        };
        let item_boxes = clustered.item_boxes(&instances);
        let items = 0..clustered.item_count() as u32;
        let local_cones = local_cones(scene, &instances, &clustered, &meshlets);
        let cones: Vec<cone::Cone> = (0..clustered.item_count() as u32)
            .into_par_iter()
            .map(|i| world_cone(&local_cones, &meshlets, &clustered, &instances, i))
            .collect();
        let mut cone_can_cull = vec![0u64; cones.len().div_ceil(64)];
        for (i, c) in cones.iter().enumerate() {
            cone_can_cull[i / 64] |= (c.can_cull() as u64) << (i % 64);
        }
        let draws = items
            .map(|i| {
                let it = clustered.item(i);
                let inst = &instances[it.instance as usize];
                let slot = meshlets.slot(it.instance);
                let cluster = meshlets.by_slot(slot).clusters.get(it.cluster as usize).copied();
                // Clusters are made from the meshlets, so each has its range; a missing one
                // would draw nothing rather than panic in release builds.
                debug_assert!(cluster.is_some(), "cluster {i} has no meshlet range");
                let (first, count) = cluster.unwrap_or((0, 0));
                ClusterDraw {
                    world_from_local: inst.world_from_local.to_cols_array(),
                    meshlets: slot,
                    first_triangle: inst.first_triangle,
                    first,
                    count,
                }
            })
            .collect();
        let node_instance = instances.iter().enumerate().map(|(i, inst)| (inst.node, i as u32)).collect();
        let reach = instances.par_iter().map(|i| instance_reach(scene, i)).reduce(|| 0.0, f32::max);
        Clusters {
            stamp: scene.stamp(),
            instances,
            node_instance,
            clustered,
            meshlets,
            draws,
            item_boxes,
            local_cones,
            cones,
            cone_can_cull,
            reach,
            // Built when the octree walk first runs (`settle_octree`): the other methods
            // never read it, and over 10^7 clusters it takes seconds.
            octree: LooseOctree::new(&Aabb::EMPTY, 0),
            octree_pending: Vec::new(),
            octree_rebuild: true,
            moves: Vec::new(),
            changed: Vec::new(),
            visible: Vec::new(),
            two_pass: TwoPass::default(),
        }
    }
}

impl Clusters {
    /// Brings the octree up to date: built on first use, then the entries of clusters that
    /// moved since it was last used are moved.
    pub(super) fn settle_octree(&mut self) {
        if std::mem::take(&mut self.octree_rebuild) {
            self.octree = LooseOctree::from_boxes(&self.item_boxes, OCTREE_DEPTH);
            return;
        }
        let mut pending = std::mem::take(&mut self.octree_pending);
        pending.sort_unstable();
        pending.dedup();
        for &item in &pending {
            self.octree.update(item, self.item_boxes[item as usize]);
        }
        pending.clear();
        self.octree_pending = pending;
    }
}

/// Each drawn mesh's cluster cones in its own space, by meshlet slot (indexed by the
/// cluster's index in its mesh), made once from the first instance of each slot.
fn local_cones(
    scene: &Scene,
    instances: &[Instance],
    clustered: &ClusteredScene,
    meshlets: &SceneMeshlets,
) -> Vec<Vec<cone::LocalCone>> {
    let mut first = vec![u32::MAX; meshlets.slots()];
    for i in 0..instances.len() as u32 {
        let s = &mut first[meshlets.slot(i) as usize];
        if *s == u32::MAX {
            *s = i;
        }
    }
    // Over the clusters of every mesh at once: one big mesh (an OBJ city) is most of them.
    first
        .par_iter()
        .map(|&i| {
            let Some(mesh) = instances.get(i as usize).and_then(|inst| scene.mesh(inst.mesh)) else {
                return Vec::new();
            };
            // The instance's items are its mesh's clusters in order (none when not clustered).
            clustered
                .instance_items(i)
                .into_par_iter()
                .with_min_len(64)
                .map(|item| cone::LocalCone::of_cluster(mesh.positions(), mesh.indices(), clustered.triangles(item)))
                .collect()
        })
        .collect()
}

/// Item `item`'s normal cone in world space: its mesh cluster's local cone under its
/// instance's transform.
pub(super) fn world_cone(
    local_cones: &[Vec<cone::LocalCone>],
    meshlets: &SceneMeshlets,
    clustered: &ClusteredScene,
    instances: &[Instance],
    item: u32,
) -> cone::Cone {
    let it = clustered.item(item);
    let local = local_cones.get(meshlets.slot(it.instance) as usize).and_then(|v| v.get(it.cluster as usize));
    match (local, instances.get(it.instance as usize)) {
        (Some(l), Some(inst)) => l.to_world(&inst.world_from_local),
        _ => cone::Cone::NEVER,
    }
}

/// Instance index by the node that draws it (indexed by the node's slot: no hashing).
pub(super) type NodeInstance = SecondaryMap<NodeId, u32>;

/// What [`super::Culler::sync`] did to follow the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SyncOutcome {
    /// Nothing had changed.
    Unchanged,
    /// Only materials changed (shading reads them; nothing spatial moved).
    Restyled,
    /// Instances moved: their boxes and cones followed, their octree entries were queued (they
    /// move when the octree walk next runs), and the cluster BVH was refitted or rebuilt (or is being rebuilt in the background, see [`RefitOutcome`]).
    Moved {
        /// How many instances moved.
        instances: usize,
        /// What became of the cluster BVH.
        bvh: RefitOutcome,
    },
    /// What is drawn changed (instances added, removed or reordered, meshes swapped): the
    /// world side was rebuilt, keeping the clusters of meshes still drawn.
    Rebuilt,
}

impl Clusters {
    /// Follows `scene` from the revision last synced to: the change report when it covers
    /// exactly that step and only moved (or restyled) instances; a rebuild otherwise.
    pub(super) fn sync(&mut self, scene: &Scene) -> SyncOutcome {
        let outcome = match scene.delta_since(self.stamp) {
            SceneDelta::UpToDate => SyncOutcome::Unchanged,
            SceneDelta::Apply(ch) if !ch.order_changed && ch.added.is_empty() && ch.removed.is_empty() => {
                for id in &ch.restyled {
                    if let (Some(&i), Some(now)) = (self.node_instance.get(*id), scene.instance(*id)) {
                        self.instances[i as usize].material = now.material;
                    }
                }
                match self.move_nodes(scene, &ch.moved) {
                    Some(bvh) => SyncOutcome::Moved { instances: ch.moved.len(), bvh },
                    None if ch.restyled.is_empty() => SyncOutcome::Unchanged,
                    None => SyncOutcome::Restyled,
                }
            }
            _ => {
                let reuse = (std::mem::take(&mut self.clustered), std::mem::take(&mut self.meshlets));
                *self = Clusters::build(scene, Some(reuse));
                SyncOutcome::Rebuilt
            }
        };
        self.stamp = scene.stamp();
        outcome
    }
}

impl Clusters {
    /// The box projector of this state's box tests: from `camera`'s eye, with the
    /// instances' reach.
    pub(super) fn projector(&self, camera: &sightline_scene::Camera, width: u32, height: u32) -> BoxProjector {
        BoxProjector::for_camera(camera, width, height, self.reach)
    }
}

/// How far the terms of the instance's vertex transform reach, per world axis: the largest
/// `Σ_j |B_kj|·|v_j|` over its mesh's local box (`B` the linear part of `world_from_local`),
/// which bounds both how far its vertices lie from its origin and the magnitudes the
/// rasterizer's `clip_from_local` product sums (with shear too). 0 for a mesh without
/// triangles, and for a transform or mesh that is not finite (those items are never culled
/// by their boxes, and must not switch every other box's test off).
pub(super) fn instance_reach(scene: &Scene, inst: &Instance) -> f32 {
    let Some(mesh) = scene.mesh(inst.mesh) else { return 0.0 };
    let b = mesh.aabb();
    if b.is_empty() {
        return 0.0;
    }
    let v = b.min.abs().max(b.max.abs());
    // Row k's sum for every k at once, from whole columns: a move has just stored the
    // matrix, and loads of single entries across its column stores could not be forwarded
    // from them (perf put them at a tenth of an animate-and-sync loop of 10^4 movers).
    let m = &inst.world_from_local.matrix3;
    let rows = m.x_axis.abs() * v.x + m.y_axis.abs() * v.y + m.z_axis.abs() * v.z;
    if rows.is_finite() {
        rows.max_element()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};
    use sightline_scene::{shapes, NodeDesc, Scene, Transform};

    use crate::cull::{Culler, Method};

    /// The reach is the largest row sum `Σ_j |B_kj|·|v_j|` (`v` the mesh box's farthest
    /// corner), and 0 for a transform that is not finite.
    #[test]
    fn the_reach_is_the_largest_row_sum_and_zero_when_not_finite() {
        let mut scene = Scene::new();
        let slab = scene.add_mesh(
            shapes::subdivided_box("s", Vec3::new(-1.0, 0.0, -4.0), Vec3::new(3.0, 0.5, 2.0), [2, 1, 2], false)
                .unwrap(),
        );
        let t = Transform {
            translation: Vec3::new(5.0, 1.0, -2.0),
            rotation: Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.2),
            scale: Vec3::new(1.0, 2.0, 3.0),
        };
        scene.add_node(None, NodeDesc::new("s").mesh(slab).transform(t)).unwrap();
        scene.update_transforms();
        let mut inst = scene.instances()[0];
        let v = [3.0f32, 0.5, 4.0];
        let b = glam::Mat3::from(inst.world_from_local.matrix3);
        let row = |k: usize| (0..3).fold(0.0, |acc, j| acc + b.col(j)[k].abs() * v[j]);
        let expected = row(0).max(row(1)).max(row(2));
        assert_eq!(super::instance_reach(&scene, &inst), expected);
        // Independently: the row sums are reached by a corner of the box `[-v, v]`, the one
        // whose signs follow the row's, so the reach is the largest coordinate any of its
        // eight corners is carried to.
        let sign = |s: u32, bit: u32| if s & bit != 0 { -1.0 } else { 1.0 };
        let corners = (0..8u32).map(|s| Vec3::from(v) * Vec3::new(sign(s, 1), sign(s, 2), sign(s, 4)));
        let farthest = corners.map(|c| (b * c).abs().max_element()).fold(0.0f32, f32::max);
        assert!((farthest - expected).abs() <= 1e-5 * expected, "{farthest} against {expected}");
        inst.world_from_local.matrix3.y_axis.z = f32::NAN;
        assert_eq!(super::instance_reach(&scene, &inst), 0.0);
    }

    /// The octree is built when first needed (by `prepare` or the octree walk), holding every
    /// cluster at its place then, including a cluster that moved before.
    #[test]
    fn the_octree_is_built_on_first_use_with_the_clusters_where_they_are() {
        let mut scene = Scene::new();
        let cube = scene.add_mesh(shapes::cube("c").unwrap());
        let at = |i: usize| Transform::from_translation(Vec3::new(i as f32 * 3.0, 0.0, 0.0));
        let nodes: Vec<_> =
            (0..5).map(|i| scene.add_node(None, NodeDesc::new("c").mesh(cube).transform(at(i))).unwrap()).collect();
        scene.update_transforms();
        let mut culler = Culler::new(&scene);
        assert!(culler.c.octree.is_empty(), "no octree before the octree walk needs one");
        scene.set_local_transform(nodes[2], Transform::from_translation(Vec3::new(0.0, 50.0, 0.0))).unwrap();
        scene.update_transforms();
        culler.sync(&scene).unwrap();
        assert!(culler.c.octree.is_empty(), "a move does not build it either");
        culler.prepare(Method::Hzb);
        assert!(culler.c.octree.is_empty(), "nor does preparing another method");
        culler.prepare(Method::OctreeHzb);
        let octree = &culler.c.octree;
        octree.validate().unwrap();
        assert_eq!(octree.len(), culler.clustered().item_count());
        for item in 0..culler.clustered().item_count() as u32 {
            assert_eq!(octree.aabb(item), Some(culler.c.item_boxes[item as usize]), "cluster {item}");
        }
        assert!(octree.aabb(2).is_some_and(|b| b.min.y > 45.0), "the moved cube is in its new place");
    }
}

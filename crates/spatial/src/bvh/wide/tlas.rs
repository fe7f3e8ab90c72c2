//! Top level: instances (a BLAS plus the matrices that place it) and a wide BVH over their
//! world boxes.
//!
//! Rays reach a BLAS by being mapped into the instance's local space with
//! `local_from_world`; directions are not renormalized, so a ray's t means the same point in
//! every space and hits from different instances compare directly. Instances whose transform
//! is singular (or nearly so, see [`invertible`]) are meant to get a private BLAS of their
//! triangles placed in world space and an identity transform instead
//! ([`InstanceRecord::in_world`]).

use glam::{Affine3A, Vec3A};
use obvhs::aabb::Aabb as ObAabb;

use super::blas::WideBlas;
use super::{WideBuildParams, WideBvh};
use crate::bvh::background::Background;
use crate::RefitOutcome;

/// One placed BLAS.
///
/// Build it with [`InstanceRecord::placed`] or [`InstanceRecord::in_world`], which keep the
/// derived fields (`local_from_world`, `identity`, `mirror`) consistent.
#[derive(Debug, Clone)]
pub struct InstanceRecord {
    /// Index into the caller's BLAS list.
    pub blas: u32,
    /// Index into `Scene::instances()` (for IDs, mesh and material).
    pub scene_index: u32,
    /// Maps world rays into the BLAS's space.
    pub local_from_world: Affine3A,
    /// Maps BLAS points to world (identity for BLASes built in world space).
    pub world_from_blas: Affine3A,
    /// True when `local_from_world` is the identity (rays are used as they are).
    pub identity: bool,
    /// The ID of the instance's triangle 0, chosen by the caller; triangle `t` of the BLAS's
    /// mesh has ID `first_id + t`.
    pub first_id: u32,
    /// True when the transform mirrors (negative determinant): front faces flip winding.
    pub mirror: bool,
}

/// True when `m` can be inverted with a finite, well-conditioned result.
pub fn invertible(m: &Affine3A) -> bool {
    inverse(m).is_some()
}

/// `m`'s inverse when `m` is [`invertible`].
fn inverse(m: &Affine3A) -> Option<Affine3A> {
    let det = m.matrix3.determinant();
    let scale = m.matrix3.x_axis.length() * m.matrix3.y_axis.length() * m.matrix3.z_axis.length();
    if !(det.is_finite() && scale.is_finite() && det.abs() > 1e-7 * scale) {
        return None;
    }
    Some(m.inverse()).filter(|inv| inv.is_finite())
}

/// Instance records plus the wide BVH over them.
#[derive(Debug, Clone)]
pub struct WideTlas {
    /// The instances, indexed by the BVH's leaves through `bvh.order()`.
    instances: Vec<InstanceRecord>,
    /// The tree over world boxes.
    bvh: WideBvh,
    /// The tree's SAH cost right after its last build (refits are measured against it).
    build_cost: f32,
    /// Each instance's world box, as the tree was last built or refitted from, except the
    /// instances in `moved`.
    boxes: Vec<ObAabb>,
    /// Instances placed anew since the last refit (their boxes are recomputed by it).
    moved: Vec<u32>,
    /// The rebuild of `bvh` under way off the frame, if any.
    background: Background<WideBvh>,
}

impl WideTlas {
    /// Builds the BVH over the instances' world boxes (BLAS bounds mapped by
    /// `world_from_blas`). Records of empty or missing BLASes are dropped.
    pub fn build(records: Vec<InstanceRecord>, blases: &[WideBlas]) -> WideTlas {
        let instances: Vec<InstanceRecord> = records
            .into_iter()
            .filter(|rec| blases.get(rec.blas as usize).is_some_and(|b| b.triangle_count() > 0))
            .collect();
        let boxes: Vec<ObAabb> = instances.iter().map(|rec| world_box(rec, blases)).collect();
        let (bvh, build_cost) = fresh_tree(&boxes);
        WideTlas { instances, bvh, build_cost, boxes, moved: Vec::new(), background: Background::default() }
    }

    /// Places instance `i` (of [`WideTlas::instances`], made by [`InstanceRecord::placed`])
    /// by a new `world_from_local`; the tree follows at the next [`WideTlas::refit`]. Returns
    /// false, changing nothing, for a transform that cannot be inverted: the caller must
    /// rebuild then (with a private world-space BLAS for it). An instance made by
    /// [`InstanceRecord::in_world`] must not be moved this way: its BLAS holds world positions.
    pub fn set_transform(&mut self, i: usize, world_from_local: Affine3A) -> bool {
        let Some(rec) = self.instances.get_mut(i) else { return false };
        let Some(local_from_world) = inverse(&world_from_local) else { return false };
        *rec =
            InstanceRecord::with_inverse(rec.blas, rec.scene_index, rec.first_id, world_from_local, local_from_world);
        self.moved.push(i as u32);
        true
    }

    /// Refits the tree to the instances' current transforms. When refitting has let its SAH
    /// cost grow past [`REBUILD_RATIO`](crate::REBUILD_RATIO) times that of the last build,
    /// a new tree is built off the frame and put in place
    /// [`rebuild_lag`](crate::rebuild_lag) refits later, as the
    /// [`ClusteredScene`](crate::ClusteredScene)'s is. The boxes of the instances placed
    /// since the last refit are recomputed; the others are kept (`blases` must be the list
    /// the tree was built with).
    pub fn refit(&mut self, blases: &[WideBlas]) -> RefitOutcome {
        for &i in &self.moved {
            self.boxes[i as usize] = world_box(&self.instances[i as usize], blases);
        }
        self.moved.clear();
        let boxes = &self.boxes;
        self.background.update(
            (&mut self.bvh, &mut self.build_cost),
            boxes,
            WideBvh::refit_cost,
            |bvh| bvh.refit_cost(boxes),
            fresh_tree,
        )
    }

    /// The instances kept (in the order given to [`WideTlas::build`]); the BVH's primitive
    /// `i` is `instances()[i]`.
    #[inline]
    pub fn instances(&self) -> &[InstanceRecord] {
        &self.instances
    }

    /// The tree over the instances' world boxes.
    #[inline]
    pub fn bvh(&self) -> &WideBvh {
        &self.bvh
    }
}

/// The tree over instance boxes `boxes`, with its SAH cost.
fn fresh_tree(boxes: &[ObAabb]) -> (WideBvh, f32) {
    let bvh = WideBvh::build_obvhs(boxes, WideBuildParams::TLAS);
    let cost = bvh.sah_cost();
    (bvh, cost)
}

/// The world box of an instance (its BLAS bounds mapped by `world_from_blas`), padded by a
/// relative epsilon so that it contains every transformed vertex despite rounding.
fn world_box(rec: &InstanceRecord, blases: &[WideBlas]) -> ObAabb {
    let wb = blases[rec.blas as usize].bounds().transformed(&rec.world_from_blas);
    let pad = (wb.max - wb.min).max(wb.max.abs().max(wb.min.abs())) * 1e-6;
    ObAabb::new(Vec3A::from(wb.min - pad), Vec3A::from(wb.max + pad))
}

impl InstanceRecord {
    /// The record of a shared BLAS placed by an invertible `world_from_local`.
    pub fn placed(blas: u32, scene_index: u32, first_id: u32, world_from_local: Affine3A) -> Self {
        Self::with_inverse(blas, scene_index, first_id, world_from_local, world_from_local.inverse())
    }

    /// [`InstanceRecord::placed`] given the inverse of `world_from_local` already.
    fn with_inverse(
        blas: u32,
        scene_index: u32,
        first_id: u32,
        world_from_local: Affine3A,
        local_from_world: Affine3A,
    ) -> Self {
        Self {
            blas,
            scene_index,
            first_id,
            local_from_world,
            world_from_blas: world_from_local,
            identity: world_from_local == Affine3A::IDENTITY,
            mirror: world_from_local.matrix3.determinant() < 0.0,
        }
    }

    /// The record of a BLAS built directly in world space.
    pub fn in_world(blas: u32, scene_index: u32, first_id: u32) -> Self {
        Self {
            blas,
            scene_index,
            first_id,
            local_from_world: Affine3A::IDENTITY,
            world_from_blas: Affine3A::IDENTITY,
            identity: true,
            mirror: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn empty_blases_are_dropped_and_boxes_cover_placed_instances() {
        let tri = |_| [Vec3::ZERO, Vec3::X, Vec3::Y];
        let blases = vec![WideBlas::build(1, tri), WideBlas::empty()];
        let shift = Affine3A::from_translation(Vec3::new(10.0, 0.0, 0.0));
        let records = vec![
            InstanceRecord::placed(0, 0, 1, Affine3A::IDENTITY),
            InstanceRecord::placed(1, 1, 2, Affine3A::IDENTITY),
            InstanceRecord::placed(0, 2, 3, shift),
            InstanceRecord::in_world(7, 3, 4),
        ];
        let tlas = WideTlas::build(records, &blases);
        let kept: Vec<u32> = tlas.instances().iter().map(|r| r.scene_index).collect();
        assert_eq!(kept, [0, 2]);
        tlas.bvh().validate(2).unwrap();
        let root = tlas.bvh().root();
        assert!(root.lo[0] <= 0.0 && root.hi[0] >= 11.0);
        assert!(tlas.instances()[0].identity && !tlas.instances()[1].identity);
        assert!(!invertible(&Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))));
        assert!(invertible(&shift));
    }

    /// Shuffling the instances degrades the tree: it is rebuilt in the background from the
    /// boxes of that refit, and put in place, refitted, `rebuild_lag` refits later.
    #[test]
    fn a_degraded_tree_is_rebuilt_in_the_background() {
        let blases = vec![WideBlas::build(1, |_| [Vec3::ZERO, Vec3::X, Vec3::Y])];
        let at = |s: usize| Affine3A::from_translation(Vec3::new((s % 20) as f32 * 3.0, 0.0, (s / 20) as f32 * 3.0));
        let records = (0..200).map(|i| InstanceRecord::placed(0, i, 1 + i, at(i as usize))).collect();
        let mut tlas = WideTlas::build(records, &blases);
        let place = |tlas: &mut WideTlas, round: usize| {
            for i in 0..200 {
                assert!(tlas.set_transform(i, at((i * 71 + round * 3) % 200)));
            }
            tlas.refit(&blases)
        };
        let trigger = match place(&mut tlas, 1) {
            RefitOutcome::Rebuilding { cost_ratio } => cost_ratio,
            o => panic!("expected a background rebuild, got {o:?}"),
        };
        let started_from = tlas.boxes.clone();
        for round in 2..=crate::rebuild_lag(200) as usize {
            assert!(matches!(place(&mut tlas, round), RefitOutcome::Rebuilding { .. }));
        }
        assert_eq!(place(&mut tlas, 0), RefitOutcome::Rebuilt { cost_ratio: trigger });
        let (mut expected, _) = fresh_tree(&started_from);
        assert!(expected.refit(&tlas.boxes));
        assert_eq!(tlas.bvh().order(), expected.order());
        assert_eq!(tlas.bvh().nodes(), expected.nodes());
        tlas.bvh().validate(200).unwrap();
    }
}

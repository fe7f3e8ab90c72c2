//! The top-level acceleration structure: instances (a BLAS plus the matrices that place it)
//! and a BVH over their world boxes.
//!
//! Rays reach a BLAS by being mapped into the instance's local space with
//! `local_from_world`; directions are not renormalized, so a ray's t means the same point in
//! every space and hits from different instances compare directly. Instances whose transform
//! is singular (or nearly so) get a private BLAS of their triangles placed in world space and
//! an identity transform instead.

use glam::{Affine3A, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use sightline_scene::Aabb;

use super::blas::Blas;
use super::bvh::{BuildParams, Bvh};

/// One placed BLAS.
#[derive(Debug, Clone)]
pub(crate) struct InstanceRec {
    /// Index into the caster's BLAS list.
    pub blas: u32,
    /// Index into `Scene::instances()` (for IDs, mesh and material).
    pub scene_index: u32,
    /// Maps world rays into the BLAS's space.
    pub local_from_world: Affine3A,
    /// Maps BLAS points to world (identity for placed BLASes).
    pub world_from_blas: Affine3A,
    /// True when `local_from_world` is the identity (rays are used as they are).
    pub identity: bool,
    /// ID of the instance's triangle 0 (`1 + first_triangle`).
    pub first_id: u32,
    /// True when the transform mirrors (negative determinant): front faces flip winding.
    pub mirror: bool,
}

/// True when `m` can be inverted with a finite, well-conditioned result.
pub(crate) fn invertible(m: &Affine3A) -> bool {
    let det = m.matrix3.determinant();
    let scale = m.matrix3.x_axis.length() * m.matrix3.y_axis.length() * m.matrix3.z_axis.length();
    det.is_finite() && scale.is_finite() && det.abs() > 1e-7 * scale && m.inverse().is_finite()
}

/// Instance records plus the BVH over them.
#[derive(Debug, Clone)]
pub(crate) struct Tlas {
    /// The instances, indexed by the BVH's leaves through `bvh.order`.
    pub instances: Vec<InstanceRec>,
    /// The tree over world boxes.
    pub bvh: Bvh,
}

impl Tlas {
    /// Builds the BVH over the instances' world boxes (BLAS bounds mapped by
    /// `world_from_blas`). Instances of empty BLASes are dropped.
    pub fn build(records: Vec<InstanceRec>, blases: &[Blas]) -> Tlas {
        let mut instances = Vec::with_capacity(records.len());
        let mut boxes = Vec::with_capacity(records.len());
        for rec in records {
            let Some(blas) = blases.get(rec.blas as usize) else {
                continue;
            };
            if blas.tris.is_empty() {
                continue;
            }
            let (lo, hi) = blas.bounds();
            let wb = Aabb::new(lo, hi).transformed(&rec.world_from_blas);
            // Pad by a relative epsilon: the box must contain every transformed vertex
            // despite rounding.
            let pad = (wb.max - wb.min).max(wb.max.abs().max(wb.min.abs())) * 1e-6;
            boxes.push(ObAabb::new(Vec3A::from(wb.min - pad), Vec3A::from(wb.max + pad)));
            instances.push(rec);
        }
        let bvh = Bvh::build(&boxes, BuildParams::TLAS);
        Tlas { instances, bvh }
    }
}

impl InstanceRec {
    /// The record of a shared BLAS placed by an invertible `world_from_local`.
    pub fn placed(blas: u32, scene_index: u32, first_id: u32, world_from_local: Affine3A) -> Self {
        Self {
            blas,
            scene_index,
            first_id,
            local_from_world: world_from_local.inverse(),
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

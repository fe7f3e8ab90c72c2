//! # sightline-spatial
//!
//! The spatial side of sightline: bounding volumes, frustum planes and the structures that
//! make large scenes cheap to cull and to order.
//!
//! * Primitives: [`Aabb`] (re-exported from the scene crate, with [`AabbExt`]), [`Sphere`],
//!   [`Plane`], [`Ray`], [`Frustum`] (six planes from any `clip_from_world`), and
//!   [`project_box`] (screen rectangle + nearest window depth, for HZB tests).
//! * [`Bvh`]: a flat binary BVH built by our PLOC and refined with `obvhs`'s reinsertion and
//!   leaf collapsing, with frustum culling (plane masking,
//!   plane coherency), front-to-back traversal with a per-node visibility callback, a
//!   resumable [`FrontToBackCursor`] for batched occlusion culling, and refit.
//! * [`InstanceBvh`] (BVH over instances, refit + rebuild policy), [`TriangleBvh`] (BVH over
//!   one mesh's triangles, single-ray casting), [`MeshClusters`] (clusters of at most 128 triangles
//!   with a triangle permutation) and [`ClusteredScene`] (one BVH over every (instance,
//!   cluster) world box).
//! * [`bvh::wide`]: the ray caster's two-level structure of 4-wide BVHs
//!   ([`bvh::wide::WideBlas`] per mesh, built by binned SAH; [`bvh::wide::WideTlas`] over
//!   placed instances, collapsed from a binary PLOC tree), laid out for SIMD packet traversal.
//! * [`LooseOctree`] over instances (Ulrich 2000) and the occupancy octree string
//!   ([`occupancy_string`]).
//! * [`BspTree`] (autopartition, Fuchs, Kedem & Naylor 1980) with painter's order.
//!
//! ## One way to ask
//!
//! Structures that cull implement [`FrustumCull`] (a frustum in, [`Visible`] items out) and
//! [`FrontToBack`] (an eye in, an order out).
//!
//! ## Bad input: the rule for boxes
//!
//! Every structure classifies an item's box with [`AabbExt::kind`]:
//! * [`BoxKind::Empty`] (`min > max` on some axis, no NaN — e.g. a mesh with no triangles):
//!   holds nothing, so it is never visible and never returned by a query;
//! * [`BoxKind::Unbounded`] (any NaN or infinite coordinate): treated as "could be anywhere":
//!   kept out of the trees, always reported visible (never `inside`), and placed first in
//!   front-to-back orders;
//! * [`BoxKind::Finite`]: the normal case.
//!
//! Nothing panics on such input, on empty scenes or on zero-area triangles.

#![warn(missing_docs)]
// `!(x > 0.0)` is how this code says "not positive, or NaN": the negated comparison is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod aabb;
mod bsp;
pub mod bvh;
mod frustum;
mod hint;
mod octree;
mod plane;
mod project;
mod ray;
pub mod simd;
mod sphere;

pub use aabb::{AabbExt, BoxKind};
pub use bsp::split::{classify_triangle, split_triangle, Pieces, Side};
pub use bsp::{BspOrder, BspParams, BspStats, BspTree, BspTriangle};
pub use bvh::background::{rebuild_lag, LAG_ITEMS, REBUILD_LAG};
pub use bvh::cluster::{Cluster, MeshClusters, CLUSTER_MAX, CLUSTER_MIN};
pub use bvh::front_to_back::FrontToBackCursor;
pub use bvh::instances::InstanceBvh;
pub use bvh::node_set::NodeSet;
pub use bvh::policy::{RefitOutcome, REBUILD_RATIO};
pub use bvh::scene::{ClusterItem, ClusteredScene};
pub use bvh::traverse::{CoherencyCache, FrustumCount};
pub use bvh::triangles::{TriangleBvh, TriangleHit};
pub use bvh::{Bvh, BvhNode, BvhPreset};
pub use frustum::{Containment, Frustum, PlaneMask, ALL_PLANES};
pub use hint::{prefetch, prefetch_all};
pub use octree::occupancy::{occupancy_string, occupancy_voxels, Occupancy};
pub use octree::{octant_order, LooseOctree, OctreeCursor};
pub use plane::Plane;
pub use project::{project_box, BoxImage, BoxProjector, ScreenRect};
pub use ray::Ray;
pub use sightline_scene::Aabb;
pub use simd::SimdLevel;
pub use sphere::Sphere;

use glam::Vec3;

/// One item that survived frustum culling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Visible {
    /// The item's index (an instance index for instance structures, an item index otherwise).
    pub index: u32,
    /// True when the item's box lies entirely inside the frustum, so drawing it needs no
    /// clipping.
    pub inside: bool,
}

/// An item callback for the front-to-back traversals that appends each item's index to
/// `out` and goes on (the [`FrontToBack::order`] of the structures that have them).
pub(crate) fn push_index(out: &mut Vec<u32>) -> impl FnMut(Visible) -> Visit + '_ {
    |v| {
        out.push(v.index);
        Visit::Continue
    }
}

/// What a traversal callback wants next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Visit {
    /// Go on: descend into the node / accept the item.
    Continue,
    /// Skip this node's subtree (or this item): e.g. it is occluded.
    Skip,
    /// End the whole traversal now.
    Stop,
}

/// Options for frustum culling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CullOptions {
    /// Plane masking (Assarsson & Möller 2000): a node fully inside a plane does not test that
    /// plane again for its children. Off: every node tests all six planes.
    pub plane_masking: bool,
}

impl Default for CullOptions {
    fn default() -> Self {
        Self { plane_masking: true }
    }
}

/// Work counters of one culling query.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CullCounters {
    /// Nodes (and items) whose box was classified against the frustum.
    pub boxes_tested: u64,
    /// Single box–plane tests performed.
    pub plane_tests: u64,
    /// Items reported visible.
    pub visible: u64,
}

/// Frustum culling: a frustum in, the visible items out (appended to `out`).
pub trait FrustumCull {
    /// Appends every item whose box may intersect `frustum` (conservative: an item that
    /// touches the frustum is reported). Uses plane masking.
    fn cull(&self, frustum: &Frustum, out: &mut Vec<Visible>);
}

/// Front-to-back order: an eye in, every item's index out, nearest first (appended to `out`).
pub trait FrontToBack {
    /// Appends every item in an approximate front-to-back order for `eye`.
    fn order(&self, eye: Vec3, out: &mut Vec<u32>);
}

//! The ray caster: image-order visibility through a two-level BVH, drawing the same
//! framebuffer as the rasterizer (IDs, window depth, shading), plus CSG solids.
//!
//! * [`RayCaster::build`] makes one BLAS per mesh (a 4-wide BVH,
//!   [`sightline_spatial::bvh::wide::WideBlas`], built in parallel over meshes with rayon,
//!   shared by every instance of the mesh) and a TLAS over the instances
//!   ([`sightline_spatial::bvh::wide::WideTlas`]); rays reach a BLAS through the instance's
//!   `local_from_world`. The structures come from `sightline-spatial`; this module casts rays
//!   through them.
//! * [`RayCaster::render`] casts one ray per pixel center from the camera
//!   ([`sightline_scene::Camera::ray_through_ndc`]'s rays) in 8 × 8 packets traced together
//!   (Wald et al. 2001) with frustum culling (Reshetov et al. 2005), over bands of rows in
//!   parallel; the image is bit-identical for any thread count and SIMD level. A hit writes
//!   the rasterizer's triangle ID (`1 + first_triangle + triangle`) and the window depth of the
//!   hit point. Colors come from the rasterizer's deferred pass over the ID buffer
//!   ([`crate::shade_pass`]), or, with shadows or CSG solids, from the shared
//!   [`crate::shading`] at each hit's exact barycentrics. Hard shadows from the directional
//!   light come from any-hit shadow packets.
//! * [`RayCaster::intersect`] and [`RayCaster::occluded`] answer single-ray queries.
//!
//! What is visible matches the rasterizer: only the part of each ray between the near and
//! far planes counts (by view depth), back faces are dropped when the rasterizer drops them,
//! triangles are tested watertight (Woop, Benthin & Wald 2013: a ray through a shared edge
//! or vertex of a mesh hits one of its triangles, never none), and
//! of two surfaces at the same depth the one with the smaller ID wins, as under a LESS depth
//! test with triangles drawn in ID order.
//!
//! CSG solids ([`crate::csg::CsgObject`], added with [`RayCaster::with_csg`]) are drawn in
//! the same image; CSG object `k` writes ID `triangle_count + 1 + k`.
//!
//! ```
//! use glam::Vec3;
//! use sightline_render::{Framebuffer, RayCaster, RaycastOptions};
//! use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene};
//!
//! let mut scene = Scene::new();
//! let cube = scene.add_mesh(shapes::cube("cube")?);
//! scene.add_node(None, NodeDesc::new("cube").mesh(cube))?;
//! scene.update_transforms();
//! let caster = RayCaster::build(&scene)?;
//! let look = LookAt { eye: Vec3::new(2.0, 1.5, 3.0), fovy: Angle::degrees(50.0), far: 100.0, ..LookAt::default() };
//! let camera = Camera::perspective(&look, 1.0)?;
//! let mut fb = Framebuffer::new(64, 64)?;
//! let stats = caster.render(&scene, &camera, &mut fb, &RaycastOptions::default())?;
//! assert!(stats.hits > 0 && fb.ids.iter().all(|&id| id <= 12));
//! let hit = caster.intersect(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY).unwrap();
//! assert_eq!(hit.t, 4.5);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod camera;
mod isa;
mod packet;
mod render;
mod shear;
mod trace;
mod traverse;
mod triangle;

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use sightline_scene::{Camera, Instance, MeshId, NodeId, Scene, SceneDelta, SceneStamp};
use slotmap::SecondaryMap;

use crate::csg::CsgObject;
use crate::shading::ShadeOptions;
use crate::{Framebuffer, RenderOptions, Result};

use packet::{Hits, Rays, NO_HIT};
use sightline_spatial::bvh::wide::{invertible, InstanceRecord, WideBlas, WideTlas};
use trace::{trace, Scratch};

pub use sightline_spatial::simd::SimdLevel;

/// How a frame is ray cast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RaycastOptions {
    /// Shading, shared with the rasterizer (mode `None`: depth and IDs only).
    pub shading: ShadeOptions,
    /// Drop triangles seen from behind, as the rasterizer's back-face culling does.
    pub backface_culling: bool,
    /// Hard shadows from `shading.light_dir` (any-hit shadow rays).
    pub shadows: bool,
    /// Clear color.
    pub background: [u8; 4],
    /// Instruction set of the packet kernels.
    pub simd: SimdLevel,
}

impl Default for RaycastOptions {
    /// The rasterizer's defaults ([`RenderOptions::default`]), shadows off.
    fn default() -> Self {
        Self::from_render(&RenderOptions::default())
    }
}

impl RaycastOptions {
    /// The options that make the ray caster draw what the rasterizer draws with `opts`
    /// (shading, back-face culling, background).
    pub fn from_render(opts: &RenderOptions) -> Self {
        Self {
            shading: opts.shading,
            backface_culling: opts.backface_culling,
            shadows: false,
            background: opts.background,
            simd: SimdLevel::Auto,
        }
    }

    /// Depth and IDs only, no shading (what visibility needs; the fastest path).
    pub fn ids_only() -> Self {
        Self::from_render(&RenderOptions::ids_only())
    }
}

/// What a ray cast frame cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct RaycastStats {
    /// Primary rays cast (one per pixel).
    pub primary_rays: u64,
    /// Shadow rays cast.
    pub shadow_rays: u64,
    /// Pixels whose ray hit something.
    pub hits: u64,
    /// Wall time of the frame in milliseconds.
    pub ms_total: f64,
}

/// The nearest surface on a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit (`origin + t·dir`).
    pub t: f32,
    /// The ID a framebuffer stores for this surface.
    pub id: u32,
    /// What was hit.
    pub target: HitTarget,
}

/// The kind of surface a [`RayHit`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HitTarget {
    /// A mesh triangle.
    Triangle {
        /// Index into `Scene::instances()`.
        instance: usize,
        /// Triangle index within the instance's mesh.
        triangle: u32,
        /// Barycentric weights of the triangle's second and third vertices.
        barycentric: Vec2,
    },
    /// A CSG solid.
    Csg {
        /// Index into the caster's CSG objects.
        object: usize,
        /// Outward unit normal (world space).
        normal: Vec3,
    },
}

/// A scene prepared for ray casting: BLASes, instances and the TLAS, plus CSG solids.
///
/// Built for one scene; the scene is handed to every frame (meshes and materials are read at
/// shading time). After edits, [`RayCaster::sync`] follows them: when instances only moved
/// (or changed material), their records take the new transforms and the TLAS is refitted,
/// or rebuilt once refitting has let its SAH cost grow past
/// [`REBUILD_RATIO`](sightline_spatial::REBUILD_RATIO) times a fresh build's (off the
/// frame, on a background thread: the new tree is put in place
/// [`rebuild_lag`](sightline_spatial::rebuild_lag) syncs later); when what is
/// drawn changed, the instances and the TLAS are made anew, keeping the BLAS of every mesh
/// still drawn. Either way a BLAS is built once per mesh. A frame of a scene the caster is
/// not synced to is refused, never drawn stale.
#[derive(Debug, Clone)]
pub struct RayCaster {
    stamp: SceneStamp,
    instances: Vec<Instance>,
    blases: Vec<WideBlas>,
    /// The mesh of each shared BLAS (the first `blas_meshes.len()` BLASes); the rest are
    /// private BLASes of instances with singular transforms.
    blas_meshes: Vec<MeshId>,
    tlas: WideTlas,
    /// Scene instance index → its position in `tlas.instances()` (`u32::MAX`: none).
    record_of: Vec<u32>,
    /// Instance index by the node that draws it.
    node_instance: SecondaryMap<NodeId, u32>,
    csg: Vec<CsgObject>,
    triangle_count: u32,
    build_ms: f64,
}

impl RayCaster {
    /// Builds the acceleration structures for `scene` (world transforms must be up to
    /// date). BLASes are built in parallel over meshes.
    pub fn build(scene: &Scene) -> Result<Self> {
        if scene.needs_update() {
            return Err(crate::Error::NotPropagated);
        }
        crate::error::check_drawable(scene)?;
        Ok(Self::build_reusing(scene, std::collections::HashMap::new()))
    }

    /// The identity of the scene this caster was built for.
    pub(crate) fn scene_id(&self) -> sightline_scene::SceneId {
        self.stamp.scene
    }

    /// Follows `scene` after edits (see the type's docs); `Ok(false)` when it was up to date.
    pub fn sync(&mut self, scene: &Scene) -> Result<bool> {
        crate::error::check_followable(scene, self.stamp.scene, "ray caster")?;
        match scene.delta_since(self.stamp) {
            SceneDelta::UpToDate => return Ok(false),
            // Only moves and material changes: follow them in place unless a move needs a
            // rebuild.
            SceneDelta::Apply(ch)
                if !ch.order_changed
                    && ch.added.is_empty()
                    && ch.removed.is_empty()
                    && self.follow_moves(scene, &ch.moved, &ch.restyled) =>
            {
                self.stamp = scene.stamp();
                return Ok(true);
            }
            _ => {}
        }
        let n = self.blas_meshes.len();
        let known =
            std::mem::take(&mut self.blas_meshes).into_iter().zip(std::mem::take(&mut self.blases).into_iter().take(n));
        let csg = std::mem::take(&mut self.csg);
        *self = Self::build_reusing(scene, known.collect());
        self.csg = csg;
        Ok(true)
    }

    /// Moves the instances of `moved` to their nodes' world transforms and refits the TLAS;
    /// takes the new materials of `restyled`. False when a move cannot be followed this way
    /// (a transform became singular, or a private world-space BLAS moved): rebuild then.
    fn follow_moves(&mut self, scene: &Scene, moved: &[NodeId], restyled: &[NodeId]) -> bool {
        for id in restyled {
            if let (Some(&i), Some(now)) = (self.node_instance.get(*id), scene.instance(*id)) {
                self.instances[i as usize].material = now.material;
            }
        }
        let shared = self.blas_meshes.len() as u32;
        let mut any = false;
        for id in moved {
            let (Some(&i), Some(node)) = (self.node_instance.get(*id), scene.node(*id)) else { continue };
            let inst = &mut self.instances[i as usize];
            inst.world_from_local = node.world_matrix();
            inst.world_aabb = node.world_aabb();
            let r = self.record_of[i as usize];
            if r == u32::MAX {
                if inst.triangle_count > 0 {
                    return false; // no record: it had a singular transform and a private BLAS
                }
                continue; // draws nothing
            }
            if self.tlas.instances()[r as usize].blas >= shared
                || !self.tlas.set_transform(r as usize, inst.world_from_local)
            {
                return false;
            }
            any = true;
        }
        if any {
            self.tlas.refit(&self.blases);
        }
        true
    }

    fn build_reusing(scene: &Scene, mut known: std::collections::HashMap<MeshId, WideBlas>) -> Self {
        let t0 = Instant::now();
        let instances = scene.instances();
        let triangle_count =
            instances.iter().map(|i| i.first_triangle.saturating_add(i.triangle_count)).max().unwrap_or(0);
        // Shared BLASes for meshes drawn by at least one instance, in first-use order.
        let mut mesh_ids: Vec<MeshId> = Vec::new();
        let mut blas_of_instance: Vec<Option<u32>> = Vec::with_capacity(instances.len());
        let mut seen = std::collections::HashMap::new();
        let mut placed_jobs = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            if inst.triangle_count == 0 || scene.mesh(inst.mesh).is_none() {
                blas_of_instance.push(None);
                continue;
            }
            if !invertible(&inst.world_from_local) {
                placed_jobs.push(i);
                blas_of_instance.push(None);
                continue;
            }
            let next = mesh_ids.len() as u32;
            let b = *seen.entry(inst.mesh).or_insert_with(|| {
                mesh_ids.push(inst.mesh);
                next
            });
            blas_of_instance.push(Some(b));
        }
        let reused: Vec<Option<WideBlas>> = mesh_ids.iter().map(|m| known.remove(m)).collect();
        let mut blases: Vec<WideBlas> = mesh_ids
            .par_iter()
            .zip(reused)
            .map(|(&m, done)| done.unwrap_or_else(|| scene.mesh(m).map_or_else(WideBlas::empty, WideBlas::from_mesh)))
            .collect();
        let placed: Vec<WideBlas> = placed_jobs
            .par_iter()
            .map(|&i| {
                let inst = &instances[i];
                scene
                    .mesh(inst.mesh)
                    .map_or_else(WideBlas::empty, |m| WideBlas::from_mesh_placed(m, &inst.world_from_local))
            })
            .collect();
        let mut records = Vec::with_capacity(instances.len());
        for (i, b) in blas_of_instance.iter().enumerate() {
            if let Some(b) = b {
                let inst = &instances[i];
                let first_id = crate::triangle_id(inst.first_triangle, 0);
                records.push(InstanceRecord::placed(*b, i as u32, first_id, inst.world_from_local));
            }
        }
        for (k, &i) in placed_jobs.iter().enumerate() {
            let first_id = crate::triangle_id(instances[i].first_triangle, 0);
            records.push(InstanceRecord::in_world((blases.len() + k) as u32, i as u32, first_id));
        }
        blases.extend(placed);
        let tlas = WideTlas::build(records, &blases);
        let mut record_of = vec![u32::MAX; instances.len()];
        for (r, rec) in tlas.instances().iter().enumerate() {
            record_of[rec.scene_index as usize] = r as u32;
        }
        let node_instance = instances.iter().enumerate().map(|(i, inst)| (inst.node, i as u32)).collect();
        Self {
            stamp: scene.stamp(),
            instances,
            blases,
            blas_meshes: mesh_ids,
            tlas,
            record_of,
            node_instance,
            csg: Vec::new(),
            triangle_count,
            build_ms: t0.elapsed().as_secs_f64() * 1e3,
        }
    }

    /// Adds CSG solids drawn with the meshes; object `k` gets ID `triangle_count() + 1 + k`.
    pub fn with_csg(mut self, objects: Vec<CsgObject>) -> Self {
        self.csg = objects;
        self
    }

    /// The CSG solids.
    pub fn csg_objects(&self) -> &[CsgObject] {
        &self.csg
    }

    /// The ID written for CSG object `k`.
    pub fn csg_id(&self, k: usize) -> u32 {
        self.triangle_count.saturating_add(1).saturating_add(k as u32)
    }

    /// Number of triangles in the flattened scene (IDs of triangles are 1..=this).
    pub fn triangle_count(&self) -> u32 {
        self.triangle_count
    }

    /// Number of BLASes (meshes in use, plus private ones for singular instances).
    pub fn blas_count(&self) -> usize {
        self.blases.len()
    }

    /// Number of instances in the TLAS.
    pub fn instance_count(&self) -> usize {
        self.tlas.instances().len()
    }

    /// Triangles stored in all BLASes (unique geometry).
    pub fn stored_triangles(&self) -> usize {
        self.blases.iter().map(|b| b.triangle_count()).sum()
    }

    /// Stored triangles paired into quads with a partner (see
    /// [`WideBlas::paired_triangles`]): a mesh whose triangles do not pair is cast as lone
    /// triangles, more slowly.
    pub fn paired_triangles(&self) -> usize {
        self.blases.iter().map(|b| b.paired_triangles()).sum()
    }

    /// How long [`RayCaster::build`] took, in milliseconds.
    pub fn build_ms(&self) -> f64 {
        self.build_ms
    }

    /// Clears `fb` and ray casts the frame of `scene` seen by `camera` into it. `scene`
    /// must be the one the caster was built for, as of its last [`RayCaster::sync`].
    ///
    /// # Panics
    /// If one of `fb`'s planes (public fields) was replaced by one that does not hold
    /// width × height values.
    pub fn render(
        &self,
        scene: &Scene,
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RaycastOptions,
    ) -> Result<RaycastStats> {
        if scene.id() != self.stamp.scene {
            return Err(crate::Error::WrongScene { structure: "ray caster" });
        }
        if scene.needs_update() {
            return Err(crate::Error::NotPropagated);
        }
        if scene.stamp() != self.stamp {
            return Err(crate::Error::NotSynced);
        }
        render::render(self, scene, camera, opts, fb)
    }

    /// The nearest surface (triangle of either facing, or CSG solid) on `origin + t·dir`
    /// with `t` in `[t_min, t_max)`. Degenerate rays (zero, NaN or infinite) miss.
    pub fn intersect(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        self.query::<false>(origin, dir, t_min, t_max)
    }

    /// True when anything lies on `origin + t·dir` with `t` in `[t_min, t_max)`.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
        self.query::<true>(origin, dir, t_min, t_max).is_some()
    }

    fn query<const ANY: bool>(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        if !origin.is_finite()
            || !dir.is_finite()
            || dir == Vec3::ZERO
            || t_min.is_nan()
            || t_max.is_nan()
            || t_min > t_max
        {
            return None;
        }
        let mut rays = Rays::new();
        let mut hits = Hits::new();
        rays.set(0, origin.into(), dir.into());
        hits.open(0, t_min, t_max);
        let mut s = Scratch::new(self.tlas.bvh().depth(), 64);
        let off = packet::BeamPlanes::OFF;
        trace::<isa::Portable, ANY>(&self.blases, &self.tlas, &rays, &off, false, &mut hits, 1, &mut s);
        let mut best = None;
        let hit = (hits.inst[0][0] != NO_HIT).then(|| {
            let rec = &self.tlas.instances()[hits.inst[0][0] as usize];
            let blas = &self.blases[rec.blas as usize];
            (rec, blas, blas.triangle(hits.prim[0][0]))
        });
        // A hit record always names a stored triangle.
        if let Some((rec, blas, Some((_, triangle)))) = hit {
            let inst = &self.instances[rec.scene_index as usize];
            let det = hits.det[0][0];
            let (b1, b2) = (hits.e1[0][0] / det, hits.e2[0][0] / det);
            let w = blas.mesh_weights(hits.prim[0][0], Vec3::new(1.0 - b1 - b2, b1, b2));
            best = Some(RayHit {
                t: if ANY { t_min } else { hits.t[0][0] },
                id: crate::triangle_id(inst.first_triangle, triangle),
                target: HitTarget::Triangle {
                    instance: rec.scene_index as usize,
                    triangle,
                    barycentric: Vec2::new(w.y, w.z),
                },
            });
            if ANY {
                return best;
            }
        }
        let mut scratch = crate::csg::CsgScratch::default();
        let mut t_best = best.map_or(t_max, |b| b.t);
        for (k, obj) in self.csg.iter().enumerate() {
            if let Some(h) = obj.intersect_with(origin, dir, t_min, t_best, &mut scratch) {
                t_best = h.t;
                best =
                    Some(RayHit { t: h.t, id: self.csg_id(k), target: HitTarget::Csg { object: k, normal: h.normal } });
                if ANY {
                    return best;
                }
            }
        }
        best
    }
}

/// `min` as one compare-and-select (`minss` order: `b` when the compare fails, NaN included),
/// shared by the scalar slab and triangle tests so they round and order like the SIMD ones.
#[inline(always)]
fn mn(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `max` as one compare-and-select (see [`mn`]).
#[inline(always)]
fn mx(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

//! The culling frame loop: draw only what can be seen, and prove nothing visible was lost.
//!
//! One [`Culler`] per scene, one call per frame, the method chosen per call:
//!
//! * [`Method::Brute`]: every triangle through the pipeline (the reference).
//! * [`Method::Frustum`]: the (instance, cluster) BVH of `sightline_spatial::ClusteredScene`
//!   culled against the view frustum; the surviving clusters are drawn.
//! * [`Method::HzbOnePass`]: frustum culling plus occlusion culling with Greene's z-pyramid
//!   ([`pyramid`]): the BVH is walked front to back in batches; before anything (node or
//!   cluster) is drawn, its box is projected to a screen rectangle and nearest depth and tested
//!   against the pyramid of what is already drawn; a batch is drawn, the pyramid refreshed over
//!   the drawn rectangles, and the walk resumes. Batches start small (the nearest occluders go
//!   in first) and double.
//! * [`Method::Hzb`]: the same walk in the two-pass form GPU engines use to exploit
//!   temporal coherence: last frame's visible clusters (still in the frustum) are drawn
//!   first, in one batch, as occluders; the walk then tests everything else against that
//!   pyramid, in big batches; at the end last frame's clusters are tested again, and those
//!   still visible join this frame's newly drawn ones as the next frame's set. Without a
//!   last frame (or after a cut) it is the one-pass walk. On the street path it needs two
//!   draw batches instead of six, and the two forms take about the same time; from above,
//!   where little is hidden, it was faster (19.8 against 22.3 ms per aerial frame in one
//!   verified walk), so it is `hzb`.
//! * [`Method::OctreeHzb`]: Greene's original: a loose octree over the same clusters, walked
//!   front to back, skipping a whole octant when its loose cube is occluded.
//!
//! Exactness. A box is skipped only when its nearest possible window depth is farther than
//! the farthest depth stored over every pixel it can touch, so none of its fragments could
//! pass the depth test; boxes crossing the near plane are always drawn. Draw order does not
//! change the image either: the depth test breaks exact-depth ties by the smaller triangle
//! ID, which is what in-order drawing with a LESS test gives. So every method's ID buffer
//! equals the brute-force one; [`compare_ids`] checks it, and the tests run it on many
//! cameras.

pub mod cone;
pub mod meshlets;
pub mod order;
pub mod query;
mod verify;

use std::cell::RefCell;

use std::time::Instant;

use glam::Affine3A;
use serde::Serialize;
use sightline_scene::{Aabb, Camera, Instance, Scene};
use sightline_spatial::{prefetch, BoxProjector, ClusteredScene, CullOptions, Frustum, LooseOctree, Visible, Visit};

pub use crate::hzb::{DepthPyramid, Level, Rect, TilePyramid};
pub use meshlets::{Meshlets, SceneMeshlets};
pub use order::DrawOrder;
pub use query::{BoxVisibility, OcclusionQueries};
pub use verify::{compare_ids, Mismatch};

use crate::stats::ms_since;
use crate::{draw_all, DrawSource, FrameStats, Framebuffer, RenderOptions, Renderer, Result};

/// How a frame decides what to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Every triangle.
    Brute,
    /// View-frustum culling of instances and clusters.
    Frustum,
    /// Frustum culling, then occlusion culling against a z-pyramid: last frame's visible
    /// clusters first, then a front-to-back walk over the rest.
    Hzb,
    /// Greene's octree walk with z-pyramid tests on octants.
    OctreeHzb,
    /// Frustum culling, then front-to-back occlusion culling against a z-pyramid, without
    /// using the last frame.
    HzbOnePass,
}

impl Method {
    /// All methods, in the order reports list them.
    pub const ALL: [Method; 5] = [Method::Brute, Method::Frustum, Method::Hzb, Method::OctreeHzb, Method::HzbOnePass];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Brute => "brute",
            Method::Frustum => "frustum",
            Method::Hzb => "hzb",
            Method::OctreeHzb => "octree-hzb",
            Method::HzbOnePass => "hzb-one-pass",
        }
    }
}

/// What one culled frame did and cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CullStats {
    /// Clusters in the scene (the units culled).
    pub clusters: u64,
    /// Clusters whose boxes intersect the view frustum.
    pub clusters_in_frustum: u64,
    /// Clusters culled by the frustum.
    pub culled_by_frustum: u64,
    /// Clusters in the frustum whose triangles all face away from the eye (normal cones).
    pub culled_by_backface: u64,
    /// Clusters in the frustum but skipped as occluded (themselves or an ancestor node).
    pub culled_by_occlusion: u64,
    /// Boxes (BVH nodes, octants, clusters) tested against the z-pyramid.
    pub occlusion_tests: u64,
    /// Boxes found occluded.
    pub occluded_boxes: u64,
    /// Clusters drawn.
    pub clusters_drawn: u64,
    /// Triangles sent to the rasterizer.
    pub triangles_drawn: u64,
    /// Draw batches.
    pub batches: u64,
    /// Milliseconds in traversal and occlusion tests.
    pub ms_cull: f64,
    /// Milliseconds drawing.
    pub ms_draw: f64,
    /// Milliseconds shading.
    pub ms_shading: f64,
    /// Milliseconds for the whole frame.
    pub ms_total: f64,
}

/// Per-scene culling state: clusters, their BVH and octree, meshlets, the z-pyramid and a
/// renderer, all reused frame after frame.
#[derive(Debug)]
pub struct Culler {
    instances: Vec<Instance>,
    clustered: ClusteredScene,
    meshlets: SceneMeshlets,
    /// Per cluster, what drawing it takes.
    draws: Vec<ClusterDraw>,
    item_boxes: Vec<Aabb>,
    cones: Vec<cone::Cone>,
    /// Per cluster, one bit: its cone [can cull](cone::Cone::can_cull) at all. A small
    /// array that stays in cache, so that clusters whose cone never culls (closed meshes
    /// such as boxes) cost no load of their cone.
    cone_can_cull: Vec<u64>,
    /// `None` only while a walk borrows it.
    octree: Option<LooseOctree>,
    renderer: Renderer,
    visible: Vec<Visible>,
    /// Two-pass state: the clusters found visible in the last frame drawn with it.
    last_visible: Vec<u32>,
    /// Two-pass state: per cluster, the number of the frame that last drew it.
    drawn_in: Vec<u32>,
    /// Two-pass state: frames drawn with it so far (never 0 once started).
    frame: u32,
    /// First batch size of the front-to-back walk.
    pub first_batch: usize,
    /// Largest batch size.
    pub max_batch: usize,
    /// Largest batch size when the calling thread pool has one thread (the lower of this
    /// and `max_batch` applies), [`Culler::ONE_THREAD_MAX_BATCH`] by default. Batch sizes
    /// change which clusters and triangles get tested and skipped, so counters such as
    /// `triangles_drawn` depend on the thread count (never the image).
    pub one_thread_max_batch: usize,
}

/// What drawing one cluster takes, in one record per cluster: a batch of clusters then
/// touches one record each (one cache line, its instance's matrix inside) instead of the
/// cluster list, the instance list and the meshlet tables at scattered places. On the
/// boxfield (one cluster per instance, 83,334 instances) those misses were a sixth of the
/// occluder pass.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct ClusterDraw {
    /// The instance's `world_from_local`, columns (one cache line with the rest).
    world_from_local: [f32; 12],
    /// Meshlet slot ([`SceneMeshlets::slot`]).
    meshlets: u32,
    /// The instance's first triangle in scene order (IDs are made from it).
    first_triangle: u32,
    /// First triangle of the cluster in its meshlets, and the count (0: nothing to draw).
    first: u32,
    count: u32,
}

/// How far ahead batch loops prefetch per-cluster records.
const PREFETCH_AHEAD: usize = 8;

/// Octree depth for the `octree-hzb` walk.
const OCTREE_DEPTH: u32 = 6;

impl Culler {
    /// The default [`Culler::first_batch`]: the nearest few clusters go in first, so that
    /// the pyramid has occluders before the bulk of the walk is tested.
    pub const DEFAULT_FIRST_BATCH: usize = 8;

    /// The default [`Culler::max_batch`]. Street walks (two threads) take the same time
    /// with 256 to 2048 and draw fewer triangles with smaller batches (hzb: 18,706 at 1024,
    /// 20,290 at 2048); the aerial walk was about 1 ms slower at 256 and the same at 1024.
    pub const DEFAULT_MAX_BATCH: usize = 1024;

    /// The default [`Culler::one_thread_max_batch`]. A
    /// batch then costs no synchronization, and smaller batches refresh the pyramid that
    /// binning tests whole triangles against more often: on the boxfield's occluder pass
    /// 256 rejects 10% more triangle-tile pairs there than 2048 and is about 0.8 ms faster.
    pub const ONE_THREAD_MAX_BATCH: usize = 256;

    /// The largest draw batch for the calling thread pool.
    fn batch_cap(&self) -> usize {
        let cap = if rayon::current_num_threads() == 1 { self.one_thread_max_batch } else { usize::MAX };
        self.max_batch.min(cap).max(1)
    }

    /// Builds clusters, meshlets, BVH and octree for the scene's instances (world transforms
    /// must be up to date).
    pub fn new(scene: &Scene) -> Self {
        let instances = scene.instances();
        let clustered = ClusteredScene::from_instances(scene, &instances);
        let meshlets = SceneMeshlets::build(scene, &instances, &clustered);
        let item_boxes = clustered.item_boxes(&instances);
        let cone_inputs: Vec<_> = (0..clustered.item_count() as u32)
            .map(|i| {
                let it = clustered.item(i);
                let inst = &instances[it.instance as usize];
                match scene.mesh(inst.mesh) {
                    Some(m) => (m.positions(), m.indices(), clustered.triangles(i), inst.world_from_local),
                    None => (&[][..], &[][..], &[][..], inst.world_from_local),
                }
            })
            .collect();
        let cones = cone::cones(&cone_inputs);
        let mut cone_can_cull = vec![0u64; cones.len().div_ceil(64)];
        for (i, c) in cones.iter().enumerate() {
            cone_can_cull[i / 64] |= (c.can_cull() as u64) << (i % 64);
        }
        let octree = LooseOctree::from_boxes(&item_boxes, OCTREE_DEPTH);
        let draws = (0..clustered.item_count() as u32)
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
        Self {
            instances,
            clustered,
            meshlets,
            draws,
            item_boxes,
            cones,
            cone_can_cull,
            octree: Some(octree),
            renderer: Renderer::new(),
            visible: Vec::new(),
            last_visible: Vec::new(),
            drawn_in: Vec::new(),
            frame: 0,
            first_batch: Self::DEFAULT_FIRST_BATCH,
            max_batch: Self::DEFAULT_MAX_BATCH,
            one_thread_max_batch: Self::ONE_THREAD_MAX_BATCH,
        }
    }

    /// The instances the culler was built for.
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// The clusters and their BVH.
    pub fn clustered(&self) -> &ClusteredScene {
        &self.clustered
    }

    /// Heap bytes of the culling structures (clusters, BVH, meshlets, octree).
    pub fn memory_bytes(&self) -> usize {
        self.clustered.memory_bytes()
            + self.meshlets.memory_bytes()
            + self.item_boxes.capacity() * std::mem::size_of::<Aabb>()
            + self.cones.capacity() * std::mem::size_of::<cone::Cone>()
            + self.cone_can_cull.capacity() * 8
            + self.draws.capacity() * std::mem::size_of::<ClusterDraw>()
            + self.octree.as_ref().map_or(0, LooseOctree::memory_bytes)
    }

    /// Renders one frame with `method` into `fb` (every plane written, so no clear needed;
    /// after an error its contents are unspecified), shaded as `opts` says; antialiasing
    /// and wireframe are the plain renderer's business and ignored here.
    pub fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        method: Method,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<(CullStats, FrameStats)> {
        let t0 = Instant::now();
        let mut cs = CullStats { clusters: self.clustered.item_count() as u64, ..Default::default() };
        let mut opts = *opts;
        opts.antialias = crate::Antialias::Off;
        opts.wireframe = crate::Wireframe::Off;
        if method == Method::Brute {
            let items = draw_all(&self.instances);
            let fs = self.renderer.render(scene, &self.instances, &items, camera, fb, &opts)?;
            cs.triangles_drawn = fs.triangles_in;
            cs.clusters_in_frustum = cs.clusters;
            cs.clusters_drawn = cs.clusters;
            cs.ms_draw = fs.ms_total - fs.ms_shading;
            cs.ms_shading = fs.ms_shading;
            cs.ms_total = ms_since(t0);
            return Ok((cs, fs));
        }
        // No clear: a fresh draw or a frame session writes every depth and ID, and shading
        // every color.
        let t = Instant::now();
        let frustum = self.frustum_cull(camera, &mut cs);
        cs.ms_cull = ms_since(t);
        let mut f = Frame { camera, fb: &mut *fb, opts: &opts, cs, fs: FrameStats::default() };
        match method {
            Method::Brute => unreachable!("handled above"),
            Method::Frustum => {
                let t = Instant::now();
                let visible = std::mem::take(&mut self.visible);
                self.renderer.start_fresh();
                let r = self.draw_items(&visible, |v| v.index, &mut f);
                self.renderer.cancel_fresh();
                self.visible = visible;
                r?;
                f.cs.ms_draw = ms_since(t);
                f.cs.batches = 1;
            }
            Method::HzbOnePass => {
                self.renderer.begin_session(f.fb, opts.depth_format);
                let r = self.hzb_bvh(&mut f, &frustum, Walk { first_batch: self.first_batch, skip: None, test: true });
                f.fs.covered_pixels = self.renderer.end_session(f.fb);
                r?
            }
            Method::Hzb => self.hzb_two_pass(&mut f, &frustum)?,
            Method::OctreeHzb => self.hzb_octree(&mut f, &frustum)?,
        }
        let Frame { mut cs, mut fs, .. } = f;
        cs.culled_by_occlusion = cs.clusters_in_frustum.saturating_sub(cs.clusters_drawn + cs.culled_by_backface);
        let t = Instant::now();
        crate::shade_pass(scene, &self.instances, camera, fb, &opts.shading, opts.background);
        cs.ms_shading = ms_since(t);
        fs.ms_shading = cs.ms_shading;
        fs.update_overdraw();
        cs.ms_total = ms_since(t0);
        fs.ms_total = cs.ms_total;
        Ok((cs, fs))
    }

    /// Draws every cluster in the view frustum as occluders (depth and IDs; back faces as
    /// `opts` says) in one frame session left open, and returns box queries against the
    /// resulting pyramid. Call [`Culler::end_occluder_pass`] afterwards to write the frame.
    pub fn occluder_pass(
        &mut self,
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<(CullStats, FrameStats, OcclusionQueries<'_>)> {
        self.occluder_pass_with(camera, fb, opts, false)
    }

    /// [`Culler::occluder_pass`]; with `skip_hidden`, occluders are themselves tested against
    /// the pyramid as it fills (BVH nodes and clusters, as in [`Method::HzbOnePass`]) and the
    /// hidden ones skipped. Hidden occluders cannot change a depth, so the z-buffer, IDs and
    /// pyramid are the same bit for bit, for far less work in deep scenes.
    pub fn occluder_pass_with(
        &mut self,
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
        skip_hidden: bool,
    ) -> Result<(CullStats, FrameStats, OcclusionQueries<'_>)> {
        let t0 = Instant::now();
        let mut cs = CullStats { clusters: self.clustered.item_count() as u64, ..Default::default() };
        let frustum = self.frustum_cull(camera, &mut cs);
        self.renderer.begin_session(fb, opts.depth_format);
        // Front to back in growing batches, so that the coarse depth test of the rasterizer
        // rejects whole triangles hidden behind earlier ones.
        let mut f = Frame { camera, fb: &mut *fb, opts, cs, fs: FrameStats::default() };
        let walk = Walk { first_batch: self.first_batch, skip: None, test: skip_hidden };
        if let Err(e) = self.hzb_bvh(&mut f, &frustum, walk) {
            self.renderer.end_session(fb);
            return Err(e);
        }
        let Frame { mut cs, fs, .. } = f;
        // The walk's split into culling and drawing is not reported for the pass.
        cs.ms_cull = 0.0;
        cs.ms_draw = ms_since(t0);
        cs.ms_total = cs.ms_draw;
        cs.culled_by_occlusion = cs.clusters_in_frustum.saturating_sub(cs.clusters_drawn + cs.culled_by_backface);
        let pyramid = self.renderer.session_pyramid().expect("a session was just begun");
        Ok((cs, fs, OcclusionQueries::new(camera, pyramid)))
    }

    /// The pyramid of the open frame session, if any (between [`Culler::occluder_pass`] and
    /// [`Culler::end_occluder_pass`]).
    pub fn renderer_pyramid(&self) -> Option<TilePyramid<'_>> {
        self.renderer.session_pyramid()
    }

    /// Ends the pass begun by [`Culler::occluder_pass`]: the frame's depth and IDs go to `fb`
    /// (its colors are left as they were).
    pub fn end_occluder_pass(&mut self, fb: &mut Framebuffer) {
        self.renderer.end_session(fb);
    }

    /// Starts a culled frame: the clusters in the view frustum go to `self.visible` (BVH
    /// order) and their counts to `cs`; returns the frustum.
    fn frustum_cull(&mut self, camera: &Camera, cs: &mut CullStats) -> Frustum {
        let frustum = Frustum::from_camera(camera);
        self.visible.clear();
        self.clustered.cull_with(&frustum, CullOptions::default(), &mut self.visible);
        cs.clusters_in_frustum = self.visible.len() as u64;
        cs.culled_by_frustum = cs.clusters - cs.clusters_in_frustum;
        frustum
    }

    /// Drops clusters whose triangles all face away from the eye (normal cones), counting them.
    fn drop_backfacing(&self, items: &mut Vec<Visible>, eye: glam::Vec3, cs: &mut CullStats) {
        let n = items.len();
        let can_cull = |i: u32| self.cone_can_cull[i as usize / 64] >> (i % 64) & 1 != 0;
        // The clusters' records are scattered over memory: ask for the cones a few ahead,
        // and for the draw records that `draw_items` reads next.
        for v in items.iter().take(PREFETCH_AHEAD).filter(|v| can_cull(v.index)) {
            prefetch(&self.cones[v.index as usize]);
        }
        let mut kept = 0;
        for k in 0..n {
            if let Some(a) = items.get(k + PREFETCH_AHEAD).filter(|a| can_cull(a.index)) {
                prefetch(&self.cones[a.index as usize]);
            }
            let v = items[k];
            if !(can_cull(v.index) && self.cones[v.index as usize].backfacing(eye)) {
                prefetch(&self.draws[v.index as usize]);
                items[kept] = v;
                kept += 1;
            }
        }
        items.truncate(kept);
        cs.culled_by_backface += (n - kept) as u64;
    }

    /// Draws the given items (cluster indices, `index` of each element) in order, counting
    /// into `f`.
    fn draw_items<T>(&mut self, items: &[T], index: impl Fn(&T) -> u32, f: &mut Frame) -> Result<()> {
        let mut sources: Vec<DrawSource> = Vec::with_capacity(items.len());
        for (k, v) in items.iter().enumerate() {
            if let Some(a) = items.get(k + PREFETCH_AHEAD) {
                prefetch(&self.draws[index(a) as usize]);
            }
            let d = &self.draws[index(v) as usize];
            if d.count == 0 {
                continue;
            }
            let ml = self.meshlets.by_slot(d.meshlets);
            sources.push(DrawSource {
                positions: &ml.positions,
                indices: &ml.indices,
                triangle_ids: Some(&ml.triangle_ids),
                world_from_local: Affine3A::from_cols_array(&d.world_from_local),
                first_triangle: d.first_triangle,
                first: d.first,
                count: d.count,
            });
            f.cs.clusters_drawn += 1;
            f.cs.triangles_drawn += d.count as u64;
        }
        // Meshlet indices point into their own positions by construction.
        f.fs.add(&self.renderer.draw_sources_checked(&sources, f.camera, f.fb, f.opts, false)?);
        Ok(())
    }

    /// The front-to-back walk of [`Method::HzbOnePass`] (and of the occluder pass, which
    /// does not test) inside an open frame session, in batches growing from
    /// `walk.first_batch` clusters; see [`Walk`] for the rest.
    fn hzb_bvh(&mut self, f: &mut Frame, frustum: &Frustum, walk: Walk) -> Result<()> {
        let projector = BoxProjector::new(f.camera.clip_from_world(), f.fb.width(), f.fb.height());
        let eye = f.camera.view.eye;
        let mut cursor = self.clustered.cursor(Some(frustum), eye);
        let mut batch = walk.first_batch.max(1);
        let mut out: Vec<Visible> = Vec::new();
        loop {
            let t = Instant::now();
            out.clear();
            let more = {
                let Some(pyramid) = self.renderer.session_pyramid() else {
                    debug_assert!(false, "the walk runs inside a frame session");
                    break Ok(());
                };
                let q = walk.test.then(|| OcclusionQueries::with_projector(projector, pyramid));
                let cs = &mut f.cs;
                cursor.next_batch(
                    self.clustered.bvh(),
                    |b| q.as_ref().is_none_or(|q| q.counted_visible(b, cs)),
                    batch,
                    &mut out,
                )
            };
            if let Some(frame) = walk.skip {
                out.retain(|v| self.drawn_in[v.index as usize] != frame);
            }
            // Clusters facing away would only be dropped triangle by triangle.
            if f.opts.backface_culling {
                self.drop_backfacing(&mut out, eye, &mut f.cs);
            }
            f.cs.ms_cull += ms_since(t);
            if !out.is_empty() {
                let t = Instant::now();
                self.draw_items(&out, |v| v.index, f)?;
                if let Some(frame) = walk.skip {
                    for v in &out {
                        self.drawn_in[v.index as usize] = frame;
                    }
                    self.last_visible.extend(out.iter().map(|v| v.index));
                }
                f.cs.ms_draw += ms_since(t);
                f.cs.batches += 1;
            }
            if !more {
                return Ok(());
            }
            batch = (batch * 2).min(self.batch_cap());
        }
    }

    /// [`Method::Hzb`]: last frame's visible clusters (those still in the frustum and
    /// not facing away) are drawn first, in one batch; the front-to-back walk then tests the
    /// rest against their pyramid, starting with big batches; finally last frame's clusters
    /// are tested against the finished pyramid, and the ones not occluded join this frame's
    /// newly drawn ones as the next frame's set.
    fn hzb_two_pass(&mut self, f: &mut Frame, frustum: &Frustum) -> Result<()> {
        let n = self.clustered.item_count();
        self.frame = self.frame.wrapping_add(1);
        if self.frame == 0 || self.drawn_in.len() != n {
            self.drawn_in.clear();
            self.drawn_in.resize(n, 0);
            self.frame = 1;
        }
        let frame = self.frame;
        let t = Instant::now();
        // Last frame's set, kept where still in the frustum (self.visible) and facing us.
        for v in &self.visible {
            self.drawn_in[v.index as usize] = frame;
        }
        let eye = f.camera.view.eye;
        let mut first: Vec<u32> = std::mem::take(&mut self.last_visible);
        first.retain(|&i| self.drawn_in.get(i as usize) == Some(&frame));
        for v in &self.visible {
            self.drawn_in[v.index as usize] = 0;
        }
        if f.opts.backface_culling {
            // Not counted here: the walk meets them again and counts them once.
            first.retain(|&i| !self.cones[i as usize].backfacing(eye));
        }
        for &i in &first {
            self.drawn_in[i as usize] = frame;
        }
        f.cs.ms_cull += ms_since(t);
        self.renderer.begin_session(f.fb, f.opts.depth_format);
        let result = (|| {
            if !first.is_empty() {
                let t = Instant::now();
                self.draw_items(&first, |&i| i, f)?;
                f.cs.ms_draw += ms_since(t);
                f.cs.batches += 1;
            }
            // With last frame's occluders in place the pyramid is mostly complete: big batches.
            let first_batch =
                if first.is_empty() { self.first_batch } else { (self.batch_cap() / 4).max(self.first_batch) };
            self.hzb_bvh(f, frustum, Walk { first_batch, skip: Some(frame), test: true })
        })();
        // Re-test last frame's clusters against the finished pyramid: the occluded ones leave
        // the set (their pixels went to nearer clusters).
        let t = Instant::now();
        if let Some(pyramid) = self.renderer.session_pyramid() {
            let q = OcclusionQueries::new(f.camera, pyramid);
            let boxes = &self.item_boxes;
            let still: Vec<u32> =
                first.iter().copied().filter(|&i| q.counted_visible(&boxes[i as usize], &mut f.cs)).collect();
            self.last_visible.extend(still);
        }
        f.cs.ms_cull += ms_since(t);
        f.fs.covered_pixels = self.renderer.end_session(f.fb);
        if result.is_err() {
            self.last_visible.clear();
        }
        result
    }

    fn hzb_octree(&mut self, f: &mut Frame, frustum: &Frustum) -> Result<()> {
        let projector = BoxProjector::new(f.camera.clip_from_world(), f.fb.width(), f.fb.height());
        let (eye, backface_culling) = (f.camera.view.eye, f.opts.backface_culling);
        self.renderer.begin_session(f.fb, f.opts.depth_format);
        let Some(octree) = self.octree.take() else {
            // Only while a walk holds the octree, which cannot call back in here; still,
            // leave a written (empty) frame rather than an open session.
            f.fs.covered_pixels = self.renderer.end_session(f.fb);
            return Ok(());
        };
        // The walk's two callbacks both need the frame (one reads depth, the other draws):
        // they never run at the same time, so a RefCell shares it.
        let batch = self.first_batch.max(1);
        let walk = RefCell::new(OctreeWalk { culler: self, f, pending: Vec::new(), batch, err: None });
        let t = Instant::now();
        octree.traverse_front_to_back(
            Some(frustum),
            eye,
            |b| {
                let mut g = walk.borrow_mut();
                let w = &mut *g;
                let vis = match w.culler.renderer.session_pyramid() {
                    Some(p) => OcclusionQueries::with_projector(projector, p).counted_visible(b, &mut w.f.cs),
                    None => true,
                };
                if vis {
                    Visit::Continue
                } else {
                    Visit::Skip
                }
            },
            |v| {
                let mut g = walk.borrow_mut();
                if backface_culling && g.culler.cones[v.index as usize].backfacing(eye) {
                    g.f.cs.culled_by_backface += 1;
                    return Visit::Continue;
                }
                g.pending.push(v);
                if g.pending.len() >= g.batch {
                    g.flush();
                }
                Visit::Continue
            },
        );
        let mut w = walk.into_inner();
        w.flush();
        w.culler.octree = Some(octree);
        w.f.fs.covered_pixels = w.culler.renderer.end_session(w.f.fb);
        // Traversal time excludes the drawing done inside it.
        w.f.cs.ms_cull += (ms_since(t) - w.f.cs.ms_draw).max(0.0);
        match w.err {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

/// One culled frame in progress: the camera and options it draws with, the framebuffer it
/// draws into, and its counters. The walks take it whole.
struct Frame<'a> {
    camera: &'a Camera,
    fb: &'a mut Framebuffer,
    opts: &'a RenderOptions,
    cs: CullStats,
    fs: FrameStats,
}

/// How [`Culler::hzb_bvh`] walks.
#[derive(Debug, Clone, Copy)]
struct Walk {
    /// Clusters in the first draw batch (batches then double up to the batch cap).
    first_batch: usize,
    /// `Some(frame)`: clusters already drawn in that frame (see `drawn_in`) are passed
    /// over, and the ones drawn get marked and join `last_visible`.
    skip: Option<u32>,
    /// Test nodes and clusters against the pyramid before drawing them (false: draw every
    /// cluster in the frustum, front to back).
    test: bool,
}

/// State of the octree walk shared by its callbacks.
struct OctreeWalk<'a, 'f> {
    culler: &'a mut Culler,
    f: &'a mut Frame<'f>,
    pending: Vec<Visible>,
    batch: usize,
    err: Option<crate::Error>,
}

impl OctreeWalk<'_, '_> {
    /// Draws the pending clusters (the tiles refresh their pyramid levels as they draw).
    fn flush(&mut self) {
        if self.pending.is_empty() || self.err.is_some() {
            return;
        }
        let t = Instant::now();
        let items = std::mem::take(&mut self.pending);
        if let Err(e) = self.culler.draw_items(&items, |v| v.index, self.f) {
            self.err = Some(e);
        }
        self.f.cs.ms_draw += ms_since(t);
        self.f.cs.batches += 1;
        self.batch = (self.batch * 2).min(self.culler.batch_cap());
        self.pending = items;
        self.pending.clear();
    }
}

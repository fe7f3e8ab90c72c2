//! The culling frame loop: draw only what can be seen, and prove nothing visible was lost.
//!
//! One [`Culler`] per scene, one call per frame, the method chosen per call:
//!
//! * [`Method::Brute`]: every triangle through the pipeline (the reference).
//! * [`Method::Frustum`]: the (instance, cluster) BVH of `sightline_spatial::ClusteredScene`
//!   culled against the view frustum; the surviving clusters are drawn in scene order, as
//!   few long ranges: whole instances as their meshes, runs of one instance's clusters as one
//!   meshlet range (`ranges.rs`). When the tree's root box lies inside the frustum (the whole
//!   scene in view), the frame is drawn as brute force draws it, without walking the tree.
//! * [`Method::HzbOnePass`]: frustum culling plus occlusion culling with Greene's z-pyramid
//!   ([`crate::hzb`]): the BVH is walked front to back in batches; before anything (node or
//!   cluster) is drawn, its box is projected to a screen rectangle and nearest depth and tested
//!   against the pyramid of what is already drawn; a batch is drawn, the pyramid refreshed over
//!   the drawn rectangles, and the walk resumes. Batches start small (the nearest occluders go
//!   in first) and double.
//! * [`Method::Hzb`]: the same walk in the two-pass form GPU engines use to exploit temporal
//!   coherence: last frame's visible clusters (still in the frustum) are drawn first, in one batch,
//!   front to back, as occluders; the walk then tests everything else against that pyramid, in big
//!   batches, passing over the clusters drawn first without testing them again (where much is
//!   in view, as on an orbit around the boxfield, those tests were a third of the walk's), and,
//!   when they are at least an eighth of the clusters, over the BVH nodes holding them too
//!   (a node holding something just drawn is rarely hidden; the coherence CHC exploits,
//!   Bittner et al., "Coherent Hierarchical Culling", Eurographics 2004); at the
//!   end last frame's clusters are tested again, and those still visible join this
//!   frame's newly drawn ones as the next frame's set. When none of last frame's set is left in
//!   view (the first frame, or after a cut) it is the one-pass walk. On the street path it needs
//!   two draw batches instead of six, and the two forms take about the same time; from above, where
//!   little is hidden, it was faster (19.8 against 22.3 ms per aerial frame in one verified walk),
//!   so it is `hzb`.
//! * [`Method::OctreeHzb`]: Greene's original: a loose octree over the same clusters, walked
//!   front to back in the same batches (a resumable `OctreeCursor`), skipping a whole
//!   octant when its loose cube is occluded.
//!
//! The walks live in `walk.rs`; each draws through one frame [`Session`] of the renderer. The
//! occluder pass on its own (draw the occluders, then ask about boxes) is in `occluder.rs`.
//!
//! Exactness. A box is skipped only when its nearest possible window depth is farther than
//! the farthest depth stored over every pixel it can touch, so none of its fragments could
//! pass the depth test; boxes crossing the near plane are always drawn. Draw order does not
//! change the image either: the depth test breaks exact-depth ties by the smaller triangle
//! ID, which is what in-order drawing with a LESS test gives. So every method's ID buffer
//! equals the brute-force one; [`compare_ids`] checks it, and the tests run it on many
//! cameras.

pub mod cone;
mod drawn;
pub mod meshlets;
mod moves;
mod occluder;
pub mod order;
pub mod query;
mod ranges;
mod two_pass;
mod update;
mod verify;
mod walk;

use std::time::Instant;

use serde::{Deserialize, Serialize};
use sightline_scene::{Aabb, Camera, Instance, Scene, SceneStamp};
use sightline_spatial::{ClusteredScene, Containment, Frustum, FrustumCount, LooseOctree, Visible};

pub use crate::hzb::{DepthPyramid, Level, Rect, TilePyramid};
pub use meshlets::{Meshlets, SceneMeshlets};
pub use occluder::OccluderPass;
pub use order::DrawOrder;
pub use query::{BoxVisibility, OcclusionQueries};
pub use update::SyncOutcome;
pub use verify::{compare_ids, Mismatch};

use crate::awake::join_helping;
use crate::pipeline::Target;
use crate::stats::ms_since;
use crate::{draw_all, FrameStats, Framebuffer, RenderOptions, Renderer, Result, Session};
use walk::{Batching, Frame, Source, TwoPass, Walk};

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
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
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
    /// Boxes (BVH nodes, octants, clusters) tested against the z-pyramid. The walks of a
    /// batch that run ahead of where it ends on another worker, and are dropped, are not
    /// counted: the count is the same on any thread count.
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

impl CullStats {
    /// Sets the clusters in the frustum, and so the ones it culled.
    fn set_in_frustum(&mut self, n: u64) {
        self.clusters_in_frustum = n;
        self.culled_by_frustum = self.clusters - n;
    }
}

/// Per-scene culling state: clusters, their BVH and octree, meshlets, the z-pyramid and a
/// renderer, all reused frame after frame.
#[derive(Debug)]
pub struct Culler {
    renderer: Renderer,
    c: Clusters,
    /// First batch of the walks that test clusters against the z-pyramid between batches
    /// (as [`Culler::max_tested_batch`]; later batches double),
    /// [`Culler::DEFAULT_FIRST_BATCH`] by default.
    pub first_batch: usize,
    /// First batch of the occluder pass that draws every occluder (as
    /// [`Culler::max_batch`]), [`Culler::DEFAULT_FIRST_UNTESTED_BATCH`] by default.
    pub first_untested_batch: usize,
    /// Largest batch of the walks that test clusters against the z-pyramid between batches
    /// (the occlusion methods, and the occluder pass that skips hidden occluders),
    /// [`Culler::DEFAULT_MAX_TESTED_BATCH`] by default.
    pub max_tested_batch: usize,
    /// Largest batch of the occluder pass that draws every occluder (its walk tests
    /// nothing, and finds the next batch while the current one is drawn),
    /// [`Culler::DEFAULT_MAX_BATCH`] by default.
    pub max_batch: usize,
    /// Largest batch of any walk when the calling thread pool has one thread (the lower of
    /// this and the walk's own cap applies), [`Culler::ONE_THREAD_MAX_BATCH`] by default.
    /// Batch sizes change which clusters and triangles get tested and skipped, so counters
    /// such as `triangles_drawn` depend on the thread count (never the image).
    pub one_thread_max_batch: usize,
    /// Clusters nearest the eye (by box distance, among those in the frustum) that the BVH
    /// walks take first, before their depth-first front-to-back order;
    /// [`Culler::DEFAULT_NEAREST_FIRST`] by default, 0 for none. The frame is the same for
    /// any value; what is drawn, and so the time, is not.
    pub nearest_first: usize,
    /// The occluder pass that draws every occluder takes a BVH subtree inside the frustum
    /// with at most this many clusters whole, in the tree's order, rather than front to
    /// back cluster by cluster ([`FrontToBackCursor::whole_subtrees`](sightline_spatial::FrontToBackCursor::whole_subtrees);
    /// at most 254); [`Culler::DEFAULT_WHOLE_SUBTREE`] by default, 0 for none. The
    /// buffers are the same for any value.
    pub whole_subtree: usize,
}

/// Everything a culled frame reads and updates besides the renderer (so that a walk can
/// hold the renderer's [`Session`] and this at once).
#[derive(Debug)]
struct Clusters {
    /// The scene and revision the state follows.
    stamp: SceneStamp,
    instances: Vec<Instance>,
    /// Instance index by the node that draws it.
    node_instance: update::NodeInstance,
    clustered: ClusteredScene,
    meshlets: SceneMeshlets,
    /// Per cluster, what drawing it takes.
    draws: Vec<ClusterDraw>,
    item_boxes: Vec<Aabb>,
    /// Per meshlet slot (mesh), its clusters' normal cones in mesh space.
    local_cones: Vec<Vec<cone::LocalCone>>,
    cones: Vec<cone::Cone>,
    /// Per cluster, one bit: its cone [can cull](cone::Cone::can_cull) at all. A small
    /// array that stays in cache, so that clusters whose cone never culls (closed meshes
    /// such as boxes) cost no load of their cone.
    cone_can_cull: Vec<u64>,
    /// The largest reach of an instance's vertex transform (world units, per axis; see
    /// `update::instance_reach`): the box projector's margins for the rasterizer's rounding
    /// grow with it ([`BoxProjector::for_camera`](sightline_spatial::BoxProjector::for_camera)). Only grows as instances move.
    reach: f32,
    octree: LooseOctree,
    /// Clusters that moved since the octree was last brought up to date.
    octree_pending: Vec<u32>,
    /// The octree is built anew at its next use instead of moving entries: it was never
    /// built, or more clusters moved than there are.
    octree_rebuild: bool,
    /// Scratch of `move_nodes`: the moved (instance, node) pairs, and the moved clusters.
    moves: Vec<(u32, sightline_scene::NodeId)>,
    changed: Vec<u32>,
    visible: Vec<Visible>,
    two_pass: TwoPass,
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
    /// the pyramid has occluders before the bulk of the walk is tested (with 32, `hzb`
    /// street frames took the same time at 10^6, 10^8 and 10^9 triangles, but a scene of a
    /// few dozen clusters is drawn whole before its first test).
    pub const DEFAULT_FIRST_BATCH: usize = 8;

    /// The default [`Culler::first_untested_batch`]. That walk tests nothing, so its first
    /// batch only starts the pipeline of finding one batch while the last is drawn: on the
    /// boxfield's occluder pass (the values taking turns pass by pass in one process) 32
    /// took 5.80–5.93 against 6.06–6.69 ms for 8 on one thread and 3.57–3.80 against
    /// 3.71–4.13 ms on two (instanced; one mesh 5.93–6.17 against 6.19–6.53 and 3.42–3.72
    /// against 3.69–4.03 ms), 16 to 128 about alike.
    pub const DEFAULT_FIRST_UNTESTED_BATCH: usize = 32;

    /// The default [`Culler::max_tested_batch`]. Smaller batches refresh the pyramid more
    /// often, so fewer clusters are drawn before their occluders: in the street walk of the
    /// 10^9-triangle city (30 frames, two threads) 4,323 clusters at 128 against 6,153 at
    /// 1,024, and 21–22 ms a frame against 25–26 ms. Below 128 the batches' own cost
    /// wins (64: 23–24 ms); the default city's street and aerial walks take the same time
    /// from 128 to 1,024.
    pub const DEFAULT_MAX_TESTED_BATCH: usize = 128;

    /// The default [`Culler::max_batch`]. The walk tests nothing, so smaller batches only
    /// add steps (each a hand-over between the workers), while larger ones refresh the
    /// pyramid that binning rejects whole triangles against less often. On the boxfield's
    /// occluder pass (every occluder, two threads, the sizes taking turns pass by pass):
    /// instanced, 2,048 took 3.60–4.01 ms against 3.81–4.31 ms for 1,024, less in each of
    /// seven runs, and 3,072 to 16,384 no less; the one-mesh layout the same from 1,024 to
    /// 16,384; 256 was 10–15% slower in an earlier measurement.
    pub const DEFAULT_MAX_BATCH: usize = 2048;

    /// The default [`Culler::one_thread_max_batch`]. A
    /// batch then costs no synchronization, and smaller batches refresh the pyramid that
    /// binning tests whole triangles against more often: on the boxfield's occluder pass
    /// 256 rejected 10% more triangle-tile pairs there than 2048 and was about 0.8 ms
    /// faster. Once binning and the walk cost less per batch, 512 took 1.3–3.6% less time
    /// than 256 on the instanced boxfield and 0.2–0.3% more on the one-mesh layout (four
    /// runs each, the sizes taking turns pass by pass); 1,024 was no better than 512.
    pub const ONE_THREAD_MAX_BATCH: usize = 512;

    /// The default [`Culler::nearest_first`]. The depth-first walk finishes the nearer
    /// child's whole subtree first, so a box beside the eye can wait behind thousands of
    /// farther ones. On the boxfield's occluder pass the nearest box (0.14 units from the
    /// eye) came in the 15th batch, after 2,800 clusters, and then overwrote a million
    /// pixels; taking the 32 nearest first made the pass 15% faster on one thread. 16 to
    /// 256 do about as well there; 1,024 and more cost more to find than they save.
    pub const DEFAULT_NEAREST_FIRST: usize = 32;

    /// The default [`Culler::whole_subtree`]. On the instanced boxfield's occluder pass
    /// (21,552 clusters of one box each in the frustum) the front-to-back walk alone took
    /// about 0.85 ms of the pass's 8.7 ms on one thread, against 0.35 ms for a plain
    /// frustum cull of the same tree: 40 ns a cluster, for nodes, box distances and leaf
    /// sorts. In one process, the values taking turns pass by pass (medians of 200), one
    /// thread: 0, 16, 32, 64 gave 9.20, 8.59, 8.52, 8.47 ms (64: 0.92×), two threads 5.02,
    /// 4.82, 4.78, 4.75 ms (0.95×); the one-mesh layout (3,422 clusters) 0.99× on both.
    pub const DEFAULT_WHOLE_SUBTREE: usize = 64;

    /// The batch sizes for the calling thread pool, of a walk that tests clusters against
    /// the pyramid (`tested`) or not.
    fn batching(&self, tested: bool) -> Batching {
        let one = if rayon::current_num_threads() == 1 { self.one_thread_max_batch } else { usize::MAX };
        let cap = if tested { self.max_tested_batch } else { self.max_batch };
        Batching {
            first: if tested { self.first_batch } else { self.first_untested_batch }.max(1),
            cap: cap.min(one).max(1),
            nearest_first: self.nearest_first,
            // The cursor caps it (at 254).
            whole_subtree: u32::try_from(self.whole_subtree).unwrap_or(u32::MAX),
        }
    }

    /// Builds clusters, meshlets and BVH for the scene's instances (world transforms
    /// must be up to date). A scene of more triangles than IDs can name
    /// ([`sightline_scene::MAX_DRAWN_TRIANGLES`]) is not built for: its frames are refused
    /// with [`Error::TooManyTriangles`](crate::Error::TooManyTriangles) until it draws few enough.
    pub fn new(scene: &Scene) -> Self {
        let c = match crate::error::check_drawable(scene) {
            Ok(()) => Clusters::build(scene, None),
            Err(_) => Clusters::empty(scene),
        };
        Self {
            renderer: Renderer::new(),
            c,
            first_batch: Self::DEFAULT_FIRST_BATCH,
            first_untested_batch: Self::DEFAULT_FIRST_UNTESTED_BATCH,
            max_tested_batch: Self::DEFAULT_MAX_TESTED_BATCH,
            max_batch: Self::DEFAULT_MAX_BATCH,
            one_thread_max_batch: Self::ONE_THREAD_MAX_BATCH,
            nearest_first: Self::DEFAULT_NEAREST_FIRST,
            whole_subtree: Self::DEFAULT_WHOLE_SUBTREE,
        }
    }

    /// Builds what `method` walks that is made on first use (the loose octree of
    /// [`Method::OctreeHzb`]), so that the first frame does not pay for it.
    pub fn prepare(&mut self, method: Method) {
        if method == Method::OctreeHzb {
            self.c.settle_octree();
        }
    }

    /// The identity of the scene this culler was built for.
    pub(crate) fn scene_id(&self) -> sightline_scene::SceneId {
        self.c.stamp.scene
    }

    /// Brings the culling state up to date with `scene` after edits: moved instances are
    /// refitted, added or removed ones rebuild the world side (see the `update` module).
    /// `scene` must have been propagated ([`Scene::update_transforms`]).
    ///
    /// [`Culler::render`] calls it first, so a frame is never drawn from stale state. A
    /// culler serves the scene it was built for: another scene (a clone is another scene
    /// too) is an error; build a culler for it.
    pub fn sync(&mut self, scene: &Scene) -> Result<SyncOutcome> {
        crate::error::check_followable(scene, self.c.stamp.scene, "culler")?;
        Ok(self.c.sync(scene))
    }

    /// The instances the culler was built for.
    pub fn instances(&self) -> &[Instance] {
        &self.c.instances
    }

    /// The largest `Σ_j |B_kj|·|v_j|` over the instances (`B` an instance's linear part, `v`
    /// its mesh's local box corners), per world axis: the `reach` its box tests project with
    /// ([`BoxProjector::for_camera`](sightline_spatial::BoxProjector::for_camera)).
    pub fn reach(&self) -> f32 {
        self.c.reach
    }

    /// The clusters and their BVH.
    pub fn clustered(&self) -> &ClusteredScene {
        &self.c.clustered
    }

    /// True when every triangle of cluster `item` (an item of [`Culler::clustered`]) faces
    /// away from `eye`, by the normal cone the culling methods test: what they drop without
    /// drawing.
    pub fn cluster_faces_away(&self, item: u32, eye: glam::Vec3) -> bool {
        (item as usize) < self.c.cones.len() && self.c.faces_away(item, eye)
    }

    /// Heap bytes of the culling structures (clusters, BVH, meshlets, octree).
    pub fn memory_bytes(&self) -> usize {
        let c = &self.c;
        c.clustered.memory_bytes()
            + c.meshlets.memory_bytes()
            + c.item_boxes.capacity() * std::mem::size_of::<Aabb>()
            + c.cones.capacity() * std::mem::size_of::<cone::Cone>()
            + c.cone_can_cull.capacity() * 8
            + c.draws.capacity() * std::mem::size_of::<ClusterDraw>()
            + c.octree.memory_bytes()
    }

    /// True when this culler's frames of `scene` with `opts` show what the plain
    /// [`Renderer`]'s show, antialiasing aside (both can draw larger and box-filter down,
    /// see [`crate::aa::supersample`]): a culled frame has brute force's IDs and is shaded
    /// from them, but the culler draws every material opaque and no wireframe. So: no
    /// wireframe, and transparency ignored or every material opaque.
    pub fn draws_like_renderer(scene: &Scene, opts: &RenderOptions) -> bool {
        let drawn = culled_options(opts);
        // Equal to what is drawn, antialiasing aside; with every material opaque, the way
        // transparency is drawn makes no difference either.
        let alike = |o: RenderOptions| RenderOptions { antialias: drawn.antialias, ..o } == drawn;
        alike(*opts)
            || (scene.materials().all(|(_, m)| m.alpha_mode.is_opaque())
                && alike(RenderOptions { transparency: drawn.transparency, ..*opts }))
    }

    /// Runs `f` on this culler drawing with `renderer` (its tiles, bins and scratch buffers)
    /// instead of its own: for frames of another size beside the regular ones (a
    /// supersampled picture between timed frames), which would otherwise resize the culler's
    /// buffers and make its next regular frame build them again.
    pub fn with_renderer<R>(&mut self, renderer: &mut Renderer, f: impl FnOnce(&mut Culler) -> R) -> R {
        std::mem::swap(&mut self.renderer, renderer);
        let r = f(self);
        std::mem::swap(&mut self.renderer, renderer);
        r
    }

    /// True when every cluster lies inside the view frustum (the BVH's root box does,
    /// or the tree holds no box: only unbounded clusters, which are always drawn). The
    /// frustum method then draws what brute force draws, and the same way (every instance
    /// whole, in scene order), with no walk of the tree and no list of its clusters: where
    /// the whole scene is in view (an orbit around it) it costs what brute force costs.
    fn all_in_view(&self, frustum: &Frustum) -> bool {
        let root = self.c.clustered.bvh().bounds();
        root.is_empty() || frustum.classify(&root) == Containment::Inside
    }

    /// Renders one frame with `method` into `fb` (every plane written, so no clear needed;
    /// after an error its contents are unspecified), shaded as `opts` says; antialiasing,
    /// wireframe and transparency are the plain renderer's business and ignored here (every
    /// material is drawn opaque: occlusion culling assumes opaque occluders; see
    /// [`Culler::draws_like_renderer`]).
    pub fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        method: Method,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<(CullStats, FrameStats)> {
        opts.depth_format.check_resolves(&camera.projection)?;
        self.sync(scene)?;
        let t0 = Instant::now();
        let mut cs = CullStats { clusters: self.c.clustered.item_count() as u64, ..Default::default() };
        let opts = culled_options(opts);
        let frustum = Frustum::from_camera(camera);
        if method == Method::Brute || method == Method::Frustum && self.all_in_view(&frustum) {
            let items = draw_all(&self.c.instances);
            let fs = self.renderer.render(scene, &self.c.instances, &items, camera, fb, &opts)?;
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
        // The occlusion methods' walks test the frustum themselves; the clusters inside it
        // are counted (for the statistics only) beside the walk and the shading, below.
        if method == Method::Frustum {
            self.c.frustum_cull(&frustum, &mut cs);
        }
        cs.ms_cull = ms_since(t);
        let mut count = (method != Method::Frustum).then(|| FrustumCount::new(self.c.clustered.bvh(), &frustum));
        let mut f = Frame { camera, opts: &opts, cs, fs: FrameStats::default() };
        let batching = self.batching(true);
        if method == Method::Frustum {
            let t = Instant::now();
            let sources = self.c.range_sources(scene, &self.c.visible, &mut f.cs);
            let target = Target::Frame { fb: &mut *fb, fresh: true };
            f.fs.add(&self.renderer.draw_sources_to(&sources, camera, target, &opts, false)?);
            f.cs.ms_draw = ms_since(t);
            f.cs.batches = 1;
        } else {
            if method == Method::OctreeHzb {
                self.c.settle_octree();
            }
            let mut two = std::mem::take(&mut self.c.two_pass);
            let c = &self.c;
            let mut session = self.renderer.begin(fb, &opts);
            // Meanwhile the other worker counts the clusters in the frustum (a statistic),
            // serving the frame's parallel steps as they come: the draws, and the walks that
            // find the BVH walk's batches (the octree walk stays on this worker).
            let (r, ()) = join_helping(
                || match method {
                    Method::HzbOnePass | Method::OctreeHzb => {
                        let source = if method == Method::OctreeHzb { Source::Octree } else { Source::Bvh };
                        let walk = Walk { first_batch: batching.first, skip: None };
                        c.hzb_walk(&mut session, &mut f, &frustum, source, walk, batching)
                    }
                    _ => c.hzb_two_pass(&mut session, &mut f, &frustum, batching, &mut two),
                },
                |poll| {
                    if let Some(count) = &mut count {
                        count.run(c.clustered.bvh(), poll);
                    }
                },
            );
            self.c.two_pass = two;
            f.fs.covered_pixels = session.finish();
            r?;
        }
        let Frame { mut cs, mut fs, .. } = f;
        let mut shade = || {
            let t = Instant::now();
            crate::shade_pass(scene, &self.c.instances, camera, fb, &opts.shading, opts.background);
            ms_since(t)
        };
        cs.ms_shading = if method == Method::Frustum {
            shade()
        } else {
            // Counting walks the BVH nodes the frustum's boundary cuts: 1–3 ms on one thread
            // in the street view of a 10^9-triangle city. What the walk left of it (all of it
            // on one thread) overlaps the shading pass, whose bands go to
            // whichever worker is free.
            let bvh = self.c.clustered.bvh();
            let (n, ms) = rayon::join(|| count.map(|c| c.finish(bvh)), shade);
            cs.set_in_frustum(n.unwrap_or(0));
            ms
        };
        cs.culled_by_occlusion = cs.clusters_in_frustum.saturating_sub(cs.clusters_drawn + cs.culled_by_backface);
        fs.ms_shading = cs.ms_shading;
        fs.update_overdraw();
        cs.ms_total = ms_since(t0);
        fs.ms_total = cs.ms_total;
        Ok((cs, fs))
    }

    /// Draws the clusters `items` (items of [`Culler::clustered`]), in the order given,
    /// into an open frame session of any renderer, as the culling methods draw a batch:
    /// each cluster's triangles as one range of its meshlets (consecutive in memory, see
    /// [`Meshlets`]) under its instance's transform as of the last [`Culler::sync`], with
    /// the scene's triangle IDs. For culling of one's own over the culler's clusters, and
    /// for measuring what a set of clusters costs to draw.
    pub fn draw_clusters(&self, session: &mut Session, items: &[u32], camera: &Camera) -> Result<FrameStats> {
        let n = self.c.draws.len();
        if let Some(i) = items.iter().find(|&&i| i as usize >= n) {
            return Err(crate::Error::InvalidDraw(format!("cluster {i} is not one of the culler's {n} clusters")));
        }
        self.c.draw_batch(session, items, |&i| i, camera, &mut CullStats::default())
    }
}

/// The options a culled frame is drawn with, out of those asked for: no antialiasing,
/// wireframe or transparency (the culler draws one sample per pixel and every material
/// opaque: occlusion culling assumes opaque occluders). [`Culler::render`] draws with them,
/// and [`Culler::draws_like_renderer`] compares with them.
fn culled_options(opts: &RenderOptions) -> RenderOptions {
    RenderOptions {
        antialias: crate::Antialias::Off,
        wireframe: crate::Wireframe::Off,
        transparency: crate::Transparency::Ignore,
        ..*opts
    }
}

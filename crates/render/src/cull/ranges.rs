//! The frustum method's draw list: the clusters in the view frustum drawn as few, long
//! triangle ranges in scene order instead of one draw per cluster.
//!
//! Frustum culling removes triangles that are outside the view, and those are the cheapest
//! triangles of a brute-force frame: the geometry stage transforms their vertices and drops
//! them on a single outcode test, and they never reach binning or the tiles. One draw per
//! cluster (64–128 triangles) costs more than that: each draw transforms its own copy of
//! the cluster's boundary vertices, scans its indices for their span and maps every triangle
//! to its ID through a table. And the BVH's order of clusters is not the scene's: on the
//! street start it wrote a third more fragments than brute force's order.
//!
//! So the clusters in the frustum (in whatever order the BVH gives them) are marked in a
//! bitmap over the items and read back in item order, which is scene order: an instance's
//! items are a contiguous range, its clusters in meshlet order. Each run of consecutive
//! marked items of one instance becomes one range:
//!
//! * every cluster of the instance marked (the instance wholly in view, as most are): the
//!   instance's original mesh, whole, exactly the draw brute force makes of it, with the
//!   mesh's own shared vertices and IDs;
//! * otherwise the run's meshlets, whose triangles (and vertices) are contiguous because
//!   [`super::Meshlets`] lays clusters out one after another: one draw over the run.
//!
//! Draws then come in brute force's order, and the triangles that can be seen are the same
//! ones, so binning and the tiles do brute force's work on them; the frame costs the
//! geometry of the culled triangles less, in about as many draws as brute force makes or
//! fewer (an instance cut by the frustum can take a few). The image does not depend on
//! draw order (depth ties go to the smaller ID), so the ID buffer stays brute force's bit
//! for bit; the tests compare it.
//!
//! Other orders tried: front to back by instance (the BVH walked nearest child first, or
//! instances sorted by their box centres) writes fewer fragments (the boxfield 0.65 million
//! instead of 1.6; the street start 0.94 instead of 0.98), but frames were no faster, and on
//! the boxfield slower than brute force: sorting and reading the records out of order cost
//! more than the early depth rejects save. The BVH's own order, kept per cluster before,
//! was faster than brute force on the boxfield (whose scene order is random) but slower on
//! the street start.
//!
//! The same idea on GPUs: drawing a BVH node that is entirely inside the frustum as one
//! range of its subtree's clusters (Wihlidal, "Optimizing the Graphics Pipeline with
//! Compute", GDC 2016: cluster culling, then merging the survivors into few indirect
//! draws).

use glam::Affine3A;
use sightline_scene::{Mesh, Scene};
use sightline_spatial::Visible;

use super::{Clusters, CullStats};
use crate::DrawSource;

/// Items marked in a bitmap, read back as runs `(start, end)` of consecutive marked items in
/// increasing order.
struct Runs<'a> {
    bits: &'a [u64],
    /// The next item to look at.
    at: usize,
}

impl Iterator for Runs<'_> {
    type Item = (u32, u32);

    fn next(&mut self) -> Option<(u32, u32)> {
        // The first marked item at or after `at`, a word at a time.
        let mut w = self.at / 64;
        let mut word = *self.bits.get(w)? & (!0u64 << (self.at % 64));
        while word == 0 {
            w += 1;
            word = *self.bits.get(w)?;
        }
        let start = w * 64 + word.trailing_zeros() as usize;
        // The first unmarked item after it.
        let mut word = !self.bits[w] & (!0u64 << (start % 64));
        while word == 0 {
            w += 1;
            match self.bits.get(w) {
                Some(b) => word = !b,
                None => break,
            }
        }
        let end = if word == 0 { w * 64 } else { w * 64 + word.trailing_zeros() as usize };
        self.at = end;
        Some((start as u32, end as u32))
    }
}

impl Clusters {
    /// The draw sources of the frustum method for the items `visible` (any order, each at
    /// most once): runs of one instance's items in scene order, whole instances as their
    /// mesh (see the module header), counted into `cs`.
    pub(super) fn range_sources<'s>(
        &'s self,
        scene: &'s Scene,
        visible: &[Visible],
        cs: &mut CullStats,
    ) -> Vec<DrawSource<'s>> {
        let n = self.clustered.item_count();
        let mut bits = vec![0u64; n.div_ceil(64)];
        for v in visible {
            bits[v.index as usize / 64] |= 1 << (v.index % 64);
        }
        // At most one source per cluster.
        let mut sources: Vec<DrawSource> = Vec::with_capacity(visible.len());
        let mut mesh: Option<(u32, &Mesh)> = None;
        for (start, end) in (Runs { bits: &bits, at: 0 }) {
            // Split the run at instance boundaries.
            let mut a = start;
            while a < end {
                let whole = self.clustered.instance_items(self.clustered.item(a).instance);
                let b = end.min(whole.end);
                let complete = a == whole.start && b == whole.end;
                if !(complete && self.push_whole(scene, a..b, &mut mesh, &mut sources, cs)) {
                    self.push_meshlet_runs(a..b, &mut sources, cs);
                }
                a = b;
            }
        }
        sources
    }

    /// An instance whole, as its mesh, when `items` (all its clusters) hold exactly the
    /// mesh's triangles; false (nothing pushed) otherwise. Everything comes from the items'
    /// draw records, which the draw needs anyway (the instance records are twice the size
    /// and elsewhere in memory); `last` keeps the last mesh looked up.
    fn push_whole<'s>(
        &'s self,
        scene: &'s Scene,
        items: std::ops::Range<u32>,
        last: &mut Option<(u32, &'s Mesh)>,
        sources: &mut Vec<DrawSource<'s>>,
        cs: &mut CullStats,
    ) -> bool {
        let draws = &self.draws[items.start as usize..items.end as usize];
        let Some(d) = draws.first() else { return false };
        let mesh = match *last {
            Some((slot, m)) if slot == d.meshlets => m,
            _ => match scene.mesh(self.meshlets.mesh_id(d.meshlets)) {
                Some(m) => {
                    *last = Some((d.meshlets, m));
                    m
                }
                None => return false,
            },
        };
        let triangles: u64 = draws.iter().map(|d| d.count as u64).sum();
        let count = mesh.triangle_count() as u64;
        if triangles != count {
            return false;
        }
        sources.push(DrawSource {
            positions: mesh.positions(),
            indices: mesh.indices(),
            triangle_ids: None,
            world_from_local: Affine3A::from_cols_array(&d.world_from_local),
            first_triangle: d.first_triangle,
            first: 0,
            count: count as u32,
        });
        cs.clusters_drawn += draws.iter().filter(|d| d.count > 0).count() as u64;
        cs.triangles_drawn += count;
        true
    }

    /// The clusters `items` (of one instance, consecutive) as meshlet ranges: one per run of
    /// clusters whose triangles follow one another in the meshlets.
    fn push_meshlet_runs<'s>(
        &'s self,
        items: std::ops::Range<u32>,
        sources: &mut Vec<DrawSource<'s>>,
        cs: &mut CullStats,
    ) {
        let mut open: Option<DrawSource> = None;
        for d in &self.draws[items.start as usize..items.end as usize] {
            if d.count == 0 {
                continue;
            }
            cs.clusters_drawn += 1;
            cs.triangles_drawn += d.count as u64;
            if let Some(s) = open.as_mut().filter(|s| s.first + s.count == d.first) {
                s.count += d.count;
                continue;
            }
            sources.extend(open.replace(self.draw_source(d)));
        }
        sources.extend(open);
    }
}

#[cfg(test)]
pub(super) mod tests {
    use glam::Vec3;
    use sightline_scene::{shapes, Angle, Camera, LookAt, NodeDesc, Scene, Transform};

    use super::Runs;
    use crate::cull::{compare_ids, CullStats, Culler, Method};
    use crate::{Framebuffer, RenderOptions};

    /// The runs of a bitmap, item by item.
    fn slow_runs(marked: &[bool]) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < marked.len() {
            if marked[i] {
                let s = i;
                while i < marked.len() && marked[i] {
                    i += 1;
                }
                out.push((s as u32, i as u32));
            } else {
                i += 1;
            }
        }
        out
    }

    #[test]
    fn runs_match_an_item_by_item_scan() {
        // Runs across word boundaries, whole words, a last partial word, single items.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for n in [0usize, 1, 63, 64, 65, 200, 640] {
            for density in [0u64, 1, 4, 7, 8] {
                let marked: Vec<bool> = (0..n)
                    .map(|_| {
                        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                        (state >> 61) < density
                    })
                    .collect();
                let mut bits = vec![0u64; n.div_ceil(64)];
                for (i, _) in marked.iter().enumerate().filter(|m| *m.1) {
                    bits[i / 64] |= 1 << (i % 64);
                }
                let fast: Vec<_> = Runs { bits: &bits, at: 0 }.collect();
                assert_eq!(fast, slow_runs(&marked), "n {n}, density {density}/8");
            }
        }
    }

    /// A row of finely split boxes (many clusters each) with a plain cube (one cluster)
    /// between them, along x from 0 to 24.
    pub(in crate::cull) fn row() -> Scene {
        let mut scene = Scene::new();
        let fine =
            scene.add_mesh(shapes::subdivided_box("fine", Vec3::ZERO, Vec3::splat(2.0), [16, 16, 16], true).unwrap());
        let cube = scene.add_mesh(shapes::cube("cube").unwrap());
        for k in 0..7 {
            let mesh = if k % 3 == 1 { cube } else { fine };
            let at = Transform::from_translation(Vec3::new(4.0 * k as f32, 0.0, 0.0));
            scene.add_node(None, NodeDesc::new(format!("b{k}")).mesh(mesh).transform(at)).unwrap();
        }
        scene.update_transforms();
        scene
    }

    pub(in crate::cull) fn camera(eye: Vec3, target: Vec3, fovy: f32) -> Camera {
        let look = LookAt { eye, target, up: Vec3::Y, fovy: Angle::degrees(fovy), near: 0.1, far: 500.0 };
        Camera::perspective(&look, 1.5).unwrap()
    }

    /// Every triangle ID the sources draw, sorted (each must appear once).
    fn source_ids(sources: &[crate::DrawSource]) -> Vec<u32> {
        let mut ids: Vec<u32> = sources
            .iter()
            .flat_map(|s| {
                (s.first..s.first + s.count).map(|t| s.first_triangle + s.triangle_ids.map_or(t, |m| m[t as usize]))
            })
            .collect();
        ids.sort_unstable();
        ids
    }

    /// The frustum method's ranges for `cam`: exactly the triangles of the clusters in the
    /// frustum, each once, and the frame's IDs and depths brute force's. Returns the sources'
    /// (count, meshlet ranges spanning several clusters, whole meshes) and the clusters drawn.
    fn check(scene: &Scene, cam: &Camera) -> (usize, usize, usize, u64) {
        let mut culler = Culler::new(scene);
        let c = &mut culler.c;
        let mut cs = CullStats { clusters: c.clustered.item_count() as u64, ..Default::default() };
        c.frustum_cull(&sightline_spatial::Frustum::from_camera(cam), &mut cs);
        let visible = c.visible.clone();
        let sources = c.range_sources(scene, &visible, &mut cs);
        let mut want: Vec<u32> = visible
            .iter()
            .flat_map(|v| {
                let d = &c.draws[v.index as usize];
                let ml = c.meshlets.by_slot(d.meshlets);
                ml.triangle_ids[d.first as usize..(d.first + d.count) as usize].iter().map(|t| d.first_triangle + t)
            })
            .collect();
        want.sort_unstable();
        assert_eq!(source_ids(&sources), want);
        assert_eq!(cs.triangles_drawn, want.len() as u64);
        assert_eq!(cs.clusters_drawn, visible.len() as u64);
        // A meshlet range over several clusters is longer than any one of them.
        let longest = visible.iter().map(|v| c.draws[v.index as usize].count).max().unwrap_or(0);
        let merged = sources.iter().filter(|s| s.triangle_ids.is_some() && s.count > longest).count();
        let whole = sources.iter().filter(|s| s.triangle_ids.is_none()).count();
        let n = sources.len();
        let opts = RenderOptions::ids_only();
        let mut brute = Framebuffer::new(96, 64).unwrap();
        let mut fb = Framebuffer::new(96, 64).unwrap();
        culler.render(scene, cam, Method::Brute, &mut brute, &opts).unwrap();
        culler.render(scene, cam, Method::Frustum, &mut fb, &opts).unwrap();
        assert!(brute.ids.iter().any(|&i| i != 0), "the camera sees something");
        assert_eq!(compare_ids(&brute.ids, &fb.ids, 96), None);
        let bits = |f: &Framebuffer| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&brute), bits(&fb));
        (n, merged, whole, visible.len() as u64)
    }

    #[test]
    fn a_camera_seeing_the_whole_scene_draws_each_instance_as_its_mesh() {
        let scene = row();
        let (n, merged, whole, clusters) =
            check(&scene, &camera(Vec3::new(12.0, 20.0, 40.0), Vec3::new(12.0, 1.0, 1.0), 60.0));
        assert_eq!(clusters as usize, Culler::new(&scene).c.clustered.item_count(), "every cluster is in view");
        assert_eq!((n, whole, merged), (7, 7, 0), "one draw per instance, the mesh itself");
    }

    /// With the whole scene in view, the frustum method's frame is brute force's: the same
    /// counters (every cluster in the frustum and drawn), drawn the same way, with no walk
    /// of the tree (no culling time, no batch of clusters). With the scene cut by the
    /// frustum, it walks the tree and draws one batch.
    #[test]
    fn a_frustum_frame_seeing_everything_is_drawn_as_brute_force() {
        let scene = row();
        let opts = RenderOptions::ids_only();
        let mut culler = Culler::new(&scene);
        let mut frame = |cam: &Camera, m: Method| {
            let mut fb = Framebuffer::new(96, 64).unwrap();
            let (cs, fs) = culler.render(&scene, cam, m, &mut fb, &opts).unwrap();
            (cs, fs.triangles_in, fb.ids.iter().copied().collect::<Vec<u32>>())
        };
        let everything = camera(Vec3::new(12.0, 20.0, 40.0), Vec3::new(12.0, 1.0, 1.0), 60.0);
        let (brute, brute_in, brute_ids) = frame(&everything, Method::Brute);
        let (cs, triangles_in, ids) = frame(&everything, Method::Frustum);
        assert_eq!((ids, triangles_in), (brute_ids, brute_in));
        let counts = |c: &CullStats| (c.clusters_in_frustum, c.clusters_drawn, c.triangles_drawn, c.batches);
        assert_eq!(counts(&cs), counts(&brute));
        assert_eq!((cs.batches, cs.ms_cull), (0, 0.0), "no walk");
        let cut = camera(Vec3::new(11.0, 1.0, 4.0), Vec3::new(24.0, 1.0, 1.0), 40.0);
        let (cs, _, _) = frame(&cut, Method::Frustum);
        assert!(cs.clusters_in_frustum < brute.clusters_in_frustum && cs.batches == 1, "{cs:?}");
    }

    #[test]
    fn a_camera_cutting_the_scene_merges_the_runs_of_each_instance() {
        let scene = row();
        // Looking down the row from near its middle: the nearest boxes are cut by the
        // frustum's sides, the farther ones seen whole, the ones behind not at all.
        let (n, merged, whole, clusters) =
            check(&scene, &camera(Vec3::new(11.0, 1.0, 4.0), Vec3::new(24.0, 1.0, 1.0), 40.0));
        let all = Culler::new(&scene).c.clustered.item_count() as u64;
        assert!(clusters < all, "the frustum cuts the scene");
        assert!(merged > 0, "a partly seen instance's clusters merged into a range");
        assert!(whole > 0, "an instance seen whole drawn as its mesh");
        assert!((n as u64) < clusters, "{n} draws for {clusters} clusters");
    }

    #[test]
    fn frustum_frames_are_bit_identical_for_any_thread_count() {
        let scene = row();
        let cam = camera(Vec3::new(11.0, 1.0, 4.0), Vec3::new(24.0, 1.0, 1.0), 40.0);
        let frame = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut culler = Culler::new(&scene);
                let mut fb = Framebuffer::new(96, 64).unwrap();
                culler.render(&scene, &cam, Method::Frustum, &mut fb, &RenderOptions::default()).unwrap();
                let depth: Vec<u32> = fb.depth.iter().map(|d| d.to_bits()).collect();
                (fb.ids, depth, fb.color)
            })
        };
        let one = frame(1);
        assert!(one.0.iter().any(|&i| i != 0));
        assert_eq!(one, frame(2));
        assert_eq!(one, frame(3));
    }
}

//! How far is occlusion culling from ideal? Along the street path of the default city, each
//! frame is rendered three ways:
//!
//! - `brute`: every triangle;
//! - `hzb`: the culler's default occlusion culling (this and `brute` drawn through the
//!   `World` facade, as a program draws its frames);
//! - `oracle`: exactly the triangles visible in the brute-force frame, found from its ID
//!   buffer beforehand (not timed), drawn as a plain frame: what perfect culling at zero
//!   cost would draw.
//!
//! The oracle frame bounds every culling method from below: what it still costs (clearing
//! the tiles, rasterizing the visible pixels, writing depth and IDs out, shading) does not
//! depend on culling, so `brute / oracle` is the largest speed-up any culling can give this
//! renderer. Each oracle frame's ID buffer is checked to equal the brute-force one. It is
//! timed after an untimed draw of itself, so that its renderer's buffers are warm, as the
//! culler's are from frame to frame; so is every other reference frame below (timed on
//! their first draw, right after other frames, they read 3–10% longer: the clusters holding
//! a visible triangle in one session batch 2.40–2.44 against 2.20–2.23 ms, the oracle in a
//! session 2.24–2.30 against 2.16–2.17 ms; the compact oracle below, whose meshes are
//! made anew for each frame, 1.72 against 1.59 ms).
//!
//! The oracle draws its triangles as runs of their meshes, and a run's vertex transform
//! covers every vertex from its least index to its greatest: where the visible triangles lie
//! scattered over big meshes (the 10^9-triangle city's), that costs more per triangle than
//! `hzb`'s meshlet ranges, so there the oracle is no floor for the geometry stage. So the
//! same triangles are drawn once more as meshes of their own, each holding only the vertices
//! its triangles use (built beforehand, not timed; the same vertices under the same
//! matrices, in the same order, so the frame is the oracle's with other IDs, mapped back and
//! checked): the compact oracle. Its data lie together, as no frame drawn from the scene's
//! own meshes finds them (its face records, which shading reads, too), so it is a lower
//! floor, one that holds where the oracle's does not.
//!
//! A second bound is for culling whole clusters by their boxes and normal cones, as `hzb`
//! does: a cluster can be skipped only when all its triangles face away (its cone says so),
//! or when its box's screen rectangle, at the box's nearest depth, lies behind every pixel
//! of the finished depth buffer. The example counts the clusters (and their triangles) that
//! survive both tests against the final frame: no z-pyramid of this frame can skip them, so
//! no method culling these clusters this way draws fewer. Beside them: the clusters `hzb`
//! drew, and those holding a visible triangle (what perfect culling at cluster granularity
//! would draw). Both sets are also drawn as plain frames like the oracle (found beforehand,
//! not timed; each checked against the reference), and the clusters holding a visible
//! triangle once more into a frame session, in one batch, nearest box first, the way `hzb`
//! draws its first batch (`Culler::draw_clusters`: each cluster one range of its meshlets,
//! whose triangles lie together; the plain frames draw the original meshes' triangles, in
//! runs). A culler of whole clusters draws at least those, and draws into a session to keep
//! its z-pyramid, so that frame is a reference cost for such a culler here (no time spent
//! culling, the fewest clusters; one batch in one order, so not a proof that no other
//! batching or order costs less). Drawn from the original meshes instead, the clusters'
//! triangles are scattered (a cluster is a patch of its mesh, not a run of it): about 100,000
//! separate runs a frame at 10^9 triangles, 15.7 ms against 7.6 ms as meshlet ranges.
//! Every cluster holding a visible triangle must pass the box test: a run stops with an
//! error otherwise, since the box projector's margins are meant to bound the rounding of
//! projecting boxes and vertices (see `BoxProjector`).
//!
//! Culling methods draw their batches into a frame session, which keeps every tile's
//! z-pyramid levels up to date between batches (and bins and rasterizes against them),
//! where a plain frame only draws; both draw each tile in a scratch buffer per worker and
//! store it to the framebuffer at once. The oracle's triangles drawn once more in a
//! one-batch session show what the session costs by itself.
//!
//! The `hzb` frame's stages (cull, draw, shading; the draw split as the oracle's is) stand
//! beside the oracle's, and a tally says where the triangles `hzb` sends to setup end up:
//! covering no pixel centre, no area once snapped, facing away, outside the view, or
//! rasterized. Whole clusters far down the street are mostly triangles smaller than a pixel
//! (about 57% of those sent on the default city; 75% at 10^9 triangles), each costing a
//! transform and a setup for nothing drawn, which the oracle never sends.
//!
//! Last, the write-out floor: what writing every pixel's depth and ID (and color) once
//! costs on this machine, from cache, in whole rows over the pool. Any frame writes at
//! least that; the oracle's stages beside it show what rasterizing and shading add.
//!
//! `--triangles N` builds the city of about N triangles (10^3 to 10^9; default 10^6), as
//! `city:N` in the CLI. Brute force costs about 1 s per frame at 10^8 and 10 s at 10^9, so
//! `--no-brute` leaves it out: the visible triangles are then read from the `hzb` frame,
//! which the tests and `sightline walk --verify` check to equal brute force, and the oracle
//! frame is checked against that. Comparing the oracle across sizes tells how a culler's
//! frame time can grow with the scene when it draws only what is visible.
//!
//! Frames run on a rayon pool worker, as in the `sightline` CLI and the benchmarks (from
//! outside the pool every parallel stage would hand its work over and wait).
//!
//! ```text
//! cargo run --release --example culling_bound [-- FRAMES] [--triangles N] [--no-brute]
//! ```

#![forbid(unsafe_code)]

use std::collections::HashMap;
use std::time::Instant;

use rayon::prelude::*;
use sightline::render::{
    compare_ids, draw_all, shade_pass, Culler, DrawItem, FrameStats, Framebuffer, Method, RenderOptions, Renderer,
    Session, World,
};
use sightline::scene::builders::{city, CityParams};
use sightline::scene::{Aabb, Camera, Instance, Mesh, NodeDesc, Scene};
use sightline::spatial::{AabbExt, BoxImage, BoxProjector, ClusteredScene};

type Error = Box<dyn std::error::Error + Send + Sync>;

fn main() -> Result<(), Error> {
    rayon::ThreadPoolBuilder::new().build()?.install(run)
}

/// The command line.
#[derive(clap::Parser)]
#[command(about = "How far occlusion culling is from ideal, on the street path of the city")]
struct Args {
    /// Frames of the street path
    #[arg(default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Triangles of the city (as `city:N` in the CLI)
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1_000..=1_000_000_000))]
    triangles: u64,
    /// Leave brute force out (about 1 s a frame at 10^8, 10 s at 10^9): the visible
    /// triangles are then read from the `hzb` frame
    #[arg(long)]
    no_brute: bool,
}

fn run() -> Result<(), Error> {
    let Args { frames, triangles, no_brute } = <Args as clap::Parser>::parse();
    let (frames, with_brute) = (frames as usize, !no_brute);
    let c = city(&CityParams::for_triangles(triangles))?;
    let cams =
        c.layout.street_path(frames, 11).iter().map(|k| k.camera(1280.0 / 720.0)).collect::<Result<Vec<_>, _>>()?;
    let instances = c.scene.instances();
    let mut world = World::new(c.scene);
    world.prepare(Method::Hzb)?;
    // The clusters' world boxes, for the box-test bound.
    let boxes = {
        let culler = world.culler()?;
        culler.clustered().item_boxes(culler.instances())
    };
    let mut renderer = Renderer::new();
    let (mut reference, mut fb) = (Framebuffer::new(1280, 720)?, Framebuffer::new(1280, 720)?);
    let opts = RenderOptions::default();
    let mut runs: [Vec<f64>; 4] = Default::default();
    // Frames of whole clusters: [holding a visible triangle, no box or cone test skips,
    // holding a visible triangle drawn front to back in a session].
    let mut cluster_runs: [Vec<f64>; 3] = Default::default();
    let (mut visible, mut stages) = (Vec::new(), Vec::new());
    // The compact oracle: its times and stages.
    let (mut compact_runs, mut compact_stages) = (Vec::new(), Vec::new());
    // Per frame, of the hzb frame: its stages, and what setup made of its triangles.
    let (mut hzb_stages, mut hzb_setup) = (Vec::new(), Vec::new());
    // Per frame: [hzb drew, box test passes, holding a visible triangle], as (clusters, triangles).
    let mut clusters: Vec<[(u64, u64); 3]> = Vec::new();
    // The first round warms caches and buffers; the second is measured.
    for round in 0..2 {
        for (k, cam) in cams.iter().enumerate() {
            let mut brute = f64::NAN;
            if with_brute {
                let t = Instant::now();
                world.render(cam, Method::Brute, &mut reference, &opts)?;
                brute = ms(t);
            }
            // Without brute force, the hzb frame is the reference: drawn into it directly.
            let t = Instant::now();
            let report = world.render(cam, Method::Hzb, if with_brute { &mut fb } else { &mut reference }, &opts)?;
            let hzb = ms(t);
            let drew = report.cull.map_or((0, 0), |c| (c.clusters_drawn, c.triangles_drawn));
            let hzb_stage = report.cull.map_or([0.0; 3], |c| [c.ms_cull, c.ms_draw, c.ms_shading]);
            let hzb_raster = report.raster.unwrap_or_default();
            let items = visible_items(&reference.ids, &instances);
            // Timed after an untimed draw of itself (`warm`; the module docs say why).
            let (st, oracle) = warm(|| renderer.render(world.scene(), &instances, &items.0, cam, &mut fb, &opts))?;
            if let Some(m) = compare_ids(&reference.ids, &fb.ids, fb.width()) {
                let of = if with_brute { "brute force" } else { "the hzb frame" };
                return Err(format!("frame {k}: the oracle frame differs from {of}: {m:?}").into());
            }
            // The same triangles as meshes of their own, only their vertices: a plain frame
            // of the visible triangles alone (built beforehand, not timed).
            let compact = Compact::of(world.scene(), &instances, &items.0)?;
            let (compact_st, compact_ms) =
                warm(|| renderer.render(&compact.scene, &compact.instances, &compact.items, cam, &mut fb, &opts))?;
            if let Some(m) = compare_ids(&reference.ids, &compact.original_ids(&fb.ids), fb.width()) {
                return Err(format!("frame {k}: the compact oracle frame differs: {m:?}").into());
            }
            // The same triangles drawn in a frame session, as the culling methods draw
            // (timed after an untimed draw, as the oracle is).
            let scene = world.scene();
            let ((), in_session) = warm(|| {
                session_frame(&mut renderer, scene, &instances, cam, &mut fb, &opts, |s| {
                    s.draw(scene, &instances, &items.0, cam)
                })
            })?;
            if let Some(m) = compare_ids(&reference.ids, &fb.ids, fb.width()) {
                return Err(format!("frame {k}: the oracle drawn in a session differs: {m:?}").into());
            }
            // The two cluster bounds, drawn as plain frames like the oracle; `reference`
            // holds the final depth (a pixel's triangle gives it the same depth in any frame).
            let (draws, ordered, tallies) = {
                let culler = world.culler()?;
                let holding = holding_visible(&items.0, culler.clustered());
                let passing = box_test_bound(&boxes, culler, cam, &reference);
                let tally = |set: &[u32]| {
                    let tris = set.iter().map(|&i| culler.clustered().triangles(i).len() as u64).sum();
                    (set.len() as u64, tris)
                };
                let draw = |set: &[u32]| cluster_items(set, culler.clustered());
                // The box test is conservative (its margins bound the rounding of projecting
                // boxes and vertices), so every cluster holding a visible triangle passes it.
                if let Some(i) = holding.iter().find(|i| passing.binary_search(i).is_err()) {
                    return Err(
                        format!("frame {k}: cluster {i} holds a visible triangle and fails the box test").into()
                    );
                }
                let ordered = front_to_back(&holding, &boxes, cam);
                ([draw(&holding), draw(&passing)], ordered, [tally(&passing), tally(&holding)])
            };
            let mut cluster_ms = [0.0; 3];
            for (ms_k, draw) in cluster_ms.iter_mut().zip(&draws) {
                *ms_k = warm(|| renderer.render(world.scene(), &instances, draw, cam, &mut fb, &opts))?.1;
                if let Some(m) = compare_ids(&reference.ids, &fb.ids, fb.width()) {
                    return Err(
                        format!("frame {k}: a frame of whole clusters differs from the reference: {m:?}").into()
                    );
                }
            }
            // About the least a culler of whole clusters drawing into a session costs: the
            // clusters it must draw, in one batch, nearest first, drawn as `hzb` draws them.
            let (culler, scene) = world.culler_and_scene()?;
            cluster_ms[2] = warm(|| {
                session_frame(&mut renderer, scene, &instances, cam, &mut fb, &opts, |s| {
                    culler.draw_clusters(s, &ordered, cam)
                })
            })?
            .1;
            if let Some(m) = compare_ids(&reference.ids, &fb.ids, fb.width()) {
                return Err(format!("frame {k}: the clusters drawn in a session differ: {m:?}").into());
            }
            if round == 1 {
                for (run, v) in runs.iter_mut().zip([brute, hzb, oracle, in_session]) {
                    run.push(v);
                }
                for (run, v) in cluster_runs.iter_mut().zip(cluster_ms) {
                    run.push(v);
                }
                compact_runs.push(compact_ms);
                compact_stages.push(compact_st);
                visible.push(items.1 as f64);
                stages.push(st);
                hzb_stages.push(hzb_stage);
                hzb_setup.push(hzb_raster);
                clusters.push([drew, tallies[0], tallies[1]]);
            }
        }
    }
    let [brute, hzb, oracle, in_session] = runs.map(median);
    println!("city of {triangles} triangles, street path, {frames} frames at 1280×720, medians:");
    if with_brute {
        println!("  brute   {brute:6.2} ms");
        println!("  hzb     {hzb:6.2} ms  ({:.2}× brute)", brute / hzb);
        println!("  oracle  {oracle:6.2} ms  ({:.2}× brute), {:.0} visible triangles", brute / oracle, median(visible));
    } else {
        println!("  hzb     {hzb:6.2} ms  (brute force not run)");
        println!(
            "  oracle  {oracle:6.2} ms  ({:.2}× faster than hzb), {:.0} visible triangles",
            hzb / oracle,
            median(visible)
        );
    }
    let compact = median(compact_runs);
    println!(
        "  oracle, the visible triangles as meshes of their own (only their vertices) {compact:.2} ms ({:.2}× oracle, {:.2}× faster than hzb)",
        compact / oracle,
        hzb / compact
    );
    let count =
        |k: usize, tris: bool| median(clusters.iter().map(|c| if tris { c[k].1 } else { c[k].0 } as f64).collect());
    for (k, what) in ["hzb drew", "no box or cone test skips", "hold a visible triangle"].iter().enumerate() {
        println!("  clusters {what:<24} {:>8.0} ({:.0} triangles)", count(k, false), count(k, true));
    }
    println!(
        "  oracle drawn in a frame session (as culling draws: pyramid kept, tiles written through) {in_session:.2} ms ({:.2}× oracle)",
        in_session / oracle
    );
    let [holding, passing, holding_session] = cluster_runs.map(median);
    println!(
        "  frames of whole clusters: those holding a visible triangle {holding:.2} ms ({:.2}× oracle), those no box or cone test skips {passing:.2} ms ({:.2}× oracle)",
        holding / oracle,
        passing / oracle
    );
    println!(
        "  the clusters holding a visible triangle in one session batch, nearest first (a reference cost for a culler of whole clusters: one batch, nearest first) {holding_session:.2} ms ({:.2}× oracle)",
        holding_session / oracle
    );
    let [geometry, binning, raster, shading] = draw_stages(&stages);
    println!(
        "  oracle stages: geometry {geometry:.2}, binning {binning:.2}, raster and write-out {raster:.2}, shading {shading:.2} ms"
    );
    let [geometry, binning, raster, shading] = draw_stages(&compact_stages);
    println!(
        "  compact oracle stages: geometry {geometry:.2}, binning {binning:.2}, raster and write-out {raster:.2}, shading {shading:.2} ms"
    );
    let hzb_stage = |k: usize| median(hzb_stages.iter().map(|s: &[f64; 3]| s[k]).collect());
    let [geometry, binning, raster, _] = draw_stages(&hzb_setup);
    println!(
        "  hzb stages: cull {:.2}, draw {:.2} (geometry {geometry:.2}, binning {binning:.2}, raster and write-out {raster:.2}), shading {:.2} ms",
        hzb_stage(0),
        hzb_stage(1),
        hzb_stage(2)
    );
    // Summed over the frames: where the triangles an hzb frame sends to setup end up.
    let sum = |f: fn(&FrameStats) -> u64| hzb_setup.iter().map(f).sum::<u64>() as f64;
    let sent = sum(|s| s.triangles_in).max(1.0);
    let share = |f: fn(&FrameStats) -> u64| 100.0 * sum(f) / sent;
    println!(
        "  triangles hzb sends to setup: {:.0} a frame on average; {:.1}% cover no pixel centre, {:.1}% have no area once snapped, {:.1}% face away, {:.1}% outside the view, {:.1}% rasterized",
        sent / hzb_setup.len().max(1) as f64,
        share(|s| s.too_small),
        share(|s| s.degenerate),
        share(|s| s.backface_culled),
        share(|s| s.trivially_rejected),
        share(|s| s.rasterized)
    );
    let (ids_depth, all) = write_floor(&mut fb, 200);
    println!(
        "  write-out floor: depth and IDs {ids_depth:.2} ms, with colors {all:.2} ms (every pixel written once, from cache)"
    );
    Ok(())
}

/// Medians over frames of the renderer's stages: geometry, binning, raster and write-out,
/// shading (ms).
fn draw_stages(frames: &[FrameStats]) -> [f64; 4] {
    let stage = |f: fn(&FrameStats) -> f64| median(frames.iter().map(f).collect());
    [stage(|s| s.ms_geometry), stage(|s| s.ms_binning), stage(|s| s.ms_raster), stage(|s| s.ms_shading)]
}

/// What writing a frame out costs at least on this machine: every pixel's depth and ID
/// (and then its color too) written once into `fb`'s planes, copied from a buffer in cache,
/// in bands of 64 rows (the tile stage's rows) over the pool. Medians of `reps` writes, in
/// ms: (depth and IDs, all three). The planes stay in cache from one write to the next,
/// which a frame's do not (the renderer streams depth and IDs past the cache instead), so
/// this is a floor. An oracle frame writes the same bytes and rasterizes and shades besides.
fn write_floor(fb: &mut Framebuffer, reps: usize) -> (f64, f64) {
    let w = fb.width() as usize;
    let band = 64 * w;
    let src: Vec<u32> = (0..64).collect();
    let colors: Vec<[u8; 4]> = (0..64u8).map(|k| [k, k, k, 255]).collect();
    let depths: Vec<f32> = (0..64).map(|k| k as f32 / 64.0).collect();
    let mut run = |with_color: bool| {
        median(
            (0..reps)
                .map(|_| {
                    let t = Instant::now();
                    let planes = fb.depth.par_chunks_mut(band).zip(fb.ids.par_chunks_mut(band));
                    planes.zip(fb.color.par_chunks_mut(band)).for_each(|((depth, ids), color)| {
                        for ((d, i), c) in depth.chunks_mut(64).zip(ids.chunks_mut(64)).zip(color.chunks_mut(64)) {
                            let n = d.len();
                            d.copy_from_slice(&depths[..n]);
                            i.copy_from_slice(&src[..n]);
                            if with_color {
                                c.copy_from_slice(&colors[..n]);
                            }
                        }
                    });
                    ms(t)
                })
                .collect(),
        )
    };
    (run(false), run(true))
}

/// The triangles with an ID in `ids`, as draw items (runs of consecutive triangles of one
/// instance merged), and how many there are.
fn visible_items(ids: &[u32], instances: &[Instance]) -> (Vec<DrawItem>, usize) {
    let mut seen: Vec<u32> = ids.iter().copied().filter(|&i| i != 0).collect();
    seen.sort_unstable();
    seen.dedup();
    let tris = seen.iter().map(|&id| {
        // IDs are 1 + the instance's first triangle + the triangle within its mesh: the owner
        // is the first instance ending after triangle g (empty instances end where they begin).
        let g = id - 1;
        let k = instances.partition_point(|i| i.first_triangle + i.triangle_count <= g);
        (k as u32, g - instances[k].first_triangle)
    });
    (runs(tris), seen.len())
}

/// Sorted (instance, triangle) pairs as draw items: runs of consecutive triangles of one
/// instance merged.
fn runs(tris: impl IntoIterator<Item = (u32, u32)>) -> Vec<DrawItem> {
    let mut items: Vec<DrawItem> = Vec::new();
    for (instance, t) in tris {
        match items.last_mut() {
            Some(it) if it.instance == instance && it.first + it.count == t => it.count += 1,
            _ => items.push(DrawItem { instance, first: t, count: 1 }),
        }
    }
    items
}

/// The visible triangles as a scene of their own: per instance holding one, a mesh of
/// those triangles alone (only the vertices they use, in their order), drawn with the
/// instance's transform and material. Vertices go through the same matrices and triangles
/// keep their order, so the frame is the oracle's with other IDs ([`Compact::original_ids`]
/// maps them back); what drawing them costs is then not inflated by the vertex spans of
/// runs scattered over big meshes (each run of an original mesh transforms the vertices from
/// its least index to its greatest).
struct Compact {
    scene: Scene,
    instances: Vec<Instance>,
    items: Vec<DrawItem>,
    /// The original ID of compact triangle `k` (its ID minus one).
    original: Vec<u32>,
}

impl Compact {
    fn of(scene: &Scene, instances: &[Instance], items: &[DrawItem]) -> Result<Compact, Error> {
        let mut out = Scene::new();
        let mut original = Vec::new();
        // Each material in effect added once, as the scene holds it once.
        let mut materials = HashMap::new();
        let mut k = 0;
        while k < items.len() {
            let instance = items[k].instance;
            let inst = &instances[instance as usize];
            let mesh = scene.mesh(inst.mesh).ok_or("an instance's mesh is gone")?;
            // Old vertex index -> new one, for this instance's triangles.
            let mut place: HashMap<u32, u32> = HashMap::new();
            let (mut positions, mut normals, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            while k < items.len() && items[k].instance == instance {
                for t in items[k].first..items[k].first + items[k].count {
                    for &v in &mesh.indices()[3 * t as usize..3 * t as usize + 3] {
                        let next = positions.len() as u32;
                        let at = *place.entry(v).or_insert_with(|| {
                            positions.push(mesh.positions()[v as usize]);
                            if let Some(n) = mesh.normals() {
                                normals.push(n[v as usize]);
                            }
                            if let Some(u) = mesh.uvs() {
                                uvs.push(u[v as usize]);
                            }
                            next
                        });
                        indices.push(at);
                    }
                    original.push(inst.first_triangle + t + 1);
                }
                k += 1;
            }
            let normals = mesh.normals().is_some().then_some(normals);
            let uvs = mesh.uvs().is_some().then_some(uvs);
            let m = out.add_mesh(Mesh::new(mesh.name(), positions, normals, uvs, indices)?);
            let material = *materials
                .entry(inst.material)
                .or_insert_with(|| out.add_material(scene.instance_material(inst).clone()));
            out.add_node(None, NodeDesc::new("visible").mesh(m).material(material).matrix(inst.world_from_local))?;
        }
        out.update_transforms();
        // Face records are made on first use: here, not in the timed frame.
        for (_, m) in out.meshes() {
            m.faces();
        }
        let instances = out.instances();
        let items = draw_all(&instances);
        Ok(Compact { scene: out, instances, items, original })
    }

    /// `ids` (a frame of this scene) with the original IDs.
    fn original_ids(&self, ids: &[u32]) -> Vec<u32> {
        ids.iter().map(|&i| if i == 0 { 0 } else { self.original[i as usize - 1] }).collect()
    }
}

/// The clusters that face the eye by their normal cones and whose box passes the exact box
/// test against the finished depth buffer of `fb`: some pixel of the box's screen rectangle
/// is at least as far as the box's nearest depth (or the box crosses the near plane).
fn box_test_bound(boxes: &[Aabb], culler: &Culler, camera: &Camera, fb: &Framebuffer) -> Vec<u32> {
    let (w, h) = (fb.width(), fb.height());
    let projector = BoxProjector::for_camera(camera, w, h, culler.reach());
    let mut out = Vec::new();
    for (i, b) in boxes.iter().enumerate() {
        if culler.cluster_faces_away(i as u32, camera.view.eye) {
            continue;
        }
        let passes = match projector.classify(b) {
            BoxImage::Outside => false,
            BoxImage::CrossesNear => true,
            BoxImage::Rect(r) => (r.y0..r.y1.min(h)).any(|y| {
                let row = &fb.depth[(y * w) as usize..][..w as usize];
                row[r.x0 as usize..r.x1.min(w) as usize].iter().any(|&d| r.depth <= d)
            }),
        };
        if passes {
            out.push(i as u32);
        }
    }
    out
}

/// The clusters holding at least one of the visible triangles `items`.
fn holding_visible(items: &[DrawItem], clustered: &ClusteredScene) -> Vec<u32> {
    let mut by_instance: HashMap<u32, Vec<u32>> = HashMap::new();
    for it in items {
        by_instance.entry(it.instance).or_default().extend(it.first..it.first + it.count);
    }
    let mut out = Vec::new();
    for (&k, visible) in &mut by_instance {
        visible.sort_unstable();
        for i in clustered.instance_items(k) {
            if clustered.triangles(i).iter().any(|l| visible.binary_search(l).is_ok()) {
                out.push(i);
            }
        }
    }
    out
}

/// One frame drawn into a frame session by `draw` (in one batch), then shaded: what the
/// culling methods' frames cost besides culling and their later batches.
fn session_frame(
    renderer: &mut Renderer,
    scene: &Scene,
    instances: &[Instance],
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &RenderOptions,
    draw: impl FnOnce(&mut Session) -> sightline::render::Result<FrameStats>,
) -> Result<(), Error> {
    let mut session = renderer.begin(fb, opts);
    draw(&mut session)?;
    session.finish();
    shade_pass(scene, instances, camera, fb, &opts.shading, opts.background);
    Ok(())
}

/// The clusters `set`, nearest box first (by the distance from the eye, as `hzb` orders its
/// first batch).
fn front_to_back(set: &[u32], boxes: &[Aabb], camera: &Camera) -> Vec<u32> {
    let eye = camera.view.eye;
    let mut order = set.to_vec();
    // The key of `hzb`'s first batch (its `hzb_two_pass`): ties (boxes holding the eye) by
    // index, so every run draws alike.
    order.sort_unstable_by_key(|&i| (boxes[i as usize].distance_squared(eye).to_bits(), i));
    order
}

/// Every triangle of the clusters `set`, as draw items (runs of consecutive triangles of
/// one instance merged), in scene order as the oracle's.
fn cluster_items(set: &[u32], clustered: &ClusteredScene) -> Vec<DrawItem> {
    let mut tris: Vec<(u32, u32)> = set
        .iter()
        .flat_map(|&i| {
            let instance = clustered.item(i).instance;
            clustered.triangles(i).iter().map(move |&t| (instance, t))
        })
        .collect();
    tris.sort_unstable();
    runs(tris)
}

/// `draw` run twice, the second run timed: a reference frame drawn after an untimed draw of
/// itself, its renderer's buffers warm as the culler's are from frame to frame. Returns the
/// second run's result and milliseconds.
fn warm<T, E>(mut draw: impl FnMut() -> Result<T, E>) -> Result<(T, f64), Error>
where
    Error: From<E>,
{
    draw()?;
    let t = Instant::now();
    let r = draw()?;
    Ok((r, ms(t)))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

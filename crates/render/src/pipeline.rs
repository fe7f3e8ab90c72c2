//! The renderer: geometry → binning → parallel tile rasterization → deferred shading.
//!
//! The core primitive is [`Renderer::draw`]: draw a list of (instance, triangle range)
//! items, in the order given, into the depth and ID planes of a framebuffer, without
//! clearing it. [`Renderer::render`] draws a whole frame, shades it (deferred: only the
//! final visible pixel of each position is shaded, from its triangle ID), resolves
//! supersampling and draws the wireframe; it writes every plane, so the target needs no
//! clear. An occlusion culler draws batch after batch inside a frame [`Session`](crate::Session)
//! ([`Renderer::begin`]): the tiles then keep their part of the z-pyramid up to date,
//! each batch writes the tiles it drew through to the framebuffer, and
//! [`Session::finish`](crate::Session::finish) writes the tiles no batch touched as cleared.
//!
//! Stages and their parallelism (rayon; the image is bit-identical for any thread count):
//! 1. geometry over chunks of the draw list (contiguous, so submission order is kept);
//! 2. binning of each chunk's triangles to 64×64 tiles (in a session, a triangle behind a
//!    tile's pyramid is not sent to it), by the same task right after the chunk's setup;
//! 3. rasterization over tiles, each tile walking the chunks' lists in order, in a
//!    per-worker scratch buffer loaded from the framebuffer (or cleared) before and stored
//!    back right after (tiles own their pixels).
//!
//! All big buffers live in the `Renderer` and are reused from frame to frame.

use std::sync::atomic::Ordering;
use std::time::Instant;

use glam::Vec4;
use rayon::prelude::*;
use sightline_scene::{Camera, Instance, Scene};

use sightline_spatial::SimdLevel;

use crate::bin::bin_chunk;
use crate::claim::{for_each_claimed, Claim};
use crate::clip_matrix::clip_from_local;
use crate::depth::{with_codec, DepthCodec, DepthFormat};
use crate::geometry::{split, Chunk, DrawList, Item, Placed, Source};
use crate::hzb::{TileLevels, TilePyramid, UpperLevels};
use crate::options::{DrawItem, DrawSource, RenderOptions, Wireframe};
use crate::raster::{raster_tiles, Planes, TileBuf, TilePass};
use crate::setup::Viewport;
use crate::stats::{ms_since, FrameStats};
use crate::stream::written_through;
use crate::tiling::Grid;
use crate::{aa, deferred, wire, Error, Framebuffer, Result};

/// Triangles per chunk of the geometry and binning stages (at most four chunks per thread).
/// The occluder pass draws batches of a few thousand triangles: at 2048 most of them were
/// one chunk, set up on one worker; at 1024 the boxfield pass on two threads took 6.41 /
/// 6.52 / 6.32 ms against 6.84 / 6.82 / 6.88, and street frames of the default city the
/// same within noise.
const CHUNK_TRIANGLES: u64 = 1024;

/// Where the geometry stage bins its chunks: the screen's tiles, and whether they are a
/// frame session's (whose pyramid levels binning tests whole triangles against).
struct Binning<'a> {
    grid: &'a Grid,
    session: bool,
    /// The depth format's tie margin (for the session's coarse depth test).
    margin: f32,
}

/// A rasterizer with its reusable buffers. Create once, render many frames.
#[derive(Debug, Default)]
pub struct Renderer {
    chunks: Vec<Chunk>,
    work: Vec<Vec<crate::geometry::Piece>>,
    /// Each tile's record: its rectangle, z-pyramid levels and session state.
    levels: Vec<TileLevels>,
    /// The tile stage's scratch tiles, one per worker, kept between passes.
    scratch: Vec<TileBuf>,
    grid: Option<Grid>,
    ranges: Vec<(u32, u32, u32)>,
    supersampled: Option<Framebuffer>,
    /// During a session: z-pyramid levels from the tile grid (level 6, one texel per tile) up.
    upper: UpperLevels,
}

/// The start of a draw: refused when the depth format cannot resolve the camera's depth
/// range, its start time otherwise.
fn start_draw(camera: &Camera, opts: &RenderOptions) -> Result<Instant> {
    opts.depth_format.check_resolves(&camera.projection)?;
    Ok(Instant::now())
}

/// Where a draw goes.
pub(crate) enum Target<'a> {
    /// Straight into a framebuffer: tiles load its pixels (or, when `fresh`, start from the
    /// clear values because every pixel will be written) and store them back.
    Frame { fb: &'a mut Framebuffer, fresh: bool },
    /// Into an open [`Session`](crate::Session) on `fb` (its options give the depth format): tiles load from
    /// and store to `fb` as in a plain frame (cleared on first use), and keep their pyramid
    /// levels.
    Session { fb: &'a mut Framebuffer },
}

impl Renderer {
    /// A renderer with no buffers yet (they grow on first use).
    pub fn new() -> Self {
        Self::default()
    }

    /// Renders a frame into `fb`: draws `items` (instances from `instances`), shades,
    /// resolves antialiasing and draws the wireframe, as `opts` says. Masked and blended
    /// materials are drawn as [`RenderOptions::transparency`] says (by default alpha-tested,
    /// and by the A-buffer; see [`crate::transparency`]). Every plane is
    /// written, so `fb` needs no clear; after an error its contents are unspecified.
    pub fn render(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        crate::error::check_drawable(scene)?;
        let t0 = Instant::now();
        let s = opts.antialias.factor();
        let mut stats = if s == 1 {
            self.fill_frame(scene, instances, items, camera, fb, opts)?
        } else {
            // Supersampling: the same frame at s × s the size, then averaged down.
            let (w, h) = (fb.width() * s, fb.height() * s);
            let mut ss = match self.supersampled.take() {
                Some(f) if f.width() == w && f.height() == h => f,
                _ => Framebuffer::new(w, h)?,
            };
            if ss.depth_tests.is_some() != fb.depth_tests.is_some() {
                ss.count_depth_tests(fb.depth_tests.is_some());
            }
            let r = self.fill_frame(scene, instances, items, camera, &mut ss, opts).map(|mut st| {
                let t = Instant::now();
                aa::resolve(&ss, s, fb);
                st.ms_shading += ms_since(t);
                st
            });
            self.supersampled = Some(ss);
            r?
        };
        if opts.wireframe != Wireframe::Off {
            let t = Instant::now();
            wire::draw_wireframe(scene, instances, items, camera, fb, opts)?;
            stats.ms_wireframe = ms_since(t);
        }
        stats.update_overdraw();
        stats.ms_total = ms_since(t0);
        Ok(stats)
    }

    /// The filled part of a frame into `target`: a fresh draw of `items` (every depth and ID
    /// written, so no clear first) shaded, or, for a wireframe-only frame, a cleared target.
    fn fill_frame(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        target: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        if opts.wireframe == Wireframe::Only {
            target.clear(opts.background);
            return Ok(FrameStats::default());
        }
        // Both paths below start with `draw_items`, which refuses a depth range the format
        // cannot resolve.
        // Masked or blended materials: the transparency module's frame driver.
        if let Some(stats) = self.draw_with_transparency(scene, instances, items, camera, target, opts)? {
            return Ok(stats);
        }
        let mut stats =
            self.draw_items(scene, instances, items, camera, Target::Frame { fb: target, fresh: true }, opts)?;
        let t = Instant::now();
        deferred::shade_pass(scene, instances, camera, target, &opts.shading, opts.background);
        stats.ms_shading = ms_since(t);
        Ok(stats)
    }

    /// Draws `items` into the depth and ID planes of `target`, not shaded (a fresh frame
    /// target needs no clear first: every pixel is written); refused when the depth format
    /// cannot resolve the camera's depth range.
    pub(crate) fn draw_items(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        target: Target,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        let t0 = start_draw(camera, opts)?;
        let resolved = self.resolve_items(scene, instances, items, camera)?;
        Ok(self.run_since(&resolved[..], target, opts, t0))
    }

    /// Draws `items` into the depth and ID planes of `fb` (depth test LESS, exact ties to the
    /// smaller ID), in order, without clearing and without shading. Counters cover this call
    /// only (`covered_pixels` stays 0: only a fresh frame, [`Renderer::render`], counts them).
    pub fn draw(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        self.draw_items(scene, instances, items, camera, Target::Frame { fb, fresh: false }, opts)
    }

    /// The geometry sources of `items` (checked against the scene), with their triangle
    /// ranges in `self.ranges`.
    fn resolve_items<'s>(
        &mut self,
        scene: &'s Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
    ) -> Result<Vec<Item<'s>>> {
        let mut resolved: Vec<Item> = Vec::with_capacity(items.len());
        self.ranges.clear();
        let mut last: Option<(u32, glam::Mat4)> = None;
        let clip_from_world = camera.clip_from_world_f64();
        let simd = SimdLevel::Auto.resolve();
        for (k, d) in items.iter().enumerate() {
            let inst = instances.get(d.instance as usize).ok_or_else(|| {
                Error::InvalidDraw(format!("item {k} names instance {} of {}", d.instance, instances.len()))
            })?;
            let mesh = scene.try_mesh(inst.mesh)?;
            let n = mesh.triangle_count() as u64;
            if d.first as u64 + d.count as u64 > n {
                return Err(Error::InvalidDraw(format!(
                    "item {k}: triangles {}..{} of mesh '{}' with {n} triangles",
                    d.first,
                    d.first as u64 + d.count as u64,
                    mesh.name()
                )));
            }
            // Consecutive clusters of one instance share the matrix.
            let m = match last {
                Some((i, m)) if i == d.instance => m,
                _ => clip_from_local(&clip_from_world, &inst.world_from_local, simd),
            };
            last = Some((d.instance, m));
            resolved.push(Item {
                src: Source::Mesh {
                    positions: mesh.positions(),
                    indices: mesh.indices(),
                    clip_from_local: m,
                    ids: None,
                },
                first_id: inst.first_triangle.wrapping_add(1),
                source_triangles: n as u32,
            });
            self.ranges.push((k as u32, d.first, d.count));
        }
        Ok(resolved)
    }

    /// Draws triangle ranges of arbitrary indexed geometry (e.g. meshlets: clusters with
    /// their own vertex ranges), in order, into the depth and ID planes of `fb`, like
    /// [`Renderer::draw`]. Source `k`'s triangle `t` (of its `indices`) writes the ID
    /// `1 + first_triangle + triangle_ids[t]` (or `t` without a map).
    pub fn draw_sources(
        &mut self,
        sources: &[DrawSource],
        camera: &Camera,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        self.draw_sources_to(sources, camera, Target::Frame { fb, fresh: false }, opts, true)
    }

    /// [`Renderer::draw_sources`] into `target`; `check_indices = false` is for sources
    /// whose indices are in range by construction (the culler's meshlets): the per-index
    /// scan, a pass over every index of every draw, is then left out of release builds.
    /// (Should such an index be out of range after all, the draw reads stale vertex-cache
    /// entries or panics on a bounds check; it never reads outside memory.)
    pub(crate) fn draw_sources_to(
        &mut self,
        sources: &[DrawSource],
        camera: &Camera,
        target: Target,
        opts: &RenderOptions,
        check_indices: bool,
    ) -> Result<FrameStats> {
        let t0 = start_draw(camera, opts)?;
        self.ranges.clear();
        for (k, d) in sources.iter().enumerate() {
            let n = (d.indices.len() / 3) as u64;
            let bad = |why: String| Err(Error::InvalidDraw(format!("source {k}: {why}")));
            if d.first as u64 + d.count as u64 > n {
                return bad(format!("triangles {}..{} of {n}", d.first, d.first as u64 + d.count as u64));
            }
            if d.triangle_ids.is_some_and(|m| (m.len() as u64) < n) {
                return bad("the triangle ID map is shorter than the index list".into());
            }
            let range = &d.indices[3 * d.first as usize..3 * (d.first + d.count) as usize];
            // Trusted sources are still checked in debug and test builds.
            if (check_indices || cfg!(debug_assertions)) && range.iter().any(|&i| i as usize >= d.positions.len()) {
                return bad("an index is out of range".into());
            }
            self.ranges.push((k as u32, d.first, d.count));
        }
        // Each source's matrix is computed by the chunk that draws it, in parallel.
        let placed = Placed { sources, clip_from_world: camera.clip_from_world_f64(), simd: SimdLevel::Auto.resolve() };
        Ok(self.run_since(&placed, target, opts, t0))
    }

    /// Draws `list` into `target`, `ranges` giving each piece's (item, first triangle, count)
    /// in order: for lists whose items are valid by construction (the culler's clusters),
    /// which resolve them as the chunks reach them.
    pub(crate) fn draw_list_to<L: DrawList + ?Sized>(
        &mut self,
        list: &L,
        ranges: &[(u32, u32, u32)],
        camera: &Camera,
        target: Target,
        opts: &RenderOptions,
    ) -> Result<FrameStats> {
        let t0 = start_draw(camera, opts)?;
        self.ranges.clear();
        self.ranges.extend_from_slice(ranges);
        Ok(self.run_since(list, target, opts, t0))
    }

    /// The per-tile records, for tests that look at a session's tiles.
    #[cfg(test)]
    pub(crate) fn tile_levels(&self) -> &[TileLevels] {
        &self.levels
    }

    /// Prepares the tiles and pyramid of a session on a `width × height` target (see
    /// [`Renderer::begin`]).
    pub(crate) fn start_session(&mut self, width: u32, height: u32) {
        let grid = Grid::new(width, height);
        self.prepare_tiles(grid);
        for lv in &mut self.levels {
            lv.touched = false;
        }
        self.upper.clear(grid.tiles_x, grid.tiles_y);
    }

    /// Ends a session on `fb`: the tiles drawn into were written through as drawn, the
    /// others are written as cleared (depth 1, ID 0, no depth tests). Returns the pixels
    /// covered (ID ≠ 0).
    pub(crate) fn finish_session(&mut self, fb: &mut Framebuffer, format: DepthFormat) -> u64 {
        let Some(grid) = self.grid else { return 0 };
        with_codec!(format, clear_untouched::<_>(&self.levels, grid.tiles_x as usize, fb))
    }

    /// The z-pyramid of a session's frame drawn so far, with level 0 from `depth`, the
    /// session's framebuffer's depth plane.
    pub(crate) fn session_pyramid<'a>(&'a self, depth: &'a [f32], format: DepthFormat) -> Option<TilePyramid<'a>> {
        let grid = self.grid?;
        Some(TilePyramid::new((&self.levels, depth), grid.tiles_x, (grid.width, grid.height), &self.upper, format))
    }

    /// Draws raw clip-space triangles (no scene), triangle `k` with ID `first_id + k`: the
    /// lower-level entry for tests and tools. Non-finite input is dropped, never a panic.
    pub fn draw_clip_triangles(
        &mut self,
        triangles: &[[Vec4; 3]],
        first_id: u32,
        fb: &mut Framebuffer,
        opts: &RenderOptions,
    ) -> FrameStats {
        self.draw_clip_to(triangles, first_id, Target::Frame { fb, fresh: false }, opts)
    }

    /// [`Renderer::draw_clip_triangles`] into `target`.
    pub(crate) fn draw_clip_to(
        &mut self,
        triangles: &[[Vec4; 3]],
        first_id: u32,
        target: Target,
        opts: &RenderOptions,
    ) -> FrameStats {
        let t0 = Instant::now();
        let n = triangles.len().min(u32::MAX as usize) as u32;
        let items = [Item { src: Source::Clip(&triangles[..n as usize]), first_id, source_triangles: n }];
        self.ranges.clear();
        self.ranges.push((0, 0, n));
        self.run_since(&items[..], target, opts, t0)
    }

    /// [`Renderer::run`], its total time counted from `t0` (when the draw began).
    fn run_since<L: DrawList + ?Sized>(
        &mut self,
        items: &L,
        target: Target,
        opts: &RenderOptions,
        t0: Instant,
    ) -> FrameStats {
        let mut st = self.run(items, target, opts);
        st.ms_total = ms_since(t0);
        st
    }

    fn run<L: DrawList + ?Sized>(&mut self, items: &L, mut target: Target, opts: &RenderOptions) -> FrameStats {
        let mut st = FrameStats::default();
        let (width, height, session) = match &target {
            Target::Frame { fb, .. } => (fb.width(), fb.height(), false),
            Target::Session { fb } => (fb.width(), fb.height(), true),
        };
        let vp = Viewport::new(width, height, opts.guard_band);
        let grid = Grid::new(width, height);
        self.prepare_tiles(grid);

        // 1 and 2. Geometry, then binning, chunk by chunk: one parallel step, so that a
        // batch waits for its workers once less and a chunk's triangles are binned while
        // still in cache. Its time is split between the two stages in proportion to the
        // time the chunks spent in each.
        let t = Instant::now();
        let n = self.geometry(
            items,
            &vp,
            opts.backface_culling,
            Some(Binning { grid: &grid, session, margin: opts.depth_format.tie_margin() }),
        );
        let step = ms_since(t);
        let (geometry, binning) = self.chunks[..n].iter().fold((0.0, 0.0), |(g, b), c| (g + c.ms.0, b + c.ms.1));
        st.ms_binning = if binning > 0.0 { step * binning / (geometry + binning) } else { 0.0 };
        st.ms_geometry = step - st.ms_binning;

        // 3. Rasterization.
        let t = Instant::now();
        let chunks = &self.chunks[..n];
        let (fb, fresh) = match &mut target {
            Target::Frame { fb, fresh } => (&mut **fb, *fresh),
            Target::Session { fb } => (&mut **fb, false),
        };
        let counting = fb.depth_tests.is_some();
        let planes = Planes::new(fb);
        let pass = TilePass { chunks, target: &planes, fresh, counting, session };
        let ts = raster_tiles(&mut self.levels, &mut self.scratch, &pass, opts.depth_format, SimdLevel::Auto);
        if session {
            self.upper.update(&self.levels);
        } else {
            // The tile store counts only on a fresh draw, which writes every pixel (after a
            // plain batch the count would include earlier batches' pixels): 0 otherwise.
            st.covered_pixels = ts.covered;
        }
        st.ms_raster = ms_since(t);

        let mut multi_empty = 0;
        for c in chunks {
            st.add(&c.stats);
            multi_empty += c.multi.iter().filter(|f| !f.load(Ordering::Relaxed)).count() as u64;
        }
        let binned: u64 = chunks.iter().map(|c| c.tris.len() as u64).sum();
        let empty = ts.empty + multi_empty + chunks.iter().map(|c| c.hidden_at_binning).sum::<u64>();
        st.too_small += empty;
        st.rasterized = binned - empty;
        st.fragments_tested = ts.tested;
        st.fragments_written = ts.written;
        st.update_overdraw();
        st
    }

    /// The geometry stage over `items` (triangle ranges in `self.ranges`), in parallel over
    /// chunks of about equal triangle counts: the set-up triangles land in the first `n`
    /// chunks, in submission order; returns `n`. With `bin`, each chunk is binned right
    /// after its setup, by the same task. Each chunk records the milliseconds it spent in
    /// each stage.
    fn geometry<L: DrawList + ?Sized>(&mut self, items: &L, vp: &Viewport, cull: bool, bin: Option<Binning>) -> usize {
        let total: u64 = self.ranges.iter().map(|r| r.2 as u64).sum();
        let threads = rayon::current_num_threads().max(1);
        // One thread gains nothing from chunks: each costs a pass over the tiles' bins.
        let n = if threads == 1 { 1 } else { ((total / CHUNK_TRIANGLES) as usize).clamp(1, 4 * threads) };
        split(&self.ranges, n, &mut self.work);
        if self.chunks.len() < n {
            self.chunks.resize_with(n, Chunk::default);
        }
        let chunks = &mut self.chunks[..n];
        let levels = &self.levels[..];
        let l6 = self.upper.levels.first().map_or(&[][..], |l| &l.texels[..]);
        // Claimed chunk by chunk, as the chunks' costs differ with the memory they read; each
        // chunk first by the same worker from batch to batch, so that its buffers (vertex
        // cache, triangles, bins) stay in that core's cache.
        for_each_claimed(
            chunks.iter_mut().zip(&self.work),
            Claim::ByWorker,
            || (),
            |_, (c, w)| {
                let t = Instant::now();
                c.process(items, w, vp, cull);
                let geometry = ms_since(t);
                c.ms = (geometry, 0.0);
                if let Some(b) = &bin {
                    let t = Instant::now();
                    bin_chunk(c, b.grid, b.session.then_some((levels, l6, b.margin)));
                    c.ms.1 = ms_since(t);
                }
            },
        );
        n
    }

    /// Transforms, clips and sets up the triangles of `items` for a `width × height` target
    /// without rasterizing them: the chunks hold them in submission order (with their
    /// counters), for passes that walk the fragments themselves (transparency).
    pub(crate) fn set_up(
        &mut self,
        scene: &Scene,
        instances: &[Instance],
        items: &[DrawItem],
        camera: &Camera,
        (width, height): (u32, u32),
        opts: &RenderOptions,
    ) -> Result<&[Chunk]> {
        let resolved = self.resolve_items(scene, instances, items, camera)?;
        let vp = Viewport::new(width, height, opts.guard_band);
        let n = self.geometry(&resolved[..], &vp, opts.backface_culling, None);
        Ok(&self.chunks[..n])
    }

    fn prepare_tiles(&mut self, grid: Grid) {
        if self.grid == Some(grid) {
            return;
        }
        self.levels.clear();
        for k in 0..grid.len() {
            self.levels.push(TileLevels::new(grid.tile_rect(k)));
        }
        self.grid = Some(grid);
    }
}

/// Writes the tiles no batch of the session touched to `fb` as cleared (depth 1, ID 0, no
/// depth tests), one task per row of tiles, pixel row by pixel row (each plane written front
/// to back in runs the hardware's stream prefetch follows); returns the covered pixels of
/// the touched ones, counted when they were last written through.
fn clear_untouched<D: DepthCodec>(levels: &[TileLevels], tiles_x: usize, fb: &mut Framebuffer) -> u64 {
    let far = D::decode(D::FORMAT.key(1.0));
    let planes = Planes::new(fb);
    levels
        .par_chunks(tiles_x.max(1))
        .map(|band| {
            let covered: u64 = band.iter().filter(|l| l.touched).map(|l| l.covered).sum();
            if band.iter().any(|l| !l.touched) {
                for r in 0..band.first().map_or(0, |l| l.rect.h as usize) {
                    for l in band.iter().filter(|l| !l.touched) {
                        // SAFETY: this task is the only one on this row of tiles, whose
                        // rectangles no other task's tiles share.
                        unsafe { planes.clear_row(l.rect, r, far) };
                    }
                }
                written_through();
            }
            covered
        })
        .sum()
}

/// Renders every instance of `scene` (world transforms must be up to date) with a fresh
/// [`Renderer`]. For many frames keep a `Renderer` and call [`Renderer::render`].
pub fn render_scene(scene: &Scene, camera: &Camera, fb: &mut Framebuffer, opts: &RenderOptions) -> Result<FrameStats> {
    let instances = scene.instances();
    let items = crate::options::draw_all(&instances);
    Renderer::new().render(scene, &instances, &items, camera, fb, opts)
}

//! The geometry stage: transform each vertex once, classify triangles with outcodes, clip
//! the few that need it, set up the rest.
//!
//! Per draw piece the referenced vertex span is transformed by one `clip_from_local`
//! matrix (eight vertices at a time with AVX2), into flat, reused arrays (outcode, snapped
//! window position), so a vertex shared by six triangles is transformed and projected once;
//! the few triangles that need clipping recompute their clip positions. Each triangle then
//! costs three array reads, an AND and an OR of outcodes (Cohen–Sutherland's trivial
//! reject/accept), and setup. Only triangles crossing the near/far planes or the guard band
//! go through the homogeneous Sutherland–Hodgman clipper ([`crate::clip`]).
//!
//! The instruction set is chosen when the program runs ([`SimdLevel`]), once per chunk: the
//! whole stage (transform, classification, setup) is compiled twice from one
//! `#[inline(always)]` body, once plainly and once inside an AVX2 `#[target_feature]`
//! function, so that a build without `-C target-cpu` still runs the 256-bit transform.
//! The eight-wide transform and classification do the scalar path's IEEE operations in the
//! same order (no fused multiply-adds), so every level gives the same triangles bit for bit.
//! At the AVX-512 level the AVX2 code runs.

use glam::{Mat4, Vec3, Vec4};
use sightline_spatial::prefetch_all;
use sightline_spatial::simd::SimdLevel;

use crate::clip::{self, BAD, GUARD, VIEW_BITS};
use crate::forward::read_alone;
use crate::setup::{setup_into, Outcome, SnappedVertex, Tri, Viewport};
use crate::stats::FrameStats;
pub(crate) use list::{placed_item, DrawList, MeshData, Placed};

/// Where a draw piece's triangles come from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Source<'a> {
    /// An indexed mesh under one matrix; `ids`, when given, maps each triangle of `indices`
    /// to the triangle number its ID is made from (meshlets keep the original IDs).
    Mesh { positions: &'a [Vec3], indices: &'a [u32], clip_from_local: Mat4, ids: Option<&'a [u32]> },
    /// Raw clip-space triangles (tests and tools).
    Clip(&'a [[Vec4; 3]]),
}

/// One item of the draw list, resolved.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Item<'a> {
    pub src: Source<'a>,
    /// ID of the source's triangle 0 (IDs are `first_id + triangle index`).
    pub first_id: u32,
    /// Total triangles in the source (to know when a piece is the whole mesh).
    pub source_triangles: u32,
}

impl Item<'_> {
    /// The item's `clip_from_local` (none for raw clip-space triangles).
    #[inline(always)]
    fn matrix(&self) -> Option<&Mat4> {
        match &self.src {
            Source::Mesh { clip_from_local, .. } => Some(clip_from_local),
            Source::Clip(_) => None,
        }
    }
}

/// A contiguous triangle range of one item.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Piece {
    pub item: u32,
    pub start: u32,
    pub count: u32,
}

/// Reused per-vertex arrays (structure of arrays: eight vertices are classified and stored
/// at once).
#[derive(Debug, Default)]
struct VertexCache {
    code: Vec<u8>,
    /// Snapped window x, y (fixed point) and depth.
    sx: Vec<i32>,
    sy: Vec<i32>,
    sz: Vec<f32>,
}

impl VertexCache {
    /// Makes room for `n` vertices. Entries past the current piece's are stale and never
    /// read, so the arrays only grow (no refill per piece).
    fn resize(&mut self, n: usize) {
        if self.code.len() < n {
            self.code.resize(n, 0);
            self.sx.resize(n, 0);
            self.sy.resize(n, 0);
            self.sz.resize(n, 0.0);
        }
    }

    #[inline(always)]
    fn set(&mut self, i: usize, code: u8, s: SnappedVertex) {
        self.code[i] = code;
        (self.sx[i], self.sy[i], self.sz[i]) = (s.x, s.y, s.z);
    }
}

/// Output of the geometry stage for one chunk of the draw list.
#[derive(Debug, Default)]
pub(crate) struct Chunk {
    verts: VertexCache,
    /// Set-up triangles in submission order.
    pub tris: Vec<Tri>,
    /// Per tile: indices into `tris`.
    pub bins: Vec<Vec<u32>>,
    /// "Covered some pixel" flags of triangles spanning several tiles.
    pub multi: Vec<std::sync::atomic::AtomicBool>,
    /// Counters of this chunk.
    pub stats: FrameStats,
    /// Single-tile triangles that binning found hidden (set up, but never rasterized).
    pub hidden_at_binning: u64,
    /// Milliseconds this chunk spent in the geometry stage and in binning, last time.
    pub ms: (f64, f64),
    /// The instruction set the stage runs on, resolved at each [`Chunk::process`] (`Auto`,
    /// the default: the best available). Every level gives the same output bit for bit.
    pub simd: SimdLevel,
}

const NONE: SnappedVertex = SnappedVertex { x: 0, y: 0, z: 0.0 };

impl Chunk {
    /// Runs the geometry stage over `pieces`, on the instruction set [`Chunk::simd`]
    /// resolves to (one branch here; none per vertex or triangle).
    #[inline(never)] // a stage of its own in profiles
    pub fn process<L: DrawList + ?Sized>(&mut self, items: &L, pieces: &[Piece], vp: &Viewport, cull: bool) {
        match self.simd.resolve() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `SimdLevel::resolve` gives AVX2 or AVX-512 only when the CPU has every
            // feature of `simd::AVX2_FEATURES`, the features `process_avx2` enables.
            SimdLevel::Avx2 | SimdLevel::Avx512 => unsafe { process_avx2(self, items, pieces, vp, cull) },
            _ => self.process_with(items, pieces, vp, cull, transform_portable),
        }
    }

    /// The stage, with `transform` filling the vertex cache for a span of positions; inlined
    /// into each instruction set's entry point.
    #[inline(always)]
    fn process_with<L: DrawList + ?Sized>(
        &mut self,
        items: &L,
        pieces: &[Piece],
        vp: &Viewport,
        cull: bool,
        transform: impl Fn(&mut VertexCache, &[Vec3], &Mat4, &Viewport),
    ) {
        self.tris.clear();
        self.stats = FrameStats::default();
        // The last piece's item and matrix: consecutive items often share the matrix (the
        // clusters of one instance), which a list that computes matrices then reuses.
        let (mut prev, mut prev_m) = (None, Mat4::IDENTITY);
        for (n, p) in pieces.iter().enumerate() {
            // Pieces are often small clusters scattered over memory: ask for the record an
            // item is made from (where the list has one) six pieces ahead, the indices
            // and IDs two pieces ahead, and for the vertices of the next one (whose indices
            // were asked for one piece earlier), unless that piece draws what this one does
            // (instances of one cluster, as in the boxfield: 0.6–1.2% of its occluder pass).
            if let Some(a) = pieces.get(n + RECORD_AHEAD) {
                items.prefetch_record(a.item as usize);
            }
            if let Some(a) = pieces.get(n + 2).filter(|a| !same_data(items, a, p)) {
                prefetch_indices(items, a);
            }
            if let Some(a) = pieces.get(n + 1).filter(|a| !same_data(items, a, p)) {
                prefetch_vertices(items, a);
            }
            let k = p.item as usize;
            let item = items.item(k, prev.map(|j| (j, &prev_m)));
            // The matrix was just stored into the item column by column; copied column by
            // column (`read_alone`), not in the compiler's 256-bit halves, so that the loads
            // do not wait for the stores (geometry in the boxfield's occluder pass 3.47–3.78
            // → 3.25–3.46 ms on one thread).
            prev = item.matrix().map(|m| {
                prev_m = Mat4::from_cols(
                    read_alone(&m.x_axis),
                    read_alone(&m.y_axis),
                    read_alone(&m.z_axis),
                    read_alone(&m.w_axis),
                );
                k
            });
            self.stats.triangles_in += p.count as u64;
            match item.src {
                Source::Mesh { positions, indices, ref clip_from_local, ids } => {
                    let idx = &indices[3 * p.start as usize..3 * (p.start + p.count) as usize];
                    let (lo, hi) = if p.count == item.source_triangles {
                        (0, positions.len())
                    } else {
                        let lo = idx.iter().copied().min().unwrap_or(0) as usize;
                        let hi = idx.iter().copied().max().map_or(0, |m| m as usize + 1);
                        (lo, hi)
                    };
                    let span = &positions[lo..hi];
                    transform(&mut self.verts, span, clip_from_local, vp);
                    let corners =
                        idx.chunks_exact(3).map(|t| [t[0] as usize - lo, t[1] as usize - lo, t[2] as usize - lo]);
                    // The clipper's input, recomputed for the few triangles that need it
                    // (the same product as the transform's, so the same bits).
                    let clip = |i: usize| *clip_from_local * span[i].extend(1.0);
                    // Two loops rather than a test per triangle of whether IDs are mapped.
                    match ids {
                        Some(m) => {
                            let m = &m[p.start as usize..(p.start + p.count) as usize];
                            self.triangles(corners, |k| item.first_id.wrapping_add(m[k]), vp, cull, clip);
                        }
                        None => {
                            let first_id = item.first_id.wrapping_add(p.start);
                            self.triangles(corners, |k| first_id.wrapping_add(k as u32), vp, cull, clip);
                        }
                    }
                }
                Source::Clip(tris) => {
                    let tris = &tris[p.start as usize..(p.start + p.count) as usize];
                    self.load_clip(tris, vp);
                    let first_id = item.first_id.wrapping_add(p.start);
                    let corners = (0..tris.len()).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]);
                    let clip = |i: usize| tris[i / 3][i % 3];
                    self.triangles(corners, |k| first_id.wrapping_add(k as u32), vp, cull, clip);
                }
            }
        }
    }

    fn load_clip(&mut self, tris: &[[Vec4; 3]], vp: &Viewport) {
        let vc = &mut self.verts;
        vc.resize(3 * tris.len());
        for (i, c) in tris.iter().flatten().enumerate() {
            let (code, s) = Self::classify(*c, vp);
            vc.set(i, code, s);
        }
    }

    /// Outcode and (inside the guard band) the snapped window position of a vertex.
    #[inline(always)]
    fn classify(c: Vec4, vp: &Viewport) -> (u8, SnappedVertex) {
        let code = vp.outcode(c);
        if code & GUARD != 0 {
            return (code, NONE);
        }
        match vp.project(c) {
            Some(s) => (code, s),
            None => (code | GUARD, NONE),
        }
    }

    /// The triangles whose vertex-cache indices `corners` gives; `id(k)` is triangle `k`'s
    /// ID and `clip(i)` vertex `i`'s clip-space position for the clipper.
    #[inline(always)]
    fn triangles(
        &mut self,
        corners: impl Iterator<Item = [usize; 3]>,
        id: impl Fn(usize) -> u32,
        vp: &Viewport,
        cull: bool,
        clip: impl Fn(usize) -> Vec4,
    ) {
        let Chunk { verts, tris, stats, .. } = self;
        // The four arrays sliced to one length, so that each vertex index is checked once;
        // held in locals, which the output's pushes cannot change.
        let n = verts.code.len();
        let (code, sx, sy, sz) = (&verts.code[..n], &verts.sx[..n], &verts.sy[..n], &verts.sz[..n]);
        let mut tally = Tally::default();
        for (k, v) in corners.enumerate() {
            let c = [code[v[0]], code[v[1]], code[v[2]]];
            let and = c[0] & c[1] & c[2];
            let or = c[0] | c[1] | c[2];
            if and & VIEW_BITS != 0 || or & BAD != 0 {
                tally.rejected += 1;
                continue;
            }
            if or & GUARD != 0 {
                clipped([clip(v[0]), clip(v[1]), clip(v[2])], id(k), vp, cull, tris, stats);
                continue;
            }
            let s = v.map(|i| SnappedVertex { x: sx[i], y: sy[i], z: sz[i] });
            tally.count(setup_into(s, id(k), cull, vp, tris));
        }
        tally.add_to(stats);
    }
}

/// What the triangle loop counts, in locals added to the chunk's [`FrameStats`] once per
/// piece (counters in the chunk would be memory that each output push may change).
#[derive(Default)]
struct Tally {
    rejected: u64,
    backface: u64,
    degenerate: u64,
    too_small: u64,
}

impl Tally {
    #[inline(always)]
    fn count(&mut self, o: Outcome) {
        match o {
            Outcome::Ready => {}
            Outcome::BackFace => self.backface += 1,
            Outcome::Degenerate => self.degenerate += 1,
            Outcome::TooSmall => self.too_small += 1,
        }
    }

    fn add_to(&self, st: &mut FrameStats) {
        st.trivially_rejected += self.rejected;
        st.backface_culled += self.backface;
        st.degenerate += self.degenerate;
        st.too_small += self.too_small;
    }
}

/// A triangle crossing the near/far planes or the guard band: facing from its clip-space
/// corners `c`, then the homogeneous clipper and setup of the fan it leaves.
#[cold]
fn clipped(c: [Vec4; 3], id: u32, vp: &Viewport, cull: bool, tris: &mut Vec<Tri>, stats: &mut FrameStats) {
    // Facing from the homogeneous determinant: valid before clipping, whatever the w's.
    let det = clip::facing_det(c);
    if !det.is_finite() {
        stats.trivially_rejected += 1;
        return;
    }
    if det == 0.0 {
        stats.degenerate += 1;
        return;
    }
    if cull && det < 0.0 {
        stats.backface_culled += 1;
        return;
    }
    stats.clipped += 1;
    let poly = clip::clip_triangle(c, vp.gx, vp.gy);
    if poly.len() < 3 {
        return;
    }
    let mut s = [NONE; clip::MAX_POLYGON];
    for (o, cv) in s.iter_mut().zip(poly.vertices()) {
        // w > 0 after near/far clipping, except for degenerate input (w = 0 points).
        match (cv.pos.w > 0.0).then(|| vp.project(cv.pos)).flatten() {
            Some(p) => *o = p,
            None => return,
        }
    }
    let mut tally = Tally::default();
    for i in 1..poly.len() - 1 {
        stats.clip_output += 1;
        // Facing was decided above; each fan piece is oriented by its own area.
        tally.count(setup_into([s[0], s[i], s[i + 1]], id, false, vp, tris));
    }
    tally.add_to(stats);
}

/// Triangles of a piece whose data [`prefetch_indices`] and [`prefetch_vertices`] ask for:
/// enough for a cluster (about 1 KB of indices); past that, a long piece's sequential
/// reads are the hardware prefetcher's to follow, and asking for all of a whole mesh would
/// only evict what is in use.
const PREFETCH_TRIANGLES: usize = 96;

/// How many pieces ahead the stage asks for the record an item is made from.
const RECORD_AHEAD: usize = 6;

/// What the prefetches of a piece read: its mesh's positions, and its first
/// [`PREFETCH_TRIANGLES`] triangles' indices and IDs (empty without IDs).
struct PieceHead<'a> {
    positions: &'a [Vec3],
    indices: &'a [u32],
    ids: &'a [u32],
}

/// True when pieces `a` and `b` draw the same triangles of the same mesh (instances of
/// one cluster), whose data the one being drawn has just brought into the cache.
#[inline(always)]
fn same_data<L: DrawList + ?Sized>(items: &L, a: &Piece, b: &Piece) -> bool {
    match (items.mesh(a.item as usize), items.mesh(b.item as usize)) {
        (Some(x), Some(y)) => a.start == b.start && std::ptr::eq(x.indices.as_ptr(), y.indices.as_ptr()),
        _ => false,
    }
}

/// The [`PieceHead`] of piece `p`, when it draws from a mesh.
#[inline(always)]
fn piece_head<'a, L: DrawList + ?Sized>(items: &'a L, p: &Piece) -> Option<PieceHead<'a>> {
    let MeshData { positions, indices, ids } = items.mesh(p.item as usize)?;
    let (s, c) = (p.start as usize, (p.count as usize).min(PREFETCH_TRIANGLES));
    let ids = ids.and_then(|m| m.get(s..s + c)).unwrap_or(&[]);
    Some(PieceHead { positions, indices: indices.get(3 * s..3 * (s + c))?, ids })
}

/// Asks for the indices and triangle IDs of piece `p`.
#[inline(always)]
fn prefetch_indices<L: DrawList + ?Sized>(items: &L, p: &Piece) {
    if let Some(h) = piece_head(items, p) {
        prefetch_all(h.indices);
        prefetch_all(h.ids);
    }
}

/// Asks for the first vertices of piece `p`: from its first index on, as many as it has
/// triangles (a meshlet numbers its vertices in order of first use, so they start there).
#[inline(always)]
fn prefetch_vertices<L: DrawList + ?Sized>(items: &L, p: &Piece) {
    if let Some(h) = piece_head(items, p) {
        if let Some(&lo) = h.indices.first() {
            let lo = lo as usize;
            prefetch_all(h.positions.get(lo..(lo + h.indices.len() / 3).min(h.positions.len())).unwrap_or(&[]));
        }
    }
}

/// Fills `vc` for `positions` under `m`, one vertex at a time.
#[inline(never)] // per-vertex work, separate in profiles
fn transform_portable(vc: &mut VertexCache, positions: &[Vec3], m: &Mat4, vp: &Viewport) {
    vc.resize(positions.len());
    transform_tail(vc, positions, m, vp, 0);
}

/// Vertices `from..` of `positions`, one at a time.
#[inline(always)]
fn transform_tail(vc: &mut VertexCache, positions: &[Vec3], m: &Mat4, vp: &Viewport, from: usize) {
    for (k, p) in positions[from..].iter().enumerate() {
        let (code, s) = Chunk::classify(*m * p.extend(1.0), vp);
        vc.set(from + k, code, s);
    }
}

/// [`Chunk::process`] with AVX2. It and the kernels below are `#[target_feature]` functions
/// with the features of [`sightline_spatial::simd::AVX2_FEATURES`] (closures inside inherit
/// them), so that the 256-bit code is compiled whatever the build's target CPU. They may be
/// called from code with these features, elsewhere only once [`SimdLevel::resolve`] has
/// given AVX2 or AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn process_avx2<L: DrawList + ?Sized>(chunk: &mut Chunk, items: &L, pieces: &[Piece], vp: &Viewport, cull: bool) {
    chunk.process_with(items, pieces, vp, cull, |vc, positions, m, vp| transform_avx2(vc, positions, m, vp));
}

/// [`transform_portable`] with AVX2: eight vertices at a time, then the rest one by one.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline(never)] // per-vertex work, separate in profiles
fn transform_avx2(vc: &mut VertexCache, positions: &[Vec3], m: &Mat4, vp: &Viewport) {
    vc.resize(positions.len());
    let n8 = positions.len() / 8 * 8;
    for g in (0..n8).step_by(8) {
        let [x, y, z, w] = transform8(&positions[g..g + 8], m);
        classify8([x, y, z, w], vp, vc, g);
    }
    transform_tail(vc, positions, m, vp, n8);
}

/// `m · (p, 1)` for eight positions at once with AVX2, as x, y, z and w vectors: the
/// three-component rows are transposed with Intel's AoS-to-SoA shuffles, and each component
/// is summed in glam's order (`((m0·x + m1·y) + m2·z) + m3`, no fused multiply-add), so the
/// results equal `Mat4 * Vec4` bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn transform8(p: &[Vec3], m: &Mat4) -> [std::arch::x86_64::__m256; 4] {
    use std::arch::x86_64::*;
    assert!(p.len() >= 8);
    // SAFETY: the function's features include AVX2, so the intrinsics may run; the six
    // 16-byte loads read floats 0..24 of eight packed Vec3 (96 bytes, asserted length).
    unsafe {
        let f = p.as_ptr() as *const f32;
        let half = |i: usize| _mm_loadu_ps(f.add(4 * i));
        let m03 = _mm256_insertf128_ps(_mm256_castps128_ps256(half(0)), half(3), 1); // x0y0z0x1 x4y4z4x5
        let m14 = _mm256_insertf128_ps(_mm256_castps128_ps256(half(1)), half(4), 1); // y1z1x2y2 y5z5x6y6
        let m25 = _mm256_insertf128_ps(_mm256_castps128_ps256(half(2)), half(5), 1); // z2x3y3z3 z6x7y7z7
        let xy = _mm256_shuffle_ps::<0b10_01_11_10>(m14, m25); // x2y2x3y3
        let yz = _mm256_shuffle_ps::<0b01_00_10_01>(m03, m14); // y0z0y1z1
        let x = _mm256_shuffle_ps::<0b10_00_11_00>(m03, xy);
        let y = _mm256_shuffle_ps::<0b11_01_10_00>(yz, xy);
        let z = _mm256_shuffle_ps::<0b11_00_11_01>(yz, m25);
        let c = m.to_cols_array_2d();
        // Called here, not through `std::array::from_fn`, whose generic body is compiled
        // without this function's target features.
        let row = |j: usize| {
            let s = |k: usize| _mm256_set1_ps(c[k][j]);
            let r = _mm256_add_ps(_mm256_mul_ps(s(0), x), _mm256_mul_ps(s(1), y));
            _mm256_add_ps(_mm256_add_ps(r, _mm256_mul_ps(s(2), z)), s(3))
        };
        [row(0), row(1), row(2), row(3)]
    }
}

/// [`Chunk::classify`] for eight vertices at once with AVX2 (clip x, y, z, w vectors),
/// stored at `at..at + 8` of `vc`: the same operations in the same order (IEEE division,
/// multiply then add, round-to-nearest-even conversion), so the same codes and snapped
/// positions bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn classify8([x, y, z, w]: [std::arch::x86_64::__m256; 4], vp: &Viewport, vc: &mut VertexCache, at: usize) {
    use crate::clip::{BOTTOM, FAR, LEFT, NEAR, RIGHT, TOP};
    use std::arch::x86_64::*;
    let (hw, hh, h_fixed) = vp.scale();
    let (code, sx, sy, sz) =
        (&mut vc.code[at..at + 8], &mut vc.sx[at..at + 8], &mut vc.sy[at..at + 8], &mut vc.sz[at..at + 8]);
    // SAFETY: the function's features include AVX2, so the intrinsics may run; stores write
    // eight elements of slices of length eight (bounds-checked just above).
    unsafe {
        let zero = _mm256_setzero_ps();
        let sign = _mm256_set1_ps(-0.0);
        let finite = |v: __m256| _mm256_cmp_ps(_mm256_sub_ps(v, v), zero, _CMP_EQ_OQ);
        let ok = _mm256_and_ps(_mm256_and_ps(finite(x), finite(y)), _mm256_and_ps(finite(z), finite(w)));
        let nw = _mm256_xor_ps(w, sign);
        let bit = |m: __m256, b: u8| _mm256_and_si256(_mm256_castps_si256(m), _mm256_set1_epi32(b as i32));
        let near = _mm256_cmp_ps(z, nw, _CMP_LT_OQ);
        let far = _mm256_cmp_ps(z, w, _CMP_GT_OQ);
        let mut codes = _mm256_or_si256(
            _mm256_or_si256(bit(_mm256_cmp_ps(x, nw, _CMP_LT_OQ), LEFT), bit(_mm256_cmp_ps(x, w, _CMP_GT_OQ), RIGHT)),
            _mm256_or_si256(bit(_mm256_cmp_ps(y, nw, _CMP_LT_OQ), BOTTOM), bit(_mm256_cmp_ps(y, w, _CMP_GT_OQ), TOP)),
        );
        codes = _mm256_or_si256(codes, _mm256_or_si256(bit(near, NEAR), bit(far, FAR)));
        let gx = _mm256_mul_ps(_mm256_set1_ps(vp.gx), w);
        let gy = _mm256_mul_ps(_mm256_set1_ps(vp.gy), w);
        let guard = _mm256_or_ps(
            _mm256_or_ps(
                _mm256_cmp_ps(_mm256_andnot_ps(sign, x), gx, _CMP_GT_OQ),
                _mm256_cmp_ps(_mm256_andnot_ps(sign, y), gy, _CMP_GT_OQ),
            ),
            _mm256_or_ps(_mm256_cmp_ps(w, zero, _CMP_LE_OQ), _mm256_or_ps(near, far)),
        );
        // Divide and viewport transform, in the order of `Viewport::project`.
        let inv = _mm256_div_ps(_mm256_set1_ps(1.0), w);
        let (vhw, vhh, half) = (_mm256_set1_ps(hw), _mm256_set1_ps(hh), _mm256_set1_ps(0.5));
        let xw = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(x, inv), vhw), vhw);
        let yw = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(y, inv), vhh), vhh);
        let zw = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(z, inv), half), half);
        let lim = _mm256_set1_ps(crate::setup::PROJECT_LIMIT);
        let in_range = _mm256_and_ps(
            _mm256_and_ps(
                _mm256_cmp_ps(_mm256_andnot_ps(sign, xw), lim, _CMP_LE_OQ),
                _mm256_cmp_ps(_mm256_andnot_ps(sign, yw), lim, _CMP_LE_OQ),
            ),
            finite(zw),
        );
        // Projection failures count as outside the guard band.
        let guard = _mm256_or_ps(guard, _mm256_andnot_ps(in_range, _mm256_set1_ps(f32::from_bits(!0))));
        codes = _mm256_or_si256(codes, bit(guard, GUARD));
        // Non-finite input: exactly BAD | GUARD, as `clip::outcode`.
        let bad = _mm256_castps_si256(ok);
        codes = _mm256_or_si256(
            _mm256_and_si256(bad, codes),
            _mm256_andnot_si256(bad, _mm256_set1_epi32((BAD | GUARD) as i32)),
        );
        let keep = _mm256_castps_si256(_mm256_andnot_ps(guard, ok));
        let one = _mm256_set1_ps(crate::setup::ONE as f32);
        let sx_v = _mm256_cvtps_epi32(_mm256_mul_ps(xw, one));
        let sy_v = _mm256_sub_epi32(_mm256_set1_epi32(h_fixed), _mm256_cvtps_epi32(_mm256_mul_ps(yw, one)));
        _mm256_storeu_si256(sx.as_mut_ptr() as *mut __m256i, _mm256_and_si256(keep, sx_v));
        _mm256_storeu_si256(sy.as_mut_ptr() as *mut __m256i, _mm256_and_si256(keep, sy_v));
        _mm256_storeu_ps(sz.as_mut_ptr(), _mm256_and_ps(_mm256_castsi256_ps(keep), zw));
        // Codes fit a byte: pack the eight i32 lanes to eight bytes.
        let p16 = _mm256_packs_epi32(codes, codes);
        let (lo, hi) = (_mm256_castsi256_si128(p16), _mm256_extracti128_si256::<1>(p16));
        let p8 = _mm_packus_epi16(_mm_unpacklo_epi64(lo, hi), _mm_setzero_si128());
        _mm_storel_epi64(code.as_mut_ptr() as *mut __m128i, p8);
    }
}

/// Loads eight clip-space positions as x, y, z and w vectors (a 4×8 transpose).
#[cfg(all(target_arch = "x86_64", test))]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn load8(c: &[Vec4]) -> [std::arch::x86_64::__m256; 4] {
    use std::arch::x86_64::*;
    assert!(c.len() >= 8);
    // SAFETY: the function's features include AVX2; the loads read eight Vec4 of the slice.
    unsafe {
        let row = |i: usize| _mm_loadu_ps(&c[i] as *const Vec4 as *const f32);
        let t0 = _mm256_set_m128(row(4), row(0));
        let t1 = _mm256_set_m128(row(5), row(1));
        let t2 = _mm256_set_m128(row(6), row(2));
        let t3 = _mm256_set_m128(row(7), row(3));
        let (u0, u1) = (_mm256_unpacklo_ps(t0, t1), _mm256_unpackhi_ps(t0, t1));
        let (u2, u3) = (_mm256_unpacklo_ps(t2, t3), _mm256_unpackhi_ps(t2, t3));
        [
            _mm256_shuffle_ps(u0, u2, 0x44),
            _mm256_shuffle_ps(u0, u2, 0xEE),
            _mm256_shuffle_ps(u1, u3, 0x44),
            _mm256_shuffle_ps(u1, u3, 0xEE),
        ]
    }
}

/// Splits the items into `n` chunks of about equal triangle counts, in order.
pub(crate) fn split(items: &[(u32, u32, u32)], n: usize, out: &mut Vec<Vec<Piece>>) {
    let n = n.max(1);
    out.resize_with(n, Vec::new);
    out.truncate(n);
    for c in out.iter_mut() {
        c.clear();
    }
    let total: u64 = items.iter().map(|i| i.2 as u64).sum();
    let quota = total.div_ceil(n as u64).max(1);
    let (mut chunk, mut filled) = (0usize, 0u64);
    for (k, &(_, start, count)) in items.iter().enumerate() {
        let (mut s, mut left) = (start, count);
        while left > 0 {
            let room = (quota - filled).min(left as u64) as u32;
            out[chunk].push(Piece { item: k as u32, start: s, count: room });
            s += room;
            left -= room;
            filled += room as u64;
            if filled >= quota && chunk + 1 < n {
                chunk += 1;
                filled = 0;
            }
        }
    }
}

mod list;
#[cfg(test)]
mod tests;

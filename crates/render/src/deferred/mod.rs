//! Deferred shading: color every pixel from its triangle ID after visibility is settled.
//!
//! Rasterization writes only depth and IDs, so each pixel is shaded once however deep the
//! overdraw. Per pixel the triangle is found from its ID, and the world-space (perspective-
//! correct) barycentric weights of the pixel center come from the 2D homogeneous form of
//! Olano & Greer ("Triangle Scan Conversion using 2D Homogeneous Coordinates", 1997): with
//! the clip-space rows `h_i = (x_i, y_i, w_i)`, the weights of the point seen through NDC
//! `p = (x, y, 1)` are proportional to `(h_j × h_k) · p`. That equals interpolating `a/w`
//! and `1/w` linearly in screen space and dividing (Heckbert & Moreton 1991; Blinn 1992),
//! needs no clipped vertices, and works for triangles crossing the eye plane. Affine
//! (screen-space) weights, for comparison, are `β_i·w_i` renormalized.
//!
//! Triangles and instances are prepared once and cached per worker (direct-mapped caches,
//! see [`Shader`]), so a triangle covering many pixels costs one setup; in a big scene the
//! setup waits on memory (a flat triangle's face record, else its indices and then its
//! corners), so when the meshes outgrow the caches, rows that prepare many triangles ask
//! for all of theirs first and the waits overlap. Bands of rows are
//! claimed one at a time ([`crate::claim`]). With AVX2 eight pixels find their cached
//! colors at once, by two gathers (sixteen with AVX-512: the oracle frame of the street
//! path, shading on one thread 0.98 → 0.87–0.96 ms), so the common case (flat shading) has
//! no branch that depends on where a triangle's run of pixels ends.

use glam::{DMat4, Mat4, Vec3, Vec3A};
use sightline_scene::{Camera, Instance, Mesh, Scene};
use sightline_spatial::{prefetch, SimdLevel};

use crate::claim::{for_each_claimed, Claim};
use crate::clip_matrix::clip_from_local;
use crate::shading::{is_constant, InstanceShading, ShadeOptions, ShadingMode, TriangleShader};
use crate::Framebuffer;

mod lookup;
pub(crate) use lookup::Lookup;

/// Rows per band of the shading pass: tall enough that few triangles span the bands of
/// both workers (each prepares such a triangle once for itself; 8 rows shaded about 10%
/// slower than 32), short enough to balance (23 bands at 720 rows).
const BAND_ROWS: usize = 32;
/// Triangle cache entries per worker (a power of two). A street frame of a 10^9-triangle
/// city shows about 54,000 triangles; at 4,096 entries, shading took 6-8% longer there and
/// on the default city (16,384 entries hold 256 KiB of keys, colors and indices).
const TRI_CACHE: usize = 16384;
/// The shift that leaves log2(TRI_CACHE) bits of the 32-bit hash.
const SLOT_SHIFT: i32 = 32 - TRI_CACHE.trailing_zeros() as i32;
/// [`SLOT_SHIFT`] as the immediate of AVX-512's shifts.
#[cfg(target_arch = "x86_64")]
const SLOT_SHIFT_U: u32 = SLOT_SHIFT as u32;
const INST_CACHE: usize = 64;

struct InstEntry<'a> {
    index: u32,
    /// `clip_from_local`, formed on the first triangle that needs interpolation: flat
    /// triangles (the common case) need none.
    clip: Option<Mat4>,
    shading: InstanceShading<'a>,
    mesh: &'a Mesh,
}

/// A triangle ready for shading at any pixel: its 2D homogeneous rows and its shader.
pub(crate) struct TriEntry<'a> {
    rows: [Vec3A; 3],
    w: [f32; 3],
    pub(crate) shader: TriangleShader<'a>,
}

impl<'a> TriEntry<'a> {
    /// Triangle `t` of `mesh`, drawn under `clip` (`clip_from_local`) with `shader`.
    pub(crate) fn new(clip: &Mat4, mesh: &Mesh, t: usize, shader: TriangleShader<'a>) -> Self {
        let h = mesh
            .triangle(t)
            .map(|i| *clip * mesh.positions()[i as usize].extend(1.0))
            .map(|c| Vec3A::new(c.x, c.y, c.w));
        TriEntry { rows: [h[1].cross(h[2]), h[2].cross(h[0]), h[0].cross(h[1])], w: [h[0].z, h[1].z, h[2].z], shader }
    }

    /// The world-space barycentric weights of the point seen through NDC `p = (x, y, 1)`
    /// (affine screen-space weights when `perspective_correct` is off).
    #[inline(always)]
    pub(crate) fn weights(&self, p: Vec3A, perspective_correct: bool) -> Vec3 {
        let mut b = Vec3::new(self.rows[0].dot(p), self.rows[1].dot(p), self.rows[2].dot(p));
        if !perspective_correct {
            b *= Vec3::from(self.w);
        }
        let s = b.x + b.y + b.z;
        if s != 0.0 {
            b / s
        } else {
            Vec3::splat(1.0 / 3.0)
        }
    }
}

/// NDC of the center of pixel column `x` (`sx` = 2 / width).
#[inline(always)]
pub(crate) fn ndc_x(x: usize, sx: f32) -> f32 {
    (x as f32 + 0.5) * sx - 1.0
}

/// NDC of the center of pixel row `y` (`sy` = 2 / height; row 0 is the top).
#[inline(always)]
pub(crate) fn ndc_y(y: usize, sy: f32) -> f32 {
    1.0 - (y as f32 + 0.5) * sy
}

/// Writes every color of `fb`: pixels with ID 0 get the sky's color for their row when
/// `opts` has a sky ([`crate::sky`]), else `background`; IDs that no instance claims, and
/// every pixel in mode `None`, get `background`; the others are shaded. So the color plane needs no
/// clearing before a frame.
pub fn shade_pass(
    scene: &Scene,
    instances: &[Instance],
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &ShadeOptions,
    background: [u8; 4],
) {
    let (w, h) = (fb.width() as usize, fb.height() as usize);
    // A replaced color plane of another length would be left partly unshaded without a word
    // (the bands below stop where it ends).
    fb.assert_planes();
    let frame = ShadeFrame::new(scene, instances, camera, (w, h), opts, background);
    let ids = &fb.ids;
    // Bands of rows claimed one at a time (see [`crate::claim`]: the sky's rows cost next
    // to nothing, the street's much more), each worker keeping its caches across its bands.
    let bands = fb.color.chunks_mut(w * BAND_ROWS).enumerate();
    for_each_claimed(bands, Claim::InOrder, Shader::default, |shader, (band, color)| {
        for (r, crow) in color.chunks_mut(w).enumerate() {
            let y = band * BAND_ROWS + r;
            frame.row(shader, &ids[y * w..(y + 1) * w], y, crow);
        }
    });
}

/// What shading one frame needs, shared by every task that shades part of it: the scene
/// and its instances, the camera, the options, the background and the sky's row colors.
struct ShadeFrame<'a> {
    scene: &'a Scene,
    lookup: Lookup<'a>,
    camera: &'a Camera,
    /// The camera's `clip_from_world` in f64, formed once for every instance's
    /// `clip_from_local` (see [`InstEntry::clip`]).
    clip_from_world: DMat4,
    opts: &'a ShadeOptions,
    background: [u8; 4],
    /// The sky's color of each row, when there is a sky.
    sky: Option<Vec<[u8; 4]>>,
    /// 2 / width and 2 / height: NDC per pixel.
    sx: f32,
    sy: f32,
    /// The instruction set of the cache lookups: gathers of eight pixels with AVX2, of
    /// sixteen with AVX-512, none below.
    simd: SimdLevel,
    /// Whether rows are asked for ahead ([`ShadeFrame::start_loads`]): only when the meshes'
    /// indices and positions take more than [`PREFETCH_BYTES`].
    prefetch: bool,
}

/// One worker's caches of prepared instances and triangles (see [`ShadeFrame::row`]);
/// empty, and allocation-free, until it shades its first row (in any mode but `None`).
///
/// The triangle cache is direct-mapped ([`slot`]) and kept in flat arrays, so that eight
/// pixels (sixteen with AVX-512) find their slots with two gathers: `pairs[s] = [key, color]`, where `key` is
/// the ID whose constant color (flat shading, the common case) is `color`, or 0 when the
/// slot holds a triangle that needs interpolation, whose ID is then `full_ids[s]` (else 0)
/// and whose entry is `fulls[full_at[s]]`; a slot keeps its entry in `fulls` for the next
/// such triangle. (ID 0, the background, is never cached.)
#[derive(Default)]
struct Shader<'a> {
    insts: Vec<Option<InstEntry<'a>>>,
    pairs: Vec<[u32; 2]>,
    full_ids: Vec<u32>,
    full_at: Vec<u32>,
    fulls: Vec<TriEntry<'a>>,
    hint: u32,
    /// The row's triangles whose loads have started: mesh and triangle index (see
    /// [`ShadeFrame::start_loads`]).
    soon: Vec<(&'a Mesh, usize)>,
    /// Triangles prepared in the row being shaded (until the next starts: in the last).
    row_prepared: u32,
}

/// Triangles prepared in a row from which the next row's are asked for ahead
/// ([`ShadeFrame::start_loads`]). On the default city's street frames 2% of rows prepare as
/// many, and scanning every row made shading 70% slower there; on the 10^9-triangle city
/// half do.
const PREFETCH_ROW: u32 = 64;

/// The size of the meshes' indices and positions above which rows are asked for ahead.
/// Below it they stay in the cores' caches and the scan is pure cost. Measured in one
/// binary with and without the scan, before flat shading read face records (24 bytes a
/// triangle): hzb aerial walks of the default city (2.0 MB) shaded in 9.7-9.9 ms without
/// it against 10.4-13.0 ms with it, while the 10^8-triangle city's (19 MB) took 30.5-31.9 ms
/// with it against 35.7-39.6 ms without, the 10^9's (68 MB) 41-45 against 61-65 ms; the
/// 10^7 (6.3 MB), 3 x 10^7 (10.6 MB) and the one-mesh OBJ city (23 MB) were even.
const PREFETCH_BYTES: usize = 8 << 20;

/// No full entry: a slot's `full_at` before it first holds one.
const NONE: u32 = u32::MAX;

/// The bytes of every mesh's indices and positions in `scene`.
fn mesh_bytes(scene: &Scene) -> usize {
    scene.meshes().map(|(_, m)| std::mem::size_of_val(m.indices()) + std::mem::size_of_val(m.positions())).sum()
}

/// The triangle cache slot of ID `id`: the top log2([`TRI_CACHE`]) bits of a multiplicative
/// hash (Knuth's constant), so that neighboring IDs spread.
#[inline(always)]
fn slot(id: u32) -> usize {
    (id.wrapping_mul(0x9E37_79B1) >> SLOT_SHIFT) as usize & (TRI_CACHE - 1)
}

impl<'a> ShadeFrame<'a> {
    /// The shading of a `width × height` frame of `scene` seen by `camera`.
    fn new(
        scene: &'a Scene,
        instances: &'a [Instance],
        camera: &'a Camera,
        (width, height): (usize, usize),
        opts: &'a ShadeOptions,
        background: [u8; 4],
    ) -> Self {
        let sky = (opts.mode != ShadingMode::None).then(|| opts.sky.map(|s| s.rows(camera, height))).flatten();
        Self {
            scene,
            lookup: Lookup::new(instances),
            camera,
            clip_from_world: camera.clip_from_world_f64(),
            opts,
            background,
            sky,
            sx: 2.0 / width.max(1) as f32,
            sy: 2.0 / height.max(1) as f32,
            simd: SimdLevel::Auto.resolve(),
            prefetch: mesh_bytes(scene) > PREFETCH_BYTES,
        }
    }

    /// The color of an empty pixel (ID 0) in row `y`.
    #[inline]
    fn empty(&self, y: usize) -> [u8; 4] {
        self.sky.as_ref().map_or(self.background, |s| s[y])
    }

    /// Colors `out[x]` of pixel `(x, y)` from its triangle ID `ids[x]`, with the task's
    /// caches `st`.
    fn row(&'a self, st: &mut Shader<'a>, ids: &[u32], y: usize, out: &mut [[u8; 4]]) {
        let ids = &ids[..out.len()];
        if self.opts.mode == ShadingMode::None {
            out.fill(self.background);
            return;
        }
        if st.pairs.is_empty() {
            st.insts = (0..INST_CACHE).map(|_| None).collect();
            st.pairs = vec![[0; 2]; TRI_CACHE];
            st.full_ids = vec![0; TRI_CACHE];
            st.full_at = vec![NONE; TRI_CACHE];
        }
        // Rows that prepare many triangles come in runs (distant facades): when the last row
        // did, ask for this row's triangles first.
        if std::mem::take(&mut st.row_prepared) >= PREFETCH_ROW && self.prefetch {
            self.start_loads(st, ids);
        }
        match self.simd {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the CPU has AVX-512 (resolved when the frame was made).
            SimdLevel::Avx512 => unsafe { self.row_avx512(st, ids, y, out) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the CPU has AVX2 (resolved when the frame was made).
            SimdLevel::Avx2 => unsafe { self.row_avx2(st, ids, y, out) },
            _ => self.row_runs(st, ids, 0, y, out),
        }
    }

    /// [`ShadeFrame::row_avx2`] sixteen pixels at a time: one 16-lane compare for a run of
    /// one ID, else the sixteen slots' (key, color) pairs by two 8-element gathers, split
    /// into keys and colors by two two-source permutes, and compared into a mask.
    ///
    /// # Safety
    /// The CPU must have AVX-512 F (and AVX2), and the caches must be allocated.
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::incompatible_msrv)]
    #[target_feature(enable = "avx512f,avx2")]
    unsafe fn row_avx512(&'a self, st: &mut Shader<'a>, ids: &[u32], y: usize, out: &mut [[u8; 4]]) {
        use std::arch::x86_64::*;
        let n = out.len() / 16 * 16;
        let empty_color = u32::from_ne_bytes(self.empty(y));
        let empty = _mm512_set1_epi32(empty_color as i32);
        let (zero, mul) = (_mm512_setzero_si512(), _mm512_set1_epi32(0x9E37_79B1_u32 as i32));
        let mask = _mm512_set1_epi32((TRI_CACHE - 1) as i32);
        // Gathered pairs are (key, color) dwords: keys at even indices of the two
        // gathers' 32 dwords, colors at odd ones.
        let keys = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let colors = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
        let mut i = 0;
        while i < n {
            // SAFETY: `i + 16 <= n <= ids.len() == out.len()`, so the loads and the store
            // stay inside the slices; slots are below TRI_CACHE, the length of `pairs` (the
            // caller allocated it); `[u8; 4]` has the layout of a u32.
            let (hit, color) = unsafe {
                let v = _mm512_loadu_si512(ids.as_ptr().add(i) as *const _);
                let first = *ids.get_unchecked(i);
                if _mm512_cmpeq_epi32_mask(v, _mm512_set1_epi32(first as i32)) == 0xFFFF {
                    let [key, c] = *st.pairs.get_unchecked(slot(first));
                    let c = if first == 0 { empty_color } else { c };
                    (if key == first || first == 0 { 0xFFFF } else { 0 }, _mm512_set1_epi32(c as i32))
                } else {
                    // `slot` in sixteen lanes.
                    let s = _mm512_and_si512(_mm512_srli_epi32::<SLOT_SHIFT_U>(_mm512_mullo_epi32(v, mul)), mask);
                    // Taken afresh: `row_runs` below writes to the cache.
                    let pairs = st.pairs.as_ptr() as *const i64;
                    let lo = _mm512_i32gather_epi64::<8>(_mm512_castsi512_si256(s), pairs);
                    let hi = _mm512_i32gather_epi64::<8>(_mm512_extracti64x4_epi64::<1>(s), pairs);
                    let k = _mm512_permutex2var_epi32(lo, keys, hi);
                    let c = _mm512_permutex2var_epi32(lo, colors, hi);
                    let bg = _mm512_cmpeq_epi32_mask(v, zero);
                    // A key of 0 never matches a non-zero ID: full entries miss here.
                    (_mm512_cmpeq_epi32_mask(k, v) | bg, _mm512_mask_blend_epi32(bg, c, empty))
                }
            };
            // Each half of eight whose pixels all found their color is stored from the
            // vector; the other goes through `row_runs`, as with AVX2. (A color found is a
            // triangle's constant color, still right after `row_runs` changes the cache.)
            if hit == 0xFFFF {
                // SAFETY: as above.
                unsafe { _mm512_storeu_si512(out.as_mut_ptr().add(i) as *mut _, color) };
                i += 16;
                continue;
            }
            for h in 0..2 {
                let at = i + 8 * h;
                if (hit >> (8 * h)) & 0xFF == 0xFF {
                    // SAFETY: as above; the mask writes only this half.
                    unsafe { _mm512_mask_storeu_epi32(out.as_mut_ptr().add(i) as *mut i32, 0xFF << (8 * h), color) };
                } else {
                    self.row_runs(st, &ids[at..at + 8], at, y, &mut out[at..at + 8]);
                }
            }
            i += 16;
        }
        self.row_runs(st, &ids[n..], n, y, &mut out[n..]);
    }

    /// [`ShadeFrame::row`] eight pixels at a time. Eight pixels of one ID (inside a
    /// triangle) take one scalar cache lookup; others look up their eight slots with two
    /// 64-bit gathers of (key, color) pairs. When every pixel is empty or finds its
    /// triangle's constant color, the eight colors are stored at once; otherwise (a
    /// triangle not yet prepared, or one that needs interpolation) those eight go through
    /// [`ShadeFrame::row_runs`]. No branch depends on where a run of one ID ends, which on
    /// small triangles was most of the cost of the run-by-run loop.
    ///
    /// # Safety
    /// The CPU must have AVX2, and the caches must be allocated.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn row_avx2(&'a self, st: &mut Shader<'a>, ids: &[u32], y: usize, out: &mut [[u8; 4]]) {
        use std::arch::x86_64::*;
        let n = out.len() / 8 * 8;
        let empty_color = u32::from_ne_bytes(self.empty(y));
        let empty = _mm256_set1_epi32(empty_color as i32);
        let (zero, mul) = (_mm256_setzero_si256(), _mm256_set1_epi32(0x9E37_79B1_u32 as i32));
        let mask = _mm256_set1_epi32((TRI_CACHE - 1) as i32);
        let order = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
        let mut i = 0;
        while i < n {
            // SAFETY: `i + 8 <= n <= ids.len() == out.len()`, so the loads and the store
            // stay inside the slices; slots are below TRI_CACHE, the length of `pairs` (the
            // caller allocated it); `[u8; 4]` has the layout of a u32.
            let (hit, color) = unsafe {
                let v = _mm256_loadu_si256(ids.as_ptr().add(i) as *const __m256i);
                let first = *ids.get_unchecked(i);
                if _mm256_movemask_epi8(_mm256_cmpeq_epi32(v, _mm256_set1_epi32(first as i32))) == -1 {
                    let [key, c] = *st.pairs.get_unchecked(slot(first));
                    let c = if first == 0 { empty_color } else { c };
                    (key == first || first == 0, _mm256_set1_epi32(c as i32))
                } else {
                    // `slot` in eight lanes.
                    let s = _mm256_and_si256(_mm256_srli_epi32::<SLOT_SHIFT>(_mm256_mullo_epi32(v, mul)), mask);
                    // Taken afresh: `row_runs` below writes to the cache.
                    let pairs = st.pairs.as_ptr() as *const i64;
                    let lo = _mm256_i32gather_epi64(pairs, _mm256_castsi256_si128(s), 8);
                    let hi = _mm256_i32gather_epi64(pairs, _mm256_extracti128_si256(s, 1), 8);
                    // Each gather holds four (key, color) pairs: keys to the low half, colors
                    // to the high half, then the two gathers' halves joined in lane order.
                    let (lo, hi) = (_mm256_permutevar8x32_epi32(lo, order), _mm256_permutevar8x32_epi32(hi, order));
                    let k = _mm256_permute2x128_si256(lo, hi, 0x20);
                    let c = _mm256_permute2x128_si256(lo, hi, 0x31);
                    let bg = _mm256_cmpeq_epi32(v, zero);
                    // A key of 0 never matches a non-zero ID: full entries miss here.
                    let hit = _mm256_or_si256(_mm256_cmpeq_epi32(k, v), bg);
                    (_mm256_movemask_epi8(hit) == -1, _mm256_blendv_epi8(c, empty, bg))
                }
            };
            if hit {
                // SAFETY: as above.
                unsafe { _mm256_storeu_si256(out.as_mut_ptr().add(i) as *mut __m256i, color) };
            } else {
                self.row_runs(st, &ids[i..i + 8], i, y, &mut out[i..i + 8]);
            }
            i += 8;
        }
        self.row_runs(st, &ids[n..], n, y, &mut out[n..]);
    }

    /// Asks for what preparing the row's uncached triangles will read: their face records
    /// when shading is flat ([`Mesh::faces`]), else their vertex indices, then their corners.
    /// Each preparation would otherwise wait on a cache miss (two dependent ones without
    /// face records) in a big scene (a street frame of the 10^9-triangle city prepares about
    /// 59,000 triangles over 120 MB of meshes); asked for a row at a time, they overlap.
    /// The scan goes run by run, a mispredicted branch per run: worth it only on rows that
    /// prepare many triangles ([`PREFETCH_ROW`]). Returns the triangles asked for.
    fn start_loads(&'a self, st: &mut Shader<'a>, ids: &[u32]) -> usize {
        let mut faces = 0;
        let mut x = 0;
        while x < ids.len() {
            let id = ids[x];
            x = run_end(ids, x + 1, id);
            let s = slot(id);
            if id == 0 || st.pairs.get(s).is_some_and(|p| p[0] == id) || st.full_ids.get(s) == Some(&id) {
                continue;
            }
            let Some((inst, _, t)) = self.locate(id, &mut st.hint) else { continue };
            let Some(mesh) = self.scene.mesh(inst.mesh) else { continue };
            let material = self.scene.instance_material(inst);
            if is_constant(material, mesh, self.opts) {
                // What `flat_color` reads.
                if let Some(f) = mesh.faces().get(t) {
                    prefetch(f);
                    faces += 1;
                }
            } else if let Some(i) = mesh.indices().get(3 * t) {
                prefetch(i);
                st.soon.push((mesh, t));
            }
        }
        let asked = faces + st.soon.len();
        // The indices asked for first have arrived by now, or soon will.
        for (mesh, t) in st.soon.drain(..) {
            if let Some(ix) = mesh.indices().get(3 * t..3 * t + 3) {
                for &i in ix {
                    if let Some(p) = mesh.positions().get(i as usize) {
                        prefetch(p);
                    }
                }
            }
        }
        asked
    }

    /// The instance drawing triangle ID `id` (not 0), its index, and the triangle's index in
    /// its mesh.
    #[inline]
    fn locate(&self, id: u32, hint: &mut u32) -> Option<(&'a Instance, u32, usize)> {
        let g = id - 1;
        let index = self.lookup.find_hinted(g, hint)?;
        let inst = &self.lookup.instances[index as usize];
        Some((inst, index, (g - inst.first_triangle) as usize))
    }

    /// [`ShadeFrame::row`] run by run, for the pixels from column `x0` on: one cache lookup
    /// (and, on a miss, the triangle's preparation) and one fill per run of one ID. The
    /// caches must be allocated.
    fn row_runs(&'a self, st: &mut Shader<'a>, ids: &[u32], x0: usize, y: usize, out: &mut [[u8; 4]]) {
        let row_y = ndc_y(y, self.sy);
        let mut x = 0;
        while x < out.len() {
            let id = ids[x];
            let end = run_end(ids, x + 1, id);
            if id == 0 {
                out[x..end].fill(self.empty(y));
                x = end;
                continue;
            }
            let s = slot(id);
            if st.pairs[s][0] != id && st.full_ids[s] != id {
                st.row_prepared += 1;
                match self.prepare(id, &mut st.insts, &mut st.hint) {
                    Some(Prepared::Full(e)) => {
                        // Reuse the entry this slot last held, else append one.
                        match st.full_at[s] {
                            NONE => {
                                st.full_at[s] = st.fulls.len() as u32;
                                st.fulls.push(e);
                            }
                            at => st.fulls[at as usize] = e,
                        }
                        (st.pairs[s][0], st.full_ids[s]) = (0, id);
                    }
                    // An ID no instance claims is drawn in the background color.
                    p => {
                        let c = match p {
                            Some(Prepared::Constant(k)) => k,
                            _ => self.background,
                        };
                        (st.pairs[s], st.full_ids[s]) = ([id, u32::from_ne_bytes(c)], 0);
                    }
                }
            }
            if st.pairs[s][0] == id {
                out[x..end].fill(st.pairs[s][1].to_ne_bytes());
            } else {
                let entry = &st.fulls[st.full_at[s] as usize];
                for (px, c) in out[x..end].iter_mut().enumerate() {
                    let p = Vec3A::new(ndc_x(x0 + x + px, self.sx), row_y, 1.0);
                    *c = entry.shader.shade(entry.weights(p, self.opts.perspective_correct), self.opts);
                }
            }
            x = end;
        }
    }

    /// Prepares triangle `id` for shading: its constant color, or its full entry.
    fn prepare(&'a self, id: u32, insts: &mut [Option<InstEntry<'a>>], hint: &mut u32) -> Option<Prepared<'a>> {
        let (scene, opts) = (self.scene, self.opts);
        let (inst, index, t) = self.locate(id, hint)?;
        let slot = index as usize & (INST_CACHE - 1);
        if !matches!(&insts[slot], Some(e) if e.index == index) {
            let mesh = scene.mesh(inst.mesh)?;
            let material = scene.instance_material(inst);
            insts[slot] = Some(InstEntry {
                index,
                clip: None,
                shading: InstanceShading::new(inst.world_from_local, material),
                mesh,
            });
        }
        let e = insts[slot].as_mut()?;
        if t >= e.mesh.triangle_count() {
            return None;
        }
        let eye = self.camera.view.eye;
        if let Some(k) = crate::shading::flat_color(&e.shading, e.mesh, t, eye, opts) {
            // No interpolation needed: skip the clip-space rows.
            return Some(Prepared::Constant(k));
        }
        let shader = TriangleShader::new(&e.shading, e.mesh, t, eye, opts);
        let clip =
            *e.clip.get_or_insert_with(|| clip_from_local(&self.clip_from_world, &inst.world_from_local, self.simd));
        Some(Prepared::Full(TriEntry::new(&clip, e.mesh, t, shader)))
    }
}

/// The end of the run of `id` in `row` that continues at `from`: the first position at or
/// after `from` holding another ID, or the row's length. Eight IDs per step while the run
/// lasts (the OR of XORs has no branch per lane, so it vectorizes), then one at a time: on
/// big triangles the scan for the run's end was most of the shading pass.
#[inline(always)]
fn run_end(row: &[u32], from: usize, id: u32) -> usize {
    let mut x = from;
    while let Some(c) = row.get(x..x + 8) {
        if c.iter().fold(0, |a, &v| a | (v ^ id)) != 0 {
            break;
        }
        x += 8;
    }
    while x < row.len() && row[x] == id {
        x += 1;
    }
    x
}

#[allow(clippy::large_enum_variant)] // a short-lived return value; boxing would allocate
enum Prepared<'a> {
    Constant([u8; 4]),
    Full(TriEntry<'a>),
}

#[cfg(test)]
mod tests;

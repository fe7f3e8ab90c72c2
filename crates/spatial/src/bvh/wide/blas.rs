//! Bottom level: one wide BVH per mesh over its triangles (paired into quads where the mesh
//! allows), built once and shared by every instance of the mesh.
//!
//! Meshes made of quads store each quad as two triangles that share a diagonal, and they
//! usually come one after the other: `(a, b, c)` then `(a, c, d)`, the fan triangulation
//! that mesh builders and OBJ loaders give a polygon, or another rotation of either, such
//! as the `(a, b, c)`, `(c, d, a)` of many exporters. The BLAS keeps such a pair as one
//! record of four corners, the quad primitive of Embree (Wald et al. 2014, "Embree: A
//! Kernel Framework for Efficient CPU Ray Tracing"): the tree has half the primitives, a
//! record is one cache line (four packed `Vec3`s and the two triangles' mesh indices,
//! aligned to 64 bytes, against 80 bytes for two triangle records), and a ray test
//! shears the shared corners and computes the shared edge once for both triangles. Each
//! triangle keeps its own corners in its own order, turned (a rotation keeps its facing
//! and its edges, so the watertight test stays watertight) so that the diagonal runs from
//! its third corner to its first; a test of the pair computes, bit for bit, what tests of
//! the two triangles in their stored order compute, and [`WideBlas::mesh_weights`]
//! gives a hit's weights back in the mesh's order.
//!
//! Triangles that share an edge but not a place in the mesh pair too: meshes reordered for
//! the vertex cache, or triangulated in another order, would otherwise keep their triangles
//! apart. So after each triangle has tried the next one, the triangles left meet across
//! their edges, matched by sorting, the tightest pairs first ([`pair_up`]); a neighbour in
//! the mesh that would make a loose pair waits for that second pass too.
//!
//! Two triangles are paired only when the pair's box is no larger (by surface area) than
//! their two boxes together: a pair folded over its diagonal would make the tree worse.
//! A triangle without a partner is a record of its own, whose second triangle is absent.
//! A BVH over quads has one quad per leaf. A mesh of which fewer than half the triangles
//! pair up keeps lone-triangle records instead (40 bytes, up to four per leaf, the
//! settings measured for triangles): in quad records they would waste a third of a line.
//!
//! Corners are exact copies of the mesh's positions (so the watertight edge test stays
//! watertight), in leaf order.

use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use rayon::iter::Either;
use rayon::prelude::*;
use sightline_scene::{Aabb, Mesh};

use super::{WideBuildParams, WideBvh};
use crate::prefetch_all;

/// [`BlasQuad::index`] of a quad's absent second triangle.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// One or two triangles of a [`WideBlas`] that share an edge: triangle 0 is corners
/// `(0, 1, 2)` and triangle 1 is corners `(0, 2, 3)`, each its mesh's vertex order turned
/// by [`BlasQuad::turns`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct BlasQuad {
    /// Vertex positions (corner 3 repeats corner 2 when there is one triangle).
    pub corners: [Vec3; 4],
    /// The mesh's index of each triangle ([`NO_TRIANGLE`] for an absent second one).
    pub index: [u32; 2],
    /// How far each triangle's stored corners are turned from its mesh order: corner `k`
    /// is the mesh's vertex `(k + turns) % 3` (0, 1 or 2).
    pub turns: [u8; 2],
}

impl BlasQuad {
    /// Corners of triangle `half` (0 or 1), in stored order (see [`BlasQuad::turns`]).
    #[inline(always)]
    pub fn triangle(&self, half: usize) -> [Vec3; 3] {
        let c = &self.corners;
        if half == 0 {
            [c[0], c[1], c[2]]
        } else {
            [c[0], c[2], c[3]]
        }
    }

    /// True when the record holds two triangles.
    #[inline(always)]
    pub fn is_pair(&self) -> bool {
        self.index[1] != NO_TRIANGLE
    }
}

/// One triangle of a [`WideBlas`] of lone triangles: its corners and its index in the mesh
/// (40 bytes: a leaf of four fills 2.5 cache lines).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct BlasTriangle {
    /// Vertex positions.
    pub corners: [Vec3; 3],
    /// The mesh's index of the triangle.
    pub index: u32,
}

/// The primitives of a [`WideBlas`], in leaf order.
#[derive(Debug, Clone)]
pub enum BlasPrims {
    /// Quads, for meshes of which at least half the triangles pair up.
    Quads(Vec<BlasQuad>),
    /// Lone triangles, for the other meshes (a quad record would waste a third of its line).
    Triangles(Vec<BlasTriangle>),
}

/// A wide triangle BVH in some local space, over its primitives in leaf order.
#[derive(Debug, Clone)]
pub struct WideBlas {
    /// The primitives, in leaf order.
    prims: BlasPrims,
    /// The tree over the primitives; `bvh.order()[k]` is the primitive stored in slot `k`
    /// (quads numbered in order of their first triangle's mesh index).
    bvh: WideBvh,
    /// Triangles stored.
    triangles: usize,
    /// True when some quad stores a triangle turned ([`BlasQuad::turns`]): without one, a
    /// hit's weights need no record read to go back to mesh order.
    turned: bool,
}

/// The box of some corners.
fn box_of(c: &[Vec3]) -> ObAabb {
    let (lo, hi) = c.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    ObAabb::new(Vec3A::from(lo), Vec3A::from(hi))
}

/// Half the surface area of a box (what SAH weighs).
fn half_area(b: &ObAabb) -> f32 {
    let d = b.max - b.min;
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Triangle `t` turned by `k` corners: corner `i` is `t[(i + k) % 3]`.
fn turned(t: &[Vec3; 3], k: u8) -> [Vec3; 3] {
    let k = k as usize;
    [t[k % 3], t[(k + 1) % 3], t[(k + 2) % 3]]
}

/// How tightly triangles `a` and `b` fill the box of their pair: its surface area over the
/// sum of their own boxes' (1 at most for a pair that makes the tree no worse; 0.5 for the
/// two halves of a square, 1 for two neighbours across a square's side). Infinite for
/// non-finite corners; 0 when neither the pair's box nor its triangles' boxes have area
/// (points, or segments along an axis).
fn pair_fit(a: &[Vec3; 3], b: &[Vec3; 3]) -> f32 {
    if !a.iter().chain(b).all(|c| c.is_finite()) {
        return f32::INFINITY;
    }
    let whole = half_area(&box_of(&[a[0], a[1], a[2], b[0], b[1], b[2]]));
    let parts = half_area(&box_of(a)) + half_area(&box_of(b));
    if parts > 0.0 {
        whole / parts
    } else if whole > 0.0 {
        f32::INFINITY
    } else {
        0.0
    }
}

/// Does triangle `b` complete triangle `a` to a quad? The turns of `a` and `b` that make
/// them `(p, q, r)` and `(p, r, s)`, the quad `(p, q, r, s)` (no turns when they already
/// are), and the pair's [`pair_fit`]: `b` runs one of `a`'s edges the other way, so both
/// face the same way. `None` when they share no such edge, when the pair's box is larger
/// (by surface area) than the two boxes together (a fit above 1), or for non-finite
/// corners.
fn completes(a: &[Vec3; 3], b: &[Vec3; 3]) -> Option<([u8; 2], f32)> {
    let fit = pair_fit(a, b);
    if fit > 1.0 {
        return None;
    }
    let turns = (0..9u8).map(|k| [k % 3, k / 3]).find(|&[ka, kb]| {
        let (a, b) = (turned(a, ka), turned(b, kb));
        b[0] == a[0] && b[1] == a[2]
    })?;
    Some((turns, fit))
}

/// One record before it is stored: the mesh indices of its one or two triangles and their
/// turns.
type Pairing = ([u32; 2], [u8; 2]);

/// Up to this many candidates an edge gives [`pair_up`] all its pairs of triangles that
/// run it opposite ways; an edge crowded with more (coincident triangles) gives only its
/// `k`-th triangle one way with its `k`-th the other way, so that it costs no quadratic
/// search.
const EDGE_CANDIDATES: usize = 16;

/// Candidates ahead of the one [`pair_up`] tests whose corners it asks for.
const CORNERS_AHEAD: usize = 16;

/// The loosest [`pair_fit`] at which [`pair_up`] takes a triangle's next one as its partner
/// at once: halfway between the halves of a square (0.5) and two neighbours across a
/// square's side (1). A looser neighbour waits for the second pass, where a tighter partner
/// across another edge can claim either triangle.
const SURE_FIT: f32 = 0.75;

/// Pairs triangles into quads, in two greedy passes.
///
/// 1. Each triangle with the next one when it completes it tightly (see [`SURE_FIT`]): the
///    fan- or strip-made meshes of builders and exporters pair this way, their records in
///    mesh order.
/// 2. The triangles left with each other across a shared edge, whatever their places in the
///    mesh (meshes reordered for the vertex cache, or triangulated in some other order):
///    their edges, keyed by a hash of the two corners' bits and marked by the way they
///    run ([`corner_hash`]), are sorted so that the triangles on one edge lie
///    together; two that run it opposite ways make a candidate (see [`EDGE_CANDIDATES`]),
///    tested by [`completes`] in parallel, and the candidates that complete are taken
///    tightest first ([`pair_fit`]; ties in order of their mesh indices) while both
///    triangles are still free. Without that order a facade's triangles would pair across
///    the sides of its cells about as often as across their diagonals, into quads whose
///    boxes are two cells wide: on the street path of a city shuffled so, rays were about
///    5% slower than with no pairs at all.
///
/// Records come in order of their first triangle's mesh index. Linear but for the sorts.
fn pair_up(tris: &[[Vec3; 3]]) -> Vec<Pairing> {
    let count = tris.len();
    let next: Vec<Option<[u8; 2]>> = (0..count)
        .into_par_iter()
        .map(|i| {
            let (turns, fit) = completes(&tris[i], tris.get(i + 1)?)?;
            (fit <= SURE_FIT).then_some(turns)
        })
        .collect();
    let mut out = Vec::with_capacity(count / 2 + 1);
    let mut lone = Vec::new();
    let mut i = 0;
    while i < count {
        if let Some(turns) = next[i] {
            out.push(([i as u32, i as u32 + 1], turns));
            i += 2;
        } else {
            lone.push(i as u32);
            i += 1;
        }
    }
    // (fit, triangles, turns) of the candidates that complete, tightest first. The
    // candidates come in the order of their edges' keys, so their triangles lie anywhere:
    // each asks ahead for the corners it will read.
    let candidates = across_edges(tris, &lone);
    let mut fits: Vec<(u32, [u32; 2], [u8; 2])> = candidates
        .par_chunks(4096)
        .flat_map_iter(|chunk| {
            chunk.iter().enumerate().filter_map(|(k, &[a, b])| {
                if let Some(&[a, b]) = chunk.get(k + CORNERS_AHEAD) {
                    prefetch_all(std::slice::from_ref(&tris[a as usize]));
                    prefetch_all(std::slice::from_ref(&tris[b as usize]));
                }
                // A fit is ≥ 0, so its bits order like it.
                completes(&tris[a as usize], &tris[b as usize]).map(|(turns, fit)| (fit.to_bits(), [a, b], turns))
            })
        })
        .collect();
    fits.par_sort_unstable();
    let mut paired = vec![false; if fits.is_empty() { 0 } else { count }];
    for (_, [a, b], turns) in fits {
        if !paired[a as usize] && !paired[b as usize] {
            paired[a as usize] = true;
            paired[b as usize] = true;
            out.push(([a, b], turns));
        }
    }
    let unpaired = |i: &&u32| paired.get(**i as usize) != Some(&true);
    out.extend(lone.iter().filter(unpaired).map(|&i| ([i, NO_TRIANGLE], [0; 2])));
    out.par_sort_unstable_by_key(|r| r.0[0]);
    out
}

/// The pairs `[a, b]` (`a < b`; possibly repeated, for triangles that share two edges) of
/// triangles `lone` (of `tris`) that run a shared edge opposite ways, as [`pair_up`] finds
/// them. Empty when a triangle's index needs more than 31 bits (a mesh of 2^31 triangles
/// would not fit in memory anyway).
fn across_edges(tris: &[[Vec3; 3]], lone: &[u32]) -> Vec<[u32; 2]> {
    const TRIANGLE: u64 = (1 << 31) - 1;
    // `lone` is ascending: its last index is its largest.
    if lone.last().is_some_and(|&i| i as u64 > TRIANGLE) {
        return Vec::new();
    }
    // Each edge as one word, sorted as fast as a word sorts: the key in the high 32 bits,
    // then whether the edge runs forward, then the triangle.
    let mut edges = vec![0u64; 3 * lone.len()];
    edges.par_chunks_mut(3).zip(lone).for_each(|(words, &i)| {
        let h = tris[i as usize].map(corner_hash);
        for (k, word) in words.iter_mut().enumerate() {
            let (p, q) = (h[k], h[(k + 1) % 3]);
            *word = (p ^ q) >> 32 << 32 | ((p < q) as u64) << 31 | i as u64;
        }
    });
    edges.par_sort_unstable();
    let pair = |a: &u64, b: &u64| {
        let (a, b) = ((a & TRIANGLE) as u32, (b & TRIANGLE) as u32);
        (a != b).then(|| [a.min(b), a.max(b)])
    };
    edges
        .par_chunk_by(|a, b| a >> 32 == b >> 32)
        .flat_map_iter(|run| {
            let (back, forth) = run.split_at(run.partition_point(|e| e >> 31 & 1 == 0));
            let crowded = back.len() * forth.len() > EDGE_CANDIDATES;
            let pairs = if crowded {
                Either::Left(back.iter().zip(forth))
            } else {
                Either::Right(back.iter().flat_map(move |a| forth.iter().map(move |b| (a, b))))
            };
            pairs.filter_map(move |(a, b)| pair(a, b))
        })
        .collect()
}

/// A 64-bit hash of a corner's bits (`+ 0.0` makes −0 and +0 one corner). [`across_edges`]
/// keys the edge between corners `p` and `q` by the high half of `hash(p) ^ hash(q)`, the
/// same either way round, and says it runs forward when `hash(p) < hash(q)`. Equal edges
/// get equal keys; [`completes`] checks the corners themselves, so edges that share a key
/// by chance (a few hundred among the three million edges of a shuffled 10^6-triangle mesh)
/// only add candidates that fail, and a degenerate edge (one corner twice) runs backward
/// in every triangle, so it pairs none.
fn corner_hash(p: Vec3) -> u64 {
    // FxHash's step (rustc's hasher) over the three words, then the MurmurHash3 finalizer's
    // mix of the high bits down (Stafford's variant 13).
    let mut h = 0u64;
    for w in (p + Vec3::ZERO).to_array().map(f32::to_bits) {
        h = (h.rotate_left(5) ^ w as u64).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

impl WideBlas {
    /// Builds over `count` triangles whose corners `corners(i)` gives, as quads when at
    /// least half of them pair up (see the module's header), else as lone triangles (corners
    /// read once, in parallel, for the pairing, the boxes and the copy in leaf order).
    pub fn build(count: usize, corners: impl Fn(usize) -> [Vec3; 3] + Sync) -> WideBlas {
        // Each triangle's corners read once: in a mesh whose triangles are not stored near
        // their neighbours, each read misses the cache four times (an index, then three
        // positions), and the pairing, the boxes and the copy in leaf order each read them.
        let tris: Vec<[Vec3; 3]> = (0..count).into_par_iter().map(&corners).collect();
        let records = pair_up(&tris);
        // Each pair saves a record.
        if 4 * (count - records.len()) < count {
            let bvh = WideBvh::build_fn(count, WideBuildParams::BLAS, |i| box_of(&tris[i]));
            let lone = bvh.order().par_iter().map(|&i| BlasTriangle { corners: tris[i as usize], index: i }).collect();
            return WideBlas { prims: BlasPrims::Triangles(lone), bvh, triangles: count, turned: false };
        }
        let quad = |&(index, turns): &Pairing| {
            let a = turned(&tris[index[0] as usize], turns[0]);
            let d = if index[1] == NO_TRIANGLE { a[2] } else { turned(&tris[index[1] as usize], turns[1])[2] };
            BlasQuad { corners: [a[0], a[1], a[2], d], index, turns }
        };
        // Made once, in record order: a pair found across the mesh reads two far places.
        let made: Vec<BlasQuad> = records.par_iter().map(quad).collect();
        let bvh = WideBvh::build_fn(made.len(), WideBuildParams::BLAS_QUADS, |i| box_of(&made[i].corners));
        let quads = bvh.order().par_iter().map(|&i| made[i as usize]).collect();
        let turned = records.iter().any(|(_, turns)| *turns != [0; 2]);
        WideBlas { prims: BlasPrims::Quads(quads), bvh, triangles: count, turned }
    }

    /// A BLAS with no triangles.
    pub fn empty() -> WideBlas {
        Self::build(0, |_| [Vec3::ZERO; 3])
    }

    /// The BLAS of a mesh in its own coordinates.
    pub fn from_mesh(mesh: &Mesh) -> WideBlas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i))
    }

    /// A BLAS of the mesh already placed in the world (for instances whose transform cannot
    /// be inverted, e.g. a zero scale that flattens the mesh).
    pub fn from_mesh_placed(mesh: &Mesh, world_from_local: &Affine3A) -> WideBlas {
        Self::build(mesh.triangle_count(), |i| mesh.triangle_positions(i).map(|p| world_from_local.transform_point3(p)))
    }

    /// The primitives in leaf order (slot `k` is the tree's primitive `k`).
    #[inline]
    pub fn prims(&self) -> &BlasPrims {
        &self.prims
    }

    /// Triangle `prim`, as a hit names it: slot `prim` of lone triangles, or half
    /// `prim % 2` of quad slot `prim / 2`. Its corners in stored order (those a hit's
    /// barycentric weights refer to) and its mesh index (`None` past the end, or for a
    /// quad's absent second triangle).
    #[inline]
    pub fn triangle(&self, prim: u32) -> Option<([Vec3; 3], u32)> {
        match &self.prims {
            BlasPrims::Triangles(t) => t.get(prim as usize).map(|t| (t.corners, t.index)),
            BlasPrims::Quads(q) => {
                let q = q.get(prim as usize / 2)?;
                let half = prim as usize % 2;
                (half == 0 || q.is_pair()).then(|| (q.triangle(half), q.index[half]))
            }
        }
    }

    /// A hit's barycentric weights `w` of triangle `prim`'s stored corners as the weights
    /// of its mesh's vertices, in mesh order (the same unless the quad turned the triangle;
    /// see [`BlasQuad::turns`]).
    #[inline]
    pub fn mesh_weights(&self, prim: u32, w: Vec3) -> Vec3 {
        // Stored corner k is mesh vertex (k + turns) % 3.
        match self.turns(prim) {
            1 => Vec3::new(w.z, w.x, w.y),
            2 => Vec3::new(w.y, w.z, w.x),
            _ => w,
        }
    }

    /// How far triangle `prim`'s stored corners are turned from its mesh order
    /// ([`BlasQuad::turns`]; 0 for lone-triangle records and past the end).
    #[inline]
    fn turns(&self, prim: u32) -> u8 {
        if !self.turned {
            return 0;
        }
        match &self.prims {
            BlasPrims::Quads(q) => q.get(prim as usize / 2).map_or(0, |q| q.turns[prim as usize % 2]),
            BlasPrims::Triangles(_) => 0,
        }
    }

    /// Number of triangles stored.
    #[inline]
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// The tree over the quads.
    #[inline]
    pub fn bvh(&self) -> &WideBvh {
        &self.bvh
    }

    /// Bounds of everything in the BLAS (an empty box for no triangles).
    pub fn bounds(&self) -> Aabb {
        let root = self.bvh.root();
        Aabb::new(Vec3::from(root.lo), Vec3::from(root.hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The turns with which `b` completes `a` ([`completes`]).
    fn turns_to_pair(a: &[Vec3; 3], b: &[Vec3; 3]) -> Option<[u8; 2]> {
        completes(a, b).map(|(turns, _)| turns)
    }

    /// Triangle `i` of a strip of unit squares along x, each split `(a, b, c)`, `(a, c, d)`.
    fn strip(i: usize) -> [Vec3; 3] {
        let o = Vec3::new((i / 2) as f32, 0.0, 0.0);
        let (a, b, c, d) = (o, o + Vec3::X, o + Vec3::new(1.0, 1.0, 0.0), o + Vec3::Y);
        if i.is_multiple_of(2) {
            [a, b, c]
        } else {
            [a, c, d]
        }
    }

    /// Triangle `i` of [`strip`], with each square's second triangle's corners taken in
    /// `order`.
    fn strip_reordered(i: usize, order: [usize; 3]) -> [Vec3; 3] {
        let t = strip(i);
        if i.is_multiple_of(2) {
            t
        } else {
            order.map(|k| t[k])
        }
    }

    /// Every triangle of `mesh` comes back once from the slots of `blas`, with its corners.
    /// The point of weights `w` on triangle `c`.
    fn at(c: [Vec3; 3], w: Vec3) -> Vec3 {
        c[0] * w.x + c[1] * w.y + c[2] * w.z
    }

    fn assert_all_triangles_once(blas: &WideBlas, count: usize, mesh: impl Fn(usize) -> [Vec3; 3]) {
        let prims = match blas.prims() {
            BlasPrims::Quads(q) => 2 * q.len(),
            BlasPrims::Triangles(t) => t.len(),
        };
        let mut seen = vec![false; count];
        for prim in 0..prims as u32 {
            if let Some((corners, i)) = blas.triangle(prim) {
                assert_eq!(corners, turned(&mesh(i as usize), blas.turns(prim)));
                assert!(!std::mem::replace(&mut seen[i as usize], true), "triangle {i} twice");
                // A hit's weights, given back in mesh order, name the same point.
                let w = Vec3::new(0.25, 0.5, 0.25);
                assert_eq!(at(corners, w), at(mesh(i as usize), blas.mesh_weights(prim, w)), "prim {prim}");
            }
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(blas.triangle(prims as u32), None);
        assert_eq!(blas.triangle_count(), count);
    }

    #[test]
    fn quads_are_stored_in_leaf_order_and_give_back_their_triangles() {
        let blas = WideBlas::build(51, strip);
        let BlasPrims::Quads(quads) = blas.prims() else { panic!("a strip of squares makes quads") };
        assert_eq!(quads.len(), 26);
        blas.bvh().validate(26).unwrap();
        for (k, q) in quads.iter().enumerate() {
            // Quads are numbered in mesh order: quad i holds triangles 2i and 2i + 1.
            assert_eq!(q.index[0] as usize, 2 * blas.bvh().order()[k] as usize);
            assert_eq!(q.is_pair(), q.index[0] != 50, "only the last triangle has no partner");
            assert_eq!(blas.triangle(2 * k as u32 + 1).is_some(), q.is_pair());
        }
        assert_all_triangles_once(&blas, 51, strip);
        assert_eq!(std::mem::size_of::<BlasQuad>(), 64);
        assert_eq!(blas.bounds(), Aabb::new(Vec3::ZERO, Vec3::new(26.0, 1.0, 0.0)));
        assert_eq!(WideBlas::empty().triangle_count(), 0);
    }

    /// A strip of squares split `(a, b, c)`, `(c, d, a)` pairs as the fan split does: each
    /// second triangle is stored turned, and a hit's weights go back to the mesh's order.
    #[test]
    fn turned_neighbours_pair_and_weights_go_back_to_mesh_order() {
        let exported = |i: usize| strip_reordered(i, [1, 2, 0]);
        let blas = WideBlas::build(40, exported);
        let BlasPrims::Quads(quads) = blas.prims() else { panic!("turned neighbours pair") };
        assert_eq!(quads.len(), 20);
        assert!(quads.iter().all(|q| q.turns == [0, 2]));
        assert_all_triangles_once(&blas, 40, exported);
        for prim in 0..40 {
            let (_, i) = blas.triangle(prim).unwrap();
            let w = Vec3::new(0.25, 0.5, 0.25);
            assert_eq!(blas.mesh_weights(prim, w) == w, i.is_multiple_of(2), "only the turned halves change weights");
        }
    }

    #[test]
    fn meshes_that_mostly_do_not_pair_keep_lone_triangles() {
        // Each square's second triangle mirrored, facing the other way: no neighbours pair.
        let mirrored = |i: usize| strip_reordered(i, [0, 2, 1]);
        let blas = WideBlas::build(40, mirrored);
        let BlasPrims::Triangles(tris) = blas.prims() else { panic!("no pairs: lone triangles") };
        blas.bvh().validate(40).unwrap();
        for (k, t) in tris.iter().enumerate() {
            assert_eq!(t.index, blas.bvh().order()[k]);
        }
        assert_all_triangles_once(&blas, 40, mirrored);
        // A quarter of the triangles in pairs is enough for quads (one pair among four).
        let some = |i: usize| if i < 2 { strip(i) } else { mirrored(i + 2) };
        assert!(matches!(WideBlas::build(4, some).prims(), BlasPrims::Quads(q) if q.len() == 3));
        assert!(matches!(WideBlas::build(5, some).prims(), BlasPrims::Triangles(_)));
        assert_all_triangles_once(&WideBlas::build(4, some), 4, some);
    }

    /// Triangle `i` of a strip of `n / 2` squares ([`strip`]) in the order of a fixed
    /// shuffle, and the square each triangle belongs to.
    fn shuffled_strip(n: usize) -> (impl Fn(usize) -> [Vec3; 3], impl Fn(usize) -> usize) {
        // i ↦ 7i + 3 mod n is a permutation when n is prime to 7.
        assert!(!n.is_multiple_of(7));
        let source = move |i: usize| (7 * i + 3) % n;
        (move |i| strip(source(i)), move |i| source(i) / 2)
    }

    /// Triangles that share an edge pair up wherever the mesh puts them, each with its
    /// square's other half (the tightest partner: one across a square's side would make a
    /// box two squares wide), the pairs in order of their first triangle.
    #[test]
    fn triangles_apart_in_the_mesh_pair_across_their_shared_edge() {
        let n = 60;
        let (tri, square) = shuffled_strip(n);
        // No two neighbours in the mesh share an edge.
        assert!((0..n - 1).all(|i| turns_to_pair(&tri(i), &tri(i + 1)).is_none()));
        let blas = WideBlas::build(n, &tri);
        let BlasPrims::Quads(quads) = blas.prims() else { panic!("every triangle has its partner") };
        assert_eq!(quads.len(), n / 2);
        blas.bvh().validate(n / 2).unwrap();
        for q in quads {
            assert!(q.is_pair());
            assert_eq!(square(q.index[0] as usize), square(q.index[1] as usize), "the two halves of one square");
        }
        // Record r (stored in the slot whose `order` is r) has the r-th smallest first index.
        let mut first = vec![0; n / 2];
        for (q, &r) in quads.iter().zip(blas.bvh().order()) {
            first[r as usize] = q.index[0];
        }
        assert!(first.windows(2).all(|w| w[0] < w[1]), "{first:?}");
        assert_all_triangles_once(&blas, n, &tri);
    }

    /// Neighbours in the mesh that meet across a square's side (a loose pair, its box two
    /// squares wide) do not pair at once: each square's halves, the tighter partners, pair
    /// instead, whether they are neighbours in the mesh or not.
    #[test]
    fn a_loose_neighbour_gives_way_to_a_tighter_partner() {
        // Squares 0..n, stored as square i's first half then square i + 1's second half,
        // which share the side x = i + 1; square 0's second half comes last.
        let n = 20;
        let source = move |i: usize| {
            if i + 1 == 2 * n {
                1
            } else if i.is_multiple_of(2) {
                i
            } else {
                i + 2
            }
        };
        let tri = move |i: usize| strip(source(i));
        assert_eq!(pair_fit(&tri(0), &tri(1)), 1.0);
        assert!(turns_to_pair(&tri(0), &tri(1)).is_some(), "a neighbour that would complete a quad");
        let blas = WideBlas::build(2 * n, tri);
        let BlasPrims::Quads(quads) = blas.prims() else { panic!("every triangle has a partner") };
        assert_eq!(quads.len(), n);
        for q in quads {
            assert!(q.is_pair());
            assert_eq!(source(q.index[0] as usize) / 2, source(q.index[1] as usize) / 2, "{q:?}");
        }
        assert_all_triangles_once(&blas, 2 * n, tri);
    }

    /// A corner written −0 in one triangle and +0 in another is one corner: the edges
    /// through it meet.
    #[test]
    fn minus_zero_corners_meet_across_the_mesh() {
        let negated = strip(1).map(|c| if c == Vec3::ZERO { -Vec3::ZERO } else { c });
        assert!(negated[0].x.is_sign_negative());
        // The two halves of square 0 apart in the mesh, square 1's first half between.
        let mesh = [strip(0), strip(2), negated];
        let records = pair_up(&mesh);
        assert_eq!(records.iter().map(|r| r.0).collect::<Vec<_>>(), [[0, 2], [1, NO_TRIANGLE]]);
    }

    /// An edge with two triangles running it one way and one the other (a non-manifold
    /// edge) tries each pair: the first one would make a kite too large to pair.
    #[test]
    fn a_non_manifold_edge_tries_every_partner() {
        let (a, c) = (Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        let long = [a, Vec3::new(10.0, 0.0, 0.0), c];
        let across = [a, c, Vec3::new(0.0, 10.0, 0.0)];
        let flat = [a, c, Vec3::new(0.5, 1.0, 0.0)];
        assert!(turns_to_pair(&long, &across).is_none() && turns_to_pair(&long, &flat).is_some());
        let mesh = [long, across, flat];
        let records = pair_up(&mesh);
        assert_eq!(records.iter().map(|r| r.0).collect::<Vec<_>>(), [[0, 2], [1, NO_TRIANGLE]]);
    }

    /// The triangles of many coincident copies of a square (thousands on each edge) still
    /// pair up, two by two, without a search over all pairs; the records come in order of
    /// their first triangle.
    #[test]
    fn crowded_edges_still_pair_in_linear_time() {
        let n = 20_000;
        let copies: Vec<[Vec3; 3]> = (0..n).map(|i| if i < n / 2 { strip(0) } else { strip(1) }).collect();
        // One candidate per copy of the diagonal, not one per pair of copies.
        let all: Vec<u32> = (0..n as u32).collect();
        assert_eq!(across_edges(&copies, &all).len(), n / 2);
        let records = pair_up(&copies);
        // Every triangle runs the diagonal: one half's copies one way, the other's the other.
        assert!(records.windows(2).all(|w| w[0].0[0] < w[1].0[0]));
        assert_eq!(records.len(), n / 2, "every copy of one half pairs with a copy of the other");
        assert!(records.iter().all(|r| r.0[1] != NO_TRIANGLE && (r.0[0] < n as u32 / 2) != (r.0[1] < n as u32 / 2)));
    }

    #[test]
    fn only_neighbours_that_make_a_flat_enough_quad_pair_up() {
        let [a, b, c] = strip(0);
        let d = strip(1)[2];
        assert_eq!(turns_to_pair(&[a, b, c], &[a, c, d]), Some([0, 0]));
        // Other rotations and the other order pair too, turned to the same pattern: the
        // `(0, 1, 2), (2, 3, 0)` of many exporters, and the second triangle first.
        assert_eq!(turns_to_pair(&[a, b, c], &[c, d, a]), Some([0, 2]));
        assert_eq!(turns_to_pair(&[b, c, a], &[d, a, c]), Some([2, 1]));
        assert_eq!(turns_to_pair(&[a, c, d], &[a, b, c]), Some([1, 2]));
        // Neighbours that face opposite ways (the shared edge run the same way) do not.
        assert_eq!(turns_to_pair(&[a, b, c], &[a, d, c]), None);
        assert_eq!(turns_to_pair(&[a, b, c], &[c, a, d]), None);
        // Nor do triangles that share a corner only.
        assert_eq!(turns_to_pair(&[a, b, c], &[c, Vec3::new(2.0, 1.0, 0.0), Vec3::new(2.0, 2.0, 0.0)]), None);
        // A long kite whose halves stick out along x and y: the pair's box (10 × 10) is far
        // larger than the halves' (10 × 1 and 1 × 10).
        assert_eq!(turns_to_pair(&[a, Vec3::new(10.0, 0.0, 0.0), c], &[a, c, Vec3::new(0.0, 10.0, 0.0)]), None);
        // A folded pair that stays compact (a box's corner) still pairs.
        assert_eq!(turns_to_pair(&[a, b, c], &[a, c, Vec3::new(1.0, 1.0, 1.0)]), Some([0, 0]));
        // Non-finite corners never pair, even with a shared edge.
        let nan = Vec3::splat(f32::NAN);
        assert_eq!(turns_to_pair(&[nan, b, c], &[nan, c, d]), None);
        assert_eq!(turns_to_pair(&[a, b, c], &[a, c, nan]), None);
        assert_eq!(turns_to_pair(&[a, b, c], &[a, c, Vec3::INFINITY]), None);
    }
}

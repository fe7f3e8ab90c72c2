//! Bottom level: one wide BVH per mesh over its triangles (paired into quads where the mesh
//! allows), built once and shared by every instance of the mesh.
//!
//! Two triangles that share an edge, paired as [`super::pairing`] decides (most meshes are
//! made of quads, each stored as two triangles that share a diagonal), are kept as one
//! record of four corners, the quad primitive of Embree (Wald et al. 2014, "Embree: A
//! Kernel Framework for Efficient CPU Ray Tracing"): the tree has half the primitives, a
//! record is one cache line (four packed `Vec3`s and the two triangles' mesh indices,
//! aligned to 64 bytes, against 80 bytes for two triangle records), and a ray test
//! shears the shared corners and computes the shared edge once for both triangles. Each
//! triangle keeps its own corners in its own order, turned (a rotation keeps its facing
//! and its edges, so the watertight test stays watertight) so that the two make
//! `(p, q, r)` and `(p, r, s)`, sharing the diagonal `p r`; a test of the pair computes, bit for bit, what tests of
//! the two triangles in their stored order compute, and [`WideBlas::mesh_weights`]
//! gives a hit's weights back in the mesh's order.
//!
//! A triangle without a partner is a record of its own, whose second triangle is absent.
//! A BVH over quads has one quad per leaf. A mesh of which fewer than half the triangles
//! pair up keeps lone-triangle records instead (40 bytes, up to four per leaf, the
//! settings measured for triangles): in quad records they would waste a third of a line.
//!
//! Corners are exact copies of the mesh's positions (so the watertight edge test stays
//! watertight), in leaf order.

use glam::{Affine3A, Vec3};
use rayon::prelude::*;
use sightline_scene::{Aabb, Mesh};

use super::pairing::{box_of, pair_up, read_triangles, turned, Pairing, NO_TRIANGLE};
use super::{WideBuildParams, WideBvh};

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

impl WideBlas {
    /// Builds over `count` triangles whose corners `corners(i)` gives, as quads when at
    /// least half of them pair up (see the module's header), else as lone triangles (corners
    /// read once, in parallel, for the pairing, the boxes and the copy in leaf order).
    pub fn build(count: usize, corners: impl Fn(usize) -> [Vec3; 3] + Sync) -> WideBlas {
        // Each triangle's corners read once: in a mesh whose triangles are not stored near
        // their neighbours, each read misses the cache four times (an index, then three
        // positions), and the pairing, the boxes and the copy in leaf order each read them.
        let (tris, joins) = read_triangles(count, &corners);
        let records = pair_up(&tris, &joins);
        // Each pair saves a record.
        if 4 * (count - records.len()) < count {
            let bvh = WideBvh::build_fn(count, WideBuildParams::BLAS, |i| box_of(&tris[i]));
            let lone = bvh.order().par_iter().map(|&i| BlasTriangle { corners: tris[i as usize], index: i }).collect();
            return WideBlas { prims: BlasPrims::Triangles(lone), bvh, triangles: count, turned: false };
        }
        let (bvh, quads) = quads_in_leaf_order(&tris, &records, make_once(&records));
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

    /// Number of stored triangles that share a quad record with a partner (the rest are
    /// records of their own): how well the mesh paired up.
    pub fn paired_triangles(&self) -> usize {
        match &self.prims {
            BlasPrims::Quads(quads) => 2 * quads.iter().filter(|q| q.is_pair()).count(),
            BlasPrims::Triangles(_) => 0,
        }
    }

    /// The tree over the primitives (quads, or lone triangles).
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

/// Whether [`quads_in_leaf_order`] makes each quad once and copies it: when more than a
/// quarter of the records pair triangles that are not neighbours in the mesh. Only the two
/// ends were measured (nearly every pair neighbours, every pair apart); the quarter between
/// them is a guess that leans towards the copy.
fn make_once(records: &[Pairing]) -> bool {
    let apart = records.iter().filter(|(i, _)| i[1] != NO_TRIANGLE && i[1] != i[0] + 1).count();
    4 * apart > records.len()
}

/// The tree over the quads that `records` make of `tris`, and the quads in its leaf order.
///
/// The leaf order is known only once the tree is built over the quads' boxes. A quad is
/// made from its record and two triangles. When the two triangles are neighbours in the
/// mesh, making each quad twice (once for its box, in record order, then again in leaf
/// order) costs less than making it once and copying it into leaf order: the copy is 64
/// bytes of fresh memory a quad. On the exported OBJ city (10^6 triangles, nearly all pairs
/// neighbours) one binary doing either way took 191 ms against 211 ms to build (medians of
/// twenty alternated cold builds; 131 against 143 ms warm). When pairs were found across
/// the mesh (`once`, see [`make_once`]), making a quad in leaf order reads two far places;
/// then each is made once, in record order, and copied (on the shuffled city, every pair
/// apart: 329 ms against 353 ms warm). Both ways give the same tree and quads.
fn quads_in_leaf_order(tris: &[[Vec3; 3]], records: &[Pairing], once: bool) -> (WideBvh, Vec<BlasQuad>) {
    let quad = |&(index, turns): &Pairing| {
        let a = turned(&tris[index[0] as usize], turns[0]);
        let d = if index[1] == NO_TRIANGLE { a[2] } else { turned(&tris[index[1] as usize], turns[1])[2] };
        BlasQuad { corners: [a[0], a[1], a[2], d], index, turns }
    };
    if once {
        let made: Vec<BlasQuad> = records.par_iter().map(quad).collect();
        let bvh = WideBvh::build_fn(made.len(), WideBuildParams::BLAS_QUADS, |i| box_of(&made[i].corners));
        let quads = bvh.order().par_iter().map(|&i| made[i as usize]).collect();
        return (bvh, quads);
    }
    let bvh = WideBvh::build_fn(records.len(), WideBuildParams::BLAS_QUADS, |i| box_of(&quad(&records[i]).corners));
    let quads = bvh.order().par_iter().map(|&i| quad(&records[i as usize])).collect();
    (bvh, quads)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::pairing::tests::{pair_mesh, strip, turns_to_pair};

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

    /// The point of weights `w` on triangle `c`.
    fn at(c: [Vec3; 3], w: Vec3) -> Vec3 {
        c[0] * w.x + c[1] * w.y + c[2] * w.z
    }

    /// Every triangle of `mesh` comes back once from the slots of `blas`, with its corners.
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
        assert_eq!(blas.paired_triangles(), 50);
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
        assert_eq!(blas.paired_triangles(), 0);
        // Half the triangles in pairs is enough for quads (one pair among four); two of five
        // is not.
        let some = |i: usize| if i < 2 { strip(i) } else { mirrored(i + 2) };
        assert!(matches!(WideBlas::build(4, some).prims(), BlasPrims::Quads(q) if q.len() == 3));
        assert_eq!(WideBlas::build(4, some).paired_triangles(), 2);
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

    /// The copy is chosen when more than a quarter of the records pair triangles apart (a
    /// lone triangle is no pair apart).
    #[test]
    fn quads_are_copied_when_many_pairs_lie_apart() {
        let (near, far, lone) = (([4, 5], [0; 2]), ([4, 9], [0; 2]), ([4, NO_TRIANGLE], [0; 2]));
        assert!(!make_once(&[near, near, lone, far]), "one of four apart");
        assert!(make_once(&[near, lone, far]), "one of three apart");
        assert!(!make_once(&[lone, lone]) && !make_once(&[]));
    }

    /// Quads made once and copied, or made twice, give the same tree and the same quads, on
    /// pairs of neighbours and on pairs found across the mesh. The squares are sheared, so
    /// that a quad's box is wider than its first triangle's.
    #[test]
    fn both_ways_of_making_quads_agree() {
        let shear = |t: [Vec3; 3]| t.map(|p| p - Vec3::X * (0.25 * p.y));
        let (shuffled, _) = shuffled_strip(60);
        let neighbours: Vec<_> = (0..61).map(|i| shear(strip(i))).collect();
        for (tris, apart) in [(neighbours, false), ((0..60).map(|i| shear(shuffled(i))).collect(), true)] {
            let records = pair_mesh(&tris);
            assert_eq!(make_once(&records), apart, "pairs of neighbours are made twice, pairs apart once");
            let (a, qa) = quads_in_leaf_order(&tris, &records, true);
            let (b, qb) = quads_in_leaf_order(&tris, &records, false);
            assert_eq!((a.order(), a.root(), a.nodes()), (b.order(), b.root(), b.nodes()));
            let key = |q: &BlasQuad| (q.corners.map(|c| c.to_array().map(f32::to_bits)), q.index, q.turns);
            assert!(qa.iter().map(key).eq(qb.iter().map(key)));
        }
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
}

//! Pairing a mesh's triangles into quads for the ray caster's BLAS ([`super::WideBlas`]):
//! two triangles that share an edge, run it opposite ways (so they face the same way) and
//! together fill their box tightly become one record of four corners.
//!
//! Meshes made of quads store each quad as two triangles that share a diagonal, and they
//! usually come one after the other: `(a, b, c)` then `(a, c, d)`, the fan triangulation
//! that mesh builders and OBJ loaders give a polygon, or another rotation of either, such
//! as the `(a, b, c)`, `(c, d, a)` of many exporters. So each triangle first tries the
//! next one. Triangles that share an edge but not a place in the mesh pair too: meshes
//! reordered for the vertex cache, or triangulated in another order, would otherwise keep
//! their triangles apart. So the triangles left meet across their edges, matched by
//! sorting, the tightest pairs first ([`pair_up`]); a neighbour in the mesh that would make
//! a loose pair waits for that second pass too.
//!
//! Two triangles are paired only when the pair's box is no larger (by surface area) than
//! their two boxes together ([`pair_fit`]): a pair folded over its diagonal would make the
//! tree worse. Each triangle of a pair is turned (a rotation keeps its facing and its
//! edges) so that the two make `(p, q, r)` and `(p, r, s)`, the quad `(p, q, r, s)`.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb as ObAabb;
use rayon::iter::Either;
use rayon::prelude::*;
use sightline_scene::Aabb;

use crate::prefetch_all;

/// [`super::BlasQuad::index`] of a quad's absent second triangle.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// The box of some corners, as the wide BVH's builder takes it.
pub(super) fn box_of(c: &[Vec3]) -> ObAabb {
    let b = Aabb::from_points(c);
    ObAabb::new(Vec3A::from(b.min), Vec3A::from(b.max))
}

/// Triangle `t` turned by `k` corners: corner `i` is `t[(i + k) % 3]`.
pub(super) fn turned(t: &[Vec3; 3], k: u8) -> [Vec3; 3] {
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
    let area = |c: &[Vec3]| Aabb::from_points(c).half_area();
    let whole = area(&[a[0], a[1], a[2], b[0], b[1], b[2]]);
    let parts = area(a) + area(b);
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
    // The shared edge first: it costs a few comparisons, the fit three boxes, and about
    // half of the neighbours a mesh holds share no edge.
    let turns = (0..9u8).map(|k| [k % 3, k / 3]).find(|&[ka, kb]| {
        let (a, b) = (turned(a, ka), turned(b, kb));
        b[0] == a[0] && b[1] == a[2]
    })?;
    let fit = pair_fit(a, b);
    (fit <= 1.0).then_some((turns, fit))
}

/// One record before it is stored: the mesh indices of its one or two triangles and their
/// turns.
pub(super) type Pairing = ([u32; 2], [u8; 2]);

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

/// The `count` triangles that `corners` gives, and pass 1 of [`pair_up`] on them: for each
/// triangle `i > 0`, the turns that pair triangle `i - 1` with it when it completes that one
/// tightly (`joins[i]`; `joins[0]` is `None`). One pass does both, each triangle tested
/// against the one read just before it, so that the pairing does not read the whole array
/// once more: on a 10^6-triangle city that second pass took 11 ms, mostly waiting for
/// memory. A run of triangles that one worker reads reads the triangle before it once more.
pub(super) fn read_triangles(
    count: usize,
    corners: impl Fn(usize) -> [Vec3; 3] + Sync,
) -> (Vec<[Vec3; 3]>, Vec<Option<[u8; 2]>>) {
    (0..count)
        .into_par_iter()
        .map_init(
            || None,
            |last: &mut Option<(usize, [Vec3; 3])>, i| {
                let t = corners(i);
                let before = match *last {
                    Some((j, p)) if j + 1 == i => Some(p),
                    _ => i.checked_sub(1).map(&corners),
                };
                *last = Some((i, t));
                let join =
                    before.and_then(|b| completes(&b, &t)).and_then(|(turns, fit)| (fit <= SURE_FIT).then_some(turns));
                (t, join)
            },
        )
        .unzip()
}

/// Pairs triangles into quads, in two greedy passes.
///
/// 1. Each triangle with the next one when it completes it tightly (see [`SURE_FIT`]): the
///    fan- or strip-made meshes of builders and exporters pair this way, their records in
///    mesh order.
/// 2. The triangles left with each other across a shared edge, whatever their places in the
///    mesh (meshes reordered for the vertex cache, or triangulated in some other order):
///    see [`mates_across_edges`].
///
/// Pass 1 comes from [`read_triangles`] (`joins`), which runs it as the mesh is read.
/// Records come in order of their first triangle's mesh index. Linear but for the sorts.
pub(super) fn pair_up(tris: &[[Vec3; 3]], joins: &[Option<[u8; 2]>]) -> Vec<Pairing> {
    let count = tris.len();
    // Turns pairing triangle `i` with triangle `i + 1`.
    let next = |i: usize| joins.get(i + 1).copied().flatten();
    // Pass 1's records: each one's first triangle, and its turns when the next one pairs.
    let firsts = || {
        let mut i = 0;
        std::iter::from_fn(move || {
            let first = (i < count).then_some(i)?;
            i += if next(first).is_some() { 2 } else { 1 };
            Some((first as u32, next(first)))
        })
    };
    let lone: Vec<u32> = firsts().filter(|(_, pair)| pair.is_none()).map(|(i, _)| i).collect();
    let mates = mates_across_edges(tris, &lone);
    let mut out = Vec::with_capacity(count / 2 + 1);
    for (i, pair) in firsts() {
        match (pair, mates.get(i as usize).copied().unwrap_or(Mate::Free)) {
            (Some(turns), _) => out.push(([i, i + 1], turns)),
            (None, Mate::Free) => out.push(([i, NO_TRIANGLE], [0; 2])),
            (None, Mate::First(b, turns)) => out.push(([i, b], turns)),
            (None, Mate::Second) => {}
        }
    }
    out
}

/// A triangle's partner across an edge ([`mates_across_edges`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mate {
    /// None: the triangle stays alone.
    Free,
    /// The first of a record with the triangle given, and their turns.
    First(u32, [u8; 2]),
    /// The second triangle of another's record.
    Second,
}

/// Pass 2 of [`pair_up`]: partners for the triangles `lone` (of `tris`) across shared
/// edges, each triangle's [`Mate`] (empty when none pairs). Their edges, keyed by a hash of
/// the two corners' bits and marked by the way they run ([`corner_hash`]), are sorted so
/// that the triangles on one edge lie together; two that run it opposite ways make a
/// candidate (see [`EDGE_CANDIDATES`]), tested by [`completes`] in parallel, and the
/// candidates that complete are taken tightest first ([`pair_fit`]; ties in the order the
/// edges' keys sort) while both triangles are still free. Without that order a facade's
/// triangles would pair across the sides of its cells about as often as across their
/// diagonals, into quads whose boxes are two cells wide: on the street path of a city
/// shuffled so, rays were about 5% slower than with no pairs at all.
fn mates_across_edges(tris: &[[Vec3; 3]], lone: &[u32]) -> Vec<Mate> {
    // (fit, triangles, turns) of the candidates that complete. The candidates come in the
    // order of their edges' keys, so their triangles lie anywhere: each asks ahead for the
    // corners it will read.
    let mut fits: Vec<(f32, [u32; 2], [u8; 2])> = across_edges(tris, lone)
        .par_chunks(4096)
        .flat_map_iter(|chunk| {
            chunk.iter().enumerate().filter_map(|(k, &[a, b])| {
                if let Some(&[a, b]) = chunk.get(k + CORNERS_AHEAD) {
                    prefetch_all(std::slice::from_ref(&tris[a as usize]));
                    prefetch_all(std::slice::from_ref(&tris[b as usize]));
                }
                completes(&tris[a as usize], &tris[b as usize]).map(|(turns, fit)| (fit, [a, b], turns))
            })
        })
        .collect();
    if fits.is_empty() {
        return Vec::new();
    }
    // By the fit alone, keeping the candidates' order among equal fits (most fits are 0.5,
    // the halves of a square, or 1, across its sides). On the 1.3 million candidates of a
    // shuffled city this serial stable sort took 13–23 ms, where a parallel sort of the
    // whole tuples, to order ties by mesh index, took 49 ms. A fit is ≥ 0, so its bits
    // order like it.
    fits.sort_by_key(|&(fit, ..)| fit.to_bits());
    let mut mates = vec![Mate::Free; tris.len()];
    for (_, [a, b], turns) in fits {
        if mates[a as usize] == Mate::Free && mates[b as usize] == Mate::Free {
            mates[a as usize] = Mate::First(b, turns);
            mates[b as usize] = Mate::Second;
        }
    }
    mates
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// [`pair_up`] of a mesh's triangles, pass 1 included.
    pub(in crate::bvh::wide) fn pair_mesh(tris: &[[Vec3; 3]]) -> Vec<Pairing> {
        let (_, joins) = read_triangles(tris.len(), |i| tris[i]);
        pair_up(tris, &joins)
    }

    /// [`read_triangles`] gives each triangle's join with the one before it, as testing
    /// every neighbouring pair one by one does, on every pool size: where a worker's run of
    /// triangles starts, the triangle before the run is read once more.
    #[test]
    fn joins_read_with_the_mesh_are_those_of_every_neighbouring_pair() {
        // The two halves of one square over and over, so that every neighbouring pair
        // joins (wherever the pool cuts the runs), but for every seventh triangle, from a
        // square far away, which joins neither neighbour.
        let mesh: Vec<[Vec3; 3]> =
            (0..60_000).map(|i| if i % 7 == 3 { strip(20 + 2 * (i % 5)) } else { strip(i % 2) }).collect();
        let want: Vec<Option<[u8; 2]>> = (0..mesh.len())
            .map(|i| {
                let (turns, fit) = completes(&mesh[i.checked_sub(1)?], &mesh[i])?;
                (fit <= SURE_FIT).then_some(turns)
            })
            .collect();
        assert!(want.iter().filter(|j| j.is_some()).count() > 40_000);
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (tris, joins) = pool.install(|| read_triangles(mesh.len(), |i| mesh[i]));
            assert_eq!(tris, mesh);
            assert_eq!(joins, want, "{threads} threads");
        }
    }

    /// The turns with which `b` completes `a` ([`completes`]).
    pub(in crate::bvh::wide) fn turns_to_pair(a: &[Vec3; 3], b: &[Vec3; 3]) -> Option<[u8; 2]> {
        completes(a, b).map(|(turns, _)| turns)
    }

    /// Triangle `i` of a strip of unit squares along x, each split `(a, b, c)`, `(a, c, d)`.
    pub(in crate::bvh::wide) fn strip(i: usize) -> [Vec3; 3] {
        let o = Vec3::new((i / 2) as f32, 0.0, 0.0);
        let (a, b, c, d) = (o, o + Vec3::X, o + Vec3::new(1.0, 1.0, 0.0), o + Vec3::Y);
        if i.is_multiple_of(2) {
            [a, b, c]
        } else {
            [a, c, d]
        }
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
        let records = pair_mesh(&mesh);
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
        let records = pair_mesh(&copies);
        // Every triangle runs the diagonal: one half's copies one way, the other's the other.
        assert!(records.windows(2).all(|w| w[0].0[0] < w[1].0[0]));
        assert_eq!(records.len(), n / 2, "every copy of one half pairs with a copy of the other");
        assert!(records.iter().all(|r| r.0[1] != NO_TRIANGLE && (r.0[0] < n as u32 / 2) != (r.0[1] < n as u32 / 2)));
    }

    /// Neighbours in the mesh that meet across a square's side (a loose pair, its box two
    /// squares wide) do not pair at once: each square's halves, the tighter partners, pair
    /// instead, whether they are neighbours in the mesh or not.
    #[test]
    fn a_loose_neighbour_gives_way_to_a_tighter_partner() {
        // Squares 0..n, stored as square i's first half then square i + 1's second half,
        // which share the side x = i + 1; square 0's second half comes last.
        let n = 20;
        let source = |i: usize| {
            if i + 1 == 2 * n {
                1
            } else if i.is_multiple_of(2) {
                i
            } else {
                i + 2
            }
        };
        let mesh: Vec<[Vec3; 3]> = (0..2 * n).map(|i| strip(source(i))).collect();
        assert_eq!(pair_fit(&mesh[0], &mesh[1]), 1.0);
        assert!(completes(&mesh[0], &mesh[1]).is_some(), "a neighbour that would complete a quad");
        let records = pair_mesh(&mesh);
        assert_eq!(records.len(), n);
        for ([a, b], _) in records {
            assert_ne!(b, NO_TRIANGLE);
            assert_eq!(source(a as usize) / 2, source(b as usize) / 2, "{a} and {b}");
        }
    }

    /// The records do not depend on the thread count, on a mesh where both passes and the
    /// crowded-edge rule all pair: a strip of squares scrambled so that neighbours in the
    /// mesh seldom share an edge, then with its triangles in runs of a thousand coincident
    /// copies.
    #[test]
    fn records_are_the_same_for_any_thread_count() {
        let n = 30_000;
        let mut mesh: Vec<[Vec3; 3]> = (0..n).map(|i| strip(7 * i % n)).collect();
        mesh.extend((0..4000).map(|i| strip(i / 1000 % 4)));
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| pair_mesh(&mesh))
        };
        let one = on(1);
        assert_eq!(one, on(2));
        assert_eq!(one, on(3));
        assert_eq!(one.len() * 2, mesh.len(), "every triangle pairs");
    }

    /// Among candidates of equal fit, the one whose edge key sorts first is taken. Each
    /// square here is cut into four triangles through its center, and each triangle fits
    /// each of its two neighbours exactly as well (fit 1; the squares lie apart, on whole
    /// coordinates, so every fit is exact). So a square's first edge in key order decides
    /// which of its two pairings it gets, whatever the triangles' places in the mesh
    /// (shuffled here) and their turns. (A sort that keeps ties in mesh order, reverses
    /// them, or does not keep their order fails it.)
    #[test]
    fn equal_fits_go_in_the_order_of_their_edges_keys() {
        let mut rng = sightline_scene::rng::Rng::new(5);
        let squares = 200;
        let mut mesh = Vec::new();
        let mut expected = Vec::new();
        for s in 0..squares {
            let o = Vec3::new(4.0 * s as f32, rng.below(1000) as f32, rng.below(1000) as f32);
            let p = [o, o + 2.0 * Vec3::X, o + Vec3::new(2.0, 2.0, 0.0), o + 2.0 * Vec3::Y];
            let c = o + Vec3::new(1.0, 1.0, 0.0);
            // Triangle k is (c, p[k], p[k + 1]); it shares the edge c p[k + 1] with triangle
            // k + 1, which runs it the other way.
            let tris: Vec<[Vec3; 3]> = (0..4).map(|k| turned(&[c, p[k], p[(k + 1) % 4]], rng.below(3) as u8)).collect();
            assert_eq!(pair_fit(&tris[0], &tris[1]), 1.0);
            let key = |k: usize| (corner_hash(c) ^ corner_hash(p[k])) >> 32;
            let first = (0..4).min_by_key(|&k| key(k)).unwrap();
            // Edge c p[first] joins triangles first − 1 and first; the other two pair after.
            let base = 6 * s;
            expected.push([base + (first + 3) % 4, base + first]);
            expected.push([base + (first + 1) % 4, base + (first + 2) % 4]);
            mesh.extend(tris);
            // And a square cut in two beside it, whose halves fit better (0.5): so that the
            // sort by fit has work to do, its candidate among the others in key order.
            let q = o + Vec3::new(0.0, 3.0, 0.0);
            let (a, b, c, d) = (q, q + Vec3::X, q + Vec3::new(1.0, 1.0, 0.0), q + Vec3::Y);
            mesh.extend([[a, b, c], [a, c, d]]);
            expected.push([base + 4, base + 5]);
        }
        // Shuffle the mesh: `place[i]` is where triangle i goes.
        let mut place: Vec<usize> = (0..mesh.len()).collect();
        for i in (1..place.len()).rev() {
            place.swap(i, rng.below(i as u32 + 1) as usize);
        }
        let mut shuffled = mesh.clone();
        for (i, &at) in place.iter().enumerate() {
            shuffled[at] = mesh[i];
        }
        let mut want: Vec<[u32; 2]> = expected
            .iter()
            .map(|&[a, b]| {
                let (a, b) = (place[a] as u32, place[b] as u32);
                [a.min(b), a.max(b)]
            })
            .collect();
        want.sort_unstable();
        let got: Vec<[u32; 2]> = pair_mesh(&shuffled).into_iter().map(|r| r.0).collect();
        assert_eq!(got, want);
    }

    /// A corner written −0 in one triangle and +0 in another is one corner: the edges
    /// through it meet.
    #[test]
    fn minus_zero_corners_meet_across_the_mesh() {
        let negated = strip(1).map(|c| if c == Vec3::ZERO { -Vec3::ZERO } else { c });
        assert!(negated[0].x.is_sign_negative());
        // The two halves of square 0 apart in the mesh, square 1's first half between.
        let mesh = [strip(0), strip(2), negated];
        let records = pair_mesh(&mesh);
        assert_eq!(records.iter().map(|r| r.0).collect::<Vec<_>>(), [[0, 2], [1, NO_TRIANGLE]]);
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

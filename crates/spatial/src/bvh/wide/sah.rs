//! Top-down binned SAH construction writing 4-wide nodes directly, as Embree builds its
//! triangle BVHs (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies"; Wald et al. 2014, "Embree: A Kernel Framework for Efficient CPU Ray
//! Tracing").
//!
//! A wide node is made by splitting its set of primitives in two ([`super::binning`]), then
//! splitting the child with the largest surface area again, until it has [`WIDTH`]
//! children or none is worth splitting; each child with more than a leaf's primitives is
//! built the same way. A child that fits in a leaf is split only when the SAH says two
//! leaves are cheaper (`area·count` summed over both against the set's
//! `area·(count − traversal cost)`): a quad's two triangles stay together, two facing walls
//! do not. Because splits partition in place, a leaf is a run of the primitive array: the
//! final array *is* the leaf order. The splits bound the depth, so the build is
//! O(n log n).
//!
//! Deterministic for any thread count: the splits are, and subtrees built in parallel are
//! laid out in a fixed order. Inner nodes come out parents before their children, as
//! `refit` requires: depth first within each subtree built as one task, each task's
//! nodes after those of the task above it.

use glam::Vec4;
use obvhs::aabb::Aabb as ObAabb;
use rayon::prelude::*;

use super::binning::{split, Bins, Bounds, Prim, Set, BIN_CHUNK};
use super::{WideBvh, WideChild, WideNode, WIDTH};

/// Subtrees at least this large are built as parallel tasks.
const PARALLEL_SUBTREE: usize = 1 << 12;

/// Builds the 4-wide tree over `n` primitives whose boxes (all finite) `bounds(i)` gives, at
/// most `max_leaf` primitives per leaf; `traversal` is the cost of a traversal step
/// against a primitive test, which decides when a set that fits in a leaf is split.
pub(crate) fn build(n: usize, max_leaf: u32, traversal: f32, bounds: impl Fn(usize) -> ObAabb + Sync) -> WideBvh {
    // Primitive indices are 32 bits; the renderers refuse larger scenes before this.
    assert!(u32::try_from(n).is_ok(), "{n} primitives: at most 2^32 - 1 fit a wide BVH");
    if n == 0 {
        return WideBvh { root: WideChild::EMPTY, nodes: Vec::new(), order: Vec::new(), depth: 0 };
    }
    let mut prims: Vec<Prim> = (0..n)
        .into_par_iter()
        .map(|i| {
            let b = bounds(i);
            // Adding +0 turns -0 into +0, so no box's bits depend on which of two equal
            // zeros `min` and `max` return.
            Prim { lo: b.min.extend(0.0) + Vec4::ZERO, hi: b.max.extend(0.0) + Vec4::ZERO }
        })
        .collect();
    let mut ids: Vec<u32> = (0..n as u32).collect();
    let set = prims
        .par_chunks(BIN_CHUNK)
        .map(Bounds::of)
        .reduce(|| (Bounds::EMPTY, Bounds::EMPTY), |a, b| (a.0.union(&b.0), a.1.union(&b.1)));
    let set = Set { start: 0, end: n, bounds: set.0, centroids: set.1, depth: 0 };
    let builder = Builder { max_leaf: max_leaf.max(1) as usize, traversal };
    let mut piece = Piece::for_prims(n);
    let part = Part { prims: &mut prims, ids: &mut ids, offset: 0 };
    let (root, depth) = builder.node(part, set, &mut piece, &mut Box::new(Bins::new()));
    // The root's piece goes first, so the root's link (0) stands.
    let nodes = piece.flatten();
    WideBvh { root, nodes, order: ids, depth }
}

/// The inner nodes of a subtree built as one task (links between them relative to its
/// first node), and the subtrees below it built as tasks of their own. Pieces are laid out
/// once, when the whole tree is built ([`Piece::flatten`]): appending each task's nodes to
/// its parent's list as it finished copied every node once per level of tasks above it,
/// into freshly allocated memory.
struct Piece {
    nodes: Vec<WideNode>,
    below: Vec<Below>,
}

/// A subtree built as a task: the root it hangs from slot `slot` of node `node` of the
/// piece above (its link relative to its own piece), and its piece.
struct Below {
    node: u32,
    slot: usize,
    root: WideChild,
    piece: Piece,
}

impl Piece {
    /// An empty piece for a subtree over `n` primitives, with room for its nodes: a set of
    /// [`PARALLEL_SUBTREE`] or more gets one node, its children being tasks of their own; a
    /// smaller one is built whole in the piece, which gets room for `n / 2` nodes, as a rule
    /// more than it needs (a list that outgrows it still grows; one grown from empty was
    /// copied into new memory at each doubling).
    fn for_prims(n: usize) -> Piece {
        let room = if n >= PARALLEL_SUBTREE { 1 } else { n / 2 };
        Piece { nodes: Vec::with_capacity(room), below: Vec::new() }
    }

    /// Lays out the piece and every piece below it as one array: each piece's nodes after
    /// those of the piece above it, the pieces below one piece in the order they were
    /// built, so parents come before their children. The pieces are copied in parallel,
    /// straight into their places in the new array: a fresh array of a 10^6-triangle BLAS
    /// is 30 MB, whose first writes (page faults) took 11–13 ms on one thread.
    fn flatten(&self) -> Vec<WideNode> {
        // Each piece's first node in the array, and the links to set once they are known.
        let mut placed: Vec<(&Piece, usize)> = Vec::new();
        let mut links: Vec<(usize, usize, WideChild)> = Vec::new();
        let total = self.place(0, &mut placed, &mut links);
        placed.retain(|(p, _)| !p.nodes.is_empty());
        let mut nodes: Vec<WideNode> = (0..total)
            .into_par_iter()
            .with_min_len(1 << 10)
            .map(|k| {
                let (piece, base) = placed[placed.partition_point(|&(_, b)| b <= k) - 1];
                piece.nodes[k - base].shifted(base as u32, 0)
            })
            .collect();
        for (node, slot, root) in links {
            nodes[node].set(slot, &root);
        }
        nodes
    }

    /// Gives this piece's nodes the places from `base` on and the pieces below it the
    /// places after them, in layout order (see [`Piece::flatten`]), noting each piece's
    /// first place in `placed` and the link from each piece below to its root in `links`
    /// (node, slot, root); returns the first place after them all.
    fn place<'a>(
        &'a self,
        base: usize,
        placed: &mut Vec<(&'a Piece, usize)>,
        links: &mut Vec<(usize, usize, WideChild)>,
    ) -> usize {
        placed.push((self, base));
        let mut at = base + self.nodes.len();
        for b in &self.below {
            let mut root = b.root;
            root.link = super::shift_link(root.link, root.count, at as u32, 0);
            links.push((base + b.node as usize, b.slot, root));
            at = b.piece.place(at, placed, links);
        }
        at
    }
}

/// The primitives (and their indices) a subtree is built over, which start at leaf-order
/// position `offset`.
struct Part<'a> {
    prims: &'a mut [Prim],
    ids: &'a mut [u32],
    offset: usize,
}

struct Builder {
    max_leaf: usize,
    traversal: f32,
}

impl Builder {
    /// Builds the subtree over `set` (a range of `part`), adding its inner nodes to `out`;
    /// returns its root and its depth in nodes counted as `WideBvh::depth` does.
    fn subtree(&self, part: Part, set: Set, out: &mut Piece, scratch: &mut Bins) -> (WideChild, usize) {
        if set.len() <= self.max_leaf {
            return (leaf(&part, &set), 1);
        }
        self.node(part, set, out, scratch)
    }

    /// [`Builder::subtree`] for a set that may be split even if it fits in a leaf: the
    /// root. (A child that fits in a leaf was weighed by its parent, or left whole when the
    /// parent's four slots filled first.)
    fn node(&self, part: Part, set: Set, out: &mut Piece, scratch: &mut Bins) -> (WideChild, usize) {
        let Part { prims, ids, offset } = part;
        let (lo, hi) = (set.bounds.lo.truncate().to_array(), set.bounds.hi.truncate().to_array());
        // Split the child with the largest area until four are made or none is worth it.
        let mut kids = [set; WIDTH];
        let mut done = [false; WIDTH];
        let mut nk = 1;
        while nk < WIDTH {
            let mut pick: Option<(usize, f32)> = None;
            for (k, s) in kids[..nk].iter().enumerate() {
                let a = s.bounds.half_area();
                if !done[k] && s.len() > 1 && pick.is_none_or(|(_, b)| a > b) {
                    pick = Some((k, a));
                }
            }
            let Some((k, a)) = pick else { break };
            // A set that fits in a leaf is split only when the SAH says two leaves are cheaper.
            let leaf_cost = (kids[k].len() <= self.max_leaf).then(|| a * (kids[k].len() as f32 - self.traversal));
            // No split costs less than the primitives' own areas summed (each side's box
            // holds its primitives): when that is already too much, skip the binning. Two
            // triangles of one quad end here.
            if leaf_cost.is_some_and(|c| {
                let own: f32 = prims[kids[k].start..kids[k].end].iter().map(Bounds::half_area).sum();
                own >= c
            }) {
                done[k] = true;
                continue;
            }
            let Some((l, r)) = split(prims, ids, &kids[k], leaf_cost, scratch) else {
                done[k] = true;
                continue;
            };
            kids[k] = l;
            kids[nk] = r;
            nk += 1;
        }
        if nk == 1 {
            return (leaf(&Part { prims, ids, offset }, &set), 1);
        }
        // Children in array order, so leaf order follows the node's slots.
        let mut idx = [0, 1, 2, 3];
        idx[..nk].sort_unstable_by_key(|&k| kids[k].start);
        let idx = &idx[..nk];
        // Slots are written in place as the children are built: a node assembled on the
        // stack and copied in was read back in 16-byte loads over its 4-byte stores, which
        // cannot be forwarded, a stall on every node.
        let me = out.nodes.len();
        out.nodes.push(WideNode::EMPTY);
        let mut depth = 0;
        if set.len() >= PARALLEL_SUBTREE {
            // Cut the arrays into the children's ranges and build them as parallel tasks,
            // each into a piece of its own, laid out after this one's (slot order).
            let mut parts = Vec::with_capacity(nk);
            let (mut p_rest, mut i_rest) = (prims, ids);
            let mut at = 0;
            for &k in idx {
                let s = kids[k];
                let (_, p) = p_rest.split_at_mut(s.start - at);
                let (_, i) = i_rest.split_at_mut(s.start - at);
                let (p, p_next) = p.split_at_mut(s.len());
                let (i, i_next) = i.split_at_mut(s.len());
                parts.push((Part { prims: p, ids: i, offset: offset + s.start }, Set { start: 0, end: s.len(), ..s }));
                (p_rest, i_rest, at) = (p_next, i_next, s.end);
            }
            let built: Vec<(WideChild, usize, Piece)> = parts
                .into_par_iter()
                .map(|(part, s)| {
                    let mut piece = Piece::for_prims(s.len());
                    let (c, depth) = self.subtree(part, s, &mut piece, &mut Box::new(Bins::new()));
                    (c, depth, piece)
                })
                .collect();
            for (slot, (root, d, piece)) in built.into_iter().enumerate() {
                // The bounds now; the link when the pieces are laid out.
                out.nodes[me].set(slot, &root);
                out.below.push(Below { node: me as u32, slot, root, piece });
                depth = depth.max(d);
            }
        } else {
            for (slot, &k) in idx.iter().enumerate() {
                let part = Part { prims: &mut *prims, ids: &mut *ids, offset };
                let (c, d) = self.subtree(part, kids[k], out, scratch);
                out.nodes[me].set(slot, &c);
                depth = depth.max(d);
            }
        }
        (WideChild { lo, link: me as u32, hi, count: 0 }, depth + 1)
    }
}

/// The leaf holding all of `set`.
fn leaf(part: &Part, set: &Set) -> WideChild {
    let (lo, hi) = (set.bounds.lo.truncate().to_array(), set.bounds.hi.truncate().to_array());
    WideChild { lo, link: (part.offset + set.start) as u32, hi, count: set.len() as u32 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::binning::MAX_SAH_DEPTH;
    use crate::bvh::wide::{WideBuildParams, EMPTY_LINK};
    use glam::Vec3A;

    fn random_boxes(n: usize, seed: u64) -> Vec<ObAabb> {
        let mut h = seed;
        (0..n)
            .map(|_| {
                h = h.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let p = Vec3A::new((h >> 40) as f32 / 1e3, (h >> 20 & 0xfff) as f32 / 1e2, (h & 0xfff) as f32 / 1e2);
                if h.is_multiple_of(7) {
                    // Flat on the plane x = 0, its sides given as -0 and +0.
                    return ObAabb::new(Vec3A::new(-0.0, p.y, p.z), Vec3A::new(0.0, p.y + 0.5, p.z + 0.5));
                }
                ObAabb::new(p, p + 0.5)
            })
            .collect()
    }

    #[test]
    fn builds_are_valid_and_thread_independent() {
        for n in [1usize, 2, 4, 5, 17, 1000, 50_000] {
            let boxes = random_boxes(n, n as u64);
            let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
            let a = one.install(|| build(n, 4, 1.0, |i| boxes[i]));
            let b = two.install(|| build(n, 4, 1.0, |i| boxes[i]));
            a.validate(n).unwrap();
            b.validate(n).unwrap();
            assert_eq!((a.order.as_slice(), a.root, a.depth), (b.order.as_slice(), b.root, b.depth));
            assert_eq!(a.nodes.len(), b.nodes.len());
            let bits = |v: &[[f32; WIDTH]; 3]| v.map(|r| r.map(f32::to_bits));
            assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| bits(&x.lo) == bits(&y.lo)
                && bits(&x.hi) == bits(&y.hi)
                && x.link == y.link
                && x.count == y.count));
            // Leaves hold at most four primitives; inner nodes come after their parents.
            for (i, node) in a.nodes.iter().enumerate() {
                for k in 0..WIDTH {
                    assert!(node.count[k] <= 4);
                    if node.count[k] == 0 && node.link[k] != EMPTY_LINK {
                        assert!(node.link[k] as usize > i);
                    }
                }
            }
        }
    }

    /// True when some leaf holds exactly the primitives `want` (sorted), in any order.
    fn has_leaf(t: &WideBvh, want: &[u32]) -> bool {
        let leaves = t.nodes.iter().flat_map(|n| (0..WIDTH).map(|k| n.child(k))).chain([t.root]);
        leaves.filter(|c| c.is_leaf()).any(|c| {
            let mut got = t.order[c.link as usize..][..c.count as usize].to_vec();
            got.sort_unstable();
            got == want
        })
    }

    #[test]
    fn a_leaf_is_split_only_when_two_are_cheaper() {
        // Two triangles of one quad share a box: one leaf. Two quads far apart: two leaves.
        let quad = |x: f32| ObAabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 0.0));
        let boxes = [quad(0.0), quad(0.0), quad(10.0), quad(10.0)];
        let t = build(4, 4, 1.0, |i| boxes[i]);
        t.validate(4).unwrap();
        assert!(has_leaf(&t, &[0, 1]) && has_leaf(&t, &[2, 3]), "{:?}", t.nodes);
        // Four copies of one quad stay one leaf.
        let t = build(4, 4, 1.0, |_| quad(0.0));
        assert!(t.root.is_leaf() && t.root.count == 4);
    }

    #[test]
    fn hostile_inputs_build_bounded_trees() {
        // Every wide level makes at least one binary split on each path below it.
        let bound = |n: usize| MAX_SAH_DEPTH as usize + (usize::BITS - n.leading_zeros()) as usize + 2;
        let n = 20_000;
        // Coincident boxes, centroids spaced geometrically (each binning peels off few), and
        // boxes at the ends of the float range (centroid sums overflow to infinity).
        let same = vec![ObAabb::new(Vec3A::ZERO, Vec3A::ONE); n];
        let geometric: Vec<ObAabb> = (0..n)
            .map(|i| {
                let x = 1.01f32.powi(i as i32 % 8000) * if i % 2 == 0 { 1.0 } else { -1.0 };
                ObAabb::new(Vec3A::splat(x), Vec3A::splat(x))
            })
            .collect();
        let huge: Vec<ObAabb> = (0..n)
            .map(|i| {
                let s = if i % 3 == 0 { f32::MAX } else { -f32::MAX * (i % 7) as f32 / 7.0 };
                ObAabb::new(Vec3A::new(s, 0.0, i as f32), Vec3A::new(f32::MAX, 1.0, i as f32 + 1.0))
            })
            .collect();
        for boxes in [same, geometric, huge] {
            let t = build(n, 4, 1.0, |i| boxes[i]);
            t.validate(n).unwrap();
            assert!(t.depth <= bound(n), "depth {} > {}", t.depth, bound(n));
        }
    }

    #[test]
    fn costs_no_more_than_the_ploc_tree_on_a_city_of_quads() {
        // Walls of quads (two triangles each) on a grid of blocks, as the builders' city.
        let mut boxes = Vec::new();
        for b in 0..400 {
            let (bx, bz) = ((b % 20) as f32 * 30.0, (b / 20) as f32 * 30.0);
            for f in 0..40 {
                let (y, x) = ((f / 8) as f32 * 3.0, bx + (f % 8) as f32 * 2.5);
                for z in [bz, bz + 20.0] {
                    let q = ObAabb::new(Vec3A::new(x, y, z), Vec3A::new(x + 2.5, y + 3.0, z));
                    boxes.extend([q, q]);
                }
            }
        }
        let n = boxes.len();
        let sah = build(n, 4, 1.0, |i| boxes[i]);
        let ploc = WideBvh::build_obvhs(&boxes, WideBuildParams::BLAS_PLOC);
        sah.validate(n).unwrap();
        assert!(sah.sah_cost() <= ploc.sah_cost(), "SAH {} against PLOC {}", sah.sah_cost(), ploc.sah_cost());
    }
}

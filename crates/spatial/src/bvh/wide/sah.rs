//! Top-down binned SAH construction writing 4-wide nodes directly, as Embree builds its
//! triangle BVHs (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies"; Wald et al. 2014, "Embree: A Kernel Framework for Efficient CPU Ray
//! Tracing").
//!
//! A set of primitives is split in two by the surface area heuristic evaluated on
//! [`BINS`] bins of box centroids per axis: one pass drops every primitive into its bin on
//! each of the three axes (growing the bin's box and count), a sweep from each end gives
//! the area and count on either side of every bin boundary, and the boundary with the
//! smallest `area(left)·count(left) + area(right)·count(right)` wins. The primitives are
//! then partitioned in place. A wide node is made by splitting its set, then splitting the
//! child with the largest surface area again, until it has [`WIDTH`] children or none is
//! worth splitting; each child with more than a leaf's primitives is built the same way.
//! A child that fits in a leaf is split only when the SAH says two leaves are cheaper
//! (`area·count` summed over both against the set's `area·(count − traversal cost)`): a
//! quad's two triangles stay together, two facing walls do not.
//! Because partitioning is in place, a leaf is a run of the primitive array: the final
//! array *is* the leaf order. Under one primitive per leaf (a BLAS of quads) most splits
//! are of two primitives; those skip the bins and split the way the bins would.
//!
//! Bounded work on any input: when the bins cannot separate a set (all centroids in one
//! bin, e.g. coincident triangles) or a path grows deeper than [`MAX_SAH_DEPTH`] binary
//! splits, the set is cut in the middle of its range instead (Embree's fallback). Every
//! split leaves both sides non-empty and middle cuts halve, so the tree depth is at most
//! `MAX_SAH_DEPTH + log2(n)` binary levels and the build is O(n log n).
//!
//! Deterministic for any thread count: bins are merged with exact operations (min, max,
//! integer counts), partitions run serially, and subtrees built in parallel are appended
//! in a fixed order. Inner nodes come out depth first, as `refit` requires.

use glam::Vec4;
use obvhs::aabb::Aabb as ObAabb;
use rayon::prelude::*;

use super::{WideBvh, WideChild, WideNode, WIDTH};

/// Most centroid bins per axis (Embree's count for object splits); smaller sets use
/// fewer, `4 + n / 20` as Embree does, since sweeping empty bins costs more than it finds.
const BINS: usize = 32;

/// Binary splits along one path beyond which sets are cut in the middle.
const MAX_SAH_DEPTH: u32 = 48;

/// Sets at least this large are binned in parallel chunks.
const PARALLEL_BINNING: usize = 1 << 15;

/// Chunk size of parallel binning.
const BIN_CHUNK: usize = 1 << 13;

/// Subtrees at least this large are built as parallel tasks.
const PARALLEL_SUBTREE: usize = 1 << 12;

/// A primitive's box (the `w` lanes are zero).
type Prim = Bounds;

/// A box accumulated by min and max; starts inverted.
#[derive(Clone, Copy)]
struct Bounds {
    lo: Vec4,
    hi: Vec4,
}

impl Bounds {
    const EMPTY: Bounds = Bounds { lo: Vec4::splat(f32::INFINITY), hi: Vec4::splat(f32::NEG_INFINITY) };

    #[inline(always)]
    fn grow(&mut self, lo: Vec4, hi: Vec4) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    #[inline(always)]
    fn union(&self, o: &Bounds) -> Bounds {
        Bounds { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }

    /// Twice the centre (the bins are scaled to match, saving a multiply).
    #[inline(always)]
    fn centroid2(&self) -> Vec4 {
        self.lo + self.hi
    }

    /// The box of `prims` and the box of their doubled centroids.
    fn of(prims: &[Prim]) -> (Bounds, Bounds) {
        let (mut b, mut c) = (Bounds::EMPTY, Bounds::EMPTY);
        for p in prims {
            b.grow(p.lo, p.hi);
            let m = p.centroid2();
            c.grow(m, m);
        }
        (b, c)
    }

    /// Half the surface area (only called on non-empty boxes).
    #[inline(always)]
    fn half_area(&self) -> f32 {
        let d = self.hi - self.lo;
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// A contiguous range of the primitive array with its box and its centroids' box.
#[derive(Clone, Copy)]
struct Set {
    start: usize,
    end: usize,
    bounds: Bounds,
    /// Box of the doubled centroids.
    centroids: Bounds,
    /// Binary splits made above this set.
    depth: u32,
}

impl Set {
    fn len(&self) -> usize {
        self.end - self.start
    }
}

/// Maps doubled centroids to bin numbers, per axis.
#[derive(Clone, Copy)]
struct Mapping {
    origin: Vec4,
    scale: Vec4,
    /// Bins in use, at most [`BINS`].
    count: usize,
}

impl Mapping {
    fn new(centroids: &Bounds, prims: usize) -> Mapping {
        let count = (4 + prims / 20).min(BINS);
        let extent = centroids.hi - centroids.lo;
        // Slightly under `count` so the largest centroid lands in the last bin; an axis with
        // no (or no finite) extent puts everything in bin 0.
        let s = |e: f32| if e > 0.0 && e.is_finite() { count as f32 * (1.0 - 1e-6) / e } else { 0.0 };
        Mapping { origin: centroids.lo, scale: Vec4::new(s(extent.x), s(extent.y), s(extent.z), 0.0), count }
    }

    /// Bin number of a doubled centroid on `axis` (NaN, from an infinite centroid on an
    /// axis of infinite extent, maps to 0).
    #[inline(always)]
    fn bin(&self, c: Vec4, axis: usize) -> usize {
        let f = ((c[axis] - self.origin[axis]) * self.scale[axis]).max(0.0).min((self.count - 1) as f32);
        // SAFETY: `f` is a number in 0 ..= count - 1 (`max` maps NaN to 0), so it fits.
        unsafe { f.to_int_unchecked::<u32>() as usize }
    }
}

/// Boxes and counts of the bins on each axis.
struct Bins {
    boxes: [[Bounds; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    fn new() -> Bins {
        Bins { boxes: [[Bounds::EMPTY; BINS]; 3], counts: [[0; BINS]; 3] }
    }

    /// Empties the first `count` bins of each axis (the ones a mapping of `count` uses):
    /// reusing one `Bins` this way saves clearing all of them for every small set.
    fn reset(&mut self, count: usize) {
        for a in 0..3 {
            self.boxes[a][..count].fill(Bounds::EMPTY);
            self.counts[a][..count].fill(0);
        }
    }

    fn add(&mut self, prims: &[Prim], map: &Mapping) {
        for p in prims {
            let c = p.centroid2();
            for a in 0..3 {
                let k = map.bin(c, a);
                self.boxes[a][k].grow(p.lo, p.hi);
                self.counts[a][k] += 1;
            }
        }
    }

    fn merge(mut self, o: Bins) -> Bins {
        for a in 0..3 {
            for k in 0..BINS {
                self.boxes[a][k] = self.boxes[a][k].union(&o.boxes[a][k]);
                self.counts[a][k] += o.counts[a][k];
            }
        }
        self
    }

    /// The cheapest boundary: (its cost, axis, first bin on the right, left box, right
    /// box), or `None` when every axis has all primitives in one bin (or only costs that
    /// overflowed to NaN).
    fn best(&self, bins: usize) -> Option<(f32, usize, usize, Bounds, Bounds)> {
        let mut best: Option<(f32, usize, usize)> = None;
        for a in 0..3 {
            // Right-side area·count for each boundary k (bins k.. on the right).
            let mut right = [0.0f32; BINS];
            let (mut acc, mut n) = (Bounds::EMPTY, 0u32);
            for k in (1..bins).rev() {
                acc = acc.union(&self.boxes[a][k]);
                n += self.counts[a][k];
                right[k] = if n > 0 { acc.half_area() * n as f32 } else { f32::NAN };
            }
            let (mut acc, mut n) = (Bounds::EMPTY, 0u32);
            for (k, &r) in right.iter().enumerate().take(bins).skip(1) {
                acc = acc.union(&self.boxes[a][k - 1]);
                n += self.counts[a][k - 1];
                if n == 0 || r.is_nan() {
                    continue;
                }
                let cost = acc.half_area() * n as f32 + r;
                if !cost.is_nan() && best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, a, k));
                }
            }
        }
        let (cost, a, k) = best?;
        let side = |r: std::ops::Range<usize>| r.fold(Bounds::EMPTY, |acc, j| acc.union(&self.boxes[a][j]));
        Some((cost, a, k, side(0..k), side(k..bins)))
    }
}

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
    let mut nodes = Vec::with_capacity(n / 2);
    let part = Part { prims: &mut prims, ids: &mut ids, offset: 0 };
    let (root, depth) = builder.node(part, set, &mut nodes, &mut Box::new(Bins::new()));
    WideBvh { root, nodes, order: ids, depth }
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
    /// Builds the subtree over `set` (a range of `part`), appending its inner nodes to
    /// `out`; returns its root and its depth in nodes counted as `WideBvh::depth` does.
    fn subtree(&self, part: Part, set: Set, out: &mut Vec<WideNode>, scratch: &mut Bins) -> (WideChild, usize) {
        if set.len() <= self.max_leaf {
            return (leaf(&part, &set), 1);
        }
        self.node(part, set, out, scratch)
    }

    /// [`Builder::subtree`] for a set that may be split even if it fits in a leaf: the
    /// root. (A child that fits in a leaf was weighed by its parent, or left whole when the
    /// parent's four slots filled first.)
    fn node(&self, part: Part, set: Set, out: &mut Vec<WideNode>, scratch: &mut Bins) -> (WideChild, usize) {
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
        let me = out.len();
        out.push(WideNode::EMPTY);
        let mut node = WideNode::EMPTY;
        let mut depth = 0;
        if set.len() >= PARALLEL_SUBTREE {
            // Cut the arrays into the children's ranges and build them as parallel tasks,
            // each into its own node list, appended afterwards in slot order.
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
            let built: Vec<(WideChild, usize, Vec<WideNode>)> = parts
                .into_par_iter()
                .map(|(part, s)| {
                    let mut local = Vec::new();
                    let (c, depth) = self.subtree(part, s, &mut local, &mut Box::new(Bins::new()));
                    (c, depth, local)
                })
                .collect();
            for (slot, (mut c, d, local)) in built.into_iter().enumerate() {
                let base = out.len() as u32;
                c.link = super::shift_link(c.link, c.count, base, 0);
                out.extend(local.iter().map(|n| n.shifted(base, 0)));
                node.set(slot, &c);
                depth = depth.max(d);
            }
        } else {
            for (slot, &k) in idx.iter().enumerate() {
                let part = Part { prims: &mut *prims, ids: &mut *ids, offset };
                let (c, d) = self.subtree(part, kids[k], out, scratch);
                node.set(slot, &c);
                depth = depth.max(d);
            }
        }
        out[me] = node;
        (WideChild { lo, link: me as u32, hi, count: 0 }, depth + 1)
    }
}

/// The leaf holding all of `set`.
fn leaf(part: &Part, set: &Set) -> WideChild {
    let (lo, hi) = (set.bounds.lo.truncate().to_array(), set.bounds.hi.truncate().to_array());
    WideChild { lo, link: (part.offset + set.start) as u32, hi, count: set.len() as u32 }
}

/// Splits `set` (a range of `prims` and `ids`) in two non-empty sets: the binned SAH's
/// best boundary, or the middle of the range when the bins cannot separate it or the path
/// is already `MAX_SAH_DEPTH` splits deep. With a `leaf_cost` (the set fits in a leaf),
/// `None` instead when no boundary costs less.
fn split(
    prims: &mut [Prim],
    ids: &mut [u32],
    set: &Set,
    leaf_cost: Option<f32>,
    scratch: &mut Bins,
) -> Option<(Set, Set)> {
    // Two primitives that must be split are most of the splits under a tree of one
    // primitive per leaf (a BLAS of quads).
    if set.len() == 2 && leaf_cost.is_none() && set.depth < MAX_SAH_DEPTH {
        if let Some(sides) = split_two(prims, ids, set) {
            return Some(sides);
        }
    }
    split_binned(prims, ids, set, leaf_cost, scratch)
}

/// [`split`] by the bins.
fn split_binned(
    prims: &mut [Prim],
    ids: &mut [u32],
    set: &Set,
    leaf_cost: Option<f32>,
    scratch: &mut Bins,
) -> Option<(Set, Set)> {
    let range = &prims[set.start..set.end];
    let map = Mapping::new(&set.centroids, set.len());
    let best = if set.depth >= MAX_SAH_DEPTH {
        None
    } else if range.len() >= PARALLEL_BINNING {
        range
            .par_chunks(BIN_CHUNK)
            .fold(Bins::new, |mut b, c| {
                b.add(c, &map);
                b
            })
            .reduce(Bins::new, Bins::merge)
            .best(map.count)
    } else {
        scratch.reset(map.count);
        scratch.add(range, &map);
        scratch.best(map.count)
    };
    let Some((cost, axis, boundary, left_box, right_box)) = best else {
        return if leaf_cost.is_some() { None } else { Some(split_middle(prims, set)) };
    };
    if leaf_cost.is_some_and(|c| cost >= c) {
        return None;
    }
    // The test is the binning's own, so the sides match the bins the boxes came from; one
    // copy of the partition per axis, as a run-time axis costs a jump table per primitive.
    let run = (set.start, set.end);
    let (mid, lc, rc) = match axis {
        0 => partition(prims, ids, run, |p| map.bin(p.centroid2(), 0) < boundary),
        1 => partition(prims, ids, run, |p| map.bin(p.centroid2(), 1) < boundary),
        _ => partition(prims, ids, run, |p| map.bin(p.centroid2(), 2) < boundary),
    };
    Some((
        Set { start: set.start, end: mid, bounds: left_box, centroids: lc, depth: set.depth + 1 },
        Set { start: mid, end: set.end, bounds: right_box, centroids: rc, depth: set.depth + 1 },
    ))
}

/// Partitions `prims[start..end]` (and `ids` alike) in place (Hoare) into those `left_of`
/// and the rest; returns where the rest begin and each side's box of doubled centroids.
#[inline(always)]
fn partition(
    prims: &mut [Prim],
    ids: &mut [u32],
    (start, end): (usize, usize),
    left_of: impl Fn(&Prim) -> bool,
) -> (usize, Bounds, Bounds) {
    let (mut lc, mut rc) = (Bounds::EMPTY, Bounds::EMPTY);
    let (mut i, mut j) = (start, end);
    loop {
        while i < j && left_of(&prims[i]) {
            let c = prims[i].centroid2();
            lc.grow(c, c);
            i += 1;
        }
        while i < j && !left_of(&prims[j - 1]) {
            let c = prims[j - 1].centroid2();
            rc.grow(c, c);
            j -= 1;
        }
        if i >= j {
            break;
        }
        prims.swap(i, j - 1);
        ids.swap(i, j - 1);
    }
    (i, lc, rc)
}

/// [`split`] of a set of two primitives that must be split (larger than a leaf, and
/// not yet `MAX_SAH_DEPTH` splits deep), without the bins, as the bins would split it:
/// every axis on which their centroids differ gives the same cost (the sum of their two
/// areas), so the first such axis wins and the one with the smaller centroid on it goes
/// left. `None` (the bins' answer is needed) when an area is not finite.
fn split_two(prims: &mut [Prim], ids: &mut [u32], set: &Set) -> Option<(Set, Set)> {
    let (a, b) = (set.start, set.start + 1);
    if !(prims[a].half_area().is_finite() && prims[b].half_area().is_finite()) {
        return None;
    }
    let extent = set.centroids.hi - set.centroids.lo;
    let Some(axis) = (0..3).find(|&k| extent[k] > 0.0 && extent[k].is_finite()) else {
        return Some(split_middle(prims, set));
    };
    if prims[a].centroid2()[axis] > prims[b].centroid2()[axis] {
        prims.swap(a, b);
        ids.swap(a, b);
    }
    let one = |i: usize| {
        let c = prims[i].centroid2();
        Set { start: i, end: i + 1, bounds: prims[i], centroids: Bounds { lo: c, hi: c }, depth: set.depth + 1 }
    };
    Some((one(a), one(b)))
}

/// Cuts `set` in the middle of its range, recomputing both sides' boxes.
fn split_middle(prims: &[Prim], set: &Set) -> (Set, Set) {
    let mid = set.start + set.len() / 2;
    let side = |start: usize, end: usize| {
        let (bounds, centroids) = Bounds::of(&prims[start..end]);
        Set { start, end, bounds, centroids, depth: set.depth + 1 }
    };
    (side(set.start, mid), side(mid, set.end))
}

#[cfg(test)]
mod tests {
    use super::*;
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

    /// [`split_two`] gives, bit for bit, what the bins give, on pairs of boxes drawn from
    /// a few coordinates (so that centroids often tie on some axes, or on all, or overflow)
    /// and sizes (flat, and too large for a finite area).
    #[test]
    fn two_primitives_split_as_the_bins_split_them() {
        let mut h = 7u64;
        let mut pick = |values: &[f32]| {
            h = h.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            values[(h >> 33) as usize % values.len()]
        };
        let key = |s: &Set| {
            let v = [s.bounds.lo, s.bounds.hi, s.centroids.lo, s.centroids.hi];
            (s.start, s.end, s.depth, v.map(|v| v.to_array().map(f32::to_bits)))
        };
        let (mut fast, mut tied, mut infinite) = (0, 0, 0);
        for _ in 0..5000 {
            let mut prim = || {
                let lo = Vec4::new(pick(&[0.0, 1.0, 2.0, -3e38]), pick(&[0.0, 1.0, 2.0]), pick(&[0.0, 1.0, 2.0]), 0.0);
                let size = Vec4::new(pick(&[0.0, 1.0, 1e30]), pick(&[0.0, 1.0, 1e30]), pick(&[0.0, 2.0]), 0.0);
                // Sometimes wider than the largest float (a NaN area when flat).
                let far = Vec4::new(pick(&[0.0, 3e38]), 0.0, 0.0, 0.0);
                Prim { lo, hi: (lo + size).max(far) }
            };
            let prims = [prim(), prim()];
            let (bounds, centroids) = Bounds::of(&prims);
            let set = Set { start: 0, end: 2, bounds, centroids, depth: 3 };
            let (mut p, mut i) = (prims.to_vec(), vec![0u32, 1]);
            let Some((l, r)) = split_two(&mut p, &mut i, &set) else {
                infinite += 1;
                continue;
            };
            let (mut bp, mut bi) = (prims.to_vec(), vec![0u32, 1]);
            let (bl, br) = split_binned(&mut bp, &mut bi, &set, None, &mut Bins::new()).unwrap();
            assert_eq!((key(&l), key(&r), &i), (key(&bl), key(&br), &bi));
            fast += 1;
            tied += (centroids.lo == centroids.hi) as usize;
        }
        assert!(fast > 1000 && tied > 10 && infinite > 1000, "{fast} {tied} {infinite}");
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
